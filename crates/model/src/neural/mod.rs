//! Neuro-kinematic calibration (seed 001, Legnani & Tiboni): a one-hidden-layer network in
//! parallel with the nominal kinematics learns what the nominal model gets wrong, for serial and
//! parallel robots alike (any [`Robot`](rigcal_core::kinematics::Robot)).
//!
//! | module | holds |
//! |---|---|
//! | [`network`] | the network, batch back-propagation with momentum or Levenberg–Marquardt, early stopping |
//! | [`schemes`] | direct and inverse schemes 2 and 4: training, the pose and joints a model predicts |
//! | [`rig_model`] | a network as an error model of a rig's chain (model files, compensation, `compare`) |
//!
//! The paper's robots, its other schemes and the reproductions of its tables are not part of the
//! calibration tool: they live in the `reproduce` module, which uses this one (never the
//! reverse).
//!
//! # Units
//! Millimetres and radians inside; millimetres and degrees in files and reports.

pub mod network;
pub mod rig_model;
pub mod schemes;

pub use network::{Network, Scaler, TrainConfig, TrainOutcome};
use rigcal_core::kinematics::KinematicsError;
pub use schemes::{AngularSum, NkModel, Sample, Scheme};

/// What went wrong in neural calibration.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NeuralError {
    /// Too few measured pairs to train on.
    #[error("{got} measured poses: at least 2 are needed to train a network")]
    TooFewSamples {
        /// Pairs given.
        got: usize,
    },
    /// The kinematics failed on one sample.
    #[error("sample {index}: {source}")]
    Kinematics {
        /// 0-based sample index.
        index: usize,
        /// The cause.
        source: KinematicsError,
    },
    /// A rig file shipped with rigcal failed to parse (a build problem).
    #[error("built-in rig: {0}")]
    Rig(#[from] rigcal_core::rig::RigError),
    /// A network does not fit the rig it is used with.
    #[error("the network expects {expected} joints but the rig moves {got}")]
    Mismatch {
        /// Joints the network was trained for.
        expected: usize,
        /// Joints the rig moves.
        got: usize,
    },
}
