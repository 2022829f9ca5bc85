//! `rigcal diagnose` works unchanged on a session directory written by `rigcal session --sim`
//! (rows with status `via` and `skipped: …`, `table_*_mm` and panel columns, `ref` rows,
//! `session.toml`): a dry-run session on the real rig file (`rigs/rv-m2.toml`: table travel, the
//! 15° rule, panel quantisation) of a scenario with nothing hidden beyond the geometry, a
//! registration offset (absorbed, conventions §1) and the instrument (quantisation, table
//! accuracy, arm repeatability) — so the diagnosis must claim nothing.

use std::path::Path;
use std::process::Command;

fn scenario(dir: &Path) -> std::path::PathBuf {
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("rigs/rv-m2.toml");
    let text = format!(
        "description = \"geometry and instrument only\"\nseed = 77\nrig = {rig:?}\n\
         [geometric]\nrandom = {{ length_mm = 0.4, angle_deg = 0.05, distribution = \"signs\" }}\n\
         [[effects]]\nkind = \"registration_offset\"\nxyz_mm = [0.3, -0.2, 0.1]\nrpy_deg = [0.0, 0.0, 0.01]\n\
         [measurement]\nnoise_mm = 0.0\narm_repeatability_mm = 0.03\ntable_accuracy_mm = 0.02\n\
         quantise = true\nseconds_per_point = 5.0\n",
        rig = rig.display().to_string()
    );
    let path = dir.join("geometry-only.toml");
    std::fs::write(&path, text).expect("write scenario");
    path
}

#[test]
fn diagnose_reads_a_dry_run_session_directory_and_claims_nothing_without_an_effect() {
    let dir = tempfile::tempdir().expect("tempdir");
    let sc = scenario(dir.path());
    let out_dir = dir.path().join("session");
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["session", "--rig", "rigs/rv-m2.toml", "--sim"])
        .arg(&sc)
        .arg("--out")
        .arg(&out_dir)
        .args([
            "--points",
            "160",
            "--regions",
            "4",
            "--reference-every",
            "10",
            "--registration-points",
            "6",
        ])
        .output()
        .expect("run rigcal session");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(out_dir.join("measurements.csv")).expect("csv");
    assert!(csv.contains(",via") || csv.contains(",via,"), "no via rows");
    assert!(csv.lines().next().is_some_and(|h| h.contains("table_x_mm")));
    let json = dir.path().join("report.json");
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["diagnose", "--rig", "rigs/rv-m2.toml", "--recording"])
        .arg(&out_dir)
        .arg("--json")
        .arg(&json)
        .output()
        .expect("run rigcal diagnose");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{text}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
    assert_eq!(v["mismatch"]["significant"], false, "{text}");
    assert_eq!(v["effects"].as_array().map(Vec::len), Some(0), "{text}");
    assert_eq!(v["unexplained"], false, "{text}");
    assert!(text.contains("quantisation"), "{text}");
}
