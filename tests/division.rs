//! The variable D-H model on an arm with position-dependent (non-geometric) joint errors: the
//! recursive division meets the demanded accuracy where one constant parameter set cannot, and
//! the FCMAC smooths the region-wise CEPs.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorModel, ErrorParams, Robot};
use rigcal_core::rig::Rig;
use rigcal_model::compensation::{compensate, CompensationOptions};
use rigcal_model::division::{divide, DivisionOptions, Measurer, Mode, RegionModel};
use rigcal_model::identification::{
    analyse, candidate_order, random_poses, Identifiability, Observation,
};
use rigcal_sim::world::paper_geometric_errors;
use std::path::Path;

/// A test arm: geometric errors plus joint errors Δq_i = Σ_j a_ij cos q_j + b_ij sin q_j.
struct TrigArm {
    rig: Rig,
    geometric: ErrorParams,
    a: [[f64; 3]; 3],
    b: [[f64; 3]; 3],
    count: usize,
}

impl TrigArm {
    fn new(rig: Rig, geometric: ErrorParams, size_deg: f64, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let s = size_deg.to_radians();
        let a = std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-s..s)));
        let b = std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-s..s)));
        Self {
            rig,
            geometric,
            a,
            b,
            count: 0,
        }
    }
    fn truth(&self, q: &[f64]) -> Vector3<f64> {
        let mut qa = q.to_vec();
        for (i, qi) in qa.iter_mut().take(3).enumerate() {
            *qi += (0..3)
                .map(|j| self.a[i][j] * q[j].cos() + self.b[i][j] * q[j].sin())
                .sum::<f64>();
        }
        self.rig.chain.position(&qa, &self.geometric)
    }
}

impl Measurer for TrigArm {
    fn measure(
        &mut self,
        q: &[f64],
    ) -> Result<
        Option<rigcal_model::identification::Observation>,
        rigcal_model::division::MeasureError,
    > {
        self.count += 1;
        Ok(Some(rigcal_model::identification::Observation {
            q: q.to_vec(),
            p: self.truth(q),
        }))
    }
}

fn fig6_path() -> Vec<Vec<f64>> {
    (0..101)
        .map(|k| {
            let t = k as f64 / 100.0;
            vec![
                (60.0 + 65.0 * t).to_radians(),
                (60.0 + 30.0 * t).to_radians(),
                (-35.0 + 25.0 * t).to_radians(),
                0.0,
                0.0,
            ]
        })
        .collect()
}

fn path_errors(arm: &TrigArm, model: &dyn ErrorModel) -> Vec<f64> {
    let nominal = ErrorParams::zeros(arm.rig.chain.layout());
    let mut seed: Option<Vec<f64>> = None;
    fig6_path()
        .iter()
        .map(|q| {
            let target = arm.rig.chain.position(q, &nominal);
            let c = compensate(
                &arm.rig.chain,
                model,
                &target,
                arm.rig.held(),
                seed.as_deref(),
                &CompensationOptions::default(),
            )
            .unwrap();
            seed = Some(c.command.clone());
            (arm.truth(&c.command) - target).norm()
        })
        .collect()
}

/// The ideal-instrument RV-M2 with the paper's geometric errors on its identifiable basis and
/// joint errors of 0.02° amplitude.
fn trig_arm() -> (Rig, Identifiability, TrigArm) {
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).unwrap();
    let design = random_poses(
        rig.chain.joints(),
        rig.held(),
        100,
        &mut ChaCha8Rng::seed_from_u64(1),
    );
    let ident = analyse(&rig.chain, &design, &candidate_order(&rig));
    let geo = paper_geometric_errors(&rig.chain, &ident, 5);
    let arm = TrigArm::new(rig.clone(), geo, 0.02, 3);
    (rig, ident, arm)
}

