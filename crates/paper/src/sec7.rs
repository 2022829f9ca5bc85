//! Seed 000 section 7 on the rig's emulators, end to end: a dry-run session registers the
//! table, then measures for a planning-mode Cartesian division (0.5 mm demanded, 20
//! measurements per region, each region's locations one z-ascending batch); the variable D-H
//! model (with and without the FCMAC) and the conventional model come out of it; a second
//! session then runs a straight Cartesian path once per method — nominal, conventional,
//! regions, FCMAC — through the controller's Cartesian command (`MP`), and a third the same
//! through joint commands (`MJ`), each in the division session's frame; the rig's own
//! instrument measures the distance to each target.
//!
//! Each region is tested sequentially on the evidence of its enclosing regions' tests, and the
//! leaves are refitted on their tests at the end ([`Section7::test_plan`](crate::preset::Section7),
//! docs/seeds.md): that, and the paper's 85 regions as the cap, keep the whole experiment near
//! the paper's "couple of hours" of rig time.
//!
//! On a `cartesian` rig every move of the division session goes through `MP` too: its test
//! points are compensated commands, and joint rounding (0.1°) alone would cost about 0.43 mm
//! of a 0.5 mm demand (conventions §9b).
//!
//! The paper's path "(−300, 520, 150) → (350, 690, 600) mm" lies in a frame it does not state
//! and leaves the table's reach in Table I's world frame (conventions §2); the preset's
//! [`Section7::path_mm`](crate::preset::Section7::path_mm) is the same line moved by
//! (0, −170, −120) mm, inside the reach, 809 mm long as the paper's.

use crate::preset::{Preset, SEED_000};
use nalgebra::Vector3;
use rigcal_calibration::rig_check::{
    cartesian_floor, compensated_commands, measured_errors_in, path_targets, registration_of,
    resolution_floor,
};
use rigcal_calibration::{
    open_session, through_session, CalibrationError, CalibrationOptions, Figures, PlanningFiles,
    SessionCalibrated,
};
use rigcal_core::kinematics::{solve_position_ik, ErrorParams, IkOptions, Robot};
use rigcal_core::recording::{Recording, RegistrationInfo, SessionInfo, Status};
use rigcal_core::rig::Rig;
use rigcal_devices::devices::CommandPath;
use rigcal_devices::devices::{OpenedRig, SimClock};
use rigcal_devices::session::plan::table_target;
use rigcal_devices::session::{
    estimate, is_division_region, read_plan, registration_points, write_plan, ContactSettings,
    PlannedPoint, Progress, RigSpeeds, RigTimeEstimate, SessionError, SessionOptions,
    SessionReport,
};
use rigcal_model::model::ModelBody;
use rigcal_model::report::{PathError, PathResult, PathSpec};
use rigcal_sim::emulation::open_rig;
use rigcal_sim::world::Scenario;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering as AtomicOrdering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The methods along the path, in the order measured and shown.
pub const METHODS: [&str; 4] = ["uncalibrated", "conventional", "regions", "fcmac"];

/// Settings of the experiment; the defaults are the paper's ([`SEED_000`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Sec7Options {
    /// The division's settings (Cartesian, 0.5 mm, 20 per region, the FCMAC:
    /// [`Preset::section7_calibration`]).
    pub calibration: CalibrationOptions,
    /// The path's ends (world mm).
    pub path_mm: [[f64; 3]; 2],
    /// Points along the path.
    pub path_points: usize,
    /// Also run the path through joint commands (`MJ`) beside the rig's own command path.
    pub joint_commands: bool,
}

impl Sec7Options {
    /// The experiment at `preset`'s settings, 101 path points, through both command paths.
    pub fn of(preset: &Preset) -> Self {
        Self {
            calibration: preset.section7_calibration(),
            path_mm: preset.section7.path_mm,
            path_points: 101,
            joint_commands: true,
        }
    }
}

impl Default for Sec7Options {
    fn default() -> Self {
        Self::of(&SEED_000)
    }
}

/// The files of the experiment.
#[derive(Debug, Clone, Copy)]
pub struct Sec7Files<'a> {
    /// The rig file.
    pub rig: &'a Path,
    /// The scenario the emulators run on.
    pub scenario: &'a Path,
    /// A new (or empty) directory for the sessions and the model.
    pub out: &'a Path,
}

