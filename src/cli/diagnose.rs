//! `rigcal diagnose`: what physics the nominal model leaves out of a recording; with `--sim`,
//! the twin that learns from it ([`rigcal_sim::twin::learn`]); with `--model`, a model file with the
//! named effects ([`rigcal_sim::twin::model_with_named_effects`]).

use super::{RecordingArg, RigArg};
use anyhow::{Context, Result};
use rigcal_calibration::conventional::{named_effects_text, physics_sessions_text};
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::sessions::PerSession;
use rigcal_model::diagnosis::{diagnose, Options};
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
    /// between days): an effect that raises their RMS (frame refitted) is not named; the
    /// geometry and the named effects fitted here are kept, the measurement frame refitted on
    /// each, and the RMS with and without the effects printed.
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
        .map(|p| rigcal_calibration::read_recording(&rig, p))
        .collect::<Result<Vec<_>, _>>()?;
    let held = rigcal_calibration::read_heldout(&rig, &a.heldout_session)?;
    let per = if a.refit_marker {
        PerSession::FrameAndMarker
    } else {
        PerSession::Frame
    };
    let opts = Options {
        heldout,
        sessions: held.clone(),
        per_session: per,
    };
    let report =
        diagnose(&rig, &rec, &opts).with_context(|| format!("diagnosing {}", path.display()))?;
    println!("recording {}", path.display());
    print!("{}", report.text());
    if !held.is_empty() {
        // Held-out sessions with the frame refitted, geometry only and with the named effects.
        print!(
            "{}",
            physics_sessions_text(&rig, &rec, &report, &held, per)?
        );
    }
    if let Some(path) = &a.json {
        let text = report.to_json()?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        println!("report written to {}", path.display());
    }
    if let Some(html) = &a.report {
        let residuals = rigcal_model::diagnosis::plots::residual_series(&rig, &rec)?;
        let source = rigcal_model::report::html::Source::of(&rig, &a.rig.rig, path, rec.rows.len());
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
        print!("{}", named_effects_text(&file, &left));
        file.save(out)?;
        println!("model written to {}", out.display());
    }
    Ok(())
}

fn twin(rig: &Rig, rec: &Recording, sim: &Path, out: &Path) -> Result<()> {
    let (scenario, source) = rigcal_calibration::files::twin_scenario(rig, sim)?;
    eprintln!("replaying {} rows in {} …", rec.rows.len(), sim.display());
    let t = rigcal_sim::twin::learn(&scenario, &source, rec, out, &Default::default())?;
    print!("{}", t.text());
    std::fs::write(out, &t.scenario).with_context(|| format!("writing {}", out.display()))?;
    println!("updated scenario written to {}", out.display());
    Ok(())
}
