//! Small dense kernels on column-major storage for identification's tall matrices (thousands
//! of rows, tens of columns): the Householder triangular factor and the Gram matrix, written
//! as contiguous dot products and updates so the compiler vectorises them.

use nalgebra::{DMatrix, DVector};

/// R of A = Q·R by Householder reflections, on A's column-major storage (m ≥ n): each
/// reflection is a dot product and an update of contiguous column tails. A row of R may have
/// either sign, which leaves RᵀR unchanged.
pub(crate) fn householder_r(mut a: DMatrix<f64>) -> DMatrix<f64> {
    let (m, n) = a.shape();
    let mut diagonal = vec![0.0; n];
    let data = a.as_mut_slice();
    for k in 0..n {
        let (done, rest) = data.split_at_mut((k + 1) * m);
        let v = &mut done[k * m + k..];
        let norm = dot(v, v).sqrt();
        if norm == 0.0 {
            continue;
        }
        // v = x − α·e₁ with α of the sign opposite x₀ (no cancellation); vᵀv = 2‖x‖(‖x‖ + |x₀|).
        let x0 = v[0];
        let alpha = if x0 > 0.0 { -norm } else { norm };
        v[0] = x0 - alpha;
        let vtv = 2.0 * norm * (norm + x0.abs());
        diagonal[k] = alpha;
        for j in 0..n - k - 1 {
            let c = &mut rest[j * m + k..(j + 1) * m];
            let w = 2.0 * dot(v, c) / vtv;
            axpy(-w, v, c);
        }
    }
    DMatrix::from_fn(n, n, |i, j| match i.cmp(&j) {
        std::cmp::Ordering::Less => a[(i, j)],
        std::cmp::Ordering::Equal => diagonal[i],
        std::cmp::Ordering::Greater => 0.0,
    })
}

/// An R factor of A (RᵀR = AᵀA, m ≥ n) for tall A, by blocks of rows: the Householder factor
/// of each block of at least [`TALL_BLOCK_ROWS`] rows (which stays in cache while its
/// reflections are applied, where one reflection of the whole of A streams all of it from
/// memory), then of those factors stacked (TSQR). A = diag(Q₁…Q_b)·Q′·R with orthogonal
/// factors, so R has A's singular values and right singular vectors and is backward stable as
/// [`householder_r`] is; its rows' signs and rounding may differ from that function's.
pub(crate) fn tall_r(a: &DMatrix<f64>) -> DMatrix<f64> {
    let (m, n) = a.shape();
    let per_block = TALL_BLOCK_ROWS.max(2 * n);
    let blocks = m / per_block;
    if blocks < 2 {
        return householder_r(a.clone());
    }
    let mut stacked = DMatrix::zeros(blocks * n, n);
    for b in 0..blocks {
        let (from, to) = (b * m / blocks, (b + 1) * m / blocks);
        let r = householder_r(a.rows(from, to - from).into_owned());
        stacked.rows_mut(b * n, n).copy_from(&r);
    }
    householder_r(stacked)
}

/// The fewest rows of a block of [`tall_r`]: 2048 rows of a few tens of columns fit in a core's
/// second-level cache.
const TALL_BLOCK_ROWS: usize = 2048;

