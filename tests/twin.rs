//! The twin learns (issue 18 item 4): a scenario with the nominal geometry and no effects is
//! compared with a recording of a hidden truth, the difference is diagnosed, and the written
//! scenario, re-simulated, matches the held-out rows at the noise floor. Reduced sizes: 480
//! measurements (1 in 8 at a repeated pose), 1 in 4 held out. Units: mm, degrees.

use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_model::effects::{discrepancy, EffectKind};
use rigcal_model::identification::random_poses;
use rigcal_sim::twin::{learn, Twin, TwinOptions};
use rigcal_sim::world::Scenario;
use std::path::{Path, PathBuf};

const NOISE_MM: f64 = 0.02;

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rigcal-twin-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn rig_path() -> String {
    std::fs::canonicalize("rigs/rv-m2-ideal.toml")
        .expect("rig")
        .display()
        .to_string()
}

/// The twin as a user starts it: the rig, the noise, no geometric errors, no effects.
fn start_text() -> String {
    format!(
        "description = \"RV-M2 twin\"\nseed = 5\nrig = \"{}\"\n[measurement]\nnoise_mm = {NOISE_MM}\nseconds_per_point = 5.0\n",
        rig_path()
    )
}

/// The hidden truth: random geometric errors of the paper's size and `effects`.
fn truth(effects: &str) -> Scenario {
    let text = format!(
        "seed = 21\nrig = \"{}\"\n[geometric]\nrandom = {{ length_mm = 0.4, angle_deg = 0.05, distribution = \"signs\" }}\n{effects}\n[measurement]\nnoise_mm = {NOISE_MM}\nseconds_per_point = 5.0\n",
        rig_path()
    );
    Scenario::parse(&text, Path::new("truth.toml"), None).expect("truth")
}

/// Random measurable poses, every 8th at one of two repeated poses (the noise floor's pure error).
fn record(sc: &Scenario, n: usize, seed: u64) -> Recording {
    let rig = &sc.rig;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut draw = || loop {
        let q = random_poses(rig.chain.joints(), rig.held(), 1, &mut rng).remove(0);
        if rig.measurable(&q).is_ok() {
            return q;
        }
    };
    let refs = [draw(), draw()];
    let poses: Vec<Vec<f64>> = (0..n)
        .map(|k| {
            if k % 8 == 0 {
                refs[(k / 8) % 2].clone()
            } else {
                draw()
            }
        })
        .collect();
    sc.world().record(&poses, 1)
}

fn run(tag: &str, effects: &str) -> (Twin, String) {
    let d = dir(tag);
    let start_path = d.join("start.toml");
    let text = start_text();
    std::fs::write(&start_path, &text).expect("write");
    let start = Scenario::load(&start_path, None).expect("start");
    let rec = record(&truth(effects), 480, 7);
    let out = d.join("learned.toml");
    let twin = learn(&start, &text, &rec, &out, &TwinOptions::default()).expect("learn");
    std::fs::write(&out, &twin.scenario).expect("write");
    // What was written reads back as a scenario.
    Scenario::load(&out, None).expect("the written twin parses");
    eprintln!("{tag}:\n{}", twin.text());
    (twin, tag.to_string())
}

fn floor() -> f64 {
    NOISE_MM * 3f64.sqrt()
}

fn assert_learned(t: &Twin, kind: &str) {
    let f = floor();
    assert!(
        t.before.heldout_mm > 5.0 * f,
        "before {:.4}",
        t.before.heldout_mm
    );
    assert!(
        t.after.heldout_mm <= 1.5 * f,
        "held-out after {:.4} vs floor {f:.4}",
        t.after.heldout_mm
    );
    assert!(
        t.terms
            .iter()
            .any(|x| x.label.starts_with(kind) && x.written.is_ok()),
        "{kind} written: {:?}",
        t.terms
    );
    assert!(
        t.scenario.contains(&format!("kind = \"{kind}\"")),
        "{}",
        t.scenario
    );
    assert!(t.discrepancy.is_none(), "{:?}", t.discrepancy);
}

