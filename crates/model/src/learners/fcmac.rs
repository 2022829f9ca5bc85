//! FCMAC: the fuzzy CMAC of seed 000's appendix.
//!
//! * Sensor layer: per input dimension d, `cells[d]` Gaussian fuzzy sensors
//!   μ(s) = exp(−|s − m|²/2σ²) (A3), centres evenly spaced over the input range, σ a fraction of
//!   the spacing. An input excites the `c[d]` sensors with the largest membership.
//! * Association layer: one cell per combination of sensors (∏ cells[d] cells, 2057 = 17·11·11
//!   for the paper); an input excites the ∏ c[d] cells formed by its excited sensors, each with
//!   strength min over d of the sensor memberships (max–min composition, fuzzy AND = min).
//!   Optional hash coding folds the cells into a smaller table.
//! * Response: centroid defuzzification P = Σ μ·w / Σ μ (A4).
//! * Training: w ← w + β·μ·(CEP − CEP′) for every excited cell (A5), pattern by pattern,
//!   until every output is within the tolerance ε, the error stops falling, or the epoch cap;
//!   the [`TrainReport`] says which.
//!
//! Weights start at `init` (the conventional CEPs), so cells no pattern reaches — an
//! unmeasurable region far from any measured one — answer with the whole-workspace CEPs.

use super::{Pattern, PositionReport, Progress, TrainReport};
use crate::division::Bounds;
use serde::{Deserialize, Serialize};

/// Settings of an FCMAC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FcmacConfig {
    /// Fuzzy sensors per input dimension.
    pub cells: [usize; 3],
    /// Sensors excited per input dimension (the paper's c).
    pub c: [usize; 3],
    /// Gaussian σ as a fraction of the sensor spacing.
    pub sigma_fraction: f64,
    /// Learning rate β of (A5).
    pub beta: f64,
    /// Tolerance ε on every output (output units).
    pub tolerance: f64,
    /// Epoch cap.
    pub max_epochs: usize,
    /// Hash the association cells into this many (None: no hash coding, as in the paper).
    pub hash_size: Option<usize>,
}

impl FcmacConfig {
    /// The paper's network: 39 sensors (17 on the widest input, 11 on the others), c = (3, 3, 3),
    /// 2057 association cells, no hash coding. `widest` is the input with the largest range.
    pub fn paper(widest: usize) -> Self {
        let mut cells = [11; 3];
        cells[widest] = 17;
        Self {
            cells,
            c: [3, 3, 3],
            sigma_fraction: 0.5,
            beta: 0.5,
            tolerance: 1e-3,
            max_epochs: 150,
            hash_size: None,
        }
    }
}

/// A trained FCMAC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fcmac {
    /// Settings.
    pub config: FcmacConfig,
    /// Input ranges.
    pub range: Bounds,
    /// Number of outputs.
    pub outputs: usize,
    /// Weights, cell-major: `weights[cell * outputs + k]`.
    pub weights: Vec<f64>,
    /// How training went.
    pub report: Option<TrainReport>,
    /// How the position-space training that followed went, when it ran.
    #[serde(default)]
    pub positions: Option<PositionReport>,
}

impl Fcmac {
    /// A network over `range` with every weight at `init`.
    pub fn new(config: FcmacConfig, range: Bounds, init: &[f64]) -> Self {
        let n = config.hash_size.unwrap_or(config.cells.iter().product());
        let outputs = init.len();
        let mut weights = Vec::with_capacity(n * outputs);
        for _ in 0..n {
            weights.extend_from_slice(init);
        }
        Self {
            config,
            range,
            outputs,
            weights,
            report: None,
            positions: None,
        }
    }

    /// A network over `range` whose unhashed association cells start at `start` of the point
    /// their sensors centre on (a hashed network starts every cell at `init`, as [`Self::new`]).
    pub fn starting_at(
        config: FcmacConfig,
        range: Bounds,
        init: &[f64],
        start: impl Fn(&[f64; 3]) -> Vec<f64>,
    ) -> Self {
        let mut f = Self::new(config, range, init);
        if f.config.hash_size.is_some() {
            return f;
        }
        let [n0, n1, n2] = f.config.cells;
        let centre = |d: usize, i: usize| {
            let n = f.config.cells[d];
            range.lo[d] + (range.hi[d] - range.lo[d]) * i as f64 / (n - 1).max(1) as f64
        };
        for i in 0..n0 {
            for j in 0..n1 {
                for k in 0..n2 {
                    let w = start(&[centre(0, i), centre(1, j), centre(2, k)]);
                    let cell = (i * n1 + j) * n2 + k;
                    if w.len() == f.outputs {
                        f.weights[cell * f.outputs..(cell + 1) * f.outputs].copy_from_slice(&w);
                    }
                }
            }
        }
        f
    }

