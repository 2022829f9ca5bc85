//! Discovery that names only what earns its place (issue 35): every effect the F-tests choose
//! is judged on rows not used to fit it (blocked cross-validation inside the recording, and the
//! given held-out recordings), and weaker evidence is reported as "below what this recording
//! can show", never as a name.
//!
//! Recordings from the generator of `tests/common/shapes.rs` (600 measurements, one in eight at
//! a repeated `ref` pose, `rigs/rv-m2-ideal.toml` with random geometric errors). Units: mm,
//! degrees.

mod common;

use common::shapes::*;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_model::diagnosis::{diagnose, Options, Report};

fn claimed(r: &Report) -> Vec<String> {
    r.effects
        .iter()
        .map(|e| format!("{} on joint {:?} / axis {:?}", e.kind, e.joint, e.axis))
        .collect()
}

/// A noiseless null: geometry only, no noise. Whatever the F-tests find at rounding level is
/// far below any share of a floor a user could see.
#[test]
fn a_noiseless_null_claims_nothing() {
    for seed in 0..2 {
        let c = null(500 + seed, 0.0);
        let r = diagnose(&c.scenario.rig, &c.recording, &Options::default()).expect("diagnose");
        eprintln!("noiseless null {seed}: {}", r.text());
        assert!(
            r.effects.is_empty(),
            "claimed {:?}\n{}",
            claimed(&r),
            r.text()
        );
    }
}

/// Real-shaped noise on a null recording: repeatability that depends on the pose (σ 0.01 to
/// 0.04 mm per coordinate along joint 2's angle, so the two repeated poses understate it), a
/// smooth residual no library effect has (a local deformation of the instrument, at the noise
/// floor) and three gross rows. No library effect may be named; the smooth residual may be
/// reported as unexplained.
#[test]
fn a_real_shaped_null_claims_no_library_effect() {
    for seed in 0..2 {
        let mut c = null(600 + seed, 0.0);
        real_shaped_noise(&mut c.recording, 600 + seed);
        let r = diagnose(&c.scenario.rig, &c.recording, &Options::default()).expect("diagnose");
        eprintln!("real-shaped null {seed}: {}", r.text());
        assert!(
            r.effects.is_empty(),
            "claimed {:?}\n{}",
            claimed(&r),
            r.text()
        );
    }
}

/// Adds pose-dependent noise, a smooth local deformation at the floor and three gross rows.
fn real_shaped_noise(rec: &mut Recording, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let centre = {
        let pts: Vec<_> = rec.rows.iter().filter_map(|r| r.position).collect();
        pts.iter().sum::<nalgebra::Vector3<f64>>() / pts.len().max(1) as f64
    };
    let deformation = Deformation {
        centre,
        width: 150.0,
        direction: nalgebra::Vector3::new(0.6, 0.0, 0.8),
        amplitude: floor(),
    };
    deformation.apply(rec);
    let n = rec.rows.len();
    for (k, row) in rec.rows.iter_mut().enumerate() {
        let s = 0.01 + 0.03 * (0.5 + 0.5 * row.q[1].sin());
        if let Some(p) = row.position.as_mut() {
            for a in 0..3 {
                // Box–Muller from two uniforms: a standard normal draw.
                let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-12), rng.random());
                p[a] += s * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            }
            if k == n / 5 || k == n / 2 || k == 4 * n / 5 + 1 {
                p[2] += 0.6;
            }
        }
    }
}

