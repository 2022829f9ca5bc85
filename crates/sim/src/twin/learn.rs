//! The twin learns (issue 18 item 4): a scenario replayed on a recording's own rows, compared
//! point by point, the difference diagnosed, and the scenario rewritten.
//!
//! 1. **Replay**: the scenario's world, without its random errors, runs the recording's rows in
//!    order at their times ([`World::replay`](crate::world::World::replay)): the same motion
//!    history (backlash), drift time and approach directions as recorded; each `ok` row gets the
//!    expected reading.
//! 2. **Compare**: difference d = recorded − simulated per row; RMS on all rows and on the
//!    held-out rows (every [`TwinOptions::holdout_every`]-th measured row, never fitted), and
//!    where it is largest (per joint interval, per time quarter, per axis).
//! 3. **Diagnose the difference**: a recording whose points are the nominal model's plus d
//!    (held-out rows as `via`, so they still set approach directions) goes through
//!    [`rigcal_model::diagnosis::diagnose`]: the geometry it fits is the twin's geometric error, the
//!    effects it names are what the twin lacks.
//! 4. **Fit in the scenario's own terms**: the identifiable geometric parameters and the named
//!    effects as the world writes them (backlash lost motion, transmission harmonics, compliance
//!    with the rig's link masses — each with its model term's basis — and warm-up drift
//!    A·(1 − e^(−t/τ)) with τ by a line search), jointly by least squares on d over the fitted
//!    rows, so what the geometry absorbs is counted once.
//! 5. **Write** the updated scenario ([`crate::world::write`]): the old file's settings and
//!    effects, the geometry as explicit values, the new effects appended (each written by its
//!    effect's file in [`rigcal_model::effects`]), and — when the diagnosis leaves structure no
//!    library effect explains — a flagged `discrepancy` effect
//!    ([`rigcal_model::effects::discrepancy`]): the shapes the diagnosis located it with,
//!    refitted here jointly with the geometry (so what the geometry absorbs is counted once),
//!    which the world simulates and which says, in its note and a comment, that it is not
//!    physics from the library.
//! 6. **Re-simulate** the written file and compare again (RMS after, all rows and held out).
//!
//! Units: mm, radians inside, degrees and mm in files.

use crate::world::write::{discrepancy_comment, scenario_text};
use crate::world::{identifiable, Scenario, ScenarioError};
use nalgebra::{DMatrix, DVector, Vector3};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::{Recording, Status};
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::{diagnose, EffectReport, Options, Report};
use rigcal_model::effects::discrepancy::{self as fitted, DiscrepancyTerm, Driver};
use rigcal_model::effects::drift::{warm_up, DriftTarget};
use rigcal_model::effects::{
    backlash, compliance, drift, transmission, EffectContext, EffectKind, NewEffect, AXES,
};
use rigcal_model::model::effects::{effect_observations, unit_columns, EffectSpec};
use std::fmt::Write as _;
use std::path::Path;

/// Why the twin could not learn.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TwinError {
    /// The scenario (or the written one) does not parse.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The recording does not fit the scenario's rig.
    #[error("the recording has {got} joints but the scenario's rig `{rig}` has {expected}")]
    Joints {
        /// The rig.
        rig: String,
        /// Its joints.
        expected: usize,
        /// The recording's.
        got: usize,
    },
    /// Too few rows to compare or fit.
    #[error("{0}")]
    TooFew(String),
    /// The diagnosis of the difference failed.
    #[error("diagnosing the difference: {0}")]
    Diagnosis(#[from] rigcal_model::diagnosis::DiagnoseError),
    /// The joint fit failed.
    #[error("fitting the twin: {0}")]
    Fit(String),
}

/// Settings of [`learn`].
#[derive(Debug, Clone)]
pub struct TwinOptions {
    /// Every n-th measured row is held out (never fitted, never diagnosed).
    pub holdout_every: usize,
}

impl Default for TwinOptions {
    fn default() -> Self {
        Self { holdout_every: 4 }
    }
}

