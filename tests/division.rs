//! The variable D-H model on an arm with position-dependent (non-geometric) joint errors: the
//! recursive division meets the demanded accuracy where one constant parameter set cannot, and
//! the FCMAC smooths the region-wise CEPs.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal::compensation::{compensate, CompensationOptions};
use rigcal::division::{divide, DivisionOptions, Measurer, Mode, RegionModel};
use rigcal::identification::{analyse, candidate_order, random_poses, Observation};
use rigcal::kinematics::{ErrorModel, ErrorParams, Robot};
use rigcal::rig::Rig;
use rigcal::world::paper_geometric_errors;
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
    ) -> Result<Option<rigcal::identification::Observation>, rigcal::division::MeasureError> {
        self.count += 1;
        Ok(Some(rigcal::identification::Observation {
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

#[test]
fn division_beats_conventional_calibration_on_position_dependent_errors() {
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).unwrap();
    let design = random_poses(
        rig.chain.joints(),
        rig.held(),
        100,
        &mut ChaCha8Rng::seed_from_u64(1),
    );
    let ident = analyse(&rig.chain, &design, &candidate_order(&rig));
    let geo = paper_geometric_errors(&rig.chain, &ident, 5);
    let mut arm = TrigArm::new(rig.clone(), geo, 0.02, 3);
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
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).unwrap();
    let design = random_poses(
        rig.chain.joints(),
        rig.held(),
        100,
        &mut ChaCha8Rng::seed_from_u64(1),
    );
    let ident = analyse(&rig.chain, &design, &candidate_order(&rig));
    let geo = paper_geometric_errors(&rig.chain, &ident, 5);
    let mut arm = TrigArm::new(rig.clone(), geo, 0.02, 3);
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