impl Sec7Files<'_> {
    /// The division session's directory.
    pub fn division_dir(&self) -> PathBuf {
        self.out.join("division")
    }

    /// The path session's directory for `command_path`.
    pub fn path_dir(&self, command_path: CommandPath) -> PathBuf {
        self.out.join(format!("path-{command_path}"))
    }

    /// The model file the experiment writes.
    pub fn model_file(&self) -> PathBuf {
        self.out.join("sec7-model.json")
    }
}

/// Why the experiment stopped.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Sec7Error {
    /// The calibration, or reading what a session wrote.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    /// The rig file.
    #[error(transparent)]
    Rig(#[from] rigcal_core::rig::RigError),
    /// The emulated devices could not be opened.
    #[error("opening the emulated rig: {0}")]
    Devices(#[from] rigcal_devices::devices::DeviceError),
    /// A path session stopped.
    #[error("the path session in {} stopped", dir.display())]
    Session {
        /// Its directory.
        dir: PathBuf,
        /// Why (boxed: large and rare).
        source: Box<SessionError>,
    },
    /// A plan file could not be written or read back.
    #[error(transparent)]
    Plan(#[from] rigcal_devices::session::PlanError),
    /// A point of the path the rig cannot measure.
    #[error("point {index} of the path cannot be measured on this rig: {reason}; choose a path inside the table's reach")]
    PathNotMeasurable {
        /// Point index (0-based).
        index: usize,
        /// Why.
        reason: String,
    },
    /// The scenario's rig is not this rig.
    #[error("scenario {} assumes rig `{scenario_rig}` with its instrument; the rig file is `{rig}`", scenario.display())]
    OtherRig {
        /// The scenario file.
        scenario: PathBuf,
        /// Its rig.
        scenario_rig: String,
        /// The rig in use.
        rig: String,
    },
}

/// One session over the path: every method's pass, through one command path.
#[derive(Debug, Clone)]
pub struct CommandPathRun {
    /// `cartesian` (`MP`) or `joint` (`MJ`).
    pub command_path: CommandPath,
    /// Distance to target measured by the rig per method ([`METHODS`] order).
    pub results: Vec<PathResult>,
    /// What the command path's rounding alone moves each method's commanded tip (mm), per
    /// method: the floor of compensation through it.
    pub floors_mm: Vec<Vec<f64>>,
    /// What the session did.
    pub session: SessionReport,
    /// Its rig time as planned.
    pub estimate: RigTimeEstimate,
    /// Moves of a Cartesian session that went through joint commands, their `MP` solution
    /// refused at a joint limit.
    pub mj_moves: usize,
}

/// What the experiment measured.
#[derive(Debug, Clone)]
pub struct Sec7Report {
    /// The scenario.
    pub scenario: PathBuf,
    /// The division through its session: the model, its figures, the session's report.
    pub division: SessionCalibrated,
    /// The division session's rig time as planned (its points in the order measured).
    pub division_estimate: RigTimeEstimate,
    /// Moves of the division session that went through joint commands, their `MP` solution
    /// refused at a joint limit.
    pub division_mj_moves: usize,
    /// Leaves without a well-conditioned measurable set of their own: (id, why).
    pub unmeasurable: Vec<(String, String)>,
    /// The registration the path sessions reused.
    pub registration: RegistrationInfo,
    /// The path.
    pub path: PathSpec,
    /// Its length (mm).
    pub path_length_mm: f64,
    /// The path sessions: the rig's own command path first, then joint commands if asked.
    pub runs: Vec<CommandPathRun>,
    /// The model file written.
    pub model_file: PathBuf,
    /// Wall time of the whole experiment.
    pub wall: Duration,
}

/// Stages the experiment reports as it goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sec7Stage {
    /// The division: regions so far of the cap.
    Division(usize, usize),
    /// A path session begins.
    Path(CommandPath),
}

/// Runs the experiment: the division session, the model, the path sessions.
pub fn run(
    files: Sec7Files<'_>,
    opts: &Sec7Options,
    progress: &mut dyn FnMut(Sec7Stage),
) -> Result<Sec7Report, Sec7Error> {
    let started = Instant::now();
    let rig = Rig::load(files.rig)?;
    let sc = Scenario::load(files.scenario, None).map_err(CalibrationError::from)?;
    if sc.rig.name != rig.name || sc.rig.instrument != rig.instrument {
        return Err(Sec7Error::OtherRig {
            scenario: sc.path.clone(),
            scenario_rig: sc.rig.name.clone(),
            rig: rig.name.clone(),
        });
    }
    let path = cartesian_line(&rig, opts.path_mm, opts.path_points)?;
    let fallbacks = Arc::new(AtomicUsize::new(0));
    let division = divide(&rig, &sc, files, &opts.calibration, &fallbacks, progress)?;
    let division_mj_moves = fallbacks.swap(0, AtomicOrdering::Relaxed);
    let model_file = files.model_file();
    division
        .calibrated
        .model
        .save(&model_file)
        .map_err(CalibrationError::from)?;
    let division_estimate = division_estimate(&rig, &files.division_dir(), opts.calibration.seed)?;
    let registration = registration_of(&rig, &files.division_dir())?;
    let models = division
        .calibrated
        .model
        .error_models(&rig, &model_file)
        .map_err(CalibrationError::from)?;
    let commands = method_commands(&rig, &path, &models)?;
    let mut paths = vec![rigcal_calibration::rig_check::command_path(&rig)];
    if opts.joint_commands && paths[0] != CommandPath::Joint {
        paths.push(CommandPath::Joint);
    }
    let mut runs = Vec::new();
    for cp in paths {
        progress(Sec7Stage::Path(cp));
        let mut run = path_session(&rig, &sc, files, &registration, &commands, cp, &fallbacks)?;
        run.mj_moves = fallbacks.swap(0, AtomicOrdering::Relaxed);
        runs.push(run);
    }
    Ok(Sec7Report {
        scenario: files.scenario.to_path_buf(),
        unmeasurable: unmeasurable_leaves(&division),
        division,
        division_estimate,
        division_mj_moves,
        registration,
        path_length_mm: (Vector3::from(opts.path_mm[1]) - Vector3::from(opts.path_mm[0])).norm(),
        path,
        runs,
        model_file,
        wall: started.elapsed(),
    })
}

/// A straight Cartesian line from `ends[0]` to `ends[1]` (world mm) of `n` points, each the
/// nominal inverse kinematics from its neighbour's joints (one configuration all along), and
/// every point measurable on the rig.
pub fn cartesian_line(rig: &Rig, ends: [[f64; 3]; 2], n: usize) -> Result<PathSpec, Sec7Error> {
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let (a, b) = (Vector3::from(ends[0]), Vector3::from(ends[1]));
    let mut seed: Option<Vec<f64>> = None;
    let mut points = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 / (n.max(2) - 1) as f64;
        let target = a + (b - a) * t;
        let q = solve_position_ik(
            &rig.chain,
            &nominal,
            &target,
            rig.held(),
            seed.as_deref(),
            &IkOptions::default(),
        )
        .map_err(|source| CalibrationError::Path(PathError::Unreachable { index: k, source }))?;
        rig.measurable(&q)
            .map_err(|reason| Sec7Error::PathNotMeasurable {
                index: k,
                reason: reason.to_string(),
            })?;
        seed = Some(q.clone());
        points.push(q);
    }
    let fmt = |p: &[f64; 3]| format!("{:.0}, {:.0}, {:.0}", p[0], p[1], p[2]);
    Ok(PathSpec {
        name: format!(
            "straight Cartesian path ({}) → ({}) mm",
            fmt(&ends[0]),
            fmt(&ends[1])
        ),
        points,
    })
}

