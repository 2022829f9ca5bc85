//! Stage 2b, what is left: the residual after the named effects tested against flexible unnamed
//! bases (Bonferroni over the bases, at [`ALPHA_PART`]) and, with pure error, the final lack of
//! fit. Either failing makes the report say `unexplained` and where.
//!
//! Units: stacked residuals in mm (3 rows per measurement).

use super::linalg::{hcat, orth_basis, partial_f, visible_basis};
use super::noise::lack_of_fit;
use super::screen::{Screen, ALPHA_PART};
use super::select::Selection;
use super::{Data, Standard};
use crate::kinematics::Robot;
use nalgebra::{DMatrix, DVector};

/// What the named effects leave.
#[derive(Debug, Clone)]
pub struct Leftover {
    /// What explains the rest (an unnamed basis, or the lack of fit), with its p-value; empty
    /// when nothing does.
    pub unexplained_by: Vec<(String, f64)>,
    /// The residual after geometry, nuisance and the named effects, unweighted (mm).
    pub residual_raw: DVector<f64>,
}

impl Leftover {
    /// A significant structured residual remains that no candidate explains.
    pub fn unexplained(&self) -> bool {
        !self.unexplained_by.is_empty()
    }
}

/// Tests what the selection leaves against the unnamed bases of `d` and, with pure error,
/// against the repeatability of the reference poses.
pub fn test_leftover(std: &Standard, screen: &Screen, sel: &Selection) -> Leftover {
    let d = &std.data;
    let nrows = screen.rows();
    let bases = unnamed_bases(d);
    let nb = bases.len().max(1) as f64;
    let dof_final = nrows - sel.basis.ncols();
    let mut unexplained_by = Vec::new();
    for (name, b) in &bases {
        if let Some((u, _)) = visible_basis(&sel.basis, &screen.weigh(b)) {
            let (p, dss) = partial_f(&u, &sel.residual, dof_final);
            tracing::debug!(basis = %name, k = u.ncols(), p, dss, rss = sel.residual.norm_squared(), "unnamed basis");
            if p < ALPHA_PART / nb {
                unexplained_by.push((name.clone(), p));
            }
        }
    }
    // What the named effects leave, unweighted.
    let mut raw_cols = vec![screen.model.clone()];
    raw_cols.extend(sel.chosen.iter().map(|c| c.x.clone()));
    let q_raw = orth_basis(&hcat(&raw_cols, nrows), 1e-9);
    let residual_raw = &std.residual - &q_raw * (q_raw.transpose() * &std.residual);
    let lof_final = if screen.use_pure_error {
        lack_of_fit(
            &screen.pure_error,
            residual_raw.norm_squared(),
            dof_final,
            screen.extra_var,
        )
    } else {
        None
    };
    if lof_final.is_some_and(|p| p < ALPHA_PART) && unexplained_by.is_empty() {
        unexplained_by.push((
            "structure beyond the repeatability of the reference poses".into(),
            lof_final.unwrap_or(1.0),
        ));
    }
    Leftover {
        unexplained_by,
        residual_raw,
    }
}

/// The Legendre polynomial P_n(x) (three-term recurrence).
fn legendre(x: f64, n: usize) -> f64 {
    let (mut p0, mut p1) = (1.0, x);
    if n == 0 {
        return 1.0;
    }
    for k in 1..n {
        let k = k as f64;
        let p2 = ((2.0 * k + 1.0) * x * p1 - k * p0) / (k + 1.0);
        p0 = p1;
        p1 = p2;
    }
    p1
}

/// `v` mapped linearly onto [−1, 1], where the Legendre polynomials are orthogonal.
fn normalise(v: &[f64]) -> Vec<f64> {
    let lo = v.iter().copied().fold(f64::MAX, f64::min);
    let hi = v.iter().copied().fold(f64::MIN, f64::max);
    let w = (hi - lo).max(1e-300);
    v.iter().map(|x| 2.0 * (x - lo) / w - 1.0).collect()
}

/// Flexible unnamed bases: (name, columns). Per moving joint Legendre polynomials of degree 1–4
/// on each axis, time polynomials of degree 1–3 on each axis, and a quadratic in the measured
/// (modelled) position on each axis.
pub fn unnamed_bases(d: &Data) -> Vec<(String, DMatrix<f64>)> {
    let n = d.len();
    let per_axis = |name: String, feats: Vec<Vec<f64>>| {
        let mut m = DMatrix::zeros(3 * n, 3 * feats.len());
        for (f, v) in feats.iter().enumerate() {
            for i in 0..n {
                for a in 0..3 {
                    m[(3 * i + a, 3 * f + a)] = v[i];
                }
            }
        }
        (name, m)
    };
    let mut out = Vec::new();
    for &j in &d.moving {
        let x = normalise(&d.obs.iter().map(|o| o.q[j]).collect::<Vec<_>>());
        let feats = (1..=4)
            .map(|k| x.iter().map(|v| legendre(*v, k)).collect())
            .collect();
        out.push(per_axis(
            format!("a smooth function of joint {}", j + 1),
            feats,
        ));
    }
    if let Some(t) = &d.t_s {
        let x = normalise(t);
        let feats = (1..=3)
            .map(|k| x.iter().map(|v| legendre(*v, k)).collect())
            .collect();
        out.push(per_axis("a smooth function of time".into(), feats));
    }
    // Modelled, not measured, positions: measured ones carry the residual itself (the stacked
    // positions lie in the span of the length parameters' columns).
    let modelled: Vec<_> = d.obs.iter().map(|o| d.chain.position(&o.q, &d.e)).collect();
    let p: Vec<Vec<f64>> = (0..3)
        .map(|a| normalise(&modelled.iter().map(|m| m[a]).collect::<Vec<_>>()))
        .collect();
    let mut feats: Vec<Vec<f64>> = p.clone();
    for a in 0..3 {
        for b in a..3 {
            feats.push((0..n).map(|i| p[a][i] * p[b][i]).collect());
        }
    }
    out.push(per_axis(
        "a smooth function of the workspace position".into(),
        feats,
    ));
    out
}
