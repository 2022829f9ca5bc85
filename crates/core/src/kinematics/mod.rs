//! Kinematics of robots: the [`Robot`] trait every robot implements (serial chains, the held-joint
//! view of a chain, the paper robots of the reproductions), forward kinematics of serial chains,
//! the error-parameter Jacobian \[M\] of seed 000 eq. (2), the joint Jacobian, numeric inverse
//! kinematics and spherical workspace coordinates.
//!
//! # Convention and units
//! Lengths are millimetres, angles radians (degrees only at file and screen edges). Joint values
//! Q: radians for revolute, millimetres for prismatic joints (a Stewart platform's legs).
//!
//! A robot is seen two ways, through one trait:
//! - **as a pose map** (what the neuro-kinematic schemes of seed 001 use): Q ↦ S, a pose vector
//!   of [`Robot::pose_len`] coordinates — millimetres for positions, radians for the coordinates
//!   [`Robot::pose_is_angle`] flags — with [`Robot::forward`], [`Robot::inverse`] and
//!   ∂S/∂Q by [`Robot::pose_jacobian`]. For a serial chain S is the measured point (x, y, z),
//!   the nominal one (all error parameters zero); the 2-DOF SCARA has S = (x, y), the Stewart
//!   platform S = (x, y, z, ψ, θ, φ).
//! - **as a measured point with error parameters** (what identification, compensation and
//!   diagnosis use): [`Robot::position`] for joint values and error parameters, and its
//!   derivatives with respect to both. A robot that carries no error-parameter model (the paper
//!   robots, calibrated by networks only) has an empty [`Robot::layout`].
//!
//! A link of a serial chain follows Veitschegger & Wu's five-parameter convention (spec/rig.md):
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
mod compiled;
mod held;
mod ik;
mod ik_at;
mod joint;
mod params;
mod pose;
mod rigid;
mod spherical;
pub mod urdf;

pub use chain::{LinkParams, SerialChain, Transform};
pub use compiled::{joint_trig, ChainAt};
pub use held::HeldChain;
pub use ik::{solve_position_ik, IkError, IkOptions};
pub use ik_at::solve_position_ik_at;
pub use joint::{JointKind, JointSpec};
pub use params::{ErrorModel, ErrorParams, ParamId, ParamKind, ParamLayout, TransformId};
pub use pose::{
    difference, newton_inverse, newton_solve, numeric_pose_jacobian, wrap, KinematicsError,
    NEWTON_ITERATIONS, NEWTON_TOLERANCE,
};
pub use spherical::{Spherical, SphericalFrame};

use nalgebra::{DMatrix, Vector3};

/// A robot: joint values Q in, a pose S out (forward, inverse, ∂S/∂Q), and the measured point
/// with the derivatives that identification needs (with respect to joints and error
/// parameters). See the module docs for the convention and units.
///
/// The pose-map methods have defaults for a robot whose pose is its measured point (a serial
/// chain): S = [`Robot::position`] at zero error parameters, three coordinates, none an angle,
/// inverted by Newton–Raphson, differentiated by central differences. A robot with another pose
/// overrides [`Robot::pose_len`], [`Robot::pose_is_angle`] and [`Robot::forward`] together.
pub trait Robot: Send + Sync {
    /// The joints, in order.
    fn joints(&self) -> &[JointSpec];

    /// Number of joints.
    fn dof(&self) -> usize {
        self.joints().len()
    }

    /// Whether joint `i` is an angle (revolute): it is encoded as sine and cosine at a network's
    /// input and stepped by 1e-6 rad in numeric derivatives.
    fn joint_is_angle(&self, i: usize) -> bool {
        self.joints()[i].kind == JointKind::Revolute
    }

    /// Number of pose coordinates S.
    fn pose_len(&self) -> usize {
        3
    }

    /// Whether pose coordinate `i` is an angle (rad; differences of it are wrapped).
    fn pose_is_angle(&self, _i: usize) -> bool {
        false
    }

    /// The pose for joint values `q`. Fails where it is found iteratively and the iteration does
    /// not converge (a parallel robot's direct kinematics).
    fn forward(&self, q: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        let p = self.position(q, &ErrorParams::zeros(self.layout()));
        Ok(vec![p.x, p.y, p.z])
    }

    /// Joint values for pose `s`; `guess` picks the branch (elbow, assembly) or seeds a search.
    /// The default is a local Newton–Raphson search from `guess` ([`NEWTON_TOLERANCE`],
    /// [`NEWTON_ITERATIONS`]).
    fn inverse(&self, s: &[f64], guess: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        newton_inverse(self, s, guess, NEWTON_TOLERANCE, NEWTON_ITERATIONS)
    }

    /// ∂S/∂Q at `q` (pose_len × dof); central differences of [`Robot::forward`] unless
    /// overridden.
    fn pose_jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>, KinematicsError> {
        numeric_pose_jacobian(&|q| self.forward(q), q, &|i| self.joint_is_angle(i))
    }

    /// The error parameters this robot's model carries ([`no_error_parameters`] for none).
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

    /// This robot as a serial chain with the same joints, when it is one: identification and
    /// compensation then take the chain's allocation-free evaluation ([`SerialChain::at`]).
    fn as_serial_chain(&self) -> Option<&SerialChain> {
        None
    }
}

/// The layout of a robot that carries no error parameters.
pub fn no_error_parameters() -> &'static ParamLayout {
    static NONE: std::sync::LazyLock<ParamLayout> =
        std::sync::LazyLock::new(|| ParamLayout::new(Vec::new(), 0));
    &NONE
}

/// Degrees to radians.
pub fn deg(x: f64) -> f64 {
    x.to_radians()
}
