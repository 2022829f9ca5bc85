//! The figures of an evaluation as data: per path and method the mean and largest position
//! error, the largest CEP jumps, and (seed 000 Fig. 8) the error inside the region that could
//! not be measured. `rigcal evaluate --json` writes them; the demo's `summary.json` holds the
//! same per-path records.

use super::evaluate::{evaluate, path_table, traced_ceps, write_path_files, TracedCep};
use super::CalibrationError;
use rigcal_model::division::{Bounds, DivisionSpace};
use rigcal_model::model::{LoadedModel, ModelBody, ModelFile};
use rigcal_model::report::{PathResult, PathSpec};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One method along one path.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodFigures {
    /// `uncalibrated`, `conventional`, `regions`, `fcmac`, `cmac`, …
    pub method: String,
    /// Mean position error (mm) over the points compensated.
    pub mean_mm: f64,
    /// Largest position error (mm).
    pub max_mm: f64,
    /// Points where compensation failed.
    pub failures: usize,
    /// Largest jump of each traced CEP between neighbouring points, keyed `name_unit`
    /// (`theta1_deg`, `d1_mm`); empty for the uncalibrated arm.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub largest_cep_jump: BTreeMap<String, f64>,
}

/// The errors along a path inside the region that could not be measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InsideFigures {
    /// The region's id, when the division made it a region of its own.
    pub region: Option<String>,
    /// Indices of the path's points inside it.
    pub points: Vec<usize>,
    /// Each method there (no CEP jumps).
    pub methods: Vec<MethodFigures>,
}

/// One path's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PathFigures {
    /// The path's name.
    pub path: String,
    /// Its points.
    pub points: usize,
    /// Every method, uncalibrated first.
    pub methods: Vec<MethodFigures>,
    /// Inside the unmeasurable region, when the model has one and the path crosses it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inside_unmeasurable: Option<InsideFigures>,
}

impl PathFigures {
    /// The figures of `results` along `path` for `model`.
    pub fn of(
        model: &LoadedModel,
        path: &PathSpec,
        results: &[PathResult],
        trace: &[TracedCep],
    ) -> Self {
        let methods = results
            .iter()
            .map(|r| method_figures(r, None, trace))
            .collect();
        Self {
            path: path.name.clone(),
            points: path.points.len(),
            methods,
            inside_unmeasurable: inside_unmeasurable(model, path, results),
        }
    }

    /// A method's figures, by name.
    pub fn method(&self, name: &str) -> Option<&MethodFigures> {
        self.methods.iter().find(|m| m.method == name)
    }

    /// The line `rigcal evaluate` prints about the unmeasurable region (empty without one).
    fn inside_text(&self) -> String {
        let Some(inside) = &self.inside_unmeasurable else {
            return String::new();
        };
        let region = inside
            .region
            .as_deref()
            .unwrap_or("(within a larger region)");
        let (first, last) = (inside.points[0], inside.points[inside.points.len() - 1]);
        let mut s = format!(
            "  inside the unmeasurable region {region} (points {first}–{last}, {} of them), mean / max mm:",
            inside.points.len()
        );
        for m in &inside.methods {
            let _ = write!(s, "  {} {:.4} / {:.4}", m.method, m.mean_mm, m.max_mm);
        }
        s.push('\n');
        s
    }
}

impl MethodFigures {
    /// The figures of one method's results along a path, with the jumps of the `trace`d CEPs.
    pub fn of(result: &PathResult, trace: &[TracedCep]) -> Self {
        method_figures(result, None, trace)
    }
}

/// The figures of one method, over `only` the points given (None: all).
fn method_figures(r: &PathResult, only: Option<&[usize]>, trace: &[TracedCep]) -> MethodFigures {
    let errors: Vec<f64> = match only {
        None => r.errors.clone(),
        Some(idx) => idx
            .iter()
            .filter_map(|&i| r.errors.get(i).copied())
            .collect(),
    };
    let finite: Vec<f64> = errors.iter().copied().filter(|e| e.is_finite()).collect();
    let mean_mm = finite.iter().sum::<f64>() / finite.len().max(1) as f64;
    let max_mm = finite.iter().copied().fold(0.0, f64::max);
    let largest_cep_jump = match only {
        Some(_) => BTreeMap::new(),
        None => trace
            .iter()
            .zip(r.largest_jumps())
            .map(|(t, j)| (format!("{}_{}", t.name, t.unit), j))
            .collect(),
    };
    MethodFigures {
        method: r.model.clone(),
        mean_mm,
        max_mm,
        failures: errors.len() - finite.len(),
        largest_cep_jump,
    }
}

