//! `backlash`: lost motion b on one joint. The joint stops short of the command by b/2 on the
//! side it came from: actual = commanded − sign(last non-zero change) · b/2; zero until the joint
//! has moved. Scenario units: degrees (mm for a prismatic joint); radians inside.

use super::effect::{Effect, JointContext, ParseCtx};
use super::scenario::ScenarioError;
use serde::Deserialize;
use std::sync::Arc;

/// Lost motion on one joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Backlash {
    /// The joint (0-based).
    pub joint: usize,
    /// Lost motion b (rad or mm).
    pub lost_motion: f64,
}

impl Effect for Backlash {
    fn kind(&self) -> &'static str {
        "backlash"
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        let dir = ctx.history.direction.get(self.joint).copied().unwrap_or(0);
        dq[self.joint] -= f64::from(dir) * self.lost_motion / 2.0;
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    joint: i64,
    /// b in degrees (mm for a prismatic joint).
    lost_motion_deg: f64,
}

/// Parses `kind = "backlash"`: `joint`, `lost_motion_deg`.
pub fn parse(ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, ScenarioError> {
    let raw: Raw = ctx.raw(t)?;
    let joint = ctx.joint(".joint", raw.joint)?;
    let b = ctx.non_negative(".lost_motion_deg", raw.lost_motion_deg)?;
    let spec = &rigcal_core::kinematics::Robot::joints(ctx.chain)[joint];
    Ok(Arc::new(Backlash {
        joint,
        lost_motion: spec.kind.from_file_units(b),
    }))
}
