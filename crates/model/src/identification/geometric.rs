//! The geometric fit of a rig's error parameters to observations: the free-frame start, the
//! identifiability analysis and the Levenberg–Marquardt fit, in that order. Both
//! [`identify`](super::identify) and the diagnosis's standard model run it; [`identify_at`] runs
//! it at a [`Level`] and returns absolute parameters, the fit every refit of the outlier search
//! ([`super::incremental`]) equals.
//!
//! With a free measurement frame the fit starts from the closed-form registration (Kabsch) of
//! the nominal arm to the measured points: the *started* chain carries that registration as its
//! nominal frame and the fitted frame parameters are relative to it. A model file needs them
//! absolute, for the rig's identity nominal frame ([`GeometricFit::into_absolute`]); the
//! diagnosis works on the started chain, where the Jacobian and the residuals were computed.

use super::registration::kabsch;
use super::{
    analyse, analyse_determined, candidate_order, fit, FitError, FitOptions, FitResult,
    Identifiability,
};
use rigcal_core::kinematics::{ErrorParams, JointKind, ParamKind, Robot, SerialChain, TransformId};
use rigcal_core::recording::Observation;
use rigcal_core::rig::{FrameMode, Rig};

/// How much of the model to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Level {
    /// Measurement frame and marker only.
    Frames,
    /// Frames plus joint offsets (θ of revolute joints, d of prismatic ones).
    Offsets,
    /// Every identifiable parameter.
    #[default]
    Full,
}

impl Level {
    /// The rig's candidate parameters ([`candidate_order`]) this level fits, in priority order.
    pub fn candidates(self, rig: &Rig) -> Vec<usize> {
        let layout = rig.chain.layout();
        candidate_order(rig)
            .into_iter()
            .filter(|&i| {
                let id = layout.ids()[i];
                match (self, id.transform) {
                    (_, TransformId::Frame | TransformId::Marker) | (Level::Full, _) => true,
                    (Level::Offsets, TransformId::Link(j)) => {
                        let kind = rig.chain.joints()[j - 1].kind;
                        (kind == JointKind::Revolute && id.kind == ParamKind::Theta)
                            || (kind == JointKind::Prismatic && id.kind == ParamKind::D)
                    }
                    _ => false,
                }
            })
            .collect()
    }
}

/// A geometric fit and the chain it was computed on.
#[derive(Debug, Clone)]
pub struct GeometricFit {
    /// The chain the fit started from: the rig's chain, with the closed-form registration as
    /// its nominal measurement frame when the frame is free.
    pub started: SerialChain,
    /// The fit, relative to `started` (frame parameters are corrections to its frame).
    pub fit: FitResult,
    /// The identifiability analysis of the candidates over the observed poses: its basis is
    /// what was fitted.
    pub identifiability: Identifiability,
    /// The rig's own chain when `started` differs from it (a free frame).
    nominal: Option<SerialChain>,
}

impl GeometricFit {
    /// The layout indices fitted (the identifiable basis).
    pub fn basis(&self) -> &[usize] {
        &self.identifiability.basis
    }

    /// The rig's chain and the fit with absolute frame parameters for it (the rig's nominal
    /// frame is the identity), so a model file stands alone. σ and covariance are unchanged:
    /// the frame moves by a constant.
    pub fn into_absolute(self) -> (SerialChain, FitResult) {
        match self.nominal {
            Some(nominal) => {
                let mut fit = self.fit;
                absolute_frame(&self.started, &mut fit);
                (nominal, fit)
            }
            None => (self.started, self.fit),
        }
    }
}

/// The chain a fit of `obs` starts from: with a free measurement frame, the nominal chain
/// registered onto the measured points (Kabsch, closed form), so that the iterations start near
/// the tracker's frame however it is turned; otherwise the rig's chain.
pub(crate) fn registered_start(rig: &Rig, obs: &[Observation]) -> SerialChain {
    if rig.calibration.measurement_frame != FrameMode::Free {
        return rig.chain.clone();
    }
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let model: Vec<_> = obs
        .iter()
        .map(|o| rig.chain.position(&o.q, &nominal))
        .collect();
    let measured: Vec<_> = obs.iter().map(|o| o.p).collect();
    rig.chain.with_frame(kabsch(&model, &measured))
}

