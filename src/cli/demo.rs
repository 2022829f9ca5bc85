//! `rigcal demo`: the whole job on simulated devices, step by step through the library.
//!
//! 1. A dry-run session of seed 000's simulation (`sim/paper-sim.toml`) on the ideal-instrument
//!    rig (conventions §2): plan, drivers and emulators on the virtual clock, every row on disk.
//! 2. The variable D-H model (division, CEPs per region, FCMAC) from that recording.
//! 3. The Fig. 6 and Fig. 7 paths: position error of the simulated arm uncalibrated, with the
//!    conventional model, the regions' CEPs and the FCMAC; plots.
//! 4. A shorter session on the real rig (`rigs/rv-m2.toml`, `sim/rig-realistic.toml`): the table's
//!    travel and the 15° pin rule at work (points dropped with reasons), registration,
//!    identification, evaluation along a path inside the measurable workspace (the Fig. 6 path
//!    cannot be measured there), and a diagnosis of what the geometric model leaves out.
//!
//! Everything goes to `--out`; `summary.txt` there repeats the closing table.

use crate::calibration::{self, rig_check, CalibrationOptions, Source};
use crate::kinematics::Robot;
use crate::model::{ModelFile, Provenance};
use crate::recording::Recording;
use crate::report::{PathResult, PathSpec};
use crate::rig::Rig;
use crate::session::{read_plan, write_plan, SessionOptions, SessionReport};
use anyhow::{bail, Context, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const PAPER_RIG: &str = "rigs/rv-m2-ideal.toml";
const PAPER_SCENARIO: &str = "sim/paper-sim.toml";
const REAL_RIG: &str = "rigs/rv-m2.toml";
const REAL_SCENARIO: &str = "sim/rig-realistic.toml";

/// Arguments of `rigcal demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory for the recordings, models, reports and plots (the demo's own subdirectories
    /// there are replaced on a new run).
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    /// Points of the paper-scenario session (the paper measures 2200).
    #[arg(long, default_value_t = 2200)]
    points: usize,
    /// Points of the session on the real rig's constraints.
    #[arg(long, default_value_t = 300)]
    rig_points: usize,
    /// Accuracy the variable D-H model must reach in every region (mm).
    #[arg(long, default_value_t = 0.02)]
    accuracy_mm: f64,
    /// Seed of the plans and the learner.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

pub fn run(a: Args) -> Result<()> {
    for f in [PAPER_RIG, PAPER_SCENARIO, REAL_RIG, REAL_SCENARIO] {
        if !Path::new(f).exists() {
            bail!("{f} not found: run `rigcal demo` from the repository's top directory (it reads rigs/ and sim/)");
        }
    }
    anyhow::ensure!(a.points >= 100, "--points must be at least 100");
    anyhow::ensure!(a.rig_points >= 60, "--rig-points must be at least 60");
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let out = |name: &str| a.out.join(name);
    for dir in ["paper", "rig"] {
        clear_session_dir(&out(dir))?;
    }
    let (paper_rig, real_rig) = (
        Rig::load(Path::new(PAPER_RIG))?,
        Rig::load(Path::new(REAL_RIG))?,
    );
    heading("1. Dry-run session: seed 000's simulation on the ideal-instrument RV-M2");
    let started = std::time::Instant::now();
    let paper_session = DrySession::planned(PAPER_RIG, PAPER_SCENARIO, a.points, a.seed);
    dry_session(&paper_session, &out("paper"))?;
    heading("2. Variable D-H model from the recording: division, CEPs per region, FCMAC");
    calibrate(&paper_rig, &out("paper"), &a, &out("paper-model.json"))?;
    heading("3. Evaluation along the paper's paths (true simulated arm vs target)");
    let paper_paths = vec![
        calibration::fig6_path(&paper_rig, 101),
        calibration::fig7_path(&paper_rig, 101)?,
    ];
    let traced = calibration::PAPER_TRACED_CEPS.map(String::from);
    let paper_results = super::evaluate::evaluate(
        &out("paper-model.json"),
        Path::new(PAPER_SCENARIO),
        &paper_paths,
        &traced,
        Some(&out("paper-plots")),
    )?;
    heading("4. Dry-run session on the real rig's constraints (table travel, 15° pin rule, panel)");
    dry_session(
        &DrySession::planned(REAL_RIG, REAL_SCENARIO, a.rig_points, a.seed),
        &out("rig"),
    )?;
    heading("5. Conventional identification from the rig recording");
    identify(&real_rig, &out("rig"), &out("rig-model.json"))?;
    let planned = read_plan(&out("rig").join("plan.csv"), &real_rig)?;
    let rig_path = rig_check::measurable_path(&real_rig, &planned, 101).context(
        "no two planned points of the rig session are joined by a measurable straight joint path",
    )?;
    heading(&format!(
        "6. Measured by the rig along {} (the Fig. 6 path lies outside the table's reach)",
        rig_path.name
    ));
    let rig_results = rig_path_check(&real_rig, &out("rig-model.json"), &rig_path, &a.out)?;
    heading("7. Diagnosis: what the geometric model leaves out of the rig recording");
    diagnose(
        &real_rig,
        &out("rig"),
        &out("rig-plots"),
        &out("rig-diagnosis.json"),
    )?;

    let mut summary = String::new();
    let _ = writeln!(
        summary,
        "rigcal demo summary (seed {}, {:.1} s wall)",
        a.seed,
        started.elapsed().as_secs_f64()
    );
    let _ = writeln!(summary, "paper scenario, ideal instrument: true position error of the simulated arm, mean / max in mm");
    for (spec, results) in paper_paths.iter().zip(&paper_results) {
        summary_rows(&mut summary, spec, results);
    }
    let _ = writeln!(
        summary,
        "real rig: distance to target measured by the rig itself, mean / max in mm"
    );
    summary_rows(&mut summary, &rig_path, &rig_results);
    let _ = writeln!(summary, "files in {}: paper/, rig/, rig-path-nominal/, rig-path-compensated/ (session recordings, plans, journals), rig-path-nominal.csv and rig-path-compensated.csv (the path as planned: joint commands and table targets), paper-model.json, rig-model.json, rig-diagnosis.json, paper-plots/ and rig-plots/ (SVG), summary.txt", a.out.display());
    heading("Summary");
    print!("{summary}");
    let file = out("summary.txt");
    std::fs::write(&file, &summary).with_context(|| format!("writing {}", file.display()))
}

/// Step 2: the variable D-H model from the recording in `dir`, written to `model`.
fn calibrate(rig: &Rig, dir: &Path, a: &Args, model: &Path) -> Result<()> {
    let rec = super::identify::read_recording(rig, dir)?;
    let observations = super::observations(&rec);
    let opts = CalibrationOptions {
        accuracy_mm: a.accuracy_mm,
        seed: a.seed,
        ..CalibrationOptions::default()
    };
    let label = dir.display().to_string();
    let calibrated = super::calibrate::with_bar(&opts, |progress| {
        calibration::calibrate_with_progress(
            rig,
            Source::Offline {
                observations: &observations,
                label,
            },
            &opts,
            progress,
        )
    })?;
    calibrated.model.save(model)?;
    println!("model written to {}", model.display());
    Ok(())
}

/// Runs the path twice on the rig — at the nominal commands and at the commands the identified
/// model compensates — each as a session reusing the rig session's registration (one frame),
/// and returns the measured distance to the target per point. On the real rig this is how a
/// model is checked: the truth is what the instrument measures.
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
    let mut results = Vec::new();
    for (label, tag, points) in [
        ("uncalibrated", "nominal", &commands.nominal),
        (name.as_str(), "compensated", &commands.compensated),
    ] {
        let plan_file = out.join(format!("rig-path-{tag}.csv"));
        write_plan(&plan_file, rig, &rig_check::path_plan(rig, points))?;
        let dir = out.join(format!("rig-path-{tag}"));
        clear_session_dir(&dir)?;
        let session = DrySession {
            plan: Plan::File(&plan_file),
            seed: None,
            registration_from: Some(out.join("rig")),
            ..DrySession::planned(REAL_RIG, REAL_SCENARIO, 0, 0)
        };
        dry_session(&session, &dir)?;
        let rec = Recording::read(&dir, rig.chain.joints())?;
        let errors = rig_check::measured_errors(&rec, &commands.targets);
        results.push(PathResult {
            model: label.to_string(),
            errors,
            traces: Vec::new(),
            failures: 0,
        });
    }
    let plots = out.join("rig-plots");
    std::fs::create_dir_all(&plots)?;
    let file = plots.join("rig-path-measured-errors.svg");
    crate::report::plot_errors(
        &file,
        &format!("distance to target measured by the rig along {}", path.name),
        &results,
    )?;
    println!(
        "{} (101 points), measured by the rig (panel quantisation and table accuracy included):",
        path.name
    );
    for r in &results {
        let st = r.stats();
        let missed = r.errors.iter().filter(|e| e.is_nan()).count();
        println!(
            "  {:<14} mean {:.4} mm   max {:.4} mm   {missed} point(s) not measured",
            r.model, st.mean_mm, st.max_mm
        );
    }
    println!("  plot: {}", file.display());
    let floor = rig_check::resolution_floor(rig, &commands.compensated);
    println!(
        "  the controller's {}° command resolution alone moves the compensated tip by {:.4} mm mean, {:.4} mm max: the floor of joint-command compensation on this rig",
        rig_check::resolution_deg(rig),
        floor.iter().sum::<f64>() / floor.len().max(1) as f64,
        floor.iter().copied().fold(0.0, f64::max)
    );
    Ok(results)
}

