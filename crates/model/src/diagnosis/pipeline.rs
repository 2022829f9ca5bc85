//! One round of the diagnosis on a standard fit (steps 2 to 7 of the module documentation of
//! [`super`]): screen → select (library and shapes) → what is left → refit → effects → the
//! discrepancy term → outliers, then the report.
//!
//! Error budget, α = [`ALPHA`](super::ALPHA) overall, split in three equal parts
//! ([`ALPHA_PART`]): the candidate steps (Bonferroni over the candidates remaining at each step),
//! the shape bases (Bonferroni over the bases, and only when sizeable) and the final lack-of-fit
//! test against pure error.
//!
//! Units: stacked residuals in mm (3 rows per measurement); coefficients in each candidate's
//! units (see the candidate files).

use super::ambiguity::separate_harmonics_from_dents;
use super::crossval::{self, HeldoutGain};
use super::discrepancy::describe;
use super::effects::{describe_effects, EffectInputs};
use super::heldout::{Heldout, HeldoutRecording};
use super::linalg::rms3;
use super::outliers::{judge_outliers, outlier_model};
use super::refit::{refit, refit_shapes_on_named, Refit};
use super::report::WeakEffect;
use super::report::{locate, FitSummary, Mismatch, Report, WhereReport};
use super::screen::{screen, Screen, ALPHA_PART};
use super::select::{
    build_shapes, forward_selection, project_candidates, set_aside, Candidates, Selection, Shapes,
};
use super::unnamed::{test_leftover, Leftover};
use super::{Candidate, DiagnoseError, Standard, MIN_PURE_ERROR_DOF};
use crate::identification::outliers::Outlier;
use nalgebra::DMatrix;

/// Runs one round on a standard fit. `heldout`: each held-out recording at the fitted
/// geometry; `sessions`: each held-out session with its frame refitted and the basis of its
/// frame Jacobian ([`super::sessions::session_for_judgement`]). Returns the report (without `outliers`: the caller fills in what it removed) and
/// the rows that fail the outlier test against the final model (the caller removes them and
/// runs again).
pub fn run(
    std: &Standard,
    lib: &[Box<dyn Candidate>],
    heldout: &[HeldoutRecording],
    sessions: &[(HeldoutRecording, DMatrix<f64>)],
) -> Result<(Report, Vec<Outlier>), DiagnoseError> {
    let screen = screen(std)?;
    let candidates = project_candidates(&screen, lib, &std.data);
    let mut shapes = build_shapes(&screen, &std.data);
    let mut selection = forward_selection(&screen, &candidates, &mut shapes, &std.data);
    let judged = judge_on_heldout(
        &screen,
        &candidates,
        &shapes,
        &mut selection,
        lib,
        (heldout, sessions),
        &std.data,
    );
    let leftover = test_leftover(std, &screen, &selection, &shapes);
    let significant = mismatch_remains(&screen, &selection, &leftover);
    let named = refit(std, &screen, &selection, false);
    let full = refit(std, &screen, &selection, true);
    let staged = refit_shapes_on_named(std, &screen, &selection, &named);
    let inputs = EffectInputs {
        std,
        screen: &screen,
        candidates: &candidates,
        selection: &selection,
        refit: &staged,
    };
    // The effects as the model file carries them: sized in the refit without the shapes, which
    // can trade with an effect they are nearly collinear with and inflate both.
    let named_inputs = EffectInputs {
        refit: &named,
        ..inputs
    };
    let mut effects = describe_effects(&named_inputs, lib, heldout);
    for (e, g) in effects.reports.iter_mut().zip(judged.gains) {
        e.heldout_gain = g;
    }
    let described = describe(&inputs, lib, heldout, rms3(&named.residual));
    let mut notes = notes(std);
    notes.extend(judged.notes);
    notes.extend(selection.dropped.iter().map(|&k| {
        format!(
            "{} was not claimed: it only soaked up part of a shape outside the library (the located shape explains what it fitted)",
            lib[k].label()
        )
    }));
    let outliers = match judge_outliers(std, &outlier_model(std, &screen, &selection, &full)) {
        Ok(found) => found,
        Err(e) => {
            notes.push(format!("outliers not removed: {e}"));
            Vec::new()
        }
    };
    let report = Report {
        notes,
        outliers: Vec::new(),
        mismatch: mismatch(std, &screen, &selection, &full, lib, significant),
        unexplained: leftover.unexplained(),
        unexplained_where: unexplained_where(std, &leftover),
        out_of_library: described.shapes,
        discrepancy: described.report,
        effects: effects.reports,
        below_evidence: judged.weak,
        absorbed: candidates.absorbed,
        fit: fit_summary(std, &screen, &named, effects.heldout),
    };
    Ok((report, outliers))
}

/// The held-out judgement of the chosen effects, applied to the selection.
struct Judged {
    /// The held-out gain of each effect left in the selection, in its order.
    gains: Vec<Option<HeldoutGain>>,
    /// The effects set aside.
    weak: Vec<WeakEffect>,
    /// Why the recording could not be judged, when it could not; why a harmonic was preferred
    /// to a local dent, when one was ([`super::ambiguity`]).
    notes: Vec<String>,
}