/// Fits the `candidates` (layout indices, priority order) that the observed poses can identify:
/// Kabsch start when the rig's frame is free, the identifiability analysis, then the fit from
/// the nominal parameters.
pub fn fit_geometry(
    rig: &Rig,
    obs: &[Observation],
    candidates: &[usize],
) -> Result<GeometricFit, FitError> {
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let free_frame = rig.calibration.measurement_frame == FrameMode::Free;
    let started = registered_start(rig, obs);
    let poses: Vec<Vec<f64>> = obs.iter().map(|o| o.q.clone()).collect();
    let identifiability = analyse_determined(&started, &poses, candidates);
    let mut fit = fit(
        &started,
        obs,
        &nominal,
        &identifiability.basis,
        &FitOptions::default(),
    )
    .map_err(|e| against_a_spread_design(rig, &started, candidates, e))?;
    fit.undetermined = identifiability.undetermined.clone();
    Ok(GeometricFit {
        started,
        fit,
        identifiability,
        nominal: free_frame.then(|| rig.chain.clone()),
    })
}

/// A [`FitError::PosesDoNotSpread`] restated for what a spread design fits: the poses' own
/// analysis lost the rank they lack, so its unknowns understate what is needed. Other errors
/// pass unchanged.
pub(crate) fn against_a_spread_design(
    rig: &Rig,
    started: &SerialChain,
    candidates: &[usize],
    e: FitError,
) -> FitError {
    match e {
        FitError::PosesDoNotSpread {
            observations,
            distinct,
            ..
        } => {
            let unknowns = spread_rank(rig, started, candidates);
            FitError::PosesDoNotSpread {
                observations,
                distinct,
                unknowns,
                needed: unknowns / 3 + 1,
            }
        }
        e => e,
    }
}

/// How many of `candidates` a design spread over the joint limits identifies (the rank of
/// \[M\] over random poses, a fixed seed): what repeated poses lose.
fn spread_rank(rig: &Rig, started: &SerialChain, candidates: &[usize]) -> usize {
    use rand::SeedableRng;
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(1);
    let poses = super::random_poses(
        rigcal_core::kinematics::Robot::joints(started),
        rig.held(),
        3 * candidates.len() + 10,
        &mut rng,
    );
    analyse(started, &poses, candidates).rank
}

/// Why an identification failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentifyError {
    /// The recording has no measured rows.
    #[error("the recording has no measured rows (status ok with x_mm, y_mm, z_mm)")]
    NoMeasurements,
    /// The level leaves no parameter to fit on this rig.
    #[error("nothing to fit at level {level:?}: the rig's measurement frame and marker are fixed (set them free in [calibration] or use --level full)")]
    NothingToFit {
        /// The level asked for.
        level: Level,
    },
    /// The least-squares fit failed.
    #[error("identification failed")]
    Fit(#[source] FitError),
    /// A value read is not finite or beyond any measurement of the rig.
    #[error(transparent)]
    Absurd(#[from] Box<super::checks::AbsurdValue>),
    /// The fit diverged (residual grew, values not finite or beyond the rig's bounds).
    #[error(transparent)]
    Diverged(#[from] super::checks::Diverged),
    /// A held-out recording has no measured rows.
    #[error("held-out recording {name}: no measured rows")]
    HeldOutEmpty {
        /// Its name.
        name: String,
    },
}

/// Fits observations at a level: the rig's chain and the fit with absolute frame parameters.
pub fn identify_at(
    rig: &Rig,
    obs: &[Observation],
    level: Level,
) -> Result<(SerialChain, FitResult), IdentifyError> {
    if obs.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    let candidates = level.candidates(rig);
    if candidates.is_empty() {
        return Err(IdentifyError::NothingToFit { level });
    }
    super::checks::check_observations(&rig.chain, obs).map_err(Box::new)?;
    let geometric = fit_geometry(rig, obs, &candidates).map_err(IdentifyError::Fit)?;
    Ok(geometric.into_absolute())
}

/// Rewrites the fitted frame parameters of a chain whose nominal frame was a start value as
/// absolute values for the identity nominal frame: F = Trans(x, y, z) · Rz(rz) · Ry(ry) · Rx(rx).
pub(crate) fn absolute_frame(started: &SerialChain, result: &mut FitResult) {
    let f = started.frame_pose(&result.params);
    let (roll, pitch, yaw) = f.rotation.euler_angles();
    let t = f.translation.vector;
    let layout = started.layout();
    for (i, id) in layout.ids().iter().enumerate() {
        if id.transform != TransformId::Frame {
            continue;
        }
        let v = match id.kind {
            ParamKind::X => t.x,
            ParamKind::Y => t.y,
            ParamKind::Z => t.z,
            ParamKind::Rx => roll,
            ParamKind::Ry => pitch,
            ParamKind::Rz => yaw,
            _ => continue,
        };
        result.params.set(i, v);
    }
}
