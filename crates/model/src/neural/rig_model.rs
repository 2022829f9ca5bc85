//! A neuro-kinematic model of a rig's serial chain, stored in a model file and used as an
//! [`ErrorModel`] by compensation, `rigcal evaluate` and `rigcal compare`.
//!
//! # How the network's output becomes error parameters
//! Inputs are the moving joints (sin, cos for revolute ones). Scheme 2's joint correction d(q)
//! is exactly an offset of each moving joint: Δθ_i = d_i (revolute) or Δd_i (prismatic) of
//! link i. Scheme 4's position correction is a translation of the measured point, i.e. of the
//! measurement frame: (frame.x, frame.y, frame.z) = R_F⁻¹·d. An inverse scheme's correction is
//! the same offset with the sign reversed, evaluated at the nominal solution q_n:
//! compensation holds the error parameters at q_n (see [`crate::compensation`]) and therefore
//! commands exactly q_n + d(q_n) (inverse scheme 2) — the inverse NK model.
//!
//! Units: the network works in internal units (rad, mm); the model file stores its weights
//! and scalings as plain numbers.

use super::network::{TrainConfig, TrainOutcome};
use super::schemes::{AngularSum, NkModel, Sample, Scheme};
use super::NeuralError;
use crate::identification::Observation;
use nalgebra::Vector3;
use rigcal_core::kinematics::{ErrorModel, ErrorParams, HeldChain, JointKind, ParamLayout, Robot};
use rigcal_core::rig::Rig;
use serde::{Deserialize, Serialize};

/// A trained network with how it was trained, as stored in a model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NeuralModel {
    /// The NK model (scheme, scalings, weights).
    pub nk: NkModel,
    /// The training settings.
    pub config: TrainConfig,
    /// Epochs run, the epoch kept, and the final RMS errors (scaled units).
    pub epochs: usize,
    /// The epoch whose weights were kept.
    pub best_epoch: usize,
    /// Training time (s).
    pub train_seconds: f64,
}

/// Trains an NK model on a rig's observations (joint values of every joint, measured point).
pub fn train_on_rig(
    rig: &Rig,
    obs: &[Observation],
    scheme: Scheme,
    cfg: &TrainConfig,
) -> Result<(NeuralModel, TrainOutcome), NeuralError> {
    let kin = HeldChain::new(rig.chain.clone(), rig.held());
    let data: Vec<Sample> = obs
        .iter()
        .map(|o| Sample {
            q: kin.moving_of(&o.q),
            s: vec![o.p.x, o.p.y, o.p.z],
            s_true: None,
        })
        .collect();
    let t0 = std::time::Instant::now();
    let (nk, outcome) = NkModel::train(&kin, &data, scheme, AngularSum::Trig, cfg)?;
    let train_seconds = t0.elapsed().as_secs_f64();
    Ok((
        NeuralModel {
            nk,
            config: *cfg,
            epochs: outcome.epochs,
            best_epoch: outcome.best_epoch,
            train_seconds,
        },
        outcome,
    ))
}

/// An NK model as the error model of a rig's chain.
#[derive(Debug, Clone)]
pub struct NeuralErrorModel {
    nk: NkModel,
    moving: Vec<usize>,
    joint_params: Vec<usize>,
    frame_params: [usize; 3],
    frame_rotation_inv: nalgebra::UnitQuaternion<f64>,
    n_params: usize,
}

impl NeuralErrorModel {
    /// Joins a network with the rig it was trained for.
    pub fn new(nk: NkModel, rig: &Rig) -> Result<Self, NeuralError> {
        let moving = rig.moving_joints();
        if nk.joint_angle.len() != moving.len() {
            return Err(NeuralError::Mismatch {
                expected: nk.joint_angle.len(),
                got: moving.len(),
            });
        }
        let layout: &ParamLayout = rig.chain.layout();
        let idx = |name: String| {
            layout
                .find(&name)
                .and_then(|id| layout.index_of(id))
                .ok_or(NeuralError::Mismatch {
                    expected: moving.len(),
                    got: 0,
                })
        };
        let joints = rig.chain.joints();
        let joint_params = moving
            .iter()
            .map(|&j| match joints[j].kind {
                JointKind::Revolute => idx(format!("theta{}", j + 1)),
                JointKind::Prismatic => idx(format!("d{}", j + 1)),
            })
            .collect::<Result<Vec<_>, _>>()?;
        let frame_params = [
            idx("frame.x".into())?,
            idx("frame.y".into())?,
            idx("frame.z".into())?,
        ];
        Ok(Self {
            nk,
            moving,
            joint_params,
            frame_params,
            frame_rotation_inv: rig.chain.frame().rotation.inverse(),
            n_params: layout.len(),
        })
    }

    /// The NK model.
    pub fn nk(&self) -> &NkModel {
        &self.nk
    }
}

impl ErrorModel for NeuralErrorModel {
    fn params_at(&self, q: &[f64]) -> ErrorParams {
        let qm: Vec<f64> = self.moving.iter().map(|&j| q[j]).collect();
        let d = self.nk.correction(&qm);
        let sign = if self.nk.scheme.is_direct() {
            1.0
        } else {
            -1.0
        };
        let mut e = ErrorParams::from_vector(nalgebra::DVector::zeros(self.n_params));
        if self.nk.scheme.corrects_joints() {
            for (k, &p) in self.joint_params.iter().enumerate() {
                e.set(p, sign * d[k]);
            }
        } else {
            let v = self.frame_rotation_inv * Vector3::new(d[0], d[1], d[2]) * sign;
            for k in 0..3 {
                e.set(self.frame_params[k], v[k]);
            }
        }
        e
    }
}

/// The position a model predicts for joint values `q` (every joint) of a rig.
pub fn predicted_position(rig: &Rig, model: &dyn ErrorModel, q: &[f64]) -> Vector3<f64> {
    rig.chain.position(q, &model.params_at(q))
}
