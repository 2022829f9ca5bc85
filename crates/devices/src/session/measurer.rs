//! Planning mode through the rig: the division asks for measurements where it needs them and a
//! [`Session`] measures each one — on the rig, or on the emulators for a dry run.
//!
//! Every request becomes a point with the next point number (so approach directions keep
//! alternating), checked like a planned point: one the rig cannot measure is written as
//! `skipped: REASON` and reported to the division as failed. A batch (a region's measurement
//! locations, or its test points) is measured as one sequence of region `div<k>` (`k`: the
//! batch's number, from 1) in the session's order ([`batch_order`]: the planner's
//! [`Ordering::Optimised`], the order of least move time in which no point's nominal contact
//! lies more than the rig's z window, [`z_window_mm`], below an earlier one: the paper's
//! ascending z with the table's pass allowance, as `rigcal session` orders a region), one
//! ascending-z pass of the table; the answers go back in the order asked. A single request is a
//! point of region [`DIVISION_REGION`]. A session
//! error (a fault the session cannot clear) stops the division at once: it is the
//! [`MeasureError`]'s source, which the division returns to its caller.
//!
//! A resumed session ([`SessionMeasurer::resuming`]) first answers the division from its
//! recording: the division is deterministic, so it asks again for the points an earlier run
//! finished, in the same order, and gets what was measured then (each request checked against
//! the recorded joints); then the session measures on from where it stopped.

use std::collections::VecDeque;

use crate::session::error::SessionError;
use crate::session::plan::{order_region_by, target_point, z_window_mm, Ordering, PlannedPoint};
use crate::session::run::Session;
use crate::session::speeds::MoveTime;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{Recording, Status};
use rigcal_model::division::{MeasureError, Measurer};
use rigcal_model::identification::Observation;

/// A point the division asked for in an earlier run of a resumed session, as recorded.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedRequest {
    /// Joints commanded (rad or mm).
    pub q: Vec<f64>,
    /// What was measured there (None: skipped).
    pub observation: Option<Observation>,
}

/// True for a region id of the division's requests: [`DIVISION_REGION`], or a batch's
/// `div<k>`.
pub fn is_division_region(region: &str) -> bool {
    region
        .strip_prefix(DIVISION_REGION)
        .is_some_and(|k| k.bytes().all(|b| b.is_ascii_digit()))
}

/// The division's requests a planning-mode recording holds, in the order measured: each is one
/// row of a division region ([`is_division_region`]) that is not a `via` row.
pub fn recorded_requests(rec: &Recording) -> Vec<RecordedRequest> {
    rec.rows
        .iter()
        .filter(|m| m.region.as_deref().is_some_and(is_division_region) && m.status != Status::Via)
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
    rig: &'r rigcal_core::rig::Rig,
    replay: VecDeque<RecordedRequest>,
    replayed: usize,
    batches: usize,
    window_mm: f64,
    order: Ordering,
    metric: MoveTime,
}

/// The order a session measures a batch of joint targets in, as indices into `qs`, by `order`
/// ([`order_region_by`]; `target` gives each one's table position): for
/// [`Ordering::Optimised`] the order of least move time under `metric` in which no table z lies
/// more than `window_mm` below an earlier one; for the layered orders ascending z in layers of
/// `window_mm`, then x-y inside a layer. Deterministic: the same batch always comes out the
/// same (a resumed session orders it as the first run did).
pub fn batch_order(
    qs: &[Vec<f64>],
    target: impl Fn(&[f64]) -> [f64; 3],
    window_mm: f64,
    order: Ordering,
    metric: &MoveTime,
) -> Vec<usize> {
    let tagged: Vec<(Vec<f64>, [f64; 3])> = qs.iter().map(|q| (q.clone(), target(q))).collect();
    let mut taken = vec![false; qs.len()];
    order_region_by(tagged, window_mm, order, metric)
        .into_iter()
        .map(|(q, _)| {
            // The first request with these joints not yet placed: a batch asking twice for the
            // same joints gets both answers, in either order (they are the same request).
            let i = (0..qs.len())
                .find(|&i| !taken[i] && qs[i] == q)
                .expect("the order holds each request once");
            taken[i] = true;
            i
        })
        .collect()
}

