//! Conventional calibration, the variable D-H model with FCMAC (seed 000) and the
//! neuro-kinematic model (seed 001) fitted on one set of measurements and checked on one
//! validation set, side by side: mean/max error on the validation set (apparent against the
//! measurements, actual against the simulated truth when there is one), along paths,
//! measurements used and training time.

use super::evaluate::{fig6_path, fig7_path};
use super::{
    calibrate, check_scenario_rig, Calibrated, CalibrationError, CalibrationOptions, Source,
};
use rand::SeedableRng;
use rigcal_core::kinematics::{ErrorModel, ErrorParams, Robot};
use rigcal_core::rig::Rig;
use rigcal_model::identification::{fit, random_poses, FitOptions, Observation};
use rigcal_model::learners::LearnerKind;
use rigcal_model::model::ModelBody;
use rigcal_model::report::{evaluate_path, plot_errors, PathResult, PathSpec};
use rigcal_sim::world::{Scenario, World};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What the methods are fitted and checked on.
pub struct CompareInput<'a> {
    /// The measurements every method is fitted on.
    pub observations: &'a [Observation],
    /// What they are, for the model files' provenance.
    pub label: String,
    /// The validation measurements.
    pub validation: &'a [Observation],
    /// The simulated truth, when there is one: actual errors and the paths.
    pub world: Option<&'a World>,
    /// Paths to evaluate along (with a world), each with its short name (`fig6`).
    pub paths: &'a [(String, PathSpec)],
}

/// What `rigcal compare` is given besides the rig and the options: files and counts.
#[derive(Debug, Clone, Copy)]
pub struct CompareFiles<'a> {
    /// The simulated truth (a scenario file): simulates the recording and validation set when
    /// they are not given, and gives actual errors and the paths.
    pub scenario: Option<&'a Path>,
    /// The recording every method is fitted on (else `opts.neural.measurements` random poses
    /// of the scenario).
    pub recording: Option<&'a Path>,
    /// A validation recording (else random poses of the scenario).
    pub validation: Option<&'a Path>,
    /// Validation poses simulated when no validation recording is given.
    pub validation_points: usize,
    /// The paper's paths to evaluate along with a scenario: `fig6`, `fig7`.
    pub paths: &'a [String],
}

/// [`compare`] on the files `rigcal compare` takes: the scenario loaded and checked against
/// the rig, the measurements read or simulated (the validation set with `opts.seed + 1000`),
/// the paths made.
pub fn compare_files(
    rig: &Rig,
    files: &CompareFiles<'_>,
    opts: &CalibrationOptions,
) -> Result<Comparison, CalibrationError> {
    let scenario = files
        .scenario
        .map(|p| Scenario::load(p, None))
        .transpose()?;
    if let Some(sc) = &scenario {
        check_scenario_rig(rig, sc)?;
    }
    let world = scenario.as_ref().map(|s| s.world());
    let (n, seed) = (opts.neural.measurements, opts.seed);
    let (obs, label) = measurements(rig, files.recording, world.as_ref(), n, seed)?;
    let (val, _) = measurements(
        rig,
        files.validation,
        world.as_ref(),
        files.validation_points,
        seed + 1000,
    )?;
    let paths = match world {
        Some(_) => paper_paths(rig, files.paths)?,
        None => Vec::new(),
    };
    let input = CompareInput {
        observations: &obs,
        label,
        validation: &val,
        world: world.as_ref(),
        paths: &paths,
    };
    compare(rig, &input, opts)
}

/// The paper's paths by name (`fig6`, `fig7`), 101 points each.
pub fn paper_paths(
    rig: &Rig,
    names: &[String],
) -> Result<Vec<(String, PathSpec)>, CalibrationError> {
    names
        .iter()
        .map(|p| {
            let spec = match p.as_str() {
                "fig6" => fig6_path(rig, 101),
                "fig7" => fig7_path(rig, 101)?,
                other => {
                    return Err(CalibrationError::PathWords(format!(
                        "unknown path `{other}`: use fig6 or fig7"
                    )))
                }
            };
            Ok((p.clone(), spec))
        })
        .collect()
}

/// One method's row of the comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodRow {
    /// `uncalibrated`, `conventional`, `variable D-H: fcmac`, …
    pub name: String,
    /// Measurements it was fitted on.
    pub measurements: usize,
    /// Time to fit it (s).
    pub train_s: f64,
    /// Validation error against the measurements: (mean, max) mm.
    pub apparent_mm: (f64, f64),
    /// Validation error against the simulated truth: (mean, max) mm.
    pub actual_mm: Option<(f64, f64)>,
}

