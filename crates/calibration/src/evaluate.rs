//! Every model of a model file along paths of a scenario's simulated arm: position error
//! without calibration and with each model, traced CEPs and their largest jumps (seed 000
//! Figs. 6–8), tables, plots and a CSV.

use super::CalibrationError;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::ErrorModel;
use rigcal_core::rig::Rig;
use rigcal_model::model::LoadedModel;
use rigcal_model::report::{
    evaluate_path, joint_path, plot_errors, plot_traces, spherical_path, PathError, PathResult,
    PathSpec,
};
use rigcal_sim::world::Scenario;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A path to evaluate along, as named on a command line.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum PathChoice {
    /// The paper's Fig. 6 joint line (60°, 60°, −35°) → (125°, 90°, −10°).
    Fig6,
    /// The paper's Fig. 7 spherical line (640 mm, 20°, 0°) → (740 mm, 125°, −20°).
    Fig7,
    /// Joint lines between random poses ([`PathOptions::random_paths`] of them).
    Random,
    /// A joint line between two sets of the moving joints' values (deg or mm).
    Joint {
        /// Its name in reports (the words it was given as).
        name: String,
        /// Start.
        from: Vec<f64>,
        /// End.
        to: Vec<f64>,
    },
}

impl PathChoice {
    /// Each of `words` parsed ([`PathChoice::parse`]), in order.
    pub fn parse_all(words: &[String]) -> Result<Vec<Self>, CalibrationError> {
        words.iter().map(|w| PathChoice::parse(w)).collect()
    }

    /// `fig6`, `fig7`, `random` or `joint:A1,A2,A3:B1,B2,B3` (degrees or mm).
    pub fn parse(words: &str) -> Result<Self, CalibrationError> {
        match words {
            "fig6" => return Ok(PathChoice::Fig6),
            "fig7" => return Ok(PathChoice::Fig7),
            "random" => return Ok(PathChoice::Random),
            _ => {}
        }
        let parts: Vec<&str> = words.splitn(3, ':').collect();
        if parts.len() != 3 || parts[0] != "joint" {
            return Err(CalibrationError::PathWords(format!(
                "unknown path `{words}`: use fig6, fig7, random or joint:A1,A2,A3:B1,B2,B3"
            )));
        }
        let numbers = |s: &str| -> Result<Vec<f64>, CalibrationError> {
            s.split(',')
                .map(|v| {
                    v.trim().parse::<f64>().map_err(|_| {
                        CalibrationError::PathWords(format!(
                            "`{v}` in --path {words} is not a number"
                        ))
                    })
                })
                .collect()
        };
        Ok(PathChoice::Joint {
            name: words.to_string(),
            from: numbers(parts[1])?,
            to: numbers(parts[2])?,
        })
    }
}

/// How paths are drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct PathOptions {
    /// Points per path.
    pub points: usize,
    /// Number of random paths for [`PathChoice::Random`].
    pub random_paths: usize,
    /// Seed of the random paths.
    pub seed: u64,
}

impl Default for PathOptions {
    fn default() -> Self {
        Self {
            points: 101,
            random_paths: 5,
            seed: 7,
        }
    }
}

/// The paper's Fig. 6 joint path.
pub fn fig6_path(rig: &Rig, points: usize) -> PathSpec {
    joint_path(
        rig,
        "Fig. 6 joint path",
        &[60.0, 60.0, -35.0],
        &[125.0, 90.0, -10.0],
        points,
    )
}

/// The paper's Fig. 7 spherical path.
pub fn fig7_path(rig: &Rig, points: usize) -> Result<PathSpec, PathError> {
    spherical_path(
        rig,
        "Fig. 7 spherical path",
        [640.0, 20.0, 0.0],
        [740.0, 125.0, -20.0],
        points,
    )
}

/// The paths of `choices` for `rig`, in order (a random choice gives several).
pub fn build_paths(
    rig: &Rig,
    choices: &[PathChoice],
    opts: &PathOptions,
) -> Result<Vec<PathSpec>, CalibrationError> {
    if opts.points < 2 {
        return Err(CalibrationError::Option {
            option: "--points",
            reason: "must be at least 2".into(),
        });
    }
    let mut out = Vec::new();
    for choice in choices {
        match choice {
            PathChoice::Fig6 => out.push(fig6_path(rig, opts.points)),
            PathChoice::Fig7 => out.push(fig7_path(rig, opts.points)?),
            PathChoice::Random => out.extend(random_paths(rig, opts)),
            PathChoice::Joint { name, from, to } => {
                out.push(joint_path(rig, name, from, to, opts.points))
            }
        }
    }
    Ok(out)
}

