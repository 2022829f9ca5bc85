//! `table_squareness`: two table axes are not at right angles.
//!
//! - truth ([`TableSquareness`]): axis b leans towards axis a by γ (the angle between them is
//!   90° − γ): true = r_a·ê_a + r_b·(cos γ·ê_b + sin γ·ê_a); scenario entry `axes = ["x", "y"]`,
//!   `angle_deg` (table_panel rigs);
//! - diagnosis candidate: the true position moves along the first axis by γ · (reading along the
//!   second): measured − true = −γ · table_b along a. Column e_a · table_b · π/180 (mm per
//!   degree); coefficient −γ in degrees. The opposite lean (a towards b) differs from this one
//!   by a rotation, which the geometry absorbs.
//!
//! The twin does not write it into a scenario, nor a model file carry it. Degrees in files;
//! radians inside the truth.

use super::candidate::{Candidate, Data, Index, Param, AXES};
use super::entry::{EntryError, KindEntry, Masses, ParseCtx};
use super::kind::EffectKind;
use super::truth::{Effect, TableMap};
use nalgebra::{DMatrix, Matrix3};
use serde::Deserialize;
use std::sync::Arc;

/// Two table axes not at right angles (the truth).
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
    fn kind(&self) -> EffectKind {
        EffectKind::TableSquareness
    }

    fn distort_table(&self, map: &mut TableMap) {
        let mut s = Matrix3::identity();
        s[(self.second, self.second)] = self.angle.cos();
        s[(self.first, self.second)] = self.angle.sin();
        map.axes *= s;
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    axes: [String; 2],
    angle_deg: f64,
}

/// The registry's entry of `table_squareness`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `axes = ["x", "y"]`, `angle_deg`.
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        ctx.require_table()?;
        let raw: Raw = ctx.raw(t)?;
        let first = ctx.axis(".axes[0]", &raw.axes[0])?;
        let second = ctx.axis(".axes[1]", &raw.axes[1])?;
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

    fn candidates(&self, on: Index, _masses: &Masses) -> Vec<Box<dyn Candidate>> {
        match on {
            Index::Axes(first, second) => {
                vec![Box::new(TableSquarenessCandidate { first, second })]
            }
            _ => Vec::new(),
        }
    }
}

/// The diagnosis candidate: squareness error of a pair of table axes.
#[derive(Debug, Clone, Copy)]
struct TableSquarenessCandidate {
    /// First axis.
    first: usize,
    /// Second axis (the one that leans).
    second: usize,
}

impl Candidate for TableSquarenessCandidate {
    fn kind(&self) -> EffectKind {
        EffectKind::TableSquareness
    }

    fn index(&self) -> Index {
        Index::Axes(self.first, self.second)
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        let t = d.table.as_ref()?;
        Some(d.axis_column(self.first, |i| {
            t[i][self.second] * std::f64::consts::PI / 180.0
        }))
    }

    fn explanation(&self) -> String {
        format!(
            "the table's {} and {} axes are not at right angles",
            AXES[self.first], AXES[self.second]
        )
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, _d: &Data) -> Vec<Param> {
        vec![Param {
            name: "angle_deg".into(),
            value: -coef[0],
            sigma: cov[(0, 0)].max(0.0).sqrt(),
        }]
    }
}
