//! `diagnose` on recordings shaped like the ones users have (issue 33): whole `rigcal diagnose`
//! processes on a TIAGo Pro motion-capture session (0701, the other two sessions held out with
//! their frame refitted, as `scripts/tiago-pro.sh` runs it), on 1 000 rows of the UR10's Series A
//! (every 12th row: 993 rows spread over the grid) and on all 11 911 rows of Series A; and in
//! memory, simulated RV-M2 recordings of 600 and 12 000 rows (white noise; and the structured
//! first-harmonic gear error of `tests/fixtures/structured-rv-m2.toml`, whose residual after the
//! geometry is all structure). Each case's verdict (effects named, rows removed) is printed
//! before it is timed.
//!
//! The UR10 data is not in the repository: `RIGCAL_BENCH_UR10_DATA` (default
//! `../shared/data/ur10-landgraf`, beside the clone) is imported into `target/bench-ur10` as
//! `scripts/ur10.sh` does; without it the UR10 cases are skipped with a message. The long cases
//! (11 911 and 12 000 rows) take 10 flat samples, and are skipped under `cargo test`. Run with
//! `cargo bench --bench diagnose_shapes` (`-- tiago`, `-- 1000`, … picks cases by name).

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::{diagnose, Options, Report};
use rigcal_model::identification::{analyse, candidate_order, random_poses};
use rigcal_sim::world::{paper_geometric_errors, Scenario, World};
use std::path::{Path, PathBuf};
use std::process::Command;

const RV_M2: &str = "rigs/rv-m2-ideal.toml";
const STRUCTURED: &str = "tests/fixtures/structured-rv-m2.toml";
const TIAGO_RIG: &str = "rigs/tiago-pro.toml";
const TIAGO_DATA: &str = "tests/data/tiago-pro";
const TIAGO_JOINTS: &str = "torso_lift_joint,arm_right_1_joint,arm_right_2_joint,arm_right_3_joint,arm_right_4_joint,arm_right_5_joint,arm_right_6_joint,arm_right_7_joint";
const UR10_JOINTS: &str =
    "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint";
/// Every this many rows of Series A make the 1 000-row subset.
const UR10_EVERY: usize = 12;

/// Whether the cases of 11 911 and 12 000 rows are skipped: when `RIGCAL_BENCH_SKIP_LONG` is set,
/// and under `cargo test --all-targets`, which runs each bench once as a check (cargo passes
/// `--bench` only to a real benchmark run); minutes of one-off diagnosis would dominate the suite.
fn skip_long() -> bool {
    if std::env::var_os("RIGCAL_BENCH_SKIP_LONG").is_some() {
        eprintln!("the 11 911- and 12 000-row cases skipped: RIGCAL_BENCH_SKIP_LONG is set");
        return true;
    }
    if !std::env::args().any(|a| a == "--bench") {
        eprintln!("the 11 911- and 12 000-row cases skipped: not a benchmark run (`cargo bench`)");
        return true;
    }
    false
}

