//! Effect-carrying models: joint-space physics a model file holds beside its geometry, so that
//! compensation can undo it (issue 18 item 5).
//!
//! Each effect is a joint error Δq_j = Σ_k c_k · b_k(q, s), linear in its coefficients c with
//! basis functions b of the commanded joints q and the approach directions s (the sign of each
//! joint's last change, −1/0/+1), the same physics as the simulated world; each basis is in its
//! effect's file ([`crate::effects`]):
//! - `backlash` (lost motion b): Δq_j = −s_j · b/2 ([`crate::effects::backlash`]);
//! - `transmission_error` (order n): Δq_j = A·sin(n·q_j + φ) = c_s·sin(n q_j) + c_c·cos(n q_j)
//!   ([`crate::effects::transmission`]);
//! - `joint_compliance` (compliance c, rad/(N·m)): Δq_j = c · τ_j(q), τ_j the gravity torque
//!   about joint j of the rig's link masses (rig file `mass_kg`/`com_mm`) plus a payload at the
//!   tool frame's origin ([`crate::effects::compliance`]).
//!
//! This file holds the model file's vocabulary of them ([`EffectSpec`], [`ModelEffect`]: a kind
//! a model file carries has its variant here) and the joint fit.
//!
//! [`fit_effects`] fits the named effects jointly with the geometric parameters (Gauss–Newton,
//! the geometry starting from a conventional fit), so the part of an effect the geometry can
//! absorb is shared out once, not counted twice. Units in files: degrees (mm for a prismatic
//! joint), deg/(N·m); radians inside.

use crate::effects::{backlash, compliance, transmission, EffectContext, EffectKind};
use crate::identification::identifiability::stacked_jacobian;
use crate::identification::{FitResult, Observation, ResidualStats};
use nalgebra::{DMatrix, DVector, Vector3};
use rigcal_core::kinematics::{ErrorParams, JointKind, Robot, SerialChain};
use rigcal_core::rig::LinkMass;
use serde::{Deserialize, Serialize};

/// Why effects could not be named or fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EffectError {
    /// A `KIND:INDEX` word that does not parse.
    #[error("effect `{word}`: {reason}")]
    Spec {
        /// The word as given.
        word: String,
        /// What is wrong and what is expected.
        reason: String,
    },
    /// Compliance needs the masses the joint carries.
    #[error("joint_compliance on joint {joint} needs the rig's link masses: give `mass_kg` and `com_mm` for every link from joint {joint} on in the rig file (`rig from-urdf` copies them from a URDF)")]
    NoMasses {
        /// Joint (1-based).
        joint: usize,
    },
    /// The recording cannot show the effect.
    #[error("{effect}: the recording cannot show it ({reason})")]
    NotVisible {
        /// The effect.
        effect: String,
        /// Why.
        reason: String,
    },
    /// The joint fit failed.
    #[error("fitting the effects: {0}")]
    Fit(String),
}

/// A named effect to fit: kind and joint (and order for a transmission error).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum EffectSpec {
    /// Lost motion of a joint (0-based).
    Backlash(usize),
    /// Cyclic error of a joint (0-based) and its order.
    TransmissionError(usize, u32),
    /// Gravity compliance of a joint (0-based).
    JointCompliance(usize),
}

/// The kinds [`EffectSpec::parse`] knows.
pub const SPEC_KINDS: &str = "backlash:J, transmission_error:J:ORDER, joint_compliance:J";

impl EffectSpec {
    /// Parses `backlash:2`, `transmission_error:1:2` (joint 1, order 2) or `joint_compliance:3`
    /// (joints 1-based) for a chain of `dof` joints.
    pub fn parse(word: &str, dof: usize) -> Result<Self, EffectError> {
        let bad = |reason: String| EffectError::Spec {
            word: word.to_string(),
            reason,
        };
        let parts: Vec<&str> = word.trim().split(':').collect();
        let number = |s: &str, what: &str| -> Result<usize, EffectError> {
            s.parse::<usize>()
                .map_err(|_| bad(format!("`{s}` is not a {what}")))
        };
        let joint = |s: &str| -> Result<usize, EffectError> {
            let j = number(s, "joint number")?;
            if j == 0 || j > dof {
                return Err(bad(format!("joint {j} is out of range 1..{dof}")));
            }
            Ok(j - 1)
        };
        let kind = parts.first().and_then(|k| EffectKind::from_name(k));
        match (kind, &parts[1..]) {
            (Some(EffectKind::Backlash), [j]) => Ok(Self::Backlash(joint(j)?)),
            (Some(EffectKind::JointCompliance), [j]) => Ok(Self::JointCompliance(joint(j)?)),
            (Some(EffectKind::TransmissionError), [j, n]) => {
                let n = number(n, "harmonic order")?;
                if n == 0 || n > 10_000 {
                    return Err(bad("the order is the cycles per revolution, ≥ 1".into()));
                }
                Ok(Self::TransmissionError(joint(j)?, n as u32))
            }
            (Some(EffectKind::TransmissionError), [_]) => Err(bad(
                "give the harmonic order too: transmission_error:JOINT:ORDER".into(),
            )),
            _ => Err(bad(format!("expected one of {SPEC_KINDS}"))),
        }
    }