/// Another straight path (`ends`, world mm, `n` points) measured with the experiment already
/// in `files.out` (its division session's registration and its model file), once per method
/// through the rig's own command path, into `dir` (`crate::extras`: the paper's "several
/// different paths").
pub fn measure_another_path(
    files: Sec7Files<'_>,
    ends: [[f64; 3]; 2],
    n: usize,
    dir: &Path,
) -> Result<CommandPathRun, Sec7Error> {
    let rig = Rig::load(files.rig)?;
    let sc = Scenario::load(files.scenario, None).map_err(CalibrationError::from)?;
    let path = cartesian_line(&rig, ends, n)?;
    let registration = registration_of(&rig, &files.division_dir())?;
    let model_file = files.model_file();
    let model =
        rigcal_model::model::ModelFile::load(&model_file).map_err(CalibrationError::from)?;
    let models = model
        .file
        .error_models(&rig, &model_file)
        .map_err(CalibrationError::from)?;
    let commands = method_commands(&rig, &path, &models)?;
    let cp = rigcal_calibration::rig_check::command_path(&rig);
    let here = Sec7Files { out: dir, ..files };
    let fallbacks = Arc::new(AtomicUsize::new(0));
    path_session(&rig, &sc, here, &registration, &commands, cp, &fallbacks)
}