/// Judges the chosen effects on held-out data ([`crossval::judge`]) and sets aside from
/// `selection` those that do not earn their place.
fn judge_on_heldout(
    screen: &Screen,
    candidates: &Candidates,
    shapes: &Shapes,
    selection: &mut Selection,
    lib: &[Box<dyn Candidate>],
    (heldout, sessions): (&[HeldoutRecording], &[(HeldoutRecording, DMatrix<f64>)]),
    data: &super::Data,
) -> Judged {
    let mut j = crossval::judge(screen, candidates, selection, lib, heldout, sessions, data);
    let preferred = separate_harmonics_from_dents(&mut j, screen, candidates, selection, lib, data);
    let n = selection.chosen.len();
    let weak_idx: Vec<usize> = j.weak.iter().map(|w| w.0).collect();
    let weak = j
        .weak
        .iter()
        .map(|(i, g, why)| {
            let c = &lib[selection.chosen[*i].cand];
            WeakEffect {
                label: c.label(),
                kind: c.kind(),
                gain: g.clone(),
                reason: why.clone(),
            }
        })
        .collect();
    let gains = (0..n)
        .filter(|i| !weak_idx.contains(i))
        .map(|i| j.kept.iter().find(|k| k.0 == i).map(|k| k.1.clone()))
        .collect();
    set_aside(screen, selection, candidates, shapes, &weak_idx);
    Judged {
        gains,
        weak,
        notes: j.not_judged.into_iter().chain(preferred).collect(),
    }
}

/// Whether a mismatch remains after the geometric fit: an effect was named, something is left
/// unexplained, or the geometry alone fails its lack-of-fit test.
fn mismatch_remains(screen: &Screen, selection: &Selection, leftover: &Leftover) -> bool {
    !selection.chosen.is_empty()
        || leftover.unexplained()
        || screen.lack_of_fit_p.is_some_and(|p| p < ALPHA_PART)
}

/// How the diagnosis read this recording.
fn notes(std: &Standard) -> Vec<String> {
    let mut notes = vec![
        "approach directions were taken from row order: each joint's direction is the sign of its change from the previous row, measured or not (carried over when unchanged)".to_string(),
    ];
    if std.data.t_s.is_none() {
        notes.push(
            "the recording has no t_s on every measured row: time-dependent effects (thermal drift, time trends) were not considered".into(),
        );
    }
    if let Some(n) = &std.instrument_note {
        notes.push(n.clone());
    }
    notes
}

/// The mismatch test's figures, and where the mismatch is when it is `significant`.
fn mismatch(
    std: &Standard,
    screen: &Screen,
    sel: &Selection,
    refit: &Refit,
    lib: &[Box<dyn Candidate>],
    significant: bool,
) -> Mismatch {
    let pe = &screen.pure_error;
    let (method, source) = if screen.use_pure_error {
        (
            "pure_error",
            format!(
                "pure error of {} repeated poses ({} dof)",
                pe.groups, pe.dof
            ),
        )
    } else {
        (
            "residual_variance",
            format!(
                "residual variance after the final model ({} dof): fewer than {MIN_PURE_ERROR_DOF} dof of repeated poses ({}), so per-term tests only",
                refit.dof, pe.dof
            ),
        )
    };
    let where_ = if significant {
        vec![locate(
            &std.data,
            &screen.residual_raw,
            "what the geometric model leaves",
        )]
    } else {
        Vec::new()
    };
    Mismatch {
        significant,
        rms_mm: rms3(&screen.residual_raw),
        noise_floor_mm: refit.noise_floor,
        noise_floor_method: method.into(),
        noise_source: source,
        lack_of_fit_p: screen.lack_of_fit_p,
        best_candidate: sel.first_best.map(|(k, _)| lib[k].label()),
        best_candidate_p: sel.first_best.map(|(_, p)| p),
        where_,
    }
}

/// Where the residual no named effect explains is, and what explains it, when something does.
fn unexplained_where(std: &Standard, leftover: &Leftover) -> Vec<WhereReport> {
    if !leftover.unexplained() {
        return Vec::new();
    }
    let mut wh = locate(
        &std.data,
        &leftover.residual_raw,
        "what the named effects leave",
    );
    let names: Vec<String> = leftover
        .unexplained_by
        .iter()
        .map(|(n, p)| format!("{n} (p = {p:.1e})"))
        .collect();
    wh.description = format!("{}; explained by {}", wh.description, names.join(", "));
    vec![wh]
}

/// RMS before and after, on the fitted and the held-out data.
fn fit_summary(std: &Standard, screen: &Screen, refit: &Refit, heldout: Heldout) -> FitSummary {
    FitSummary {
        measurements: std.data.len(),
        geometric_parameters: std.free.len(),
        before_rms_mm: rms3(&screen.residual_raw),
        after_rms_mm: rms3(&refit.residual),
        heldout_before_rms_mm: heldout.before,
        heldout_after_rms_mm: heldout.after,
        heldout_before_mean_mm: heldout.before_mean_max.map(|m| m.0),
        heldout_before_max_mm: heldout.before_mean_max.map(|m| m.1),
        heldout_after_mean_mm: heldout.after_mean_max.map(|m| m.0),
        heldout_after_max_mm: heldout.after_mean_max.map(|m| m.1),
        heldout: heldout.what,
    }
}
