//! Planning mode through the rig: the division asks for measurements where it needs them and a
//! [`Session`] measures each one — on the rig, or on the emulators for a dry run.
//!
//! Every request becomes a point of region [`DIVISION_REGION`] with the next point number (so
//! approach directions keep alternating), checked like a planned point: one the rig cannot
//! measure is written as `skipped: REASON` and reported to the division as failed. A session
//! error (a fault the session cannot clear) stops the division at once: it is the
//! [`MeasureError`]'s source, which the division returns to its caller.
//!
//! A resumed session ([`SessionMeasurer::resuming`]) first answers the division from its
//! recording: the division is deterministic, so it asks again for the points an earlier run
//! finished, in the same order, and gets what was measured then (each request checked against
//! the recorded joints); then the session measures on from where it stopped.

use std::collections::VecDeque;

use crate::division::{MeasureError, Measurer};
use crate::identification::Observation;
use crate::kinematics::Robot;
use crate::recording::{Recording, Status};
use crate::session::plan::{target_point, PlannedPoint};
use crate::session::{Session, SessionError};

/// A point the division asked for in an earlier run of a resumed session, as recorded.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedRequest {
    /// Joints commanded (rad or mm).
    pub q: Vec<f64>,
    /// What was measured there (None: skipped).
    pub observation: Option<Observation>,
}

/// The division's requests a planning-mode recording holds, in order: each is one row of
/// region [`DIVISION_REGION`] that is not a `via` row.
pub fn recorded_requests(rec: &Recording) -> Vec<RecordedRequest> {
    rec.rows
        .iter()
        .filter(|m| m.region.as_deref() == Some(DIVISION_REGION) && m.status != Status::Via)
        .map(|m| RecordedRequest {
            q: m.q.clone(),
            observation: match m.status {
                Status::Ok => m.position.map(|p| Observation { q: m.q.clone(), p }),
                _ => None,
            },
        })
        .collect()
}

/// Region id of the points a division asked for.
pub const DIVISION_REGION: &str = "div";

/// A session as the division's measurer.
#[derive(Debug)]
pub struct SessionMeasurer<'s, 'r> {
    session: &'s mut Session<'r>,
    rig: &'r crate::rig::Rig,
    replay: VecDeque<RecordedRequest>,
    replayed: usize,
}

impl<'s, 'r> SessionMeasurer<'s, 'r> {
    /// Measures through `session` on `rig`.
    pub fn new(session: &'s mut Session<'r>, rig: &'r crate::rig::Rig) -> Self {
        Self::resuming(session, rig, Vec::new())
    }

    /// Answers the first requests from `recorded` (the points a resumed `session` finished in
    /// earlier runs, see [`recorded_requests`]), then measures through `session`.
    pub fn resuming(
        session: &'s mut Session<'r>,
        rig: &'r crate::rig::Rig,
        recorded: Vec<RecordedRequest>,
    ) -> Self {
        SessionMeasurer {
            session,
            rig,
            replay: recorded.into(),
            replayed: 0,
        }
    }

    /// The next recorded answer, if `q` is what was recorded; the divergence as the error
    /// otherwise (`None` once the recording is replayed). The arm rounds commands to its
    /// resolution, so joints within half a step of the request are the same request.
    fn replay(&mut self, q: &[f64]) -> Option<Result<Option<Observation>, SessionError>> {
        let r = self.replay.pop_front()?;
        self.replayed += 1;
        let half_step = self
            .rig
            .devices
            .as_ref()
            .map_or(0.0, |d| d.arm.resolution_deg.to_radians() / 2.0);
        let same = r.q.len() == q.len()
            && r.q
                .iter()
                .zip(q)
                .all(|(a, b)| (a - b).abs() <= half_step + 1e-9);
        if same {
            return Some(Ok(r.observation));
        }
        let deg = |v: &[f64]| -> Vec<f64> {
            self.rig
                .chain
                .joints()
                .iter()
                .zip(v)
                .map(|(j, x)| (j.kind.to_file_units(*x) * 1e4).round() / 1e4)
                .collect()
        };
        let diverged = SessionError::ResumeDiverged {
            point: self.replayed,
            asked_deg: deg(q),
            recorded_deg: deg(&r.q),
        };
        self.replay.clear();
        Some(Err(diverged))
    }
}

impl Measurer for SessionMeasurer<'_, '_> {
    fn measure(&mut self, q: &[f64]) -> Result<Option<Observation>, MeasureError> {
        if let Some(answer) = self.replay(q) {
            return answer.map_err(MeasureError::new);
        }
        let p = PlannedPoint {
            point: self.session.points_done() + 1,
            region: DIVISION_REGION.into(),
            q: q.to_vec(),
            table_mm: target_point(self.rig, q),
        };
        self.session
            .measure_point(&p, false)
            .map_err(MeasureError::new)
    }
}
