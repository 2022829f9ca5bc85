//! Checks on both sides of a fit: every value read is bounded before any matrix is formed, and
//! every fit is judged before anything is written from it.
//!
//! * In ([`check_recording`], [`check_observations`]): measured coordinates (`x_mm`…,
//!   `table_x_mm`…) must be finite and within [`COORDINATE_REACH_FACTOR`] (1000) times the
//!   chain's reach ([`Rig::reach_mm`]) of the origin — 1.3 km on the RV-M2, far beyond any
//!   measurement frame, yet far inside the float range, so sums of squares cannot overflow and
//!   no SVD meets an infinity (nalgebra's never returns on one). Joint values must be finite and
//!   within [`JOINT_TURNS`] turns (revolute) or the coordinate bound (prismatic). A row beyond
//!   is refused with its seq, file line and column: it is a typo or a broken reading, not data
//!   the outlier search should weigh.
//! * Out ([`check_fit`]): a fit whose residual grew (RMS after above RMS before), whose values
//!   are not finite, or whose kinematic corrections leave the rig's physical bounds
//!   ([`CalibrationSettings::max_angle_correction`], default 90°;
//!   [`CalibrationSettings::max_length_correction_mm`], default a tenth of the reach) has
//!   diverged: it is an error, never a model. A free measurement frame's parameters are
//!   absolute (the tracker may stand anywhere) and are held to the coordinate bound only.
//!
//! [`CalibrationSettings::max_angle_correction`]: rigcal_core::rig::CalibrationSettings::max_angle_correction
//! [`CalibrationSettings::max_length_correction_mm`]: rigcal_core::rig::CalibrationSettings::max_length_correction_mm

use super::FitResult;
use rigcal_core::kinematics::{ErrorParams, JointKind, JointSpec, Robot, SerialChain, TransformId};
use rigcal_core::recording::{Observation, Recording, Status};
use rigcal_core::rig::{chain_reach_mm, Rig};

/// Measured coordinates may lie this many times the rig's reach from the origin, no farther.
pub const COORDINATE_REACH_FACTOR: f64 = 1000.0;

/// Revolute joint values may span this many turns either way, no more.
pub const JOINT_TURNS: f64 = 10.0;

/// A value read that no instrument or arm produces: not finite, or beyond the bound.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{} `{column}` = {value:e} {}: correct or delete the row (a typo or a broken reading; the fit cannot weigh it)", where_(.seq, .line, .index), what(.value, .bound, .unit, .reach_mm))]
pub struct AbsurdValue {
    /// The row's `seq`, when it came from a recording.
    pub seq: Option<u64>,
    /// Its CSV line (1-based, header = 1), when read from a file.
    pub line: Option<u64>,
    /// Its index among the observations checked (0-based).
    pub index: usize,
    /// The column (`x_mm`, `table_y_mm`, `q2_deg`).
    pub column: String,
    /// The value, in the column's unit.
    pub value: f64,
    /// The bound it broke, in the column's unit.
    pub bound: f64,
    /// The column's unit (`mm`, `deg`).
    pub unit: &'static str,
    /// The rig's reach (mm) the bound derives from.
    pub reach_mm: f64,
}

fn where_(seq: &Option<u64>, line: &Option<u64>, index: &usize) -> String {
    match (seq, line) {
        (Some(s), Some(l)) => format!("recording row seq {s} (line {l}):"),
        (Some(s), None) => format!("recording row seq {s}:"),
        _ => format!("measurement {} (1-based):", index + 1),
    }
}

fn what(value: &f64, bound: &f64, unit: &&str, reach_mm: &f64) -> String {
    if !value.is_finite() {
        "is not a finite number".into()
    } else if *unit == "deg" {
        format!("is beyond ±{bound:.0}° ({JOINT_TURNS} turns), no joint turns that far")
    } else {
        format!(
            "is beyond ±{bound:.4e} mm ({COORDINATE_REACH_FACTOR} × the rig's reach of {reach_mm:.0} mm), no instrument on this arm reads that"
        )
    }
}

/// The bound (mm) on a measured coordinate of a chain: [`COORDINATE_REACH_FACTOR`] × its
/// reach.
pub fn coordinate_bound_mm(chain: &SerialChain) -> f64 {
    COORDINATE_REACH_FACTOR * chain_reach_mm(chain).max(1.0)
}

/// Checks every measured row of a recording (status `ok`): its joint values, its position and
/// its table coordinates ([`AbsurdValue`] names the first row and column beyond).
pub fn check_recording(chain: &SerialChain, rec: &Recording) -> Result<(), AbsurdValue> {
    let checker = Checker::of(chain);
    rec.rows
        .iter()
        .enumerate()
        .filter(|(_, m)| m.status == Status::Ok)
        .enumerate()
        .try_for_each(|(index, (k, m))| {
            let at = Row {
                seq: Some(m.seq),
                line: rec.lines.get(k).copied(),
                index,
            };
            checker.joints(&at, &m.q)?;
            if let Some(p) = m.position {
                checker.point(&at, ["x_mm", "y_mm", "z_mm"], &p.into())?;
            }
            if let Some(t) = m.table {
                checker.point(&at, ["table_x_mm", "table_y_mm", "table_z_mm"], &t.into())?;
            }
            Ok(())
        })
}

/// Checks observations (joint values and measured points) that come without their rows: the
/// error names the measurement by its index.
pub fn check_observations(chain: &SerialChain, obs: &[Observation]) -> Result<(), AbsurdValue> {
    let checker = Checker::of(chain);
    obs.iter().enumerate().try_for_each(|(index, o)| {
        let at = Row {
            seq: None,
            line: None,
            index,
        };
        checker.joints(&at, &o.q)?;
        checker.point(&at, ["x_mm", "y_mm", "z_mm"], &o.p.into())
    })
}

