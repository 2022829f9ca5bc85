//! Never silently wrong: counts out of range, plans and targets whose columns are ambiguous or
//! missing, and an empty plan are refused with the file and the remedy named; a model file with
//! a byte-order mark is read like the CSV and TOML files that accept one.

use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{read_targets, RecordingError};
use rigcal_core::rig::Rig;
use rigcal_devices::session::{
    plan, read_plan, write_plan, PlanError, PlanOptions, PlannedPoint, MAX_PLAN_POINTS,
};
use rigcal_model::identification::ResidualStats;
use rigcal_model::model::{FitSummary, ModelBody, ModelFile, Provenance};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

const RIG: &str = "rigs/rv-m2-ideal.toml";

fn rigcal(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .expect("run rigcal");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn rig() -> Rig {
    Rig::load(Path::new(RIG)).unwrap()
}

// ---- 1. counts checked up front -------------------------------------------------------------

#[test]
fn plan_refuses_zero_and_huge_point_counts_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let max = MAX_PLAN_POINTS.to_string();
    for (n, says) in [("0", "0 points"), ("99999999999", "above the maximum")] {
        let start = Instant::now();
        let (ok, _, err) = rigcal(&["plan", "--rig", RIG, "--points", n, "--out", s(&out)]);
        assert!(!ok, "--points {n} was accepted");
        assert!(err.contains(says) && err.contains(&max), "{err}");
        // Refused as the flag is read: no planning, no allocation, no plan file.
        assert!(start.elapsed() < Duration::from_secs(20), "{n}");
        assert!(!out.exists(), "{n}: a plan was written");
    }
}

#[test]
fn simulate_and_session_refuse_a_zero_count() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec");
    let (ok, _, err) = rigcal(&[
        "simulate",
        "--rig",
        RIG,
        "--scenario",
        "sim/paper-sim.toml",
        "--random",
        "0",
        "--out",
        s(&out),
    ]);
    assert!(!ok, "simulate --random 0 was accepted");
    assert!(
        err.contains("0 points") && err.contains("--random"),
        "{err}"
    );
    let (ok, _, err) = rigcal(&[
        "session",
        "--rig",
        RIG,
        "--sim",
        "sim/paper-sim.toml",
        "--points",
        "0",
        "--out",
        s(&out),
    ]);
    assert!(!ok, "session --points 0 was accepted");
    assert!(
        err.contains("0 points") && err.contains("--points"),
        "{err}"
    );
}

#[test]
fn help_states_the_maximum_count() {
    let max = MAX_PLAN_POINTS.to_string();
    for cmd in ["plan", "simulate", "session"] {
        let (ok, out, err) = rigcal(&[cmd, "--help"]);
        assert!(ok, "{err}");
        assert!(out.contains(&max), "{cmd} --help: {out}");
    }
}

#[test]
fn the_planner_refuses_a_zero_count() {
    let opts = PlanOptions {
        points: 0,
        ..PlanOptions::default()
    };
    let Err(e) = plan(&rig(), &opts) else {
        panic!("0 points planned")
    };
    assert!(matches!(e, PlanError::PointCount { wanted: 0 }), "{e}");
    let opts = PlanOptions {
        points: MAX_PLAN_POINTS + 1,
        ..PlanOptions::default()
    };
    let Err(e) = plan(&rig(), &opts) else {
        panic!("too many points planned")
    };
    assert!(e.to_string().contains(&MAX_PLAN_POINTS.to_string()), "{e}");
}

// ---- 2. plan files read by header name ------------------------------------------------------

/// Two points of the RV-M2 written as `rigcal plan` writes them; the file's text.
fn written_plan(dir: &Path) -> (Vec<PlannedPoint>, String) {
    let rig = rig();
    let dof = rig.chain.dof();
    let points: Vec<PlannedPoint> = (1..=2)
        .map(|k| PlannedPoint {
            point: k,
            region: format!("r{k}"),
            // Distinct values within every joint's limits (J3's are [-120°, 0°]).
            q: (0..dof).map(|j| -0.01 * (k * 10 + j) as f64).collect(),
            table_mm: [k as f64, 2.0 * k as f64, 3.0 * k as f64],
        })
        .collect();
    let path = dir.join("written.csv");
    write_plan(&path, &rig, &points).unwrap();
    (points, std::fs::read_to_string(&path).unwrap())
}

#[test]
fn a_plan_without_a_header_is_refused_not_short_of_its_first_point() {
    let dir = tempfile::tempdir().unwrap();
    let (_, text) = written_plan(dir.path());
    let headless: String = text.lines().skip(1).map(|l| format!("{l}\n")).collect();
    let path = dir.path().join("headless.csv");
    std::fs::write(&path, headless).unwrap();
    let e = read_plan(&path, &rig()).expect_err("a headless plan was read");
    let msg = e.to_string();
    assert!(matches!(e, PlanError::MissingHeader { .. }), "{msg}");
    assert!(
        msg.contains("headless.csv") && msg.contains("add the header line `point,region,"),
        "{msg}"
    );
}

