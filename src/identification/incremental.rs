//! Refits of one recording's geometric model without some of its rows: the mechanics of the
//! outlier search ([`super::outliers`] decides which rows go).
//!
//! A refit without a few rows of a fit that has just converged starts where that fit ended:
//! the removed rows' contributions are subtracted from its normal equations (a rank-3
//! downdate per measurement), which is the first Levenberg–Marquardt step of a refit from
//! that start without another pass over the data, and the iteration continues to the same
//! tolerance as a fit from the nominal parameters. The least-squares minimum does not depend on
//! the start, so parameters, σ, κ and residuals equal those of a refit from scratch up to
//! the fit's tolerance; only the iteration count is smaller. The identifiability analysis of the
//! kept rows is repeated exactly, on [M] at the nominal parameters computed once for every row;
//! when its basis changes the refit starts from the nominal parameters, as from scratch.
//!
//! With a free measurement frame the fit starts from a closed-form registration of the kept
//! rows, which moves with them: such refits run from scratch ([`super::identify_at`]).

use super::fit::{NormalEquations, Problem};
use super::geometric::Level;
use super::identifiability::{analyse_jacobian, stacked_jacobian};
use super::pipeline::{identify_at, IdentifyError};
use super::{FitOptions, FitResult, ResidualStats};
use crate::kinematics::{ErrorParams, Robot, SerialChain};
use crate::recording::Observation;
use crate::rig::{FrameMode, Rig};
use nalgebra::{DMatrix, Vector3};

/// Refits of a rig's geometry at a level to subsets of one set of observations (see the module
/// docs).
pub struct GeometricRefits<'a> {
    rig: &'a Rig,
    obs: &'a [Observation],
    level: Level,
    candidates: Vec<usize>,
    /// [M] at the nominal parameters, every row (3 per observation), candidate columns; `None`
    /// when refits run from scratch (a free frame).
    nominal_jacobian: Option<DMatrix<f64>>,
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
        let nominal_jacobian = incremental.then(|| {
            let poses: Vec<Vec<f64>> = obs.iter().map(|o| o.q.clone()).collect();
            stacked_jacobian(&rig.chain, &nominal, &poses, &candidates)
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
            nominal_jacobian,
            nominal_errors,
            last: None,
        }
    }

    /// The fit on the rows `kept` (increasing indices into the observations): the rig's chain
    /// and the fit with absolute frame parameters, as [`identify_at`] on those rows gives them.
    pub fn fit(&mut self, kept: &[usize]) -> Result<(SerialChain, FitResult), IdentifyError> {
        let Some(m) = &self.nominal_jacobian else {
            let fitted: Vec<Observation> = kept.iter().map(|&i| self.obs[i].clone()).collect();
            return identify_at(self.rig, &fitted, self.level);
        };
        if kept.is_empty() {
            return Err(IdentifyError::NoMeasurements);
        }
        if self.candidates.is_empty() {
            return Err(IdentifyError::NothingToFit { level: self.level });
        }
        let basis = if kept.len() == self.obs.len() {
            analyse_jacobian(m, &self.candidates).basis
        } else {
            analyse_jacobian(&select_rows(m, kept), &self.candidates).basis
        };
        let chain = &self.rig.chain;
        let problem = Problem::new(chain, self.obs, Some(kept), &basis, None);
        problem.check_size().map_err(IdentifyError::Fit)?;
        let before = ResidualStats::of(
            &kept
                .iter()
                .map(|&i| self.nominal_errors[i])
                .collect::<Vec<_>>(),
        );
        let (start, normal) = match self.last.take() {
            Some(last) if last.basis == basis && is_subset(kept, &last.kept) => {
                let normal = downdate(chain, self.obs, &last, kept);
                (last.params, Some(normal))
            }
            _ => (ErrorParams::zeros(chain.layout()), None),
        };
        let (fit, normal) = problem
            .solve_keeping_normal(start, normal, before, &FitOptions::default())
            .map_err(IdentifyError::Fit)?;
        self.last = Some(LastFit {
            kept: kept.to_vec(),
            basis,
            params: fit.params.clone(),
            normal,
        });
        Ok((chain.clone(), fit))
    }
}

/// The rows of [M] (3 per observation) of the observations `kept`.
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
