//! `rigcal compare`: conventional calibration, the variable D-H model with FCMAC (seed 000) and
//! the neuro-kinematic model (seed 001) on one recording and one validation set, side by side;
//! as a table (terminal and Markdown) and SVG plots. See [`rigcal_calibration::compare`].

use anyhow::{bail, Result};
use rigcal_calibration::{self as calibration, CalibrationOptions, CompareInput};
use rigcal_core::rig::Rig;
use rigcal_model::report::PathSpec;
use rigcal_sim::world::Scenario;
use std::path::PathBuf;

/// Arguments of `rigcal compare`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Rig file (TOML).
    #[arg(long)]
    pub rig: PathBuf,
    /// The simulated truth: simulates the recording and validation set when they are not given,
    /// and gives actual errors and the paths.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// The recording every method is fitted on.
    #[arg(long)]
    pub recording: Option<PathBuf>,
    /// A validation recording (otherwise random poses of the scenario).
    #[arg(long)]
    pub validation: Option<PathBuf>,
    /// Validation poses simulated when no validation recording is given.
    #[arg(long, default_value_t = 1000)]
    pub validation_points: usize,
    /// Demanded accuracy of the variable D-H model's division (mm).
    #[arg(long, default_value_t = 0.02)]
    pub accuracy_mm: f64,
    /// Paths (with a scenario): `fig6`, `fig7`. Repeatable.
    #[arg(long = "path", default_values_t = vec!["fig6".to_string(), "fig7".to_string()])]
    pub paths: Vec<String>,
    #[command(flatten)]
    pub settings: CalibrationOptions,
    /// Directory for the table (`compare.md`), plots (SVG) and CSVs.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let scenario = a
        .scenario
        .as_deref()
        .map(|p| Scenario::load(p, None))
        .transpose()?;
    if let Some(sc) = &scenario {
        calibration::check_scenario_rig(&rig, sc)?;
    }
    let world = scenario.as_ref().map(|s| s.world());
    let (n, seed) = (a.settings.neural.measurements, a.settings.seed);
    let (obs, label) =
        calibration::measurements(&rig, a.recording.as_deref(), world.as_ref(), n, seed)?;
    let val = a.validation.as_deref();
    let (val, _) =
        calibration::measurements(&rig, val, world.as_ref(), a.validation_points, seed + 1000)?;
    let paths = match world {
        Some(_) => paper_paths(&rig, &a.paths)?,
        None => Vec::new(),
    };
    let input = CompareInput {
        observations: &obs,
        label,
        validation: &val,
        world: world.as_ref(),
        paths: &paths,
    };
    let opts = CalibrationOptions {
        accuracy_mm: a.accuracy_mm,
        ..a.settings.clone()
    };
    let c = calibration::compare(&rig, &input, &opts)?;
    print!("{}", c.text(a.accuracy_mm));
    if let Some(dir) = &a.out {
        for file in c.write_files(dir)? {
            let kind = if file.extension().is_some_and(|e| e == "md") {
                "table"
            } else {
                "plot"
            };
            println!("{kind}: {}", file.display());
        }
    }
    Ok(())
}

/// The paper's paths named on the command line.
fn paper_paths(rig: &Rig, names: &[String]) -> Result<Vec<(String, PathSpec)>> {
    names
        .iter()
        .map(|p| {
            let spec = match p.as_str() {
                "fig6" => calibration::fig6_path(rig, 101),
                "fig7" => calibration::fig7_path(rig, 101)?,
                other => bail!("unknown path `{other}`: use fig6 or fig7"),
            };
            Ok((p.clone(), spec))
        })
        .collect()
}
