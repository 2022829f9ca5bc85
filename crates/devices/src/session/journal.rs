//! The session journal: `journal.json` beside `measurements.csv`, rewritten atomically (write a
//! temporary file, fsync, rename) after each point's last row, so a session killed at any
//! moment resumes with no point lost or duplicated (conventions §7).
//!
//! It holds what the rows alone cannot give back: the session clock, the rig's opaque state
//! (a dry run's world keeps its motion history there: backlash and drift depend on it), where
//! the arm and table stand, the registration, and the
//! byte length of the CSV at that moment (a resume cuts the CSV back to it, removing a torn line
//! or the rows of a point that was not finished).

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use rigcal_core::kinematics::JointSpec;
use rigcal_core::recording::{Recording, RegistrationInfo};

/// The journal's file name in a session directory.
pub const JOURNAL_FILE: &str = "journal.json";

/// What went wrong with the journal.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum JournalError {
    /// Reading or writing failed.
    #[error("session journal {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The journal is not valid JSON of the expected shape.
    #[error("session journal {path}: {reason}; the session cannot resume safely: start a new session in another directory")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        reason: String,
    },
    /// The recording does not hold what the journal committed (checked before a resume).
    #[error("{}: {reason}; the session cannot resume safely: restore the recording (or its journal) from a backup, or start a new session in another directory", csv.display())]
    Disagrees {
        /// The recording.
        csv: PathBuf,
        /// What differs.
        reason: String,
    },
}

/// The state of a session after a completed point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Journal {
    /// Format version.
    pub version: u32,
    /// Index (0-based) of the next plan point to measure.
    pub next_point: usize,
    /// The next row's `seq`.
    pub next_seq: u64,
    /// Session time (s): the virtual clock of a dry run, or elapsed rig time.
    pub clock_s: f64,
    /// The rig's state, as its [`RigHook`](crate::devices::RigHook) gave it (a dry run's
    /// world: its motion history; nothing on the real rig). Opaque to the session.
    #[serde(alias = "history")]
    pub rig_state: Option<serde_json::Value>,
    /// The arm's last commanded joints (rad).
    pub arm_q: Option<Vec<f64>>,
    /// The table's last position (mm).
    pub table_mm: Option<[f64; 3]>,
    /// The registration used for `x_mm…`.
    pub registration: Option<RegistrationInfo>,
    /// Byte length of `measurements.csv` at this moment.
    pub csv_bytes: u64,
    /// Rows written so far.
    pub rows: u64,
    /// True once every point is done.
    pub finished: bool,
    /// The contact procedure the session runs (journals before it was kept: rigcal's).
    #[serde(default)]
    pub procedure: crate::session::procedure::ContactProcedure,
}

impl Journal {
    /// The journal path in a session directory.
    pub fn path(dir: &Path) -> PathBuf {
        dir.join(JOURNAL_FILE)
    }

    /// Writes the journal atomically and durably.
    pub fn save(&self, dir: &Path) -> Result<(), JournalError> {
        self.save_with(dir, true)
    }

    /// Writes the journal atomically (temporary file, rename); `fsync` also forces it to disk.
    pub fn save_with(&self, dir: &Path, fsync: bool) -> Result<(), JournalError> {
        let path = Self::path(dir);
        let tmp = dir.join(format!("{JOURNAL_FILE}.tmp"));
        let io = |source| JournalError::Io {
            path: path.clone(),
            source,
        };
        let text = serde_json::to_string(self).map_err(|e| JournalError::Corrupt {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        {
            let mut f = std::fs::File::create(&tmp).map_err(io)?;
            f.write_all(text.as_bytes()).map_err(io)?;
            if fsync {
                f.sync_all().map_err(io)?;
            }
        }
        std::fs::rename(&tmp, &path).map_err(io)?;
        if fsync {
            if let Ok(d) = std::fs::File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }

    /// Reads the journal of a session directory.
    pub fn load(dir: &Path) -> Result<Journal, JournalError> {
        let path = Self::path(dir);
        let text = std::fs::read_to_string(&path).map_err(|source| JournalError::Io {
            path: path.clone(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| JournalError::Corrupt {
            path,
            reason: e.to_string(),
        })
    }
}

impl Journal {
    /// Checks that the recording `csv` holds what this journal committed, before a resume
    /// cuts it back to [`Journal::csv_bytes`] and appends to it: at least that many bytes (a
    /// shorter file was cut inside committed rows, or the journal claims rows that were never
    /// written), ending at a line end, every committed row complete and readable with these
    /// `joints`, [`Journal::rows`] of them, the last one numbered just before
    /// [`Journal::next_seq`].
    pub fn check_recording(&self, csv: &Path, joints: &[JointSpec]) -> Result<(), JournalError> {
        let disagrees = |reason: String| JournalError::Disagrees {
            csv: csv.to_path_buf(),
            reason,
        };
        let io = |source| JournalError::Io {
            path: csv.to_path_buf(),
            source,
        };
        let len = std::fs::metadata(csv).map_err(io)?.len();
        if len < self.csv_bytes {
            return Err(disagrees(format!(
                "the file holds {len} bytes but the journal committed {} ({} bytes of measured rows are missing: the file was cut inside its committed rows, or the journal claims rows that were never written)",
                self.csv_bytes,
                self.csv_bytes - len
            )));
        }
        if !ends_a_line(csv, self.csv_bytes).map_err(io)? {
            return Err(disagrees(format!(
                "the journal's {} committed bytes end inside a row (a committed row is torn)",
                self.csv_bytes
            )));
        }
        let rec = Recording::read_prefix(csv, self.csv_bytes, joints).map_err(|e| {
            disagrees(format!(
                "a committed row does not read ({e}): it was torn or edited"
            ))
        })?;
        let held = rec.rows.len() as u64;
        if held != self.rows {
            return Err(disagrees(format!(
                "the journal counts {} committed rows, the file's first {} bytes hold {held}",
                self.rows, self.csv_bytes
            )));
        }
        if let Some(last) = rec.rows.last() {
            if last.seq + 1 != self.next_seq {
                return Err(disagrees(format!(
                    "the last committed row has seq {}, the journal continues at seq {}",
                    last.seq, self.next_seq
                )));
            }
        }
        Ok(())
    }
}

/// Whether the first `len` bytes of the file end with a line end (the header's at least).
fn ends_a_line(path: &Path, len: u64) -> std::io::Result<bool> {
    use std::io::{Read, Seek, SeekFrom};
    if len == 0 {
        return Ok(false);
    }
    let mut f = std::fs::File::open(path)?;
    f.seek(SeekFrom::Start(len - 1))?;
    let mut last = [0u8; 1];
    f.read_exact(&mut last)?;
    Ok(last[0] == b'\n')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rig_state_is_opaque_and_an_older_journals_history_still_reads() {
        let old = r#"{"version":1,"next_point":3,"next_seq":9,"clock_s":12.5,
            "history":{"moves":4,"t_s":11.0},"arm_q":null,"table_mm":null,
            "registration":null,"csv_bytes":100,"rows":8,"finished":false}"#;
        let j: Journal = serde_json::from_str(old).expect("an older journal");
        assert_eq!(
            j.rig_state,
            Some(serde_json::json!({"moves": 4, "t_s": 11.0}))
        );
        let text = serde_json::to_string(&j).expect("serialises");
        assert!(text.contains("\"rig_state\":{"), "{text}");
        let back: Journal = serde_json::from_str(&text).expect("reads back");
        assert_eq!(back, j);
    }
}
