//! Least-squares identification: Levenberg–Marquardt with column scaling.
//!
//! Residual r = measured − modelled position (mm), stacked over observations. Each step solves
//! (JsᵀJs + λ·diag(JsᵀJs)) δs = Jsᵀr with Js = J·D⁻¹, D the column norms, so millimetres and
//! radians are treated alike. At the solution the covariance is σ̂²(JᵀJ)⁻¹ with
//! σ̂² = RSS / (3m − p).
//!
//! The iteration stops when the scaled step falls below [`FitOptions::step_tolerance`], or
//! when the step's predicted decrease of rᵀr is below what rounding in the modelled positions
//! moves rᵀr by (the minimum is then reached as far as double precision can tell; iterating
//! further only samples rounding noise).
//!
//! Speed (2 200 measurements, 15 parameters, a few milliseconds): a serial chain is evaluated
//! multiplied out at each parameter set ([`rigcal_core::kinematics::ChainAt`], through
//! `robot_at`) with the joints' sines and cosines computed once; the data rows of J fill
//! one buffer reused by every pass, from which JᵀJ and Jᵀr are one product each; trial steps
//! evaluate positions only; κ goes through the QR factor of J.

use super::dense::{gram, transpose_times};
use super::identifiability::kappa_eq4;
use super::robot_at::Kinematics;
use nalgebra::{DMatrix, DVector, Vector3};
use rigcal_core::kinematics::{joint_trig, ErrorParams, Robot};

// Observations come from recordings; identification reads them.
pub use rigcal_core::recording::Observation;

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
    /// The measurements repeat too few poses: however many rows, they cannot determine the
    /// unknowns with any redundancy (rank loss), so a fit would report σ 0 and RMS 0.
    #[error("{observations} measurements hold only {distinct} distinct pose(s): the poses do not spread, so they give at most {} independent equations for {unknowns} unknowns (rank loss; every residual and σ would read 0). Measure at least {needed} distinct poses spread over the workspace (ten times that for a calibration worth the name)", 3 * distinct)]
    PosesDoNotSpread {
        /// Measurements given.
        observations: usize,
        /// Distinct joint vectors among them.
        distinct: usize,
        /// Unknowns.
        unknowns: usize,
        /// Distinct poses needed at least.
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
    /// Parameters the poses do not determine, held at their start values and not fitted
    /// ([`super::analyse_determined`]; empty when the caller chose `free` itself).
    pub undetermined: Vec<super::Undetermined>,
}

/// Fits the `free` parameters (layout indices) to the observations, starting from `start`.
pub fn fit(
    robot: &dyn Robot,
    obs: &[Observation],
    start: &ErrorParams,
    free: &[usize],
    opts: &FitOptions,
) -> Result<FitResult, FitError> {
    let mut problem = Problem::new(robot, obs, None, free, opts.prior.as_ref());
    problem.check_size()?;
    let before = ResidualStats::of(&problem.errors(start));
    problem.solve(start.clone(), None, before, opts)
}

/// Position errors (measured − modelled) of a parameter set over observations.
pub fn errors(robot: &dyn Robot, obs: &[Observation], e: &ErrorParams) -> Vec<Vector3<f64>> {
    let k = Kinematics::at(robot, e);
    obs.iter().map(|o| o.p - k.position(&o.q)).collect()
}

/// The Gauss–Newton normal equations of a fit at one parameter set: JᵀJ, Jᵀr and the cost
/// rᵀr, prior rows included.
#[derive(Debug, Clone)]
pub(crate) struct NormalEquations {
    /// JᵀJ (p × p).
    pub(crate) jtj: DMatrix<f64>,
    /// Jᵀr.
    pub(crate) jtr: DVector<f64>,
    /// rᵀr.
    pub(crate) cost: f64,
    /// How far rounding in the modelled positions moves rᵀr: a step predicted to lower the
    /// cost by less cannot be told from no step.
    pub(crate) rounding: f64,
}