/// RMS of the difference between a simulation and the recording (mm, 3-D).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Comparison {
    /// All measured rows.
    pub all_mm: f64,
    /// Held-out rows.
    pub heldout_mm: f64,
    /// Fitted rows.
    pub fitted_mm: f64,
}

/// What a term the diagnosis named became in the written scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinTerm {
    /// "backlash on joint 2".
    pub label: String,
    /// The written values in file units ("lost_motion_deg = 0.0498"), or why it was not written.
    pub written: Result<String, String>,
}

/// An out-of-library remainder: described from the diagnosis' `unexplained` flag and where it
/// is ([`discrepancy_of`]), and written as a flagged `discrepancy` effect the world simulates
/// when the diagnosis located it in shapes the twin can refit.
#[derive(Debug, Clone, PartialEq)]
pub struct Discrepancy {
    /// Where it is and what it depends on, in the diagnosis' words.
    pub description: Vec<String>,
    /// 3-D RMS the re-simulated twin leaves on the held-out rows (mm).
    pub heldout_rms_mm: f64,
    /// The noise floor (mm).
    pub noise_floor_mm: f64,
    /// Library terms the diagnosis named beside it, not claimed (they may only soak up part of
    /// the unknown shape): written commented.
    pub unclaimed: Vec<String>,
    /// The shapes written as the flagged `discrepancy` effect (labels), empty when none could be
    /// refitted (the remainder is then only described).
    pub simulated: Vec<String>,
    /// Coefficients of the written term.
    pub coefficients: usize,
}

/// What [`learn`] found and wrote.
#[derive(Debug, Clone)]
pub struct Twin {
    /// Simulation vs recording with the given scenario.
    pub before: Comparison,
    /// With the updated scenario, re-simulated from the written file.
    pub after: Comparison,
    /// Where the given scenario and the recording differ most, one line each.
    pub differs: Vec<String>,
    /// The diagnosis of the difference.
    pub diagnosis: Report,
    /// The named terms and what was written for each.
    pub terms: Vec<TwinTerm>,
    /// The flagged out-of-library remainder, if any.
    pub discrepancy: Option<Discrepancy>,
    /// The updated scenario's text.
    pub scenario: String,
    /// Measured rows compared, and how many were held out.
    pub rows: (usize, usize),
}

impl Twin {
    /// The terminal text.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "simulation and recording differ: RMS {:.4} mm on {} rows ({:.4} mm on the {} held-out rows)",
            self.before.all_mm, self.rows.0, self.before.heldout_mm, self.rows.1
        );
        for d in &self.differs {
            let _ = writeln!(s, "  {d}");
        }
        let _ = writeln!(s, "diagnosis of the difference:");
        for line in self.diagnosis.text().lines() {
            let _ = writeln!(s, "  {line}");
        }
        let _ = writeln!(s, "the updated twin:");
        for t in &self.terms {
            match &t.written {
                Ok(v) => {
                    let _ = writeln!(s, "  {}: {v}", t.label);
                }
                Err(why) => {
                    let _ = writeln!(s, "  {}: not written ({why})", t.label);
                }
            }
        }
        if let Some(d) = &self.discrepancy {
            let how = if d.simulated.is_empty() {
                "not simulated".to_string()
            } else {
                format!(
                    "simulated as a fitted smooth term of {} coefficients: {}",
                    d.coefficients,
                    d.simulated.join(", ")
                )
            };
            let _ = writeln!(
                s,
                "  discrepancy (flagged, not library physics; {how}): {}",
                d.description.join("; ")
            );
            if !d.unclaimed.is_empty() {
                let _ = writeln!(
                    s,
                    "  not claimed beside it (written commented): {}",
                    d.unclaimed.join(", ")
                );
            }
        }
        let _ = writeln!(
            s,
            "RMS sim vs recording: before {:.4} mm → after {:.4} mm (all rows); held out {:.4} → {:.4} mm; noise floor {:.4} mm",
            self.before.all_mm,
            self.after.all_mm,
            self.before.heldout_mm,
            self.after.heldout_mm,
            self.diagnosis.mismatch.noise_floor_mm
        );
        s
    }
}

