//! The regression algebra of the diagnosis tests, on stacked residuals (3 rows per measurement,
//! mm): orthonormal bases and projections, a candidate's part the model cannot already show, the
//! partial F-test of adding it, column-scaled least squares, row selection and weighting.

use super::MIN_VISIBLE;
use crate::identification::dense::{self, bounded_svd, gram, tall_r};
use nalgebra::{DMatrix, DVector};
use rigcal_core::stats::{f_sf, ln_f_sf};

/// An orthonormal basis of the column space of `m` (columns scaled to unit norm first; singular
/// values below `tol` dropped).
///
/// How: the singular values and right vectors come from the SVD of the small triangular factor
/// R of the Householder QR of the scaled matrix S (S and R have the same singular values and
/// right vectors), so the rank decision is the one an SVD of S makes, to rounding; the basis is
/// S·V·Σ⁻¹ over the kept directions, orthonormalised once more through the Cholesky factor of
/// its Gram matrix (a full-rank, nearly orthonormal set: the span does not change). On the tall
/// matrices of the diagnosis (thousands of rows, tens of columns) this costs a few passes over
/// S, where the SVD of S itself rotates its left vectors over all rows at every sweep.
pub fn orth_basis(m: &DMatrix<f64>, tol: f64) -> DMatrix<f64> {
    if m.ncols() == 0 {
        return DMatrix::zeros(m.nrows(), 0);
    }
    let s = unit_columns(m);
    if s.nrows() < 2 * s.ncols() {
        return orth_basis_by_svd(s, tol);
    }
    match orth_basis_by_qr(&s, tol) {
        Some(q) => q,
        None => orth_basis_by_svd(s, tol),
    }
}

/// `m` with each non-zero column scaled to unit norm.
fn unit_columns(m: &DMatrix<f64>) -> DMatrix<f64> {
    let mut s = m.clone();
    for mut c in s.column_iter_mut() {
        let n = c.norm();
        if n > 0.0 {
            c /= n;
        }
    }
    s
}

/// [`orth_basis`] of the column-scaled `s` by the SVD of its Householder factor; None when a
/// value is not finite or the kept directions cannot be orthonormalised (then the caller takes
/// the SVD of `s` itself).
fn orth_basis_by_qr(s: &DMatrix<f64>, tol: f64) -> Option<DMatrix<f64>> {
    if s.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let r = tall_r(s);
    let svd = bounded_svd(r, false, true)?;
    let vt = svd.v_t?;
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > tol)
        .collect();
    if keep.is_empty() {
        return Some(DMatrix::zeros(s.nrows(), 0));
    }
    // S·vₖ = σₖ·uₖ: the left vectors of the kept directions.
    let v_scaled = DMatrix::from_fn(s.ncols(), keep.len(), |i, c| {
        vt[(keep[c], i)] / svd.singular_values[keep[c]]
    });
    let u = s * v_scaled;
    // Rounding in S·v is amplified by 1/σ for the weakest kept directions: one Cholesky pass
    // (U ← U·L⁻ᵀ with UᵀU = L·Lᵀ) restores orthonormality without changing the span.
    let chol = nalgebra::Cholesky::new(dense::gram_by_kernel(&u))?;
    let l_inv = chol
        .l()
        .solve_lower_triangular(&DMatrix::identity(keep.len(), keep.len()))?;
    let q = u * l_inv.transpose();
    q.iter().all(|v| v.is_finite()).then_some(q)
}

/// [`orth_basis`] of the column-scaled `s` by its own SVD.
fn orth_basis_by_svd(s: DMatrix<f64>, tol: f64) -> DMatrix<f64> {
    let nrows = s.nrows();
    let Some(svd) = bounded_svd(s, true, false) else {
        return DMatrix::zeros(nrows, 0);
    };
    let Some(u) = svd.u else {
        return DMatrix::zeros(nrows, 0);
    };
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > tol)
        .collect();
    DMatrix::from_fn(nrows, keep.len(), |r, c| u[(r, keep[c])])
}

/// `x` with the column space of the orthonormal `q` removed (twice, for accuracy).
pub fn project_out(q: &DMatrix<f64>, x: &DMatrix<f64>) -> DMatrix<f64> {
    if q.ncols() == 0 {
        return x.clone();
    }
    let n = q.nrows();
    let mut out = x.clone();
    for _ in 0..2 {
        let c = tr_mul(q, &out);
        dense::sub_mul(&mut out, q.as_slice(), n, &c);
    }
    out
}

/// QᵀX without copying Qᵀ ([`dense::transpose_mul_view`]): the same numbers as
/// `q.transpose() * x`, to the bit.
pub fn tr_mul(q: &DMatrix<f64>, x: &DMatrix<f64>) -> DMatrix<f64> {
    dense::transpose_mul_view(q.as_slice(), q.nrows(), &x.as_view())
}

/// A candidate's visible part after projecting out `q`: an orthonormal basis and the visible
/// fraction ‖(I − QQᵀ)X‖ / ‖X‖ (Frobenius, columns scaled to unit norm), or None when the
/// candidate is numerically absorbed or empty.
pub fn visible_basis(q: &DMatrix<f64>, x: &DMatrix<f64>) -> Option<(DMatrix<f64>, f64)> {
    let norms: Vec<f64> = x.column_iter().map(|c| c.norm()).collect();
    visible_basis_of_projection(&norms, &project_out(q, x))
}