#[test]
fn division_beats_conventional_calibration_on_position_dependent_errors() {
    let (rig, ident, mut arm) = trig_arm();
    let opts = DivisionOptions {
        max_regions: 40,
        ..DivisionOptions::default()
    };
    let report = divide(
        &rig,
        &ident.basis,
        Mode::Planning(&mut arm),
        &opts,
        |_, _| {},
    )
    .unwrap();
    let leaves = report.tree.leaf_count();
    assert!(leaves > 1 && leaves <= 40);
    assert!(
        report.observations.len() >= 20 * leaves / 2,
        "{} measurements",
        report.observations.len()
    );
    let model = RegionModel::new(
        report.tree.clone(),
        report.space.clone(),
        ident.basis.clone(),
        rig.chain.layout().len(),
    );
    let conv = path_errors(&arm, &report.conventional.params);
    let var = path_errors(&arm, &model);
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    assert!(
        max(&var) < 0.6 * max(&conv),
        "variable {:.4} vs conventional {:.4}",
        max(&var),
        max(&conv)
    );
}

#[test]
fn offline_division_works_from_a_recording_without_regions() {
    let (rig, ident, mut arm) = trig_arm();
    let poses = random_poses(
        rig.chain.joints(),
        rig.held(),
        1500,
        &mut ChaCha8Rng::seed_from_u64(2),
    );
    let obs: Vec<Observation> = poses
        .iter()
        .map(|q| Observation {
            q: q.clone(),
            p: arm.measure(q).unwrap().unwrap().p,
        })
        .collect();
    let opts = DivisionOptions {
        max_regions: 30,
        accuracy_mm: 0.05,
        ..DivisionOptions::default()
    };
    let report = divide(&rig, &ident.basis, Mode::Offline(&obs), &opts, |_, _| {}).unwrap();
    assert!(report.tree.leaf_count() > 1);
    assert_eq!(report.test_measurements, 0);
    assert_eq!(report.observations.len(), 1500);
    let model = RegionModel::new(
        report.tree.clone(),
        report.space.clone(),
        ident.basis.clone(),
        rig.chain.layout().len(),
    );
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    let conv = path_errors(&arm, &report.conventional.params);
    let var = path_errors(&arm, &model);
    assert!(
        max(&var) < max(&conv),
        "variable {:.4} vs conventional {:.4}",
        max(&var),
        max(&conv)
    );
}

/// A measurer that keeps every pose it was sent to.
struct Recorder<'a> {
    inner: &'a mut dyn Measurer,
    asked: Vec<Vec<f64>>,
}

impl Measurer for Recorder<'_> {
    fn measure(
        &mut self,
        q: &[f64],
    ) -> Result<Option<Observation>, rigcal_model::division::MeasureError> {
        self.asked.push(q.to_vec());
        self.inner.measure(q)
    }
}

