//! `rigcal demo`: the whole job on simulated devices, step by step through the library, at
//! seed 000's settings ([`Preset`]).
//!
//! 1. Seed 000's simulations in the paper's regime (`sim/paper-fig6.toml`, conventions §3) on
//!    the ideal-instrument rig (conventions §2), at the paper's settings: 0.1 mm demanded, 20
//!    measurements per region, the region caps 110 / 130. Planning-mode divisions on the
//!    simulated arm (it measures where the division asks), FCMAC, and along the paper's paths
//!    the four cases: Fig. 6 (joint-space division), Fig. 7 (Cartesian division, D-optimal
//!    locations), Fig. 8 (Fig. 6 with one region on the path unmeasurable: nothing measured in
//!    it), and the CEP jumps of regions, FCMAC and CMAC on one division; each figure beside the
//!    paper's; then Figs. 6 and 7 again at about half the paper's measurements.
//! 2. Seed 000 section 7 on the real rig's emulators (`rigs/rv-m2.toml`, `sim/rig-sec7.toml`,
//!    [`sec7`]): registration, a Cartesian division at 0.5 mm through region sessions (each
//!    region's 20 κ-selected locations one z-ascending batch), the variable D-H model with and
//!    without the FCMAC, and a straight Cartesian path of the paper's length measured by the rig
//!    itself per method through `MP` and, beside it, through `MJ`, with both floors; then a
//!    diagnosis of what the geometric model leaves out of the division's recording.
//!
//! Everything goes to [`DemoOptions::out`]; `summary.txt` there repeats the closing table and
//! `summary.json` holds its figures. Nothing here prints: what a terminal shows, and the
//! progress of section 7, go to the caller's [`DemoEvent`] sink.

use crate::paper_regime::{FigureRun, PaperFigure, PaperRegimeSummary};
use crate::preset::Preset;
use crate::sec7::{self, Sec7Error, Sec7Files, Sec7Options, Sec7Report, Sec7Stage, Sec7Summary};
use rigcal_calibration::{self as calibration, CalibrationError, CalibrationOptions, PathFigures};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::division::{DivisionError, DivisionSpace, Selection, Space};
use rigcal_model::learners::{FcmacInit, FcmacTraining, LearnerKind};
use rigcal_model::model::{ModelBody, ModelFile};
use rigcal_model::report::{mean_max_rows, PathSpec};
use rigcal_sim::world::Scenario;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

const PAPER_RIG: &str = "rigs/rv-m2-ideal.toml";
const PAPER_SCENARIO: &str = "sim/paper-fig6.toml";
const REAL_RIG: &str = "rigs/rv-m2.toml";
const REAL_SCENARIO: &str = "sim/rig-sec7.toml";

/// What the demo runs with: the paper's settings and the demo's own.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoOptions {
    /// Directory for the recordings, models, reports and plots (the demo's own subdirectories
    /// there are replaced on a new run).
    pub out: PathBuf,
    /// Seed 000's settings; the demanded accuracies of sections 6 and 7 among them.
    pub preset: Preset,
    /// Points of the section 7 path, measured once per method and command path.
    pub path_points: usize,
    /// Seed of the divisions, the plans and the learner.
    pub seed: u64,
    /// The learner tolerance of every FCMAC and CMAC
    /// ([`CalibrationOptions::learner_tolerance`]).
    pub learner_tolerance: Option<f64>,
    /// What every FCMAC is trained to reproduce.
    pub fcmac_training: FcmacTraining,
    /// The division's acceptance ([`CalibrationOptions::confidence_z`]); None: the library's.
    pub confidence_z: Option<f64>,
    /// Regions' CEPs by the paper's plain least squares instead of rigcal's MAP estimate
    /// around the parent's ([`CalibrationOptions::map_prior`] false): the departure's measure.
    pub plain_least_squares: bool,
    /// Where every FCMAC's cells start ([`FcmacInit`]; the paper does not say).
    pub fcmac_init: FcmacInit,
    /// Section 6 with Gaussian measurement noise of this share of the mean uncalibrated
    /// error on the Fig. 6 path (the paper's further run: about 0.03); None: the scenario's
    /// own (none) ([`crate::paper_regime::noise_sigma_mm`]).
    pub noise_share: Option<f64>,
}