/// [`visible_basis`] from a candidate's column norms `norms` and its part `xp` past the model
/// (already projected out, e.g. by [`Projection`]).
pub fn visible_basis_of_projection(
    norms: &[f64],
    xp: &DMatrix<f64>,
) -> Option<(DMatrix<f64>, f64)> {
    visible_basis_in(norms, xp, xp.nrows())
}

/// [`visible_basis_of_projection`] of a candidate over `nrows` stacked rows, given its part
/// past the model `xp` in any form with the same inner products (e.g. compressed to a
/// triangular factor): the basis is in `xp`'s rows.
pub fn visible_basis_in(
    norms: &[f64],
    xp: &DMatrix<f64>,
    nrows: usize,
) -> Option<(DMatrix<f64>, f64)> {
    let mut cols = Vec::new();
    let mut vis2 = 0.0;
    for (c, &n) in norms.iter().enumerate() {
        if n <= 1e-12 * (nrows as f64).sqrt() {
            continue;
        }
        let v = xp.column(c).norm() / n;
        vis2 += v * v;
        if v >= MIN_VISIBLE {
            cols.push(xp.column(c) / n);
        }
    }
    if cols.is_empty() {
        return None;
    }
    let visible = (vis2 / norms.len() as f64).sqrt();
    let m = DMatrix::from_columns(&cols);
    let u = orth_basis(&m, VISIBLE_RANK_TOL);
    (u.ncols() > 0).then_some((u, visible))
}

/// The rank and ΔSS of a candidate's visible part, as [`visible_basis_of_projection`] and
/// [`partial_f_ln`] would find them, without forming its basis: from the eigen-decomposition of
/// the small Gram matrix SᵀS of the visible columns S (scaled to unit norm), the rank counts the
/// singular values √λ above [`VISIBLE_RANK_TOL`], and ΔSS = Σ (vᵢᵀSᵀr)²/λᵢ over them. Outer None:
/// nothing visible (as `visible_basis_of_projection`). Inner None: a singular value lies within
/// a factor √2 of the tolerance, where the Gram matrix's rounding could tip the rank decision;
/// the caller then takes the basis itself. Outer None also when no singular value passes.
pub fn visible_rank_and_dss(
    norms: &[f64],
    xp: &DMatrix<f64>,
    r: &DVector<f64>,
) -> Option<Option<(usize, f64)>> {
    let n = xp.nrows();
    let mut kept = Vec::new();
    let mut scale = Vec::new();
    for (c, &nc) in norms.iter().enumerate() {
        if nc <= 1e-12 * (n as f64).sqrt() {
            continue;
        }
        let pn = xp.column(c).norm();
        if pn / nc >= MIN_VISIBLE {
            kept.push(c);
            scale.push(1.0 / pn);
        }
    }
    if kept.is_empty() {
        return None;
    }
    let s = if kept.len() == xp.ncols() {
        xp.clone()
    } else {
        xp.select_columns(&kept)
    };
    let k = kept.len();
    let g = DMatrix::from_fn(k, k, |i, j| scale[i] * scale[j]);
    let g = gram(&s).component_mul(&g);
    let b = DVector::from_fn(k, |i, _| scale[i] * s.column(i).dot(r));
    // The Gram matrix's entries are sums of n products of unit-norm columns: rounding moves its
    // eigenvalues by at most about k·n·ε.
    let slack = (k * n) as f64 * f64::EPSILON;
    rank_and_dss_of_scaled_gram(g, &b, slack)
}

/// The rank and ΔSS of the columns with (unit-diagonal) Gram matrix `g` and products `b` with
/// the residual, as in [`visible_rank_and_dss`]: singular values √λ above
/// [`VISIBLE_RANK_TOL`] count, ΔSS = Σ (vᵢᵀb)²/λᵢ over them; Some(None) when an eigenvalue lies
/// within a factor 2 (√2 in singular value) or `slack` of the tolerance; None when no direction
/// counts.
fn rank_and_dss_of_scaled_gram(
    g: DMatrix<f64>,
    b: &DVector<f64>,
    slack: f64,
) -> Option<Option<(usize, f64)>> {
    // Not finite (never on bounded data): the caller takes the basis, whose SVD is bounded.
    if g.iter().any(|v| !v.is_finite()) || b.iter().any(|v| !v.is_finite()) {
        return Some(None);
    }
    rank_and_dss_of_eigen(&nalgebra::SymmetricEigen::new(g), b, slack)
}

/// [`rank_and_dss_of_scaled_gram`] from the Gram matrix's eigen-decomposition `eig`.
fn rank_and_dss_of_eigen(
    eig: &nalgebra::SymmetricEigen<f64, nalgebra::Dyn>,
    b: &DVector<f64>,
    slack: f64,
) -> Option<Option<(usize, f64)>> {
    if b.iter().any(|v| !v.is_finite()) {
        return Some(None);
    }
    let t2 = VISIBLE_RANK_TOL * VISIBLE_RANK_TOL;
    let mut rank = 0;
    let mut dss = 0.0;
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 2.0 * t2 && l - slack > t2 {
            rank += 1;
            dss += eig.eigenvectors.column(i).dot(b).powi(2) / l;
        } else if !(l < 0.5 * t2 && l + slack < t2) {
            return Some(None);
        }
    }
    (rank > 0).then_some(Some((rank, dss)))
}