/// Joint lines between random poses, a tenth of each joint's range clear of its limits.
fn random_paths(rig: &Rig, opts: &PathOptions) -> Vec<PathSpec> {
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(opts.seed);
    let joints = rigcal_core::kinematics::Robot::joints(&rig.chain);
    let moving = rig.moving_joints();
    let mut draw = || -> Vec<f64> {
        moving
            .iter()
            .map(|&j| {
                let s = &joints[j];
                let m = 0.1 * (s.max - s.min);
                s.kind.to_file_units(rng.random_range(s.min + m..s.max - m))
            })
            .collect()
    };
    (0..opts.random_paths)
        .map(|k| {
            let (x, y) = (draw(), draw());
            joint_path(rig, &format!("random path {}", k + 1), &x, &y, opts.points)
        })
        .collect()
}

/// A CEP traced along paths.
#[derive(Debug, Clone, PartialEq)]
pub struct TracedCep {
    /// Its file name (`theta1`).
    pub name: String,
    /// Its symbol (`Δθ1`).
    pub symbol: String,
    /// Its file unit (`deg`, `mm`).
    pub unit: &'static str,
}

/// The CEPs of `names` in `rig`; a name the rig does not have is an error.
pub fn traced_ceps(rig: &Rig, names: &[String]) -> Result<Vec<TracedCep>, CalibrationError> {
    let layout = rigcal_core::kinematics::Robot::layout(&rig.chain);
    names
        .iter()
        .map(|n| {
            let id = layout
                .find(n)
                .ok_or_else(|| CalibrationError::UnknownCep(n.clone()))?;
            Ok(TracedCep {
                name: n.clone(),
                symbol: layout.symbol(id),
                unit: id.kind.unit(),
            })
        })
        .collect()
}

/// Evaluates every model of `model` (read from `model_path`) along `paths` in `scenario`'s
/// truth, uncalibrated first, tracing `trace`: one list of results per path.
pub fn evaluate(
    model: &LoadedModel,
    model_path: &Path,
    scenario: &Scenario,
    paths: &[PathSpec],
    trace: &[TracedCep],
) -> Result<Vec<Vec<PathResult>>, CalibrationError> {
    let rig = &model.rig;
    if scenario.rig.name != rig.name {
        return Err(CalibrationError::ModelScenarioRig {
            model_rig: rig.name.clone(),
            scenario: scenario.path.clone(),
            scenario_rig: scenario.rig.name.clone(),
        });
    }
    let world = scenario.world();
    let truth = |q: &[f64]| world.true_position(q);
    let mut models = model.file.error_models(rig, model_path)?;
    // Conventional first, the model compensation uses last: simplest to best.
    models.reverse();
    let refs: Vec<(String, &dyn ErrorModel)> = models
        .iter()
        .map(|(n, m)| (n.clone(), m.as_ref()))
        .collect();
    let names: Vec<&str> = trace.iter().map(|t| t.name.as_str()).collect();
    Ok(paths
        .iter()
        .map(|path| evaluate_path(rig, path, &refs, &truth, &names))
        .collect())
}

/// For a model file with effects (`rigcal identify --effects`), each path's targets
/// compensated in order with the geometry alone and with the effects, and the true error of
/// the moves in the scenario file's world ([`rigcal_sim::twin::hybrid::geometry_vs_effects`]),
/// `payload_kg` at the tool: the text `rigcal evaluate` prints (empty for a model without
/// effects).
pub fn effects_text(
    model: &Path,
    scenario: &Path,
    paths: &[PathSpec],
    payload_kg: f64,
) -> Result<String, CalibrationError> {
    let loaded = rigcal_model::model::ModelFile::load(model)?;
    let mut s = String::new();
    if loaded.file.effects.is_empty() {
        return Ok(s);
    }
    let world = Scenario::load(scenario, None)?.world();
    let opts = rigcal_model::model::hybrid::HybridOptions {
        payload_kg,
        ..Default::default()
    };
    for path in paths {
        let _ = writeln!(
            s,
            "{}: true error of the compensated moves, in the path's order (backlash from it)",
            path.name
        );
        let (geometry, effects) =
            rigcal_sim::twin::hybrid::geometry_vs_effects(&loaded, &world, &path.points, &opts)
                .map_err(|e| CalibrationError::PathPoint {
                    line: e.line,
                    source: e.source,
                })?;
        for r in [geometry, effects] {
            let _ = writeln!(
                s,
                "  {:<14} mean {:.4} mm, max {:.4} mm",
                r.model,
                r.mean_mm(),
                r.max_mm()
            );
        }
    }
    Ok(s)
}

