//! A cheap judgement of outliers against the smooth structure a recording commonly holds beyond
//! the geometry, for [`super::pipeline`]: the rows the geometric outlier search flags are judged
//! again against a linear model of fixed shape, factored once, before (and mostly instead of)
//! the diagnosis's term selection, which costs seconds where this costs milliseconds.
//!
//! The model, linearised at the geometric fit on every row (r = measured − modelled, mm):
//!
//! ```text
//! r_i ≈ M_i·δe + Σ_j ∂p/∂q_j(q_i) · Σ_k c_jk·B_k(q_ij) + Σ_k d_k·B_k(t_i)
//! ```
//!
//! * M_i: the position Jacobian of every candidate parameter at level full (the frame and marker
//!   included), whatever level is fitted: structure the level leaves out is structure;
//! * per moving joint j, its error as a smooth function of its own angle — cubic B-splines on
//!   [`JOINT_INTERVALS`] equal intervals of the recorded range (transmission errors of low
//!   order, compliance along that joint, offsets) — entering through the joint's Jacobian
//!   column;
//! * a Cartesian drift in time, cubic B-splines on [`TIME_INTERVALS`] equal intervals of the
//!   recording's time (its `t_s` when every measured row has one, else the order taken: warm-up
//!   drift is shared by neighbouring rows whichever clock measures it), one set per world axis.
//!
//! The columns are scaled to unit length and the model reduced once to the eigenvectors of its
//! Gram matrix above a relative floor ([`RANK_TOL`]), which drops what the geometry and the
//! splines share (the constant of a joint's spline is its offset). The outlier search
//! ([`super::outliers::remove_outliers`]) then refits it without each removed row by
//! subtracting the row's 3 × k block from the reduced Gram matrix and solving by Cholesky:
//! every refit costs O(k³ + n·k), no pass over the Jacobian, so the search costs a few fits
//! whatever it finds. Units: mm, rad, s.

use super::identifiability::stacked_jacobian;
use super::outliers::{remove_outliers, Outlier, OutlierError, OutlierSettings};
use nalgebra::{Cholesky, DMatrix, DVector, Matrix3, SymmetricEigen, Vector3};
use rigcal_core::basis::spline_values;
use rigcal_core::kinematics::{ErrorParams, JointKind, ParamId, ParamKind, Robot, TransformId};
use rigcal_core::recording::{Observation, Recording};
use rigcal_core::stats::f_sf;
use std::convert::Infallible;

/// Intervals of each joint's error spline: 11 functions, enough for a first and second
/// harmonic over a full turn and for a smooth compliance, too coarse to follow one row.
pub const JOINT_INTERVALS: usize = 8;

/// Intervals of the drift-in-time spline (per world axis): a warm-up of a tenth of the
/// recording is followed, one row is not.
pub const TIME_INTERVALS: usize = 10;

/// Eigenvalues of the scaled Gram matrix below this fraction of the largest are dropped
/// (directions the columns share; relative to unit-length columns, so κ up to about 10⁵ is
/// kept).
pub const RANK_TOL: f64 = 1e-10;

/// The screen's outcome.
pub struct Screened {
    /// The search: the rows removed (in the order found) and the rows kept, or too many failed.
    pub search: Result<(Vec<Outlier>, Vec<usize>), OutlierError<Infallible>>,
    /// Every row's residual against the model refitted on the rows kept last (mm).
    pub residuals: Vec<Vector3<f64>>,
    /// The model's rank (columns kept after the reduction).
    pub rank: usize,
    /// The reduced model, for [`Screened::keeps_unpredicted`].
    reduced: Reduced,
    /// The Cholesky factor of its Gram matrix on the rows kept last and σ̂² (see
    /// [`Screened::keeps_unpredicted`]); None when the search stopped or the Gram matrix is
    /// singular there.
    kept_fit: Option<(Cholesky<f64, nalgebra::Dyn>, f64)>,
}

