//! Numeric position inverse kinematics for any chain.
//!
//! Damped least squares (Levenberg–Marquardt on the joint values) from deterministic starts: the
//! caller's seed, the middle of the joint box, then a Halton sequence over it. Joints the caller
//! holds (the RV-M2's q4 = q5 = 0 during calibration) keep their values. Units: mm and rad inside.

use super::joint::JointKind;
use super::params::ErrorParams;
use super::Robot;
use nalgebra::{DMatrix, DVector, Vector3};
use std::f64::consts::PI;

/// Why a target has no joint solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IkError {
    /// No joint values reach the target; `closest_mm` is the nearest the search came.
    #[error("target ({:.3}, {:.3}, {:.3}) mm is out of reach: the closest the arm comes is {closest_mm:.3} mm away", target[0], target[1], target[2])]
    Unreachable {
        /// The target (mm).
        target: [f64; 3],
        /// Distance of the best attempt (mm).
        closest_mm: f64,
    },
    /// The only solutions found put a joint outside its limits.
    #[error("target ({:.3}, {:.3}, {:.3}) mm needs joint {joint} at {value:.3} {unit}, outside its limits {min:.3}..{max:.3} {unit}", target[0], target[1], target[2])]
    JointLimit {
        /// The target (mm).
        target: [f64; 3],
        /// Joint number (1-based).
        joint: usize,
        /// Required value (deg or mm).
        value: f64,
        /// Lower limit (deg or mm).
        min: f64,
        /// Upper limit (deg or mm).
        max: f64,
        /// `deg` or `mm`.
        unit: &'static str,
    },
    /// The solution lies at a singular pose: joint values cannot be trusted to move the point.
    #[error("target ({:.3}, {:.3}, {:.3}) mm lies at a singular pose (smallest singular value {sigma_min:.2e} mm/unit): move the target away from the workspace boundary or the axis of joint 1", target[0], target[1], target[2])]
    Singular {
        /// The target (mm).
        target: [f64; 3],
        /// Smallest singular value of the position Jacobian over the free joints.
        sigma_min: f64,
    },
}

/// Settings of the inverse-kinematics search.
#[derive(Debug, Clone)]
pub struct IkOptions {
    /// Position tolerance (mm).
    pub tolerance_mm: f64,
    /// Iterations per start.
    pub max_iterations: usize,
    /// Number of starts tried at most.
    pub max_starts: usize,
    /// Smallest singular value (mm per rad or mm per mm) below which a pose counts as singular.
    pub singular_threshold: f64,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            tolerance_mm: 1e-7,
            max_iterations: 60,
            max_starts: 48,
            singular_threshold: 1e-3,
        }
    }
}

/// Joint values (internal units) that put the measured point of `robot` with error parameters
/// `e` at `target`. `held[j] = Some(v)` keeps joint j at v; `seed` is tried first.
pub fn solve_position_ik(
    robot: &dyn Robot,
    e: &ErrorParams,
    target: &Vector3<f64>,
    held: &[Option<f64>],
    seed: Option<&[f64]>,
    opts: &IkOptions,
) -> Result<Vec<f64>, IkError> {
    let joints = robot.joints();
    let free: Vec<usize> = (0..joints.len())
        .filter(|&j| held.get(j).copied().flatten().is_none())
        .collect();
    let mut best_residual = f64::INFINITY;
    let mut out_of_limits: Option<(usize, f64)> = None;
    let target_arr = [target.x, target.y, target.z];
    for start in starts(robot, held, seed, &free, opts.max_starts) {
        let (q, residual) = descend(robot, e, target, &free, start, opts);
        best_residual = best_residual.min(residual);
        if residual > opts.tolerance_mm {
            continue;
        }
        match first_violation(robot, &q) {
            None => {
                let sigma_min = smallest_singular_value(robot, e, &q, &free);
                if sigma_min < opts.singular_threshold {
                    return Err(IkError::Singular {
                        target: target_arr,
                        sigma_min,
                    });
                }
                return Ok(q);
            }
            Some(v) => {
                out_of_limits.get_or_insert(v);
            }
        }
    }
    if let Some((j, v)) = out_of_limits {
        let spec = &joints[j];
        return Err(IkError::JointLimit {
            target: target_arr,
            joint: j + 1,
            value: spec.kind.to_file_units(v),
            min: spec.kind.to_file_units(spec.min),
            max: spec.kind.to_file_units(spec.max),
            unit: spec.kind.unit(),
        });
    }
    Err(IkError::Unreachable {
        target: target_arr,
        closest_mm: best_residual,
    })
}