/// Fig. 8 without leaks, planning mode: not one measurement (identification or test) is taken
/// inside the unmeasurable region, the region is a leaf of its own with its neighbours' mean
/// CEPs, and no learner pattern lies inside it.
#[test]
fn planning_never_measures_inside_the_unmeasurable_region() {
    use rigcal_calibration::{calibrate, CalibrationOptions, Source, WorldMeasurer};
    use rigcal_model::division::{Bounds, DivisionSpace, Space};
    use rigcal_model::model::ModelBody;
    let sc = rigcal_sim::world::Scenario::load(Path::new("sim/paper-fig6.toml"), None).unwrap();
    let rig = &sc.rig;
    let at = [92.0, 75.0, -22.0];
    let depth = 5;
    let space = DivisionSpace::new(rig, Space::Joint).unwrap();
    let x = at.map(f64::to_radians);
    let (hole, id) = Bounds::region_at(&space.full, &x, depth);
    let mut world = WorldMeasurer::of(&sc);
    let mut recorder = Recorder {
        inner: &mut world,
        asked: Vec::new(),
    };
    let opts = CalibrationOptions {
        max_regions: Some(24),
        unmeasurable_at: Some(at),
        unmeasurable_depth: Some(depth),
        ..CalibrationOptions::default()
    };
    let source = Source::Measurer {
        measurer: &mut recorder,
        label: "recorder".into(),
    };
    let cal = calibrate(rig, source, &opts).unwrap();
    assert!(recorder.asked.len() > 200, "{}", recorder.asked.len());
    let inside = recorder
        .asked
        .iter()
        .filter(|q| hole.holds(&space.coords(q)))
        .count();
    assert_eq!(inside, 0, "measurements inside region {id}");
    let ModelBody::Variable { tree, division, .. } = &cal.model.model else {
        panic!("not a variable model");
    };
    assert_eq!(division.unmeasurable, Some(hole));
    let holes = tree.unmeasurable();
    assert_eq!(holes.len(), 1);
    let leaf = holes[0];
    assert_eq!((leaf.id.as_str(), leaf.bounds), (id.as_str(), hole));
    assert_eq!(leaf.measurements, 0);
    // Its CEPs are the mean of the named neighbours', each of which shares a face with it.
    let neighbours: Vec<_> = tree
        .root
        .leaves()
        .into_iter()
        .filter(|l| leaf.borrowed_from.as_ref().unwrap().contains(&l.id))
        .collect();
    assert!(!neighbours.is_empty());
    let cep = leaf.cep.as_ref().unwrap();
    for (k, v) in cep.iter().enumerate() {
        let mean = neighbours
            .iter()
            .map(|n| n.cep.as_ref().unwrap()[k])
            .sum::<f64>()
            / neighbours.len() as f64;
        assert!((v - mean).abs() < 1e-12);
    }
    for n in &neighbours {
        assert!(n.bounds.shares_face(&hole) && n.is_measured(), "{}", n.id);
    }
    let patterns = rigcal_model::learners::patterns_from_tree(tree, &[1.0; 15], [33, 21, 21]);
    assert!(!patterns.is_empty());
    assert!(patterns.iter().all(|p| !hole.contains(&p.x, &tree.full)));
}

/// Fig. 8 without leaks, offline: poisoning every recorded point inside the unmeasurable region
/// (5 mm off) changes nothing — not the regions' CEPs, not the conventional fit, not the FCMAC —
/// so none of them reaches any fit.
#[test]
fn offline_points_inside_the_unmeasurable_region_reach_no_fit() {
    use rigcal_calibration::{calibrate, CalibrationOptions, Source};
    use rigcal_model::division::{Bounds, DivisionSpace, Space};
    let sc = rigcal_sim::world::Scenario::load(Path::new("sim/paper-fig6.toml"), None).unwrap();
    let rig = &sc.rig;
    let poses = random_poses(
        rig.chain.joints(),
        rig.held(),
        1200,
        &mut ChaCha8Rng::seed_from_u64(4),
    );
    let world = sc.world();
    let at = [92.0, 75.0, -22.0];
    let depth = 4;
    let space = DivisionSpace::new(rig, Space::Joint).unwrap();
    let (hole, _) = Bounds::region_at(&space.full, &at.map(f64::to_radians), depth);
    let clean: Vec<Observation> = poses
        .iter()
        .map(|q| Observation {
            q: q.clone(),
            p: world.true_position(q),
        })
        .collect();
    let poisoned: Vec<Observation> = clean
        .iter()
        .map(|o| {
            let mut o = o.clone();
            if hole.holds(&space.coords(&o.q)) {
                o.p += Vector3::new(5.0, -5.0, 5.0);
            }
            o
        })
        .collect();
    let n_inside = clean
        .iter()
        .filter(|o| hole.holds(&space.coords(&o.q)))
        .count();
    assert!(n_inside >= 20, "{n_inside} recorded points inside");
    let outside: Vec<Observation> = clean
        .iter()
        .filter(|o| !hole.holds(&space.coords(&o.q)))
        .cloned()
        .collect();
    let opts = CalibrationOptions {
        max_regions: Some(16),
        unmeasurable_at: Some(at),
        unmeasurable_depth: Some(depth),
        ..CalibrationOptions::default()
    };
    let model = |obs: &[Observation]| {
        let source = Source::Offline {
            observations: obs,
            label: "recording".into(),
        };
        calibrate(rig, source, &opts).unwrap().model
    };
    let (a, b) = (model(&poisoned), model(&outside));
    assert_eq!(a.model, b.model);
    assert_eq!(a.fitted_from.measurements, clean.len() - n_inside);
}

