//! Stage 5, the outlier judgement: rows no model explains, judged last against the final linear
//! model (geometry and named effects) with [`crate::identification::outliers`], so a row a
//! named effect explains is never one. The caller removes the rows found and diagnoses again.
//!
//! [`outliers_against_structure`] serves `identification::identify`: the same judgement against
//! the structure the diagnosis finds, for a recording whose geometric residual is structured.
//!
//! Units: residuals in mm.

use super::linalg::{hcat, lstsq, rows_of, rows_of_vector, LSTSQ_RANK_TOL};
use super::refit::Refit;
use super::select::{select_terms, Selection};
use super::{Candidate, Data, Standard};
use crate::identification::dense::{bounded_svd, tall_r};
use crate::identification::outliers::{remove_outliers, Outlier, OutlierError, OutlierSettings};
use crate::identification::{IdentifyOptions, StructureJudge};
use nalgebra::{DMatrix, DVector, Vector3};
use std::convert::Infallible;

/// A shape of the discrepancy term takes part in the outlier judgement only while it has at
/// most one coefficient per this many measurements. A shape with about one coefficient per
/// measurement can follow single rows: fitted with them, it bends to a gross row and hides it
/// (a position shape of 24 coefficients on 29 measurements took two of three rows 17× the
/// floor), so the rows must be judged without it. Three measurements per coefficient leave
/// each coefficient's local fit at least two measurements of slack; the library's effects
/// (1–3 coefficients each) and the geometry stay, and a shape that meets the bound
/// (the UR10's 23-coefficient splines on 990 measurements) stays too.
pub const MEASUREMENTS_PER_SHAPE_COEFFICIENT: usize = 3;

/// The model the outliers are judged against: `full` (geometry, effects and shapes) when every
/// shape of `sel` has at most one coefficient per [`MEASUREMENTS_PER_SHAPE_COEFFICIENT`]
/// measurements, else the same refit without the shapes that have more.
pub fn outlier_model<'a>(
    std: &Standard,
    screen: &super::screen::Screen,
    sel: &Selection,
    full: &'a Refit,
) -> std::borrow::Cow<'a, Refit> {
    let m = std.data.len();
    let fits = |k: usize| k * MEASUREMENTS_PER_SHAPE_COEFFICIENT <= m;
    if sel.shapes.iter().all(|s| fits(s.x.ncols())) {
        return std::borrow::Cow::Borrowed(full);
    }
    let mut narrow = sel.clone();
    narrow.shapes.retain(|s| fits(s.x.ncols()));
    std::borrow::Cow::Owned(super::refit::refit(std, screen, &narrow, true))
}

/// The rows that fail the outlier test against the refitted model `refit` (its design
/// refitted on the rows kept at each round of the search, by [`RowDowndates`]).
pub fn judge_outliers(
    std: &Standard,
    refit: &Refit,
) -> Result<Vec<Outlier>, OutlierError<Infallible>> {
    let d = &std.data;
    let ids: Vec<(u64, Option<u64>)> = d.seq.iter().copied().zip(d.line.iter().copied()).collect();
    let fits = RowDowndates::new(&refit.design, &std.residual);
    let (found, _) = remove_outliers(&ids, &OutlierSettings::default(), |kept| {
        Ok::<_, Infallible>(fits.residuals(kept))
    })?;
    Ok(found)
}

/// How far (as a factor) every singular value must stay from [`LSTSQ_RANK_TOL`] for the
/// downdated fit to stand in for `lstsq`: kept ones above `TOL·MARGIN`, dropped ones below
/// `TOL / MARGIN`, both bounded after the removal of rows and the rescaling of columns that
/// lstsq would do. Rounding moves a singular value by about 1e-16 of the largest, so within
/// these margins the two make the same rank decision; nearer the tolerance the search falls
/// back to lstsq itself.
const RANK_MARGIN: f64 = 1e3;

/// Largest error (relative to the largest singular value) accepted in the SVD of the
/// triangular factor and in the orthonormality of the basis built from it: rounding leaves
/// about 1e-11 there; a wrong factorisation, order one.
const SVD_CHECK: f64 = 1e-8;

