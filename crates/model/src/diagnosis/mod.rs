//! Diagnosis: what physics the nominal (geometric) model leaves out of a recording.
//!
//! Steps (issues 4/7 and 18, conventions §1 and §9), one module per stage, run in order by
//! [`pipeline::run`]:
//! 1. fit the standard model: the identifiable geometric parameters (the registration is part of
//!    them, so a registration offset is absorbed and never named);
//! 2. screen ([`screen`]): the standard model as the tests see it, the noise floor from pure
//!    error ([`noise`]) and the lack-of-fit F-test of the geometry; a mismatch remains when that
//!    test or the naming below finds one, Bonferroni corrected, α = 0.01 overall;
//! 3. locate it ([`report::locate`]): axis, joint ranges, correlation with joint angle, approach
//!    direction, time, table coordinate, gravity torque;
//! 4. name it ([`select`]): candidates from the library (one file per effect, in
//!    [`crate::effects`]) projected onto the
//!    orthogonal complement of the geometric Jacobian, and flexible *shape bases* ([`shapes`]:
//!    a joint's error along its own angle or another joint's, along its angle by approach
//!    direction, a Cartesian error along time or across the workspace) beside them; forward
//!    selection with partial F-tests takes whichever explains the residual best — a library
//!    effect the data show exactly wins, an unknown shape wins over the library terms that each
//!    soak up part of it — and drops the library terms a chosen shape makes redundant;
//! 5. refit with the chosen effects and shapes ([`refit`]) and report each effect ([`effects`]):
//!    RMS before/after on the fitted and held-out data ([`heldout`]), per effect the share the
//!    geometry absorbed and the held-out RMS with and without it;
//! 6. what is left ([`unnamed`]): the located shapes are reported as `unexplained`, each
//!    described by its shape ([`discrepancy`]: what it depends on, localised or periodic, where,
//!    its size ± σ), and fitted as a smooth *discrepancy term* whose held-out gain is reported
//!    apart from the named physics. Structure counts only when it is *sizeable*, at least
//!    [`select::SHAPE_MIN_SIZE`] of the noise floor: a large effect named right leaves a
//!    residual at the floor that a test over thousands of degrees of freedom may still find
//!    significant, and is not flagged;
//! 7. judge outliers against the final model ([`outliers`], with
//!    [`crate::identification::outliers`]), remove them and diagnose again without them, naming
//!    each with its seq, line and size. `identification::identify` judges rows against the same
//!    model ([`outliers::outliers_against_structure`]), so a structured residual keeps its rows.
//!
//! The discrepancy term is a regression spline (cubic B-splines on equal intervals of the
//! located variable; harmonics above the library's orders for periodic joint errors) or, over
//! the workspace, Gaussian radial functions, refined where a coarse fit found something.
//! Why: it is linear in its coefficients, so the same F-tests, sizes and σ's serve the library
//! and the shapes and the term is ordinary least squares (a Gaussian process would fit similar
//! curves at O(n³), with hyper-parameters to choose and a marginal likelihood that does not
//! compare with the library's tests); the splines' local support keeps a dent where it is; a
//! shape joins only when it lowers the leave-one-measurement-out error, so it cannot fit a few
//! gross rows or the noise of a small recording.
//!
//! The regression algebra the stages share is in [`linalg`], the distribution functions in
//! [`rigcal_core::stats`].
//!
//! Without enough repeated poses (tracker recordings of 40–60 postures) the noise floor is the
//! residual variance and every term is tested against it; the report says which method it used,
//! that approach directions came from row order, and that time effects were left out when the
//! recording has no `t_s`. A quantising instrument (the table rig's panel) adds its known cell
//! variance to the noise floor, the tests weight each axis by its variance, and the quantisation
//! sawtooth is projected out with the geometry ([`quantisation_nuisance`]).
//!
//! Conventions: residual r = measured − modelled (mm), 3 rows per measurement (x, y, z, world);
//! joint values in radians (mm for prismatic joints) inside; time in seconds; the "noise floor"
//! is the 3-D RMS of pure noise, √3·σ with σ the per-coordinate standard deviation, so it
//! compares with the RMS figures of [`ResidualStats`](crate::identification::ResidualStats).
//! The diagnosis reads the recording and the rig only, never a simulated world.