/// The CEPs a learner is trained on (`RegionNode::learner_cep`): each measured region's CEPs
/// with what its own measurements cannot see put back to its parent's learner CEPs. At the
/// region's measurements the predicted points move by at most the tolerance (RMS, checked here
/// on the forward kinematics), the deviation from the parent (scaled by the prior σ) only
/// shrinks, and in the small, ill-conditioned regions it shrinks a lot.
#[test]
fn learner_ceps_keep_what_a_region_sees_and_drop_what_it_cannot() {
    let (rig, ident, mut arm) = trig_arm();
    let opts = DivisionOptions {
        max_regions: 24,
        accuracy_mm: 0.05,
        learner_tolerance: 0.3,
        ..DivisionOptions::default()
    };
    let report = divide(
        &rig,
        &ident.basis,
        Mode::Planning(&mut arm),
        &opts,
        |_, _| {},
    )
    .unwrap();
    let tol = opts.learner_tolerance * opts.accuracy_mm;
    let n = rig.chain.layout().len();
    let layout = rig.chain.layout();
    let unit: Vec<f64> = ident
        .basis
        .iter()
        .map(|&i| {
            if layout.ids()[i].kind.is_angle() {
                opts.prior_sigma.1
            } else {
                opts.prior_sigma.0
            }
        })
        .collect();
    let scaled_norm = |a: &[f64], b: &[f64]| -> f64 {
        a.iter()
            .zip(b)
            .zip(&unit)
            .map(|((x, y), u)| ((x - y) / u).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let tree = &report.tree;
    let mut shrunk_a_lot = 0;
    let mut checked = 0;
    let mut stack = vec![(&tree.root, tree.root.cep.clone().unwrap())];
    while let Some((node, parent_learner)) = stack.pop() {
        let learner = node
            .learner_cep
            .clone()
            .expect("every identified region has them");
        if node.id != "r" && node.is_measured() {
            let cep = node.cep.as_ref().unwrap();
            let (p_cep, p_learner) = (
                rigcal_model::division::tree_expand(&ident.basis, n, cep),
                rigcal_model::division::tree_expand(&ident.basis, n, &learner),
            );
            let inside: Vec<&Observation> = report
                .observations
                .iter()
                .filter(|o| node.bounds.contains(&report.space.coords(&o.q), &tree.full))
                .collect();
            assert!(!inside.is_empty(), "{}", node.id);
            let moved = (inside
                .iter()
                .map(|o| {
                    (rig.chain.position(&o.q, &p_cep) - rig.chain.position(&o.q, &p_learner))
                        .norm_squared()
                })
                .sum::<f64>()
                / inside.len() as f64)
                .sqrt();
            // The tolerance holds on the linearised model; the kinematics differ by far less
            // than a micrometre at these sizes.
            assert!(moved <= tol + 1e-3, "{}: moved {moved} mm", node.id);
            let (raw, kept) = (
                scaled_norm(cep, &parent_learner),
                scaled_norm(&learner, &parent_learner),
            );
            assert!(kept <= raw + 1e-9, "{}: {kept} > {raw}", node.id);
            shrunk_a_lot += usize::from(kept < 0.5 * raw);
            checked += 1;
        }
        for c in &node.children {
            stack.push((c, learner.clone()));
        }
    }
    assert!(checked >= 10, "{checked} regions");
    assert!(shrunk_a_lot >= checked / 4, "{shrunk_a_lot} of {checked}");
}

/// The acceptance margin this suite holds an accepted region to (docs/seeds.md): along the
/// Fig. 6 path, inside every region the division accepted, the regions' error stays within
/// the demand plus this fraction of it.
const ACCEPTANCE_MARGIN: f64 = 0.1;

/// Seeds 8, 10 and 11 of `sim/paper-fig6.toml` fooled the paper's acceptance (every test point
/// below the demand): at seed 8 a half workspace holding the whole Fig. 6 path (region r1)
/// passed its 27 test points at 0.096 mm, and the path then reached 0.145 mm inside it (this
/// test fails so with `confidence_z: 0.0`, the old rule). The division at the paper's settings
/// (0.1 mm, 20 per region, cap 110; no learner: the regions' own CEPs), then every path point
/// compensated with its region's CEPs: no region accepted on its test may hold a path point
/// above the demand by more than [`ACCEPTANCE_MARGIN`]. (The full Fig. 6 division: about half
/// a second per seed in release.)
#[test]
fn no_accepted_region_holds_a_path_error_beyond_the_demand_and_its_margin() {
    use rigcal_sim::world::Scenario;

    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).unwrap();
    let sc = Scenario::load(Path::new("sim/paper-fig6.toml"), None).unwrap();
    for seed in [8, 10, 11] {
        accepted_regions_hold_the_path(&rig, &sc, seed, Default::default());
    }
}

/// Sequential testing with earlier tests as evidence (`TestPlan`, section 7's plan): a region
/// stops its test at the first stage that misses the demand, and the test measurements of the
/// regions enclosing it count as its own (predicted by its CEPs, never part of a fit). On seed
/// 8's Fig. 6 division it measures well under two thirds of the paper's test points, and no
/// region it accepts holds a path point beyond the demand and its margin.
#[test]
fn sequential_tests_on_earlier_evidence_measure_fewer_points_and_hold_the_path() {
    use rigcal_model::division::TestPlan;
    use rigcal_sim::world::Scenario;

    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).unwrap();
    let sc = Scenario::load(Path::new("sim/paper-fig6.toml"), None).unwrap();
    let paper = accepted_regions_hold_the_path(&rig, &sc, 8, TestPlan::default());
    let plan = TestPlan {
        first_stage: 9,
        reuse: true,
        ..TestPlan::default()
    };
    let sequential = accepted_regions_hold_the_path(&rig, &sc, 8, plan);
    assert!(
        (sequential as f64) < 0.65 * paper as f64,
        "{sequential} test measurements against {paper}"
    );
}