/// The least-squares fits of one design on the subsets of rows an outlier search keeps, each
/// equal (to rounding) to [`lstsq`] on the kept rows but costing O(n·r + k·r² + r³)
/// for k removed rows and r the design's rank, where lstsq costs an SVD of the 3n × p kept rows.
///
/// Convention: `a` (3n × p, row 3i + k = coordinate k of measurement i) and `r` (3n, mm) are
/// fixed. Once: the columns are scaled to unit norm (as lstsq does), the scaled design's SVD
/// from its triangular factor R (A_s = Q·R, R = W·Σ·Vᵀ) gives an orthonormal basis
/// U = A_s·V_r·Σ_r⁻¹ (3n × r) of its column space and c = Uᵀr. The fit on the kept rows K
/// (removed rows S) projects r_K on the span of U_K; with M = Uᵀ_K U_K = I − Uᵀ_S U_S (the
/// rank-3|S| downdate of the identity) its coefficients are M⁻¹(c − Uᵀ_S r_S), and every row's
/// residual (removed rows predicted) is r − U·M⁻¹(c − Uᵀ_S r_S). While the kept rows keep the
/// full rank r, the rows of S lie in the row space of the kept design, so their predictions
/// are the same for every least-squares solution, lstsq's minimum-norm one included.
///
/// lstsq decides the rank on the kept rows with the columns scaled by their kept norms. That
/// decision is bounded from the full one: M's smallest eigenvalue λ bounds how much the
/// removal shrinks the design, g = max over columns of (full norm / kept norm) how much the
/// rescaling moves a singular value. When the bounds leave the decision within
/// [`RANK_MARGIN`] of lstsq's tolerance (a removed row carried a direction, a column lives on
/// the removed rows, a design near its rank tolerance), that round is lstsq on the kept rows.
pub(crate) struct RowDowndates<'a> {
    a: &'a DMatrix<f64>,
    r: &'a DVector<f64>,
    basis: Option<RowBasis>,
    /// The design without the columns that are zero on every kept row (their indices, the
    /// design, its basis), built the first round they are.
    #[allow(clippy::type_complexity)]
    without: std::cell::RefCell<Option<(Vec<usize>, DMatrix<f64>, Option<RowBasis>)>>,
}

/// The full design's orthonormal basis and what the rank bounds need.
struct RowBasis {
    /// U (3n × r): orthonormal basis of the column space of the design.
    u: DMatrix<f64>,
    /// Uᵀ r.
    c: DVector<f64>,
    /// Smallest kept singular value over the largest (column-scaled design).
    kept_ratio: f64,
    /// Largest dropped singular value over the largest (0 when none is dropped).
    dropped_ratio: f64,
    /// Squared norm of each column over all rows.
    column_sq: Vec<f64>,
}

impl<'a> RowDowndates<'a> {
    /// Factors the design `a` (3n × p) once for fits of `r` on subsets of its rows.
    pub(crate) fn new(a: &'a DMatrix<f64>, r: &'a DVector<f64>) -> Self {
        Self {
            a,
            r,
            basis: RowBasis::of(a, r),
            without: std::cell::RefCell::new(None),
        }
    }

    /// Every row's residual (mm) against the fit on the rows `kept` (increasing indices), and
    /// the rank of that fit: what [`remove_outliers`]'s refit returns.
    pub(crate) fn residuals(&self, kept: &[usize]) -> (Vec<Vector3<f64>>, usize) {
        let (res, rank) = self.downdated(kept).unwrap_or_else(|| self.by_lstsq(kept));
        (
            (0..res.len() / 3)
                .map(|i| Vector3::new(res[3 * i], res[3 * i + 1], res[3 * i + 2]))
                .collect(),
            rank,
        )
    }

    /// The present path: lstsq on the kept rows.
    fn by_lstsq(&self, kept: &[usize]) -> (DVector<f64>, usize) {
        let fit = lstsq(&rows_of(self.a, kept), &rows_of_vector(self.r, kept));
        (self.r - self.a * fit.solution, fit.rank)
    }

