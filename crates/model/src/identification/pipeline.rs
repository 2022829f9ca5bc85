//! Conventional calibration of a recording, end to end: the geometric fit at a level
//! ([`super::geometric`]), robust outlier removal that refits after each removal
//! ([`super::outliers`], each refit starting from the last: [`super::incremental`]), and the
//! fitted model's error on held-out recordings.
//!
//! Outliers are judged against the structure of the recording, not only against the geometry:
//! when the geometric judgement flags rows that are not gross beyond any structure (each more
//! than [`GROSS_FACTOR`] times the largest residual of the rows kept), they are judged again
//! against the model the diagnosis finds (geometry, named effects, discrepancy term), and only
//! rows that fail there are removed. A clean recording with structured residuals keeps every
//! row; a reflection or a touch on dirt, far beyond every other row, is removed without the
//! diagnosis's cost (seconds on thousands of rows, against milliseconds).
//!
//! The parameters returned are absolute (free frames included), for the rig's own chain, so a
//! model file written from them stands alone.

use super::geometric::{fit_geometry, Level};
use super::incremental::GeometricRefits;
use super::outliers::{remove_outliers, Outlier, OutlierError, OutlierSettings};
use super::{errors, FitError, FitResult, ResidualStats};
use nalgebra::Vector3;
use rigcal_core::kinematics::{Robot, SerialChain, TransformId};
use rigcal_core::recording::{Observation, Recording};
use rigcal_core::rig::Rig;

/// A recording to check the fitted model on, with the name reports give it.
#[derive(Debug, Clone)]
pub struct HeldOut {
    /// What to call it (its path, say).
    pub name: String,
    /// The recording.
    pub recording: Recording,
}

/// Settings of [`identify`].
#[derive(Debug, Clone, Default)]
pub struct IdentifyOptions {
    /// Recordings not fitted (another day's session, say) to report the model's error on.
    pub heldout: Vec<HeldOut>,
    /// The outlier search.
    pub outliers: OutlierSettings,
}

/// The error of a fitted model on one held-out recording (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct HeldOutReport {
    /// The held-out recording's name.
    pub name: String,
    /// Its measured points.
    pub points: usize,
    /// With nominal kinematics: every parameter zero except the fitted measurement frame and
    /// marker, so it compares kinematics, not frames.
    pub nominal: ResidualStats,
    /// With the fitted model.
    pub fitted: ResidualStats,
}

/// The outcome of [`identify`].
#[derive(Debug, Clone)]
pub struct Identification {
    /// The rig's chain, which the parameters apply to.
    pub chain: SerialChain,
    /// The fit without the outliers, frame parameters absolute.
    pub fit: FitResult,
    /// The rows removed as outliers, in the order found.
    pub outliers: Vec<Outlier>,
    /// Set when more rows failed than the outlier search may remove: the data or the model are
    /// bad, nothing was removed, and this says so (for the user and the model file's notes).
    pub outlier_warning: Option<String>,
    /// One report per held-out recording, in the order given.
    pub heldout: Vec<HeldOutReport>,
}

/// Why an identification failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentifyError {
    /// The recording has no measured rows.
    #[error("the recording has no measured rows (status ok with x_mm, y_mm, z_mm)")]
    NoMeasurements,
    /// The level leaves no parameter to fit on this rig.
    #[error("nothing to fit at level {level:?}: the rig's measurement frame and marker are fixed (set them free in [calibration] or use --level full)")]
    NothingToFit {
        /// The level asked for.
        level: Level,
    },
    /// The least-squares fit failed.
    #[error("identification failed")]
    Fit(#[source] FitError),
    /// A held-out recording has no measured rows.
    #[error("held-out recording {name}: no measured rows")]
    HeldOutEmpty {
        /// Its name.
        name: String,
    },
}

/// Identifies a rig's error parameters from a recording at a level: outliers are found
/// robustly and removed, each removal refitting the model without the row, and judged again
/// against the recording's structure when the geometry flags any; more than
/// [`OutlierSettings::max_fraction`] of the rows failing removes nothing and sets
/// [`Identification::outlier_warning`]. Then each held-out recording is checked.
pub fn identify(
    rig: &Rig,
    rec: &Recording,
    level: Level,
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let (chain, fit, outliers, outlier_warning) = identify_robust(rig, rec, level, &opts.outliers)?;
    let heldout = opts
        .heldout
        .iter()
        .map(|h| heldout_report(&chain, &fit, h))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Identification {
        chain,
        fit,
        outliers,
        outlier_warning,
        heldout,
    })
}