/// The comparison.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// The variable D-H model (seed 000).
    pub variable: Calibrated,
    /// The neural model (seed 001).
    pub neural: Calibrated,
    /// One row per method, uncalibrated first.
    pub methods: Vec<MethodRow>,
    /// Per path (short name): every method's results, uncalibrated first.
    pub paths: Vec<(String, Vec<PathResult>)>,
    /// Validation poses.
    pub validation_points: usize,
}

/// Measurements of `world` at `n` random poses of `rig` drawn from `seed`.
pub fn simulated_observations(rig: &Rig, world: &World, n: usize, seed: u64) -> Vec<Observation> {
    let poses = random_poses(
        rig.chain.joints(),
        rig.held(),
        n,
        &mut rand::rngs::ChaCha8Rng::seed_from_u64(seed),
    );
    world.record(&poses, seed << 32).observations()
}

/// The measurements of the recording at `path`, or else `n` simulated ones of `world` drawn
/// from `seed`; with what they are.
pub fn measurements(
    rig: &Rig,
    path: Option<&Path>,
    world: Option<&World>,
    n: usize,
    seed: u64,
) -> Result<(Vec<Observation>, String), CalibrationError> {
    match (path, world) {
        (Some(dir), _) => {
            let rec = rigcal_core::recording::Recording::read(dir, rig.chain.joints()).map_err(
                |source| CalibrationError::Recording {
                    path: dir.to_path_buf(),
                    source,
                },
            )?;
            Ok((rec.observations(), dir.display().to_string()))
        }
        (None, Some(w)) => Ok((
            simulated_observations(rig, w, n, seed),
            format!("{n} simulated random poses"),
        )),
        (None, None) => Err(CalibrationError::NothingToCompare),
    }
}

struct Method {
    name: String,
    model: Box<dyn ErrorModel>,
    measurements: usize,
    train_s: f64,
}

/// Fits every method on `input` with `opts` (its learner is set: FCMAC for the variable model,
/// `nn-direct` for the network) and checks them.
pub fn compare(
    rig: &Rig,
    input: &CompareInput<'_>,
    opts: &CalibrationOptions,
) -> Result<Comparison, CalibrationError> {
    if input.observations.is_empty() || input.validation.is_empty() {
        return Err(CalibrationError::NoMeasurements {
            label: "fit or validation set".into(),
        });
    }
    let mut methods = vec![Method {
        name: "uncalibrated".into(),
        model: Box::new(ErrorParams::zeros(rig.chain.layout())),
        measurements: 0,
        train_s: 0.0,
    }];
    methods.push(conventional(rig, input.observations, opts)?);
    let (variable, mut models) = fitted(rig, input, opts, LearnerKind::Fcmac, "variable D-H")?;
    // fcmac, regions: the conventional one is above.
    models.truncate(2);
    methods.extend(models);
    let (neural, mut models) = fitted(rig, input, opts, LearnerKind::NnDirect, "neural")?;
    models.truncate(1);
    methods.extend(models);
    let rows = methods
        .iter()
        .map(|m| MethodRow {
            name: m.name.clone(),
            measurements: m.measurements,
            train_s: m.train_s,
            apparent_mm: mean_max(
                input
                    .validation
                    .iter()
                    .map(|o| (rig.chain.position(&o.q, &m.model.params_at(&o.q)) - o.p).norm()),
            ),
            actual_mm: input.world.map(|w| {
                mean_max(input.validation.iter().map(|o| {
                    let p = rig.chain.position(&o.q, &m.model.params_at(&o.q));
                    (p - w.true_position(&o.q)).norm()
                }))
            }),
        })
        .collect();
    let paths = match input.world {
        Some(w) => {
            let truth = |q: &[f64]| w.true_position(q);
            let refs: Vec<(String, &dyn ErrorModel)> = methods
                .iter()
                .skip(1)
                .map(|m| (m.name.clone(), m.model.as_ref()))
                .collect();
            input
                .paths
                .iter()
                .map(|(name, spec)| (name.clone(), evaluate_path(rig, spec, &refs, &truth, &[])))
                .collect()
        }
        None => Vec::new(),
    };
    Ok(Comparison {
        variable,
        neural,
        methods: rows,
        paths,
        validation_points: input.validation.len(),
    })
}

