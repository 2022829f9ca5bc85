//! Stage 2c, the held-out judgement (issue 35): a library effect the selection chose earns its
//! place only by what it gains on rows not used to fit it.
//!
//! The recording's measurements are cut into K contiguous blocks in row order ([`blocks`]:
//! neighbouring rows share a pose region and a moment, so a row's neighbour would leak its
//! structure into the fit); each block is predicted by the model fitted on the others, with and
//! without the effect, and the effect's gain on the block is the held-out RMS without it minus
//! the RMS with it (the tests' weighted units, mm when the instrument adds no known variance).
//! A time-driven effect (a warm-up drift, [`judged_in_time`]) is judged instead on folds
//! interleaved in time ([`interleaved_folds`]: every K-th measurement in time order), so its
//! held-out rows are predicted inside the span it was fitted over; why that is honest for a
//! function of time and not for one of the pose is said there.
//! The model is the geometry (with the instrument's nuisance) and every other effect still in
//! play — not the shapes of the discrepancy term: an effect is physics the model file carries
//! without them, and a flexible shape beside it can trade with it (a joint's harmonics of
//! orders 5–12 and its order-4 gear error are nearly collinear when the joint visits few
//! angles, as on the UR10's grid), so its gain would be the shapes' instability, not its own.
//! An effect is claimed when
//! - its mean gain over the blocks exceeds [`SIGNIFICANCE_Z`] standard errors, strictly (σ over
//!   the blocks ÷ √K: on white noise the blocks' gains of a term that is not there are, if
//!   anything, negatively correlated, so this does not understate the spread of their mean —
//!   checked by simulation in the tests below),
//! - the part of the held-out error it explains, √(MSE without − MSE with), reaches
//!   [`MIN_GAIN_SHARE`] of the noise floor (below it no user can see it in a held-out figure;
//!   the floor is taken no lower than [`MIN_FLOOR_MM`]),
//! - its fitted joint error is one a joint can have ([`joint_error_limit_deg`]),
//! - and, when held-out recordings or sessions are given, it raises none of them by more than
//!   the rise's own uncertainty: fitted on the whole recording (a session's frame refitted),
//!   each held-out recording is cut into contiguous blocks like the training recording, and a
//!   rise is evidence against the effect only when the mean of its blocks' RMS differences is
//!   below −[`RISE_Z`] standard errors of that mean ([`gain_on`]). A rise within its own noise
//!   (0.056 mm of 14 mm on one TIAGo session, 0.0002 mm on a UR10 series) is no evidence; a
//!   rise of 14 % is.
//! - and, when no held-out recording is given, it does not raise the held-out figure the report
//!   prints in their place, the recording's own split (time blocks 2 and 6 of 8, fitted on the
//!   rest, [`super::heldout`]), at all. That split is a quarter of the recording the blocks
//!   already found the effect significant on, so an effect that earns its place gains there
//!   too (600-row rough recordings: 200 of 200 library effects at 1–5× the floor); one at the
//!   edge of significance on the blocks may not (993 rows of the UR10's series A: joint 3's
//!   compliance at +0.0080 ± 0.0040 mm raised it 0.3930 → 0.3959 mm), and the report must not
//!   print a claim that makes its own held-out figure worse. Given held-out recordings and
//!   sessions are judged with the tolerance above instead: they are other days, where a rise
//!   within its noise is no evidence (an effect that restarts with the arm's warm-up on each
//!   session rose on one by 0.0015 ± 0.0083 mm).
//!
//! The effect failing worst (smallest gain ÷ σ) is set aside and the others judged again
//! without it, until every effect left passes (backward elimination: two effects that share a
//! cause each look useless beside the other, and one of them must stay). What is set aside is
//! reported as "below what this recording can show", with its gain ± σ, never as a name.
//!
//! Cost: one Gram matrix per block of the weighted design (columns scaled to unit norm), summed;
//! a block's training fit solves the normal equations of the sum less the block (one Cholesky
//! factorisation per block and round), and the fit without an effect follows from the same
//! inverse by the Schur complement (removing variables S from a least-squares fit:
//! β₋ = β − M[:,S] M[S,S]⁻¹ β[S], M the inverse normal matrix), so judging E effects costs E
//! small solves per block, not E refits. Only the effects the F-tests chose are judged.
//!
//! Units: residuals and RMS in mm (3 rows per measurement, 3-D RMS per measurement).

use super::heldout::HeldoutRecording;
use super::screen::Screen;
use super::select::{Candidates, Selection};
use super::{Candidate, Data, Index};
use nalgebra::{DMatrix, DVector};
use rigcal_core::kinematics::{JointKind, Robot};
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// At most this many blocks.
pub const MAX_FOLDS: usize = 10;
/// At least this many blocks (a recording too small for them is not judged and claims nothing).
pub const MIN_FOLDS: usize = 3;
/// Measurements per block below which fewer blocks are used: K = clamp(n ÷ this, 3, 10).
const MEASUREMENTS_PER_FOLD: usize = 10;
/// An effect's mean held-out gain must exceed this many standard errors over the blocks.
pub const SIGNIFICANCE_Z: f64 = 2.0;
/// A held-out recording or session refuses an effect when the effect's mean gain over the
/// recording's blocks is below −this many standard errors: the same evidence, one-sided, that a
/// claim needs, here for a rise. Checked on the simulated sessions with moved frames of
/// `tests/real_shaped.rs` (seeds named there), not on the UR10 or the TIAGo.
pub const RISE_Z: f64 = 2.0;
/// The held-out error an effect explains, √(MSE without − MSE with), must reach this share of
/// the noise floor. The library's rate table names effects whose visible size is 0.3× the floor
/// and more; the over-claims of issue 35 were 0.1–0.2×, with held-out RMS unchanged in the
/// fourth digit.
pub const MIN_GAIN_SHARE: f64 = 0.2;

/// The largest joint error (degrees) a gear error or lost motion may fit. Both are
/// arc-minutes on industrial and service arms (0.01–0.1°); 1° is 17 mm at a metre of reach. A
/// larger fit is the effect trading with nearly collinear geometry (issue 35: gear errors of
/// 1.3–5.3° on the UR10), and is not claimed.
pub const MAX_JOINT_ERROR_DEG: f64 = 1.0;

/// The same for a deflection that grows with load or time (joint compliance, a joint's thermal
/// drift): elastic transmissions of service arms deflect a degree or two under gravity (the
/// TIAGo Pro's joint 2: 2.4°, confirmed on another day); 5° is 90 mm at a metre, beyond any arm
/// that reaches its targets (issue 35: a UR10 "deflection" of 2 405°).
pub const MAX_DEFLECTION_DEG: f64 = 5.0;

/// The noise floor the share is taken of is never below this (mm, 3-D RMS): about the
/// resolution of laser trackers and CMMs. A quieter recording (a noiseless simulation) shows
/// rounding, not structure a user could see.
pub const MIN_FLOOR_MM: f64 = 0.005;

/// The joint-error limit of an effect of `kind` (degrees): see [`MAX_JOINT_ERROR_DEG`] and
/// [`MAX_DEFLECTION_DEG`].
pub fn joint_error_limit_deg(kind: crate::effects::EffectKind) -> f64 {
    use crate::effects::EffectKind;
    match kind {
        EffectKind::JointCompliance | EffectKind::ThermalDrift => MAX_DEFLECTION_DEG,
        _ => MAX_JOINT_ERROR_DEG,
    }
}