/// The singular-value tolerance of a visible part's basis ([`visible_basis_of_projection`]).
pub const VISIBLE_RANK_TOL: f64 = 0.1 * MIN_VISIBLE;

/// A candidate's columns past an orthonormal basis (projected out twice, as in [`project_out`]),
/// with their norms before the projection.
#[derive(Debug, Clone)]
pub struct Projection {
    /// The column norms of the candidate before any projection.
    pub norms: Vec<f64>,
    /// Its columns past the basis.
    pub xp: DMatrix<f64>,
}

impl Projection {
    /// `x` past the orthonormal `q` (all its columns).
    pub fn new(q: &DMatrix<f64>, x: &DMatrix<f64>) -> Self {
        Projection {
            norms: x.column_iter().map(|c| c.norm()).collect(),
            xp: project_out(q, x),
        }
    }
}

/// A term's columns past a growing orthonormal model, tracked through their Gram matrix: the
/// columns X are projected past the model once, when the term is first tested, and as the model
/// grows by orthonormal directions U (orthogonal to the model before them) the products C = UᵀX
/// are kept and the Gram matrix of the columns past the grown model is updated as
/// G ← G − CᵀC (UᵀX is U's product with the columns themselves, since U is orthogonal to the
/// model X was made past). A test then needs the k × k Gram matrix and the columns' products
/// with the residual, never the projected columns over all rows; those are formed, as
/// X − U·C, only for the terms whose basis or leverages are needed ([`TrackedTerm::past`]).
#[derive(Debug, Clone)]
pub struct TrackedTerm {
    /// The column norms of the term before any projection.
    pub norms: Vec<f64>,
    /// Its columns past the first `made_at` columns of the model.
    xp: DMatrix<f64>,
    /// How many leading model columns `xp` is past.
    made_at: usize,
    /// UᵀX for the model columns U from `made_at` to `upto`, one row per column.
    products: DMatrix<f64>,
    /// The Gram matrix of its columns past the first `upto` columns of the model.
    gram: DMatrix<f64>,
    /// How many leading model columns `gram` is past.
    upto: usize,
}

/// The visible columns of a tracked term and its Gram matrix's eigen-decomposition over them
/// (scaled to unit diagonal), or why there is none ([`TrackedTerm::eigen`]).
struct VisibleEigen {
    /// The visible columns.
    kept: Vec<usize>,
    /// 1 / each visible column's norm past the model.
    scale: Vec<f64>,
    eig: nalgebra::SymmetricEigen<f64, nalgebra::Dyn>,
    /// The rounding bound of the eigenvalues.
    slack: f64,
}

impl TrackedTerm {
    /// `x` past the orthonormal `q` (all its columns).
    pub fn new(q: &DMatrix<f64>, x: &DMatrix<f64>) -> Self {
        let xp = project_out(q, x);
        TrackedTerm {
            norms: x.column_iter().map(|c| c.norm()).collect(),
            gram: dense::gram_by_kernel(&xp),
            products: DMatrix::zeros(0, x.ncols()),
            xp,
            made_at: q.ncols(),
            upto: q.ncols(),
        }
    }

    /// Accounts for the columns of `q` past the first `upto` (`q` starts with the model this
    /// term was last brought up to, unchanged, and has orthonormal columns).
    pub fn catch_up(&mut self, q: &DMatrix<f64>) {
        if q.ncols() > self.upto {
            let n = q.nrows();
            let new = &q.as_slice()[self.upto * n..];
            // A model grown by a few directions, or a term of a few columns: one dot product
            // per entry (nalgebra's kernel does not take such shapes).
            let c = if new.len() <= 5 * n || self.xp.ncols() <= 5 {
                dense::transpose_mul_dots(new, n, &self.xp)
            } else {
                dense::transpose_mul_view(new, n, &self.xp.as_view())
            };
            self.gram -= dense::transpose_mul_view(c.as_slice(), c.nrows(), &c.as_view());
            let old = std::mem::replace(&mut self.products, DMatrix::zeros(0, 0));
            let m = old.nrows();
            self.products = DMatrix::from_fn(m + c.nrows(), c.ncols(), |i, j| {
                if i < m {
                    old[(i, j)]
                } else {
                    c[(i - m, j)]
                }
            });
            self.upto = q.ncols();
        }
    }

    /// The term's columns past the model it was brought up to ([`Self::catch_up`]), over all
    /// rows: X − U·(UᵀX) with the kept products, then projected past U once more for accuracy
    /// (as [`project_out`] does twice). `q` is that model.
    pub fn past(&self, q: &DMatrix<f64>) -> DMatrix<f64> {
        let once = self.past_once(q);
        let n = q.nrows();
        let new = &q.as_slice()[self.made_at * n..self.upto * n];
        if new.is_empty() {
            return once;
        }
        let mut once = once;
        let again = dense::transpose_mul_view(new, n, &once.as_view());
        dense::sub_mul(&mut once, new, n, &again);
        once
    }

