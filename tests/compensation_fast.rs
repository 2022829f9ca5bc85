//! The compensator (compiled chain, seed start on the stack, 3 × 3 Newton steps) against the
//! one-target functions it speeds up: the same nominal solutions, commands, residuals and
//! errors, warm (each target seeded with the previous command) and cold. Units: mm and rad.

use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::Target;
use rigcal_core::rig::Rig;
use rigcal_model::compensation::{
    compensate, compensate_from, compensate_targets, CompensationError, CompensationOptions,
    Compensator,
};
use rigcal_model::identification::{analyse, candidate_order, random_poses};
use rigcal_sim::world::paper_geometric_errors;
use std::path::Path;

fn setup() -> (Rig, ErrorParams) {
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).expect("rig file");
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let design = random_poses(rig.chain.joints(), rig.held(), 80, &mut rng);
    let ident = analyse(&rig.chain, &design, &candidate_order(&rig));
    let model = paper_geometric_errors(&rig.chain, &ident, 5);
    (rig, model)
}

fn assert_same(
    fast: &Result<rigcal_model::compensation::Compensated, CompensationError>,
    slow: &Result<rigcal_model::compensation::Compensated, CompensationError>,
    what: &str,
) {
    match (fast, slow) {
        (Ok(f), Ok(s)) => {
            for (a, b) in f.nominal.iter().zip(&s.nominal) {
                assert!((a - b).abs() < 1e-9, "{what}: nominal {a} vs {b}");
            }
            for (a, b) in f.command.iter().zip(&s.command) {
                assert!((a - b).abs() < 1e-9, "{what}: command {a} vs {b}");
            }
            assert!(f.residual_mm <= 1e-6 && s.residual_mm <= 1e-6, "{what}");
            assert!(f.iterations.abs_diff(s.iterations) <= 1, "{what}");
        }
        (Err(f), Err(s)) => assert_eq!(
            std::mem::discriminant(f),
            std::mem::discriminant(s),
            "{what}: {f} vs {s}"
        ),
        _ => panic!("{what}: {fast:?} vs {slow:?}"),
    }
}

#[test]
fn the_compensator_equals_compensate_warm_and_cold() {
    let (rig, model) = setup();
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let opts = CompensationOptions::default();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let poses = random_poses(rig.chain.joints(), rig.held(), 300, &mut rng);
    let mut fast = Compensator::new(&rig.chain, &model, &opts);
    let mut previous: Option<Vec<f64>> = None;
    let mut ok = 0;
    for (k, q) in poses.iter().enumerate() {
        let t = rig.chain.position(q, &nominal);
        let cold_fast = fast.compensate(&t, rig.held(), None);
        let cold_slow = compensate(&rig.chain, &model, &t, rig.held(), None, &opts);
        assert_same(&cold_fast, &cold_slow, &format!("cold {k}"));
        let seed = previous.as_deref();
        let warm_fast = fast.compensate(&t, rig.held(), seed);
        let warm_slow = compensate(&rig.chain, &model, &t, rig.held(), seed, &opts);
        assert_same(&warm_fast, &warm_slow, &format!("warm {k}"));
        if let Ok(c) = &warm_slow {
            // The command brings the modelled arm to the target (an independent check).
            assert!((rig.chain.position(&c.command, &model) - t).norm() < 1e-6);
            ok += 1;
            previous = Some(c.command.clone());
        }
    }
    assert!(ok > 250, "most random targets compensate: {ok}");
}

#[test]
fn joint_targets_and_paths_match_the_one_target_functions() {
    let (rig, model) = setup();
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let opts = CompensationOptions::default();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    // Targets that compensate on their own (a few random ones near a limit do not).
    let poses: Vec<Vec<f64>> = random_poses(rig.chain.joints(), rig.held(), 60, &mut rng)
        .into_iter()
        .filter(|q| {
            let t = rig.chain.position(q, &nominal);
            compensate(&rig.chain, &model, &t, rig.held(), None, &opts).is_ok()
        })
        .take(40)
        .collect();
    let targets: Vec<(u64, Target)> = poses
        .iter()
        .enumerate()
        .map(|(k, q)| {
            let t = if k % 2 == 0 {
                Target::Position(rig.chain.position(q, &nominal))
            } else {
                Target::Joints(q.clone())
            };
            (k as u64 + 1, t)
        })
        .collect();
    let path = compensate_targets(&rig.chain, &model, rig.held(), &targets, &opts)
        .expect("every target compensates");
    assert_eq!(path.len(), 40);
    let mut previous: Option<Vec<f64>> = None;
    for ((_, t), c) in targets.iter().zip(&path) {
        let slow = match t {
            Target::Position(p) => compensate(
                &rig.chain,
                &model,
                p,
                rig.held(),
                previous.as_deref(),
                &opts,
            ),
            Target::Joints(q) => {
                let p = rig.chain.position(q, &nominal);
                let held: Vec<Option<f64>> = rig
                    .held()
                    .iter()
                    .zip(q)
                    .map(|(h, v)| h.map(|_| *v))
                    .collect();
                compensate_from(&rig.chain, &model, &p, &held, q.clone(), &opts)
            }
        };
        assert_same(&Ok(c.clone()), &slow, "path");
        previous = Some(c.command.clone());
    }
}