    /// Its kind.
    pub fn kind(&self) -> EffectKind {
        match self {
            Self::Backlash(_) => EffectKind::Backlash,
            Self::TransmissionError(..) => EffectKind::TransmissionError,
            Self::JointCompliance(_) => EffectKind::JointCompliance,
        }
    }

    /// The joint (0-based).
    pub fn joint(&self) -> usize {
        match *self {
            Self::Backlash(j) | Self::TransmissionError(j, _) | Self::JointCompliance(j) => j,
        }
    }

    /// "backlash on joint 2".
    pub fn label(&self) -> String {
        match *self {
            Self::TransmissionError(j, n) => {
                format!("{} (order {n}) on joint {}", self.kind(), j + 1)
            }
            _ => format!("{} on joint {}", self.kind(), self.joint() + 1),
        }
    }

    /// Checks what the effect needs from the rig (compliance: the masses).
    pub fn check(&self, masses: &[Option<LinkMass>], dof: usize) -> Result<(), EffectError> {
        if let Self::JointCompliance(j) = *self {
            if !compliance::masses_cover(masses, j, dof) {
                return Err(EffectError::NoMasses { joint: j + 1 });
            }
        }
        Ok(())
    }

    /// The basis functions b_k(q, s) at commanded joints `q` and approach directions `dir`:
    /// Δq_joint = Σ c_k · b_k.
    pub fn basis(&self, ctx: &EffectContext<'_>, q: &[f64], dir: &[i8]) -> Vec<f64> {
        match *self {
            Self::Backlash(j) => backlash::basis(j, dir),
            Self::TransmissionError(j, n) => transmission::basis(n, q[j]),
            Self::JointCompliance(j) => vec![compliance::gravity_torque(ctx, q, j)],
        }
    }

    /// The model effect with coefficients `c` (internal units) and their covariance `cov`.
    pub fn effect(&self, chain: &SerialChain, c: &[f64], cov: &DMatrix<f64>) -> ModelEffect {
        let sd = |k: usize| cov[(k, k)].max(0.0).sqrt();
        let file = |j: usize, v: f64| chain.joints()[j].kind.to_file_units(v);
        match *self {
            Self::Backlash(j) => ModelEffect::Backlash {
                joint: j + 1,
                lost_motion_deg: file(j, c[0]),
                sigma_deg: Some(file(j, sd(0))),
            },
            Self::TransmissionError(j, order) => {
                let (a, sa) = transmission::amplitude_sigma(c, cov);
                ModelEffect::TransmissionError {
                    joint: j + 1,
                    order,
                    amplitude_deg: a.to_degrees(),
                    phase_deg: c[1].atan2(c[0]).to_degrees(),
                    sigma_deg: sa.is_finite().then(|| sa.to_degrees()),
                }
            }
            Self::JointCompliance(j) => ModelEffect::JointCompliance {
                joint: j + 1,
                deg_per_nm: c[0].to_degrees(),
                sigma_deg_per_nm: Some(sd(0).to_degrees()),
            },
        }
    }
}

/// An effect in a model file (section `effects`), file units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
#[non_exhaustive]
pub enum ModelEffect {
    /// Lost motion: the joint stops short by b/2 on the side it came from.
    Backlash {
        /// Joint (1-based).
        joint: usize,
        /// Lost motion b (deg; mm for a prismatic joint).
        lost_motion_deg: f64,
        /// Its standard deviation.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sigma_deg: Option<f64>,
    },
    /// Cyclic error A·sin(n·q + φ) of a revolute joint.
    TransmissionError {
        /// Joint (1-based).
        joint: usize,
        /// Cycles per revolution.
        order: u32,
        /// Amplitude A (deg).
        amplitude_deg: f64,
        /// Phase φ (deg).
        phase_deg: f64,
        /// Standard deviation of A (deg).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sigma_deg: Option<f64>,
    },
    /// Deflection c · τ(q) under the gravity torque of the rig's masses and the payload.
    JointCompliance {
        /// Joint (1-based).
        joint: usize,
        /// Compliance c (deg/(N·m)).
        deg_per_nm: f64,
        /// Its standard deviation.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sigma_deg_per_nm: Option<f64>,
    },
}

