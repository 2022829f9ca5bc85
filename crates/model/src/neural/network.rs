//! A feed-forward network with one hidden layer of logistic sigmoid units and linear outputs,
//! trained by batch back-propagation with a learning rate and momentum (seed 001 section 3.1,
//! Haykin 1999), with early stopping on a validation split.
//!
//! # Conventions
//! Inputs and outputs are plain numbers; the caller scales them (see [`Scaler`]). The loss is
//! half the summed squared error over a batch, E = ½ Σ_n ‖y_n − t_n‖², so the learning rate η
//! multiplies the gradient summed over the batch, as in Haykin's batch mode. The weight update is
//! Δw(k) = μ·Δw(k−1) − η·∂E/∂w. Everything is deterministic from the seed given at construction.
//!
//! Besides the paper's rule, [`Method::LevenbergMarquardt`] minimises the same loss with
//! Levenberg–Marquardt steps on the same back-propagated derivatives (the Jacobian of every
//! output with respect to every weight): plain gradient descent with momentum needs 10⁵–10⁶
//! epochs to reach the sub-micrometre errors of the paper's Table 5, Levenberg–Marquardt a few
//! hundred iterations (see `rigcal reproduce seed001`, which reports both).

use nalgebra::{DMatrix, DVector};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};

/// One hidden layer of sigmoid units, linear outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Network {
    /// Hidden weights, hidden × inputs.
    pub w1: DMatrix<f64>,
    /// Hidden biases.
    pub b1: DVector<f64>,
    /// Output weights, outputs × hidden.
    pub w2: DMatrix<f64>,
    /// Output biases.
    pub b2: DVector<f64>,
}

/// The gradient of the loss with respect to every weight, shaped like the network.
#[derive(Debug, Clone, PartialEq)]
pub struct Gradient {
    /// ∂E/∂w1.
    pub w1: DMatrix<f64>,
    /// ∂E/∂b1.
    pub b1: DVector<f64>,
    /// ∂E/∂w2.
    pub w2: DMatrix<f64>,
    /// ∂E/∂b2.
    pub b2: DVector<f64>,
}

/// How the weights are updated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Batch gradient descent with momentum: Δw(k) = μ·Δw(k−1) − η·∂E/∂w (the paper's).
    #[default]
    Momentum,
    /// Levenberg–Marquardt on the same loss; an epoch is one accepted or rejected step.
    LevenbergMarquardt,
}

/// Settings of batch back-propagation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Update rule.
    pub method: Method,
    /// Hidden neurons.
    pub hidden: usize,
    /// Learning rate η (on the batch-summed gradient; paper 0.01).
    pub learning_rate: f64,
    /// Momentum α (paper 0.9).
    pub momentum: f64,
    /// Most epochs.
    pub epochs: usize,
    /// Fraction of the training patterns held out for early stopping (0: none; train on all).
    pub validation_fraction: f64,
    /// Early stopping: stop after this many epochs without a better validation error.
    pub patience: usize,
    /// Seed of the initial weights and of the validation split.
    pub seed: u64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            method: Method::Momentum,
            hidden: 20,
            learning_rate: 0.01,
            momentum: 0.9,
            epochs: 1000,
            validation_fraction: 0.0,
            patience: 500,
            seed: 1,
        }
    }
}

/// How training went.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainOutcome {
    /// Epochs run.
    pub epochs: usize,
    /// The epoch whose weights were kept (the best validation error with early stopping, else
    /// the last).
    pub best_epoch: usize,
    /// RMS training error per output at the kept weights (scaled units).
    pub train_rms: f64,
    /// RMS validation error at the kept weights (scaled units), when a split was held out.
    pub validation_rms: Option<f64>,
    /// Training RMS every `history_every` epochs (scaled units), for learning curves.
    pub history: Vec<f64>,
}

/// How often [`TrainOutcome::history`] samples the training error.
pub const HISTORY_EVERY: usize = 10;

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

impl Network {
    /// Random weights, uniform in ±1/√fan-in, from `seed`.
    pub fn new(inputs: usize, hidden: usize, outputs: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let r1 = 1.0 / (inputs.max(1) as f64).sqrt();
        let r2 = 1.0 / (hidden.max(1) as f64).sqrt();
        let w1 = DMatrix::from_fn(hidden, inputs, |_, _| rng.random_range(-r1..r1));
        let b1 = DVector::from_fn(hidden, |_, _| rng.random_range(-r1..r1));
        let w2 = DMatrix::from_fn(outputs, hidden, |_, _| rng.random_range(-r2..r2));
        let b2 = DVector::zeros(outputs);
        Self { w1, b1, w2, b2 }
    }

