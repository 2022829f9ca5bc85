//! `trig_joint_errors`: seed 000 eq. (6) as conventions §3 reads it, acting on the joint angles:
//!
//! ```text
//! Δq_i = Σ_j (a_ij · cos q_j + b_ij · sin q_j),   i, j = 1..3
//! ```
//!
//! Scenario entry: the coefficients are given (`a_deg`, `b_deg`, rows i, columns j, degrees) or
//! drawn uniformly in ±`random_deg` from the scenario seed; with `share`, they are then scaled so
//! the non-geometric share on the Fig. 6 path (conventions §3, with the scenario's geometric
//! errors and this effect alone) equals it. Also here, since the share is defined by them: the
//! Fig. 6 joint path ([`fig6_path`]) and the split of the uncalibrated error into its total and
//! its non-geometric part ([`error_split`]).
//!
//! Truth only: the diagnosis names the smooth joint errors it causes by their shapes, not as this
//! kind. Radians inside; errors in millimetres.

use super::entry::{EntryError, KindEntry, ParseCtx};
use super::kind::EffectKind;
use super::truth::{Effect, JointContext};
use nalgebra::Matrix3;
use rand::RngExt;
use rigcal_core::kinematics::{ErrorParams, JointKind, Robot, SerialChain};
use serde::Deserialize;
use std::sync::Arc;

/// Eq. (6) joint errors of the first three joints.
#[derive(Debug, Clone, PartialEq)]
pub struct TrigJointErrors {
    /// a_ij (rad): row i (joint whose error it is), column j (joint whose cosine).
    pub a: Matrix3<f64>,
    /// b_ij (rad), with sines.
    pub b: Matrix3<f64>,
}

impl TrigJointErrors {
    /// Δq_1..3 (rad) at joint values `q`.
    fn offsets(&self, q: &[f64]) -> [f64; 3] {
        let mut d = [0.0; 3];
        for (i, di) in d.iter_mut().enumerate() {
            for (j, qj) in q.iter().take(3).enumerate() {
                *di += self.a[(i, j)] * qj.cos() + self.b[(i, j)] * qj.sin();
            }
        }
        d
    }

    fn scaled(&self, k: f64) -> Self {
        Self {
            a: self.a * k,
            b: self.b * k,
        }
    }

    /// The non-geometric share on the Fig. 6 path with geometric errors `truth`.
    fn fig6_share(&self, chain: &SerialChain, truth: &ErrorParams) -> f64 {
        let path = fig6_path(101, chain.dof());
        let n = chain.dof();
        error_split(chain, truth, &path, &|q: &[f64]| {
            let mut dq = vec![0.0; n];
            dq[..3].copy_from_slice(&self.offsets(q));
            dq
        })
        .share()
    }

    /// These coefficients scaled so that [`Self::fig6_share`] equals `target` (bisection on the
    /// scale; the share grows monotonically with it). None when it cannot be reached.
    fn scaled_to_share(
        &self,
        chain: &SerialChain,
        truth: &ErrorParams,
        target: f64,
    ) -> Option<Self> {
        let share = |k: f64| self.scaled(k).fig6_share(chain, truth);
        let (mut lo, mut hi) = (0.0, 1.0);
        let mut grow = 0;
        while share(hi) < target {
            lo = hi;
            hi *= 2.0;
            grow += 1;
            if grow > 60 {
                return None;
            }
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if share(mid) < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(self.scaled(0.5 * (lo + hi)))
    }
}

impl Effect for TrigJointErrors {
    fn kind(&self) -> EffectKind {
        EffectKind::TrigJointErrors
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        let d = self.offsets(ctx.commanded);
        for (i, di) in d.iter().enumerate() {
            dq[i] += di;
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    a_deg: Option<[[f64; 3]; 3]>,
    b_deg: Option<[[f64; 3]; 3]>,
    random_deg: Option<f64>,
    share: Option<f64>,
}

/// The registry's entry of `trig_joint_errors`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `a_deg`/`b_deg` (3 × 3, degrees) or `random_deg`; optional `share` (fraction, e.g. 0.09).
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        let raw: Raw = ctx.raw(t)?;
        let joints = ctx.chain.joints();
        if joints.len() < 3 || joints[..3].iter().any(|j| j.kind != JointKind::Revolute) {
            return Err(ctx.invalid(
                ".kind",
                "eq. (6) needs a chain whose first three joints are revolute",
            ));
        }
        let explicit = raw.a_deg.is_some() || raw.b_deg.is_some();
        let matrix = |m: Option<[[f64; 3]; 3]>, key: &str| -> Result<Matrix3<f64>, EntryError> {
            let m = m.unwrap_or([[0.0; 3]; 3]);
            for (i, row) in m.iter().enumerate() {
                for (j, v) in row.iter().enumerate() {
                    ctx.finite(&format!(".{key}[{i}][{j}]"), *v)?;
                }
            }
            Ok(Matrix3::from_fn(|i, j| m[i][j].to_radians()))
        };
        let effect = match (explicit, raw.random_deg) {
            (true, None) => TrigJointErrors {
                a: matrix(raw.a_deg, "a_deg")?,
                b: matrix(raw.b_deg, "b_deg")?,
            },
            (false, Some(r)) => {
                let r = ctx.positive(".random_deg", r)?.to_radians();
                let mut rng = ctx.rng();
                let mut draw = || Matrix3::from_fn(|_, _| rng.random_range(-r..=r));
                let a = draw();
                let b = draw();
                TrigJointErrors { a, b }
            }
            _ => {
                return Err(ctx.invalid(
                    "",
                    "give the coefficients (`a_deg`, `b_deg`) or `random_deg`, not both",
                ))
            }
        };
        let effect = match raw.share {
            None => effect,
            Some(s) => {
                if !(s.is_finite() && s > 0.0 && s < 0.9) {
                    return Err(ctx.invalid(".share", "must be a fraction between 0 and 0.9"));
                }
                effect
                    .scaled_to_share(ctx.chain, ctx.truth, s)
                    .ok_or_else(|| {
                        ctx.invalid(".share", "cannot be reached with these coefficients")
                    })?
            }
        };
        Ok(Arc::new(effect))
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq6_by_hand() {
        // Δq_1 = a_12 cos q_2 + b_13 sin q_3 with q_2 = 60°, q_3 = −30°: 0.02 · 0.5 − 0.04 · 0.5.
        let mut t = TrigJointErrors {
            a: Matrix3::zeros(),
            b: Matrix3::zeros(),
        };
        t.a[(0, 1)] = 0.02;
        t.b[(0, 2)] = 0.04;
        t.b[(2, 0)] = 1.0;
        let d = t.offsets(&[
            90f64.to_radians(),
            60f64.to_radians(),
            (-30f64).to_radians(),
        ]);
        assert!((d[0] - (0.01 - 0.02)).abs() < 1e-15);
        assert!(d[1].abs() < 1e-15);
        assert!((d[2] - 1.0).abs() < 1e-15);
    }
}