/// One measured row the scenario also measured.
struct Row {
    /// Index into the recording's rows.
    index: usize,
    q: Vec<f64>,
    t_s: f64,
    d: Vector3<f64>,
    direction: Vec<i8>,
    heldout: bool,
}

/// Learns from `rec`: see the module documentation. `source` is the scenario's file text (its
/// settings and effects are kept as written), `out` where the updated scenario will be written
/// (its rig path is made relative to it).
pub fn learn(
    scenario: &Scenario,
    source: &str,
    rec: &Recording,
    out: &Path,
    opts: &TwinOptions,
) -> Result<Twin, TwinError> {
    let rig = &scenario.rig;
    let dof = rig.chain.joints().len();
    if let Some(r) = rec.rows.iter().find(|r| r.q.len() != dof) {
        return Err(TwinError::Joints {
            rig: rig.name.clone(),
            expected: dof,
            got: r.q.len(),
        });
    }
    let rows = compare_rows(scenario, rec, opts)?;
    let before = comparison(&rows);
    let differs = where_differs(scenario, &rows);
    let diagnosis = diagnose(
        rig,
        &difference_recording(scenario, rec, &rows),
        &Options::default(),
    )?;
    let specs: Vec<(String, Term)> = diagnosis.effects.iter().map(term_of).collect();
    let (fitted_truth, written, _) = fit_twin(scenario, &rows, &specs, &[])?;
    // Conventions §9: beside structure no library effect explains, a named library term may only
    // soak up part of an unknown shape, so it is not claimed: the twin keeps the geometry alone
    // and lists the terms, commented, in the flagged section.
    let claim = !diagnosis.unexplained;
    let (shape_labels, shapes) = if claim {
        (Vec::new(), Vec::new())
    } else {
        discrepancy_terms(&diagnosis)
    };
    let (truth, shapes) = if claim {
        (fitted_truth, Vec::new())
    } else {
        let (t, _, shapes) = fit_twin(scenario, &rows, &[], &shapes)?;
        (t, shapes)
    };
    let mut terms = Vec::new();
    let mut effects = Vec::new();
    let mut unclaimed = Vec::new();
    for ((label, _), w) in specs.iter().zip(written) {
        match (claim, w) {
            (true, Ok(e)) => {
                terms.push(TwinTerm {
                    label: label.clone(),
                    written: Ok(e.summary.clone()),
                });
                effects.push(e);
            }
            (true, Err(why)) => terms.push(TwinTerm {
                label: label.clone(),
                written: Err(why),
            }),
            (false, w) => unclaimed.push((label.clone(), w.ok())),
        }
    }
    let coefficients: usize = shapes.iter().map(DiscrepancyTerm::width).sum();
    if !shapes.is_empty() {
        effects.push(discrepancy_effect(scenario, shapes));
    }
    let mut text = scenario_text(scenario, source, out, &truth, &effects)?;
    let updated = Scenario::parse(&text, out, None)?;
    let after = comparison(&compare_rows(&updated, rec, opts)?);
    let mut discrepancy = discrepancy_of(&diagnosis, after);
    if let Some(d) = &mut discrepancy {
        d.unclaimed = unclaimed.iter().map(|(l, _)| l.clone()).collect();
        d.simulated = shape_labels;
        d.coefficients = coefficients;
        text.push_str(&discrepancy_comment(
            &d.description,
            !d.simulated.is_empty(),
            d.heldout_rms_mm,
            d.noise_floor_mm,
        ));
        text.push_str(&unclaimed_comment(&unclaimed));
    }
    let n_held = rows.iter().filter(|r| r.heldout).count();
    Ok(Twin {
        before,
        after,
        differs,
        rows: (rows.len(), n_held),
        diagnosis,
        terms,
        discrepancy,
        scenario: text,
    })
}

