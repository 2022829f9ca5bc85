//! `rigcal evaluate`: position error along paths of a simulated arm without calibration and with
//! every model a model file holds (conventional, regions, learner), with CEP traces and plots;
//! see [`rigcal_calibration::evaluate`].

use anyhow::{Context, Result};
use rigcal_calibration::{self as calibration, PathChoice, PathFigures, PathOptions, TracedCep};
use rigcal_model::model::ModelFile;
use rigcal_model::report::PathSpec;
use rigcal_sim::world::Scenario;
use std::path::{Path, PathBuf};

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
    #[arg(long, value_delimiter = ',', default_values_t = calibration::PAPER_TRACED_CEPS.map(String::from))]
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
    let choices = a
        .paths
        .iter()
        .map(|p| PathChoice::parse(p))
        .collect::<Result<Vec<_>, _>>()?;
    let rig = ModelFile::load(&a.model)?.rig;
    let paths = calibration::build_paths(
        &rig,
        &choices,
        &PathOptions {
            points: a.points,
            random_paths: a.random_paths,
            seed: a.seed,
        },
    )?;
    let figures = evaluate(
        &a.model,
        &a.scenario,
        &paths,
        &a.trace_ceps,
        a.out.as_deref(),
    )?;
    if let Some(file) = &a.json {
        let json = calibration::EvaluationJson {
            format: "rigcal-evaluation",
            model: a.model.display().to_string(),
            scenario: a.scenario.display().to_string(),
            paths: figures,
        };
        std::fs::write(file, serde_json::to_string_pretty(&json)? + "\n")
            .with_context(|| format!("writing {}", file.display()))?;
        println!("figures written to {}", file.display());
    }
    evaluate_effects(&a.model, &a.scenario, &paths, a.payload_kg)
}

/// For a model with effects: each path's targets compensated in order with the geometry alone
/// and with the effects, and the true error of the moves in the scenario's world
/// ([`rigcal_sim::twin::hybrid::compensated_errors`]).
fn evaluate_effects(
    model: &Path,
    scenario: &Path,
    paths: &[PathSpec],
    payload_kg: f64,
) -> Result<()> {
    let loaded = ModelFile::load(model)?;
    if loaded.file.effects.is_empty() {
        return Ok(());
    }
    let world = Scenario::load(scenario, None)?.world();
    let opts = rigcal_model::model::hybrid::HybridOptions {
        payload_kg,
        ..Default::default()
    };
    for path in paths {
        println!(
            "{}: true error of the compensated moves, in the path's order (backlash from it)",
            path.name
        );
        let (geometry, effects) =
            rigcal_sim::twin::hybrid::geometry_vs_effects(&loaded, &world, &path.points, &opts)
                .map_err(|e| {
                    anyhow::Error::new(e.source).context(format!("path point {}", e.line))
                })?;
        for r in [geometry, effects] {
            println!(
                "  {:<14} mean {:.4} mm, max {:.4} mm",
                r.model,
                r.mean_mm(),
                r.max_mm()
            );
        }
    }
    Ok(())
}

/// Evaluates every model of the model file at `model` along `paths` in `scenario`'s truth,
/// tracing `trace`, printing a table per path (and the error inside an unmeasurable region)
/// and, with `out`, writing plots and a CSV there; the figures per path.
pub(crate) fn evaluate(
    model: &Path,
    scenario: &Path,
    paths: &[PathSpec],
    trace: &[String],
    out: Option<&Path>,
) -> Result<Vec<PathFigures>> {
    let loaded = ModelFile::load(model)?;
    let trace: Vec<TracedCep> = calibration::traced_ceps(&loaded.rig, trace)?;
    let scenario = Scenario::load(scenario, None)?;
    let all = calibration::evaluate(&loaded, model, &scenario, paths, &trace)?;
    let mut figures = Vec::with_capacity(paths.len());
    for (path, results) in paths.iter().zip(&all) {
        let f = PathFigures::of(&loaded, path, results, &trace);
        print!(
            "{}{}",
            calibration::path_table(path, results, &trace),
            f.inside_text()
        );
        if let Some(dir) = out {
            let files = calibration::write_path_files(dir, path, results, &trace)?;
            print!("{}", files.text());
        }
        figures.push(f);
    }
    Ok(figures)
}
