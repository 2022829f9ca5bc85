//! `rigcal compare`: conventional calibration, the variable D-H model with FCMAC (seed 000) and
//! the neuro-kinematic model (seed 001) on one recording and one validation set, side by side;
//! as a table (terminal and Markdown) and SVG plots. See [`crate::calibration::compare`].

use super::calibrate::{NeuralArgs, PaperArgs};
use crate::calibration::{self, CompareInput};
use crate::identification::Observation;
use crate::kinematics::Robot;
use crate::learners::LearnerKind;
use crate::recording::Recording;
use crate::report::plot_errors;
use crate::rig::Rig;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

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
    /// Measurements simulated when no recording is given (the paper's 110 regions × 20).
    #[arg(long, default_value_t = 2200)]
    pub measurements: usize,
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
    pub paper: PaperArgs,
    #[command(flatten)]
    pub neural: NeuralArgs,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Directory for the table (`compare.md`), plots (SVG) and CSVs.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let scenario = match &a.scenario {
        Some(p) => Some(crate::world::Scenario::load(p, None)?),
        None => None,
    };
    if let Some(sc) = &scenario {
        if sc.rig.name != rig.name {
            bail!(
                "scenario {} is for rig `{}`, not `{}`",
                sc.path.display(),
                sc.rig.name,
                rig.name
            );
        }
    }
    let world = scenario.as_ref().map(|s| s.world());
    let read = |dir: &PathBuf| -> Result<Vec<Observation>> {
        Ok(super::observations(&Recording::read(
            dir,
            rig.chain.joints(),
        )?))
    };
    let simulate = |n: usize, seed: u64| -> Result<Vec<Observation>> {
        let w = world
            .as_ref()
            .context("give --scenario to simulate measurements, or --recording and --validation")?;
        Ok(calibration::simulated_observations(&rig, w, n, seed))
    };
    let (obs, label) = match &a.recording {
        Some(d) => (read(d)?, d.display().to_string()),
        None => (
            simulate(a.measurements, a.seed)?,
            format!("{} simulated random poses", a.measurements),
        ),
    };
    let val = match &a.validation {
        Some(d) => read(d)?,
        None => simulate(a.validation_points, a.seed + 1000)?,
    };
    let paths = match &world {
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
    let mut opts = a.paper.options(a.accuracy_mm, LearnerKind::Fcmac, a.seed);
    opts.neural = a.neural.options(a.measurements);
    let c = calibration::compare(&rig, &input, &opts)?;
    println!(
        "== variable D-H model (seed 000), offline division at {} mm",
        a.accuracy_mm
    );
    print!("{}", c.variable.text());
    println!("== neuro-kinematic model (seed 001)");
    print!("{}", c.neural.text());
    let md = c.markdown();
    println!("\n{md}");
    println!("validation: {} poses; apparent = against the measurements, actual = against the simulated truth", c.validation_points);
    if let Some(dir) = &a.out {
        write_files(dir, &md, &c.paths)?;
    }
    Ok(())
}

/// The paper's paths named on the command line.
fn paper_paths(rig: &Rig, names: &[String]) -> Result<Vec<(String, crate::report::PathSpec)>> {
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

/// Writes the table and one plot per path into `dir`.
fn write_files(
    dir: &Path,
    md: &str,
    paths: &[(String, Vec<crate::report::PathResult>)],
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let f = dir.join("compare.md");
    std::fs::write(&f, md).with_context(|| format!("cannot write {}", f.display()))?;
    for (p, res) in paths {
        let svg = dir.join(format!("compare-{p}.svg"));
        plot_errors(
            &svg,
            &format!("position error along {p}: three calibrations"),
            res,
        )?;
        println!("plot: {}", svg.display());
    }
    println!("table: {}", f.display());
    Ok(())
}
