//! `rigcal register`: the table-to-world registration from a recording's table coordinates
//! ([`rigcal_model::identification::registration::register_recording`]).

use super::{RecordingArg, RigArg};
use anyhow::Result;
use rigcal_model::identification::registration::{register_recording, Registration};
use std::path::PathBuf;

/// Arguments of `rigcal register`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of(
    "recording",
    "Recording whose rows carry table_x_mm, table_y_mm, table_z_mm"
)))]
pub struct Args {
    #[command(flatten)]
    rig: RigArg,
    #[command(flatten)]
    recording: RecordingArg,
    /// Write a registered copy of the recording here: x_mm… recomputed from the table
    /// coordinates, and the registration stored in its session.toml.
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    let rec = a.recording.read(&rig)?;
    let reg = register_recording(&rig.chain, &rec)?;
    print_registration(&reg);
    if let Some(out) = a.out {
        reg.apply(&rec).write_dir(&out)?;
        println!("registered recording written to {}", out.display());
    }
    Ok(())
}

/// Prints a registration: the transform with its σ, and the residual.
fn print_registration(reg: &Registration) {
    let info = reg.info();
    let (xyz, rpy) = (info.translation_mm, info.rpy_deg);
    println!(
        "registration from {} points (nominal kinematics): world = R · table + t",
        reg.n
    );
    println!(
        "  t   = ({:+.4}, {:+.4}, {:+.4}) mm   σ ({:.4}, {:.4}, {:.4}) mm",
        xyz[0], xyz[1], xyz[2], reg.sigma[0], reg.sigma[1], reg.sigma[2]
    );
    println!(
        "  rpy = ({:+.5}, {:+.5}, {:+.5}) deg",
        rpy[0], rpy[1], rpy[2]
    );
    println!(
        "  residual: RMS {:.4} mm, max {:.4} mm (what the nominal kinematics cannot explain; identification absorbs it)",
        reg.stats.rms_mm, reg.stats.max_mm
    );
}
