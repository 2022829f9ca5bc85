//! `rigcal evaluate`: position error along paths of a simulated arm without calibration and with
//! every model a model file holds (conventional, regions, learner), with CEP traces and plots.

use crate::model::ModelFile;
use crate::report::{
    evaluate_path, joint_path, plot_errors, plot_traces, spherical_path, PathResult, PathSpec,
};
use crate::world::Scenario;
use anyhow::{bail, Context, Result};
use rand::{RngExt, SeedableRng};
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
    /// Directory for the plots (SVG) and a CSV of the errors.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// The CEPs the paper traces (Figs. 6–8).
pub(crate) const TRACED: [&str; 4] = ["theta1", "d1", "a1", "alpha1"];

pub fn run(a: Args) -> Result<()> {
    anyhow::ensure!(a.points >= 2, "--points must be at least 2");
    let loaded = ModelFile::load(&a.model)?;
    let paths = build_paths(&loaded.rig, &a)?;
    evaluate(&a.model, &a.scenario, &paths, a.out.as_deref())?;
    Ok(())
}

/// Evaluates every model of the model file at `model` along `paths` in `scenario`'s truth,
/// printing a table per path and, with `out`, writing plots and a CSV there.
pub(crate) fn evaluate(
    model: &Path,
    scenario: &Path,
    paths: &[PathSpec],
    out: Option<&Path>,
) -> Result<Vec<Vec<PathResult>>> {
    let loaded = ModelFile::load(model)?;
    let rig = &loaded.rig;
    let scenario_path = scenario;
    let scenario = Scenario::load(scenario_path, None)?;
    if scenario.rig.name != rig.name {
        bail!(
            "the model is for rig `{}` but scenario {} is for `{}`",
            rig.name,
            scenario_path.display(),
            scenario.rig.name
        );
    }
    let world = scenario.world();
    let truth = |q: &[f64]| world.true_position(q);
    let mut models = loaded.file.error_models(rig, model)?;
    models.reverse();
    let refs: Vec<(String, &dyn crate::kinematics::ErrorModel)> = models
        .iter()
        .map(|(n, m)| (n.clone(), m.as_ref()))
        .collect();
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let mut all = Vec::with_capacity(paths.len());
    for path in paths {
        let results = evaluate_path(rig, path, &refs, &truth, &TRACED);
        print_results(path, &results);
        if let Some(dir) = out {
            let stem = path.name.replace([' ', '/', ':', ',', '.'], "_");
            let f = dir.join(format!("{stem}-errors.svg"));
            plot_errors(&f, &format!("position error along {}", path.name), &results)?;
            let units = ["deg", "mm", "mm", "deg"];
            let g = dir.join(format!("{stem}-ceps.svg"));
            let traced: Vec<PathResult> = results
                .iter()
                .filter(|r| !r.traces.is_empty())
                .cloned()
                .collect();
            if !traced.is_empty() {
                plot_traces(
                    &g,
                    &format!("CEPs along {}", path.name),
                    &TRACED,
                    &units,
                    &traced,
                )?;
            }
            write_csv(&dir.join(format!("{stem}.csv")), &results)?;
            println!(
                "  plots: {}{}",
                f.display(),
                if traced.is_empty() {
                    String::new()
                } else {
                    format!(" and {}", g.display())
                }
            );
        }
        all.push(results);
    }
    Ok(all)
}

/// The paper's Fig. 6 joint path.
pub(crate) fn fig6(rig: &crate::rig::Rig, points: usize) -> PathSpec {
    joint_path(
        rig,
        "Fig. 6 joint path",
        &[60.0, 60.0, -35.0],
        &[125.0, 90.0, -10.0],
        points,
    )
}

fn build_paths(rig: &crate::rig::Rig, a: &Args) -> Result<Vec<PathSpec>> {
    let mut out = Vec::new();
    for p in &a.paths {
        match p.as_str() {
            "fig6" => out.push(fig6(rig, a.points)),
            "fig7" => out.push(spherical_path(
                rig,
                "Fig. 7 spherical path",
                [640.0, 20.0, 0.0],
                [740.0, 125.0, -20.0],
                a.points,
            )?),
            "random" => {
                let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(a.seed);
                let joints = crate::kinematics::Robot::joints(&rig.chain);
                let moving = rig.moving_joints();
                for k in 0..a.random_paths {
                    let draw = |rng: &mut rand::rngs::ChaCha8Rng| -> Vec<f64> {
                        moving
                            .iter()
                            .map(|&j| {
                                let s = &joints[j];
                                let m = 0.1 * (s.max - s.min);
                                s.kind.to_file_units(rng.random_range(s.min + m..s.max - m))
                            })
                            .collect()
                    };
                    let x = draw(&mut rng);
                    let y = draw(&mut rng);
                    out.push(joint_path(
                        rig,
                        &format!("random path {}", k + 1),
                        &x,
                        &y,
                        a.points,
                    ));
                }
            }
            other => {
                let parts: Vec<&str> = other.splitn(3, ':').collect();
                if parts.len() != 3 || parts[0] != "joint" {
                    bail!(
                        "unknown path `{other}`: use fig6, fig7, random or joint:A1,A2,A3:B1,B2,B3"
                    );
                }
                let parse = |s: &str| -> Result<Vec<f64>> {
                    s.split(',')
                        .map(|v| {
                            v.trim()
                                .parse::<f64>()
                                .with_context(|| format!("`{v}` in --path {other} is not a number"))
                        })
                        .collect()
                };
                out.push(joint_path(
                    rig,
                    other,
                    &parse(parts[1])?,
                    &parse(parts[2])?,
                    a.points,
                ));
            }
        }
    }
    Ok(out)
}

fn print_results(path: &PathSpec, results: &[PathResult]) {
    println!(
        "{} ({} points): position error of the simulated arm",
        path.name,
        path.points.len()
    );
    println!("  {:<14} {:>10} {:>10} {:>10}   largest CEP jump between points: Δθ1 (deg) Δd1 (mm) Δa1 (mm) Δα1 (deg)", "model", "mean mm", "max mm", "failures");
    for r in results {
        let s = r.stats();
        let jumps = r.largest_jumps();
        let j = if jumps.is_empty() {
            String::new()
        } else {
            jumps
                .iter()
                .map(|v| format!("{v:.5}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        println!(
            "  {:<14} {:>10.4} {:>10.4} {:>10}   {}",
            r.model, s.mean_mm, s.max_mm, r.failures, j
        );
    }
}

fn write_csv(file: &std::path::Path, results: &[PathResult]) -> Result<()> {
    use std::fmt::Write;
    let mut s = String::from("point");
    for r in results {
        let _ = write!(s, ",{}_error_mm", r.model);
    }
    s.push('\n');
    let n = results.first().map_or(0, |r| r.errors.len());
    for i in 0..n {
        let _ = write!(s, "{i}");
        for r in results {
            let _ = write!(s, ",{:.6}", r.errors[i]);
        }
        s.push('\n');
    }
    std::fs::write(file, s).with_context(|| format!("cannot write {}", file.display()))
}
