//! The diagnosis report (shared/spec/recordings.md, "Diagnosis report"), its terminal text, and
//! where a residual lives in the workspace.
//!
//! Units: mm for sizes and RMS (3-D RMS over measurements), degrees for joint ranges.

use super::crossval::HeldoutGain;
use super::shapes::ShapeSpec;
use super::{Data, AXES};
use crate::effects::compliance::unit_torques_all;
use crate::effects::EffectKind;
use nalgebra::DVector;
use rigcal_core::kinematics::{JointKind, Robot};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write;

/// The whole report.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    /// Whether a mismatch remains after the geometric fit, and where.
    pub mismatch: Mismatch,
    /// The named effects.
    pub effects: Vec<EffectReport>,
    /// A significant structured residual remains that no candidate explains.
    pub unexplained: bool,
    /// Where the unexplained residual is.
    pub unexplained_where: Vec<WhereReport>,
    /// The unexplained residual described by its shape: one entry per located shape (what it
    /// depends on, localised or periodic, where, size ± σ). Empty when nothing is unexplained
    /// or the structure could not be located (the lack of fit alone).
    #[serde(default)]
    pub out_of_library: Vec<ShapeReport>,
    /// The smooth discrepancy term fitted in the located variables, apart from the named
    /// effects: its RMS on the fitted and held-out data with and without it.
    #[serde(default)]
    pub discrepancy: Option<DiscrepancyReport>,
    /// Effects the F-tests chose that did not earn their place on held-out data
    /// ([`super::crossval`]): below what this recording can show, never named.
    #[serde(default)]
    pub below_evidence: Vec<WeakEffect>,
    /// Candidates the geometry absorbs entirely (visible fraction below 1e-3).
    pub absorbed: Vec<String>,
    /// RMS before and after.
    pub fit: FitSummary,
    /// Measurements removed from the fit as outliers (judged after the effects were named),
    /// each with its seq, file line and size.
    #[serde(default)]
    pub outliers: Vec<crate::identification::outliers::Outlier>,
    /// How the diagnosis worked on this recording: approach directions from row order, time
    /// effects left out without `t_s`, the instrument's quantisation, outliers kept.
    #[serde(default)]
    pub notes: Vec<String>,
}

/// The mismatch test.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Mismatch {
    /// A significant mismatch remains after the geometric fit.
    pub significant: bool,
    /// 3-D RMS of the residual after the geometric fit (mm).
    pub rms_mm: f64,
    /// 3-D RMS of pure noise, √3·σ (mm).
    pub noise_floor_mm: f64,
    /// Which noise floor the tests used: `pure_error` (repeated poses, lack-of-fit test) or
    /// `residual_variance` (too few repeated poses: per-term tests against the residual
    /// variance only).
    #[serde(default)]
    pub noise_floor_method: String,
    /// How the noise floor was estimated.
    pub noise_source: String,
    /// p-value of the lack-of-fit test of the geometric model (when pure error is available).
    pub lack_of_fit_p: Option<f64>,
    /// The best single candidate.
    pub best_candidate: Option<String>,
    /// Its partial F-test p-value (before Bonferroni).
    pub best_candidate_p: Option<f64>,
    /// Where the mismatch is.
    #[serde(rename = "where")]
    pub where_: Vec<WhereReport>,
}

/// Where a residual lives.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WhereReport {
    /// Plain language.
    pub description: String,
    /// Per joint, the range (degrees, or mm for prismatic joints) where it is largest; null for
    /// joints it does not depend on.
    pub joint_ranges_deg: Vec<Option<[f64; 2]>>,
    /// The axis with the largest residual.
    pub axis: String,
    /// Features the residual correlates with most, with the correlation coefficient.
    pub correlates_with: Vec<(String, f64)>,
}