impl NormalEquations {
    /// Adds (sign +1) or removes (sign −1) one observation's rows: columns `cols`, residual `r`.
    pub(crate) fn add_rows(&mut self, cols: &[Vector3<f64>], r: &Vector3<f64>, sign: f64) {
        let p = cols.len();
        for a in 0..p {
            let ca = cols[a];
            self.jtr[a] += sign * ca.dot(r);
            for (b, cb) in cols.iter().enumerate().skip(a) {
                self.jtj[(a, b)] += sign * ca.dot(cb);
            }
        }
        self.cost += sign * r.norm_squared();
    }

    /// Copies the upper triangle to the lower.
    pub(crate) fn symmetrise(&mut self) {
        let p = self.jtr.len();
        for a in 0..p {
            for b in a + 1..p {
                self.jtj[(b, a)] = self.jtj[(a, b)];
            }
        }
    }
}

/// Joint values closer than this (rad or mm) in every joint are one pose.
const SAME_POSE: f64 = 1e-9;

/// The number of distinct joint vectors among `poses` (equal within [`SAME_POSE`] in every
/// joint), counted on them sorted.
pub(crate) fn distinct_poses(mut poses: Vec<&[f64]>) -> usize {
    let cmp = |a: &&[f64], b: &&[f64]| {
        a.iter()
            .zip(b.iter())
            .map(|(x, y)| x.total_cmp(y))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    };
    poses.sort_by(cmp);
    let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= SAME_POSE);
    poses
        .iter()
        .enumerate()
        .filter(|(k, q)| *k == 0 || !same(poses[k - 1], q))
        .count()
}

/// Relative rounding error of a modelled position (a dozen rigid products and the
/// subtraction), in units of ε: what [`NormalEquations::rounding`] assumes.
const POSITION_ULPS: f64 = 32.0;

/// Most parameters a fit evaluates on the stack; more use the heap.
const STACK_COLUMNS: usize = 64;

/// One least-squares problem: observations (all, or the rows `subset`), the parameters fitted
/// and the prior. Each pass over the observations evaluates the robot once per row without
/// allocating: the joints' sines and cosines are computed once, the data rows of J go into one
/// buffer reused by every pass, and JᵀJ, Jᵀr come from it in one product each.
pub(crate) struct Problem<'a> {
    robot: &'a dyn Robot,
    obs: &'a [Observation],
    subset: Option<&'a [usize]>,
    free: &'a [usize],
    prior: Option<&'a Prior>,
    /// [sin q, cos q] of every joint of every fitted row, `dof` entries per row (serial chains).
    trig: Vec<[f64; 2]>,
    dof: usize,
    /// Data rows of J (3 per fitted row) at the last pass.
    jacobian: DMatrix<f64>,
    /// Residuals (3 per fitted row) at the last pass.
    residual: DVector<f64>,
}

impl<'a> Problem<'a> {
    /// The problem of fitting `free` to `obs` (or its rows `subset`, increasing).
    pub(crate) fn new(
        robot: &'a dyn Robot,
        obs: &'a [Observation],
        subset: Option<&'a [usize]>,
        free: &'a [usize],
        prior: Option<&'a Prior>,
    ) -> Self {
        let mut problem = Self {
            robot,
            obs,
            subset,
            free,
            prior,
            trig: Vec::new(),
            dof: robot.dof(),
            jacobian: DMatrix::zeros(0, 0),
            residual: DVector::zeros(0),
        };
        if robot.as_serial_chain().is_some() {
            let dof = problem.dof;
            let mut trig = vec![[0.0; 2]; dof * problem.rows()];
            let mut k = 0;
            problem.for_each_obs(|o| {
                joint_trig(&o.q, &mut trig[k * dof..(k + 1) * dof]);
                k += 1;
            });
            problem.trig = trig;
        }
        problem
    }

    fn rows(&self) -> usize {
        self.subset.map_or(self.obs.len(), <[usize]>::len)
    }

    fn for_each_obs(&self, mut f: impl FnMut(&Observation)) {
        match self.subset {
            Some(rows) => rows.iter().for_each(|&i| f(&self.obs[i])),
            None => self.obs.iter().for_each(f),
        }
    }

