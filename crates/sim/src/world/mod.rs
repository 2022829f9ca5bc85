//! The simulated truth: what the arm really does and what the instrument really reads.
//!
//! Only emulators and `rigcal simulate`/`demo` read it; identification, division, learners,
//! compensation and diagnosis see recordings and rig files, never the world. Random draws are a
//! function of (seed, seq, attempt), never of a running generator, so a resumed session draws
//! what the uninterrupted one drew (conventions §7).
//!
//! # The chain of truth
//! 1. The arm is commanded to q at time t. The motion history records the direction each joint
//!    came from ([`MotionHistory`]).
//! 2. Joint-space effects give the actual joints q + Δq (eq. 6, compliance, backlash,
//!    transmission error, drift); the true geometry ([`ErrorParams`]) gives the true tool pose;
//!    tip effects (Cartesian drift) move the tip; repeatability scatters it per measurement.
//!    Each effect's truth is in its own file of [`rigcal_model::effects`] (beside its scenario
//!    entry, diagnosis candidate and model term); the world only composes them through the
//!    [`Effect`] hooks, giving each the motion history's approach directions.
//! 3. Ideal instrument: the reading is the tip plus Gaussian noise. Table and panel: the table goes
//!    to the nominal tip in x and y and rises until the panel meets the pin; the table's truth
//!    ([`TableMap`]: scale, squareness, registration) says where the panel really is; the panel
//!    reports quantised counts or misses; the measured point is the table reading (with its
//!    accuracy noise) plus (u, v), in world coordinates through the nominal registration.
//!
//! Units: mm and radians inside (degrees in files).

mod geometric;
mod instrument;
mod scenario;
pub mod simulate;
pub mod write;

pub use geometric::{identifiable, paper_geometric_errors};
use instrument::within_travel;
pub use instrument::{panel_report, pin_angle_ok, Draws, MeasurementSettings, MissReason, Touch};
pub use rigcal_model::effects::{
    error_split, fig6_path, Backlash, DriftTarget, Effect, ErrorSplit, Harmonic, JointCompliance,
    JointContext, PointMass, RegistrationOffset, TableMap, TableScale, TableSquareness,
    ThermalDrift, TransmissionError,
};
pub use scenario::{Scenario, ScenarioError};
pub use simulate::{check_same_rig, random_session_poses, simulate_session, SimulateError};

use nalgebra::{Isometry3, Vector3};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};
use rigcal_core::recording::{Measurement, Recording, Status};
use rigcal_core::rig::Instrument;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The arm's motion history: what backlash and drift depend on. Serialisable so a session
/// journal can store it and a resume continue it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MotionHistory {
    /// The last commanded joint values (internal units: rad or mm); empty before the first move.
    pub last_q: Vec<f64>,
    /// Per joint: +1 or −1, the sign of its last non-zero change; 0 while it has not moved.
    pub direction: Vec<i8>,
    /// Time of the last command (s since the session started).
    pub t_s: f64,
    /// Commands so far.
    pub moves: u64,
}

impl MotionHistory {
    /// Records a command to `q` at `t_s`.
    pub fn record(&mut self, q: &[f64], t_s: f64) {
        if self.direction.len() != q.len() {
            self.direction = vec![0; q.len()];
        }
        if self.last_q.len() == q.len() {
            for (j, (new, old)) in q.iter().zip(&self.last_q).enumerate() {
                // Below a nano-radian a "change" is rounding, not motion.
                if (new - old).abs() > 1e-9 {
                    self.direction[j] = if new > old { 1 } else { -1 };
                }
            }
        }
        self.last_q = q.to_vec();
        self.t_s = t_s;
        self.moves += 1;
    }
}

/// Where the arm really is after a command.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmState {
    /// Commanded joints (rad or mm).
    pub commanded: Vec<f64>,
    /// Actual joints after every joint-space effect.
    pub actual: Vec<f64>,
    /// True tool pose (world).
    pub tool: Isometry3<f64>,
    /// True pin tip (world, mm), before the per-measurement repeatability scatter.
    pub tip: Vector3<f64>,
}

