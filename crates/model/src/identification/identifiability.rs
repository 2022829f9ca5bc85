//! Which error parameters position measurements can identify.
//!
//! \[M\] is stacked over poses (3 rows per pose, one column per parameter) at the nominal
//! parameters. Columns are scaled to unit 2-norm so millimetres and radians compare. The rank is
//! the number of singular values above `RANK_TOL` · σ_max. The basis is chosen by Gram–Schmidt
//! in a priority order (conventions §4): a column enters when what is left of it after the
//! columns already chosen exceeds `RANK_TOL`'s square root. A parameter left out either has no
//! effect on the measured point at all, or its column is a combination of basis columns — the
//! coefficients of that combination are its null-space vector, reported in parameter units.
//!
//! κ is eq. (4): κ(\[M\]) = ‖MᵀM‖·‖(MᵀM)⁻¹‖ = (σ_max/σ_min)² of the scaled basis columns.

use super::robot_at::Kinematics;
use nalgebra::{DMatrix, DVector, Vector3};
use rigcal_core::kinematics::{ErrorParams, ParamId, ParamLayout, Robot, TransformId};
use rigcal_core::rig::{FrameMode, Rig};

/// Singular values below this fraction of the largest count as zero.
pub const RANK_TOL: f64 = 1e-9;
/// A column whose norm is below this (mm per unit) has no effect on the measured point.
const NO_EFFECT_TOL: f64 = 1e-9;

/// The outcome of an identifiability analysis.
#[derive(Debug, Clone)]
pub struct Identifiability {
    /// Numerical rank of \[M\] over the candidate parameters.
    pub rank: usize,
    /// Layout indices of the identifiable basis, in the order chosen.
    pub basis: Vec<usize>,
    /// Candidates with no effect on the measured point.
    pub no_effect: Vec<usize>,
    /// Candidates outside the basis, with the basis combination that has the same effect:
    /// `(parameter, [(basis parameter, coefficient in parameter units)])`, largest terms first.
    pub confounded: Vec<(usize, Vec<(usize, f64)>)>,
    /// κ of eq. (4) on the scaled basis columns.
    pub kappa: f64,
    /// Singular values of the scaled candidate matrix, largest first.
    pub singular_values: Vec<f64>,
    /// Number of poses used.
    pub poses: usize,
}

/// The candidate parameters of a rig in priority order: measurement frame and marker first when
/// they are free, then the rig's preferred basis, then every other kinematic parameter in chain
/// order. Fixed frame and marker parameters are not candidates.
pub fn candidate_order(rig: &Rig) -> Vec<usize> {
    let layout = rig.chain.layout();
    let mut order = Vec::new();
    let free_frame = rig.calibration.measurement_frame == FrameMode::Free;
    let free_marker = rig.calibration.marker == FrameMode::Free;
    for (i, id) in layout.ids().iter().enumerate() {
        if (id.transform == TransformId::Frame && free_frame)
            || (id.transform == TransformId::Marker && free_marker)
        {
            order.push(i);
        }
    }
    for id in &rig.calibration.basis_priority {
        if let Some(i) = layout.index_of(*id) {
            if !order.contains(&i) && is_kinematic(*id) {
                order.push(i);
            }
        }
    }
    for (i, id) in layout.ids().iter().enumerate() {
        if is_kinematic(*id) && !order.contains(&i) {
            order.push(i);
        }
    }
    order
}

fn is_kinematic(id: ParamId) -> bool {
    !matches!(id.transform, TransformId::Frame | TransformId::Marker)
}

/// Stacks \[M\] (3 rows per pose) over the given layout columns at parameters `e`.
pub fn stacked_jacobian(
    robot: &dyn Robot,
    e: &ErrorParams,
    poses: &[Vec<f64>],
    columns: &[usize],
) -> DMatrix<f64> {
    let k = Kinematics::at(robot, e);
    let mut m = DMatrix::zeros(3 * poses.len(), columns.len());
    let mut cols = vec![Vector3::zeros(); columns.len()];
    for (row, q) in poses.iter().enumerate() {
        k.position_and_columns(q, columns, &mut cols);
        for (c, col) in cols.iter().enumerate() {
            m.fixed_view_mut::<3, 1>(3 * row, c).copy_from(col);
        }
    }
    m
}

