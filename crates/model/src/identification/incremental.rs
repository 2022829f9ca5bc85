//! Refits of one recording's geometric model without some of its rows: the mechanics of the
//! outlier search ([`super::outliers`] decides which rows go).
//!
//! A refit without a few rows of a fit that has just converged starts where that fit ended:
//! the removed rows' contributions are subtracted from its normal equations (a rank-3
//! downdate per measurement), which is the first Levenberg–Marquardt step of a refit from
//! that start without another pass over the data, and the iteration continues to the same
//! tolerance as a fit from the nominal parameters. The least-squares minimum does not depend on
//! the start, so parameters, σ, κ and residuals equal those of a refit from scratch up to
//! the fit's tolerance; only the iteration count is smaller. That holds when the last fit was
//! near the minimum of the kept rows; a gross row drags it far off (degrees, metres), where the
//! kept rows' cost has other minima — a refit that ends above the nominal parameters' residual
//! is therefore redone from the nominal parameters.
//!
//! The identifiability analysis of the kept rows is repeated exactly, on the triangular factor
//! of \[M\] at the nominal parameters ([`super::identifiability`] decides on it). \[M\] is computed
//! once for every row and factored in blocks of poses; the factor of the kept rows is the
//! factor of the stacked block factors (a tall-skinny QR), so removing a row refactors its
//! block and the small stack only. When the basis changes the refit starts from the nominal
//! parameters, as from scratch.
//!
//! With a free measurement frame the fit starts from a closed-form registration of the kept
//! rows, which moves with them: such refits run from scratch ([`super::identify_at`]).

use super::fit::{NormalEquations, Problem};
use super::geometric::{against_a_spread_design, identify_at, IdentifyError, Level};
use super::identifiability::{determined_factor, stacked_jacobian, triangular_factor};
use super::{FitOptions, FitResult, ResidualStats};
use nalgebra::{DMatrix, Vector3};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};
use rigcal_core::recording::Observation;
use rigcal_core::rig::{FrameMode, Rig};

/// Refits of a rig's geometry at a level to subsets of one set of observations (see the module
/// docs).
pub struct GeometricRefits<'a> {
    rig: &'a Rig,
    obs: &'a [Observation],
    level: Level,
    candidates: Vec<usize>,
    /// \[M\] at the nominal parameters in factored blocks; `None` when refits run from scratch
    /// (a free frame).
    factors: Option<BlockFactors>,
    /// Position errors of every row at the nominal parameters: a refit's "before".
    nominal_errors: Vec<Vector3<f64>>,
    last: Option<LastFit>,
}

/// What the next refit starts from.
struct LastFit {
    kept: Vec<usize>,
    basis: Vec<usize>,
    params: ErrorParams,
    normal: NormalEquations,
}

impl<'a> GeometricRefits<'a> {
    /// Refits of `rig` at `level` to subsets of `obs`.
    pub fn new(rig: &'a Rig, obs: &'a [Observation], level: Level) -> Self {
        let candidates = level.candidates(rig);
        let incremental = rig.calibration.measurement_frame != FrameMode::Free;
        let nominal = ErrorParams::zeros(rig.chain.layout());
        let factors = incremental.then(|| {
            let poses: Vec<Vec<f64>> = obs.iter().map(|o| o.q.clone()).collect();
            BlockFactors::new(stacked_jacobian(&rig.chain, &nominal, &poses, &candidates))
        });
        let nominal_errors = if incremental {
            super::errors(&rig.chain, obs, &nominal)
        } else {
            Vec::new()
        };
        Self {
            rig,
            obs,
            level,
            candidates,
            factors,
            nominal_errors,
            last: None,
        }
    }

    /// The fit on the rows `kept` (increasing indices into the observations): the rig's chain
    /// and the fit with absolute frame parameters, as [`identify_at`] on those rows gives them.
    pub fn fit(&mut self, kept: &[usize]) -> Result<(SerialChain, FitResult), IdentifyError> {
        let Some(factors) = &mut self.factors else {
            let fitted: Vec<Observation> = kept.iter().map(|&i| self.obs[i].clone()).collect();
            return identify_at(self.rig, &fitted, self.level);
        };
        if kept.is_empty() {
            return Err(IdentifyError::NoMeasurements);
        }
        if self.candidates.is_empty() {
            return Err(IdentifyError::NothingToFit { level: self.level });
        }
        let analysis = determined_factor(
            &factors.factor(kept),
            kept.len(),
            &self.candidates,
            self.rig.chain.layout(),
        );
        let basis = analysis.basis;
        let chain = &self.rig.chain;
        let mut problem = Problem::new(chain, self.obs, Some(kept), &basis, None);
        problem.check_size().map_err(|e| {
            IdentifyError::Fit(against_a_spread_design(
                self.rig,
                chain,
                &self.candidates,
                e,
            ))
        })?;
        let before = ResidualStats::of(
            &kept
                .iter()
                .map(|&i| self.nominal_errors[i])
                .collect::<Vec<_>>(),
        );
        let from_last = match self.last.take() {
            Some(last)
                if last.basis == basis
                    && is_subset(kept, &last.kept)
                    && self.within_bounds(&last) =>
            {
                let normal = downdate(chain, self.obs, &last, kept);
                Some((last.params, normal))
            }
            _ => None,
        };
        let opts = FitOptions::default();
        let mut solved = match from_last {
            Some((start, normal)) => {
                problem.solve_keeping_normal(start, Some(normal), before, &opts)
            }
            None => problem.solve_keeping_normal(
                ErrorParams::zeros(chain.layout()),
                None,
                before,
                &opts,
            ),
        }
        .map_err(IdentifyError::Fit)?;
        if worse_than_nominal(&solved.0) {
            // The last fit had chased the removed rows away from the nominal parameters; from
            // there the kept rows' cost has other, worse minima than the one near the nominal
            // values, and the refit stayed in one. Start again from the nominal parameters, as
            // a fit from scratch.
            tracing::debug!(
                after_mm = solved.0.after.rms_mm,
                nominal_mm = before.rms_mm,
                "refit from the last fit ended above the nominal residual: refitting from nominal"
            );
            solved = problem
                .solve_keeping_normal(ErrorParams::zeros(chain.layout()), None, before, &opts)
                .map_err(IdentifyError::Fit)?;
        }
        let (mut fit, normal) = solved;
        fit.undetermined = analysis.undetermined;
        self.last = Some(LastFit {
            kept: kept.to_vec(),
            basis,
            params: fit.params.clone(),
            normal,
        });
        Ok((chain.clone(), fit))
    }
}

