//! Naming the physics: projection onto the orthogonal complement of the geometric Jacobian,
//! forward selection (orthogonal matching pursuit) with partial F-tests, the refit, held-out
//! checks and the test of what is left against flexible unnamed bases.
//!
//! Error budget, α = [`ALPHA`] overall, split in three equal parts: the candidate steps
//! (Bonferroni over the candidates remaining at each step), the unnamed bases (Bonferroni over
//! the bases) and the final lack-of-fit test against pure error.
//!
//! Units: stacked residuals in mm (3 rows per measurement); coefficients in each candidate's
//! units (see the candidate files).

use super::noise::{lack_of_fit, pure_error};
use super::report::{locate, EffectReport, FitSummary, Mismatch, Report};
use super::{
    Candidate, Data, DiagnoseError, Index, Standard, ALPHA, AXES, MIN_PURE_ERROR_DOF, MIN_VISIBLE,
    SEPARABLE_CORRELATION,
};
use crate::identification::outliers::{remove_outliers, Outlier, OutlierSettings};
use crate::kinematics::Robot;
use crate::stats::f_sf;
use nalgebra::{DMatrix, DVector};
use std::collections::BTreeMap;

/// An orthonormal basis of the column space of `m` (columns scaled to unit norm first; singular
/// values below `tol` dropped).
pub fn orth_basis(m: &DMatrix<f64>, tol: f64) -> DMatrix<f64> {
    if m.ncols() == 0 {
        return DMatrix::zeros(m.nrows(), 0);
    }
    let mut s = m.clone();
    for mut c in s.column_iter_mut() {
        let n = c.norm();
        if n > 0.0 {
            c /= n;
        }
    }
    let svd = s.svd(true, false);
    let Some(u) = svd.u else {
        return DMatrix::zeros(m.nrows(), 0);
    };
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > tol)
        .collect();
    DMatrix::from_fn(m.nrows(), keep.len(), |r, c| u[(r, keep[c])])
}

/// `x` with the column space of the orthonormal `q` removed (twice, for accuracy).
pub fn project_out(q: &DMatrix<f64>, x: &DMatrix<f64>) -> DMatrix<f64> {
    if q.ncols() == 0 {
        return x.clone();
    }
    let once = x - q * (q.transpose() * x);
    &once - q * (q.transpose() * &once)
}

