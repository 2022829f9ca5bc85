//! Outliers in `rigcal identify` and [`rigcal_model::identification::identify`]: gross errors planted
//! in a recording (a marker seen through a reflection) are found with the right seq and file
//! line, removed, and the fit then equals the fit of the recording with those rows deleted; on
//! clean recordings nothing is flagged; too many outliers remove nothing and say so; a clean
//! recording whose residual is strongly structured (large non-geometric effects, in or out of
//! the diagnosis's library) keeps every row, and planted rows are still found in it. The
//! pipeline's held-out report and its refusals are checked here too. Units: mm.

mod common;

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::identification::{
    analyse, candidate_order, identify, random_poses, HeldOut, IdentifyError, IdentifyOptions,
    Level,
};
use rigcal_sim::world::{paper_geometric_errors, World};
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
fn run_identify(rec_dir: &Path, model: &Path) -> (String, serde_json::Value) {
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
    let (text, v) = run_identify(&bad, &dir.path().join("bad.json"));
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
    let (_, c) = run_identify(&clean_dir, &dir.path().join("clean.json"));
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
        let (text, v) = run_identify(&d, &dir.path().join(format!("m{seed}.json")));
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
        let (_, v) = run_identify(&d, &dir.path().join(format!("m{seed}.json")));
        if v.get("outliers").is_some() {
            flagged += 1;
        }
    }
    eprintln!("clean recordings with a row flagged: {flagged}/{n}");
}