/// xᵀy with four partial sums (so the compiler can use vector registers).
pub(crate) fn dot(x: &[f64], y: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (xc, yc) = (x.chunks_exact(4), y.chunks_exact(4));
    let tail: f64 = xc
        .remainder()
        .iter()
        .zip(yc.remainder())
        .map(|(a, b)| a * b)
        .sum();
    for (a, b) in xc.zip(yc) {
        for i in 0..4 {
            acc[i] += a[i] * b[i];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// y ← y + s·x.
fn axpy(s: f64, x: &[f64], y: &mut [f64]) {
    for (b, a) in y.iter_mut().zip(x) {
        *b += s * a;
    }
}

/// AᵀA of a column-major matrix, each entry of the upper triangle one dot product of two
/// contiguous columns, mirrored to the lower.
pub(crate) fn gram(a: &DMatrix<f64>) -> DMatrix<f64> {
    let (m, n) = a.shape();
    let data = a.as_slice();
    let mut g = DMatrix::zeros(n, n);
    for i in 0..n {
        let ci = &data[i * m..(i + 1) * m];
        for j in i..n {
            let v = dot(ci, &data[j * m..(j + 1) * m]);
            g[(i, j)] = v;
            g[(j, i)] = v;
        }
    }
    g
}

/// Aᵀx of a column-major matrix.
pub(crate) fn transpose_times(a: &DMatrix<f64>, x: &DVector<f64>) -> DVector<f64> {
    let m = a.nrows();
    let data = a.as_slice();
    DVector::from_fn(a.ncols(), |i, _| {
        dot(&data[i * m..(i + 1) * m], x.as_slice())
    })
}

/// AᵀB for A of `rows` rows held column-major in `a` (e.g. a run of a matrix's columns), read
/// in place: Aᵀ is a strided view of A's storage, so no copy of it is made (on the diagnosis's
/// tall matrices that copy, tens of megabytes per call, cost more than the product), and the
/// product goes through nalgebra's matrix-multiply kernel (its own `tr_mul` takes an
/// entry-by-entry dot product, several times slower here). The kernel sees the same numbers in
/// the same order as for a copy of Aᵀ, so the result is the same to the bit.
pub(crate) fn transpose_mul_view(
    a: &[f64],
    rows: usize,
    b: &nalgebra::DMatrixView<'_, f64>,
) -> DMatrix<f64> {
    assert_eq!(
        rows,
        b.nrows(),
        "transpose_mul_view: A and B have different row counts"
    );
    if rows == 0 || a.is_empty() {
        return DMatrix::zeros(a.len().checked_div(rows).unwrap_or(0), b.ncols());
    }
    let cols = a.len() / rows;
    if cols <= NALGEBRA_SMALL_DIM || rows <= NALGEBRA_SMALL_DIM || b.ncols() <= NALGEBRA_SMALL_DIM {
        return transpose_mul_sequential(a, rows, b);
    }
    // Row i of Aᵀ is column i of A: a row stride of `rows`, a column stride of 1.
    let at = nalgebra::DMatrixView::from_slice_with_strides(a, cols, rows, rows, 1);
    at * b
}

/// Up to this many rows or columns (of any operand) nalgebra 0.35 multiplies by its own column
/// loop instead of the matrix-multiply kernel (`SMALL_DIM` in `blas_uninit::gemm_uninit`). That
/// loop must never see the strided view of Aᵀ: its `axcpy_uninit` walks a strided column for
/// as many steps as the column's underlying slice is long, not as the column has entries, and
/// reads past the storage (a crash seen here while this was written).
const NALGEBRA_SMALL_DIM: usize = 5;

/// AᵀB for A of `rows` rows held column-major in `a`, each entry one [`dot`] of two contiguous
/// columns (vectorised; rounding as `dot`'s four partial sums): for products with a side of
/// at most a few columns, where nalgebra leaves its matrix-multiply kernel for a scalar loop.
pub(crate) fn transpose_mul_dots(a: &[f64], rows: usize, b: &DMatrix<f64>) -> DMatrix<f64> {
    assert_eq!(
        rows,
        b.nrows(),
        "transpose_mul_dots: A and B have different row counts"
    );
    let cols = a.len().checked_div(rows).unwrap_or(0);
    let bs = b.as_slice();
    DMatrix::from_fn(cols, b.ncols(), |i, l| {
        dot(&a[i * rows..(i + 1) * rows], &bs[l * rows..(l + 1) * rows])
    })
}

/// AᵀB as nalgebra's column loop computes it for the copied Aᵀ when a dimension is small: each
/// entry the sum over rows j = 0, 1, … in order of A[j, i]·B[j, l], no fused multiply-add (so
/// the same to the bit). Four entries at a time, each still summed in order, so the additions
/// of one entry need not wait for another's.
fn transpose_mul_sequential(
    a: &[f64],
    rows: usize,
    b: &nalgebra::DMatrixView<'_, f64>,
) -> DMatrix<f64> {
    let cols = a.len() / rows;
    let mut out = DMatrix::zeros(cols, b.ncols());
    for l in 0..b.ncols() {
        let bl = b.column(l);
        let bl: Vec<f64> = bl.iter().copied().collect();
        let mut i = 0;
        while i < cols {
            let w = (cols - i).min(4);
            let mut acc = [0.0f64; 4];
            for (c, slot) in acc.iter_mut().enumerate().take(w) {
                *slot = a[(i + c) * rows] * bl[0];
            }
            for (j, &bj) in bl.iter().enumerate().skip(1) {
                for (c, slot) in acc.iter_mut().enumerate().take(w) {
                    *slot += a[(i + c) * rows + j] * bj;
                }
            }
            for (c, v) in acc.iter().enumerate().take(w) {
                out[(i + c, l)] = *v;
            }
            i += w;
        }
    }
    out
}

/// X ← X − U·C in place, for U of `rows` rows held column-major in `u` (e.g. a run of a
/// matrix's columns) and C of U's columns by X's, with no temporary of X's size. Through the matrix-multiply kernel when every dimension is past nalgebra's small
/// sizes; otherwise (a term of a few columns, or a model grown by a few directions) by blocks
/// of rows, so U is read once whatever C's width (nalgebra's own loop reads all of U once per
/// column of C). Rounding differs from forming U·C first by the order of the subtractions.
pub(crate) fn sub_mul(x: &mut DMatrix<f64>, u: &[f64], rows: usize, c: &DMatrix<f64>) {
    let k = x.ncols();
    sub_mul_slice(x.as_mut_slice(), k, u, rows, c);
}

/// [`sub_mul`] on the `k` columns of `rows` rows held column-major in `x` (e.g. a run of a
/// matrix's columns).
pub(crate) fn sub_mul_slice(x: &mut [f64], k: usize, u: &[f64], rows: usize, c: &DMatrix<f64>) {
    let n = rows;
    let m = u.len().checked_div(rows).unwrap_or(0);
    assert_eq!(
        (x.len(), c.nrows(), c.ncols()),
        (n * k, m, k),
        "sub_mul: shapes differ"
    );
    if n == 0 || m == 0 || k == 0 {
        return;
    }
    if n > NALGEBRA_SMALL_DIM && m > NALGEBRA_SMALL_DIM && k > NALGEBRA_SMALL_DIM {
        let uv = nalgebra::DMatrixView::from_slice(u, n, m);
        nalgebra::DMatrixViewMut::from_slice(x, n, k).gemm(-1.0, &uv, c, 1.0);
        return;
    }
    const BLOCK: usize = 512;
    let mut from = 0;
    while from < n {
        let len = BLOCK.min(n - from);
        for j in 0..m {
            let uj = &u[j * n + from..j * n + from + len];
            for l in 0..k {
                let w = c[(j, l)];
                if w == 0.0 {
                    continue;
                }
                let xl = &mut x[l * n + from..l * n + from + len];
                for (xr, ur) in xl.iter_mut().zip(uj) {
                    *xr -= w * ur;
                }
            }
        }
        from += len;
    }
}

/// AᵀA through the matrix-multiply kernel, made exactly symmetric (the mean of the product and
/// its transpose): [`gram`]'s dot product per entry reads every column once per other column,
/// which on tall matrices of tens of columns costs several times more.
pub(crate) fn gram_by_kernel(a: &DMatrix<f64>) -> DMatrix<f64> {
    let g = transpose_mul_view(a.as_slice(), a.nrows(), &a.as_view());
    let gt = g.transpose();
    (g + gt) * 0.5
}

/// The convergence tolerance of nalgebra's own `svd` (5 ε): bounded SVDs give its results.
pub(crate) const SVD_EPSILON: f64 = 5.0 * f64::EPSILON;

/// Most sweeps an SVD may take per column before it is abandoned: convergence takes a few per
/// column on any finite matrix.
const SVD_SWEEPS_PER_COLUMN: usize = 1_000;

/// The SVD of `m`, or `None` when `m` holds a value that is not finite or the iteration does
/// not converge within a bound. nalgebra's `svd` iterates without a bound and never returns on
/// an infinity or a NaN: every SVD of identification and diagnosis goes through here, so no
/// input can hang one.
pub(crate) fn bounded_svd(
    m: DMatrix<f64>,
    compute_u: bool,
    compute_v: bool,
) -> Option<nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>> {
    if m.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let sweeps = SVD_SWEEPS_PER_COLUMN * m.ncols().min(m.nrows()).max(1);
    m.try_svd(compute_u, compute_v, SVD_EPSILON, sweeps)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// AᵀB through a copy of Aᵀ (A of `rows` rows, column-major in `a`): the reference the
    /// in-place products are checked against.
    fn copied_transpose_mul(a: &[f64], rows: usize, b: &DMatrix<f64>) -> DMatrix<f64> {
        nalgebra::DMatrixView::from_slice(a, rows, a.len() / rows).transpose() * b
    }

    #[test]
    fn gram_and_transpose_times_equal_the_products() {
        let a = DMatrix::from_fn(103, 5, |r, c| {
            ((r * 7 + c * 3) % 11) as f64 - 4.5 + c as f64
        });
        let x = DVector::from_fn(103, |r, _| (r as f64 * 0.1).sin());
        assert!((gram(&a) - a.transpose() * &a).norm() < 1e-10);
        assert!((transpose_times(&a, &x) - a.transpose() * &x).norm() < 1e-12);
        let b = DMatrix::from_fn(103, 7, |r, c| (r as f64 * 0.3 + c as f64).cos());
        let want = a.transpose() * &b;
        let got = transpose_mul_view(a.as_slice(), 103, &b.as_view());
        assert!((got - &want).norm() < 1e-12 * want.norm());
        // Columns 1..4 of A, read in place.
        let part = transpose_mul_view(&a.as_slice()[103..4 * 103], 103, &b.as_view());
        assert!((part - want.rows(1, 3)).norm() < 1e-12 * want.norm());
    }

    #[test]
    fn the_view_product_equals_the_copied_transpose_to_the_bit() {
        // Tall A (inner dimension past the kernel's blocks) and short ones (nalgebra's own
        // loop below 6 rows or columns), against the product with a copy of Aᵀ.
        for (rows, ca, cb) in [(3001, 23, 17), (3001, 2, 9), (40, 7, 1), (600, 6, 6)] {
            let a = DMatrix::from_fn(rows, ca, |r, c| ((r * 13 + c * 7) as f64 * 0.011).sin());
            let b = DMatrix::from_fn(rows, cb, |r, c| ((r * 5 + c * 3) as f64 * 0.017).cos());
            let want = copied_transpose_mul(a.as_slice(), rows, &b);
            let got = transpose_mul_view(a.as_slice(), rows, &b.as_view());
            assert_eq!(got, want, "{rows} x {ca} by {cb}");
            let sub = b.columns(1, cb - 1).into_owned();
            let part = transpose_mul_view(&a.as_slice()[rows..], rows, &sub.as_view());
            assert_eq!(
                part,
                copied_transpose_mul(&a.as_slice()[rows..], rows, &sub)
            );
        }
    }

    #[test]
    fn in_place_products_equal_the_plain_ones() {
        // Every route of `sub_mul` (kernel, blocks of rows for few columns or few directions,
        // rows past one block) and `gram_by_kernel`, against nalgebra's products.
        for (n, m, k) in [(1100, 9, 7), (1100, 3, 7), (1100, 9, 2), (40, 1, 1)] {
            let u = DMatrix::from_fn(n, m, |r, c| ((r * 3 + c * 11) as f64 * 0.013).sin());
            let c = DMatrix::from_fn(m, k, |r, c| (r as f64 - 0.5 * c as f64).cos());
            let x = DMatrix::from_fn(n, k, |r, c| ((r + 7 * c) as f64 * 0.021).cos());
            let want = &x - &u * &c;
            let mut got = x.clone();
            sub_mul(&mut got, u.as_slice(), n, &c);
            assert!((&got - &want).norm() < 1e-12 * want.norm(), "{n} {m} {k}");
            let want = u.transpose() * &x;
            let got = transpose_mul_dots(u.as_slice(), n, &x);
            assert!((&got - &want).norm() < 1e-12 * want.norm().max(1.0));
            let g = gram_by_kernel(&u);
            assert_eq!(g, g.transpose());
            assert!((&g - u.transpose() * &u).norm() < 1e-12 * g.norm());
        }
    }

    #[test]
    fn the_householder_factor_has_the_matrix_inner_products_and_singular_values() {
        // A tall matrix with columns of very different sizes and one exactly dependent column.
        let mut a = DMatrix::from_fn(301, 6, |r, c| {
            let x = r as f64 * 0.37 + c as f64;
            if c == 0 {
                500.0 * x.cos()
            } else {
                (x * (c as f64 + 1.0)).sin()
            }
        });
        let dependent = a.column(1) * 2.0 - a.column(0) * 0.002;
        a.set_column(5, &dependent);
        let r = householder_r(a.clone());
        let (g, h) = (a.tr_mul(&a), r.tr_mul(&r));
        for i in 0..6 {
            for j in 0..6 {
                assert!((g[(i, j)] - h[(i, j)]).abs() < 1e-9 * g.max(), "{i} {j}");
            }
            for k in i + 1..6 {
                assert_eq!(r[(k, i)], 0.0);
            }
        }
        let (sa, sr) = (a.singular_values(), r.singular_values());
        let (mut sa, mut sr): (Vec<f64>, Vec<f64>) =
            (sa.iter().copied().collect(), sr.iter().copied().collect());
        sa.sort_by(f64::total_cmp);
        sr.sort_by(f64::total_cmp);
        for (x, y) in sa.iter().zip(&sr) {
            assert!((x - y).abs() < 1e-12 * sa[5], "{x} vs {y}");
        }
        // The dependent column leaves a zero singular value.
        assert!(sr[0] < 1e-12 * sr[5], "{}", sr[0]);
    }

    #[test]
    fn the_blocked_factor_has_the_matrix_inner_products_and_singular_values() {
        // 9 001 rows (4 blocks of uneven size), columns of very different sizes, one dependent.
        let mut a = DMatrix::from_fn(9001, 7, |r, c| {
            let x = r as f64 * 0.0137 + c as f64;
            if c == 0 {
                300.0 * x.cos()
            } else {
                (x * (c as f64 + 1.0)).sin() + 0.01 * c as f64
            }
        });
        let dependent = a.column(2) * 0.5 - a.column(0) * 0.01;
        a.set_column(6, &dependent);
        let r = tall_r(&a);
        assert_eq!(r.shape(), (7, 7));
        let (g, h) = (a.tr_mul(&a), r.tr_mul(&r));
        for i in 0..7 {
            for j in 0..7 {
                assert!((g[(i, j)] - h[(i, j)]).abs() < 1e-10 * g.max(), "{i} {j}");
            }
            for k in i + 1..7 {
                assert_eq!(r[(k, i)], 0.0);
            }
        }
        // The singular values of the plain factor (an independent route), to rounding.
        let mut sa: Vec<f64> = householder_r(a.clone())
            .singular_values()
            .iter()
            .copied()
            .collect();
        let mut sr: Vec<f64> = r.singular_values().iter().copied().collect();
        sa.sort_by(f64::total_cmp);
        sr.sort_by(f64::total_cmp);
        for (x, y) in sa.iter().zip(&sr) {
            assert!((x - y).abs() < 1e-11 * sa[6], "{x} vs {y}");
        }
        assert!(sr[0] < 1e-11 * sr[6], "{}", sr[0]);
    }
}