impl std::fmt::Debug for Screened {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Screened")
            .field("search", &self.search)
            .field("rank", &self.rank)
            .finish_non_exhaustive()
    }
}

impl Screened {
    /// The largest residual among the rows kept (mm); 0 when the search stopped early.
    pub fn largest_kept(&self) -> f64 {
        match &self.search {
            Ok((_, kept)) => kept
                .iter()
                .map(|&i| self.residuals[i].norm())
                .fold(0.0, f64::max),
            Err(_) => 0.0,
        }
    }
}

/// Judges the rows of `obs` against the smooth model of the module docs, linearised at
/// `params` on `robot` (the geometric fit on every row). `candidates`: the layout indices of
/// the geometric columns; `times`: each observation's time (s, or its order); `ids`: (seq,
/// CSV line) of each observation. None when there are too few rows to judge (fewer equations
/// than twice the columns).
pub fn screen(
    robot: &dyn Robot,
    params: &ErrorParams,
    obs: &[Observation],
    candidates: &[usize],
    times: &[f64],
    ids: &[(u64, Option<u64>)],
    settings: &OutlierSettings,
) -> Option<Screened> {
    let n = obs.len();
    let residual = residual_vector(&super::errors(robot, obs, params));
    let started = std::time::Instant::now();
    let design = smooth_design(robot, params, obs, candidates, times);
    tracing::debug!(
        seconds = started.elapsed().as_secs_f64(),
        columns = design.ncols(),
        "smooth structure's design"
    );
    if 3 * n < 2 * design.ncols() {
        return None;
    }
    let started = std::time::Instant::now();
    let reduced = Reduced::of(design, &residual)?;
    tracing::debug!(
        seconds = started.elapsed().as_secs_f64(),
        rank = reduced.rank(),
        "smooth structure reduced"
    );
    let mut residuals = Vec::new();
    let mut state = None;
    let search = remove_outliers(ids, settings, |kept| {
        residuals = reduced.residuals_without(&residual, kept, &mut state);
        Ok::<_, Infallible>((residuals.clone(), reduced.rank()))
    });
    let rank = reduced.rank();
    let kept_fit = match (&search, state) {
        (Ok((_, kept)), Some(last)) if last.kept == *kept => {
            let dof_share = 1.0 - rank as f64 / (3 * kept.len()) as f64;
            let kept_res: Vec<Vector3<f64>> = kept.iter().map(|&k| residuals[k]).collect();
            let s2 = rigcal_core::stats::mad_sigma(&kept_res).powi(2) / dof_share;
            Cholesky::new(last.gram)
                .filter(|_| dof_share > 0.0)
                .map(|ch| (ch, s2))
        }
        _ => None,
    };
    Some(Screened {
        search,
        residuals,
        rank,
        reduced,
        kept_fit,
    })
}

impl Screened {
    /// True when the search kept row `i` although the smooth model, fitted on the rows it kept
    /// *without row `i`*, does not predict it within the outlier gate: its externally
    /// studentised residual eᵢᵀ(I − Hᵢᵢ)⁻¹eᵢ / σ̂² is above the χ²(3) quantile at 1 − `alpha`/m
    /// (Bonferroni over the m kept rows, as the search). Hᵢᵢ = BᵢG⁻¹Bᵢᵀ is the row's 3 × 3
    /// leverage block in the reduced model; σ̂² the robust variance of the kept rows' residuals
    /// per coordinate, divided by 1 − rank/(3m) (in-sample residuals shrink by the average
    /// leverage). A kept row that cannot be predicted at all (it alone determines a direction,
    /// or the kept rows' Gram matrix is singular) counts as not predicted. False for a row the
    /// search removed (judged against the fit without it already) and when the search stopped
    /// at too many (its verdict is the warning).
    ///
    /// Why: a model flexible enough for its rows (the screen's splines on a short recording)
    /// bends towards gross rows and leaves each a small in-sample residual; only its
    /// prediction from the other rows shows whether the structure explains the row or the row
    /// shaped the structure.
    pub fn keeps_unpredicted(&self, i: usize, alpha: f64) -> bool {
        let Ok((_, kept)) = &self.search else {
            return false;
        };
        if kept.binary_search(&i).is_err() {
            return false;
        }
        let Some((factor, s2)) = &self.kept_fit else {
            return true;
        };
        let b = self.reduced.a.rows(3 * i, 3) * &self.reduced.v;
        let leverage = &b * factor.solve(&b.transpose());
        let Some(inflation) =
            (Matrix3::identity() - Matrix3::from_iterator(leverage.iter().copied())).try_inverse()
        else {
            return true;
        };
        let e = self.residuals[i];
        let t = e.dot(&(inflation * e)) / s2.max(1e-300);
        !(t.is_finite() && t <= rigcal_core::stats::chi2_3_isf(alpha / kept.len() as f64))
    }
}

