//! `transmission_error`: cyclic gear error of one joint, periodic in its own angle:
//! Δq = Σ_k A_k · sin(n_k · q + φ_k). A harmonic of order n repeats every 360°/n.
//! Scenario units: degrees; radians inside.

use super::effect::{Effect, JointContext, ParseCtx};
use super::scenario::ScenarioError;
use serde::Deserialize;
use std::sync::Arc;

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

/// Cyclic error of one revolute joint.
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
    fn kind(&self) -> &'static str {
        "transmission_error"
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

/// Parses `kind = "transmission_error"`: `joint`, `harmonics = [{ order, amplitude_deg,
/// phase_deg }]`.
pub fn parse(ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, ScenarioError> {
    let raw: Raw = ctx.raw(t)?;
    let joint = ctx.joint(".joint", raw.joint)?;
    if rigcal_core::kinematics::Robot::joints(ctx.chain)[joint].kind
        != rigcal_core::kinematics::JointKind::Revolute
    {
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
