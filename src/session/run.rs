//! Running a session: registration, then every planned point, each row appended and flushed
//! before the next motion, the journal committed after each point.
//!
//! Per point: the arm goes to a pre-approach (via) pose while the table travels to the approach
//! start (both move at once: the table's move is started, then the arm's is awaited — on the real
//! clock in its own thread — then the table's), the arm goes on to the target, and a two-stage
//! contact follows: a locating approach at `fast_mm_s`, a back-off, and the final approach at the
//! latency-rule speed (conventions §8). A missed touch or a retryable device error is retried
//! with doubling backoff; a drive fault is cleared with `fault_reset`, an arm position error
//! (mode II) with `reset`; a hardware error, a lost heartbeat or a configuration error stops the
//! session (resume with `--resume` after clearing the cause). A point the rig cannot measure, or
//! one still failing after the last attempt, becomes a `skipped: REASON` row.
//!
//! On a point-sensor rig (a tracker, or the ideal instrument of the papers' simulations) a point
//! is the via pose, the target, and one sensor reading; there is no registration step (the
//! sensor's frame is the world, or free and fitted with the kinematics, conventions §1).
//!
//! Rows (conventions §6): `via` for the pre-approach and registration moves, `ok` for a
//! measurement, `skipped: …` for a point given up. Measurement draws of the simulated world are
//! keyed by (seed, seq, attempt).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Vector3};

use crate::devices::contact::{approach_speed, measure_contact, Contact};
use crate::devices::{DeviceError, OpenedRig, RigDevices, RigHook};
use crate::identification::{register, Observation};
use crate::kinematics::{ErrorParams, Robot};
use crate::recording::{
    write_session, Measurement, RecordingError, RecordingWriter, RegistrationInfo, SessionInfo,
    Status,
};
use crate::rig::Rig;
use crate::session::journal::{Journal, JournalError};
use crate::session::plan::{
    approach_signs, registration_candidates, table_target, via_pose, ContactSettings, PlannedPoint,
};

/// The recording's file name in a session directory.
pub const CSV_FILE: &str = "measurements.csv";

/// Timeout of a single device exchange.
const IO: Duration = Duration::from_secs(2);
/// Timeout of an arm or table move.
const MOVE: Duration = Duration::from_secs(120);

/// What stopped a session.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SessionError {
    /// A device failed in a way the session cannot clear by itself.
    #[error("{stage}: {source}; the session stopped with every finished point saved: clear the cause, then run again with --resume")]
    Device {
        /// What the session was doing.
        stage: String,
        /// The device's error.
        source: DeviceError,
    },
    /// The recording could not be written.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The journal could not be written or read.
    #[error(transparent)]
    Journal(#[from] JournalError),
    /// The registration step failed.
    #[error("registration: {0}; check that the panel sees the pin at the registration poses")]
    Registration(String),
    /// `--resume` without a journal.
    #[error("{dir}: no session journal to resume from; start a new session (without --resume)")]
    NothingToResume {
        /// The directory.
        dir: PathBuf,
    },
    /// A new session would overwrite a recording.
    #[error(
        "{dir} already holds a recording; resume it with --resume or choose another directory"
    )]
    AlreadyExists {
        /// The directory.
        dir: PathBuf,
    },
    /// A resumed planning-mode session was asked for other joints than its recording holds.
    #[error("point {point}: the division asks for joints {asked_deg:?}° where the recording holds {recorded_deg:?}°; resume with the same rig, scenario, seed and division options as the first run")]
    ResumeDiverged {
        /// 1-based point number.
        point: usize,
        /// Joints asked for (deg or mm).
        asked_deg: Vec<f64>,
        /// Joints recorded (deg or mm).
        recorded_deg: Vec<f64>,
    },
    /// A file operation failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// How to run a session.
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// Output directory (measurements.csv, session.toml, journal.json).
    pub dir: PathBuf,
    /// Continue the session in `dir` from its journal.
    pub resume: bool,
    /// Poses of the registration step.
    pub registration_points: usize,
    /// Attempts per point before it is skipped.
    pub max_attempts: u32,
    /// First retry backoff (doubles per attempt).
    pub backoff: Duration,
    /// Contact settings.
    pub contact: ContactSettings,
    /// Seed of the registration poses.
    pub seed: u64,
    /// fsync each row and the journal (on by default; a dry run on the virtual clock may turn it
    /// off: a killed process loses nothing that was written).
    pub fsync: bool,
    /// What goes into session.toml besides the registration.
    pub info: SessionInfo,
    /// A registration to reuse (another session's, same rig set-up) instead of the
    /// registration step: both recordings are then in one frame.
    pub registration: Option<RegistrationInfo>,
}

impl SessionOptions {
    /// Defaults for a directory.
    pub fn new(dir: &Path) -> Self {
        SessionOptions {
            dir: dir.to_path_buf(),
            resume: false,
            registration_points: 12,
            max_attempts: 3,
            backoff: Duration::from_millis(200),
            contact: ContactSettings::default(),
            seed: 1,
            fsync: true,
            info: SessionInfo::default(),
            registration: None,
        }
    }
}