/// The errors along `path` inside the model's unmeasurable region, if it has one and the path
/// enters it.
fn inside_unmeasurable(
    model: &LoadedModel,
    path: &PathSpec,
    results: &[PathResult],
) -> Option<InsideFigures> {
    let ModelBody::Variable { division, tree, .. } = &model.file.model else {
        return None;
    };
    let bounds: Bounds = division.unmeasurable?;
    let space = DivisionSpace::new(&model.rig, tree.space).ok()?;
    let points: Vec<usize> = path
        .points
        .iter()
        .enumerate()
        .filter(|(_, q)| bounds.holds(&space.coords(q)))
        .map(|(i, _)| i)
        .collect();
    if points.is_empty() {
        return None;
    }
    let region = tree
        .unmeasurable()
        .into_iter()
        .find(|l| l.bounds == bounds)
        .map(|l| l.id.clone());
    Some(InsideFigures {
        region,
        methods: results
            .iter()
            .map(|r| method_figures(r, Some(&points), &[]))
            .collect(),
        points,
    })
}

/// `rigcal evaluate --json`: the model and scenario files and every path's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvaluationJson {
    /// Always `rigcal-evaluation`.
    pub format: &'static str,
    /// The model file.
    pub model: String,
    /// The scenario whose arm is the truth.
    pub scenario: String,
    /// Per path.
    pub paths: Vec<PathFigures>,
}

impl EvaluationJson {
    /// The figures of `paths` of the model file `model` in the truth of the scenario file
    /// `scenario`.
    pub fn new(model: &Path, scenario: &Path, paths: Vec<PathFigures>) -> Self {
        EvaluationJson {
            format: "rigcal-evaluation",
            model: model.display().to_string(),
            scenario: scenario.display().to_string(),
            paths,
        }
    }

    /// Writes the figures as pretty JSON (with a final newline) to `file`.
    pub fn write(&self, file: &Path) -> Result<(), CalibrationError> {
        let text = serde_json::to_string_pretty(self)? + "\n";
        std::fs::write(file, text).map_err(|source| CalibrationError::Writing {
            path: file.to_path_buf(),
            source,
        })
    }
}

/// [`evaluate`] from the files `rigcal evaluate` takes: every model of the model file at
/// `model` along `paths` in the truth of the scenario file `scenario`, tracing the CEPs named
/// in `trace`; with `out`, each path's plots and CSV written there. Per path its figures, and
/// the text `rigcal evaluate` prints: each path's table, the error inside an unmeasurable
/// region, the files written.
pub fn evaluate_files(
    model: &Path,
    scenario: &Path,
    paths: &[PathSpec],
    trace: &[String],
    out: Option<&Path>,
) -> Result<(Vec<PathFigures>, String), CalibrationError> {
    let loaded = ModelFile::load(model)?;
    let trace = traced_ceps(&loaded.rig, trace)?;
    let scenario = rigcal_sim::world::Scenario::load(scenario, None)?;
    let all = evaluate(&loaded, model, &scenario, paths, &trace)?;
    let mut text = String::new();
    let mut figures = Vec::with_capacity(paths.len());
    for (path, results) in paths.iter().zip(&all) {
        let f = PathFigures::of(&loaded, path, results, &trace);
        text.push_str(&path_table(path, results, &trace));
        text.push_str(&f.inside_text());
        if let Some(dir) = out {
            text.push_str(&write_path_files(dir, path, results, &trace)?.text());
        }
        figures.push(f);
    }
    Ok((figures, text))
}

/// The CEPs of every model of the model file at `model` along `path`, as each model gives
/// them at the path's nominal joints (no compensation, no truth: what seed 000's Fig. 10 e–g
/// shows for the rig's path), conventional first; each result's `traces` holds the CEPs named
/// in `trace` (file units: mm and degrees) and its `errors` are empty.
pub fn cep_traces(
    model: &Path,
    path: &PathSpec,
    trace: &[String],
) -> Result<(Vec<PathResult>, Vec<TracedCep>), CalibrationError> {
    let loaded = ModelFile::load(model)?;
    let traced = traced_ceps(&loaded.rig, trace)?;
    let layout = rigcal_core::kinematics::Robot::layout(&loaded.rig.chain);
    let index: Vec<usize> = traced
        .iter()
        .filter_map(|t| layout.find(&t.name).and_then(|id| layout.index_of(id)))
        .collect();
    let mut models = loaded.file.error_models(&loaded.rig, model)?;
    // Conventional first, as `rigcal evaluate` lists them.
    models.reverse();
    let results = models
        .iter()
        .map(|(name, m)| {
            let mut traces = vec![Vec::with_capacity(path.points.len()); index.len()];
            for q in &path.points {
                let e = m.params_at(q);
                for (k, &i) in index.iter().enumerate() {
                    traces[k].push(layout.ids()[i].kind.to_file_units(e.get(i)));
                }
            }
            PathResult {
                model: name.clone(),
                errors: Vec::new(),
                traces,
                failures: 0,
            }
        })
        .collect();
    Ok((results, traced))
}