impl ModelEffect {
    /// What it is, with its joint: the spec it was fitted as.
    pub fn spec(&self) -> EffectSpec {
        match *self {
            Self::Backlash { joint, .. } => EffectSpec::Backlash(joint.saturating_sub(1)),
            Self::TransmissionError { joint, order, .. } => {
                EffectSpec::TransmissionError(joint.saturating_sub(1), order)
            }
            Self::JointCompliance { joint, .. } => {
                EffectSpec::JointCompliance(joint.saturating_sub(1))
            }
        }
    }

    /// The coefficients of [`EffectSpec::basis`] (internal units).
    pub fn coefficients(&self, chain: &SerialChain) -> Vec<f64> {
        let internal = |j: usize, v: f64| {
            chain
                .joints()
                .get(j.saturating_sub(1))
                .map_or(v.to_radians(), |s| s.kind.from_file_units(v))
        };
        match *self {
            Self::Backlash {
                joint,
                lost_motion_deg,
                ..
            } => vec![internal(joint, lost_motion_deg)],
            Self::TransmissionError {
                amplitude_deg,
                phase_deg,
                ..
            } => {
                let (a, p) = (amplitude_deg.to_radians(), phase_deg.to_radians());
                vec![a * p.cos(), a * p.sin()]
            }
            Self::JointCompliance { deg_per_nm, .. } => vec![deg_per_nm.to_radians()],
        }
    }

    /// One line for a terminal.
    pub fn text(&self) -> String {
        let pm = |s: &Option<f64>| s.map(|s| format!(" ± {s:.5}")).unwrap_or_default();
        match self {
            Self::Backlash {
                joint,
                lost_motion_deg,
                sigma_deg,
            } => format!(
                "backlash on joint {joint}: lost motion {lost_motion_deg:.5}{} deg",
                pm(sigma_deg)
            ),
            Self::TransmissionError {
                joint,
                order,
                amplitude_deg,
                phase_deg,
                sigma_deg,
            } => format!(
                "transmission_error (order {order}) on joint {joint}: amplitude {amplitude_deg:.5}{} deg, phase {phase_deg:.1} deg",
                pm(sigma_deg)
            ),
            Self::JointCompliance {
                joint,
                deg_per_nm,
                sigma_deg_per_nm,
            } => format!(
                "joint_compliance on joint {joint}: {deg_per_nm:.6}{} deg/(N·m)",
                pm(sigma_deg_per_nm)
            ),
        }
    }
}

/// The joint errors (rad or mm, added to the commanded joints) of `effects` at commanded joints
/// `q` approached from directions `dir`.
pub fn joint_offsets(
    effects: &[ModelEffect],
    ctx: &EffectContext<'_>,
    q: &[f64],
    dir: &[i8],
) -> Vec<f64> {
    let mut dq = vec![0.0; q.len()];
    for e in effects {
        let spec = e.spec();
        let j = spec.joint();
        if j >= dq.len() {
            continue;
        }
        let b = spec.basis(ctx, q, dir);
        dq[j] += b
            .iter()
            .zip(e.coefficients(ctx.chain))
            .map(|(b, c)| b * c)
            .sum::<f64>();
    }
    dq
}

/// One measurement for [`fit_effects`]: joints, measured point and approach directions.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectObservation {
    /// Commanded joints and the measured point.
    pub obs: Observation,
    /// Approach direction of each joint (−1, 0, +1).
    pub direction: Vec<i8>,
}

/// A joint fit of geometry and effects.
#[derive(Debug, Clone)]
pub struct EffectFit {
    /// The geometric fit, re-estimated beside the effects (`after`, σ and covariance of the
    /// geometric parameters from the joint fit).
    pub fit: FitResult,
    /// The effects at their fitted sizes.
    pub effects: Vec<ModelEffect>,
}

/// Gauss–Newton iterations of the joint fit (the effects are small: it converges in two or three).
const JOINT_FIT_ITERATIONS: usize = 6;

