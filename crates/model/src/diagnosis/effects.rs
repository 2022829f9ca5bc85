//! Stage 4, the effects: each chosen effect as the report states it — its named parameters with
//! their σ, its size (RMS over the measurements of what it does) with σ, the share of it the
//! geometry absorbs, what it cannot be told apart from — and the held-out RMS with every named
//! effect and without each one in turn.
//!
//! Units: sizes in mm (3-D RMS), parameters in each candidate's report units.

use super::heldout::{heldout_rms, Heldout, HeldoutRecording, Terms};
use super::linalg::project_out;
use super::refit::Refit;
use super::report::EffectReport;
use super::screen::Screen;
use super::select::{not_separable_from, Candidates, Chosen, Selection};
use super::{Candidate, Index, Standard, AXES};
use nalgebra::{DMatrix, DVector};
use std::collections::BTreeMap;

/// What the effect stage reads: every earlier stage's result.
#[derive(Debug, Clone, Copy)]
pub struct EffectInputs<'a> {
    /// The standard fit.
    pub std: &'a Standard,
    /// The screen of the standard model.
    pub screen: &'a Screen,
    /// The projected candidates.
    pub candidates: &'a Candidates,
    /// The selection.
    pub selection: &'a Selection,
    /// The refit the effects are read from (the effects' coefficients come first after the
    /// geometry): without the shapes for the effects' reports, with them for the shapes'.
    pub refit: &'a Refit,
}

/// The named effects and the held-out RMS of the model with all of them.
#[derive(Debug, Clone)]
pub struct Effects {
    /// One report per chosen effect, in the order chosen.
    pub reports: Vec<EffectReport>,
    /// Held-out RMS of geometry only and of geometry with every named effect.
    pub heldout: Heldout,
}

/// Reports every chosen effect, with the held-out RMS with and without it.
pub fn describe_effects(
    inp: &EffectInputs<'_>,
    lib: &[Box<dyn Candidate>],
    heldout: &[HeldoutRecording],
) -> Effects {
    let chosen = &inp.selection.chosen;
    let mut col = inp.std.jacobian.ncols();
    let mut reports = Vec::with_capacity(chosen.len());
    for c in chosen {
        reports.push(effect_report(inp, lib, c, col));
        col += c.x.ncols();
    }
    let all: Vec<&Chosen> = chosen.iter().collect();
    let terms = |effects: &[&Chosen]| -> Heldout {
        heldout_rms(
            inp.std,
            Terms {
                effects,
                shapes: &[],
            },
            lib,
            heldout,
        )
    };
    let with_all = terms(&all);
    for (k, e) in reports.iter_mut().enumerate() {
        let others: Vec<&Chosen> = chosen
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != k)
            .map(|(_, c)| c)
            .collect();
        e.heldout_rms_with_mm = with_all.after;
        e.heldout_rms_without_mm = terms(&others).after;
    }
    Effects {
        reports,
        heldout: with_all,
    }
}

/// The report of chosen effect `c`, whose coefficients start at column `col` of the refit.
fn effect_report(
    inp: &EffectInputs<'_>,
    lib: &[Box<dyn Candidate>],
    c: &Chosen,
    col: usize,
) -> EffectReport {
    let d = &inp.std.data;
    let refit = inp.refit;
    let k = c.x.ncols();
    let coef: Vec<f64> = (col..col + k).map(|i| refit.fit.solution[i]).collect();
    let cov = DMatrix::from_fn(k, k, |i, j| {
        refit.fit.normal_inverse[(col + i, col + j)] * refit.s2
    });
    let cand = &lib[c.cand];
    let beta = DVector::from_column_slice(&coef);
    let xb = &c.x * &beta;
    let (size, size_sigma) = size_with_sigma(&c.x, &xb, &cov);
    let xbw = inp
        .screen
        .weigh(&DMatrix::from_column_slice(xb.len(), 1, xb.as_slice()));
    let vis_part = project_out(&inp.screen.basis, &xbw);
    let visible_fraction = vis_part.norm() / xbw.norm().max(1e-300);
    let mut params = BTreeMap::new();
    let mut params_sigma = BTreeMap::new();
    for p in cand.params(&coef, &cov, d) {
        params.insert(p.name.clone(), p.value);
        if p.sigma.is_finite() {
            params_sigma.insert(p.name, p.sigma);
        }
    }
    let (joint, axis, axes) = index_fields(cand.index());
    EffectReport {
        absorbed_fraction: 1.0 - visible_fraction,
        heldout_rms_with_mm: None,
        heldout_rms_without_mm: None,
        kind: cand.kind(),
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
        not_separable_from: not_separable_from(c.cand, inp.candidates, lib),
        heldout_gain: None,
    }
}

/// The size of a fitted term, the 3-D RMS over the measurements of its displacement `v`
/// (stacked, 3 rows per measurement, mm), with its σ by error propagation from the covariance
/// `cov` of the coefficients of its regressors `x` (`v` = `x`·β, or a part of it linear in β).
pub fn size_with_sigma(x: &DMatrix<f64>, v: &DVector<f64>, cov: &DMatrix<f64>) -> (f64, f64) {
    let m = (v.len() / 3) as f64;
    let size = (v.norm_squared() / m).sqrt();
    // Gradient of the size in the coefficients.
    let g = x.transpose() * v / (m * size.max(1e-300));
    let sigma = (g.transpose() * cov * &g)[(0, 0)].max(0.0).sqrt();
    (size, sigma)
}

/// The report's `joint` (1-based), `axis` and `axes` fields.
type IndexFields = (Option<usize>, Option<String>, Option<[String; 2]>);

/// The report fields of a candidate index.
fn index_fields(index: Index) -> IndexFields {
    match index {
        Index::Joint(j) => (Some(j + 1), None, None),
        Index::Axis(a) => (None, Some(AXES[a].to_string()), None),
        Index::Axes(a, b) => (None, None, Some([AXES[a].to_string(), AXES[b].to_string()])),
    }
}
