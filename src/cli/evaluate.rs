//! `rigcal evaluate`: position error along paths of a simulated arm without calibration and with
//! every model a model file holds (conventional, regions, learner), with CEP traces and plots;
//! see [`rigcal_calibration::evaluate`]. With `--recording` instead of `--scenario`: every model
//! scored on a measured recording ([`rigcal_calibration::evaluate_recording`]).

use anyhow::Result;
use rigcal_calibration::{self as calibration, PathChoice, PathOptions};
use rigcal_model::model::ModelFile;
use std::path::PathBuf;

/// Arguments of `rigcal evaluate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file from `rigcal calibrate` or `rigcal identify`.
    #[arg(long)]
    model: PathBuf,
    /// Scenario whose simulated arm is the truth.
    #[arg(
        long,
        required_unless_present = "recording",
        conflicts_with = "recording"
    )]
    scenario: Option<PathBuf>,
    /// A measured recording (a held-out series of a real arm) to score every model on instead
    /// of a scenario: mean, RMS and max position error (mm), and orientation error (degrees)
    /// when the recording has orientations, for the nominal kinematics and each model.
    #[arg(long)]
    recording: Option<PathBuf>,
    /// With --recording: refit each model's measurement frame (only that) to the recording,
    /// kinematics, marker and effects kept: for a series measured with its own instrument set-up.
    #[arg(long, requires = "recording")]
    refit_frame: bool,
    /// Paths: `fig6` (joint line (60°, 60°, −35°) → (125°, 90°, −10°)), `fig7` (spherical line
    /// (640 mm, 20°, 0°) → (740 mm, 125°, −20°)), `random` (joint lines between random poses),
    /// or `joint:A1,A2,A3:B1,B2,B3` (degrees). Repeatable.
    #[arg(long = "path", default_values_t = vec!["fig6".to_string()])]
    paths: Vec<String>,
    /// Points per path, 2 to 1000000.
    #[arg(long, default_value_t = 101, value_parser = clap::value_parser!(u64).range(2..=MAX_POINTS))]
    points: u64,
    /// Number of random paths for `--path random`, 1 to 10000.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=MAX_RANDOM_PATHS))]
    random_paths: u64,
    /// Seed of the random paths.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// CEPs to trace along the paths, comma-separated (the paper's Figs. 6–8 trace these).
    #[arg(long, value_delimiter = ',', default_values_t = rigcal_paper::preset::SEED_000.traced_ceps())]
    trace_ceps: Vec<String>,
    /// Directory for the plots (SVG) and a CSV of the errors.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write the figures (per path and model: mean_mm, max_mm, failures, largest CEP
    /// jumps; the error inside an unmeasurable region) as JSON to this file.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Payload at the tool (kg), for a model with joint compliance: the compensation assumes it
    /// (the scenario's world carries what its file says).
    #[arg(long, default_value_t = 0.0)]
    payload_kg: f64,
}

/// Most points per path: the counts are refused up front rather than filling memory.
const MAX_POINTS: u64 = 1_000_000;

/// Most random paths.
const MAX_RANDOM_PATHS: u64 = 10_000;

pub fn run(a: Args) -> Result<()> {
    let Some(scenario) = a.scenario.clone() else {
        return run_recording(&a);
    };
    let choices = PathChoice::parse_all(&a.paths)?;
    let rig = ModelFile::load(&a.model)?.rig;
    let opts = PathOptions {
        points: usize::try_from(a.points)?,
        random_paths: usize::try_from(a.random_paths)?,
        seed: a.seed,
    };
    let paths = calibration::build_paths(&rig, &choices, &opts)?;
    let out = a.out.as_deref();
    let (figures, text) =
        calibration::evaluate_files(&a.model, &scenario, &paths, &a.trace_ceps, out)?;
    print!("{text}");
    let failures = calibration::path_figures::first_failures(&a.model, &paths, &figures)?;
    for f in &failures {
        eprintln!(
            "{}: {} of {} points not compensated; the first, point {} of {}: {}",
            f.model, f.failed, f.points, f.point, f.path, f.reason
        );
    }
    let none: Vec<&str> = failures
        .iter()
        .filter(|f| f.none_compensated())
        .map(|f| f.model.as_str())
        .collect();
    if !none.is_empty() {
        let _ = std::io::Write::flush(&mut std::io::stdout());
        anyhow::bail!(
            "{} compensated none of the points: there is no error to report (see the reasons above;              check the model against the scenario's rig, or refit it)",
            none.join(", ")
        );
    }
    if let Some(file) = &a.json {
        calibration::EvaluationJson::new(&a.model, &scenario, figures).write(file)?;
        println!("figures written to {}", file.display());
    }
    print!(
        "{}",
        calibration::effects_text(&a.model, &scenario, &paths, a.payload_kg)?
    );
    Ok(())
}

/// `--recording`: every model of the file scored on a measured recording.
fn run_recording(a: &Args) -> Result<()> {
    let Some(path) = &a.recording else {
        anyhow::bail!("give --scenario FILE or --recording DIR");
    };
    let loaded = ModelFile::load(&a.model)?;
    let rec = calibration::read_recording(&loaded.rig, path)?;
    let name = path.display().to_string();
    let scores = calibration::evaluate_recording::evaluate_recording(
        &loaded.rig,
        &loaded.file,
        &a.model,
        &rec,
        &name,
        a.refit_frame,
    )?;
    print!(
        "{}",
        calibration::evaluate_recording::recording_scores_text(&scores)
    );
    if let Some(file) = &a.json {
        let text = serde_json::to_string_pretty(&scores)?;
        std::fs::write(file, text + "\n")
            .map_err(|e| anyhow::anyhow!("writing {}: {e}", file.display()))?;
        println!("figures written to {}", file.display());
    }
    Ok(())
}
