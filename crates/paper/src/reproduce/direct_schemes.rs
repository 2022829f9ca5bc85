//! The other direct neuro-kinematic schemes of seed 001 Fig. 5 (1, 3, 5, 6 and 7), for the
//! comparison of all seven in Table 5. Schemes 2 and 4, the ones rigcal calibrates with, are in
//! [`rigcal_model::neural::schemes`].
//!
//! # How we read the figures
//! The figures are not in the text we have. What the text says about them: schemes 1–5 feed
//! the joint coordinates Q to the network and 6–7 only gripper coordinates S (section 4.3);
//! 2, 3, 4, 5 and 6 are *parallel* (the network learns only the difference between nominal
//! and actual kinematics) and 1 and 7 *series*; 2, 3, 4 and 6 have an angular sum; 3, 4 and 6
//! sum on gripper coordinates (sections 5 and 6). With K the nominal direct kinematics, N the
//! network, T(·) the sine/cosine encoding of angles and ⊕ the angular sum of Table 1, type 2:
//!
//! | scheme | kind | model | trained on |
//! |---|---|---|---|
//! | 1 | series | S = K(N(T(Q))): the network gives the joints to use | T(K⁻¹(S_re)) |
//! | 3 | parallel | S = K(Q ⊕ N_q(T(Q))) ⊕ N_s(T(Q)): both corrections, one network | ‖S_re − S‖, end to end |
//! | 5 | parallel | S = N(T(Q), T(K(Q))): the nominal pose as an input, no sum | T(S_re) |
//! | 6 | parallel | S = K(Q) ⊕ N(T(K(Q))): a pose correction from the pose | S_re ⊖ K(Q) |
//! | 7 | series | S = N(T(K(Q))): the pose mapped to the pose | T(S_re) |
//!
//! Scheme 3's split between joint and pose correction is not fixed by any target, so it is
//! trained end to end on the pose error with Levenberg–Marquardt ([`Network::train_through`]).
//! The others are trained on their targets like schemes 2 and 4, with the [`TrainConfig`] given.
//!
//! Units: millimetres and radians inside.

use super::evaluation::{ErrorVectors, PoseErrors};
use nalgebra::DMatrix;
use rigcal_core::kinematics::{difference, wrap, KinematicsError, Robot};
use rigcal_model::neural::network::{
    columns, MappedResidual, Network, Scaler, TrainConfig, TrainOutcome,
};
use rigcal_model::neural::schemes::{angle_flags, decode_trig, share_sine_scale, NkModel, Sample};
use rigcal_model::neural::NeuralError;

/// Most Levenberg–Marquardt steps of scheme 3 (its fits converge within a few hundred).
pub const SCHEME3_MAX_ITERATIONS: usize = 300;

/// Early stopping of scheme 3: steps without a better held-out error (a Levenberg–Marquardt
/// step does what hundreds of gradient epochs do).
pub const SCHEME3_PATIENCE: usize = 10;

/// One of the direct schemes of this module.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OtherDirect {
    /// Series: the network gives the joints K is evaluated at.
    Scheme1,
    /// Parallel: joint and pose correction from one network, trained end to end.
    Scheme3,
    /// Parallel: the pose from the joints and the nominal pose, no sum.
    Scheme5,
    /// Parallel: a pose correction from the nominal pose.
    Scheme6,
    /// Series: the pose from the nominal pose.
    Scheme7,
}

impl OtherDirect {
    /// All of them, in the paper's order.
    pub const ALL: [OtherDirect; 5] = [
        OtherDirect::Scheme1,
        OtherDirect::Scheme3,
        OtherDirect::Scheme5,
        OtherDirect::Scheme6,
        OtherDirect::Scheme7,
    ];

    /// The paper's scheme number.
    pub fn number(self) -> u8 {
        match self {
            OtherDirect::Scheme1 => 1,
            OtherDirect::Scheme3 => 3,
            OtherDirect::Scheme5 => 5,
            OtherDirect::Scheme6 => 6,
            OtherDirect::Scheme7 => 7,
        }
    }
}

