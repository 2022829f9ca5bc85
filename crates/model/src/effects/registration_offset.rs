//! `registration_offset`: the true table-to-world transform is the nominal one followed by a
//! small rigid transform of the world, world = R(rpy)·(nominal) + xyz. Scenario entry `xyz_mm`,
//! `rpy_deg` (R = Rz(yaw)·Ry(pitch)·Rx(roll); table_panel rigs).
//!
//! Truth only: conventions §1, the base parameters absorb it, so the diagnosis never names it, a
//! model never carries it and the twin never writes it.

use super::entry::{EntryError, KindEntry, ParseCtx};
use super::kind::EffectKind;
use super::truth::{Effect, TableMap};
use nalgebra::Isometry3;
use serde::Deserialize;
use std::sync::Arc;

/// The true table-to-world transform differs from the nominal (the truth).
#[derive(Debug, Clone, PartialEq)]
pub struct RegistrationOffset {
    /// The small rigid transform applied after the nominal one.
    pub offset: Isometry3<f64>,
}

impl Effect for RegistrationOffset {
    fn kind(&self) -> EffectKind {
        EffectKind::RegistrationOffset
    }

    fn distort_table(&self, map: &mut TableMap) {
        map.registration = self.offset * map.registration;
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    #[serde(default)]
    xyz_mm: [f64; 3],
    #[serde(default)]
    rpy_deg: [f64; 3],
}

/// The registry's entry of `registration_offset`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `xyz_mm`, `rpy_deg`.
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        ctx.require_table()?;
        let raw: Raw = ctx.raw(t)?;
        for (k, v) in raw.xyz_mm.iter().enumerate() {
            ctx.finite(&format!(".xyz_mm[{k}]"), *v)?;
        }
        for (k, v) in raw.rpy_deg.iter().enumerate() {
            ctx.finite(&format!(".rpy_deg[{k}]"), *v)?;
        }
        Ok(Arc::new(RegistrationOffset {
            offset: rigcal_core::rig::pose_from_xyz_rpy(raw.xyz_mm, raw.rpy_deg),
        }))
    }
}
