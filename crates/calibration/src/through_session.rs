//! Planning mode through a measurement session: every measurement the division asks for is
//! made by the session's devices and recorded in its directory; a killed session resumes.
//!
//! The session's `session.toml` notes the options that decide which points it measures and on
//! what ([`planning_note`]); a resume with other options is refused before anything is touched
//! ([`refuse_other_options`]). A resumed session first replays its finished points to the
//! division ([`resumed_requests`]), which asks for them again in the same order, then measures
//! on: the run ends as an uninterrupted one would.

use super::{Calibrated, CalibrationError, CalibrationOptions, Source};
use rigcal_core::rig::Rig;
use rigcal_devices::session::{
    recorded_requests, RecordedRequest, Session, SessionError, SessionMeasurer, SessionReport,
};
use rigcal_model::division::DivisionError;
use std::path::{Path, PathBuf};

/// How `session.toml` notes a planning-mode session; the options that shaped it follow.
const PLANNING_NOTE: &str =
    "rigcal calibrate --session: planning-mode division, the session measures where it asks; options: ";

/// The files that set a planning-mode session up: the rig file and, for a dry run, the
/// scenario the emulators run on.
#[derive(Debug, Clone, Copy)]
pub struct PlanningFiles<'a> {
    /// The rig file.
    pub rig: &'a Path,
    /// The scenario of a dry run (None: the rig's own devices).
    pub sim: Option<&'a Path>,
}

/// The options that decide which points a planning-mode session measures and what it measures
/// them on: a resume must be given the same.
fn planning_options(files: PlanningFiles<'_>, opts: &CalibrationOptions) -> String {
    let file = |p: &Path| {
        std::fs::canonicalize(p)
            .unwrap_or_else(|_| p.to_path_buf())
            .display()
            .to_string()
    };
    let mut s = format!(
        "--rig {} --sim {} --division {:?} --accuracy-mm {} --max-regions {} --per-region {} --test-points {} --seed {} --unmeasurable-at {}",
        file(files.rig),
        files.sim.map_or("(none: the rig)".to_string(), file),
        opts.space,
        opts.accuracy_mm,
        opts.max_regions.map_or("(default)".to_string(), |n| n.to_string()),
        opts.per_region,
        opts.test_points,
        opts.seed,
        opts.unmeasurable_at
            .map_or("(none)".to_string(), |p| format!("{},{},{}", p[0], p[1], p[2])),
    );
    // Only when not the paper's: sessions recorded before the option existed resume as before.
    if opts.design_poses != super::PAPER_DESIGN_POSES {
        s.push_str(&format!(" --design-poses {}", opts.design_poses));
    }
    if opts.selection != rigcal_model::division::Selection::Kappa {
        s.push_str(&format!(" --selection {:?}", opts.selection));
    }
    if !opts.reuse_parent {
        s.push_str(" --no-reuse");
    }
    if let Some(depth) = opts.unmeasurable_depth {
        s.push_str(&format!(" --unmeasurable-depth {depth}"));
    }
    s
}

/// The `notes` of a planning-mode session's `session.toml`.
pub fn planning_note(files: PlanningFiles<'_>, opts: &CalibrationOptions) -> String {
    format!("{PLANNING_NOTE}{}", planning_options(files, opts))
}

/// Refuses to resume the planning-mode session in `dir` with options other than its own: the
/// division would ask for other points, or the session would mix measurements of two set-ups.
pub fn refuse_other_options(
    dir: &Path,
    files: PlanningFiles<'_>,
    opts: &CalibrationOptions,
) -> Result<(), CalibrationError> {
    let info = rigcal_core::recording::read_session_info(dir).map_err(|source| {
        CalibrationError::Recording {
            path: dir.join("session.toml"),
            source,
        }
    })?;
    let Some(recorded) = info
        .and_then(|i| i.notes)
        .and_then(|n| n.strip_prefix(PLANNING_NOTE).map(str::to_string))
    else {
        return Err(CalibrationError::NotPlanningSession {
            dir: dir.to_path_buf(),
        });
    };
    let given = planning_options(files, opts);
    if recorded != given {
        return Err(CalibrationError::OtherOptions {
            dir: dir.to_path_buf(),
            recorded,
            given,
        });
    }
    Ok(())
}

