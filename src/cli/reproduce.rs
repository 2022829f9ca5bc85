//! `rigcal reproduce seed001 --table N`: seed 001's tables beside our numbers.

use crate::neural::network::Method;
use crate::neural::reproduce::{table11, table18, table5, table7, ReproOptions, Table};
use anyhow::{bail, Context, Result};
use std::path::PathBuf;

/// Arguments of `rigcal reproduce`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The paper: `seed001` (neural-network calibration).
    pub paper: String,
    /// Tables: 5 (with 4), 7 (with 6 and 8), 11 or 12 (with 10), 17 or 18 (with 16). Repeatable;
    /// all when omitted.
    #[arg(long = "table")]
    pub tables: Vec<u32>,
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
    #[arg(long, default_value_t = crate::neural::reproduce::TABLE5_POSES)]
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
    let tables = if a.tables.is_empty() {
        vec![5, 7, 11, 18]
    } else {
        a.tables.clone()
    };
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let mut done: Vec<u32> = Vec::new();
    for t in tables {
        let key = match t {
            4 | 5 => 5,
            6..=8 => 7,
            10..=12 => 11,
            16..=18 => 18,
            other => bail!("table {other} is not reproduced: use 5, 7, 11, 12, 17 or 18"),
        };
        if done.contains(&key) {
            continue;
        }
        done.push(key);
        let start = std::time::Instant::now();
        let table: Table = match key {
            5 => table5(&o)?,
            7 => table7(&o)?,
            11 => table11(&o, a.hidden)?,
            _ => table18(&o, a.hidden)?,
        };
        let text = table.render();
        println!("{text}  ({:.1} s)\n", start.elapsed().as_secs_f64());
        if let Some(dir) = &a.out {
            let f = dir.join(format!("seed001-table-{key}.txt"));
            std::fs::write(&f, &text).with_context(|| format!("cannot write {}", f.display()))?;
        }
    }
    Ok(())
}
