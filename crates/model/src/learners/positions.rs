//! The FCMAC trained on what the instrument measured, after the paper's training on CEPs.
//!
//! Region-wise CEPs of small regions are only right together: a region of a few tens of
//! millimetres cannot see every one of its 15 parameters (κ of eq. (4) up to 10¹⁰), so a
//! direction it cannot see wanders, and its neighbour's wanders another way. The paper's
//! training (A5) makes the network reproduce those CEPs; its response blends neighbouring cells,
//! and a blend of two parameter sets that are each right only with their own region is right
//! with neither. This training changes the objective, not the network: the same cells and the
//! same response (A4), with weights that make the *measured points* right.
//!
//! Convention: a measurement i with division-space input xᵢ excites cells c with normalised
//! strengths aᵢc = μᵢc / Σμ; the network's outputs there are P(xᵢ) = Σ aᵢc w_c (output units:
//! mm and degrees). Linearised about the conventional CEPs, its modelled point moves by Jᵢ ΔP,
//! Jᵢ the 3 × k derivative of the measured point (mm per output unit). The weight change Δw
//! minimises Σᵢ |rᵢ − Jᵢ Σ aᵢc Δw_c|², rᵢ the measured minus the modelled point at the current
//! weights (mm, through the full kinematics), by conjugate gradients on the normal equations
//! (CGLS) from Δw = 0, plus λ Σ |s_o (Δw_c,o − Δw_c′,o)|² over neighbouring cells c, c′ of the
//! association grid, s_o the RMS length of output o's derivative (mm per output unit), so
//! the smoothing is counted in millimetres of point motion for every output alike. Smoothing
//! carries what the measurements around a cell say into cells they barely excite (an
//! unmeasurable region); stopping early regularises further. λ and the iteration count are
//! the pair that predicts a held-out fifth of the measurements best, after which the run is
//! repeated on all of them. A cell no measurement reaches keeps its CEP training, so what it
//! carries there is set by the CEPs that training saw: with a learner tolerance (the default
//! under this training, [`POSITION_TRAINING_TOLERANCE`](rigcal_calibration::POSITION_TRAINING_TOLERANCE))
//! those are the parent's along what a small region cannot see, not the region's wandering
//! least-squares values; the measured points are put right here either way.

use super::Fcmac;
use serde::{Deserialize, Serialize};

/// A measurement as the position-space training sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct PositionSample {
    /// Division-space input.
    pub x: [f64; 3],
    /// ∂(measured point)/∂(outputs): row r, output k at `jacobian[r][k]` (mm per output unit).
    pub jacobian: [Vec<f64>; 3],
    /// Measured minus modelled point at the network's current outputs (mm).
    pub residual: [f64; 3],
}

/// How the position-space training went, kept in the model file with the network.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PositionReport {
    /// Measurements trained on.
    pub measurements: usize,
    /// Conjugate-gradient iterations run (chosen on the held-out fifth).
    pub iterations: usize,
    /// The smoothing weight λ (chosen on the held-out fifth; 0: none).
    pub smoothing: f64,
    /// RMS position error (mm) over the measurements after the CEP training.
    pub rms_before_mm: f64,
    /// The same after this training (linearised).
    pub rms_after_mm: f64,
    /// RMS error (mm) on the held-out fifth, trained without it: after the CEP training and at
    /// the chosen iteration.
    pub heldout_before_mm: f64,
    /// See [`PositionReport::heldout_before_mm`].
    pub heldout_after_mm: f64,
}

impl PositionReport {
    /// One line for a person.
    pub fn text(&self) -> String {
        format!(
            "trained on {} measured points: RMS {:.4} → {:.4} mm ({} iterations, smoothing λ {}; held-out fifth {:.4} → {:.4} mm)",
            self.measurements,
            self.rms_before_mm,
            self.rms_after_mm,
            self.iterations,
            self.smoothing,
            self.heldout_before_mm,
            self.heldout_after_mm
        )
    }
}

/// Iteration cap of the conjugate gradients.
const MAX_ITERATIONS: usize = 300;
/// One measurement in this many is held out to choose λ and the iteration count.
const HOLDOUT_EVERY: usize = 5;
/// The smoothing weights λ tried.
const LAMBDAS: [f64; 4] = [0.0, 0.01, 0.03, 0.1];

