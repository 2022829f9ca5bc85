//! `rigcal identify`: conventional calibration of a recording ([`rigcal_model::identification::identify`]).

use super::{OutArg, RecordingArg, RigArg};
use anyhow::Result;
use rigcal_core::kinematics::Robot;
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::sessions::{fit_sessions, heldout_sessions, PerSession};
use rigcal_model::identification::outliers::Outlier;
use rigcal_model::identification::{identify, FitResult, HeldOut, Identification, IdentifyOptions};
use rigcal_model::model::effects::{fit_recording_effects, EffectSpec, ModelEffect};
use rigcal_model::model::{ModelFile, Provenance};
use std::path::{Path, PathBuf};

use super::read_recording;

/// Arguments of `rigcal identify`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of("out", "Where to write the model (JSON)")))]
pub struct Args {
    #[command(flatten)]
    rig: RigArg,
    #[command(flatten)]
    recording: RecordingArg,
    #[command(flatten)]
    out: OutArg,
    /// What to fit: `frames` (the free measurement frame and marker only), `offsets` (plus the
    /// joint offsets that stay identifiable after them), `full` (every identifiable parameter).
    #[arg(long, value_enum, default_value_t = Level::Full)]
    level: Level,
    /// Held-out recordings (another day's session, say): RMS and max position error of the
    /// fitted model on each.
    #[arg(long, num_args = 1..)]
    heldout: Vec<PathBuf>,
    /// Effects to fit beside the geometry and write into the model, which `compensate` and
    /// `evaluate` then undo: comma-separated `backlash:J`, `transmission_error:J:ORDER`,
    /// `joint_compliance:J` (joints 1-based; compliance needs the rig's link masses). Name the
    /// ones `rigcal diagnose` reports.
    #[arg(long, value_delimiter = ',')]
    effects: Vec<String>,
    /// Held-out sessions not registered to the training one (the tracker or motion-capture
    /// frame moved between days): the fitted kinematic parameters are kept and the measurement
    /// frame is refitted on each, so the figure judges the kinematics, not the frame shift.
    #[arg(long, num_args = 1..)]
    heldout_session: Vec<PathBuf>,
    /// More training sessions, each with its own measurement frame (the marker is shared);
    /// the model is in the first recording's frame.
    #[arg(long, num_args = 1..)]
    with_session: Vec<PathBuf>,
    /// Refit the marker too on each held-out session (when the marker or its rigid-body
    /// definition may have been re-made between sessions).
    #[arg(long)]
    refit_marker: bool,
    /// Also write a self-contained HTML report (parameters with σ, correlations, residuals,
    /// outliers, held-out figures) here.
    #[arg(long, value_name = "FILE.html")]
    report: Option<PathBuf>,
}

/// How much of the model to fit (the command line's names for
/// [`rigcal_model::identification::Level`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Level {
    /// Measurement frame and marker only.
    Frames,
    /// Frames plus joint offsets.
    Offsets,
    /// Every identifiable parameter.
    Full,
}

impl From<Level> for rigcal_model::identification::Level {
    fn from(l: Level) -> Self {
        match l {
            Level::Frames => Self::Frames,
            Level::Offsets => Self::Offsets,
            Level::Full => Self::Full,
        }
    }
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    if !a.heldout_session.is_empty() || !a.with_session.is_empty() {
        return run_sessions(&a, &rig);
    }
    let rec = a.recording.read(&rig)?;
    let heldout = read_heldout(&rig, &a.heldout)?;
    let options = IdentifyOptions {
        heldout,
        ..IdentifyOptions::default()
    };
    let id = identify(&rig, &rec, a.level.into(), &options)?;
    let recording = &a.recording.recording;
    println!(
        "recording {}: {} rows, {} measurements used",
        recording.display(),
        rec.rows.len(),
        id.fit.after.n
    );
    print_identification(&id);
    if let Some(path) = &a.report {
        let source = super::report_source(&rig, &a.rig.rig, recording, rec.rows.len());
        let html = rigcal_model::report::html::identification_report(&source, &id);
        super::write_report(path, &html)?;
    }
    if a.effects.is_empty() {
        return write_model(&rig, &id, recording, &a.out.out);
    }
    let specs = a
        .effects
        .iter()
        .map(|w| EffectSpec::parse(w, rig.chain.joints().len()))
        .collect::<Result<Vec<_>, _>>()?;
    let fitted = fit_recording_effects(&rig, &rec, &id, &specs)?;
    println!("fitted with the effects, beside the geometry:");
    for e in &fitted.effects {
        println!("  {}", e.text());
    }
    print_fit_summary(&fitted.fit);
    let id = Identification {
        fit: fitted.fit,
        ..id
    };
    write_model_with_effects(&rig, &id, recording, &a.out.out, &fitted.effects)
}