/// An effect's gain on data not used to fit it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeldoutGain {
    /// Blocks of the recording predicted in turn.
    pub folds: usize,
    /// Held-out RMS over all blocks without the effect (mm).
    pub rms_without_mm: f64,
    /// Held-out RMS over all blocks with it (mm).
    pub rms_with_mm: f64,
    /// Mean over the blocks of (RMS without − RMS with) (mm): positive when the effect helps.
    pub gain_mm: f64,
    /// Standard error of that mean: σ over the blocks ÷ √blocks (mm).
    pub gain_sigma_mm: f64,
    /// The held-out error it explains, √max(0, MSE without − MSE with) over all blocks (mm).
    pub explained_mm: f64,
    /// `explained_mm` ÷ the noise floor.
    pub explained_over_floor: f64,
    /// On the given held-out recordings, fitted on the whole recording: the mean over each
    /// recording's blocks of RMS without − RMS with (mm), of the recording where it is least
    /// in standard errors; None without held-out recordings.
    #[serde(default)]
    pub recordings_gain_mm: Option<f64>,
    /// The standard error of `recordings_gain_mm` (mm).
    #[serde(default)]
    pub recordings_gain_sigma_mm: Option<f64>,
    /// The same on the given held-out sessions, each with its measurement frame refitted; None
    /// without held-out sessions.
    #[serde(default)]
    pub sessions_gain_mm: Option<f64>,
    /// The standard error of `sessions_gain_mm` (mm).
    #[serde(default)]
    pub sessions_gain_sigma_mm: Option<f64>,
    /// On the recording's own held-out split, the figure the report prints when no held-out
    /// recording is given, fitted on the rest: RMS without − RMS with (mm); None with held-out
    /// recordings or when the recording is too small for the split.
    #[serde(default)]
    pub printed_gain_mm: Option<f64>,
    /// For an effect on a revolute joint: the largest joint error it predicts at the
    /// measurements, fitted on the whole recording (degrees).
    #[serde(default)]
    pub peak_joint_error_deg: Option<f64>,
    /// The largest joint error an effect of its kind may have (degrees), when it has one.
    #[serde(default)]
    pub joint_error_limit_deg: Option<f64>,
    /// Whether `folds` are interleaved in time (a time-driven effect, [`judged_in_time`])
    /// rather than contiguous blocks.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub interleaved: bool,
}

impl HeldoutGain {
    /// Why the effect does not earn its place, or None when it does.
    pub fn shortfall(&self) -> Option<String> {
        if self.gain_mm <= SIGNIFICANCE_Z * self.gain_sigma_mm || self.gain_mm <= 0.0 {
            return Some(format!(
                "its held-out gain, {:+.4} ± {:.4} mm over {} {}, is not above {SIGNIFICANCE_Z} σ",
                self.gain_mm,
                self.gain_sigma_mm,
                self.folds,
                self.folds_word()
            ));
        }
        if let (Some(p), Some(limit)) = (self.peak_joint_error_deg, self.joint_error_limit_deg) {
            if p > limit {
                return Some(format!(
                    "its fitted joint error reaches {p:.2}°, more than a joint can have of it ({limit}°): it trades with the geometry or another term, it is not physics"
                ));
            }
        }
        if self.explained_over_floor < MIN_GAIN_SHARE {
            return Some(format!(
                "it explains {:.4} mm of the held-out error, {:.2}× the noise floor (at least {MIN_GAIN_SHARE}× needed)",
                self.explained_mm, self.explained_over_floor
            ));
        }
        if let Some((g, s)) =
            significant_rise(self.recordings_gain_mm, self.recordings_gain_sigma_mm)
        {
            return Some(format!(
                "it raises the RMS of a held-out recording by {:.4} ± {s:.4} mm (more than {RISE_Z} σ)",
                -g
            ));
        }
        if let Some((g, s)) = significant_rise(self.sessions_gain_mm, self.sessions_gain_sigma_mm) {
            return Some(format!(
                "it raises the RMS of a held-out session (frame refitted) by {:.4} ± {s:.4} mm (more than {RISE_Z} σ)",
                -g
            ));
        }
        if let Some(g) = self.printed_gain_mm.filter(|g| *g < 0.0) {
            return Some(format!(
                "it raises the recording's own held-out split (time blocks 2 and 6 of 8, the held-out figure the report prints) by {:.4} mm",
                -g
            ));
        }
        None
    }

    /// What the folds were: "blocks" (contiguous) or "time-interleaved folds".
    fn folds_word(&self) -> &'static str {
        if self.interleaved {
            "time-interleaved folds"
        } else {
            "blocks"
        }
    }

    /// "gain 0.0123 ± 0.0021 mm over 10 blocks (RMS 0.0456 → 0.0333 mm), 0.52× the floor".
    pub fn text(&self) -> String {
        let mut s = format!(
            "held-out gain {:+.4} ± {:.4} mm over {} {} (RMS {:.4} → {:.4} mm; explains {:.4} mm, {:.2}× the floor)",
            self.gain_mm,
            self.gain_sigma_mm,
            self.folds,
            self.folds_word(),
            self.rms_without_mm,
            self.rms_with_mm,
            self.explained_mm,
            self.explained_over_floor
        );
        if let Some(g) = self.recordings_gain_mm {
            let sg = self.recordings_gain_sigma_mm.unwrap_or(f64::NAN);
            s.push_str(&format!(
                "; on the held-out recordings {g:+.4} ± {sg:.4} mm (the least)"
            ));
        }
        if let Some(g) = self.sessions_gain_mm {
            let sg = self.sessions_gain_sigma_mm.unwrap_or(f64::NAN);
            s.push_str(&format!(
                "; on the held-out sessions {g:+.4} ± {sg:.4} mm (the least)"
            ));
        }
        if let Some(g) = self.printed_gain_mm {
            s.push_str(&format!("; on the printed held-out split {g:+.4} mm"));
        }
        s
    }
}

/// A held-out gain `g` ± `sigma` (mm) that is a rise beyond [`RISE_Z`] standard errors: (g, σ).
/// A gain with no σ (a single measurement) is judged by its sign alone.
fn significant_rise(g: Option<f64>, sigma: Option<f64>) -> Option<(f64, f64)> {
    let g = g?;
    let s = sigma.filter(|s| s.is_finite()).unwrap_or(0.0);
    (g < 0.0 && -g > RISE_Z * s).then_some((g, s))
}

/// What the judgement found, per chosen effect (indices into `Selection::chosen`).
#[derive(Debug, Clone, Default)]
pub struct Judgement {
    /// The effects that earn their place, with their gain in the final model.
    pub kept: Vec<(usize, HeldoutGain)>,
    /// The effects set aside, with their gain when set aside and why, in the order set aside.
    pub weak: Vec<(usize, HeldoutGain, String)>,
    /// Why the recording could not be judged (too few measurements), when it could not.
    pub not_judged: Option<String>,
}

/// K contiguous blocks of `n` measurements in row order, sizes differing by at most one:
/// K = clamp(n ÷ 10, 3, 10); empty when n < 3·2 (no block could be predicted from the others).
pub fn blocks(n: usize) -> Vec<Range<usize>> {
    if n < 2 * MIN_FOLDS {
        return Vec::new();
    }
    let k = (n / MEASUREMENTS_PER_FOLD).clamp(MIN_FOLDS, MAX_FOLDS);
    (0..k).map(|f| f * n / k..(f + 1) * n / k).collect()
}

