//! HTML reports of `identify`, `diagnose` and `calibrate`: self-contained (inline CSS and SVG,
//! no http(s) reference), with their sections, tables of the right rows, and the plots' text
//! (Okabe–Ito colours, no "-0" tick, a binned mean with its band). The model file keeps the
//! covariance; the diagnosis JSON carries `format` and `version`.

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::Rig;
use rigcal_model::identification::random_poses;
use rigcal_sim::world::World;
use std::path::Path;
use std::process::Command;

mod common;

fn ok(args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// The synthetic 8-joint rig and a noisy recording of it through an unknown tracker frame,
/// with one gross outlier, and a held-out recording.
fn setup(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf, std::path::PathBuf) {
    let urdf = dir.join("s8.urdf");
    std::fs::write(&urdf, common::synthetic8::urdf()).unwrap();
    let rig_path = dir.join("s8.toml");
    ok(&[
        "rig",
        "from-urdf",
        &s(&urdf),
        "--base",
        "base",
        "--tip",
        "marker",
        "--out",
        &s(&rig_path),
    ]);
    let rig = Rig::load(&rig_path).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut truth = ErrorParams::zeros(rig.chain.layout());
    for i in 0..rig.chain.layout().len() {
        if rng.random_bool(0.3) {
            let id = rig.chain.layout().ids()[i];
            truth.set(i, if id.kind.is_angle() { 0.001 } else { 0.3 });
        }
    }
    let frame = Isometry3::from_parts(
        Translation3::new(1500.0, -300.0, 800.0),
        UnitQuaternion::from_axis_angle(&Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)), 1.0),
    );
    let w = World::new(rig.chain.with_frame(frame), truth, 0.05, 11);
    let rec = dir.join("rec");
    w.record(
        &random_poses(rig.chain.joints(), rig.held(), 120, &mut rng),
        1,
    )
    .write_dir(&rec)
    .unwrap();
    // One row 5 mm off: an outlier with its line.
    let csv = rec.join("measurements.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let xi = header.iter().position(|h| *h == "x_mm").unwrap();
    let mut cells: Vec<String> = lines[10].split(',').map(String::from).collect();
    cells[xi] = (cells[xi].parse::<f64>().unwrap() + 5.0).to_string();
    lines[10] = cells.join(",");
    std::fs::write(&csv, lines.join("\n") + "\n").unwrap();
    let held = dir.join("held");
    w.record(
        &random_poses(rig.chain.joints(), rig.held(), 60, &mut rng),
        1000,
    )
    .write_dir(&held)
    .unwrap();
    (rig_path, rec, held)
}

/// The rows of the table with this id (the header row excluded).
fn table_rows(html: &str, id: &str) -> usize {
    let start = html
        .find(&format!("<table id=\"{id}\""))
        .unwrap_or_else(|| panic!("no table {id}"));
    let end = html[start..].find("</table>").unwrap() + start;
    html[start..end].matches("<tr").count() - 1
}

fn self_contained(html: &str) {
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(html.contains("<style>"));
    assert!(
        !html.contains("http://")
            || html.matches("http://").count()
                == html.matches("xmlns=\"http://www.w3.org/2000/svg\"").count(),
        "no link but the SVG namespace"
    );
    assert!(!html.contains("https://"));
    assert!(!html.contains("<script src") && !html.contains("<link "));
    assert!(!html.contains(">-0<"), "a -0 tick");
}

