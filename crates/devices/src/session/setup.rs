//! Setting a session up as `rigcal session` does: the session directory taken and checked, the
//! plan kept in it (`plan.csv`, written at the start and read back from there on a resume), the
//! rig time estimated beforehand, and the [`SessionOptions`] the session runs with.
//!
//! [`SessionSetup::take_dir`] runs before any device is opened: it locks the directory (one
//! writer at a time, [`SessionLock`]), and on a resume reads the journal, checks that the
//! directory can be written, that the rig file, scenario, seeds, procedure and `plan.csv` are
//! the ones the session began with (the [`ResumeCheck`] its `session.toml` noted at the start)
//! and that the recording holds every row the journal committed. A directory left before the
//! session's first journal commit (nothing measured) starts again, fresh or on `--resume`.

use std::path::{Path, PathBuf};

use crate::session::inputs::{file_hash, ResumeCheck};
use crate::session::journal::{Journal, JournalError, JOURNAL_FILE};
use crate::session::lock::{utc_now_rfc3339, LockError, SessionLock};
use crate::session::options::SessionOptions;
use crate::session::plan::{
    estimate, plan, read_plan, registration_points, write_plan, ContactSettings, PlanError,
    PlanOptions, PlannedPoint, RigTimeEstimate,
};
use crate::session::procedure::ContactProcedure;
use crate::session::run::CSV_FILE;
use crate::session::speeds::RigSpeeds;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{
    read_session_info, write_session, Recording, RecordingError, RegistrationInfo, SessionInfo,
    SESSION_TOML,
};
use rigcal_core::rig::{Instrument, Rig};

/// The session's own copy of its plan, in the session directory.
pub const PLAN_FILE: &str = "plan.csv";