/// The rig's devices on the emulators of `sc`, every arm move on command path `cp`
/// ([`OpenedRig::on_command_path`], counting its joint-command moves in `fallbacks`).
fn emulated_rig(
    rig: &Rig,
    sc: &Scenario,
    cp: CommandPath,
    fallbacks: &Arc<AtomicUsize>,
) -> Result<OpenedRig, Sec7Error> {
    Ok(open_rig(rig, Some(sc), SimClock::Virtual)?.on_command_path(cp, fallbacks))
}

/// What `session.toml` says about a session of the experiment.
fn session_info(files: Sec7Files<'_>, sc: &Scenario, notes: String) -> SessionInfo {
    SessionInfo {
        rig: Some(files.rig.display().to_string()),
        scenario: Some(files.scenario.display().to_string()),
        seed: Some(sc.seed),
        notes: Some(notes),
        ..Default::default()
    }
}

/// The division through a session on the emulators: registration, then the region batches.
fn divide(
    rig: &Rig,
    sc: &Scenario,
    files: Sec7Files<'_>,
    opts: &CalibrationOptions,
    fallbacks: &Arc<AtomicUsize>,
    progress: &mut dyn FnMut(Sec7Stage),
) -> Result<SessionCalibrated, Sec7Error> {
    let dir = files.division_dir();
    let planning = PlanningFiles {
        rig: files.rig,
        sim: Some(files.scenario),
    };
    let session = open_session(rig, planning, Some(sc), &dir, opts, false, fallbacks)?;
    Ok(through_session(
        rig,
        session,
        &dir,
        Vec::new(),
        opts,
        &mut |n, cap| progress(Sec7Stage::Division(n, cap)),
    )?)
}

/// The rig time the division session's points would take as planned, in the order measured
/// (registration first).
fn division_estimate(rig: &Rig, dir: &Path, seed: u64) -> Result<RigTimeEstimate, Sec7Error> {
    let rec = read_recording(rig, dir)?;
    let registration = registration_points(rig, SessionOptions::new(dir).registration_points, seed);
    let measured: Vec<PlannedPoint> = rec
        .rows
        .iter()
        .filter(|m| m.region.as_deref().is_some_and(is_division_region) && m.status != Status::Via)
        .enumerate()
        .map(|(k, m)| PlannedPoint {
            point: k + 1,
            region: m.region.clone().unwrap_or_default(),
            q: m.q.clone(),
            table_mm: table_target(rig, &m.q).unwrap_or_default(),
        })
        .collect();
    let all = [registration, measured].concat();
    Ok(estimate(
        rig,
        &all,
        &RigSpeeds::of(rig),
        &ContactSettings::of(rig),
    ))
}

fn read_recording(rig: &Rig, dir: &Path) -> Result<Recording, Sec7Error> {
    Recording::read(dir, rig.chain.joints()).map_err(|source| {
        Sec7Error::Calibration(CalibrationError::Recording {
            path: dir.to_path_buf(),
            source,
        })
    })
}

/// The leaves of the division that have no CEPs of their own fitted from their own
/// measurements, with why.
fn unmeasurable_leaves(division: &SessionCalibrated) -> Vec<(String, String)> {
    let ModelBody::Variable { tree, .. } = &division.calibrated.model.model else {
        return Vec::new();
    };
    tree.root
        .leaves()
        .into_iter()
        .filter(|l| !l.is_measured())
        .map(|l| {
            let why = l
                .note
                .clone()
                .unwrap_or_else(|| "no measurement of its own".into());
            (l.id.clone(), why)
        })
        .collect()
}

/// Per method, the commands along the path: the nominal joints uncalibrated, each model's
/// compensated joints otherwise ([`METHODS`] order); with the targets.
struct MethodCommands {
    targets: Vec<Vector3<f64>>,
    commands: Vec<(String, Vec<Vec<f64>>)>,
}

