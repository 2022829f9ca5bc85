//! `rigcal demo`: the whole job on simulated devices, step by step through the library.
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
//! Everything goes to `--out`; `summary.txt` there repeats the closing table and
//! `summary.json` holds its figures.

use anyhow::{bail, Context, Result};
use rigcal_calibration::{self as calibration, CalibrationOptions, PathFigures, Source};
use rigcal_core::kinematics::Robot;
use rigcal_core::rig::Rig;
use rigcal_model::division::{Selection, Space};
use rigcal_model::learners::{FcmacTraining, LearnerKind, LearnerSettings};
use rigcal_model::model::{ModelBody, ModelFile};
use rigcal_model::report::{mean_max_rows, PathSpec};
use rigcal_paper::paper_regime::{FigureRun, PaperFigure, PaperRegimeSummary};
use rigcal_paper::sec7::{self, Sec7Files, Sec7Options, Sec7Report, Sec7Stage, Sec7Summary};
use rigcal_sim::world::Scenario;
use serde::Serialize;
use std::path::{Path, PathBuf};

const PAPER_RIG: &str = "rigs/rv-m2-ideal.toml";
const PAPER_SCENARIO: &str = "sim/paper-fig6.toml";
const REAL_RIG: &str = "rigs/rv-m2.toml";
const REAL_SCENARIO: &str = "sim/rig-sec7.toml";
/// The point of Fig. 8's unmeasurable region: on the Fig. 6 path, half way along.
const FIG8_POINT: [f64; 3] = [92.0, 75.0, -22.0];

/// Arguments of `rigcal demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory for the recordings, models, reports and plots (the demo's own subdirectories
    /// there are replaced on a new run).
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    /// Accuracy the section 7 division demands on the real rig (mm; the paper's 0.5).
    #[arg(long, default_value_t = 0.5)]
    rig_accuracy_mm: f64,
    /// Points of the section 7 path, measured once per method and command path.
    #[arg(long, default_value_t = 101)]
    path_points: usize,
    /// Accuracy the variable D-H model must reach in every region (mm; the paper's 0.1).
    #[arg(long, default_value_t = 0.1)]
    accuracy_mm: f64,
    /// Seed of the divisions, the plans and the learner.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Train every FCMAC and CMAC on the regions' CEPs with what each region's measurements
    /// cannot see put back to its parent's, moving predicted points by at most this fraction
    /// of the demanded accuracy (`rigcal calibrate --learner-tolerance`; 0: the paper's)
    /// [default: 0.5 with position training, 0 with `--fcmac-training ceps`].
    #[arg(long, value_name = "FRACTION")]
    learner_tolerance: Option<f64>,
    /// What every FCMAC is trained to reproduce (`rigcal calibrate --fcmac-training`).
    #[arg(long, value_enum, default_value_t = FcmacTraining::Positions)]
    fcmac_training: FcmacTraining,
}

impl Args {
    /// The paper's learner sizes with the FCMAC training asked for.
    fn learner_settings(&self) -> LearnerSettings {
        LearnerSettings {
            training: self.fcmac_training,
            ..Default::default()
        }
    }
}

/// What `summary.json` holds.
#[derive(Debug, Serialize)]
struct DemoSummary {
    format: &'static str,
    seed: u64,
    wall_s: f64,
    paper: PaperRegimeSummary,
    rig: Sec7Summary,
}