/// Whether an effect of `kind` is judged on time-interleaved folds ([`interleaved_folds`])
/// rather than contiguous blocks: an effect whose regressors vary with time alone (a warm-up
/// drift: a cubic in t times a fixed direction or a fixed joint column).
pub fn judged_in_time(kind: crate::effects::EffectKind) -> bool {
    kind == crate::effects::EffectKind::ThermalDrift
}

/// `k` folds of the measurements interleaved in time: measurement i goes to fold
/// rank(i) mod k, rank(i) its place when the measurements are sorted by time `t_s` (ties
/// in row order). Each fold is then spread over the whole session, and predicting it from the
/// others interpolates in time. Empty when k < [`MIN_FOLDS`] or there are fewer than 2·k
/// measurements.
///
/// Why this is honest for a function of time and blocks are kept for a function of pose:
/// folds must not let the fit carry a held-out row's own structure to it through its
/// neighbours. A term that varies with the pose (a joint's harmonic, a compliance, a shape)
/// can follow pose-local structure, and in a path or grid recording rows that are
/// neighbours in order are neighbours in pose, so an interleaved fold would be predicted from
/// its pose-neighbours and a flexible term credited with what it merely interpolates:
/// contiguous blocks prevent it. A warm-up drift is three coefficients of a cubic in time
/// (one per power), global over the session: it cannot follow a local structure of time or
/// of pose, only the session's trend, and whether that trend exists *during the recording*
/// is what the judgement asks. Held out in contiguous time blocks, the trend of the first or
/// last third must be extrapolated from the rest — a cubic's ends, with a σ from three blocks
/// — and a drift 30 times the F-test's threshold loses (20-row recordings: p = 2·10⁻¹⁴, gain
/// −0.016 ± 0.045 mm on 3 blocks). Interleaved, each fold is predicted inside the time span
/// it was fitted over.
pub fn interleaved_folds(t_s: &[f64], k: usize) -> Vec<Vec<usize>> {
    let n = t_s.len();
    if k < MIN_FOLDS || n < 2 * k {
        return Vec::new();
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| t_s[a].total_cmp(&t_s[b]).then(a.cmp(&b)));
    let mut folds = vec![Vec::with_capacity(n / k + 1); k];
    for (rank, &i) in order.iter().enumerate() {
        folds[rank % k].push(i);
    }
    folds
}

/// The [`FoldSystem`] of `parts` and `y` (3 rows per measurement) on `k` time-interleaved
/// folds ([`interleaved_folds`]): the measurements permuted so that each fold's are
/// contiguous, which leaves every sum and fit of the system unchanged but its cut. None
/// without times on every measurement or with too few measurements.
fn interleaved_system(
    k: usize,
    data: &Data,
    parts: &[DMatrix<f64>],
    y: &DVector<f64>,
) -> Option<FoldSystem> {
    let t = data.t_s.as_ref()?;
    let folds = interleaved_folds(t, k);
    if folds.is_empty() {
        return None;
    }
    let rows: Vec<usize> = folds
        .iter()
        .flatten()
        .flat_map(|&i| 3 * i..3 * i + 3)
        .collect();
    let mut cut = Vec::with_capacity(folds.len());
    let mut start = 0;
    for f in &folds {
        cut.push(start..start + f.len());
        start += f.len();
    }
    let parts: Vec<DMatrix<f64>> = parts.iter().map(|p| p.select_rows(&rows)).collect();
    Some(FoldSystem::new(cut, &parts, y.select_rows(&rows)))
}

/// The weighted design of the final model split by term, with its per-block Gram matrices.
struct FoldSystem {
    /// Weighted design, columns scaled to unit norm: base (geometry, nuisance), then each term.
    a: DMatrix<f64>,
    /// Weighted residual of the geometric fit (mm).
    y: DVector<f64>,
    /// Column scale applied to `a` (the norm of each weighted column).
    scale: Vec<f64>,
    /// Columns of each term; term 0 is the base, always in the model.
    terms: Vec<Range<usize>>,
    /// Measurement ranges of the blocks.
    blocks: Vec<Range<usize>>,
    /// Aᵀ A and Aᵀ y of each block.
    grams: Vec<(DMatrix<f64>, DVector<f64>)>,
    /// Their sums.
    total: (DMatrix<f64>, DVector<f64>),
}

impl FoldSystem {
    fn new(cut: Vec<Range<usize>>, parts: &[DMatrix<f64>], y: DVector<f64>) -> Self {
        let nrows = y.len();
        let mut terms = Vec::with_capacity(parts.len());
        let mut c = 0;
        for p in parts {
            terms.push(c..c + p.ncols());
            c += p.ncols();
        }
        let mut a = super::linalg::hcat(parts, nrows);
        let scale: Vec<f64> = a.column_iter().map(|col| col.norm().max(1e-300)).collect();
        for (j, s) in scale.iter().enumerate() {
            a.column_mut(j).scale_mut(1.0 / s);
        }
        let p = a.ncols();
        let mut total = (DMatrix::zeros(p, p), DVector::zeros(p));
        let mut grams = Vec::with_capacity(cut.len());
        for b in &cut {
            let rows = 3 * b.start..3 * b.end;
            let af = a.rows(rows.start, rows.len());
            let yf = y.rows(rows.start, rows.len());
            let g = af.tr_mul(&af);
            let r = af.tr_mul(&yf);
            total.0 += &g;
            total.1 += &r;
            grams.push((g, r));
        }
        FoldSystem {
            a,
            y,
            scale,
            terms,
            blocks: cut,
            grams,
            total,
        }
    }

    /// Columns of the model with the terms `active` (base always).
    fn columns(&self, active: &[usize]) -> Vec<usize> {
        let mut cols: Vec<usize> = self.terms[0].clone().collect();
        for &t in active {
            cols.extend(self.terms[t].clone());
        }
        cols
    }
}

/// Inverse of the symmetric positive semi-definite `n` (unit-scaled columns' normal matrix) by
/// Cholesky with a small ridge: directions no training row shows (a spline interval inside the
/// held-out block) get a coefficient near zero instead of failing. None if even the largest
/// ridge fails.
pub(super) fn regularised_inverse(n: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let p = n.nrows();
    let top = (0..p).map(|i| n[(i, i)]).fold(0.0f64, f64::max).max(1e-300);
    for ridge in [1e-10, 1e-8, 1e-6] {
        let mut m = n.clone();
        for i in 0..p {
            m[(i, i)] += ridge * top;
        }
        if let Some(ch) = m.cholesky() {
            return Some(ch.inverse());
        }
    }
    None
}

/// A training fit (inverse normal matrix and solution over `cols`), and each judged term's
/// coefficient change when it is removed (padded to all columns).
struct Fit {
    beta: DVector<f64>,
    /// Per judged term: β − β₋ (the fit's change when the term is removed), over all columns.
    drop_delta: Vec<DVector<f64>>,
}