/// Fits `specs` jointly with the geometric parameters `start.free`, starting from the
/// conventional fit `start` on `chain` (no payload during the recording).
pub fn fit_effects(
    chain: &SerialChain,
    masses: &[Option<LinkMass>],
    start: &FitResult,
    data: &[EffectObservation],
    specs: &[EffectSpec],
) -> Result<EffectFit, EffectError> {
    let dof = chain.joints().len();
    for s in specs {
        s.check(masses, dof)?;
        visible(s, chain, data)?;
    }
    let free = &start.free;
    let widths: Vec<usize> = specs
        .iter()
        .map(|s| {
            let ctx = EffectContext {
                chain,
                e: &start.params,
                masses,
                payload_kg: 0.0,
            };
            s.basis(&ctx, &data[0].obs.q, &data[0].direction).len()
        })
        .collect();
    let k: usize = widths.iter().sum();
    let p = free.len() + k;
    let rows = 3 * data.len();
    if rows <= p {
        return Err(EffectError::Fit(format!(
            "{} measurements are too few for {p} unknowns",
            data.len()
        )));
    }
    let mut e = start.params.clone();
    let mut coef = vec![0.0; k];
    let mut cov = DMatrix::zeros(p, p);
    let mut sigma2 = 0.0;
    let mut residuals = Vec::new();
    for _ in 0..JOINT_FIT_ITERATIONS {
        let ctx = EffectContext {
            chain,
            e: &e,
            masses,
            payload_kg: 0.0,
        };
        let (a, r) = joint_system(&ctx, free, specs, &coef, data, p);
        let (step, c, s2) = solve_scaled(&a, &r)?;
        for (m, &i) in free.iter().enumerate() {
            e.set(i, e.get(i) + step[m]);
        }
        for (m, c) in coef.iter_mut().enumerate() {
            *c += step[free.len() + m];
        }
        cov = c;
        sigma2 = s2;
        if step.norm() < 1e-12 {
            break;
        }
    }
    let ctx = EffectContext {
        chain,
        e: &e,
        masses,
        payload_kg: 0.0,
    };
    let specs_effects = model_effects(chain, specs, &widths, &coef, &cov, free.len());
    for d in data {
        let dq = joint_offsets(&specs_effects, &ctx, &d.obs.q, &d.direction);
        let actual: Vec<f64> = d.obs.q.iter().zip(&dq).map(|(a, b)| a + b).collect();
        residuals.push(d.obs.p - chain.position(&actual, &e));
    }
    let mut fit = start.clone();
    fit.params = e;
    fit.sigma = (0..free.len())
        .map(|m| cov[(m, m)].max(0.0).sqrt())
        .collect();
    fit.covariance = cov.view((0, 0), (free.len(), free.len())).into_owned();
    fit.after = ResidualStats::of(&residuals);
    fit.sigma0_mm = sigma2.sqrt();
    fit.residuals = residuals;
    Ok(EffectFit {
        fit,
        effects: specs_effects,
    })
}

/// Fails when the recording cannot show `spec` (a joint that never moves, backlash approached
/// from one side only).
fn visible(
    spec: &EffectSpec,
    chain: &SerialChain,
    data: &[EffectObservation],
) -> Result<(), EffectError> {
    let j = spec.joint();
    let not = |reason: &str| EffectError::NotVisible {
        effect: spec.label(),
        reason: reason.into(),
    };
    let Some(first) = data.first() else {
        return Err(not("no measurements"));
    };
    if data
        .iter()
        .all(|d| (d.obs.q[j] - first.obs.q[j]).abs() < 1e-9)
    {
        return Err(not("the joint never moves"));
    }
    match spec {
        EffectSpec::Backlash(_) => {
            let up = data.iter().any(|d| d.direction[j] > 0);
            let down = data.iter().any(|d| d.direction[j] < 0);
            if !(up && down) {
                return Err(not("the joint is approached from one side only"));
            }
        }
        EffectSpec::TransmissionError(..) => {
            if chain.joints()[j].kind != JointKind::Revolute {
                return Err(not("a transmission error needs a revolute joint"));
            }
        }
        EffectSpec::JointCompliance(_) => {}
    }
    Ok(())
}

