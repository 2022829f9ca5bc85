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
//! 2. A shorter session on the real rig (`rigs/rv-m2.toml`, `sim/rig-realistic.toml`): the table's
//!    travel and the 15° pin rule at work (points dropped with reasons), registration,
//!    identification, evaluation along a path inside the measurable workspace (the Fig. 6 path
//!    cannot be measured there), and a diagnosis of what the geometric model leaves out.
//!
//! Everything goes to `--out`; `summary.txt` there repeats the closing table and
//! `summary.json` holds its figures.

use crate::calibration::{
    self, rig_check, CalibrationOptions, FigureRun, MethodFigures, PaperFigure, PaperRegimeSummary,
    PathFigures, Source,
};
use crate::division::{Selection, Space};
use crate::identification::Level;
use crate::kinematics::Robot;
use crate::learners::LearnerKind;
use crate::model::{ModelBody, ModelFile};
use crate::recording::{Recording, RegistrationInfo, SessionInfo};
use crate::report::{mean_max_rows, PathResult, PathSpec};
use crate::rig::Rig;
use crate::session::{read_plan, write_plan, SessionOptions};
use crate::world::Scenario;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

const PAPER_RIG: &str = "rigs/rv-m2-ideal.toml";
const PAPER_SCENARIO: &str = "sim/paper-fig6.toml";
const REAL_RIG: &str = "rigs/rv-m2.toml";
const REAL_SCENARIO: &str = "sim/rig-realistic.toml";
/// The point of Fig. 8's unmeasurable region: on the Fig. 6 path, half way along.
const FIG8_POINT: [f64; 3] = [92.0, 75.0, -22.0];

/// Arguments of `rigcal demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory for the recordings, models, reports and plots (the demo's own subdirectories
    /// there are replaced on a new run).
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    /// Points of the session on the real rig's constraints.
    #[arg(long, default_value_t = 300)]
    rig_points: usize,
    /// Accuracy the variable D-H model must reach in every region (mm; the paper's 0.1).
    #[arg(long, default_value_t = 0.1)]
    accuracy_mm: f64,
    /// Seed of the divisions, the plans and the learner.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// What `summary.json` holds.
#[derive(Debug, Serialize)]
struct DemoSummary {
    format: &'static str,
    seed: u64,
    wall_s: f64,
    paper: PaperRegimeSummary,
    rig: RigSummary,
}

/// The rig part of `summary.json`: the path measured by the rig itself.
#[derive(Debug, Serialize)]
struct RigSummary {
    path: String,
    methods: Vec<MethodFigures>,
}

pub fn run(a: Args) -> Result<()> {
    for f in [PAPER_RIG, PAPER_SCENARIO, REAL_RIG, REAL_SCENARIO] {
        if !Path::new(f).exists() {
            bail!("{f} not found: run `rigcal demo` from the repository's top directory (it reads rigs/ and sim/)");
        }
    }
    anyhow::ensure!(a.rig_points >= 60, "--rig-points must be at least 60");
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    clear_session_dir(&a.out.join("rig"))?;
    let started = std::time::Instant::now();
    let paper = paper_steps(&a)?;
    let rig = rig_steps(&a)?;
    let wall_s = started.elapsed().as_secs_f64();
    let mut summary = format!(
        "rigcal demo summary (seed {}, {wall_s:.1} s wall)\n{}",
        a.seed,
        paper.text()
    );
    summary.push_str("real rig: distance to target measured by the rig itself, mean / max in mm\n");
    summary.push_str(&mean_max_rows(&rig.0, &rig.1));
    summary.push_str(&format!("files in {}: paper-fig6-model.json, paper-fig7-model.json, paper-fig8-model.json, paper-fig6-cmac-model.json, paper-fig6-d-optimal-10-model.json and paper-fig7-d-optimal-9-model.json (half the measurements), paper-plots/ (SVG, CSV), rig/, rig-path-nominal/, rig-path-compensated/ (session recordings, plans, journals), rig-path-nominal.csv and rig-path-compensated.csv (the path as planned: joint commands and table targets), rig-model.json, rig-diagnosis.json, rig-plots/ (SVG), summary.txt, summary.json\n", a.out.display()));
    heading("Summary");
    print!("{summary}");
    let file = a.out.join("summary.txt");
    std::fs::write(&file, &summary).with_context(|| format!("writing {}", file.display()))?;
    let json = DemoSummary {
        format: "rigcal-demo-summary",
        seed: a.seed,
        wall_s,
        paper,
        rig: RigSummary {
            path: rig.0,
            methods: rig.1.iter().map(|r| MethodFigures::of(r, &[])).collect(),
        },
    };
    let file = a.out.join("summary.json");
    std::fs::write(&file, serde_json::to_string_pretty(&json)? + "\n")
        .with_context(|| format!("writing {}", file.display()))
}