/// What a session did.
#[derive(Debug, Clone, Default)]
pub struct SessionReport {
    /// Planned points.
    pub points: usize,
    /// Points measured by this run (including earlier runs when resumed: see `resumed_at`).
    pub ok: usize,
    /// Points skipped, with the full reason.
    pub skipped: Vec<(usize, String)>,
    /// `via` rows written.
    pub via: usize,
    /// Retries made.
    pub retries: usize,
    /// Passes begun beyond one per region run, where the travel clearance had to go lower than
    /// the ascending-z rule allows within a pass.
    pub extra_passes: usize,
    /// Faults cleared (drive fault reset, arm reset).
    pub faults_cleared: Vec<String>,
    /// Session time at the end (s): the rig time the session took (virtual clock on a dry run).
    pub rig_time_s: f64,
    /// Wall time of this run.
    pub wall: Duration,
    /// RMS of the registration fit (mm).
    pub registration_rms_mm: Option<f64>,
    /// The point index this run resumed at.
    pub resumed_at: Option<usize>,
}

/// Progress output: a bar with rate and ETA on a terminal, plain lines otherwise.
#[derive(Debug)]
pub enum Progress {
    /// No output.
    Quiet,
    /// A log line every `every` points.
    Lines {
        /// Points between lines.
        every: usize,
        /// Started at.
        started: Instant,
    },
    /// An indicatif bar.
    Bar(indicatif::ProgressBar),
}

impl Progress {
    /// A bar if stderr is a terminal, lines otherwise.
    pub fn auto(total: usize) -> Progress {
        if std::io::stderr().is_terminal() {
            let bar = indicatif::ProgressBar::new(total as u64);
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} points  {per_sec}  ETA {eta}  {msg}",
            ) {
                bar.set_style(style);
            }
            Progress::Bar(bar)
        } else {
            Progress::Lines {
                every: (total / 10).max(1),
                started: Instant::now(),
            }
        }
    }

    fn update(&self, done: usize, total: usize, rig_s: f64) {
        match self {
            Progress::Quiet => {}
            Progress::Lines { every, started } => {
                if done.is_multiple_of(*every) || done == total {
                    let el = started.elapsed().as_secs_f64();
                    eprintln!(
                        "session: {done}/{total} points, rig time {:.0} s, {:.1} points/s",
                        rig_s,
                        done as f64 / el.max(1e-9)
                    );
                }
            }
            Progress::Bar(b) => {
                b.set_position(done as u64);
                b.set_message(format!("rig {:.0} s", rig_s));
            }
        }
    }

    fn finish(&self) {
        if let Progress::Bar(b) = self {
            b.finish();
        }
    }
}

/// How one point ended.
enum Outcome {
    /// A contact on the table rig.
    Measured(Contact),
    /// A point sensor's reading (sensor frame, mm).
    Seen([f64; 3]),
    Skipped(String),
}

struct Runner<'a> {
    rig: &'a Rig,
    dev: RigDevices,
    hook: Box<dyn RigHook>,
    opts: SessionOptions,
    writer: RecordingWriter,
    csv: PathBuf,
    seq: u64,
    rows: u64,
    /// Session time (s) = clock (s) + offset.
    offset_s: f64,
    registration: Isometry3<f64>,
    registration_info: Option<RegistrationInfo>,
    arm_q: Option<Vec<f64>>,
    table_at: Option<[f64; 3]>,
    pass_region: Option<String>,
    pass_top: Option<f64>,
    retract_mm: f64,
    travel_mm_s: f64,
    travel_z: f64,
    approach_mm_s: f64,
    report: SessionReport,
}

fn dev(stage: impl Into<String>) -> impl FnOnce(DeviceError) -> SessionError {
    let stage = stage.into();
    move |source| SessionError::Device { stage, source }
}

/// Runs (or resumes) a session over `points` on the rig the factory opened.
pub fn run_session(
    rig: &Rig,
    opened: OpenedRig,
    points: &[PlannedPoint],
    opts: SessionOptions,
    progress: &Progress,
) -> Result<SessionReport, SessionError> {
    let mut session = Session::open(rig, opened, opts)?;
    session.r.report.points = points.len();
    let start_point = session.next_point;
    for (i, p) in points.iter().enumerate().skip(start_point) {
        session.measure_point(p, i + 1 == points.len())?;
        progress.update(i + 1, points.len(), session.r.now_s());
    }
    progress.finish();
    session.finish()
}

/// An open session: the arm homed, the instrument ready, the recording open, the registration
/// done (or restored from the journal on a resume). Points are measured one at a time — from a
/// plan ([`run_session`]) or as a division asks for them in planning mode
/// ([`SessionMeasurer`](crate::session::SessionMeasurer)); each point's rows are flushed and the
/// journal committed before the next motion.
pub struct Session<'a> {
    r: Runner<'a>,
    started: Instant,
    next_point: usize,
}

impl std::fmt::Debug for Session<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("dir", &self.r.opts.dir)
            .field("next_point", &self.next_point)
            .finish_non_exhaustive()
    }
}