fn method_commands(
    rig: &Rig,
    path: &PathSpec,
    models: &[rigcal_model::model::NamedModel],
) -> Result<MethodCommands, Sec7Error> {
    let targets = path_targets(rig, path);
    let mut commands = vec![(METHODS[0].to_string(), path.points.clone())];
    for name in &METHODS[1..] {
        let Some((_, model)) = models.iter().find(|(n, _)| n == name) else {
            continue;
        };
        let compensated = compensated_commands(rig, model.as_ref(), path, &targets)?;
        commands.push((name.to_string(), compensated));
    }
    Ok(MethodCommands { targets, commands })
}

/// Region id of a method's pass along the path.
fn path_region(method: &str) -> String {
    format!("path-{method}")
}

/// One session over the path through `cp`: each method's pass in turn, in the division
/// session's frame.
fn path_session(
    rig: &Rig,
    sc: &Scenario,
    files: Sec7Files<'_>,
    registration: &RegistrationInfo,
    commands: &MethodCommands,
    cp: CommandPath,
    fallbacks: &Arc<AtomicUsize>,
) -> Result<CommandPathRun, Sec7Error> {
    let dir = files.path_dir(cp);
    std::fs::create_dir_all(&dir).map_err(|source| CalibrationError::Io {
        path: dir.clone(),
        source,
    })?;
    let mut plan = Vec::new();
    for (method, qs) in &commands.commands {
        for q in qs {
            plan.push(PlannedPoint {
                point: plan.len() + 1,
                region: path_region(method),
                q: q.clone(),
                table_mm: table_target(rig, q).unwrap_or_default(),
            });
        }
    }
    let plan_file = dir.join("plan.csv");
    write_plan(&plan_file, rig, &plan)?;
    // Measured as read back from the file, as a session on the rig does.
    let plan = read_plan(&plan_file, rig)?;
    let estimate = estimate(rig, &plan, &RigSpeeds::of(rig), &ContactSettings::of(rig));
    let opened = emulated_rig(rig, sc, cp, fallbacks)?;
    let mut so = SessionOptions::new(&dir);
    so.seed = sc.seed;
    so.fsync = false;
    so.registration = Some(*registration);
    let notes = format!(
        "rigcal section 7: the path, {} passes of {} points through the {cp} command path",
        commands.commands.len(),
        commands.targets.len()
    );
    so.info = session_info(files, sc, notes);
    let session = rigcal_devices::session::run_session(rig, opened, &plan, so, &Progress::Quiet)
        .map_err(|source| Sec7Error::Session {
            dir: dir.clone(),
            source: Box::new(source),
        })?;
    let rec = read_recording(rig, &dir)?;
    let floor = |qs: &[Vec<f64>]| match cp {
        CommandPath::Joint => Some(resolution_floor(rig, qs)),
        CommandPath::Cartesian => cartesian_floor(rig, qs),
    };
    let mut results = Vec::new();
    let mut floors_mm = Vec::new();
    for (method, qs) in &commands.commands {
        results.push(PathResult {
            model: method.clone(),
            errors: measured_errors_in(&rec, &path_region(method), &commands.targets),
            traces: Vec::new(),
            failures: 0,
        });
        floors_mm.push(floor(qs).unwrap_or_default());
    }
    Ok(CommandPathRun {
        command_path: cp,
        results,
        floors_mm,
        session,
        estimate,
        mj_moves: 0,
    })
}

fn mean(v: &[f64]) -> f64 {
    let ok: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    ok.iter().sum::<f64>() / ok.len().max(1) as f64
}

fn max(v: &[f64]) -> f64 {
    v.iter()
        .copied()
        .filter(|x| x.is_finite())
        .fold(0.0, f64::max)
}

fn hours(s: f64) -> String {
    format!("{s:.0} s ({:.2} h)", s / 3600.0)
}

impl CommandPathRun {
    /// The command's name as the Movemaster spells it.
    pub fn command(&self) -> &'static str {
        match self.command_path {
            CommandPath::Cartesian => "MP",
            CommandPath::Joint => "MJ",
        }
    }

    /// A method's measured result, by name.
    pub fn result(&self, method: &str) -> Option<&PathResult> {
        self.results.iter().find(|r| r.model == method)
    }
}

impl Sec7Report {
    /// The division's figures.
    fn division_figures(&self) -> Option<&rigcal_calibration::DivisionFigures> {
        match &self.division.calibrated.figures {
            Figures::Division(d) => Some(d),
            Figures::Neural(_) => None,
        }
    }