/// True when every row of `rows` stands out from its own neighbourhood as well as from the
/// recording: a structure the smooth model lacks (a local deformation, a dent) raises the
/// residuals of neighbouring rows together, a reflection or a touch on dirt one row alone.
/// For each row, the residual variance per coordinate of its [`NEIGHBOURS`] nearest rows (by
/// measured position) among `kept` — never below that of every kept row (rank `rank` fitted) —
/// is the scale its residual is F-tested against, F(3, 3·NEIGHBOURS), at `alpha` over the kept
/// rows (Bonferroni, as the outlier search itself).
pub fn isolated(
    obs: &[Observation],
    residuals: &[Vector3<f64>],
    kept: &[usize],
    rows: &[usize],
    rank: usize,
    alpha: f64,
) -> bool {
    let dof = (3 * kept.len()).saturating_sub(rank);
    if kept.len() <= NEIGHBOURS || dof == 0 {
        return false;
    }
    let s2_all = kept
        .iter()
        .map(|&j| residuals[j].norm_squared())
        .sum::<f64>()
        / dof as f64;
    let level = alpha / kept.len() as f64;
    rows.iter().all(|&i| {
        let mut by_distance: Vec<(f64, usize)> = kept
            .iter()
            .map(|&j| ((obs[j].p - obs[i].p).norm_squared(), j))
            .collect();
        by_distance.select_nth_unstable_by(NEIGHBOURS - 1, |a, b| a.0.total_cmp(&b.0));
        let s2_local = by_distance[..NEIGHBOURS]
            .iter()
            .map(|&(_, j)| residuals[j].norm_squared())
            .sum::<f64>()
            / (3 * NEIGHBOURS) as f64;
        let f = residuals[i].norm_squared() / (3.0 * s2_local.max(s2_all).max(1e-300));
        let p = f_sf(f, 3.0, (3 * NEIGHBOURS) as f64);
        tracing::debug!(row = i, f, p, level, "against its neighbourhood");
        p < level
    })
}

/// Neighbours of a row in [`isolated`]'s test: enough for its local scale to have 60 degrees
/// of freedom, few enough to stay within a local deformation of the workspace.
pub const NEIGHBOURS: usize = 20;

/// Each measured row's time in the order of [`Recording::observations`]: `t_s` (s) when every
/// measured row has one, else the row's place in the order taken.
pub fn observation_times(rec: &Recording) -> Vec<f64> {
    let t: Vec<Option<f64>> = rec.measured().map(|(m, _)| m.t_s).collect();
    if t.iter().all(|x| x.is_some_and(f64::is_finite)) {
        t.into_iter().flatten().collect()
    } else {
        (0..t.len()).map(|k| k as f64).collect()
    }
}

/// The stacked residuals (3n).
fn residual_vector(r: &[Vector3<f64>]) -> DVector<f64> {
    DVector::from_iterator(3 * r.len(), r.iter().flat_map(|v| v.iter().copied()))
}

