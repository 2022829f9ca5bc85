//! Neuro-kinematic (NK) calibration schemes of seed 001 (Figs. 3–6): a network in parallel with
//! the nominal kinematics learns the difference between nominal and real robot.
//!
//! # The schemes implemented, and how we read the figures
//! The figures of the schemes are not in the text we have; we read them from what the text says
//! about them: schemes 1–5 feed the joint coordinates Q to the network, the parallel schemes learn
//! only the difference between nominal and actual kinematics, schemes 2, 3, 4 and 6 add joint
//! rotations or pose coordinates (Tables 1–2), and for the Stewart platform and the 3-DOF SCARA
//! "schemes 4 and 6 involve an angular sum on gripper coordinates S". Hence, with K the nominal
//! direct kinematics, K⁻¹ its inverse, N the network and T(·) the sine/cosine encoding:
//!
//! | scheme | direct (predict S from Q) | inverse (predict Q for a desired S) |
//! |---|---|---|
//! | 2 | S = K(Q ⊕ N(T(Q))): a joint correction | Q = K⁻¹(S) ⊕ N(T(K⁻¹(S))) |
//! | 4 | S = K(Q) ⊕ N(T(Q)): a pose correction | Q = K⁻¹(S ⊕ N(T(K⁻¹(S)))) |
//!
//! ⊕ is the angular sum of Table 1: [`AngularSum::Plain`] (θ + dθ) or [`AngularSum::Trig`]
//! (the network outputs sin dθ and cos dθ; θ + atan2(sin dθ, cos dθ), the type the paper found
//! best). Coordinates that are not angles are summed plainly.
//!
//! Training targets come from the measured pairs (Q, S_re): the joint correction is
//! K⁻¹(S_re) − Q (direct 2) or Q − K⁻¹(S_re) (inverse 2), the pose correction S_re − K(Q)
//! (direct 4) or K(Q) − S_re (inverse 4); the network then fits them by least squares, which is
//! the paper's E = ‖S_re − S_NK‖ to first order.
//!
//! How well a model does on simulated robots (apparent and actual errors, FI) is the
//! reproductions' business (`reproduce::evaluation`).

use super::network::{columns, Network, Scaler, TrainConfig, TrainOutcome};
use super::NeuralError;
use rigcal_core::kinematics::{
    difference, newton_solve, numeric_pose_jacobian, wrap, KinematicsError, Robot,
};
use serde::{Deserialize, Serialize};

/// A calibration scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Scheme {
    /// Direct scheme 2: joint correction before the nominal direct kinematics.
    Direct2,
    /// Direct scheme 4: pose correction after the nominal direct kinematics.
    Direct4,
    /// Inverse scheme 2: joint correction after the nominal inverse kinematics.
    Inverse2,
    /// Inverse scheme 4: pose correction before the nominal inverse kinematics.
    Inverse4,
}

impl Scheme {
    /// The paper's scheme number.
    pub fn number(self) -> u8 {
        match self {
            Scheme::Direct2 | Scheme::Inverse2 => 2,
            Scheme::Direct4 | Scheme::Inverse4 => 4,
        }
    }

    /// Direct (predicts S) or inverse (predicts Q).
    pub fn is_direct(self) -> bool {
        matches!(self, Scheme::Direct2 | Scheme::Direct4)
    }

    /// Whether the network's correction is in joint space (scheme 2) or pose space (scheme 4).
    pub fn corrects_joints(self) -> bool {
        self.number() == 2
    }

    /// A short name (`direct-2`, `inverse-4`).
    pub fn name(self) -> &'static str {
        match self {
            Scheme::Direct2 => "direct-2",
            Scheme::Direct4 => "direct-4",
            Scheme::Inverse2 => "inverse-2",
            Scheme::Inverse4 => "inverse-4",
        }
    }
}

/// How corrections of angles are added (seed 001 Table 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AngularSum {
    /// θ + dθ: the network outputs dθ.
    Plain,
    /// θ + atan2(sin dθ, cos dθ): the network outputs sin dθ and cos dθ.
    Trig,
}

/// A measured pair: joint values and the pose reached (internal units).
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Joint values commanded (rad, mm).
    pub q: Vec<f64>,
    /// Pose measured (mm, rad), random errors included.
    pub s: Vec<f64>,
    /// The pose the robot reaches with its constant errors only, where a simulation knows it
    /// (`None` for measurements; training never reads it).
    pub s_true: Option<Vec<f64>>,
}

/// A trained neuro-kinematic model: scheme, scalings and network.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NkModel {
    /// The scheme.
    pub scheme: Scheme,
    /// How angle corrections are added.
    pub angular_sum: AngularSum,
    /// Which joint coordinates are angles (encoded as sin, cos at the input).
    pub joint_angle: Vec<bool>,
    /// Which pose coordinates are angles.
    pub pose_angle: Vec<bool>,
    /// Scaling of the encoded inputs.
    pub input_scaler: Scaler,
    /// Scaling of the encoded outputs (the network is trained on scaled targets).
    pub output_scaler: Scaler,
    /// The network.
    pub network: Network,
}

