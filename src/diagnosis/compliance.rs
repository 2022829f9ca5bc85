//! `joint_compliance`: a joint deflects in proportion to the gravity torque it carries.
//!
//! The real masses are unknown, so the torque comes from a generic model: a unit mass (1 kg) at
//! each point along the links beyond the joint — the origin of every later joint's axis frame,
//! the tool frame and the measured tip. A mass anywhere on the straight segments between those
//! points is a non-negative combination of them, so the fitted combination is the effective mass
//! distribution. Column k = τ_k(q) · (joint j's column of the joint Jacobian), with
//! τ_k = ((p_k − o_j) × (0, 0, −9.81 N/kg)) · z_j in N·m per kg (lever in metres), gravity along
//! world −z. Coefficients: rad per N·m times kg. Reported: the deflection it causes (degrees).

use super::{Candidate, Data, Index, Param};
use crate::kinematics::{JointKind, Robot};
use nalgebra::{DMatrix, Vector3};

/// Standard gravity (m/s²) along world −z.
const G: f64 = 9.81;

/// Gravity compliance of one joint.
#[derive(Debug, Clone, Copy)]
pub struct JointCompliance {
    /// The joint (0-based).
    pub joint: usize,
}

/// Torques (N·m per kg) about joint `j` at `q` of a unit mass at each generic point beyond it.
pub fn unit_torques(d: &Data, q: &[f64], j: usize) -> Vec<f64> {
    let chain = &d.chain;
    let n = chain.joints().len();
    let axis = chain.frame_before_joint(q, &d.e, j);
    let z = axis.rotation * Vector3::z();
    let o = axis.translation.vector;
    let weight = Vector3::new(0.0, 0.0, -G);
    let mut points: Vec<Vector3<f64>> = (j + 1..=n)
        .map(|k| chain.frame_before_joint(q, &d.e, k).translation.vector)
        .collect();
    points.push(chain.position(q, &d.e));
    points
        .iter()
        .map(|p| ((p - o) / 1000.0).cross(&weight).dot(&z))
        .collect()
}

impl JointCompliance {
    fn deflections(&self, coef: &[f64], d: &Data) -> Vec<f64> {
        d.obs
            .iter()
            .map(|o| {
                unit_torques(d, &o.q, self.joint)
                    .iter()
                    .zip(coef)
                    .map(|(t, c)| t * c)
                    .sum()
            })
            .collect()
    }
}

impl Candidate for JointCompliance {
    fn kind(&self) -> &'static str {
        "joint_compliance"
    }

    fn index(&self) -> Index {
        Index::Joint(self.joint)
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        if !d.moving.contains(&self.joint) {
            return None;
        }
        let torques: Vec<Vec<f64>> = d
            .obs
            .iter()
            .map(|o| unit_torques(d, &o.q, self.joint))
            .collect();
        // A joint whose axis is (nearly) vertical carries no gravity torque: its columns would be
        // numerical dust that column scaling blows up, so it is not a candidate.
        let max_torque = torques.iter().flatten().fold(0.0f64, |a, t| a.max(t.abs()));
        let max_lever_m = d
            .obs
            .iter()
            .map(|o| {
                let axis = d.chain.frame_before_joint(&o.q, &d.e, self.joint);
                (d.chain.position(&o.q, &d.e) - axis.translation.vector).norm() / 1000.0
            })
            .fold(0.0f64, f64::max);
        if max_torque < 0.01 * G * max_lever_m {
            return None;
        }
        let k = torques.first().map_or(0, Vec::len);
        let mut m = DMatrix::zeros(3 * d.len(), k);
        for (i, t) in torques.iter().enumerate() {
            for (c, tc) in t.iter().enumerate() {
                for r in 0..3 {
                    m[(3 * i + r, c)] = tc * d.joint_jacobian[i][(r, self.joint)];
                }
            }
        }
        Some(m)
    }

    fn explanation(&self) -> String {
        format!(
            "joint {} deflects in proportion to the gravity torque it carries",
            self.joint + 1
        )
    }

    fn params(&self, coef: &[f64], _cov: &DMatrix<f64>, d: &Data) -> Vec<Param> {
        let defl = self.deflections(coef, d);
        let unit = |v: f64| match d.chain.joints()[self.joint].kind {
            JointKind::Revolute => v.to_degrees(),
            JointKind::Prismatic => v,
        };
        let n = defl.len().max(1) as f64;
        let rms = (defl.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        let max = defl.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        vec![
            Param {
                name: "deflection_rms_deg".into(),
                value: unit(rms),
                sigma: f64::NAN,
            },
            Param {
                name: "deflection_max_deg".into(),
                value: unit(max),
                sigma: f64::NAN,
            },
        ]
    }
}