/// The unscaled design: geometry, each moving joint's spline through its Jacobian column, the
/// drift spline per axis.
fn smooth_design(
    robot: &dyn Robot,
    params: &ErrorParams,
    obs: &[Observation],
    candidates: &[usize],
    times: &[f64],
) -> DMatrix<f64> {
    let n = obs.len();
    let poses: Vec<Vec<f64>> = obs.iter().map(|o| o.q.clone()).collect();
    let moving = moving_joint_columns(robot, &poses);
    let joint_cols: Vec<usize> = moving.iter().map(|m| m.1).collect();
    let geometry = stacked_jacobian(robot, params, &poses, candidates);
    let joints = stacked_jacobian(robot, params, &poses, &joint_cols);
    let per_joint = JOINT_INTERVALS + 3;
    let (t_lo, t_hi) = range(times.iter().copied());
    let drift = t_hi > t_lo;
    let per_axis = if drift { TIME_INTERVALS + 3 } else { 0 };
    let cols = geometry.ncols() + moving.len() * per_joint + 3 * per_axis;
    let mut a = DMatrix::zeros(3 * n, cols);
    a.columns_mut(0, geometry.ncols()).copy_from(&geometry);
    let mut c0 = geometry.ncols();
    for (k, &(joint, _, lo, hi)) in moving.iter().enumerate() {
        for (i, q) in poses.iter().enumerate() {
            let b = spline_values(q[joint], lo, hi, JOINT_INTERVALS);
            for (m, bm) in b.iter().enumerate() {
                for x in 0..3 {
                    a[(3 * i + x, c0 + m)] = joints[(3 * i + x, k)] * bm;
                }
            }
        }
        c0 += per_joint;
    }
    if drift {
        for (i, &t) in times.iter().enumerate() {
            let b = spline_values(t, t_lo, t_hi, TIME_INTERVALS);
            for (m, bm) in b.iter().enumerate() {
                for x in 0..3 {
                    a[(3 * i + x, c0 + x * per_axis + m)] = *bm;
                }
            }
        }
    }
    a
}

/// (joint index, layout index of its variable's parameter, lowest and highest recorded value)
/// of every joint that moves in the recording.
fn moving_joint_columns(robot: &dyn Robot, poses: &[Vec<f64>]) -> Vec<(usize, usize, f64, f64)> {
    let layout = robot.layout();
    robot
        .joints()
        .iter()
        .enumerate()
        .filter_map(|(j, spec)| {
            let kind = match spec.kind {
                JointKind::Revolute => ParamKind::Theta,
                JointKind::Prismatic => ParamKind::D,
            };
            let col = layout.index_of(ParamId {
                transform: TransformId::Link(j + 1),
                kind,
            })?;
            let (lo, hi) = range(poses.iter().map(|q| q[j]));
            (hi - lo > 1e-6).then_some((j, col, lo, hi))
        })
        .collect()
}

/// (min, max) of finite values; (0, 0) when there are none.
fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
    if lo <= hi {
        (lo, hi)
    } else {
        (0.0, 0.0)
    }
}

/// The design reduced to its well-determined directions: B = A·S·V (S the column scaling, V the
/// Gram matrix's eigenvectors above [`RANK_TOL`]), with BᵀB = diag(λ) and Bᵀr on every row. B
/// is never formed: a removed row's block is A_i·V, the fit on every row A·(V·x).
struct Reduced {
    /// A·S (3n × p).
    a: DMatrix<f64>,
    /// V (p × k).
    v: DMatrix<f64>,
    gram: DMatrix<f64>,
    btr: DVector<f64>,
}

impl Reduced {
    /// None when the design has no column left (nothing to judge against).
    fn of(mut a: DMatrix<f64>, r: &DVector<f64>) -> Option<Self> {
        for mut c in a.column_iter_mut() {
            let norm = c.norm();
            if norm > 0.0 {
                c /= norm;
            }
        }
        let eig = SymmetricEigen::new(sparse_gram(&a));
        let top = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
        let keep: Vec<usize> = (0..eig.eigenvalues.len())
            .filter(|&k| eig.eigenvalues[k] > RANK_TOL * top)
            .collect();
        if keep.is_empty() {
            return None;
        }
        let v = eig.eigenvectors.select_columns(&keep);
        let gram = DMatrix::from_diagonal(&eig.eigenvalues.select_rows(&keep));
        let btr = v.tr_mul(&a.tr_mul(r));
        Some(Self { a, v, gram, btr })
    }