/// \[M\] of every observation (3 rows each) in blocks of poses, each with the triangular factor
/// of its kept rows.
struct BlockFactors {
    m: DMatrix<f64>,
    /// Per block: the end of its range of observations (exclusive), the kept observations it
    /// was factored for, and the factor.
    blocks: Vec<(usize, Vec<usize>, DMatrix<f64>)>,
}

impl BlockFactors {
    fn new(m: DMatrix<f64>) -> Self {
        let n = m.nrows() / 3;
        // About √(p·n/3) poses a block balance refactoring a block against the stack.
        let size = ((m.ncols() * n) as f64 / 3.0).sqrt().ceil().max(1.0) as usize;
        let blocks = (0..n)
            .step_by(size)
            .map(|start| {
                let end = (start + size).min(n);
                let rows: Vec<usize> = (start..end).collect();
                let r = triangular_factor(select_rows(&m, &rows));
                (end, rows, r)
            })
            .collect();
        Self { m, blocks }
    }

    /// A factor R with RᵀR = \[M\]ᵀ\[M\] over the observations `kept` (increasing).
    fn factor(&mut self, kept: &[usize]) -> DMatrix<f64> {
        let mut rest = kept;
        let mut stacked_rows = 0;
        for (end, rows, r) in &mut self.blocks {
            let take = rest.partition_point(|&i| i < *end);
            let (here, after) = rest.split_at(take);
            rest = after;
            if here != rows.as_slice() {
                *rows = here.to_vec();
                *r = triangular_factor(select_rows(&self.m, here));
            }
            stacked_rows += r.nrows();
        }
        let mut stack = DMatrix::zeros(stacked_rows, self.m.ncols());
        let mut at = 0;
        for (_, _, r) in &self.blocks {
            stack.rows_mut(at, r.nrows()).copy_from(r);
            at += r.nrows();
        }
        triangular_factor(stack)
    }
}

/// The rows of \[M\] (3 per observation) of the observations `kept`.
fn select_rows(m: &DMatrix<f64>, kept: &[usize]) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(3 * kept.len(), m.ncols());
    for c in 0..m.ncols() {
        let src = m.column(c);
        let mut dst = out.column_mut(c);
        for (k, &i) in kept.iter().enumerate() {
            dst.fixed_rows_mut::<3>(3 * k)
                .copy_from(&src.fixed_rows::<3>(3 * i));
        }
    }
    out
}

impl GeometricRefits<'_> {
    /// Whether the last fit's parameters lie within the rig's bounds on corrections
    /// ([`super::checks::check_parameters`]). A gross row drags a fit by degrees or metres, to
    /// where the kept rows' cost has other minima — worse ones, or equivalent descriptions of
    /// the same arm with joints turned half a turn and lengths negated — so a refit starts
    /// from there only when the last fit stayed physical.
    fn within_bounds(&self, last: &LastFit) -> bool {
        super::checks::check_parameters(self.rig, &self.rig.chain, &last.params, &last.basis)
            .is_ok()
    }
}

/// True when a fit ended with a larger residual than the nominal parameters give: it did not
/// start in the nominal parameters' basin (a fit from them never ends above them).
fn worse_than_nominal(fit: &FitResult) -> bool {
    fit.after.rms_mm > fit.before.rms_mm * (1.0 + 1e-9)
}

/// True when every element of `a` (increasing) is in `b` (increasing).
fn is_subset(a: &[usize], b: &[usize]) -> bool {
    let mut it = b.iter();
    a.iter().all(|x| it.any(|y| y == x))
}

/// The last fit's normal equations without the rows it kept that `kept` drops.
fn downdate(
    chain: &SerialChain,
    obs: &[Observation],
    last: &LastFit,
    kept: &[usize],
) -> NormalEquations {
    let mut normal = last.normal.clone();
    let k = chain.at(&last.params);
    let mut cols = vec![Vector3::zeros(); last.basis.len()];
    let mut next = kept.iter().peekable();
    for &i in &last.kept {
        if next.peek() == Some(&&i) {
            next.next();
            continue;
        }
        let o = &obs[i];
        let r = o.p - k.position_and_columns(&o.q, &last.basis, &mut cols);
        normal.add_rows(&cols, &r, -1.0);
    }
    normal.symmetrise();
    normal
}