/// An effect the training recording shows but a held-out recording of the same arm does not
/// (the effect was switched off: a loose joint tightened between the recordings): its gain on
/// the held-out recording is negative, so it is not named — and is, with a held-out recording
/// that shows it (so the test can fail).
#[test]
fn an_effect_that_does_not_hold_on_held_out_data_is_not_claimed() {
    let case = library_cases()
        .into_iter()
        .find(|c| c.name == "backlash:3")
        .expect("backlash case");
    let c = in_library(&case, 7, Some(3.0));
    let (poses, refs) = poses(&c.scenario, MEASUREMENTS, 77);
    let mut without = c.scenario.clone();
    without.effects.clear();
    let held_without = record(&without, &poses, &refs);
    let held_with = record(&c.scenario, &poses, &refs);
    let run = |h: Recording| {
        diagnose(
            &c.scenario.rig,
            &c.recording,
            &Options {
                heldout: vec![h],
                ..Default::default()
            },
        )
        .expect("diagnose")
    };
    let shown = run(held_with);
    eprintln!("held out with the effect: {}", shown.text());
    assert!(
        shown
            .effects
            .iter()
            .any(|e| e.kind.to_string() == "backlash" && e.joint == Some(3)),
        "{}",
        shown.text()
    );
    let gone = run(held_without);
    eprintln!("held out without the effect: {}", gone.text());
    assert!(gone.effects.is_empty(), "{}", gone.text());
    let weak = gone
        .below_evidence
        .iter()
        .find(|w| w.label == "backlash on joint 3")
        .expect("backlash reported below what the recording can show");
    assert!(weak.gain.recordings_gain_mm.is_some_and(|g| g < 0.0));
    assert!(gone
        .text()
        .contains("below what this recording can show: backlash on joint 3"));
}

/// Every effect named carries its held-out gain, significant and above the share of the floor.
#[test]
fn a_named_effect_reports_its_held_out_gain() {
    let case = library_cases()
        .into_iter()
        .find(|c| c.name == "transmission_error:1")
        .expect("case");
    let c = in_library(&case, 3, Some(2.0));
    let r = diagnose(&c.scenario.rig, &c.recording, &Options::default()).expect("diagnose");
    eprintln!("{}", r.text());
    assert_eq!(r.effects.len(), 1, "{}", r.text());
    let g = r.effects[0].heldout_gain.as_ref().expect("gain");
    assert!(g.shortfall().is_none(), "{g:?}");
    assert!(g.gain_mm > 2.0 * g.gain_sigma_mm && g.explained_over_floor >= 0.2);
    assert!(r.text().contains("held-out gain"));
    // Held-out figures give mean, RMS and max: mean ≤ RMS ≤ max for any set of lengths.
    let f = &r.fit;
    for (mean, rms, max) in [
        (
            f.heldout_before_mean_mm,
            f.heldout_before_rms_mm,
            f.heldout_before_max_mm,
        ),
        (
            f.heldout_after_mean_mm,
            f.heldout_after_rms_mm,
            f.heldout_after_max_mm,
        ),
    ] {
        let (mean, rms, max) = (mean.expect("mean"), rms.expect("rms"), max.expect("max"));
        assert!(
            mean <= rms + 1e-12 && rms <= max + 1e-12,
            "{mean} {rms} {max}"
        );
    }
    assert!(r.text().contains("held out: geometry mean"), "{}", r.text());
}