/// A candidate's visible part after projecting out `q`: an orthonormal basis and the visible
/// fraction ‖(I − QQᵀ)X‖ / ‖X‖ (Frobenius, columns scaled to unit norm), or None when the
/// candidate is numerically absorbed or empty.
pub fn visible_basis(q: &DMatrix<f64>, x: &DMatrix<f64>) -> Option<(DMatrix<f64>, f64)> {
    let mut cols = Vec::new();
    let mut vis2 = 0.0;
    let xp = project_out(q, x);
    for c in 0..x.ncols() {
        let n = x.column(c).norm();
        if n <= 1e-12 * (x.nrows() as f64).sqrt() {
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
    let visible = (vis2 / x.ncols() as f64).sqrt();
    let m = DMatrix::from_columns(&cols);
    let u = orth_basis(&m, 0.1 * MIN_VISIBLE);
    (u.ncols() > 0).then_some((u, visible))
}

/// Partial F-test of adding the orthonormal `u` (already orthogonal to the model) to a model
/// with residual `r` and `dof` residual degrees of freedom: (p-value, ΔSS).
pub fn partial_f(u: &DMatrix<f64>, r: &DVector<f64>, dof: usize) -> (f64, f64) {
    let k = u.ncols();
    if k == 0 || dof <= k {
        return (1.0, 0.0);
    }
    let rss = r.norm_squared();
    let dss = (u.transpose() * r).norm_squared().min(rss);
    let d2 = (dof - k) as f64;
    let f = (dss / k as f64) / ((rss - dss).max(1e-300) / d2);
    (f_sf(f, k as f64, d2), dss)
}

/// Least squares with column scaling and an SVD pseudo-inverse: (solution, (AᵀA)⁺, rank).
pub fn lstsq(a: &DMatrix<f64>, b: &DVector<f64>) -> (DVector<f64>, DMatrix<f64>, usize) {
    let p = a.ncols();
    if p == 0 {
        return (DVector::zeros(0), DMatrix::zeros(0, 0), 0);
    }
    let d: Vec<f64> = (0..p).map(|c| a.column(c).norm().max(1e-300)).collect();
    let mut s = a.clone();
    for (c, dc) in d.iter().enumerate() {
        s.column_mut(c).scale_mut(1.0 / dc);
    }
    let svd = s.svd(true, true);
    let smax = svd.singular_values.max();
    let tol = smax * 1e-10;
    let rank = svd.singular_values.iter().filter(|&&v| v > tol).count();
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return (DVector::zeros(p), DMatrix::zeros(p, p), 0);
    };
    let mut x = DVector::zeros(p);
    let mut cov = DMatrix::zeros(p, p);
    for k in 0..svd.singular_values.len() {
        let sv = svd.singular_values[k];
        if sv <= tol {
            continue;
        }
        let v = vt.row(k).transpose();
        x += &v * (u.column(k).dot(b) / sv);
        cov += &v * v.transpose() / (sv * sv);
    }
    for i in 0..p {
        x[i] /= d[i];
        for j in 0..p {
            cov[(i, j)] /= d[i] * d[j];
        }
    }
    (x, cov, rank)
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

struct Chosen {
    cand: usize,
    x: DMatrix<f64>,
    p: f64,
    visible: f64,
}

/// Runs steps 2 to 6 on a standard fit, then judges outliers against the final model (geometry
/// and named effects). `heldout`: (data, geometric Jacobian, residual) of each held-out
/// recording at the fitted geometry. Returns the report and the rows that fail the outlier test
/// (the caller removes them and runs again).
pub fn run(
    std: &Standard,
    lib: &[Box<dyn Candidate>],
    heldout: &[(Data, DMatrix<f64>, DVector<f64>)],
) -> Result<(Report, Vec<Outlier>), DiagnoseError> {
    let d = &std.data;
    let nrows = 3 * d.len();
    // The standard model: geometry and the instrument's nuisance columns.
    let gn = hcat(&[std.jacobian.clone(), std.nuisance.clone()], nrows);
    let qg_raw = orth_basis(&gn, 1e-9);
    let r0_raw = &std.residual - &qg_raw * (qg_raw.transpose() * &std.residual);
    // Noise floor from pure error.
    let pe = pure_error(d, &std.residual);
    let use_pe = pe.dof >= MIN_PURE_ERROR_DOF;
    // The tests weight each row by 1/σ of its axis (generalised least squares) when the
    // instrument's known variance differs by axis (the panel quantises x and y, not z); an
    // unweighted test would take y's larger variance for structure. All 1 otherwise.
    let wrow = row_weights(std, &pe, use_pe, &r0_raw);
    let w = |m: &DMatrix<f64>| scale_rows(m, &wrow);
    let qg = orth_basis(&w(&gn), 1e-9);
    let rw = DVector::from_iterator(nrows, std.residual.iter().zip(&wrow).map(|(a, b)| a * b));
    let r0 = &rw - &qg * (qg.transpose() * &rw);
    let dof0 = nrows.saturating_sub(qg.ncols());
    if dof0 < 2 * qg.ncols().max(10) {
        return Err(DiagnoseError::TooFew {
            measurements: d.len(),
            unknowns: qg.ncols(),
        });
    }
    let alpha3 = ALPHA / 3.0;
    // Known instrument variance per coordinate that repeated poses cannot show.
    let extra_var = std.instrument_var.iter().sum::<f64>() / 3.0;
    let lof_geo = if use_pe {
        lack_of_fit(&pe, r0_raw.norm_squared(), dof0, extra_var)
    } else {
        None
    };

    // Candidate regressors.
    let xs: Vec<Option<DMatrix<f64>>> = lib.iter().map(|c| c.regressors(d)).collect();
    let xs_w: Vec<Option<DMatrix<f64>>> = xs.iter().map(|x| x.as_ref().map(&w)).collect();
    let mut absorbed = Vec::new();
    let mut remaining = Vec::new();
    let mut visible_geo = vec![0.0; lib.len()];
    let mut basis_geo: Vec<Option<DMatrix<f64>>> = vec![None; lib.len()];
    for (k, x) in xs_w.iter().enumerate() {
        let Some(x) = x else { continue };
        match visible_basis(&qg, x) {
            Some((u, v)) => {
                visible_geo[k] = v;
                basis_geo[k] = Some(u);
                remaining.push(k);
            }
            None => absorbed.push(lib[k].label()),
        }
    }

    // Forward selection.
    let mut q = qg.clone();
    let mut r = r0.clone();
    let mut chosen: Vec<Chosen> = Vec::new();
    let mut first_best: Option<(usize, f64)> = None;
    let mut chosen_geo = DMatrix::zeros(nrows, 0);
    while !remaining.is_empty() {
        let kk = remaining.len() as f64;
        let dof = nrows - q.ncols();
        let mut best: Option<(usize, f64, DMatrix<f64>)> = None;
        for &k in &remaining {
            let Some(x) = &xs_w[k] else { continue };
            let Some((u, _)) = visible_basis(&q, x) else {
                continue;
            };
            // Some combination of it is (nearly) one of the chosen effects: not separable, and
            // its coefficients would fight theirs in the refit.
            if let (Some(bk), true) = (&basis_geo[k], chosen_geo.ncols() > 0) {
                let s = (bk.transpose() * &chosen_geo)
                    .svd(false, false)
                    .singular_values
                    .max();
                if s > SEPARABLE_CORRELATION {
                    continue;
                }
            }
            let (p, _) = partial_f(&u, &r, dof);
            if best.as_ref().is_none_or(|b| p < b.1) {
                best = Some((k, p, u));
            }
        }
        let Some((k, p, u)) = best else { break };
        if first_best.is_none() {
            first_best = Some((k, p));
        }
        if p >= alpha3 / kk {
            break;
        }
        r = &r - &u * (u.transpose() * &r);
        q = DMatrix::from_columns(&q.column_iter().chain(u.column_iter()).collect::<Vec<_>>());
        if let Some(bk) = &basis_geo[k] {
            let cols: Vec<_> = chosen_geo.column_iter().chain(bk.column_iter()).collect();
            chosen_geo = orth_basis(&DMatrix::from_columns(&cols), 1e-6);
        }
        remaining.retain(|&c| c != k);
        chosen.push(Chosen {
            cand: k,
            x: xs[k].clone().unwrap_or_else(|| DMatrix::zeros(nrows, 0)),
            p,
            visible: visible_geo[k],
        });
    }

    // Unnamed bases on what is left, and the final lack of fit.
    let bases = unnamed_bases(d);
    let nb = bases.len().max(1) as f64;
    let dof_final = nrows - q.ncols();
    let mut unexplained_by = Vec::new();
    for (name, b) in &bases {
        if let Some((u, _)) = visible_basis(&q, &w(b)) {
            let (p, dss) = partial_f(&u, &r, dof_final);
            tracing::debug!(basis = %name, k = u.ncols(), p, dss, rss = r.norm_squared(), "unnamed basis");
            if p < alpha3 / nb {
                unexplained_by.push((name.clone(), p));
            }
        }
    }
    // What the named effects leave, unweighted.
    let mut raw_cols = vec![gn.clone()];
    raw_cols.extend(chosen.iter().map(|c| c.x.clone()));
    let q_raw = orth_basis(&hcat(&raw_cols, nrows), 1e-9);
    let r_raw = &std.residual - &q_raw * (q_raw.transpose() * &std.residual);
    let lof_final = if use_pe {
        lack_of_fit(&pe, r_raw.norm_squared(), dof_final, extra_var)
    } else {
        None
    };
    if lof_final.is_some_and(|p| p < alpha3) && unexplained_by.is_empty() {
        unexplained_by.push((
            "structure beyond the repeatability of the reference poses".into(),
            lof_final.unwrap_or(1.0),
        ));
    }
    let unexplained = !unexplained_by.is_empty();
    let significant = !chosen.is_empty() || unexplained || lof_geo.is_some_and(|p| p < alpha3);

    // Refit: geometry and chosen effects together (linear about the geometric fit).
    let mut a_cols: Vec<DMatrix<f64>> = vec![std.jacobian.clone()];
    a_cols.extend(chosen.iter().map(|c| c.x.clone()));
    let a = hcat(&a_cols, nrows);
    let (delta, ata_inv, rank) = lstsq(&a, &std.residual);
    let r_after = &std.residual - &a * &delta;
    let dof_after = nrows.saturating_sub(rank).max(1);
    let s2_after = r_after.norm_squared() / dof_after as f64;
    let sigma = if use_pe {
        (pe.sigma().powi(2) + extra_var).sqrt()
    } else {
        s2_after.sqrt()
    };
    let noise_floor = 3f64.sqrt() * sigma;

    // Effects.
    let mut effects = Vec::new();
    let mut col = std.jacobian.ncols();
    for c in &chosen {
        let k = c.x.ncols();
        let coef: Vec<f64> = (col..col + k).map(|i| delta[i]).collect();
        let cov = DMatrix::from_fn(k, k, |i, j| ata_inv[(col + i, col + j)] * s2_after);
        col += k;
        let cand = &lib[c.cand];
        let beta = DVector::from_column_slice(&coef);
        let xb = &c.x * &beta;
        let m = d.len() as f64;
        let size = (xb.norm_squared() / m).sqrt();
        let g = c.x.transpose() * &xb / (m * size.max(1e-300));
        let size_sigma = (g.transpose() * &cov * &g)[(0, 0)].max(0.0).sqrt();
        let xbw = w(&DMatrix::from_column_slice(nrows, 1, xb.as_slice()));
        let vis_part = project_out(&qg, &xbw);
        let visible_fraction = vis_part.norm() / xbw.norm().max(1e-300);
        let not_separable = alternatives(c.cand, &basis_geo, lib);
        let mut params = BTreeMap::new();
        let mut params_sigma = BTreeMap::new();
        for p in cand.params(&coef, &cov, d) {
            params.insert(p.name.clone(), p.value);
            if p.sigma.is_finite() {
                params_sigma.insert(p.name, p.sigma);
            }
        }
        let (joint, axis, axes) = match cand.index() {
            Index::Joint(j) => (Some(j + 1), None, None),
            Index::Axis(a) => (None, Some(AXES[a].to_string()), None),
            Index::Axes(a, b) => (None, None, Some([AXES[a].to_string(), AXES[b].to_string()])),
        };
        effects.push(EffectReport {
            absorbed_fraction: 1.0 - visible_fraction,
            heldout_rms_with_mm: None,
            heldout_rms_without_mm: None,
            kind: cand.kind().to_string(),
            joint,
            axis,
            axes,
            order: cand.order(),
            params,
            params_sigma,
            size_mm: size,
            size_sigma_mm: size_sigma,
            visible_fraction,
            visible_fraction_of_candidate: c.visible,
            p_value: c.p,
            explanation: cand.explanation(),
            not_separable_from: not_separable,
        });
    }

    // Held-out RMS, with every named effect and without each one in turn.
    let all: Vec<&Chosen> = chosen.iter().collect();
    let (ho_before, ho_after, ho_what) = heldout_rms(std, &all, lib, heldout);
    for (k, e) in effects.iter_mut().enumerate() {
        let others: Vec<&Chosen> = chosen
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != k)
            .map(|(_, c)| c)
            .collect();
        e.heldout_rms_with_mm = ho_after;
        e.heldout_rms_without_mm = heldout_rms(std, &others, lib, heldout).1;
    }

    // Outliers, judged last against the final linear model (geometry and named effects).
    let ids: Vec<(u64, Option<u64>)> = d.seq.iter().copied().zip(d.line.iter().copied()).collect();
    let mut notes = vec![
        "approach directions were taken from row order: each joint's direction is the sign of its change from the previous row, measured or not (carried over when unchanged)".to_string(),
    ];
    if d.t_s.is_none() {
        notes.push(
            "the recording has no t_s on every measured row: time-dependent effects (thermal drift, time trends) were not considered".into(),
        );
    }
    if let Some(n) = &std.instrument_note {
        notes.push(n.clone());
    }
    let outliers = match remove_outliers(&ids, &OutlierSettings::default(), |kept| {
        let ak = rows_of(&a, kept);
        let rk = rows_of(
            &DMatrix::from_column_slice(nrows, 1, std.residual.as_slice()),
            kept,
        );
        let (delta, _, rank) = lstsq(&ak, &DVector::from_column_slice(rk.as_slice()));
        let res = &std.residual - &a * delta;
        Ok::<_, std::convert::Infallible>((
            (0..d.len())
                .map(|i| nalgebra::Vector3::new(res[3 * i], res[3 * i + 1], res[3 * i + 2]))
                .collect(),
            rank,
        ))
    }) {
        Ok((found, _)) => found,
        Err(e) => {
            notes.push(format!("outliers not removed: {e}"));
            Vec::new()
        }
    };

    let where_ = if significant {
        vec![locate(d, &r0_raw, "what the geometric model leaves")]
    } else {
        Vec::new()
    };
    let unexplained_where = if unexplained {
        let mut wh = locate(d, &r_raw, "what the named effects leave");
        let names: Vec<String> = unexplained_by
            .iter()
            .map(|(n, p)| format!("{n} (p = {p:.1e})"))
            .collect();
        wh.description = format!("{}; explained by {}", wh.description, names.join(", "));
        vec![wh]
    } else {
        Vec::new()
    };
    Ok((
        Report {
            notes,
            outliers: Vec::new(),
            mismatch: Mismatch {
                significant,
                rms_mm: rms3(&r0_raw),
                noise_floor_mm: noise_floor,
                noise_floor_method: if use_pe {
                    "pure_error".into()
                } else {
                    "residual_variance".into()
                },
                noise_source: if use_pe {
                    format!(
                        "pure error of {} repeated poses ({} dof)",
                        pe.groups, pe.dof
                    )
                } else {
                    format!(
                    "residual variance after the final model ({} dof): fewer than {MIN_PURE_ERROR_DOF} dof of repeated poses ({}), so per-term tests only",
                    dof_after, pe.dof
                )
                },
                lack_of_fit_p: lof_geo,
                best_candidate: first_best.map(|(k, _)| lib[k].label()),
                best_candidate_p: first_best.map(|(_, p)| p),
                where_,
            },
            effects,
            unexplained,
            unexplained_where,
            absorbed,
            fit: FitSummary {
                measurements: d.len(),
                geometric_parameters: std.free.len(),
                before_rms_mm: rms3(&r0_raw),
                after_rms_mm: rms3(&r_after),
                heldout_before_rms_mm: ho_before,
                heldout_after_rms_mm: ho_after,
                heldout: ho_what,
            },
        },
        outliers,
    ))
}

/// Row weights of the tests: 1/√(σ² + q_a²) for the rows of axis a, scaled so z-like rows keep
/// weight 1, with q_a² the instrument's known variance and σ² the rest of the noise (pure error,
/// else the residual of the unquantised axes). All 1 when the instrument adds nothing.
fn row_weights(
    std: &Standard,
    pe: &super::noise::PureError,
    use_pe: bool,
    r0: &DVector<f64>,
) -> Vec<f64> {
    let n = r0.len();
    let q = std.instrument_var;
    if q.iter().all(|v| *v <= 0.0) {
        return vec![1.0; n];
    }
    let s2 = if use_pe {
        pe.sigma().powi(2)
    } else {
        let plain: Vec<usize> = (0..3).filter(|&a| q[a] <= 0.0).collect();
        let m = (n / 3).max(1) as f64;
        plain
            .iter()
            .map(|&a| (0..n / 3).map(|i| r0[3 * i + a].powi(2)).sum::<f64>() / m)
            .sum::<f64>()
            / plain.len().max(1) as f64
    }
    .max(1e-12);
    (0..n).map(|k| (s2 / (s2 + q[k % 3])).sqrt()).collect()
}

fn scale_rows(m: &DMatrix<f64>, w: &[f64]) -> DMatrix<f64> {
    let mut out = m.clone();
    for (r, wr) in w.iter().enumerate() {
        if *wr != 1.0 {
            out.row_mut(r).scale_mut(*wr);
        }
    }
    out
}

fn hcat(blocks: &[DMatrix<f64>], nrows: usize) -> DMatrix<f64> {
    let cols: Vec<_> = blocks.iter().flat_map(|b| b.column_iter()).collect();
    if cols.is_empty() {
        return DMatrix::zeros(nrows, 0);
    }
    DMatrix::from_columns(&cols)
}

fn alternatives(
    k: usize,
    basis: &[Option<DMatrix<f64>>],
    lib: &[Box<dyn Candidate>],
) -> Vec<String> {
    let Some(uk) = &basis[k] else {
        return Vec::new();
    };
    basis
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k)
        .filter_map(|(i, b)| {
            let b = b.as_ref()?;
            let s = (uk.transpose() * b).svd(false, false).singular_values.max();
            (s > SEPARABLE_CORRELATION).then(|| lib[i].label())
        })
        .collect()
}