/// Step 1: Figs. 6, 7 and 8 and the CEP jumps in the paper's regime.
fn paper_steps(a: &Args) -> Result<PaperRegimeSummary> {
    let rig = Rig::load(Path::new(PAPER_RIG))?;
    let sc = Scenario::load(Path::new(PAPER_SCENARIO), None)?;
    let opts = CalibrationOptions {
        accuracy_mm: a.accuracy_mm,
        seed: a.seed,
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
        .error_split(&crate::world::fig6_path(101, rig.chain.dof()))
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
    let space = crate::division::DivisionSpace::new(rig, tree.space)?;
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

/// Steps 2–5 on the real rig's constraints; the measured path's name and results.
fn rig_steps(a: &Args) -> Result<(String, Vec<PathResult>)> {
    let out = |name: &str| a.out.join(name);
    let rig = Rig::load(Path::new(REAL_RIG))?;
    heading("2. Dry-run session on the real rig's constraints (table travel, 15° pin rule, panel)");
    dry_session(
        REAL_RIG,
        REAL_SCENARIO,
        Plan::Points(a.rig_points, a.seed),
        &out("rig"),
    )?;
    heading("3. Conventional identification from the rig recording");
    identify(&rig, &out("rig"), &out("rig-model.json"))?;
    let planned = read_plan(&out("rig").join("plan.csv"), &rig)?;
    let path = rig_check::measurable_path(&rig, &planned, 101).context(
        "no two planned points of the rig session are joined by a measurable straight joint path",
    )?;
    heading(&format!(
        "4. Measured by the rig along {} (the Fig. 6 path lies outside the table's reach)",
        path.name
    ));
    let results = rig_path_check(&rig, &out("rig-model.json"), &path, &a.out)?;
    heading("5. Diagnosis: what the geometric model leaves out of the rig recording");
    diagnose(
        &rig,
        &out("rig"),
        &out("rig-plots"),
        &out("rig-diagnosis.json"),
    )?;
    Ok((path.name, results))
}

/// Runs the path twice on the rig — at the nominal commands and at the commands the identified
/// model compensates — each as a session reusing the rig session's registration (one frame).
/// On the real rig this is how a model is checked: the truth is what the instrument measures.
fn rig_path_check(
    rig: &Rig,
    model_path: &Path,
    path: &PathSpec,
    out: &Path,
) -> Result<Vec<PathResult>> {
    let models = ModelFile::load(model_path)?
        .file
        .error_models(rig, model_path)?;
    let (name, model) = models.first().context("the model file holds no model")?;
    let commands = rig_check::path_commands(rig, model.as_ref(), path)?;
    let registration = rig_check::registration_of(rig, &out.join("rig"))?;
    let mut recordings = Vec::new();
    for (tag, points) in [
        ("nominal", &commands.nominal),
        ("compensated", &commands.compensated),
    ] {
        let plan = out.join(format!("rig-path-{tag}.csv"));
        write_plan(&plan, rig, &rig_check::path_plan(rig, points))?;
        let dir = out.join(format!("rig-path-{tag}"));
        clear_session_dir(&dir)?;
        dry_session(
            REAL_RIG,
            REAL_SCENARIO,
            Plan::File(
                &plan,
                registration,
                tag == "compensated"
                    && rig_check::command_path(rig)
                        == crate::rig::controller::CommandPath::Cartesian,
            ),
            &dir,
        )?;
        recordings.push(Recording::read(&dir, rig.chain.joints())?);
    }
    let check =
        rig_check::RigPathCheck::new(rig, path, &commands, name, &recordings[0], &recordings[1]);
    std::fs::create_dir_all(out.join("rig-plots"))?;
    let plot = out.join("rig-plots").join("rig-path-measured-errors.svg");
    check.plot(&plot)?;
    print!("{}", check.text(&plot));
    Ok(check.results)
}

/// What a dry-run session measures.
enum Plan<'a> {
    /// This many points planned here from a seed, the dropped candidates reported; then a
    /// registration.
    Points(usize, u64),
    /// The points of a plan file, in the frame of this registration; through the arm's
    /// Cartesian command (`MP`) if the flag is set.
    File(&'a Path, RegistrationInfo, bool),
}

/// Runs a dry-run session into `dir` as `rigcal session --sim` does: emulators on the virtual
/// clock. The demo's only calls into the session API.
fn dry_session(rig_file: &str, scenario: &str, plan: Plan<'_>, dir: &Path) -> Result<()> {
    use crate::session::{
        estimate, registration_points, run_session, ContactSettings, Progress, RigSpeeds,
    };
    let rig = Rig::load(Path::new(rig_file))?;
    let sc =
        super::session::load_scenario(&rig, Path::new(rig_file), Some(Path::new(scenario)), None)?
            .context("a dry run needs its scenario")?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let plan_path = dir.join("plan.csv");
    let mut opts = SessionOptions::new(dir);
    let (points, registration) = match plan {
        Plan::Points(n, seed) => {
            let p = crate::session::plan(&rig, &super::plan::options(n, 8, 50, seed))?;
            super::plan::report_dropped(&rig, &p, &plan_path)?;
            opts.seed = seed;
            (
                p.points,
                registration_points(&rig, opts.registration_points, seed),
            )
        }
        Plan::File(file, registration, _) => {
            opts.seed = sc.seed;
            opts.registration = Some(registration);
            (read_plan(file, &rig)?, Vec::new())
        }
    };
    write_plan(&plan_path, &rig, &points)?;
    // Measured as read back from the file, as a session does.
    let points = read_plan(&plan_path, &rig)?;
    let all = [registration, points.clone()].concat();
    println!(
        "{}",
        super::plan::describe(&estimate(
            &rig,
            &all,
            &RigSpeeds::of(&rig),
            &ContactSettings::of(&rig)
        ))
    );
    let cartesian = matches!(plan, Plan::File(_, _, true));
    let mut opened = crate::devices::open_rig(&rig, Some(&sc), crate::devices::SimClock::Virtual)?;
    if cartesian {
        let crate::devices::OpenedRig { devices, hook } = opened;
        let arm = Box::new(crate::devices::safety::CartesianArm::new(devices.arm));
        opened = crate::devices::OpenedRig {
            devices: crate::devices::RigDevices { arm, ..devices },
            hook,
        };
    }
    opts.fsync = !opened.devices.clock.is_virtual();
    let notes = format!(
        "rigcal session: {} points, dry run on the virtual clock",
        points.len()
    );
    opts.info = SessionInfo {
        rig: Some(rig_file.into()),
        scenario: Some(scenario.into()),
        seed: Some(sc.seed),
        notes: Some(notes),
        ..Default::default()
    };
    let r = run_session(&rig, opened, &points, opts, &Progress::auto(points.len()))?;
    print_session(dir, &r);
    Ok(())
}

/// What `rigcal session` prints after a fresh dry run.
fn print_session(dir: &Path, r: &crate::session::SessionReport) {
    println!("session {}: {} points, {} measured, {} skipped, {} via rows, {} retries, {} faults cleared", dir.display(), r.points, r.ok, r.skipped.len(), r.via, r.retries, r.faults_cleared.len());
    for (p, why) in &r.skipped {
        println!("  point {p} skipped: {why}");
    }
    for f in &r.faults_cleared {
        println!("  cleared: {f}");
    }
    if let Some(rms) = r.registration_rms_mm {
        println!("registration RMS {rms:.3} mm (written to session.toml)");
    }
    println!("rig time {:.0} s ({:.2} h) on the virtual clock: what the rig would have taken; wall time {:.2} s", r.rig_time_s, r.rig_time_s / 3600.0, r.wall.as_secs_f64());
}

/// Step 3: conventional identification as `rigcal identify` prints it (the demo's one call into
/// the identification pipeline).
fn identify(rig: &Rig, recording: &Path, out: &Path) -> Result<()> {
    use super::identify::{print_identification, write_model};
    let rec = super::read_recording(rig, recording)?;
    let id = crate::identification::identify(rig, &rec, Level::Full, &Default::default())?;
    println!(
        "recording {}: {} rows, {} measurements used",
        recording.display(),
        rec.rows.len(),
        id.fit.after.n
    );
    print_identification(&id);
    write_model(rig, &id, recording, out)
}

/// Step 5: the diagnosis as `rigcal diagnose` prints it, its report and plots written.
fn diagnose(rig: &Rig, recording: &Path, plots: &Path, json: &Path) -> Result<()> {
    let rec = super::read_recording(rig, recording)?;
    let report = crate::diagnosis::diagnose(rig, &rec, &Default::default())
        .with_context(|| format!("diagnosing {}", recording.display()))?;
    println!(
        "recording {}\n{}",
        recording.display(),
        report.text().trim_end()
    );
    std::fs::write(json, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", json.display()))?;
    let written = crate::diagnosis::plots::write(rig, &rec, plots)?;
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

/// Removes a session directory an earlier demo wrote (it holds a journal); refuses anything else.
fn clear_session_dir(dir: &Path) -> Result<()> {
    if !dir.exists() {
        return Ok(());
    }
    if !dir.join(crate::session::journal::JOURNAL_FILE).exists() && dir.read_dir()?.next().is_some()
    {
        bail!(
            "{} exists and is not a session directory of an earlier demo; choose another --out",
            dir.display()
        );
    }
    std::fs::remove_dir_all(dir).with_context(|| format!("removing {}", dir.display()))
}
