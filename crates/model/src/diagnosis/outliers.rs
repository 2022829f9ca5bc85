//! Stage 5, the outlier judgement: rows no model explains, judged last against the final linear
//! model (geometry and named effects) with [`crate::identification::outliers`], so a row a
//! named effect explains is never one. The caller removes the rows found and diagnoses again.
//!
//! [`outliers_against_structure`] serves `identification::identify`: the same judgement against
//! the structure the diagnosis finds, for a recording whose geometric residual is structured.
//!
//! Units: residuals in mm.

use super::linalg::{hcat, lstsq, rows_of, rows_of_vector};
use super::refit::Refit;
use super::select::{select_terms, Selection};
use super::{Candidate, Data, Standard};
use crate::identification::outliers::{remove_outliers, Outlier, OutlierError, OutlierSettings};
use crate::identification::{IdentifyOptions, StructureJudge};
use nalgebra::DMatrix;
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

/// The columns of the final model of `std` (geometry, the chosen effects and shapes of `sel`,
/// the instrument's nuisance) rebuilt on the measurements of `d`, which share its chain and
/// geometry; zero where `d` cannot show a term.
fn design_on(
    rig: &rigcal_core::rig::Rig,
    rec: &rigcal_core::recording::Recording,
    std: &Standard,
    sel: &Selection,
    lib: &[Box<dyn Candidate>],
    d: &Data,
) -> DMatrix<f64> {
    let n = 3 * d.len();
    let poses: Vec<Vec<f64>> = d.obs.iter().map(|o| o.q.clone()).collect();
    let mut cols = vec![crate::identification::identifiability::stacked_jacobian(
        &d.chain, &d.e, &poses, &std.free,
    )];
    for c in &sel.chosen {
        cols.push(
            lib[c.cand]
                .regressors(d)
                .unwrap_or_else(|| DMatrix::zeros(n, c.x.ncols())),
        );
    }
    for s in &sel.shapes {
        cols.push(
            s.spec
                .columns(d)
                .unwrap_or_else(|| DMatrix::zeros(n, s.x.ncols())),
        );
    }
    if std.nuisance.ncols() > 0 {
        cols.push(super::quantisation_nuisance(rig, rec, d));
    }
    hcat(&cols, n)
}

/// Rounds of "find the structure, judge outliers against it, find it again without them".
const STRUCTURE_ROUNDS: usize = 2;

/// [`outliers_against_structure`] as identification's [`StructureJudge`] (the diagnosis's
/// failure to model the recording as text).
const STRUCTURE_JUDGE: StructureJudge =
    |rig, rec, settings| outliers_against_structure(rig, rec, settings).map_err(|e| e.to_string());

/// [`IdentifyOptions`] whose outliers are judged against the structure the diagnosis finds
/// where the geometric judgement alone cannot decide: what `rigcal identify` does.
pub fn identify_options() -> IdentifyOptions {
    IdentifyOptions {
        structure: Some(STRUCTURE_JUDGE),
        ..IdentifyOptions::default()
    }
}

/// Outliers of a recording judged against the structure the diagnosis finds in it — geometry
/// (every identifiable parameter), named effects and the discrepancy term — rather than against
/// a geometric fit that leaves that structure in the residual, where its largest rows look like
/// outliers. The structure is found on every measured row, the outliers judged against it, and
/// (when some were found) the structure found again without them and the judgement repeated
/// from all rows, so a gross row cannot shape the model it is judged by. Indices are among the
/// measured rows of `rec`, in order. The outer error: the diagnosis could not model the
/// recording; the inner one: too many rows fail.
#[allow(clippy::type_complexity)]
pub fn outliers_against_structure(
    rig: &rigcal_core::rig::Rig,
    rec: &rigcal_core::recording::Recording,
    settings: &OutlierSettings,
) -> Result<Result<Vec<Outlier>, OutlierError<Infallible>>, super::DiagnoseError> {
    let lib = super::library_for(rig);
    let mut set_aside: Vec<u64> = Vec::new();
    let mut last = Ok(Vec::new());
    for _ in 0..STRUCTURE_ROUNDS {
        let mut work = rec.clone();
        for row in work.rows.iter_mut().filter(|r| set_aside.contains(&r.seq)) {
            row.status = rigcal_core::recording::Status::Via;
        }
        let started = std::time::Instant::now();
        let std = super::standard_fit(rig, &work)?;
        let sel = select_terms(&std, &lib)?;
        tracing::debug!(seconds = started.elapsed().as_secs_f64(), "structure found");
        let started = std::time::Instant::now();
        // Judged on every measured row: the rows set aside to find the structure are back,
        // predicted by it.
        let all = super::prepare(&std.data.chain, &std.data.e, rec)?;
        let a = design_on(rig, rec, &std, &sel, &lib, &all);
        let r = super::residual_of(&all);
        let ids: Vec<(u64, Option<u64>)> = all
            .seq
            .iter()
            .copied()
            .zip(all.line.iter().copied())
            .collect();
        last = remove_outliers(&ids, settings, |kept| {
            let fit = lstsq(&rows_of(&a, kept), &rows_of_vector(&r, kept));
            let res = &r - &a * fit.solution;
            Ok::<_, Infallible>((
                (0..all.len())
                    .map(|i| Vector3::new(res[3 * i], res[3 * i + 1], res[3 * i + 2]))
                    .collect(),
                fit.rank,
            ))
        })
        .map(|(found, _)| found);
        tracing::debug!(
            seconds = started.elapsed().as_secs_f64(),
            columns = a.ncols(),
            "outliers judged against it"
        );
        let found: Vec<u64> = match &last {
            Ok(f) => f.iter().map(|o| o.seq).collect(),
            Err(_) => break,
        };
        if found.is_empty() || found == set_aside {
            break;
        }
        set_aside = found;
    }
    Ok(last)
}