/// Held-out RMS before (geometry only) and after (geometry and chosen effects), both fitted on
/// the training part: the `--heldout` recordings when given, else 2 of 8 whole time blocks.
fn heldout_rms(
    std: &Standard,
    chosen: &[&Chosen],
    lib: &[Box<dyn Candidate>],
    heldout: &[(Data, DMatrix<f64>, DVector<f64>)],
) -> (Option<f64>, Option<f64>, String) {
    let d = &std.data;
    let nrows = 3 * d.len();
    let mut a_cols = vec![std.jacobian.clone()];
    a_cols.extend(chosen.iter().map(|c| c.x.clone()));
    let a_all = hcat(&a_cols, nrows);
    if !heldout.is_empty() {
        let (dg, _, _) = lstsq(&std.jacobian, &std.residual);
        let (da, _, _) = lstsq(&a_all, &std.residual);
        let mut before = Vec::new();
        let mut after = Vec::new();
        for (hd, hg, hr) in heldout {
            let mut cols = vec![hg.clone()];
            for c in chosen {
                match lib[c.cand].regressors(hd) {
                    Some(x) => cols.push(x),
                    None => cols.push(DMatrix::zeros(3 * hd.len(), c.x.ncols())),
                }
            }
            let ha = hcat(&cols, 3 * hd.len());
            before.extend((hr - hg * &dg).iter().copied());
            after.extend((hr - ha * &da).iter().copied());
        }
        return (
            Some(rms3(&DVector::from_vec(before))),
            Some(rms3(&DVector::from_vec(after))),
            format!("{} held-out recording(s)", heldout.len()),
        );
    }
    let n = d.len();
    if n < 80 {
        return (
            None,
            None,
            "too few measurements for a held-out split".into(),
        );
    }
    let block = |i: usize| i * 8 / n;
    let (test, train): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| matches!(block(i), 1 | 5));
    let rt = rows_of(
        &DMatrix::from_column_slice(nrows, 1, std.residual.as_slice()),
        &train,
    );
    let rt = DVector::from_column_slice(rt.as_slice());
    let rh = rows_of(
        &DMatrix::from_column_slice(nrows, 1, std.residual.as_slice()),
        &test,
    );
    let rh = DVector::from_column_slice(rh.as_slice());
    let gt = rows_of(&std.jacobian, &train);
    let gh = rows_of(&std.jacobian, &test);
    let at = rows_of(&a_all, &train);
    let ah = rows_of(&a_all, &test);
    let (dg, _, _) = lstsq(&gt, &rt);
    let (da, _, _) = lstsq(&at, &rt);
    (
        Some(rms3(&(&rh - gh * dg))),
        Some(rms3(&(&rh - ah * da))),
        "time blocks 2 and 6 of 8 held out, fitted on the rest".into(),
    )
}
