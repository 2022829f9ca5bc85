//! The poses the tables train and validate on: joint values, the pose the simulated real robot
//! reaches with a random draw of errors, and the one it reaches with its constant errors only.
//! Deterministic from the generator given.

use crate::reproduce::robots::scara2::{Scara2Random, Scara2Real, WORKING_AREA};
use crate::reproduce::robots::scara3::{self, Scara3Real};
use crate::reproduce::robots::stewart::{Stewart, StewartErrors};
use rand::rngs::ChaCha8Rng;
use rand::RngExt;
use rigcal_core::kinematics::Robot;
use rigcal_model::neural::{NeuralError, Sample};

/// Samples of the 2-DOF SCARA: `n` random poses of the working area.
pub fn scara2_samples(
    real: &Scara2Real,
    random: Option<&Scara2Random>,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Sample> {
    (0..n)
        .map(|_| {
            let q = WORKING_AREA
                .at(rng.random_range(0.0..1.0), rng.random_range(0.0..1.0))
                .to_vec();
            let clean = real.pose(&q, &[0.0; 6]);
            let s = match random {
                Some(a) => real.pose(&q, &Scara2Real::draw(a, rng)).to_vec(),
                None => clean.to_vec(),
            };
            Sample {
                q,
                s,
                s_true: Some(clean.to_vec()),
            }
        })
        .collect()
}

/// Samples of the 2-DOF SCARA on a regular grid of `na` × `nb` poses over the working area
/// (boundaries included).
pub fn scara2_grid(
    real: &Scara2Real,
    random: Option<&Scara2Random>,
    na: usize,
    nb: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Sample> {
    let mut out = Vec::with_capacity(na * nb);
    for i in 0..na {
        for j in 0..nb {
            let q = WORKING_AREA
                .at(
                    i as f64 / (na.max(2) - 1) as f64,
                    j as f64 / (nb.max(2) - 1) as f64,
                )
                .to_vec();
            let clean = real.pose(&q, &[0.0; 6]).to_vec();
            let s = match random {
                Some(a) => real.pose(&q, &Scara2Real::draw(a, rng)).to_vec(),
                None => clean.clone(),
            };
            out.push(Sample {
                q,
                s,
                s_true: Some(clean),
            });
        }
    }
    out
}

/// Evenly spread samples of the 2-DOF SCARA: the first `n` points of the Halton sequence in
/// bases 2 and 3 over the working area (the paper's "poses uniformly distributed in the working
/// area"; random draws leave gaps that 46 poses cannot afford).
pub fn scara2_spread(real: &Scara2Real, n: usize) -> Vec<Sample> {
    (1..=n)
        .map(|k| {
            let q = WORKING_AREA.at(halton(k, 2), halton(k, 3)).to_vec();
            let s = real.pose(&q, &[0.0; 6]).to_vec();
            Sample {
                q,
                s: s.clone(),
                s_true: Some(s),
            }
        })
        .collect()
}

/// The `k`-th element of the van der Corput sequence in base `b` (the radical inverse of k).
fn halton(mut k: usize, b: usize) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    while k > 0 {
        f /= b as f64;
        r += f * (k % b) as f64;
        k /= b;
    }
    r
}

/// Samples of the Stewart platform: desired poses of the workspace, commanded leg lengths from
/// the nominal inverse kinematics, reached poses from the real platform (constant errors plus a
/// random draw per pose) by Newton–Raphson.
pub fn stewart_samples(
    real: &Stewart,
    random: &StewartErrors,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Sample>, NeuralError> {
    let nominal = Stewart::nominal();
    (0..n)
        .map(|index| {
            let kin = |source| NeuralError::Kinematics { index, source };
            let s_des = Stewart::random_pose(rng);
            let q = nominal.inverse(&s_des, &[]).map_err(kin)?;
            let s_true = real.direct(&q, &s_des, 1e-10).map_err(kin)?;
            let noisy = real.perturbed(&random.draw(rng));
            let s = noisy.direct(&q, &s_true, 1e-10).map_err(kin)?;
            Ok(Sample {
                q,
                s,
                s_true: Some(s_true),
            })
        })
        .collect()
}
/// Samples of the 3-DOF SCARA: random poses of the torus workspace.
pub fn scara3_samples(
    real: &Scara3Real,
    random_scale: f64,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Sample> {
    (0..n)
        .map(|_| {
            let q = scara3::random_joints(rng);
            let clean = real.position(&q, &[0.0; scara3::N_ERRORS]);
            let s = if random_scale > 0.0 {
                real.position(&q, &Scara3Real::draw(random_scale, rng))
            } else {
                clean
            };
            Sample {
                q,
                s: s.as_slice().to_vec(),
                s_true: Some(clean.as_slice().to_vec()),
            }
        })
        .collect()
}
