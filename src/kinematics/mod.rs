//! Kinematics of serial chains: forward kinematics, the error-parameter Jacobian [M] of seed 000
//! eq. (2), the joint Jacobian, numeric inverse kinematics and spherical workspace coordinates.
//!
//! # Convention and units
//! Lengths are millimetres, angles radians (degrees only at file and screen edges).
//! A link follows Veitschegger & Wu's five-parameter convention (spec/rig.md):
//!
//! ```text
//! A(θ, d, a, α, β) = Rz(θ) · Tz(d) · Tx(a) · Rx(α) · Ry(β)
//! ```
//!
//! A revolute joint i adds q_i to θ of link i, a prismatic joint adds q_i to d. The measured
//! point of a chain is
//!
//! ```text
//! m = F · BASE · A1 · … · AN · TOOL · p
//! ```
//!
//! where F is the measurement frame (the instrument's frame relative to the world, identity when
//! measurements are already in world coordinates) and p the marker point on the last link
//! (the tool frame's origin for a pin). Every transform is a fixed nominal prefix followed by
//! elementary motions (a rotation about or a translation along one local axis), each carrying one
//! error parameter. This one representation serves five-parameter links, base and tool given as a
//! pose, the measurement frame (x y z rx ry rz) and the marker (x y z), so identification,
//! compensation and diagnosis see a single list of parameters, [`ParamLayout`].
//!
//! The Jacobian column of an error parameter is exact at any parameter value: a rotation about
//! world axis ω through point o moves the measured point by ω × (m − o); a translation along u
//! moves it by u.

mod chain;
mod ik;
mod params;
mod spherical;
pub mod urdf;

pub use chain::{
    five_par_transform, FixedPose, JointKind, JointSpec, LinkParams, SerialChain, Transform,
};
pub use ik::{solve_position_ik, IkError, IkOptions};
pub use params::{ErrorModel, ErrorParams, ParamId, ParamKind, ParamLayout, TransformId};
pub use spherical::{Spherical, SphericalFrame};

use nalgebra::{DMatrix, Vector3};

/// A robot as the calibration pipeline sees it: joint values in, a measured point out, and the
/// derivatives of that point with respect to joints and error parameters.
///
/// Serial chains implement it through [`SerialChain`]; closed chains (a Stewart platform) may
/// implement it too. Joint values use internal units: radians for revolute, millimetres for
/// prismatic joints.
pub trait Robot: Send + Sync {
    /// The joints, in order.
    fn joints(&self) -> &[JointSpec];
    /// The error parameters this robot's model carries.
    fn layout(&self) -> &ParamLayout;
    /// The measured point (mm) for joint values `q` and error parameters `e`.
    fn position(&self, q: &[f64], e: &ErrorParams) -> Vector3<f64>;
    /// The measured point and the 3 × n derivative with respect to every error parameter.
    fn position_and_param_jacobian(
        &self,
        q: &[f64],
        e: &ErrorParams,
    ) -> (Vector3<f64>, DMatrix<f64>);
    /// The 3 × N derivative of the measured point with respect to the joint values.
    fn joint_jacobian(&self, q: &[f64], e: &ErrorParams) -> DMatrix<f64>;
    /// Number of joints.
    fn dof(&self) -> usize {
        self.joints().len()
    }
}

/// Degrees to radians.
pub fn deg(x: f64) -> f64 {
    x.to_radians()
}