/// Training on one or more sessions with a frame each, held-out sessions with their frame
/// refitted ([`rigcal_model::diagnosis::sessions`]).
fn run_sessions(a: &Args, rig: &Rig) -> Result<()> {
    let mut train = read_heldout(rig, std::slice::from_ref(&a.recording.recording))?;
    train.extend(read_heldout(rig, &a.with_session)?);
    let held = read_heldout(rig, &a.heldout_session)?;
    let per = if a.refit_marker {
        PerSession::FrameAndMarker
    } else {
        PerSession::Frame
    };
    let trained = fit_sessions(rig, &train, a.level.into())?;
    for s in &trained.sessions {
        println!(
            "training session {}: {} measurements used",
            s.name,
            s.recording.observations().len()
        );
        print_outliers(&s.outliers);
    }
    print!(
        "{}",
        super::parameter_table(trained.chain.layout(), &trained.fit, None)
    );
    print_fit_summary(&trained.fit);
    println!(
        "training RMS {:.4} mm over {} points, each session in its own frame ({} alternation round(s))",
        trained.training.rms_mm, trained.training.n, trained.rounds
    );
    println!("held-out sessions: {}", per.describe());
    for h in heldout_sessions(rig, &trained.chain, &trained.fit, &held, per)? {
        for o in &h.outliers {
            println!(
                "held-out session {}: bad row seq {} left out ({:.4} mm off the full model, {:.1} σ)",
                h.name, o.seq, o.size_mm, o.sigmas
            );
        }
        println!(
            "held-out session {} ({} points): nominal kinematics RMS {:.4} mm → fitted RMS {:.4} mm, max {:.4} mm (through the training frame, nothing refitted: {:.4} mm)",
            h.name, h.points, h.nominal_refit.rms_mm, h.refit.rms_mm, h.refit.max_mm, h.frozen.rms_mm
        );
    }
    let id = Identification {
        chain: trained.chain,
        fit: trained.fit,
        outliers: trained
            .sessions
            .into_iter()
            .flat_map(|s| s.outliers)
            .collect(),
        outlier_warning: None,
        heldout: Vec::new(),
    };
    write_model(rig, &id, &a.recording.recording, &a.out.out)
}

/// Reads the held-out recordings, each named by its path.
pub(crate) fn read_heldout(rig: &Rig, paths: &[PathBuf]) -> Result<Vec<HeldOut>> {
    paths
        .iter()
        .map(|p| {
            Ok(HeldOut {
                name: p.display().to_string(),
                recording: read_recording(rig, p)?,
            })
        })
        .collect()
}

/// Prints an identification: the outlier warning (stderr), the outliers, the parameter table,
/// the fit summary and the held-out errors.
pub(crate) fn print_identification(id: &Identification) {
    if let Some(w) = &id.outlier_warning {
        // The data (or the geometric model) are bad: say so loudly.
        eprintln!("warning: {w}; no rows removed");
    }
    print_outliers(&id.outliers);
    print!(
        "{}",
        super::parameter_table(id.chain.layout(), &id.fit, None)
    );
    print_fit_summary(&id.fit);
    for h in &id.heldout {
        println!(
            "held-out {} ({} points): nominal kinematics RMS {:.4} mm, max {:.4} mm → fitted RMS {:.4} mm, max {:.4} mm",
            h.name, h.points, h.nominal.rms_mm, h.nominal.max_mm, h.fitted.rms_mm, h.fitted.max_mm
        );
    }
}

/// Writes the identified model file (outliers and any outlier warning in it) and says where.
pub(crate) fn write_model(
    rig: &Rig,
    id: &Identification,
    recording: &Path,
    out: &Path,
) -> Result<()> {
    write_model_with_effects(rig, id, recording, out, &[])
}

/// [`write_model`] with effects fitted beside the geometry.
fn write_model_with_effects(
    rig: &Rig,
    id: &Identification,
    recording: &Path,
    out: &Path,
    effects: &[ModelEffect],
) -> Result<()> {
    let mut file = ModelFile::constant(
        rig,
        &id.fit,
        Provenance {
            recording: Some(recording.display().to_string()),
            measurements: id.fit.after.n,
            notes: id.outlier_warning.clone(),
        },
    );
    file.outliers = id.outliers.clone();
    file.effects = effects.to_vec();
    file.save(out)?;
    println!("model written to {}", out.display());
    Ok(())
}

/// Prints the outliers removed from a fit (or that there were none).
pub(crate) fn print_outliers(outliers: &[Outlier]) {
    if outliers.is_empty() {
        println!("outliers: none");
    }
    for o in outliers {
        let line = o.line.map(|l| format!(", line {l}")).unwrap_or_default();
        println!(
            "outlier removed from the fit: seq {}{line}, {:.4} mm off ({:.1} σ; residual x {:.4}, y {:.4}, z {:.4} mm)",
            o.seq, o.size_mm, o.sigmas, o.residual_mm[0], o.residual_mm[1], o.residual_mm[2]
        );
    }
}

/// Prints κ and the residual statistics of a fit.
pub(crate) fn print_fit_summary(r: &FitResult) {
    println!(
        "κ (eq. 4): {:.1}   σ̂ per coordinate: {:.4} mm   iterations: {}",
        r.kappa, r.sigma0_mm, r.iterations
    );
    println!(
        "residual before: RMS {:.4} mm, mean {:.4} mm, max {:.4} mm",
        r.before.rms_mm, r.before.mean_mm, r.before.max_mm
    );
    println!(
        "residual after:  RMS {:.4} mm, mean {:.4} mm, max {:.4} mm  (x {:.4}, y {:.4}, z {:.4})",
        r.after.rms_mm,
        r.after.mean_mm,
        r.after.max_mm,
        r.after.axis_rms_mm[0],
        r.after.axis_rms_mm[1],
        r.after.axis_rms_mm[2]
    );
}
