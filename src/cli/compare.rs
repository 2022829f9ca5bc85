//! `rigcal compare`: conventional calibration, the variable D-H model with FCMAC (seed 000) and
//! the neuro-kinematic model (seed 001) on one recording and one validation set, side by side;
//! as a table (terminal and Markdown) and SVG plots. See [`rigcal_calibration::compare`].

use anyhow::Result;
use rigcal_calibration::{self as calibration, CalibrationOptions, CompareFiles};
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
    pub settings: super::options::CalibrationArgs,
    /// Directory for the table (`compare.md`), plots (SVG) and CSVs.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let rig = rigcal_devices::config::load_rig(&a.rig)?;
    let files = CompareFiles {
        scenario: a.scenario.as_deref(),
        recording: a.recording.as_deref(),
        validation: a.validation.as_deref(),
        validation_points: a.validation_points,
        paths: &a.paths,
    };
    let opts = CalibrationOptions {
        accuracy_mm: a.accuracy_mm,
        ..a.settings.clone().into()
    };
    let c = calibration::compare_files(&rig, &files, &opts)?;
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
