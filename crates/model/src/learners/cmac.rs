//! Albus's CMAC, the plain (crisp) counterpart of the FCMAC, for the paper's comparison.
//!
//! `layers` overlapping quantisations of the input box, layer l shifted by l/layers of a cell
//! along every dimension (Albus's diagonal offsets); an input excites one cell per layer; the
//! response is the mean of the excited cells' weights, so it is piecewise constant and jumps where
//! any layer's cell changes. Training is the LMS rule w ← w + β·(y − P)/layers on every excited
//! cell. Weights start at `init` (the conventional CEPs).

use super::{Pattern, Progress, TrainReport};
use crate::division::Bounds;
use serde::{Deserialize, Serialize};

/// Settings of a CMAC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CmacConfig {
    /// Quantisation cells per dimension in each layer.
    pub cells: [usize; 3],
    /// Number of overlapping layers (the generalisation width).
    pub layers: usize,
    /// Learning rate β.
    pub beta: f64,
    /// Tolerance on every output.
    pub tolerance: f64,
    /// Epoch cap.
    pub max_epochs: usize,
}

impl CmacConfig {
    /// A CMAC at the FCMAC's resolution: the same cells per dimension, three layers (as c = 3).
    pub fn matching(cells: [usize; 3]) -> Self {
        Self {
            cells,
            layers: 3,
            beta: 0.5,
            tolerance: 1e-3,
            max_epochs: 150,
        }
    }
}

/// A trained CMAC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cmac {
    /// Settings.
    pub config: CmacConfig,
    /// Input ranges.
    pub range: Bounds,
    /// Number of outputs.
    pub outputs: usize,
    /// Weights: layer-major, then cell, then output.
    pub weights: Vec<f64>,
    /// How training went.
    pub report: Option<TrainReport>,
}

impl Cmac {
    /// A network over `range` with every weight at `init`.
    pub fn new(config: CmacConfig, range: Bounds, init: &[f64]) -> Self {
        let per_layer: usize = config.cells.iter().map(|c| c + 1).product();
        let n = per_layer * config.layers;
        let mut weights = Vec::with_capacity(n * init.len());
        for _ in 0..n {
            weights.extend_from_slice(init);
        }
        Self {
            outputs: init.len(),
            config,
            range,
            weights,
            report: None,
        }
    }

    fn excited(&self, x: &[f64; 3]) -> Vec<usize> {
        let dims = self.config.cells.map(|c| c + 1);
        let per_layer: usize = dims.iter().product();
        (0..self.config.layers)
            .map(|l| {
                let shift = l as f64 / self.config.layers as f64;
                let idx: [usize; 3] = std::array::from_fn(|d| {
                    let width = (self.range.hi[d] - self.range.lo[d]) / self.config.cells[d] as f64;
                    let u = ((x[d] - self.range.lo[d]) / width + shift).floor();
                    u.clamp(0.0, self.config.cells[d] as f64) as usize
                });
                l * per_layer + (idx[0] * dims[1] + idx[1]) * dims[2] + idx[2]
            })
            .collect()
    }

    /// The response at `x`.
    pub fn predict(&self, x: &[f64; 3]) -> Vec<f64> {
        self.respond(&self.excited(x))
    }

    fn respond(&self, cells: &[usize]) -> Vec<f64> {
        let mut y = vec![0.0; self.outputs];
        for &c in cells {
            for (yk, wk) in y
                .iter_mut()
                .zip(&self.weights[c * self.outputs..(c + 1) * self.outputs])
            {
                *yk += wk;
            }
        }
        let n = cells.len().max(1) as f64;
        y.iter_mut().for_each(|v| *v /= n);
        y
    }

    /// Trains with the LMS rule until every output is within tolerance.
    pub fn train(&mut self, patterns: &[Pattern]) -> TrainReport {
        let excited: Vec<Vec<usize>> = patterns.iter().map(|p| self.excited(&p.x)).collect();
        let mut progress = Progress::new(self.config.tolerance, self.config.max_epochs);
        let mut report = progress.untrained();
        for _ in 0..self.config.max_epochs {
            for (p, cells) in patterns.iter().zip(&excited) {
                let y = self.respond(cells);
                let step: Vec<f64> =
                    p.y.iter()
                        .zip(&y)
                        .map(|(t, o)| self.config.beta * (t - o))
                        .collect();
                for &c in cells {
                    for (wk, s) in self.weights[c * self.outputs..(c + 1) * self.outputs]
                        .iter_mut()
                        .zip(&step)
                    {
                        *wk += s;
                    }
                }
            }
            let mut max: f64 = 0.0;
            let mut sq = 0.0;
            let mut n = 0usize;
            for (p, cells) in patterns.iter().zip(&excited) {
                for (t, o) in p.y.iter().zip(self.respond(cells)) {
                    max = max.max((t - o).abs());
                    sq += (t - o).powi(2);
                    n += 1;
                }
            }
            let (r, stop) = progress.epoch(max, (sq / n.max(1) as f64).sqrt());
            report = r;
            if stop {
                break;
            }
        }
        self.report = Some(report);
        report
    }
}
