//! `transmission_error`: cyclic gear error, periodic in the joint's own angle.
//!
//! Model for order n (cycles per 360°): Δq = A·sin(n·q + φ) = βs·sin(n q) + βc·cos(n q) with
//! βs = A cos φ, βc = A sin φ. Columns: sin(n q_j)·J_j and cos(n q_j)·J_j (J_j the joint's column
//! of the joint Jacobian, mm/rad); coefficients in rad. Reported: amplitude and phase (degrees).

use super::{Candidate, Data, Index, Param};
use nalgebra::DMatrix;
use rigcal_core::kinematics::Robot;

/// Highest order in the library.
pub const MAX_ORDER: u32 = 4;

/// A cyclic error of one order on one joint.
#[derive(Debug, Clone, Copy)]
pub struct TransmissionError {
    /// The joint (0-based).
    pub joint: usize,
    /// Cycles per 360°.
    pub order: u32,
}

impl Candidate for TransmissionError {
    fn kind(&self) -> &'static str {
        "transmission_error"
    }

    fn index(&self) -> Index {
        Index::Joint(self.joint)
    }

    fn order(&self) -> Option<u32> {
        Some(self.order)
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        let j = self.joint;
        if !d.moving.contains(&j)
            || d.chain.joints()[j].kind != rigcal_core::kinematics::JointKind::Revolute
        {
            return None;
        }
        let n = f64::from(self.order);
        let s = d.joint_column(j, |i| (n * d.obs[i].q[j]).sin());
        let c = d.joint_column(j, |i| (n * d.obs[i].q[j]).cos());
        Some(DMatrix::from_columns(&[s.column(0), c.column(0)]))
    }

    fn explanation(&self) -> String {
        format!(
            "joint {}'s gearing has a cyclic error repeating {} time(s) per revolution",
            self.joint + 1,
            self.order
        )
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, _d: &Data) -> Vec<Param> {
        let (bs, bc) = (coef[0], coef[1]);
        let a = bs.hypot(bc);
        // σ of the amplitude along the fitted direction (delta method).
        let sa = if a > 0.0 {
            let g = [bs / a, bc / a];
            (g[0] * g[0] * cov[(0, 0)]
                + 2.0 * g[0] * g[1] * cov[(0, 1)]
                + g[1] * g[1] * cov[(1, 1)])
                .max(0.0)
                .sqrt()
        } else {
            f64::NAN
        };
        vec![
            Param {
                name: "amplitude_deg".into(),
                value: a.to_degrees(),
                sigma: sa.to_degrees(),
            },
            Param {
                name: "phase_deg".into(),
                value: bc.atan2(bs).to_degrees(),
                sigma: f64::NAN,
            },
            Param {
                name: "order".into(),
                value: f64::from(self.order),
                sigma: 0.0,
            },
        ]
    }
}
