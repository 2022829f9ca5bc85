//! Planning mode through a measurement session: every measurement the division asks for is
//! made by the session's devices and recorded in its directory; a killed session resumes.
//!
//! The session's `session.toml` notes the options that decide which points it measures and on
//! what ([`planning_note`]); a resume with other options is refused before anything is touched
//! ([`refuse_other_options`]). A resumed session first replays its finished points to the
//! division ([`resumed_requests`]), which asks for them again in the same order, then measures
//! on: the run ends as an uninterrupted one would.

use super::{Calibrated, CalibrationError, CalibrationOptions, Source};
use rigcal_core::recording::SessionInfo;
use rigcal_core::rig::Rig;
use rigcal_devices::devices::{CommandPath, SimClock};
use rigcal_devices::session::{
    recorded_requests, RecordedRequest, Session, SessionError, SessionMeasurer, SessionOptions,
    SessionReport, StopRequest,
};
use rigcal_model::division::DivisionError;
use rigcal_sim::world::Scenario;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicUsize;
use std::sync::Arc;

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
    // Only when not the default: sessions recorded before the option existed resume as before.
    if opts.design_poses != super::DEFAULT_DESIGN_POSES {
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
    // The acceptance and the test plan decide which regions split, so which points come next
    // (section 7 sets them through the library; the command line has the defaults).
    if opts.unmeasurable_halves {
        s.push_str(" --unmeasurable-halves");
    }
    if opts.confidence_z != rigcal_model::division::CONFIDENCE_Z {
        s.push_str(&format!(" --confidence-z {}", opts.confidence_z));
    }
    if opts.test_plan != rigcal_model::division::TestPlan::default() {
        let t = opts.test_plan;
        s.push_str(&format!(
            " --test-plan first-stage={},reuse={},refit={}",
            t.first_stage, t.reuse, t.refit
        ));
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

/// Opens (or, with `resume`, resumes) the planning-mode session in `dir` on the rig's devices,
/// or on emulators of `scenario`'s world on the virtual clock, every arm move on the rig's
/// command path (`MP` on a `cartesian` rig, the moves that went through `MJ` instead counted in
/// `fallbacks`); its `session.toml` notes `files`, the scenario's seed and the options that
/// shape the session ([`planning_note`]).
pub fn open_session<'r>(
    rig: &'r Rig,
    files: PlanningFiles<'_>,
    scenario: Option<&Scenario>,
    dir: &Path,
    opts: &CalibrationOptions,
    resume: bool,
    fallbacks: &Arc<AtomicUsize>,
) -> Result<Session<'r>, CalibrationError> {
    let never = StopRequest::new();
    open_session_stoppable(rig, files, scenario, dir, opts, resume, fallbacks, never)
}

/// [`open_session`], stopping safely (drives halted, the journal at the last finished point,
/// resumable) when `stop` is raised — by SIGINT or SIGTERM from `rigcal calibrate --session`.
#[allow(clippy::too_many_arguments)]
pub fn open_session_stoppable<'r>(
    rig: &'r Rig,
    files: PlanningFiles<'_>,
    scenario: Option<&Scenario>,
    dir: &Path,
    opts: &CalibrationOptions,
    resume: bool,
    fallbacks: &Arc<AtomicUsize>,
    stop: StopRequest,
) -> Result<Session<'r>, CalibrationError> {
    let opened = rigcal_sim::emulation::open_rig(rig, scenario, SimClock::Virtual)?
        .on_command_path(super::rig_check::command_path(rig), fallbacks);
    let mut so = SessionOptions::new(dir);
    so.seed = opts.seed;
    so.resume = resume;
    so.fsync = !opened.devices.clock.is_virtual();
    so.stop = stop;
    so.info = SessionInfo {
        rig: Some(files.rig.display().to_string()),
        scenario: files.sim.map(|p| p.display().to_string()),
        seed: scenario.map(|s| s.seed),
        notes: Some(planning_note(files, opts)),
        ..Default::default()
    };
    Session::open(rig, opened, so).map_err(|e| CalibrationError::OpenSession(Box::new(e)))
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

/// A planning-mode session as `rigcal calibrate --session` runs it, opened and ready to
/// measure: the session, what an earlier run of it finished, and the count of arm moves that
/// went through `MJ` on a `cartesian` rig.
pub struct PlanningSession<'r> {
    session: Session<'r>,
    dir: PathBuf,
    recorded: Vec<RecordedRequest>,
    fallbacks: Arc<AtomicUsize>,
    dry_run: bool,
}

impl<'r> PlanningSession<'r> {
    /// Opens (or, with `resume`, resumes after refusing other options) the planning-mode
    /// session in `dir`, on emulators of the `files.sim` scenario's world (checked against the
    /// rig) or on the rig's devices. A resumed session's finished points are read for the
    /// division to replay. Raising `stop` halts it safely, resumable.
    pub fn open(
        rig: &'r Rig,
        files: PlanningFiles<'_>,
        dir: &Path,
        opts: &CalibrationOptions,
        resume: bool,
        stop: StopRequest,
    ) -> Result<Self, CalibrationError> {
        if opts.is_neural() {
            return Err(CalibrationError::NeuralNeedsData);
        }
        if resume {
            refuse_other_options(dir, files, opts)?;
        }
        let fallbacks = Arc::new(AtomicUsize::new(0));
        let scenario = super::dry_run_scenario(rig, files.rig, files.sim, None)?;
        let session = open_session_stoppable(
            rig,
            files,
            scenario.as_ref(),
            dir,
            opts,
            resume,
            &fallbacks,
            stop,
        )?;
        let recorded = if resume {
            resumed_requests(rig, dir, session.points_done())?
        } else {
            Vec::new()
        };
        Ok(PlanningSession {
            session,
            dir: dir.to_path_buf(),
            recorded,
            fallbacks,
            dry_run: files.sim.is_some(),
        })
    }

    /// The finished points of earlier runs, replayed to the division before it measures on.
    pub fn replayed(&self) -> usize {
        self.recorded.len()
    }

    /// Runs the division through the session ([`through_session`]) and finishes it: the
    /// calibration, and the text `rigcal calibrate --session` prints (the calibration's, the
    /// session's line, and on a `cartesian` rig how the arm moves went).
    pub fn calibrate(
        self,
        rig: &'r Rig,
        opts: &CalibrationOptions,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<(Calibrated, String), CalibrationError> {
        let dir = self.dir;
        let s = through_session(rig, self.session, &dir, self.recorded, opts, progress)?;
        let mj_moves = self.fallbacks.load(std::sync::atomic::Ordering::Relaxed);
        let text = format!(
            "{}{}{}",
            s.calibrated.text(),
            s.session_text(&dir, self.dry_run),
            command_path_text(rig, mj_moves)
        );
        Ok((s.calibrated, text))
    }
}

/// How a session's arm moves went: on a `cartesian` rig through `MP`, with the count that went
/// through `MJ` instead (their `MP` solution refused at a joint limit); nothing on a `joint` rig.
pub fn command_path_text(rig: &Rig, mj_moves: usize) -> String {
    match super::rig_check::command_path(rig) {
        CommandPath::Cartesian => format!(
            "arm moves through MP (the rig's cartesian command path); {mj_moves} through MJ, their MP solution refused at a joint limit\n"
        ),
        CommandPath::Joint => String::new(),
    }
}
