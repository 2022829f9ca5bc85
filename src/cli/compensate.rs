//! `rigcal compensate`: joint commands for target positions with a calibrated model
//! ([`crate::compensation::compensate_targets`]).

use crate::compensation::{compensate_targets, CompensationOptions};
use crate::kinematics::Robot;
use crate::model::ModelFile;
use crate::recording::{commands_csv, read_targets};
use anyhow::{Context, Result};
use std::path::PathBuf;

/// Arguments of `rigcal compensate`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of(
    "out",
    "Output CSV: one row of joint commands (`q1_deg…`) per target, same order"
)))]
pub struct Args {
    /// Model file written by `rigcal identify` or `rigcal calibrate`.
    #[arg(long)]
    model: PathBuf,
    /// Targets CSV: `x_mm,y_mm,z_mm` per row, or joint columns `q1_deg…` whose nominal positions
    /// are the targets.
    #[arg(long)]
    targets: PathBuf,
    #[command(flatten)]
    out: super::OutArg,
}

pub fn run(a: Args) -> Result<()> {
    let loaded = ModelFile::load(&a.model)?;
    let rig = &loaded.rig;
    let chain = &rig.chain;
    let targets = read_targets(&a.targets, chain.joints())?;
    let commands = compensate_targets(
        chain,
        loaded.errors.as_ref(),
        rig.held(),
        &targets,
        &CompensationOptions::default(),
    )
    .map_err(|e| {
        anyhow::Error::new(e.source).context(format!("{}: line {}", a.targets.display(), e.line))
    })?;
    let worst = commands.iter().map(|c| c.residual_mm).fold(0.0, f64::max);
    let text = commands_csv(
        chain.joints(),
        commands.iter().map(|c| c.command.as_slice()),
    );
    let out = &a.out.out;
    std::fs::write(out, text).with_context(|| format!("cannot write {}", out.display()))?;
    println!(
        "{} targets compensated (largest modelled error left {:.1e} mm); commands written to {}",
        targets.len(),
        worst,
        out.display()
    );
    Ok(())
}
