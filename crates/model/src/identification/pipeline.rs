//! Conventional calibration of a recording, end to end: the geometric fit at a level
//! ([`super::geometric`]), robust outlier removal that refits after each removal
//! ([`super::outliers`], each refit starting from the last: [`super::incremental`]), and the
//! fitted model's error on held-out recordings.
//!
//! Outliers are judged against the structure of the recording, not only against the geometry:
//! when the geometric judgement flags rows that are not gross beyond any structure (each more
//! than `GROSS_FACTOR` (3) times the largest residual of the rows kept), they are judged again
//! against a model of the recording's structure ([`IdentifyOptions::structure`]: the one the
//! diagnosis finds, geometry, named effects and discrepancy term), and only rows that fail
//! there are removed. A clean recording with structured residuals keeps every
//! row; a reflection or a touch on dirt, far beyond every other row, is removed without the
//! diagnosis's cost (seconds on thousands of rows, against milliseconds).
//!
//! Between the two stands a screen of a few fits' cost ([`super::screen`]): the flagged rows
//! judged against geometry, each joint's error as a spline of its own angle and a drift in
//! time, linearised and factored once. A row is removed there only when it fails against the
//! geometry and against that structure and stands out from its own neighbourhood as well
//! ([`super::screen::isolated`]); when no flagged row fails there every row is kept; when too
//! many fail nothing is removed and a warning says so. Only rows that fail beside neighbours
//! that fail too — local structure the screen lacks (a dent, a deformation of the workspace) —
//! go on to the diagnosis's judgement.
//!
//! The parameters returned are absolute (free frames included), for the rig's own chain, so a
//! model file written from them stands alone.

use super::checks::{check_fit, check_recording};
use super::geometric::{identify_at, IdentifyError, Level};
use super::incremental::GeometricRefits;
use super::outliers::{remove_outliers, Outlier, OutlierError, OutlierSettings};
use super::{errors, FitResult, ResidualStats};
use nalgebra::Vector3;
use rigcal_core::kinematics::{Robot, SerialChain, TransformId};
use rigcal_core::recording::{Observation, Recording};
use rigcal_core::rig::Rig;
use std::convert::Infallible;

/// A recording to check the fitted model on, with the name reports give it.
#[derive(Debug, Clone)]
pub struct HeldOut {
    /// What to call it (its path, say).
    pub name: String,
    /// The recording.
    pub recording: Recording,
}

/// A judgement of a recording's rows against a model of its structure beyond the geometry
/// (named effects, a discrepancy term): the rows that fail. The outer error says the recording
/// could not be modelled (the judgement then falls back to the geometric one), the inner one that
/// too many rows fail. The diagnosis layer provides one
/// (`diagnosis::outliers::outliers_against_structure`); identification itself knows no physics.
#[allow(clippy::type_complexity)]
pub type StructureJudge = fn(
    &Rig,
    &Recording,
    &OutlierSettings,
) -> Result<Result<Vec<Outlier>, OutlierError<Infallible>>, String>;