/// `diagnose --model` on a recording with a library effect (backlash on joint 2, 0.02°) and an
/// out-of-library remainder (one joint's error driven by another joint's angle, 3× the floor,
/// from the generator): the report flags the remainder unexplained, the model file keeps the
/// backlash that earned its place, and `compensate` uses it (with an effect and `--approach
/// consistent` it writes a `move` column and a via row per target).
#[test]
fn diagnose_model_keeps_an_earned_effect_beside_an_unexplained_remainder() {
    let mut sc = out_of_library(Class::Coupling, 4, 3.0).scenario;
    sc.effects
        .push(std::sync::Arc::new(rigcal_sim::world::Backlash {
            joint: 1,
            lost_motion: 0.02f64.to_radians(),
        }));
    let rec = recording(&sc, MEASUREMENTS, 900);
    let dir = tempfile::tempdir().expect("tempdir");
    let rec_dir = dir.path().join("rec");
    rec.write_dir(&rec_dir).expect("write");
    let model = dir.path().join("model.json");
    let bin = env!("CARGO_BIN_EXE_rigcal");
    let out = std::process::Command::new(bin)
        .args(["diagnose", "--rig", "rigs/rv-m2-ideal.toml", "--recording"])
        .arg(&rec_dir)
        .arg("--model")
        .arg(&model)
        .output()
        .expect("run rigcal");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("unexplained:"), "{stdout}");
    assert!(
        stdout.contains("in the model: backlash on joint 2"),
        "{stdout}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).expect("model")).expect("json");
    assert!(
        v["effects"]
            .as_array()
            .is_some_and(|a| a.iter().any(|e| e.to_string().contains("backlash"))),
        "{v}"
    );
    let (targets_q, _) = poses(&sc, 6, 901);
    let targets = dir.path().join("targets.csv");
    std::fs::write(
        &targets,
        rigcal_core::recording::commands_csv(
            sc.rig.chain.joints(),
            targets_q.iter().skip(1).map(|q| q.as_slice()),
        ),
    )
    .expect("targets");
    let cmds = dir.path().join("commands.csv");
    let out = std::process::Command::new(bin)
        .args(["compensate", "--model"])
        .arg(&model)
        .arg("--targets")
        .arg(&targets)
        .args(["--approach", "consistent", "--out"])
        .arg(&cmds)
        .output()
        .expect("run rigcal");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&cmds).expect("commands");
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].ends_with(",move"), "{text}");
    assert_eq!(lines.len(), 1 + 2 * 5, "{text}");
}

/// `export urdf` after `identify --effects`: a URDF cannot carry the effects, so it gets the
/// geometry fitted without them — the same URDF as a plain `identify` exports — and says so;
/// the effects stay in the model file.
#[test]
fn export_urdf_after_identify_with_effects_writes_the_stand_alone_geometry() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (_, rig_path) = common::synthetic8::rig_in(dir.path());
    let text = format!(
        "description = \"export test\"\nseed = 11\nrig = \"{}\"\n\
         [geometric]\nrandom = {{ length_mm = 0.4, angle_deg = 0.05, distribution = \"signs\" }}\n\
         [[effects]]\nkind = \"backlash\"\njoint = 3\nlost_motion_deg = 0.05\n\
         [measurement]\nnoise_mm = 0.02\nseconds_per_point = 5.0\n",
        rig_path.display()
    );
    let sc = rigcal_sim::world::Scenario::parse(&text, &dir.path().join("sc.toml"), None)
        .expect("scenario");
    let (q, refs) = poses(&sc, 300, 12);
    let rec_dir = dir.path().join("rec");
    record(&sc, &q, &refs).write_dir(&rec_dir).expect("write");
    let bin = env!("CARGO_BIN_EXE_rigcal");
    let run = |args: &[&std::ffi::OsStr]| {
        let o = std::process::Command::new(bin)
            .args(args)
            .output()
            .expect("run");
        assert!(
            o.status.success(),
            "{args:?}: {}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        (
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let os = |s: &str| std::ffi::OsString::from(s);
    let p = |x: &std::path::Path| x.as_os_str().to_owned();
    let with = dir.path().join("with.json");
    let plain = dir.path().join("plain.json");
    let identify = |out: &std::path::Path, effects: bool| {
        let mut a = vec![
            os("identify"),
            os("--rig"),
            p(&rig_path),
            os("--recording"),
            p(&rec_dir),
        ];
        if effects {
            a.extend([os("--effects"), os("backlash:3")]);
        }
        a.extend([os("--out"), p(out)]);
        let refs: Vec<&std::ffi::OsStr> = a.iter().map(|s| s.as_os_str()).collect();
        run(&refs)
    };
    let (stdout, _) = identify(&with, true);
    assert!(stdout.contains("backlash on joint 3"), "{stdout}");
    identify(&plain, false);
    let urdf = dir.path().join("synthetic8.urdf");
    let export = |model: &std::path::Path, out: &std::path::Path| {
        let a = [
            os("export"),
            os("urdf"),
            os("--model"),
            p(model),
            os("--urdf"),
            p(&urdf),
            os("--out"),
            p(out),
        ];
        let refs: Vec<&std::ffi::OsStr> = a.iter().map(|s| s.as_os_str()).collect();
        run(&refs)
    };
    let (_, said) = export(&with, &dir.path().join("with.urdf"));
    assert!(
        said.contains("a URDF cannot carry the model's effects (backlash on joint 3)")
            && said.contains("geometry fitted without them, which stands alone"),
        "{said}"
    );
    let (_, quiet) = export(&plain, &dir.path().join("plain.urdf"));
    assert!(!quiet.contains("cannot carry"), "{quiet}");
    let read = |f: &str| std::fs::read_to_string(dir.path().join(f)).expect("urdf");
    assert_eq!(read("with.urdf"), read("plain.urdf"));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&with).expect("model")).expect("json");
    assert!(m["effects"].as_array().is_some_and(|a| !a.is_empty()));
    assert!(m["standalone_parameters"]
        .as_array()
        .is_some_and(|a| !a.is_empty()));
}

