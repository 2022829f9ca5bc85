//! Outliers in `rigcal identify`: gross errors planted in a recording (a marker seen through a
//! reflection) are found with the right seq and file line, removed, and the fit then equals the
//! fit of the recording with those rows deleted; on clean recordings nothing is flagged.
//! Units: mm.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal::identification::{analyse, candidate_order, random_poses};
use rigcal::kinematics::Robot;
use rigcal::recording::Recording;
use rigcal::rig::Rig;
use rigcal::world::{paper_geometric_errors, World};
use std::path::Path;
use std::process::Command;

const RIG: &str = "rigs/rv-m2-ideal.toml";
const NOISE_MM: f64 = 0.05;

fn recording(seed: u64) -> Recording {
    let rig = Rig::load(Path::new(RIG)).expect("rig");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let design = random_poses(rig.chain.joints(), rig.held(), 60, &mut rng);
    let ident = analyse(&rig.chain, &design, &candidate_order(&rig));
    let truth = paper_geometric_errors(&rig.chain, &ident, seed);
    let poses = random_poses(rig.chain.joints(), rig.held(), 100, &mut rng);
    World::new(rig.chain.clone(), truth, NOISE_MM, 50 + seed).record(&poses, 1)
}

/// Runs `rigcal identify` and returns (stdout, model JSON).
fn identify(rec_dir: &Path, model: &Path) -> (String, serde_json::Value) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["identify", "--rig", RIG, "--recording"])
        .arg(rec_dir)
        .arg("--out")
        .arg(model)
        .output()
        .expect("run rigcal");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = serde_json::from_str(&std::fs::read_to_string(model).expect("model")).expect("json");
    (text, v)
}

fn params(v: &serde_json::Value) -> Vec<(String, f64, f64)> {
    v["model"]["parameters"]
        .as_array()
        .expect("parameters")
        .iter()
        .map(|p| {
            (
                p["name"].as_str().unwrap_or("").to_string(),
                p["value"].as_f64().unwrap_or(f64::NAN),
                p["sigma"].as_f64().unwrap_or(f64::NAN),
            )
        })
        .collect()
}

#[test]
fn planted_gross_errors_are_named_removed_and_the_fit_matches_the_clean_fit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut rec = recording(3);
    // Rows 17, 52 and 88 (seq 18, 53, 89; CSV lines 19, 54, 90) off by 2, 3.5 and 5 mm.
    let planted = [(17usize, 2.0), (52, 3.5), (88, 5.0)];
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    for &(k, size) in &planted {
        let dir3 = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize();
        if let Some(p) = rec.rows[k].position.as_mut() {
            *p += dir3 * size;
        }
    }
    let bad = dir.path().join("bad");
    rec.write_dir(&bad).expect("write");
    let (text, v) = identify(&bad, &dir.path().join("bad.json"));
    eprintln!("{text}");
    let found = v["outliers"].as_array().cloned().unwrap_or_default();
    let mut seqs: Vec<u64> = found.iter().filter_map(|o| o["seq"].as_u64()).collect();
    seqs.sort_unstable();
    assert_eq!(seqs, vec![18, 53, 89], "{text}");
    for o in &found {
        let seq = o["seq"].as_u64().unwrap_or(0);
        assert_eq!(o["line"].as_u64(), Some(seq + 1), "header is line 1");
        let size = o["size_mm"].as_f64().unwrap_or(0.0);
        let want = planted
            .iter()
            .find(|(k, _)| *k as u64 + 1 == seq)
            .map_or(0.0, |p| p.1);
        assert!((size - want).abs() < 0.5, "seq {seq}: {size} mm vs {want}");
        assert!(
            text.contains(&format!("seq {seq}, line {}", seq + 1)),
            "{text}"
        );
    }
    // The same recording with the three rows deleted: the fits agree.
    let mut clean = rec.clone();
    let drop: Vec<usize> = planted.iter().map(|p| p.0).collect();
    clean.rows = clean
        .rows
        .iter()
        .enumerate()
        .filter(|(k, _)| !drop.contains(k))
        .map(|(_, r)| r.clone())
        .collect();
    let clean_dir = dir.path().join("clean");
    clean.write_dir(&clean_dir).expect("write");
    let (_, c) = identify(&clean_dir, &dir.path().join("clean.json"));
    assert_eq!(c["outliers"].as_array().map_or(0, Vec::len), 0);
    for ((n, a, sa), (m, b, _)) in params(&v).iter().zip(params(&c).iter()) {
        assert_eq!(n, m);
        assert!(
            (a - b).abs() <= 1e-3 * sa.max(1e-9),
            "{n}: {a} vs {b} (σ {sa})"
        );
    }
}

#[test]
fn clean_recordings_have_no_outliers() {
    let dir = tempfile::tempdir().expect("tempdir");
    for seed in 10..15u64 {
        let d = dir.path().join(format!("r{seed}"));
        recording(seed).write_dir(&d).expect("write");
        let (text, v) = identify(&d, &dir.path().join(format!("m{seed}.json")));
        assert!(v.get("outliers").is_none(), "seed {seed}: {text}");
        assert!(text.contains("outliers: none"), "{text}");
    }
}

/// False flags on clean recordings over many seeds (run with `--ignored --nocapture`; designed
/// rate about 1 % of recordings).
#[test]
#[ignore]
fn clean_recording_false_flag_rate() {
    let dir = tempfile::tempdir().expect("tempdir");
    let n = 100u64;
    let mut flagged = 0;
    for seed in 1000..1000 + n {
        let d = dir.path().join(format!("r{seed}"));
        recording(seed).write_dir(&d).expect("write");
        let (_, v) = identify(&d, &dir.path().join(format!("m{seed}.json")));
        if v.get("outliers").is_some() {
            flagged += 1;
        }
    }
    eprintln!("clean recordings with a row flagged: {flagged}/{n}");
}