/// The outcome of one simulated measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// The arm's true state.
    pub arm: ArmState,
    /// The true tip with the repeatability scatter (what touched the panel), world, mm.
    pub tip: Vector3<f64>,
    /// The measured point in world coordinates (nominal registration), None on a miss.
    pub position: Option<Vector3<f64>>,
    /// The measured point in the table frame (table reading + (u, v, 0)), table rigs only.
    pub table: Option<Vector3<f64>>,
    /// The panel's (u, v) offset (mm), table rigs only.
    pub panel_uv: Option<[f64; 2]>,
    /// The panel counts, table rigs only.
    pub counts: Option<[u32; 2]>,
    /// Why there is no measurement.
    pub missed: Option<MissReason>,
}

impl Reading {
    /// This reading as a recording row.
    fn to_measurement(&self, seq: u64, t_s: f64) -> Measurement {
        Measurement {
            seq,
            t_s: Some(t_s),
            q: self.arm.commanded.clone(),
            position: self.position,
            table: self.table,
            panel_uv: self.panel_uv,
            status: match self.missed {
                None => Status::Ok,
                Some(r) => Status::Skipped(r.as_text().to_string()),
            },
            ..Default::default()
        }
    }
}

/// A simulated rig: the arm's true geometry and physics, and the instrument's truth.
#[derive(Debug, Clone)]
pub struct World {
    chain: SerialChain,
    truth: ErrorParams,
    instrument: Instrument,
    effects: Vec<Arc<dyn Effect>>,
    settings: MeasurementSettings,
    table: Option<TableMap>,
    seed: u64,
    history: MotionHistory,
}

impl World {
    /// A world whose arm has error parameters `truth` and no other physics, measured by an ideal
    /// instrument with noise σ = `noise_mm` per coordinate; `seed` fixes every random draw.
    pub fn new(chain: SerialChain, truth: ErrorParams, noise_mm: f64, seed: u64) -> Self {
        Self::with_effects(
            chain,
            truth,
            Instrument::Ideal,
            Vec::new(),
            MeasurementSettings::noise_only(noise_mm),
            seed,
        )
    }

    /// A world with effects and an instrument (what [`Scenario::world`] builds).
    pub fn with_effects(
        chain: SerialChain,
        truth: ErrorParams,
        instrument: Instrument,
        effects: Vec<Arc<dyn Effect>>,
        settings: MeasurementSettings,
        seed: u64,
    ) -> Self {
        let table = match &instrument {
            Instrument::TablePanel(tp) => {
                let mut map = TableMap::nominal(tp.table_to_world_mm);
                for e in &effects {
                    e.distort_table(&mut map);
                }
                Some(map)
            }
            _ => None,
        };
        Self {
            chain,
            truth,
            instrument,
            effects,
            settings,
            table,
            seed,
            history: MotionHistory::default(),
        }
    }

    /// The true error parameters (for tests and reports of simulations only).
    pub fn truth(&self) -> &ErrorParams {
        &self.truth
    }

    /// The chain.
    pub fn chain(&self) -> &SerialChain {
        &self.chain
    }

    /// The instrument.
    pub fn instrument(&self) -> &Instrument {
        &self.instrument
    }

    /// The random-error settings.
    pub fn settings(&self) -> &MeasurementSettings {
        &self.settings
    }

    /// The motion history, to store in a journal.
    pub fn snapshot(&self) -> MotionHistory {
        self.history.clone()
    }

    /// Continues from a stored motion history.
    pub fn restore(&mut self, history: MotionHistory) {
        self.history = history;
    }

    /// The actual joints for a command `q` at `t_s` given `history` (already holding this
    /// command).
    pub fn actual_joints(&self, q: &[f64], t_s: f64, history: &MotionHistory) -> Vec<f64> {
        let ctx = JointContext {
            chain: &self.chain,
            truth: &self.truth,
            commanded: q,
            t_s,
            direction: &history.direction,
        };
        let mut dq = vec![0.0; q.len()];
        for e in &self.effects {
            e.joint_offsets(&ctx, &mut dq);
        }
        q.iter().zip(&dq).map(|(a, b)| a + b).collect()
    }

    fn arm_state(&self, q: &[f64], t_s: f64, history: &MotionHistory) -> ArmState {
        let actual = self.actual_joints(q, t_s, history);
        let tool = self.chain.tool_pose(&actual, &self.truth);
        let at = self.chain.position(&actual, &self.truth);
        let drift: Vector3<f64> = self.effects.iter().map(|e| e.tip_offset(t_s, &at)).sum();
        let tip = at + drift;
        ArmState {
            commanded: q.to_vec(),
            actual,
            tool,
            tip,
        }
    }