#[test]
fn the_identify_report_has_its_sections_tables_and_inline_plots() {
    let dir = tempfile::tempdir().unwrap();
    let (rig, rec, held) = setup(dir.path());
    let model = dir.path().join("m.json");
    let report = dir.path().join("r.html");
    ok(&[
        "identify",
        "--rig",
        &s(&rig),
        "--recording",
        &s(&rec),
        "--out",
        &s(&model),
        "--heldout",
        &s(&held),
        "--report",
        &s(&report),
    ]);
    let html = std::fs::read_to_string(&report).unwrap();
    self_contained(&html);
    for id in [
        "source",
        "parameters",
        "correlations",
        "residuals",
        "outliers",
        "heldout",
    ] {
        assert!(
            html.contains(&format!("<section id=\"{id}\">")),
            "section {id}"
        );
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let n = v["model"]["parameters"].as_array().unwrap().len();
    assert_eq!(table_rows(&html, "parameter-table"), n);
    assert_eq!(table_rows(&html, "correlation-table"), n);
    assert_eq!(table_rows(&html, "residual-table"), 2);
    assert_eq!(table_rows(&html, "heldout-table"), 2);
    let outliers = v["outliers"].as_array().unwrap();
    assert!(!outliers.is_empty(), "the 5 mm row is found");
    assert_eq!(table_rows(&html, "outlier-table"), outliers.len());
    assert!(html.contains(&format!("<td class=\"name\">{}</td>", outliers[0]["seq"])));
    // The model keeps the covariance: n × n, its diagonal the squared σ.
    let cov = &v["covariance"];
    assert_eq!(cov["names"].as_array().unwrap().len(), n);
    for (k, p) in v["model"]["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let var = cov["values"][k][k].as_f64().unwrap();
        let sd = p["sigma"].as_f64().unwrap();
        assert!(
            (var.sqrt() - sd).abs() <= 1e-9 * sd.max(1e-12) + 1e-15,
            "{k}: {var} vs σ {sd}"
        );
    }
    // Plots: inline, Okabe–Ito, the binned mean and its band.
    assert!(html.contains("<svg xmlns=\"http://www.w3.org/2000/svg\""));
    assert!(html.contains("#0072B2") && html.contains("#D55E00"));
    assert!(html.contains("class=\"binned-mean\"") && html.contains("class=\"band\""));
}

#[test]
fn the_diagnose_report_shows_each_effect_with_its_evidence_and_the_json_is_tagged() {
    let dir = tempfile::tempdir().unwrap();
    let (rig, rec, _) = setup(dir.path());
    let report = dir.path().join("d.html");
    let json = dir.path().join("d.json");
    ok(&[
        "diagnose",
        "--rig",
        &s(&rig),
        "--recording",
        &s(&rec),
        "--report",
        &s(&report),
        "--json",
        &s(&json),
    ]);
    let html = std::fs::read_to_string(&report).unwrap();
    self_contained(&html);
    for id in [
        "source",
        "mismatch",
        "residuals",
        "effects",
        "outliers",
        "heldout",
        "plots",
    ] {
        assert!(
            html.contains(&format!("<section id=\"{id}\">")),
            "section {id}"
        );
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["format"], "rigcal-diagnosis");
    assert_eq!(v["version"], 1);
    let effects = v["effects"].as_array().unwrap().len();
    assert_eq!(table_rows(&html, "effect-table"), effects);
    assert_eq!(html.matches("<div class=\"effect\"").count(), effects);
    // One residual plot per moving joint (8) and one against time in the plots section, plus
    // one evidence plot per effect.
    assert_eq!(html.matches("<title>residual vs joint").count(), 8);
    assert_eq!(html.matches("<title>residual vs time").count(), 1);
    assert_eq!(html.matches("<svg ").count(), 9 + effects);
}

#[test]
fn small_things_help_texts_and_an_empty_recording() {
    let top = ok(&["--help"]);
    assert!(
        top.contains("calibrate a robot arm from position measurements"),
        "{top}"
    );
    let d = ok(&["diagnose", "--help"]);
    assert!(!d.contains("shared/spec"), "{d}");
    assert!(d.contains("--report"));
    let dir = tempfile::tempdir().unwrap();
    let (rig, rec, _) = setup(dir.path());
    let csv = rec.join("measurements.csv");
    let header = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_string();
    std::fs::write(&csv, header + "\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args([
            "identify",
            "--rig",
            &s(&rig),
            "--recording",
            &s(&rec),
            "--out",
            &s(&dir.path().join("m.json")),
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&s(&csv)) && err.contains("no measured rows"),
        "{err}"
    );
}
