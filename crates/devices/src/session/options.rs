//! How to run a session.

use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::session::procedure::ContactProcedure;
use rigcal_core::recording::{RegistrationInfo, SessionInfo};

/// How to run a session.
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// Output directory (measurements.csv, session.toml, journal.json).
    pub dir: PathBuf,
    /// Continue the session in `dir` from its journal.
    pub resume: bool,
    /// Poses of the registration step.
    pub registration_points: usize,
    /// Attempts per point before it is skipped.
    pub max_attempts: u32,
    /// First retry backoff (doubles per attempt).
    pub backoff: Duration,
    /// Seed of the registration poses.
    pub seed: u64,
    /// fsync each row and the journal (on by default; a dry run on the virtual clock may turn it
    /// off: a killed process loses nothing that was written).
    pub fsync: bool,
    /// What goes into session.toml besides the registration.
    pub info: SessionInfo,
    /// A registration to reuse (another session's, same rig set-up) instead of the
    /// registration step: both recordings are then in one frame.
    pub registration: Option<RegistrationInfo>,
    /// The contact procedure on the table-and-panel rig (kept in the journal: a resume runs
    /// the one the session began with).
    pub procedure: ContactProcedure,
}

impl SessionOptions {
    /// Defaults for a directory.
    pub fn new(dir: &Path) -> Self {
        SessionOptions {
            dir: dir.to_path_buf(),
            resume: false,
            registration_points: 12,
            max_attempts: 3,
            backoff: Duration::from_millis(200),
            seed: 1,
            fsync: true,
            info: SessionInfo::default(),
            registration: None,
            procedure: ContactProcedure::Rigcal,
        }
    }
}