impl<'s, 'r> SessionMeasurer<'s, 'r> {
    /// Measures through `session` on `rig`.
    pub fn new(session: &'s mut Session<'r>, rig: &'r rigcal_core::rig::Rig) -> Self {
        Self::resuming(session, rig, Vec::new())
    }

    /// Answers the first requests from `recorded` (the points a resumed `session` finished in
    /// earlier runs, see [`recorded_requests`]), then measures through `session`.
    pub fn resuming(
        session: &'s mut Session<'r>,
        rig: &'r rigcal_core::rig::Rig,
        recorded: Vec<RecordedRequest>,
    ) -> Self {
        SessionMeasurer {
            session,
            rig,
            replay: recorded.into(),
            replayed: 0,
            batches: 0,
            window_mm: z_window_mm(rig),
            order: Ordering::Optimised,
            metric: MoveTime::of(rig),
        }
    }

    /// Batches asked for so far (replayed ones included).
    pub fn batches(&self) -> usize {
        self.batches
    }

    /// One request of `region`: from the recording while it lasts, then through the session.
    fn one(&mut self, q: &[f64], region: &str) -> Result<Option<Observation>, MeasureError> {
        if let Some(answer) = self.replay(q) {
            return answer.map_err(MeasureError::new);
        }
        let p = PlannedPoint {
            point: self.session.points_done() + 1,
            region: region.into(),
            q: q.to_vec(),
            table_mm: target_point(self.rig, q),
        };
        self.session
            .measure_point(&p, false)
            .map_err(MeasureError::new)
    }