/// Fits observations at a level: the rig's chain and the fit with absolute frame parameters.
pub fn identify_at(
    rig: &Rig,
    obs: &[Observation],
    level: Level,
) -> Result<(SerialChain, FitResult), IdentifyError> {
    if obs.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    let candidates = level.candidates(rig);
    if candidates.is_empty() {
        return Err(IdentifyError::NothingToFit { level });
    }
    let geometric = fit_geometry(rig, obs, &candidates).map_err(IdentifyError::Fit)?;
    Ok(geometric.into_absolute())
}

/// The robust fit: (chain, fit, outliers removed, warning when there were too many to remove).
fn identify_robust(
    rig: &Rig,
    rec: &Recording,
    level: Level,
    settings: &OutlierSettings,
) -> Result<Robust, IdentifyError> {
    let obs = rec.observations();
    // The cheap refusals first, so they are not reported as failures of the outlier search.
    if obs.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    if level.candidates(rig).is_empty() {
        return Err(IdentifyError::NothingToFit { level });
    }
    // The geometric judgement decides alone when no row fails, or when every row that fails is
    // gross beyond any structure ([`GROSS_FACTOR`]); otherwise the rows are judged
    // again against the recording's structure ([`judge_against_structure`]).
    let judged = geometric_judgement(rig, rec, level, settings)?;
    let decided = judged.decided_without_structure();
    let GeometricJudgement {
        search,
        first,
        last,
    } = judged;
    match search {
        Ok((outliers, _)) if decided => {
            tracing::debug!(
                outliers = outliers.len(),
                "outliers decided by the geometric judgement"
            );
            let (chain, result) = last_or_all_rows(last, first, rig, &obs, level)?;
            Ok((chain, result, outliers, None))
        }
        Ok(_) | Err(OutlierError::TooMany { .. }) => {
            judge_against_structure(rig, rec, level, settings)
        }
        Err(OutlierError::Fit(e)) => Err(e),
    }
}

/// The outcome of the robust fit: (chain, fit, outliers removed, warning when too many failed).
type Robust = (SerialChain, FitResult, Vec<Outlier>, Option<String>);

/// A row the geometric judgement removes is decided without the recording's structure when it
/// is off by more than this many times the largest residual of every row kept. Structure the
/// diagnosis models is shared by neighbouring poses (a library effect, a spline, a radial
/// function that must lower the leave-one-out error): it cannot put one row several times
/// beyond every other row of the recording, while a marker seen through a reflection can.
/// Rows that fail by less — the largest rows of a structured residual look like that — are
/// judged against the structure.
pub const GROSS_FACTOR: f64 = 3.0;

/// The outlier search against the geometric fit at a level, each removal refitting from the
/// last fit without the row ([`GeometricRefits`]).
struct GeometricJudgement {
    /// The search's outcome: the rows removed and the rows kept, or why it stopped.
    search: Result<(Vec<Outlier>, Vec<usize>), OutlierError<IdentifyError>>,
    /// The fit on every row (the search's first).
    first: Option<(SerialChain, FitResult)>,
    /// The search's last fit and every row's residual against it.
    last: Option<(SerialChain, FitResult, Vec<Vector3<f64>>)>,
}

impl GeometricJudgement {
    /// True when the search ended and no row failed, or every removed row is off by more than
    /// [`GROSS_FACTOR`] times the largest residual of the rows kept, against the last fit (the
    /// removed rows predicted by it).
    fn decided_without_structure(&self) -> bool {
        let (Ok((outliers, kept)), Some((_, _, residuals))) = (&self.search, &self.last) else {
            return matches!(&self.search, Ok((outliers, _)) if outliers.is_empty());
        };
        let largest_kept = kept
            .iter()
            .map(|&i| residuals[i].norm())
            .fold(0.0, f64::max);
        outliers
            .iter()
            .all(|o| o.size_mm > GROSS_FACTOR * largest_kept)
    }
}

/// The last fit (on the rows kept), or the fit on every row when the search fitted none.
fn last_or_all_rows(
    last: Option<(SerialChain, FitResult, Vec<Vector3<f64>>)>,
    first: Option<(SerialChain, FitResult)>,
    rig: &Rig,
    obs: &[Observation],
    level: Level,
) -> Result<(SerialChain, FitResult), IdentifyError> {
    match last {
        Some((chain, result, _)) => Ok((chain, result)),
        None => first_or_all_rows(first, rig, obs, level),
    }
}

/// The fit on every row: the search's first, or a fit when the search fitted none.
fn first_or_all_rows(
    first: Option<(SerialChain, FitResult)>,
    rig: &Rig,
    obs: &[Observation],
    level: Level,
) -> Result<(SerialChain, FitResult), IdentifyError> {
    match first {
        Some(fitted) => Ok(fitted),
        None => identify_at(rig, obs, level),
    }
}