pub mod ambiguity;
pub mod crossval;
pub mod discrepancy;
pub mod effects;
pub mod heldout;
pub mod linalg;
pub mod noise;
pub mod outliers;
pub mod pipeline;
pub mod plots;
pub mod refit;
pub mod report;
pub mod screen;
pub mod select;
pub mod sessions;
pub mod shapes;
pub mod unnamed;

pub use crossval::HeldoutGain;
pub use report::{
    DiscrepancyModel, DiscrepancyReport, EffectReport, FitSummary, Mismatch, Region, Report,
    ShapeReport, WeakEffect, WhereReport,
};

use crate::identification::{fit_geometry, FitError, Level, Observation};
use nalgebra::DMatrix;
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};
use rigcal_core::recording::{Recording, Status};
use rigcal_core::rig::Rig;

/// Overall false-claim rate of the diagnosis.
pub const ALPHA: f64 = 0.01;
/// A candidate is numerically absorbed by the geometry below this visible fraction.
pub const MIN_VISIBLE: f64 = 1e-3;
/// Projected candidates correlating above this are reported as not separable.
pub const SEPARABLE_CORRELATION: f64 = 0.95;
/// Degrees of freedom of pure error needed to use it as the noise floor.
pub const MIN_PURE_ERROR_DOF: usize = 60;

/// Why a diagnosis failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiagnoseError {
    /// The recording has no measured rows.
    #[error("the recording has no measured rows (status ok with x_mm, y_mm, z_mm)")]
    NoMeasurements,
    /// The recording's joints do not match the rig.
    #[error("the recording has {got} joints but the rig has {expected}")]
    JointCount {
        /// Joints of the rig.
        expected: usize,
        /// Joints in the recording.
        got: usize,
    },
    /// A value read is not finite or beyond any measurement of the rig.
    #[error(transparent)]
    Absurd(#[from] Box<crate::identification::AbsurdValue>),
    /// The standard (geometric) fit failed.
    #[error("the geometric fit failed: {0}")]
    Fit(#[from] FitError),
    /// A plot could not be written.
    #[error("plot: {0}")]
    Plot(String),
    /// A held-out session could not be prepared (its bad rows, its frame refit).
    #[error("held-out session: {0}")]
    Session(Box<sessions::SessionError>),
    /// Too few measurements for the tests.
    #[error("{measurements} measurements give {equations} equations for {unknowns} unknowns: the diagnosis needs at least {needed} equations ({} residual degrees of freedom for its tests)", screen::MIN_RESIDUAL_DOF)]
    TooFew {
        /// Measurements.
        measurements: usize,
        /// Scalar equations (3 per measurement).
        equations: usize,
        /// Unknowns of the largest model.
        unknowns: usize,
        /// Equations needed.
        needed: usize,
    },
}

pub use crate::effects::{Candidate, Data, Index, Param, AXES};

/// The candidate library for a joint count: every kind on every joint or axis (compliance with
/// the generic unit-mass model).
pub fn library(dof: usize) -> Vec<Box<dyn Candidate>> {
    library_with_masses(dof, None)
}

/// The candidate library for a rig: compliance uses the rig's link masses where it states them,
/// with the payload it carried while recorded ([`Rig::masses_with_payload`]).
pub fn library_for(rig: &Rig) -> Vec<Box<dyn Candidate>> {
    let link_masses = rig.masses_with_payload();
    let masses = link_masses
        .iter()
        .any(Option::is_some)
        .then(|| std::sync::Arc::new(link_masses));
    library_with_masses(rig.chain.joints().len(), masses)
}

fn library_with_masses(
    dof: usize,
    masses: Option<std::sync::Arc<Vec<Option<rigcal_core::rig::LinkMass>>>>,
) -> Vec<Box<dyn Candidate>> {
    crate::effects::candidates(dof, &masses)
}

/// Options of a diagnosis.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// Held-out recordings; without them a split of whole time blocks is held out.
    pub heldout: Vec<Recording>,
    /// Held-out sessions not registered to the recording (the instrument's frame moved): each
    /// effect's gain on them, their frame refitted, joins the held-out judgement
    /// ([`crossval`]): an effect that raises their RMS is not claimed.
    pub sessions: Vec<crate::identification::HeldOut>,
    /// What is refitted on each held-out session.
    pub per_session: sessions::PerSession,
}