/// A trained model of one of [`OtherDirect`]'s schemes.
#[derive(Debug, Clone, PartialEq)]
pub struct OtherDirectModel {
    scheme: OtherDirect,
    joint_angle: Vec<bool>,
    pose_angle: Vec<bool>,
    input_scaler: Scaler,
    output_scaler: Scaler,
    network: Network,
}

/// Angles as (sin, cos), other coordinates as they are.
fn encode(v: &[f64], is_angle: &[bool]) -> Vec<f64> {
    NkModel::encode_joints(v, is_angle)
}

/// The inverse of [`encode`]: angles by atan2.
fn decode(y: &[f64], is_angle: &[bool]) -> Vec<f64> {
    decode_trig(y, is_angle)
}

/// ∂decode/∂y: one row per decoded coordinate.
fn decode_jacobian(y: &[f64], is_angle: &[bool]) -> DMatrix<f64> {
    let width = is_angle.iter().map(|&a| if a { 2 } else { 1 }).sum();
    let mut d = DMatrix::zeros(is_angle.len(), width);
    let mut k = 0;
    for (i, &a) in is_angle.iter().enumerate() {
        if a {
            let (s, c) = (y[k], y[k + 1]);
            let r2 = (s * s + c * c).max(1e-300);
            d[(i, k)] = c / r2;
            d[(i, k + 1)] = -s / r2;
            k += 2;
        } else {
            d[(i, k)] = 1.0;
            k += 1;
        }
    }
    d
}

fn sum_angles(x: &[f64], d: &[f64], is_angle: &[bool]) -> Vec<f64> {
    x.iter()
        .zip(d)
        .zip(is_angle)
        .map(|((a, b), &ang)| if ang { wrap(a + b) } else { a + b })
        .collect()
}

impl OtherDirectModel {
    fn input(&self, nominal: &dyn Robot, q: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        Self::input_of(self.scheme, nominal, q, &self.joint_angle, &self.pose_angle)
    }

    fn input_of(
        scheme: OtherDirect,
        nominal: &dyn Robot,
        q: &[f64],
        joint_angle: &[bool],
        pose_angle: &[bool],
    ) -> Result<Vec<f64>, KinematicsError> {
        Ok(match scheme {
            OtherDirect::Scheme1 | OtherDirect::Scheme3 => encode(q, joint_angle),
            OtherDirect::Scheme5 => {
                let mut x = encode(q, joint_angle);
                x.extend(encode(&nominal.forward(q)?, pose_angle));
                x
            }
            OtherDirect::Scheme6 | OtherDirect::Scheme7 => encode(&nominal.forward(q)?, pose_angle),
        })
    }

    /// Trains `scheme` on measured pairs with the nominal kinematics `nominal`. Scheme 3 is
    /// trained end to end by Levenberg–Marquardt whatever `cfg.method` says: at most
    /// [`SCHEME3_MAX_ITERATIONS`] steps, and with early stopping at most
    /// [`SCHEME3_PATIENCE`] steps without a better held-out error.
    pub fn train(
        nominal: &dyn Robot,
        data: &[Sample],
        scheme: OtherDirect,
        cfg: &TrainConfig,
    ) -> Result<(Self, TrainOutcome), NeuralError> {
        Self::train_observed(nominal, data, scheme, cfg, &mut |_, _| {})
    }

