//! `rigcal diagnose` on tracker recordings of the synthetic 8-joint robot (issue 11, item 6):
//! frame and marker unknown (the tracker frame rotated by up to 180°), 0.5 mm / 0.05° geometric
//! errors, 50 static postures per recording with no repeated pose and no time column (as an
//! import without `--time` gives), marker noise σ = 0.03 mm per coordinate (a laser tracker at a
//! few metres). The world hides a backlash of 0.5° total lost motion (±0.25°) on joint 6 and
//! simulates it from the move history; the diagnosis sees only the CSV and the rig file, and must
//! take the approach directions from row order.
//!
//! Units: mm and degrees in files, radians inside.

mod common;

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rigcal::identification::{analyse, candidate_order, random_poses};
use rigcal::kinematics::{ErrorParams, Robot, TransformId};
use rigcal::recording::Recording;
use rigcal::rig::{Instrument, Rig};
use rigcal::world::{Backlash, Effect, MeasurementSettings, World};
use std::path::Path;
use std::process::Command;
use std::sync::Arc;

/// Marker noise per coordinate (mm).
const NOISE_MM: f64 = 0.03;
/// Postures per recording.
const POSTURES: usize = 50;
/// Joint 6 (0-based 5), lost motion 0.5° total.
const BACKLASH_JOINT: usize = 5;
const LOST_MOTION_DEG: f64 = 0.5;

/// A tracker world on the synthetic robot: random geometric errors (0.5 mm / 0.05° on the
/// identifiable kinematic parameters), an unknown tracker frame, optional backlash on joint 6.
fn world(rig: &Rig, seed: u64, backlash: bool) -> World {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let design = random_poses(rig.chain.joints(), rig.held(), 80, &mut rng);
    let ident = analyse(&rig.chain, &design, &candidate_order(rig));
    let mut truth = ErrorParams::zeros(rig.chain.layout());
    for &i in &ident.basis {
        let id = rig.chain.layout().ids()[i];
        if matches!(id.transform, TransformId::Frame | TransformId::Marker) {
            continue;
        }
        let size = if id.kind.is_angle() {
            0.05f64.to_radians()
        } else {
            0.5
        };
        truth.set(i, if rng.gen_bool(0.5) { size } else { -size });
    }
    let angle = rng.gen_range(0.5..std::f64::consts::PI);
    let frame = Isometry3::from_parts(
        Translation3::new(1800.0, -400.0, 900.0),
        UnitQuaternion::from_axis_angle(&Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)), angle),
    );
    let effects: Vec<Arc<dyn Effect>> = if backlash {
        vec![Arc::new(Backlash {
            joint: BACKLASH_JOINT,
            lost_motion: LOST_MOTION_DEG.to_radians(),
        })]
    } else {
        Vec::new()
    };
    World::with_effects(
        rig.chain.with_frame(frame),
        truth,
        Instrument::Tracker,
        effects,
        MeasurementSettings::noise_only(NOISE_MM),
        1000 + seed,
    )
}

/// `POSTURES` random static postures in row order, as a tracker export without time.
fn record(w: &World, rig: &Rig, seed: u64) -> (Recording, Vec<Vec<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xbac1);
    let poses = random_poses(rig.chain.joints(), rig.held(), POSTURES, &mut rng);
    let mut rec = w.record(&poses, 1);
    for row in &mut rec.rows {
        row.t_s = None;
    }
    (rec, poses)
}

/// Fraction of moves in which joint `j` reverses its direction of travel.
fn reversal_fraction(poses: &[Vec<f64>], j: usize) -> f64 {
    let signs: Vec<f64> = poses
        .windows(2)
        .map(|w| (w[1][j] - w[0][j]).signum())
        .collect();
    let rev = signs.windows(2).filter(|s| s[0] != s[1]).count();
    rev as f64 / signs.len().max(1) as f64
}

fn diagnose(rig_path: &Path, rec: &Path, held: &Path, json: &Path) -> (String, serde_json::Value) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["diagnose", "--rig"])
        .arg(rig_path)
        .arg("--recording")
        .arg(rec)
        .arg("--heldout")
        .arg(held)
        .arg("--json")
        .arg(json)
        .output()
        .expect("run rigcal");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = serde_json::from_str(&std::fs::read_to_string(json).expect("json")).expect("parse");
    (stdout, v)
}