impl<'a> Session<'a> {
    /// Opens (or, with `opts.resume`, resumes) a session on `devices`.
    pub fn open(
        rig: &'a Rig,
        opened: OpenedRig,
        opts: SessionOptions,
    ) -> Result<Self, SessionError> {
        let started = Instant::now();
        let OpenedRig { mut devices, hook } = opened;
        let dir = opts.dir.clone();
        std::fs::create_dir_all(&dir).map_err(|source| SessionError::Io {
            path: dir.clone(),
            source,
        })?;
        let csv = dir.join(CSV_FILE);
        let cfg = rig.devices.clone().unwrap_or_default();
        devices.arm.home(MOVE).map_err(dev("homing the arm"))?;
        devices
            .arm
            .set_speed(cfg.arm.speed, IO)
            .map_err(dev("setting the arm speed"))?;
        // The table's contact speed follows the latency rule; a point sensor needs none.
        let approach_mm_s = match devices.table_and_panel() {
            Ok((table, panel)) => {
                table.enable(IO * 5).map_err(dev("enabling the table"))?;
                approach_speed(panel.latency(), table.latency(), cfg.panel.max_overshoot_mm)
            }
            Err(_) => 0.0,
        };
        let joints = rig.chain.joints();
        let journal = if opts.resume {
            match Journal::load(&dir) {
                Ok(j) => Some(j),
                Err(JournalError::Io { source, .. })
                    if source.kind() == std::io::ErrorKind::NotFound =>
                {
                    return Err(SessionError::NothingToResume { dir });
                }
                Err(e) => return Err(e.into()),
            }
        } else {
            if csv.exists() {
                return Err(SessionError::AlreadyExists { dir });
            }
            None
        };
        let writer = match &journal {
            Some(j) => {
                let f = std::fs::OpenOptions::new()
                    .write(true)
                    .open(&csv)
                    .map_err(|source| SessionError::Io {
                        path: csv.clone(),
                        source,
                    })?;
                f.set_len(j.csv_bytes).map_err(|source| SessionError::Io {
                    path: csv.clone(),
                    source,
                })?;
                RecordingWriter::open_append(&csv, joints, &[])?.0
            }
            None => RecordingWriter::create(&csv, joints, &[])?,
        }
        .sync_each_row(opts.fsync);
        let mut r = Runner {
            rig,
            hook,
            writer,
            csv,
            seq: 1,
            rows: 0,
            offset_s: 0.0,
            registration: Isometry3::identity(),
            registration_info: None,
            arm_q: devices.arm.commanded(),
            table_at: None,
            pass_region: None,
            pass_top: None,
            retract_mm: cfg.table.pass_retract_mm,
            travel_mm_s: cfg.table.profile_velocity_mm_s,
            travel_z: match &rig.instrument {
                crate::rig::Instrument::TablePanel(tp) => tp.travel_mm.z,
                _ => f64::MAX,
            },
            approach_mm_s,
            report: SessionReport::default(),
            dev: devices,
            opts,
        };
        let next_point = match journal {
            Some(j) => r.resume_from(&j)?,
            None => {
                r.offset_s = -r.dev.clock.now().as_secs_f64();
                r.set_time_base();
                r.commit(0, false)?;
                r.registration_step()?;
                r.commit(0, false)?;
                0
            }
        };
        if next_point > 0 || r.opts.resume {
            r.report.resumed_at = Some(next_point);
            r.report.points = next_point;
        }
        Ok(Session {
            r,
            started,
            next_point,
        })
    }

    /// Points finished so far (including earlier runs of a resumed session).
    pub fn points_done(&self) -> usize {
        self.next_point
    }

    /// Session time now (s): the rig time so far.
    pub fn rig_time_s(&self) -> f64 {
        self.r.now_s()
    }

    /// Measures `p` (or writes why it cannot be), then commits the journal; `last` marks the
    /// session finished in it. Returns the joints the arm was commanded to (after the
    /// controller's resolution) with the measured position (world, mm); `None` for a skip.
    pub fn measure_point(
        &mut self,
        p: &PlannedPoint,
        last: bool,
    ) -> Result<Option<Observation>, SessionError> {
        let measured = self.r.point(p)?;
        self.next_point += 1;
        self.r.report.points = self.r.report.points.max(self.next_point);
        self.r.commit(self.next_point, last)?;
        Ok(measured)
    }

    /// Ends the session: the journal marked finished, the report with the rig and wall time.
    pub fn finish(mut self) -> Result<SessionReport, SessionError> {
        self.r.commit(self.next_point, true)?;
        self.r.report.rig_time_s = self.r.now_s();
        self.r.report.wall = self.started.elapsed();
        Ok(self.r.report)
    }
}

