//! `rigcal diagnose`: what physics the nominal model leaves out of a recording; with `--sim`,
//! the twin that learns from it ([`rigcal_sim::twin::learn`]); with `--model`, a model file with the
//! named effects ([`rigcal_sim::twin::model_with_named_effects`]).

use super::{RecordingArg, RigArg};
use anyhow::{Context, Result};
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::sessions::{physics_heldout, without_rows, PerSession};
use rigcal_model::diagnosis::{diagnose, Options, Report};
use rigcal_sim::world::Scenario;
use std::path::{Path, PathBuf};

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
    /// The twin: a scenario to replay the recording's own rows in (poses, order, times), compare
    /// point by point and diagnose the difference (1 row in 4 held out).
    #[arg(long, requires = "write_scenario")]
    sim: Option<PathBuf>,
    /// With `--sim`: write the updated scenario (fitted geometry, named effects, any flagged
    /// discrepancy) here.
    #[arg(long, requires = "sim")]
    write_scenario: Option<PathBuf>,
    /// Write a model file with the geometry and the named joint effects, for `compensate` and
    /// `evaluate`.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Held-out sessions not registered to this one (the tracker or motion-capture frame moved
    /// between days): the geometry and the named effects fitted here are kept, the measurement
    /// frame refitted on each, and the RMS with and without the effects printed.
    #[arg(long, num_args = 1..)]
    heldout_session: Vec<PathBuf>,
    /// Refit the marker too on each held-out session.
    #[arg(long)]
    refit_marker: bool,
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    let rec = a.recording.read(&rig)?;
    let path = &a.recording.recording;
    if let (Some(sim), Some(out)) = (&a.sim, &a.write_scenario) {
        return twin(&rig, &rec, sim, out);
    }
    let heldout = a
        .heldout
        .iter()
        .map(|p| super::read_recording(&rig, p))
        .collect::<Result<Vec<_>>>()?;
    let report = diagnose(&rig, &rec, &Options { heldout })
        .with_context(|| format!("diagnosing {}", path.display()))?;
    println!("recording {}", path.display());
    print!("{}", report.text());
    if !a.heldout_session.is_empty() {
        print_sessions(&a, &rig, &rec, &report)?;
    }
    if let Some(path) = &a.json {
        let text = report.to_json()?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        println!("report written to {}", path.display());
    }
    if let Some(html) = &a.report {
        let residuals = rigcal_model::diagnosis::plots::residual_series(&rig, &rec)?;
        let source = super::report_source(&rig, &a.rig.rig, path, rec.rows.len());
        let text = rigcal_model::report::html::diagnosis_report(&source, &report, &residuals);
        super::write_report(html, &text)?;
    }
    if let Some(dir) = &a.plots {
        let written = rigcal_model::diagnosis::plots::write(&rig, &rec, dir)
            .with_context(|| format!("writing plots to {}", dir.display()))?;
        println!("{written} plot(s) written to {}", dir.display());
    }
    if let Some(out) = &a.model {
        let (file, left) = rigcal_sim::twin::model_with_named_effects(&rig, &rec, &report)?;
        for l in left {
            println!("not in the model: {l}");
        }
        for e in &file.effects {
            println!("in the model: {}", e.text());
        }
        file.save(out)?;
        println!("model written to {}", out.display());
    }
    Ok(())
}

fn twin(
    rig: &rigcal_core::rig::Rig,
    rec: &rigcal_core::recording::Recording,
    sim: &Path,
    out: &Path,
) -> Result<()> {
    let source =
        std::fs::read_to_string(sim).with_context(|| format!("reading {}", sim.display()))?;
    let scenario = Scenario::parse(&source, sim, None)?;
    if scenario.rig.name != rig.name {
        anyhow::bail!(
            "the scenario {} runs rig `{}`, the recording is read with rig `{}`",
            sim.display(),
            scenario.rig.name,
            rig.name
        );
    }
    eprintln!("replaying {} rows in {} …", rec.rows.len(), sim.display());
    let t = rigcal_sim::twin::learn(&scenario, &source, rec, out, &Default::default())?;
    print!("{}", t.text());
    std::fs::write(out, &t.scenario).with_context(|| format!("writing {}", out.display()))?;
    println!("updated scenario written to {}", out.display());
    Ok(())
}

/// Held-out sessions with the frame refitted, geometry only and with the named effects.
fn print_sessions(a: &Args, rig: &Rig, rec: &Recording, report: &Report) -> Result<()> {
    let held = super::identify::read_heldout(rig, &a.heldout_session)?;
    let per = if a.refit_marker {
        PerSession::FrameAndMarker
    } else {
        PerSession::Frame
    };
    let training = without_rows(rec, report.outliers.iter().map(|o| o.seq));
    let ph = physics_heldout(rig, &training, &report.effects, &held, per)?;
    println!(
        "held-out sessions ({}); effects: {}",
        per.describe(),
        if ph.effects.is_empty() {
            "none".to_string()
        } else {
            ph.effects.join(", ")
        }
    );
    println!(
        "  training RMS {:.4} mm geometry only, {:.4} mm with the effects",
        ph.training_geometry, ph.training_physics
    );
    for (name, geometry, physics) in &ph.heldout {
        println!("  held-out session {name}: RMS {geometry:.4} mm geometry only, {physics:.4} mm with the effects");
    }
    Ok(())
}
