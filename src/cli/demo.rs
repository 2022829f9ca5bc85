//! `rigcal demo`: the whole job on simulated devices, through the same commands a user types.
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

use super::evaluate::{evaluate, fig6};
use crate::kinematics::Robot;
use crate::report::{joint_path, spherical_path, PathResult, PathSpec};
use crate::rig::Rig;
use crate::session::read_plan;
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
    let seed = a.seed.to_string();

    heading("1. Dry-run session: seed 000's simulation on the ideal-instrument RV-M2");
    let started = std::time::Instant::now();
    step(
        &[
            "session",
            "--rig",
            PAPER_RIG,
            "--sim",
            PAPER_SCENARIO,
            "--points",
            &a.points.to_string(),
            "--seed",
            &seed,
            "--out",
        ],
        &out("paper"),
    )?;

    heading("2. Variable D-H model from the recording: division, CEPs per region, FCMAC");
    step(
        &[
            "calibrate",
            "--rig",
            PAPER_RIG,
            "--accuracy-mm",
            &a.accuracy_mm.to_string(),
            "--seed",
            &seed,
            "--recording",
            &path_str(&out("paper")),
            "--out",
        ],
        &out("paper-model.json"),
    )?;

    heading("3. Evaluation along the paper's paths (true simulated arm vs target)");
    let paper_rig = Rig::load(Path::new(PAPER_RIG))?;
    let paper_paths = vec![
        fig6(&paper_rig, 101),
        spherical_path(
            &paper_rig,
            "Fig. 7 spherical path",
            [640.0, 20.0, 0.0],
            [740.0, 125.0, -20.0],
            101,
        )?,
    ];
    let paper_results = evaluate(
        &out("paper-model.json"),
        Path::new(PAPER_SCENARIO),
        &paper_paths,
        Some(&out("paper-plots")),
    )?;

    heading("4. Dry-run session on the real rig's constraints (table travel, 15° pin rule, panel)");
    step(
        &[
            "session",
            "--rig",
            REAL_RIG,
            "--sim",
            REAL_SCENARIO,
            "--points",
            &a.rig_points.to_string(),
            "--seed",
            &seed,
            "--out",
        ],
        &out("rig"),
    )?;
    heading("5. Conventional identification from the rig recording");
    step(
        &[
            "identify",
            "--rig",
            REAL_RIG,
            "--recording",
            &path_str(&out("rig")),
            "--out",
        ],
        &out("rig-model.json"),
    )?;
    let real_rig = Rig::load(Path::new(REAL_RIG))?;
    let rig_path = measurable_path(&real_rig, &out("rig").join("plan.csv"))?;
    heading(&format!(
        "6. Measured by the rig along {} (the Fig. 6 path lies outside the table's reach)",
        rig_path.name
    ));
    let rig_results = rig_path_check(&real_rig, &out("rig-model.json"), &rig_path, &a.out)?;
    heading("7. Diagnosis: what the geometric model leaves out of the rig recording");
    step(
        &[
            "diagnose",
            "--rig",
            REAL_RIG,
            "--recording",
            &path_str(&out("rig")),
            "--plots",
            &path_str(&out("rig-plots")),
            "--json",
        ],
        &out("rig-diagnosis.json"),
    )?;

    let mut summary = String::new();
    let _ = writeln!(
        summary,
        "rigcal demo summary (seed {}, {:.1} s wall)",
        a.seed,
        started.elapsed().as_secs_f64()
    );
    let _ = writeln!(
        summary,
        "paper scenario, ideal instrument: true position error of the simulated arm, mean / max in mm"
    );
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
    std::fs::write(&file, &summary).with_context(|| format!("writing {}", file.display()))?;
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
    let loaded = crate::model::ModelFile::load(model_path)?;
    let models = loaded.file.error_models(rig, model_path)?;
    let (name, model) = models.first().context("the model file holds no model")?;
    let nominal = crate::kinematics::ErrorParams::zeros(rig.chain.layout());
    let targets: Vec<nalgebra::Vector3<f64>> = path
        .points
        .iter()
        .map(|q| rig.chain.position(q, &nominal))
        .collect();
    let opts = crate::compensation::CompensationOptions::default();
    let compensated = path
        .points
        .iter()
        .zip(&targets)
        .map(|(q, t)| {
            crate::compensation::compensate_from(
                &rig.chain,
                model.as_ref(),
                t,
                rig.held(),
                q.clone(),
                &opts,
            )
            .map(|c| c.command)
            .with_context(|| format!("compensating the target {t:?}"))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut results = Vec::new();
    for (label, commands) in [
        ("uncalibrated", &path.points),
        (name.as_str(), &compensated),
    ] {
        let tag = if label == "uncalibrated" {
            "nominal"
        } else {
            "compensated"
        };
        let plan_file = out.join(format!("rig-path-{tag}.csv"));
        let points: Vec<crate::session::PlannedPoint> = commands
            .iter()
            .enumerate()
            .map(|(k, q)| crate::session::PlannedPoint {
                point: k + 1,
                region: "path".into(),
                q: q.clone(),
                table_mm: crate::session::plan::table_target(rig, q).unwrap_or_default(),
            })
            .collect();
        crate::session::write_plan(&plan_file, rig, &points)?;
        let dir = out.join(format!("rig-path-{tag}"));
        clear_session_dir(&dir)?;
        step(
            &[
                "session",
                "--rig",
                REAL_RIG,
                "--sim",
                REAL_SCENARIO,
                "--plan",
                &path_str(&plan_file),
                "--registration-from",
                &path_str(&out.join("rig")),
                "--out",
            ],
            &dir,
        )?;
        let rec = crate::recording::Recording::read(&dir, rig.chain.joints())?;
        let measured: Vec<&crate::recording::Measurement> = rec
            .rows
            .iter()
            .filter(|m| {
                m.region.as_deref() == Some("path") && m.status != crate::recording::Status::Via
            })
            .collect();
        let errors = measured
            .iter()
            .zip(&targets)
            .map(|(m, t)| m.position.map_or(f64::NAN, |p| (p - t).norm()))
            .collect();
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
        println!(
            "  {:<14} mean {:.4} mm   max {:.4} mm   {} point(s) not measured",
            r.model,
            st.mean_mm,
            st.max_mm,
            r.errors.iter().filter(|e| e.is_nan()).count()
        );
    }
    println!("  plot: {}", file.display());
    let floor = resolution_floor(rig, &compensated);
    println!(
        "  the controller's {}° command resolution alone moves the compensated tip by {:.4} mm mean, {:.4} mm max: the floor of joint-command compensation on this rig",
        rig.devices.clone().unwrap_or_default().arm.resolution_deg,
        floor.iter().sum::<f64>() / floor.len().max(1) as f64,
        floor.iter().copied().fold(0.0, f64::max)
    );
    Ok(results)
}

/// How far rounding each command to the arm controller's resolution moves the nominal tip (mm).
fn resolution_floor(rig: &Rig, commands: &[Vec<f64>]) -> Vec<f64> {
    let step = rig
        .devices
        .clone()
        .unwrap_or_default()
        .arm
        .resolution_deg
        .to_radians();
    let nominal = crate::kinematics::ErrorParams::zeros(rig.chain.layout());
    commands
        .iter()
        .map(|q| {
            let rounded: Vec<f64> = q.iter().map(|v| (v / step).round() * step).collect();
            (rig.chain.position(&rounded, &nominal) - rig.chain.position(q, &nominal)).norm()
        })
        .collect()
}

fn heading(text: &str) {
    println!("\n== {text}");
}

fn path_str(p: &Path) -> String {
    p.display().to_string()
}

/// Runs a subcommand whose last word is `last` (an output path).
fn step(words: &[&str], last: &Path) -> Result<()> {
    let mut w: Vec<String> = words.iter().map(|s| s.to_string()).collect();
    w.push(path_str(last));
    super::run_words(&w).with_context(|| format!("`rigcal {}`", w.join(" ")))
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

/// A straight joint path of 101 points between two planned points of the rig session whose every
/// point the rig can measure: the longest such among the first planned points.
fn measurable_path(rig: &Rig, plan: &Path) -> Result<PathSpec> {
    let pts: Vec<Vec<f64>> = read_plan(plan, rig)?
        .into_iter()
        .filter(|p| p.region != crate::session::plan::REFERENCE_REGION)
        .take(80)
        .map(|p| p.q)
        .collect();
    let nominal = crate::kinematics::ErrorParams::zeros(rig.chain.layout());
    let joints = rig.chain.joints();
    let mut best: Option<(f64, PathSpec)> = None;
    for (i, a) in pts.iter().enumerate() {
        for b in &pts[i + 1..] {
            let length = (rig.chain.position(a, &nominal) - rig.chain.position(b, &nominal)).norm();
            if best.as_ref().is_some_and(|(l, _)| *l >= length) {
                continue;
            }
            let deg = |q: &[f64]| -> Vec<f64> {
                rig.moving_joints()
                    .iter()
                    .map(|&j| joints[j].kind.to_file_units(q[j]))
                    .collect()
            };
            let (da, db) = (deg(a), deg(b));
            let fmt = |v: &[f64]| {
                v.iter()
                    .map(|x| format!("{x:.1}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            let name = format!("joint path ({}) → ({})", fmt(&da), fmt(&db));
            let spec = joint_path(rig, &name, &da, &db, 101);
            if spec.points.iter().all(|q| rig.measurable(q).is_ok()) {
                best = Some((length, spec));
            }
        }
    }
    best.map(|(_, s)| s).context(
        "no two planned points of the rig session are joined by a measurable straight joint path",
    )
}
