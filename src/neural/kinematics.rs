//! The robot interface the neuro-kinematic schemes need: forward and inverse kinematics between
//! joint coordinates Q and gripper coordinates S, for serial and parallel robots alike.
//!
//! # Conventions
//! Internal units: millimetres and radians. Joint coordinates are radians (revolute) or
//! millimetres (prismatic, Stewart legs); gripper coordinates are millimetres for positions and
//! radians for orientation angles. Which coordinates are angles is stated by the robot, so the
//! schemes can encode them as sine and cosine (seed 001 section 4.1).

use crate::kinematics::{solve_position_ik, ErrorParams, IkOptions, Robot, SerialChain};
use nalgebra::{DMatrix, DVector, Vector3};

/// Why a kinematics call failed.
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

/// Forward and inverse kinematics of a robot, serial or parallel.
pub trait Kinematics: Send + Sync {
    /// Number of joint coordinates.
    fn joint_count(&self) -> usize;
    /// Number of gripper coordinates.
    fn pose_len(&self) -> usize;
    /// Whether joint coordinate `i` is an angle.
    fn joint_is_angle(&self, i: usize) -> bool;
    /// Whether gripper coordinate `i` is an angle.
    fn pose_is_angle(&self, i: usize) -> bool;
    /// Gripper pose for joint values `q`.
    fn forward(&self, q: &[f64]) -> Result<Vec<f64>, KinematicsError>;
    /// Joint values for pose `s`; `guess` picks the branch (elbow, assembly) or seeds a search.
    fn inverse(&self, s: &[f64], guess: &[f64]) -> Result<Vec<f64>, KinematicsError>;
    /// ∂S/∂Q at `q` (pose_len × joint_count), by central differences unless overridden.
    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>, KinematicsError> {
        let n = self.joint_count();
        let m = self.pose_len();
        let mut j = DMatrix::zeros(m, n);
        for c in 0..n {
            let h = if self.joint_is_angle(c) { 1e-6 } else { 1e-4 };
            let mut qp = q.to_vec();
            let mut qm = q.to_vec();
            qp[c] += h;
            qm[c] -= h;
            let (sp, sm) = (self.forward(&qp)?, self.forward(&qm)?);
            for r in 0..m {
                j[(r, c)] = (sp[r] - sm[r]) / (2.0 * h);
            }
        }
        Ok(j)
    }
}

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

/// Joint values that put the forward kinematics of `k` at `s`, by Newton–Raphson with the
/// Jacobian of [`Kinematics::jacobian`] (damped least squares when the pose has fewer
/// coordinates than joints), starting at `guess`.
pub fn newton_inverse(
    k: &dyn Kinematics,
    s: &[f64],
    guess: &[f64],
    tolerance: f64,
    max_iterations: usize,
) -> Result<Vec<f64>, KinematicsError> {
    let mut q = guess.to_vec();
    let mut residual = f64::INFINITY;
    for it in 0..max_iterations {
        let f = k.forward(&q)?;
        let r = DVector::from_vec(difference(s, &f, |i| k.pose_is_angle(i)));
        residual = r.norm();
        if residual <= tolerance {
            return Ok(q);
        }
        let j = k.jacobian(&q)?;
        let dq = j.clone().svd(true, true).solve(&r, 1e-12).map_err(|_| {
            KinematicsError::NoConvergence {
                what: "Newton–Raphson inverse",
                iterations: it,
                residual,
            }
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

/// A serial chain from a rig file as [`Kinematics`]: the moving joints are Q, the measured point
/// (mm) is S; held joints stay at their calibration values; error parameters `e` (zero for the
/// nominal robot) are part of the model.
#[derive(Debug, Clone)]
pub struct SerialKinematics {
    chain: SerialChain,
    e: ErrorParams,
    held: Vec<Option<f64>>,
    moving: Vec<usize>,
}

impl SerialKinematics {
    /// The nominal chain with joints `held[j] = Some(v)` fixed at v.
    pub fn new(chain: SerialChain, held: &[Option<f64>]) -> Self {
        let e = ErrorParams::zeros(chain.layout());
        Self::with_errors(chain, e, held)
    }

    /// The chain with error parameters `e`.
    pub fn with_errors(chain: SerialChain, e: ErrorParams, held: &[Option<f64>]) -> Self {
        let n = chain.joints().len();
        let held: Vec<Option<f64>> = (0..n).map(|j| held.get(j).copied().flatten()).collect();
        let moving = (0..n).filter(|&j| held[j].is_none()).collect();
        Self {
            chain,
            e,
            held,
            moving,
        }
    }

    /// The chain.
    pub fn chain(&self) -> &SerialChain {
        &self.chain
    }

    /// Full joint vector (every joint, held ones included) from the moving joints' values.
    pub fn full(&self, q: &[f64]) -> Vec<f64> {
        let mut out: Vec<f64> = self.held.iter().map(|h| h.unwrap_or(0.0)).collect();
        for (k, &j) in self.moving.iter().enumerate() {
            out[j] = q[k];
        }
        out
    }

    /// The moving joints' values from a full joint vector.
    pub fn moving_of(&self, full: &[f64]) -> Vec<f64> {
        self.moving.iter().map(|&j| full[j]).collect()
    }
}

impl Kinematics for SerialKinematics {
    fn joint_count(&self) -> usize {
        self.moving.len()
    }
    fn pose_len(&self) -> usize {
        3
    }
    fn joint_is_angle(&self, i: usize) -> bool {
        self.chain.joints()[self.moving[i]].kind == crate::kinematics::JointKind::Revolute
    }
    fn pose_is_angle(&self, _i: usize) -> bool {
        false
    }
    fn forward(&self, q: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        let p = self.chain.position(&self.full(q), &self.e);
        Ok(vec![p.x, p.y, p.z])
    }
    fn inverse(&self, s: &[f64], guess: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        let target = Vector3::new(s[0], s[1], s[2]);
        let seed = self.full(guess);
        // Try a local Newton step from the guess first (keeps the branch), then the global search.
        if let Ok(q) = newton_inverse(self, s, guess, 1e-9, 30) {
            return Ok(q);
        }
        let q = solve_position_ik(
            &self.chain,
            &self.e,
            &target,
            &self.held,
            Some(&seed),
            &IkOptions::default(),
        )
        .map_err(|e| KinematicsError::Unreachable {
            pose: s.to_vec(),
            reason: e.to_string(),
        })?;
        Ok(self.moving_of(&q))
    }
    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>, KinematicsError> {
        let j = self.chain.joint_jacobian(&self.full(q), &self.e);
        Ok(DMatrix::from_fn(3, self.moving.len(), |r, c| {
            j[(r, self.moving[c])]
        }))
    }
}