/// `recording(seed)` with rows moved by the given sizes (mm) in random directions.
fn with_planted(seed: u64, planted: &[(usize, f64)]) -> Recording {
    let mut rec = recording(seed);
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    for &(k, size) in planted {
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
    rec
}

#[test]
fn the_library_pipeline_returns_the_planted_rows_with_their_file_lines() {
    let rig = Rig::load(Path::new(RIG)).expect("rig");
    let dir = tempfile::tempdir().expect("tempdir");
    with_planted(3, &[(17, 2.0), (52, 3.5), (88, 5.0)])
        .write_dir(dir.path())
        .expect("write");
    let rec = Recording::read(dir.path(), rig.chain.joints()).expect("read");
    let id = identify(
        &rig,
        &rec,
        Level::Full,
        &rigcal_model::diagnosis::outliers::identify_options(),
    )
    .expect("identify");
    let mut found: Vec<(u64, Option<u64>)> = id.outliers.iter().map(|o| (o.seq, o.line)).collect();
    found.sort_unstable();
    assert_eq!(found, vec![(18, Some(19)), (53, Some(54)), (89, Some(90))]);
    assert!(id.outlier_warning.is_none());
    assert_eq!(id.fit.after.n, 97, "the three rows are not fitted");
}

#[test]
fn gross_rows_past_five_percent_are_removed_and_named() {
    let rig = Rig::load(Path::new(RIG)).expect("rig");
    let options = rigcal_model::diagnosis::outliers::identify_options();
    // 8 of 100 rows off by 3–6 mm: more than 5 %, but each gross beyond doubt (far past the
    // robust scale of the rest): removed and named.
    let planted: Vec<(usize, f64)> = (0..8).map(|k| (5 + 12 * k, 3.0 + k as f64 / 2.0)).collect();
    let id = identify(&rig, &with_planted(4, &planted), Level::Full, &options).expect("identify");
    let mut found: Vec<u64> = id.outliers.iter().map(|o| o.seq).collect();
    found.sort_unstable();
    let expected: Vec<u64> = planted.iter().map(|&(i, _)| i as u64 + 1).collect();
    assert_eq!(found, expected);
    assert!(id.outlier_warning.is_none());
    assert_eq!(id.fit.after.n, 92);
}

/// `recording(seed)` with `count` rows, drawn at random, moved `lo`–`hi` mm in random
/// directions; returns the recording and the moved rows' seqs.
fn with_random_gross_rows(seed: u64, count: usize, lo: f64, hi: f64) -> (Recording, Vec<u64>) {
    let mut rec = recording(seed);
    let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
    let n = rec.rows.len();
    let mut order: Vec<usize> = (0..n).collect();
    for i in 0..count {
        let j = rng.random_range(i..n);
        order.swap(i, j);
    }
    for &k in &order[..count] {
        let dir = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize();
        let size = rng.random_range(lo..hi);
        if let Some(p) = rec.rows[k].position.as_mut() {
            *p += dir * size;
        }
    }
    let mut seqs: Vec<u64> = order[..count].iter().map(|&k| rec.rows[k].seq).collect();
    seqs.sort_unstable();
    (rec, seqs)
}

#[test]
fn more_gross_rows_than_the_cap_are_refused_never_partly_removed_in_silence() {
    // 24 of 100 rows gross (past the 20 % cap): the identification must remove none and say
    // so. 18 of 100 (within the cap) are all removed and named. Before the screen's
    // leave-one-out check (`Screened::keeps_unpredicted`) its smooth model (rank 85 on 300
    // equations) bent to the gross rows: identify removed 0–7 of the 24 without a warning in
    // 15 of these 24 cases (seed 12 at 1–2 mm: none removed, no warning), and at seed 4 not
    // the 18 planted.
    let rig = Rig::load(Path::new(RIG)).expect("rig");
    let options = rigcal_model::diagnosis::outliers::identify_options();
    for seed in 1..=12 {
        for (lo, hi) in [(1.0, 2.0), (3.0, 6.5)] {
            let (rec, _) = with_random_gross_rows(seed, 24, lo, hi);
            let id = identify(&rig, &rec, Level::Full, &options).expect("identify");
            assert!(
                id.outlier_warning.is_some() && id.outliers.is_empty(),
                "seed {seed}, 24 rows at {lo}–{hi} mm: {} removed, warning {:?}",
                id.outliers.len(),
                id.outlier_warning
            );
        }
        let (rec, planted) = with_random_gross_rows(seed, 18, 0.5, 1.5);
        let id = identify(&rig, &rec, Level::Full, &options).expect("identify");
        let mut found: Vec<u64> = id.outliers.iter().map(|o| o.seq).collect();
        found.sort_unstable();
        assert_eq!(found, planted, "seed {seed}, 18 rows at 0.5–1.5 mm");
        assert!(id.outlier_warning.is_none());
    }
}

#[test]
fn held_out_recordings_compare_nominal_kinematics_with_the_fit() {
    let rig = Rig::load(Path::new(RIG)).expect("rig");
    let options = IdentifyOptions {
        heldout: vec![HeldOut {
            name: "another day".into(),
            recording: recording(3),
        }],
        ..rigcal_model::diagnosis::outliers::identify_options()
    };
    let id = identify(&rig, &recording(3), Level::Full, &options).expect("identify");
    let [h] = id.heldout.as_slice() else {
        panic!("one report per held-out recording: {:?}", id.heldout)
    };
    assert_eq!((h.name.as_str(), h.points), ("another day", 100));
    assert!(h.nominal.rms_mm > 10.0 * h.fitted.rms_mm, "{h:?}");
    // 3-D RMS of the noise is √3 · 0.05 mm.
    assert!(h.fitted.rms_mm < 1.3 * 3f64.sqrt() * NOISE_MM, "{h:?}");
    let empty = IdentifyOptions {
        heldout: vec![HeldOut {
            name: "empty".into(),
            recording: Recording::new(rig.chain.joints()),
        }],
        ..rigcal_model::diagnosis::outliers::identify_options()
    };
    let e = identify(&rig, &recording(3), Level::Full, &empty).expect_err("no measured rows");
    assert!(
        matches!(&e, IdentifyError::HeldOutEmpty { name } if name == "empty"),
        "{e}"
    );
}

#[test]
fn a_fixed_frame_leaves_nothing_to_fit_at_level_frames_and_no_rows_is_an_error() {
    let rig = Rig::load(Path::new(RIG)).expect("rig");
    let opts = rigcal_model::diagnosis::outliers::identify_options();
    let e = identify(&rig, &recording(3), Level::Frames, &opts).expect_err("nothing to fit");
    assert!(
        matches!(
            e,
            IdentifyError::NothingToFit {
                level: Level::Frames
            }
        ),
        "{e}"
    );
    let e = identify(
        &rig,
        &Recording::new(rig.chain.joints()),
        Level::Full,
        &opts,
    )
    .expect_err("no rows");
    assert!(matches!(e, IdentifyError::NoMeasurements), "{e}");
}

/// Clean recordings whose residual after the geometry is strongly structured: each of these
/// lost 16–20 rows (or warned of too many outliers) when outliers were judged against the
/// geometric fit alone, since the largest rows of a structured residual look like outliers.
fn structured_cases() -> Vec<common::shapes::Case> {
    use common::shapes::*;
    let lib = library_cases();
    let by_name = |n: &str| lib.iter().find(|c| c.name == n).expect("case");
    vec![
        in_library(by_name("joint_compliance:2"), 1, Some(10.0)),
        in_library(by_name("transmission_error:1"), 1, Some(10.0)),
        in_library(by_name("thermal_drift:z"), 0, Some(10.0)),
        out_of_library(Class::Deformation, 1, 5.0),
        out_of_library(Class::Dent, 0, 5.0),
    ]
}

#[test]
fn a_clean_recording_with_structured_residuals_keeps_every_row() {
    for (k, c) in structured_cases().into_iter().enumerate() {
        let n = c.recording.observations().len();
        let levels: &[Level] = if k == 0 {
            &[Level::Full, Level::Offsets]
        } else {
            &[Level::Full]
        };
        for &level in levels {
            let id = identify(
                &c.scenario.rig,
                &c.recording,
                level,
                &rigcal_model::diagnosis::outliers::identify_options(),
            )
            .expect("identify");
            assert!(
                id.outliers.is_empty() && id.outlier_warning.is_none(),
                "{} at {level:?}: {:?} {:?}",
                c.label,
                id.outliers
                    .iter()
                    .map(|o| (o.seq, o.size_mm))
                    .collect::<Vec<_>>(),
                id.outlier_warning
            );
            assert_eq!(id.fit.after.n, n, "{}: every row fitted", c.label);
        }
    }
    // The realistic table rig (compliance, backlash, gear error, drift, table errors,
    // quantisation) keeps every row too.
    let sc =
        rigcal_sim::world::Scenario::load(Path::new("sim/rig-realistic.toml"), None).expect("sc");
    let rig = &sc.rig;
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let mut poses = Vec::new();
    while poses.len() < 300 {
        let q = random_poses(rig.chain.joints(), rig.held(), 1, &mut rng).remove(0);
        if rig.measurable(&q).is_ok() {
            poses.push(q);
        }
    }
    let rec = sc.world().record(&poses, 1);
    let id = identify(
        rig,
        &rec,
        Level::Full,
        &rigcal_model::diagnosis::outliers::identify_options(),
    )
    .expect("identify");
    assert!(
        id.outliers.is_empty() && id.outlier_warning.is_none(),
        "{:?}",
        id.outliers
    );
}

#[test]
fn planted_rows_are_found_in_a_structured_recording() {
    // The structured cases with rows 17, 52 and 88 moved by 2, 3.5 and 5 mm: exactly those are
    // found, with their sizes, and the fit equals the fit without them.
    for mut c in structured_cases().into_iter().step_by(3) {
        let rig = c.scenario.rig.clone();
        let planted = [(17usize, 2.0), (52, 3.5), (88, 5.0)];
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        for &(k, size) in &planted {
            let d = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            if let Some(p) = c.recording.rows[k].position.as_mut() {
                *p += d * size;
            }
        }
        let id = identify(
            &rig,
            &c.recording,
            Level::Full,
            &rigcal_model::diagnosis::outliers::identify_options(),
        )
        .expect("identify");
        let mut found: Vec<(u64, f64)> = id.outliers.iter().map(|o| (o.seq, o.size_mm)).collect();
        found.sort_by_key(|f| f.0);
        assert_eq!(
            found.iter().map(|f| f.0).collect::<Vec<_>>(),
            vec![18, 53, 89],
            "{}: {found:?}",
            c.label
        );
        for ((_, size), (_, want)) in found.iter().zip(planted) {
            assert!((size - want).abs() < 0.5, "{}: {size} vs {want}", c.label);
        }
        let mut clean = c.recording.clone();
        clean.rows = clean
            .rows
            .iter()
            .enumerate()
            .filter(|(k, _)| !planted.iter().any(|p| p.0 == *k))
            .map(|(_, r)| r.clone())
            .collect();
        let plain = identify(
            &rig,
            &clean,
            Level::Full,
            &rigcal_model::diagnosis::outliers::identify_options(),
        )
        .expect("identify");
        for k in 0..id.fit.params.len() {
            let (a, b) = (id.fit.params.get(k), plain.fit.params.get(k));
            assert!(
                (a - b).abs() < 1e-9 + 1e-6 * b.abs(),
                "{}: parameter {k}: {a} vs {b}",
                c.label
            );
        }
    }
}

#[test]
fn gross_rows_in_a_structured_recording_are_the_rows_the_structure_judgement_finds() {
    // The paper's recording: geometry, eq. (6) joint errors (9 % of the error) and 0.016 mm
    // noise, so the geometric residual is structured. Rows 40 and 200 moved by 3 and 2 mm are
    // far beyond every other row: the geometric judgement removes them alone (no diagnosis),
    // and they are the rows the diagnosis's structure judgement finds, with the same sizes.
    use rigcal_model::identification::outliers::OutlierSettings;
    let sc = rigcal_sim::world::Scenario::load(Path::new("sim/paper-sim-noise.toml"), None)
        .expect("scenario");
    let rig = &sc.rig;
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let poses = random_poses(rig.chain.joints(), rig.held(), 300, &mut rng);
    let mut rec = sc.world().record(&poses, 1);
    for (k, d) in [
        (40usize, Vector3::new(3.0, 0.0, 0.0)),
        (200, Vector3::new(0.0, 1.2, -1.6)),
    ] {
        if let Some(p) = rec.rows[k].position.as_mut() {
            *p += d;
        }
    }
    let id = identify(
        rig,
        &rec,
        Level::Full,
        &rigcal_model::diagnosis::outliers::identify_options(),
    )
    .expect("identify");
    let mut fast: Vec<(u64, f64)> = id.outliers.iter().map(|o| (o.seq, o.size_mm)).collect();
    fast.sort_by_key(|f| f.0);
    assert_eq!(fast.iter().map(|f| f.0).collect::<Vec<_>>(), vec![41, 201]);
    assert_eq!(id.fit.after.n, 298);
    let mut judged: Vec<(u64, f64)> =
        rigcal_model::diagnosis::outliers::outliers_against_structure(
            rig,
            &rec,
            &OutlierSettings::default(),
        )
        .expect("the diagnosis models the recording")
        .expect("two rows are not too many")
        .iter()
        .map(|o| (o.seq, o.size_mm))
        .collect();
    judged.sort_by_key(|f| f.0);
    assert_eq!(
        judged.iter().map(|f| f.0).collect::<Vec<_>>(),
        vec![41, 201],
        "{judged:?}"
    );
    for ((_, a), (_, b)) in fast.iter().zip(&judged) {
        assert!((a - b).abs() < 0.05, "{a} vs {b} mm");
    }
    for ((_, size), want) in fast.iter().zip([3.0, 2.0]) {
        assert!((size - want).abs() < 0.1, "{size} vs {want}");
    }
}
