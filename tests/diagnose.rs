//! `rigcal diagnose` against the simulated world: one hidden effect at a time (each library
//! effect), null controls, a registration offset alone and out-of-library effects. The world
//! generates the recordings with its own physics (link masses, lost motion, …); the diagnosis
//! sees only the recording and the rig file.
//!
//! Sizes are reduced for CI (600 measurements, 1 in 8 at a repeated `ref` pose, which gives
//! 3·(75 − 1)… ≥ 60 degrees of freedom of pure error). `rates` (ignored) runs many seeds and
//! prints the naming and false-claim rates. Units: mm and degrees.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_model::diagnosis::{diagnose, Options, Report};
use rigcal_model::identification::random_poses;
use rigcal_sim::world::Scenario;
use std::path::Path;

/// Scenario text on `rig` (ideal or table) with random geometric errors, `effects` (TOML
/// `[[effects]]` blocks) and Gaussian noise `noise_mm`.
fn scenario(rig: &str, seed: u64, effects: &str, noise_mm: f64) -> Scenario {
    let extra = if rig == "rv-m2" {
        "quantise = false\ntable_accuracy_mm = 0.0\n"
    } else {
        ""
    };
    let text = format!(
        "description = \"diagnosis test\"\nseed = {seed}\nrig = \"../rigs/{rig}.toml\"\n\
         [geometric]\nrandom = {{ length_mm = 0.4, angle_deg = 0.05, distribution = \"signs\" }}\n\
         {effects}\n[measurement]\nnoise_mm = {noise_mm}\nseconds_per_point = 5.0\n{extra}"
    );
    Scenario::parse(&text, Path::new("sim/diagnose-test.toml"), None).expect("scenario")
}

/// A recording of `n` measurements: random measurable poses, every 8th at one of two repeated
/// reference poses (region `ref`).
fn record(sc: &Scenario, n: usize, seed: u64) -> Recording {
    let rig = &sc.rig;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let draw = |rng: &mut ChaCha8Rng| loop {
        let q = random_poses(rig.chain.joints(), rig.held(), 1, rng).remove(0);
        if rig.measurable(&q).is_ok() {
            return q;
        }
    };
    let refs = [draw(&mut rng), draw(&mut rng)];
    let mut poses = Vec::with_capacity(n);
    let mut is_ref = Vec::with_capacity(n);
    for k in 0..n {
        if k % 8 == 0 {
            poses.push(refs[(k / 8) % 2].clone());
            is_ref.push(true);
        } else {
            poses.push(draw(&mut rng));
            is_ref.push(false);
        }
    }
    let _ = rng.random::<u8>();
    let mut rec = sc.world().record(&poses, 1);
    for (row, r) in rec.rows.iter_mut().zip(is_ref) {
        row.region = Some(if r { "ref".into() } else { "w".into() });
    }
    rec
}

fn run(sc: &Scenario, n: usize, seed: u64) -> Report {
    let rec = record(sc, n, seed);
    diagnose(&sc.rig, &rec, &Options::default()).expect("diagnose")
}

fn names(r: &Report) -> Vec<String> {
    r.effects
        .iter()
        .map(|e| {
            let idx = e
                .joint
                .map(|j| j.to_string())
                .or(e.axis.clone())
                .or(e.axes.as_ref().map(|a| a.join("")))
                .unwrap_or_default();
            format!("{}:{idx}", e.kind)
        })
        .collect()
}

