//! `rigcal evaluate`: position error along paths of a simulated arm without calibration and with
//! every model a model file holds (conventional, regions, learner), with CEP traces and plots;
//! see [`rigcal_calibration::evaluate`].

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
    #[arg(long)]
    scenario: PathBuf,
    /// Paths: `fig6` (joint line (60°, 60°, −35°) → (125°, 90°, −10°)), `fig7` (spherical line
    /// (640 mm, 20°, 0°) → (740 mm, 125°, −20°)), `random` (joint lines between random poses),
    /// or `joint:A1,A2,A3:B1,B2,B3` (degrees). Repeatable.
    #[arg(long = "path", default_values_t = vec!["fig6".to_string()])]
    paths: Vec<String>,
    /// Points per path.
    #[arg(long, default_value_t = 101)]
    points: usize,
    /// Number of random paths for `--path random`.
    #[arg(long, default_value_t = 5)]
    random_paths: usize,
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

pub fn run(a: Args) -> Result<()> {
    let choices = PathChoice::parse_all(&a.paths)?;
    let rig = ModelFile::load(&a.model)?.rig;
    let opts = PathOptions {
        points: a.points,
        random_paths: a.random_paths,
        seed: a.seed,
    };
    let paths = calibration::build_paths(&rig, &choices, &opts)?;
    let out = a.out.as_deref();
    let (figures, text) =
        calibration::evaluate_files(&a.model, &a.scenario, &paths, &a.trace_ceps, out)?;
    print!("{text}");
    if let Some(file) = &a.json {
        calibration::EvaluationJson::new(&a.model, &a.scenario, figures).write(file)?;
        println!("figures written to {}", file.display());
    }
    print!(
        "{}",
        calibration::effects_text(&a.model, &a.scenario, &paths, a.payload_kg)?
    );
    Ok(())
}