/// Conventional calibration of the identifiable basis on `obs`.
fn conventional(
    rig: &Rig,
    obs: &[Observation],
    opts: &CalibrationOptions,
) -> Result<Method, CalibrationError> {
    let t0 = Instant::now();
    let basis = super::design_basis(rig, opts);
    let zero = ErrorParams::zeros(rig.chain.layout());
    let conv = fit(&rig.chain, obs, &zero, &basis, &FitOptions::default())?;
    Ok(Method {
        name: "conventional".into(),
        model: Box::new(conv.params),
        measurements: obs.len(),
        train_s: t0.elapsed().as_secs_f64(),
    })
}

/// Calibrates with `learner` offline on the input, and the model file's error models as
/// methods named `{prefix}: {model}`.
fn fitted(
    rig: &Rig,
    input: &CompareInput<'_>,
    opts: &CalibrationOptions,
    learner: LearnerKind,
    prefix: &str,
) -> Result<(Calibrated, Vec<Method>), CalibrationError> {
    let opts = CalibrationOptions {
        learner,
        ..opts.clone()
    };
    let t0 = Instant::now();
    let cal = calibrate(
        rig,
        Source::Offline {
            observations: input.observations,
            label: input.label.clone(),
        },
        &opts,
    )?;
    let train_s = t0.elapsed().as_secs_f64();
    let measurements = match &cal.model.model {
        ModelBody::Variable { division, .. } => division.measurements,
        _ => input.observations.len(),
    };
    let methods = cal
        .model
        .error_models(rig, Path::new("-"))?
        .into_iter()
        .map(|(name, model)| Method {
            name: format!("{prefix}: {name}"),
            model,
            measurements,
            train_s,
        })
        .collect();
    Ok((cal, methods))
}

/// (mean, max) of non-negative values; (0, 0) for none.
fn mean_max(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut n, mut sum, mut max) = (0usize, 0.0, 0.0f64);
    for x in v {
        n += 1;
        sum += x;
        max = max.max(x);
    }
    (sum / n.max(1) as f64, max)
}

impl Comparison {
    /// The comparison as `rigcal compare` prints it: each model's figures, the table and what
    /// its columns mean.
    pub fn text(&self, accuracy_mm: f64) -> String {
        format!(
            "== variable D-H model (seed 000), offline division at {accuracy_mm} mm\n{}== neuro-kinematic model (seed 001)\n{}\n{}\nvalidation: {} poses; apparent = against the measurements, actual = against the simulated truth\n",
            self.variable.text(),
            self.neural.text(),
            self.markdown(),
            self.validation_points
        )
    }

    /// The comparison as a Markdown table (what `rigcal compare` prints and writes).
    fn markdown(&self) -> String {
        let mut md = String::new();
        md.push_str("| method | measurements | training (s) | validation mean / max, apparent (mm) | actual (mm) |");
        for (p, _) in &self.paths {
            let _ = write!(md, " {p} mean / max (mm) |");
        }
        md.push_str("\n|---|---|---|---|---|");
        for _ in &self.paths {
            md.push_str("---|");
        }
        md.push('\n');
        for (k, m) in self.methods.iter().enumerate() {
            let (apm, apx) = m.apparent_mm;
            let acs = m
                .actual_mm
                .map_or("—".to_string(), |(m, x)| format!("{m:.4} / {x:.4}"));
            let _ = write!(
                md,
                "| {} | {} | {:.2} | {apm:.4} / {apx:.4} | {acs} |",
                m.name, m.measurements, m.train_s
            );
            for (_, res) in &self.paths {
                let r = res
                    .iter()
                    .find(|r| r.model == m.name || (k == 0 && r.model == "uncalibrated"));
                match r {
                    Some(r) => {
                        let s = r.stats();
                        let _ = write!(md, " {:.4} / {:.4} |", s.mean_mm, s.max_mm);
                    }
                    None => md.push_str(" — |"),
                }
            }
            md.push('\n');
        }
        md
    }
}

impl Comparison {
    /// Writes the table (`compare.md`) and one plot per path (`compare-PATH.svg`) into `dir`;
    /// returns the files, plots first.
    pub fn write_files(&self, dir: &Path) -> Result<Vec<PathBuf>, CalibrationError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| CalibrationError::Io { path, source }
        };
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        let mut files = Vec::new();
        for (p, res) in &self.paths {
            let svg = dir.join(format!("compare-{p}.svg"));
            plot_errors(
                &svg,
                &format!("position error along {p}: three calibrations"),
                res,
            )?;
            files.push(svg);
        }
        let table = dir.join("compare.md");
        std::fs::write(&table, self.markdown()).map_err(io(&table))?;
        files.push(table);
        Ok(files)
    }
}
