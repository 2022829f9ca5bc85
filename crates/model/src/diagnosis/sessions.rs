//! Cross-session figures for sessions that are not registered to each other: motion-capture or
//! tracker sessions taken on different days, where the instrument's frame moved in between.
//!
//! A held-out session predicted through the training session's measurement frame measures the
//! frame shift as much as the kinematics. Here the kinematic parameters of a fit are kept and
//! only the measurement frame (and, if asked, the marker) is refitted on each held-out session
//! ([`heldout_sessions`]): what is left is what the kinematics predict.
//!
//! Training on several sessions ([`fit_sessions`]) fits one set of kinematic parameters and one
//! frame per session, by alternation: fit on the first session, refit each other session's frame
//! with those kinematics, map its points into the first session's frame, fit all of them
//! together, and repeat until the RMS settles. The marker is shared (the same rigid body on the
//! same tool: refitting it per training session would hide the tool's geometry from the fit).
//!
//! [`physics_heldout`] does the same with the effects a diagnosis named: the geometry and the
//! effects' coefficients are fitted on the training data, the effects' displacements predicted
//! on the held-out session, and only its frame refitted.
//!
//! Units: mm and rad inside; RMS figures are 3-D RMS in mm.

use crate::diagnosis::{self, Candidate, DiagnoseError, EffectReport, Index};
use crate::identification::outliers::Outlier;
use crate::identification::registration::kabsch;
use crate::identification::{
    errors, fit, identify, identify_at, FitError, FitOptions, FitResult, HeldOut, IdentifyError,
    Level, ResidualStats,
};
use nalgebra::{DMatrix, DVector, Isometry3, Vector3};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain, TransformId};
use rigcal_core::recording::{Observation, Recording, Status};
use rigcal_core::rig::Rig;

/// What is refitted on each held-out session, the kinematic parameters kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PerSession {
    /// The measurement frame (6 parameters).
    #[default]
    Frame,
    /// The measurement frame and the marker (9 parameters): for sessions where the marker or
    /// its rigid-body definition may have been re-made.
    FrameAndMarker,
}

impl PerSession {
    /// In words, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            PerSession::Frame => "measurement frame refitted per held-out session (6 parameters), kinematic parameters and marker kept",
            PerSession::FrameAndMarker => "measurement frame and marker refitted per held-out session (9 parameters), kinematic parameters kept",
        }
    }

    /// Layout indices of the parameters refitted.
    fn indices(self, chain: &SerialChain) -> Vec<usize> {
        chain
            .layout()
            .ids()
            .iter()
            .enumerate()
            .filter(|(_, id)| match id.transform {
                TransformId::Frame => true,
                TransformId::Marker => self == PerSession::FrameAndMarker,
                _ => false,
            })
            .map(|(i, _)| i)
            .collect()
    }
}

