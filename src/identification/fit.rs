//! Least-squares identification: Levenberg–Marquardt with column scaling.
//!
//! Residual r = measured − modelled position (mm), stacked over observations. Each step solves
//! (JsᵀJs + λ·diag(JsᵀJs)) δs = Jsᵀr with Js = J·D⁻¹, D the column norms, so millimetres and
//! radians are treated alike. At the solution the covariance is σ̂²(JᵀJ)⁻¹ with
//! σ̂² = RSS / (3m − p).

use super::identifiability::kappa_eq4;
use crate::kinematics::{ErrorParams, Robot};
use nalgebra::{DMatrix, DVector, Vector3};

// Observations come from recordings; identification reads them.
pub use crate::recording::Observation;

/// Settings of the fit.
#[derive(Debug, Clone)]
pub struct FitOptions {
    /// Iteration cap.
    pub max_iterations: usize,
    /// Stop when the scaled step norm falls below this.
    pub step_tolerance: f64,
    /// A weak prior pulling each fitted parameter towards a value.
    pub prior: Option<Prior>,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            step_tolerance: 1e-10,
            prior: None,
        }
    }
}

/// A Gaussian prior on the fitted parameters, added as extra residual rows
/// `weight_i · (mean_i − x_i)` (mm). With `weight_i = σ_noise / σ_prior,i` this is the maximum
/// a-posteriori estimate; directions the data determine are hardly affected.
#[derive(Debug, Clone)]
pub struct Prior {
    /// Prior means, all parameters (internal units).
    pub mean: ErrorParams,
    /// Row weight per fitted parameter, in `free` order (mm per internal unit).
    pub weight: Vec<f64>,
}

/// Why a fit failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// Fewer scalar measurements than unknowns.
    #[error("{observations} measurements give {rows} equations for {unknowns} unknowns: measure at least {needed} poses")]
    TooFewObservations {
        /// Observations given.
        observations: usize,
        /// Scalar equations.
        rows: usize,
        /// Unknowns.
        unknowns: usize,
        /// Poses needed.
        needed: usize,
    },
    /// The normal equations are singular: the poses do not separate the parameters.
    #[error("the poses do not separate the parameters (κ = {kappa:.3e}): spread the poses over the workspace or fit fewer parameters")]
    Singular {
        /// κ of eq. (4).
        kappa: f64,
    },
}

/// Position-error statistics over a set of points (mm).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct ResidualStats {
    /// Number of points.
    pub n: usize,
    /// Root mean square of the 3-D error.
    pub rms_mm: f64,
    /// Mean 3-D error.
    pub mean_mm: f64,
    /// Largest 3-D error.
    pub max_mm: f64,
    /// Per-axis RMS (x, y, z).
    pub axis_rms_mm: [f64; 3],
}

impl ResidualStats {
    /// Statistics of a list of error vectors.
    pub fn of(errors: &[Vector3<f64>]) -> Self {
        let n = errors.len();
        if n == 0 {
            return Self::default();
        }
        let nf = n as f64;
        let norms: Vec<f64> = errors.iter().map(|e| e.norm()).collect();
        let mut axis = [0.0; 3];
        for e in errors {
            for k in 0..3 {
                axis[k] += e[k] * e[k];
            }
        }
        Self {
            n,
            rms_mm: (norms.iter().map(|v| v * v).sum::<f64>() / nf).sqrt(),
            mean_mm: norms.iter().sum::<f64>() / nf,
            max_mm: norms.iter().copied().fold(0.0, f64::max),
            axis_rms_mm: axis.map(|s| (s / nf).sqrt()),
        }
    }
}

/// The outcome of a fit.
#[derive(Debug, Clone)]
pub struct FitResult {
    /// All error parameters, the fitted ones at their estimates.
    pub params: ErrorParams,
    /// Layout indices fitted.
    pub free: Vec<usize>,
    /// Standard deviation of each fitted parameter (internal units), in `free` order.
    pub sigma: Vec<f64>,
    /// Covariance of the fitted parameters.
    pub covariance: DMatrix<f64>,
    /// κ of eq. (4) at the solution.
    pub kappa: f64,
    /// Residuals before the fit (at the start values).
    pub before: ResidualStats,
    /// Residuals after the fit.
    pub after: ResidualStats,
    /// Estimated measurement noise σ̂ per coordinate (mm).
    pub sigma0_mm: f64,
    /// Iterations taken.
    pub iterations: usize,
    /// Residual vectors (measured − modelled) per observation, after the fit.
    pub residuals: Vec<Vector3<f64>>,
}