pub fn run(a: Args) -> Result<()> {
    for f in [PAPER_RIG, PAPER_SCENARIO, REAL_RIG, REAL_SCENARIO] {
        if !Path::new(f).exists() {
            bail!("{f} not found: run `rigcal demo` from the repository's top directory (it reads rigs/ and sim/)");
        }
    }
    anyhow::ensure!(a.path_points >= 2, "--path-points must be at least 2");
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let started = std::time::Instant::now();
    let paper = paper_steps(&a)?;
    let rig = rig_steps(&a)?;
    let wall_s = started.elapsed().as_secs_f64();
    let mut summary = format!(
        "rigcal demo summary (seed {}, {wall_s:.1} s wall)\n{}",
        a.seed,
        paper.text()
    );
    summary.push_str(&rig_summary_text(&rig));
    summary.push_str(&format!("files in {}: paper-fig6-model.json, paper-fig7-model.json, paper-fig8-model.json, paper-fig6-cmac-model.json, paper-fig6-d-optimal-10-model.json and paper-fig7-d-optimal-9-model.json (half the measurements), paper-plots/ (SVG, CSV), rig/ (section 7: division/, path-cartesian/, path-joint/ session recordings, plans and journals; sec7-model.json), rig-plots/ (SVG), rig-diagnosis.json, summary.txt, summary.json\n", a.out.display()));
    heading("Summary");
    print!("{summary}");
    let file = a.out.join("summary.txt");
    std::fs::write(&file, &summary).with_context(|| format!("writing {}", file.display()))?;
    let json = DemoSummary {
        format: "rigcal-demo-summary",
        seed: a.seed,
        wall_s,
        paper,
        rig: rig.summary(),
    };
    let file = a.out.join("summary.json");
    std::fs::write(&file, serde_json::to_string_pretty(&json)? + "\n")
        .with_context(|| format!("writing {}", file.display()))
}

