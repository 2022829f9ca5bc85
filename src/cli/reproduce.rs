//! `rigcal reproduce seed001 --table N`: seed 001's tables beside our numbers.

use super::options::{parse_seeds, SeedList};
use anyhow::{bail, Context, Result};
use rigcal_model::neural::network::Method;
use rigcal_paper::reproduce::seed001::{reproduce, Audit, ReproOptions, TABLE5_POSES};
use std::path::{Path, PathBuf};

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
    #[arg(long, default_value_t = 1, conflicts_with = "seeds")]
    pub seed: u64,
    /// Run the tables at every seed of `A-B` or `3,8,10` and print, per paper table, each
    /// figure as ours ÷ paper (median, share within 10×, worst) and how often the paper's order
    /// of the schemes holds, instead of the tables themselves (with --out: DIR/seed001-seeds.txt
    /// and .csv, one row per figure and seed).
    #[arg(long, value_name = "SEEDS", value_parser = parse_seeds)]
    seeds: Option<SeedList>,
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
    if let Some(SeedList(seeds)) = a.seeds {
        if !a.figures.is_empty() {
            bail!("--seeds runs tables only: drop --figure");
        }
        return audit(&seeds, &a.tables, &o, a.hidden, out);
    }
    reproduce(&a.tables, &a.figures, &o, a.hidden, out, &mut |t| {
        print!("{t}")
    })?;
    Ok(())
}

/// `--seeds`: the tables at every seed, summarised per paper table.
fn audit(
    seeds: &[u64],
    tables: &[u32],
    o: &ReproOptions,
    hidden: usize,
    out: Option<&Path>,
) -> Result<()> {
    let mut done = 0;
    let audit = Audit::run(seeds, tables, o, hidden, &mut |seed| {
        done += 1;
        eprintln!("seed {seed} done ({done}/{})", seeds.len());
    })?;
    let text = audit.text();
    print!("{text}");
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for (name, body) in [
            ("seed001-seeds.txt", text),
            ("seed001-seeds.csv", audit.csv()),
        ] {
            let file = dir.join(name);
            std::fs::write(&file, body)
                .with_context(|| format!("cannot write {}", file.display()))?;
            println!("wrote {}", file.display());
        }
    }
    Ok(())
}