/// The files [`write_cep_traces`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct CepTraceFiles {
    /// One panel per traced CEP, one series per model (SVG).
    pub svg: PathBuf,
    /// Point, then per model and CEP its value (CSV, file units).
    pub csv: PathBuf,
}

/// [`cep_traces`] plotted into `dir/STEM.svg` (one panel per CEP, a series per model) and
/// written as `dir/STEM.csv`.
pub fn write_cep_traces(
    model: &Path,
    path: &PathSpec,
    trace: &[String],
    dir: &Path,
    stem: &str,
) -> Result<CepTraceFiles, CalibrationError> {
    let (results, traced) = cep_traces(model, path, trace)?;
    std::fs::create_dir_all(dir).map_err(|source| CalibrationError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let svg = dir.join(format!("{stem}.svg"));
    let names: Vec<&str> = traced.iter().map(|t| t.name.as_str()).collect();
    let units: Vec<&str> = traced.iter().map(|t| t.unit).collect();
    rigcal_model::report::plot_traces(
        &svg,
        &format!("CEPs along {} (seed 000 Fig. 10 e–g)", path.name),
        &names,
        &units,
        &results,
    )?;
    let mut text = String::from("point");
    for r in &results {
        for t in &traced {
            let _ = write!(text, ",{}_{}_{}", r.model, t.name, t.unit);
        }
    }
    text.push('\n');
    for i in 0..path.points.len() {
        let _ = write!(text, "{i}");
        for r in &results {
            for t in &r.traces {
                let _ = write!(text, ",{:.6}", t[i]);
            }
        }
        text.push('\n');
    }
    let csv = dir.join(format!("{stem}.csv"));
    std::fs::write(&csv, text).map_err(|source| CalibrationError::Io {
        path: csv.clone(),
        source,
    })?;
    Ok(CepTraceFiles { svg, csv })
}

/// The first point of a model where compensation failed, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct FirstFailure {
    /// The model's name (`conventional`, `regions`, …).
    pub model: String,
    /// The path's name.
    pub path: String,
    /// The point's index along the path (0-based).
    pub point: usize,
    /// The compensation's error.
    pub reason: String,
    /// Points of the model that failed, over every path.
    pub failed: usize,
    /// Points evaluated, over every path.
    pub points: usize,
}

impl FirstFailure {
    /// True when the model compensated no point at all.
    pub fn none_compensated(&self) -> bool {
        self.failed >= self.points
    }
}

/// For each model of `model` that failed somewhere along `paths` (per [`PathFigures`] of an
/// evaluation, `figures`), the first point where it failed and the compensation's reason:
/// what `rigcal evaluate` reports beside the count.
///
pub fn first_failures(
    model: &Path,
    paths: &[PathSpec],
    figures: &[PathFigures],
) -> Result<Vec<FirstFailure>, CalibrationError> {
    let mut totals: Vec<(String, usize, usize)> = Vec::new();
    for (f, path) in figures.iter().zip(paths) {
        for m in f.methods.iter().filter(|m| m.method != "uncalibrated") {
            match totals.iter_mut().find(|(name, _, _)| *name == m.method) {
                Some(t) => {
                    t.1 += m.failures;
                    t.2 += path.points.len();
                }
                None => totals.push((m.method.clone(), m.failures, path.points.len())),
            }
        }
    }
    totals.retain(|(_, failed, _)| *failed > 0);
    if totals.is_empty() {
        return Ok(Vec::new());
    }
    let loaded = rigcal_model::model::ModelFile::load(model)?;
    let rig = &loaded.rig;
    let models = loaded.file.error_models(rig, model)?;
    let nominal = rigcal_core::kinematics::ErrorParams::zeros(
        rigcal_core::kinematics::Robot::layout(&rig.chain),
    );
    let opts = rigcal_model::compensation::CompensationOptions::default();
    let mut out = Vec::new();
    for (name, failed, points) in totals {
        let Some((_, m)) = models.iter().find(|(n, _)| *n == name) else {
            continue;
        };
        let first = paths.iter().find_map(|path| {
            path.points.iter().enumerate().find_map(|(k, q)| {
                let target = rigcal_core::kinematics::Robot::position(&rig.chain, q, &nominal);
                rigcal_model::compensation::compensate_from(
                    &rig.chain,
                    m.as_ref(),
                    &target,
                    rig.held(),
                    q.clone(),
                    &opts,
                )
                .err()
                .map(|e| (path.name.clone(), k, e.to_string()))
            })
        });
        let (path, point, reason) =
            first.unwrap_or_else(|| (String::new(), 0, "not reproduced".to_string()));
        out.push(FirstFailure {
            model: name,
            path,
            point,
            reason,
            failed,
            points,
        });
    }
    Ok(out)
}
