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

use super::dense::bounded_svd;
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
    /// Basis parameters the poses do not determine ([`analyse_determined`]): left out of
    /// `basis`, held at their nominal values; empty from [`analyse`].
    pub undetermined: Vec<Undetermined>,
}

/// Below this, a basis column's part independent of the determined columns (relative to the
/// column's own length, after the measurement frame) leaves its parameter undetermined: the
/// pivoted QR diagonal |R_kk| / ‖column k‖ of the column-scaled \[M\], as FIGAROH's base
/// parameter selection reads the diagonal of a column-pivoted QR. At 10⁻³ a parameter's own
/// effect on the measured points is at least 0.1 % of its whole effect, so its estimate is at
/// most about a thousand times noisier than the same parameter measured alone; κ (eq. 4) of
/// the determined set stays below about 10⁶ · (number of parameters). The synthetic rigs'
/// designs keep every basis parameter well above it (smallest ≈ 10⁻¹); the UR10's Series D
/// (ISO cubes, one tool direction) falls below it for the marker's z (κ 6.2·10⁷ before).
pub const DETERMINED_TOL: f64 = 1e-3;

/// A basis parameter the poses do not determine.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Undetermined {
    /// Its layout index.
    pub param: usize,
    /// Its column's part independent of the determined columns, relative to its length
    /// (the pivoted QR diagonal; below [`DETERMINED_TOL`]).
    pub independent: f64,
    /// The determined parameters that take over its effect: `(parameter, coefficient in
    /// parameter units)`, largest first. A shift δ of this parameter moves the measured points
    /// as the shifts `coefficient · δ` of these do, to within `independent`.
    pub combination: Vec<(usize, f64)>,
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
    // No SVD (a value not finite: the inputs are bounded before, so never on data) leaves no
    // singular value, rank 0 and an empty basis: nothing is fitted.
    let mut singular_values: Vec<f64> = if r.ncols() > 0 {
        bounded_svd(r.clone(), false, false)
            .map(|svd| svd.singular_values.iter().copied().collect())
            .unwrap_or_default()
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
    let svd_b = bounded_svd(mb.clone(), true, true);
    let mut confounded = Vec::new();
    for k in 0..effective.len() {
        if chosen.contains(&k) {
            continue;
        }
        let col = unscaled(k);
        let coef = svd_b
            .as_ref()
            .and_then(|svd| svd.solve(&col, 1e-12).ok())
            .unwrap_or_else(|| DVector::zeros(b_cols.len()));
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
        undetermined: Vec::new(),
    }
}

/// [`analyse`], then the basis reduced to what the poses determine: rank-revealing QR with
/// column pivoting on the column-scaled \[M\] of the basis ([`DETERMINED_TOL`]). The measurement
/// frame's parameters come first and always stay (each recording re-registers its frame, so it
/// has no nominal to hold); then the column with the largest part independent of those chosen
/// enters, until none is left above the threshold. The others are moved to
/// [`Identifiability::undetermined`] with the combination of determined parameters that
/// takes over their effect; a fit holds them at nominal.
pub fn analyse_determined(
    robot: &dyn Robot,
    poses: &[Vec<f64>],
    candidates: &[usize],
) -> Identifiability {
    let e = ErrorParams::zeros(robot.layout());
    let m = stacked_jacobian(robot, &e, poses, candidates);
    determined_factor(
        &triangular_factor(m),
        poses.len(),
        candidates,
        robot.layout(),
    )
}

/// [`analyse_determined`] from the triangular factor of \[M\] (as [`analyse_factor`]).
pub(crate) fn determined_factor(
    r: &DMatrix<f64>,
    poses: usize,
    candidates: &[usize],
    layout: &ParamLayout,
) -> Identifiability {
    let mut a = analyse_factor(r, poses, candidates);
    restrict_to_determined(r, candidates, layout, &mut a);
    a
}

