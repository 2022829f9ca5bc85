//! Geometric errors of the truth: the `[geometric]` section of a scenario and seed 000's sizes.
//!
//! A scenario gives explicit values by parameter name (`theta0`, `a1`, `beta2`, … in mm or
//! degrees), or draws them at random on the identifiable parameters (found by the rank of the
//! identification Jacobian over random poses, conventions §4), or both: explicit values override
//! drawn ones. Radians inside.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};
use rigcal_core::rig::Rig;
use rigcal_model::effects::{setup_rng, EntryError};
use rigcal_model::identification::{analyse, candidate_order, random_poses, Identifiability};
use serde::Deserialize;
use std::collections::BTreeMap;

/// How drawn errors are distributed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub(crate) enum Distribution {
    /// ± the magnitude, sign drawn (seed 000's "0.4 mm or 0.05°").
    #[default]
    Signs,
    /// Uniform in ± the magnitude.
    Uniform,
}

/// `[geometric.random]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRandom {
    length_mm: f64,
    angle_deg: f64,
    #[serde(default)]
    distribution: Distribution,
}

/// `[geometric]`.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawGeometric {
    #[serde(default)]
    values: BTreeMap<String, f64>,
    random: Option<RawRandom>,
}

/// Seed 000's geometric errors: ±0.4 mm on every identifiable length and ±0.05° on every
/// identifiable angle, with signs drawn from `seed`.
pub fn paper_geometric_errors(
    chain: &SerialChain,
    ident: &Identifiability,
    seed: u64,
) -> ErrorParams {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut e = ErrorParams::zeros(chain.layout());
    for &i in &ident.basis {
        let kind = chain.layout().ids()[i].kind;
        let size = if kind.is_angle() {
            0.05f64.to_radians()
        } else {
            0.4
        };
        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        e.set(i, sign * size);
    }
    e
}

/// The identifiable parameters of a rig (layout indices, basis order), from 60 random poses.
pub fn identifiable(rig: &Rig) -> Vec<usize> {
    // Fixed poses: the basis does not depend on them, and a fixed draw keeps scenarios stable.
    let mut rng = ChaCha8Rng::seed_from_u64(0x05ee_d000);
    let poses = random_poses(rig.chain.joints(), rig.held(), 60, &mut rng);
    analyse(&rig.chain, &poses, &candidate_order(rig)).basis
}

/// Builds the true geometric errors from a scenario's `[geometric]` section.
pub(crate) fn build(raw: &RawGeometric, rig: &Rig, seed: u64) -> Result<ErrorParams, EntryError> {
    let invalid = |key: String, reason: String| EntryError { key, reason };
    let layout = rig.chain.layout();
    let mut e = ErrorParams::zeros(layout);
    if let Some(r) = &raw.random {
        for (key, v) in [("length_mm", r.length_mm), ("angle_deg", r.angle_deg)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(
                    format!("geometric.random.{key}"),
                    "must be zero or positive".into(),
                ));
            }
        }
        let mut rng = setup_rng(seed, usize::MAX);
        for i in identifiable(rig) {
            let kind = layout.ids()[i].kind;
            let size = if kind.is_angle() {
                r.angle_deg.to_radians()
            } else {
                r.length_mm
            };
            let v = match r.distribution {
                Distribution::Signs => {
                    if rng.random_bool(0.5) {
                        size
                    } else {
                        -size
                    }
                }
                Distribution::Uniform => size * rng.random_range(-1.0..=1.0),
            };
            e.set(i, v);
        }
    }
    for (name, v) in &raw.values {
        let key = format!("geometric.values.{name}");
        let Some(id) = layout.find(name) else {
            return Err(invalid(
                key,
                "not a parameter of this chain (names look like theta0, d1, a2, alpha3, beta2)"
                    .into(),
            ));
        };
        if !v.is_finite() {
            return Err(invalid(key, "must be a finite number".into()));
        }
        let Some(i) = layout.index_of(id) else {
            return Err(invalid(key, "not a parameter of this chain".into()));
        };
        e.set(i, id.kind.from_file_units(*v));
    }
    Ok(e)
}