    /// [`OtherDirectModel::train`], calling `observe(epoch, model)` with the model as it stands
    /// after every epoch or step (for learning curves).
    pub fn train_observed(
        nominal: &dyn Robot,
        data: &[Sample],
        scheme: OtherDirect,
        cfg: &TrainConfig,
        observe: &mut dyn FnMut(usize, &OtherDirectModel),
    ) -> Result<(Self, TrainOutcome), NeuralError> {
        let (joint_angle, pose_angle) = angle_flags(nominal, data.len())?;
        let mut inputs = Vec::with_capacity(data.len());
        let mut targets = Vec::with_capacity(data.len());
        for (index, smp) in data.iter().enumerate() {
            let kin = |source: KinematicsError| NeuralError::Kinematics { index, source };
            inputs.push(
                Self::input_of(scheme, nominal, &smp.q, &joint_angle, &pose_angle).map_err(kin)?,
            );
            targets.push(
                Self::target_of(scheme, nominal, smp, &joint_angle, &pose_angle).map_err(kin)?,
            );
        }
        let input_scaler = Scaler::fit(&inputs);
        let output_scaler = Self::output_scaler(scheme, &targets, &joint_angle, &pose_angle);
        let x = columns(
            &inputs
                .iter()
                .map(|r| input_scaler.apply(r))
                .collect::<Vec<_>>(),
        );
        let outputs = targets.first().map_or(0, Vec::len);
        let mut model = Self {
            scheme,
            joint_angle,
            pose_angle,
            input_scaler,
            output_scaler,
            network: Network::new(x.nrows(), cfg.hidden, outputs, cfg.seed),
        };
        let outcome = model.fit(nominal, data, &x, &targets, cfg, observe);
        Ok((model, outcome))
    }

    /// What the network of `scheme` is trained on for one sample (for scheme 3, only to scale
    /// the outputs: the joint correction alone and the pose correction alone).
    fn target_of(
        scheme: OtherDirect,
        nominal: &dyn Robot,
        smp: &Sample,
        joint_angle: &[bool],
        pose_angle: &[bool],
    ) -> Result<Vec<f64>, KinematicsError> {
        Ok(match scheme {
            OtherDirect::Scheme1 => encode(&nominal.inverse(&smp.s, &smp.q)?, joint_angle),
            OtherDirect::Scheme3 => {
                let qs = nominal.inverse(&smp.s, &smp.q)?;
                let dq = difference(&qs, &smp.q, |i| joint_angle[i]);
                let s0 = nominal.forward(&smp.q)?;
                let ds = difference(&smp.s, &s0, |i| pose_angle[i]);
                let mut t = encode(&dq, joint_angle);
                t.extend(encode(&ds, pose_angle));
                t
            }
            OtherDirect::Scheme5 | OtherDirect::Scheme7 => encode(&smp.s, pose_angle),
            OtherDirect::Scheme6 => {
                let s0 = nominal.forward(&smp.q)?;
                encode(&difference(&smp.s, &s0, |i| pose_angle[i]), pose_angle)
            }
        })
    }

    /// The scaling of the targets, every cosine output sharing its sine's scale.
    fn output_scaler(
        scheme: OtherDirect,
        targets: &[Vec<f64>],
        joint_angle: &[bool],
        pose_angle: &[bool],
    ) -> Scaler {
        let mut output_scaler = Scaler::fit(targets);
        match scheme {
            OtherDirect::Scheme3 => {
                share_sine_scale(&mut output_scaler, joint_angle, 0);
                let offset = joint_angle.iter().map(|&a| 1 + a as usize).sum();
                share_sine_scale(&mut output_scaler, pose_angle, offset);
            }
            OtherDirect::Scheme6 => share_sine_scale(&mut output_scaler, pose_angle, 0),
            _ => {}
        }
        output_scaler
    }

    /// Trains the network on scaled inputs `x`: scheme 3 end to end by Levenberg–Marquardt,
    /// the others on their `targets`.
    fn fit(
        &mut self,
        nominal: &dyn Robot,
        data: &[Sample],
        x: &nalgebra::DMatrix<f64>,
        targets: &[Vec<f64>],
        cfg: &TrainConfig,
        observe: &mut dyn FnMut(usize, &OtherDirectModel),
    ) -> TrainOutcome {
        let mut network = self.network.clone();
        let mut view = self.clone();
        let mut watch = |epoch: usize, net: &Network| {
            view.network.clone_from(net);
            observe(epoch, &view);
        };
        let outcome = if self.scheme == OtherDirect::Scheme3 {
            let residual = |p: usize, y: &[f64]| self.scheme3_residual(nominal, &data[p], y);
            let lm = TrainConfig {
                epochs: cfg.epochs.min(SCHEME3_MAX_ITERATIONS),
                patience: cfg.patience.min(SCHEME3_PATIENCE),
                ..*cfg
            };
            network.train_through_observed(x, &residual, &lm, &mut watch)
        } else {
            let t = columns(
                &targets
                    .iter()
                    .map(|r| self.output_scaler.apply(r))
                    .collect::<Vec<_>>(),
            );
            network.train_observed(x, &t, cfg, &mut watch)
        };
        self.network = network;
        outcome
    }