    /// The fit on `kept` from the full design's basis, or `None` when lstsq's rank decision
    /// on the kept rows is not certain to be the full one (see the type's documentation).
    /// Columns that are exactly zero on every kept row (a spline piece only removed rows
    /// reach) are fitted out: lstsq gives them no weight (their scaled column is zero, a
    /// dropped singular value), so the fit is that of the design without them, whose basis is
    /// built once and kept while the same columns are dead.
    fn downdated(&self, kept: &[usize]) -> Option<(DVector<f64>, usize)> {
        let n = self.r.len() / 3;
        let removed = complement(kept, n);
        let p = self.a.ncols();
        let mut removed_sq = vec![0.0; p];
        for &i in &removed {
            for k in 0..3 {
                for (c, sq) in removed_sq.iter_mut().enumerate() {
                    *sq += self.a[(3 * i + k, c)].powi(2);
                }
            }
        }
        let dead: Vec<usize> = (0..p)
            .filter(|&c| {
                removed_sq[c] > 0.0
                    && kept
                        .iter()
                        .all(|&i| (0..3).all(|k| self.a[(3 * i + k, c)] == 0.0))
            })
            .collect();
        if dead.is_empty() {
            let b = self.basis.as_ref()?;
            return downdate(self.r, b, &removed, &removed_sq);
        }
        let mut cache = self.without.borrow_mut();
        if cache.as_ref().is_none_or(|(d, _, _)| *d != dead) {
            let design = self.a.clone().remove_columns_at(&dead);
            let basis = RowBasis::of(&design, self.r);
            *cache = Some((dead.clone(), design, basis));
        }
        let (_, _, basis) = cache.as_ref().expect("cached above");
        let removed_sq: Vec<f64> = (0..p)
            .filter(|c| !dead.contains(c))
            .map(|c| removed_sq[c])
            .collect();
        downdate(self.r, basis.as_ref()?, &removed, &removed_sq)
    }
}

/// The fit of `r` on a design's kept rows (all but `removed`, whose squared column norms are
/// `removed_sq`) from the design's basis `b`, or `None` when lstsq's rank decision on the
/// kept rows is not certain to be `b`'s (see [`RowDowndates`]).
fn downdate(
    r: &DVector<f64>,
    b: &RowBasis,
    removed: &[usize],
    removed_sq: &[f64],
) -> Option<(DVector<f64>, usize)> {
    let rank = b.u.ncols();
    // Column scale change lstsq would make on the kept rows.
    let mut g2: f64 = 1.0;
    for (full, gone) in b.column_sq.iter().zip(removed_sq) {
        let kept_sq = full - gone;
        if *full == 0.0 {
            // A column zero on every row: lstsq and the basis both give it no weight.
            continue;
        }
        if kept_sq <= full * 1e-12 {
            tracing::debug!(
                share = kept_sq / full,
                "outlier refit by lstsq: a column lives on the removed rows"
            );
            return None;
        }
        g2 = g2.max(full / kept_sq);
    }
    let us = rows_of(&b.u, removed);
    let rs = rows_of_vector(r, removed);
    let m = DMatrix::identity(rank, rank) - us.tr_mul(&us);
    let eig = m.symmetric_eigen();
    let lambda = eig.eigenvalues.min();
    if lambda.is_nan() || lambda <= 0.0 {
        return None;
    }
    let shrink = lambda.sqrt();
    let kept_low = b.kept_ratio * shrink / g2.sqrt();
    let dropped_high = b.dropped_ratio * g2 / shrink;
    if kept_low < LSTSQ_RANK_TOL * RANK_MARGIN || dropped_high > LSTSQ_RANK_TOL / RANK_MARGIN {
        tracing::debug!(
            kept_low,
            dropped_high,
            lambda,
            g2,
            "outlier refit by lstsq: the rank decision is near lstsq's tolerance"
        );
        return None;
    }
    let rhs = eig.eigenvectors.tr_mul(&(&b.c - us.tr_mul(&rs)));
    let scaled = rhs.component_div(&eig.eigenvalues);
    let coef = &eig.eigenvectors * scaled;
    Some((r - &b.u * coef, rank))
}