#[test]
fn learns_backlash() {
    let (t, _) = run(
        "backlash",
        "[[effects]]\nkind = \"backlash\"\njoint = 2\nlost_motion_deg = 0.03\n",
    );
    assert_learned(&t, "backlash");
}

#[test]
fn learns_a_transmission_error() {
    let (t, _) = run(
        "transmission",
        "[[effects]]\nkind = \"transmission_error\"\njoint = 1\nharmonics = [{ order = 2, amplitude_deg = 0.01, phase_deg = 30.0 }]\n",
    );
    assert_learned(&t, "transmission_error");
}

#[test]
fn learns_warm_up_drift() {
    let (t, _) = run(
        "drift",
        "[[effects]]\nkind = \"thermal_drift\"\naxis = \"z\"\namplitude_mm = 0.12\ntau_s = 900.0\n",
    );
    assert_learned(&t, "thermal_drift");
}

#[test]
fn flags_what_is_not_in_the_library_claims_no_library_effect_and_simulates_the_discrepancy() {
    // Each joint's error depends on the other joints' angles (eq. 6, cross terms only): no
    // library candidate acts like that.
    let (t, _) = run(
        "outside",
        "[[effects]]\nkind = \"trig_joint_errors\"\na_deg = [[0.0, 0.02, -0.015], [0.015, 0.0, 0.02], [-0.02, 0.015, 0.0]]\nb_deg = [[0.0, -0.01, 0.02], [0.02, 0.0, -0.015], [0.01, -0.02, 0.0]]\n",
    );
    assert!(
        t.terms.is_empty(),
        "no library effect claimed: {:?}",
        t.terms
    );
    let d = t.discrepancy.as_ref().expect("a flagged discrepancy");
    assert!(
        t.scenario.contains("NOT PHYSICS FROM THE LIBRARY"),
        "{}",
        t.scenario
    );
    assert!(!d.description.is_empty());
    // The geometry was learned and the unknown physics written as the flagged discrepancy
    // term, which the world simulates: re-simulated from the written file, the twin matches the
    // held-out rows at the noise floor as it does for library effects.
    assert!(t.before.heldout_mm > 5.0 * floor());
    assert!(
        t.after.heldout_mm <= 1.5 * floor(),
        "held-out after {:.4} vs floor {:.4}",
        t.after.heldout_mm,
        floor()
    );
    assert!((d.heldout_rms_mm - t.after.heldout_mm).abs() < 1e-12);
    assert!(!d.simulated.is_empty() && d.coefficients > 0, "{d:?}");
    assert!(
        t.scenario.contains("kind = \"discrepancy\""),
        "{}",
        t.scenario
    );
    assert!(t.scenario.contains(discrepancy::FLAG));
    // Library terms the diagnosis named beside it are written commented only.
    let written: Vec<&str> = t.scenario.lines().filter(|l| !l.starts_with('#')).collect();
    for kind in [
        "backlash",
        "transmission_error",
        "joint_compliance",
        "thermal_drift",
    ] {
        let line = format!("kind = \"{kind}\"");
        assert!(
            !written.contains(&line.as_str()),
            "{kind} claimed:\n{}",
            t.scenario
        );
    }
}

#[test]
fn cli_learns_and_writes_the_updated_scenario() {
    let d = dir("cli");
    let start = d.join("start.toml");
    std::fs::write(&start, start_text()).unwrap();
    let rec_dir = d.join("rec");
    record(
        &truth("[[effects]]\nkind = \"backlash\"\njoint = 3\nlost_motion_deg = 0.03\n"),
        400,
        9,
    )
    .write_dir(&rec_dir)
    .unwrap();
    let out = d.join("learned.toml");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["diagnose", "--rig", "rigs/rv-m2-ideal.toml", "--recording"])
        .arg(&rec_dir)
        .arg("--sim")
        .arg(&start)
        .arg("--write-scenario")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("simulation and recording differ"),
        "{stdout}"
    );
    assert!(stdout.contains("RMS sim vs recording: before"), "{stdout}");
    let learned = Scenario::load(&out, None).expect("written scenario");
    assert!(
        learned
            .effects
            .iter()
            .any(|e| e.kind() == EffectKind::Backlash),
        "{stdout}"
    );
}