    fn rank(&self) -> usize {
        self.v.ncols()
    }

    /// Every row's residual against the model fitted on `kept` (increasing indices): the rows
    /// not kept are subtracted from BᵀB and Bᵀr. `state` carries the last call's kept rows
    /// and sums, so that a search that only ever removes rows subtracts each row once.
    fn residuals_without(
        &self,
        r: &DVector<f64>,
        kept: &[usize],
        state: &mut Option<Downdated>,
    ) -> Vec<Vector3<f64>> {
        let n = r.len() / 3;
        let start = match state.take() {
            Some(s) if is_subset(kept, &s.kept) => s,
            _ => Downdated {
                kept: (0..n).collect(),
                gram: self.gram.clone(),
                btr: self.btr.clone(),
            },
        };
        let Downdated {
            kept: was,
            mut gram,
            mut btr,
        } = start;
        let mut next = kept.iter().copied().peekable();
        for i in was {
            if next.peek() == Some(&i) {
                next.next();
                continue;
            }
            let rows = self.a.rows(3 * i, 3) * &self.v;
            gram -= rows.tr_mul(&rows);
            btr -= rows.tr_mul(&r.rows(3 * i, 3));
        }
        let x = match Cholesky::new(gram.clone()) {
            Some(ch) => ch.solve(&btr),
            // Removing rows left a direction undetermined: the minimum-norm solution.
            None => gram
                .clone()
                .svd(true, true)
                .solve(&btr, 1e-12)
                .unwrap_or_else(|_| DVector::zeros(btr.len())),
        };
        *state = Some(Downdated {
            kept: kept.to_vec(),
            gram,
            btr,
        });
        let fitted = &self.a * (&self.v * x);
        (0..n)
            .map(|i| {
                Vector3::new(
                    r[3 * i] - fitted[3 * i],
                    r[3 * i + 1] - fitted[3 * i + 1],
                    r[3 * i + 2] - fitted[3 * i + 2],
                )
            })
            .collect()
    }
}

/// AᵀA summed row by row over each row's nonzero entries: a spline column is nonzero on 4 of
/// its 11 functions, a drift column on one axis of three, so a row holds a third of the
/// columns and this costs about a ninth of the dense product.
fn sparse_gram(a: &DMatrix<f64>) -> DMatrix<f64> {
    let p = a.ncols();
    let mut g = DMatrix::zeros(p, p);
    let mut nonzero: Vec<(usize, f64)> = Vec::with_capacity(p);
    {
        let gs = g.as_mut_slice();
        for i in 0..a.nrows() {
            nonzero.clear();
            nonzero.extend((0..p).map(|c| (c, a[(i, c)])).filter(|&(_, v)| v != 0.0));
            for (k, &(c1, v1)) in nonzero.iter().enumerate() {
                let column = &mut gs[c1 * p..(c1 + 1) * p];
                for &(c2, v2) in &nonzero[k..] {
                    column[c2] += v1 * v2;
                }
            }
        }
    }
    // The lower triangle was summed (column c1, rows c2 ≥ c1): mirror it.
    for c1 in 0..p {
        for c2 in c1 + 1..p {
            g[(c1, c2)] = g[(c2, c1)];
        }
    }
    g
}

/// BᵀB and Bᵀr summed over the rows `kept` (increasing indices).
struct Downdated {
    kept: Vec<usize>,
    gram: DMatrix<f64>,
    btr: DVector<f64>,
}