#[test]
fn backlash_on_joint_6_is_found_named_and_modelled_on_tracker_recordings() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (rig, rig_path) = common::synthetic8::rig_in(dir.path());
    let mut sizes = Vec::new();
    for seed in [1u64, 2] {
        let w = world(&rig, seed, true);
        let (mut rec, poses) = record(&w, &rig, seed);
        // Seed 2 also carries two gross errors (rows 10 and 31: seq 11 and 32), 3 and 4 mm.
        let planted: Vec<u64> = if seed == 2 {
            for (k, off) in [
                (10usize, Vector3::new(3.0, 0.0, 0.0)),
                (31, Vector3::new(0.0, -2.4, 3.2)),
            ] {
                if let Some(p) = rec.rows[k].position.as_mut() {
                    *p += off;
                }
            }
            vec![11, 32]
        } else {
            Vec::new()
        };
        for j in 0..rig.chain.dof() {
            let f = reversal_fraction(&poses, j);
            assert!(
                f >= 1.0 / 3.0,
                "joint {} reverses in {f:.2} of moves",
                j + 1
            );
        }
        let (held, _) = record(&w, &rig, seed + 100);
        let rec_dir = dir.path().join(format!("rec{seed}"));
        let held_dir = dir.path().join(format!("held{seed}"));
        rec.write_dir(&rec_dir).expect("write");
        held.write_dir(&held_dir).expect("write");
        let (text, v) = diagnose(
            &rig_path,
            &rec_dir,
            &held_dir,
            &dir.path().join(format!("r{seed}.json")),
        );
        eprintln!("seed {seed}:\n{text}");
        // What the report must say about how it worked.
        assert!(text.contains("row order"), "{text}");
        assert!(
            text.contains("time-dependent effects") && text.contains("not considered"),
            "{text}"
        );
        assert!(
            v["mismatch"]["noise_floor_method"] == "residual_variance",
            "{}",
            v["mismatch"]
        );
        assert_eq!(v["mismatch"]["significant"], true);
        let e = &v["effects"][0];
        assert_eq!(e["kind"], "backlash", "{text}");
        assert_eq!(e["joint"], 6, "{text}");
        assert_eq!(v["effects"].as_array().map(Vec::len), Some(1), "{text}");
        assert_eq!(v["unexplained"], false, "{text}");
        let b = e["params"]["lost_motion_deg"].as_f64().expect("b");
        let sb = e["params_sigma"]["lost_motion_deg"].as_f64().expect("σ");
        assert!(
            (b - LOST_MOTION_DEG).abs() < (4.0 * sb).max(0.05),
            "lost motion {b} ± {sb}"
        );
        sizes.push((b, sb));
        // Outliers are judged after backlash is modelled: its reversal rows are never among them.
        let mut seqs: Vec<u64> = v["outliers"]
            .as_array()
            .map(|a| a.iter().filter_map(|o| o["seq"].as_u64()).collect())
            .unwrap_or_default();
        seqs.sort_unstable();
        assert_eq!(seqs, planted, "{text}");
        let before = v["fit"]["heldout_before_rms_mm"].as_f64().expect("before");
        let after = v["fit"]["heldout_after_rms_mm"].as_f64().expect("after");
        assert!(after < 0.7 * before, "held-out {before} → {after}");
        // Per effect: what the geometry absorbed and the held-out improvement it brings.
        let absorbed = e["absorbed_fraction"].as_f64().expect("absorbed");
        assert!((0.0..1.0).contains(&absorbed));
        let without = e["heldout_rms_without_mm"].as_f64().expect("without");
        let with = e["heldout_rms_with_mm"].as_f64().expect("with");
        assert!(with < without, "{with} vs {without}");
    }
    eprintln!("lost motion found (deg, ±σ): {sizes:?} (hidden: {LOST_MOTION_DEG})");
}

#[test]
fn no_effect_hidden_claims_nothing_on_tracker_recordings() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (rig, rig_path) = common::synthetic8::rig_in(dir.path());
    for seed in 10u64..14 {
        let w = world(&rig, seed, false);
        let (rec, _) = record(&w, &rig, seed);
        let (held, _) = record(&w, &rig, seed + 100);
        let rec_dir = dir.path().join(format!("rec{seed}"));
        let held_dir = dir.path().join(format!("held{seed}"));
        rec.write_dir(&rec_dir).expect("write");
        held.write_dir(&held_dir).expect("write");
        let (text, v) = diagnose(
            &rig_path,
            &rec_dir,
            &held_dir,
            &dir.path().join(format!("n{seed}.json")),
        );
        assert_eq!(v["mismatch"]["significant"], false, "seed {seed}:\n{text}");
        assert_eq!(v["effects"].as_array().map(Vec::len), Some(0), "{text}");
        assert_eq!(v["unexplained"], false, "{text}");
        assert_eq!(
            v["outliers"].as_array().map(Vec::len),
            Some(0),
            "seed {seed}:\n{text}"
        );
    }
}
