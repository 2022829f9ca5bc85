//! Least-squares identification: Levenberg–Marquardt with column scaling.
//!
//! Residual r = measured − modelled position (mm), stacked over observations. Each step solves
//! (JsᵀJs + λ·diag(JsᵀJs)) δs = Jsᵀr with Js = J·D⁻¹, D the column norms, so millimetres and
//! radians are treated alike. At the solution the covariance is σ̂²(JᵀJ)⁻¹ with
//! σ̂² = RSS / (3m − p).

use super::identifiability::kappa_eq4;
use crate::kinematics::{ChainAt, ErrorParams, Robot};
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
    let problem = Problem::new(robot, obs, None, free, opts.prior.as_ref());
    problem.check_size()?;
    let before = ResidualStats::of(&problem.errors(start));
    problem.solve(start.clone(), None, before, opts)
}

/// Position errors (measured − modelled) of a parameter set over observations.
pub fn errors(robot: &dyn Robot, obs: &[Observation], e: &ErrorParams) -> Vec<Vector3<f64>> {
    let k = Kinematics::at(robot, e);
    obs.iter().map(|o| o.p - k.position(&o.q)).collect()
}

/// A robot at fixed error parameters: a serial chain multiplied out ([`ChainAt`]), any other
/// robot through its [`Robot`] methods.
pub(crate) enum Kinematics<'a> {
    /// A serial chain, allocation-free.
    Chain(ChainAt),
    /// Any robot.
    Generic(&'a dyn Robot, ErrorParams),
}

impl<'a> Kinematics<'a> {
    /// `robot` at parameters `e`.
    pub(crate) fn at(robot: &'a dyn Robot, e: &ErrorParams) -> Self {
        match robot.as_serial_chain() {
            Some(chain) => Kinematics::Chain(chain.at(e)),
            None => Kinematics::Generic(robot, e.clone()),
        }
    }

    /// The measured point at joint values `q`.
    pub(crate) fn position(&self, q: &[f64]) -> Vector3<f64> {
        match self {
            Kinematics::Chain(c) => c.position(q),
            Kinematics::Generic(r, e) => r.position(q, e),
        }
    }

    /// The measured point and the Jacobian columns of the layout indices `columns` in `out`.
    pub(crate) fn position_and_columns(
        &self,
        q: &[f64],
        columns: &[usize],
        out: &mut [Vector3<f64>],
    ) -> Vector3<f64> {
        match self {
            Kinematics::Chain(c) => c.position_and_columns(q, columns, out),
            Kinematics::Generic(r, e) => {
                let (p, m) = r.position_and_param_jacobian(q, e);
                for (o, &i) in out.iter_mut().zip(columns) {
                    *o = m.fixed_view::<3, 1>(0, i).into_owned();
                }
                p
            }
        }
    }
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
}

impl NormalEquations {
    fn zeros(p: usize) -> Self {
        Self {
            jtj: DMatrix::zeros(p, p),
            jtr: DVector::zeros(p),
            cost: 0.0,
        }
    }