impl Runner<'_> {
    fn now_s(&self) -> f64 {
        self.dev.clock.now().as_secs_f64() + self.offset_s
    }

    fn set_time_base(&mut self) {
        self.hook.time_base(self.offset_s);
    }

    fn set_draws(&mut self, seq: u64, attempt: u32) {
        self.hook.before_measurement(seq, attempt);
    }

    fn resume_from(&mut self, j: &Journal) -> Result<usize, SessionError> {
        if let Some(q) = &j.arm_q {
            let q = self
                .dev
                .arm
                .move_to(q, MOVE)
                .map_err(dev("moving the arm back to its last pose"))?;
            self.arm_q = Some(q);
        }
        if let Some(t) = j.table_mm.filter(|_| self.dev.has_table()) {
            self.pass_top = None;
            let at = self.table_back(t).map_err(dev("moving the table back"))?;
            self.table_at = Some(at);
        }
        if let Some(state) = &j.rig_state {
            self.hook
                .restore(state)
                .map_err(|e| JournalError::Corrupt {
                    path: Journal::path(&self.opts.dir),
                    reason: e.to_string(),
                })?;
        }
        self.offset_s = j.clock_s - self.dev.clock.now().as_secs_f64();
        self.set_time_base();
        self.seq = j.next_seq;
        self.rows = j.rows;
        match &j.registration {
            Some(info) => {
                self.registration =
                    crate::rig::pose_from_xyz_rpy(info.translation_mm, info.rpy_deg);
                self.registration_info = Some(*info);
            }
            None => {
                // Killed during the registration step, or a point-sensor rig (none to do): the
                // journal keeps the point reached, never rewinds it.
                self.registration_step()?;
                self.commit(j.next_point, false)?;
            }
        }
        Ok(j.next_point)
    }

    /// Returns the table to `t` on a resume (a new pass: it may have to go down).
    fn table_back(&mut self, t: [f64; 3]) -> Result<[f64; 3], DeviceError> {
        let table = self.dev.table()?;
        table.begin_pass();
        table.set_speed(self.travel_mm_s, IO)?;
        table.start_move(t, IO)?;
        table.wait_reached(MOVE)
    }

    /// Saves the journal: the state after the last finished point.
    fn commit(&mut self, next_point: usize, finished: bool) -> Result<(), SessionError> {
        let csv_bytes = std::fs::metadata(&self.csv)
            .map_err(|source| SessionError::Io {
                path: self.csv.clone(),
                source,
            })?
            .len();
        let j = Journal {
            version: 1,
            next_point,
            next_seq: self.seq,
            clock_s: self.now_s(),
            rig_state: self.hook.snapshot(),
            arm_q: self.arm_q.clone(),
            table_mm: self.table_at,
            registration: self.registration_info,
            csv_bytes,
            rows: self.rows,
            finished,
        };
        j.save_with(&self.opts.dir, self.opts.fsync)?;
        Ok(())
    }

    fn write(&mut self, m: Measurement) -> Result<(), SessionError> {
        self.writer.append(&m)?;
        self.rows += 1;
        self.seq += 1;
        Ok(())
    }

    fn row(&self, q: Vec<f64>, region: &str, status: Status) -> Measurement {
        Measurement {
            seq: self.seq,
            t_s: Some(self.now_s()),
            q,
            region: Some(region.to_string()),
            status,
            ..Default::default()
        }
    }

    /// Moves the arm to `q` while the table travels to `table` (both at once).
    fn move_both(&mut self, q: &[f64], table: [f64; 3]) -> Result<Vec<f64>, DeviceError> {
        self.dev.table()?.set_speed(self.travel_mm_s, IO)?;
        self.start_move(table)?;
        let virtual_clock = self.dev.clock.is_virtual();
        let (arm, tab) = self.dev.arm_and_table()?;
        let (a, t) = if virtual_clock {
            // Deterministic: the table moves on its profile while the arm's wait advances the
            // shared virtual clock.
            let a = arm.move_to(q, MOVE);
            let t = tab.wait_reached(MOVE);
            (a, t)
        } else {
            std::thread::scope(|s| {
                let h = s.spawn(|| arm.move_to(q, MOVE));
                let t = tab.wait_reached(MOVE);
                let a = h.join().unwrap_or_else(|_| {
                    Err(DeviceError::NotReady {
                        device: crate::devices::DeviceName::Arm,
                        detail: "the arm thread panicked; home the arm before going on".into(),
                    })
                });
                (a, t)
            })
        };
        match t {
            Ok(p) => self.table_at = Some(p),
            Err(e) => {
                let _ = a;
                return Err(e);
            }
        }
        let q = a?;
        self.arm_q = Some(q.clone());
        Ok(q)
    }

    /// From wherever the table stands to the approach start `start` while the arm goes to `via`:
    /// down to a clearance height first, then x-y with the arm (at once), then up.
    fn travel(&mut self, via: &[f64], start: [f64; 3]) -> Result<Vec<f64>, DeviceError> {
        let here = match self.table_at {
            Some(p) => p,
            None => self.dev.table()?.position(IO)?,
        };
        // Below the current height, the next approach start and the via pose's tip.
        let via_z =
            table_target(self.rig, via).map_or(start[2], |t| t[2] - self.opts.contact.margin_mm);
        let clear = (here[2].min(start[2]).min(via_z) - self.opts.contact.clearance_mm).max(0.0);
        if let Some(top) = self.pass_top {
            if clear < top - self.retract_mm {
                // Going this low breaks the ascending pass: start a new one (away from the pin).
                self.dev.table()?.begin_pass();
                self.pass_top = None;
                self.report.extra_passes += 1;
            }
        }
        if here[2] > clear + 1e-3 {
            self.dev.table()?.set_speed(self.travel_mm_s, IO)?;
            self.start_move([here[0], here[1], clear])?;
            self.table_at = Some(self.dev.table()?.wait_reached(MOVE)?);
        }
        self.move_both(via, [start[0], start[1], clear])
    }

    /// Starts a table move and tracks the pass's top.
    fn start_move(&mut self, target: [f64; 3]) -> Result<(), DeviceError> {
        self.dev.table()?.start_move(target, IO)?;
        self.pass_top = Some(self.pass_top.map_or(target[2], |z| z.max(target[2])));
        Ok(())
    }

    /// Clears what the protocol allows; false if the error must stop the session.
    fn recover(&mut self, e: &DeviceError) -> Result<bool, SessionError> {
        if arm_lost_track(e) {
            // The controller may have executed a command whose reply was lost (MJ moves are
            // relative): home again so the driver knows the joints, then retry.
            return match self.dev.arm.home(MOVE) {
                Ok(nest) => {
                    self.report
                        .faults_cleared
                        .push(format!("arm re-homed after: {e}"));
                    self.arm_q = Some(nest.clone());
                    let m = self.row(nest, "home", Status::Via);
                    self.report.via += 1;
                    self.write(m)?;
                    Ok(true)
                }
                Err(_) => Ok(false),
            };
        }
        Ok(match e {
            DeviceError::DriveFault { .. } | DeviceError::FollowingError { .. } => {
                self.dev.halt_table(IO);
                match self.dev.table().and_then(|t| t.fault_reset(IO * 5)) {
                    Ok(()) => {
                        self.report.faults_cleared.push(format!("table: {e}"));
                        true
                    }
                    Err(_) => false,
                }
            }
            DeviceError::ArmErrorMode { code: 2, .. } => match self.dev.arm.reset(IO) {
                Ok(()) => {
                    self.report.faults_cleared.push(format!("arm: {e}"));
                    true
                }
                Err(_) => false,
            },
            other => other.is_retryable(),
        })
    }

    fn fatal(e: &DeviceError) -> bool {
        matches!(
            e,
            DeviceError::ArmErrorMode { code: 1, .. }
                | DeviceError::HeartbeatLost { .. }
                | DeviceError::Config { .. }
                | DeviceError::NotReady { .. }
                | DeviceError::ResetNotSafe { .. }
        )
    }

    /// The pass rule: a new ascending-z pass whenever the region changes (and for every
    /// registration pose).
    fn pass(&mut self, region: &str) {
        if self.pass_region.as_deref() != Some(region) || region == "reg" {
            if let Ok(t) = self.dev.table() {
                t.begin_pass();
            }
            self.pass_top = None;
            self.pass_region = Some(region.to_string());
        }
    }

    /// Measures at `q` with the table under `table_nominal`: via move, final move, two-stage
    /// contact, retries.
    fn measure(
        &mut self,
        point: usize,
        region: &str,
        q: &[f64],
        nominal: [f64; 3],
    ) -> Result<(Vec<f64>, Outcome), SessionError> {
        let c = self.opts.contact;
        let signs = approach_signs(self.rig, point);
        let via = via_pose(self.rig, q, &signs, c.via_delta);
        let zmax = self.travel_z;
        let mut start = [nominal[0], nominal[1], (nominal[2] - c.margin_mm).max(0.0)];
        let end_z = (nominal[2] + c.margin_mm).min(zmax);
        self.pass(region);
        // 1. Via pose, the table to the approach start — or lower, when the via pose (a small
        // joint offset away, to set the approach directions) brings the pin below the approach
        // start: the panel must never sit above the pin while the arm moves onto the target.
        let via_z = crate::session::plan::table_target(self.rig, &via)
            .map_or(start[2], |t| t[2] - c.margin_mm);
        let via_start = [start[0], start[1], start[2].min(via_z).max(0.0)];
        if let Some(out) = self.via_move(region, |r| r.travel(&via, via_start))? {
            return Ok((q.to_vec(), out));
        }
        // 2. The target, then the contact.
        let mut attempt = 0u32;
        let mut commanded: Option<Vec<f64>> = None;
        loop {
            let mut pin_on_panel = false;
            let step: Result<Contact, DeviceError> = (|| {
                if commanded.is_none() {
                    self.set_draws(self.seq, attempt);
                    let done = self.dev.arm.move_to(q, MOVE)?;
                    self.arm_q = Some(done.clone());
                    commanded = Some(done);
                }
                // Back to the approach start (a retry): from wherever the table was halted.
                let here = match self.table_at {
                    Some(p) => p,
                    None => self.dev.table()?.position(IO)?,
                };
                if let Some(top) = self.pass_top {
                    if start[2] < top - self.retract_mm {
                        // Down and away from the pin: a new pass.
                        self.dev.table()?.begin_pass();
                        self.pass_top = None;
                        self.report.extra_passes += 1;
                    }
                }
                if (here[2] - start[2]).abs() > 1e-3 || (here[0] - start[0]).abs() > 1e-3 {
                    self.dev.table()?.set_speed(self.travel_mm_s, IO)?;
                    self.start_move(start)?;
                    self.table_at = Some(self.dev.table()?.wait_reached(MOVE)?);
                }
                let xy = [start[0], start[1]];
                let timeout = |d: f64, v: f64| Duration::from_secs_f64(2.0 * d / v + 2.0);
                let (table, panel) = self.dev.table_and_panel()?;
                let first = measure_contact(
                    table,
                    panel,
                    xy,
                    start[2],
                    end_z,
                    c.fast_mm_s,
                    timeout(end_z - start[2], c.fast_mm_s),
                );
                self.table_at = None;
                self.pass_top = Some(self.pass_top.map_or(end_z, |z| z.max(end_z)));
                let first = first?;
                if first.table_mm[2] <= start[2] + 0.01 {
                    pin_on_panel = true;
                    return Err(bad_touch(format!(
                        "touch at the approach start (z {:.3} mm): the pin was already on the panel",
                        first.table_mm[2]
                    )));
                }
                let off = |t: &Contact| t.touch.u_mm.abs().max(t.touch.v_mm.abs());
                if off(&first) > c.max_offset_mm {
                    return Err(bad_touch(format!(
                        "touch at ({:.2}, {:.2}) mm from the panel centre, more than {} mm: a stale or misread packet",
                        first.touch.u_mm, first.touch.v_mm, c.max_offset_mm
                    )));
                }
                let back = (first.table_mm[2] - c.backoff_mm).max(0.0);
                self.dev.table()?.set_speed(self.travel_mm_s, IO)?;
                self.start_move([xy[0], xy[1], back])?;
                self.dev.table()?.wait_reached(MOVE)?;
                let top = (first.table_mm[2] + 2.0 * c.backoff_mm).min(zmax);
                let (table, panel) = self.dev.table_and_panel()?;
                let fin = measure_contact(
                    table,
                    panel,
                    xy,
                    back,
                    top,
                    self.approach_mm_s,
                    timeout(top - back, self.approach_mm_s),
                );
                self.pass_top = Some(self.pass_top.map_or(top, |z| z.max(top)));
                let fin = fin?;
                self.table_at = Some(fin.table_mm);
                let du = (fin.touch.u_mm - first.touch.u_mm).abs();
                let dv = (fin.touch.v_mm - first.touch.v_mm).abs();
                if du.max(dv) > 1.0 || fin.table_mm[2] < back - 0.01 {
                    return Err(bad_touch(format!(
                        "final touch at ({:.2}, {:.2}) mm, z {:.3} mm disagrees with the locating touch at ({:.2}, {:.2}) mm, z {:.3} mm",
                        fin.touch.u_mm, fin.touch.v_mm, fin.table_mm[2], first.touch.u_mm, first.touch.v_mm, first.table_mm[2]
                    )));
                }
                Ok(fin)
            })();
            match step {
                Ok(contact) => {
                    return Ok((
                        commanded.unwrap_or_else(|| q.to_vec()),
                        Outcome::Measured(contact),
                    ))
                }
                Err(e) => {
                    if arm_lost_track(&e) || matches!(e, DeviceError::ArmErrorMode { .. }) {
                        commanded = None;
                    }
                    if pin_on_panel {
                        // The pin is lower than the nominal kinematics say, by more than the
                        // margin: start the next attempt lower, never from the same place.
                        start[2] = (start[2] - c.margin_mm).max(0.0);
                    }
                    if let Some(out) = self.handle(&e, &mut attempt, "measuring")? {
                        return Ok((commanded.unwrap_or_else(|| q.to_vec()), out));
                    }
                }
            }
        }
    }

    /// The move to a point's via pose by `step` (the arm alone, or arm and table together),
    /// retried like any device error, and its `via` row; `Some` when the point is given up.
    fn via_move(
        &mut self,
        region: &str,
        mut step: impl FnMut(&mut Self) -> Result<Vec<f64>, DeviceError>,
    ) -> Result<Option<Outcome>, SessionError> {
        let mut attempt = 0u32;
        loop {
            self.set_draws(self.seq, attempt);
            match step(self) {
                Ok(done) => {
                    self.arm_q = Some(done.clone());
                    let m = self.row(done, region, Status::Via);
                    self.write(m)?;
                    self.report.via += 1;
                    return Ok(None);
                }
                Err(e) => {
                    if let Some(out) = self.handle(&e, &mut attempt, "moving to the via pose")? {
                        return Ok(Some(out));
                    }
                }
            }
        }
    }

    /// Decides about an error: Ok(None) to retry, Ok(Some(skip)) to give up the point, Err to
    /// stop the session.
    fn handle(
        &mut self,
        e: &DeviceError,
        attempt: &mut u32,
        stage: &str,
    ) -> Result<Option<Outcome>, SessionError> {
        if Self::fatal(e) {
            self.dev.halt_table(IO);
            return Err(SessionError::Device {
                stage: format!("point seq {}: {stage}", self.seq),
                source: clone_error(e),
            });
        }
        if matches!(e, DeviceError::Refused { .. }) {
            return Ok(Some(Outcome::Skipped(format!(
                "refused by the safety limits: {e}"
            ))));
        }
        if !self.recover(e)? {
            self.dev.halt_table(IO);
            return Err(SessionError::Device {
                stage: format!("point seq {}: {stage}", self.seq),
                source: clone_error(e),
            });
        }
        *attempt += 1;
        if *attempt >= self.opts.max_attempts {
            return Ok(Some(Outcome::Skipped(format!(
                "{} after {} attempts ({stage})",
                short_reason(e),
                attempt
            ))));
        }
        self.report.retries += 1;
        tracing::info!("retrying ({stage}, attempt {}): {e}", *attempt + 1);
        self.dev
            .clock
            .sleep(self.opts.backoff * 2u32.saturating_pow(*attempt - 1));
        Ok(None)
    }

    /// The table position under the nominal tip at `q` through the session's registration (the
    /// plan's targets use the rig file's nominal table pose, which the registration corrects).
    fn registered_table_target(&self, q: &[f64]) -> Option<[f64; 3]> {
        self.registration_info?;
        let tip = self
            .rig
            .chain
            .position(q, &ErrorParams::zeros(self.rig.chain.layout()));
        let t = self.registration.inverse() * nalgebra::Point3::from(tip);
        Some([t.x, t.y, t.z])
    }

    /// Measures at `q` with a point sensor: via move, final move, one reading, retries.
    fn sight(
        &mut self,
        point: usize,
        region: &str,
        q: &[f64],
    ) -> Result<(Vec<f64>, Outcome), SessionError> {
        let signs = approach_signs(self.rig, point);
        let via = via_pose(self.rig, q, &signs, self.opts.contact.via_delta);
        if let Some(out) = self.via_move(region, |r| r.dev.arm.move_to(&via, MOVE))? {
            return Ok((q.to_vec(), out));
        }
        let mut attempt = 0u32;
        let mut commanded: Option<Vec<f64>> = None;
        loop {
            self.set_draws(self.seq, attempt);
            let step: Result<[f64; 3], DeviceError> = (|| {
                if commanded.is_none() {
                    let done = self.dev.arm.move_to(q, MOVE)?;
                    self.arm_q = Some(done.clone());
                    commanded = Some(done);
                }
                self.dev.sensor()?.read(IO)
            })();
            match step {
                Ok(p) => return Ok((commanded.unwrap_or_else(|| q.to_vec()), Outcome::Seen(p))),
                Err(e) => {
                    if arm_lost_track(&e) || matches!(e, DeviceError::ArmErrorMode { .. }) {
                        commanded = None;
                    }
                    if let Some(out) = self.handle(&e, &mut attempt, "reading the sensor")? {
                        return Ok((commanded.unwrap_or_else(|| q.to_vec()), out));
                    }
                }
            }
        }
    }

    /// Measures one point and writes its rows; the commanded joints and measured position.
    fn point(&mut self, p: &PlannedPoint) -> Result<Option<Observation>, SessionError> {
        if let Err(reason) = self.rig.measurable(&p.q) {
            let m = self.row(p.q.clone(), &p.region, Status::Skipped(reason.to_string()));
            self.report.skipped.push((p.point, reason.to_string()));
            self.write(m)?;
            return Ok(None);
        }
        let (q, out) = if self.dev.has_table() {
            let target = self.registered_table_target(&p.q).unwrap_or(p.table_mm);
            self.measure(p.point, &p.region, &p.q, target)?
        } else {
            self.sight(p.point, &p.region, &p.q)?
        };
        let m = match out {
            Outcome::Seen(reading) => {
                let mut m = self.row(q, &p.region, Status::Ok);
                m.position = Some(Vector3::from(reading));
                m
            }
            Outcome::Measured(c) => {
                let t = Vector3::from(c.point_table_mm());
                let mut m = self.row(q, &p.region, Status::Ok);
                m.table = Some(t);
                m.panel_uv = Some([c.touch.u_mm, c.touch.v_mm]);
                m.position = Some((self.registration * nalgebra::Point3::from(t)).coords);
                m
            }
            Outcome::Skipped(reason) => {
                let m = self.row(q, &p.region, Status::Skipped(reason.clone()));
                self.report.skipped.push((p.point, reason));
                m
            }
        };
        // As a reader of the recording will see it, so that a resumed planning-mode session
        // replays exactly what its first run measured.
        let (q_file, p_file) = crate::recording::as_recorded(&m, self.rig.chain.joints());
        let measured = p_file.map(|p| Observation { q: q_file, p });
        if measured.is_some() {
            self.report.ok += 1;
        }
        self.write(m)?;
        Ok(measured)
    }

    /// Measures random reachable poses with the nominal kinematics and fits the table-to-world
    /// transform (conventions §1); writes it to session.toml.
    fn registration_step(&mut self) -> Result<(), SessionError> {
        if let Some(info) = self.opts.registration {
            self.registration = crate::rig::pose_from_xyz_rpy(info.translation_mm, info.rpy_deg);
            self.registration_info = Some(info);
            return self.write_info();
        }
        if !self.dev.has_table() {
            // A point sensor's frame is the world (ideal instrument) or free, fitted with the
            // kinematics (a tracker, conventions §1): nothing to register before the session.
            self.registration = Isometry3::identity();
            return self.write_info();
        }
        let n = self.opts.registration_points;
        if n == 0 {
            self.registration = match &self.rig.instrument {
                crate::rig::Instrument::TablePanel(tp) => Isometry3::translation(
                    tp.table_to_world_mm.x,
                    tp.table_to_world_mm.y,
                    tp.table_to_world_mm.z,
                ),
                _ => Isometry3::identity(),
            };
            let (t, rpy) = crate::identification::registration::to_xyz_rpy(&self.registration);
            self.registration_info = Some(RegistrationInfo {
                translation_mm: t,
                rpy_deg: rpy,
                rms_mm: None,
            });
            return self.write_info();
        }
        let rig = self.rig;
        let mut candidates = registration_candidates(rig, self.opts.seed);
        let mut obs = Vec::new();
        let mut k = 0usize;
        while obs.len() < n {
            let Some(q) = candidates.next() else {
                break;
            };
            let Some(nominal) = table_target(rig, &q) else {
                break;
            };
            k += 1;
            let (qc, out) = self.measure(k, "reg", &q, nominal)?;
            let mut m = self.row(qc.clone(), "reg", Status::Via);
            if let Outcome::Measured(c) = out {
                let t = Vector3::from(c.point_table_mm());
                m.table = Some(t);
                m.panel_uv = Some([c.touch.u_mm, c.touch.v_mm]);
                obs.push(Observation { q: qc, p: t });
            }
            self.report.via += 1;
            self.write(m)?;
        }
        let e = ErrorParams::zeros(self.rig.chain.layout());
        let reg = register(&self.rig.chain, &e, &obs)
            .map_err(|e| SessionError::Registration(e.to_string()))?;
        self.registration = reg.world_from_instrument;
        let (t, rpy) = crate::identification::registration::to_xyz_rpy(&self.registration);
        self.registration_info = Some(RegistrationInfo {
            translation_mm: t,
            rpy_deg: rpy,
            rms_mm: Some(reg.stats.rms_mm),
        });
        self.report.registration_rms_mm = Some(reg.stats.rms_mm);
        self.write_info()
    }

    fn write_info(&self) -> Result<(), SessionError> {
        let mut info = self.opts.info.clone();
        info.registration = self.registration_info;
        write_session(&self.opts.dir, &info)?;
        Ok(())
    }
}

