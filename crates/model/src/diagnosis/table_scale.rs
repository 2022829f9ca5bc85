//! `table_scale`: a table axis reads long or short in proportion to travel.
//!
//! Model: measured − true = s · (table reading along a) along a, s in ppm. Column:
//! e_a · table_a · 1e-6 (mm per ppm). Needs the recording's `table_*_mm` columns.

use super::{Candidate, Data, Index, Param};
use nalgebra::DMatrix;

/// Scale error of one table axis.
#[derive(Debug, Clone, Copy)]
pub struct TableScale {
    /// The axis (0 x, 1 y, 2 z).
    pub axis: usize,
}

impl Candidate for TableScale {
    fn kind(&self) -> &'static str {
        "table_scale"
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
            super::AXES[self.axis]
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