/// The standard model of a recording: the measurements, chain, fitted geometry and residuals.
#[derive(Debug, Clone)]
pub struct Standard {
    /// The data for candidates.
    pub data: Data,
    /// Layout indices of the fitted geometric parameters.
    pub free: Vec<usize>,
    /// Residuals after the geometric fit, stacked (3 per measurement, mm).
    pub residual: nalgebra::DVector<f64>,
    /// The geometric Jacobian at the fit (3 per measurement × fitted parameters).
    pub jacobian: DMatrix<f64>,
    /// Known variance the instrument adds per world coordinate (mm²) beyond what repeated
    /// poses show: the panel's quantisation, uniform over one count, w²/12 per axis.
    pub instrument_var: [f64; 3],
    /// How `instrument_var` was found, when it is not zero.
    pub instrument_note: Option<String>,
    /// Nuisance columns of the instrument (3 per measurement × k), projected out with the
    /// geometry before any candidate is tested: see [`quantisation_nuisance`].
    pub nuisance: DMatrix<f64>,
}

/// Harmonics of the panel's quantisation error modelled as nuisance.
const QUANTISATION_HARMONICS: usize = 3;

/// The panel's quantisation error as nuisance columns. A panel count rounds the pin's true
/// offset u from the panel centre to its cell's centre, so the error is a sawtooth of u with the
/// cell width w as period. The table goes to the *nominal* tip, so u is the arm's error there —
/// a smooth function of the pose — and the sawtooth of a smooth function is itself structured:
/// smooth candidates and the shape bases would pick up part of it. The columns are
/// sin(2πk·û/w) and cos(2πk·û/w), k = 1..3 (`QUANTISATION_HARMONICS`), on the x and the y rows,
/// û the offset the fitted model predicts (modelled tip − panel centre, the panel centre being
/// the table-frame point minus the reported (u, v)). Empty when the recording is not quantised
/// or lacks the table and panel columns.
pub fn quantisation_nuisance(rig: &Rig, rec: &Recording, data: &Data) -> DMatrix<f64> {
    let n = data.len();
    let empty = DMatrix::zeros(3 * n, 0);
    let rigcal_core::rig::Instrument::TablePanel(tp) = &rig.instrument else {
        return empty;
    };
    let uv: Vec<Option<[f64; 2]>> = rec
        .rows
        .iter()
        .filter(|r| r.status == Status::Ok && r.position.is_some())
        .map(|r| r.panel_uv)
        .collect();
    let (Some(table), true) = (&data.table, uv.len() == n && uv.iter().all(Option::is_some)) else {
        return empty;
    };
    let cell = [
        tp.panel_size_mm[0] / f64::from(tp.panel_counts[0].max(1)),
        tp.panel_size_mm[1] / f64::from(tp.panel_counts[1].max(1)),
    ];
    let k = QUANTISATION_HARMONICS;
    let mut m = DMatrix::zeros(3 * n, 4 * k);
    for i in 0..n {
        let Some(p) = uv[i] else { continue };
        let model = data.chain.position(&data.obs[i].q, &data.e) - tp.table_to_world_mm;
        for a in 0..2 {
            let centre = table[i][a] - p[a];
            let u = model[a] - centre;
            for h in 0..k {
                let x = 2.0 * std::f64::consts::PI * (h + 1) as f64 * u / cell[a];
                m[(3 * i + a, 2 * k * a + 2 * h)] = x.sin();
                m[(3 * i + a, 2 * k * a + 2 * h + 1)] = x.cos();
            }
        }
    }
    m
}

