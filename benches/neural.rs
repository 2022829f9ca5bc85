//! Benchmarks of neuro-kinematic training (seed 001): the reproduction's Table 5 network and the
//! RV-M2 network of `rigcal calibrate --learner nn-direct` / `rigcal compare` on the paper
//! scenario's 2200 measurements. Run with `cargo bench --bench neural`.

use criterion::{criterion_group, criterion_main, Criterion};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::Robot;
use rigcal_model::identification::{random_poses, Observation};
use rigcal_model::neural::network::Method;
use rigcal_model::neural::rig_model::train_on_rig;
use rigcal_model::neural::{AngularSum, NkModel, Scheme, TrainConfig};
use rigcal_paper::reproduce::robots::{Scara2, Scara2Errors, Scara2Real};
use rigcal_paper::reproduce::seed001::{scara2_spread, TABLE5_LM_ITERATIONS};
use std::path::Path;

fn table5_network(c: &mut Criterion) {
    let nominal = Scara2::default();
    let real = Scara2Real {
        nominal,
        errors: Scara2Errors::case(2),
    };
    let lea = scara2_spread(&real, 46);
    let cfg = TrainConfig {
        hidden: 20,
        epochs: 20_000,
        ..TrainConfig::default()
    };
    let lm = TrainConfig {
        method: Method::LevenbergMarquardt,
        hidden: 20,
        epochs: TABLE5_LM_ITERATIONS,
        ..TrainConfig::default()
    };
    let mut g = c.benchmark_group("neural");
    g.sample_size(10);
    g.bench_function(
        "Table 5: scheme 2, 46 poses, 20 hidden, 20000 epochs",
        |b| {
            b.iter(|| {
                NkModel::train(&nominal, &lea, Scheme::Direct2, AngularSum::Trig, &cfg)
                    .expect("train")
            })
        },
    );
    g.bench_function(
        "Table 5: scheme 2, 46 poses, 20 hidden, Levenberg-Marquardt",
        |b| {
            b.iter(|| {
                NkModel::train(&nominal, &lea, Scheme::Direct2, AngularSum::Trig, &lm)
                    .expect("train")
            })
        },
    );
    g.finish();
}

fn rv_m2_network(c: &mut Criterion) {
    let sc =
        rigcal_sim::world::Scenario::load(Path::new("sim/paper-sim.toml"), None).expect("scenario");
    let rig = &sc.rig;
    let world = sc.world();
    let poses = random_poses(
        rig.chain.joints(),
        rig.held(),
        2200,
        &mut ChaCha8Rng::seed_from_u64(1),
    );
    let obs: Vec<Observation> = poses
        .iter()
        .enumerate()
        .map(|(k, q)| Observation {
            q: q.clone(),
            p: world.measure(q, k as u64, 0),
        })
        .collect();
    let cfg = TrainConfig {
        hidden: 20,
        epochs: 3000,
        learning_rate: 0.46 / (0.8 * 2200.0),
        validation_fraction: 0.2,
        patience: 600,
        ..TrainConfig::default()
    };
    let mut g = c.benchmark_group("neural");
    g.sample_size(10);
    g.bench_function(
        "RV-M2: scheme 4, 2200 measurements, 20 hidden, 3000 epochs",
        |b| b.iter(|| train_on_rig(rig, &obs, Scheme::Direct4, &cfg).expect("train")),
    );
    g.finish();
}

criterion_group!(benches, table5_network, rv_m2_network);
criterion_main!(benches);