impl RowBasis {
    /// The basis of `a`'s column space (columns scaled to unit norm, as lstsq does), or `None`
    /// when the design is empty, wider than tall, or near lstsq's rank tolerance.
    fn of(a: &DMatrix<f64>, r: &DVector<f64>) -> Option<Self> {
        let (rows, p) = a.shape();
        if p == 0 || rows < p {
            return None;
        }
        let column_sq: Vec<f64> = (0..p).map(|c| a.column(c).norm_squared()).collect();
        let mut s = a.clone();
        for (c, sq) in column_sq.iter().enumerate() {
            s.column_mut(c).scale_mut(1.0 / sq.sqrt().max(1e-300));
        }
        let r_factor = tall_r(&s);
        let svd = bounded_svd(r_factor.clone(), true, true)?;
        let (w_left, v_t) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
        let sv = &svd.singular_values;
        let smax = sv.max();
        if smax.is_nan() || smax <= 0.0 {
            return None;
        }
        let tol = smax * LSTSQ_RANK_TOL;
        let kept: Vec<usize> = (0..sv.len()).filter(|&k| sv[k] > tol).collect();
        let kept_ratio = kept.iter().map(|&k| sv[k]).fold(f64::INFINITY, f64::min) / smax;
        let dropped_ratio = (0..sv.len())
            .filter(|&k| sv[k] <= tol)
            .map(|k| sv[k])
            .fold(0.0, f64::max)
            / smax;
        if kept_ratio < LSTSQ_RANK_TOL * RANK_MARGIN || dropped_ratio > LSTSQ_RANK_TOL / RANK_MARGIN
        {
            tracing::debug!(
                kept_ratio,
                dropped_ratio,
                "outlier design near lstsq's tolerance"
            );
            return None;
        }
        // nalgebra's SVD can return a wrong factorisation of a matrix with an exactly zero
        // singular value (seen here: R − W·Σ·Vᵀ of 0.25 on unit columns): checked, and left
        // to lstsq when wrong.
        let rebuilt = w_left * DMatrix::from_diagonal(sv) * v_t;
        if (rebuilt - &r_factor).amax() > SVD_CHECK * smax {
            tracing::debug!("outlier design: the SVD of its triangular factor is wrong");
            return None;
        }
        let w = DMatrix::from_fn(p, kept.len(), |row, col| {
            v_t[(kept[col], row)] / sv[kept[col]]
        });
        let u = s * w;
        let gram = u.tr_mul(&u);
        if (gram - DMatrix::identity(kept.len(), kept.len())).amax() > SVD_CHECK {
            return None;
        }
        let c = u.tr_mul(r);
        Some(Self {
            u,
            c,
            kept_ratio,
            dropped_ratio,
            column_sq,
        })
    }
}

/// The indices of 0..n not in `kept` (increasing).
fn complement(kept: &[usize], n: usize) -> Vec<usize> {
    let mut next = kept.iter().copied().peekable();
    (0..n)
        .filter(|&i| {
            if next.peek() == Some(&i) {
                next.next();
                false
            } else {
                true
            }
        })
        .collect()
}

/// The columns of the final model of `std` (geometry, the chosen effects and shapes of `sel`,
/// the instrument's nuisance) rebuilt on the measurements of `d`, which share its chain and
/// geometry; zero where `d` cannot show a term.
fn design_on(
    rig: &rigcal_core::rig::Rig,
    rec: &rigcal_core::recording::Recording,
    std: &Standard,
    sel: &Selection,
    lib: &[Box<dyn Candidate>],
    d: &Data,
) -> DMatrix<f64> {
    let n = 3 * d.len();
    let poses: Vec<Vec<f64>> = d.obs.iter().map(|o| o.q.clone()).collect();
    let mut cols = vec![crate::identification::identifiability::stacked_jacobian(
        &d.chain, &d.e, &poses, &std.free,
    )];
    for c in &sel.chosen {
        cols.push(
            lib[c.cand]
                .regressors(d)
                .unwrap_or_else(|| DMatrix::zeros(n, c.x.ncols())),
        );
    }
    for s in &sel.shapes {
        cols.push(
            s.spec
                .columns(d)
                .unwrap_or_else(|| DMatrix::zeros(n, s.x.ncols())),
        );
    }
    if std.nuisance.ncols() > 0 {
        cols.push(super::quantisation_nuisance(rig, rec, d));
    }
    hcat(&cols, n)
}

/// Rounds of "find the structure, judge outliers against it, find it again without them".
const STRUCTURE_ROUNDS: usize = 2;

/// [`outliers_against_structure`] as identification's [`StructureJudge`] (the diagnosis's
/// failure to model the recording as text).
const STRUCTURE_JUDGE: StructureJudge =
    |rig, rec, settings| outliers_against_structure(rig, rec, settings).map_err(|e| e.to_string());

/// [`IdentifyOptions`] whose outliers are judged against the structure the diagnosis finds
/// where the geometric judgement alone cannot decide: what `rigcal identify` does.
pub fn identify_options() -> IdentifyOptions {
    IdentifyOptions {
        structure: Some(STRUCTURE_JUDGE),
        ..IdentifyOptions::default()
    }
}