/// The instrument's quantisation variance per world coordinate (mm²): a table_panel rig whose
/// recorded panel offsets lie on the count grid (cell centres, conventions §8) reads x and y to
/// a cell of W/Nx × H/Ny mm, an error uniform over the cell, variance w²/12. The grid is checked
/// on the data so a simulation with quantisation switched off is not penalised; without panel
/// columns the rig's panel is assumed to quantise. Table axes are parallel to the world axes
/// (the registration is a translation, `rigs/rv-m2.toml`).
fn quantisation_variance(rig: &Rig, rec: &Recording) -> ([f64; 3], Option<String>) {
    let rigcal_core::rig::Instrument::TablePanel(tp) = &rig.instrument else {
        return ([0.0; 3], None);
    };
    let cell = [
        tp.panel_size_mm[0] / f64::from(tp.panel_counts[0].max(1)),
        tp.panel_size_mm[1] / f64::from(tp.panel_counts[1].max(1)),
    ];
    let on_grid = |v: f64, a: usize| {
        let c = (v + tp.panel_size_mm[a] / 2.0) / cell[a] - 0.5;
        (c - c.round()).abs() * cell[a] < 2e-3
    };
    let uv: Vec<[f64; 2]> = rec
        .rows
        .iter()
        .filter(|r| r.status == Status::Ok)
        .filter_map(|r| r.panel_uv)
        .collect();
    let quantised = uv.is_empty() || uv.iter().all(|p| on_grid(p[0], 0) && on_grid(p[1], 1));
    if !quantised {
        return ([0.0; 3], None);
    }
    let var = [cell[0].powi(2) / 12.0, cell[1].powi(2) / 12.0, 0.0];
    let how = if uv.is_empty() {
        "the rig's panel (no panel columns in the recording)"
    } else {
        "the panel readings, which lie on its count grid"
    };
    (
        var,
        Some(format!(
            "the noise floor includes the panel's quantisation ({:.3} × {:.3} mm cells, σ {:.3} / {:.3} mm in x / y, from {how}): it repeats at repeated poses, so their pure error cannot show it",
            cell[0],
            cell[1],
            var[0].sqrt(),
            var[1].sqrt()
        )),
    )
}

/// Measurement data of a recording with the chain and geometry given (no fit).
pub fn prepare(
    chain: &SerialChain,
    e: &ErrorParams,
    rec: &Recording,
) -> Result<Data, DiagnoseError> {
    let n = chain.joints().len();
    let mut dir = vec![0i8; n];
    let mut prev: Option<&[f64]> = None;
    let mut obs = Vec::new();
    let mut times = Vec::new();
    let mut direction = Vec::new();
    let mut table = Vec::new();
    let mut region = Vec::new();
    let mut seq = Vec::new();
    let mut line = Vec::new();
    for (k, row) in rec.rows.iter().enumerate() {
        if row.q.len() != n {
            return Err(DiagnoseError::JointCount {
                expected: n,
                got: row.q.len(),
            });
        }
        if let Some(p) = prev {
            for j in 0..n {
                let d = row.q[j] - p[j];
                if d > 0.0 {
                    dir[j] = 1;
                } else if d < 0.0 {
                    dir[j] = -1;
                }
            }
        }
        prev = Some(&row.q);
        let (Status::Ok, Some(p)) = (&row.status, row.position) else {
            continue;
        };
        obs.push(Observation {
            q: row.q.clone(),
            p,
        });
        times.push(row.t_s);
        direction.push(dir.clone());
        table.push(row.table);
        region.push(row.region.clone());
        seq.push(row.seq);
        line.push(rec.lines.get(k).copied());
    }
    if obs.is_empty() {
        return Err(DiagnoseError::NoMeasurements);
    }
    let t_s = times.iter().copied().collect::<Option<Vec<f64>>>();
    let table = table.iter().copied().collect::<Option<Vec<_>>>();
    let joint_jacobian = obs.iter().map(|o| chain.joint_jacobian(&o.q, e)).collect();
    let moving = (0..n)
        .filter(|&j| {
            let (lo, hi) = obs.iter().fold((f64::MAX, f64::MIN), |(a, b), o| {
                (a.min(o.q[j]), b.max(o.q[j]))
            });
            hi - lo > 1e-9
        })
        .collect();
    Ok(Data {
        chain: chain.clone(),
        e: e.clone(),
        obs,
        t_s,
        direction,
        table,
        region,
        joint_jacobian,
        moving,
        seq,
        line,
    })
}