/// The rig part of `summary.txt`: per command path, each method as the rig measured it.
fn rig_summary_text(rig: &Sec7Report) -> String {
    let (ident, tests) = rig.measurements();
    let mut s = format!(
        "real rig, seed 000 section 7 ({REAL_SCENARIO}): {} regions (paper {}), {ident} identification and {tests} test measurements, {} unmeasurable; rig time {:.2} h on the dry-run clock ({:.2} h planned); distance to target measured by the rig itself, mean / max in mm (paper: uncalibrated 0.3–2.5, conventional below 1.2, variable below 0.5)\n",
        rig.regions(),
        sec7::PAPER_REGIONS,
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

/// Step 1: Figs. 6, 7 and 8 and the CEP jumps in the paper's regime.
fn paper_steps(a: &Args) -> Result<PaperRegimeSummary> {
    let rig = Rig::load(Path::new(PAPER_RIG))?;
    let sc = Scenario::load(Path::new(PAPER_SCENARIO), None)?;
    let opts = CalibrationOptions {
        accuracy_mm: a.accuracy_mm,
        seed: a.seed,
        learner_tolerance: a.learner_tolerance,
        learner_settings: a.learner_settings(),
        ..Default::default()
    };
    heading(
        "1. Seed 000's simulations in the paper's regime (sim/paper-fig6.toml, ideal instrument)",
    );
    let fig6_path = calibration::fig6_path(&rig, 101);
    let fig6 = paper_model(a, &rig, &sc, "fig6", &opts)?;
    let fig6_run = paper_run(a, PaperFigure::Fig6, Selection::Kappa, &fig6, &fig6_path)?;
    // D-optimal locations: at the cap of 130 the κ rule leaves regions above 0.1 mm on the
    // Fig. 7 path (0.129 mm at seed 1); D-optimal ones keep them below it (0.072).
    let cartesian = CalibrationOptions {
        space: Space::Cartesian,
        selection: Selection::DOptimal,
        ..opts.clone()
    };
    let fig7 = paper_model(a, &rig, &sc, "fig7", &cartesian)?;
    let fig7_run = paper_run(
        a,
        PaperFigure::Fig7,
        Selection::DOptimal,
        &fig7,
        &calibration::fig7_path(&rig, 101)?,
    )?;
    let fig8_opts = CalibrationOptions {
        unmeasurable_at: Some(FIG8_POINT),
        unmeasurable_depth: Some(leaf_depth_at(&fig6.0, &rig, FIG8_POINT)?),
        ..opts.clone()
    };
    let fig8 = paper_model(a, &rig, &sc, "fig8", &fig8_opts)?;
    let fig8_run = paper_run(a, PaperFigure::Fig8, Selection::Kappa, &fig8, &fig6_path)?;
    let half_budget = half_budget_runs(a, &rig, &sc, &opts)?;
    heading("The same Fig. 6 division with Albus's CMAC in place of the FCMAC");
    let cmac = calibration::with_learner(&fig6.0, &rig, LearnerKind::Cmac, &opts.learner_settings)?;
    let cmac_file = a.out.join("paper-fig6-cmac-model.json");
    cmac.save(&cmac_file)?;
    let cmac_path = evaluate_paper(a, &cmac_file, &fig6_path)?;
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

/// Measurements per region of the half-budget runs (D-optimal locations): Fig. 6 (joint space)
/// and Fig. 7 (Cartesian, the cap of 130 reached). `scripts/measurements-vs-accuracy.sh` sweeps
/// them.
const HALF_BUDGET_PER_REGION: [usize; 2] = [10, 9];

/// Figs. 6 and 7 at about half the paper's measurements: D-optimal locations, fewer per region.
fn half_budget_runs(
    a: &Args,
    rig: &Rig,
    sc: &Scenario,
    opts: &CalibrationOptions,
) -> Result<Vec<FigureRun>> {
    heading("Figs. 6 and 7 with half the measurements: D-optimal locations, fewer per region");
    let fig7_path = calibration::fig7_path(rig, 101)?;
    let cases = [
        (
            PaperFigure::Fig6,
            Space::Joint,
            calibration::fig6_path(rig, 101),
        ),
        (PaperFigure::Fig7, Space::Cartesian, fig7_path),
    ];
    let mut runs = Vec::new();
    for ((figure, space, path), per_region) in cases.into_iter().zip(HALF_BUDGET_PER_REGION) {
        let o = CalibrationOptions {
            space,
            per_region,
            selection: Selection::DOptimal,
            ..opts.clone()
        };
        let name = format!("{}-d-optimal-{per_region}", figure_tag(figure));
        let model = paper_model(a, rig, sc, &name, &o)?;
        runs.push(paper_run(a, figure, Selection::DOptimal, &model, &path)?);
    }
    Ok(runs)
}

fn figure_tag(figure: PaperFigure) -> &'static str {
    match figure {
        PaperFigure::Fig6 => "fig6",
        PaperFigure::Fig7 => "fig7",
        PaperFigure::Fig8 => "fig8",
    }
}

/// A planning-mode calibration on the paper's scenario, printed and saved as
/// `paper-NAME-model.json`: the model and its file.
fn paper_model(
    a: &Args,
    rig: &Rig,
    sc: &Scenario,
    name: &str,
    opts: &CalibrationOptions,
) -> Result<(ModelFile, PathBuf)> {
    let file = a.out.join(format!("paper-{name}-model.json"));
    println!(
        "\n-- {name}: rigcal calibrate --scenario {PAPER_SCENARIO} --division {:?}",
        opts.space
    );
    let c = calibration::calibrate(rig, Source::Scenario(sc), opts)?;
    print!("{}", c.text());
    c.model.save(&file)?;
    println!("model written to {}", file.display());
    Ok((c.model, file))
}

/// The run of `figure`: its model evaluated along `path`.
fn paper_run(
    a: &Args,
    figure: PaperFigure,
    selection: Selection,
    model: &(ModelFile, PathBuf),
    path: &PathSpec,
) -> Result<FigureRun> {
    let figures = evaluate_paper(a, &model.1, path)?;
    FigureRun::of(figure, selection, &model.0, figures)
        .context("the paper's calibration made no division")
}

/// Evaluates the model file along `path` on the paper's scenario, plots into `paper-plots/`.
fn evaluate_paper(a: &Args, model: &Path, path: &PathSpec) -> Result<PathFigures> {
    let traced = calibration::PAPER_TRACED_CEPS.map(String::from);
    let plots = a.out.join("paper-plots").join(
        model
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
    );
    let mut f = super::evaluate::evaluate(
        model,
        Path::new(PAPER_SCENARIO),
        std::slice::from_ref(path),
        &traced,
        Some(&plots),
    )?;
    f.pop().context("no path evaluated")
}

/// The depth of the leaf of `model`'s division containing `at` (file units).
fn leaf_depth_at(model: &ModelFile, rig: &Rig, at: [f64; 3]) -> Result<usize> {
    let ModelBody::Variable { tree, .. } = &model.model else {
        bail!("the Fig. 6 model has no division");
    };
    let space = rigcal_model::division::DivisionSpace::new(rig, tree.space)?;
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

/// Step 2: seed 000 section 7 on the rig's emulators ([`sec7`]), then a diagnosis of what the
/// geometric model leaves out of the division session's recording.
fn rig_steps(a: &Args) -> Result<Sec7Report> {
    let out = a.out.join("rig");
    clear_sec7_dir(&out)?;
    heading("2. Seed 000 section 7 on the real rig's emulators (sim/rig-sec7.toml): registration, region sessions, the path measured by the rig");
    let opts = Sec7Options {
        calibration: CalibrationOptions {
            space: Space::Cartesian,
            accuracy_mm: a.rig_accuracy_mm,
            seed: a.seed,
            learner_tolerance: a.learner_tolerance,
            learner_settings: a.learner_settings(),
            unmeasurable_halves: true,
            ..Default::default()
        },
        path_points: a.path_points,
        ..Default::default()
    };
    let files = Sec7Files {
        rig: Path::new(REAL_RIG),
        scenario: Path::new(REAL_SCENARIO),
        out: &out,
    };
    let report = sec7::run(files, &opts, &mut |stage| match stage {
        Sec7Stage::Division(n, cap) if n % 10 == 0 => {
            eprintln!("dividing: {n} regions (cap {cap})")
        }
        Sec7Stage::Division(..) => {}
        Sec7Stage::Path(cp) => eprintln!("measuring the path through the {cp} command path"),
    })?;
    print!("{}", report.text());
    for plot in report.plot(&a.out.join("rig-plots"))? {
        println!("plot: {}", plot.display());
    }
    heading(
        "3. Diagnosis: what the geometric model leaves out of the division session's recording",
    );
    let rig = Rig::load(Path::new(REAL_RIG))?;
    diagnose(
        &rig,
        &files.division_dir(),
        &a.out.join("rig-plots"),
        &a.out.join("rig-diagnosis.json"),
    )?;
    Ok(report)
}

/// The diagnosis as `rigcal diagnose` prints it, its report and plots written.
fn diagnose(rig: &Rig, recording: &Path, plots: &Path, json: &Path) -> Result<()> {
    let rec = super::read_recording(rig, recording)?;
    let report = rigcal_model::diagnosis::diagnose(rig, &rec, &Default::default())
        .with_context(|| format!("diagnosing {}", recording.display()))?;
    println!(
        "recording {}\n{}",
        recording.display(),
        report.text().trim_end()
    );
    std::fs::write(json, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", json.display()))?;
    let written = rigcal_model::diagnosis::plots::write(rig, &rec, plots)?;
    println!(
        "report written to {}\n{written} plot(s) written to {}",
        json.display(),
        plots.display()
    );
    Ok(())
}

fn heading(text: &str) {
    println!("\n== {text}");
}

/// Removes the section 7 directory an earlier demo wrote (its division session holds a
/// journal); refuses anything else.
fn clear_sec7_dir(dir: &Path) -> Result<()> {
    if !dir.exists() {
        return Ok(());
    }
    let journal = |d: &Path| {
        d.join(rigcal_devices::session::journal::JOURNAL_FILE)
            .exists()
    };
    if !journal(dir) && !journal(&dir.join("division")) && dir.read_dir()?.next().is_some() {
        bail!(
            "{} exists and is not a directory of an earlier demo; choose another --out",
            dir.display()
        );
    }
    std::fs::remove_dir_all(dir).with_context(|| format!("removing {}", dir.display()))
}