    /// X − U·(UᵀX) with the kept products (one pass, for leverages).
    fn past_once(&self, q: &DMatrix<f64>) -> DMatrix<f64> {
        let mut once = self.xp.clone();
        if self.upto > self.made_at {
            let n = q.nrows();
            let u = &q.as_slice()[self.made_at * n..self.upto * n];
            dense::sub_mul(&mut once, u, n, &self.products);
        }
        once
    }

    /// [`visible_rank_and_dss`] of the term past the model it was brought up to, against the
    /// residual `r` of that model (orthogonal to it), from the tracked Gram matrix. Inner None
    /// also where the Gram matrix's rounding could tip whether a column counts as visible.
    pub fn rank_and_dss(&self, r: &DVector<f64>) -> Option<Option<(usize, f64)>> {
        let v = match self.eigen()? {
            Some(v) => v,
            None => return Some(None),
        };
        let b = DVector::from_fn(v.kept.len(), |i, _| {
            v.scale[i] * dense::dot(self.xp.column(v.kept[i]).as_slice(), r.as_slice())
        });
        rank_and_dss_of_eigen(&v.eig, &b, v.slack)
    }

    /// The rank and ΔSS of the term's visible part past the model `q` it was brought up to,
    /// against that model's residual `r`, decided as [`visible_basis_of_projection`] decides
    /// them (the SVD of the Householder factor of the visible columns scaled to unit norm,
    /// singular values above [`VISIBLE_RANK_TOL`]) but without forming the basis:
    /// ΔSS = Σ (vₖᵀSᵀr / σₖ)² over the kept directions. For the terms whose Gram matrix leaves
    /// the rank unsettled ([`Self::rank_and_dss`]). None: nothing visible.
    pub fn rank_and_dss_by_qr(&self, q: &DMatrix<f64>, r: &DVector<f64>) -> Option<(usize, f64)> {
        let xp = self.past_once(q);
        let n = xp.nrows();
        let mut kept = Vec::new();
        for (c, &nc) in self.norms.iter().enumerate() {
            if nc > 1e-12 * (n as f64).sqrt() && xp.column(c).norm() / nc >= MIN_VISIBLE {
                kept.push(c);
            }
        }
        if kept.is_empty() {
            return None;
        }
        let s = unit_columns(&xp.select_columns(&kept));
        if s.nrows() < 2 * s.ncols() || s.iter().any(|v| !v.is_finite()) {
            let (u, _) = visible_basis_of_projection(&self.norms, &self.past(q))?;
            return Some((u.ncols(), (u.transpose() * r).norm_squared()));
        }
        let b = dense::transpose_times(&s, r);
        let svd = bounded_svd(tall_r(&s), false, true)?;
        let vt = svd.v_t?;
        let mut rank = 0;
        let mut dss = 0.0;
        for (k, &sv) in svd.singular_values.iter().enumerate() {
            if sv > VISIBLE_RANK_TOL {
                rank += 1;
                dss += (vt.row(k).transpose().dot(&b) / sv).powi(2);
            }
        }
        (rank > 0).then_some((rank, dss))
    }

    /// An orthonormal basis (to rounding) of the term's visible part past the model `q` it was
    /// brought up to, from the Gram matrix's eigenvectors: S·V·Λ^(−1/2) over the kept
    /// directions, S the visible columns past the model scaled to unit norm. The span and rank
    /// [`visible_basis_of_projection`] gives, for leverages (not for growing the model); None
    /// where the rank decision is not clear-cut or nothing is visible.
    pub fn leverage_basis(&self, q: &DMatrix<f64>) -> Option<DMatrix<f64>> {
        let v = self.eigen()??;
        let t2 = VISIBLE_RANK_TOL * VISIBLE_RANK_TOL;
        let mut dirs = Vec::new();
        for (i, &l) in v.eig.eigenvalues.iter().enumerate() {
            if l > 2.0 * t2 && l - v.slack > t2 {
                dirs.push(i);
            } else if !(l < 0.5 * t2 && l + v.slack < t2) {
                return None;
            }
        }
        if dirs.is_empty() {
            return None;
        }
        let past = self.past_once(q);
        let k = v.kept.len();
        // Column c of the coefficients: the kept column i scaled, times eigenvector c over √λ.
        let coef = DMatrix::from_fn(k, dirs.len(), |i, c| {
            v.scale[i] * v.eig.eigenvectors[(i, dirs[c])] / v.eig.eigenvalues[dirs[c]].sqrt()
        });
        let s = if k == past.ncols() {
            past
        } else {
            past.select_columns(&v.kept)
        };
        Some(s * coef)
    }