#[test]
fn plan_columns_are_found_by_name_in_any_order() {
    let dir = tempfile::tempdir().unwrap();
    let (points, text) = written_plan(dir.path());
    // Reverse every line's fields: header and values stay together, positions all change.
    let reversed: String = text
        .lines()
        .map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            f.reverse();
            format!("{}\n", f.join(","))
        })
        .collect();
    let path = dir.path().join("reversed.csv");
    std::fs::write(&path, reversed).unwrap();
    let read = read_plan(&path, &rig()).unwrap();
    assert_eq!(read.len(), points.len());
    for (r, p) in read.iter().zip(&points) {
        assert_eq!((r.point, &r.region), (p.point, &p.region));
        assert_eq!(r.table_mm, p.table_mm);
        for (a, b) in r.q.iter().zip(&p.q) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
    }
    // A swapped header over unswapped values is read by the names, not the positions.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[0] = lines[0].replacen("table_x_mm,table_y_mm", "table_y_mm,table_x_mm", 1);
    lines[0] = lines[0].replacen("tip_x_mm,tip_y_mm", "tip_y_mm,tip_x_mm", 1);
    let path = dir.path().join("swapped.csv");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let read = read_plan(&path, &rig()).unwrap();
    assert_eq!(read[0].table_mm, [2.0, 1.0, 3.0]);
}

#[test]
fn a_plan_point_outside_the_joint_limits_is_refused_with_its_line_and_joint() {
    let dir = tempfile::tempdir().unwrap();
    let (_, text) = written_plan(dir.path());
    // J3 (limits -120°..0°) at +20° on the second point: a plan made for another rig, or edited.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let k = header.iter().position(|h| *h == "q3_deg").unwrap();
    let mut f: Vec<String> = lines[2].split(',').map(String::from).collect();
    f[k] = "20.0".into();
    lines[2] = f.join(",");
    let path = dir.path().join("outside.csv");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let msg = read_plan(&path, &rig()).expect_err("accepted").to_string();
    assert!(
        msg.contains("line 3") && msg.contains("J3") && msg.contains("outside its limits"),
        "{msg}"
    );
}

#[test]
fn a_plan_with_a_column_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (_, text) = written_plan(dir.path());
    let (header, rows) = text.split_once('\n').unwrap();
    assert!(header.contains(",q1_deg,q2_deg,"), "{header}");
    // `q1_deg` in place of `q2_deg` (the same number of fields, so nothing else gives it away),
    // and `q1_deg` added once more at the end.
    let renamed = format!("{}\n{rows}", header.replacen(",q2_deg,", ",q1_deg,", 1));
    let appended: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let extra = if i == 0 {
                "q1_deg"
            } else {
                l.split(',').nth(2).unwrap()
            };
            format!("{l},{extra}\n")
        })
        .collect();
    let path = dir.path().join("dup.csv");
    for content in [renamed, appended] {
        std::fs::write(&path, &content).unwrap();
        let e = read_plan(&path, &rig()).expect_err("a duplicated column was read");
        let msg = e.to_string();
        assert!(matches!(e, PlanError::DuplicateColumn { .. }), "{msg}");
        assert!(
            msg.contains("dup.csv") && msg.contains("`q1_deg` appears more"),
            "{msg}"
        );
    }
}

#[test]
fn an_empty_plan_is_refused_by_the_reader_and_by_the_session() {
    let dir = tempfile::tempdir().unwrap();
    let (_, text) = written_plan(dir.path());
    let header_only = format!("{}\n", text.lines().next().unwrap());
    let path = dir.path().join("empty.csv");
    for content in [header_only.as_str(), ""] {
        std::fs::write(&path, content).unwrap();
        let e = read_plan(&path, &rig()).expect_err("an empty plan was read");
        assert!(matches!(e, PlanError::EmptyPlan { .. }), "{e}");
    }
    std::fs::write(&path, header_only).unwrap();
    let (ok, out, err) = rigcal(&[
        "session",
        "--rig",
        RIG,
        "--sim",
        "sim/paper-sim.toml",
        "--plan",
        s(&path),
        "--out",
        s(&dir.path().join("session")),
    ]);
    assert!(!ok, "a session ran an empty plan: {out}");
    assert!(
        err.contains("empty.csv") && err.contains("no points"),
        "{err}"
    );
}

// ---- 3. targets with a column twice ---------------------------------------------------------

#[test]
fn a_targets_file_with_a_column_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("targets.csv");
    std::fs::write(&path, "x_mm,y_mm,z_mm,x_mm\n0,600,500,100\n").unwrap();
    let e = read_targets(&path, rig().chain.joints()).expect_err("x_mm twice was read");
    let msg = e.to_string();
    assert!(matches!(e, RecordingError::DuplicateColumn { .. }), "{msg}");
    assert!(
        msg.contains("targets.csv") && msg.contains("`x_mm`"),
        "{msg}"
    );
}

// ---- 4. a model file with a byte-order mark -------------------------------------------------

#[test]
fn a_model_file_with_a_byte_order_mark_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let rig = rig();
    let file = ModelFile::new(
        &rig,
        Provenance::default(),
        ModelBody::Constant {
            parameters: Vec::new(),
            fit: FitSummary {
                kappa_eq4: 1.0,
                before: ResidualStats::default(),
                after: ResidualStats::default(),
                sigma0_mm: 0.0,
                iterations: 0,
            },
        },
    );
    let path = dir.path().join("model.json");
    file.save(&path).unwrap();
    ModelFile::load(&path).expect("the model without a BOM");
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, format!("\u{feff}{text}")).unwrap();
    let loaded = ModelFile::load(&path).expect("the model with a BOM");
    assert_eq!(loaded.rig.name, rig.name);
}