/// T⁻¹: angles from their (sin, cos) pair by atan2, other coordinates as they are.
pub fn decode_trig(y: &[f64], is_angle: &[bool]) -> Vec<f64> {
    let mut out = Vec::with_capacity(is_angle.len());
    let mut k = 0;
    for &a in is_angle {
        if a {
            out.push(y[k].atan2(y[k + 1]));
            k += 2;
        } else {
            out.push(y[k]);
            k += 1;
        }
    }
    out
}

/// Which joint and which pose coordinates of `nominal` are angles; refuses fewer than two
/// training samples.
pub fn angle_flags(
    nominal: &dyn Robot,
    samples: usize,
) -> Result<(Vec<bool>, Vec<bool>), NeuralError> {
    if samples < 2 {
        return Err(NeuralError::TooFewSamples { got: samples });
    }
    Ok((
        (0..nominal.dof())
            .map(|i| nominal.joint_is_angle(i))
            .collect(),
        (0..nominal.pose_len())
            .map(|i| nominal.pose_is_angle(i))
            .collect(),
    ))
}

/// Gives every encoded cosine output (from `offset` on, one (sin, cos) pair per angle in
/// `is_angle`) the scale of its sine: cos dθ barely varies, and scaling it alone would let
/// magnified noise in it dominate the loss and early stopping.
pub fn share_sine_scale(scaler: &mut Scaler, is_angle: &[bool], offset: usize) {
    let mut k = offset;
    for &a in is_angle {
        if a {
            scaler.scale[k + 1] = scaler.scale[k];
            k += 2;
        } else {
            k += 1;
        }
    }
}

fn sum_coords(x: &[f64], d: &[f64], is_angle: &[bool]) -> Vec<f64> {
    x.iter()
        .zip(d)
        .zip(is_angle)
        .map(|((a, b), &ang)| if ang { wrap(a + b) } else { a + b })
        .collect()
}

impl NkModel {
    /// T(Q): angles as (sin, cos), other coordinates as they are.
    pub fn encode_joints(q: &[f64], is_angle: &[bool]) -> Vec<f64> {
        let mut out = Vec::with_capacity(2 * q.len());
        for (v, &a) in q.iter().zip(is_angle) {
            if a {
                out.push(v.sin());
                out.push(v.cos());
            } else {
                out.push(*v);
            }
        }
        out
    }

    fn correction_flags(&self) -> &[bool] {
        if self.scheme.corrects_joints() {
            &self.joint_angle
        } else {
            &self.pose_angle
        }
    }

    fn encode_correction(d: &[f64], is_angle: &[bool], sum: AngularSum) -> Vec<f64> {
        match sum {
            AngularSum::Plain => d.to_vec(),
            AngularSum::Trig => Self::encode_joints(d, is_angle),
        }
    }

    fn decode_correction(y: &[f64], is_angle: &[bool], sum: AngularSum) -> Vec<f64> {
        match sum {
            AngularSum::Plain => y.to_vec(),
            AngularSum::Trig => decode_trig(y, is_angle),
        }
    }

    /// The correction the network gives for network-input joint values `q_in` (internal units).
    pub fn correction(&self, q_in: &[f64]) -> Vec<f64> {
        let x = self
            .input_scaler
            .apply(&Self::encode_joints(q_in, &self.joint_angle));
        let y = self.output_scaler.invert(&self.network.predict(&x));
        Self::decode_correction(&y, self.correction_flags(), self.angular_sum)
    }

    /// Trains a model of `scheme` on measured pairs with the nominal kinematics `nominal`.
    pub fn train(
        nominal: &dyn Robot,
        data: &[Sample],
        scheme: Scheme,
        angular_sum: AngularSum,
        cfg: &TrainConfig,
    ) -> Result<(Self, TrainOutcome), NeuralError> {
        Self::train_observed(nominal, data, scheme, angular_sum, cfg, &mut |_, _| {})
    }