/// Analyses identifiability of the `candidates` (layout indices, in priority order) over `poses`.
pub fn analyse(robot: &dyn Robot, poses: &[Vec<f64>], candidates: &[usize]) -> Identifiability {
    let e = ErrorParams::zeros(robot.layout());
    let m = stacked_jacobian(robot, &e, poses, candidates);
    analyse_factor(&triangular_factor(m), poses.len(), candidates)
}

/// [`analyse`] from any matrix R with RᵀR = \[M\]ᵀ\[M\] (its triangular factor, say), \[M\] stacked
/// at the nominal parameters over `poses` poses (3 rows per pose, one column per candidate, in
/// priority order).
///
/// Every decision depends on \[M\] only through the inner products of its columns, so it is
/// taken on the triangular factor R of \[M\] = Q·R (Householder, backward stable column by
/// column like the SVD of \[M\], so the column scaling may follow it): the singular values, the
/// Gram–Schmidt residuals and the least-squares combinations of R equal those of \[M\] up to
/// rounding, at a fraction of the cost.
pub(crate) fn analyse_factor(
    r: &DMatrix<f64>,
    poses: usize,
    candidates: &[usize],
) -> Identifiability {
    let m = r;
    let norms: Vec<f64> = (0..m.ncols()).map(|c| m.column(c).norm()).collect();
    let scale = (3 * poses) as f64;
    let mut no_effect = Vec::new();
    let mut effective = Vec::new();
    for (c, &n) in norms.iter().enumerate() {
        if n < NO_EFFECT_TOL * scale.sqrt() {
            no_effect.push(candidates[c]);
        } else {
            effective.push(c);
        }
    }
    let r = DMatrix::from_fn(m.nrows(), effective.len(), |row, k| {
        m[(row, effective[k])] / norms[effective[k]]
    });
    let mut singular_values: Vec<f64> = if r.ncols() > 0 {
        r.clone()
            .svd(false, false)
            .singular_values
            .iter()
            .copied()
            .collect()
    } else {
        Vec::new()
    };
    singular_values.sort_by(|a, b| b.total_cmp(a));
    let smax = singular_values.first().copied().unwrap_or(0.0);
    let rank = singular_values
        .iter()
        .filter(|&&s| s > RANK_TOL * smax)
        .count();

    // Ordered Gram–Schmidt (twice, for orthogonality) picks the basis in priority order.
    let gs_tol = RANK_TOL.sqrt();
    let mut q_basis: Vec<DVector<f64>> = Vec::new();
    let mut chosen: Vec<usize> = Vec::new();
    for k in 0..effective.len() {
        let mut v = r.column(k).clone_owned();
        for _ in 0..2 {
            for b in &q_basis {
                let d = b.dot(&v);
                v -= b * d;
            }
        }
        let n = v.norm();
        if n > gs_tol && chosen.len() < rank {
            q_basis.push(v / n);
            chosen.push(k);
        }
    }
    let basis: Vec<usize> = chosen.iter().map(|&k| candidates[effective[k]]).collect();

    // R's columns in parameter units: the coordinates of [M]'s columns in Q.
    let b_cols: Vec<usize> = chosen.iter().map(|&k| effective[k]).collect();
    let unscaled = |k: usize| r.column(k) * norms[effective[k]];
    let mb = DMatrix::from_fn(r.nrows(), chosen.len(), |row, c| {
        r[(row, chosen[c])] * norms[b_cols[c]]
    });
    let kappa = kappa_eq4(&mb);
    let svd_b = mb.clone().svd(true, true);
    let mut confounded = Vec::new();
    for k in 0..effective.len() {
        if chosen.contains(&k) {
            continue;
        }
        let col = unscaled(k);
        let coef = svd_b
            .solve(&col, 1e-12)
            .unwrap_or_else(|_| DVector::zeros(b_cols.len()));
        let mut terms: Vec<(usize, f64)> = coef
            .iter()
            .enumerate()
            .map(|(i, &c)| (candidates[b_cols[i]], c))
            .collect();
        terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        confounded.push((candidates[effective[k]], terms));
    }
    Identifiability {
        rank,
        basis,
        no_effect,
        confounded,
        kappa,
        singular_values,
        poses,
    }
}