    /// Scheme 3: the joint and pose corrections from raw outputs `z`.
    fn scheme3_corrections(&self, z: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let nq: usize = self.joint_angle.iter().map(|&a| 1 + a as usize).sum();
        (
            decode(&z[..nq], &self.joint_angle),
            decode(&z[nq..], &self.pose_angle),
        )
    }

    /// Scheme 3's pose residual (scaled like the pose correction) for scaled outputs `y`, and
    /// its derivatives with respect to `y`.
    fn scheme3_residual(
        &self,
        nominal: &dyn Robot,
        smp: &Sample,
        y: &[f64],
    ) -> Option<MappedResidual> {
        let z = self.output_scaler.invert(y);
        let nq: usize = self.joint_angle.iter().map(|&a| 1 + a as usize).sum();
        let (dq, ds) = self.scheme3_corrections(&z);
        let qc = sum_angles(&smp.q, &dq, &self.joint_angle);
        let s = sum_angles(&nominal.forward(&qc).ok()?, &ds, &self.pose_angle);
        // Residuals in units of the pose correction's spread, so that they are O(1).
        let sigma: Vec<f64> = self.output_scaler.scale[nq..].to_vec();
        let pose_sigma = decode_scale(&sigma, &self.pose_angle);
        let e = difference(&s, &smp.s, |i| self.pose_angle[i]);
        let r: Vec<f64> = e.iter().zip(&pose_sigma).map(|(v, w)| v / w).collect();
        // ∂S/∂z = [J_K(Q_c) · ∂dq/∂z_q, ∂ds/∂z_s]; ∂z/∂y = diag(scale).
        let jk = nominal.pose_jacobian(&qc).ok()?;
        let dq_dz = decode_jacobian(&z[..nq], &self.joint_angle);
        let ds_dz = decode_jacobian(&z[nq..], &self.pose_angle);
        let mut d = DMatrix::zeros(r.len(), z.len());
        d.columns_mut(0, nq).copy_from(&(jk * dq_dz));
        d.columns_mut(nq, z.len() - nq).copy_from(&ds_dz);
        for (c, sc) in self.output_scaler.scale.iter().enumerate() {
            d.column_mut(c).scale_mut(*sc);
        }
        for (row, w) in pose_sigma.iter().enumerate() {
            d.row_mut(row).unscale_mut(*w);
        }
        Some((r, d))
    }

    /// The pose predicted for joint values `q`.
    pub fn pose(&self, nominal: &dyn Robot, q: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        let x = self.input_scaler.apply(&self.input(nominal, q)?);
        let z = self.output_scaler.invert(&self.network.predict(&x));
        match self.scheme {
            OtherDirect::Scheme1 => nominal.forward(&decode(&z, &self.joint_angle)),
            OtherDirect::Scheme3 => {
                let (dq, ds) = self.scheme3_corrections(&z);
                let s = nominal.forward(&sum_angles(q, &dq, &self.joint_angle))?;
                Ok(sum_angles(&s, &ds, &self.pose_angle))
            }
            OtherDirect::Scheme5 | OtherDirect::Scheme7 => Ok(decode(&z, &self.pose_angle)),
            OtherDirect::Scheme6 => Ok(sum_angles(
                &nominal.forward(q)?,
                &decode(&z, &self.pose_angle),
                &self.pose_angle,
            )),
        }
    }
}

impl PoseErrors for OtherDirectModel {
    fn errors(&self, nominal: &dyn Robot, data: &[Sample]) -> Result<ErrorVectors, NeuralError> {
        let pa = |i: usize| self.pose_angle[i];
        let mut ap = Vec::with_capacity(data.len());
        let mut ac = Vec::with_capacity(data.len());
        for (index, smp) in data.iter().enumerate() {
            let p = self
                .pose(nominal, &smp.q)
                .map_err(|source| NeuralError::Kinematics { index, source })?;
            ap.push(difference(&p, &smp.s, pa));
            ac.push(smp.s_true.as_ref().map(|t| difference(&p, t, pa)));
        }
        Ok((ap, ac))
    }
}

