//! Stage 5, the outlier judgement: rows no model explains, judged last against the final linear
//! model (geometry and named effects) with [`crate::identification::outliers`], so a row a
//! named effect explains is never one. The caller removes the rows found and diagnoses again.
//!
//! Units: residuals in mm.

use super::linalg::{lstsq, rows_of, rows_of_vector};
use super::refit::Refit;
use super::Standard;
use crate::identification::outliers::{remove_outliers, Outlier, OutlierError, OutlierSettings};
use nalgebra::Vector3;
use std::convert::Infallible;

/// The rows that fail the outlier test against the refitted model `refit` (its design
/// refitted on the rows kept at each round of the search).
pub fn judge_outliers(
    std: &Standard,
    refit: &Refit,
) -> Result<Vec<Outlier>, OutlierError<Infallible>> {
    let d = &std.data;
    let a = &refit.design;
    let ids: Vec<(u64, Option<u64>)> = d.seq.iter().copied().zip(d.line.iter().copied()).collect();
    let (found, _) = remove_outliers(&ids, &OutlierSettings::default(), |kept| {
        let fit = lstsq(&rows_of(a, kept), &rows_of_vector(&std.residual, kept));
        let res = &std.residual - a * fit.solution;
        Ok::<_, Infallible>((
            (0..d.len())
                .map(|i| Vector3::new(res[3 * i], res[3 * i + 1], res[3 * i + 2]))
                .collect(),
            fit.rank,
        ))
    })?;
    Ok(found)
}
