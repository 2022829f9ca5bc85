//! Seed 000 section 6 helpers: the Fig. 6 joint path and the split of the uncalibrated error into
//! its total and its non-geometric part (conventions §3).
//!
//! Units: joint values in radians, errors in millimetres.

use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};

/// The Fig. 6 path: straight in joint space from (60°, 60°, −35°) to (125°, 90°, −10°), `n`
/// points, every further joint at zero. `n_joints` ≥ 3.
pub fn fig6_path(n: usize, n_joints: usize) -> Vec<Vec<f64>> {
    let a = [60.0f64, 60.0, -35.0];
    let b = [125.0f64, 90.0, -10.0];
    (0..n)
        .map(|k| {
            let t = k as f64 / (n.max(2) - 1) as f64;
            let mut q = vec![0.0; n_joints.max(3)];
            for j in 0..3 {
                q[j] = (a[j] + t * (b[j] - a[j])).to_radians();
            }
            q.truncate(n_joints.max(3));
            q
        })
        .collect()
}

/// Position errors along a path (mm): the total uncalibrated error and the part the
/// non-geometric joint errors cause alone.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorSplit {
    /// |true position − nominal position| per point.
    pub total_mm: Vec<f64>,
    /// |nominal position at the actual joints − nominal position| per point.
    pub non_geometric_mm: Vec<f64>,
}

impl ErrorSplit {
    /// Mean total error (mm).
    pub fn mean_total(&self) -> f64 {
        mean(&self.total_mm)
    }

    /// Smallest and largest total error (mm).
    pub fn total_range(&self) -> (f64, f64) {
        let lo = self.total_mm.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = self
            .total_mm
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    }

    /// Conventions §3: mean non-geometric error ÷ mean total error.
    pub fn share(&self) -> f64 {
        mean(&self.non_geometric_mm) / self.mean_total()
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// The error split along `path` for an arm with geometric errors `truth` whose actual joints are
/// the commanded ones plus `offsets(q)`.
pub fn error_split(
    chain: &SerialChain,
    truth: &ErrorParams,
    path: &[Vec<f64>],
    offsets: &dyn Fn(&[f64]) -> Vec<f64>,
) -> ErrorSplit {
    let nominal = ErrorParams::zeros(chain.layout());
    let mut total_mm = Vec::with_capacity(path.len());
    let mut non_geometric_mm = Vec::with_capacity(path.len());
    for q in path {
        let dq = offsets(q);
        let actual: Vec<f64> = q.iter().zip(&dq).map(|(a, b)| a + b).collect();
        let target = chain.position(q, &nominal);
        total_mm.push((chain.position(&actual, truth) - target).norm());
        non_geometric_mm.push((chain.position(&actual, &nominal) - target).norm());
    }
    ErrorSplit {
        total_mm,
        non_geometric_mm,
    }
}
