//! An upper confidence bound of a region's largest error from its test points: what the
//! division accepts a region on (planning mode), instead of the sample maximum alone.
//!
//! # Why
//! The paper accepts a region when every test point meets the demand. A large region whose
//! error varies quickly can pass that way on few points: at seeds 8, 10 and 11 of
//! `sim/paper-fig6.toml` a half workspace holding the whole Fig. 6 path passed its 27 test
//! points at 0.096–0.098 mm and the path then reached 0.106–0.145 mm. The test points' errors
//! say more than their maximum: how fast the error varies between them, so how much it may rise
//! where no test point looked.
//!
//! # The rule
//! Each component of the test points' error vectors (measured − target, mm) is modelled as a
//! Gaussian process over the region's unit cube: zero mean, squared-exponential covariance
//! σ²·exp(−d²/2ℓ²) with a nugget g·σ² (isotropic in unit-cube coordinates: a region splits
//! across its widest dimension, so its sides are comparable). ℓ and g are chosen by maximum
//! likelihood over a grid shared by the three components ([`LENGTHS`], [`NUGGETS`]), σ² per
//! component in closed form. On a 9 × 9 × 9 grid over the cube the bound at each point is
//! √Σ_c (|μ_c| + z·s_c)², μ_c and s_c the posterior mean and standard deviation of component
//! c; the region's bound is the largest over the grid and the test points' own errors. A
//! region is accepted when its bound meets the demand. An error that varies faster than the
//! test points are spaced looks like noise to the process (short ℓ): its posterior reverts to
//! the prior's spread away from the points and the bound rises — the evidence does not support
//! the region, which splits. A smooth error interpolates with a small s and the bound stays
//! close to the sample maximum.
//!
//! With fewer than [`MIN_POINTS`] test points there is not enough to fit the process: the
//! bound is the sample maximum (the paper's rule).

use nalgebra::{DMatrix, DVector, Vector3};

/// Length scales tried (unit-cube coordinates).
pub const LENGTHS: [f64; 10] = [0.06, 0.09, 0.13, 0.18, 0.25, 0.35, 0.5, 0.7, 1.0, 1.5];

/// Nuggets tried, as a fraction of the signal variance (noise, and what the squared
/// exponential cannot follow).
pub const NUGGETS: [f64; 4] = [1e-6, 1e-3, 1e-2, 1e-1];

/// Fewest test points the process is fitted on.
pub const MIN_POINTS: usize = 10;

/// Levels per dimension of the grid the bound is taken over.
const GRID: usize = 9;

/// One test point: its unit-cube coordinates in the region and its error vector (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TestError {
    /// Unit-cube coordinates (each 0..=1) of the target in the region's box.
    pub u: [f64; 3],
    /// Measured − target (mm).
    pub error: Vector3<f64>,
}

/// The process fitted to a region's test errors.
struct Fit {
    length: f64,
    /// Cholesky factor of the correlation matrix (with nugget).
    chol: nalgebra::Cholesky<f64, nalgebra::Dyn>,
    /// R⁻¹ y per component.
    alpha: [DVector<f64>; 3],
    /// Signal standard deviation per component (mm).
    sigma: [f64; 3],
}

fn correlation(a: &[f64; 3], b: &[f64; 3], length: f64) -> f64 {
    let d2: f64 = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum();
    (-d2 / (2.0 * length * length)).exp()
}

/// The maximum-likelihood process over [`LENGTHS`] × [`NUGGETS`]; None if no correlation
/// matrix could be factored.
fn fit(points: &[TestError]) -> Option<Fit> {
    let n = points.len();
    let mut best: Option<(f64, Fit)> = None;
    for &length in &LENGTHS {
        for &nugget in &NUGGETS {
            let r = DMatrix::from_fn(n, n, |i, j| {
                correlation(&points[i].u, &points[j].u, length) + if i == j { nugget } else { 0.0 }
            });
            let Some(chol) = r.cholesky() else {
                continue;
            };
            let log_det: f64 = 2.0 * chol.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
            let mut alpha: [DVector<f64>; 3] = std::array::from_fn(|_| DVector::zeros(n));
            let mut sigma = [0.0; 3];
            let mut log_lik = -1.5 * log_det;
            for c in 0..3 {
                let y = DVector::from_fn(n, |i, _| points[i].error[c]);
                let a = chol.solve(&y);
                // Profile likelihood: σ² = yᵀR⁻¹y / n; a floor keeps an all-zero component finite.
                let var = (y.dot(&a) / n as f64).max(1e-18);
                log_lik -= 0.5 * n as f64 * var.ln();
                sigma[c] = var.sqrt();
                alpha[c] = a;
            }
            if best.as_ref().is_none_or(|(b, _)| log_lik > *b) {
                best = Some((
                    log_lik,
                    Fit {
                        length,
                        chol,
                        alpha,
                        sigma,
                    },
                ));
            }
        }
    }
    best.map(|(_, f)| f)
}

