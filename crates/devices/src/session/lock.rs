//! The session directory's owner: an exclusive advisory lock on `session.lock` in the
//! directory, taken before anything in it is written and held until the session ends, so that
//! two runs never write one session (a second fresh run would overwrite `plan.csv`, a second
//! `--resume` would interleave its rows with the first one's).
//!
//! The lock is the operating system's (`flock` on Unix): it ends with the process that holds
//! it, however that process ends. The file itself only says who holds it (pid, host, start
//! time, command line) for the refusal a second run prints; a file left by a killed run is not
//! held, and the next run takes it over. A run that ends normally empties the file.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// The lock file's name in a session directory.
pub const LOCK_FILE: &str = "session.lock";

/// Why the session directory could not be taken.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LockError {
    /// Another run holds the directory.
    #[error("{} is in use by another run ({holder}); wait for it to end or stop it, then run again", dir.display())]
    Held {
        /// The session directory.
        dir: PathBuf,
        /// Who holds it, as its lock file says.
        holder: String,
    },
    /// The lock file could not be opened, locked or written.
    #[error("locking the session directory: {}: {source}", path.display())]
    Io {
        /// The lock file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Who holds a session directory: what its lock file says.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Holder {
    /// Process id.
    pub pid: u32,
    /// Host name, when the system gives it cheaply.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
    /// When the run took the lock (RFC 3339, UTC).
    pub started: String,
    /// The command line.
    pub command: String,
}

impl Holder {
    /// This process, now.
    fn this_process() -> Holder {
        Holder {
            pid: std::process::id(),
            host: host_name(),
            started: utc_now_rfc3339(),
            command: std::env::args().collect::<Vec<_>>().join(" "),
        }
    }
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "pid {}", self.pid)?;
        if let Some(host) = &self.host {
            write!(f, " on {host}")?;
        }
        write!(f, ", since {}, running `{}`", self.started, self.command)
    }
}

/// The lock on a session directory, held until dropped.
#[derive(Debug)]
pub struct SessionLock {
    file: File,
    path: PathBuf,
    stale: Option<String>,
}

impl SessionLock {
    /// Takes the lock of the session directory `dir` (which must exist) without waiting:
    /// refused with who holds it when another run does.
    pub fn acquire(dir: &Path) -> Result<SessionLock, LockError> {
        let path = dir.join(LOCK_FILE);
        let io = |source| LockError::Io {
            path: path.clone(),
            source,
        };
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                return Err(LockError::Held {
                    dir: dir.to_path_buf(),
                    holder: described(&read_text(&mut file)),
                });
            }
            Err(TryLockError::Error(e)) => return Err(io(e)),
        }
        let left = read_text(&mut file);
        let stale = (!left.trim().is_empty()).then(|| described(&left));
        let me = toml::to_string(&Holder::this_process()).unwrap_or_default();
        file.set_len(0).map_err(io)?;
        file.seek(SeekFrom::Start(0)).map_err(io)?;
        file.write_all(me.as_bytes()).map_err(io)?;
        file.flush().map_err(io)?;
        Ok(SessionLock { file, path, stale })
    }

    /// Who held the lock before this run, when a run that did not end normally (killed, or a
    /// power loss) left its lock file: that run is gone, the lock was free.
    pub fn stale_holder(&self) -> Option<&str> {
        self.stale.as_deref()
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for SessionLock {
    fn drop(&mut self) {
        // Emptied while still held: an empty lock file says nobody holds the directory. The
        // lock itself ends when the file closes (and with the process, however it ends).
        let _ = self.file.set_len(0);
        let _ = self.file.unlock();
    }
}

/// The lock file's text, or nothing if it cannot be read.
fn read_text(file: &mut File) -> String {
    let mut text = String::new();
    if file.seek(SeekFrom::Start(0)).is_ok() {
        let _ = file.read_to_string(&mut text);
    }
    text
}

/// Who the lock file's text names.
fn described(text: &str) -> String {
    match toml::from_str::<Holder>(text) {
        Ok(h) => h.to_string(),
        Err(_) if text.trim().is_empty() => "a run that is just starting".to_string(),
        Err(_) => format!("its lock file says: {}", text.trim()),
    }
}

/// The host name, on systems that keep it in a file (Linux); none elsewhere.
fn host_name() -> Option<String> {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
}

/// Now in RFC 3339, UTC, to the second.
pub(crate) fn utc_now_rfc3339() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    rfc3339(secs)
}

/// Seconds since 1970 in RFC 3339, UTC.
fn rfc3339(secs: u64) -> String {
    format!(
        "{}Z",
        rigcal_core::recording::import::time::iso_of(secs as f64)
    )
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_civil_utc() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00Z");
        assert_eq!(rfc3339(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(rfc3339(1_700_000_000), "2023-11-14T22:13:20Z");
    }

    #[test]
    fn a_second_lock_is_refused_with_its_holder_and_a_dropped_one_is_free() {
        let dir = tempfile::tempdir().unwrap();
        let first = SessionLock::acquire(dir.path()).unwrap();
        assert!(first.stale_holder().is_none());
        let err = SessionLock::acquire(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains(&format!("pid {}", std::process::id())) && err.contains("in use"),
            "{err}"
        );
        drop(first);
        let again = SessionLock::acquire(dir.path()).unwrap();
        assert!(
            again.stale_holder().is_none(),
            "a released lock file is empty"
        );
    }

    #[test]
    fn a_lock_file_left_by_a_killed_run_does_not_block() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(LOCK_FILE),
            "pid = 4000000\nstarted = \"2020-01-01T00:00:00Z\"\ncommand = \"rigcal session\"\n",
        )
        .unwrap();
        let lock = SessionLock::acquire(dir.path()).unwrap();
        assert!(lock.stale_holder().unwrap().contains("pid 4000000"));
    }
}