/// What a dry-run session measures.
enum Plan<'a> {
    /// This many points planned here, the dropped candidates reported.
    Points(usize),
    /// The points of this plan file.
    File(&'a Path),
}

/// A dry-run session as `rigcal session --sim` runs it: emulators on the virtual clock.
struct DrySession<'a> {
    rig: &'a str,
    scenario: &'a str,
    plan: Plan<'a>,
    /// Seed of the plan and the registration (None: the scenario's).
    seed: Option<u64>,
    /// Reuse this session's registration instead of registering again.
    registration_from: Option<PathBuf>,
}

impl<'a> DrySession<'a> {
    fn planned(rig: &'a str, scenario: &'a str, points: usize, seed: u64) -> Self {
        Self {
            rig,
            scenario,
            plan: Plan::Points(points),
            seed: Some(seed),
            registration_from: None,
        }
    }
}

/// Runs a dry-run session into `dir`, printing what `rigcal session` prints. With
/// [`print_session`], the demo's only calls into the session API.
fn dry_session(s: &DrySession<'_>, dir: &Path) -> Result<()> {
    use crate::session::{
        estimate, plan, registration_points, run_session, ContactSettings, Progress, RigSpeeds,
    };
    let rig = Rig::load(Path::new(s.rig))?;
    let scenario =
        super::session::load_scenario(&rig, Path::new(s.rig), Some(Path::new(s.scenario)), None)?
            .context("a dry run needs its scenario")?;
    let seed = s.seed.unwrap_or(scenario.seed);
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let plan_path = dir.join("plan.csv");
    let points = match s.plan {
        Plan::Points(n) => {
            let p = plan(&rig, &super::plan::options(n, 8, 50, seed))?;
            super::plan::report_dropped(&rig, &p, &plan_path)?;
            p.points
        }
        Plan::File(file) => read_plan(file, &rig)?,
    };
    write_plan(&plan_path, &rig, &points)?;
    // Measured as read back from the file, as a session does.
    let points = read_plan(&plan_path, &rig)?;
    let mut opts = SessionOptions::new(dir);
    opts.seed = seed;
    let registration = match &s.registration_from {
        Some(from) => {
            let rec = Recording::read(from, rig.chain.joints())
                .with_context(|| format!("reading the session {}", from.display()))?;
            let reg = rec.session.and_then(|i| i.registration);
            opts.registration = Some(reg.with_context(|| {
                format!(
                    "{}: its session.toml holds no [registration]",
                    from.display()
                )
            })?);
            Vec::new()
        }
        None => registration_points(&rig, opts.registration_points, seed),
    };
    let all = [registration, points.clone()].concat();
    println!(
        "{}",
        super::plan::describe(&estimate(
            &rig,
            &all,
            &RigSpeeds::of(&rig),
            &ContactSettings::default()
        ))
    );
    let (devices, world) = super::session::open_rig(&rig, Some(&scenario), false)?;
    opts.fsync = !devices.clock.is_virtual();
    opts.info = crate::recording::SessionInfo {
        rig: Some(s.rig.to_string()),
        scenario: Some(s.scenario.to_string()),
        seed: Some(scenario.seed),
        notes: Some(format!(
            "rigcal session: {} points, dry run on the virtual clock",
            points.len()
        )),
        ..Default::default()
    };
    let report = run_session(
        &rig,
        devices,
        world,
        &points,
        opts,
        &Progress::auto(points.len()),
    )?;
    print_session(dir, &report);
    Ok(())
}

