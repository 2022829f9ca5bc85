//! What stops a session: one error type for every step of it (its own file, so that the steps
//! need not import the session that runs them).

use std::path::PathBuf;

use crate::devices::{DeviceError, DeviceName};
use crate::session::journal::JournalError;
use crate::session::procedure::ContactProcedure;
use rigcal_core::recording::RecordingError;

/// What stopped a session.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SessionError {
    /// A device failed in a way the session cannot clear by itself.
    #[error("{stage}: {source}; the session stopped with every finished point saved: clear the cause, then run again with --resume")]
    Device {
        /// What the session was doing.
        stage: String,
        /// The device's error.
        source: DeviceError,
    },
    /// The session was asked to stop ([`StopRequest`](crate::session::StopRequest): SIGINT,
    /// SIGTERM) and stopped safely: the point in progress abandoned, the table's drives
    /// quick-stopped, the arm stopped, the journal at the last finished point.
    #[error("stopped on {reason} {during}: {devices}; every finished point is saved: run the same command with --resume to continue (the interrupted point is measured again)")]
    Stopped {
        /// What asked for the stop (`SIGINT`, `SIGTERM`, …).
        reason: String,
        /// What the session was doing.
        during: String,
        /// What the devices did (quick-stopped where, at rest or not).
        devices: String,
    },
    /// A device stopped answering (the device-loss rule of the session's recovery): the session
    /// ends as a fault, resumable, rather than giving up every remaining point.
    #[error("{device} stopped answering ({stage}): {detail}; the session stopped with every finished point saved (the point in progress is measured again): check the {device}'s power, cable and bus, then run again with --resume")]
    DeviceLost {
        /// The device.
        device: DeviceName,
        /// What the session was doing.
        stage: String,
        /// What was seen.
        detail: String,
    },
    /// The recording could not be written.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The journal could not be written or read.
    #[error(transparent)]
    Journal(#[from] JournalError),
    /// The registration step failed.
    #[error("registration: {0}; check that the panel sees the pin at the registration poses")]
    Registration(String),
    /// `--resume` without a journal.
    #[error("{dir}: no session journal to resume from; start a new session (without --resume)")]
    NothingToResume {
        /// The directory.
        dir: PathBuf,
    },
    /// A new session would overwrite a recording.
    #[error(
        "{dir} already holds a recording; resume it with --resume or choose another directory"
    )]
    AlreadyExists {
        /// The directory.
        dir: PathBuf,
    },
    /// A resumed planning-mode session was asked for other joints than its recording holds.
    #[error("point {point}: the division asks for joints {asked_deg:?}° where the recording holds {recorded_deg:?}°; resume with the same rig, scenario, seed and division options as the first run")]
    ResumeDiverged {
        /// 1-based point number.
        point: usize,
        /// Joints asked for (deg or mm).
        asked_deg: Vec<f64>,
        /// Joints recorded (deg or mm).
        recorded_deg: Vec<f64>,
    },
    /// A resume was asked for another contact procedure than the session began with.
    #[error("the session in {dir} began with the {journal} contact procedure; resume it with --procedure {journal} (or start a new session for {asked})")]
    ProcedureDiffers {
        /// The directory.
        dir: PathBuf,
        /// The journal's procedure.
        journal: ContactProcedure,
        /// The procedure asked for.
        asked: ContactProcedure,
    },
    /// The session's runtime could not be started.
    #[error("cannot start the session's runtime: {0}")]
    Runtime(std::io::Error),
    /// A file operation failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}
