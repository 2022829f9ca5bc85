//! `thermal_drift`: an error that grows as the machine warms, A · (1 − exp(−t/τ)), on a joint
//! angle (`joint`, `amplitude_deg`) or on the pin tip along a world axis (`axis`,
//! `amplitude_mm`). t is seconds since the session started. Radians and mm inside.

use super::effect::{axis_index, Effect, JointContext, ParseCtx};
use super::scenario::ScenarioError;
use nalgebra::Vector3;
use serde::Deserialize;
use std::sync::Arc;

/// Where a drift acts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DriftTarget {
    /// A joint (0-based); amplitude in rad (mm for a prismatic joint).
    Joint(usize),
    /// A world axis (0 x, 1 y, 2 z); amplitude in mm.
    Axis(usize),
}

/// Warm-up drift.
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalDrift {
    /// What drifts.
    pub target: DriftTarget,
    /// Final size A (rad or mm).
    pub amplitude: f64,
    /// Time constant τ (s).
    pub tau_s: f64,
}

impl ThermalDrift {
    /// The drift at time `t_s` (rad or mm); zero before the session starts.
    pub fn at(&self, t_s: f64) -> f64 {
        self.amplitude * (1.0 - (-t_s.max(0.0) / self.tau_s).exp())
    }
}

impl Effect for ThermalDrift {
    fn kind(&self) -> &'static str {
        "thermal_drift"
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        if let DriftTarget::Joint(j) = self.target {
            dq[j] += self.at(ctx.t_s);
        }
    }

    fn tip_offset(&self, t_s: f64, _tip: &Vector3<f64>) -> Vector3<f64> {
        let mut v = Vector3::zeros();
        if let DriftTarget::Axis(k) = self.target {
            v[k] = self.at(t_s);
        }
        v
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    joint: Option<i64>,
    axis: Option<String>,
    amplitude_deg: Option<f64>,
    amplitude_mm: Option<f64>,
    tau_s: f64,
}

/// Parses `kind = "thermal_drift"`: `joint` + `amplitude_deg`, or `axis` + `amplitude_mm`;
/// `tau_s`.
pub fn parse(ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, ScenarioError> {
    let raw: Raw = ctx.raw(t)?;
    let tau_s = ctx.positive(".tau_s", raw.tau_s)?;
    let (target, amplitude) = match (raw.joint, &raw.axis, raw.amplitude_deg, raw.amplitude_mm) {
        (Some(j), None, Some(a), None) => {
            let j = ctx.joint(".joint", j)?;
            let kind = rigcal_core::kinematics::Robot::joints(ctx.chain)[j].kind;
            let a = kind.from_file_units(ctx.finite(".amplitude_deg", a)?);
            (DriftTarget::Joint(j), a)
        }
        (None, Some(axis), None, Some(a)) => (
            DriftTarget::Axis(axis_index(ctx, ".axis", axis)?),
            ctx.finite(".amplitude_mm", a)?,
        ),
        _ => {
            return Err(ctx.invalid(
                "",
                "give `joint` with `amplitude_deg`, or `axis` with `amplitude_mm`",
            ))
        }
    };
    Ok(Arc::new(ThermalDrift {
        target,
        amplitude,
        tau_s,
    }))
}
