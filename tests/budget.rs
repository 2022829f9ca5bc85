//! Half the measurements (issue [4/5] item 3) on `sim/paper-fig6.toml` at the paper's 0.1 mm:
//! D-optimal location selection, the parent's measurements reused by its halves and never
//! counted twice, and the accuracy of the paper's Figs. 6 and 7 at about half the paper's count.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_calibration::{
    self as calibration, CalibrationOptions, PathChoice, PathFigures, PathOptions, Source,
};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_model::division::select::{choose, log_det_of, Selection};
use rigcal_model::division::{divide, DivisionOptions, MeasureError, Measurer, Mode, Space};
use rigcal_model::identification::{analyse, candidate_order, random_poses, Observation};
use rigcal_model::model::{ModelBody, ModelFile};
use rigcal_sim::world::Scenario;
use std::path::Path;

const SCENARIO: &str = "sim/paper-fig6.toml";

fn scenario() -> Scenario {
    Scenario::load(Path::new(SCENARIO), None).unwrap()
}

fn calibrate(opts: &CalibrationOptions) -> ModelFile {
    let sc = scenario();
    calibration::calibrate(&sc.rig, Source::Scenario(&sc), opts)
        .unwrap()
        .model
}

/// (regions, identification measurements, test measurements) of a division's model.
fn counts(model: &ModelFile) -> (usize, usize, usize) {
    match &model.model {
        ModelBody::Variable { division, .. } => (
            division.regions,
            division.measurements,
            division.test_measurements,
        ),
        _ => panic!("not a variable model"),
    }
}

fn figures(model: &ModelFile, path: PathChoice) -> PathFigures {
    let sc = scenario();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("m.json");
    model.save(&file).unwrap();
    let loaded = ModelFile::load(&file).unwrap();
    let paths = calibration::build_paths(&loaded.rig, &[path], &PathOptions::default()).unwrap();
    let names = rigcal_paper::preset::SEED_000.traced_ceps();
    let trace = calibration::traced_ceps(&loaded.rig, &names).unwrap();
    let results = calibration::evaluate(&loaded, &file, &sc, &paths, &trace).unwrap();
    PathFigures::of(&loaded, &paths[0], &results[0], &trace)
}

fn max(f: &PathFigures, method: &str) -> f64 {
    let m = f.method(method).unwrap();
    assert_eq!(m.failures, 0, "{method} failed somewhere on {}", f.path);
    m.max_mm
}

/// Fig. 6 at the paper's 0.1 mm with D-optimal locations, 10 per region: at most 1 100
/// identification measurements (the paper's 2 200), regions and FCMAC below 0.1 mm on the
/// path, conventional calibration on the same data between 0.1 and 0.2 mm as at 20 per region.
#[test]
fn d_optimal_fig6_meets_the_demand_with_at_most_1100_measurements() {
    let model = calibrate(&CalibrationOptions {
        selection: Selection::DOptimal,
        per_region: 10,
        ..Default::default()
    });
    let (regions, measurements, _) = counts(&model);
    assert!(measurements <= 1100, "{measurements} measurements");
    assert!((20..=110).contains(&regions), "{regions} regions");
    let f = figures(&model, PathChoice::Fig6);
    let conv = max(&f, "conventional");
    assert!((0.1..0.2).contains(&conv), "conventional max {conv}");
    for m in ["regions", "fcmac"] {
        assert!(max(&f, m) < 0.1, "{m} max {}", max(&f, m));
    }
}

/// Fig. 7 (Cartesian division, the paper's cap of 130) with D-optimal locations, 9 per region:
/// at most 1 300 identification measurements (half of 130 × 20), regions and FCMAC below
/// 0.1 mm on the spherical path.
#[test]
fn d_optimal_fig7_meets_the_demand_with_half_the_measurements() {
    let model = calibrate(&CalibrationOptions {
        space: Space::Cartesian,
        selection: Selection::DOptimal,
        per_region: 9,
        ..Default::default()
    });
    let (_, measurements, _) = counts(&model);
    assert!(measurements <= 1300, "{measurements} measurements");
    let f = figures(&model, PathChoice::Fig7);
    for m in ["regions", "fcmac"] {
        assert!(max(&f, m) < 0.1, "{m} max {}", max(&f, m));
    }
}

/// The world of the scenario as a measurer that counts its calls.
struct Counting {
    inner: calibration::WorldMeasurer,
    calls: usize,
    poses: Vec<Vec<f64>>,
}

impl Measurer for Counting {
    fn measure(&mut self, q: &[f64]) -> Result<Option<Observation>, MeasureError> {
        self.calls += 1;
        self.poses.push(q.to_vec());
        self.inner.measure(q)
    }
}

fn basis(rig: &rigcal_core::rig::Rig) -> Vec<usize> {
    let design = random_poses(
        rig.chain.joints(),
        rig.held(),
        100,
        &mut ChaCha8Rng::seed_from_u64(1),
    );
    analyse(&rig.chain, &design, &candidate_order(rig)).basis
}