/// Fits the `free` parameters (layout indices) to the observations, starting from `start`.
pub fn fit(
    robot: &dyn Robot,
    obs: &[Observation],
    start: &ErrorParams,
    free: &[usize],
    opts: &FitOptions,
) -> Result<FitResult, FitError> {
    let p = free.len();
    let rows = 3 * obs.len();
    if rows < p + 1 {
        return Err(FitError::TooFewObservations {
            observations: obs.len(),
            rows,
            unknowns: p,
            needed: p / 3 + 1,
        });
    }
    let mut e = start.clone();
    let prior = opts.prior.as_ref();
    let (mut r, mut j) = residual_and_jacobian(robot, obs, &e, free, prior);
    let before = ResidualStats::of(&errors(robot, obs, &e));
    let mut cost = r.norm_squared();
    let mut lambda = 1e-4;
    let mut iterations = 0;
    for _ in 0..opts.max_iterations {
        iterations += 1;
        let d: Vec<f64> = (0..p).map(|c| j.column(c).norm().max(1e-300)).collect();
        let js = scale_columns(&j, &d);
        let a = js.transpose() * &js;
        let g = js.transpose() * &r;
        let mut improved = false;
        let mut step_norm = 0.0;
        for _ in 0..12 {
            let mut damped = a.clone();
            for k in 0..p {
                damped[(k, k)] += lambda * a[(k, k)].max(1e-12);
            }
            let Some(chol) = damped.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let ds = chol.solve(&g);
            step_norm = ds.norm();
            let mut trial = e.clone();
            for (k, &i) in free.iter().enumerate() {
                trial.set(i, trial.get(i) + ds[k] / d[k]);
            }
            let r_trial = residual(robot, obs, &trial, free, prior);
            let c_trial = r_trial.norm_squared();
            if c_trial <= cost {
                e = trial;
                cost = c_trial;
                lambda = (lambda * 0.2).max(1e-12);
                improved = true;
                break;
            }
            lambda *= 10.0;
        }
        if !improved || step_norm < opts.step_tolerance {
            break;
        }
        let rj = residual_and_jacobian(robot, obs, &e, free, prior);
        r = rj.0;
        j = rj.1;
    }
    let (r, j) = residual_and_jacobian(robot, obs, &e, free, prior);
    let data_rows = 3 * obs.len();
    let kappa = kappa_eq4(&j.rows(0, data_rows).clone_owned());
    let jtj = j.transpose() * &j;
    let Some(inv) = jtj
        .clone()
        .try_inverse()
        .filter(|m| m.iter().all(|v| v.is_finite()))
    else {
        return Err(FitError::Singular { kappa });
    };
    let dof = (rows - p).max(1) as f64;
    let s2 = r.rows(0, data_rows).norm_squared() / dof;
    let covariance = inv * s2;
    let sigma = (0..p).map(|k| covariance[(k, k)].max(0.0).sqrt()).collect();
    let residuals = to_vectors(&r.rows(0, data_rows).clone_owned());
    Ok(FitResult {
        params: e,
        free: free.to_vec(),
        sigma,
        covariance,
        kappa,
        before,
        after: ResidualStats::of(&residuals),
        sigma0_mm: s2.sqrt(),
        iterations,
        residuals,
    })
}

/// Position errors (measured − modelled) of a parameter set over observations.
pub fn errors(robot: &dyn Robot, obs: &[Observation], e: &ErrorParams) -> Vec<Vector3<f64>> {
    obs.iter().map(|o| o.p - robot.position(&o.q, e)).collect()
}

fn prior_rows(prior: Option<&Prior>, free: &[usize]) -> usize {
    prior.map_or(0, |_| free.len())
}

fn fill_prior(
    r: &mut DVector<f64>,
    j: Option<&mut DMatrix<f64>>,
    prior: Option<&Prior>,
    e: &ErrorParams,
    free: &[usize],
    start: usize,
) {
    let Some(prior) = prior else { return };
    for (k, &i) in free.iter().enumerate() {
        let w = prior.weight.get(k).copied().unwrap_or(0.0);
        r[start + k] = w * (prior.mean.get(i) - e.get(i));
    }
    if let Some(j) = j {
        for k in 0..free.len() {
            j[(start + k, k)] = prior.weight.get(k).copied().unwrap_or(0.0);
        }
    }
}

fn residual(
    robot: &dyn Robot,
    obs: &[Observation],
    e: &ErrorParams,
    free: &[usize],
    prior: Option<&Prior>,
) -> DVector<f64> {
    let mut r = DVector::zeros(3 * obs.len() + prior_rows(prior, free));
    for (k, o) in obs.iter().enumerate() {
        let d = o.p - robot.position(&o.q, e);
        r.fixed_rows_mut::<3>(3 * k).copy_from(&d);
    }
    fill_prior(&mut r, None, prior, e, free, 3 * obs.len());
    r
}

fn residual_and_jacobian(
    robot: &dyn Robot,
    obs: &[Observation],
    e: &ErrorParams,
    free: &[usize],
    prior: Option<&Prior>,
) -> (DVector<f64>, DMatrix<f64>) {
    let extra = prior_rows(prior, free);
    let mut r = DVector::zeros(3 * obs.len() + extra);
    let mut j = DMatrix::zeros(3 * obs.len() + extra, free.len());
    for (k, o) in obs.iter().enumerate() {
        let (p, m) = robot.position_and_param_jacobian(&o.q, e);
        r.fixed_rows_mut::<3>(3 * k).copy_from(&(o.p - p));
        for (c, &i) in free.iter().enumerate() {
            for row in 0..3 {
                j[(3 * k + row, c)] = m[(row, i)];
            }
        }
    }
    fill_prior(&mut r, Some(&mut j), prior, e, free, 3 * obs.len());
    (r, j)
}

fn scale_columns(j: &DMatrix<f64>, d: &[f64]) -> DMatrix<f64> {
    let mut js = j.clone();
    for (c, s) in d.iter().enumerate() {
        js.column_mut(c).scale_mut(1.0 / s);
    }
    js
}

fn to_vectors(r: &DVector<f64>) -> Vec<Vector3<f64>> {
    (0..r.len() / 3)
        .map(|k| Vector3::new(r[3 * k], r[3 * k + 1], r[3 * k + 2]))
        .collect()
}
