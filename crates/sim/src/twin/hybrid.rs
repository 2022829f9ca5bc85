//! Hybrid-compensated paths in a simulated world: the true error (the world's truth, not the
//! model's) of a path compensated with the geometry only and with the model file's effects.
//!
//! The arm runs the path's moves in order (via moves included) from a fresh motion history at
//! t = 0, so backlash sees the approach directions the path really makes. Units: mm.

use crate::world::World;
use nalgebra::Vector3;
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::Target;
use rigcal_model::compensation::TargetError;
use rigcal_model::model::hybrid::{
    compensate_path, moves, HybridArm, HybridCommand, HybridOptions,
};
use rigcal_model::model::LoadedModel;

/// True position errors along a path.
#[derive(Debug, Clone, PartialEq)]
pub struct PathErrors {
    /// What was compensated (`geometric only`, `with effects`).
    pub model: String,
    /// Error at each target (mm).
    pub errors: Vec<f64>,
    /// Moves made (targets and via moves).
    pub moves: usize,
}

impl PathErrors {
    /// Mean error (mm).
    pub fn mean_mm(&self) -> f64 {
        self.errors.iter().sum::<f64>() / self.errors.len().max(1) as f64
    }

    /// Largest error (mm).
    pub fn max_mm(&self) -> f64 {
        self.errors.iter().copied().fold(0.0, f64::max)
    }
}

/// Where the world's arm really puts the tip at each command of `path`, against `targets`.
pub fn true_errors(
    world: &World,
    path: &[HybridCommand],
    targets: &[Vector3<f64>],
    model: &str,
) -> PathErrors {
    let all = moves(path);
    let timed: Vec<(Vec<f64>, f64)> = all.iter().map(|(_, q)| (q.clone(), 0.0)).collect();
    let states = world.noiseless().run_moves(&timed);
    let errors = all
        .iter()
        .zip(&states)
        .filter(|((is_target, _), _)| *is_target)
        .zip(targets)
        .map(|((_, s), t)| (s.tip - t).norm())
        .collect();
    PathErrors {
        model: model.into(),
        errors,
        moves: all.len(),
    }
}

/// The target positions of targets (a joint target's nominal position).
pub fn target_positions(world: &World, targets: &[(u64, Target)]) -> Vec<Vector3<f64>> {
    let chain = world.chain();
    let nominal = ErrorParams::zeros(chain.layout());
    targets
        .iter()
        .map(|(_, t)| match t {
            Target::Position(p) => *p,
            Target::Joints(q) => chain.position(q, &nominal),
        })
        .collect()
}

/// Compensates `targets` with `model` (its effects too when `with_effects`) and measures the
/// path's true errors in `world`, named `name`.
pub fn compensated_errors(
    model: &LoadedModel,
    with_effects: bool,
    world: &World,
    targets: &[(u64, Target)],
    opts: &HybridOptions,
    name: &str,
) -> Result<PathErrors, TargetError> {
    let rig = &model.rig;
    let arm = HybridArm {
        chain: &rig.chain,
        masses: &rig.link_masses,
        held: rig.held(),
    };
    let effects: &[rigcal_model::model::effects::ModelEffect] = if with_effects {
        &model.file.effects
    } else {
        &[]
    };
    let path = compensate_path(&arm, model.errors.as_ref(), effects, targets, None, opts)?;
    Ok(true_errors(
        world,
        &path,
        &target_positions(world, targets),
        name,
    ))
}

/// A path's joint targets (each numbered from 1, in order) compensated with the model's geometry
/// alone and with its effects, and the true errors of both in `world`: (geometry only, with
/// effects).
pub fn geometry_vs_effects(
    model: &LoadedModel,
    world: &World,
    path: &[Vec<f64>],
    opts: &HybridOptions,
) -> Result<(PathErrors, PathErrors), TargetError> {
    let targets: Vec<(u64, Target)> = path
        .iter()
        .enumerate()
        .map(|(k, q)| (k as u64 + 1, Target::Joints(q.clone())))
        .collect();
    let geometry = compensated_errors(model, false, world, &targets, opts, "geometry only")?;
    let effects = compensated_errors(model, true, world, &targets, opts, "with effects")?;
    Ok((geometry, effects))
}