fn rigcal(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .expect("rigcal runs");
    assert!(
        out.status.success(),
        "rigcal {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

/// The lines of a printed diagnosis that carry its verdict.
fn printed_verdict(stdout: &str) -> String {
    stdout
        .lines()
        .filter(|l| {
            l.starts_with("effect:")
                || l.starts_with("outlier removed")
                || l.starts_with("unexplained")
                || l.starts_with("significant")
        })
        .map(|l| l.chars().take(110).collect::<String>())
        .collect::<Vec<_>>()
        .join("\n  ")
}

/// A report's verdict in one line: effects named, shapes left unexplained, rows removed.
fn verdict(r: &Report) -> String {
    let effects: Vec<String> = r
        .effects
        .iter()
        .map(|e| {
            format!(
                "{:?}{}",
                e.kind,
                e.joint
                    .map(|j| format!(" on joint {j}"))
                    .unwrap_or_default()
            )
        })
        .collect();
    format!(
        "effects named [{}], {} unexplained shape(s), {} row(s) removed",
        effects.join(", "),
        r.out_of_library.len(),
        r.outliers.len()
    )
}

/// The TIAGo Pro sessions imported into `target/bench-tiago`: (0701, [0702, 0805]).
fn tiago_sessions() -> (PathBuf, Vec<PathBuf>) {
    let out = PathBuf::from("target/bench-tiago");
    let import = |stamp: &str| {
        let dir = out.join(&stamp[..4]);
        rigcal(&[
            "import",
            &format!("{TIAGO_DATA}/calibration_samples_2026{stamp}.csv"),
            "--rig",
            TIAGO_RIG,
            "--joints",
            TIAGO_JOINTS,
            "--point",
            "x1,y1,z1",
            "--out",
            s(&dir),
        ]);
        dir
    };
    let train = import("0701_0913");
    let held = vec![import("0702_0756"), import("0805_1246")];
    (train, held)
}

fn tiago(c: &mut Criterion) {
    let (train, held) = tiago_sessions();
    let mut args = vec![
        "diagnose",
        "--rig",
        TIAGO_RIG,
        "--recording",
        s(&train),
        "--heldout-session",
    ];
    args.extend(held.iter().map(|p| s(p)));
    eprintln!("TIAGo 0701: {}", printed_verdict(&rigcal(&args)));
    let mut g = c.benchmark_group("rigcal diagnose process, TIAGo Pro");
    g.sample_size(10);
    g.bench_function("0701, 0702 and 0805 held out", |b| b.iter(|| rigcal(&args)));
    g.finish();
}

/// The UR10 rig and Series A imported into `target/bench-ur10` as `scripts/ur10.sh` does, and
/// its every-12th-row subset: (rig, all of A, the subset). None (said why) without the data.
fn ur10_files() -> Option<(PathBuf, PathBuf, PathBuf)> {
    let data = PathBuf::from(
        std::env::var("RIGCAL_BENCH_UR10_DATA")
            .unwrap_or_else(|_| "../shared/data/ur10-landgraf".into()),
    );
    if !data.join("ur10.urdf").is_file() {
        eprintln!(
            "UR10 cases skipped: no UR10 data at {} (set RIGCAL_BENCH_UR10_DATA)",
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
    let all = out.join("rec-A-pose");
    rigcal(&[
        "import",
        s(&data.join("Series_A/measurements_grid.csv")),
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
        "--orientation",
        "measurement_rx,measurement_ry,measurement_rz",
        "--euler",
        "intrinsic-xyz",
        "--orientation-unit",
        "deg",
        "--temperature",
        "measurement_temperature",
        "--out",
        s(&all),
    ]);
    // Every 12th data row, header kept (scripts/ur10.sh's UR10_TRAIN_EVERY=12).
    let subset = out.join(format!("A-every{UR10_EVERY}"));
    std::fs::create_dir_all(&subset).expect("recording directory");
    let text = std::fs::read_to_string(all.join("measurements.csv")).expect("imported");
    let rows: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(k, _)| *k == 0 || (k - 1) % UR10_EVERY == 0)
        .map(|(_, l)| l)
        .collect();
    std::fs::write(subset.join("measurements.csv"), rows.join("\n") + "\n").expect("written");
    Some((rig, all, subset))
}

fn ur10(c: &mut Criterion) {
    let Some((rig, all, subset)) = ur10_files() else {
        return;
    };
    let args = |rec: &Path| -> Vec<String> {
        ["diagnose", "--rig", s(&rig), "--recording", s(rec)]
            .map(String::from)
            .to_vec()
    };
    let run = |a: &[String]| rigcal(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let few = args(&subset);
    eprintln!("UR10 A every 12th row: {}", printed_verdict(&run(&few)));
    let mut g = c.benchmark_group("rigcal diagnose process, UR10 Series A");
    g.sample_size(10);
    g.bench_function("993 rows (every 12th)", |b| b.iter(|| run(&few)));
    if !skip_long() {
        let many = args(&all);
        g.sampling_mode(SamplingMode::Flat);
        g.bench_function("all 11 911 rows", |b| b.iter(|| run(&many)));
    }
    g.finish();
}

/// `rows` random RV-M2 poses measured in a world with the paper's geometric errors and 0.02 mm
/// of noise, or in the structured scenario (no noise).
fn simulated(rows: usize, structured: bool) -> (Rig, Recording) {
    let rig = Rig::load(Path::new(RV_M2)).expect("rig file");
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let poses = random_poses(rig.chain.joints(), rig.held(), rows, &mut rng);
    let rec = if structured {
        let scenario = Scenario::load(Path::new(STRUCTURED), None).expect("the scenario");
        scenario.world().record(&poses, 1)
    } else {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let design = random_poses(rig.chain.joints(), rig.held(), 100, &mut rng);
        let ident = analyse(&rig.chain, &design, &candidate_order(&rig));
        let truth = paper_geometric_errors(&rig.chain, &ident, 1);
        World::new(rig.chain.clone(), truth, 0.02, 1).record(&poses, 1)
    };
    (rig, rec)
}

fn simulated_rows(c: &mut Criterion) {
    let mut g = c.benchmark_group("diagnose simulated RV-M2 rows");
    g.sample_size(10);
    let long = !skip_long();
    for (rows, structured) in [(600, false), (600, true), (12_000, false), (12_000, true)] {
        if rows > 1_000 && !long {
            continue;
        }
        let (rig, rec) = simulated(rows, structured);
        let name = format!(
            "{rows} rows, {}",
            if structured {
                "structured"
            } else {
                "white noise"
            }
        );
        let report = diagnose(&rig, &rec, &Options::default()).expect("diagnose");
        eprintln!("{name}: {}", verdict(&report));
        if rows > 1_000 {
            g.sampling_mode(SamplingMode::Flat);
        }
        g.bench_function(&name, |b| {
            b.iter(|| diagnose(&rig, &rec, &Options::default()).expect("diagnose"))
        });
    }
    g.finish();
}

criterion_group!(benches, tiago, ur10, simulated_rows);
criterion_main!(benches);
