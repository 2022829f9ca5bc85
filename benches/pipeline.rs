//! Benchmarks of the calibration pipeline: identification from 2200 measurements (the paper's
//! data set size) and compensation throughput. Run with `cargo bench --bench pipeline`.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rigcal::compensation::{compensate, CompensationOptions};
use rigcal::identification::{
    analyse, candidate_order, fit, random_poses, FitOptions, Observation,
};
use rigcal::kinematics::{ErrorParams, Robot};
use rigcal::rig::Rig;
use rigcal::world::{paper_geometric_errors, World};
use std::path::Path;

fn setup() -> (Rig, World, Vec<usize>) {
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).expect("rig file");
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let design = random_poses(rig.chain.joints(), rig.held(), 100, &mut rng);
    let ident = analyse(&rig.chain, &design, &candidate_order(&rig));
    let truth = paper_geometric_errors(&rig.chain, &ident, 1);
    let world = World::new(rig.chain.clone(), truth, 0.02, 1);
    (rig, world, ident.basis)
}

fn identification(c: &mut Criterion) {
    let (rig, world, basis) = setup();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let poses = random_poses(rig.chain.joints(), rig.held(), 2200, &mut rng);
    let obs: Vec<Observation> = poses
        .iter()
        .enumerate()
        .map(|(k, q)| Observation {
            q: q.clone(),
            p: world.measure(q, k as u64, 0),
        })
        .collect();
    let zero = ErrorParams::zeros(rig.chain.layout());
    let mut g = c.benchmark_group("identification");
    g.sample_size(20);
    g.bench_function("15 parameters from 2200 measurements", |b| {
        b.iter(|| fit(&rig.chain, &obs, &zero, &basis, &FitOptions::default()).expect("fit"))
    });
    g.finish();
}

fn compensation(c: &mut Criterion) {
    let (rig, world, basis) = setup();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let poses = random_poses(rig.chain.joints(), rig.held(), 200, &mut rng);
    let obs: Vec<Observation> = poses
        .iter()
        .enumerate()
        .map(|(k, q)| Observation {
            q: q.clone(),
            p: world.measure(q, k as u64, 0),
        })
        .collect();
    let zero = ErrorParams::zeros(rig.chain.layout());
    let model = fit(&rig.chain, &obs, &zero, &basis, &FitOptions::default())
        .expect("fit")
        .params;
    let opts = CompensationOptions::default();
    // Targets whose compensated command stays within the limits (a few near a limit do not).
    let targets: Vec<_> = random_poses(rig.chain.joints(), rig.held(), 1100, &mut rng)
        .iter()
        .map(|q| rig.chain.position(q, &zero))
        .filter(|t| compensate(&rig.chain, &model, t, rig.held(), None, &opts).is_ok())
        .take(1000)
        .collect();
    let mut g = c.benchmark_group("compensation");
    g.throughput(Throughput::Elements(targets.len() as u64));
    g.sample_size(10);
    g.bench_function(
        "1000 random targets, cold start (nominal IK + iteration)",
        |b| {
            b.iter_batched(
                || (),
                |_| {
                    for t in &targets {
                        compensate(&rig.chain, &model, t, rig.held(), None, &opts)
                            .expect("compensate");
                    }
                },
                BatchSize::SmallInput,
            )
        },
    );
    g.finish();
}

criterion_group!(benches, identification, compensation);
criterion_main!(benches);