    /// Moves the arm to `q` at `t_s` (updating the motion history) and returns where it really
    /// is.
    pub fn move_arm(&mut self, q: &[f64], t_s: f64) -> ArmState {
        self.history.record(q, t_s);
        self.arm_state(q, t_s, &self.history)
    }

    /// Where the pin really is at `q` (mm) in a static world: a fresh motion history (no
    /// backlash yet) at t = 0 (no drift), no random scatter.
    pub fn true_position(&self, q: &[f64]) -> Vector3<f64> {
        let mut h = MotionHistory::default();
        h.record(q, 0.0);
        self.arm_state(q, 0.0, &h).tip
    }

    /// The standard-normal draws of measurement `seq`, attempt `attempt`.
    pub fn draws(&self, seq: u64, attempt: u32) -> Draws {
        Draws::new(self.seed, seq, attempt)
    }

    /// The tip that touches the instrument: the true tip scattered by the arm's repeatability.
    pub fn scattered_tip(&self, arm: &ArmState, draws: &Draws) -> Vector3<f64> {
        arm.tip + draws.arm * self.settings.arm_repeatability_mm
    }

    /// World position of the panel centre when the table reads `reading` (mm); None without a
    /// table.
    pub fn panel_centre(&self, reading: &Vector3<f64>) -> Option<Vector3<f64>> {
        self.table.as_ref().map(|m| m.world(reading))
    }

    /// What the panel reports when the table reads `reading` and the pin (tool pose `tool`) has
    /// its tip at `tip`: counts, or why there is no valid touch. An ideal instrument never misses.
    fn touch(&self, tool: &Isometry3<f64>, tip: &Vector3<f64>, reading: &Vector3<f64>) -> Touch {
        let (Instrument::TablePanel(tp), Some(map)) = (&self.instrument, &self.table) else {
            return Touch::Contact {
                counts: [0, 0],
                uv_mm: [0.0, 0.0],
            };
        };
        if !within_travel(tp, reading) {
            return Touch::Missed(MissReason::OutOfTravel);
        }
        if !pin_angle_ok(tool, &tp.pin_axis, tp.min_pin_angle) {
            return Touch::Missed(MissReason::PinAngle);
        }
        // The panel is mounted rigidly on the z arm: its axes are the registered table axes.
        let rel = tip - map.world(reading);
        let u = map.registration.rotation * Vector3::x();
        let v = map.registration.rotation * Vector3::y();
        panel_report(tp, [rel.dot(&u), rel.dot(&v)], self.settings.quantise)
    }

    /// One complete measurement: command `q` at `t_s`, then measure as the instrument does.
    /// Random draws depend on (seed, `seq`, `attempt`) only.
    pub fn measure_at(&mut self, q: &[f64], t_s: f64, seq: u64, attempt: u32) -> Reading {
        let arm = self.move_arm(q, t_s);
        let draws = self.draws(seq, attempt);
        let tip = self.scattered_tip(&arm, &draws);
        let noise = draws.noise * self.settings.noise_mm;
        let (Instrument::TablePanel(tp), Some(map)) = (&self.instrument, &self.table) else {
            return Reading {
                arm,
                tip,
                position: Some(tip + noise),
                table: None,
                panel_uv: None,
                counts: None,
                missed: None,
            };
        };
        // The planner sends the table under the nominal tip (nominal registration); the z arm
        // rises until the panel meets the pin.
        let nominal = ErrorParams::zeros(self.chain.layout());
        let target = self.chain.position(q, &nominal) - tp.table_to_world_mm;
        let mut reading = map.reading_at_height([target.x, target.y], tip.z);
        let touch = self.touch(&arm.tool, &tip, &reading);
        let mut out = Reading {
            arm,
            tip,
            position: None,
            table: None,
            panel_uv: None,
            counts: None,
            missed: None,
        };
        match touch {
            Touch::Missed(r) => out.missed = Some(r),
            Touch::Contact { counts, uv_mm } => {
                reading += draws.table * self.settings.table_accuracy_mm;
                let table = reading + Vector3::new(uv_mm[0], uv_mm[1], 0.0);
                out.table = Some(table);
                out.panel_uv = Some(uv_mm);
                out.counts = Some(counts);
                out.position = Some(table + tp.table_to_world_mm + noise);
            }
        }
        out
    }