    /// Regions of the division (leaves).
    pub fn regions(&self) -> usize {
        self.division_figures().map_or(0, |d| d.regions)
    }

    /// Identification measurements, and test measurements, of the division.
    pub fn measurements(&self) -> (usize, usize) {
        self.division_figures()
            .map_or((0, 0), |d| (d.measurements, d.test_measurements))
    }

    /// The run through `cp`, if made.
    pub fn run(&self, cp: CommandPath) -> Option<&CommandPathRun> {
        self.runs.iter().find(|r| r.command_path == cp)
    }

    /// Rig time on the dry-run clock, every session (s).
    pub fn rig_time_s(&self) -> f64 {
        self.division.report.rig_time_s
            + self.runs.iter().map(|r| r.session.rig_time_s).sum::<f64>()
    }

    /// Rig time as planned, every session (s).
    pub fn planned_s(&self) -> f64 {
        self.division_estimate.total_s + self.runs.iter().map(|r| r.estimate.total_s).sum::<f64>()
    }

    /// The experiment as `rigcal demo` prints it: the division, the sessions' rig time, then
    /// per command path each method's measured errors beside the floor of that command path.
    pub fn text(&self) -> String {
        let mut s = self.division.calibrated.text();
        let (ident, tests) = self.measurements();
        let d = &self.division.report;
        let _ = writeln!(
            s,
            "division session: {} measurements ({ident} identification, {tests} test; paper about {} × {} identification), {} skipped; registration RMS {}; rig time {} on the dry-run clock, {} as planned (paper: \"a couple of hours\")",
            d.ok,
            SEED_000.section7.regions,
            SEED_000.per_region,
            d.skipped.len(),
            d.registration_rms_mm.map_or("-".into(), |r| format!("{r:.3} mm")),
            hours(d.rig_time_s),
            hours(self.division_estimate.total_s),
        );
        let _ = writeln!(
            s,
            "regions used: {} (paper {}); {} without a measurable well-conditioned set of their own{}",
            self.regions(),
            SEED_000.section7.regions,
            self.unmeasurable.len(),
            if self.unmeasurable.is_empty() { String::new() } else { ":".into() }
        );
        for (id, why) in &self.unmeasurable {
            let _ = writeln!(s, "  {id}: {why}");
        }
        let paper = SEED_000.section7.paper_path_mm;
        let _ = writeln!(
            s,
            "{} ({} points, {:.0} mm; the paper's ({:.0}, {:.0}, {:.0}) → ({:.0}, {:.0}, {:.0}) mm lies outside the table's reach), measured by the rig itself:",
            self.path.name,
            self.path.points.len(),
            self.path_length_mm,
            paper[0][0], paper[0][1], paper[0][2],
            paper[1][0], paper[1][1], paper[1][2],
        );
        for run in &self.runs {
            s.push_str(&run.text());
        }
        let _ = writeln!(
            s,
            "rig time, all sessions: {} on the dry-run clock, {} as planned; wall {:.1} s",
            hours(self.rig_time_s()),
            hours(self.planned_s()),
            self.wall.as_secs_f64()
        );
        s
    }
}

impl CommandPathRun {
    /// This run's table: per method mean / max measured, and the floor.
    pub fn text(&self) -> String {
        let mut s = format!(
            "  through {} ({} command path), mean / max mm (floor: the {} rounding alone):\n",
            self.command(),
            self.command_path,
            self.command()
        );
        for (r, f) in self.results.iter().zip(&self.floors_mm) {
            let missed = r.errors.iter().filter(|e| !e.is_finite()).count();
            let _ = writeln!(
                s,
                "    {:<13} {:.3} / {:.3}   floor {:.3} / {:.3}{}",
                r.model,
                mean(&r.errors),
                max(&r.errors),
                mean(f),
                max(f),
                if missed > 0 {
                    format!("   {missed} point(s) not measured")
                } else {
                    String::new()
                }
            );
        }
        let _ = writeln!(
            s,
            "    session: {} points, {} skipped, rig time {} on the dry-run clock, {} as planned",
            self.session.points,
            self.session.skipped.len(),
            hours(self.session.rig_time_s),
            hours(self.estimate.total_s)
        );
        s
    }
}