/// Every location is measured once and counted once: the measurer's calls are exactly the
/// identification measurements plus the test measurements; every identification measurement
/// lies in exactly one leaf, so the leaves' fits use them all once; the inner regions reused
/// them (their fits together used more than were measured).
#[test]
fn reused_measurements_are_never_counted_twice() {
    let sc = scenario();
    let rig = &sc.rig;
    let basis = basis(rig);
    for selection in [Selection::Kappa, Selection::DOptimal] {
        let mut m = Counting {
            inner: calibration::WorldMeasurer::of(&sc),
            calls: 0,
            poses: Vec::new(),
        };
        let opts = DivisionOptions {
            max_regions: 12,
            per_region: 10,
            selection,
            ..Default::default()
        };
        let r = divide(rig, &basis, Mode::Planning(&mut m), &opts, |_, _| {}).unwrap();
        assert_eq!(m.calls, r.observations.len() + r.test_measurements);
        let leaves = r.tree.root.leaves();
        assert_eq!(leaves.len(), 12);
        let in_leaves: usize = leaves.iter().map(|l| l.measurements).sum();
        assert_eq!(in_leaves, r.observations.len(), "{selection:?}");
        let in_nodes: usize = r.tree.root.nodes().iter().map(|n| n.measurements).sum();
        assert!(in_nodes > r.observations.len() + 100, "{in_nodes}");
        // No location measured twice.
        for (i, a) in r.observations.iter().enumerate() {
            assert!(r.observations[..i].iter().all(|b| b.q != a.q));
        }
    }
}

/// Reusing the parent's points: fewer new measurements than measuring every region afresh, at
/// the same accuracy along the Fig. 6 path (both below the demanded 0.1 mm).
#[test]
fn reuse_needs_fewer_new_measurements_than_measuring_each_region_afresh() {
    let reuse = calibrate(&CalibrationOptions::default());
    let fresh = calibrate(&CalibrationOptions {
        reuse_parent: false,
        ..Default::default()
    });
    let (_, with_reuse, _) = counts(&reuse);
    let (fresh_regions, afresh, _) = counts(&fresh);
    // Afresh, every region of the tree (inner ones too) is measured with its own 20.
    assert!(afresh >= 20 * (2 * fresh_regions - 1), "{afresh}");
    assert!(
        (with_reuse as f64) < 0.6 * afresh as f64,
        "{with_reuse} against {afresh}"
    );
    for model in [&reuse, &fresh] {
        let f = figures(model, PathChoice::Fig6);
        for m in ["regions", "fcmac"] {
            assert!(max(&f, m) < 0.1, "{m} max {}", max(&f, m));
        }
    }
}

/// On the same candidates of one region of the Fig. 6 path, with the same measurements already
/// held, the D-optimal rule's locations have a larger det(MᵀM) than the κ rule's.
#[test]
fn d_optimal_locations_have_a_larger_determinant_than_the_kappa_rules() {
    let sc = scenario();
    let rig = &sc.rig;
    let basis = basis(rig);
    let e = ErrorParams::zeros(rig.chain.layout());
    let block = |q: &[f64]| {
        let (_, j) = rig.chain.position_and_param_jacobian(q, &e);
        nalgebra::DMatrix::from_fn(3, basis.len(), |r, c| j[(r, basis[c])])
    };
    for seed in 1..=5 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut pose = || -> Vec<f64> {
            vec![
                rng.random_range(80f64..100.0).to_radians(),
                rng.random_range(65f64..80.0).to_radians(),
                rng.random_range(-30f64..-15.0).to_radians(),
                0.0,
                0.0,
            ]
        };
        let held: Vec<_> = (0..6).map(|_| block(&pose())).collect();
        let candidates: Vec<_> = (0..60).map(|_| block(&pose())).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = choose(Selection::Kappa, &held, &candidates, 10, 60, &mut rng);
        let d = choose(Selection::DOptimal, &held, &candidates, 10, 60, &mut rng);
        assert_eq!((k.len(), d.len()), (10, 10));
        let (lk, ld) = (
            log_det_of(&held, &candidates, &k),
            log_det_of(&held, &candidates, &d),
        );
        assert!(ld >= lk, "seed {seed}: ln det D-optimal {ld}, κ rule {lk}");
    }
}

/// Fig. 7 at the paper's settings (Cartesian division, 20 per region, the cap of 130) with
/// D-optimal locations: regions and FCMAC below 0.1 mm on the spherical path (the κ rule
/// leaves the regions at 0.129 mm at this seed). The paper's split order, worst first: the
/// library's excess × size leaves this seed's regions at 0.124 mm on this path (seed 1 is one of
/// the two of seeds 1–20 where it misses, docs/seeds.md).
#[test]
fn d_optimal_fig7_at_the_cap_keeps_the_regions_below_the_demand() {
    let model = calibrate(&CalibrationOptions {
        space: Space::Cartesian,
        selection: Selection::DOptimal,
        split_order: rigcal_model::division::SplitOrder::Worst,
        ..Default::default()
    });
    let (regions, _, _) = counts(&model);
    assert_eq!(regions, 130);
    let f = figures(&model, PathChoice::Fig7);
    for m in ["regions", "fcmac"] {
        assert!(max(&f, m) < 0.1, "{m} max {}", max(&f, m));
    }
}