    /// Number of inputs.
    pub fn inputs(&self) -> usize {
        self.w1.ncols()
    }

    /// Number of hidden neurons.
    pub fn hidden(&self) -> usize {
        self.w1.nrows()
    }

    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.w2.nrows()
    }

    fn hidden_of(&self, x: &DMatrix<f64>) -> DMatrix<f64> {
        let mut a = &self.w1 * x;
        for mut c in a.column_iter_mut() {
            c += &self.b1;
        }
        a.map(sigmoid)
    }

    /// Outputs for a batch: `x` is inputs × patterns, the result outputs × patterns.
    pub fn forward(&self, x: &DMatrix<f64>) -> DMatrix<f64> {
        let h = self.hidden_of(x);
        let mut y = &self.w2 * h;
        for mut c in y.column_iter_mut() {
            c += &self.b2;
        }
        y
    }

    /// Outputs for one pattern.
    pub fn predict(&self, x: &[f64]) -> Vec<f64> {
        let xm = DMatrix::from_column_slice(x.len(), 1, x);
        self.forward(&xm).column(0).iter().copied().collect()
    }

    /// The loss E = ½ Σ ‖y − t‖² over a batch and its gradient (back-propagation).
    pub fn loss_and_gradient(&self, x: &DMatrix<f64>, t: &DMatrix<f64>) -> (f64, Gradient) {
        let h = self.hidden_of(x);
        let mut y = &self.w2 * &h;
        for mut c in y.column_iter_mut() {
            c += &self.b2;
        }
        let dy = y - t;
        let loss = 0.5 * dy.norm_squared();
        let gw2 = &dy * h.transpose();
        let gb2 = row_sums(&dy);
        let dh = self.w2.transpose() * &dy;
        let da = dh.zip_map(&h, |g, s| g * s * (1.0 - s));
        let gw1 = &da * x.transpose();
        let gb1 = row_sums(&da);
        (
            loss,
            Gradient {
                w1: gw1,
                b1: gb1,
                w2: gw2,
                b2: gb2,
            },
        )
    }

    /// The Jacobian of every output of every pattern with respect to every weight
    /// ((outputs · patterns) × weights, row o + outputs · n; columns in the order of
    /// [`Network::weights`]) and the residuals y − t in the same row order.
    pub fn output_jacobian(
        &self,
        x: &DMatrix<f64>,
        t: &DMatrix<f64>,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let (ni, nh, no, n) = (self.inputs(), self.hidden(), self.outputs(), x.ncols());
        let h = self.hidden_of(x);
        let nw = nh * ni + nh + no * nh + no;
        let mut j = DMatrix::zeros(no * n, nw);
        let mut r = DVector::zeros(no * n);
        let (o_b1, o_w2, o_b2) = (nh * ni, nh * ni + nh, nh * ni + nh + no * nh);
        for p in 0..n {
            for o in 0..no {
                let row = o + no * p;
                let mut y = self.b2[o];
                for k in 0..nh {
                    let s = h[(k, p)];
                    y += self.w2[(o, k)] * s;
                    j[(row, o_w2 + o + no * k)] = s;
                    let g = self.w2[(o, k)] * s * (1.0 - s);
                    j[(row, o_b1 + k)] = g;
                    for i in 0..ni {
                        j[(row, k + nh * i)] = g * x[(i, p)];
                    }
                }
                j[(row, o_b2 + o)] = 1.0;
                r[row] = y - t[(o, p)];
            }
        }
        (j, r)
    }

    /// The loss alone.
    pub fn loss(&self, x: &DMatrix<f64>, t: &DMatrix<f64>) -> f64 {
        0.5 * (self.forward(x) - t).norm_squared()
    }

    /// Every weight in one vector (w1 column-major, b1, w2, b2): for gradient checks.
    pub fn weights(&self) -> Vec<f64> {
        let mut v = Vec::new();
        v.extend(self.w1.iter());
        v.extend(self.b1.iter());
        v.extend(self.w2.iter());
        v.extend(self.b2.iter());
        v
    }

    /// Sets every weight from a vector in the order of [`Network::weights`].
    pub fn set_weights(&mut self, v: &[f64]) {
        let mut it = v.iter().copied();
        for w in self.w1.iter_mut() {
            *w = it.next().unwrap_or(0.0);
        }
        for w in self.b1.iter_mut() {
            *w = it.next().unwrap_or(0.0);
        }
        for w in self.w2.iter_mut() {
            *w = it.next().unwrap_or(0.0);
        }
        for w in self.b2.iter_mut() {
            *w = it.next().unwrap_or(0.0);
        }
    }

    /// One Levenberg–Marquardt step on residuals `r` with Jacobian `j` (rows: residuals,
    /// columns: weights) at loss ½‖r‖² = `loss`: raises the damping `lambda` until a step lowers
    /// `loss_of`, keeps that step and lowers the damping. Returns `false` when training is over
    /// (gradient vanished, or no damping finds a better point; the weights are then unchanged).
    fn levenberg_marquardt_step(
        &mut self,
        j: &DMatrix<f64>,
        r: &DVector<f64>,
        loss: f64,
        lambda: &mut f64,
        loss_of: &dyn Fn(&Network) -> Option<f64>,
    ) -> bool {
        let jtj = j.transpose() * j;
        let g = j.transpose() * r;
        if g.amax() < 1e-14 || *lambda > 1e12 {
            return false;
        }
        let w0 = self.weights();
        while *lambda <= 1e12 {
            let mut a = jtj.clone();
            for k in 0..a.nrows() {
                a[(k, k)] += *lambda;
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&g)) else {
                *lambda *= 10.0;
                continue;
            };
            let w: Vec<f64> = w0.iter().zip(step.iter()).map(|(w, d)| w - d).collect();
            self.set_weights(&w);
            if loss_of(self).is_some_and(|l| l < loss) {
                *lambda = (*lambda * 0.1).max(1e-12);
                return true;
            }
            self.set_weights(&w0);
            *lambda *= 10.0;
        }
        true
    }

    /// Trains on patterns `x` (inputs × n) with targets `t` (outputs × n). With a validation
    /// fraction, that share of the patterns (chosen from the seed) is held out, training stops
    /// after `patience` epochs without improvement, and the best-validation weights are restored.
    pub fn train(&mut self, x: &DMatrix<f64>, t: &DMatrix<f64>, cfg: &TrainConfig) -> TrainOutcome {
        self.train_observed(x, t, cfg, &mut |_, _| {})
    }

    /// [`Network::train`], calling `observe(epoch, network)` after every epoch's update (for
    /// learning curves).
    pub fn train_observed(
        &mut self,
        x: &DMatrix<f64>,
        t: &DMatrix<f64>,
        cfg: &TrainConfig,
        observe: &mut dyn FnMut(usize, &Network),
    ) -> TrainOutcome {
        let (val_idx, train_idx) = validation_split(x.ncols(), cfg);
        let (val_idx, train_idx) = (val_idx.as_slice(), train_idx.as_slice());
        let n_val = val_idx.len();
        let pick = |m: &DMatrix<f64>, idx: &[usize]| {
            DMatrix::from_fn(m.nrows(), idx.len(), |r, c| m[(r, idx[c])])
        };
        let (xt, tt) = (pick(x, train_idx), pick(t, train_idx));
        let (xv, tv) = (pick(x, val_idx), pick(t, val_idx));
        let outs = t.nrows().max(1) as f64;
        let rms = |loss: f64, m: usize| (2.0 * loss / (m.max(1) as f64 * outs)).sqrt();

        let mut v = Gradient {
            w1: DMatrix::zeros(self.w1.nrows(), self.w1.ncols()),
            b1: DVector::zeros(self.b1.len()),
            w2: DMatrix::zeros(self.w2.nrows(), self.w2.ncols()),
            b2: DVector::zeros(self.b2.len()),
        };
        let mut best = self.clone();
        let mut best_val = f64::INFINITY;
        let mut best_epoch = 0;
        let mut history = Vec::new();
        let mut epochs = 0;
        let (eta, mu) = (cfg.learning_rate, cfg.momentum);
        let mut lambda = 1e-3;
        for epoch in 1..=cfg.epochs {
            match cfg.method {
                Method::Momentum => {
                    let (loss, g) = self.loss_and_gradient(&xt, &tt);
                    if !loss.is_finite() {
                        break;
                    }
                    if (epoch - 1) % HISTORY_EVERY == 0 {
                        history.push(rms(loss, xt.ncols()));
                    }
                    v.w1 = &v.w1 * mu - &g.w1 * eta;
                    v.b1 = &v.b1 * mu - &g.b1 * eta;
                    v.w2 = &v.w2 * mu - &g.w2 * eta;
                    v.b2 = &v.b2 * mu - &g.b2 * eta;
                    self.w1 += &v.w1;
                    self.b1 += &v.b1;
                    self.w2 += &v.w2;
                    self.b2 += &v.b2;
                }
                Method::LevenbergMarquardt => {
                    let (j, r) = self.output_jacobian(&xt, &tt);
                    let loss = 0.5 * r.norm_squared();
                    if (epoch - 1) % HISTORY_EVERY == 0 {
                        history.push(rms(loss, xt.ncols()));
                    }
                    if !self.levenberg_marquardt_step(&j, &r, loss, &mut lambda, &|net| {
                        Some(net.loss(&xt, &tt))
                    }) {
                        epochs = epoch;
                        break;
                    }
                }
            }
            epochs = epoch;
            observe(epoch, self);
            if n_val > 0 {
                let lv = self.loss(&xv, &tv);
                if lv < best_val {
                    best_val = lv;
                    best = self.clone();
                    best_epoch = epoch;
                } else if epoch - best_epoch >= cfg.patience {
                    break;
                }
            }
        }
        if n_val > 0 {
            *self = best;
        } else {
            best_epoch = epochs;
        }
        let train_rms = rms(self.loss(&xt, &tt), xt.ncols());
        TrainOutcome {
            epochs,
            best_epoch,
            train_rms,
            validation_rms: (n_val > 0).then(|| rms(best_val, n_val)),
            history,
        }
    }
}