/// The region's bound (mm): the largest of √Σ_c (|μ_c| + z·s_c)² over a 9 × 9 × 9 grid of the
/// unit cube and of the test errors themselves; the sample maximum with fewer than
/// [`MIN_POINTS`] points or `z` ≤ 0.
pub fn upper_bound(points: &[TestError], z: f64) -> f64 {
    let sample_max = points.iter().map(|p| p.error.norm()).fold(0.0, f64::max);
    if points.len() < MIN_POINTS || z <= 0.0 {
        return sample_max;
    }
    let Some(f) = fit(points) else {
        return sample_max;
    };
    let n = points.len();
    let mut worst = sample_max;
    let level = |k: usize| k as f64 / (GRID - 1) as f64;
    for i in 0..GRID {
        for j in 0..GRID {
            for k in 0..GRID {
                let x = [level(i), level(j), level(k)];
                let r = DVector::from_fn(n, |m, _| correlation(&x, &points[m].u, f.length));
                // Latent variance: the nugget is not part of the error field's value.
                let v = f
                    .chol
                    .l()
                    .solve_lower_triangular(&r)
                    .unwrap_or_else(|| r.clone());
                let var = (1.0 - v.dot(&v)).max(0.0);
                let b2: f64 = (0..3)
                    .map(|c| (r.dot(&f.alpha[c]).abs() + z * f.sigma[c] * var.sqrt()).powi(2))
                    .sum();
                worst = worst.max(b2.sqrt());
            }
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_points(field: impl Fn(&[f64; 3]) -> Vector3<f64>) -> Vec<TestError> {
        let level = [0.01, 0.5, 0.99];
        let mut v = Vec::new();
        for a in level {
            for b in level {
                for c in level {
                    let u = [a, b, c];
                    v.push(TestError {
                        u,
                        error: field(&u),
                    });
                }
            }
        }
        v
    }

    #[test]
    fn a_smooth_error_keeps_the_bound_near_the_sample_max() {
        let pts = grid_points(|u| Vector3::new(0.02 + 0.05 * u[0], 0.01 * u[1], 0.0));
        let max = pts.iter().map(|p| p.error.norm()).fold(0.0, f64::max);
        let b = upper_bound(&pts, 2.0);
        assert!(b >= max && b < 1.15 * max, "bound {b} against max {max}");
    }

    #[test]
    fn an_error_faster_than_the_test_points_raises_the_bound() {
        // Wavelengths of a fifth of the cube or less along every axis: the 3 × 3 × 3 grid
        // sees scatter.
        let f = |u: &[f64; 3]| {
            let phase = 37.0 * u[0] + 53.0 * u[1] + 71.0 * u[2];
            Vector3::new(0.05 * phase.sin(), 0.04 * (1.3 * phase).cos(), 0.0)
        };
        let pts = grid_points(f);
        let max = pts.iter().map(|p| p.error.norm()).fold(0.0, f64::max);
        let b = upper_bound(&pts, 2.0);
        assert!(b > 1.3 * max, "bound {b} against max {max}");
    }

    #[test]
    fn few_points_give_the_sample_max() {
        let pts: Vec<TestError> = grid_points(|u| Vector3::new(u[0], 0.0, 0.0))
            .into_iter()
            .take(MIN_POINTS - 1)
            .collect();
        let max = pts.iter().map(|p| p.error.norm()).fold(0.0, f64::max);
        assert_eq!(upper_bound(&pts, 2.0), max);
    }
}
