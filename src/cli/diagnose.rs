//! `rigcal diagnose`: what physics the nominal model leaves out of a recording.

use super::{RecordingArg, RigArg};
use crate::diagnosis::{diagnose, Options};
use anyhow::{Context, Result};
use std::path::PathBuf;

/// Arguments of `rigcal diagnose`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    rig: RigArg,
    #[command(flatten)]
    recording: RecordingArg,
    /// Write the diagnosis report as JSON here (`format` rigcal-diagnosis, `version` 1: the
    /// mismatch, the named effects with their parameters and evidence, the fit, the outliers).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write a self-contained HTML report (each effect with its evidence plot) here.
    #[arg(long, value_name = "FILE.html")]
    report: Option<PathBuf>,
    /// Write SVG residual plots into this directory.
    #[arg(long)]
    plots: Option<PathBuf>,
    /// Held-out recordings to check the named effects on (default: a split of time blocks).
    #[arg(long, num_args = 1..)]
    heldout: Vec<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    let rec = a.recording.read(&rig)?;
    let heldout = a
        .heldout
        .iter()
        .map(|p| super::read_recording(&rig, p))
        .collect::<Result<Vec<_>>>()?;
    let path = &a.recording.recording;
    let report = diagnose(&rig, &rec, &Options { heldout })
        .with_context(|| format!("diagnosing {}", path.display()))?;
    println!("recording {}", path.display());
    print!("{}", report.text());
    if let Some(path) = &a.json {
        let text = report.to_json()?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        println!("report written to {}", path.display());
    }
    if let Some(html) = &a.report {
        let residuals = crate::diagnosis::plots::residual_series(&rig, &rec)?;
        let source = super::report_source(&rig, &a.rig.rig, path, rec.rows.len());
        let text = crate::report::html::diagnosis_report(&source, &report, &residuals);
        super::write_report(html, &text)?;
    }
    if let Some(dir) = &a.plots {
        let written = crate::diagnosis::plots::write(&rig, &rec, dir)
            .with_context(|| format!("writing plots to {}", dir.display()))?;
        println!("{written} plot(s) written to {}", dir.display());
    }
    Ok(())
}
