//! `rigcal compensate`: joint commands for target positions with a calibrated model
//! ([`crate::compensation::compensate_targets`]).

use crate::compensation::{compensate_targets, with_pose_columns, CompensationOptions};
use crate::kinematics::Robot;
use crate::model::ModelFile;
use crate::recording::{commands_csv, read_targets};
use crate::rig::controller::{CommandPath, ControllerKinematics};
use anyhow::{Context, Result};
use std::path::PathBuf;

/// Arguments of `rigcal compensate`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of(
    "out",
    "Output CSV: one row of joint commands (`q1_deg…`) per target, same order; on a rig whose `[devices.arm] command_path` is `cartesian`, the `MP` pose of each command beside it (`mp_x_mm…mp_roll_deg`, controller frame, one decimal)"
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
    let mut text = commands_csv(
        chain.joints(),
        commands.iter().map(|c| c.command.as_slice()),
    );
    let path = rig
        .devices
        .as_ref()
        .map(|d| d.arm.command_path)
        .unwrap_or_default();
    if path == CommandPath::Cartesian {
        let controller = ControllerKinematics::of_rig(rig)?;
        let joints: Vec<Vec<f64>> = commands.iter().map(|c| c.command.clone()).collect();
        text = with_pose_columns(&text, &controller, &joints);
    }
    let out = &a.out.out;
    std::fs::write(out, text).with_context(|| format!("cannot write {}", out.display()))?;
    println!("command path: {path}");
    println!(
        "{} targets compensated (largest modelled error left {:.1e} mm); commands written to {}",
        targets.len(),
        worst,
        out.display()
    );
    Ok(())
}