    /// The next recorded answer, if `q` is what was recorded; the divergence as the error
    /// otherwise (`None` once the recording is replayed). The arm rounds joint commands to its
    /// resolution, so joints within half a step of the request are the same request. Through
    /// the Cartesian command the controller solves the rounded pose (0.1 mm, 0.1°) for the
    /// joints itself, and may land on another wrist solution: there the same request is one
    /// whose nominal tip lies within the pose rounding of the request's.
    fn replay(&mut self, q: &[f64]) -> Option<Result<Option<Observation>, SessionError>> {
        let r = self.replay.pop_front()?;
        self.replayed += 1;
        let same = r.q.len() == q.len() && self.same_request(&r.q, q);
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

impl SessionMeasurer<'_, '_> {
    /// Whether the recorded joints `recorded` answer a request for `asked` (see [`Self::replay`]).
    fn same_request(&self, recorded: &[f64], asked: &[f64]) -> bool {
        let Some(arm) = crate::devices::config::DevicesConfig::read_opt(self.rig).map(|d| d.arm)
        else {
            return recorded
                .iter()
                .zip(asked)
                .all(|(a, b)| (a - b).abs() <= 1e-9);
        };
        let half_step = arm.resolution_deg.to_radians() / 2.0;
        let joints_agree = recorded
            .iter()
            .zip(asked)
            .all(|(a, b)| (a - b).abs() <= half_step + 1e-9);
        if joints_agree || arm.command_path != crate::devices::command_path::CommandPath::Cartesian
        {
            return joints_agree;
        }
        let nominal = rigcal_core::kinematics::ErrorParams::zeros(self.rig.chain.layout());
        let tip = |q: &[f64]| self.rig.chain.position(q, &nominal);
        // The pose's position rounds to 0.1 mm per axis: at most 0.087 mm away.
        (tip(recorded) - tip(asked)).norm() <= CARTESIAN_SAME_MM
    }
}

/// Nominal tips this close are the same request through the Cartesian command: its position
/// rounding (0.05 mm per axis) with room for the controller's servo rounding.
const CARTESIAN_SAME_MM: f64 = 0.15;

impl Measurer for SessionMeasurer<'_, '_> {
    fn measure(&mut self, q: &[f64]) -> Result<Option<Observation>, MeasureError> {
        self.one(q, DIVISION_REGION)
    }

    fn measure_batch(&mut self, qs: &[Vec<f64>]) -> Result<Vec<Option<Observation>>, MeasureError> {
        self.batches += 1;
        let region = format!("{DIVISION_REGION}{}", self.batches);
        // Ordered by where the table will go: through the session's registration (journaled,
        // so a resumed session orders a batch as the first run did).
        let session = &*self.session;
        let rig = self.rig;
        let order = batch_order(
            qs,
            |q| {
                session
                    .table_target(q)
                    .unwrap_or_else(|| target_point(rig, q))
            },
            self.window_mm,
            self.order,
            &self.metric,
        );
        let mut out = vec![None; qs.len()];
        for i in order {
            out[i] = self.one(&qs[i], &region)?;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Table positions stand in for the joints here: the target is the "joints" themselves.
    fn target(q: &[f64]) -> [f64; 3] {
        [q[0], q[1], q[2]]
    }

    /// The table's x-y move time along `order` (s), by the same metric the order minimises.
    fn travel_s(qs: &[Vec<f64>], order: &[usize], metric: &MoveTime) -> f64 {
        order
            .windows(2)
            .map(|w| {
                let (a, b) = (&qs[w[0]], &qs[w[1]]);
                metric.between(a, &target(a), b, &target(b))
            })
            .sum()
    }

    /// A batch whose ascending z zigzags across the table (x 0 and 300 mm, z 0.5 mm apart
    /// within each 3 mm band): strictly ascending it crosses the table at every point; inside
    /// the 3 mm window each band's side is measured together, no point more than the window
    /// below an earlier one, every request exactly once (the repeated one twice).
    #[test]
    fn a_batch_is_ordered_inside_the_z_window_by_move_time_and_keeps_every_request() {
        let mut qs: Vec<Vec<f64>> = (0..12)
            .map(|i| {
                let band = (i / 4) as f64 * 10.0;
                let x = if i % 2 == 0 { 0.0 } else { 300.0 };
                vec![x, 100.0, band + 0.5 * (i % 4) as f64]
            })
            .collect();
        qs.push(qs[5].clone());
        let metric = MoveTime::table_only();
        let window = 3.0;
        let windowed = batch_order(&qs, target, window, Ordering::Optimised, &metric);
        let strict = batch_order(&qs, target, 1e-6, Ordering::ZThenXY, &metric);
        for order in [&windowed, &strict] {
            let mut seen = order.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..qs.len()).collect::<Vec<_>>(), "{order:?}");
        }
        let mut top = f64::NEG_INFINITY;
        for &i in &windowed {
            assert!(qs[i][2] >= top - window - 1e-9, "{windowed:?}");
            top = top.max(qs[i][2]);
        }
        for w in strict.windows(2) {
            assert!(qs[w[1]][2] >= qs[w[0]][2], "{strict:?}");
        }
        // By hand: strictly ascending, 11 of the 12 steps cross the 300 mm (3.2 s each on the
        // table-only metric's 100 mm/s, 500 mm/s² profile: 35.2 s); inside the window one
        // crossing per band is enough (3 of them, 9.6 s).
        let (t_windowed, t_strict) = (
            travel_s(&qs, &windowed, &metric),
            travel_s(&qs, &strict, &metric),
        );
        assert!(t_strict > 25.0, "{t_strict}");
        assert!(
            t_windowed < 0.5 * t_strict,
            "{t_windowed} against {t_strict}"
        );
        // Deterministic: a resumed session orders the batch as the first run did.
        assert_eq!(
            windowed,
            batch_order(&qs, target, window, Ordering::Optimised, &metric)
        );
    }
}
