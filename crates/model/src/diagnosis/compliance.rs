//! `joint_compliance`: a joint deflects in proportion to the gravity torque it carries.
//!
//! Two models, chosen by what the rig file knows (the report says which):
//!
//! * **Masses known** — every link from the joint to the tip has `mass_kg` (and `com_mm`) in the
//!   rig file (`rig from-urdf` copies them from the URDF's `<inertial>`). The gravity torque
//!   τ_j(q) = Σ_{links k ≥ j} ((c_k − o_j) × m_k·g) · z_j (N·m, lever in metres) is then known,
//!   the column is τ_j(q) · (joint j's column of the joint Jacobian) and its coefficient is the
//!   compliance itself, rad/(N·m): reported as `deg_per_nm` with its σ (spec/recordings.md).
//! * **Masses unknown** — the torque comes from a generic model: a unit mass (1 kg) at each point
//!   along the links beyond the joint (the origin of every later joint's axis frame, the tool
//!   frame and the measured tip). A mass anywhere on the straight segments between those points
//!   is a non-negative combination of them, so the fitted combination is the effective mass
//!   distribution. Column k = τ_k(q) · J_j with τ_k in N·m per kg; coefficient k = compliance ×
//!   the mass effectively at point k. Compliance and mass cannot be told apart from positions
//!   alone, so `deg_per_nm` is *not* reported (an honest figure needs the masses): instead
//!   `compliance_times_mass_deg_kg_per_nm` (Σ_k of the coefficients: compliance × the mass it
//!   carries, ± σ) and the deflection it causes (RMS and max, degrees), and the explanation says
//!   why.
//!
//! Gravity is along the robot base's −z (for a free tracker frame, rotated into the tracker's
//! coordinates with the fitted frame). Units: kg, mm (metres inside torques), N·m, degrees in
//! reports, radians inside.

use super::{Candidate, Data, Index, Param};
use nalgebra::{DMatrix, Vector3};
use rigcal_core::kinematics::{JointKind, Robot};
use rigcal_core::rig::LinkMass;

/// Standard gravity (m/s²) along world −z.
const G: f64 = 9.81;

/// Gravity compliance of one joint.
#[derive(Debug, Clone)]
pub struct JointCompliance {
    /// The joint (0-based).
    pub joint: usize,
    /// The rig's link masses, per joint (see [`rigcal_core::rig::Rig::link_masses`]); the mass model
    /// is used when every link from this joint on has one.
    pub masses: Option<std::sync::Arc<Vec<Option<LinkMass>>>>,
}

/// Gravity (N per kg) in the coordinates the chain's points are in: the robot base's −z, turned
/// by the measurement frame when it is fitted.
fn gravity(d: &Data) -> Vector3<f64> {
    d.chain.frame_pose(&d.e).rotation * Vector3::new(0.0, 0.0, -G)
}

/// The gravity torque (N·m) about joint `j` at `q` from the rig's link masses, or None when a
/// link from `j` on has no mass.
pub fn mass_torque(d: &Data, q: &[f64], j: usize, masses: &[Option<LinkMass>]) -> Option<f64> {
    let chain = &d.chain;
    let n = chain.joints().len();
    let axis = chain.frame_before_joint(q, &d.e, j);
    let z = axis.rotation * Vector3::z();
    let o = axis.translation.vector;
    let g = gravity(d);
    let mut tau = 0.0;
    for k in j..n {
        let m = masses.get(k).copied().flatten()?;
        let end = chain.frame_before_joint(q, &d.e, k + 1);
        let c = end * nalgebra::Point3::from(m.com_mm);
        tau += ((c.coords - o) / 1000.0).cross(&(g * m.kg)).dot(&z);
    }
    Some(tau)
}

impl JointCompliance {
    /// The rig's masses when they cover every link from this joint on.
    fn known_masses(&self, n: usize) -> Option<&[Option<LinkMass>]> {
        let m = self.masses.as_deref()?;
        (self.joint..n)
            .all(|k| m.get(k).is_some_and(Option::is_some))
            .then_some(m.as_slice())
    }
}

/// Torques (N·m per kg) about joint `j` at `q` of a unit mass at each generic point beyond it.
pub fn unit_torques(d: &Data, q: &[f64], j: usize) -> Vec<f64> {
    let chain = &d.chain;
    let n = chain.joints().len();
    let axis = chain.frame_before_joint(q, &d.e, j);
    let z = axis.rotation * Vector3::z();
    let o = axis.translation.vector;
    let weight = gravity(d);
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
        let torques: Vec<Vec<f64>> = match self.known_masses(d.chain.joints().len()) {
            Some(m) => d
                .obs
                .iter()
                .map(|o| mass_torque(d, &o.q, self.joint, m).into_iter().collect())
                .collect(),
            None => d
                .obs
                .iter()
                .map(|o| unit_torques(d, &o.q, self.joint))
                .collect(),
        };
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
        let base = format!(
            "joint {} deflects in proportion to the gravity torque it carries",
            self.joint + 1
        );
        if self
            .masses
            .as_deref()
            .is_some_and(|m| self.known_masses(m.len()).is_some())
        {
            format!("{base} (torque from the rig's link masses)")
        } else {
            format!("{base}; deg_per_nm is not available: the rig file gives no mass for every link from this joint on (mass_kg/com_mm, or a URDF with <inertial>), and positions alone cannot tell compliance from the mass it carries — reported are compliance × carried mass and the deflection")
        }
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, d: &Data) -> Vec<Param> {
        let unit = |v: f64| match d.chain.joints()[self.joint].kind {
            JointKind::Revolute => v.to_degrees(),
            JointKind::Prismatic => v,
        };
        let (per_nm, times_mass) = match d.chain.joints()[self.joint].kind {
            JointKind::Revolute => ("deg_per_nm", "compliance_times_mass_deg_kg_per_nm"),
            JointKind::Prismatic => ("mm_per_n", "compliance_times_mass_mm_kg_per_n"),
        };
        let mut out = Vec::new();
        if self.known_masses(d.chain.joints().len()).is_some() {
            let torques: Vec<f64> = self
                .known_masses(d.chain.joints().len())
                .map(|m| {
                    d.obs
                        .iter()
                        .filter_map(|o| mass_torque(d, &o.q, self.joint, m))
                        .collect()
                })
                .unwrap_or_default();
            out.push(Param {
                name: per_nm.into(),
                value: unit(coef[0]),
                sigma: unit(cov[(0, 0)].max(0.0).sqrt()),
            });
            let defl: Vec<f64> = torques.iter().map(|t| t * coef[0]).collect();
            let n = defl.len().max(1) as f64;
            out.push(Param {
                name: "deflection_rms_deg".into(),
                value: unit((defl.iter().map(|v| v * v).sum::<f64>() / n).sqrt()),
                sigma: f64::NAN,
            });
            return out;
        }
        let k = coef.len();
        let sum: f64 = coef.iter().sum();
        let var: f64 = (0..k)
            .flat_map(|a| (0..k).map(move |b| (a, b)))
            .map(|(a, b)| cov[(a, b)])
            .sum();
        out.push(Param {
            name: times_mass.into(),
            value: unit(sum),
            sigma: unit(var.max(0.0).sqrt()),
        });
        let defl = self.deflections(coef, d);
        let n = defl.len().max(1) as f64;
        let rms = (defl.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        let max = defl.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        out.extend([
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
        ]);
        out
    }
}