/// The division's requests a resumed session in `dir` finished in earlier runs, read after
/// opening it (a resumed session has cut its recording back to the last finished point);
/// `points_done` is what its journal says, and the two must agree.
pub fn resumed_requests(
    rig: &Rig,
    dir: &Path,
    points_done: usize,
) -> Result<Vec<RecordedRequest>, CalibrationError> {
    let rec = rigcal_core::recording::Recording::read(
        dir,
        rigcal_core::kinematics::Robot::joints(&rig.chain),
    )
    .map_err(|source| CalibrationError::Recording {
        path: dir.to_path_buf(),
        source,
    })?;
    let recorded = recorded_requests(&rec);
    if recorded.len() != points_done {
        return Err(CalibrationError::ResumeMismatch {
            dir: dir.to_path_buf(),
            journal: points_done,
            recorded: recorded.len(),
        });
    }
    Ok(recorded)
}

/// A planning-mode session's result: the calibration and the finished session's report.
#[derive(Debug, Clone)]
pub struct SessionCalibrated {
    /// The calibration.
    pub calibrated: Calibrated,
    /// What the session did (this run's counts on a resume).
    pub report: SessionReport,
}

impl SessionCalibrated {
    /// The session's line as `rigcal calibrate --session` prints it; `virtual_clock` for a dry
    /// run.
    pub fn session_text(&self, dir: &Path, virtual_clock: bool) -> String {
        let r = &self.report;
        format!(
            "session {}: {} points asked for{}, {} measured, {} skipped, rig time {:.0} s ({:.2} h){}\n",
            dir.display(),
            r.points,
            match r.resumed_at {
                Some(k) => format!(" ({k} from earlier runs, replayed; this run's counts follow)"),
                None => String::new(),
            },
            r.ok,
            r.skipped.len(),
            r.rig_time_s,
            r.rig_time_s / 3600.0,
            if virtual_clock { " on the virtual clock" } else { "" }
        )
    }
}

/// Planning mode through the opened `session` in `dir`: the division asks, the session
/// measures, and the session is finished. `recorded` answers the first requests of a resumed
/// session ([`resumed_requests`]; empty for a new one).
pub fn through_session<'r>(
    rig: &'r Rig,
    mut session: Session<'r>,
    dir: &Path,
    recorded: Vec<RecordedRequest>,
    opts: &CalibrationOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<SessionCalibrated, CalibrationError> {
    if opts.is_neural() {
        return Err(CalibrationError::NeuralNeedsData);
    }
    let mut measurer = SessionMeasurer::resuming(&mut session, rig, recorded);
    let calibrated = super::calibrate_with_progress(
        rig,
        Source::Measurer {
            measurer: &mut measurer,
            label: dir.display().to_string(),
        },
        opts,
        progress,
    );
    let stopped = |source| CalibrationError::Session {
        dir: PathBuf::from(dir),
        source: Box::new(source),
    };
    // A session fault ends the division at once: it, not the division's view of it, is the error.
    let calibrated = calibrated.map_err(|e| match e {
        CalibrationError::Division(DivisionError::Measurement(m)) => {
            match m.source.downcast::<SessionError>() {
                Ok(source) => CalibrationError::Session {
                    dir: PathBuf::from(dir),
                    source,
                },
                Err(other) => CalibrationError::Division(DivisionError::Measurement(
                    rigcal_model::division::MeasureError { source: other },
                )),
            }
        }
        e => e,
    })?;
    let report = session.finish().map_err(stopped)?;
    Ok(SessionCalibrated { calibrated, report })
}