/// What the demo tells its caller as it goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DemoEvent<'a> {
    /// Text for the terminal (whole lines), in order.
    Text(&'a str),
    /// How section 7 is getting on.
    Sec7(Sec7Stage),
}

/// Why the demo stopped.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DemoError {
    /// A file the demo reads is not there.
    #[error("{0} not found: run `rigcal demo` from the repository's top directory (it reads rigs/ and sim/)")]
    NotFound(&'static str),
    /// Too few path points.
    #[error("--path-points must be at least 2")]
    PathPoints,
    /// The output's section 7 directory holds something an earlier demo did not write.
    #[error("{} exists and is not a directory of an earlier demo; choose another --out", .0.display())]
    NotADemo(PathBuf),
    /// A file or directory could not be written, read or removed.
    #[error("{doing} {}", path.display())]
    Io {
        /// What was being done (`creating`, `writing`, `removing`).
        doing: &'static str,
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A calibration, an evaluation, or a file they read or write.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    /// Section 7.
    #[error(transparent)]
    Sec7(#[from] Sec7Error),
    /// A model that should hold a division does not.
    #[error("{0}")]
    NoDivision(&'static str),
    /// The diagnosis of the division session's recording.
    #[error("diagnosing {}", recording.display())]
    Diagnosis {
        /// The recording.
        recording: PathBuf,
        /// The cause.
        source: rigcal_model::diagnosis::DiagnoseError,
    },
    /// A report could not be made into JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// One seed of a sweep ([`crate::seeds`]) failed.
    #[error("seed {seed}: {source}")]
    Seed {
        /// The seed.
        seed: u64,
        /// What failed.
        source: Box<DemoError>,
    },
}

impl From<rigcal_core::rig::RigError> for DemoError {
    fn from(e: rigcal_core::rig::RigError) -> Self {
        Self::Sec7(e.into())
    }
}

impl From<rigcal_model::model::ModelError> for DemoError {
    fn from(e: rigcal_model::model::ModelError) -> Self {
        Self::Calibration(e.into())
    }
}

impl From<rigcal_sim::world::ScenarioError> for DemoError {
    fn from(e: rigcal_sim::world::ScenarioError) -> Self {
        Self::Calibration(e.into())
    }
}

/// What `summary.json` holds.
#[derive(Debug, Serialize)]
pub struct DemoSummary {
    format: &'static str,
    /// The seed.
    pub seed: u64,
    /// Wall time of both steps (s).
    pub wall_s: f64,
    /// Step 1.
    pub paper: PaperRegimeSummary,
    /// Step 2.
    pub rig: Sec7Summary,
}

/// The demo's run: its options, the paths of section 6 and the sink it tells.
struct Demo<'a> {
    o: &'a DemoOptions,
    paths: PathSet,
    tell: &'a mut dyn FnMut(DemoEvent<'_>),
}

/// Which paths section 6's figures are evaluated along (and where Fig. 8's unmeasurable region
/// lies).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PathSet {
    /// The paper's: the Fig. 6 joint path, the Fig. 7 spherical path, Fig. 8's region half way
    /// along the Fig. 6 path ([`Preset::fig8_point_deg`]). The figures the README reports.
    Paper,
    /// Paths no reported figure uses, for choosing settings (docs/seeds.md): a joint line on
    /// the other side of the base, (−125°, 40°, −60°) → (−60°, 70°, −30°); a spherical line
    /// (600 mm, −125°, 10°) → (700 mm, −20°, −10°); the unmeasurable region half way along
    /// the joint line, at (−92.5°, 55°, −45°).
    Tuning,
}

/// The tuning set's joint line (q1, q2, q3 in deg).
const TUNING_JOINT: [[f64; 3]; 2] = [[-125.0, 40.0, -60.0], [-60.0, 70.0, -30.0]];
/// The tuning set's spherical line (R mm, azimuth deg, elevation deg).
const TUNING_SPHERICAL: [[f64; 3]; 2] = [[600.0, -125.0, 10.0], [700.0, -20.0, -10.0]];