/// True when every index of `a` is in `b` (both increasing).
fn is_subset(a: &[usize], b: &[usize]) -> bool {
    let mut b = b.iter().peekable();
    a.iter().all(|x| {
        while b.next_if(|y| *y < x).is_some() {}
        b.next_if(|y| *y == x).is_some()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reduced_fit_equals_a_dense_least_squares_fit_without_the_removed_rows() {
        // A rank-deficient design (column 2 = column 0 + column 1) and rows 3 and 7 removed:
        // the residuals equal those of nalgebra's SVD least squares on the kept rows.
        let n = 12;
        let mut a = DMatrix::zeros(3 * n, 4);
        for i in 0..3 * n {
            let x = i as f64 / 7.0;
            a[(i, 0)] = 1.0;
            a[(i, 1)] = x.sin();
            a[(i, 2)] = 1.0 + x.sin();
            a[(i, 3)] = (x * x).cos();
        }
        let r = DVector::from_iterator(3 * n, (0..3 * n).map(|i| ((i * 37 % 11) as f64).sqrt()));
        let kept: Vec<usize> = (0..n).filter(|&i| i != 3 && i != 7).collect();
        let reduced = Reduced::of(a.clone(), &r).expect("columns");
        assert_eq!(reduced.rank(), 3);
        // Through a state that has seen row 3 removed first, as the search calls it.
        let mut state = None;
        let first: Vec<usize> = (0..n).filter(|&i| i != 3).collect();
        reduced.residuals_without(&r, &first, &mut state);
        let got = reduced.residuals_without(&r, &kept, &mut state);
        let rows: Vec<usize> = kept.iter().flat_map(|&i| 3 * i..3 * i + 3).collect();
        let x = a
            .select_rows(&rows)
            .svd(true, true)
            .solve(&r.select_rows(&rows), 1e-10)
            .expect("solve");
        let want = &r - &a * x;
        for i in 0..n {
            for k in 0..3 {
                assert!(
                    (got[i][k] - want[3 * i + k]).abs() < 1e-9,
                    "row {i} axis {k}: {} vs {}",
                    got[i][k],
                    want[3 * i + k]
                );
            }
        }
    }

    #[test]
    fn a_lone_row_is_isolated_and_a_row_of_a_local_bump_is_not() {
        // 400 points on a 20 × 20 grid (10 mm apart), residual 0.01 mm noise-like pattern;
        // a bump of 0.5 mm (width 20 mm) around point 210; point 45 alone 0.5 mm off.
        let obs: Vec<Observation> = (0..400)
            .map(|k| Observation {
                q: vec![],
                p: Vector3::new(10.0 * (k % 20) as f64, 10.0 * (k / 20) as f64, 0.0),
            })
            .collect();
        let centre = obs[210].p;
        let residuals: Vec<Vector3<f64>> = (0..400)
            .map(|k| {
                let noise = 0.01 * (((k * 7919) % 13) as f64 / 6.0 - 1.0);
                let d2 = (obs[k].p - centre).norm_squared();
                let bump = 0.5 * (-d2 / (2.0 * 20.0 * 20.0)).exp();
                let lone = if k == 45 { 0.5 } else { 0.0 };
                Vector3::new(noise + bump + lone, -noise, noise)
            })
            .collect();
        let kept_without = |row: usize| -> Vec<usize> { (0..400).filter(|&k| k != row).collect() };
        assert!(isolated(
            &obs,
            &residuals,
            &kept_without(45),
            &[45],
            3,
            0.01
        ));
        assert!(!isolated(
            &obs,
            &residuals,
            &kept_without(210),
            &[210],
            3,
            0.01
        ));
    }

    #[test]
    fn the_sparse_gram_matrix_equals_the_dense_product() {
        let a = DMatrix::from_fn(30, 7, |i, j| {
            if (i + 2 * j) % 3 == 0 {
                0.0
            } else {
                ((i * 31 + j * 17) % 23) as f64 / 7.0 - 1.5
            }
        });
        let dense = a.tr_mul(&a);
        let sparse = sparse_gram(&a);
        assert!((dense - sparse).abs().max() < 1e-12);
    }
}
