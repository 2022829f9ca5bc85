//! `rigcal register`: the table-to-world registration from a recording's table coordinates
//! ([`rigcal_model::identification::registration::register_recording`]).

use super::{RecordingArg, RigArg};
use anyhow::Result;
use rigcal_calibration::conventional::registration_text;
use rigcal_model::identification::registration::register_recording;
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
    print!("{}", registration_text(&reg));
    if let Some(out) = a.out {
        reg.apply(&rec).write_dir(&out)?;
        println!("registered recording written to {}", out.display());
    }
    Ok(())
}
