//! Which contact procedure a session runs on the table-and-panel rig (the rig-time comparison
//! of the procedures and orders is [`compare`](mod@crate::session::compare)).
//!
//! - [`ContactProcedure::Baseline`]: the procedure the product had before the rig-time work
//!   (commit 0573ddc), a paper-style sequence of one move after another — the table down a
//!   clearance below both the current and the next approach height, x-y beside the arm's move
//!   to the via pose, the arm onto the target, then the table up to the approach start, the
//!   locating approach, a back-off of [`BASELINE_BACKOFF_MM`] and the final approach crept at
//!   the latency-rule speed over the whole back-off.
//! - [`ContactProcedure::Rigcal`] (the default): the same safety limits (approach margin, §8
//!   contact speed, ascending-z window) with the moves overlapped and shortened: the back-off
//!   at the rig file's `backoff_mm`, a quick rise to a standoff so only its last fraction of a
//!   millimetre is crept, the travel at the next approach start when that is lower than a
//!   clearance below the current contact, and the table rising beside the arm's last move.
//!
//! Both run in the session ([`SessionOptions::procedure`](crate::session::SessionOptions)) and
//! in the estimate ([`ContactSettings::procedure`](crate::session::ContactSettings)); a point
//! sensor has no contact and runs the same either way.

/// The back-off of the baseline procedure (mm): `rigs/rv-m2.toml`'s and the defaults' at
/// 0573ddc, where the whole back-off was crept at the latency-rule speed. A rig file asking
/// for more keeps its own.
pub const BASELINE_BACKOFF_MM: f64 = 0.3;

/// The contact procedure of the table-and-panel rig (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ContactProcedure {
    /// The paper-style procedure of commit 0573ddc: one move after another, a one-phase final
    /// approach over a [`BASELINE_BACKOFF_MM`] back-off.
    Baseline,
    /// rigcal's procedure: the two-phase final approach and the overlapped, shortened moves.
    #[default]
    Rigcal,
}

impl ContactProcedure {
    /// The name on the command line and in the journal (`baseline`, `rigcal`).
    pub fn name(self) -> &'static str {
        match self {
            ContactProcedure::Baseline => "baseline",
            ContactProcedure::Rigcal => "rigcal",
        }
    }
}

impl std::fmt::Display for ContactProcedure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ContactProcedure {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "baseline" => Ok(ContactProcedure::Baseline),
            "rigcal" => Ok(ContactProcedure::Rigcal),
            _ => Err(format!(
                "unknown contact procedure `{s}`: baseline or rigcal"
            )),
        }
    }
}
