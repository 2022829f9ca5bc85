//! `rigcal export`: a calibration taken home ([`rigcal_model::export`]).

use anyhow::{Context, Result};
use rigcal_model::export::{export_urdf, exported_parameters, offsets_yaml, ExportOptions};
use rigcal_model::model::ModelFile;
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

/// What `rigcal export urdf` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Format {
    Urdf,
    Yaml,
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
    let loaded = ModelFile::load(&model)?;
    let (e, note) = exported_parameters(&loaded.file, &loaded.rig, &model)?;
    if let Some(n) = note {
        tracing::warn!("{n}");
    }
    let text = std::fs::read_to_string(&urdf)
        .with_context(|| format!("cannot read {}", urdf.display()))?;
    let x = export_urdf(&text, &loaded.rig.chain, &e, &ExportOptions { base, tip })
        .with_context(|| format!("exporting {} into {}", model.display(), urdf.display()))?;
    let body = match format {
        Format::Urdf => x.text.clone(),
        Format::Yaml => offsets_yaml(&x, &urdf.display().to_string()),
    };
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