    /// Refuses fewer equations than unknowns + 1, counting a pose measured many times once:
    /// repeats measure the noise, not the parameters.
    pub(crate) fn check_size(&self) -> Result<(), FitError> {
        let p = self.free.len();
        let rows = 3 * self.rows();
        if rows < p + 1 {
            return Err(FitError::TooFewObservations {
                observations: self.rows(),
                rows,
                unknowns: p,
                needed: p / 3 + 1,
            });
        }
        let poses: Vec<&[f64]> = match self.subset {
            Some(rows) => rows.iter().map(|&i| self.obs[i].q.as_slice()).collect(),
            None => self.obs.iter().map(|o| o.q.as_slice()).collect(),
        };
        let distinct = distinct_poses(poses);
        if 3 * distinct < p + 1 {
            return Err(FitError::PosesDoNotSpread {
                observations: self.rows(),
                distinct,
                unknowns: p,
                needed: p / 3 + 1,
            });
        }
        Ok(())
    }

    /// Calls `f(k, observation, its joints' trig)` for each fitted row k, the kinematics at `e`.
    fn for_each_row(
        &self,
        e: &ErrorParams,
        mut f: impl FnMut(usize, &Kinematics<'_>, &Observation, Option<&[[f64; 2]]>),
    ) {
        let kin = Kinematics::at(self.robot, e);
        let dof = self.dof;
        let mut k = 0;
        self.for_each_obs(|o| {
            let trig = (!self.trig.is_empty()).then(|| &self.trig[k * dof..(k + 1) * dof]);
            f(k, &kin, o, trig);
            k += 1;
        });
    }

    /// Position errors of the fitted rows at `e`.
    pub(crate) fn errors(&self, e: &ErrorParams) -> Vec<Vector3<f64>> {
        let mut out = Vec::with_capacity(self.rows());
        self.for_each_row(e, |_, kin, o, trig| {
            out.push(o.p - kin.position_trig(&o.q, trig));
        });
        out
    }

    /// rᵀr at `e`, prior rows included.
    fn cost(&self, e: &ErrorParams) -> f64 {
        let mut c = 0.0;
        self.for_each_row(e, |_, kin, o, trig| {
            c += (o.p - kin.position_trig(&o.q, trig)).norm_squared();
        });
        c + self.prior_cost(e)
    }

    fn prior_cost(&self, e: &ErrorParams) -> f64 {
        let Some(prior) = self.prior else { return 0.0 };
        self.free
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let w = prior.weight.get(k).copied().unwrap_or(0.0);
                (w * (prior.mean.get(i) - e.get(i))).powi(2)
            })
            .sum()
    }

    fn add_prior(&self, n: &mut NormalEquations, e: &ErrorParams) {
        let Some(prior) = self.prior else { return };
        for (k, &i) in self.free.iter().enumerate() {
            let w = prior.weight.get(k).copied().unwrap_or(0.0);
            let r = w * (prior.mean.get(i) - e.get(i));
            n.jtj[(k, k)] += w * w;
            n.jtr[k] += w * r;
            n.cost += r * r;
        }
    }

    /// The normal equations at `e`; the data rows of J and the residuals stay in the buffers.
    pub(crate) fn normal(&mut self, e: &ErrorParams) -> NormalEquations {
        let p = self.free.len();
        let m = self.rows();
        let mut jacobian = std::mem::replace(&mut self.jacobian, DMatrix::zeros(0, 0));
        let mut residual = std::mem::replace(&mut self.residual, DVector::zeros(0));
        if jacobian.shape() != (3 * m, p) {
            jacobian = DMatrix::zeros(3 * m, p);
            residual = DVector::zeros(3 * m);
        }
        let mut stack = [Vector3::zeros(); STACK_COLUMNS];
        let mut heap = Vec::new();
        let cols: &mut [Vector3<f64>] = if p <= STACK_COLUMNS {
            &mut stack[..p]
        } else {
            heap.resize(p, Vector3::zeros());
            &mut heap
        };
        let mut scale = 0.0;
        self.for_each_row(e, |k, kin, o, trig| {
            let r = o.p - kin.position_and_columns_trig(&o.q, trig, self.free, cols);
            scale += r.norm() * o.p.norm();
            residual.fixed_rows_mut::<3>(3 * k).copy_from(&r);
            for (c, col) in cols.iter().enumerate() {
                jacobian.fixed_view_mut::<3, 1>(3 * k, c).copy_from(col);
            }
        });
        let mut n = NormalEquations {
            jtj: gram(&jacobian),
            jtr: transpose_times(&jacobian, &residual),
            cost: residual.norm_squared(),
            // d(rᵀr) = 2 rᵀ dr, each modelled coordinate good to a few dozen ulps of its size.
            rounding: 2.0 * POSITION_ULPS * f64::EPSILON * scale,
        };
        self.add_prior(&mut n, e);
        self.jacobian = jacobian;
        self.residual = residual;
        n
    }

    /// Levenberg–Marquardt from `start` (see the module docs); `normal` are the normal equations
    /// at `start` when the caller has them (a refit after removing rows), `before` the residual
    /// statistics reported as the start's.
    pub(crate) fn solve(
        &mut self,
        start: ErrorParams,
        normal: Option<NormalEquations>,
        before: ResidualStats,
        opts: &FitOptions,
    ) -> Result<FitResult, FitError> {
        self.solve_keeping_normal(start, normal, before, opts)
            .map(|(fit, _)| fit)
    }

    /// [`Problem::solve`], also returning the normal equations at the solution (for a later
    /// refit without some rows to downdate).
    pub(crate) fn solve_keeping_normal(
        &mut self,
        start: ErrorParams,
        normal: Option<NormalEquations>,
        before: ResidualStats,
        opts: &FitOptions,
    ) -> Result<(FitResult, NormalEquations), FitError> {
        let mut e = start;
        // Whether `n` and the pass buffers are at `e` (no step taken since the last pass); normal
        // equations from the caller come without the buffers.
        let mut current = normal.is_none();
        let mut n = match normal {
            Some(n) => n,
            None => self.normal(&e),
        };
        let mut cost = n.cost;
        let mut lambda = 1e-4;
        let mut iterations = 0;
        for _ in 0..opts.max_iterations {
            iterations += 1;
            let (d, a, g) = scaled_normal_equations(&n.jtj, &n.jtr);
            let mut improved = false;
            let mut converged = false;
            let mut step_norm = 0.0;
            for _ in 0..12 {
                let Some(ds) = damped_step(&a, &g, lambda) else {
                    lambda *= 10.0;
                    continue;
                };
                step_norm = ds.norm();
                // rᵀr − |r − J·δ|² of the linearised model: what the step can gain at most.
                let predicted = 2.0 * g.dot(&ds) - ds.dot(&(&a * &ds));
                if predicted <= n.rounding {
                    // The step cannot lower the cost by more than rounding moves it: the
                    // minimum is reached as far as double precision tells (more damping only
                    // shortens the step).
                    converged = true;
                    break;
                }
                let mut trial = e.clone();
                for (k, &i) in self.free.iter().enumerate() {
                    trial.set(i, trial.get(i) + ds[k] / d[k]);
                }
                let c_trial = self.cost(&trial);
                if c_trial <= cost {
                    e = trial;
                    cost = c_trial;
                    current = false;
                    lambda = (lambda * 0.2).max(1e-12);
                    improved = true;
                    break;
                }
                lambda *= 10.0;
            }
            if converged || !improved || step_norm < opts.step_tolerance {
                break;
            }
            n = self.normal(&e);
            current = true;
        }
        if !current {
            n = self.normal(&e);
        }
        self.finish(e, n, before, iterations)
    }

    /// σ, covariance, κ and residuals at the solution.
    /// `normal` and the pass buffers are at `e`.
    fn finish(
        &mut self,
        e: ErrorParams,
        normal: NormalEquations,
        before: ResidualStats,
        iterations: usize,
    ) -> Result<(FitResult, NormalEquations), FitError> {
        let p = self.free.len();
        let kappa = match self.prior {
            None => kappa_from_normal(&normal.jtj),
            Some(_) => None,
        }
        .unwrap_or_else(|| kappa_eq4(&self.jacobian));
        let Some(inv) = normal
            .jtj
            .clone()
            .try_inverse()
            .filter(|m| m.iter().all(|v| v.is_finite()))
        else {
            return Err(FitError::Singular { kappa });
        };
        // Degrees of freedom of the data rows only: the prior's rows are not measurements.
        let dof = (3 * self.rows()).saturating_sub(p).max(1) as f64;
        let rss = self.residual.norm_squared();
        let s2 = rss / dof;
        let covariance = inv * s2;
        let sigma = (0..p).map(|k| covariance[(k, k)].max(0.0).sqrt()).collect();
        let residuals: Vec<Vector3<f64>> = (0..self.rows())
            .map(|k| self.residual.fixed_rows::<3>(3 * k).into_owned())
            .collect();
        let fit = FitResult {
            params: e,
            free: self.free.to_vec(),
            sigma,
            covariance,
            kappa,
            before,
            after: ResidualStats::of(&residuals),
            sigma0_mm: s2.sqrt(),
            iterations,
            residuals,
            undetermined: Vec::new(),
        };
        Ok((fit, normal))
    }
}

