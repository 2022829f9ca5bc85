//! Poses as vectors: why a pose-level kinematics call fails, differences of poses with angle
//! coordinates wrapped, and the numeric tools every [`Robot`] shares — Newton–Raphson inversion
//! and central-difference Jacobians. Units as in [`crate::kinematics`]: mm and rad.

use super::Robot;
use nalgebra::{DMatrix, DVector};

/// Why a pose-level kinematics call ([`Robot::forward`], [`Robot::inverse`],
/// [`Robot::pose_jacobian`]) failed.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum KinematicsError {
    /// No joint solution for the pose.
    #[error("pose {pose:?} is out of reach: {reason}")]
    Unreachable {
        /// The pose asked for (internal units).
        pose: Vec<f64>,
        /// Why.
        reason: String,
    },
    /// An iterative solution did not converge.
    #[error("{what} did not converge in {iterations} iterations (residual {residual:.3e})")]
    NoConvergence {
        /// Which solution.
        what: &'static str,
        /// Iterations made.
        iterations: usize,
        /// Residual left.
        residual: f64,
    },
}

/// Tolerance of [`Robot::inverse`]'s local Newton–Raphson step (pose units: mm, rad).
pub const NEWTON_TOLERANCE: f64 = 1e-9;

/// Iterations of [`Robot::inverse`]'s local Newton–Raphson step.
pub const NEWTON_ITERATIONS: usize = 30;

/// A pose as a function of the joint values, fallible.
pub(crate) type PoseFn<'a> = dyn Fn(&[f64]) -> Result<Vec<f64>, KinematicsError> + 'a;

/// ∂S/∂Q as a function of the joint values, fallible.
pub(crate) type JacobianFn<'a> = dyn Fn(&[f64]) -> Result<DMatrix<f64>, KinematicsError> + 'a;

/// Wraps an angle to (−π, π].
pub fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}

/// `a − b`, with angle coordinates wrapped.
pub fn difference(a: &[f64], b: &[f64], is_angle: impl Fn(usize) -> bool) -> Vec<f64> {
    a.iter()
        .zip(b)
        .enumerate()
        .map(|(i, (x, y))| if is_angle(i) { wrap(x - y) } else { x - y })
        .collect()
}

/// ∂S/∂Q at `q` by central differences of `forward` (steps 1e-6 rad for angle joints, 1e-4 mm
/// for the others): one row per pose coordinate, one column per joint.
pub fn numeric_pose_jacobian(
    forward: &PoseFn<'_>,
    q: &[f64],
    joint_is_angle: &dyn Fn(usize) -> bool,
) -> Result<DMatrix<f64>, KinematicsError> {
    let mut columns = Vec::with_capacity(q.len());
    for c in 0..q.len() {
        let h = if joint_is_angle(c) { 1e-6 } else { 1e-4 };
        let mut qp = q.to_vec();
        let mut qm = q.to_vec();
        qp[c] += h;
        qm[c] -= h;
        let (sp, sm) = (forward(&qp)?, forward(&qm)?);
        columns.push(DVector::from_iterator(
            sp.len(),
            sp.iter().zip(&sm).map(|(p, m)| (p - m) / (2.0 * h)),
        ));
    }
    if columns.is_empty() {
        return Ok(DMatrix::zeros(forward(q)?.len(), 0));
    }
    Ok(DMatrix::from_columns(&columns))
}

/// Joint values that put `forward` at pose `s`, by Newton–Raphson with `jacobian` (damped least
/// squares through the SVD when the pose has fewer coordinates than joints), starting at
/// `guess`; `pose_is_angle` says which pose coordinates wrap.
pub fn newton_solve(
    forward: &PoseFn<'_>,
    jacobian: &JacobianFn<'_>,
    pose_is_angle: &dyn Fn(usize) -> bool,
    s: &[f64],
    guess: &[f64],
    tolerance: f64,
    max_iterations: usize,
) -> Result<Vec<f64>, KinematicsError> {
    let mut q = guess.to_vec();
    let mut residual = f64::INFINITY;
    for it in 0..max_iterations {
        let f = forward(&q)?;
        let r = DVector::from_vec(difference(s, &f, pose_is_angle));
        residual = r.norm();
        if residual <= tolerance {
            return Ok(q);
        }
        let j = jacobian(&q)?;
        let dq =
            j.svd(true, true)
                .solve(&r, 1e-12)
                .map_err(|_| KinematicsError::NoConvergence {
                    what: "Newton–Raphson inverse",
                    iterations: it,
                    residual,
                })?;
        for (qi, d) in q.iter_mut().zip(dq.iter()) {
            *qi += d;
        }
    }
    Err(KinematicsError::NoConvergence {
        what: "Newton–Raphson inverse",
        iterations: max_iterations,
        residual,
    })
}

/// [`newton_solve`] on a robot's [`Robot::forward`] and [`Robot::pose_jacobian`].
pub fn newton_inverse<R: Robot + ?Sized>(
    robot: &R,
    s: &[f64],
    guess: &[f64],
    tolerance: f64,
    max_iterations: usize,
) -> Result<Vec<f64>, KinematicsError> {
    newton_solve(
        &|q| robot.forward(q),
        &|q| robot.pose_jacobian(q),
        &|i| robot.pose_is_angle(i),
        s,
        guess,
        tolerance,
        max_iterations,
    )
}