/// The triangular factor R of a tall matrix (the matrix itself when it is not taller than
/// wide): RᵀR = AᵀA, so R has A's singular values and column inner products.
pub(crate) fn triangular_factor(a: DMatrix<f64>) -> DMatrix<f64> {
    if a.nrows() <= a.ncols() || a.ncols() == 0 {
        return a;
    }
    super::dense::householder_r(a)
}

/// κ of eq. (4) for a matrix: (σ_max/σ_min)² after scaling each column to unit norm.
pub fn kappa_eq4(m: &DMatrix<f64>) -> f64 {
    if m.ncols() == 0 {
        return 1.0;
    }
    let mut scaled = m.clone();
    for mut col in scaled.column_iter_mut() {
        let n = col.norm();
        if n > 0.0 {
            col /= n;
        } else {
            col.fill(0.0);
        }
    }
    let sv = triangular_factor(scaled).svd(false, false).singular_values;
    let smax = sv.max();
    let smin = sv.min();
    if smin <= 0.0 {
        f64::INFINITY
    } else {
        (smax / smin).powi(2)
    }
}

/// A readable report of an analysis.
pub fn report(layout: &ParamLayout, a: &Identifiability, candidates: usize) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let name = |i: usize| layout.symbol(layout.ids()[i]);
    let _ = writeln!(
        s,
        "rank of [M]: {} of {} candidate parameters ({} poses, position only)",
        a.rank, candidates, a.poses
    );
    let _ = writeln!(
        s,
        "identifiable basis ({}): {}",
        a.basis.len(),
        a.basis
            .iter()
            .map(|&i| name(i))
            .collect::<Vec<_>>()
            .join(" ")
    );
    let _ = writeln!(
        s,
        "κ (eq. 4, column-scaled, = (σmax/σmin)²): {:.1}",
        a.kappa
    );
    if !a.no_effect.is_empty() {
        let _ = writeln!(
            s,
            "no effect on the measured position ({}): {}",
            a.no_effect.len(),
            a.no_effect
                .iter()
                .map(|&i| name(i))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    if !a.confounded.is_empty() {
        let _ = writeln!(
            s,
            "not identifiable: each has the same effect as a combination of basis parameters"
        );
        for (p, terms) in &a.confounded {
            let pid = layout.ids()[*p];
            let shown: Vec<String> = terms
                .iter()
                .take(4)
                .filter(|(_, c)| c.abs() > 1e-6)
                .map(|(b, c)| {
                    let bid = layout.ids()[*b];
                    let (cv, unit) = coefficient_units(*c, pid, bid);
                    format!("{cv:+.4}{unit}·{}", name(*b))
                })
                .collect();
            let _ = writeln!(s, "  {:<10} ≡ {}", name(*p), shown.join(" "));
        }
    }
    s
}

/// A coefficient "basis units per parameter unit", converted to file units.
fn coefficient_units(c: f64, p: ParamId, b: ParamId) -> (f64, &'static str) {
    match (p.kind.is_angle(), b.kind.is_angle()) {
        (false, false) | (true, true) => (c, ""),
        (true, false) => (c.to_radians(), " mm/°"),
        (false, true) => (c.to_degrees(), " °/mm"),
    }
}
