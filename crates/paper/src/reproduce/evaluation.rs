//! How well a trained model does on a simulated robot (seed 001 section 4.4).
//!
//! Direct schemes: E = ‖S_NK(Q) − S‖. Inverse schemes: the equivalent pose error
//! ‖J·(Q_re − Q_NK)‖ with J the nominal Jacobian at Q_re. *Apparent* against the measured (noisy)
//! pose, *actual* against the pose of the robot with its constant errors only (the simulation's
//! truth, [`Sample::s_true`]); E_r = ‖S_noisy − S_constant‖ and the filtering index
//! FI = mean E_ac / mean E_r (eq. 5). Units: the pose's (mm, rad).

use rigcal_core::kinematics::{difference, KinematicsError, Robot};
use rigcal_model::neural::{NeuralError, NkModel, Sample};
use serde::{Deserialize, Serialize};

/// Apparent error vectors, and actual ones where the truth is known, per sample.
pub type ErrorVectors = (Vec<Vec<f64>>, Vec<Option<Vec<f64>>>);

/// A trained model whose pose errors can be measured on samples.
pub trait PoseErrors {
    /// Apparent and actual pose-error vectors on `data` (see the module docs); the actual ones
    /// only where the truth is known.
    fn errors(&self, nominal: &dyn Robot, data: &[Sample]) -> Result<ErrorVectors, NeuralError>;
}

impl PoseErrors for NkModel {
    fn errors(&self, nominal: &dyn Robot, data: &[Sample]) -> Result<ErrorVectors, NeuralError> {
        let mut ap = Vec::with_capacity(data.len());
        let mut ac = Vec::with_capacity(data.len());
        let pa = |i: usize| self.pose_angle[i];
        for (index, smp) in data.iter().enumerate() {
            let kin = |source: KinematicsError| NeuralError::Kinematics { index, source };
            if self.scheme.is_direct() {
                let p = self.pose(nominal, &smp.q).map_err(kin)?;
                ap.push(difference(&p, &smp.s, pa));
                ac.push(smp.s_true.as_ref().map(|t| difference(&p, t, pa)));
            } else {
                let j = nominal.pose_jacobian(&smp.q).map_err(kin)?;
                let eq = |s: &[f64]| -> Result<Vec<f64>, NeuralError> {
                    let qn = self.joints(nominal, s, &smp.q).map_err(kin)?;
                    let dq = difference(&smp.q, &qn, |i| self.joint_angle[i]);
                    Ok((&j * nalgebra::DVector::from_vec(dq)).as_slice().to_vec())
                };
                ap.push(eq(&smp.s)?);
                ac.push(match &smp.s_true {
                    Some(t) => Some(eq(t)?),
                    None => None,
                });
            }
        }
        Ok((ap, ac))
    }
}

/// Mean and maximum of the norms of error vectors over a range of coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct ErrorStats {
    /// Mean norm.
    pub mean: f64,
    /// Largest norm.
    pub max: f64,
}

impl ErrorStats {
    /// Statistics of ‖v\[range\]‖ · `scale` over the vectors.
    pub fn of<'a>(
        v: impl IntoIterator<Item = &'a Vec<f64>>,
        range: std::ops::Range<usize>,
        scale: f64,
    ) -> Self {
        let norms: Vec<f64> = v
            .into_iter()
            .map(|x| x[range.clone()].iter().map(|a| a * a).sum::<f64>().sqrt() * scale)
            .collect();
        if norms.is_empty() {
            return Self::default();
        }
        Self {
            mean: norms.iter().sum::<f64>() / norms.len() as f64,
            max: norms.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// The filtering index FI = mean E_ac / mean E_r (eq. 5).
pub fn filtering_index(actual_mean: f64, random_mean: f64) -> Option<f64> {
    (random_mean > 0.0).then(|| actual_mean / random_mean)
}