fn starts(
    robot: &dyn Robot,
    held: &[Option<f64>],
    seed: Option<&[f64]>,
    free: &[usize],
    n: usize,
) -> Vec<Vec<f64>> {
    let joints = robot.joints();
    let base: Vec<f64> = (0..joints.len())
        .map(|j| {
            held.get(j)
                .copied()
                .flatten()
                .unwrap_or(0.5 * (joints[j].min + joints[j].max))
        })
        .collect();
    let mut out = Vec::with_capacity(n + 1);
    if let Some(s) = seed {
        let mut q = base.clone();
        for &j in free {
            q[j] = s[j];
        }
        out.push(q);
    }
    out.push(base.clone());
    for k in 1..n {
        let mut q = base.clone();
        for (dim, &j) in free.iter().enumerate() {
            let u = halton(k, PRIMES[dim % PRIMES.len()]);
            q[j] = joints[j].min + u * (joints[j].max - joints[j].min);
        }
        out.push(q);
    }
    out
}

const PRIMES: [usize; 12] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37];

fn halton(mut i: usize, b: usize) -> f64 {
    let mut f = 1.0;
    let mut r = 0.0;
    while i > 0 {
        f /= b as f64;
        r += f * (i % b) as f64;
        i /= b;
    }
    r
}

fn descend(
    robot: &dyn Robot,
    e: &ErrorParams,
    target: &Vector3<f64>,
    free: &[usize],
    mut q: Vec<f64>,
    opts: &IkOptions,
) -> (Vec<f64>, f64) {
    let joints = robot.joints();
    let mut err = robot.position(&q, e) - target;
    let mut lambda = 1e-3;
    for _ in 0..opts.max_iterations {
        if err.norm() <= opts.tolerance_mm {
            break;
        }
        let jf = free_columns(&robot.joint_jacobian(&q, e), free);
        let jjt = &jf * jf.transpose();
        let mut accepted = false;
        for _ in 0..8 {
            let damped = &jjt + DMatrix::identity(3, 3) * (lambda * (1.0 + jjt.trace() / 3.0));
            let Some(chol) = damped.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let dq = jf.transpose() * chol.solve(&DVector::from_column_slice(err.as_slice()));
            let mut trial = q.clone();
            for (k, &j) in free.iter().enumerate() {
                trial[j] -= dq[k];
                if joints[j].kind == JointKind::Revolute {
                    trial[j] = wrap_near(trial[j], 0.5 * (joints[j].min + joints[j].max));
                }
            }
            let trial_err = robot.position(&trial, e) - target;
            if trial_err.norm() < err.norm() {
                q = trial;
                err = trial_err;
                lambda = (lambda * 0.1).max(1e-12);
                accepted = true;
                break;
            }
            lambda *= 10.0;
        }
        if !accepted {
            break;
        }
    }
    let residual = err.norm();
    (q, residual)
}

/// `v` (rad) moved by whole turns to within half a turn of `centre`.
pub(super) fn wrap_near(v: f64, centre: f64) -> f64 {
    let mut d = (v - centre) % (2.0 * PI);
    if d > PI {
        d -= 2.0 * PI;
    } else if d < -PI {
        d += 2.0 * PI;
    }
    centre + d
}

fn free_columns(j: &DMatrix<f64>, free: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(3, free.len(), |r, c| j[(r, free[c])])
}

/// The first joint of `q` outside its limits, and its value.
pub(super) fn first_violation(robot: &dyn Robot, q: &[f64]) -> Option<(usize, f64)> {
    robot
        .joints()
        .iter()
        .zip(q)
        .enumerate()
        .find(|(_, (s, &v))| !s.within(v))
        .map(|(j, (_, &v))| (j, v))
}

/// Smallest singular value of the position Jacobian over the free joints.
pub(crate) fn smallest_singular_value(
    robot: &dyn Robot,
    e: &ErrorParams,
    q: &[f64],
    free: &[usize],
) -> f64 {
    let jf = free_columns(&robot.joint_jacobian(q, e), free);
    let sv = jf.singular_values();
    let rank_needed = free.len().min(3);
    let mut values: Vec<f64> = sv.iter().copied().collect();
    values.sort_by(|a, b| b.total_cmp(a));
    values
        .get(rank_needed.saturating_sub(1))
        .copied()
        .unwrap_or(0.0)
}
