//! Benchmarks of the calibration pipeline: identification from 2200 measurements (the paper's
//! data set size) — the fit alone, `identify` in memory, and `identify` end to end as the
//! command runs it (CSV read, analysis, fit, outlier search with two bad rows, model file) —
//! `diagnose` on 600 rows, compensation throughput (one target at a time as before, and the
//! [`Compensator`] cold and warm along a path) and `calibrate` (division, region fits, FCMAC) at
//! 0.1 mm on `sim/paper-fig6.toml` and 0.02 mm on `sim/paper-sim.toml`, as `rigcal calibrate`
//! runs them. Run with `cargo bench --bench pipeline` (a few minutes on 2 cores).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::compensation::{compensate, CompensationOptions, Compensator};
use rigcal_model::identification::{
    analyse, candidate_order, fit, identify, random_poses, FitOptions, Level, Observation,
};
use rigcal_sim::world::{paper_geometric_errors, World};
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
    let mut rec = world.record(&poses, 1);
    g.bench_function(
        "identify at level full from a 2200-row recording (outlier search included)",
        |b| {
            b.iter(|| {
                identify(
                    &rig,
                    &rec,
                    Level::Full,
                    &rigcal_model::diagnosis::outliers::identify_options(),
                )
                .expect("identify")
            })
        },
    );
    // Two gross rows (a reflection, a touch on dirt): the outlier search removes them.
    for (k, d) in [(700usize, [3.0, 0.0, -1.5]), (1500, [0.0, -2.0, 2.0])] {
        if let Some(p) = rec.rows[k].position.as_mut() {
            *p += nalgebra::Vector3::from(d);
        }
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let rec_dir = dir.path().join("rec");
    rec.write_dir(&rec_dir).expect("write the recording");
    let out = dir.path().join("model.json");
    g.bench_function(
        "identify end to end: 2200-row CSV with 2 bad rows to model file (as rigcal identify)",
        |b| b.iter(|| identify_to_model_file(&rig, &rec_dir, &out)),
    );
    g.finish();
}

/// What `rigcal identify` does between reading the rig and printing: the recording read from
/// its CSV, identified with the outlier search, the model file written. Returns the outliers.
fn identify_to_model_file(rig: &Rig, rec_dir: &Path, out: &Path) -> usize {
    use rigcal_model::model::{ModelFile, Provenance};
    let rec = Recording::read(rec_dir, rig.chain.joints()).expect("read the recording");
    let id = identify(
        rig,
        &rec,
        Level::Full,
        &rigcal_model::diagnosis::outliers::identify_options(),
    )
    .expect("identify");
    let mut file = ModelFile::constant(
        rig,
        &id.fit,
        Provenance {
            recording: Some(rec_dir.display().to_string()),
            measurements: id.fit.after.n,
            notes: id.outlier_warning.clone(),
        },
    );
    file.outliers = id.outliers.clone();
    file.save(out).expect("write the model");
    assert_eq!(id.outliers.len(), 2, "the two bad rows are found");
    id.outliers.len()
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
    g.bench_function("1000 random targets, compensator, cold start", |b| {
        b.iter(|| {
            let mut fast = Compensator::new(&rig.chain, &model, &opts);
            for t in &targets {
                fast.compensate(t, rig.held(), None).expect("compensate");
            }
        })
    });
    // A path: consecutive targets a few millimetres apart, each seeded with the last command.
    let start = random_poses(rig.chain.joints(), rig.held(), 1, &mut rng).remove(0);
    let path: Vec<_> = (0..1000)
        .map(|k| {
            let mut q = start.clone();
            q[0] += 0.001 * k as f64 * if q[0] > 0.0 { -1.0 } else { 1.0 };
            q[1] += 0.3 * (k as f64 * 0.01).sin() * 0.1;
            rig.chain.position(&q, &zero)
        })
        .collect();
    g.bench_function(
        "1000 path targets, compensator, warm (seeded by the last)",
        |b| {
            b.iter(|| {
                let mut fast = Compensator::new(&rig.chain, &model, &opts);
                let mut seed: Option<Vec<f64>> = None;
                for t in &path {
                    let c = fast
                        .compensate(t, rig.held(), seed.as_deref())
                        .expect("compensate");
                    seed = Some(c.command);
                }
            })
        },
    );
    g.bench_function(
        "1000 path targets, one at a time, warm (seeded by the last)",
        |b| {
            b.iter(|| {
                let mut seed: Option<Vec<f64>> = None;
                for t in &path {
                    let c = compensate(&rig.chain, &model, t, rig.held(), seed.as_deref(), &opts)
                        .expect("compensate");
                    seed = Some(c.command);
                }
            })
        },
    );
    g.finish();
}

fn diagnosis(c: &mut Criterion) {
    use rigcal_model::diagnosis::{diagnose, Options};
    let (rig, world, _) = setup();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let poses = random_poses(rig.chain.joints(), rig.held(), 600, &mut rng);
    let rec = world.record(&poses, 1);
    let mut g = c.benchmark_group("diagnosis");
    g.sample_size(10);
    g.bench_function("diagnose 600 rows", |b| {
        b.iter(|| diagnose(&rig, &rec, &Options::default()).expect("diagnose"))
    });
    g.finish();
}

fn variable_model(c: &mut Criterion) {
    use rigcal_calibration::{calibrate, CalibrationOptions, Source};
    use rigcal_model::learners::Learner;
    use rigcal_model::model::ModelBody;
    let mut g = c.benchmark_group("calibrate (division + region fits + FCMAC)");
    g.sample_size(10);
    let mut fcmac = None;
    let mut rig = None;
    for (file, accuracy) in [("sim/paper-fig6.toml", 0.1), ("sim/paper-sim.toml", 0.02)] {
        let scenario = rigcal_sim::world::Scenario::load(Path::new(file), None).expect("scenario");
        // The options `rigcal calibrate --scenario FILE --accuracy A` runs with.
        let opts = CalibrationOptions {
            accuracy_mm: accuracy,
            ..CalibrationOptions::default()
        };
        g.bench_function(format!("{file}, demanded {accuracy} mm"), |b| {
            b.iter(|| {
                let cal = calibrate(&scenario.rig, Source::Scenario(&scenario), &opts)
                    .expect("calibrate");
                if let ModelBody::Variable { learner, .. } = cal.model.model {
                    fcmac = learner;
                }
            })
        });
        rig = Some(scenario.rig.clone());
    }
    g.finish();
    let (Some(Learner::Fcmac(f)), Some(rig)) = (fcmac, rig) else {
        return;
    };
    let mut rng = ChaCha8Rng::seed_from_u64(1);
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

criterion_group!(
    benches,
    identification,
    compensation,
    diagnosis,
    variable_model
);
criterion_main!(benches);
