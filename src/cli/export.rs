//! `rigcal export`: a calibration taken home ([`rigcal_calibration::convert::export_files`]).

use anyhow::{Context, Result};
use rigcal_calibration::convert::{export_files, ExportFormat};
use rigcal_model::export::ExportOptions;
use std::path::PathBuf;

/// Arguments of `rigcal export`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: ExportCommand,
}

#[derive(Debug, clap::Subcommand)]
enum ExportCommand {
    /// Fold a model's fitted parameters into the URDF its rig came from: each moving joint's
    /// <origin> is rewritten (joint offsets go into its rotation; axes and limits stay), and
    /// two fixed links are added, <base>_tracker (the fitted measurement frame) and
    /// <tip>_marker (the fitted marker). Every other byte of the URDF is kept.
    #[command(mut_args(super::help_of("out", "Where to write the calibrated URDF (or YAML)")))]
    Urdf {
        /// The model file (from `rigcal identify` or `rigcal calibrate`).
        #[arg(long)]
        model: PathBuf,
        /// The URDF the rig was made from (`rigcal rig from-urdf`).
        #[arg(long)]
        urdf: PathBuf,
        #[command(flatten)]
        out: super::OutArg,
        /// `urdf`: the calibrated URDF; `yaml`: a flat list of corrected joint offsets and
        /// origins.
        #[arg(long, value_enum, default_value_t = Format::Urdf)]
        format: Format,
        /// Base link (default: the link above the first joint that is the rig's world frame).
        #[arg(long)]
        base: Option<String>,
        /// Tip link (default: the link below the last joint that is the rig's tool frame).
        #[arg(long)]
        tip: Option<String>,
    },
}

super::options::value_enum! {
    /// What `rigcal export urdf` writes.
    Format => ExportFormat {
        Urdf,
        Yaml,
    }
}

pub fn run(a: Args) -> Result<()> {
    let ExportCommand::Urdf {
        model,
        urdf,
        out,
        format,
        base,
        tip,
    } = a.command;
    let options = ExportOptions { base, tip };
    let (body, x) = export_files(&model, &urdf, format.into(), &options)?;
    std::fs::write(&out.out, body)
        .with_context(|| format!("cannot write {}", out.out.display()))?;
    println!(
        "{} joints from `{}` to `{}`, tracker `{}_tracker`, marker `{}_marker` → {}",
        x.joints.len(),
        x.base,
        x.tip,
        x.base,
        x.tip,
        out.out.display()
    );
    Ok(())
}
