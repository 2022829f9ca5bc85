//! `rigcal compensate`: joint commands for target positions with a calibrated model.

use crate::compensation::{compensate, compensate_from, CompensationOptions};
use crate::kinematics::{ErrorParams, Robot};
use crate::model::ModelFile;
use crate::recording::{read_targets, Target};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `rigcal compensate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file written by `rigcal identify` or `rigcal calibrate`.
    #[arg(long)]
    model: PathBuf,
    /// Targets CSV: `x_mm,y_mm,z_mm` per row, or joint columns `q1_deg…` whose nominal positions
    /// are the targets.
    #[arg(long)]
    targets: PathBuf,
    /// Output CSV: one row of joint commands (`q1_deg…`) per target, same order.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    let loaded = ModelFile::load(&a.model)?;
    let rig = &loaded.rig;
    let chain = &rig.chain;
    let targets = read_targets(&a.targets, chain.joints())?;
    let nominal = ErrorParams::zeros(chain.layout());
    let opts = CompensationOptions::default();
    let mut out = String::new();
    let header: Vec<String> = chain
        .joints()
        .iter()
        .enumerate()
        .map(|(i, j)| j.kind.column(i + 1))
        .collect();
    out.push_str(&header.join(","));
    out.push('\n');
    let mut seed: Option<Vec<f64>> = None;
    let mut worst = 0.0f64;
    for (line, target) in &targets {
        let c = match target {
            Target::Position(p) => compensate(
                chain,
                loaded.errors.as_ref(),
                p,
                rig.held(),
                seed.as_deref(),
                &opts,
            ),
            Target::Joints(q) => {
                let p = chain.position(q, &nominal);
                let held: Vec<Option<f64>> = rig
                    .held()
                    .iter()
                    .zip(q)
                    .map(|(h, v)| h.map(|_| *v))
                    .collect();
                compensate_from(chain, loaded.errors.as_ref(), &p, &held, q.clone(), &opts)
            }
        }
        .with_context(|| format!("{}: line {line}", a.targets.display()))?;
        worst = worst.max(c.residual_mm);
        let fields: Vec<String> = chain
            .joints()
            .iter()
            .zip(&c.command)
            .map(|(j, v)| format!("{:.6}", j.kind.to_file_units(*v)))
            .collect();
        let _ = writeln!(out, "{}", fields.join(","));
        seed = Some(c.command);
    }
    std::fs::write(&a.out, out).with_context(|| format!("cannot write {}", a.out.display()))?;
    println!(
        "{} targets compensated (largest modelled error left {:.1e} mm); commands written to {}",
        targets.len(),
        worst,
        a.out.display()
    );
    Ok(())
}