/// Section 6's paths of one set: joint, spherical, and the point of Fig. 8's unmeasurable
/// region (q1, q2, q3 in deg).
struct Paths {
    joint: PathSpec,
    spherical: PathSpec,
    fig8_point_deg: [f64; 3],
}

impl PathSet {
    fn paths(self, rig: &Rig, preset: &Preset) -> Result<Paths, DemoError> {
        Ok(match self {
            PathSet::Paper => Paths {
                joint: calibration::fig6_path(rig, 101),
                spherical: calibration::fig7_path(rig, 101).map_err(CalibrationError::from)?,
                fig8_point_deg: preset.fig8_point_deg,
            },
            PathSet::Tuning => {
                let [a, b] = TUNING_JOINT;
                let [c, d] = TUNING_SPHERICAL;
                Paths {
                    joint: rigcal_model::report::joint_path(rig, "tuning joint path", &a, &b, 101),
                    spherical: rigcal_model::report::spherical_path(
                        rig,
                        "tuning spherical path",
                        c,
                        d,
                        101,
                    )
                    .map_err(CalibrationError::from)?,
                    fig8_point_deg: std::array::from_fn(|k| 0.5 * (a[k] + b[k])),
                }
            }
        })
    }
}

/// Runs the demo into `opts.out`, telling `tell` what a terminal shows: the summary (also
/// written to `summary.txt` and `summary.json`).
pub fn run(
    opts: &DemoOptions,
    tell: &mut dyn FnMut(DemoEvent<'_>),
) -> Result<DemoSummary, DemoError> {
    if let Some(f) = [PAPER_RIG, PAPER_SCENARIO, REAL_RIG, REAL_SCENARIO]
        .into_iter()
        .find(|f| !Path::new(f).exists())
    {
        return Err(DemoError::NotFound(f));
    }
    if opts.path_points < 2 {
        return Err(DemoError::PathPoints);
    }
    let out = &opts.out;
    std::fs::create_dir_all(out).map_err(|source| io("creating", out, source))?;
    let mut demo = Demo {
        o: opts,
        paths: PathSet::Paper,
        tell,
    };
    let started = Instant::now();
    let paper = demo.paper_steps()?;
    let rig = demo.rig_steps()?;
    let wall_s = started.elapsed().as_secs_f64();
    let mut summary = format!(
        "rigcal demo summary (seed {}, {wall_s:.1} s wall)\n{}",
        opts.seed,
        paper.text()
    );
    summary.push_str(&rig_summary_text(&rig, &opts.preset));
    summary.push_str(&format!("files in {}: paper-fig6-model.json, paper-fig7-model.json, paper-fig8-model.json, paper-fig6-cmac-model.json, paper-fig6-d-optimal-10-model.json and paper-fig7-d-optimal-9-model.json (half the measurements), paper-plots/ (SVG, CSV), rig/ (section 7: division/, path-cartesian/, path-joint/ session recordings, plans and journals; sec7-model.json), rig-plots/ (SVG), rig-diagnosis.json, summary.txt, summary.json\n", out.display()));
    demo.heading("Summary");
    demo.say(&summary);
    write(&out.join("summary.txt"), &summary)?;
    let json = DemoSummary {
        format: "rigcal-demo-summary",
        seed: opts.seed,
        wall_s,
        paper,
        rig: rig.summary(),
    };
    write(
        &out.join("summary.json"),
        &(serde_json::to_string_pretty(&json)? + "\n"),
    )?;
    Ok(json)
}

/// Section 6 alone (the demo's first step) into `opts.out`, along the paths of `paths`:
/// what the seed sweep ([`crate::seeds`]) runs at each seed.
pub fn paper_regime(
    opts: &DemoOptions,
    paths: PathSet,
    tell: &mut dyn FnMut(DemoEvent<'_>),
) -> Result<PaperRegimeSummary, DemoError> {
    if let Some(f) = [PAPER_RIG, PAPER_SCENARIO]
        .into_iter()
        .find(|f| !Path::new(f).exists())
    {
        return Err(DemoError::NotFound(f));
    }
    let out = &opts.out;
    std::fs::create_dir_all(out).map_err(|source| io("creating", out, source))?;
    Demo {
        o: opts,
        paths,
        tell,
    }
    .paper_steps()
}

/// The tuning set's section 7 path (world mm): a measurable straight line of 700 mm on the
/// other side of the table's reach from the preset's, which no reported figure uses.
pub const TUNING_SEC7_PATH_MM: [[f64; 3]; 2] = [[300.0, 330.0, 40.0], [-300.0, 480.0, 360.0]];

/// Section 7's options at the demo's settings, along the paths of `paths`, through `MJ` too
/// when `joint_commands`.
fn sec7_options(o: &DemoOptions, paths: PathSet, joint_commands: bool) -> Sec7Options {
    let mut calibration = o.preset.section7_calibration();
    calibration.seed = o.seed;
    // `--learner-tolerance` overrides the preset's section 7 choice.
    calibration.learner_tolerance = o.learner_tolerance.or(calibration.learner_tolerance);
    calibration.learner_settings.training = o.fcmac_training;
    calibration.learner_settings.init = o.fcmac_init;
    calibration.confidence_z = o.confidence_z.unwrap_or(calibration.confidence_z);
    calibration.map_prior = !o.plain_least_squares;
    Sec7Options {
        calibration,
        path_points: o.path_points,
        path_mm: match paths {
            PathSet::Paper => o.preset.section7.path_mm,
            PathSet::Tuning => TUNING_SEC7_PATH_MM,
        },
        joint_commands,
    }
}

/// [`sec7::run`] into `files.out`, replacing what an earlier demo wrote there.
fn run_sec7(
    files: Sec7Files<'_>,
    opts: &Sec7Options,
    progress: &mut dyn FnMut(Sec7Stage),
) -> Result<Sec7Report, DemoError> {
    clear_sec7_dir(files.out)?;
    Ok(sec7::run(files, opts, progress)?)
}

/// Section 7 alone (the demo's second step without the diagnosis) into `opts.out`/rig, along
/// the path of `paths`, through the rig's own command path only (`MP` on `rigs/rv-m2.toml`):
/// what the seed sweep ([`crate::seeds`]) runs at each seed with `--rig`.
pub fn rig_experiment(opts: &DemoOptions, paths: PathSet) -> Result<Sec7Report, DemoError> {
    if let Some(f) = [REAL_RIG, REAL_SCENARIO]
        .into_iter()
        .find(|f| !Path::new(f).exists())
    {
        return Err(DemoError::NotFound(f));
    }
    let out = opts.out.join("rig");
    let files = Sec7Files {
        rig: Path::new(REAL_RIG),
        scenario: Path::new(REAL_SCENARIO),
        out: &out,
    };
    run_sec7(files, &sec7_options(opts, paths, false), &mut |_| {})
}

fn io(doing: &'static str, path: &Path, source: std::io::Error) -> DemoError {
    DemoError::Io {
        doing,
        path: path.to_path_buf(),
        source,
    }
}

fn write(file: &Path, text: &str) -> Result<(), DemoError> {
    std::fs::write(file, text).map_err(|source| io("writing", file, source))
}

/// The rig part of `summary.txt`: per command path, each method as the rig measured it.
fn rig_summary_text(rig: &Sec7Report, preset: &Preset) -> String {
    let (ident, tests) = rig.measurements();
    let mut s = format!(
        "real rig, seed 000 section 7 ({REAL_SCENARIO}): {} regions (paper {}), {ident} identification and {tests} test measurements, {} unmeasurable; rig time {:.2} h on the dry-run clock ({:.2} h planned); distance to target measured by the rig itself, mean / max in mm (paper: uncalibrated 0.3–2.5, conventional below 1.2, variable below 0.5)\n",
        rig.regions(),
        preset.section7.regions,
        rig.unmeasurable.len(),
        rig.rig_time_s() / 3600.0,
        rig.planned_s() / 3600.0,
    );
    for run in &rig.runs {
        s.push_str(&mean_max_rows(
            &format!("{} through {}", rig.path.name, run.command()),
            &run.results,
        ));
    }
    s
}

fn figure_tag(figure: PaperFigure) -> &'static str {
    match figure {
        PaperFigure::Fig6 => "fig6",
        PaperFigure::Fig7 => "fig7",
        PaperFigure::Fig8 => "fig8",
    }
}

impl Demo<'_> {
    fn say(&mut self, text: &str) {
        (self.tell)(DemoEvent::Text(text));
    }

    fn heading(&mut self, text: &str) {
        self.say(&format!("\n== {text}\n"));
    }

    /// The preset's calibration of a division in `space`, with the demo's seed and learner.
    fn options(&self, space: Space) -> CalibrationOptions {
        let mut o = self.o.preset.calibration(space);
        o.seed = self.o.seed;
        o.learner_tolerance = self.o.learner_tolerance;
        o.learner_settings.training = self.o.fcmac_training;
        o.learner_settings.init = self.o.fcmac_init;
        o.confidence_z = self.o.confidence_z.unwrap_or(o.confidence_z);
        o.map_prior = !self.o.plain_least_squares;
        o
    }

    /// Step 1: Figs. 6, 7 and 8 and the CEP jumps in the paper's regime.
    fn paper_steps(&mut self) -> Result<PaperRegimeSummary, DemoError> {
        let rig = Rig::load(Path::new(PAPER_RIG))?;
        let mut sc = Scenario::load(Path::new(PAPER_SCENARIO), None)?;
        if let Some(share) = self.o.noise_share {
            sc.measurement.noise_mm = crate::paper_regime::noise_sigma_mm(&sc, share);
        }
        let opts = self.options(Space::Joint);
        self.heading(
            "1. Seed 000's simulations in the paper's regime (sim/paper-fig6.toml, ideal instrument)",
        );
        let paths = self.paths.paths(&rig, &self.o.preset)?;
        let fig6_path = paths.joint;
        let fig6 = self.paper_model(&rig, &sc, "fig6", &opts)?;
        let fig6_run = self.paper_run(PaperFigure::Fig6, Selection::Kappa, &fig6, &fig6_path)?;
        // D-optimal locations: at the cap of 130 the κ rule leaves regions above 0.1 mm on the
        // Fig. 7 path (0.129 mm at seed 1); D-optimal ones keep them below it (0.072).
        let cartesian = CalibrationOptions {
            selection: Selection::DOptimal,
            ..self.options(Space::Cartesian)
        };
        let fig7 = self.paper_model(&rig, &sc, "fig7", &cartesian)?;
        let fig7_path = paths.spherical;
        let fig7_run = self.paper_run(PaperFigure::Fig7, Selection::DOptimal, &fig7, &fig7_path)?;
        let at = paths.fig8_point_deg;
        let fig8_opts = CalibrationOptions {
            unmeasurable_at: Some(at),
            unmeasurable_depth: Some(leaf_depth_at(&fig6.0, &rig, at)?),
            ..opts.clone()
        };
        let fig8 = self.paper_model(&rig, &sc, "fig8", &fig8_opts)?;
        let fig8_run = self.paper_run(PaperFigure::Fig8, Selection::Kappa, &fig8, &fig6_path)?;
        let half_budget = self.half_budget_runs(&rig, &sc, [fig6_path.clone(), fig7_path])?;
        self.heading("The same Fig. 6 division with Albus's CMAC in place of the FCMAC");
        let cmac =
            calibration::with_learner(&fig6.0, &rig, LearnerKind::Cmac, &opts.learner_settings)?;
        let cmac_file = self.o.out.join("paper-fig6-cmac-model.json");
        cmac.save(&cmac_file)?;
        let cmac_path = self.evaluate(&cmac_file, &fig6_path)?;
        let jumps = ["regions", "fcmac"]
            .iter()
            .filter_map(|m| fig6_run.path.method(m))
            .chain(cmac_path.method("cmac"))
            .cloned()
            .collect();
        let share = sc
            .world()
            .error_split(&rigcal_sim::world::fig6_path(101, rig.chain.dof()))
            .share();
        Ok(PaperRegimeSummary {
            scenario: PAPER_SCENARIO.into(),
            non_geometric_share: share,
            accuracy_mm: opts.accuracy_mm,
            per_region: opts.per_region,
            runs: vec![fig6_run, fig7_run, fig8_run],
            half_budget,
            cep_jumps: jumps,
        })
    }

    /// Figs. 6 and 7 at about half the paper's measurements along `paths` (theirs): D-optimal
    /// locations, fewer per region.
    fn half_budget_runs(
        &mut self,
        rig: &Rig,
        sc: &Scenario,
        paths: [PathSpec; 2],
    ) -> Result<Vec<FigureRun>, DemoError> {
        self.heading(
            "Figs. 6 and 7 with half the measurements: D-optimal locations, fewer per region",
        );
        let cases = [
            (PaperFigure::Fig6, Space::Joint),
            (PaperFigure::Fig7, Space::Cartesian),
        ];
        let per_region = self.o.preset.half_budget_per_region;
        let mut runs = Vec::new();
        for (((figure, space), path), per_region) in cases.into_iter().zip(paths).zip(per_region) {
            let o = CalibrationOptions {
                per_region,
                selection: Selection::DOptimal,
                ..self.options(space)
            };
            let name = format!("{}-d-optimal-{per_region}", figure_tag(figure));
            let model = self.paper_model(rig, sc, &name, &o)?;
            runs.push(self.paper_run(figure, Selection::DOptimal, &model, &path)?);
        }
        Ok(runs)
    }

    /// A planning-mode calibration on the paper's scenario, told and saved as
    /// `paper-NAME-model.json`: the model and its file.
    fn paper_model(
        &mut self,
        rig: &Rig,
        sc: &Scenario,
        name: &str,
        opts: &CalibrationOptions,
    ) -> Result<(ModelFile, PathBuf), DemoError> {
        let file = self.o.out.join(format!("paper-{name}-model.json"));
        self.say(&format!(
            "\n-- {name}: rigcal calibrate --scenario {PAPER_SCENARIO} --division {:?}\n",
            opts.space
        ));
        let c = calibration::calibrate(rig, calibration::Source::Scenario(sc), opts)?;
        self.say(&c.text());
        c.model.save(&file)?;
        self.say(&format!("model written to {}\n", file.display()));
        Ok((c.model, file))
    }

    /// The run of `figure`: its model evaluated along `path`.
    fn paper_run(
        &mut self,
        figure: PaperFigure,
        selection: Selection,
        model: &(ModelFile, PathBuf),
        path: &PathSpec,
    ) -> Result<FigureRun, DemoError> {
        let figures = self.evaluate(&model.1, path)?;
        FigureRun::of(figure, selection, &model.0, figures).ok_or(DemoError::NoDivision(
            "the paper's calibration made no division",
        ))
    }

    /// Evaluates the model file along `path` on the paper's scenario, plots into `paper-plots/`.
    fn evaluate(&mut self, model: &Path, path: &PathSpec) -> Result<PathFigures, DemoError> {
        let plots = self.o.out.join("paper-plots").join(
            model
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
        );
        let (mut figures, text) = calibration::evaluate_files(
            model,
            Path::new(PAPER_SCENARIO),
            std::slice::from_ref(path),
            &self.o.preset.traced_ceps(),
            Some(&plots),
        )?;
        self.say(&text);
        figures
            .pop()
            .ok_or(DemoError::NoDivision("no path evaluated"))
    }

    /// Step 2: seed 000 section 7 on the rig's emulators ([`sec7`]), then a diagnosis of what
    /// the geometric model leaves out of the division session's recording.
    fn rig_steps(&mut self) -> Result<Sec7Report, DemoError> {
        let out = self.o.out.join("rig");
        self.heading("2. Seed 000 section 7 on the real rig's emulators (sim/rig-sec7.toml): registration, region sessions, the path measured by the rig");
        let opts = sec7_options(self.o, PathSet::Paper, true);
        let files = Sec7Files {
            rig: Path::new(REAL_RIG),
            scenario: Path::new(REAL_SCENARIO),
            out: &out,
        };
        let tell = &mut *self.tell;
        let report = run_sec7(files, &opts, &mut |stage| tell(DemoEvent::Sec7(stage)))?;
        self.say(&report.text());
        for plot in report.plot(&self.o.out.join("rig-plots"))? {
            self.say(&format!("plot: {}\n", plot.display()));
        }
        let ceps =
            crate::sec7::rig_cep_plot(&report, &self.o.preset, &self.o.out.join("rig-plots"))?;
        self.say(&format!(
            "plot: {} (CEPs along the path, seed 000 Fig. 10 e–g; values in {})\n",
            ceps.svg.display(),
            ceps.csv.display()
        ));
        self.heading(
            "3. Diagnosis: what the geometric model leaves out of the division session's recording",
        );
        let rig = Rig::load(Path::new(REAL_RIG))?;
        self.diagnose(&rig, &files.division_dir())?;
        Ok(report)
    }

    /// The diagnosis of `recording` as `rigcal diagnose` prints it, its report and plots
    /// written.
    fn diagnose(&mut self, rig: &Rig, recording: &Path) -> Result<(), DemoError> {
        let (plots, json) = (
            self.o.out.join("rig-plots"),
            self.o.out.join("rig-diagnosis.json"),
        );
        let rec = Recording::read_measured(recording, rig.chain.joints()).map_err(|source| {
            CalibrationError::Recording {
                path: recording.to_path_buf(),
                source,
            }
        })?;
        let diagnosis = |source| DemoError::Diagnosis {
            recording: recording.to_path_buf(),
            source,
        };
        let report =
            rigcal_model::diagnosis::diagnose(rig, &rec, &Default::default()).map_err(diagnosis)?;
        self.say(&format!(
            "recording {}\n{}\n",
            recording.display(),
            report.text().trim_end()
        ));
        write(&json, &serde_json::to_string_pretty(&report)?)?;
        let written =
            rigcal_model::diagnosis::plots::write(rig, &rec, &plots).map_err(diagnosis)?;
        self.say(&format!(
            "report written to {}\n{written} plot(s) written to {}\n",
            json.display(),
            plots.display()
        ));
        Ok(())
    }
}

