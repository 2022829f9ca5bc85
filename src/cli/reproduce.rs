//! `rigcal reproduce seed001 --table N`: seed 001's tables beside our numbers.

use crate::neural::network::Method;
use crate::report::{plot_log_curves, CurvePanel};
use crate::reproduce::seed001::{
    fig7, table11, table18, table5, table7, Fig7, ReproOptions, Table, TABLE5_POSES,
};
use anyhow::{bail, Context, Result};
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
    let everything = a.tables.is_empty() && a.figures.is_empty();
    let tables = if everything {
        vec![5, 7, 11, 18]
    } else {
        a.tables.clone()
    };
    let figures = if everything {
        vec![7]
    } else {
        a.figures.clone()
    };
    if let Some(f) = figures.iter().find(|&&f| f != 7) {
        bail!("figure {f} is not reproduced: use 7");
    }
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
    if figures.contains(&7) {
        let start = std::time::Instant::now();
        let fig = fig7(&o)?;
        println!(
            "{}  ({:.1} s)\n",
            fig.render(),
            start.elapsed().as_secs_f64()
        );
        if let Some(dir) = &a.out {
            write_fig7(&fig, dir)?;
        }
    }
    Ok(())
}

/// Writes Fig. 7 as CSV and as an SVG of three log-log panels.
fn write_fig7(fig: &Fig7, dir: &std::path::Path) -> Result<()> {
    let csv = dir.join("seed001-fig7.csv");
    std::fs::write(&csv, fig.csv()).with_context(|| format!("cannot write {}", csv.display()))?;
    let panels: Vec<CurvePanel> = fig
        .cases
        .iter()
        .enumerate()
        .map(|(c, curves)| CurvePanel {
            title: format!("case {}", c + 1),
            curves: curves
                .iter()
                .map(|k| {
                    (
                        format!("scheme {}", k.scheme),
                        k.points.iter().map(|&(i, e)| (i as f64, e)).collect(),
                    )
                })
                .collect(),
        })
        .collect();
    let svg = dir.join("seed001-fig7.svg");
    plot_log_curves(
        &svg,
        "Seed 001 Fig. 7: mean validation error during training (2-DOF SCARA)",
        "Levenberg–Marquardt iteration",
        "mean validation error (mm)",
        &panels,
    )?;
    println!("plot: {}  data: {}", svg.display(), csv.display());
    Ok(())
}