    /// What the instrument would read at `q` for measurement `seq`, attempt `attempt`, in a
    /// static world (see [`World::true_position`]), as an ideal instrument: the true tip with
    /// the repeatability scatter and Gaussian noise.
    pub fn measure(&self, q: &[f64], seq: u64, attempt: u32) -> Vector3<f64> {
        let d = self.draws(seq, attempt);
        self.true_position(q)
            + d.arm * self.settings.arm_repeatability_mm
            + d.noise * self.settings.noise_mm
    }

    /// A recording of measurements at `poses` in that order, numbered from `first_seq`,
    /// `seconds_per_point` apart from t = 0, starting from this world's motion history (the
    /// world itself is left unchanged). Missed touches become `skipped` rows.
    pub fn record(&self, poses: &[Vec<f64>], first_seq: u64) -> Recording {
        let mut w = self.clone();
        let mut rec = Recording::new(self.chain.joints());
        for (k, q) in poses.iter().enumerate() {
            let seq = first_seq + k as u64;
            let t = k as f64 * self.settings.seconds_per_point;
            rec.rows
                .push(w.measure_at(q, t, seq, 0).to_measurement(seq, t));
        }
        rec
    }

    /// Moves the arm through `moves` (commanded joints, time in s) in that order, from this
    /// world's motion history (the world itself is left unchanged): where the arm really is
    /// after each move, backlash and drift as the order and times make them.
    pub fn run_moves(&self, moves: &[(Vec<f64>, f64)]) -> Vec<ArmState> {
        let mut w = self.clone();
        moves.iter().map(|(q, t)| w.move_arm(q, *t)).collect()
    }

    /// This world without its random errors (noise, repeatability, table accuracy and
    /// quantisation): what it measures on average, for comparing with a recording point by point.
    pub fn noiseless(&self) -> World {
        let mut w = self.clone();
        w.settings.noise_mm = 0.0;
        w.settings.arm_repeatability_mm = 0.0;
        w.settings.table_accuracy_mm = 0.0;
        w.settings.quantise = false;
        w
    }

    /// Replays a recording's rows in order at their times (`t_s`, or the row index times
    /// `seconds_per_point` without it), from a fresh motion history: every row moves the arm
    /// (so `via` rows set approach directions as they did), and each `ok` row gets what this
    /// world measures there (None for other rows and for misses). Use [`World::noiseless`]
    /// first for the expected readings.
    pub fn replay(&self, rec: &Recording) -> Vec<Option<Vector3<f64>>> {
        let mut w = self.clone();
        w.history = MotionHistory::default();
        rec.rows
            .iter()
            .enumerate()
            .map(|(k, row)| {
                let t = row
                    .t_s
                    .unwrap_or(k as f64 * self.settings.seconds_per_point);
                if row.status == Status::Ok && row.position.is_some() {
                    w.measure_at(&row.q, t, row.seq, 0).position
                } else {
                    w.move_arm(&row.q, t);
                    None
                }
            })
            .collect()
    }

    /// The uncalibrated error along `path` split into total and non-geometric (conventions §3),
    /// in a static world.
    pub fn error_split(&self, path: &[Vec<f64>]) -> ErrorSplit {
        error_split(&self.chain, &self.truth, path, &|q: &[f64]| {
            let mut h = MotionHistory::default();
            h.record(q, 0.0);
            let actual = self.actual_joints(q, 0.0, &h);
            actual.iter().zip(q).map(|(a, b)| a - b).collect()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_keeps_the_last_nonzero_direction_per_joint() {
        let mut h = MotionHistory::default();
        h.record(&[0.0, 1.0], 0.0);
        assert_eq!(h.direction, vec![0, 0]);
        h.record(&[0.5, 1.0], 1.0);
        assert_eq!(h.direction, vec![1, 0]);
        h.record(&[0.5, 0.2], 2.0);
        assert_eq!(h.direction, vec![1, -1]);
        h.record(&[0.1, 0.2], 3.0);
        assert_eq!(h.direction, vec![-1, -1]);
        assert_eq!(h.moves, 4);
        assert_eq!(h.t_s, 3.0);
    }

    #[test]
    fn draws_depend_on_seed_seq_and_attempt_only() {
        assert_eq!(Draws::new(1, 2, 3), Draws::new(1, 2, 3));
        assert_ne!(Draws::new(1, 2, 3), Draws::new(1, 2, 4));
        assert_ne!(Draws::new(1, 2, 3), Draws::new(1, 3, 3));
        assert_ne!(Draws::new(2, 2, 3), Draws::new(1, 2, 3));
    }
}