/// Where a value was read.
struct Row {
    seq: Option<u64>,
    line: Option<u64>,
    index: usize,
}

struct Checker<'a> {
    joints: &'a [JointSpec],
    bound_mm: f64,
    reach_mm: f64,
}

impl<'a> Checker<'a> {
    fn of(chain: &'a SerialChain) -> Self {
        Self {
            joints: chain.joints(),
            bound_mm: coordinate_bound_mm(chain),
            reach_mm: chain_reach_mm(chain),
        }
    }

    fn absurd(
        &self,
        at: &Row,
        column: String,
        value: f64,
        bound: f64,
        unit: &'static str,
    ) -> AbsurdValue {
        AbsurdValue {
            seq: at.seq,
            line: at.line,
            index: at.index,
            column,
            value,
            bound,
            unit,
            reach_mm: self.reach_mm,
        }
    }

    fn point(&self, at: &Row, columns: [&str; 3], p: &[f64; 3]) -> Result<(), AbsurdValue> {
        for (column, &v) in columns.iter().zip(p) {
            if !(v.is_finite() && v.abs() <= self.bound_mm) {
                return Err(self.absurd(at, (*column).into(), v, self.bound_mm, "mm"));
            }
        }
        Ok(())
    }

    fn joints(&self, at: &Row, q: &[f64]) -> Result<(), AbsurdValue> {
        for (j, (spec, &v)) in self.joints.iter().zip(q).enumerate() {
            let (bound, unit) = match spec.kind {
                JointKind::Revolute => (360.0 * JOINT_TURNS, "deg"),
                JointKind::Prismatic => (self.bound_mm, "mm"),
            };
            let shown = spec.kind.to_file_units(v);
            if !(shown.is_finite() && shown.abs() <= bound) {
                let column = format!("q{}_{unit}", j + 1);
                return Err(self.absurd(at, column, shown, bound, unit));
            }
        }
        Ok(())
    }
}

/// Why a fit is refused: it diverged (see the module docs).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the fit diverged: {what}. No model was written: look for gross errors in the recording (the rows the fit leans on) and check the rig file's nominal kinematics (joint offsets, signs, units); if the arm really is that far off its nominal values, state larger bounds in the rig file's [calibration] (max_angle_correction_deg, max_length_correction_mm)")]
pub struct Diverged {
    /// What is wrong, with the parameter and its value when one is out of bounds.
    pub what: String,
}

/// Judges a fit of `chain` for `rig` (see the module docs): the first thing wrong with it.
pub fn check_fit(rig: &Rig, chain: &SerialChain, fit: &FitResult) -> Result<(), Diverged> {
    check_parameters(rig, chain, &fit.params, &fit.free)?;
    let diverged = |what: String| Err(Diverged { what });
    let after = &fit.after;
    let stats = [after.rms_mm, after.max_mm, fit.sigma0_mm, fit.before.rms_mm];
    if stats.iter().any(|v| !v.is_finite()) || fit.sigma.iter().any(|v| !v.is_finite()) {
        return diverged(format!(
            "its residual or a standard deviation is not a finite number (RMS after {} mm, σ̂ {} mm)",
            after.rms_mm, fit.sigma0_mm
        ));
    }
    // The fit only ever takes steps that lower the cost from its start: a residual above the
    // start's is a fit that wandered off on other rows (or from another start) and stayed.
    if after.rms_mm > fit.before.rms_mm * (1.0 + 1e-9) + 1e-12 {
        return diverged(format!(
            "its residual grew from RMS {:.4} mm before to {:.4} mm after",
            fit.before.rms_mm, after.rms_mm
        ));
    }
    Ok(())
}

/// Judges the `free` parameters (layout indices) of `params` for `rig`'s chain `chain`: finite,
/// and within the rig's bounds on kinematic corrections (a free frame's within the coordinate
/// bound).
pub fn check_parameters(
    rig: &Rig,
    chain: &SerialChain,
    params: &ErrorParams,
    free: &[usize],
) -> Result<(), Diverged> {
    let layout = chain.layout();
    let diverged = |what: String| Err(Diverged { what });
    for &i in free {
        let id = layout.ids()[i];
        let v = params.get(i);
        let shown = id.kind.to_file_units(v);
        let name = layout.symbol(id);
        let unit = id.kind.unit();
        if !v.is_finite() {
            return diverged(format!("{name} is not a finite number ({v})"));
        }
        if id.transform == TransformId::Frame {
            let bound = coordinate_bound_mm(&rig.chain);
            if !id.kind.is_angle() && v.abs() > bound {
                return diverged(format!(
                    "the measurement frame's {name} = {shown:+.1} mm lies beyond ±{bound:.3e} mm ({COORDINATE_REACH_FACTOR} × the reach)"
                ));
            }
            continue;
        }
        let (bound, key) = if id.kind.is_angle() {
            (
                rig.calibration.max_angle_correction,
                "max_angle_correction_deg",
            )
        } else {
            (
                rig.calibration.max_length_correction_mm,
                "max_length_correction_mm",
            )
        };
        if v.abs() > bound {
            return diverged(format!(
                "{name} = {shown:+.4} {unit} is beyond the ±{:.4} {unit} a kinematic correction of this rig can be (calibration.{key})",
                id.kind.to_file_units(bound)
            ));
        }
    }
    Ok(())
}
