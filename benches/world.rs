//! Simulating a paper-sized session (2200 measurements = 20 × 110 regions, seed 000 section 6)
//! on the ideal rig and on the table-and-panel rig with its physics.

use criterion::{criterion_group, criterion_main, Criterion};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::Robot;
use rigcal_model::identification::random_poses;
use rigcal_sim::world::Scenario;
use std::hint::black_box;
use std::path::Path;

fn simulate_2200(c: &mut Criterion) {
    for name in ["paper-sim", "rig-realistic"] {
        let sc = Scenario::load(Path::new(&format!("sim/{name}.toml")), None)
            .unwrap_or_else(|e| panic!("{e}"));
        let world = sc.world();
        let poses = random_poses(
            sc.rig.chain.joints(),
            sc.rig.held(),
            2200,
            &mut ChaCha8Rng::seed_from_u64(1),
        );
        c.bench_function(&format!("simulate 2200 measurements ({name})"), |b| {
            b.iter(|| black_box(world.record(black_box(&poses), 1)))
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = simulate_2200
}
criterion_main!(benches);
