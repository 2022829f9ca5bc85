//! `table_scale`: a table axis reads long or short in proportion to travel.
//!
//! - truth ([`TableScale`]): reading = true · (1 + s) on axis k, so true = reading / (1 + s);
//!   scenario entry `axis`, `scale_ppm` (table_panel rigs);
//! - diagnosis candidate: measured − true = s · (table reading along a) along a, s in ppm;
//!   column e_a · table_a · 1e-6 (mm per ppm). Needs the recording's `table_*_mm` columns.
//!
//! The twin does not write it into a scenario, nor a model file carry it.

use super::candidate::{Candidate, Data, Index, Param, AXES};
use super::entry::{EntryError, KindEntry, Masses, ParseCtx};
use super::kind::EffectKind;
use super::truth::{Effect, TableMap};
use nalgebra::{DMatrix, Matrix3};
use serde::Deserialize;
use std::sync::Arc;

/// A table axis reading long or short in proportion to travel (the truth).
#[derive(Debug, Clone, PartialEq)]
pub struct TableScale {
    /// The axis (0 x, 1 y, 2 z).
    pub axis: usize,
    /// s: reading = true · (1 + s).
    pub scale: f64,
}

impl Effect for TableScale {
    fn kind(&self) -> EffectKind {
        EffectKind::TableScale
    }

    fn distort_table(&self, map: &mut TableMap) {
        let mut d = Matrix3::identity();
        d[(self.axis, self.axis)] = 1.0 / (1.0 + self.scale);
        map.axes *= d;
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    axis: String,
    scale_ppm: f64,
}

/// The registry's entry of `table_scale`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `axis`, `scale_ppm`.
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        ctx.require_table()?;
        let raw: Raw = ctx.raw(t)?;
        let axis = ctx.axis(".axis", &raw.axis)?;
        let ppm = ctx.finite(".scale_ppm", raw.scale_ppm)?;
        if ppm.abs() >= 1e5 {
            return Err(ctx.invalid(".scale_ppm", "must be well under 100000 ppm"));
        }
        Ok(Arc::new(TableScale {
            axis,
            scale: ppm * 1e-6,
        }))
    }

    fn candidates(&self, on: Index, _masses: &Masses) -> Vec<Box<dyn Candidate>> {
        match on {
            Index::Axis(axis) => vec![Box::new(TableScaleCandidate { axis })],
            _ => Vec::new(),
        }
    }
}

/// The diagnosis candidate: scale error of one table axis.
#[derive(Debug, Clone, Copy)]
struct TableScaleCandidate {
    /// The axis (0 x, 1 y, 2 z).
    axis: usize,
}

impl Candidate for TableScaleCandidate {
    fn kind(&self) -> EffectKind {
        EffectKind::TableScale
    }

    fn index(&self) -> Index {
        Index::Axis(self.axis)
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        let t = d.table.as_ref()?;
        Some(d.axis_column(self.axis, |i| t[i][self.axis] * 1e-6))
    }

    fn explanation(&self) -> String {
        format!(
            "the table's {} axis reads long or short in proportion to its travel",
            AXES[self.axis]
        )
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, _d: &Data) -> Vec<Param> {
        vec![Param {
            name: "scale_ppm".into(),
            value: coef[0],
            sigma: cov[(0, 0)].max(0.0).sqrt(),
        }]
    }
}