/// Why a cross-session figure failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SessionError {
    /// No training session was given.
    #[error("no training session given")]
    NoTraining,
    /// A session has no measured rows.
    #[error("session {name}: no measured rows")]
    Empty {
        /// The session's name.
        name: String,
    },
    /// Identification of a training session failed.
    #[error("identification failed")]
    Identify(#[from] IdentifyError),
    /// A frame refit failed.
    #[error("frame refit of session {name} failed")]
    Refit {
        /// The session's name.
        name: String,
        /// Why.
        #[source]
        source: FitError,
    },
    /// The diagnosis' standard fit failed.
    #[error("diagnosis")]
    Diagnose(#[from] DiagnoseError),
}

/// Refits the measurement frame (and the marker, per `per`) of `params` on observations, the
/// other parameters kept. The points are first brought near the model by a closed-form rigid
/// registration (Kabsch), so a session whose frame moved far still converges; the returned
/// transform `g` is that registration (measured = g · registered) and the fit is on the
/// registered points.
fn refit_frame(
    chain: &SerialChain,
    params: &ErrorParams,
    obs: &[Observation],
    per: PerSession,
) -> Result<(FitResult, Isometry3<f64>), FitError> {
    let model: Vec<Vector3<f64>> = obs.iter().map(|o| chain.position(&o.q, params)).collect();
    let measured: Vec<Vector3<f64>> = obs.iter().map(|o| o.p).collect();
    let g = kabsch(&model, &measured);
    let registered = transformed(obs, &g.inverse());
    let result = fit(
        chain,
        &registered,
        params,
        &per.indices(chain),
        &FitOptions::default(),
    )?;
    Ok((result, g))
}

/// Observations with their points mapped by `t`.
fn transformed(obs: &[Observation], t: &Isometry3<f64>) -> Vec<Observation> {
    obs.iter()
        .map(|o| Observation {
            q: o.q.clone(),
            p: t.transform_point(&o.p.into()).coords,
        })
        .collect()
}

/// A held-out session's error with the kinematics of a fit (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct SessionHeldOut {
    /// The session's name.
    pub name: String,
    /// Its measured points.
    pub points: usize,
    /// Through the training frame, nothing refitted (frame shift included).
    pub frozen: ResidualStats,
    /// Nominal kinematics (every kinematic parameter zero), frame (and marker) refitted: what
    /// the fit gains over the robot's own model.
    pub nominal_refit: ResidualStats,
    /// The fitted kinematics, frame (and marker) refitted: the held-out figure.
    pub refit: ResidualStats,
    /// The session's bad rows, left out of its figures ([`clean_session`]).
    pub outliers: Vec<Outlier>,
}

/// Each held-out session's error with the kinematic parameters of `fit` kept and the frame
/// (and marker, per `per`) refitted on it; beside the same for nominal kinematics and the error
/// through the training frame. Each session's bad rows ([`clean_session`]) are left out.
pub fn heldout_sessions(
    rig: &Rig,
    chain: &SerialChain,
    fit: &FitResult,
    held: &[HeldOut],
    per: PerSession,
) -> Result<Vec<SessionHeldOut>, SessionError> {
    held.iter()
        .map(|h| {
            let clean = clean_session(rig, h)?;
            let obs = clean.recording.observations();
            if obs.is_empty() {
                return Err(SessionError::Empty {
                    name: h.name.clone(),
                });
            }
            let refit_stats = |params: &ErrorParams| {
                refit_frame(chain, params, &obs, per)
                    .map(|(r, _)| r.after)
                    .map_err(|source| SessionError::Refit {
                        name: h.name.clone(),
                        source,
                    })
            };
            Ok(SessionHeldOut {
                name: h.name.clone(),
                points: obs.len(),
                frozen: ResidualStats::of(&errors(chain, &obs, &fit.params)),
                nominal_refit: refit_stats(&frames_only(chain, &fit.params))?,
                refit: refit_stats(&fit.params)?,
                outliers: clean.outliers,
            })
        })
        .collect()
}

/// `params` with every kinematic parameter zero (frame and marker kept).
fn frames_only(chain: &SerialChain, params: &ErrorParams) -> ErrorParams {
    let mut e = params.clone();
    for (k, id) in chain.layout().ids().iter().enumerate() {
        if !matches!(id.transform, TransformId::Frame | TransformId::Marker) {
            e.set(k, 0.0);
        }
    }
    e
}

/// A session with its bad rows found: the rows `identify --level full` removes as outliers are
/// marked `via` (kept for the approach directions, not measured).
#[derive(Debug, Clone)]
pub struct CleanSession {
    /// The session's name.
    pub name: String,
    /// The recording without its bad rows.
    pub recording: Recording,
    /// The bad rows, as the outlier search found them.
    pub outliers: Vec<Outlier>,
}