/// Settings of [`identify`].
#[derive(Debug, Clone, Default)]
pub struct IdentifyOptions {
    /// Recordings not fitted (another day's session, say) to report the model's error on.
    pub heldout: Vec<HeldOut>,
    /// The outlier search.
    pub outliers: OutlierSettings,
    /// Where the geometric judgement finds outliers that structure could explain, the rows are
    /// judged again against the recording's structure with this; `None`: the geometric
    /// judgement alone.
    pub structure: Option<StructureJudge>,
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

/// Identifies a rig's error parameters from a recording at a level: outliers are found
/// robustly and removed, each removal refitting the model without the row, and judged again
/// against the recording's structure when the geometry flags any; more than
/// [`OutlierSettings::max_fraction`] of the rows failing removes nothing and sets
/// [`Identification::outlier_warning`]. Then each held-out recording is checked.
///
/// Every recording is checked for absurd values first ([`check_recording`]) and the fit after
/// ([`check_fit`]): a diverged fit is an error, not an identification.
pub fn identify(
    rig: &Rig,
    rec: &Recording,
    level: Level,
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    check_recording(&rig.chain, rec).map_err(Box::new)?;
    for h in &opts.heldout {
        check_recording(&rig.chain, &h.recording).map_err(Box::new)?;
    }
    let (chain, fit, outliers, outlier_warning) =
        identify_robust(rig, rec, level, &opts.outliers, opts.structure)?;
    check_fit(rig, &chain, &fit)?;
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

/// The robust fit: (chain, fit, outliers removed, warning when there were too many to remove).
///
/// The geometric judgement decides alone when no row fails, when every row that fails is gross
/// beyond any structure ([`GROSS_FACTOR`]), or without a `structure` judge; otherwise the rows
/// are judged again against the recording's structure — the smooth-structure screen first,
/// the `structure` judge where the screen cannot decide ([`Screen`]) — and the fit at `level`
/// is redone without the rows that fail there, so that a clean recording whose residual is
/// structured — its largest rows are structure, not gross errors — keeps every row. When the
/// structure cannot be modelled (too few rows, say) the geometric judgement stands.
fn identify_robust(
    rig: &Rig,
    rec: &Recording,
    level: Level,
    settings: &OutlierSettings,
    structure: Option<StructureJudge>,
) -> Result<Robust, IdentifyError> {
    let obs = rec.observations();
    // The cheap refusals first, so they are not reported as failures of the outlier search.
    if obs.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    if level.candidates(rig).is_empty() {
        return Err(IdentifyError::NothingToFit { level });
    }
    let started = std::time::Instant::now();
    let ids = measured_ids(rec);
    let judged = geometric_judgement(rig, &obs, &ids, level, settings)?;
    tracing::debug!(
        seconds = started.elapsed().as_secs_f64(),
        failed = ?judged.search.as_ref().map(|(found, _)| found
            .iter()
            .map(|o| (o.seq, o.size_mm))
            .collect::<Vec<_>>()),
        "geometric outlier search"
    );
    if judged.decided_without_structure() {
        tracing::debug!(
            outliers = judged.search.as_ref().map_or(0, |(found, _)| found.len()),
            "outliers decided by the geometric judgement"
        );
    } else if let Some(judge) = structure {
        let started = std::time::Instant::now();
        let screened = judged.screened(rig, rec, &obs, &ids, settings);
        tracing::debug!(
            seconds = started.elapsed().as_secs_f64(),
            decided = screened.is_some(),
            "outliers screened against the smooth structure"
        );
        match screened {
            Some(Screen::AllRowsKept) => return judged.on_every_row(rig, &obs, level),
            Some(Screen::GeometricVerdict) => return judged.into_robust(rig, &obs, level),
            Some(Screen::Rows(found)) => {
                return without_rows_that_fail(rig, &obs, level, Ok(found))
            }
            Some(Screen::TooMany(warning)) => {
                let (chain, result, _, _) = judged.on_every_row(rig, &obs, level)?;
                return Ok((chain, result, Vec::new(), Some(warning)));
            }
            None => {}
        }
        let started = std::time::Instant::now();
        let verdict = judge(rig, rec, settings);
        tracing::debug!(
            seconds = started.elapsed().as_secs_f64(),
            "outliers judged against the structure"
        );
        match verdict {
            Ok(found) => return without_rows_that_fail(rig, &obs, level, found),
            Err(e) => tracing::debug!(%e, "outliers judged against the geometry only"),
        }
    }
    judged.into_robust(rig, &obs, level)
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
const GROSS_FACTOR: f64 = 3.0;

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

    /// The judgement as the robust fit: the last fit (on the rows kept) and the rows removed;
    /// when too many rows failed, the fit on every row, nothing removed and the warning. A fit
    /// the search did not make is made here.
    fn into_robust(
        self,
        rig: &Rig,
        obs: &[Observation],
        level: Level,
    ) -> Result<Robust, IdentifyError> {
        let fitted_or_all_rows = |fitted: Option<(SerialChain, FitResult)>| match fitted {
            Some(fitted) => Ok(fitted),
            None => identify_at(rig, obs, level),
        };
        match self.search {
            Ok((outliers, _)) => {
                let last = self.last.map(|(chain, result, _)| (chain, result));
                let (chain, result) = fitted_or_all_rows(last.or(self.first))?;
                Ok((chain, result, outliers, None))
            }
            Err(e @ OutlierError::TooMany { .. }) => {
                let (chain, result) = fitted_or_all_rows(self.first)?;
                Ok((chain, result, Vec::new(), Some(e.to_string())))
            }
            Err(OutlierError::Fit(e)) => Err(e),
        }
    }
}

/// What the smooth-structure screen ([`super::screen`]) decides about the rows the geometric
/// search flagged.
enum Screen {
    /// No flagged row fails against the smooth structure: they are structure, every row is
    /// kept.
    AllRowsKept,
    /// Every row the geometric search removed fails there too, each beyond its own
    /// neighbourhood: its verdict stands.
    GeometricVerdict,
    /// These rows fail against both (or against the structure, when the geometric search
    /// stopped at too many), each beyond its own neighbourhood: they are removed.
    Rows(Vec<Outlier>),
    /// Too many rows fail against the structure too: nothing is removed, and this says so.
    TooMany(String),
}

impl GeometricJudgement {
    /// The flagged rows judged against the smooth structure of [`super::screen`] (geometry,
    /// each joint's error in its own angle, a drift in time), linearised at the fit on every
    /// row: a few fits' cost. A row is an outlier when it fails against the geometry and
    /// against the structure: the structure explains rows, it accuses none the geometry
    /// clears. None when the screen cannot judge (too few rows for its columns) or cannot
    /// decide: a failing row's neighbours fail with it (local structure it lacks), or a flagged
    /// row it keeps is not predicted by its model fitted without that row
    /// ([`super::screen::Screened::keeps_unpredicted`]: the model bent to the row).
    fn screened(
        &self,
        rig: &Rig,
        rec: &Recording,
        obs: &[Observation],
        ids: &[(u64, Option<u64>)],
        settings: &OutlierSettings,
    ) -> Option<Screen> {
        let (chain, first) = self.first.as_ref()?;
        let candidates = Level::Full.candidates(rig);
        let times = super::screen::observation_times(rec);
        let screened = super::screen::screen(
            chain,
            &first.params,
            obs,
            &candidates,
            &times,
            ids,
            settings,
        )?;
        tracing::debug!(
            rank = screened.rank,
            failed = ?screened.search.as_ref().map(|(found, _)| found
                .iter()
                .map(|o| (o.seq, o.size_mm))
                .collect::<Vec<_>>()),
            "smooth-structure screen"
        );
        let cleared_unpredicted = self
            .flagged()
            .into_iter()
            .find(|&i| screened.keeps_unpredicted(i, settings.alpha));
        if let Some(i) = cleared_unpredicted {
            tracing::debug!(
                row = i,
                "a flagged row the screen keeps is not predicted without it: the diagnosis judges"
            );
            return None;
        }
        let (found, kept) = match screened.search {
            Ok(search) => search,
            Err(e) => return Some(Screen::TooMany(e.to_string())),
        };
        let both: Vec<Outlier> = match &self.search {
            Ok((geometric, _)) => found
                .into_iter()
                .filter(|o| geometric.iter().any(|g| g.index == o.index))
                .collect(),
            Err(_) => found,
        };
        if both.is_empty() {
            return Some(Screen::AllRowsKept);
        }
        let rows: Vec<usize> = both.iter().map(|o| o.index).collect();
        if !super::screen::isolated(
            obs,
            &screened.residuals,
            &kept,
            &rows,
            screened.rank,
            settings.alpha,
        ) {
            tracing::debug!("rows fail with their neighbourhood: the diagnosis judges them");
            return None;
        }
        Some(match &self.search {
            Ok((geometric, _)) if geometric.len() == both.len() => Screen::GeometricVerdict,
            _ => Screen::Rows(both),
        })
    }

    /// The rows the geometric search flagged (indices into the observations): those it removed,
    /// or, when it stopped at too many, as many rows as it had found, the largest against its
    /// last fit.
    fn flagged(&self) -> Vec<usize> {
        match &self.search {
            Ok((outliers, _)) => outliers.iter().map(|o| o.index).collect(),
            Err(OutlierError::TooMany { found, .. }) => {
                let Some((_, _, residuals)) = &self.last else {
                    return Vec::new();
                };
                let mut order: Vec<usize> = (0..residuals.len()).collect();
                order.sort_by(|&a, &b| residuals[b].norm().total_cmp(&residuals[a].norm()));
                order.truncate(*found);
                order
            }
            Err(OutlierError::Fit(_)) => Vec::new(),
        }
    }

    /// The fit on every row, nothing removed.
    fn on_every_row(
        self,
        rig: &Rig,
        obs: &[Observation],
        level: Level,
    ) -> Result<Robust, IdentifyError> {
        let (chain, result) = match self.first {
            Some(first) => first,
            None => identify_at(rig, obs, level)?,
        };
        Ok((chain, result, Vec::new(), None))
    }
}

/// Outliers judged against the geometric fit at `level`, each removal refitting without the row
/// (from the last fit, the removed rows downdated: [`GeometricRefits`]). `ids`: (seq, CSV line)
/// of each observation.
fn geometric_judgement(
    rig: &Rig,
    obs: &[Observation],
    ids: &[(u64, Option<u64>)],
    level: Level,
    settings: &OutlierSettings,
) -> Result<GeometricJudgement, IdentifyError> {
    let mut refits = GeometricRefits::new(rig, obs, level);
    let mut first = None;
    let mut last = None;
    let search = remove_outliers(ids, settings, |kept| {
        // The removed rows stay in the recording (joints, order), they are only not fitted.
        let (chain, result) = refits.fit(kept)?;
        let residuals = errors(&chain, obs, &result.params);
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

/// The fit at `level` without the rows that fail a structure judgement (`found`, indices into
/// `obs`); when too many failed there, nothing is removed and the warning says so.
fn without_rows_that_fail(
    rig: &Rig,
    obs: &[Observation],
    level: Level,
    found: Result<Vec<Outlier>, OutlierError<Infallible>>,
) -> Result<Robust, IdentifyError> {
    let (outliers, warning) = match found {
        Ok(found) => (found, None),
        Err(e) => (Vec::new(), Some(e.to_string())),
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
fn heldout_report(
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
