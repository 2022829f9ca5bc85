//! Hybrid compensation: the geometric model and the model file's effects (backlash,
//! transmission error, gravity compliance with a payload) undone together (issue 18 item 5).
//!
//! For each target the geometric compensation ([`crate::compensation::compensate`]) gives the joints q^a the
//! modelled arm must *actually* reach; the command q^c then solves q^c + Δq(q^c, s) = q^a by
//! fixed-point iteration, Δq the effects' joint errors ([`crate::model::effects`]). Backlash
//! depends on the approach direction s: with [`Approach::FromPath`] it is the sign of each
//! joint's motion from the previous command into this one (the path's order, as the arm will
//! move); with [`Approach::Consistent`] a via move is planned before every target, a fixed
//! offset below the command on every moving joint, so each joint always arrives moving up.
//! Units: mm and rad inside.

use crate::compensation::{
    compensate, compensate_from, CompensationError, CompensationOptions, TargetError,
};
use crate::effects::EffectContext;
use crate::model::effects::{joint_offsets, ModelEffect};
use rigcal_core::kinematics::{ErrorModel, ErrorParams, Robot, SerialChain};
use rigcal_core::recording::Target;
use rigcal_core::rig::LinkMass;

/// How the approach direction of each target is set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Approach {
    /// As the path's order gives it: each joint arrives moving from the previous command.
    #[default]
    FromPath,
    /// Every target approached from below on every moving joint, through a via move.
    Consistent,
}

/// Settings of hybrid compensation.
#[derive(Debug, Clone)]
pub struct HybridOptions {
    /// The geometric compensation's settings.
    pub base: CompensationOptions,
    /// Approach directions.
    pub approach: Approach,
    /// Payload at the tool (kg), for compliance.
    pub payload_kg: f64,
    /// Via offset for [`Approach::Consistent`] (rad; mm for a prismatic joint): larger than
    /// any lost motion.
    pub via_offset: f64,
    /// Fixed-point iterations for the command.
    pub iterations: usize,
}

impl Default for HybridOptions {
    fn default() -> Self {
        Self {
            base: CompensationOptions::default(),
            approach: Approach::FromPath,
            payload_kg: 0.0,
            via_offset: 1.0f64.to_radians(),
            iterations: 8,
        }
    }
}

/// A command of a hybrid-compensated path.
#[derive(Debug, Clone, PartialEq)]
pub struct HybridCommand {
    /// The via move before it ([`Approach::Consistent`]), rad or mm.
    pub via: Option<Vec<f64>>,
    /// The command (rad or mm).
    pub command: Vec<f64>,
    /// The joints the modelled arm actually reaches (the geometric compensation's command).
    pub actual: Vec<f64>,
    /// The nominal solution.
    pub nominal: Vec<f64>,
    /// The approach direction assumed per joint.
    pub direction: Vec<i8>,
    /// Modelled position error left by the geometric step (mm).
    pub residual_mm: f64,
}

/// The arm the effects act on: chain, link masses.
#[derive(Debug, Clone, Copy)]
pub struct HybridArm<'a> {
    /// The chain.
    pub chain: &'a SerialChain,
    /// The rig's link masses.
    pub masses: &'a [Option<LinkMass>],
    /// Joints the rig holds (`Some(value)`).
    pub held: &'a [Option<f64>],
}

/// Direction of each joint moving from `from` to `to`, `last` where it does not move (as the
/// world's motion history records it).
fn directions(from: Option<&[f64]>, to: &[f64], last: &[i8]) -> Vec<i8> {
    let mut d = last.to_vec();
    d.resize(to.len(), 0);
    if let Some(from) = from {
        for (j, (a, b)) in to.iter().zip(from).enumerate() {
            if (a - b).abs() > 1e-9 {
                d[j] = if a > b { 1 } else { -1 };
            }
        }
    }
    d
}

/// Compensates `targets` in order with the geometric `model` and the `effects`, the arm
/// starting at `start` (its current joints, None when unknown). Stops at the first target that
/// cannot be compensated.
pub fn compensate_path(
    arm: &HybridArm<'_>,
    model: &dyn ErrorModel,
    effects: &[ModelEffect],
    targets: &[(u64, Target)],
    start: Option<&[f64]>,
    opts: &HybridOptions,
) -> Result<Vec<HybridCommand>, TargetError> {
    path_in_order(arm, model, effects, targets, start, opts, true)
        .into_iter()
        .collect()
}

/// [`compensate_path`] past failures: one result per target, in order. A target that cannot be
/// compensated is skipped: the arm does not move there, so the next target's approach
/// directions and start are those of the last command compensated.
pub fn compensate_path_each(
    arm: &HybridArm<'_>,
    model: &dyn ErrorModel,
    effects: &[ModelEffect],
    targets: &[(u64, Target)],
    start: Option<&[f64]>,
    opts: &HybridOptions,
) -> Vec<Result<HybridCommand, TargetError>> {
    path_in_order(arm, model, effects, targets, start, opts, false)
}

/// The path in order, the last result an error when `stop_at_first` and one failed.
fn path_in_order(
    arm: &HybridArm<'_>,
    model: &dyn ErrorModel,
    effects: &[ModelEffect],
    targets: &[(u64, Target)],
    start: Option<&[f64]>,
    opts: &HybridOptions,
    stop_at_first: bool,
) -> Vec<Result<HybridCommand, TargetError>> {
    let mut out: Vec<Result<HybridCommand, TargetError>> = Vec::with_capacity(targets.len());
    let mut state = PathState {
        prev: start.map(<[f64]>::to_vec),
        last_dir: vec![0i8; arm.chain.joints().len()],
        seed: None,
    };
    for (line, target) in targets {
        let one =
            path_target(arm, model, effects, target, &state, opts).map_err(|source| TargetError {
                line: *line,
                source,
            });
        if let Ok(c) = &one {
            state = PathState {
                prev: Some(c.command.clone()),
                last_dir: c.direction.clone(),
                seed: Some(c.actual.clone()),
            };
        }
        let failed = one.is_err();
        out.push(one);
        if failed && stop_at_first {
            break;
        }
    }
    out
}