    /// The visible columns and their scaled Gram matrix's eigen-decomposition. Outer None:
    /// nothing visible. Inner None: the Gram matrix's rounding could tip whether a column counts
    /// as visible, or it is not finite.
    fn eigen(&self) -> Option<Option<VisibleEigen>> {
        let n = self.xp.nrows();
        // Each tracked Gram entry carries the rounding of n products and of one subtraction
        // per model direction added since: at most about (n + m)·ε·‖xᵢ‖‖xⱼ‖ for the columns
        // past the model the term was made with.
        let m = self.upto - self.made_at;
        let unit = (n + m) as f64 * f64::EPSILON;
        let mut kept = Vec::new();
        let mut scale = Vec::new();
        let mut spread: f64 = 1.0;
        for (c, &nc) in self.norms.iter().enumerate() {
            if nc <= 1e-12 * (n as f64).sqrt() {
                continue;
            }
            let made2 = self.xp.column(c).norm_squared();
            let pn2 = self.gram[(c, c)];
            let edge = (MIN_VISIBLE * nc).powi(2);
            if (pn2 - edge).abs() <= 2.0 * unit * made2 {
                return Some(None);
            }
            if pn2 >= edge {
                kept.push(c);
                scale.push(1.0 / pn2.sqrt());
                spread = spread.max(made2 / pn2);
            }
        }
        if kept.is_empty() {
            return None;
        }
        let k = kept.len();
        let g = DMatrix::from_fn(k, k, |i, j| {
            scale[i] * scale[j] * self.gram[(kept[i], kept[j])]
        });
        if g.iter().any(|v| !v.is_finite()) {
            return Some(None);
        }
        Some(Some(VisibleEigen {
            kept,
            scale,
            eig: nalgebra::SymmetricEigen::new(g),
            slack: k as f64 * unit * spread,
        }))
    }
}

/// Partial F-test of adding the orthonormal `u` (already orthogonal to the model) to a model
/// with residual `r` and `dof` residual degrees of freedom, with the log of the p-value exact
/// where the p-value underflows: (p, ln p, ΔSS). Terms are ranked by ln p, so a 10× effect and
/// its rivals do not all tie at 0.
pub fn partial_f_ln(u: &DMatrix<f64>, r: &DVector<f64>, dof: usize) -> (f64, f64, f64) {
    partial_f_ln_of(u.ncols(), (u.transpose() * r).norm_squared(), r, dof)
}

/// [`partial_f_ln`] of `k` added directions that explain `dss` of the residual `r`.
pub fn partial_f_ln_of(k: usize, dss: f64, r: &DVector<f64>, dof: usize) -> (f64, f64, f64) {
    if k == 0 || dof <= k {
        return (1.0, 0.0, 0.0);
    }
    let rss = r.norm_squared();
    let dss = dss.min(rss);
    let d2 = (dof - k) as f64;
    let f = (dss / k as f64) / ((rss - dss).max(1e-300) / d2);
    (f_sf(f, k as f64, d2), ln_f_sf(f, k as f64, d2), dss)
}

/// A least-squares solution with what the tests need of it.
#[derive(Debug, Clone, PartialEq)]
pub struct LeastSquares {
    /// The solution x minimising ‖A x − b‖.
    pub solution: DVector<f64>,
    /// (AᵀA)⁺: times the residual variance, the covariance of the solution.
    pub normal_inverse: DMatrix<f64>,
    /// Numerical rank of A (singular values of the column-scaled A above 1e-10 of the largest).
    pub rank: usize,
}

/// [`lstsq`]'s rank tolerance: a singular value of the column-scaled design at or below this
/// share of the largest is dropped.
pub(crate) const LSTSQ_RANK_TOL: f64 = 1e-10;

/// Least squares with column scaling and an SVD pseudo-inverse (directions A cannot see get no
/// weight, so nearly absorbed candidates do not blow up the solution).
///
/// How: with S the column-scaled A, the Householder QR of [S | b] = Q·[R r; 0 ρ] carries all of
/// it: S and R have the same singular values σₖ and right vectors vₖ, and the left vectors'
/// products with b are uₖᵀb = u'ₖᵀr for the left vectors u'ₖ of R (uₖ = Q·u'ₖ). So the SVD is
/// taken of the small R instead of the tall S (whose left vectors nalgebra rotates over every
/// row at each sweep), the same solution to rounding. Matrices with fewer than twice as many
/// rows as columns take the SVD of S itself.
pub fn lstsq(a: &DMatrix<f64>, b: &DVector<f64>) -> LeastSquares {
    let p = a.ncols();
    let failed = |p: usize| LeastSquares {
        solution: DVector::zeros(p),
        normal_inverse: DMatrix::zeros(p, p),
        rank: 0,
    };
    if p == 0 {
        return failed(0);
    }
    let d: Vec<f64> = (0..p).map(|c| a.column(c).norm().max(1e-300)).collect();
    let mut s = a.clone();
    for (c, dc) in d.iter().enumerate() {
        s.column_mut(c).scale_mut(1.0 / dc);
    }
    let compressed = if s.nrows() >= 2 * (p + 1) && b.iter().all(|v| v.is_finite()) {
        compress_with(s.clone(), b)
    } else {
        None
    };
    let (s, b) = match compressed {
        Some((r, rb)) => (r, rb),
        None => (s, b.clone()),
    };
    let Some(svd) = bounded_svd(s, true, true) else {
        return failed(p);
    };
    let smax = svd.singular_values.max();
    let tol = smax * LSTSQ_RANK_TOL;
    let rank = svd.singular_values.iter().filter(|&&v| v > tol).count();
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return failed(p);
    };
    let mut x = DVector::zeros(p);
    let mut cov = DMatrix::zeros(p, p);
    for k in 0..svd.singular_values.len() {
        let sv = svd.singular_values[k];
        if sv <= tol {
            continue;
        }
        let v = vt.row(k).transpose();
        x += &v * (u.column(k).dot(&b) / sv);
        cov += &v * v.transpose() / (sv * sv);
    }
    for i in 0..p {
        x[i] /= d[i];
        for j in 0..p {
            cov[(i, j)] /= d[i] * d[j];
        }
    }
    LeastSquares {
        solution: x,
        normal_inverse: cov,
        rank,
    }
}

