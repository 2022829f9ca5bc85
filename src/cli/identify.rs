//! `rigcal identify`: conventional calibration of a recording ([`rigcal_model::identification::identify`]).

use super::{OutArg, RecordingArg, RigArg};
use anyhow::Result;
use rigcal_calibration::conventional::{self, identification_text};
use rigcal_calibration::read_heldout;
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::sessions::PerSession;
use rigcal_model::identification::Level as IdentificationLevel;
use rigcal_model::identification::{identify, pose, Identification, IdentifyOptions};
use rigcal_model::model::effects::ModelEffect;
use std::path::{Path, PathBuf};

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
    /// fitted model on each, and the orientation error (degrees) when orientations were fitted.
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
    /// Fit positions only, even when the recording has orientations (a 6-DoF probe's). By
    /// default such a recording is fitted with its orientations as well: position and
    /// orientation rows weighted by their stated σ (or one σ per block estimated from the
    /// residuals), the marker frame a full pose.
    #[arg(long)]
    position_only: bool,
    /// With orientations: weight every block by one σ estimated from the residuals, even where
    /// the rows state their σ (when the stated σ leave out the model's own error, say).
    #[arg(long, conflicts_with = "position_only")]
    estimate_weights: bool,
    /// Also write a self-contained HTML report (parameters with σ, correlations, residuals,
    /// outliers, held-out figures) here.
    #[arg(long, value_name = "FILE.html")]
    report: Option<PathBuf>,
}

super::options::value_enum! {
    /// How much of the model to fit (the command line's names for
    /// [`rigcal_model::identification::Level`]).
    Level => IdentificationLevel {
        /// Measurement frame and marker only.
        Frames,
        /// Frames plus joint offsets.
        Offsets,
        /// Every identifiable parameter.
        Full,
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
        ..rigcal_model::diagnosis::outliers::identify_options()
    };
    let mut id = identify(&rig, &rec, a.level.into(), &options)?;
    let recording = &a.recording.recording;
    let pose = (!a.position_only && pose::has_orientation(&rec))
        .then(|| {
            let opts = pose::PoseOptions {
                weights: if a.estimate_weights {
                    pose::WeightChoice::Estimated
                } else {
                    pose::WeightChoice::StatedWhereGiven
                },
                ..Default::default()
            };
            pose::refit_with_orientation(
                &rig,
                &rec,
                &mut id,
                a.level.into(),
                &options.heldout,
                &opts,
            )
        })
        .transpose()?;
    println!(
        "recording {}: {} rows, {} measurements used",
        recording.display(),
        rec.rows.len(),
        id.fit.after.n
    );
    if let Some(w) = &id.outlier_warning {
        // The data (or the geometric model) are bad: say so loudly.
        eprintln!("warning: {w}; no rows removed");
    }
    print!("{}", identification_text(&id));
    match &pose {
        Some((fit, held)) => {
            print!("{}", pose::pose_fit_text(fit));
            print!("{}", pose::pose_heldout_text(held));
        }
        None => {
            let kept = |i: usize| !id.outliers.iter().any(|o| o.index == i);
            if let Some((_, o)) =
                pose::orientation_of_position_fit(&id.chain, &id.fit.params, &rec, kept)
            {
                println!(
                    "orientation residual (°, not fitted: --position-only; marker rotation in closed form): mean {:.4}  RMS {:.4}  max {:.4} over {} rows",
                    o.mean_deg, o.rms_deg, o.max_deg, o.n
                );
            }
        }
    }
    if let Some(path) = &a.report {
        let source =
            rigcal_model::report::html::Source::of(&rig, &a.rig.rig, recording, rec.rows.len());
        let html = rigcal_model::report::html::identification_report(&source, &id);
        super::write_report(path, &html)?;
    }
    if a.effects.is_empty() {
        return write_model(&rig, &id, recording, &a.out.out, &[]);
    }
    // The geometry fitted without the effects stands alone (a URDF carries no effects).
    let standalone = rigcal_model::model::entries(&rig, &id.fit);
    let (id, effects, text) = conventional::identify_effects(&rig, &rec, id, &a.effects)?;
    print!("{text}");
    for h in &options.heldout {
        // The held-out figure above is the geometry's alone: this one is the model's.
        let errors = rigcal_model::model::effects::errors_with_effects(
            &id.chain,
            &id.fit.params,
            &rig.masses_with_payload(),
            &effects,
            &h.recording,
        );
        let s = rigcal_model::identification::ResidualStats::of(&errors);
        println!(
            "held out {} with the effects: mean {:.4}  RMS {:.4}  max {:.4} mm over {} points",
            h.name, s.mean_mm, s.rms_mm, s.max_mm, s.n
        );
    }
    rigcal_model::identification::check_fit(&rig, &id.chain, &id.fit)?;
    let mut file = conventional::model_file(&rig, &id, recording, &effects);
    file.standalone_parameters = standalone;
    file.save(&a.out.out)?;
    println!(
        "model written to {} (with the geometry fitted without the effects, for `export urdf`)",
        a.out.out.display()
    );
    Ok(())
}

/// Training on one or more sessions with a frame each, held-out sessions with their frame
/// refitted ([`conventional::identify_sessions`]).
fn run_sessions(a: &Args, rig: &Rig) -> Result<()> {
    let mut train = read_heldout(rig, std::slice::from_ref(&a.recording.recording))?;
    train.extend(read_heldout(rig, &a.with_session)?);
    let held = read_heldout(rig, &a.heldout_session)?;
    let per = if a.refit_marker {
        PerSession::FrameAndMarker
    } else {
        PerSession::Frame
    };
    let (id, text) = conventional::identify_sessions(rig, &train, &held, a.level.into(), per)?;
    print!("{text}");
    write_model(rig, &id, &a.recording.recording, &a.out.out, &[])
}

/// Writes the identified model file (with `effects` fitted beside the geometry) and says where.
fn write_model(
    rig: &Rig,
    id: &Identification,
    recording: &Path,
    out: &Path,
    effects: &[ModelEffect],
) -> Result<()> {
    // Every path to a model file (one recording, sessions, effects) passes the fit's check.
    rigcal_model::identification::check_fit(rig, &id.chain, &id.fit)?;
    conventional::model_file(rig, id, recording, effects).save(out)?;
    println!("model written to {}", out.display());
    Ok(())
}