/// The division of `seed` at the paper's settings with `test_plan`, checked along the Fig. 6
/// path: its test measurements.
fn accepted_regions_hold_the_path(
    rig: &Rig,
    sc: &rigcal_sim::world::Scenario,
    seed: u64,
    test_plan: rigcal_model::division::TestPlan,
) -> usize {
    use rigcal_calibration::{calibrate, CalibrationOptions, Source};
    use rigcal_model::division::{DivisionSpace, Space};
    use rigcal_model::learners::LearnerKind;
    use rigcal_model::model::ModelBody;

    let demand = 0.1;
    let opts = CalibrationOptions {
        space: Space::Joint,
        accuracy_mm: demand,
        per_region: 20,
        max_regions: Some(110),
        learner: LearnerKind::None,
        seed,
        test_plan,
        ..Default::default()
    };
    let c = calibrate(rig, Source::Scenario(sc), &opts).unwrap();
    let tests = match &c.figures {
        rigcal_calibration::Figures::Division(d) => d.test_measurements,
        rigcal_calibration::Figures::Neural(_) => panic!("not a division"),
    };
    let ModelBody::Variable { tree, .. } = c.model.model else {
        panic!("not a division");
    };
    let layout = rig.chain.layout();
    let basis: Vec<usize> = tree
        .basis
        .iter()
        .map(|n| layout.find(n).and_then(|id| layout.index_of(id)).unwrap())
        .collect();
    let space = DivisionSpace::new(rig, tree.space).unwrap();
    let model = RegionModel::new(tree.clone(), space.clone(), basis, layout.len());
    let world = sc.world();
    let nominal = ErrorParams::zeros(layout);
    let mut start: Option<Vec<f64>> = None;
    let mut worst: Vec<(String, f64, f64)> = Vec::new();
    for q in fig6_path() {
        let target = rig.chain.position(&q, &nominal);
        let cmd = compensate(
            &rig.chain,
            &model,
            &target,
            rig.held(),
            start.as_deref(),
            &CompensationOptions::default(),
        )
        .unwrap();
        start = Some(cmd.command.clone());
        let error = (world.true_position(&cmd.command) - target).norm();
        let leaf = tree.root.leaf_at(&space.coords(&q), &tree.full);
        let accepted = leaf.note.is_none()
            && leaf
                .test
                .is_some_and(|t| t.verdict_mm() <= demand && t.max_mm <= demand);
        if accepted && error > demand * (1.0 + ACCEPTANCE_MARGIN) {
            let test = leaf.test.map_or(f64::NAN, |t| t.max_mm);
            worst.push((leaf.id.clone(), test, error));
        }
    }
    assert!(
        worst.is_empty(),
        "seed {seed}: accepted regions (id, largest test error, path error, mm) beyond {} mm: {worst:?}",
        demand * (1.0 + ACCEPTANCE_MARGIN)
    );
    tests
}