/// Outliers judged against the geometric fit at `level`, each removal refitting without the row
/// (from the last fit, the removed rows downdated: [`GeometricRefits`]).
fn geometric_judgement(
    rig: &Rig,
    rec: &Recording,
    level: Level,
    settings: &OutlierSettings,
) -> Result<GeometricJudgement, IdentifyError> {
    let obs = rec.observations();
    let ids = measured_ids(rec);
    let mut refits = GeometricRefits::new(rig, &obs, level);
    let mut first = None;
    let mut last = None;
    let search = remove_outliers(&ids, settings, |kept| {
        // The removed rows stay in the recording (joints, order), they are only not fitted.
        let (chain, result) = refits.fit(kept)?;
        let residuals = errors(&chain, &obs, &result.params);
        let p = result.free.len();
        if first.is_none() {
            first = Some((chain.clone(), result.clone()));
        }
        last = Some((chain, result, residuals.clone()));
        Ok::<_, IdentifyError>((residuals, p))
    });
    if let Err(OutlierError::Fit(e)) = search {
        return Err(e);
    }
    Ok(GeometricJudgement {
        search,
        first,
        last,
    })
}

/// The rows judged against the structure the diagnosis finds in the recording (every
/// identifiable geometric parameter, the named effects and the discrepancy term:
/// [`crate::diagnosis::outliers::outliers_against_structure`]), so that a clean recording whose
/// residual is structured — its largest rows are structure, not gross errors — keeps every
/// row; the fit at `level` is redone without the rows that fail. When the diagnosis cannot
/// model the recording (too few rows, say) the judgement is the geometric one.
fn judge_against_structure(
    rig: &Rig,
    rec: &Recording,
    level: Level,
    settings: &OutlierSettings,
) -> Result<Robust, IdentifyError> {
    let obs = rec.observations();
    let (outliers, warning) =
        match crate::diagnosis::outliers::outliers_against_structure(rig, rec, settings) {
            Ok(Ok(found)) => (found, None),
            Ok(Err(e)) => (Vec::new(), Some(e.to_string())),
            Err(e) => {
                tracing::debug!(%e, "outliers judged against the geometry only");
                return geometric_only(rig, rec, level, settings);
            }
        };
    let kept: Vec<Observation> = obs
        .iter()
        .enumerate()
        .filter(|(i, _)| !outliers.iter().any(|o| o.index == *i))
        .map(|(_, o)| o.clone())
        .collect();
    let (chain, result) = identify_at(rig, &kept, level)?;
    Ok((chain, result, outliers, warning))
}

/// The geometric judgement alone: outliers against the geometric fit, each removal refitting
/// from the last fit without the row.
fn geometric_only(
    rig: &Rig,
    rec: &Recording,
    level: Level,
    settings: &OutlierSettings,
) -> Result<Robust, IdentifyError> {
    let obs = rec.observations();
    let GeometricJudgement {
        search,
        first,
        last,
    } = geometric_judgement(rig, rec, level, settings)?;
    match search {
        Ok((outliers, _)) => {
            let (chain, result) = last_or_all_rows(last, first, rig, &obs, level)?;
            Ok((chain, result, outliers, None))
        }
        Err(e @ OutlierError::TooMany { .. }) => {
            let warning = e.to_string();
            let (chain, result) = first_or_all_rows(first, rig, &obs, level)?;
            Ok((chain, result, Vec::new(), Some(warning)))
        }
        Err(OutlierError::Fit(e)) => Err(e),
    }
}

/// (seq, CSV line) of each measured row, in the order of [`Recording::observations`].
fn measured_ids(rec: &Recording) -> Vec<(u64, Option<u64>)> {
    rec.rows
        .iter()
        .enumerate()
        .filter(|(_, m)| m.status == rigcal_core::recording::Status::Ok && m.position.is_some())
        .map(|(k, m)| (m.seq, rec.lines.get(k).copied()))
        .collect()
}

/// The fitted model's error on a held-out recording, beside nominal kinematics seen through the
/// fitted frame and marker.
pub fn heldout_report(
    chain: &SerialChain,
    fit: &FitResult,
    held: &HeldOut,
) -> Result<HeldOutReport, IdentifyError> {
    let obs = held.recording.observations();
    if obs.is_empty() {
        return Err(IdentifyError::HeldOutEmpty {
            name: held.name.clone(),
        });
    }
    let mut nominal = fit.params.clone();
    for (k, id) in chain.layout().ids().iter().enumerate() {
        if !matches!(id.transform, TransformId::Frame | TransformId::Marker) {
            nominal.set(k, 0.0);
        }
    }
    Ok(HeldOutReport {
        name: held.name.clone(),
        points: obs.len(),
        nominal: ResidualStats::of(&errors(chain, &obs, &nominal)),
        fitted: ResidualStats::of(&errors(chain, &obs, &fit.params)),
    })
}
