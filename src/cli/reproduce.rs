//! `rigcal reproduce seed001 --table N`: seed 001's tables beside our numbers.

use anyhow::{bail, Result};
use rigcal_model::neural::network::Method;
use rigcal_paper::reproduce::seed001::{reproduce, ReproOptions, TABLE5_POSES};
use std::path::PathBuf;

/// Arguments of `rigcal reproduce`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The paper: `seed001` (neural-network calibration).
    pub paper: String,
    /// Tables: 5 (with 4), 7 (with 6 and 8), 11 or 12 (with 10), 17 or 18 (with 16). Repeatable;
    /// all tables and figures when neither --table nor --figure is given.
    #[arg(long = "table")]
    pub tables: Vec<u32>,
    /// Figures: 7 (learning curves of the seven direct schemes, Table 5's setting; with --out,
    /// DIR/seed001-fig7.svg and .csv). Repeatable.
    #[arg(long = "figure")]
    pub figures: Vec<u32>,
    /// Epochs of batch back-propagation (Table 5: of its "paper's rule" rows; its main rows are
    /// Levenberg–Marquardt fits).
    #[arg(long, default_value_t = 20_000)]
    pub epochs: usize,
    /// Levenberg–Marquardt instead of the paper's gradient descent with momentum, for Tables 7,
    /// 11/12 and 17/18 (Table 5 prints both).
    #[arg(long)]
    pub lm: bool,
    /// Training poses of Table 5 (the paper: 46, evenly spread); η of its gradient-descent rows
    /// is rescaled to keep the mean-gradient step.
    #[arg(long, default_value_t = TABLE5_POSES)]
    pub poses: usize,
    /// Hidden neurons for the Stewart platform and the 3-DOF SCARA (the paper does not say).
    #[arg(long, default_value_t = 10)]
    pub hidden: usize,
    /// Seed of poses, random errors and weights.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write each table to DIR/seed001-table-N.txt.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    if a.paper != "seed001" {
        bail!("unknown paper `{}`: only `seed001` is reproduced here (seed 000: scripts/reproduce-paper.sh)", a.paper);
    }
    let o = ReproOptions {
        seed: a.seed,
        epochs: a.epochs,
        table5_poses: a.poses,
        method: if a.lm {
            Method::LevenbergMarquardt
        } else {
            Method::Momentum
        },
        ..ReproOptions::default()
    };
    let out = a.out.as_deref();
    reproduce(&a.tables, &a.figures, &o, a.hidden, out, &mut |t| {
        print!("{t}")
    })?;
    Ok(())
}
