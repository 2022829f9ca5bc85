//! `thermal_drift`: an error that grows with time as the machine warms.
//!
//! Model: a smooth warm-up curve over the session, β1·u + β2·u² + β3·u³ with u = t / T (T the
//! last measurement's time), on a joint angle (columns u·J_j, u²·J_j, u³·J_j; rad) or on the tip
//! along a world axis (columns u·e_a, u²·e_a, u³·e_a; mm). A constant part is geometry.
//! Reported: the drift over the whole session, β1 + β2 + β3 (degrees or mm).
//!
//! Why cubic: a warm-up A·(1 − e^(−t/τ)) over a session of 1.7 τ leaves 2.9 % of its visible
//! RMS to a quadratic and 0.3 % to a cubic. At ten times the noise floor the quadratic's
//! leftover (0.3 × the floor) reads as a shape outside the library; the cubic's does not.

use super::{Candidate, Data, Index, Param};
use nalgebra::DMatrix;

/// Warm-up drift of a joint or along an axis.
#[derive(Debug, Clone, Copy)]
pub struct ThermalDrift {
    /// [`Index::Joint`] or [`Index::Axis`].
    pub target: Index,
}

fn normalised_time(d: &Data) -> Option<Vec<f64>> {
    let t = d.t_s.as_ref()?;
    let tmax = t.iter().copied().fold(0.0f64, f64::max);
    (tmax > 0.0).then(|| t.iter().map(|v| v / tmax).collect())
}

impl Candidate for ThermalDrift {
    fn kind(&self) -> &'static str {
        "thermal_drift"
    }

    fn index(&self) -> Index {
        self.target
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        let u = normalised_time(d)?;
        let cols = match self.target {
            Index::Joint(j) => {
                if !d.moving.contains(&j)
                    && d.joint_jacobian.iter().all(|m| m.column(j).norm() == 0.0)
                {
                    return None;
                }
                [1, 2, 3].map(|k| d.joint_column(j, |i| u[i].powi(k)))
            }
            Index::Axis(a) => [1, 2, 3].map(|k| d.axis_column(a, |i| u[i].powi(k))),
            Index::Axes(..) => return None,
        };
        Some(DMatrix::from_columns(&[
            cols[0].column(0),
            cols[1].column(0),
            cols[2].column(0),
        ]))
    }

    fn explanation(&self) -> String {
        match self.target {
            Index::Joint(j) => format!("joint {} drifts with time as the machine warms", j + 1),
            Index::Axis(a) => format!(
                "the tip drifts along world {} with time as the machine warms",
                super::AXES[a]
            ),
            Index::Axes(..) => String::new(),
        }
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, _d: &Data) -> Vec<Param> {
        let v: f64 = coef.iter().sum();
        // σ of the sum: 1ᵀ·Σ·1.
        let s = cov.iter().sum::<f64>().max(0.0).sqrt();
        match self.target {
            Index::Joint(_) => vec![Param {
                name: "drift_over_session_deg".into(),
                value: v.to_degrees(),
                sigma: s.to_degrees(),
            }],
            _ => vec![Param {
                name: "drift_over_session_mm".into(),
                value: v,
                sigma: s,
            }],
        }
    }
}
