//! `transmission_error`: cyclic gear error of one revolute joint, periodic in its own angle:
//! Δq = Σ_k A_k · sin(n_k · q + φ_k). A harmonic of order n repeats every 360°/n.
//!
//! - truth ([`TransmissionError`]) and scenario entry: `joint`, `harmonics = [{ order,
//!   amplitude_deg, phase_deg }]`;
//! - diagnosis candidate (one order, 1 to [`MAX_ORDER`]): Δq = A·sin(n·q + φ) = βs·sin(n q) +
//!   βc·cos(n q) with βs = A cos φ, βc = A sin φ; columns sin(n q_j)·J_j and cos(n q_j)·J_j (J_j
//!   the joint's column of the joint Jacobian, mm/rad), coefficients in rad; reported as
//!   amplitude and phase (degrees);
//! - model term: the same basis ([`basis`]), amplitude and its σ by [`amplitude_sigma`].
//!
//! Degrees in files; radians inside.

use super::candidate::{Candidate, Data, Index, Param};
use super::entry::{float, one_based, EntryError, KindEntry, Masses, NewEffect, ParseCtx};
use super::kind::EffectKind;
use super::truth::{Effect, JointContext};
use nalgebra::DMatrix;
use rigcal_core::kinematics::{JointKind, Robot};
use serde::Deserialize;
use std::sync::Arc;

/// Highest order in the diagnosis's library.
pub const MAX_ORDER: u32 = 4;

/// One harmonic of a transmission error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Harmonic {
    /// Cycles per revolution (≥ 1).
    pub order: u32,
    /// Amplitude (rad).
    pub amplitude: f64,
    /// Phase (rad).
    pub phase: f64,
}

/// Cyclic error of one revolute joint (the truth).
#[derive(Debug, Clone, PartialEq)]
pub struct TransmissionError {
    /// The joint (0-based).
    pub joint: usize,
    /// Its harmonics.
    pub harmonics: Vec<Harmonic>,
}

impl TransmissionError {
    /// The joint error (rad) at joint angle `q` (rad).
    pub fn error_at(&self, q: f64) -> f64 {
        self.harmonics
            .iter()
            .map(|h| h.amplitude * (f64::from(h.order) * q + h.phase).sin())
            .sum()
    }
}

impl Effect for TransmissionError {
    fn kind(&self) -> EffectKind {
        EffectKind::TransmissionError
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        dq[self.joint] += self.error_at(ctx.commanded[self.joint]);
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHarmonic {
    order: i64,
    amplitude_deg: f64,
    #[serde(default)]
    phase_deg: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    joint: i64,
    harmonics: Vec<RawHarmonic>,
}

/// The registry's entry of `transmission_error`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `joint`, `harmonics = [{ order, amplitude_deg, phase_deg }]`.
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        let raw: Raw = ctx.raw(t)?;
        let joint = ctx.joint(".joint", raw.joint)?;
        if Robot::joints(ctx.chain)[joint].kind != JointKind::Revolute {
            return Err(ctx.invalid(".joint", "a transmission error needs a revolute joint"));
        }
        if raw.harmonics.is_empty() {
            return Err(ctx.invalid(".harmonics", "needs at least one harmonic"));
        }
        let mut harmonics = Vec::new();
        for (k, h) in raw.harmonics.iter().enumerate() {
            let key = |f: &str| format!(".harmonics[{k}].{f}");
            if !(1..=10_000).contains(&h.order) {
                return Err(ctx.invalid(&key("order"), "must be a whole number of cycles ≥ 1"));
            }
            harmonics.push(Harmonic {
                order: h.order as u32,
                amplitude: ctx
                    .finite(&key("amplitude_deg"), h.amplitude_deg)?
                    .to_radians(),
                phase: ctx.finite(&key("phase_deg"), h.phase_deg)?.to_radians(),
            });
        }
        Ok(Arc::new(TransmissionError { joint, harmonics }))
    }