/// Residuals of one pattern through a map of the network's outputs, and their derivatives
/// with respect to those outputs (rows: residuals, columns: outputs).
pub type MappedResidual = (Vec<f64>, DMatrix<f64>);

impl Network {
    /// Levenberg–Marquardt on E = ½ Σ_n ‖r_n(y_n)‖², where y_n are the outputs for pattern n
    /// (column n of `x`) and `residual(n, y_n)` maps them to residuals and their derivatives:
    /// trains a network whose outputs are not compared with targets directly but pass through a
    /// model first (a neuro-kinematic scheme trained end to end, E = ‖S_re − S_NK‖ of seed 001
    /// section 3.2). `None` from `residual` (the model failed on that pattern) rejects the step,
    /// or ends training if it happens at the current weights.
    ///
    /// Runs at most `cfg.epochs` steps; with `cfg.validation_fraction` > 0 that share of the
    /// patterns is held out, training stops after `cfg.patience` steps without a better
    /// held-out loss and the best weights are restored (as [`Network::train`]).
    pub fn train_through(
        &mut self,
        x: &DMatrix<f64>,
        residual: &dyn Fn(usize, &[f64]) -> Option<MappedResidual>,
        cfg: &TrainConfig,
    ) -> TrainOutcome {
        self.train_through_observed(x, residual, cfg, &mut |_, _| {})
    }