    /// Adds (sign +1) or removes (sign −1) one observation's rows: columns `cols`, residual `r`.
    pub(crate) fn add_rows(&mut self, cols: &[Vector3<f64>], r: &Vector3<f64>, sign: f64) {
        let p = cols.len();
        for a in 0..p {
            let ca = cols[a];
            self.jtr[a] += sign * ca.dot(r);
            for b in a..p {
                self.jtj[(a, b)] += sign * ca.dot(&cols[b]);
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

/// Most parameters a fit evaluates on the stack; more use the heap.
const STACK_COLUMNS: usize = 64;

/// One least-squares problem: observations (all, or the rows `subset`), the parameters fitted
/// and the prior. Each pass over the observations evaluates the robot once per row, without
/// allocating per row.
pub(crate) struct Problem<'a> {
    robot: &'a dyn Robot,
    obs: &'a [Observation],
    subset: Option<&'a [usize]>,
    free: &'a [usize],
    prior: Option<&'a Prior>,
}

/// What the last pass of a fit keeps: residuals, the data rows of J and the normal equations.
struct FinalPass {
    residuals: Vec<Vector3<f64>>,
    jacobian: DMatrix<f64>,
    normal: NormalEquations,
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
        Self {
            robot,
            obs,
            subset,
            free,
            prior,
        }
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

    /// Refuses fewer equations than unknowns + 1.
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
        Ok(())
    }

    /// Position errors of the fitted rows at `e`.
    pub(crate) fn errors(&self, e: &ErrorParams) -> Vec<Vector3<f64>> {
        let k = Kinematics::at(self.robot, e);
        let mut out = Vec::with_capacity(self.rows());
        self.for_each_obs(|o| out.push(o.p - k.position(&o.q)));
        out
    }

    /// rᵀr at `e`, prior rows included.
    fn cost(&self, e: &ErrorParams) -> f64 {
        let k = Kinematics::at(self.robot, e);
        let mut c = 0.0;
        self.for_each_obs(|o| c += (o.p - k.position(&o.q)).norm_squared());
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

    /// One pass at `e` calling `row(cols, residual)` per observation, then the normal equations.
    fn pass(
        &self,
        e: &ErrorParams,
        mut row: impl FnMut(&[Vector3<f64>], &Vector3<f64>),
    ) -> NormalEquations {
        let p = self.free.len();
        let k = Kinematics::at(self.robot, e);
        let mut stack = [Vector3::zeros(); STACK_COLUMNS];
        let mut heap = Vec::new();
        let cols: &mut [Vector3<f64>] = if p <= STACK_COLUMNS {
            &mut stack[..p]
        } else {
            heap.resize(p, Vector3::zeros());
            &mut heap
        };
        let mut n = NormalEquations::zeros(p);
        self.for_each_obs(|o| {
            let r = o.p - k.position_and_columns(&o.q, self.free, cols);
            n.add_rows(cols, &r, 1.0);
            row(cols, &r);
        });
        self.add_prior(&mut n, e);
        n.symmetrise();
        n
    }

    /// The normal equations at `e`.
    pub(crate) fn normal(&self, e: &ErrorParams) -> NormalEquations {
        self.pass(e, |_, _| {})
    }

    /// The last pass: normal equations, residuals and the data rows of J.
    fn final_pass(&self, e: &ErrorParams) -> FinalPass {
        let m = self.rows();
        let mut residuals = Vec::with_capacity(m);
        let mut jacobian = DMatrix::zeros(3 * m, self.free.len());
        let normal = self.pass(e, |cols, r| {
            let k = residuals.len();
            for (c, col) in cols.iter().enumerate() {
                jacobian.fixed_view_mut::<3, 1>(3 * k, c).copy_from(col);
            }
            residuals.push(*r);
        });
        FinalPass {
            residuals,
            jacobian,
            normal,
        }
    }

    /// Levenberg–Marquardt from `start` (see the module docs); `normal` are the normal equations
    /// at `start` when the caller has them (a refit after removing rows), `before` the residual
    /// statistics reported as the start's.
    pub(crate) fn solve(
        &self,
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
        &self,
        start: ErrorParams,
        normal: Option<NormalEquations>,
        before: ResidualStats,
        opts: &FitOptions,
    ) -> Result<(FitResult, NormalEquations), FitError> {
        let p = self.free.len();
        let mut e = start;
        let mut n = normal.unwrap_or_else(|| self.normal(&e));
        let mut cost = n.cost;
        let mut lambda = 1e-4;
        let mut iterations = 0;
        for _ in 0..opts.max_iterations {
            iterations += 1;
            let d: Vec<f64> = (0..p).map(|c| n.jtj[(c, c)].sqrt().max(1e-300)).collect();
            let a = DMatrix::from_fn(p, p, |r, c| n.jtj[(r, c)] / (d[r] * d[c]));
            let g = DVector::from_fn(p, |r, _| n.jtr[r] / d[r]);
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
                for (k, &i) in self.free.iter().enumerate() {
                    trial.set(i, trial.get(i) + ds[k] / d[k]);
                }
                let c_trial = self.cost(&trial);
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
            n = self.normal(&e);
        }
        self.finish(e, before, iterations)
    }

    /// σ, covariance, κ and residuals at the solution.
    fn finish(
        &self,
        e: ErrorParams,
        before: ResidualStats,
        iterations: usize,
    ) -> Result<(FitResult, NormalEquations), FitError> {
        let p = self.free.len();
        let last = self.final_pass(&e);
        let kappa = kappa_eq4(&last.jacobian);
        let Some(inv) = last
            .normal
            .jtj
            .clone()
            .try_inverse()
            .filter(|m| m.iter().all(|v| v.is_finite()))
        else {
            return Err(FitError::Singular { kappa });
        };
        // Degrees of freedom of the data rows only: the prior's rows are not measurements.
        let dof = (3 * self.rows()).saturating_sub(p).max(1) as f64;
        let rss: f64 = last.residuals.iter().map(|r| r.norm_squared()).sum();
        let s2 = rss / dof;
        let covariance = inv * s2;
        let sigma = (0..p).map(|k| covariance[(k, k)].max(0.0).sqrt()).collect();
        let fit = FitResult {
            params: e,
            free: self.free.to_vec(),
            sigma,
            covariance,
            kappa,
            before,
            after: ResidualStats::of(&last.residuals),
            sigma0_mm: s2.sqrt(),
            iterations,
            residuals: last.residuals,
        };
        Ok((fit, last.normal))
    }
}
