//! `table_squareness`: two table axes are not at right angles.
//!
//! Model: the second axis leans towards the first by a small angle γ, so the true position moves
//! along the first axis by γ · (reading along the second): measured − true = −γ · table_b along
//! a. Column: e_a · table_b · π/180 (mm per degree); coefficient −γ in degrees. The opposite
//! lean (a towards b) differs from this one by a rotation, which the geometry absorbs.

use super::{Candidate, Data, Index, Param};
use nalgebra::DMatrix;

/// Squareness error of a pair of table axes.
#[derive(Debug, Clone, Copy)]
pub struct TableSquareness {
    /// First axis.
    pub first: usize,
    /// Second axis (the one that leans).
    pub second: usize,
}

impl Candidate for TableSquareness {
    fn kind(&self) -> &'static str {
        "table_squareness"
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
            super::AXES[self.first],
            super::AXES[self.second]
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
