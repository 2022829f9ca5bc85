//! Position inverse kinematics on a serial chain multiplied out at its error parameters
//! ([`ChainAt`]): the seed's start of [`solve_position_ik`] with the 3 × 3 algebra on the stack,
//! for compensation's pose-by-pose loop. Units: mm and rad inside.

use super::compiled::ChainAt;
use super::ik::{first_violation, solve_position_ik, wrap_near, IkError, IkOptions};
use super::joint::JointKind;
use super::params::ErrorParams;
use super::Robot;
use nalgebra::{Matrix3, Vector3};

/// [`solve_position_ik`] on a serial chain multiplied out at its error parameters
/// ([`ChainAt`], `at`), the chain's joints `joints`: the same starts, steps and checks, with
/// the 3 × 3 algebra on the stack. Falls back to [`solve_position_ik`] on `robot` (the same
/// chain) when the fixed-size path does not apply (other than three free joints).
pub fn solve_position_ik_at(
    robot: &dyn Robot,
    at: &ChainAt,
    e: &ErrorParams,
    target: &Vector3<f64>,
    held: &[Option<f64>],
    seed: Option<&[f64]>,
    opts: &IkOptions,
) -> Result<Vec<f64>, IkError> {
    let joints = robot.joints();
    let mut free = [0usize; 3];
    let mut n_free = 0;
    for j in (0..joints.len()).filter(|&j| held.get(j).copied().flatten().is_none()) {
        if n_free == 3 {
            n_free += 1;
            break;
        }
        free[n_free] = j;
        n_free += 1;
    }
    if n_free != 3 {
        return solve_position_ik(robot, e, target, held, seed, opts);
    }
    // The seed's start alone first: along a path it is almost always the answer, and the full
    // search below tries it first too, so falling back changes nothing.
    if let Some(s) = seed {
        let mut q: Vec<f64> = (0..joints.len())
            .map(|j| {
                held.get(j)
                    .copied()
                    .flatten()
                    .unwrap_or(0.5 * (joints[j].min + joints[j].max))
            })
            .collect();
        for &j in &free {
            q[j] = s[j];
        }
        let residual = descend_at(at, robot, target, &free, &mut q, opts);
        if residual <= opts.tolerance_mm
            && first_violation(robot, &q).is_none()
            && smallest_singular_value_at(at, &q, &free) >= opts.singular_threshold
        {
            return Ok(q);
        }
    }
    solve_position_ik(robot, e, target, held, seed, opts)
}

/// `descend` of [`super::ik`] on a compiled chain with three free joints; `q` moves in place,
/// the residual is returned.
fn descend_at(
    at: &ChainAt,
    robot: &dyn Robot,
    target: &Vector3<f64>,
    free: &[usize; 3],
    q: &mut [f64],
    opts: &IkOptions,
) -> f64 {
    let joints = robot.joints();
    let mut cols = [Vector3::zeros(); 3];
    let mut err = at.position(q) - target;
    let mut lambda = 1e-3;
    for _ in 0..opts.max_iterations {
        if err.norm() <= opts.tolerance_mm {
            break;
        }
        at.position_and_joint_columns(q, free, &mut cols);
        let jf = Matrix3::from_columns(&cols);
        let jjt = jf * jf.transpose();
        let mut accepted = false;
        for _ in 0..8 {
            let damped = jjt + Matrix3::identity() * (lambda * (1.0 + jjt.trace() / 3.0));
            let Some(chol) = damped.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let dq = jf.transpose() * chol.solve(&err);
            let saved = [q[free[0]], q[free[1]], q[free[2]]];
            for (k, &j) in free.iter().enumerate() {
                let mut v = saved[k] - dq[k];
                if joints[j].kind == JointKind::Revolute {
                    v = wrap_near(v, 0.5 * (joints[j].min + joints[j].max));
                }
                q[j] = v;
            }
            let trial_err = at.position(q) - target;
            if trial_err.norm() < err.norm() {
                err = trial_err;
                lambda = (lambda * 0.1).max(1e-12);
                accepted = true;
                break;
            }
            for (k, &j) in free.iter().enumerate() {
                q[j] = saved[k];
            }
            lambda *= 10.0;
        }
        if !accepted {
            break;
        }
    }
    err.norm()
}

/// [`smallest_singular_value`](super::ik::smallest_singular_value) on a compiled chain with three
/// free joints.
fn smallest_singular_value_at(at: &ChainAt, q: &[f64], free: &[usize; 3]) -> f64 {
    let mut cols = [Vector3::zeros(); 3];
    at.position_and_joint_columns(q, free, &mut cols);
    Matrix3::from_columns(&cols).singular_values().min()
}