    /// [`Network::train_through`], calling `observe(step, network)` after every step.
    pub fn train_through_observed(
        &mut self,
        x: &DMatrix<f64>,
        residual: &dyn Fn(usize, &[f64]) -> Option<MappedResidual>,
        cfg: &TrainConfig,
        observe: &mut dyn FnMut(usize, &Network),
    ) -> TrainOutcome {
        let no = self.outputs();
        let (val_idx, train_idx) = validation_split(x.ncols(), cfg);
        let loss_over = |net: &Network, idx: &[usize]| -> Option<f64> {
            let y = net.forward(x);
            let mut l = 0.0;
            for &p in idx {
                let yp: Vec<f64> = y.column(p).iter().copied().collect();
                let (r, _) = residual(p, &yp)?;
                l += 0.5 * r.iter().map(|v| v * v).sum::<f64>();
            }
            Some(l)
        };
        let mut lambda = 1e-3;
        let mut history = Vec::new();
        let mut epochs = 0;
        let mut residual_count = 0;
        let mut best = (self.clone(), f64::INFINITY, 0usize);
        for epoch in 1..=cfg.epochs {
            let (jy, y) = self.output_jacobian(x, &DMatrix::zeros(no, x.ncols()));
            let mut rows: Vec<MappedResidual> = Vec::with_capacity(train_idx.len());
            for &p in &train_idx {
                let yp: Vec<f64> = (0..no).map(|o| y[o + no * p]).collect();
                match residual(p, &yp) {
                    Some(r) => rows.push(r),
                    None => break,
                }
            }
            if rows.len() < train_idx.len() {
                break;
            }
            residual_count = rows.iter().map(|(r, _)| r.len()).sum();
            let mut j = DMatrix::zeros(residual_count, jy.ncols());
            let mut r = DVector::zeros(residual_count);
            let mut row = 0;
            for (&p, (rp, dr)) in train_idx.iter().zip(&rows) {
                j.rows_mut(row, rp.len())
                    .copy_from(&(dr * jy.rows(no * p, no)));
                for (k, v) in rp.iter().enumerate() {
                    r[row + k] = *v;
                }
                row += rp.len();
            }
            let loss = 0.5 * r.norm_squared();
            if (epoch - 1) % HISTORY_EVERY == 0 {
                history.push((2.0 * loss / residual_count.max(1) as f64).sqrt());
            }
            epochs = epoch;
            if !self.levenberg_marquardt_step(&j, &r, loss, &mut lambda, &|net| {
                loss_over(net, &train_idx)
            }) {
                break;
            }
            observe(epoch, self);
            if !val_idx.is_empty() {
                let lv = loss_over(self, &val_idx).unwrap_or(f64::INFINITY);
                if lv < best.1 {
                    best = (self.clone(), lv, epoch);
                } else if epoch - best.2 >= cfg.patience {
                    break;
                }
            }
        }
        let mut best_epoch = epochs;
        let mut validation_rms = None;
        if !val_idx.is_empty() && best.1.is_finite() {
            *self = best.0;
            best_epoch = best.2;
            let count = residual_count.max(1) as f64 / train_idx.len().max(1) as f64;
            validation_rms = Some((2.0 * best.1 / (count * val_idx.len() as f64)).sqrt());
        }
        let final_loss = loss_over(self, &train_idx).unwrap_or(f64::NAN);
        TrainOutcome {
            epochs,
            best_epoch,
            train_rms: (2.0 * final_loss / residual_count.max(1) as f64).sqrt(),
            validation_rms,
            history,
        }
    }
}