/// The flagged remainder: the diagnosis' unexplained structure, with what the twin leaves.
pub fn discrepancy_of(report: &Report, after: Comparison) -> Option<Discrepancy> {
    if !report.unexplained {
        return None;
    }
    let mut description: Vec<String> = report
        .unexplained_where
        .iter()
        .map(|w| w.description.clone())
        .collect();
    if description.is_empty() {
        description.push("structured residual no library effect explains".into());
    }
    Some(Discrepancy {
        description,
        heldout_rms_mm: after.heldout_mm,
        noise_floor_mm: report.mismatch.noise_floor_mm,
        unclaimed: Vec::new(),
        simulated: Vec::new(),
        coefficients: 0,
    })
}

/// The shapes of the diagnosis' discrepancy term as world terms (labels, terms with zero
/// coefficients), to refit with the twin's geometry.
fn discrepancy_terms(report: &Report) -> (Vec<String>, Vec<DiscrepancyTerm>) {
    use rigcal_model::diagnosis::shapes::Variable as V;
    let Some(d) = &report.discrepancy else {
        return (Vec::new(), Vec::new());
    };
    d.model
        .shapes
        .iter()
        .map(|spec| {
            let driver = match spec.variable {
                V::OwnAngle { joint } => Driver::Joint {
                    acted: joint,
                    driver: joint,
                    flips: false,
                },
                V::OtherAngle { acted, driver } => Driver::Joint {
                    acted,
                    driver,
                    flips: false,
                },
                V::Direction { joint } => Driver::Joint {
                    acted: joint,
                    driver: joint,
                    flips: true,
                },
                V::Time => Driver::Time,
                V::Position => Driver::Position,
            };
            let mut term = DiscrepancyTerm {
                driver,
                form: spec.form.clone(),
                coefficients: Vec::new(),
            };
            term.coefficients = vec![0.0; term.width()];
            (spec.label(), term)
        })
        .unzip()
}

/// The flagged `discrepancy` effect to append.
fn discrepancy_effect(scenario: &Scenario, terms: Vec<DiscrepancyTerm>) -> NewEffect {
    let d = fitted::Discrepancy {
        terms,
        note: format!(
            "{}: the structure of the recording no library effect explains, fitted in the shapes the diagnosis located it with; it describes a residual and explains nothing",
            fitted::FLAG
        ),
    };
    fitted::scenario_entry(&scenario.rig.chain, &d)
}

/// The library terms not claimed, as commented `[[effects]]` tables a user may uncomment to
/// try them.
fn unclaimed_comment(unclaimed: &[(String, Option<NewEffect>)]) -> String {
    if unclaimed.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "# Library terms the diagnosis named beside it, NOT claimed (each may only soak up part of\n\
         # the unknown shape, conventions §9); fitted sizes for reference:\n",
    );
    for (label, e) in unclaimed {
        let _ = writeln!(s, "#   {label}");
        if let Some(e) = e {
            let mut doc = toml::Table::new();
            doc.insert(
                "effects".into(),
                toml::Value::Array(vec![toml::Value::Table(e.table.clone())]),
            );
            for line in toml::to_string(&doc).unwrap_or_default().lines() {
                let _ = writeln!(s, "#   {line}");
            }
        }
    }
    s
}

