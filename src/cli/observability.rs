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
    /// Number of random poses (uniform within the joint limits) to analyse over.
    #[arg(long, default_value_t = 100)]
    poses: usize,
    /// Seed of the random poses.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Move every joint, ignoring the rig's held joints (e.g. the RV-M2's wrist).
    #[arg(long)]
    all_joints: bool,
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    anyhow::ensure!(a.poses >= 2, "--poses must be at least 2");
    print!(
        "{}",
        observability_text(&rig, a.poses, a.seed, a.all_joints)
    );
    Ok(())
}