    /// Number of association cells.
    pub fn cell_count(&self) -> usize {
        self.weights.len() / self.outputs.max(1)
    }

    /// Excited sensors of one dimension: (index, membership), strongest first.
    fn sensors(&self, d: usize, s: f64) -> Vec<(usize, f64)> {
        let n = self.config.cells[d];
        let lo = self.range.lo[d];
        let spacing = (self.range.hi[d] - lo) / (n - 1).max(1) as f64;
        let sigma = self.config.sigma_fraction * spacing;
        // An input beyond the range answers as at its nearest edge: the network holds nothing
        // beyond it, and unclamped the memberships underflow to zero a few spacings out and the
        // answer is all-zero CEPs (the nominal arm, the marker at its nominal place), which on
        // a held-out UR10 series outside the training's joint range was 92 mm off.
        let s = s.clamp(lo.min(self.range.hi[d]), self.range.hi[d].max(lo));
        let pos = ((s - lo) / spacing).clamp(0.0, (n - 1) as f64);
        let c = self.config.c[d].min(n);
        // The c strongest sensors are the c nearest centres: a window around the input.
        let mut first = (pos - 0.5 * (c as f64 - 1.0)).round() as isize;
        first = first.clamp(0, (n - c) as isize);
        (first as usize..first as usize + c)
            .map(|i| {
                let m = lo + i as f64 * spacing;
                (i, (-(s - m).powi(2) / (2.0 * sigma * sigma)).exp())
            })
            .collect()
    }

    /// Excited association cells: (cell index, strength).
    pub(super) fn excited(&self, x: &[f64; 3]) -> Vec<(usize, f64)> {
        let a = self.sensors(0, x[0]);
        let b = self.sensors(1, x[1]);
        let c = self.sensors(2, x[2]);
        let [_, n1, n2] = self.config.cells;
        let mut out = Vec::with_capacity(a.len() * b.len() * c.len());
        for &(i, mi) in &a {
            for &(j, mj) in &b {
                for &(k, mk) in &c {
                    let cell = (i * n1 + j) * n2 + k;
                    let cell = match self.config.hash_size {
                        Some(h) => hash_cell(cell, h),
                        None => cell,
                    };
                    out.push((cell, mi.min(mj).min(mk)));
                }
            }
        }
        out
    }

    /// The response at `x` (A4).
    pub fn predict(&self, x: &[f64; 3]) -> Vec<f64> {
        let cells = self.excited(x);
        self.respond(&cells)
    }

    fn respond(&self, cells: &[(usize, f64)]) -> Vec<f64> {
        let total: f64 = cells.iter().map(|(_, m)| m).sum();
        let mut y = vec![0.0; self.outputs];
        if total <= 0.0 {
            return y;
        }
        for &(cell, m) in cells {
            let w = &self.weights[cell * self.outputs..(cell + 1) * self.outputs];
            for (yk, wk) in y.iter_mut().zip(w) {
                *yk += m * wk;
            }
        }
        y.iter_mut().for_each(|v| *v /= total);
        y
    }

    /// Trains on the patterns with (A5) until every output is within tolerance.
    pub fn train(&mut self, patterns: &[Pattern]) -> TrainReport {
        let excited: Vec<Vec<(usize, f64)>> = patterns.iter().map(|p| self.excited(&p.x)).collect();
        let mut progress = Progress::new(self.config.tolerance, self.config.max_epochs);
        let mut report = progress.untrained();
        for _ in 0..self.config.max_epochs {
            for (p, cells) in patterns.iter().zip(&excited) {
                let y = self.respond(cells);
                let diff: Vec<f64> = p.y.iter().zip(&y).map(|(t, o)| t - o).collect();
                for &(cell, m) in cells {
                    let w = &mut self.weights[cell * self.outputs..(cell + 1) * self.outputs];
                    for (wk, dk) in w.iter_mut().zip(&diff) {
                        *wk += self.config.beta * m * dk;
                    }
                }
            }
            let (max, rms) = self.errors(patterns, &excited);
            let (r, stop) = progress.epoch(max, rms);
            report = r;
            if stop {
                break;
            }
        }
        self.report = Some(report);
        report
    }

    fn errors(&self, patterns: &[Pattern], excited: &[Vec<(usize, f64)>]) -> (f64, f64) {
        let mut max: f64 = 0.0;
        let mut sq = 0.0;
        let mut n = 0usize;
        for (p, cells) in patterns.iter().zip(excited) {
            for (t, o) in p.y.iter().zip(self.respond(cells)) {
                max = max.max((t - o).abs());
                sq += (t - o).powi(2);
                n += 1;
            }
        }
        (max, (sq / n.max(1) as f64).sqrt())
    }
}

fn hash_cell(cell: usize, size: usize) -> usize {
    // A multiplicative hash (Knuth) spreads neighbouring cells over the table.
    ((cell as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 20) as usize % size.max(1)
}