/// A touch that cannot be right (retryable).
fn bad_touch(detail: String) -> DeviceError {
    DeviceError::Protocol {
        device: crate::devices::DeviceName::Panel,
        request: "touch".into(),
        detail,
    }
}

/// True for an arm error after which the driver may not know where the arm is.
fn arm_lost_track(e: &DeviceError) -> bool {
    use crate::devices::DeviceName;
    matches!(
        e,
        DeviceError::Timeout {
            device: DeviceName::Arm,
            ..
        } | DeviceError::Protocol {
            device: DeviceName::Arm,
            ..
        } | DeviceError::Transport {
            device: DeviceName::Arm,
            ..
        } | DeviceError::PoseMismatch { .. }
    )
}

/// A short reason for a `skipped:` row.
fn short_reason(e: &DeviceError) -> String {
    match e {
        DeviceError::MissedTouch { .. } => "missed touch".into(),
        DeviceError::Timeout { device, .. } => format!("{device} timeout"),
        DeviceError::Protocol { device, detail, .. } => format!("{device} bad reply ({detail})"),
        DeviceError::Transport { device, .. } => format!("{device} transport error"),
        DeviceError::DriveFault { axis, .. } => format!("table axis {axis} drive fault"),
        DeviceError::FollowingError { axis, .. } => format!("table axis {axis} following error"),
        DeviceError::ArmErrorMode { code, .. } => format!("arm error mode {code}"),
        other => format!("{:?}", other.kind()),
    }
}

/// DeviceError holds a transport error that is not Clone; rebuild it as text where needed.
fn clone_error(e: &DeviceError) -> DeviceError {
    match e {
        DeviceError::HeartbeatLost {
            axis,
            node,
            silent_for,
            limit,
        } => DeviceError::HeartbeatLost {
            axis: *axis,
            node: *node,
            silent_for: *silent_for,
            limit: *limit,
        },
        other => DeviceError::NotReady {
            device: match other {
                DeviceError::ArmErrorMode { .. } | DeviceError::PoseMismatch { .. } => {
                    crate::devices::DeviceName::Arm
                }
                _ => crate::devices::DeviceName::Table,
            },
            detail: other.to_string(),
        },
    }
}