/// The triangular factor R (p × p) of the tall `s` (p columns) and r, the first p entries of
/// Qᵀb, from the Householder QR of [s | b]; None when a value is not finite.
fn compress_with(s: DMatrix<f64>, b: &DVector<f64>) -> Option<(DMatrix<f64>, DVector<f64>)> {
    let p = s.ncols();
    let mut sb = s.insert_column(p, 0.0);
    sb.set_column(p, b);
    if sb.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let r = tall_r(&sb);
    Some((
        r.view((0, 0), (p, p)).into_owned(),
        r.view((0, p), (p, 1)).column(0).into_owned(),
    ))
}

/// The rows of measurements `idx` from a stacked matrix.
pub fn rows_of(m: &DMatrix<f64>, idx: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(3 * idx.len(), m.ncols(), |r, c| {
        m[(3 * idx[r / 3] + r % 3, c)]
    })
}

/// 3-D RMS (mm) of a stacked residual.
pub fn rms3(r: &DVector<f64>) -> f64 {
    let m = (r.len() / 3).max(1) as f64;
    (r.norm_squared() / m).sqrt()
}

/// The rows of measurements `idx` from a stacked vector.
pub fn rows_of_vector(v: &DVector<f64>, idx: &[usize]) -> DVector<f64> {
    DVector::from_fn(3 * idx.len(), |r, _| v[3 * idx[r / 3] + r % 3])
}

/// `m` with row r scaled by `w[r]` (rows of weight 1 untouched).
pub fn scale_rows(m: &DMatrix<f64>, w: &[f64]) -> DMatrix<f64> {
    let mut out = m.clone();
    for (r, wr) in w.iter().enumerate() {
        if *wr != 1.0 {
            out.row_mut(r).scale_mut(*wr);
        }
    }
    out
}