/// One named effect (17 fields: the report format's, spec/recordings.md).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EffectReport {
    /// The vocabulary's kind.
    pub kind: EffectKind,
    /// Joint, 1-based.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint: Option<usize>,
    /// Axis.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axis: Option<String>,
    /// Axis pair.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axes: Option<[String; 2]>,
    /// Harmonic order.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub order: Option<u32>,
    /// Named parameters (units in the names).
    pub params: BTreeMap<String, f64>,
    /// Their standard deviations, where available.
    pub params_sigma: BTreeMap<String, f64>,
    /// 3-D RMS of the displacement the effect causes at the measured poses (mm).
    pub size_mm: f64,
    /// Its standard deviation (mm).
    pub size_sigma_mm: f64,
    /// Fraction of the fitted effect that the geometry does not absorb.
    pub visible_fraction: f64,
    /// Fraction the geometric parameters absorb: 1 − `visible_fraction`.
    #[serde(default)]
    pub absorbed_fraction: f64,
    /// Held-out 3-D RMS with every named effect (mm).
    #[serde(default)]
    pub heldout_rms_with_mm: Option<f64>,
    /// Held-out 3-D RMS with every named effect but this one (mm): the difference is the
    /// held-out improvement this effect brings.
    #[serde(default)]
    pub heldout_rms_without_mm: Option<f64>,
    /// The same for the candidate's regressors (columns scaled to unit norm).
    pub visible_fraction_of_candidate: f64,
    /// p-value of its partial F-test when it was selected (before Bonferroni).
    pub p_value: f64,
    /// Plain language.
    pub explanation: String,
    /// Candidates these poses cannot tell apart from this one ("X or Y").
    pub not_separable_from: Vec<String>,
    /// Its gain on held-out blocks of the recording (and the held-out recordings): what earned
    /// it its place ([`super::crossval`]).
    #[serde(default)]
    pub heldout_gain: Option<HeldoutGain>,
}

/// An effect the F-tests chose whose held-out gain does not show it: below what this
/// recording can show.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeakEffect {
    /// "backlash on joint 2".
    pub label: String,
    /// The vocabulary's kind.
    pub kind: EffectKind,
    /// Its held-out gain when it was set aside.
    pub gain: HeldoutGain,
    /// Why it falls short.
    pub reason: String,
}

/// A located residual no library effect explains, described by its shape (16 fields: the
/// report format's, spec/recordings.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeReport {
    /// What it depends on: `own_joint_angle`, `other_joint_angle`, `approach_direction`,
    /// `time` or `position`.
    pub depends_on: String,
    /// The joint whose error it is (1-based), for joint-space shapes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint: Option<usize>,
    /// The joint whose angle it varies along (1-based), for joint-space shapes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub driver_joint: Option<usize>,
    /// `localised`, `periodic` or `smooth`.
    pub form: String,
    /// Cycles per 360° of a periodic shape.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub order: Option<u32>,
    /// Where it is largest along the driving variable: where it reaches half its peak around
    /// the peak (the whole range for a periodic shape), in `interval_unit`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interval: Option<[f64; 2]>,
    /// `deg`, `mm` or `s`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interval_unit: Option<String>,
    /// How many measurements lie in `interval`, for a localised or smooth joint-space shape:
    /// a shape a handful of poses carry may be no more than those poses' own errors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measurements_in_interval: Option<usize>,
    /// Where it is largest in the workspace, for a position shape.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub region: Option<Region>,
    /// Its largest value: joint error (degrees, or mm for a prismatic joint) or displacement
    /// (mm).
    pub peak: f64,
    /// `deg` or `mm`.
    pub peak_unit: String,
    /// 3-D RMS over the measurements of its part the geometry cannot absorb (mm).
    pub size_mm: f64,
    /// Its standard deviation (mm).
    pub size_sigma_mm: f64,
    /// `size_mm` ÷ the noise floor.
    pub size_over_floor: f64,
    /// p-value of its partial F-test when chosen (before Bonferroni).
    pub p_value: f64,
    /// The flexible basis it was fitted with.
    pub basis: String,
    /// Plain language.
    pub description: String,
}

/// A region of the workspace (world, mm).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Region {
    /// Centre: the mean of the measured (modelled) positions where the shape reaches half its
    /// peak, weighted by its square.
    pub centre_mm: [f64; 3],
    /// Their RMS distance from the centre.
    pub radius_mm: f64,
    /// Their bounding box, lower corner.
    pub min_mm: [f64; 3],
    /// Upper corner.
    pub max_mm: [f64; 3],
    /// How many measurements that is.
    pub measurements: usize,
}

