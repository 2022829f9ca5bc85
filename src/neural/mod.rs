//! Neuro-kinematic calibration (seed 001, Legnani & Tiboni): a one-hidden-layer network in
//! parallel with the nominal kinematics learns what the nominal model gets wrong, for serial and
//! parallel robots alike.
//!
//! | module | holds |
//! |---|---|
//! | [`network`] | the network, batch back-propagation with momentum, early stopping |
//! | [`kinematics`] | the [`Kinematics`] trait (forward, inverse) for serial chains and the Stewart platform |
//! | [`schemes`] | direct and inverse schemes 2 and 4, apparent/actual error, FI (eq. 5) |
//! | [`direct_schemes`] | the other direct schemes (1, 3, 5, 6, 7) for Table 5's comparison and Table 17 |
//! | [`scara2`], [`stewart`], [`scara3`] | the paper's simulated robots |
//! | [`reproduce`] | Tables 4–8, 10–12, 16–18 beside the paper's numbers |
//! | [`rig_model`] | a network as an error model of a rig's chain (model files, compensation, `compare`) |
//!
//! # Units
//! Millimetres and radians inside; millimetres and degrees in files and reports (the Stewart
//! platform's orientation errors in mrad, as in the paper).

pub mod direct_schemes;
pub mod kinematics;
pub mod network;
pub mod reproduce;
pub mod rig_model;
pub mod scara2;
pub mod scara3;
pub mod schemes;
pub mod stewart;

pub use kinematics::{Kinematics, KinematicsError, SerialKinematics};
pub use network::{Network, Scaler, TrainConfig, TrainOutcome};
pub use schemes::{AngularSum, ErrorStats, NkModel, Sample, Scheme};

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
    Rig(#[from] crate::rig::RigError),
    /// A network does not fit the rig it is used with.
    #[error("the network expects {expected} joints but the rig moves {got}")]
    Mismatch {
        /// Joints the network was trained for.
        expected: usize,
        /// Joints the rig moves.
        got: usize,
    },
}
