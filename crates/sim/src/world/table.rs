//! Table effects: `table_scale`, `table_squareness` and `registration_offset`. They change the
//! table's truth ([`TableMap`]): where the panel really is for a given reading.
//!
//! - scale on axis k: reading = true · (1 + s), so true = reading / (1 + s); files give `scale_ppm`.
//! - squareness of axes (a, b): axis b leans towards axis a by γ (the angle between them is
//!   90° − γ): true = r_a·ê_a + r_b·(cos γ·ê_b + sin γ·ê_a).
//! - registration offset: the true table-to-world transform is the nominal one followed by a
//!   small rigid transform of the world, world = R(rpy)·(nominal) + xyz. Conventions §1: this is
//!   absorbed by the base parameters and never diagnosable.
//!
//! Units: mm and degrees in files; radians inside.

use super::effect::{axis_index, Effect, ParseCtx, TableMap};
use super::scenario::ScenarioError;
use nalgebra::{Isometry3, Matrix3};
use serde::Deserialize;
use std::sync::Arc;

/// A table axis reading long or short in proportion to travel.
#[derive(Debug, Clone, PartialEq)]
pub struct TableScale {
    /// The axis (0 x, 1 y, 2 z).
    pub axis: usize,
    /// s: reading = true · (1 + s).
    pub scale: f64,
}

impl Effect for TableScale {
    fn kind(&self) -> &'static str {
        "table_scale"
    }

    fn distort_table(&self, map: &mut TableMap) {
        let mut d = Matrix3::identity();
        d[(self.axis, self.axis)] = 1.0 / (1.0 + self.scale);
        map.axes *= d;
    }
}

/// Two table axes not at right angles.
#[derive(Debug, Clone, PartialEq)]
pub struct TableSquareness {
    /// The reference axis a.
    pub first: usize,
    /// The axis b that leans towards a.
    pub second: usize,
    /// γ (rad): the angle between them is 90° − γ.
    pub angle: f64,
}

impl Effect for TableSquareness {
    fn kind(&self) -> &'static str {
        "table_squareness"
    }

    fn distort_table(&self, map: &mut TableMap) {
        let mut s = Matrix3::identity();
        s[(self.second, self.second)] = self.angle.cos();
        s[(self.first, self.second)] = self.angle.sin();
        map.axes *= s;
    }
}

/// The true table-to-world transform differs from the nominal.
#[derive(Debug, Clone, PartialEq)]
pub struct RegistrationOffset {
    /// The small rigid transform applied after the nominal one.
    pub offset: Isometry3<f64>,
}

impl Effect for RegistrationOffset {
    fn kind(&self) -> &'static str {
        "registration_offset"
    }

    fn distort_table(&self, map: &mut TableMap) {
        map.registration = self.offset * map.registration;
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScale {
    axis: String,
    scale_ppm: f64,
}

/// Parses `kind = "table_scale"`: `axis`, `scale_ppm`.
pub fn parse_scale(ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, ScenarioError> {
    ctx.require_table()?;
    let raw: RawScale = ctx.raw(t)?;
    let axis = axis_index(ctx, ".axis", &raw.axis)?;
    let ppm = ctx.finite(".scale_ppm", raw.scale_ppm)?;
    if ppm.abs() >= 1e5 {
        return Err(ctx.invalid(".scale_ppm", "must be well under 100000 ppm"));
    }
    Ok(Arc::new(TableScale {
        axis,
        scale: ppm * 1e-6,
    }))
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSquareness {
    axes: [String; 2],
    angle_deg: f64,
}

/// Parses `kind = "table_squareness"`: `axes = ["x", "y"]`, `angle_deg`.
pub fn parse_squareness(
    ctx: &ParseCtx<'_>,
    t: &toml::Table,
) -> Result<Arc<dyn Effect>, ScenarioError> {
    ctx.require_table()?;
    let raw: RawSquareness = ctx.raw(t)?;
    let first = axis_index(ctx, ".axes[0]", &raw.axes[0])?;
    let second = axis_index(ctx, ".axes[1]", &raw.axes[1])?;
    if first == second {
        return Err(ctx.invalid(".axes", "needs two different axes"));
    }
    let angle = ctx.finite(".angle_deg", raw.angle_deg)?;
    if angle.abs() >= 10.0 {
        return Err(ctx.invalid(".angle_deg", "must be a small angle (under 10°)"));
    }
    Ok(Arc::new(TableSquareness {
        first,
        second,
        angle: angle.to_radians(),
    }))
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRegistration {
    #[serde(default)]
    xyz_mm: [f64; 3],
    #[serde(default)]
    rpy_deg: [f64; 3],
}

/// Parses `kind = "registration_offset"`: `xyz_mm`, `rpy_deg` (R = Rz(yaw)·Ry(pitch)·Rx(roll)).
pub fn parse_registration_offset(
    ctx: &ParseCtx<'_>,
    t: &toml::Table,
) -> Result<Arc<dyn Effect>, ScenarioError> {
    ctx.require_table()?;
    let raw: RawRegistration = ctx.raw(t)?;
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