/// Replays the recording in `scenario`'s noiseless world and pairs each measured row with its
/// difference.
fn compare_rows(
    scenario: &Scenario,
    rec: &Recording,
    opts: &TwinOptions,
) -> Result<Vec<Row>, TwinError> {
    let sim = scenario.world().noiseless().replay(rec);
    let obs = effect_observations(rec, &[]);
    let every = opts.holdout_every.max(2);
    let mut rows = Vec::new();
    let mut measured = 0usize;
    let mut k_obs = 0usize;
    for (index, (row, s)) in rec.rows.iter().zip(&sim).enumerate() {
        let (Status::Ok, Some(p)) = (&row.status, row.position) else {
            continue;
        };
        let direction = obs
            .get(k_obs)
            .map(|o| o.direction.clone())
            .unwrap_or_default();
        k_obs += 1;
        let Some(s) = s else { continue };
        rows.push(Row {
            index,
            q: row.q.clone(),
            t_s: row
                .t_s
                .unwrap_or(index as f64 * scenario.measurement.seconds_per_point),
            d: p - s,
            direction,
            heldout: measured % every == every - 1,
        });
        measured += 1;
    }
    if rows.len() < 2 * every {
        return Err(TwinError::TooFew(format!(
            "{} measured rows the scenario also measures: too few to compare",
            rows.len()
        )));
    }
    Ok(rows)
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

fn comparison(rows: &[Row]) -> Comparison {
    Comparison {
        all_mm: rms(rows.iter().map(|r| r.d.norm())),
        heldout_mm: rms(rows.iter().filter(|r| r.heldout).map(|r| r.d.norm())),
        fitted_mm: rms(rows.iter().filter(|r| !r.heldout).map(|r| r.d.norm())),
    }
}

/// Where the difference is largest: the worst quarter of each moving joint's range, the worst
/// quarter of the session's time, the largest axis; the three worst of the joint lines first.
fn where_differs(scenario: &Scenario, rows: &[Row]) -> Vec<String> {
    let joints = scenario.rig.chain.joints();
    let mut lines: Vec<(f64, String)> = Vec::new();
    for (j, spec) in joints.iter().enumerate() {
        let (lo, hi) = rows.iter().fold((f64::MAX, f64::MIN), |(a, b), r| {
            (a.min(r.q[j]), b.max(r.q[j]))
        });
        if hi - lo < 1e-9 {
            continue;
        }
        let bin = |v: f64| (((v - lo) / (hi - lo) * 4.0) as usize).min(3);
        let worst = (0..4)
            .map(|b| {
                let v = rms(rows.iter().filter(|r| bin(r.q[j]) == b).map(|r| r.d.norm()));
                (b, if v.is_nan() { 0.0 } else { v })
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((b, v)) = worst {
            let f = |x: f64| spec.kind.to_file_units(x);
            let w = (hi - lo) / 4.0;
            lines.push((
                v,
                format!(
                    "joint {} in [{:.1}, {:.1}] {}: RMS {v:.4} mm",
                    j + 1,
                    f(lo + w * b as f64),
                    f(lo + w * (b + 1) as f64),
                    spec.kind.unit()
                ),
            ));
        }
    }
    lines.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut out: Vec<String> = lines.into_iter().take(3).map(|(_, s)| s).collect();
    let t_max = rows.iter().map(|r| r.t_s).fold(0.0, f64::max);
    if t_max > 0.0 {
        let quarter = |r: &Row| ((r.t_s / t_max * 4.0) as usize).min(3);
        let per: Vec<f64> = (0..4)
            .map(|b| rms(rows.iter().filter(|r| quarter(r) == b).map(|r| r.d.norm())))
            .collect();
        out.push(format!(
            "by time quarter of the session (0–{t_max:.0} s): RMS {} mm",
            per.iter()
                .map(|v| format!("{v:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let axes: Vec<f64> = (0..3).map(|a| rms(rows.iter().map(|r| r.d[a]))).collect();
    out.push(format!(
        "by axis: x {:.4}, y {:.4}, z {:.4} mm",
        axes[0], axes[1], axes[2]
    ));
    out
}

/// The recording the diagnosis sees: the nominal model's point plus the difference on every
/// fitted row; held-out rows and rows the scenario did not measure become `via` rows.
fn difference_recording(scenario: &Scenario, rec: &Recording, rows: &[Row]) -> Recording {
    let chain = &scenario.rig.chain;
    let nominal = ErrorParams::zeros(chain.layout());
    let mut out = rec.clone();
    for row in out.rows.iter_mut().filter(|r| r.status == Status::Ok) {
        row.status = Status::Via;
    }
    for r in rows.iter().filter(|r| !r.heldout) {
        let row = &mut out.rows[r.index];
        row.status = Status::Ok;
        row.position = Some(chain.position(&r.q, &nominal) + r.d);
    }
    out
}

/// A term of the twin in the scenario's own form.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Term {
    /// A joint effect with the model's basis (backlash, transmission, compliance).
    Joint(EffectSpec),
    /// Warm-up drift of a joint or of the tip along an axis.
    Drift(DriftTarget),
    /// A named effect the twin cannot write (table effects), with its kind.
    Unsupported(EffectKind),
}

fn term_of(e: &EffectReport) -> (String, Term) {
    let joint = e.joint.map(|j| j.saturating_sub(1));
    let axis = e
        .axis
        .as_deref()
        .and_then(|a| AXES.iter().position(|x| *x == a));
    let label = match (joint, &e.axis, e.order) {
        (Some(j), _, Some(n)) => format!("{} (order {n}) on joint {}", e.kind, j + 1),
        (Some(j), _, None) => format!("{} on joint {}", e.kind, j + 1),
        (None, Some(a), _) => format!("{} along {a}", e.kind),
        _ => e.kind.to_string(),
    };
    let term = match (e.kind, joint, axis) {
        (EffectKind::Backlash, Some(j), _) => Term::Joint(EffectSpec::Backlash(j)),
        (EffectKind::TransmissionError, Some(j), _) => {
            Term::Joint(EffectSpec::TransmissionError(j, e.order.unwrap_or(1)))
        }
        (EffectKind::JointCompliance, Some(j), _) => Term::Joint(EffectSpec::JointCompliance(j)),
        (EffectKind::ThermalDrift, Some(j), _) => Term::Drift(DriftTarget::Joint(j)),
        (EffectKind::ThermalDrift, None, Some(a)) => Term::Drift(DriftTarget::Axis(a)),
        (kind, ..) => Term::Unsupported(kind),
    };
    (label, term)
}

/// Time constants tried for a warm-up drift, as fractions of the session's length.
const TAU_FRACTIONS: [f64; 12] = [
    0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0,
];

/// The joint fit of geometry and terms on the fitted rows; the updated truth and, per term,
/// the effect to write or why not.
#[allow(clippy::type_complexity)]
fn fit_twin(
    scenario: &Scenario,
    rows: &[Row],
    terms: &[(String, Term)],
    shapes: &[DiscrepancyTerm],
) -> Result<
    (
        ErrorParams,
        Vec<Result<NewEffect, String>>,
        Vec<DiscrepancyTerm>,
    ),
    TwinError,
> {
    let rig = &scenario.rig;
    let masses_ok = |j: usize| {
        EffectSpec::JointCompliance(j)
            .check(&rig.link_masses, rig.chain.joints().len())
            .map_err(|e| e.to_string())
    };
    let usable: Vec<Result<Term, String>> = terms
        .iter()
        .map(|(_, t)| match t {
            Term::Unsupported(k) => Err(format!(
                "the twin writes joint and tip effects; a {k} is not fitted into the scenario"
            )),
            Term::Joint(EffectSpec::JointCompliance(j)) => masses_ok(*j).map(|_| *t),
            _ => Ok(*t),
        })
        .collect();
    let active: Vec<Term> = usable.iter().filter_map(|t| t.clone().ok()).collect();
    let has_drift = active.iter().any(|t| matches!(t, Term::Drift(_)));
    let t_max = rows.iter().map(|r| r.t_s).fold(0.0, f64::max).max(1.0);
    let taus: Vec<f64> = if has_drift {
        TAU_FRACTIONS.iter().map(|f| f * t_max).collect()
    } else {
        vec![t_max]
    };
    let free = identifiable(rig);
    let mut best: Option<(f64, f64, DVector<f64>)> = None;
    for &tau in &taus {
        let (a, r) = twin_system(scenario, rows, &free, &active, shapes, tau);
        let x = solve(&a, &r)?;
        let rss = (&r - &a * &x).norm_squared();
        if best.as_ref().is_none_or(|b| rss < b.0) {
            best = Some((rss, tau, x));
        }
    }
    let (_, tau, x) = best.ok_or_else(|| TwinError::Fit("nothing to fit".into()))?;
    let mut truth = scenario.truth.clone();
    for (m, &i) in free.iter().enumerate() {
        truth.set(i, truth.get(i) + x[m]);
    }
    let mut at = free.len();
    let mut coef_of = Vec::new();
    for t in &active {
        let w = width(t);
        coef_of.push(x.rows(at, w).iter().copied().collect::<Vec<f64>>());
        at += w;
    }
    let fitted_shapes = shapes
        .iter()
        .map(|s| {
            let w = s.width();
            let mut s = s.clone();
            s.coefficients = x.rows(at, w).iter().copied().collect();
            at += w;
            s
        })
        .collect();
    let mut k = 0;
    let written = usable
        .iter()
        .map(|u| match u {
            Err(why) => Err(why.clone()),
            Ok(t) => {
                let c = &coef_of[k];
                k += 1;
                written(rig, t, c, tau)
            }
        })
        .collect();
    Ok((truth, written, fitted_shapes))
}

fn width(t: &Term) -> usize {
    match t {
        Term::Joint(EffectSpec::TransmissionError(..)) => 2,
        _ => 1,
    }
}

/// The scenario entry of term `t` with fitted coefficients `c` (internal units) and, for a drift,
/// time constant `tau_s`, written by its effect's file; an error says why it cannot be written
/// (a negative lost motion or compliance is not that physics).
fn written(rig: &Rig, t: &Term, c: &[f64], tau_s: f64) -> Result<NewEffect, String> {
    match *t {
        Term::Joint(EffectSpec::Backlash(j)) => backlash::scenario_entry(&rig.chain, j, c[0]),
        Term::Joint(EffectSpec::TransmissionError(j, n)) => {
            Ok(transmission::scenario_entry(j, n, c))
        }
        Term::Joint(EffectSpec::JointCompliance(j)) => {
            compliance::scenario_entry(&rig.link_masses, j, c[0])
        }
        Term::Drift(target) => drift::scenario_entry(&rig.chain, target, c[0], tau_s),
        // Filtered out before the fit.
        Term::Joint(_) | Term::Unsupported(_) => Err("not a term the twin writes".into()),
    }
}

/// Columns (geometry, then each term) and the difference, over the fitted rows.
fn twin_system(
    scenario: &Scenario,
    rows: &[Row],
    free: &[usize],
    terms: &[Term],
    shapes: &[DiscrepancyTerm],
    tau: f64,
) -> (DMatrix<f64>, DVector<f64>) {
    let rig = &scenario.rig;
    let chain = &rig.chain;
    let e = &scenario.truth;
    let ctx = EffectContext {
        chain,
        e,
        masses: &rig.link_masses,
        payload_kg: 0.0,
    };
    let fitted: Vec<&Row> = rows.iter().filter(|r| !r.heldout).collect();
    let p = free.len()
        + terms.iter().map(width).sum::<usize>()
        + shapes.iter().map(DiscrepancyTerm::width).sum::<usize>();
    let mut a = DMatrix::zeros(3 * fitted.len(), p);
    let mut r = DVector::zeros(3 * fitted.len());
    for (i, row) in fitted.iter().enumerate() {
        let g = rigcal_model::identification::identifiability::stacked_jacobian(
            chain,
            e,
            std::slice::from_ref(&row.q),
            free,
        );
        let jj = chain.joint_jacobian(&row.q, e);
        let warm = warm_up(row.t_s, tau);
        for k in 0..3 {
            r[3 * i + k] = row.d[k];
            for c in 0..free.len() {
                a[(3 * i + k, c)] = g[(k, c)];
            }
            let mut c = free.len();
            for t in terms {
                match t {
                    Term::Joint(s) => {
                        for b in s.basis(&ctx, &row.q, &row.direction) {
                            a[(3 * i + k, c)] = b * jj[(k, s.joint())];
                            c += 1;
                        }
                    }
                    Term::Drift(DriftTarget::Joint(j)) => {
                        a[(3 * i + k, c)] = warm * jj[(k, *j)];
                        c += 1;
                    }
                    Term::Drift(DriftTarget::Axis(ax)) => {
                        a[(3 * i + k, c)] = if k == *ax { warm } else { 0.0 };
                        c += 1;
                    }
                    Term::Unsupported(_) => {}
                }
            }
        }
        let mut c = p - shapes.iter().map(DiscrepancyTerm::width).sum::<usize>();
        let at = chain.position(&row.q, e);
        for s in shapes {
            shape_columns(s, row, &jj, &at, &mut a, 3 * i, c);
            c += s.width();
        }
    }
    (a, r)
}

/// A discrepancy term's columns for one row (3 rows from `r0`, columns from `c0`), built with
/// the world's own evaluation so what is fitted is what is simulated.
fn shape_columns(
    s: &DiscrepancyTerm,
    row: &Row,
    jj: &DMatrix<f64>,
    at: &Vector3<f64>,
    a: &mut DMatrix<f64>,
    r0: usize,
    c0: usize,
) {
    match s.driver {
        Driver::Joint { acted, .. } => {
            for (f, v) in s.joint_values(&row.q, &row.direction).iter().enumerate() {
                for k in 0..3 {
                    a[(r0 + k, c0 + f)] = v * jj[(k, acted)];
                }
            }
        }
        Driver::Time | Driver::Position => {
            let v = s.tip_values(row.t_s, at);
            for (f, val) in v.iter().enumerate() {
                for k in 0..3 {
                    a[(r0 + k, c0 + k * v.len() + f)] = *val;
                }
            }
        }
    }
}

fn solve(a: &DMatrix<f64>, r: &DVector<f64>) -> Result<DVector<f64>, TwinError> {
    let p = a.ncols();
    if a.nrows() <= p {
        return Err(TwinError::TooFew(format!(
            "{} fitted rows are too few for {p} unknowns",
            a.nrows() / 3
        )));
    }
    let (s, scale) = unit_columns(a);
    let x = s
        .svd(true, true)
        .solve(r, 1e-10)
        .map_err(|e| TwinError::Fit(e.to_string()))?;
    Ok(DVector::from_fn(p, |i, _| x[i] * scale[i]))
}

/// Why [`model_with_named_effects`] failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NamedModelError {
    /// The identification failed.
    #[error(transparent)]
    Identify(#[from] rigcal_model::identification::IdentifyError),
    /// The effects could not be fitted.
    #[error(transparent)]
    Effects(#[from] rigcal_model::model::effects::EffectError),
}

/// The model file `rigcal diagnose --model` writes: the conventional identification of `rec`
/// and the joint effects `report` named that a model can carry (backlash, transmission errors,
/// compliance when the rig has the masses), fitted beside the geometry. Also returns the named
/// effects left out, each with why. An effect the diagnosis named has earned its place on
/// held-out data (`rigcal_model::diagnosis::crossval`), so it is kept even beside an
/// unexplained remainder.
pub fn model_with_named_effects(
    rig: &rigcal_core::rig::Rig,
    rec: &Recording,
    report: &Report,
) -> Result<(rigcal_model::model::ModelFile, Vec<String>), NamedModelError> {
    let id = rigcal_model::identification::identify(
        rig,
        rec,
        rigcal_model::identification::Level::Full,
        &rigcal_model::diagnosis::outliers::identify_options(),
    )?;
    let mut specs = Vec::new();
    let mut left = Vec::new();
    for e in &report.effects {
        let (label, term) = term_of(e);
        match term {
            Term::Joint(s) => match s.check(&rig.link_masses, rig.chain.joints().len()) {
                Ok(()) => specs.push(s),
                Err(why) => left.push(format!("{label}: {why}")),
            },
            _ => left.push(format!(
                "{label}: a model file carries joint effects only (backlash, transmission_error, joint_compliance)"
            )),
        }
    }
    let provenance = rigcal_model::model::Provenance {
        measurements: id.fit.after.n,
        notes: Some("rigcal diagnose --model: geometry and the named effects".into()),
        ..Default::default()
    };
    if specs.is_empty() {
        return Ok((
            rigcal_model::model::ModelFile::constant(rig, &id.fit, provenance),
            left,
        ));
    }
    let fitted = rigcal_model::model::effects::fit_recording_effects(rig, rec, &id, &specs)?;
    let mut file = rigcal_model::model::ModelFile::constant(rig, &fitted.fit, provenance);
    file.outliers = id.outliers.clone();
    file.effects = fitted.effects;
    file.standalone_parameters = rigcal_model::model::entries(rig, &id.fit);
    Ok((file, left))
}