/// The share of the workspace's volume held by leaves still above the demand on their own
/// tests (their verdict) once the division stopped.
fn share_above_demand(report: &rigcal_model::division::DivisionReport, demand: f64) -> f64 {
    let tree = &report.tree;
    tree.root
        .leaves()
        .into_iter()
        .filter(|l| l.test.is_some_and(|t| t.verdict_mm() > demand))
        .map(|l| l.bounds.volume_share(&tree.full))
        .sum()
}

/// At a region cap the split order decides what is left above the demand: worst first (the
/// paper's) spends the cap halving small regions far above the demand and leaves large ones
/// barely above it; excess × volume first leaves a smaller part of the workspace above the
/// demand (docs/seeds.md: Fig. 7's path failed in such large regions). On the trigonometric
/// arm at a cap of 60 regions and 0.06 mm: 2 % of the workspace against 27 %. (Not at any
/// demand: where the cap is far too small for it, 0.04–0.05 mm at 20–60 regions, both orders
/// leave 70–100 % above it and worst first a little less. The library's default, excess ×
/// size, sits between the two and here leaves 38 %: it weighs how likely a path is to cross a
/// region, not its volume, and was chosen on the tuning set, docs/seeds.md.)
#[test]
fn at_the_region_cap_excess_times_volume_leaves_less_of_the_workspace_above_the_demand() {
    use rigcal_model::division::SplitOrder;

    let (rig, ident, _) = trig_arm();
    let run = |order: SplitOrder| {
        let (_, _, mut arm) = trig_arm();
        let opts = DivisionOptions {
            max_regions: 60,
            accuracy_mm: 0.06,
            split_order: order,
            ..DivisionOptions::default()
        };
        let report = divide(
            &rig,
            &ident.basis,
            Mode::Planning(&mut arm),
            &opts,
            |_, _| {},
        )
        .unwrap();
        assert_eq!(
            report.tree.root.leaves().len(),
            60,
            "{order:?}: cap not reached"
        );
        share_above_demand(&report, opts.accuracy_mm)
    };
    let worst = run(SplitOrder::Worst);
    let excess = run(SplitOrder::ExcessVolume);
    assert!(
        worst > 0.0 && excess < 0.5 * worst,
        "above the demand: {excess:.4} of the workspace (excess × volume) against {worst:.4} (worst first)"
    );
}