/// What `rigcal session` prints after a fresh run on the virtual clock.
fn print_session(dir: &Path, r: &SessionReport) {
    println!(
        "session {}: {} points, {} measured, {} skipped, {} via rows, {} retries, {} faults cleared",
        dir.display(), r.points, r.ok, r.skipped.len(), r.via, r.retries, r.faults_cleared.len()
    );
    for (p, why) in &r.skipped {
        println!("  point {p} skipped: {why}");
    }
    for f in &r.faults_cleared {
        println!("  cleared: {f}");
    }
    if let Some(rms) = r.registration_rms_mm {
        println!("registration RMS {rms:.3} mm (written to session.toml)");
    }
    println!(
        "rig time {:.0} s ({:.2} h) on the virtual clock: what the rig would have taken; wall time {:.2} s",
        r.rig_time_s, r.rig_time_s / 3600.0, r.wall.as_secs_f64()
    );
}

/// Step 5: conventional identification as `rigcal identify` prints it (the demo's one call into
/// identification's pipeline).
fn identify(rig: &Rig, recording: &Path, out: &Path) -> Result<()> {
    use super::identify::{
        identify_robust, print_fit_summary, print_outliers, read_recording, Level,
    };
    let rec = read_recording(rig, recording)?;
    let (chain, result, outliers, warning) = identify_robust(rig, &rec, Level::Full)?;
    println!(
        "recording {}: {} rows, {} measurements used",
        recording.display(),
        rec.rows.len(),
        result.after.n
    );
    print_outliers(&outliers);
    print!(
        "{}",
        super::parameter_table(crate::kinematics::Robot::layout(&chain), &result, None)
    );
    print_fit_summary(&result);
    let provenance = Provenance {
        recording: Some(recording.display().to_string()),
        measurements: result.after.n,
        notes: warning,
    };
    let mut file = ModelFile::constant(rig, &result, provenance);
    file.outliers = outliers;
    file.save(out)?;
    println!("model written to {}", out.display());
    Ok(())
}

/// Step 7: the diagnosis as `rigcal diagnose` prints it, its report and plots written.
fn diagnose(rig: &Rig, recording: &Path, plots: &Path, json: &Path) -> Result<()> {
    let rec = super::identify::read_recording(rig, recording)?;
    let report = crate::diagnosis::diagnose(
        rig,
        &rec,
        &crate::diagnosis::Options {
            heldout: Vec::new(),
        },
    )
    .with_context(|| format!("diagnosing {}", recording.display()))?;
    println!("recording {}", recording.display());
    print!("{}", report.text());
    std::fs::write(json, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", json.display()))?;
    println!("report written to {}", json.display());
    let written = crate::diagnosis::plots::write(rig, &rec, plots)
        .with_context(|| format!("writing plots to {}", plots.display()))?;
    println!("{written} plot(s) written to {}", plots.display());
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

fn summary_rows(s: &mut String, spec: &PathSpec, results: &[PathResult]) {
    let _ = writeln!(s, "  {}", spec.name);
    let _ = write!(s, "   ");
    for r in results {
        let st = r.stats();
        let _ = write!(s, "  {} {:.4} / {:.4}", r.model, st.mean_mm, st.max_mm);
    }
    s.push('\n');
}