/// Largest κ taken from JᵀJ's eigenvalues: rounding in forming JᵀJ moves κ by about n·ε·κ,
/// under 1e-9 relative below this; larger κ go through the QR factor of J.
const GRAM_KAPPA_MAX: f64 = 1e6;

/// κ of eq. (4) from JᵀJ itself (eq. (4) is defined on it): the eigenvalue ratio of the
/// column-scaled JᵀJ, when it is small enough for that to be exact to 1e-9.
fn kappa_from_normal(jtj: &DMatrix<f64>) -> Option<f64> {
    let p = jtj.nrows();
    if p == 0 {
        return None;
    }
    let d: Vec<f64> = (0..p).map(|c| jtj[(c, c)].sqrt()).collect();
    if d.iter().any(|&v| v.is_nan() || v <= 0.0 || !v.is_finite()) {
        return None;
    }
    let scaled = DMatrix::from_fn(p, p, |r, c| jtj[(r, c)] / (d[r] * d[c]));
    let eig = scaled.symmetric_eigenvalues();
    let (max, min) = (eig.max(), eig.min());
    let kappa = max / min;
    (min > 0.0 && kappa < GRAM_KAPPA_MAX).then_some(kappa)
}

/// The normal equations JᵀJ·δ = Jᵀr scaled to a unit diagonal (Marquardt's scaling, so that
/// the damping treats millimetres and radians alike): the column scales d, JᵀJ/(d·dᵀ) and Jᵀr/d.
/// The step in the original units is δ_k = δs_k / d_k.
pub(crate) fn scaled_normal_equations(
    jtj: &DMatrix<f64>,
    jtr: &DVector<f64>,
) -> (Vec<f64>, DMatrix<f64>, DVector<f64>) {
    let p = jtj.nrows();
    let d: Vec<f64> = (0..p).map(|c| jtj[(c, c)].sqrt().max(1e-300)).collect();
    let a = DMatrix::from_fn(p, p, |r, c| jtj[(r, c)] / (d[r] * d[c]));
    let g = DVector::from_fn(p, |r, _| jtr[r] / d[r]);
    (d, a, g)
}

/// The Levenberg–Marquardt step of scaled normal equations `a`·δs = `g` with the diagonal
/// damped by `lambda` (relative to itself); None when the damped matrix is not positive
/// definite (the caller raises `lambda`).
pub(crate) fn damped_step(a: &DMatrix<f64>, g: &DVector<f64>, lambda: f64) -> Option<DVector<f64>> {
    let mut damped = a.clone();
    for k in 0..a.nrows() {
        damped[(k, k)] += lambda * a[(k, k)].max(1e-12);
    }
    damped.cholesky().map(|chol| chol.solve(g))
}
