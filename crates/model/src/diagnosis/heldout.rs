//! Held-out RMS of a model (geometry with some of the chosen effects and shapes): fitted on the
//! training part and evaluated on the rest — the `--heldout` recordings when given, else 2 of 8
//! whole time blocks of the recording itself.
//!
//! Units: 3-D RMS, mean and max of the 3-D error, in mm.

use super::linalg::{hcat, lstsq, rms3, rows_of, rows_of_vector};
use super::select::{Chosen, ChosenShape};
use super::{Candidate, Data, Standard};
use nalgebra::{DMatrix, DVector};

/// Fewer measurements than this leave no held-out split of the recording itself.
const MIN_FOR_SPLIT: usize = 80;

/// A held-out recording at the fitted geometry: its data, geometric Jacobian and residual.
pub type HeldoutRecording = (Data, DMatrix<f64>, DVector<f64>);

/// Held-out RMS before (geometry only) and after (geometry and the terms).
#[derive(Debug, Clone, PartialEq)]
pub struct Heldout {
    /// Geometry only (mm); None without a held-out part.
    pub before: Option<f64>,
    /// Geometry and the terms (mm); None without a held-out part.
    pub after: Option<f64>,
    /// What was held out, in words.
    pub what: String,
    /// Mean and max of the 3-D error (mm), geometry only; None without a held-out part.
    pub before_mean_max: Option<(f64, f64)>,
    /// The same with the terms.
    pub after_mean_max: Option<(f64, f64)>,
}

/// Mean and max over the measurements of the 3-D length of a stacked residual (mm).
pub fn mean_max3(r: &DVector<f64>) -> (f64, f64) {
    let n = r.len() / 3;
    let lengths =
        (0..n).map(|i| (r[3 * i].powi(2) + r[3 * i + 1].powi(2) + r[3 * i + 2].powi(2)).sqrt());
    let (sum, max) = lengths.fold((0.0, 0.0f64), |(s, m), l| (s + l, m.max(l)));
    (sum / n.max(1) as f64, max)
}

/// The terms of a model beside the geometry: named effects and shapes.
#[derive(Debug, Clone, Copy)]
pub struct Terms<'a> {
    /// Named effects.
    pub effects: &'a [&'a Chosen],
    /// Shapes of the discrepancy term.
    pub shapes: &'a [&'a ChosenShape],
}

impl Terms<'_> {
    /// The training columns, geometry first.
    fn design(&self, std: &Standard) -> DMatrix<f64> {
        let mut cols = vec![std.jacobian.clone()];
        cols.extend(self.effects.iter().map(|c| c.x.clone()));
        cols.extend(self.shapes.iter().map(|c| c.x.clone()));
        hcat(&cols, 3 * std.data.len())
    }

    /// The same columns rebuilt on a held-out recording (zero where it cannot show a term).
    fn design_on(&self, lib: &[Box<dyn Candidate>], hd: &Data, hg: &DMatrix<f64>) -> DMatrix<f64> {
        let n = 3 * hd.len();
        let mut cols = vec![hg.clone()];
        for c in self.effects {
            cols.push(
                lib[c.cand]
                    .regressors(hd)
                    .unwrap_or_else(|| DMatrix::zeros(n, c.x.ncols())),
            );
        }
        for s in self.shapes {
            cols.push(
                s.spec
                    .columns(hd)
                    .unwrap_or_else(|| DMatrix::zeros(n, s.x.ncols())),
            );
        }
        hcat(&cols, n)
    }
}

/// Held-out RMS before and after adding `terms` to the geometry, both fitted on the training
/// part.
pub fn heldout_rms(
    std: &Standard,
    terms: Terms<'_>,
    lib: &[Box<dyn Candidate>],
    heldout: &[HeldoutRecording],
) -> Heldout {
    let a_all = terms.design(std);
    if heldout.is_empty() {
        time_block_split(std, &a_all)
    } else {
        other_recordings(std, &a_all, terms, lib, heldout)
    }
}

/// Fitted on the whole recording, evaluated on the held-out recordings (each term's columns
/// rebuilt on them).
fn other_recordings(
    std: &Standard,
    a_all: &DMatrix<f64>,
    terms: Terms<'_>,
    lib: &[Box<dyn Candidate>],
    heldout: &[HeldoutRecording],
) -> Heldout {
    let dg = lstsq(&std.jacobian, &std.residual).solution;
    let da = lstsq(a_all, &std.residual).solution;
    let mut before = Vec::new();
    let mut after = Vec::new();
    for (hd, hg, hr) in heldout {
        let ha = terms.design_on(lib, hd, hg);
        before.extend((hr - hg * &dg).iter().copied());
        after.extend((hr - ha * &da).iter().copied());
    }
    let (before, after) = (DVector::from_vec(before), DVector::from_vec(after));
    Heldout {
        before: Some(rms3(&before)),
        after: Some(rms3(&after)),
        what: format!("{} held-out recording(s)", heldout.len()),
        before_mean_max: Some(mean_max3(&before)),
        after_mean_max: Some(mean_max3(&after)),
    }
}

/// The measurements the recording's own held-out split holds out (time blocks 2 and 6 of 8),
/// None when it is too small for one. The held-out judgement ([`super::crossval`]) checks a
/// claim against the same split.
pub(crate) fn own_split(n: usize) -> Option<Vec<usize>> {
    (n >= MIN_FOR_SPLIT).then(|| (0..n).filter(|&i| in_own_split(i, n)).collect())
}

fn in_own_split(i: usize, n: usize) -> bool {
    matches!(i * 8 / n, 1 | 5)
}

/// Time blocks 2 and 6 of 8 held out, fitted on the rest: whole blocks, so a slow drift cannot
/// be interpolated from neighbouring rows.
fn time_block_split(std: &Standard, a_all: &DMatrix<f64>) -> Heldout {
    let n = std.data.len();
    if n < MIN_FOR_SPLIT {
        return Heldout {
            before: None,
            after: None,
            what: "too few measurements for a held-out split".into(),
            before_mean_max: None,
            after_mean_max: None,
        };
    }
    let (test, train): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| in_own_split(i, n));
    let rt = rows_of_vector(&std.residual, &train);
    let rh = rows_of_vector(&std.residual, &test);
    let gt = rows_of(&std.jacobian, &train);
    let gh = rows_of(&std.jacobian, &test);
    let at = rows_of(a_all, &train);
    let ah = rows_of(a_all, &test);
    let dg = lstsq(&gt, &rt).solution;
    let da = lstsq(&at, &rt).solution;
    let (before, after) = (&rh - gh * dg, &rh - ah * da);
    Heldout {
        before: Some(rms3(&before)),
        after: Some(rms3(&after)),
        what: "time blocks 2 and 6 of 8 held out, fitted on the rest".into(),
        before_mean_max: Some(mean_max3(&before)),
        after_mean_max: Some(mean_max3(&after)),
    }
}
