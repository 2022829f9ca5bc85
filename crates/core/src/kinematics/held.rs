//! A serial chain with some joints held at fixed values (the RV-M2's q4 = q5 = 0 during
//! calibration), seen as a robot of its moving joints only: what the neuro-kinematic schemes
//! learn on, since a held joint is no input of theirs.

use super::pose::{newton_inverse, KinematicsError, NEWTON_ITERATIONS, NEWTON_TOLERANCE};
use super::SerialChain;
use super::{solve_position_ik, ErrorParams, IkOptions, JointSpec, ParamLayout, Robot};
use nalgebra::{DMatrix, Vector3};

/// A serial chain whose held joints stay at their values: its joints Q are the chain's moving
/// joints in order, its pose S the measured point (mm). The error parameters are the whole
/// chain's ([`SerialChain`]'s layout, held links included).
#[derive(Debug, Clone)]
pub struct HeldChain {
    chain: SerialChain,
    held: Vec<Option<f64>>,
    moving: Vec<usize>,
    moving_specs: Vec<JointSpec>,
    nominal: ErrorParams,
}

impl HeldChain {
    /// The chain with joints `held[j] = Some(v)` fixed at v (missing entries move).
    pub fn new(chain: SerialChain, held: &[Option<f64>]) -> Self {
        let n = chain.joints().len();
        let held: Vec<Option<f64>> = (0..n).map(|j| held.get(j).copied().flatten()).collect();
        let moving: Vec<usize> = (0..n).filter(|&j| held[j].is_none()).collect();
        let moving_specs = moving.iter().map(|&j| chain.joints()[j].clone()).collect();
        let nominal = ErrorParams::zeros(chain.layout());
        Self {
            chain,
            held,
            moving,
            moving_specs,
            nominal,
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

    /// The moving columns of a 3 × (every joint) matrix.
    fn moving_columns(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
        DMatrix::from_fn(3, self.moving.len(), |r, c| j[(r, self.moving[c])])
    }
}

impl Robot for HeldChain {
    fn joints(&self) -> &[JointSpec] {
        &self.moving_specs
    }

    fn forward(&self, q: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        let p = self.chain.position(&self.full(q), &self.nominal);
        Ok(vec![p.x, p.y, p.z])
    }

    /// A local Newton step from the guess first (it keeps the branch), then the chain's global
    /// search with the held joints kept.
    fn inverse(&self, s: &[f64], guess: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        if let Ok(q) = newton_inverse(self, s, guess, NEWTON_TOLERANCE, NEWTON_ITERATIONS) {
            return Ok(q);
        }
        let target = Vector3::new(s[0], s[1], s[2]);
        let seed = self.full(guess);
        let q = solve_position_ik(
            &self.chain,
            &self.nominal,
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

    fn pose_jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>, KinematicsError> {
        Ok(self.moving_columns(&self.chain.joint_jacobian(&self.full(q), &self.nominal)))
    }

    fn layout(&self) -> &ParamLayout {
        self.chain.layout()
    }

    fn position(&self, q: &[f64], e: &ErrorParams) -> Vector3<f64> {
        self.chain.position(&self.full(q), e)
    }

    fn position_and_param_jacobian(
        &self,
        q: &[f64],
        e: &ErrorParams,
    ) -> (Vector3<f64>, DMatrix<f64>) {
        self.chain.position_and_param_jacobian(&self.full(q), e)
    }

    fn joint_jacobian(&self, q: &[f64], e: &ErrorParams) -> DMatrix<f64> {
        self.moving_columns(&self.chain.joint_jacobian(&self.full(q), e))
    }
}
