//! `rigcal compensate`: joint commands for target positions with a calibrated model
//! ([`rigcal_model::compensation::compensate_targets`]; with the model's effects or a planned
//! approach, [`rigcal_model::model::hybrid::compensate_path`]).

use anyhow::{Context, Result};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{commands_csv, read_targets, Target};
use rigcal_devices::devices::controller::{with_pose_columns, CommandPath, ControllerKinematics};
use rigcal_model::compensation::{compensate_targets, CompensationOptions, TargetError};
use rigcal_model::model::hybrid::{compensate_path, path_csv, Approach, HybridArm, HybridOptions};
use rigcal_model::model::{LoadedModel, ModelFile};
use std::path::PathBuf;

/// Arguments of `rigcal compensate`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of(
    "out",
    "Output CSV: one row of joint commands (`q1_deg…`) per target, same order; with effects or \
     `--approach consistent`, one row per move with a `move` column (`via` or `target`); on a rig \
     whose `[devices.arm] command_path` is `cartesian`, the `MP` pose of each command beside it \
     (`mp_x_mm…mp_roll_deg`, controller frame, one decimal)"
)))]
pub struct Args {
    /// Model file written by `rigcal identify` or `rigcal calibrate`.
    #[arg(long)]
    model: PathBuf,
    /// Targets CSV: `x_mm,y_mm,z_mm` per row, or joint columns `q1_deg…` whose nominal positions
    /// are the targets.
    #[arg(long)]
    targets: PathBuf,
    /// How backlash sees each target: `path` (the sign of each joint's motion from the previous
    /// command, in the targets' order) or `consistent` (a via move 1° below every moving joint
    /// before each target, so all are approached from the same side; the via rows are written).
    #[arg(long, value_enum, default_value_t = ApproachArg::Path)]
    approach: ApproachArg,
    /// Payload at the tool (kg) for the model's joint compliance (the rig's link masses carry
    /// the arm's own weight).
    #[arg(long, default_value_t = 0.0)]
    payload_kg: f64,
    #[command(flatten)]
    out: super::OutArg,
}

/// `--approach`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ApproachArg {
    /// From the path's order.
    Path,
    /// Every target from below, through a via move.
    Consistent,
}

pub fn run(a: Args) -> Result<()> {
    let loaded = ModelFile::load(&a.model)?;
    let targets = read_targets(&a.targets, loaded.rig.chain.joints())?;
    let at_line = |e: TargetError| {
        anyhow::Error::new(e.source).context(format!("{}: line {}", a.targets.display(), e.line))
    };
    if !(a.payload_kg.is_finite() && a.payload_kg >= 0.0) {
        anyhow::bail!("--payload-kg must be zero or positive");
    }
    let hybrid = !loaded.file.effects.is_empty() || a.approach == ApproachArg::Consistent;
    let path = rigcal_devices::config::DevicesConfig::read_opt(&loaded.rig)
        .map(|d| d.arm.command_path)
        .unwrap_or_default();
    let (text, worst) = if hybrid {
        hybrid_commands(&loaded, &targets, &a).map_err(at_line)?
    } else {
        let (text, worst, joints) = plain_commands(&loaded, &targets).map_err(at_line)?;
        let text = if path == CommandPath::Cartesian {
            with_pose_columns(&text, &ControllerKinematics::of_rig(&loaded.rig)?, &joints)
        } else {
            text
        };
        (text, worst)
    };
    let out = &a.out.out;
    std::fs::write(out, text).with_context(|| format!("cannot write {}", out.display()))?;
    println!("command path: {path}");
    for e in &loaded.file.effects {
        println!("compensating {}", e.text());
    }
    println!(
        "{} targets compensated (largest modelled error left {:.1e} mm); commands written to {}",
        targets.len(),
        worst,
        out.display()
    );
    Ok(())
}

fn plain_commands(
    loaded: &LoadedModel,
    targets: &[(u64, Target)],
) -> Result<(String, f64, Vec<Vec<f64>>), TargetError> {
    let chain = &loaded.rig.chain;
    let commands = compensate_targets(
        chain,
        loaded.errors.as_ref(),
        loaded.rig.held(),
        targets,
        &CompensationOptions::default(),
    )?;
    let worst = commands.iter().map(|c| c.residual_mm).fold(0.0, f64::max);
    let text = commands_csv(
        chain.joints(),
        commands.iter().map(|c| c.command.as_slice()),
    );
    Ok((
        text,
        worst,
        commands.into_iter().map(|c| c.command).collect(),
    ))
}

fn hybrid_commands(
    loaded: &LoadedModel,
    targets: &[(u64, Target)],
    a: &Args,
) -> Result<(String, f64), TargetError> {
    let rig = &loaded.rig;
    let arm = HybridArm {
        chain: &rig.chain,
        masses: &rig.link_masses,
        held: rig.held(),
    };
    let opts = HybridOptions {
        approach: match a.approach {
            ApproachArg::Path => Approach::FromPath,
            ApproachArg::Consistent => Approach::Consistent,
        },
        payload_kg: a.payload_kg,
        ..HybridOptions::default()
    };
    let path = compensate_path(
        &arm,
        loaded.errors.as_ref(),
        &loaded.file.effects,
        targets,
        None,
        &opts,
    )?;
    let worst = path.iter().map(|c| c.residual_mm).fold(0.0, f64::max);
    Ok((path_csv(rig.chain.joints(), &path), worst))
}