/// Moves the basis parameters the columns of `r` (candidate order) do not determine out of
/// the basis (see [`analyse_determined`]); κ is then that of the determined columns.
fn restrict_to_determined(
    r: &DMatrix<f64>,
    candidates: &[usize],
    layout: &ParamLayout,
    a: &mut Identifiability,
) {
    let column = |p: usize| {
        candidates
            .iter()
            .position(|&c| c == p)
            .map(|c| r.column(c).clone_owned())
    };
    let cols: Vec<(usize, DVector<f64>)> = a
        .basis
        .iter()
        .filter_map(|&p| column(p).map(|c| (p, c)))
        .collect();
    let is_frame = |p: usize| layout.ids()[p].transform == TransformId::Frame;
    let unit = |v: &DVector<f64>| {
        let n = v.norm();
        if n > 0.0 {
            v / n
        } else {
            v.clone()
        }
    };
    let mut q: Vec<DVector<f64>> = Vec::new();
    let independent = |q: &[DVector<f64>], v: &DVector<f64>| {
        let mut w = unit(v);
        for _ in 0..2 {
            for b in q {
                let d = b.dot(&w);
                w -= b * d;
            }
        }
        w
    };
    let mut chosen: Vec<usize> = Vec::new();
    for (p, c) in cols.iter().filter(|(p, _)| is_frame(*p)) {
        let w = independent(&q, c);
        q.push(unit(&w));
        chosen.push(*p);
    }
    let mut left: Vec<&(usize, DVector<f64>)> =
        cols.iter().filter(|(p, _)| !is_frame(*p)).collect();
    let share: Vec<f64> = loop {
        let share: Vec<f64> = left
            .iter()
            .map(|(_, c)| independent(&q, c).norm())
            .collect();
        let best = share
            .iter()
            .enumerate()
            .max_by(|x, y| x.1.total_cmp(y.1))
            .map(|(k, &s)| (k, s));
        let Some((k, s)) = best else { break share };
        if s < DETERMINED_TOL {
            break share;
        }
        let (p, c) = left.remove(k);
        q.push(unit(&independent(&q, c)));
        chosen.push(*p);
    };
    if left.is_empty() {
        return;
    }
    // The basis keeps its priority order; the determined columns' own κ replaces the basis's.
    a.basis.retain(|p| chosen.contains(p));
    let mb = DMatrix::from_columns(
        &a.basis
            .iter()
            .filter_map(|&p| column(p))
            .collect::<Vec<_>>(),
    );
    a.kappa = kappa_eq4(&mb);
    let svd = bounded_svd(mb, true, true);
    a.undetermined = left
        .iter()
        .zip(&share)
        .map(|((p, c), &independent)| {
            let coef = svd
                .as_ref()
                .and_then(|svd| svd.solve(c, 1e-12).ok())
                .unwrap_or_else(|| DVector::zeros(a.basis.len()));
            let mut combination: Vec<(usize, f64)> =
                a.basis.iter().copied().zip(coef.iter().copied()).collect();
            combination.sort_by(|x, y| y.1.abs().total_cmp(&x.1.abs()));
            Undetermined {
                param: *p,
                independent,
                combination,
            }
        })
        .collect();
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
    let Some(svd) = bounded_svd(triangular_factor(scaled), false, false) else {
        return f64::INFINITY;
    };
    let sv = svd.singular_values;
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
    if !a.undetermined.is_empty() {
        let _ = write!(s, "{}", undetermined_text(layout, &a.undetermined, name));
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

/// The lines that name the undetermined parameters, each with the determined combination that
/// takes over its effect (`name(i)` names layout index i).
pub fn undetermined_text(
    layout: &ParamLayout,
    undetermined: &[Undetermined],
    name: impl Fn(usize) -> String,
) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    if undetermined.is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "not determined by these poses (held at nominal, not exported; independent part below {DETERMINED_TOL:.0e} of the column):"
    );
    for u in undetermined {
        let pid = layout.ids()[u.param];
        let shown: Vec<String> = u
            .combination
            .iter()
            .take(4)
            .filter(|(_, c)| c.abs() > 1e-6)
            .map(|(b, c)| {
                let (cv, unit) = coefficient_units(*c, pid, layout.ids()[*b]);
                format!("{cv:+.4}{unit}·{}", name(*b))
            })
            .collect();
        let _ = writeln!(
            s,
            "  {:<10} independent part {:.1e}; its effect ≈ {}",
            name(u.param),
            u.independent,
            if shown.is_empty() {
                "none".to_string()
            } else {
                shown.join(" ")
            }
        );
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