/// A sample with its excited cells, strengths normalised.
struct Row<'a> {
    sample: &'a PositionSample,
    cells: Vec<(usize, f64)>,
}

impl Fcmac {
    /// Trains the weights on measured points (see the module's doc); returns and keeps the
    /// report. Samples with no excited cell are ignored; with fewer than [`HOLDOUT_EVERY`]
    /// samples nothing changes.
    pub fn train_on_positions(&mut self, samples: &[PositionSample]) -> Option<PositionReport> {
        let rows: Vec<Row<'_>> = samples
            .iter()
            .filter(|s| s.jacobian.iter().all(|r| r.len() == self.outputs))
            .filter_map(|s| {
                let cells = self.excited(&s.x);
                let total: f64 = cells.iter().map(|(_, m)| m).sum();
                (total > 0.0).then(|| Row {
                    sample: s,
                    cells: cells.into_iter().map(|(c, m)| (c, m / total)).collect(),
                })
            })
            .collect();
        if rows.len() < HOLDOUT_EVERY {
            return None;
        }
        let is_held = |i: &usize| i % HOLDOUT_EVERY == HOLDOUT_EVERY - 1;
        let split = |held: bool| -> Vec<&Row<'_>> {
            rows.iter()
                .enumerate()
                .filter(|(i, _)| is_held(i) == held)
                .map(|(_, r)| r)
                .collect()
        };
        let (fit, held, all) = (split(false), split(true), rows.iter().collect::<Vec<_>>());
        let k = self.outputs;
        let zero = vec![0.0; self.weights.len()];
        let heldout_before = rms(&held, k, &zero);
        // (held-out RMS, λ, iterations)
        let mut best = (heldout_before, 0.0, 0);
        for lambda in LAMBDAS {
            let op = Operator::new(self, &fit, lambda);
            op.cgls(MAX_ITERATIONS, |it, dw| {
                let e = rms(&held, k, dw);
                if e < best.0 {
                    best = (e, lambda, it);
                }
            });
        }
        let (heldout_after, lambda, iterations) = best;
        let mut dw = zero.clone();
        if iterations > 0 {
            Operator::new(self, &all, lambda).cgls(iterations, |it, x| {
                // The last iterate up to the chosen count (the run may end sooner).
                if it <= iterations {
                    dw.copy_from_slice(x);
                }
            });
        }
        for (w, d) in self.weights.iter_mut().zip(&dw) {
            *w += d;
        }
        let report = PositionReport {
            measurements: rows.len(),
            iterations,
            smoothing: lambda,
            rms_before_mm: rms(&all, k, &zero),
            rms_after_mm: rms(&all, k, &dw),
            heldout_before_mm: heldout_before,
            heldout_after_mm: heldout_after,
        };
        self.positions = Some(report);
        Some(report)
    }
}

/// The least-squares operator: the rows' linearised point changes, then the smoothing terms
/// between neighbouring cells.
struct Operator<'r, 'a> {
    rows: &'r [&'r Row<'a>],
    n: usize,
    k: usize,
    /// Neighbouring cell pairs of the association grid (none for a hashed network).
    pairs: Vec<(usize, usize)>,
    /// √λ · s_o per output.
    weight: Vec<f64>,
}

impl<'r, 'a> Operator<'r, 'a> {
    fn new(net: &Fcmac, rows: &'r [&'r Row<'a>], lambda: f64) -> Self {
        let k = net.outputs;
        let pairs = if lambda > 0.0 && net.config.hash_size.is_none() {
            grid_pairs(net.config.cells)
        } else {
            Vec::new()
        };
        let weight = (0..k)
            .map(|o| {
                let sq: f64 = rows
                    .iter()
                    .map(|r| (0..3).map(|d| r.sample.jacobian[d][o].powi(2)).sum::<f64>())
                    .sum();
                (lambda * sq / rows.len().max(1) as f64).sqrt()
            })
            .collect();
        Self {
            rows,
            n: net.weights.len(),
            k,
            pairs,
            weight,
        }
    }

    /// A·v: the rows' point changes, then the weighted neighbour differences.
    fn forward(&self, v: &[f64]) -> (Vec<[f64; 3]>, Vec<f64>) {
        let data = self.rows.iter().map(|row| apply(row, self.k, v)).collect();
        let mut smooth = Vec::with_capacity(self.pairs.len() * self.k);
        for &(a, b) in &self.pairs {
            for o in 0..self.k {
                smooth.push(self.weight[o] * (v[a * self.k + o] - v[b * self.k + o]));
            }
        }
        (data, smooth)
    }