/// The effect blocks of each in-library case with the name:index the diagnosis must report.
fn in_library() -> Vec<(&'static str, &'static str, String)> {
    vec![
        (
            "rv-m2-ideal",
            "joint_compliance:2",
            "[[effects]]\nkind = \"joint_compliance\"\nmasses = [ { link = 2, kg = 3.5, at_mm = [-125.0, 0.0, 0.0] }, { link = 3, kg = 2.5, at_mm = [-130.0, 0.0, 0.0] }, { link = 5, kg = 1.0, at_mm = [-150.0, 0.0, 0.0] } ]\njoints = [ { joint = 2, deg_per_nm = 0.0005 } ]\n".into(),
        ),
        (
            "rv-m2-ideal",
            "joint_compliance:3",
            "[[effects]]\nkind = \"joint_compliance\"\nmasses = [ { link = 2, kg = 3.5, at_mm = [-125.0, 0.0, 0.0] }, { link = 3, kg = 2.5, at_mm = [-130.0, 0.0, 0.0] }, { link = 5, kg = 1.0, at_mm = [-150.0, 0.0, 0.0] } ]\njoints = [ { joint = 3, deg_per_nm = 0.001 } ]\n".into(),
        ),
        (
            "rv-m2-ideal",
            "backlash:1",
            "[[effects]]\nkind = \"backlash\"\njoint = 1\nlost_motion_deg = 0.01\n".into(),
        ),
        (
            "rv-m2-ideal",
            "backlash:3",
            "[[effects]]\nkind = \"backlash\"\njoint = 3\nlost_motion_deg = 0.01\n".into(),
        ),
        (
            "rv-m2-ideal",
            "transmission_error:1",
            "[[effects]]\nkind = \"transmission_error\"\njoint = 1\nharmonics = [{ order = 2, amplitude_deg = 0.005, phase_deg = 30.0 }]\n".into(),
        ),
        (
            "rv-m2-ideal",
            "transmission_error:2",
            "[[effects]]\nkind = \"transmission_error\"\njoint = 2\nharmonics = [{ order = 3, amplitude_deg = 0.005, phase_deg = -60.0 }]\n".into(),
        ),
        (
            "rv-m2-ideal",
            "thermal_drift:z",
            "[[effects]]\nkind = \"thermal_drift\"\naxis = \"z\"\namplitude_mm = 0.05\ntau_s = 1800.0\n".into(),
        ),
        (
            "rv-m2-ideal",
            "thermal_drift:2",
            "[[effects]]\nkind = \"thermal_drift\"\njoint = 2\namplitude_deg = 0.008\ntau_s = 1800.0\n".into(),
        ),
        (
            "rv-m2",
            "table_scale:x",
            "[[effects]]\nkind = \"table_scale\"\naxis = \"x\"\nscale_ppm = 150.0\n".into(),
        ),
        (
            "rv-m2",
            "table_squareness:xy",
            "[[effects]]\nkind = \"table_squareness\"\naxes = [\"x\", \"y\"]\nangle_deg = 0.01\n".into(),
        ),
    ]
}

