//! Reproductions of seed 001's tables, each printed beside the paper's numbers.
//!
//! | table | what | robot | module |
//! |---|---|---|---|
//! | 4, 5 | error before calibration; mean validation error of the seven direct schemes, cases 1–3, and their ranking | 2-DOF SCARA | [`scara2_schemes`] |
//! | 6, 7, 8 | random errors: apparent/actual error and FI, direct (7) and inverse (8) | 2-DOF SCARA | [`random_errors`] |
//! | 10, 11, 12 | Stewart platform before calibration; inverse schemes 2 (11) and 4 (12) | Stewart | [`stewart_platform`] |
//! | 16, 17, 18 | 3-DOF SCARA before calibration; direct schemes 3 (17) and 4 (18) | 3-DOF SCARA | [`scara3_direct`] |
//! | Fig. 7 | learning curves of the seven direct schemes, Table 5's setting | 2-DOF SCARA | [`learning_curves`] |
//!
//! The poses every table trains and validates on are drawn in [`poses`]; training a scheme and
//! measuring it is [`runs`]. Choices where the paper is silent are stated in the robots' modules
//! and in [`Table::notes`]. Everything is deterministic from the seed. Which tables to run and
//! writing them to files is [`selection`]; the same tables over many seeds, each figure as a
//! ratio to the paper's and the paper's order of the schemes kept or not, is [`audit`].

pub mod audit;
pub mod learning_curves;
pub mod poses;
pub mod random_errors;
pub mod runs;
pub mod scara2_schemes;
pub mod scara3_direct;
pub mod selection;
pub mod stewart_platform;

pub use audit::{Audit, TableSummary};
pub use learning_curves::{fig7, Curve, Fig7, FIG7_CHECKPOINTS};
pub use poses::{scara2_grid, scara2_samples, scara2_spread, scara3_samples, stewart_samples};
pub use random_errors::{table7, TABLE7_MAX_HIDDEN};
pub use runs::{run_scheme, SchemeRun};
pub use scara2_schemes::{table5, TABLE5_HIDDEN, TABLE5_LM_ITERATIONS};
pub use scara3_direct::table18;
pub use selection::{
    check_figures, reproduce, reproduced_table, run_fig7, run_table, tables_for, write_fig7,
    write_table, ReproduceError, REPRODUCED_FIGURES, REPRODUCED_TABLES,
};
pub use stewart_platform::table11;

use rigcal_model::neural::network::{Method, TrainConfig};
use rigcal_model::neural::AngularSum;
use std::fmt::Write;

/// Sizes and training settings of a reproduction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReproOptions {
    /// Seed of poses, random errors and initial weights.
    pub seed: u64,
    /// Epochs of batch back-propagation (the paper: 1000 for Table 5).
    pub epochs: usize,
    /// Learning rate η (paper 0.01).
    pub learning_rate: f64,
    /// Momentum (paper 0.9).
    pub momentum: f64,
    /// Update rule: the paper's gradient descent with momentum, or Levenberg–Marquardt.
    pub method: Method,
    /// How angle corrections are added (Table 1).
    pub angular_sum: AngularSum,
    /// Hidden neurons for Table 5 (the paper: 20).
    pub hidden: usize,
    /// Divides the validation set sizes (1 = the paper's; larger for quick tests).
    pub reduce: usize,
    /// Training poses of Table 5 (the paper: 46). The learning rate η applies to the gradient
    /// summed over the paper's 46 poses; with another count it is rescaled by 46 / poses, so the
    /// step on the mean gradient (0.46 η / 0.01) stays the one that is stable at 46 poses.
    pub table5_poses: usize,
}

impl Default for ReproOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            epochs: 20_000,
            learning_rate: 0.01,
            momentum: 0.9,
            method: Method::Momentum,
            angular_sum: AngularSum::Trig,
            hidden: 20,
            reduce: 1,
            table5_poses: TABLE5_POSES,
        }
    }
}

impl ReproOptions {
    /// The training settings for `hidden` neurons, with early stopping on a quarter of the
    /// poses when `early`, initial weights from `seed`.
    pub fn cfg(&self, hidden: usize, early: bool, seed: u64) -> TrainConfig {
        TrainConfig {
            method: self.method,
            hidden,
            learning_rate: self.learning_rate,
            momentum: self.momentum,
            epochs: self.epochs,
            validation_fraction: if early { 0.25 } else { 0.0 },
            patience: (self.epochs / 5).max(200),
            seed,
        }
    }
}

/// The paper's training poses for Table 5.
pub const TABLE5_POSES: usize = 46;

/// A reproduced table: text with our numbers beside the paper's, and the numbers themselves.
#[derive(Debug, Clone, Default)]
pub struct Table {
    /// Title.
    pub title: String,
    /// The printed table.
    pub text: String,
    /// Our choices and why numbers differ.
    pub notes: Vec<String>,
    /// (label, ours, paper) for every number compared.
    pub values: Vec<(String, f64, f64)>,
}

impl Table {
    /// Table text and notes.
    pub fn render(&self) -> String {
        let mut s = format!("== {}\n{}", self.title, self.text);
        for n in &self.notes {
            let _ = writeln!(s, "  note: {n}");
        }
        s
    }

    /// The value labelled `label`, ours.
    pub fn ours(&self, label: &str) -> Option<f64> {
        self.values
            .iter()
            .find(|(l, _, _)| l == label)
            .map(|(_, v, _)| *v)
    }
}