    /// [`NkModel::train`], calling `observe(epoch, model)` with the model as it stands after
    /// every epoch (for learning curves).
    pub fn train_observed(
        nominal: &dyn Robot,
        data: &[Sample],
        scheme: Scheme,
        angular_sum: AngularSum,
        cfg: &TrainConfig,
        observe: &mut dyn FnMut(usize, &NkModel),
    ) -> Result<(Self, TrainOutcome), NeuralError> {
        let (joint_angle, pose_angle) = angle_flags(nominal, data.len())?;
        let mut inputs = Vec::with_capacity(data.len());
        let mut targets = Vec::with_capacity(data.len());
        let flags = if scheme.corrects_joints() {
            &joint_angle
        } else {
            &pose_angle
        };
        for (index, smp) in data.iter().enumerate() {
            let kin = |source: KinematicsError| NeuralError::Kinematics { index, source };
            let (q_in, d) = match scheme {
                Scheme::Direct2 => {
                    let qs = nominal.inverse(&smp.s, &smp.q).map_err(kin)?;
                    let d = difference(&qs, &smp.q, |i| joint_angle[i]);
                    (smp.q.clone(), d)
                }
                Scheme::Direct4 => {
                    let s0 = nominal.forward(&smp.q).map_err(kin)?;
                    (smp.q.clone(), difference(&smp.s, &s0, |i| pose_angle[i]))
                }
                Scheme::Inverse2 => {
                    let qth = nominal.inverse(&smp.s, &smp.q).map_err(kin)?;
                    let d = difference(&smp.q, &qth, |i| joint_angle[i]);
                    (qth, d)
                }
                Scheme::Inverse4 => {
                    let qth = nominal.inverse(&smp.s, &smp.q).map_err(kin)?;
                    let s0 = nominal.forward(&smp.q).map_err(kin)?;
                    (qth, difference(&s0, &smp.s, |i| pose_angle[i]))
                }
            };
            inputs.push(Self::encode_joints(&q_in, &joint_angle));
            targets.push(Self::encode_correction(&d, flags, angular_sum));
        }
        let input_scaler = Scaler::fit(&inputs);
        let mut output_scaler = Scaler::fit(&targets);
        if angular_sum == AngularSum::Trig {
            share_sine_scale(&mut output_scaler, flags, 0);
        }
        let x = columns(
            &inputs
                .iter()
                .map(|r| input_scaler.apply(r))
                .collect::<Vec<_>>(),
        );
        let t = columns(
            &targets
                .iter()
                .map(|r| output_scaler.apply(r))
                .collect::<Vec<_>>(),
        );
        let mut model = Self {
            scheme,
            angular_sum,
            joint_angle,
            pose_angle,
            input_scaler,
            output_scaler,
            network: Network::new(x.nrows(), cfg.hidden, t.nrows(), cfg.seed),
        };
        let mut network = model.network.clone();
        let mut view = model.clone();
        let outcome = network.train_observed(&x, &t, cfg, &mut |epoch, net| {
            view.network.clone_from(net);
            observe(epoch, &view);
        });
        model.network = network;
        Ok((model, outcome))
    }

    /// The pose predicted for joint values `q` (direct schemes; an inverse scheme is inverted
    /// numerically around `q`).
    pub fn pose(&self, nominal: &dyn Robot, q: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        match self.scheme {
            Scheme::Direct2 => {
                let d = self.correction(q);
                nominal.forward(&sum_coords(q, &d, &self.joint_angle))
            }
            Scheme::Direct4 => {
                let d = self.correction(q);
                Ok(sum_coords(&nominal.forward(q)?, &d, &self.pose_angle))
            }
            Scheme::Inverse2 | Scheme::Inverse4 => {
                // S such that joints(S) = q, by Newton on S starting at K(q).
                let mut s = nominal.forward(q)?;
                for _ in 0..20 {
                    let qq = self.joints(nominal, &s, q)?;
                    let dq = difference(q, &qq, |i| self.joint_angle[i]);
                    let j = nominal.pose_jacobian(&qq)?;
                    let ds = j * nalgebra::DVector::from_vec(dq.clone());
                    s = sum_coords(&s, ds.as_slice(), &self.pose_angle);
                    if dq.iter().map(|v| v * v).sum::<f64>().sqrt() < 1e-12 {
                        break;
                    }
                }
                Ok(s)
            }
        }
    }

    /// The joint values predicted to reach pose `s` (inverse schemes; a direct scheme is inverted
    /// by Newton–Raphson). `guess` picks the branch.
    pub fn joints(
        &self,
        nominal: &dyn Robot,
        s: &[f64],
        guess: &[f64],
    ) -> Result<Vec<f64>, KinematicsError> {
        match self.scheme {
            Scheme::Inverse2 => {
                let qth = nominal.inverse(s, guess)?;
                let d = self.correction(&qth);
                Ok(sum_coords(&qth, &d, &self.joint_angle))
            }
            Scheme::Inverse4 => {
                let qth = nominal.inverse(s, guess)?;
                let d = self.correction(&qth);
                nominal.inverse(&sum_coords(s, &d, &self.pose_angle), &qth)
            }
            Scheme::Direct2 | Scheme::Direct4 => {
                let start = nominal.inverse(s, guess)?;
                let forward = |q: &[f64]| self.pose(nominal, q);
                let jacobian =
                    |q: &[f64]| numeric_pose_jacobian(&forward, q, &|i| nominal.joint_is_angle(i));
                newton_solve(
                    &forward,
                    &jacobian,
                    &|i| nominal.pose_is_angle(i),
                    s,
                    &start,
                    1e-9,
                    30,
                )
            }
        }
    }
}