/// The table `rigcal evaluate` prints for a path.
pub fn path_table(path: &PathSpec, results: &[PathResult], trace: &[TracedCep]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} ({} points): position error of the simulated arm",
        path.name,
        path.points.len()
    );
    let traced: Vec<String> = trace
        .iter()
        .map(|t| format!("{} ({})", t.symbol, t.unit))
        .collect();
    let _ = writeln!(
        s,
        "  {:<14} {:>10} {:>10} {:>10}   largest CEP jump between points: {}",
        "model",
        "mean mm",
        "max mm",
        "failures",
        traced.join(" ")
    );
    for r in results {
        let st = r.stats();
        let jumps: Vec<String> = r
            .largest_jumps()
            .iter()
            .map(|v| format!("{v:.5}"))
            .collect();
        // A mean over no compensated point is no figure: print none rather than 0.
        let (mean, max) = if st.n == 0 {
            ("—".to_string(), "—".to_string())
        } else {
            (format!("{:.4}", st.mean_mm), format!("{:.4}", st.max_mm))
        };
        let _ = writeln!(
            s,
            "  {:<14} {:>10} {:>10} {:>10}   {}",
            r.model,
            mean,
            max,
            r.failures,
            jumps.join(" ")
        );
    }
    for r in results.iter().filter(|r| r.failures > 0) {
        let n = r.errors.len();
        let _ = if r.failures >= n {
            writeln!(
                s,
                "  {}: none of the {n} points could be compensated: no mean or max",
                r.model
            )
        } else {
            writeln!(
                s,
                "  {}: {} of {n} points could not be compensated; its mean and max are over the other {}",
                r.model,
                r.failures,
                n - r.failures
            )
        };
    }
    s
}

/// The files [`write_path_files`] wrote for a path.
#[derive(Debug, Clone, PartialEq)]
pub struct PathFiles {
    /// Position error along the path (SVG).
    pub errors: PathBuf,
    /// Traced CEPs (SVG), when a model traced any.
    pub ceps: Option<PathBuf>,
    /// The errors per point (CSV).
    pub csv: PathBuf,
}

impl PathFiles {
    /// The line `rigcal evaluate` prints for them.
    pub fn text(&self) -> String {
        match &self.ceps {
            Some(g) => format!("  plots: {} and {}\n", self.errors.display(), g.display()),
            None => format!("  plots: {}\n", self.errors.display()),
        }
    }
}

/// A path's name as a file stem a shell need not quote: lower case, letters and digits, one
/// `-` for each run of anything else ("Fig. 6 joint path" → `fig-6-joint-path`).
pub fn file_stem(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.is_empty() && !out.ends_with('-') {
            out.push('-');
        }
    }
    let out = out.trim_end_matches('-').to_string();
    if out.is_empty() {
        "path".into()
    } else {
        out
    }
}

/// Writes the plots and the CSV of one path's results into `dir` (created if needed), named
/// after the path.
pub fn write_path_files(
    dir: &Path,
    path: &PathSpec,
    results: &[PathResult],
    trace: &[TracedCep],
) -> Result<PathFiles, CalibrationError> {
    std::fs::create_dir_all(dir).map_err(|source| CalibrationError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let stem = file_stem(&path.name);
    let errors = dir.join(format!("{stem}-errors.svg"));
    plot_errors(
        &errors,
        &format!("position error along {}", path.name),
        results,
    )?;
    let traced: Vec<PathResult> = results
        .iter()
        .filter(|r| !r.traces.is_empty())
        .cloned()
        .collect();
    let ceps = if traced.is_empty() {
        None
    } else {
        let g = dir.join(format!("{stem}-ceps.svg"));
        let names: Vec<&str> = trace.iter().map(|t| t.name.as_str()).collect();
        let units: Vec<&str> = trace.iter().map(|t| t.unit).collect();
        plot_traces(
            &g,
            &format!("CEPs along {}", path.name),
            &names,
            &units,
            &traced,
        )?;
        Some(g)
    };
    let csv = dir.join(format!("{stem}.csv"));
    std::fs::write(&csv, errors_csv(results)).map_err(|source| CalibrationError::Io {
        path: csv.clone(),
        source,
    })?;
    Ok(PathFiles { errors, ceps, csv })
}

/// The errors per point and model (CSV text).
fn errors_csv(results: &[PathResult]) -> String {
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
    s
}

#[cfg(test)]
mod stem_tests {
    use super::file_stem;

    #[test]
    fn path_names_become_stems_a_shell_need_not_quote() {
        assert_eq!(file_stem("Fig. 6 joint path"), "fig-6-joint-path");
        assert_eq!(
            file_stem("straight Cartesian path (-300, 350, 30) → (350, 520, 480) mm"),
            "straight-cartesian-path-300-350-30-350-520-480-mm"
        );
        assert_eq!(file_stem("  ./ "), "path");
    }
}