/// Where the arm is along the path: the last command compensated.
struct PathState {
    /// The last command (None before the first, when the start is unknown).
    prev: Option<Vec<f64>>,
    /// The approach direction each joint last moved in.
    last_dir: Vec<i8>,
    /// The joints the modelled arm last reached, the next inverse kinematics' start.
    seed: Option<Vec<f64>>,
}

/// One target of the path, the arm at `state`.
fn path_target(
    arm: &HybridArm<'_>,
    model: &dyn ErrorModel,
    effects: &[ModelEffect],
    target: &Target,
    state: &PathState,
    opts: &HybridOptions,
) -> Result<HybridCommand, CompensationError> {
    let chain = arm.chain;
    let nominal_e = ErrorParams::zeros(chain.layout());
    let geo = match target {
        Target::Position(p) => {
            compensate(chain, model, p, arm.held, state.seed.as_deref(), &opts.base)
        }
        Target::Joints(q) => {
            let p = chain.position(q, &nominal_e);
            let held_here: Vec<Option<f64>> =
                arm.held.iter().zip(q).map(|(h, v)| h.map(|_| *v)).collect();
            compensate_from(chain, model, &p, &held_here, q.clone(), &opts.base)
        }
    }?;
    let e = model.params_at(&geo.nominal);
    let ctx = EffectContext {
        chain,
        e: &e,
        masses: arm.masses,
        payload_kg: opts.payload_kg,
    };
    let moving: Vec<bool> = arm.held.iter().map(Option::is_none).collect();
    let mut cmd = geo.command.clone();
    let mut via = None;
    let mut dir = state.last_dir.clone();
    for _ in 0..opts.iterations {
        match opts.approach {
            Approach::FromPath => dir = directions(state.prev.as_deref(), &cmd, &state.last_dir),
            Approach::Consistent => {
                // Near the lower limit the via stops at the limit: still below the target.
                let v: Vec<f64> = cmd
                    .iter()
                    .zip(&moving)
                    .zip(chain.joints())
                    .map(|((c, &m), s)| {
                        if m {
                            (c - opts.via_offset).max(s.min)
                        } else {
                            *c
                        }
                    })
                    .collect();
                let after_via = directions(state.prev.as_deref(), &v, &state.last_dir);
                dir = directions(Some(&v), &cmd, &after_via);
                via = Some(v);
            }
        }
        let dq = joint_offsets(effects, &ctx, &cmd, &dir);
        cmd = geo.command.iter().zip(&dq).map(|(a, d)| a - d).collect();
    }
    check_limits(chain, target, &cmd)?;
    if let Some(v) = &via {
        check_limits(chain, target, v)?;
    }
    Ok(HybridCommand {
        via,
        command: cmd,
        actual: geo.command,
        nominal: geo.nominal,
        direction: dir,
        residual_mm: geo.residual_mm,
    })
}

fn check_limits(chain: &SerialChain, target: &Target, q: &[f64]) -> Result<(), CompensationError> {
    let p = match target {
        Target::Position(p) => *p,
        Target::Joints(q) => chain.position(q, &ErrorParams::zeros(chain.layout())),
    };
    match chain
        .joints()
        .iter()
        .enumerate()
        .find(|(jn, s)| !s.within(q[*jn]))
    {
        None => Ok(()),
        Some((jn, spec)) => Err(CompensationError::JointLimit {
            target: [p.x, p.y, p.z],
            joint: jn + 1,
            value: spec.kind.to_file_units(q[jn]),
            min: spec.kind.to_file_units(spec.min),
            max: spec.kind.to_file_units(spec.max),
            unit: spec.kind.unit(),
        }),
    }
}

/// The moves the arm makes for a compensated path, in order: each via move, then its command.
/// `true` marks a command (a target), `false` a via move.
pub fn moves(path: &[HybridCommand]) -> Vec<(bool, Vec<f64>)> {
    path.iter()
        .flat_map(|c| {
            c.via
                .iter()
                .map(|v| (false, v.clone()))
                .chain(std::iter::once((true, c.command.clone())))
        })
        .collect()
}

/// The text of a hybrid path's CSV: the joint columns of [`rigcal_core::recording::commands_csv`]
/// and a `move` column, `via` for a planned via move and `target` for a target's command, one
/// row per move in the order the arm makes them.
pub fn path_csv(joints: &[rigcal_core::kinematics::JointSpec], path: &[HybridCommand]) -> String {
    let all = moves(path);
    let text = rigcal_core::recording::commands_csv(joints, all.iter().map(|(_, q)| q.as_slice()));
    let mut out = String::with_capacity(text.len() + 8 * all.len());
    for (k, line) in text.lines().enumerate() {
        out.push_str(line);
        out.push_str(match k {
            0 => ",move",
            _ if all[k - 1].0 => ",target",
            _ => ",via",
        });
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_follow_the_motion_and_carry_over() {
        assert_eq!(directions(None, &[1.0, 2.0], &[0, -1]), vec![0, -1]);
        assert_eq!(
            directions(Some(&[0.0, 2.0]), &[1.0, 2.0], &[-1, -1]),
            vec![1, -1]
        );
    }
}
