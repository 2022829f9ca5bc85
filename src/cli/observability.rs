//! `rigcal observability`: rank, identifiable basis and confounded parameters of a rig
//! ([`observability_text`]).

use super::RigArg;
use anyhow::Result;
use rigcal_calibration::conventional::observability_text;

/// Arguments of `rigcal observability`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    rig: RigArg,
    /// Number of random poses (uniform within the joint limits) to analyse over, 2 to 100000.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(2..=MAX_POSES))]
    poses: u64,
    /// Seed of the random poses.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Move every joint, ignoring the rig's held joints (e.g. the RV-M2's wrist).
    #[arg(long)]
    all_joints: bool,
}

/// Most poses analysed: the Jacobian holds 3 rows per pose, refused up front rather than
/// filling memory.
const MAX_POSES: u64 = 100_000;

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    let poses = usize::try_from(a.poses)?;
    print!("{}", observability_text(&rig, poses, a.seed, a.all_joints));
    Ok(())
}