/// Fits `cols` with normal matrix `n` and right-hand side `c` (all columns), and the fits
/// without each term of `judged` (columns `sys.terms[t]`) by the Schur complement.
fn fit_with_drops(
    sys: &FoldSystem,
    n: &DMatrix<f64>,
    c: &DVector<f64>,
    cols: &[usize],
    judged: &[usize],
) -> Option<Fit> {
    let p = sys.a.ncols();
    let k = cols.len();
    let nn = DMatrix::from_fn(k, k, |i, j| n[(cols[i], cols[j])]);
    let cc = DVector::from_fn(k, |i, _| c[cols[i]]);
    let m = regularised_inverse(&nn)?;
    let b = &m * &cc;
    let pad = |v: &DVector<f64>| {
        let mut out = DVector::zeros(p);
        for (i, &col) in cols.iter().enumerate() {
            out[col] = v[i];
        }
        out
    };
    let mut drop_delta = Vec::with_capacity(judged.len());
    for &t in judged {
        let s: Vec<usize> = cols
            .iter()
            .enumerate()
            .filter(|(_, col)| sys.terms[t].contains(col))
            .map(|(i, _)| i)
            .collect();
        let mss = DMatrix::from_fn(s.len(), s.len(), |i, j| m[(s[i], s[j])]);
        let bs = DVector::from_fn(s.len(), |i, _| b[s[i]]);
        let msi = regularised_inverse(&mss)?;
        let ms = DMatrix::from_fn(k, s.len(), |i, j| m[(i, s[j])]);
        // β − β₋ = M[:,S] M[S,S]⁻¹ β[S] (β₋[S] is then zero).
        drop_delta.push(pad(&(ms * (msi * bs))));
    }
    Some(Fit {
        beta: pad(&b),
        drop_delta,
    })
}

/// Per judged term, the held-out sums of squares of the blocks with and without it:
/// (SSE with, SSE without, rows) per block; plus the residual variance of the whole fit.
struct BlockSums {
    per_term: Vec<Vec<(f64, f64, usize)>>,
}

fn block_sums(sys: &FoldSystem, cols: &[usize], judged: &[usize]) -> Option<BlockSums> {
    let mut per_term = vec![Vec::with_capacity(sys.blocks.len()); judged.len()];
    for (f, b) in sys.blocks.iter().enumerate() {
        let n = &sys.total.0 - &sys.grams[f].0;
        let c = &sys.total.1 - &sys.grams[f].1;
        let fit = fit_with_drops(sys, &n, &c, cols, judged)?;
        let rows = 3 * b.start..3 * b.end;
        let af = sys.a.rows(rows.start, rows.len());
        let e = sys.y.rows(rows.start, rows.len()) - af * &fit.beta;
        let sse_with = e.norm_squared();
        for (t, d) in fit.drop_delta.iter().enumerate() {
            let without = &e + af * d;
            per_term[t].push((sse_with, without.norm_squared(), b.len()));
        }
    }
    Some(BlockSums { per_term })
}

/// The gain of one term from its blocks' sums; `floor` the noise floor (mm, 3-D RMS).
fn gain_of(sums: &[(f64, f64, usize)], floor: f64) -> HeldoutGain {
    let k = sums.len();
    let per: Vec<f64> = sums
        .iter()
        .map(|&(w, wo, m)| {
            let m = m.max(1) as f64;
            (wo / m).sqrt() - (w / m).sqrt()
        })
        .collect();
    let mean = per.iter().sum::<f64>() / k.max(1) as f64;
    let var = per.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (k.max(2) - 1) as f64;
    let m: f64 = sums.iter().map(|s| s.2 as f64).sum::<f64>().max(1.0);
    let sse_w: f64 = sums.iter().map(|s| s.0).sum();
    let sse_wo: f64 = sums.iter().map(|s| s.1).sum();
    let explained = ((sse_wo - sse_w) / m).max(0.0).sqrt();
    HeldoutGain {
        folds: k,
        rms_without_mm: (sse_wo / m).sqrt(),
        rms_with_mm: (sse_w / m).sqrt(),
        gain_mm: mean,
        gain_sigma_mm: (var / k.max(1) as f64).sqrt(),
        explained_mm: explained,
        explained_over_floor: explained / floor.max(1e-300),
        recordings_gain_mm: None,
        recordings_gain_sigma_mm: None,
        sessions_gain_mm: None,
        sessions_gain_sigma_mm: None,
        printed_gain_mm: None,
        peak_joint_error_deg: None,
        joint_error_limit_deg: None,
        interleaved: false,
    }
}

/// The design of the model on the given held-out recordings (rows weighted by axis like the
/// training rows, columns scaled like the training design): base (their geometric Jacobian,
/// zero nuisance), then each term rebuilt on them (zero where they cannot show it).
fn heldout_design(
    sys: &FoldSystem,
    screen: &Screen,
    parts_on: &dyn Fn(&HeldoutRecording) -> Vec<DMatrix<f64>>,
    h: &HeldoutRecording,
) -> (DMatrix<f64>, DVector<f64>) {
    let n = 3 * h.0.len();
    let mut a = super::linalg::hcat(&parts_on(h), n);
    let w = |r: usize| screen.weights.get(r % 3).copied().unwrap_or(1.0);
    for r in 0..n {
        let wr = w(r);
        if wr != 1.0 {
            a.row_mut(r).scale_mut(wr);
        }
    }
    for (j, s) in sys.scale.iter().enumerate() {
        a.column_mut(j).scale_mut(1.0 / s);
    }
    let y = DVector::from_fn(n, |r, _| h.2[r] * w(r));
    (a, y)
}