/// The linearised system at the current estimate: columns geometry then effects, rows
/// measured − modelled.
fn joint_system(
    ctx: &EffectContext<'_>,
    free: &[usize],
    specs: &[EffectSpec],
    coef: &[f64],
    data: &[EffectObservation],
    p: usize,
) -> (DMatrix<f64>, DVector<f64>) {
    let chain = ctx.chain;
    let n = data.len();
    let mut a = DMatrix::zeros(3 * n, p);
    let mut r = DVector::zeros(3 * n);
    for (i, d) in data.iter().enumerate() {
        let mut dq = vec![0.0; d.obs.q.len()];
        let mut col = free.len();
        let mut bases = Vec::new();
        for s in specs {
            let b = s.basis(ctx, &d.obs.q, &d.direction);
            dq[s.joint()] += b
                .iter()
                .zip(&coef[col - free.len()..])
                .map(|(b, c)| b * c)
                .sum::<f64>();
            col += b.len();
            bases.push(b);
        }
        let actual: Vec<f64> = d.obs.q.iter().zip(&dq).map(|(a, b)| a + b).collect();
        let g = stacked_jacobian(chain, ctx.e, std::slice::from_ref(&actual), free);
        let jj = chain.joint_jacobian(&actual, ctx.e);
        let res = d.obs.p - chain.position(&actual, ctx.e);
        for row in 0..3 {
            r[3 * i + row] = res[row];
            for c in 0..free.len() {
                a[(3 * i + row, c)] = g[(row, c)];
            }
            let mut c = free.len();
            for (s, b) in specs.iter().zip(&bases) {
                for bk in b {
                    a[(3 * i + row, c)] = bk * jj[(row, s.joint())];
                    c += 1;
                }
            }
        }
    }
    (a, r)
}

/// `a` with its columns scaled to unit norm (a zero column left as it is) and the scales: the
/// solution of the scaled system times the scales solves the original one. Fits of effects
/// beside the geometry mix mm/rad and mm per N·m columns; scaling keeps their SVD honest.
pub fn unit_columns(a: &DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    let scale: Vec<f64> = (0..a.ncols())
        .map(|c| {
            let n = a.column(c).norm();
            if n > 0.0 {
                1.0 / n
            } else {
                1.0
            }
        })
        .collect();
    let mut s = a.clone();
    for (c, f) in scale.iter().enumerate() {
        s.column_mut(c).scale_mut(*f);
    }
    (s, scale)
}

/// Least squares with unit-norm columns: the step, the covariance σ²(AᵀA)⁻¹ and σ².
fn solve_scaled(
    a: &DMatrix<f64>,
    r: &DVector<f64>,
) -> Result<(DVector<f64>, DMatrix<f64>, f64), EffectError> {
    let p = a.ncols();
    let (s, scale) = unit_columns(a);
    let svd = s.clone().svd(true, true);
    let step = svd
        .solve(r, 1e-12)
        .map_err(|e| EffectError::Fit(e.to_string()))?;
    let dof = (a.nrows() - p).max(1) as f64;
    let rss = (r - &s * &step).norm_squared();
    let sigma2 = rss / dof;
    let ata = s.transpose() * &s;
    let inv = ata
        .pseudo_inverse(1e-14)
        .map_err(|e| EffectError::Fit(e.to_string()))?;
    let cov = DMatrix::from_fn(p, p, |i, j| sigma2 * inv[(i, j)] * scale[i] * scale[j]);
    let step = DVector::from_fn(p, |i, _| step[i] * scale[i]);
    Ok((step, cov, sigma2))
}

fn model_effects(
    chain: &SerialChain,
    specs: &[EffectSpec],
    widths: &[usize],
    coef: &[f64],
    cov: &DMatrix<f64>,
    offset: usize,
) -> Vec<ModelEffect> {
    let mut at = 0;
    specs
        .iter()
        .zip(widths)
        .map(|(s, &w)| {
            let c = &coef[at..at + w];
            let sub = cov.view((offset + at, offset + at), (w, w)).into_owned();
            at += w;
            s.effect(chain, c, &sub)
        })
        .collect()
}

/// Measurements of a recording with their approach directions (each joint's sign of change
/// from the previous row, measured or not, carried over when unchanged — the world's motion
/// history), skipping rows whose `seq` is in `skip`.
pub fn effect_observations(
    rec: &rigcal_core::recording::Recording,
    skip: &[u64],
) -> Vec<EffectObservation> {
    use rigcal_core::recording::Status;
    let mut dir: Vec<i8> = Vec::new();
    let mut prev: Option<&[f64]> = None;
    let mut out = Vec::new();
    for row in &rec.rows {
        if dir.len() != row.q.len() {
            dir = vec![0; row.q.len()];
        }
        if let Some(p) = prev.filter(|p| p.len() == row.q.len()) {
            for (j, (a, b)) in row.q.iter().zip(p).enumerate() {
                if (a - b).abs() > 1e-9 {
                    dir[j] = if a > b { 1 } else { -1 };
                }
            }
        }
        prev = Some(&row.q);
        if let (Status::Ok, Some(p)) = (&row.status, row.position) {
            if !skip.contains(&row.seq) {
                out.push(EffectObservation {
                    obs: Observation {
                        q: row.q.clone(),
                        p,
                    },
                    direction: dir.clone(),
                });
            }
        }
    }
    out
}