/// Finds a session's bad rows with the full geometric model (the most complete model has the
/// fewest structured residuals to mistake for outliers) and marks them `via`.
pub fn clean_session(rig: &Rig, session: &HeldOut) -> Result<CleanSession, SessionError> {
    if session.recording.observations().is_empty() {
        return Err(SessionError::Empty {
            name: session.name.clone(),
        });
    }
    let id = identify(
        rig,
        &session.recording,
        Level::Full,
        &crate::diagnosis::outliers::identify_options(),
    )?;
    let mut recording = session.recording.clone();
    for o in &id.outliers {
        for row in recording.rows.iter_mut().filter(|r| r.seq == o.seq) {
            row.status = Status::Via;
        }
    }
    Ok(CleanSession {
        name: session.name.clone(),
        recording,
        outliers: id.outliers,
    })
}

/// A fit on one or more sessions, each with its own measurement frame.
#[derive(Debug, Clone)]
pub struct TrainedSessions {
    /// The rig's chain, which the parameters apply to.
    pub chain: SerialChain,
    /// The fit in the first session's frame, frame parameters absolute.
    pub fit: FitResult,
    /// Residual statistics over every training point, each session in its own frame.
    pub training: ResidualStats,
    /// The training sessions merged into one recording in the first session's frame (rows in
    /// session order, `seq` renumbered), for tools that read one recording (the diagnosis).
    pub merged: Recording,
    /// Alternation rounds run.
    pub rounds: usize,
    /// Each training session with its bad rows found (left out of the fit).
    pub sessions: Vec<CleanSession>,
}

/// Alternation rounds at most, and the RMS change (mm) that ends them.
const MAX_ROUNDS: usize = 30;
const RMS_SETTLED_MM: f64 = 1e-5;

/// Fits the kinematic parameters at `level` on one or more sessions, one measurement frame per
/// session and a shared marker (see the module documentation); each session's bad rows
/// ([`clean_session`]) are left out.
pub fn fit_sessions(
    rig: &Rig,
    sessions: &[HeldOut],
    level: Level,
) -> Result<TrainedSessions, SessionError> {
    let clean = sessions
        .iter()
        .map(|s| clean_session(rig, s))
        .collect::<Result<Vec<_>, _>>()?;
    let recs: Vec<&Recording> = clean.iter().map(|c| &c.recording).collect();
    let (first, others) = recs.split_first().ok_or(SessionError::NoTraining)?;
    let obs: Vec<Vec<Observation>> = recs.iter().map(|s| s.observations()).collect();
    let (chain, mut result) = identify_at(rig, &obs[0], level)?;
    let mut maps = vec![Isometry3::identity(); sessions.len()];
    let mut rounds = 0;
    let mut last_rms = f64::INFINITY;
    while !others.is_empty() && rounds < MAX_ROUNDS {
        rounds += 1;
        let f0 = chain.frame_pose(&result.params);
        for (k, o) in obs.iter().enumerate().skip(1) {
            let (r, g) =
                refit_frame(&chain, &result.params, o, PerSession::Frame).map_err(|source| {
                    SessionError::Refit {
                        name: format!("training session {}", k + 1),
                        source,
                    }
                })?;
            // measured = g · F_k · c(q): into the first frame by F_0 · F_k⁻¹ · g⁻¹.
            maps[k] = f0 * chain.frame_pose(&r.params).inverse() * g.inverse();
        }
        let all: Vec<Observation> = obs
            .iter()
            .zip(&maps)
            .flat_map(|(o, m)| transformed(o, m))
            .collect();
        let (_, fitted) = identify_at(rig, &all, level)?;
        result = fitted;
        let rms = result.after.rms_mm;
        if (last_rms - rms).abs() < RMS_SETTLED_MM {
            break;
        }
        last_rms = rms;
    }
    let all: Vec<Observation> = obs
        .iter()
        .zip(&maps)
        .flat_map(|(o, m)| transformed(o, m))
        .collect();
    let training = ResidualStats::of(&errors(&chain, &all, &result.params));
    let merged = merge(first, others, &maps);
    Ok(TrainedSessions {
        chain,
        fit: result,
        training,
        merged,
        rounds,
        sessions: clean,
    })
}

