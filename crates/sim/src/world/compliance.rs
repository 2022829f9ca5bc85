//! `joint_compliance`: joints deflect under the gravity torque of the links they carry.
//!
//! Physics, not a fitted formula: every link carries point masses at stated positions in its
//! own frame; gravity pulls along world −z with g = 9.81 m/s². The torque about joint j's axis
//! (world axis z_j through origin o_j) is τ_j = Σ_{masses beyond j} ((p − o_j) × m·g) · z_j, and
//! the joint deflects by Δq_j = τ_j / k_j in the direction of the torque.
//!
//! Frames: a mass on link i (1-based: the body joint i moves) is given in the frame at the end of
//! that link, i.e. the frame of joint i+1's axis (D-H frame i), or the tool frame for the last
//! link. Units: kg, mm in files (metres in the torque), N·m/rad or deg/(N·m); radians inside.

use super::effect::{Effect, JointContext, ParseCtx};
use super::scenario::ScenarioError;
use nalgebra::Vector3;
use rigcal_core::kinematics::{ErrorParams, JointKind, Robot, SerialChain};
use serde::Deserialize;
use std::sync::Arc;

/// Standard gravity (m/s²), along world −z.
pub const G: f64 = 9.81;

/// A point mass on a link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointMass {
    /// The link (0-based joint index whose motion carries it).
    pub link: usize,
    /// Mass (kg).
    pub kg: f64,
    /// Position in the link's end frame (mm).
    pub at_mm: Vector3<f64>,
}

/// Gravity compliance of the arm.
#[derive(Debug, Clone, PartialEq)]
pub struct JointCompliance {
    /// The link masses.
    pub masses: Vec<PointMass>,
    /// (joint 0-based, stiffness N·m/rad) of every compliant joint.
    pub stiffness: Vec<(usize, f64)>,
}

impl JointCompliance {
    /// Gravity torque (N·m) about joint `j`'s axis at joint values `q`, with the geometry `e`.
    pub fn gravity_torque(&self, chain: &SerialChain, e: &ErrorParams, q: &[f64], j: usize) -> f64 {
        let axis_frame = chain.frame_before_joint(q, e, j);
        let z = axis_frame.rotation * Vector3::z();
        let o = axis_frame.translation.vector;
        let weight = |kg: f64| Vector3::new(0.0, 0.0, -kg * G);
        self.masses
            .iter()
            .filter(|m| m.link >= j)
            .map(|m| {
                let end = chain.frame_before_joint(q, e, m.link + 1);
                let p = end * nalgebra::Point3::from(m.at_mm);
                let lever_m = (p.coords - o) / 1000.0;
                lever_m.cross(&weight(m.kg)).dot(&z)
            })
            .sum()
    }

    /// Deflection (rad) of every compliant joint at `q`.
    pub fn deflections(
        &self,
        chain: &SerialChain,
        e: &ErrorParams,
        q: &[f64],
    ) -> Vec<(usize, f64)> {
        self.stiffness
            .iter()
            .map(|&(j, k)| (j, self.gravity_torque(chain, e, q, j) / k))
            .collect()
    }
}

impl Effect for JointCompliance {
    fn kind(&self) -> &'static str {
        "joint_compliance"
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        for (j, d) in self.deflections(ctx.chain, ctx.truth, ctx.commanded) {
            dq[j] += d;
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMass {
    link: i64,
    kg: f64,
    at_mm: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJoint {
    joint: i64,
    stiffness_nm_per_rad: Option<f64>,
    deg_per_nm: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    masses: Vec<RawMass>,
    joints: Vec<RawJoint>,
}

/// Parses `kind = "joint_compliance"`: `masses = [{ link, kg, at_mm }]`,
/// `joints = [{ joint, stiffness_nm_per_rad | deg_per_nm }]`.
pub fn parse(ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, ScenarioError> {
    let raw: Raw = ctx.raw(t)?;
    let mut masses = Vec::new();
    for (k, m) in raw.masses.iter().enumerate() {
        let key = |f: &str| format!(".masses[{k}].{f}");
        let link = ctx.joint(&key("link"), m.link)?;
        let kg = ctx.positive(&key("kg"), m.kg)?;
        for (c, v) in m.at_mm.iter().enumerate() {
            ctx.finite(&format!("{}[{c}]", key("at_mm")), *v)?;
        }
        masses.push(PointMass {
            link,
            kg,
            at_mm: Vector3::from(m.at_mm),
        });
    }
    if masses.is_empty() {
        return Err(ctx.invalid(".masses", "needs at least one link mass"));
    }
    let mut stiffness = Vec::new();
    for (k, r) in raw.joints.iter().enumerate() {
        let key = |f: &str| format!(".joints[{k}].{f}");
        let j = ctx.joint(&key("joint"), r.joint)?;
        if ctx.chain.joints()[j].kind != JointKind::Revolute {
            return Err(ctx.invalid(&key("joint"), "compliance is modelled on revolute joints"));
        }
        let k_nm = match (r.stiffness_nm_per_rad, r.deg_per_nm) {
            (Some(s), None) => ctx.positive(&key("stiffness_nm_per_rad"), s)?,
            (None, Some(c)) => 1.0 / ctx.positive(&key("deg_per_nm"), c)?.to_radians(),
            _ => {
                return Err(ctx.invalid(
                    &format!(".joints[{k}]"),
                    "give exactly one of `stiffness_nm_per_rad` and `deg_per_nm`",
                ))
            }
        };
        if stiffness.iter().any(|&(s, _)| s == j) {
            return Err(ctx.invalid(&key("joint"), "joint listed twice"));
        }
        stiffness.push((j, k_nm));
    }
    if stiffness.is_empty() {
        return Err(ctx.invalid(".joints", "needs at least one compliant joint"));
    }
    Ok(Arc::new(JointCompliance { masses, stiffness }))
}
