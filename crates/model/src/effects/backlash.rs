//! `backlash`: lost motion b on one joint. The joint stops short of the command by b/2 on the
//! side it came from: actual = commanded − s·b/2, s = the sign of its last non-zero change (−1,
//! 0, +1; zero until the joint has moved, and from every row of a recording, measured or not).
//!
//! - truth ([`Backlash`]) and scenario entry: `joint`, `lost_motion_deg` (mm for a prismatic
//!   joint);
//! - diagnosis candidate: column s · (joint column of the joint Jacobian), coefficient β = −b/2
//!   (rad or mm), reported as `lost_motion_deg` (`_mm`);
//! - model term: basis −s/2, coefficient b ([`basis`]).
//!
//! Radians inside.

use super::candidate::{Candidate, Data, Index, Param};
use super::entry::{float, one_based, EntryError, KindEntry, Masses, NewEffect, ParseCtx};
use super::kind::EffectKind;
use super::truth::{Effect, JointContext};
use nalgebra::DMatrix;
use rigcal_core::kinematics::{JointKind, Robot, SerialChain};
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
    fn kind(&self) -> EffectKind {
        EffectKind::Backlash
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        let dir = ctx.direction.get(self.joint).copied().unwrap_or(0);
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

/// The registry's entry of `backlash`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `joint`, `lost_motion_deg`.
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        let raw: Raw = ctx.raw(t)?;
        let joint = ctx.joint(".joint", raw.joint)?;
        let b = ctx.non_negative(".lost_motion_deg", raw.lost_motion_deg)?;
        let spec = &Robot::joints(ctx.chain)[joint];
        Ok(Arc::new(Backlash {
            joint,
            lost_motion: spec.kind.from_file_units(b),
        }))
    }

    fn candidates(&self, on: Index, _masses: &Masses) -> Vec<Box<dyn Candidate>> {
        match on {
            Index::Joint(joint) => vec![Box::new(BacklashCandidate { joint })],
            _ => Vec::new(),
        }
    }
}

/// The scenario entry of a fitted lost motion `b` (rad or mm) on joint `joint` (0-based); an
/// error says why it cannot be written (a negative lost motion is not backlash).
pub fn scenario_entry(chain: &SerialChain, joint: usize, b: f64) -> Result<NewEffect, String> {
    let b = chain
        .joints()
        .get(joint)
        .map_or(b, |s| s.kind.to_file_units(b));
    if b < 0.0 {
        return Err(format!(
            "the fitted lost motion is negative ({b:.5}): the joint overshoots, which backlash is not"
        ));
    }
    let mut t = toml::Table::new();
    t.insert("kind".into(), EffectKind::Backlash.name().into());
    t.insert("joint".into(), one_based(joint));
    t.insert("lost_motion_deg".into(), float(b));
    Ok(NewEffect {
        table: t,
        summary: format!("lost_motion_deg = {b:.5}"),
    })
}

/// The model term's basis at approach directions `dir`: Δq_joint = b · (−s/2).
pub fn basis(joint: usize, dir: &[i8]) -> Vec<f64> {
    vec![-f64::from(dir.get(joint).copied().unwrap_or(0)) / 2.0]
}

/// The diagnosis candidate: lost motion of one joint.
#[derive(Debug, Clone, Copy)]
struct BacklashCandidate {
    /// The joint (0-based).
    joint: usize,
}

impl Candidate for BacklashCandidate {
    fn kind(&self) -> EffectKind {
        EffectKind::Backlash
    }

    fn index(&self) -> Index {
        Index::Joint(self.joint)
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        let j = self.joint;
        let signs: Vec<f64> = d.direction.iter().map(|s| f64::from(s[j])).collect();
        let both = signs.iter().any(|&s| s > 0.0) && signs.iter().any(|&s| s < 0.0);
        if !d.moving.contains(&j) || !both {
            return None;
        }
        Some(d.joint_column(j, |i| signs[i]))
    }

    fn explanation(&self) -> String {
        format!(
            "joint {} has lost motion: its error flips with the direction it approached from",
            self.joint + 1
        )
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, d: &Data) -> Vec<Param> {
        let (name, f): (&str, fn(f64) -> f64) = match d.chain.joints()[self.joint].kind {
            JointKind::Revolute => ("lost_motion_deg", f64::to_degrees),
            JointKind::Prismatic => ("lost_motion_mm", |v| v),
        };
        vec![Param {
            name: name.into(),
            value: f(-2.0 * coef[0]),
            sigma: f(2.0 * cov[(0, 0)].max(0.0).sqrt()),
        }]
    }
}