/// The sessions' rows one after another, points mapped by each session's map, `seq` renumbered.
fn merge(first: &Recording, others: &[&Recording], maps: &[Isometry3<f64>]) -> Recording {
    let mut out = Recording::new(&first.joints);
    let mut seq = 0;
    for (rec, m) in std::iter::once(first)
        .chain(others.iter().copied())
        .zip(maps)
    {
        for row in &rec.rows {
            let mut row = row.clone();
            seq += 1;
            row.seq = seq;
            row.position = row.position.map(|p| m.transform_point(&p.into()).coords);
            out.rows.push(row);
        }
    }
    out
}

/// Training and held-out RMS with the geometry alone and with the effects a diagnosis named.
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicsHeldOut {
    /// The effects used, as the diagnosis labels them.
    pub effects: Vec<String>,
    /// Training RMS, geometry only (mm).
    pub training_geometry: f64,
    /// Training RMS, geometry and the effects (mm).
    pub training_physics: f64,
    /// Per held-out session: (name, geometry only, with the effects), each the mean, RMS and
    /// max of the 3-D error (mm) with the frame refitted.
    pub heldout: Vec<(String, ResidualStats, ResidualStats)>,
}

/// Training and held-out RMS with the diagnosis' named `effects` (from a diagnosis of
/// `training`): the geometry (every identifiable parameter) and the effects' coefficients are
/// fitted together on the training recording; on each held-out session the effects'
/// displacements are predicted and removed, and the frame (and marker, per `per`) refitted with
/// the geometry kept. Effects a held-out session cannot show contribute nothing there. Each
/// held-out session's bad rows ([`clean_session`]) are left out; `training` is used as given.
pub fn physics_heldout(
    rig: &Rig,
    training: &Recording,
    effects: &[EffectReport],
    held: &[HeldOut],
    per: PerSession,
) -> Result<PhysicsHeldOut, SessionError> {
    let lib = diagnosis::library_for(rig);
    let chosen: Vec<&dyn Candidate> = effects
        .iter()
        .filter_map(|e| lib.iter().find(|c| same_effect(c.as_ref(), e)))
        .map(|c| c.as_ref())
        .collect();
    let std = diagnosis::standard_fit(rig, training)?;
    let n = std.data.len();
    let mut cols = vec![std.jacobian.clone()];
    let mut widths = Vec::new();
    for c in &chosen {
        let x = c
            .regressors(&std.data)
            .unwrap_or_else(|| DMatrix::zeros(3 * n, 1));
        widths.push(x.ncols());
        cols.push(x);
    }
    let a = diagnosis::linalg::hcat(&cols, 3 * n);
    let coef = diagnosis::linalg::lstsq(&a, &std.residual).solution;
    let training_physics = diagnosis::linalg::rms3(&(&std.residual - &a * &coef));
    let training_geometry = diagnosis::linalg::rms3(&std.residual);
    // The geometry of the joint fit: the standard fit's parameters moved by the linear step.
    let mut e = std.data.e.clone();
    for (k, &i) in std.free.iter().enumerate() {
        e.set(i, e.get(i) + coef[k]);
    }
    let chain = &std.data.chain;
    let mut heldout = Vec::new();
    for h in held {
        let clean = clean_session(rig, h)?;
        let d = diagnosis::prepare(chain, &e, &clean.recording)?;
        let shift = effect_displacements(&chosen, &widths, &coef, std.free.len(), &d);
        let corrected: Vec<Observation> = d
            .obs
            .iter()
            .zip(&shift)
            .map(|(o, s)| Observation {
                q: o.q.clone(),
                p: o.p - s,
            })
            .collect();
        let refit_stats = |obs: &[Observation], params: &ErrorParams| {
            refit_frame(chain, params, obs, per)
                .map(|(r, _)| r.after)
                .map_err(|source| SessionError::Refit {
                    name: h.name.clone(),
                    source,
                })
        };
        let geometry = refit_stats(&d.obs, &std.data.e)?;
        let physics = refit_stats(&corrected, &e)?;
        heldout.push((h.name.clone(), geometry, physics));
    }
    Ok(PhysicsHeldOut {
        effects: chosen.iter().map(|c| c.label()).collect(),
        training_geometry,
        training_physics,
        heldout,
    })
}

