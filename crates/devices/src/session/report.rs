//! What a session did.

use std::time::Duration;

/// What a session did.
#[derive(Debug, Clone, Default)]
pub struct SessionReport {
    /// Planned points.
    pub points: usize,
    /// Points measured by this run (including earlier runs when resumed: see `resumed_at`).
    pub ok: usize,
    /// Points skipped, with the full reason.
    pub skipped: Vec<(usize, String)>,
    /// `via` rows written.
    pub via: usize,
    /// Retries made.
    pub retries: usize,
    /// Passes begun beyond one per region run, where the travel clearance had to go lower than
    /// the ascending-z rule allows within a pass.
    pub extra_passes: usize,
    /// Faults cleared (drive fault reset, arm reset).
    pub faults_cleared: Vec<String>,
    /// Session time at the end (s): the rig time the session took (virtual clock on a dry run).
    pub rig_time_s: f64,
    /// Wall time of this run.
    pub wall: Duration,
    /// RMS of the registration fit (mm).
    pub registration_rms_mm: Option<f64>,
    /// The point index this run resumed at.
    pub resumed_at: Option<usize>,
}