/// The discrepancy term: what it is made of and what it gains, apart from the named physics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiscrepancyReport {
    /// The shapes it is made of (labels).
    pub terms: Vec<String>,
    /// Its columns (coefficients fitted).
    pub columns: usize,
    /// 3-D RMS on the fitted data with the named effects only (mm).
    pub rms_without_mm: f64,
    /// The same with the discrepancy term (mm).
    pub rms_with_mm: f64,
    /// Held-out 3-D RMS with the named effects only (mm).
    pub heldout_rms_without_mm: Option<f64>,
    /// Held-out 3-D RMS with the discrepancy term too (mm).
    pub heldout_rms_with_mm: Option<f64>,
    /// What was held out.
    pub heldout: String,
    /// The fitted term, to evaluate it on other recordings (not written to the JSON report).
    #[serde(skip)]
    pub model: DiscrepancyModel,
}

/// A fitted discrepancy term: shape bases with their coefficients. The displacement is relative
/// to the diagnosis's fitted geometry (joint-space shapes act through its joint Jacobian).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DiscrepancyModel {
    /// The bases (knots, orders, centres fixed by the diagnosed recording).
    pub shapes: Vec<ShapeSpec>,
    /// Coefficients of each basis (rad, or mm for prismatic joints and Cartesian shapes).
    pub coefficients: Vec<Vec<f64>>,
}

impl DiscrepancyModel {
    /// The displacement (measured − modelled, mm) the term predicts at each measurement of `d`,
    /// stacked 3 per measurement; zero for a basis the data cannot show.
    pub fn displacement(&self, d: &Data) -> DVector<f64> {
        let mut out = DVector::zeros(3 * d.len());
        for (spec, c) in self.shapes.iter().zip(&self.coefficients) {
            if let Some(x) = spec.columns(d) {
                out += x * DVector::from_column_slice(c);
            }
        }
        out
    }
}

/// RMS before and after.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FitSummary {
    /// Measurements fitted.
    pub measurements: usize,
    /// Geometric parameters fitted.
    pub geometric_parameters: usize,
    /// 3-D RMS after the geometric fit (mm).
    pub before_rms_mm: f64,
    /// 3-D RMS after the refit with the named effects (mm).
    pub after_rms_mm: f64,
    /// Held-out 3-D RMS, geometric model (mm).
    pub heldout_before_rms_mm: Option<f64>,
    /// Held-out 3-D RMS, with the named effects (mm).
    pub heldout_after_rms_mm: Option<f64>,
    /// Held-out mean 3-D error, geometric model (mm).
    #[serde(default)]
    pub heldout_before_mean_mm: Option<f64>,
    /// Held-out largest 3-D error, geometric model (mm).
    #[serde(default)]
    pub heldout_before_max_mm: Option<f64>,
    /// Held-out mean 3-D error, with the named effects (mm).
    #[serde(default)]
    pub heldout_after_mean_mm: Option<f64>,
    /// Held-out largest 3-D error, with the named effects (mm).
    #[serde(default)]
    pub heldout_after_max_mm: Option<f64>,
    /// What was held out.
    pub heldout: String,
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().max(1) as f64;
    let ma = a.iter().sum::<f64>() / n;
    let mb = b.iter().sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Where the stacked residual `r` is: its largest axis, the joint range where it is largest and
/// what it correlates with (joint angle, approach direction, time, table coordinate, gravity
/// torque of the generic unit-mass model).
pub fn locate(d: &Data, r: &DVector<f64>, what: &str) -> WhereReport {
    let n = d.len();
    let axis_rms: Vec<f64> = (0..3)
        .map(|a| ((0..n).map(|i| r[3 * i + a].powi(2)).sum::<f64>() / n.max(1) as f64).sqrt())
        .collect();
    let axis = (0..3)
        .max_by(|&a, &b| axis_rms[a].total_cmp(&axis_rms[b]))
        .unwrap_or(0);
    let norm2: Vec<f64> = (0..n)
        .map(|i| r[3 * i].powi(2) + r[3 * i + 1].powi(2) + r[3 * i + 2].powi(2))
        .collect();
    let overall = (norm2.iter().sum::<f64>() / n.max(1) as f64).sqrt();
    // The joint the residual depends on most.
    let mut best: Option<JointRange> = None;
    for &j in &d.moving {
        let c = joint_range(d, j, &norm2, overall);
        if best.as_ref().is_none_or(|b| c.spread > b.spread) {
            best = Some(c);
        }
    }
    // Correlations of the largest axis's residual with the features.
    let ra: Vec<f64> = (0..n).map(|i| r[3 * i + axis]).collect();
    let corr = strongest_correlations(&ra, features(d));
    let mut ranges = vec![None; d.chain.joints().len()];
    let mut desc = format!(
        "{what}: RMS {overall:.4} mm, largest along {} ({:.4} mm)",
        AXES[axis], axis_rms[axis]
    );
    if let Some(best) = best {
        ranges[best.joint] = Some(best.range);
        let _ = write!(
            desc,
            "; largest for joint {} in [{:.0}, {:.0}] (RMS {:.4} mm there)",
            best.joint + 1,
            best.range[0],
            best.range[1],
            best.top_rms
        );
    }
    if let Some((name, c)) = corr.first() {
        let _ = write!(
            desc,
            "; {} residual correlates most with {name} (r = {c:.2})",
            AXES[axis]
        );
    }
    WhereReport {
        description: desc,
        joint_ranges_deg: ranges,
        axis: AXES[axis].to_string(),
        correlates_with: corr,
    }
}

