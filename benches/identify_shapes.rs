//! `identify` on recordings shaped like the ones users have (issue 33), not only white noise:
//! 2 200 RV-M2 rows whose residual after the geometry is white noise, structure (a first-harmonic
//! gear error of 0.025° on joints 1–3, no noise: `tests/fixtures/structured-rv-m2.toml`), the
//! same structure with a warm-up drift whose first rows the geometric judgement flags
//! (`benches/fixtures/structured-warm-up-rv-m2.toml`: the structure judgement runs), or white
//! noise with 20 gross rows; and a 6-DOF laser-tracker recording at every level. Each as
//! `rigcal identify` runs it in memory (outlier search and its judgement against the structure
//! included), then whole `rigcal identify` processes on the warm-up recording and the 6-DOF one
//! (the targets are whole processes).
//!
//! The 6-DOF recording is not in the repository: `RIGCAL_BENCH_6DOF_RIG` (a rig file) and
//! `RIGCAL_BENCH_6DOF_REC` (a recording directory) name one; otherwise the UR10 data of
//! `RIGCAL_BENCH_UR10_DATA` (default `../shared/data/ur10-landgraf`, beside the clone) is
//! imported as `scripts/ur10.sh` does and the first 1 000 rows of Series B are used (held-out
//! scoring: trained on the first 1 000 rows of Series A); without either that group is skipped
//! with a message. Run with `cargo bench --bench identify_shapes`.

use criterion::{criterion_group, criterion_main, Criterion};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::outliers::identify_options;
use rigcal_model::identification::{
    analyse, candidate_order, identify, random_poses, Identification, Level,
};
use rigcal_sim::world::{paper_geometric_errors, Scenario, World};
use std::path::{Path, PathBuf};
use std::process::Command;

const ROWS: usize = 2200;
const RV_M2: &str = "rigs/rv-m2-ideal.toml";
const WARM_UP: &str = "benches/fixtures/structured-warm-up-rv-m2.toml";
const UR10_JOINTS: &str =
    "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint";

/// White noise: the paper's geometric errors and 0.02 mm of noise.
fn white(rig: &Rig, poses: &[Vec<f64>]) -> Recording {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let design = random_poses(rig.chain.joints(), rig.held(), 100, &mut rng);
    let ident = analyse(&rig.chain, &design, &candidate_order(rig));
    let truth = paper_geometric_errors(&rig.chain, &ident, 1);
    World::new(rig.chain.clone(), truth, 0.02, 1).record(poses, 1)
}

/// `rec` with 20 rows (about 1 %) moved by 2–6 mm in random directions.
fn with_gross_rows(mut rec: Recording) -> Recording {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for k in 0..20 {
        let row = 50 + 107 * k;
        let d = nalgebra::Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize()
            * (2.0 + 0.2 * k as f64);
        if let Some(p) = rec.rows[row].position.as_mut() {
            *p += d;
        }
    }
    rec
}

/// What the identification decided, for the bench's log: rows removed, warning, RMS after.
fn verdict(id: &Identification) -> String {
    format!(
        "{} rows removed{}, RMS after {:.4} mm",
        id.outliers.len(),
        if id.outlier_warning.is_some() {
            " (too many failed: warning)"
        } else {
            ""
        },
        id.fit.after.rms_mm
    )
}

fn rv_m2(c: &mut Criterion) {
    let rig = Rig::load(Path::new(RV_M2)).expect("rig file");
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let poses = random_poses(rig.chain.joints(), rig.held(), ROWS, &mut rng);
    let scenario = |path: &str| Scenario::load(Path::new(path), None).expect("the scenario");
    let cases = [
        ("white noise", white(&rig, &poses)),
        (
            "structured, no noise",
            scenario("tests/fixtures/structured-rv-m2.toml")
                .world()
                .record(&poses, 1),
        ),
        (
            "structured with a warm-up, no noise",
            scenario(WARM_UP).world().record(&poses, 1),
        ),
        (
            "white noise, 20 gross rows",
            with_gross_rows(white(&rig, &poses)),
        ),
    ];
    let opts = identify_options();
    let mut g = c.benchmark_group("identify 2200 RV-M2 rows");
    g.sample_size(10);
    for (name, rec) in &cases {
        let id = identify(&rig, rec, Level::Full, &opts).expect("identify");
        eprintln!("{name}: {}", verdict(&id));
        g.bench_function(*name, |b| {
            b.iter(|| identify(&rig, rec, Level::Full, &opts).expect("identify"))
        });
    }
    g.finish();
}

