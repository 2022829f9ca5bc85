//! `thermal_drift`: an error that grows with time as the machine warms.
//!
//! Model: a smooth warm-up curve over the session, β1·u + β2·u² with u = t / T (T the last
//! measurement's time), on a joint angle (columns u·J_j, u²·J_j; rad) or on the tip along a
//! world axis (columns u·e_a, u²·e_a; mm). A constant part is geometry. Reported: the drift
//! over the whole session, β1 + β2 (degrees or mm).

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
        let (a, b) = match self.target {
            Index::Joint(j) => {
                if !d.moving.contains(&j)
                    && d.joint_jacobian.iter().all(|m| m.column(j).norm() == 0.0)
                {
                    return None;
                }
                (
                    d.joint_column(j, |i| u[i]),
                    d.joint_column(j, |i| u[i] * u[i]),
                )
            }
            Index::Axis(a) => (
                d.axis_column(a, |i| u[i]),
                d.axis_column(a, |i| u[i] * u[i]),
            ),
            Index::Axes(..) => return None,
        };
        Some(DMatrix::from_columns(&[a.column(0), b.column(0)]))
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
        let v = coef[0] + coef[1];
        let s = (cov[(0, 0)] + 2.0 * cov[(0, 1)] + cov[(1, 1)])
            .max(0.0)
            .sqrt();
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
