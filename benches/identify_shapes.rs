//! `identify` on recordings shaped like the ones users have (issue 33), not only white noise:
//! 2 200 RV-M2 rows whose residual after the geometry is white noise, structure (a first-harmonic
//! gear error of 0.025° on joints 1–3, no noise: `tests/fixtures/structured-rv-m2.toml`) or
//! white noise with 20 gross rows; and a 6-DOF tracker recording at every level, when one is
//! given. Each as `rigcal identify` runs it in memory (outlier search and its judgement against
//! the structure included).
//!
//! The 6-DOF recording is not in the repository: set `RIGCAL_BENCH_6DOF_RIG` (a rig file) and
//! `RIGCAL_BENCH_6DOF_REC` (a recording directory), e.g. the first 1 000 rows of the UR10's
//! Series B imported as docs/real-data.md shows (docs/benchmarks.md has the commands); without
//! them that group is skipped. Run with `cargo bench --bench identify_shapes`.

use criterion::{criterion_group, criterion_main, Criterion};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::outliers::identify_options;
use rigcal_model::identification::{analyse, candidate_order, identify, random_poses, Level};
use rigcal_sim::world::{paper_geometric_errors, Scenario, World};
use std::path::Path;

const ROWS: usize = 2200;

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

fn rv_m2(c: &mut Criterion) {
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).expect("rig file");
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let poses = random_poses(rig.chain.joints(), rig.held(), ROWS, &mut rng);
    let sc = Scenario::load(Path::new("tests/fixtures/structured-rv-m2.toml"), None)
        .expect("the structured scenario");
    let cases = [
        ("white noise", white(&rig, &poses)),
        ("structured, no noise", sc.world().record(&poses, 1)),
        (
            "white noise, 20 gross rows",
            with_gross_rows(white(&rig, &poses)),
        ),
    ];
    let opts = identify_options();
    let mut g = c.benchmark_group("identify 2200 RV-M2 rows");
    g.sample_size(10);
    for (name, rec) in &cases {
        g.bench_function(*name, |b| {
            b.iter(|| identify(&rig, rec, Level::Full, &opts).expect("identify"))
        });
    }
    g.finish();
}

fn six_dof(c: &mut Criterion) {
    let (Ok(rig), Ok(rec)) = (
        std::env::var("RIGCAL_BENCH_6DOF_RIG"),
        std::env::var("RIGCAL_BENCH_6DOF_REC"),
    ) else {
        eprintln!("6-DOF group skipped: set RIGCAL_BENCH_6DOF_RIG and RIGCAL_BENCH_6DOF_REC");
        return;
    };
    let rig = Rig::load(Path::new(&rig)).expect("the 6-DOF rig file");
    let rec = Recording::read(Path::new(&rec), rig.chain.joints()).expect("the 6-DOF recording");
    let opts = identify_options();
    let mut g = c.benchmark_group(format!("identify {} 6-DOF poses", rec.observations().len()));
    g.sample_size(10);
    for (name, level) in [
        ("frames", Level::Frames),
        ("offsets", Level::Offsets),
        ("full", Level::Full),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| identify(&rig, &rec, level, &opts).expect("identify"))
        });
    }
    g.finish();
}

criterion_group!(benches, rv_m2, six_dof);
criterion_main!(benches);
