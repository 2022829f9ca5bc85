//! `thermal_drift`: an error that grows as the machine warms, on a joint angle or on the pin tip
//! along a world axis. t is seconds since the session started.
//!
//! - truth ([`ThermalDrift`]) and scenario entry: A · (1 − exp(−t/τ)) ([`warm_up`]); `joint` +
//!   `amplitude_deg`, or `axis` + `amplitude_mm`; `tau_s`;
//! - diagnosis candidate: a smooth warm-up curve over the session, β1·u + β2·u² + β3·u³ with
//!   u = t / T (T the last measurement's time), on a joint angle (columns u·J_j, u²·J_j, u³·J_j;
//!   rad) or on the tip along a world axis (columns u·e_a, u²·e_a, u³·e_a; mm). A constant part
//!   is geometry. Reported: the drift over the whole session, β1 + β2 + β3 (degrees or mm).
//!
//! Why cubic: a warm-up A·(1 − e^(−t/τ)) over a session of 1.7 τ leaves 2.9 % of its visible
//! RMS to a quadratic and 0.3 % to a cubic. At ten times the noise floor the quadratic's
//! leftover (0.3 × the floor) reads as a shape outside the library; the cubic's does not.
//!
//! Radians and mm inside.

use super::candidate::{Candidate, Data, Index, Param, AXES};
use super::entry::{float, one_based, EntryError, KindEntry, Masses, NewEffect, ParseCtx};
use super::kind::EffectKind;
use super::truth::{Effect, JointContext};
use nalgebra::{DMatrix, Vector3};
use rigcal_core::kinematics::{Robot, SerialChain};
use serde::Deserialize;
use std::sync::Arc;

/// Where a drift acts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DriftTarget {
    /// A joint (0-based); amplitude in rad (mm for a prismatic joint).
    Joint(usize),
    /// A world axis (0 x, 1 y, 2 z); amplitude in mm.
    Axis(usize),
}

/// Warm-up drift (the truth).
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalDrift {
    /// What drifts.
    pub target: DriftTarget,
    /// Final size A (rad or mm).
    pub amplitude: f64,
    /// Time constant τ (s).
    pub tau_s: f64,
}

/// The share 1 − exp(−t/τ) of its final size a warm-up drift of time constant `tau_s` has
/// reached at `t_s` (s); zero before the session starts.
pub fn warm_up(t_s: f64, tau_s: f64) -> f64 {
    1.0 - (-t_s.max(0.0) / tau_s).exp()
}

impl ThermalDrift {
    /// The drift at time `t_s` (rad or mm); zero before the session starts.
    fn at(&self, t_s: f64) -> f64 {
        self.amplitude * warm_up(t_s, self.tau_s)
    }
}

impl Effect for ThermalDrift {
    fn kind(&self) -> EffectKind {
        EffectKind::ThermalDrift
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        if let DriftTarget::Joint(j) = self.target {
            dq[j] += self.at(ctx.t_s);
        }
    }

    fn tip_offset(&self, t_s: f64, _tip: &Vector3<f64>) -> Vector3<f64> {
        let mut v = Vector3::zeros();
        if let DriftTarget::Axis(k) = self.target {
            v[k] = self.at(t_s);
        }
        v
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    joint: Option<i64>,
    axis: Option<String>,
    amplitude_deg: Option<f64>,
    amplitude_mm: Option<f64>,
    tau_s: f64,
}

/// The registry's entry of `thermal_drift`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `joint` + `amplitude_deg`, or `axis` + `amplitude_mm`; `tau_s`.
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        let raw: Raw = ctx.raw(t)?;
        let tau_s = ctx.positive(".tau_s", raw.tau_s)?;
        let (target, amplitude) = match (raw.joint, &raw.axis, raw.amplitude_deg, raw.amplitude_mm)
        {
            (Some(j), None, Some(a), None) => {
                let j = ctx.joint(".joint", j)?;
                let kind = Robot::joints(ctx.chain)[j].kind;
                let a = kind.from_file_units(ctx.finite(".amplitude_deg", a)?);
                (DriftTarget::Joint(j), a)
            }
            (None, Some(axis), None, Some(a)) => (
                DriftTarget::Axis(ctx.axis(".axis", axis)?),
                ctx.finite(".amplitude_mm", a)?,
            ),
            _ => {
                return Err(ctx.invalid(
                    "",
                    "give `joint` with `amplitude_deg`, or `axis` with `amplitude_mm`",
                ))
            }
        };
        Ok(Arc::new(ThermalDrift {
            target,
            amplitude,
            tau_s,
        }))
    }

    fn candidates(&self, on: Index, _masses: &Masses) -> Vec<Box<dyn Candidate>> {
        match on {
            Index::Joint(_) | Index::Axis(_) => vec![Box::new(DriftCandidate { target: on })],
            Index::Axes(..) => Vec::new(),
        }
    }
}