/// The blocks side by side (an `nrows` × 0 matrix when there are no columns).
pub fn hcat(blocks: &[DMatrix<f64>], nrows: usize) -> DMatrix<f64> {
    let cols: Vec<_> = blocks.iter().flat_map(|b| b.column_iter()).collect();
    if cols.is_empty() {
        return DMatrix::zeros(nrows, 0);
    }
    DMatrix::from_columns(&cols)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(got: f64, want: f64, tol: f64) {
        assert!((got - want).abs() <= tol, "got {got}, want {want}");
    }

    /// A 9 × 3 matrix of full column rank (3 measurements).
    fn tall() -> DMatrix<f64> {
        DMatrix::from_fn(9, 3, |r, c| {
            ((r * 7 + c * 3) % 5) as f64 - 2.0 + (r * c) as f64 * 0.1
        })
    }

    #[test]
    fn orth_basis_is_orthonormal_and_drops_dependent_columns() {
        let a = tall();
        // A fourth column that is a combination of the first two adds no direction.
        let dependent = a.column(0) * 2.0 - a.column(1) * 0.5;
        let m = hcat(
            &[
                a.clone(),
                DMatrix::from_column_slice(9, 1, dependent.as_slice()),
            ],
            9,
        );
        let q = orth_basis(&m, 1e-9);
        assert_eq!(q.ncols(), 3);
        assert!((q.transpose() * &q - DMatrix::identity(3, 3)).norm() < 1e-12);
        // It spans A: projecting A out leaves nothing.
        assert!(project_out(&q, &a).norm() < 1e-12);
        assert_eq!(orth_basis(&DMatrix::zeros(9, 0), 1e-9).ncols(), 0);
    }

    #[test]
    fn orth_basis_spans_what_the_svd_of_the_matrix_keeps() {
        // 600 rows: two exactly dependent columns, one weak direction kept at tol 1e-9 and
        // dropped at 1e-4 (σ ≈ 1e-6 after scaling), against the SVD of the matrix itself.
        let mut a = DMatrix::from_fn(600, 8, |r, c| {
            let x = r as f64 * 0.013 + c as f64 * 0.7;
            (x * (c as f64 + 1.0)).sin() * (1.0 + c as f64)
        });
        let dependent = a.column(1) * 3.0 - a.column(4) * 0.25;
        a.set_column(6, &dependent);
        let other = DVector::from_fn(600, |r, _| (r as f64 * 0.031).cos().powi(3));
        let weak = a.column(2) + &other * (1e-6 * a.column(2).norm() / other.norm());
        a.set_column(7, &weak);
        for tol in [1e-9, 1e-4] {
            let fast = orth_basis(&a, tol);
            let svd = orth_basis_by_svd(unit_columns(&a), tol);
            assert_eq!(fast.ncols(), svd.ncols(), "rank at tol {tol}");
            let k = fast.ncols();
            assert!((fast.transpose() * &fast - DMatrix::identity(k, k)).norm() < 1e-12);
            // The same span: each basis projects the other onto itself.
            assert!(project_out(&fast, &svd).norm() < 1e-8, "span at tol {tol}");
            assert!(project_out(&svd, &fast).norm() < 1e-8, "span at tol {tol}");
        }
        assert_eq!(orth_basis(&a, 1e-9).ncols(), 7);
        assert_eq!(orth_basis(&a, 1e-4).ncols(), 6);
    }

    #[test]
    fn products_with_the_transpose_in_place_equal_the_copied_ones_to_the_bit() {
        let q = orth_basis(
            &DMatrix::from_fn(3000, 9, |r, c| ((r * (c + 2)) as f64 * 1e-3).sin()),
            1e-9,
        );
        let x = DMatrix::from_fn(3000, 14, |r, c| ((r + 31 * c) as f64 * 0.007).cos());
        let r = DMatrix::from_fn(3000, 1, |i, _| (i as f64 * 0.003).sin());
        assert_eq!(tr_mul(&q, &x), q.transpose() * &x);
        assert_eq!(tr_mul(&q, &r), q.transpose() * &r);
        let one = q.columns(0, 1).into_owned();
        assert_eq!(tr_mul(&one, &r), one.transpose() * &r);
        assert_eq!(tr_mul(&one, &x), one.transpose() * &x);
    }

    #[test]
    fn project_out_leaves_the_orthogonal_part() {
        let q = orth_basis(&tall(), 1e-9);
        let x = DMatrix::from_fn(9, 2, |r, c| (r as f64 - 4.0).powi(2) + c as f64);
        let p = project_out(&q, &x);
        assert!((q.transpose() * &p).norm() < 1e-12);
        // x = its part in span(q) + p, and the two parts are orthogonal (Pythagoras).
        let inside = &x - &p;
        close(
            x.norm_squared(),
            inside.norm_squared() + p.norm_squared(),
            1e-10,
        );
        assert_eq!(project_out(&DMatrix::zeros(9, 0), &x), x);
    }

    #[test]
    fn visible_basis_measures_what_the_model_cannot_show() {
        let a = tall();
        let q = orth_basis(&a, 1e-9);
        // A column inside the model is absorbed.
        let inside = DMatrix::from_column_slice(9, 1, (a.column(0) + a.column(2)).as_slice());
        assert!(visible_basis(&q, &inside).is_none());
        // A unit column at 45° to the model: visible fraction 1/√2.
        let u0 = q.column(0).into_owned();
        let mut e = DVector::zeros(9);
        e[4] = 1.0;
        let perp = &e - &q * (q.transpose() * &e);
        let perp = &perp / perp.norm();
        let x = DMatrix::from_column_slice(9, 1, (&u0 + &perp).as_slice());
        let (u, visible) = visible_basis(&q, &x).expect("visible");
        close(visible, 0.5f64.sqrt(), 1e-12);
        assert_eq!(u.ncols(), 1);
        close(u.column(0).dot(&perp).abs(), 1.0, 1e-12);
    }

    /// A model grown in two steps and a term of 6 columns, one nearly inside the model and one
    /// a combination of two others, over 900 rows.
    fn grown_model_and_term() -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, DVector<f64>) {
        let n = 900;
        let f =
            |r: usize, c: usize| ((r as f64 * 0.021 + c as f64 * 0.37) * (c as f64 + 1.3)).sin();
        let model = DMatrix::from_fn(n, 5, f);
        let q0 = orth_basis(&model, 1e-9);
        let extra = project_out(&q0, &DMatrix::from_fn(n, 3, |r, c| f(r, c + 11).powi(2)));
        let q1 = hcat(&[q0.clone(), orth_basis(&extra, 1e-9)], n);
        let mut x = DMatrix::from_fn(n, 6, |r, c| f(r, c + 20) * (1.0 + c as f64));
        let inside = q1.column(6) * 10.0 + x.column(0) * 1e-5;
        x.set_column(4, &inside);
        let combo = x.column(1) * 2.0 - x.column(2);
        x.set_column(5, &combo);
        let y = DVector::from_fn(n, |r, _| f(r, 40) + 0.3 * x[(r, 1)]);
        let r1 = &y - &q1 * (q1.transpose() * &y);
        (q0, q1, x, r1)
    }

    #[test]
    fn a_tracked_term_tests_as_its_basis_past_the_grown_model_does() {
        let (q0, q1, x, r1) = grown_model_and_term();
        // Made past the first model, brought up to the grown one.
        let mut term = TrackedTerm::new(&q0, &x);
        term.catch_up(&q1);
        // The direct route: the columns past the grown model and their orthonormal basis.
        let (u, _) = visible_basis(&q1, &x).expect("visible");
        let dss = (u.transpose() * &r1).norm_squared();
        assert_eq!(
            u.ncols(),
            4,
            "the dependent column adds nothing, the absorbed one is dropped"
        );
        let (rank, got) = term.rank_and_dss(&r1).expect("visible").expect("settled");
        assert_eq!(rank, 4);
        close(got, dss, 1e-9 * dss);
        let (rank, got) = term.rank_and_dss_by_qr(&q1, &r1).expect("visible");
        assert_eq!(rank, 4);
        close(got, dss, 1e-9 * dss);
        // The same part past the grown model, and a leverage basis of the same span.
        assert!((term.past(&q1) - project_out(&q1, &x)).norm() < 1e-10 * x.norm());
        let b = term.leverage_basis(&q1).expect("settled");
        assert_eq!(b.ncols(), 4);
        assert!((b.transpose() * &b - DMatrix::identity(4, 4)).norm() < 1e-8);
        assert!(project_out(&u, &b).norm() < 1e-8 && project_out(&b, &u).norm() < 1e-8);
    }

    #[test]
    fn least_squares_on_the_compressed_problem_equals_the_svd_of_the_matrix() {
        // The SVD pseudo-inverse of the column-scaled matrix itself, written out, against
        // `lstsq` (which takes the SVD of the Householder factor of [S | b]) on 400 rows with
        // columns of very different sizes.
        let a = DMatrix::from_fn(400, 5, |r, c| {
            (r as f64 * 0.05 * (c as f64 + 1.0)).cos() * 10f64.powi(c as i32 - 2)
        });
        let b = DVector::from_fn(400, |r, _| (r as f64 * 0.013).sin() + 0.1);
        let d: Vec<f64> = a.column_iter().map(|c| c.norm()).collect();
        let s = DMatrix::from_fn(400, 5, |r, c| a[(r, c)] / d[c]);
        let svd = s.svd(true, true);
        let (u, vt) = (svd.u.expect("u"), svd.v_t.expect("v"));
        let mut want = DVector::zeros(5);
        for k in 0..5 {
            want += vt.row(k).transpose() * (u.column(k).dot(&b) / svd.singular_values[k]);
        }
        let fit = lstsq(&a, &b);
        assert_eq!(fit.rank, 5);
        for c in 0..5 {
            close(
                fit.solution[c],
                want[c] / d[c],
                1e-9 * (want[c] / d[c]).abs().max(1e-3),
            );
        }
    }

    #[test]
    fn partial_f_ln_is_the_f_test_of_the_added_columns() {
        // 40 rows, residual dof 30, one added direction u = e0 carrying ΔSS = 4 of RSS = 10.
        let mut u = DMatrix::zeros(40, 1);
        u[(0, 0)] = 1.0;
        let mut r = DVector::from_element(40, (6.0f64 / 39.0).sqrt());
        r[0] = 2.0;
        let (p, ln_p, dss) = partial_f_ln(&u, &r, 30);
        close(dss, 4.0, 1e-12);
        // F = (4/1) / (6/29) on (1, 29) degrees of freedom.
        close(p, f_sf(4.0 / (6.0 / 29.0), 1.0, 29.0), 1e-15);
        assert!(p < 1e-3);
        close(ln_p, p.ln(), 1e-9);
        assert_eq!(partial_f_ln(&u, &r, 1), (1.0, 0.0, 0.0));
        assert_eq!(
            partial_f_ln(&DMatrix::zeros(40, 0), &r, 30),
            (1.0, 0.0, 0.0)
        );
    }

    #[test]
    fn lstsq_solves_full_rank_systems_and_reports_rank() {
        let a = tall();
        let x_true = DVector::from_vec(vec![1.5, -2.0, 0.25]);
        let fit = lstsq(&a, &(&a * &x_true));
        assert_eq!(fit.rank, 3);
        assert!((&fit.solution - &x_true).norm() < 1e-10);
        // (AᵀA)⁺ is the inverse for a full-rank A.
        let ata = a.transpose() * &a;
        assert!((&ata * &fit.normal_inverse - DMatrix::identity(3, 3)).norm() < 1e-9);
        // A repeated column: rank 1, and the minimum-norm solution splits the weight evenly.
        let twice = hcat(
            &[a.columns(0, 1).into_owned(), a.columns(0, 1).into_owned()],
            9,
        );
        let fit = lstsq(&twice, &(a.column(0) * 2.0));
        assert_eq!(fit.rank, 1);
        assert!((fit.solution[0] - 1.0).abs() < 1e-10 && (fit.solution[1] - 1.0).abs() < 1e-10);
        assert_eq!(lstsq(&DMatrix::zeros(9, 0), &DVector::zeros(9)).rank, 0);
    }

    #[test]
    fn rows_of_pick_whole_measurements_and_rms3_is_per_measurement() {
        let m = DMatrix::from_fn(9, 2, |r, c| (10 * r + c) as f64);
        let picked = rows_of(&m, &[2, 0]);
        assert_eq!(picked.nrows(), 6);
        assert_eq!(picked[(0, 1)], 61.0);
        assert_eq!(picked[(3, 0)], 0.0);
        let v = DVector::from_fn(9, |r, _| r as f64);
        assert_eq!(rows_of_vector(&v, &[1]).as_slice(), &[3.0, 4.0, 5.0]);
        // Two measurements of 3-D length 3 and 4: RMS √((9 + 16)/2).
        let r = DVector::from_vec(vec![3.0, 0.0, 0.0, 0.0, 0.0, 4.0]);
        close(rms3(&r), 12.5f64.sqrt(), 1e-15);
    }

    #[test]
    fn scale_rows_weights_each_row() {
        let m = DMatrix::from_element(3, 2, 2.0);
        let w = scale_rows(&m, &[1.0, 0.5, 3.0]);
        assert_eq!(w.row(0).iter().copied().collect::<Vec<_>>(), vec![2.0, 2.0]);
        assert_eq!(w[(1, 1)], 1.0);
        assert_eq!(w[(2, 0)], 6.0);
        assert_eq!(hcat(&[], 6).shape(), (6, 0));
    }
}