/// Bins of a joint's range in [`locate`].
const BINS: usize = 6;

/// Where along one joint's range a residual is largest.
#[derive(Debug, Clone, Copy)]
struct JointRange {
    /// The joint (0-based).
    joint: usize,
    /// (largest − smallest non-empty bin RMS) ÷ overall RMS: how much the residual depends on
    /// this joint.
    spread: f64,
    /// The contiguous bins around the largest whose RMS reaches the overall RMS (degrees, or mm
    /// for a prismatic joint).
    range: [f64; 2],
    /// RMS in the largest bin (mm).
    top_rms: f64,
}

/// Joint `j`'s range binned in [`BINS`]; `norm2` the squared 3-D residual per measurement.
fn joint_range(d: &Data, j: usize, norm2: &[f64], overall: f64) -> JointRange {
    let unit = |v: f64| match d.chain.joints()[j].kind {
        JointKind::Revolute => v.to_degrees(),
        JointKind::Prismatic => v,
    };
    let q: Vec<f64> = d.obs.iter().map(|o| o.q[j]).collect();
    let lo = q.iter().copied().fold(f64::MAX, f64::min);
    let hi = q.iter().copied().fold(f64::MIN, f64::max);
    let w = (hi - lo) / BINS as f64;
    let mut ss = [0.0; BINS];
    let mut cnt = [0usize; BINS];
    for (i, v) in q.iter().enumerate() {
        let b = (((v - lo) / w) as usize).min(BINS - 1);
        ss[b] += norm2[i];
        cnt[b] += 1;
    }
    let rms: Vec<f64> = (0..BINS)
        .map(|b| {
            if cnt[b] > 0 {
                (ss[b] / cnt[b] as f64).sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let top = (0..BINS)
        .max_by(|&a, &b| rms[a].total_cmp(&rms[b]))
        .unwrap_or(0);
    let min = rms
        .iter()
        .copied()
        .filter(|v| *v > 0.0)
        .fold(f64::MAX, f64::min);
    let (mut a, mut b) = (top, top);
    while a > 0 && rms[a - 1] >= overall {
        a -= 1;
    }
    while b + 1 < BINS && rms[b + 1] >= overall {
        b += 1;
    }
    JointRange {
        joint: j,
        spread: (rms[top] - min) / overall.max(1e-300),
        range: [unit(lo + a as f64 * w), unit(lo + (b + 1) as f64 * w)],
        top_rms: rms[top],
    }
}

/// What a residual may correlate with, per measurement: each moving joint's angle, approach
/// direction and gravity torque, time, and the table coordinates.
fn features(d: &Data) -> Vec<(String, Vec<f64>)> {
    let mut feats: Vec<(String, Vec<f64>)> = Vec::new();
    // Every joint's gravity torques at each pose from one pass over the chain.
    let torques: Vec<Vec<Vec<f64>>> = d.obs.iter().map(|o| unit_torques_all(d, &o.q)).collect();
    for &j in &d.moving {
        feats.push((
            format!("joint {} angle", j + 1),
            d.obs.iter().map(|o| o.q[j]).collect(),
        ));
        feats.push((
            format!("joint {} approach direction", j + 1),
            d.direction.iter().map(|s| f64::from(s[j])).collect(),
        ));
        feats.push((
            format!("gravity torque of joint {}", j + 1),
            torques.iter().map(|t| t[j].iter().sum()).collect(),
        ));
    }
    if let Some(t) = &d.t_s {
        feats.push(("time".into(), t.clone()));
    }
    if let Some(t) = &d.table {
        for (a, name) in AXES.iter().enumerate() {
            feats.push((format!("table {name}"), t.iter().map(|v| v[a]).collect()));
        }
    }
    feats
}

/// The three features correlating most (by |r|) with `ra`.
fn strongest_correlations(ra: &[f64], feats: Vec<(String, Vec<f64>)>) -> Vec<(String, f64)> {
    let mut corr: Vec<(String, f64)> = feats
        .into_iter()
        .map(|(name, v)| {
            let c = pearson(ra, &v);
            (name, c)
        })
        .filter(|(_, c)| c.is_finite())
        .collect();
    corr.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    corr.truncate(3);
    corr
}

impl Report {
    /// The report as terminal text.
    pub fn text(&self) -> String {
        let mut s = String::new();
        self.mismatch_text(&mut s);
        for e in &self.effects {
            e.write_text(&mut s);
        }
        for w in &self.below_evidence {
            let _ = writeln!(
                s,
                "below what this recording can show: {} ({}): {}",
                w.label,
                w.gain.text(),
                w.reason
            );
        }
        if self.unexplained {
            let _ = writeln!(s, "unexplained: a significant structured residual remains that no known effect explains");
            for w in &self.unexplained_where {
                let _ = writeln!(s, "  where: {}", w.description);
            }
            for o in &self.out_of_library {
                let _ = writeln!(
                    s,
                    "  not in the library: {} (p = {:.1e}; fitted with {})",
                    o.description, o.p_value, o.basis
                );
            }
        }
        if let Some(d) = &self.discrepancy {
            d.write_text(&mut s);
        }
        for o in &self.outliers {
            let line = o.line.map(|l| format!(", line {l}")).unwrap_or_default();
            let _ = writeln!(
                s,
                "outlier removed from the fit: seq {}{line}, {:.4} mm off ({:.1} σ; residual x {:.4}, y {:.4}, z {:.4} mm)",
                o.seq, o.size_mm, o.sigmas, o.residual_mm[0], o.residual_mm[1], o.residual_mm[2]
            );
        }
        if self.outliers.is_empty() {
            let _ = writeln!(s, "outliers: none (judged after naming the effects)");
        }
        for n in &self.notes {
            let _ = writeln!(s, "note: {n}");
        }
        let f = &self.fit;
        let _ = writeln!(
            s,
            "RMS on the fitted data: {:.4} mm before, {:.4} mm after",
            f.before_rms_mm, f.after_rms_mm
        );
        if let (Some(b), Some(a)) = (f.heldout_before_rms_mm, f.heldout_after_rms_mm) {
            let _ = writeln!(
                s,
                "RMS held out ({}): {b:.4} mm before, {a:.4} mm after",
                f.heldout
            );
            let fig = |m: Option<f64>, r: f64, x: Option<f64>| match (m, x) {
                (Some(m), Some(x)) => format!("mean {m:.4}, RMS {r:.4}, max {x:.4} mm"),
                _ => format!("RMS {r:.4} mm"),
            };
            let _ = writeln!(
                s,
                "held out: geometry {}; with the named effects {}",
                fig(f.heldout_before_mean_mm, b, f.heldout_before_max_mm),
                fig(f.heldout_after_mean_mm, a, f.heldout_after_max_mm)
            );
        }
        s
    }

    /// The geometric fit, the noise floor and the mismatch test, as text.
    fn mismatch_text(&self, s: &mut String) {
        let m = &self.mismatch;
        let _ = writeln!(
            s,
            "geometric fit: {} measurements, {} parameters; residual RMS {:.4} mm",
            self.fit.measurements, self.fit.geometric_parameters, m.rms_mm
        );
        let _ = writeln!(
            s,
            "noise floor: {:.4} mm (3-D RMS), method {}: from {}",
            m.noise_floor_mm, m.noise_floor_method, m.noise_source
        );
        if let Some(p) = m.lack_of_fit_p {
            let _ = writeln!(s, "lack-of-fit test of the geometric model: p = {p:.2e}");
        }
        if let (Some(c), Some(p)) = (&m.best_candidate, m.best_candidate_p) {
            let _ = writeln!(
                s,
                "best single candidate: {c} (p = {p:.2e} before Bonferroni)"
            );
        }
        if !m.significant {
            let _ = writeln!(
                s,
                "no significant mismatch: the geometric model explains the recording down to the noise; nothing to name"
            );
        } else {
            let _ = writeln!(s, "significant mismatch remains after the geometric fit");
            for w in &m.where_ {
                let _ = writeln!(s, "  where: {}", w.description);
            }
        }
    }
}

impl DiscrepancyReport {
    /// Appends the discrepancy term as text.
    fn write_text(&self, s: &mut String) {
        let _ = writeln!(
            s,
            "discrepancy term (a smooth fit of the unexplained shape, not physics; apart from the named effects): {} coefficient(s); RMS on the fitted data {:.4} mm with the named effects, {:.4} mm with the term",
            self.columns, self.rms_without_mm, self.rms_with_mm
        );
        if let (Some(a), Some(b)) = (self.heldout_rms_without_mm, self.heldout_rms_with_mm) {
            let _ = writeln!(
                s,
                "  held out ({}): {a:.4} mm with the named effects, {b:.4} mm with the term ({:+.4} mm)",
                self.heldout,
                b - a
            );
        }
    }
}

impl EffectReport {
    /// Appends this effect as text.
    fn write_text(&self, s: &mut String) {
        let e = self;
        let idx = match (&e.joint, &e.axis, &e.axes) {
            (Some(j), _, _) => format!("joint {j}"),
            (_, Some(a), _) => format!("axis {a}"),
            (_, _, Some(p)) => format!("axes {}–{}", p[0], p[1]),
            _ => String::new(),
        };
        let order = e.order.map(|o| format!(" (order {o})")).unwrap_or_default();
        let _ = writeln!(
            s,
            "effect: {}{} on {}: {:.4} ± {:.4} mm RMS, {:.0} % visible to the geometry, p = {:.1e}",
            e.kind,
            order,
            idx,
            e.size_mm,
            e.size_sigma_mm,
            100.0 * e.visible_fraction,
            e.p_value
        );
        let _ = writeln!(s, "  {}", e.explanation);
        let _ = writeln!(
            s,
            "  the geometric parameters absorbed {:.0} % of it",
            100.0 * e.absorbed_fraction
        );
        if let Some(g) = &e.heldout_gain {
            let _ = writeln!(s, "  {}", g.text());
        }
        if let (Some(w), Some(wo)) = (e.heldout_rms_with_mm, e.heldout_rms_without_mm) {
            let _ = writeln!(
                s,
                "  held-out RMS {wo:.4} mm without it, {w:.4} mm with it ({:+.4} mm)",
                w - wo
            );
        }
        for (k, v) in &e.params {
            match e.params_sigma.get(k) {
                Some(sd) => {
                    let _ = writeln!(s, "  {k} = {v:.5} ± {sd:.5}");
                }
                None => {
                    let _ = writeln!(s, "  {k} = {v:.5}");
                }
            }
        }
        if !e.not_separable_from.is_empty() {
            let _ = writeln!(
                s,
                "  {}{} on {} or {}: not separable with these poses",
                e.kind,
                order,
                idx,
                e.not_separable_from.join(" or ")
            );
        }
    }
}

/// The `format` tag of a diagnosis report file.
pub const DIAGNOSIS_FORMAT: &str = "rigcal-diagnosis";
/// The diagnosis report file version this build writes.
pub const DIAGNOSIS_VERSION: u32 = 1;

/// A report as written to a file: tagged like the model file.
#[derive(Serialize)]
struct ReportFile<'a> {
    format: &'static str,
    version: u32,
    created_by: String,
    #[serde(flatten)]
    report: &'a Report,
}

impl Report {
    /// The report as pretty JSON with its `format`, `version` and `created_by`.
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        serde_json::to_string_pretty(&ReportFile {
            format: DIAGNOSIS_FORMAT,
            version: DIAGNOSIS_VERSION,
            created_by: format!("rigcal {}", env!("CARGO_PKG_VERSION")),
            report: self,
        })
    }
}
