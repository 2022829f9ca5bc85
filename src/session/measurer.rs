//! Planning mode through the rig: the division asks for measurements where it needs them and a
//! [`Session`] measures each one — on the rig, or on the emulators for a dry run.
//!
//! Every request becomes a point of region [`DIVISION_REGION`] with the next point number (so
//! approach directions keep alternating), checked like a planned point: one the rig cannot
//! measure is written as `skipped: REASON` and reported to the division as failed. A session
//! error (a fault the session cannot clear) stops the measuring: every later request fails at
//! once and the error is kept for the caller, which must report it.

use crate::division::Measurer;
use crate::identification::Observation;
use crate::session::plan::{target_point, PlannedPoint};
use crate::session::{Session, SessionError};

/// Region id of the points a division asked for.
pub const DIVISION_REGION: &str = "div";

/// A session as the division's measurer.
#[derive(Debug)]
pub struct SessionMeasurer<'s, 'r> {
    session: &'s mut Session<'r>,
    rig: &'r crate::rig::Rig,
    error: Option<SessionError>,
}

impl<'s, 'r> SessionMeasurer<'s, 'r> {
    /// Measures through `session` on `rig`.
    pub fn new(session: &'s mut Session<'r>, rig: &'r crate::rig::Rig) -> Self {
        SessionMeasurer {
            session,
            rig,
            error: None,
        }
    }

    /// The error that stopped the session, if one did.
    pub fn into_error(self) -> Option<SessionError> {
        self.error
    }
}

impl Measurer for SessionMeasurer<'_, '_> {
    fn measure(&mut self, q: &[f64]) -> Option<Observation> {
        if self.error.is_some() {
            return None;
        }
        let p = PlannedPoint {
            point: self.session.points_done() + 1,
            region: DIVISION_REGION.into(),
            q: q.to_vec(),
            table_mm: target_point(self.rig, q),
        };
        match self.session.measure_point(&p, false) {
            Ok(measured) => measured,
            Err(e) => {
                self.error = Some(e);
                None
            }
        }
    }
}