/// Outliers of a recording judged against the structure the diagnosis finds in it — geometry
/// (every identifiable parameter), named effects and the discrepancy term — rather than against
/// a geometric fit that leaves that structure in the residual, where its largest rows look like
/// outliers. The structure is found on every measured row, the outliers judged against it, and
/// (when some were found) the structure found again without them and the judgement repeated
/// from all rows, so a gross row cannot shape the model it is judged by. Indices are among the
/// measured rows of `rec`, in order. The outer error: the diagnosis could not model the
/// recording; the inner one: too many rows fail.
#[allow(clippy::type_complexity)]
pub fn outliers_against_structure(
    rig: &rigcal_core::rig::Rig,
    rec: &rigcal_core::recording::Recording,
    settings: &OutlierSettings,
) -> Result<Result<Vec<Outlier>, OutlierError<Infallible>>, super::DiagnoseError> {
    let lib = super::library_for(rig);
    let mut set_aside: Vec<u64> = Vec::new();
    let mut last = Ok(Vec::new());
    for _ in 0..STRUCTURE_ROUNDS {
        let mut work = rec.clone();
        for row in work.rows.iter_mut().filter(|r| set_aside.contains(&r.seq)) {
            row.status = rigcal_core::recording::Status::Via;
        }
        let started = std::time::Instant::now();
        let std = super::standard_fit(rig, &work)?;
        let sel = select_terms(&std, &lib)?;
        tracing::debug!(seconds = started.elapsed().as_secs_f64(), "structure found");
        let started = std::time::Instant::now();
        // Judged on every measured row: the rows set aside to find the structure are back,
        // predicted by it.
        let all = super::prepare(&std.data.chain, &std.data.e, rec)?;
        let a = design_on(rig, rec, &std, &sel, &lib, &all);
        let r = super::residual_of(&all);
        let ids: Vec<(u64, Option<u64>)> = all
            .seq
            .iter()
            .copied()
            .zip(all.line.iter().copied())
            .collect();
        let fits = RowDowndates::new(&a, &r);
        last = remove_outliers(&ids, settings, |kept| {
            Ok::<_, Infallible>(fits.residuals(kept))
        })
        .map(|(found, _)| found);
        tracing::debug!(
            seconds = started.elapsed().as_secs_f64(),
            columns = a.ncols(),
            "outliers judged against it"
        );
        let found: Vec<u64> = match &last {
            Ok(f) => f.iter().map(|o| o.seq).collect(),
            Err(_) => break,
        };
        if found.is_empty() || found == set_aside {
            break;
        }
        set_aside = found;
    }
    Ok(last)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// A seeded design (3n × p) of smooth and random columns of sizes 1e-2 to 1e2, its last
    /// `dependent` columns exact combinations of the first ones, and a residual (mm) of the
    /// design's span, noise σ ≈ 0.02 mm and `gross` rows 0.3–0.9 mm off per coordinate.
    fn case(
        seed: u64,
        n: usize,
        p: usize,
        dependent: usize,
        gross: usize,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut a = DMatrix::from_fn(3 * n, p, |row, c| {
            let x = row as f64 / (3 * n) as f64;
            let scale = 10f64.powi(c as i32 % 5 - 2);
            scale * ((c as f64 + 1.0) * 3.0 * x).sin() + scale * 0.3 * rng.random_range(-1.0..1.0)
        });
        for k in 0..dependent {
            let combo = a.column(k) * 2.0 - a.column(k + 1) * 0.5;
            a.set_column(p - 1 - k, &combo);
        }
        let mut r = DVector::from_fn(3 * n, |_, _| 0.02 * rng.random_range(-1.7..1.7));
        r += &a * DVector::from_fn(p, |_, _| rng.random_range(-0.1..0.1));
        for _ in 0..gross {
            let i = rng.random_range(0..n);
            for k in 0..3 {
                let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                r[3 * i + k] += sign * rng.random_range(0.3..0.9);
            }
        }
        (a, r)
    }

    /// The independent reference: the normal equations (Cholesky) on the kept rows of the
    /// `p − dependent` independent columns, every row's residual.
    fn reference(
        a: &DMatrix<f64>,
        r: &DVector<f64>,
        dependent: usize,
        kept: &[usize],
    ) -> DVector<f64> {
        let independent = a.columns(0, a.ncols() - dependent).into_owned();
        let ak = rows_of(&independent, kept);
        let x = ak
            .tr_mul(&ak)
            .cholesky()
            .expect("independent columns")
            .solve(&ak.tr_mul(&rows_of_vector(r, kept)));
        r - independent * x
    }

    fn as_rows(res: &DVector<f64>) -> Vec<Vector3<f64>> {
        (0..res.len() / 3)
            .map(|i| Vector3::new(res[3 * i], res[3 * i + 1], res[3 * i + 2]))
            .collect()
    }

    /// The search through the downdates and through a refit on every round (`refit`): the
    /// same rows, in the same order, of the same sizes and σ. Returns the rows flagged.
    fn same_search<F>(a: &DMatrix<f64>, r: &DVector<f64>, mut refit: F) -> usize
    where
        F: FnMut(&[usize]) -> (Vec<Vector3<f64>>, usize),
    {
        let n = r.len() / 3;
        let ids: Vec<(u64, Option<u64>)> = (0..n).map(|i| (i as u64 + 1, None)).collect();
        let fits = RowDowndates::new(a, r);
        let settings = OutlierSettings::default();
        let fast = remove_outliers(&ids, &settings, |kept| {
            Ok::<_, Infallible>(fits.residuals(kept))
        });
        let slow = remove_outliers(&ids, &settings, |kept| Ok::<_, Infallible>(refit(kept)));
        match (fast, slow) {
            (Ok((f, fk)), Ok((s, sk))) => {
                assert_eq!(fk, sk);
                assert_eq!(f.len(), s.len());
                for (x, y) in f.iter().zip(&s) {
                    assert_eq!(x.seq, y.seq);
                    // Printed to 1e-4 mm and 0.1 σ.
                    assert!((x.size_mm - y.size_mm).abs() < 1e-7, "{x:?} {y:?}");
                    assert!((x.sigmas - y.sigmas).abs() < 1e-5, "{x:?} {y:?}");
                }
                f.len()
            }
            (
                Err(OutlierError::TooMany { found: a, .. }),
                Err(OutlierError::TooMany { found: b, .. }),
            ) => {
                assert_eq!(a, b);
                a
            }
            (f, s) => panic!("the two searches disagree: {f:?} against {s:?}"),
        }
    }

    #[test]
    fn downdated_fits_equal_lstsq_and_the_normal_equations_on_random_subsets() {
        for seed in 0..12 {
            let dependent = (seed % 3) as usize;
            let (a, r) = case(seed, 80, 12, dependent, 0);
            let fits = RowDowndates::new(&a, &r);
            assert!(
                fits.basis.is_some(),
                "seed {seed}: a clear rank is downdated"
            );
            let mut rng = rand::rngs::StdRng::seed_from_u64(100 + seed);
            for _ in 0..5 {
                let kept: Vec<usize> = (0..80).filter(|_| rng.random_bool(0.9)).collect();
                let (fast, rank) = fits.downdated(&kept).expect("downdate within the margins");
                assert_eq!(rank, 12 - dependent, "seed {seed}");
                let truth = reference(&a, &r, dependent, &kept);
                // Rounding: the basis holds to about 1e-11, the residuals to 1e-9 of their size.
                let tol = 1e-8 * r.amax();
                assert!((&fast - &truth).amax() < tol, "seed {seed}");
                if dependent == 0 {
                    let (slow, slow_rank) = fits.by_lstsq(&kept);
                    assert_eq!(slow_rank, rank);
                    assert!((&fast - &slow).amax() < tol, "seed {seed}");
                }
            }
        }
    }

    #[test]
    fn the_search_flags_what_refits_flag_on_seeded_designs() {
        let mut flagged = 0;
        for seed in 0..24 {
            let dependent = (seed % 3) as usize;
            let (a, r) = case(1000 + seed, 60, 10, dependent, (seed % 4) as usize);
            flagged += if dependent == 0 {
                let fits = RowDowndates::new(&a, &r);
                same_search(&a, &r, |kept| {
                    let (res, rank) = fits.by_lstsq(kept);
                    (as_rows(&res), rank)
                })
            } else {
                same_search(&a, &r, |kept| {
                    (as_rows(&reference(&a, &r, dependent, kept)), 10 - dependent)
                })
            };
        }
        // The planted rows were found (a search that flags nothing would agree trivially).
        assert!(flagged >= 24, "{flagged} rows flagged");
    }

    /// `lstsq` on exactly rank-deficient designs: on seeds of this generator where nalgebra's
    /// SVD of the tall matrix returned a wrong factorisation (1001, 1004, 1007 among them), the
    /// SVD of the small triangular factor that `lstsq` now takes gives the normal equations'
    /// residuals on the independent columns.
    #[test]
    fn lstsq_on_exactly_dependent_columns_equals_the_normal_equations() {
        for seed in (0..24u64).filter(|s| s % 3 != 0) {
            // The designs of `the_search_flags_what_refits_flag_on_seeded_designs`.
            let dependent = (seed % 3) as usize;
            let (a, r) = case(1000 + seed, 60, 10, dependent, (seed % 4) as usize);
            let fits = RowDowndates::new(&a, &r);
            let all: Vec<usize> = (0..60).collect();
            let (res, rank) = fits.by_lstsq(&all);
            assert_eq!(rank, 10 - dependent, "seed {}", 1000 + seed);
            let truth = reference(&a, &r, dependent, &all);
            assert!(
                (&res - &truth).amax() < 1e-8 * r.amax(),
                "seed {}: {}",
                1000 + seed,
                (&res - &truth).amax()
            );
        }
    }

    /// The normal equations on the kept rows of the columns not zero on all of them.
    fn reference_live(a: &DMatrix<f64>, r: &DVector<f64>, kept: &[usize]) -> (DVector<f64>, usize) {
        let ak = rows_of(a, kept);
        let live: Vec<usize> = (0..a.ncols())
            .filter(|&c| ak.column(c).amax() > 0.0)
            .collect();
        let design = DMatrix::from_fn(a.nrows(), live.len(), |row, k| a[(row, live[k])]);
        let dk = rows_of(&design, kept);
        let x = dk
            .tr_mul(&dk)
            .cholesky()
            .expect("independent columns")
            .solve(&dk.tr_mul(&rows_of_vector(r, kept)));
        (r - design * x, live.len())
    }

    #[test]
    fn a_column_living_on_removed_rows_is_fitted_out_or_left_to_lstsq() {
        // Column 0 is nonzero on row 5 only, which is also gross: without it column 0 is zero
        // on every kept row (the rank drops by one), fitted out as lstsq gives it no weight.
        let (mut a, mut r) = case(7, 50, 8, 0, 0);
        a.column_mut(0).fill(0.0);
        a[(15, 0)] = 1.0;
        r[16] += 1.0;
        let fits = RowDowndates::new(&a, &r);
        let kept: Vec<usize> = (0..50).filter(|&i| i != 5).collect();
        let (fast, rank) = fits
            .downdated(&kept)
            .expect("the dead column is fitted out");
        let (truth, live) = reference_live(&a, &r, &kept);
        assert_eq!((rank, live), (7, 7));
        assert!((fast - truth).amax() < 1e-8 * r.amax());
        let flagged = same_search(&a, &r, |kept| {
            let (res, rank) = reference_live(&a, &r, kept);
            (as_rows(&res), rank)
        });
        assert!(flagged >= 1);
        // Nearly dead (1e-9 of the column left on a kept row): lstsq's scaling of that
        // column is not one the downdate can bound, so that round is lstsq.
        a[(30, 0)] = 1e-9;
        let fits = RowDowndates::new(&a, &r);
        assert!(fits.downdated(&kept).is_none());
        assert_eq!(fits.residuals(&kept), {
            let (res, rank) = fits.by_lstsq(&kept);
            (as_rows(&res), rank)
        });
    }

    #[test]
    fn a_design_near_the_rank_tolerance_is_left_to_lstsq() {
        let (mut a, r) = case(11, 40, 6, 0, 1);
        // Column 5 is column 0 turned by 1e-9 rad out of the span: a singular value of about
        // 1e-9 of the largest, between lstsq's tolerance and the downdate's margin.
        let off = DVector::from_fn(120, |row, _| (row as f64 * 1.7).cos());
        let near = a.column(0) * 3.0 + off * (3e-9 * a.column(0).norm() / 120f64.sqrt());
        a.set_column(5, &near);
        let fits = RowDowndates::new(&a, &r);
        assert!(fits.basis.is_none());
        let kept: Vec<usize> = (1..40).collect();
        assert_eq!(fits.residuals(&kept), {
            let (res, rank) = fits.by_lstsq(&kept);
            (as_rows(&res), rank)
        });
    }
}
