//! `rigcal compensate`: joint commands for target positions with a calibrated model
//! ([`rigcal_calibration::commands`]).

use anyhow::{Context, Result};
use rigcal_calibration::commands::{compensate_files, CommandOptions};
use rigcal_model::model::hybrid::Approach;
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `rigcal compensate`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of(
    "out",
    "Output CSV: one row of joint commands (`q1_deg…`) per target, same order; with effects or \
     `--approach consistent`, one row per move with a `move` column (`via` or `target`); on a rig \
     whose `[devices.arm] command_path` is `cartesian`, the `MP` pose of each command beside it \
     (`mp_x_mm…mp_roll_deg`, controller frame, one decimal); when a target cannot be \
     compensated, its row with empty command cells and a last `status` column (`ok`, or why not)"
)))]
#[command(
    after_help = "Exit status: 0 when every target is compensated; 3 when some are not \
    (the others are written, with the `status` column, and stderr names each target left out); \
    1 on any other error, or with --strict on the first target left out (nothing written)."
)]
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
    #[arg(long, value_enum, default_value_t = ApproachArg::FromPath)]
    approach: ApproachArg,
    /// Payload at the tool (kg) for the model's joint compliance (the rig's link masses carry
    /// the arm's own weight).
    #[arg(long, default_value_t = 0.0)]
    payload_kg: f64,
    /// Fail on the first target that cannot be compensated and write nothing (by default the
    /// others are written, with a `status` column, and the exit status is 3).
    #[arg(long)]
    strict: bool,
    #[command(flatten)]
    out: super::OutArg,
}

super::options::value_enum! {
    /// `--approach`.
    ApproachArg => Approach {
        /// From the path's order.
        #[value(name = "path")]
        FromPath,
        /// Every target from below, through a via move.
        Consistent,
    }
}

/// The exit status of a partial result: the file is written but some targets are missing, which
/// a script must not take for a success (0) nor for a run that wrote nothing (1).
const PARTIAL_EXIT: i32 = 3;

pub fn run(a: Args) -> Result<()> {
    let opts = CommandOptions {
        approach: a.approach.into(),
        payload_kg: a.payload_kg,
        strict: a.strict,
    };
    let commands = compensate_files(&a.model, &a.targets, &opts)?;
    let out = &a.out.out;
    std::fs::write(out, &commands.csv)
        .with_context(|| format!("cannot write {}", out.display()))?;
    print!("{}", commands.text(out));
    if commands.complete() {
        return Ok(());
    }
    let _ = std::io::stdout().flush();
    eprint!(
        "error: {} of {} targets not compensated (their rows in {} have empty commands and the \
         reason in `status`; exit status {PARTIAL_EXIT}; --strict writes nothing instead):\n{}",
        commands.failed.len(),
        commands.targets,
        out.display(),
        commands.failures_text()
    );
    // A distinct status rather than an error through `main`: the file is written, unlike
    // every other failure, and a script must be able to tell the two apart.
    std::process::exit(PARTIAL_EXIT)
}
