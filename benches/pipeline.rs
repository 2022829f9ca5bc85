//! Benchmarks of the calibration pipeline: identification from 2200 measurements (the paper's
//! data set size) and compensation throughput. Run with `cargo bench --bench pipeline`.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
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

/// The world's measurements at `poses`, numbered from 0.
fn observe(world: &World, poses: &[Vec<f64>]) -> Vec<Observation> {
    poses
        .iter()
        .enumerate()
        .map(|(k, q)| Observation {
            q: q.clone(),
            p: world.measure(q, k as u64, 0),
        })
        .collect()
}

fn identification(c: &mut Criterion) {
    let (rig, world, basis) = setup();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let poses = random_poses(rig.chain.joints(), rig.held(), 2200, &mut rng);
    let obs = observe(&world, &poses);
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
    let obs = observe(&world, &poses);
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

struct ScenarioMeasurer(rigcal::world::World, u64);

impl rigcal::division::Measurer for ScenarioMeasurer {
    fn measure(
        &mut self,
        q: &[f64],
    ) -> Result<Option<rigcal::identification::Observation>, rigcal::division::MeasureError> {
        self.1 += 1;
        let p = self.0.measure_at(q, self.1 as f64, self.1, 0).position;
        Ok(p.map(|p| rigcal::identification::Observation { q: q.to_vec(), p }))
    }
}

fn variable_model(c: &mut Criterion) {
    use rigcal::division::{divide, DivisionOptions, Mode};
    use rigcal::learners::{train, Learner, LearnerKind};
    let scenario =
        rigcal::world::Scenario::load(Path::new("sim/paper-sim.toml"), None).expect("scenario");
    let rig = scenario.rig.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let design = random_poses(rig.chain.joints(), rig.held(), 100, &mut rng);
    let basis = analyse(&rig.chain, &design, &candidate_order(&rig)).basis;
    let scale = rigcal::model::cep_scale(&rig, &basis);
    let mut g = c.benchmark_group("variable model (paper-sim, joint space)");
    g.sample_size(10);
    let mut fcmac = None;
    for accuracy in [0.1, 0.02] {
        g.bench_function(
            format!("divide + identify + train FCMAC, demanded {accuracy} mm"),
            |b| {
                b.iter(|| {
                    let mut m = ScenarioMeasurer(scenario.world(), 0);
                    let opts = DivisionOptions {
                        accuracy_mm: accuracy,
                        ..DivisionOptions::default()
                    };
                    let r = divide(&rig, &basis, Mode::Planning(&mut m), &opts, |_, _| {})
                        .expect("divide");
                    let init: Vec<f64> = basis
                        .iter()
                        .map(|&i| r.conventional.params.get(i))
                        .collect();
                    fcmac = train(LearnerKind::Fcmac, &r.tree, &init, &scale);
                })
            },
        );
    }
    g.finish();
    let Some(Learner::Fcmac(f)) = fcmac else {
        return;
    };
    let points: Vec<[f64; 3]> = random_poses(rig.chain.joints(), rig.held(), 1000, &mut rng)
        .iter()
        .map(|q| [q[0], q[1], q[2]])
        .collect();
    let mut g = c.benchmark_group("FCMAC query");
    g.throughput(Throughput::Elements(points.len() as u64));
    g.bench_function("1000 points, 15 CEPs each", |b| {
        b.iter(|| points.iter().map(|x| f.predict(x)[0]).sum::<f64>())
    });
    g.finish();
}

criterion_group!(benches, identification, compensation, variable_model);
criterion_main!(benches);