    fn candidates(&self, on: Index, _masses: &Masses) -> Vec<Box<dyn Candidate>> {
        match on {
            Index::Joint(joint) => (1..=MAX_ORDER)
                .map(|order| -> Box<dyn Candidate> {
                    Box::new(TransmissionCandidate { joint, order })
                })
                .collect(),
            _ => Vec::new(),
        }
    }
}

/// The scenario entry of harmonic `order` of joint `joint` (0-based) with fitted coefficients
/// `c` = (A cos φ, A sin φ) (rad).
pub fn scenario_entry(joint: usize, order: u32, c: &[f64]) -> NewEffect {
    let a = c[0].hypot(c[1]).to_degrees();
    let phase = c[1].atan2(c[0]).to_degrees();
    let mut h = toml::Table::new();
    h.insert("order".into(), toml::Value::Integer(i64::from(order)));
    h.insert("amplitude_deg".into(), float(a));
    h.insert("phase_deg".into(), float(phase));
    let mut t = toml::Table::new();
    t.insert("kind".into(), EffectKind::TransmissionError.name().into());
    t.insert("joint".into(), one_based(joint));
    t.insert(
        "harmonics".into(),
        toml::Value::Array(vec![toml::Value::Table(h)]),
    );
    NewEffect {
        table: t,
        summary: format!("order {order}, amplitude_deg = {a:.5}, phase_deg = {phase:.1}"),
    }
}

/// The model term's basis of order `order` at joint angle `q` (rad): (sin n q, cos n q).
pub fn basis(order: u32, q: f64) -> Vec<f64> {
    let x = f64::from(order) * q;
    vec![x.sin(), x.cos()]
}

/// The amplitude A = |(c_s, c_c)| (rad) of coefficients `c` and its σ along the fitted direction
/// (delta method) from their covariance `cov`; the σ is NaN at A = 0.
pub fn amplitude_sigma(c: &[f64], cov: &DMatrix<f64>) -> (f64, f64) {
    let a = c[0].hypot(c[1]);
    let sigma = if a > 0.0 {
        let g = [c[0] / a, c[1] / a];
        (g[0] * g[0] * cov[(0, 0)] + 2.0 * g[0] * g[1] * cov[(0, 1)] + g[1] * g[1] * cov[(1, 1)])
            .max(0.0)
            .sqrt()
    } else {
        f64::NAN
    };
    (a, sigma)
}

/// The diagnosis candidate: a cyclic error of one order on one joint.
#[derive(Debug, Clone, Copy)]
struct TransmissionCandidate {
    /// The joint (0-based).
    joint: usize,
    /// Cycles per 360°.
    order: u32,
}

impl Candidate for TransmissionCandidate {
    fn kind(&self) -> EffectKind {
        EffectKind::TransmissionError
    }

    fn index(&self) -> Index {
        Index::Joint(self.joint)
    }

    fn order(&self) -> Option<u32> {
        Some(self.order)
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        let j = self.joint;
        if !d.moving.contains(&j) || d.chain.joints()[j].kind != JointKind::Revolute {
            return None;
        }
        let n = f64::from(self.order);
        let s = d.joint_column(j, |i| (n * d.obs[i].q[j]).sin());
        let c = d.joint_column(j, |i| (n * d.obs[i].q[j]).cos());
        Some(DMatrix::from_columns(&[s.column(0), c.column(0)]))
    }

    fn explanation(&self) -> String {
        format!(
            "joint {}'s gearing has a cyclic error repeating {} time(s) per revolution",
            self.joint + 1,
            self.order
        )
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, _d: &Data) -> Vec<Param> {
        let (a, sa) = amplitude_sigma(coef, cov);
        vec![
            Param {
                name: "amplitude_deg".into(),
                value: a.to_degrees(),
                sigma: sa.to_degrees(),
            },
            Param {
                name: "phase_deg".into(),
                value: coef[1].atan2(coef[0]).to_degrees(),
                sigma: f64::NAN,
            },
            Param {
                name: "order".into(),
                value: f64::from(self.order),
                sigma: 0.0,
            },
        ]
    }
}