    /// Aᵀ·(u, t).
    fn transpose(&self, u: &[[f64; 3]], t: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.n];
        for (row, u) in self.rows.iter().zip(u) {
            apply_transpose(row, self.k, u, &mut out);
        }
        for (p, &(a, b)) in self.pairs.iter().enumerate() {
            for o in 0..self.k {
                let g = self.weight[o] * t[p * self.k + o];
                out[a * self.k + o] += g;
                out[b * self.k + o] -= g;
            }
        }
        out
    }

    /// CGLS from zero for up to `iterations` on residuals (the rows' own, zero smoothing);
    /// `each(i, x)` sees the iterate after iteration i (1-based). Stops early when the gradient
    /// vanishes.
    fn cgls(&self, iterations: usize, mut each: impl FnMut(usize, &[f64])) {
        let mut x = vec![0.0; self.n];
        let mut r: Vec<[f64; 3]> = self.rows.iter().map(|row| row.sample.residual).collect();
        let mut t = vec![0.0; self.pairs.len() * self.k];
        let mut s = self.transpose(&r, &t);
        let mut p = s.clone();
        let mut gamma = dot(&s, &s);
        let gamma0 = gamma;
        for it in 1..=iterations {
            if gamma <= 1e-24 * gamma0.max(f64::MIN_POSITIVE) {
                break;
            }
            let (q, qs) = self.forward(&p);
            let delta: f64 = q.iter().map(|v| dot(v, v)).sum::<f64>() + dot(&qs, &qs);
            if delta <= 0.0 {
                break;
            }
            let alpha = gamma / delta;
            x.iter_mut().zip(&p).for_each(|(xi, pi)| *xi += alpha * pi);
            for (ri, qi) in r.iter_mut().zip(&q) {
                (0..3).for_each(|c| ri[c] -= alpha * qi[c]);
            }
            t.iter_mut().zip(&qs).for_each(|(ti, qi)| *ti -= alpha * qi);
            s = self.transpose(&r, &t);
            let next = dot(&s, &s);
            let beta = next / gamma;
            gamma = next;
            p.iter_mut()
                .zip(&s)
                .for_each(|(pi, si)| *pi = si + beta * *pi);
            each(it, &x);
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Pairs of association cells adjacent along one input of a `cells` grid (cell-major order as
/// in [`Fcmac`]).
fn grid_pairs(cells: [usize; 3]) -> Vec<(usize, usize)> {
    let [n0, n1, n2] = cells;
    let index = |i: usize, j: usize, l: usize| (i * n1 + j) * n2 + l;
    let mut out = Vec::new();
    for i in 0..n0 {
        for j in 0..n1 {
            for l in 0..n2 {
                let c = index(i, j, l);
                if i + 1 < n0 {
                    out.push((c, index(i + 1, j, l)));
                }
                if j + 1 < n1 {
                    out.push((c, index(i, j + 1, l)));
                }
                if l + 1 < n2 {
                    out.push((c, index(i, j, l + 1)));
                }
            }
        }
    }
    out
}

/// The modelled change of a row's point for weight change `dw` (mm).
fn apply(row: &Row<'_>, k: usize, dw: &[f64]) -> [f64; 3] {
    let mut dp = vec![0.0; k];
    for &(c, a) in &row.cells {
        for (d, w) in dp.iter_mut().zip(&dw[c * k..(c + 1) * k]) {
            *d += a * w;
        }
    }
    let j = &row.sample.jacobian;
    [0, 1, 2].map(|r| dot(&j[r], &dp))
}

/// Adds the transpose of a row's operator applied to `u` (mm) into `out` (weight units).
fn apply_transpose(row: &Row<'_>, k: usize, u: &[f64; 3], out: &mut [f64]) {
    let j = &row.sample.jacobian;
    let g: Vec<f64> = (0..k)
        .map(|o| j[0][o] * u[0] + j[1][o] * u[1] + j[2][o] * u[2])
        .collect();
    for &(c, a) in &row.cells {
        for (o, gk) in out[c * k..(c + 1) * k].iter_mut().zip(&g) {
            *o += a * gk;
        }
    }
}

/// RMS over rows of the residual left after weight change `dw` (mm, per point).
fn rms(rows: &[&Row<'_>], k: usize, dw: &[f64]) -> f64 {
    if rows.is_empty() {
        return 0.0;
    }
    let sq: f64 = rows
        .iter()
        .map(|row| {
            let m = apply(row, k, dw);
            (0..3)
                .map(|r| (row.sample.residual[r] - m[r]).powi(2))
                .sum::<f64>()
        })
        .sum();
    (sq / rows.len() as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::division::Bounds;
    use crate::learners::FcmacConfig;

    fn net() -> Fcmac {
        let range = Bounds {
            lo: [0.0; 3],
            hi: [1.0; 3],
        };
        Fcmac::new(FcmacConfig::paper(0), range, &[0.0, 0.0])
    }

    /// The measured point moves by 2 mm per unit of output 0 along x and 1 mm per unit of
    /// output 1 along z; the "measured" residual is a smooth field the network must learn.
    fn field(x: &[f64; 3]) -> [f64; 2] {
        [
            0.05 * (3.0 * x[0]).sin() + 0.02 * x[1],
            0.03 * (2.0 * x[2]).cos(),
        ]
    }

    fn samples(n: usize) -> Vec<PositionSample> {
        (0..n)
            .map(|i| {
                // A low-discrepancy set inside the range.
                let x = [0.618_034, 0.754_878, 0.569_840]
                    .map(|a: f64| ((i as f64 + 0.5) * a).fract() * 0.9 + 0.05);
                let [f0, f1] = field(&x);
                PositionSample {
                    x,
                    jacobian: [vec![2.0, 0.0], vec![0.0, 0.0], vec![0.0, 1.0]],
                    residual: [2.0 * f0, 0.0, f1],
                }
            })
            .collect()
    }

    #[test]
    fn grid_pairs_counts_every_face_neighbour_once() {
        let [a, b, c] = [4, 3, 5];
        let pairs = grid_pairs([a, b, c]);
        assert_eq!(pairs.len(), 3 * a * b * c - b * c - a * c - a * b);
        let mut unique = pairs.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), pairs.len());
    }

    #[test]
    fn training_learns_a_smooth_field_and_predicts_points_it_did_not_see() {
        let mut net = net();
        let report = net
            .train_on_positions(&samples(600))
            .expect("600 samples train");
        assert!(report.iterations > 0);
        assert!(
            report.rms_after_mm < 0.2 * report.rms_before_mm,
            "{report:?}"
        );
        assert!(
            report.heldout_after_mm < 0.3 * report.heldout_before_mm,
            "{report:?}"
        );
        // Points off the training set, checked against the field directly.
        let mut worst: f64 = 0.0;
        for x in [[0.3, 0.4, 0.5], [0.71, 0.22, 0.35], [0.5, 0.85, 0.15]] {
            let y = net.predict(&x);
            let f = field(&x);
            worst = worst.max((y[0] - f[0]).abs()).max((y[1] - f[1]).abs());
        }
        assert!(worst < 0.01, "worst output error {worst}");
        assert_eq!(net.positions, Some(report));
    }

    #[test]
    fn too_few_or_malformed_samples_change_nothing() {
        let mut net = net();
        let before = net.weights.clone();
        assert_eq!(net.train_on_positions(&samples(4)), None);
        let mut bad = samples(50);
        bad.iter_mut().for_each(|s| s.jacobian[1] = vec![1.0]);
        assert_eq!(net.train_on_positions(&bad), None);
        assert_eq!(net.weights, before);
        assert_eq!(net.positions, None);
    }

    #[test]
    fn files_written_before_the_position_training_still_load_as_the_papers() {
        let mut value = serde_json::to_value(net()).expect("serialise");
        value
            .as_object_mut()
            .expect("an FCMAC is a JSON object")
            .remove("positions");
        let back: Fcmac = serde_json::from_value(value).expect("an old FCMAC loads");
        assert_eq!(back.positions, None);
        let settings: crate::learners::LearnerSettings =
            serde_json::from_str(r#"{"sensors": null, "c": [3, 3, 3], "cmac_layers": 3}"#)
                .expect("old settings load");
        assert_eq!(settings.training, crate::learners::FcmacTraining::Ceps);
    }
}