/// A 6-DOF rig file and recording directory, with a second recording of the same rig for
/// held-out scoring when there is one: the `RIGCAL_BENCH_6DOF_*` pair, else the UR10 series
/// imported into `target/bench-ur10`. None (said why) when neither is there.
fn six_dof_files() -> Option<(PathBuf, PathBuf, Option<PathBuf>)> {
    if let (Ok(rig), Ok(rec)) = (
        std::env::var("RIGCAL_BENCH_6DOF_RIG"),
        std::env::var("RIGCAL_BENCH_6DOF_REC"),
    ) {
        return Some((rig.into(), rec.into(), None));
    }
    let data = PathBuf::from(
        std::env::var("RIGCAL_BENCH_UR10_DATA")
            .unwrap_or_else(|_| "../shared/data/ur10-landgraf".into()),
    );
    if !data.join("ur10.urdf").is_file() {
        eprintln!(
            "6-DOF groups skipped: no UR10 data at {} (set RIGCAL_BENCH_UR10_DATA, or \
             RIGCAL_BENCH_6DOF_RIG and RIGCAL_BENCH_6DOF_REC)",
            data.display()
        );
        return None;
    }
    let out = PathBuf::from("target/bench-ur10");
    std::fs::create_dir_all(&out).expect("target/bench-ur10");
    let rig = out.join("ur10.toml");
    rigcal(&[
        "rig",
        "from-urdf",
        s(&data.join("ur10.urdf")),
        "--base",
        "base_link",
        "--tip",
        "tool0",
        "--out",
        s(&rig),
    ]);
    let first_1000 = |series: &str, file: &str| {
        let all = out.join(format!("rec-{series}"));
        rigcal(&[
            "import",
            s(&data.join(format!("Series_{series}")).join(file)),
            "--rig",
            s(&rig),
            "--joints",
            UR10_JOINTS,
            "--point",
            "measurement_x,measurement_y,measurement_z",
            "--length-unit",
            "mm",
            "--angle-unit",
            "rad",
            "--out",
            s(&all),
        ]);
        let dir = out.join(format!("{series}-1000"));
        std::fs::create_dir_all(&dir).expect("recording directory");
        let text = std::fs::read_to_string(all.join("measurements.csv")).expect("imported");
        let head: Vec<&str> = text.lines().take(1001).collect();
        std::fs::write(dir.join("measurements.csv"), head.join("\n") + "\n").expect("written");
        dir
    };
    let b = first_1000("B", "measurements_joint_configurations.csv");
    let a = first_1000("A", "measurements_grid.csv");
    Some((rig, b, Some(a)))
}

fn rigcal(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .expect("rigcal runs");
    assert!(
        out.status.success(),
        "rigcal {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

const LEVELS: [(&str, Level); 3] = [
    ("frames", Level::Frames),
    ("offsets", Level::Offsets),
    ("full", Level::Full),
];

fn six_dof(c: &mut Criterion) {
    let Some((rig_path, rec_path, train)) = six_dof_files() else {
        return;
    };
    let rig = Rig::load(&rig_path).expect("the 6-DOF rig file");
    let rec = Recording::read(&rec_path, rig.chain.joints()).expect("the 6-DOF recording");
    let opts = identify_options();
    let mut g = c.benchmark_group(format!("identify {} 6-DOF poses", rec.observations().len()));
    g.sample_size(10);
    for (name, level) in LEVELS {
        let id = identify(&rig, &rec, level, &opts).expect("identify");
        eprintln!("{name}: {}", verdict(&id));
        g.bench_function(name, |b| {
            b.iter(|| identify(&rig, &rec, level, &opts).expect("identify"))
        });
    }
    g.finish();

    // Whole processes, as a user runs them (the targets).
    let model = std::env::temp_dir().join(format!("rigcal-bench-{}.json", std::process::id()));
    let mut g = c.benchmark_group("rigcal identify process, 6-DOF");
    g.sample_size(10);
    for (name, _) in LEVELS {
        g.bench_function(format!("--level {name}"), |b| {
            b.iter(|| {
                rigcal(&[
                    "identify",
                    "--rig",
                    s(&rig_path),
                    "--recording",
                    s(&rec_path),
                    "--level",
                    name,
                    "--out",
                    s(&model),
                ])
            })
        });
    }
    if let Some(train) = train {
        g.bench_function("A 1000 trained, B 1000 --heldout-session", |b| {
            b.iter(|| {
                rigcal(&[
                    "identify",
                    "--rig",
                    s(&rig_path),
                    "--recording",
                    s(&train),
                    "--heldout-session",
                    s(&rec_path),
                    "--out",
                    s(&model),
                ])
            })
        });
    }
    g.finish();
    let _ = std::fs::remove_file(&model);
}

fn warm_up_process(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("rigcal-bench-warm-{}", std::process::id()));
    let rec = dir.join("rec");
    rigcal(&[
        "simulate",
        "--rig",
        RV_M2,
        "--scenario",
        WARM_UP,
        "--random",
        &ROWS.to_string(),
        "--out",
        s(&rec),
    ]);
    let model = dir.join("model.json");
    let mut g = c.benchmark_group("rigcal identify process, 2200 RV-M2 rows");
    g.sample_size(10);
    g.bench_function("structured with a warm-up", |b| {
        b.iter(|| {
            rigcal(&[
                "identify",
                "--rig",
                RV_M2,
                "--recording",
                s(&rec),
                "--out",
                s(&model),
            ])
        })
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, rv_m2, six_dof, warm_up_process);
criterion_main!(benches);