/// Judges the library effects of `sel` on held-out blocks of the recording (and the given
/// held-out recordings), beside the geometry and each other: see the module
/// documentation. The noise floor is the screen's pure error when it uses it, else the residual
/// variance of the whole model.
pub fn judge(
    screen: &Screen,
    cands: &Candidates,
    sel: &Selection,
    lib: &[Box<dyn Candidate>],
    heldout: &[HeldoutRecording],
    sessions: &[(HeldoutRecording, DMatrix<f64>)],
    data: &Data,
) -> Judgement {
    let nrows = screen.rows();
    let m = nrows / 3;
    if sel.chosen.is_empty() {
        return Judgement::default();
    }
    let cut = blocks(m);
    if cut.is_empty() {
        return Judgement {
            not_judged: Some(format!(
                "{m} measurements are too few to hold out {MIN_FOLDS} blocks: no effect can earn its place"
            )),
            weak: (0..sel.chosen.len())
                .map(|i| (i, empty_gain(), "too few measurements to hold any out".into()))
                .collect(),
            ..Default::default()
        };
    }
    let base = screen.weigh(&screen.model);
    let mut parts = vec![base];
    for c in &sel.chosen {
        parts.push(
            cands.weighted[c.cand]
                .clone()
                .unwrap_or_else(|| DMatrix::zeros(nrows, c.x.ncols())),
        );
    }
    let y = screen.weighted_residual();
    let time_driven: Vec<bool> = sel
        .chosen
        .iter()
        .map(|c| judged_in_time(lib[c.cand].kind()))
        .collect();
    let interleaved = time_driven
        .contains(&true)
        .then(|| interleaved_system(cut.len(), data, &parts, &y))
        .flatten();
    let sys = FoldSystem::new(cut, &parts, y);
    let n_eff = sel.chosen.len();
    let floor = noise_floor(screen, &sys);
    let parts_on = |h: &HeldoutRecording| -> Vec<DMatrix<f64>> {
        let (hd, hg, _) = h;
        let n = 3 * hd.len();
        let mut out = vec![super::linalg::hcat(
            &[
                hg.clone(),
                DMatrix::zeros(n, screen.model.ncols() - hg.ncols()),
            ],
            n,
        )];
        for c in &sel.chosen {
            out.push(
                lib[c.cand]
                    .regressors(hd)
                    .unwrap_or_else(|| DMatrix::zeros(n, c.x.ncols())),
            );
        }
        out
    };
    let held: Vec<(DMatrix<f64>, DVector<f64>)> = heldout
        .iter()
        .map(|h| heldout_design(&sys, screen, &parts_on, h))
        .collect();
    let on_sessions: Vec<(DMatrix<f64>, DVector<f64>)> = sessions
        .iter()
        .map(|(h, frame)| {
            let (a, y) = heldout_design(&sys, screen, &parts_on, h);
            (
                super::linalg::project_out(frame, &a),
                &y - frame * (frame.transpose() * &y),
            )
        })
        .collect();
    let own_split = if heldout.is_empty() {
        super::heldout::own_split(m).map(|rows| split_system(&sys, &rows))
    } else {
        None
    };
    let mut active: Vec<usize> = (1..=n_eff).collect();
    let mut out = Judgement::default();
    loop {
        let cols = sys.columns(&active);
        let Some(sums) = block_sums(&sys, &cols, &active) else {
            out.not_judged =
                Some("the held-out fits are singular: no effect can earn its place".into());
            for &t in &active {
                out.weak
                    .push((t - 1, empty_gain(), "the held-out fits are singular".into()));
            }
            return out;
        };
        let in_time = interleaved
            .as_ref()
            .and_then(|isys| block_sums(isys, &cols, &active));
        let mut gains: Vec<HeldoutGain> = sums
            .per_term
            .iter()
            .zip(&active)
            .enumerate()
            .map(|(i, (s, &t))| match &in_time {
                Some(it) if time_driven[t - 1] => {
                    let mut g = gain_of(&it.per_term[i], floor);
                    g.interleaved = true;
                    g
                }
                _ => gain_of(s, floor),
            })
            .collect();
        if let Some(fit) = fit_with_drops(&sys, &sys.total.0, &sys.total.1, &cols, &active) {
            for ((g, d), &t) in gains.iter_mut().zip(&fit.drop_delta).zip(&active) {
                (g.recordings_gain_mm, g.recordings_gain_sigma_mm) =
                    gain_on(&held, &fit.beta, d).unzip();
                (g.sessions_gain_mm, g.sessions_gain_sigma_mm) =
                    gain_on(&on_sessions, &fit.beta, d).unzip();
                let c = &sel.chosen[t - 1];
                let coef = DVector::from_fn(c.x.ncols(), |i, _| {
                    let col = sys.terms[t].start + i;
                    fit.beta[col] / sys.scale[col]
                });
                g.peak_joint_error_deg =
                    peak_joint_error_deg(lib[c.cand].as_ref(), &c.x, &coef, data);
                g.joint_error_limit_deg = g
                    .peak_joint_error_deg
                    .map(|_| joint_error_limit_deg(lib[c.cand].kind()));
            }
        }
        if let Some(split) = &own_split {
            if let Some(fit) = fit_with_drops(&sys, &split.normal, &split.rhs, &cols, &active) {
                let test = [(split.a.clone(), split.y.clone())];
                for (g, d) in gains.iter_mut().zip(&fit.drop_delta) {
                    g.printed_gain_mm = pooled_gain(&test, &fit.beta, d);
                }
            }
        }
        let worst = gains
            .iter()
            .enumerate()
            .filter_map(|(i, g)| g.shortfall().map(|why| (i, g, why)))
            .min_by(|a, b| z_of(a.1).total_cmp(&z_of(b.1)))
            .map(|(i, g, why)| (i, g.clone(), why))
            .or_else(|| together_rise(&sys, &cols, (&held, &on_sessions), &gains));
        match worst {
            None => {
                out.kept = active.iter().map(|t| t - 1).zip(gains).collect();
                return out;
            }
            Some((i, g, why)) => {
                tracing::debug!(effect = %lib[sel.chosen[active[i] - 1].cand].label(), %why, "set aside: held-out gain");
                out.weak.push((active[i] - 1, g, why));
                active.remove(i);
                if active.is_empty() {
                    return out;
                }
            }
        }
    }
}

/// The largest joint error (degrees) the effect `c` with regressors `x` (unweighted) and
/// coefficients `coef` predicts at the measurements of `d`, for an effect on a revolute joint:
/// each measurement's displacement v_i (mm) read as a joint error through the joint's column
/// J_j of the joint Jacobian, J_jᵀ v_i ÷ ‖J_j‖² (exact for the library's joint effects, whose
/// columns are multiples of J_j). None for other effects.
fn peak_joint_error_deg(
    c: &dyn Candidate,
    x: &DMatrix<f64>,
    coef: &DVector<f64>,
    d: &Data,
) -> Option<f64> {
    let Index::Joint(j) = c.index() else {
        return None;
    };
    if d.chain.joints()[j].kind != JointKind::Revolute || x.ncols() != coef.len() {
        return None;
    }
    let v = x * coef;
    let peak = (0..d.len())
        .map(|i| {
            let jj = d.joint_jacobian[i].column(j);
            let n2 = jj.norm_squared();
            if n2 <= 1e-12 {
                return 0.0;
            }
            let vi = nalgebra::Vector3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
            (jj.dot(&vi) / n2).abs()
        })
        .fold(0.0, f64::max);
    Some(peak.to_degrees())
}

/// A term's gain on each of the designs `held` (the whole-recording fit `beta` and the term's
/// coefficient change `delta` when removed): the mean over the design's contiguous blocks
/// ([`blocks`]; one measurement per block when it has fewer than 6) of RMS without − RMS with
/// (mm), with its standard error (σ over the blocks ÷ √blocks: the fit is fixed, so the blocks
/// are independent predictions). Of the designs, the one whose gain is least in standard errors,
/// so an effect is judged on every held-out recording or session, not their pool (an effect that
/// helps one series and hurts another does not carry); None without designs.
fn gain_on(
    held: &[(DMatrix<f64>, DVector<f64>)],
    beta: &DVector<f64>,
    delta: &DVector<f64>,
) -> Option<(f64, f64)> {
    held.iter()
        .map(|(a, y)| {
            let with = y - a * beta;
            let without = &with + a * delta;
            blocked_gain(&with, &without)
        })
        .min_by(|a, b| rise_order(*a).total_cmp(&rise_order(*b)))
}

/// A held-out recording or session as the judgement reads it: its weighted, column-scaled
/// design and its weighted residual (mm).
type HeldDesign = (DMatrix<f64>, DVector<f64>);

/// How an effect's gain on the held-out recordings or on the sessions is read from its
/// [`HeldoutGain`]: (gain, σ) in mm.
type OwnGain = fn(&HeldoutGain) -> (f64, f64);