/// Fits the standard model: the identifiable geometric parameters (registration included), by
/// the geometric fit of `rigcal identify --level full`. The data, Jacobian and residuals are
/// those of the started chain (a free frame relative to its closed-form start).
pub fn standard_fit(rig: &Rig, rec: &Recording) -> Result<Standard, DiagnoseError> {
    // Absurd values first: an infinity in a matrix hangs the SVDs below.
    crate::identification::check_recording(&rig.chain, rec).map_err(Box::new)?;
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let pre = prepare(&rig.chain, &nominal, rec)?;
    let geometric = fit_geometry(rig, &pre.obs, &Level::Full.candidates(rig))?;
    let poses: Vec<Vec<f64>> = pre.obs.iter().map(|o| o.q.clone()).collect();
    let data = prepare(&geometric.started, &geometric.fit.params, rec)?;
    let jacobian = crate::identification::identifiability::stacked_jacobian(
        &geometric.started,
        &geometric.fit.params,
        &poses,
        geometric.basis(),
    );
    let residual = residual_of(&data);
    let (instrument_var, instrument_note) = quantisation_variance(rig, rec);
    let nuisance = if instrument_var.iter().any(|v| *v > 0.0) {
        quantisation_nuisance(rig, rec, &data)
    } else {
        DMatrix::zeros(3 * data.len(), 0)
    };
    Ok(Standard {
        nuisance,
        data,
        free: geometric.identifiability.basis,
        residual,
        jacobian,
        instrument_var,
        instrument_note,
    })
}

/// Stacked residuals (measured − modelled) of the data at its geometry.
pub fn residual_of(d: &Data) -> nalgebra::DVector<f64> {
    let mut r = nalgebra::DVector::zeros(3 * d.len());
    for (i, o) in d.obs.iter().enumerate() {
        let v = o.p - d.chain.position(&o.q, &d.e);
        for k in 0..3 {
            r[3 * i + k] = v[k];
        }
    }
    r
}

/// Rounds of "diagnose, then judge outliers, then diagnose again without them".
const OUTLIER_ROUNDS: usize = 3;

/// Diagnoses a recording: see the module documentation. Outliers are judged last, against the
/// geometry and the named effects; rows that fail are removed from the fit (kept for the
/// approach directions, as `via` rows are) and the diagnosis runs again without them, so a row
/// a diagnosed effect explains is never removed, and no removal is silent (the report lists
/// each with its seq, line and size).
pub fn diagnose(rig: &Rig, rec: &Recording, opts: &Options) -> Result<Report, DiagnoseError> {
    for h in &opts.heldout {
        crate::identification::check_recording(&rig.chain, h).map_err(Box::new)?;
    }
    let lib = library_for(rig);
    let clean_sessions = opts
        .sessions
        .iter()
        .map(|h| sessions::clean_session(rig, h))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| DiagnoseError::Session(Box::new(e)))?;
    let mut work = rec.clone();
    let mut removed: Vec<crate::identification::outliers::Outlier> = Vec::new();
    let measured: Vec<u64> = rec
        .rows
        .iter()
        .filter(|r| r.status == Status::Ok && r.position.is_some())
        .map(|r| r.seq)
        .collect();
    for round in 0..OUTLIER_ROUNDS {
        let std = standard_fit(rig, &work)?;
        let heldout = opts
            .heldout
            .iter()
            .map(|h| {
                let d = prepare(&std.data.chain, &std.data.e, h)?;
                let poses: Vec<Vec<f64>> = d.obs.iter().map(|o| o.q.clone()).collect();
                let g = crate::identification::identifiability::stacked_jacobian(
                    &d.chain, &d.e, &poses, &std.free,
                );
                let r = residual_of(&d);
                Ok((d, g, r))
            })
            .collect::<Result<Vec<_>, DiagnoseError>>()?;
        let sessions = clean_sessions
            .iter()
            .map(|c| {
                sessions::session_for_judgement(
                    &std.data.chain,
                    &std.data.e,
                    &std.free,
                    c,
                    opts.per_session,
                )
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| DiagnoseError::Session(Box::new(e)))?;
        let (mut report, found) = pipeline::run(&std, &lib, &heldout, &sessions)?;
        if found.is_empty() || round + 1 == OUTLIER_ROUNDS {
            if !found.is_empty() {
                report.notes.push(format!(
                    "{} more row(s) look like outliers after {OUTLIER_ROUNDS} rounds and were kept: {}",
                    found.len(),
                    found
                        .iter()
                        .map(|o| format!("seq {} ({:.3} mm)", o.seq, o.size_mm))
                        .collect::<Vec<_>>()
                        .join(", ")
                ));
            }
            report.outliers = removed;
            return Ok(report);
        }
        for mut o in found {
            for row in work.rows.iter_mut().filter(|r| r.seq == o.seq) {
                row.status = Status::Via;
            }
            o.index = measured.iter().position(|&s| s == o.seq).unwrap_or(o.index);
            removed.push(o);
        }
    }
    Err(DiagnoseError::NoMeasurements)
}