/// The UR10 check of issue 35 (ignored: needs the real data, prepared by `scripts/ur10.sh` or
/// as in docs/diagnosis.md, in `RIGCAL_UR10_DIR`: `ur10.toml`, `rec-A1k` — 1 000 rows spread
/// over series A — and `rec-B`, `rec-C`, `rec-D`). Diagnose on A1k with series B and D as
/// held-out sessions in the judgement (frames refitted), then series C, which took no part,
/// with its frame refitted: no claimed effect may raise its error. Prints the figures.
#[test]
#[ignore]
fn ur10_claimed_effects_do_not_raise_the_held_out_error() {
    use rigcal_model::diagnosis::sessions::{physics_heldout, without_rows, PerSession};
    use rigcal_model::identification::HeldOut;
    let dir = std::path::PathBuf::from(
        std::env::var("RIGCAL_UR10_DIR").expect("RIGCAL_UR10_DIR: the prepared UR10 directory"),
    );
    let rig = rigcal_core::rig::Rig::load(&dir.join("ur10.toml")).expect("rig");
    let read = |name: &str| HeldOut {
        name: name.into(),
        recording: rigcal_calibration::read_recording(&rig, &dir.join(name)).expect("recording"),
    };
    let train = read("rec-A1k").recording;
    let t0 = std::time::Instant::now();
    let plain = diagnose(&rig, &train, &Options::default()).expect("diagnose");
    let t_plain = t0.elapsed().as_secs_f64();
    let t0 = std::time::Instant::now();
    let judged = diagnose(
        &rig,
        &train,
        &Options {
            sessions: vec![read("rec-B"), read("rec-D")],
            per_session: PerSession::Frame,
            ..Default::default()
        },
    )
    .expect("diagnose");
    let t_judged = t0.elapsed().as_secs_f64();
    for (what, r, t) in [
        ("blocks only", &plain, t_plain),
        ("blocks, B and D", &judged, t_judged),
    ] {
        eprintln!("== {what}: {t:.1} s\n{}", r.text());
        let clean = without_rows(&train, r.outliers.iter().map(|o| o.seq));
        let ph = physics_heldout(
            &rig,
            &clean,
            &r.effects,
            &[read("rec-C")],
            PerSession::Frame,
        )
        .expect("held out");
        eprintln!(
            "{what}: claimed {:?}; series C (frame refitted) {:?}",
            ph.effects, ph.heldout
        );
        // Both rules now: a claim may not raise the recording's own split, nor a held-out
        // series beyond its noise. Series C took no part. 1 nm of slack: with nothing claimed
        // the frame refit of C with and without "the effects" differs by 1.2e-9 mm, iteration
        // noise, not a rise.
        let (geometry, physics) = (ph.heldout[0].1.rms_mm, ph.heldout[0].2.rms_mm);
        assert!(physics <= geometry + 1e-6, "{what}: {physics} > {geometry}");
    }
}