/// Why a session could not be set up.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SetupError {
    /// A new session would overwrite a recording.
    #[error("{} already holds a recording; resume it with --resume or choose another --out", dir.display())]
    AlreadyRecorded {
        /// The session directory.
        dir: PathBuf,
    },
    /// A resume where no session was begun.
    #[error("{}: no session to resume here (no {JOURNAL_FILE}); start one without --resume", dir.display())]
    NothingToResume {
        /// The session directory.
        dir: PathBuf,
    },
    /// The session directory could not be made.
    #[error("creating {}", dir.display())]
    CreateDir {
        /// The session directory.
        dir: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The session whose registration is to be reused could not be read.
    #[error("reading the session {}", dir.display())]
    ReadSession {
        /// Its directory.
        dir: PathBuf,
        /// The cause.
        source: RecordingError,
    },
    /// The session whose registration is to be reused has none.
    #[error("{}: its session.toml holds no [registration]", dir.display())]
    NoRegistration {
        /// Its directory.
        dir: PathBuf,
    },
    /// The plan could not be made, read or written.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The session's plan could not be read back.
    #[error("reading the session plan {}", path.display())]
    ReadPlan {
        /// The plan file.
        path: PathBuf,
        /// The cause.
        source: PlanError,
    },
    /// Another run holds the directory, or it could not be locked.
    #[error(transparent)]
    Lock(#[from] LockError),
    /// The journal of a resumed session is unreadable, or the recording does not hold what
    /// it committed.
    #[error(transparent)]
    Journal(#[from] JournalError),
    /// A resume was given other files or settings than the session began with.
    #[error("{}: the session began with other inputs than this resume gives:\n  - {}\nresume it with the command it began with (and its plan.csv unedited), or start a new session in another directory", dir.display(), differences.join("\n  - "))]
    OtherInputs {
        /// The session directory.
        dir: PathBuf,
        /// What differs, one line each.
        differences: Vec<String>,
    },
    /// A file the session continues from could not be read to compare it.
    #[error("reading {}: {source}", path.display())]
    ReadInput {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The `[resume_check]` of session.toml is unreadable.
    #[error("{}: {reason}; the session cannot be checked before a resume: start a new session in another directory", path.display())]
    BadResumeCheck {
        /// The session.toml.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// session.toml could not be written at the start.
    #[error("writing the session's {SESSION_TOML} in {}", dir.display())]
    WriteSession {
        /// The session directory.
        dir: PathBuf,
        /// The cause.
        source: RecordingError,
    },
    /// A resume could not write where it must.
    #[error("{}: {source}; a resume writes its rows, journal and session.toml here: make them writable, then run again", path.display())]
    NotWritable {
        /// The directory or file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A resume where the recording has rows but no journal says which are complete.
    #[error("{}: {CSV_FILE} holds rows but there is no {JOURNAL_FILE}: which of them are complete cannot be told, so the session cannot resume; start a new session in another directory", dir.display())]
    RowsWithoutJournal {
        /// The session directory.
        dir: PathBuf,
    },
}

/// The session directory, taken by this run ([`SessionSetup::take_dir`]): its lock is held
/// until this is dropped, so keep it alive until the session has ended.
#[derive(Debug)]
pub struct OwnedDir {
    lock: SessionLock,
    /// What the run should tell its user: a lock left by a killed run taken over, a resume
    /// that starts again, checks an older session cannot have.
    pub notes: Vec<String>,
}

impl OwnedDir {
    /// The lock file.
    pub fn lock_path(&self) -> &Path {
        self.lock.path()
    }
}

/// Where a fresh session's points come from.
#[derive(Debug, Clone)]
pub enum PlanSource<'a> {
    /// A plan file (from `rigcal plan`).
    File(&'a Path),
    /// Planned now with these options.
    Make(PlanOptions),
}

/// How a session is set up: the command line's choices, which the session directory, its
/// `session.toml` and the estimate follow.
#[derive(Debug, Clone)]
pub struct SessionSetup<'a> {
    /// The session directory (measurements.csv, session.toml, journal.json, plan.csv).
    pub dir: &'a Path,
    /// Continue the session in `dir` from its journal.
    pub resume: bool,
    /// The rig file, noted in session.toml.
    pub rig_file: &'a Path,
    /// The scenario file of a dry run, noted in session.toml.
    pub scenario_file: Option<&'a Path>,
    /// The rig file the scenario refers to (a dry run), noted by its content for a resume.
    pub scenario_rig_file: Option<&'a Path>,
    /// The scenario's own seed, noted in session.toml.
    pub scenario_seed: Option<u64>,
    /// Seed of the plan and the registration poses.
    pub seed: u64,
    /// The contact procedure on the table rig.
    pub procedure: ContactProcedure,
    /// Poses of the registration step.
    pub registration_points: usize,
    /// An earlier session directory whose registration is reused instead of registering again.
    pub registration_from: Option<&'a Path>,
    /// fsync every row and journal even on the virtual clock (always on with real devices).
    pub fsync: bool,
}

impl SessionSetup<'_> {
    /// Takes the session directory (made if missing) before anything in it is written: locks
    /// it, then refuses a fresh session over a recording and checks a resume (see the module
    /// docs) — all before any device is opened. A directory left before the session's first
    /// journal commit is cleared for a fresh start; a resume of one starts again from its
    /// `plan.csv` (`resume` is then false). Keep the returned [`OwnedDir`] until the session
    /// has ended.
    pub fn take_dir(&mut self, rig: &Rig) -> Result<OwnedDir, SetupError> {
        if self.resume && !self.dir.is_dir() {
            // A mistyped directory is not made (with a lock file in it) only to be refused.
            return Err(SetupError::NothingToResume {
                dir: self.dir.to_path_buf(),
            });
        }
        std::fs::create_dir_all(self.dir).map_err(|source| SetupError::CreateDir {
            dir: self.dir.to_path_buf(),
            source,
        })?;
        let lock = SessionLock::acquire(self.dir)?;
        let mut notes = Vec::new();
        if let Some(stale) = lock.stale_holder() {
            notes.push(format!(
                "{} was left by a run that did not end normally ({stale}); that run is gone and this one takes the directory over",
                lock.path().display()
            ));
        }
        if self.resume {
            self.check_resume(rig, &mut notes)?;
        } else {
            self.check_fresh()?;
        }
        Ok(OwnedDir { lock, notes })
    }

    /// A fresh session: refused over a recording that holds committed rows; the files of one
    /// that never committed any are removed.
    fn check_fresh(&self) -> Result<(), SetupError> {
        let begun = match load_journal(self.dir) {
            Ok(Some(j)) => j.rows > 0 || j.next_point > 0,
            Ok(None) => holds_rows(&self.dir.join(CSV_FILE))?,
            Err(_) => true,
        };
        if begun {
            return Err(SetupError::AlreadyRecorded {
                dir: self.dir.to_path_buf(),
            });
        }
        clear_unbegun(self.dir)
    }

    /// A resume: the journal read, the directory writable, the inputs and the recording the
    /// ones the session began with.
    fn check_resume(&mut self, rig: &Rig, notes: &mut Vec<String>) -> Result<(), SetupError> {
        let dir = self.dir.to_path_buf();
        let journal = load_journal(self.dir)?;
        let csv = self.dir.join(CSV_FILE);
        if journal.is_none() && holds_rows(&csv)? {
            return Err(SetupError::RowsWithoutJournal { dir });
        }
        let (info, recorded) = recorded_check(self.dir)?;
        if journal.is_none() && recorded.is_none() {
            return Err(SetupError::NothingToResume { dir });
        }
        check_writable(self.dir)?;
        let contact = matches!(rig.instrument, Instrument::TablePanel(_));
        let differences = match &recorded {
            Some(r) => r.differences(&self.resume_check()?, contact),
            None => {
                notes.push(format!(
                    "{}: no [resume_check] (a session begun before rigcal noted one): the rig file's and the scenario's content, --seed, --registration-points and plan.csv cannot be checked; resume only with the command the session began with",
                    dir.join(SESSION_TOML).display()
                ));
                self.older_session_differences(info.as_ref(), journal.as_ref(), contact)
            }
        };
        if !differences.is_empty() {
            return Err(SetupError::OtherInputs { dir, differences });
        }
        match journal {
            Some(j) => j.check_recording(&csv, rig.chain.joints())?,
            None => {
                clear_unbegun(self.dir)?;
                self.resume = false;
                notes.push(format!(
                    "{}: the session ended before its first journal commit (nothing measured): it starts again from its {PLAN_FILE}",
                    dir.display()
                ));
            }
        }
        Ok(())
    }

    /// What a resume can still compare for a session begun before [`ResumeCheck`] was noted:
    /// the scenario and its seed in session.toml, the procedure in the journal.
    fn older_session_differences(
        &self,
        info: Option<&SessionInfo>,
        journal: Option<&Journal>,
        contact: bool,
    ) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(info) = info {
            if info.scenario.is_some() != self.scenario_file.is_some() {
                out.push(format!(
                    "--sim: the session began with {}, now {}",
                    info.scenario.as_deref().unwrap_or("no scenario"),
                    self.scenario_file
                        .map_or("none".to_string(), |p| p.display().to_string())
                ));
            }
            if info.seed != self.scenario_seed {
                let shown = |s: Option<u64>| s.map_or("none".to_string(), |s| s.to_string());
                out.push(format!(
                    "--sim-seed: the simulated world's seed was {}, now {}",
                    shown(info.seed),
                    shown(self.scenario_seed)
                ));
            }
        }
        if let Some(j) = journal {
            if contact && j.procedure != self.procedure {
                out.push(format!(
                    "--procedure: was {}, now {}",
                    j.procedure, self.procedure
                ));
            }
        }
        out
    }

    /// What this run would continue from, as [`ResumeCheck`] notes it.
    fn resume_check(&self) -> Result<ResumeCheck, SetupError> {
        let hash = |p: &Path| {
            file_hash(p).map_err(|source| SetupError::ReadInput {
                path: p.to_path_buf(),
                source,
            })
        };
        Ok(ResumeCheck {
            rig_hash: hash(self.rig_file)?,
            scenario_hash: self.scenario_file.map(hash).transpose()?,
            scenario_rig_hash: self.scenario_rig_file.map(hash).transpose()?,
            scenario_seed: self.scenario_seed,
            seed: self.seed,
            procedure: self.procedure,
            registration_points: self.registration_points,
            plan_hash: hash(&self.plan_path())?,
        })
    }

    /// What session.toml says of this run before its registration: the files, the seed.
    fn base_info(&self) -> SessionInfo {
        SessionInfo {
            rig: Some(self.rig_file.display().to_string()),
            scenario: self.scenario_file.map(|p| p.display().to_string()),
            seed: self.scenario_seed,
            ..Default::default()
        }
    }

    /// Writes session.toml at the start of a fresh session, with its start time and what a
    /// resume must be given again ([`ResumeCheck`], after the plan file is written).
    fn note_start(&self) -> Result<(), SetupError> {
        let mut info = self.base_info();
        info.start_time = Some(utc_now_rfc3339());
        self.resume_check()?.put_into(&mut info);
        write_session(self.dir, &info).map_err(|source| SetupError::WriteSession {
            dir: self.dir.to_path_buf(),
            source,
        })
    }

    /// The session's plan file ([`PLAN_FILE`] in its directory).
    pub fn plan_path(&self) -> PathBuf {
        self.dir.join(PLAN_FILE)
    }

    /// The session's plan. On a fresh run it is read or made from `source` (made: its dropped
    /// candidates are written beside the plan file and their summary handed to `dropped`) and
    /// written to the plan file, and session.toml notes the start ([`ResumeCheck`]); then, on
    /// a fresh and a resumed run (`source` None) alike, it is read back from there.
    pub fn plan(
        &self,
        rig: &Rig,
        source: Option<PlanSource<'_>>,
        dropped: &mut dyn FnMut(&str),
    ) -> Result<Vec<PlannedPoint>, SetupError> {
        let path = self.plan_path();
        if let Some(source) = source {
            let points = match source {
                PlanSource::File(p) => read_plan(p, rig)?,
                PlanSource::Make(opts) => {
                    let p = plan(rig, &opts)?;
                    dropped(&p.write_dropped(rig, &path)?);
                    p.points
                }
            };
            write_plan(&path, rig, &points)?;
            self.note_start()?;
        }
        read_plan(&path, rig).map_err(|source| SetupError::ReadPlan { path, source })
    }

    /// The rig time the session should take: the registration step's own poses first (none
    /// when the registration is reused, or on a resume, which estimates the whole plan again),
    /// then `points`.
    pub fn estimate(&self, rig: &Rig, points: &[PlannedPoint]) -> RigTimeEstimate {
        let registration = if self.registration_from.is_none() && !self.resume {
            registration_points(rig, self.registration_points, self.seed)
        } else {
            Vec::new()
        };
        estimate(
            rig,
            &[registration.as_slice(), points].concat(),
            &RigSpeeds::of(rig),
            &ContactSettings::for_procedure(rig, self.procedure),
        )
    }

    /// The options of a session of `points` planned points; `virtual_clock` for a dry run on
    /// the virtual clock (fsync then only when asked for). A reused registration is read from
    /// its session here. Their session.toml information is what the session's own noted at
    /// its start (its [`ResumeCheck`] kept), with this run's notes on a fresh start.
    pub fn options(
        &self,
        rig: &Rig,
        points: usize,
        virtual_clock: bool,
    ) -> Result<SessionOptions, SetupError> {
        let mut opts = SessionOptions::new(self.dir);
        opts.resume = self.resume;
        opts.registration_points = self.registration_points;
        if let Some(dir) = self.registration_from {
            opts.registration = Some(reused_registration(rig, dir)?);
        }
        opts.seed = self.seed;
        opts.procedure = self.procedure;
        opts.fsync = self.fsync || !virtual_clock;
        let recorded = read_session_info(self.dir).map_err(|source| SetupError::ReadSession {
            dir: self.dir.to_path_buf(),
            source,
        })?;
        let mut info = recorded.unwrap_or_else(|| self.base_info());
        if !self.resume || info.notes.is_none() {
            info.notes = Some(format!(
                "rigcal session: {points} points, {} contact procedure{}",
                self.procedure.name(),
                if virtual_clock {
                    ", dry run on the virtual clock"
                } else {
                    ""
                }
            ));
        }
        opts.info = info;
        Ok(opts)
    }
}

/// The journal of the session in `dir`; none when there is no journal file.
fn load_journal(dir: &Path) -> Result<Option<Journal>, JournalError> {
    match Journal::load(dir) {
        Ok(j) => Ok(Some(j)),
        Err(JournalError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            Ok(None)
        }
        Err(e) => Err(e),
    }
}

/// The session.toml of `dir` and the [`ResumeCheck`] it holds (none for a session begun before
/// one was noted, or before session.toml was written).
fn recorded_check(dir: &Path) -> Result<(Option<SessionInfo>, Option<ResumeCheck>), SetupError> {
    let info = read_session_info(dir).map_err(|source| SetupError::ReadSession {
        dir: dir.to_path_buf(),
        source,
    })?;
    let check = match &info {
        Some(i) => ResumeCheck::of(i).map_err(|reason| SetupError::BadResumeCheck {
            path: dir.join(SESSION_TOML),
            reason,
        })?,
        None => None,
    };
    Ok((info, check))
}

/// Whether the recording at `csv` holds anything after its header line (a missing file holds
/// nothing).
fn holds_rows(csv: &Path) -> Result<bool, SetupError> {
    /// Longer than any header: a file this long holds rows.
    const HEADER_MAX: u64 = 1 << 20;
    let io = |source| SetupError::ReadInput {
        path: csv.to_path_buf(),
        source,
    };
    let len = match std::fs::metadata(csv) {
        Ok(m) => m.len(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(e) => return Err(io(e)),
    };
    if len > HEADER_MAX {
        return Ok(true);
    }
    let bytes = std::fs::read(csv).map_err(io)?;
    Ok(match bytes.iter().position(|&b| b == b'\n') {
        Some(end) => bytes[end + 1..].iter().any(|b| !b.is_ascii_whitespace()),
        None => false,
    })
}

/// Removes the recording and journal of a session that never committed a row.
fn clear_unbegun(dir: &Path) -> Result<(), SetupError> {
    let tmp = format!("{JOURNAL_FILE}.tmp");
    for name in [CSV_FILE, JOURNAL_FILE, tmp.as_str()] {
        let path = dir.join(name);
        match std::fs::remove_file(&path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(source) => return Err(SetupError::NotWritable { path, source }),
        }
    }
    Ok(())
}

/// Refuses a resume that could not write its rows, journal and session.toml: checked before
/// any device moves (otherwise the arm homes and the table enables before the first write
/// fails).
fn check_writable(dir: &Path) -> Result<(), SetupError> {
    let probe = dir.join(".rigcal-write-check");
    std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(&probe)
        .and_then(|_| std::fs::remove_file(&probe))
        .map_err(|source| SetupError::NotWritable {
            path: dir.to_path_buf(),
            source,
        })?;
    for name in [CSV_FILE, SESSION_TOML, JOURNAL_FILE] {
        let path = dir.join(name);
        if path.exists() {
            std::fs::OpenOptions::new()
                .append(true)
                .open(&path)
                .map_err(|source| SetupError::NotWritable { path, source })?;
        }
    }
    Ok(())
}

/// The registration of the earlier session in `dir`, to reuse (same rig set-up).
fn reused_registration(rig: &Rig, dir: &Path) -> Result<RegistrationInfo, SetupError> {
    let rec =
        Recording::read(dir, rig.chain.joints()).map_err(|source| SetupError::ReadSession {
            dir: dir.to_path_buf(),
            source,
        })?;
    rec.session
        .and_then(|s| s.registration)
        .ok_or_else(|| SetupError::NoRegistration {
            dir: dir.to_path_buf(),
        })
}