/// One scale per pose coordinate from the scales of its encoded outputs (an angle's sine).
fn decode_scale(scale: &[f64], is_angle: &[bool]) -> Vec<f64> {
    let mut out = Vec::with_capacity(is_angle.len());
    let mut k = 0;
    for &a in is_angle {
        out.push(scale[k]);
        k += 1 + a as usize;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reproduce::robots::scara2::{Scara2, Scara2Errors, Scara2Real, WORKING_AREA};

    fn scara2_data(n: usize) -> (Scara2, Vec<Sample>) {
        let nominal = Scara2::default();
        let real = Scara2Real {
            nominal,
            errors: Scara2Errors::case(2),
        };
        let data = (0..n)
            .map(|k| {
                let u = (k as f64 + 0.5) / n as f64;
                let q = WORKING_AREA.at(u, (3.0 * u).fract()).to_vec();
                let s = real.pose(&q, &[0.0; 6]).to_vec();
                Sample {
                    q,
                    s: s.clone(),
                    s_true: Some(s),
                }
            })
            .collect();
        (nominal, data)
    }

    #[test]
    fn scheme3_residual_derivatives_match_finite_differences() {
        let (nominal, data) = scara2_data(12);
        let cfg = TrainConfig {
            hidden: 5,
            epochs: 1,
            ..TrainConfig::default()
        };
        let (model, _) =
            OtherDirectModel::train(&nominal, &data, OtherDirect::Scheme3, &cfg).expect("train");
        let y = [0.3, -0.2, 0.5, 0.1, -0.4, 0.7];
        let (r0, d) = model
            .scheme3_residual(&nominal, &data[4], &y)
            .expect("residual");
        let h = 1e-6;
        for c in 0..y.len() {
            let mut yp = y;
            yp[c] += h;
            let (r1, _) = model
                .scheme3_residual(&nominal, &data[4], &yp)
                .expect("residual");
            for row in 0..r0.len() {
                let fd = (r1[row] - r0[row]) / h;
                let tol = 1e-4 * (1.0 + fd.abs());
                assert!(
                    (fd - d[(row, c)]).abs() < tol,
                    "({row},{c}) {fd} vs {}",
                    d[(row, c)]
                );
            }
        }
    }

    #[test]
    fn every_scheme_learns_a_noise_free_scara_from_its_own_poses() {
        // Each scheme, trained on 60 poses, must predict them far better than the nominal
        // kinematics does (8.7 mm mean in case 2): at least 40× better.
        let (nominal, data) = scara2_data(60);
        let cfg = TrainConfig {
            method: rigcal_model::neural::network::Method::LevenbergMarquardt,
            hidden: 10,
            epochs: 100,
            ..TrainConfig::default()
        };
        for scheme in OtherDirect::ALL {
            let (model, _) = OtherDirectModel::train(&nominal, &data, scheme, &cfg).expect("train");
            let (ap, _) = model.errors(&nominal, &data).expect("errors");
            let mean = ap.iter().map(|e| e[0].hypot(e[1])).sum::<f64>() / ap.len() as f64;
            assert!(mean < 0.2, "scheme {}: {mean} mm", scheme.number());
        }
    }

    #[test]
    fn decode_jacobian_matches_finite_differences() {
        let flags = [true, false];
        let y = [0.3, 0.9, 2.0];
        let d = decode_jacobian(&y, &flags);
        let h = 1e-7;
        for c in 0..y.len() {
            let mut yp = y;
            yp[c] += h;
            let (a, b) = (decode(&yp, &flags), decode(&y, &flags));
            for r in 0..flags.len() {
                let fd = (a[r] - b[r]) / h;
                assert!(
                    (fd - d[(r, c)]).abs() < 1e-5,
                    "({r},{c}) {fd} vs {}",
                    d[(r, c)]
                );
            }
        }
    }
}
