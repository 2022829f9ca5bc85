//! `rigcal rig`: rig-file tools. `rigcal rig from-urdf` writes a rig file from a URDF chain
//! ([`rigcal_calibration::convert::rig_from_urdf`]).

use anyhow::{Context, Result};
use rigcal_calibration::convert::{rig_from_urdf, FK_CHECK_SAMPLES};
use rigcal_core::kinematics::Robot;
use std::path::PathBuf;

/// Arguments of `rigcal rig`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: RigCommand,
}

#[derive(Debug, clap::Subcommand)]
enum RigCommand {
    /// Write a rig file (five-parameter convention) whose forward kinematics equals a URDF's
    /// chain from --base to --tip. The measurement frame and the marker are left free, as for a
    /// laser tracker or motion capture.
    #[command(mut_args(super::help_of("out", "Output rig file")))]
    FromUrdf {
        /// The URDF file.
        urdf: PathBuf,
        /// Base link of the chain.
        #[arg(long)]
        base: String,
        /// Tip link (where the marker is fixed).
        #[arg(long)]
        tip: String,
        #[command(flatten)]
        out: super::OutArg,
    },
}

pub fn run(a: Args) -> Result<()> {
    let RigCommand::FromUrdf {
        urdf,
        base,
        tip,
        out,
    } = a.command;
    let out = &out.out;
    let converted = rig_from_urdf(&urdf, &base, &tip, out)?;
    std::fs::write(out, &converted.toml)
        .with_context(|| format!("cannot write {}", out.display()))?;
    println!(
        "{} joints from `{base}` to `{tip}` → {} (forward kinematics checked against the URDF at {FK_CHECK_SAMPLES} joint vectors: largest difference {:.1e} mm)",
        converted.rig.chain.dof(),
        out.display(),
        converted.deviation_mm
    );
    Ok(())
}