/// The displacement (world, mm) the fitted effects cause at each of `d`'s measurements.
fn effect_displacements(
    chosen: &[&dyn Candidate],
    widths: &[usize],
    coef: &DVector<f64>,
    geometric: usize,
    d: &diagnosis::Data,
) -> Vec<Vector3<f64>> {
    let mut total = DVector::zeros(3 * d.len());
    let mut at = geometric;
    for (c, &w) in chosen.iter().zip(widths) {
        if let Some(x) = c.regressors(d) {
            if x.ncols() == w {
                total += x * coef.rows(at, w);
            }
        }
        at += w;
    }
    (0..d.len())
        .map(|i| Vector3::new(total[3 * i], total[3 * i + 1], total[3 * i + 2]))
        .collect()
}

/// True when the library candidate is the effect the report names.
fn same_effect(c: &dyn Candidate, e: &EffectReport) -> bool {
    if c.kind() != e.kind || c.order() != e.order {
        return false;
    }
    match c.index() {
        Index::Joint(j) => e.joint == Some(j + 1),
        Index::Axis(a) => e.axis.as_deref() == Some(diagnosis::AXES[a]),
        Index::Axes(a, b) => e
            .axes
            .as_ref()
            .is_some_and(|[x, y]| x == diagnosis::AXES[a] && y == diagnosis::AXES[b]),
    }
}

/// A copy of `rec` with the rows of `seqs` marked `via` (kept for the approach directions, not
/// measured): a recording without the outliers a diagnosis removed.
pub fn without_rows(rec: &Recording, seqs: impl IntoIterator<Item = u64>) -> Recording {
    let mut out = rec.clone();
    for s in seqs {
        for row in out.rows.iter_mut().filter(|m| m.seq == s) {
            row.status = Status::Via;
        }
    }
    out
}

/// A held-out session as the held-out judgement ([`super::crossval`]) reads it: the session at
/// the training geometry with its measurement frame (and marker, per `per`) refitted, its
/// geometric Jacobian over the training fit's free parameters `free`, its residual, and an
/// orthonormal basis of the frame parameters' Jacobian there. The judgement projects that basis
/// out of every prediction: the frame is refitted per session, so the part of a term's
/// displacement a frame shift can take is no gain (the linearised form of [`physics_heldout`]'s
/// refit, about a frame that has already converged).
pub fn session_for_judgement(
    chain: &SerialChain,
    params: &ErrorParams,
    free: &[usize],
    clean: &CleanSession,
    per: PerSession,
) -> Result<(super::heldout::HeldoutRecording, DMatrix<f64>), SessionError> {
    let obs = clean.recording.observations();
    if obs.is_empty() {
        return Err(SessionError::Empty {
            name: clean.name.clone(),
        });
    }
    let (fit, g) = refit_frame(chain, params, &obs, per).map_err(|source| SessionError::Refit {
        name: clean.name.clone(),
        source,
    })?;
    let back = g.inverse();
    let mut rec = clean.recording.clone();
    for row in &mut rec.rows {
        row.position = row.position.map(|p| back.transform_point(&p.into()).coords);
    }
    let d = diagnosis::prepare(chain, &fit.params, &rec)?;
    let poses: Vec<Vec<f64>> = d.obs.iter().map(|o| o.q.clone()).collect();
    let jac = |idx: &[usize]| {
        crate::identification::identifiability::stacked_jacobian(chain, &fit.params, &poses, idx)
    };
    let hg = jac(free);
    let frame = diagnosis::linalg::orth_basis(&jac(&per.indices(chain)), 1e-9);
    let r = diagnosis::residual_of(&d);
    Ok(((d, hg, r), frame))
}