/// When every effect passes alone: whether the effects together raise a given held-out
/// recording or session beyond [`RISE_Z`] standard errors (rises within each effect's noise
/// can add up: on the TIAGo Pro, four compliances each within 2 σ of no change on session 0805
/// raised it together by about 1 mm of 14). Then the effect whose own held-out gain is least in
/// standard errors is set aside: its index in `gains`, its gain and why.
fn together_rise(
    sys: &FoldSystem,
    cols: &[usize],
    (held, sessions): (&[HeldDesign], &[HeldDesign]),
    gains: &[HeldoutGain],
) -> Option<(usize, HeldoutGain, String)> {
    if gains.len() < 2 || (held.is_empty() && sessions.is_empty()) {
        return None;
    }
    let fit = fit_with_drops(sys, &sys.total.0, &sys.total.1, cols, &[])?;
    let base = fit_with_drops(sys, &sys.total.0, &sys.total.1, &sys.columns(&[]), &[])?;
    let delta = &fit.beta - &base.beta;
    let rise = |designs: &[(DMatrix<f64>, DVector<f64>)], what: &str| {
        let (g, sigma) = gain_on(designs, &fit.beta, &delta)?;
        significant_rise(Some(g), Some(sigma)).map(|(g, s)| {
            format!("together the named effects raise the RMS of a held-out {what} by {:.4} ± {s:.4} mm (more than {RISE_Z} σ), and this one's own gain there is the least", -g)
        })
    };
    let (why, own): (String, OwnGain) = if let Some(why) = rise(held, "recording") {
        (why, |g| {
            (
                g.recordings_gain_mm.unwrap_or(0.0),
                g.recordings_gain_sigma_mm.unwrap_or(f64::NAN),
            )
        })
    } else {
        (rise(sessions, "session (frames refitted)")?, |g| {
            (
                g.sessions_gain_mm.unwrap_or(0.0),
                g.sessions_gain_sigma_mm.unwrap_or(f64::NAN),
            )
        })
    };
    let (i, g) = gains
        .iter()
        .enumerate()
        .min_by(|a, b| rise_order(own(a.1)).total_cmp(&rise_order(own(b.1))))?;
    Some((i, g.clone(), why))
}

/// The recording's own held-out split (the rows of [`super::heldout::own_split`]): its design
/// rows and residual, and the normal equations of the other rows.
struct SplitSystem {
    a: DMatrix<f64>,
    y: DVector<f64>,
    normal: DMatrix<f64>,
    rhs: DVector<f64>,
}

fn split_system(sys: &FoldSystem, measurements: &[usize]) -> SplitSystem {
    let rows: Vec<usize> = measurements
        .iter()
        .flat_map(|&i| 3 * i..3 * i + 3)
        .collect();
    let a = sys.a.select_rows(&rows);
    let y = sys.y.select_rows(&rows);
    SplitSystem {
        normal: &sys.total.0 - a.tr_mul(&a),
        rhs: &sys.total.1 - a.tr_mul(&y),
        a,
        y,
    }
}

/// RMS without − RMS with a term over all the designs `held` pooled (mm); None without
/// designs.
fn pooled_gain(
    held: &[(DMatrix<f64>, DVector<f64>)],
    beta: &DVector<f64>,
    delta: &DVector<f64>,
) -> Option<f64> {
    if held.is_empty() {
        return None;
    }
    let (mut with, mut without, mut m) = (0.0, 0.0, 0usize);
    for (a, y) in held {
        let e = y - a * beta;
        without += (&e + a * delta).norm_squared();
        with += e.norm_squared();
        m += y.len() / 3;
    }
    let m = m.max(1) as f64;
    Some((without / m).sqrt() - (with / m).sqrt())
}

/// Mean and standard error (mm) over contiguous blocks of measurements of RMS without − RMS
/// with, from the stacked residuals with and without a term (3 rows per measurement).
fn blocked_gain(with: &DVector<f64>, without: &DVector<f64>) -> (f64, f64) {
    let m = with.len() / 3;
    let mut cut = blocks(m);
    if cut.is_empty() {
        cut = (0..m).map(|i| i..i + 1).collect();
    }
    let rms = |r: &DVector<f64>, b: &Range<usize>| {
        (r.rows(3 * b.start, 3 * b.len()).norm_squared() / b.len().max(1) as f64).sqrt()
    };
    let per: Vec<f64> = cut.iter().map(|b| rms(without, b) - rms(with, b)).collect();
    let k = per.len().max(1) as f64;
    let mean = per.iter().sum::<f64>() / k;
    if per.len() < 2 {
        return (mean, f64::NAN);
    }
    let var = per.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (k - 1.0);
    (mean, (var / k).sqrt())
}

/// Gain ÷ σ of a held-out gain, the order in which held-out recordings are worst for an effect
/// (a rise with no σ first).
fn rise_order((g, s): (f64, f64)) -> f64 {
    if s.is_finite() && s > 0.0 {
        g / s
    } else if g < 0.0 {
        f64::NEG_INFINITY
    } else {
        f64::INFINITY
    }
}

/// Gain ÷ its σ, the order in which failing effects are set aside (∞ for an exact gain).
fn z_of(g: &HeldoutGain) -> f64 {
    if g.gain_sigma_mm > 0.0 {
        g.gain_mm / g.gain_sigma_mm
    } else if g.gain_mm > 0.0 {
        f64::INFINITY
    } else {
        f64::NEG_INFINITY
    }
}

fn empty_gain() -> HeldoutGain {
    HeldoutGain {
        folds: 0,
        rms_without_mm: f64::NAN,
        rms_with_mm: f64::NAN,
        gain_mm: 0.0,
        gain_sigma_mm: f64::NAN,
        explained_mm: 0.0,
        explained_over_floor: 0.0,
        recordings_gain_mm: None,
        recordings_gain_sigma_mm: None,
        sessions_gain_mm: None,
        sessions_gain_sigma_mm: None,
        printed_gain_mm: None,
        peak_joint_error_deg: None,
        joint_error_limit_deg: None,
        interleaved: false,
    }
}

/// The noise floor (3-D RMS, mm) the share is taken of: √3·σ with σ² from pure error when the
/// screen uses it, else the residual variance of the whole model (every term) on all rows; never
/// below [`MIN_FLOOR_MM`].
fn noise_floor(screen: &Screen, sys: &FoldSystem) -> f64 {
    measured_floor(screen, sys).max(MIN_FLOOR_MM)
}

