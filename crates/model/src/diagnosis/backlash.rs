//! `backlash`: lost motion b on a joint; its error flips with the direction it approached from.
//!
//! Model: actual = commanded − s·b/2, s = sign of the joint's last change before the
//! measurement (−1, 0, +1; from every row of the recording, measured or not). Column:
//! s · (joint column of the joint Jacobian); coefficient β = −b/2 (rad or mm).

use super::{Candidate, Data, Index, Param};
use nalgebra::DMatrix;
use rigcal_core::kinematics::{JointKind, Robot};

/// Lost motion of one joint.
#[derive(Debug, Clone, Copy)]
pub struct Backlash {
    /// The joint (0-based).
    pub joint: usize,
}

impl Candidate for Backlash {
    fn kind(&self) -> &'static str {
        "backlash"
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