/// The experiment's figures as data (the demo's `summary.json` rig part).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Sec7Summary {
    /// The scenario.
    pub scenario: String,
    /// The path's name.
    pub path: String,
    /// Its length (mm).
    pub path_length_mm: f64,
    /// Demanded accuracy (mm).
    pub accuracy_mm: f64,
    /// Regions of the division (leaves).
    pub regions: usize,
    /// The paper's.
    pub paper_regions: usize,
    /// Identification measurements of the division.
    pub measurements: usize,
    /// Test measurements of the division.
    pub test_measurements: usize,
    /// Leaves without a measurable well-conditioned set of their own.
    pub unmeasurable_regions: Vec<String>,
    /// Rig hours as planned, every session.
    pub rig_hours_planned: f64,
    /// Rig hours on the dry-run clock, every session.
    pub rig_hours_clock: f64,
    /// Per command path, each method measured by the rig.
    pub command_paths: Vec<CommandPathSummary>,
}

/// One command path's figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CommandPathSummary {
    /// `cartesian` or `joint`.
    pub command_path: CommandPath,
    /// `MP` or `MJ`.
    pub command: String,
    /// Each method: mean and max of the measured distance to target.
    pub methods: Vec<rigcal_calibration::MethodFigures>,
    /// Each method's floor (the command path's rounding alone), mean and max (mm).
    pub floors: Vec<FloorFigures>,
}

/// A method's floor along the path.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FloorFigures {
    /// The method.
    pub method: String,
    /// Mean (mm).
    pub mean_mm: f64,
    /// Max (mm).
    pub max_mm: f64,
}

impl Sec7Report {
    /// The figures as data.
    pub fn summary(&self) -> Sec7Summary {
        let (measurements, test_measurements) = self.measurements();
        Sec7Summary {
            scenario: self.scenario.display().to_string(),
            path: self.path.name.clone(),
            path_length_mm: self.path_length_mm,
            accuracy_mm: self.division_figures().map_or(0.0, |d| d.accuracy_mm),
            regions: self.regions(),
            paper_regions: SEED_000.section7.regions,
            measurements,
            test_measurements,
            unmeasurable_regions: self.unmeasurable.iter().map(|(id, _)| id.clone()).collect(),
            rig_hours_planned: self.planned_s() / 3600.0,
            rig_hours_clock: self.rig_time_s() / 3600.0,
            command_paths: self
                .runs
                .iter()
                .map(|r| CommandPathSummary {
                    command_path: r.command_path,
                    command: r.command().into(),
                    methods: r
                        .results
                        .iter()
                        .map(|m| rigcal_calibration::MethodFigures::of(m, &[]))
                        .collect(),
                    floors: r
                        .results
                        .iter()
                        .zip(&r.floors_mm)
                        .map(|(m, f)| FloorFigures {
                            method: m.model.clone(),
                            mean_mm: mean(f),
                            max_mm: max(f),
                        })
                        .collect(),
                })
                .collect(),
        }
    }

    /// Plots each command path's measured distances along the path into `dir` (SVG), one file
    /// per command path: the files written.
    pub fn plot(&self, dir: &Path) -> Result<Vec<PathBuf>, CalibrationError> {
        std::fs::create_dir_all(dir).map_err(|source| CalibrationError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        let mut files = Vec::new();
        for r in &self.runs {
            let file = dir.join(format!("sec7-path-{}-measured-errors.svg", r.command_path));
            rigcal_model::report::plot_errors(
                &file,
                &format!(
                    "distance to target measured by the rig through {} along {}",
                    r.command(),
                    self.path.name
                ),
                &r.results,
            )?;
            files.push(file);
        }
        Ok(files)
    }
}

/// Seed 000's Fig. 10 e–g for the rig: the traced CEPs (Δθ1, Δd1, Δa1, Δα1) of conventional
/// calibration, the regions and the FCMAC along section 7's path, from the experiment's model
/// file, into `dir/sec7-path-ceps.svg` and `.csv`.
pub fn rig_cep_plot(
    report: &Sec7Report,
    preset: &Preset,
    dir: &Path,
) -> Result<rigcal_calibration::path_figures::CepTraceFiles, CalibrationError> {
    rigcal_calibration::path_figures::write_cep_traces(
        &report.model_file,
        &report.path,
        &preset.traced_ceps(),
        dir,
        "sec7-path-ceps",
    )
}