/// The floor of [`noise_floor`] before its lower bound.
fn measured_floor(screen: &Screen, sys: &FoldSystem) -> f64 {
    if let Some(v) = screen.noise_var() {
        return (3.0 * v).sqrt();
    }
    let cols: Vec<usize> = (0..sys.a.ncols()).collect();
    let Some(fit) = fit_with_drops(sys, &sys.total.0, &sys.total.1, &cols, &[]) else {
        return f64::NAN;
    };
    let e = &sys.y - &sys.a * &fit.beta;
    let dof = sys.y.len().saturating_sub(cols.len()).max(1);
    (3.0 * e.norm_squared() / dof as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_contiguous_cover_every_row_and_scale_with_n() {
        assert!(blocks(5).is_empty());
        let b = blocks(22);
        assert_eq!(b.len(), 3);
        assert_eq!(b.first().map(|r| r.start), Some(0));
        assert_eq!(b.last().map(|r| r.end), Some(22));
        assert!(b.windows(2).all(|w| w[0].end == w[1].start));
        assert_eq!(blocks(600).len(), 10);
        assert!(blocks(601).iter().all(|r| r.len() == 60 || r.len() == 61));
    }

    #[test]
    fn interleaved_folds_take_every_kth_measurement_in_time_order() {
        // Times out of row order: row 3 is first in time, row 0 last.
        let t = [9.0, 2.0, 5.0, 0.0, 7.0, 1.0, 3.0];
        assert!(interleaved_folds(&t, 3).len() == 3);
        // Time order: rows 3, 5, 1, 6, 2, 4, 0 → folds {3, 6, 0}, {5, 2}, {1, 4}.
        assert_eq!(
            interleaved_folds(&t, 3),
            vec![vec![3, 6, 0], vec![5, 2], vec![1, 4]]
        );
        assert!(interleaved_folds(&t[..5], 3).is_empty());
        assert!(interleaved_folds(&t, 2).is_empty());
    }

    /// The gain of a cubic-in-time term on time-interleaved folds (30 measurements, 3 folds):
    /// on noise without a drift the held-out rule claims it in at most 1 % of recordings, and
    /// a drift at 3× the noise floor earns its place.
    #[test]
    fn a_time_term_on_interleaved_folds_is_not_optimistic_on_noise_and_sees_a_drift() {
        let n = 30;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 60.0).collect();
        let u = |i: usize| t[i] / t[n - 1];
        let base = DMatrix::from_fn(3 * n, 3, |r, c| if r % 3 == c { 1.0 } else { 0.0 });
        let drift = DMatrix::from_fn(3 * n, 3, |r, c| {
            if r % 3 == 2 {
                u(r / 3).powi(c as i32 + 1)
            } else {
                0.0
            }
        });
        let folds = interleaved_folds(&t, blocks(n).len());
        let system = |y: &DVector<f64>| {
            let data_rows: Vec<usize> = folds
                .iter()
                .flatten()
                .flat_map(|&i| 3 * i..3 * i + 3)
                .collect();
            let mut cut = Vec::new();
            let mut start = 0;
            for f in &folds {
                cut.push(start..start + f.len());
                start += f.len();
            }
            let parts = [base.select_rows(&data_rows), drift.select_rows(&data_rows)];
            FoldSystem::new(cut, &parts, y.select_rows(&data_rows))
        };
        let sigma = 0.02;
        let floor = sigma * 3f64.sqrt();
        let gain = |y: &DVector<f64>| {
            let sys = system(y);
            let cols = sys.columns(&[1]);
            gain_of(
                &block_sums(&sys, &cols, &[1]).expect("fits").per_term[0],
                floor,
            )
        };
        let reps = 300;
        let (mut means, mut naive) = (Vec::with_capacity(reps), 0.0);
        let (mut passes, mut z2) = (0usize, 0usize);
        for rep in 0..reps {
            let y = DVector::from_fn(3 * n, |r, _| sigma * pseudo_noise(r + rep * 1_000_003 + 11));
            let g = gain(&y);
            means.push(g.gain_mm);
            naive += g.gain_sigma_mm.powi(2);
            passes += usize::from(g.shortfall().is_none());
            z2 += usize::from(g.gain_mm > 2.0 * g.gain_sigma_mm);
        }
        let mu = means.iter().sum::<f64>() / reps as f64;
        let spread = means.iter().map(|m| (m - mu).powi(2)).sum::<f64>() / (reps - 1) as f64;
        let naive = naive / reps as f64;
        eprintln!(
            "spread² {spread:.3e}, mean σ² {naive:.3e}, passes {passes}/{reps}, z > 2 {z2}/{reps}"
        );
        // The 2 σ gate alone is optimistic here (measured: z > 2 in 56 of 300, spread² 1.3×
        // the mean σ²: three folds' gains are a t with 2 dof, and interleaved folds share most
        // of their training rows), so the rule does not rest on it alone: the gain must also
        // explain MIN_GAIN_SHARE of the floor, which no noise recording does (0 of 300), and
        // the F-test before it chose the term at a Bonferroni α.
        assert!(
            passes <= reps / 100,
            "{passes}/{reps} noise recordings pass"
        );
        assert!(z2 < reps / 3, "{z2}/{reps}");
        // A warm-up 1 − e^(−t/τ) along z whose visible RMS is 3× the floor.
        let w = |i: usize| 1.0 - (-t[i] / 900.0).exp();
        let mean_w = (0..n).map(w).sum::<f64>() / n as f64;
        let rms_w = ((0..n).map(|i| (w(i) - mean_w).powi(2)).sum::<f64>() / n as f64).sqrt();
        let a = 3.0 * floor / rms_w;
        let y = DVector::from_fn(3 * n, |r, _| {
            // Uniform on [−1, 1] has σ 1/√3.
            sigma * 3f64.sqrt() * pseudo_noise(r + 77) + if r % 3 == 2 { a * w(r / 3) } else { 0.0 }
        });
        let g = gain(&y);
        assert!(g.shortfall().is_none(), "{g:?}");
    }

    /// An independent check of the Schur-complement drop: the fit without a term equals the
    /// fit of the remaining columns solved directly.
    #[test]
    fn dropping_a_term_by_schur_complement_equals_refitting_without_it() {
        let n = 40;
        let a0 = DMatrix::from_fn(3 * n, 2, |r, c| ((r * 7 + c * 3) % 11) as f64 - 5.0);
        let a1 = DMatrix::from_fn(3 * n, 1, |r, _| ((r * r) % 13) as f64 * 0.1);
        let a2 = DMatrix::from_fn(3 * n, 2, |r, c| ((r as f64) * 0.3 + c as f64).sin());
        let y = DVector::from_fn(3 * n, |r, _| ((r * 5) % 7) as f64 - 3.0 + 0.01 * r as f64);
        let sys = FoldSystem::new(blocks(n), &[a0, a1, a2], y.clone());
        let cols = sys.columns(&[1, 2]);
        let fit = fit_with_drops(&sys, &sys.total.0, &sys.total.1, &cols, &[1]).expect("fit");
        let without = &fit.beta - &fit.drop_delta[0];
        // Direct least squares on the base and term 2 columns.
        let keep: Vec<usize> = sys.columns(&[2]);
        let sub = DMatrix::from_fn(3 * n, keep.len(), |r, c| sys.a[(r, keep[c])]);
        let direct = super::super::linalg::lstsq(&sub, &y).solution;
        for (i, &c) in keep.iter().enumerate() {
            assert!(
                (without[c] - direct[i]).abs() < 1e-6,
                "{} vs {}",
                without[c],
                direct[i]
            );
        }
        assert!(without[sys.terms[1].start].abs() < 1e-9);
    }

    /// A deterministic stand-in for noise: a hash of the row mapped to [−1, 1].
    fn pseudo_noise(r: usize) -> f64 {
        let h = (r as u64)
            .wrapping_mul(0x9e37_79b9_7f4a_7c15)
            .rotate_left(17);
        (h % 20_001) as f64 / 10_000.0 - 1.0
    }

    /// The gain of term 1 (one column `x`) beside a two-column base, for `y`.
    fn gain_for(x: &DVector<f64>, y: &DVector<f64>, n: usize) -> HeldoutGain {
        let base = DMatrix::from_fn(3 * n, 2, |r, c| {
            if c == 0 {
                1.0
            } else {
                (r / 3) as f64 / n as f64
            }
        });
        let xm = DMatrix::from_column_slice(3 * n, 1, x.as_slice());
        let sys = FoldSystem::new(blocks(n), &[base, xm], y.clone());
        let cols = sys.columns(&[1]);
        let sums = block_sums(&sys, &cols, &[1]).expect("fits");
        gain_of(&sums.per_term[0], 0.02 * 3f64.sqrt())
    }

    /// A term that explains every block earns its place; the same term when the structure it
    /// fits lives in one block only (the F-test over all rows still sees it) does not: its
    /// gain is large on one block and negative on the others, not above 2 σ.
    #[test]
    fn a_gain_on_one_block_only_is_not_significant() {
        let n = 400;
        let x = DVector::from_fn(3 * n, |r, _| ((r as f64) * 0.37).sin());
        let noise = DVector::from_fn(3 * n, |r, _| 0.02 * pseudo_noise(r));
        let everywhere = &noise + &x * 0.02;
        let g = gain_for(&x, &everywhere, n);
        assert!(g.shortfall().is_none(), "{g:?}");
        // The same structure, 4× larger, in the rows of the fourth block only.
        let local = DVector::from_fn(3 * n, |r, _| {
            let i = r / 3;
            noise[r]
                + if (3 * n / 10..4 * n / 10).contains(&i) {
                    0.08 * x[r]
                } else {
                    0.0
                }
        });
        // The F-test on all rows finds it: ΔSS of the one column far above σ².
        let xn = x.normalize();
        let dss = xn.dot(&local).powi(2);
        assert!(dss > 100.0 * (0.02f64.powi(2) / 3.0), "ΔSS {dss}");
        let g = gain_for(&x, &local, n);
        assert!(g.gain_mm <= SIGNIFICANCE_Z * g.gain_sigma_mm, "{g:?}");
        assert!(g.shortfall().is_some());
    }

    #[test]
    fn a_gain_within_two_sigma_or_below_the_share_falls_short() {
        let g = |gain: f64, sigma: f64, over: f64| HeldoutGain {
            folds: 10,
            rms_without_mm: 1.0,
            rms_with_mm: 1.0 - gain,
            gain_mm: gain,
            gain_sigma_mm: sigma,
            explained_mm: over,
            explained_over_floor: over,
            recordings_gain_mm: None,
            recordings_gain_sigma_mm: None,
            sessions_gain_mm: None,
            sessions_gain_sigma_mm: None,
            printed_gain_mm: None,
            peak_joint_error_deg: None,
            joint_error_limit_deg: None,
            interleaved: false,
        };
        assert!(g(0.01, 0.004, 0.5).shortfall().is_none());
        assert!(g(0.01, 0.006, 0.5).shortfall().is_some());
        assert!(g(0.01, 0.001, 0.1).shortfall().is_some());
        let mut worse = g(0.01, 0.001, 0.5);
        worse.recordings_gain_mm = Some(-0.002);
        assert!(worse.shortfall().is_some());
        let mut implausible = g(0.01, 0.001, 0.5);
        implausible.peak_joint_error_deg = Some(5.3);
        implausible.joint_error_limit_deg = Some(MAX_JOINT_ERROR_DEG);
        assert!(implausible.shortfall().is_some_and(|w| w.contains("5.30°")));
        // A held-out rise within its own noise is no evidence; beyond RISE_Z σ it refuses.
        let mut noisy = g(0.01, 0.001, 0.5);
        noisy.sessions_gain_mm = Some(-0.056);
        noisy.sessions_gain_sigma_mm = Some(0.05);
        assert!(noisy.shortfall().is_none(), "{noisy:?}");
        noisy.sessions_gain_sigma_mm = Some(0.02);
        assert!(noisy
            .shortfall()
            .is_some_and(|w| w.contains("held-out session")));
    }

    /// The blocked gain of a held-out recording: its mean is the blocks' mean and its σ the
    /// blocks' spread ÷ √K, computed here by hand on a two-block-valued residual.
    #[test]
    fn a_held_out_gain_is_the_mean_of_its_blocks_with_their_standard_error() {
        let m = 30; // 3 blocks of 10
        let with = DVector::from_element(3 * m, 1.0);
        // Block b's RMS without is √3·(1 + b/10): gains √3·{0, 0.1, 0.2}.
        let without = DVector::from_fn(3 * m, |r, _| 1.0 + (r / 30) as f64 / 10.0);
        let (mean, sigma) = blocked_gain(&with, &without);
        let s3 = 3f64.sqrt();
        assert!((mean - s3 * 0.1).abs() < 1e-12, "{mean}");
        // Sample σ of {0, 0.1, 0.2}·√3 is 0.1·√3; ÷ √3 blocks.
        assert!((sigma - 0.1).abs() < 1e-12, "{sigma}");
        // Fewer than 6 measurements: one per block.
        let (_, s) = blocked_gain(&with.rows(0, 6).into(), &without.rows(0, 6).into());
        assert!(s.abs() < 1e-12);
    }

    /// Two terms the training recording shows and a held-out session does not: together they
    /// raise it beyond 2 σ, and the one whose own gain there is least is set aside; on a
    /// session that shows them, nothing is.
    #[test]
    fn effects_that_together_raise_a_held_out_session_lose_the_weakest() {
        let (n, m) = (200, 100);
        let col = |seed: usize, rows: usize| {
            DMatrix::from_fn(3 * rows, 1, |r, _| ((r * 7 + seed) as f64 * 0.173).sin())
        };
        let base = |rows: usize| {
            DMatrix::from_fn(3 * rows, 2, |r, c| {
                if c == 0 {
                    1.0
                } else {
                    (r / 3) as f64 / rows as f64
                }
            })
        };
        let (x1, x2) = (col(1, n), col(2, n));
        let y = DVector::from_fn(3 * n, |r, _| x1[r] + x2[r] + 0.05 * pseudo_noise(r));
        let sys = FoldSystem::new(blocks(n), &[base(n), x1, x2], y);
        let cols = sys.columns(&[1, 2]);
        let a_h = super::super::linalg::hcat(&[base(m), col(11, m), col(12, m)], 3 * m);
        let scaled = DMatrix::from_fn(a_h.nrows(), a_h.ncols(), |r, c| a_h[(r, c)] / sys.scale[c]);
        let noise = DVector::from_fn(3 * m, |r, _| 0.05 * pseudo_noise(r + 9_999));
        let mut gains = vec![empty_gain(), empty_gain()];
        gains[0].sessions_gain_mm = Some(-0.2);
        gains[0].sessions_gain_sigma_mm = Some(0.15);
        gains[1].sessions_gain_mm = Some(-0.1);
        gains[1].sessions_gain_sigma_mm = Some(0.15);
        let absent = [(scaled.clone(), noise.clone())];
        let (i, _, why) =
            together_rise(&sys, &cols, (&[], &absent), &gains).expect("a rise together");
        assert_eq!(i, 0, "{why}");
        assert!(why.contains("together"), "{why}");
        let shown = noise + a_h.columns(2, 2) * DVector::from_element(2, 1.0);
        let present = [(scaled, shown)];
        assert!(together_rise(&sys, &cols, (&[], &present), &gains).is_none());
    }

    /// The standard error σ ÷ √K treats the blocks' gains as independent, though their
    /// training sets overlap. Against simulation: over many pure-noise recordings the spread of
    /// the mean block gain of a term that is not there is not larger than the standard error
    /// says (the blocks' gains are negatively correlated here: measured, the spread² is about
    /// half the mean σ²), so 2 σ is not optimistic on white noise.
    #[test]
    fn the_block_standard_error_does_not_understate_the_spread_of_null_gains() {
        let n = 100;
        let reps = 400;
        let mut means = Vec::with_capacity(reps);
        let mut naive = 0.0;
        for rep in 0..reps {
            let x = DVector::from_fn(3 * n, |r, _| pseudo_noise(r * 7 + 13 + rep * 100_003));
            let y = DVector::from_fn(3 * n, |r, _| pseudo_noise(r + rep * 1_000_003 + 5));
            let g = gain_for(&x, &y, n);
            means.push(g.gain_mm);
            naive += g.gain_sigma_mm.powi(2);
        }
        let mu = means.iter().sum::<f64>() / reps as f64;
        let spread = means.iter().map(|m| (m - mu).powi(2)).sum::<f64>() / (reps - 1) as f64;
        let naive = naive / reps as f64;
        eprintln!("spread² {spread:.3e}, mean σ² {naive:.3e}");
        assert!(spread < naive, "spread² {spread:.3e}, mean σ² {naive:.3e}");
    }
}