/// A half whose own measurements cannot separate its CEPs (κ above the cap, a rank-deficient
/// data Jacobian at few measurements per region) is held to its parent's CEPs in the
/// directions it cannot see and judged by its test (`prior_holds_unseen`), instead of stopping
/// its parent's split as "too small to identify" while far wider than the smallest region
/// (docs/seeds.md: at 10 measurements per region such refusals left regions of 1/16 of the
/// workspace at 0.17–0.19 mm on the tuning path). With the rule off, the same division
/// refuses such splits (10 of 60 leaves carry the refusal); with it on, none.
#[test]
fn a_half_its_measurements_cannot_separate_is_held_by_its_parents_ceps() {
    use rigcal_model::division::Selection;

    let (rig, ident, _) = trig_arm();
    let run = |held: bool| {
        let (_, _, mut arm) = trig_arm();
        let opts = DivisionOptions {
            max_regions: 60,
            accuracy_mm: 0.03,
            per_region: 6,
            selection: Selection::DOptimal,
            prior_holds_unseen: held,
            ..DivisionOptions::default()
        };
        let report = divide(
            &rig,
            &ident.basis,
            Mode::Planning(&mut arm),
            &opts,
            |_, _| {},
        )
        .unwrap();
        report
            .tree
            .root
            .leaves()
            .into_iter()
            .filter(|l| {
                l.note
                    .as_deref()
                    .is_some_and(|n| n.contains("too small to identify"))
            })
            .count()
    };
    assert!(run(false) > 0, "no refusal to test against");
    assert_eq!(run(true), 0);
}

/// `map_prior: false` is the paper's plain least squares: every leaf's CEPs equal an
/// independent unweighted least-squares fit (no prior) of the measurements in its box, started
/// from its parent's CEPs; with the MAP prior (rigcal's default) they differ.
#[test]
fn without_the_map_prior_a_regions_ceps_are_its_plain_least_squares_fit() {
    use rigcal_model::division::tree_expand;
    use rigcal_model::identification::{fit, FitOptions};

    let (rig, ident, _) = trig_arm();
    let n = rig.chain.layout().len();
    let largest_gap = |map_prior: bool| {
        let (_, _, mut arm) = trig_arm();
        let opts = DivisionOptions {
            max_regions: 6,
            accuracy_mm: 0.01,
            map_prior,
            ..DivisionOptions::default()
        };
        let report = divide(
            &rig,
            &ident.basis,
            Mode::Planning(&mut arm),
            &opts,
            |_, _| {},
        )
        .unwrap();
        let tree = &report.tree;
        let mut gap: f64 = 0.0;
        let mut stack = vec![&tree.root];
        while let Some(node) = stack.pop() {
            for child in &node.children {
                stack.push(child);
                // A split region's halves measured more inside it after its fit; a leaf's
                // box holds what its fit used.
                if !child.children.is_empty() {
                    continue;
                }
                let obs: Vec<Observation> = report
                    .observations
                    .iter()
                    .filter(|o| {
                        child
                            .bounds
                            .contains(&report.space.coords(&o.q), &tree.full)
                    })
                    .cloned()
                    .collect();
                let start = tree_expand(&ident.basis, n, node.cep.as_ref().unwrap());
                let lsq = fit(
                    &rig.chain,
                    &obs,
                    &start,
                    &ident.basis,
                    &FitOptions::default(),
                )
                .unwrap();
                let cep = child.cep.as_ref().unwrap();
                for (k, &i) in ident.basis.iter().enumerate() {
                    gap = gap.max((cep[k] - lsq.params.get(i)).abs());
                }
            }
        }
        gap
    };
    let plain = largest_gap(false);
    assert!(plain < 1e-9, "plain least squares off by {plain:e}");
    let map = largest_gap(true);
    assert!(map > 1e-6, "the MAP prior changed nothing ({map:e})");
}