/// The scenario entry of a fitted warm-up drift on `target` of final size `amplitude` (rad or
/// mm) and time constant `tau_s`; an error for an axis that does not exist.
pub fn scenario_entry(
    chain: &SerialChain,
    target: DriftTarget,
    amplitude: f64,
    tau_s: f64,
) -> Result<NewEffect, String> {
    let mut t = toml::Table::new();
    t.insert("kind".into(), EffectKind::ThermalDrift.name().into());
    let summary = match target {
        DriftTarget::Joint(j) => {
            let a = chain
                .joints()
                .get(j)
                .map_or(amplitude, |s| s.kind.to_file_units(amplitude));
            t.insert("joint".into(), one_based(j));
            t.insert("amplitude_deg".into(), float(a));
            format!("amplitude_deg = {a:.5}, tau_s = {tau_s:.0}")
        }
        DriftTarget::Axis(ax) => {
            let name = AXES.get(ax).ok_or_else(|| "no such axis".to_string())?;
            t.insert("axis".into(), (*name).into());
            t.insert("amplitude_mm".into(), float(amplitude));
            format!("amplitude_mm = {amplitude:.5}, tau_s = {tau_s:.0}")
        }
    };
    t.insert("tau_s".into(), float(tau_s));
    Ok(NewEffect { table: t, summary })
}

/// The diagnosis candidate: warm-up drift of a joint or along an axis.
#[derive(Debug, Clone, Copy)]
struct DriftCandidate {
    /// [`Index::Joint`] or [`Index::Axis`].
    target: Index,
}

fn normalised_time(d: &Data) -> Option<Vec<f64>> {
    let t = d.t_s.as_ref()?;
    let tmax = t.iter().copied().fold(0.0f64, f64::max);
    (tmax > 0.0).then(|| t.iter().map(|v| v / tmax).collect())
}

impl Candidate for DriftCandidate {
    fn kind(&self) -> EffectKind {
        EffectKind::ThermalDrift
    }

    fn index(&self) -> Index {
        self.target
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        let u = normalised_time(d)?;
        let cols = match self.target {
            Index::Joint(j) => {
                if !d.moving.contains(&j)
                    && d.joint_jacobian.iter().all(|m| m.column(j).norm() == 0.0)
                {
                    return None;
                }
                [1, 2, 3].map(|k| d.joint_column(j, |i| u[i].powi(k)))
            }
            Index::Axis(a) => [1, 2, 3].map(|k| d.axis_column(a, |i| u[i].powi(k))),
            Index::Axes(..) => return None,
        };
        Some(DMatrix::from_columns(&[
            cols[0].column(0),
            cols[1].column(0),
            cols[2].column(0),
        ]))
    }

    fn explanation(&self) -> String {
        match self.target {
            Index::Joint(j) => format!("joint {} drifts with time as the machine warms", j + 1),
            Index::Axis(a) => format!(
                "the tip drifts along world {} with time as the machine warms",
                AXES[a]
            ),
            Index::Axes(..) => String::new(),
        }
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, _d: &Data) -> Vec<Param> {
        let v: f64 = coef.iter().sum();
        // σ of the sum: 1ᵀ·Σ·1.
        let s = cov.iter().sum::<f64>().max(0.0).sqrt();
        match self.target {
            Index::Joint(_) => vec![Param {
                name: "drift_over_session_deg".into(),
                value: v.to_degrees(),
                sigma: s.to_degrees(),
            }],
            _ => vec![Param {
                name: "drift_over_session_mm".into(),
                value: v,
                sigma: s,
            }],
        }
    }
}