#[test]
fn names_each_library_effect_and_predicts_held_out_data() {
    let mut failures = Vec::new();
    for (k, (rig, want, effects)) in in_library().into_iter().enumerate() {
        let sc = scenario(rig, 100 + k as u64, &effects, 0.02);
        let r = run(&sc, 600, k as u64);
        let got = names(&r);
        let floor = r.mismatch.noise_floor_mm;
        let ho = r.fit.heldout_after_rms_mm.unwrap_or(f64::NAN);
        eprintln!(
            "{want}: named {got:?}, unexplained {}, floor {floor:.4}, before {:.4}, held-out {:.4} → {ho:.4}",
            r.unexplained, r.mismatch.rms_mm, r.fit.heldout_before_rms_mm.unwrap_or(f64::NAN)
        );
        let first_ok = got.first().is_some_and(|g| g == want)
            || r.effects.first().is_some_and(|e| {
                e.not_separable_from
                    .iter()
                    .any(|s| s.starts_with(want.split(':').next().unwrap_or("")))
            });
        if !first_ok || ho.is_nan() || ho > 1.2 * floor {
            failures.push(format!(
                "{want}: {got:?}, held-out {ho:.4} vs floor {floor:.4}"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn claims_nothing_without_an_effect() {
    for (k, noise) in [0.01, 0.05].into_iter().enumerate() {
        let sc = scenario("rv-m2-ideal", 300 + k as u64, "", noise);
        let r = run(&sc, 600, 300 + k as u64);
        eprintln!("null σ = {noise}: {}", r.text());
        assert!(!r.mismatch.significant, "{}", r.text());
        assert!(r.effects.is_empty() && !r.unexplained);
    }
}

#[test]
fn registration_offset_alone_is_absorbed() {
    let sc = scenario(
        "rv-m2",
        400,
        "[[effects]]\nkind = \"registration_offset\"\nxyz_mm = [0.3, -0.2, 0.1]\nrpy_deg = [0.0, 0.0, 0.01]\n",
        0.02,
    );
    let r = run(&sc, 600, 400);
    eprintln!("registration: {}", r.text());
    assert!(r.effects.is_empty() && !r.unexplained, "{}", r.text());
}

#[test]
fn out_of_library_effect_is_unexplained() {
    // Eq. (6) with cross terms only: each joint's error depends on the other joints' angles, which
    // no single candidate (each acting on one joint through its own angle) fits.
    let sc = scenario(
        "rv-m2-ideal",
        500,
        "[[effects]]\nkind = \"trig_joint_errors\"\na_deg = [[0.0, 0.02, -0.015], [0.015, 0.0, 0.02], [-0.02, 0.015, 0.0]]\nb_deg = [[0.0, -0.01, 0.02], [0.02, 0.0, -0.015], [0.01, -0.02, 0.0]]\n",
        0.02,
    );
    let r = run(&sc, 600, 500);
    eprintln!("trig: {}", r.text());
    assert!(r.mismatch.significant && r.unexplained, "{}", r.text());
    assert!(!r.mismatch.where_.is_empty() && !r.unexplained_where.is_empty());
}

#[test]
fn cli_writes_the_json_report_and_plots() {
    let sc = scenario(
        "rv-m2-ideal",
        600,
        "[[effects]]\nkind = \"backlash\"\njoint = 2\nlost_motion_deg = 0.012\n",
        0.02,
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let rec_dir = dir.path().join("rec");
    record(&sc, 400, 600).write_dir(&rec_dir).expect("write");
    let held_dir = dir.path().join("held");
    record(&sc, 200, 601).write_dir(&held_dir).expect("write");
    let json = dir.path().join("report.json");
    let plots = dir.path().join("plots");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["diagnose", "--rig", "rigs/rv-m2-ideal.toml", "--recording"])
        .arg(&rec_dir)
        .arg("--json")
        .arg(&json)
        .arg("--plots")
        .arg(&plots)
        .arg("--heldout")
        .arg(&held_dir)
        .output()
        .expect("run rigcal");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("backlash"), "{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
    assert_eq!(v["mismatch"]["significant"], true);
    assert_eq!(v["effects"][0]["kind"], "backlash");
    assert_eq!(v["effects"][0]["joint"], 2);
    assert_eq!(v["unexplained"], false);
    for key in [
        "before_rms_mm",
        "after_rms_mm",
        "heldout_before_rms_mm",
        "heldout_after_rms_mm",
    ] {
        assert!(v["fit"][key].as_f64().is_some(), "{key}");
    }
    let b = v["effects"][0]["params"]["lost_motion_deg"]
        .as_f64()
        .expect("b");
    assert!((b - 0.012).abs() < 0.003, "lost motion {b}");
    assert!(plots.join("residual_vs_q2.svg").exists());
}

/// Rates over many seeds (run with `--ignored --nocapture`): naming rate per in-library case
/// with the mean visible size ÷ noise floor and held-out success, and the false-claim rate on
/// null recordings at two noise levels.
#[test]
#[ignore]
fn rates() {
    let seeds: u64 = std::env::var("RIGCAL_RATE_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    for (rig, want, effects) in in_library() {
        let (mut named, mut held, mut ratio) = (0, 0, 0.0);
        for s in 0..seeds {
            let sc = scenario(rig, 1000 + s, &effects, 0.02);
            let r = run(&sc, 600, 1000 + s);
            let floor = r.mismatch.noise_floor_mm;
            if names(&r).first().is_some_and(|g| g == want) {
                named += 1;
                let e = &r.effects[0];
                ratio += e.size_mm * e.visible_fraction / floor;
            }
            if r.fit.heldout_after_rms_mm.is_some_and(|h| h <= 1.2 * floor) {
                held += 1;
            }
        }
        eprintln!(
            "{want:<22} named {named}/{seeds}, held-out ≤ 1.2 floor {held}/{seeds}, mean visible size / floor {:.2}",
            ratio / f64::from(named.max(1))
        );
    }
    for noise in [0.01, 0.05] {
        let mut claims = 0;
        let n = 5 * seeds;
        for s in 0..n {
            let sc = scenario("rv-m2-ideal", 5000 + s, "", noise);
            let r = run(&sc, 600, 5000 + s);
            if r.mismatch.significant || !r.effects.is_empty() || r.unexplained {
                claims += 1;
            }
        }
        eprintln!("null σ = {noise}: something claimed in {claims}/{n}");
    }
    let (mut reg_claims, mut unexplained) = (0, 0);
    for s in 0..seeds {
        let sc = scenario(
            "rv-m2",
            7000 + s,
            "[[effects]]\nkind = \"registration_offset\"\nxyz_mm = [0.3, -0.2, 0.1]\nrpy_deg = [0.0, 0.0, 0.01]\n",
            0.02,
        );
        let r = run(&sc, 600, 7000 + s);
        if !r.effects.is_empty() || r.unexplained {
            reg_claims += 1;
        }
        let sc = scenario(
            "rv-m2-ideal",
            8000 + s,
            "[[effects]]\nkind = \"trig_joint_errors\"\na_deg = [[0.0, 0.02, -0.015], [0.015, 0.0, 0.02], [-0.02, 0.015, 0.0]]\nb_deg = [[0.0, -0.01, 0.02], [0.02, 0.0, -0.015], [0.01, -0.02, 0.0]]\n",
            0.02,
        );
        if run(&sc, 600, 8000 + s).unexplained {
            unexplained += 1;
        }
    }
    eprintln!("registration offset alone: something claimed in {reg_claims}/{seeds}");
    eprintln!("eq. (6) cross terms: reported unexplained in {unexplained}/{seeds}");
}

/// Null recordings on the table rig as it is (panel quantisation, table accuracy, arm
/// repeatability 0.03 mm), no effect: how many of `n` (seeds from `first`) claim something.
/// Quantisation repeats at the `ref` poses, so pure error alone understates the noise; the
/// diagnosis adds the panel's cell variance w²/12 and projects out its structure.
fn table_null_claims(first: u64, n: u64) -> u64 {
    let mut claims = 0;
    for s in first..first + n {
        let text = format!(
            "description = \"null\"\nseed = {s}\nrig = \"../rigs/rv-m2.toml\"\n[geometric]\nrandom = {{ length_mm = 0.4, angle_deg = 0.05, distribution = \"signs\" }}\n[measurement]\narm_repeatability_mm = 0.03\nseconds_per_point = 5.0\n"
        );
        let sc =
            Scenario::parse(&text, Path::new("sim/diagnose-test.toml"), None).expect("scenario");
        let r = run(&sc, 600, s);
        if r.mismatch.significant || !r.effects.is_empty() || r.unexplained {
            claims += 1;
            eprintln!("seed {s}:\n{}", r.text());
        }
    }
    claims
}

#[test]
fn table_rig_claims_nothing_without_an_effect() {
    let claims = table_null_claims(9000, 10);
    assert_eq!(
        claims, 0,
        "table rig nulls: something claimed in {claims}/10"
    );
}

/// The table rig's null rate over many seeds (run with `--ignored --nocapture`; default 100,
/// `RIGCAL_RATE_SEEDS` × 5): conventions §9 asks at most 2 %.
#[test]
#[ignore]
fn table_rig_null_rate() {
    let n: u64 = std::env::var("RIGCAL_RATE_SEEDS")
        .ok()
        .and_then(|s| s.parse::<u64>().ok())
        .map_or(100, |s| 5 * s);
    let claims = table_null_claims(9000, n);
    eprintln!("table rig, quantised, no effect: something claimed in {claims}/{n}");
    assert!(claims as f64 <= 0.02 * n as f64, "{claims}/{n}");
}

/// Naming on the quantised table rig (run with `--ignored --nocapture`): the quantisation
/// handling of the null controls must leave effects of `sim/rig-realistic.toml`'s size visible.
#[test]
#[ignore]
fn table_rig_naming_rate() {
    let seeds: u64 = std::env::var("RIGCAL_RATE_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let cases = [
        (
            "backlash:2",
            "[[effects]]\nkind = \"backlash\"\njoint = 2\nlost_motion_deg = 0.015\n",
        ),
        (
            "table_scale:x",
            "[[effects]]\nkind = \"table_scale\"\naxis = \"x\"\nscale_ppm = 150.0\n",
        ),
        (
            "joint_compliance:3",
            "[[effects]]\nkind = \"joint_compliance\"\nmasses = [ { link = 2, kg = 3.5, at_mm = [-125.0, 0.0, 0.0] }, { link = 3, kg = 2.5, at_mm = [-130.0, 0.0, 0.0] }, { link = 5, kg = 1.0, at_mm = [-150.0, 0.0, 0.0] } ]\njoints = [ { joint = 3, deg_per_nm = 0.003 } ]\n",
        ),
    ];
    for (want, effects) in cases {
        let mut named = 0;
        for s in 0..seeds {
            let text = format!(
                "description = \"quantised\"\nseed = {}\nrig = \"../rigs/rv-m2.toml\"\n[geometric]\nrandom = {{ length_mm = 0.4, angle_deg = 0.05, distribution = \"signs\" }}\n{effects}\n[measurement]\narm_repeatability_mm = 0.03\nseconds_per_point = 5.0\n",
                11000 + s
            );
            let sc = Scenario::parse(&text, Path::new("sim/diagnose-test.toml"), None)
                .expect("scenario");
            let r = run(&sc, 600, 11000 + s);
            if names(&r).first().is_some_and(|g| g == want) {
                named += 1;
            }
        }
        eprintln!("table rig, quantised: {want} named first in {named}/{seeds}");
    }
}