/// The patterns held out for early stopping and those trained on (indices), as
/// [`Network::train`] splits `n` patterns: a seeded shuffle, the first
/// round(n · validation_fraction) held out.
pub fn validation_split(n: usize, cfg: &TrainConfig) -> (Vec<usize>, Vec<usize>) {
    let n_val = if cfg.validation_fraction > 0.0 && n >= 4 {
        ((n as f64 * cfg.validation_fraction).round() as usize).clamp(1, n - 2)
    } else {
        0
    };
    let mut order: Vec<usize> = (0..n).collect();
    if n_val > 0 {
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x5eed_0001);
        for i in (1..n).rev() {
            let j = rng.random_range(0..=i);
            order.swap(i, j);
        }
    }
    let train = order.split_off(n_val);
    (order, train)
}

fn row_sums(m: &DMatrix<f64>) -> DVector<f64> {
    DVector::from_fn(m.nrows(), |r, _| m.row(r).sum())
}

/// Affine scaling of each coordinate to zero mean and unit spread (spread 1 when constant).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scaler {
    /// Mean per coordinate.
    pub mean: Vec<f64>,
    /// Standard deviation per coordinate.
    pub scale: Vec<f64>,
}

impl Scaler {
    /// Fits to rows (one pattern per row).
    pub fn fit(rows: &[Vec<f64>]) -> Self {
        let d = rows.first().map_or(0, Vec::len);
        let n = rows.len().max(1) as f64;
        let mean: Vec<f64> = (0..d)
            .map(|k| rows.iter().map(|r| r[k]).sum::<f64>() / n)
            .collect();
        let scale = (0..d)
            .map(|k| {
                let s = (rows.iter().map(|r| (r[k] - mean[k]).powi(2)).sum::<f64>() / n).sqrt();
                if s > 1e-12 {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        Self { mean, scale }
    }

    /// The identity scaling of `d` coordinates.
    pub fn identity(d: usize) -> Self {
        Self {
            mean: vec![0.0; d],
            scale: vec![1.0; d],
        }
    }

    /// Raw to scaled.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        x.iter()
            .zip(self.mean.iter().zip(&self.scale))
            .map(|(v, (m, s))| (v - m) / s)
            .collect()
    }

    /// Scaled to raw.
    pub fn invert(&self, y: &[f64]) -> Vec<f64> {
        y.iter()
            .zip(self.mean.iter().zip(&self.scale))
            .map(|(v, (m, s))| v * s + m)
            .collect()
    }
}

/// Columns from rows: a d × n matrix.
pub fn columns(rows: &[Vec<f64>]) -> DMatrix<f64> {
    let d = rows.first().map_or(0, Vec::len);
    DMatrix::from_fn(d, rows.len(), |r, c| rows[c][r])
}