/// The depth of the leaf of `model`'s division containing `at` (file units).
fn leaf_depth_at(model: &ModelFile, rig: &Rig, at: [f64; 3]) -> Result<usize, DemoError> {
    let ModelBody::Variable { tree, .. } = &model.model else {
        return Err(DemoError::NoDivision("the Fig. 6 model has no division"));
    };
    let space = DivisionSpace::new(rig, tree.space)
        .map_err(|e| CalibrationError::from(DivisionError::from(e)))?;
    let q: Vec<f64> = rig
        .held()
        .iter()
        .enumerate()
        .map(|(j, h)| match j {
            0..=2 => at[j].to_radians(),
            _ => h.unwrap_or(0.0),
        })
        .collect();
    let leaf = tree.root.leaf_at(&space.coords(&q), &tree.full);
    Ok(leaf.id.len() - 1)
}

/// Removes the section 7 directory an earlier demo wrote (its division session holds a
/// journal); refuses anything else.
fn clear_sec7_dir(dir: &Path) -> Result<(), DemoError> {
    if !dir.exists() {
        return Ok(());
    }
    let journal = |d: &Path| {
        d.join(rigcal_devices::session::journal::JOURNAL_FILE)
            .exists()
    };
    let empty = dir
        .read_dir()
        .map_err(|source| io("reading", dir, source))?
        .next()
        .is_none();
    if !journal(dir) && !journal(&dir.join("division")) && !empty {
        return Err(DemoError::NotADemo(dir.to_path_buf()));
    }
    std::fs::remove_dir_all(dir).map_err(|source| io("removing", dir, source))
}