/// The errors (measured − modelled, mm, world) of a recording's measured rows under the
/// geometry `e` of `chain` with `effects` applied at the commanded joints (approach directions
/// from row order, as [`effect_observations`] reads them; no payload): the held-out figure of a
/// model with effects, where the geometry's own figure leaves them out. Summarise with
/// [`ResidualStats::of`] for mean, RMS and max.
pub fn errors_with_effects(
    chain: &SerialChain,
    e: &ErrorParams,
    masses: &[Option<LinkMass>],
    effects: &[ModelEffect],
    rec: &rigcal_core::recording::Recording,
) -> Vec<Vector3<f64>> {
    let ctx = EffectContext {
        chain,
        e,
        masses,
        payload_kg: 0.0,
    };
    effect_observations(rec, &[])
        .iter()
        .map(|d| {
            let dq = joint_offsets(effects, &ctx, &d.obs.q, &d.direction);
            let actual: Vec<f64> = d.obs.q.iter().zip(&dq).map(|(a, b)| a + b).collect();
            d.obs.p - chain.position(&actual, e)
        })
        .collect()
}

/// Fits `specs` on a recording beside the geometry of an identification of it
/// ([`crate::identification::identify`]): the rows it removed as outliers stay out, every row
/// still sets the approach directions.
pub fn fit_recording_effects(
    rig: &rigcal_core::rig::Rig,
    rec: &rigcal_core::recording::Recording,
    id: &crate::identification::Identification,
    specs: &[EffectSpec],
) -> Result<EffectFit, EffectError> {
    let skip: Vec<u64> = id.outliers.iter().map(|o| o.seq).collect();
    let data = effect_observations(rec, &skip);
    fit_effects(&id.chain, &rig.masses_with_payload(), &id.fit, &data, specs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcal_core::kinematics::ErrorParams;

    #[test]
    fn specs_parse_with_one_based_joints_and_clear_errors() {
        assert_eq!(
            EffectSpec::parse("backlash:2", 5).unwrap(),
            EffectSpec::Backlash(1)
        );
        assert_eq!(
            EffectSpec::parse("transmission_error:1:3", 5).unwrap(),
            EffectSpec::TransmissionError(0, 3)
        );
        assert_eq!(
            EffectSpec::parse("joint_compliance:3", 5).unwrap(),
            EffectSpec::JointCompliance(2)
        );
        let e = EffectSpec::parse("backlash:7", 5).unwrap_err().to_string();
        assert!(e.contains("out of range 1..5"), "{e}");
        let e = EffectSpec::parse("transmission_error:1", 5)
            .unwrap_err()
            .to_string();
        assert!(e.contains("ORDER"), "{e}");
        let e = EffectSpec::parse("gear_wobble:1", 5)
            .unwrap_err()
            .to_string();
        assert!(e.contains(SPEC_KINDS), "{e}");
    }

    #[test]
    fn coefficients_round_trip_through_file_units() {
        let rig = rigcal_core::rig::Rig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2-ideal.toml"
        )))
        .unwrap();
        let chain = &rig.chain;
        let spec = EffectSpec::TransmissionError(0, 2);
        let c = [0.0001, -0.00005];
        let m = spec.effect(chain, &c, &DMatrix::zeros(2, 2));
        let back = m.coefficients(chain);
        assert!((back[0] - c[0]).abs() < 1e-15 && (back[1] - c[1]).abs() < 1e-15);
        let b = EffectSpec::Backlash(1).effect(chain, &[0.0002], &DMatrix::zeros(1, 1));
        assert!((b.coefficients(chain)[0] - 0.0002).abs() < 1e-15);
        // The world's backlash: actual = commanded − s·b/2.
        let ctx = EffectContext {
            chain,
            e: &ErrorParams::zeros(chain.layout()),
            masses: &rig.link_masses,
            payload_kg: 0.0,
        };
        let dq = joint_offsets(&[b], &ctx, &[0.0; 5], &[0, 1, 0, 0, 0]);
        assert!((dq[1] + 0.0001).abs() < 1e-15, "{dq:?}");
    }
}
