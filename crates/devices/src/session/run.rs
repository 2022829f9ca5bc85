//! Running a session: registration, then every planned point, each row appended and flushed
//! before the next motion, the journal committed after each point.
//!
//! The choreography runs on tokio: the session holds a runtime (current-thread on the virtual
//! clock, deterministic; one worker on real time) and runs each point's procedure on it, so
//! the public calls stay synchronous (a division's [`Measurer`](rigcal_model::division::Measurer)
//! asks for one point at a time). The modules it is made of:
//!
//! - `core`: the recording, `seq`, the time base, the journal, the registration;
//! - `motion`: the devices as futures — arm and table together, waits raced
//!   against the drives' supervision alarm, a fault cancelling the motion in progress;
//! - `contact` and `sensor`: the procedures per instrument,
//!   each with its thresholds from the rig file;
//! - `recovery`: retry, give the point up, or stop;
//! - `registration`: the table-to-world registration step.
//!
//! A stop request ([`SessionOptions::stop`]: SIGINT, SIGTERM) is looked at between any two
//! device calls: the session abandons what it is doing, quick-stops the table's drives, stops
//! the arm (`motion::Brakes`), leaves the journal at the last finished point and ends with
//! [`SessionError::Stopped`]; a device that stops answering ends it with
//! [`SessionError::DeviceLost`] (the rule is in `recovery`). Both resume with `--resume`.
//!
//! A point the rig cannot measure, or one still failing after the last attempt, becomes a
//! `skipped: REASON` row. Rows (conventions §6): `via` for the pre-approach and registration
//! moves, `ok` for a measurement, `skipped: …` for a point given up. A table-and-panel
//! recording has one more column, `latency_ms`: on an `ok` row, how long the table's position
//! took to come after the touch was seen (request to answer; see
//! [`Contact::read_latency`](crate::devices::contact::Contact::read_latency)); readers that
//! do not know it keep and ignore it (recordings.md). A dry run's measurement draws are keyed
//! by (seed, seq, attempt) through the rig's hook, which the session cannot tell from the real
//! rig's.

use std::path::Path;
use std::time::{Duration, Instant};

use nalgebra::Vector3;

use crate::devices::contact::approach_speed;
use crate::devices::pace::Pace;
use crate::devices::{DeviceError, OpenedRig, RigHook};
use crate::session::contact::{FinalApproach, TableContact};
use crate::session::core::{Outcome, SessionCore};
use crate::session::error::SessionError;
use crate::session::journal::{Journal, JournalError};
use crate::session::motion::{Brakes, Motion, IO, MOVE};
use crate::session::options::SessionOptions;
use crate::session::plan::PlannedPoint;
use crate::session::progress::Progress;
use crate::session::registration::registration_step;
use crate::session::report::SessionReport;
use crate::session::sensor::SensorProcedure;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{as_recorded, RecordingWriter, Status};
use rigcal_core::rig::Rig;
use rigcal_model::identification::Observation;

/// The recording's file name in a session directory.
pub const CSV_FILE: &str = "measurements.csv";

/// The recording's column for the latency of a contact's position reading (ms).
pub const LATENCY_COLUMN: &str = "latency_ms";

/// Runs (or resumes) a session over `points` on the rig the factory opened.
pub fn run_session(
    rig: &Rig,
    opened: OpenedRig,
    points: &[PlannedPoint],
    opts: SessionOptions,
    progress: &Progress,
) -> Result<SessionReport, SessionError> {
    let mut session = Session::open(rig, opened, opts)?;
    session.run.core.report.points = points.len();
    let start_point = session.next_point;
    for (i, p) in points.iter().enumerate().skip(start_point) {
        session.measure_point(p, i + 1 == points.len())?;
        progress.update(i + 1, points.len(), session.rig_time_s());
    }
    progress.finish();
    session.finish()
}

/// An open session: the arm homed, the instrument ready, the recording open, the registration
/// done (or restored from the journal on a resume). Points are measured one at a time — from a
/// plan ([`run_session`]) or as a division asks for them in planning mode
/// ([`SessionMeasurer`](crate::session::SessionMeasurer)); each point's rows are flushed and the
/// journal committed before the next motion. Its calls block on the session's own runtime, so
/// they must not be made from within another tokio runtime.
pub struct Session<'a> {
    runtime: tokio::runtime::Runtime,
    run: Run<'a>,
    brakes: Brakes,
    started: Instant,
    next_point: usize,
}

impl std::fmt::Debug for Session<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("dir", &self.run.core.opts.dir)
            .field("next_point", &self.next_point)
            .finish_non_exhaustive()
    }
}

/// The instrument's procedure.
enum Procedure {
    Contact(TableContact),
    Sensor(SensorProcedure),
}

/// What a session runs on its runtime: the core, the devices, the procedure.
struct Run<'a> {
    core: SessionCore<'a>,
    motion: Motion,
    procedure: Procedure,
}

fn dev(stage: impl Into<String>) -> impl FnOnce(DeviceError) -> SessionError {
    let stage = stage.into();
    move |source| SessionError::Device { stage, source }
}

impl<'a> Session<'a> {
    /// Opens (or, with `opts.resume`, resumes) a session on the rig the factory opened.
    pub fn open(
        rig: &'a Rig,
        opened: OpenedRig,
        opts: SessionOptions,
    ) -> Result<Self, SessionError> {
        let started = Instant::now();
        let OpenedRig { devices, hook } = opened;
        let runtime = Pace::new(std::sync::Arc::clone(&devices.clock))
            .runtime()
            .map_err(SessionError::Runtime)?;
        let motion = Motion::new(devices).map_err(dev("starting the devices"))?;
        let brakes = Brakes::of(&motion);
        let stop = opts.stop.clone();
        let opened = runtime.block_on(async {
            tokio::select! {
                biased;
                why = stop.requested() => Err(why),
                r = Run::open(rig, motion, hook, opts) => Ok(r),
            }
        });
        let (run, next_point) = match opened.and_then(|r| stop.reason().map_or(Ok(r), Err)) {
            Ok(r) => r?,
            Err(reason) => {
                let during = "while the rig was brought up or registered".to_string();
                return Err(safe_stop(&runtime, &brakes, reason, during));
            }
        };
        Ok(Session {
            runtime,
            run,
            brakes,
            started,
            next_point,
        })
    }

    /// Points finished so far (including earlier runs of a resumed session).
    pub fn points_done(&self) -> usize {
        self.next_point
    }

    /// Where the table goes for `q` (mm, table frame) through the session's registration;
    /// `None` before a registration or on a point-sensor rig.
    pub fn table_target(&self, q: &[f64]) -> Option<[f64; 3]> {
        self.run.core.registered_table_target(q)
    }

    /// Session time now (s): the rig time so far.
    pub fn rig_time_s(&self) -> f64 {
        self.run.core.now_s()
    }

    /// Measures `p` (or writes why it cannot be), then commits the journal; `last` marks the
    /// session finished in it. Returns the joints the arm was commanded to (after the
    /// controller's resolution) with the measured position (world, mm); `None` for a skip.
    pub fn measure_point(
        &mut self,
        p: &PlannedPoint,
        last: bool,
    ) -> Result<Option<Observation>, SessionError> {
        let stop = self.run.core.opts.stop.clone();
        let run = &mut self.run;
        let measured = self.runtime.block_on(async {
            tokio::select! {
                biased;
                why = stop.requested() => Err(why),
                r = async {
                    let measured = run.point(p).await?;
                    run.where_the_devices_stand().await?;
                    Ok::<_, SessionError>(measured)
                } => Ok(r),
            }
        });
        // A stop requested while the point ended (or failed on the refusal to move) is a stop.
        let measured = match measured.and_then(|r| stop.reason().map_or(Ok(r), Err)) {
            Ok(r) => r?,
            Err(reason) => {
                let during = format!(
                    "during plan point {} (row seq {})",
                    p.point, self.run.core.seq
                );
                return Err(safe_stop(&self.runtime, &self.brakes, reason, during));
            }
        };
        self.next_point += 1;
        let core = &mut self.run.core;
        core.report.points = core.report.points.max(self.next_point);
        core.commit(self.next_point, last)?;
        Ok(measured)
    }

    /// Ends the session: the journal marked finished, the report with the rig and wall time.
    pub fn finish(mut self) -> Result<SessionReport, SessionError> {
        let core = &mut self.run.core;
        core.commit(self.next_point, true)?;
        core.report.rig_time_s = core.now_s();
        core.report.wall = self.started.elapsed();
        Ok(std::mem::take(&mut core.report))
    }
}

/// The safe stop after a stop request: the brakes applied, the error that says what they did.
/// The journal is left as the last finished point committed it.
fn safe_stop(
    runtime: &tokio::runtime::Runtime,
    brakes: &Brakes,
    reason: String,
    during: String,
) -> SessionError {
    tracing::warn!("{reason}: stopping the session safely ({during})");
    let devices = runtime.block_on(brakes.apply());
    SessionError::Stopped {
        reason,
        during,
        devices,
    }
}

impl<'a> Run<'a> {
    /// Brings the rig up (arm homed, table enabled and supervised), opens the recording, and
    /// registers — or takes everything back from the journal on a resume. Also returns the
    /// next point.
    async fn open(
        rig: &'a Rig,
        mut motion: Motion,
        hook: Box<dyn RigHook>,
        opts: SessionOptions,
    ) -> Result<(Run<'a>, usize), SessionError> {
        let dir = opts.dir.clone();
        motion.stop = opts.stop.clone();
        std::fs::create_dir_all(&dir).map_err(|source| SessionError::Io {
            path: dir.clone(),
            source,
        })?;
        let csv = dir.join(CSV_FILE);
        let cfg = crate::devices::config::DevicesConfig::read(rig);
        motion
            .arm
            .run(MOVE, |a| a.home(MOVE))
            .await
            .map_err(dev("homing the arm"))?;
        let level = cfg.arm.speed;
        motion
            .arm
            .run(IO, move |a| a.set_speed(level, IO))
            .await
            .map_err(dev("setting the arm speed"))?;
        let procedure = if motion.has_table() {
            let last = Self::bring_up_table(&mut motion, &cfg, &opts).await?;
            Procedure::Contact(TableContact::new(rig, last, opts.procedure))
        } else {
            Procedure::Sensor(SensorProcedure::new(rig))
        };
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
        if let (Some(j), Procedure::Contact(_)) = (&journal, &procedure) {
            if j.procedure != opts.procedure {
                return Err(SessionError::ProcedureDiffers {
                    dir,
                    journal: j.procedure,
                    asked: opts.procedure,
                });
            }
        }
        // A table-and-panel recording keeps each contact's latency; a resumed one keeps the
        // columns it was begun with.
        let latency_column = match &journal {
            _ if !motion.has_table() => false,
            None => true,
            Some(_) => has_column(&csv, LATENCY_COLUMN)?,
        };
        let extra = if latency_column {
            vec![LATENCY_COLUMN.to_string()]
        } else {
            Vec::new()
        };
        let writer = open_recording(rig, &csv, journal.as_ref(), &extra, opts.fsync)?;
        let clock = std::sync::Arc::clone(motion.pace.clock());
        let resume = opts.resume;
        let mut core = SessionCore::new(rig, opts, hook, clock, writer, csv);
        core.latency_column = latency_column;
        core.arm_q = motion
            .arm
            .call(IO, |a| a.commanded())
            .await
            .map_err(dev("reading the arm"))?;
        let mut run = Run {
            core,
            motion,
            procedure,
        };
        let next_point = match journal {
            Some(j) => run.resume_from(&j).await?,
            None => {
                run.core.start_time();
                run.core.commit(0, false)?;
                run.register().await?;
                run.core.commit(0, false)?;
                0
            }
        };
        if next_point > 0 || resume {
            run.core.report.resumed_at = Some(next_point);
            run.core.report.points = next_point;
        }
        Ok((run, next_point))
    }

    /// Enables the table (retried like a measuring step: a lost frame must not stop the
    /// session before it has begun), starts supervising its drives, and returns the final
    /// approach: its speed from the latency rule and the budget its readings are held to.
    async fn bring_up_table(
        motion: &mut Motion,
        cfg: &crate::devices::config::DevicesConfig,
        opts: &SessionOptions,
    ) -> Result<FinalApproach, SessionError> {
        let table = motion.table().map_err(dev("enabling the table"))?;
        let mut attempt = 1u32;
        loop {
            match table.run(IO * 5, |t| t.enable(IO * 5)).await {
                Ok(()) => break,
                Err(e) if e.is_retryable() && attempt < opts.max_attempts.max(1) => {
                    tracing::info!("enabling the table again (attempt {}): {e}", attempt + 1);
                    let backoff = opts.backoff * 2u32.saturating_pow(attempt - 1);
                    motion.pace.pause(backoff).await;
                    attempt += 1;
                }
                Err(e) => return Err(dev("enabling the table")(e)),
            }
        }
        let table_latency = table.call(IO, |t| t.latency()).await;
        let panel = motion.panel().map_err(dev("reading the panel"))?;
        let panel_latency = panel.call(IO, |p| p.latency()).await;
        let (Ok(table_latency), Ok(panel_latency)) = (table_latency, panel_latency) else {
            return Err(SessionError::Device {
                stage: "reading the devices' latencies".into(),
                source: DeviceError::NotReady {
                    device: crate::devices::DeviceName::Table,
                    detail: "a device thread stopped".into(),
                },
            });
        };
        motion.supervise(Duration::from_millis(u64::from(cfg.table.heartbeat_ms)));
        Ok(FinalApproach {
            speed_mm_s: approach_speed(panel_latency, table_latency, cfg.panel.max_overshoot_mm),
            panel_latency,
            budget_mm: cfg.panel.max_overshoot_mm,
        })
    }

    /// The registration step with the instrument's procedure.
    async fn register(&mut self) -> Result<(), SessionError> {
        let contact = match &mut self.procedure {
            Procedure::Contact(c) => Some(c),
            Procedure::Sensor(_) => None,
        };
        registration_step(&mut self.core, &self.motion, contact).await
    }

    /// Takes the session back to where its journal left it; the next point.
    async fn resume_from(&mut self, j: &Journal) -> Result<usize, SessionError> {
        if let Some(q) = &j.arm_q {
            let q = self
                .motion
                .arm_to(q)
                .await
                .map_err(dev("moving the arm back to its last pose"))?;
            self.core.arm_q = Some(q);
        }
        if let (Some(t), Procedure::Contact(c)) = (j.table_mm, &mut self.procedure) {
            c.table_back(&mut self.core, &self.motion, t)
                .await
                .map_err(dev("moving the table back"))?;
        }
        self.core.restore(j)?;
        match &j.registration {
            Some(info) => {
                let pose = rigcal_core::rig::pose_from_xyz_rpy(info.translation_mm, info.rpy_deg);
                self.core.register(pose, Some(*info));
            }
            None => {
                // Killed during the registration step, or a point-sensor rig (none to do): the
                // journal keeps the point reached, never rewinds it.
                self.register().await?;
                self.core.commit(j.next_point, false)?;
            }
        }
        Ok(j.next_point)
    }

    /// Makes sure the core knows where arm and table stand before the journal is committed: a
    /// point given up after a failed or refused move leaves the table's position unknown (and
    /// the arm where an abandoned move took it), and a resume must take both back to where the
    /// uninterrupted session had them, or its next moves (and their times) differ.
    async fn where_the_devices_stand(&mut self) -> Result<(), SessionError> {
        let q = self
            .motion
            .arm
            .call(IO, |a| a.commanded())
            .await
            .map_err(dev("reading the arm"))?;
        if q.is_some() {
            self.core.arm_q = q;
        }
        if self.core.table_at.is_none() && self.motion.has_table() {
            let table = self.motion.table().map_err(dev("reading the table"))?;
            let at = table
                .run(IO, |t| t.position(IO))
                .await
                .map_err(dev("reading the table's position"))?;
            self.core.table_at = Some(at);
        }
        Ok(())
    }

    /// Measures one point and writes its rows; the commanded joints and measured position.
    async fn point(&mut self, p: &PlannedPoint) -> Result<Option<Observation>, SessionError> {
        let core = &mut self.core;
        if let Err(reason) = core.rig.measurable(&p.q) {
            let m = core.row(p.q.clone(), &p.region, Status::Skipped(reason.to_string()));
            core.report.skipped.push((p.point, reason.to_string()));
            core.write(m)?;
            return Ok(None);
        }
        let (q, out) = match &mut self.procedure {
            Procedure::Contact(c) => {
                let target = core.registered_table_target(&p.q).unwrap_or(p.table_mm);
                c.measure(core, &self.motion, p.point, &p.region, &p.q, target)
                    .await?
            }
            Procedure::Sensor(s) => {
                s.measure(core, &self.motion, p.point, &p.region, &p.q)
                    .await?
            }
        };
        let m = match out {
            Outcome::Seen(reading) => {
                core.silent_points = 0;
                let mut m = core.row(q, &p.region, Status::Ok);
                m.position = Some(Vector3::from(reading));
                m
            }
            Outcome::Measured(c) => {
                core.silent_points = 0;
                let t = Vector3::from(c.point_table_mm());
                let mut m = core.row(q, &p.region, Status::Ok);
                m.table = Some(t);
                m.panel_uv = Some([c.touch.u_mm, c.touch.v_mm]);
                let world = core.registration.world_from_instrument;
                m.position = Some((world * nalgebra::Point3::from(t)).coords);
                if core.latency_column {
                    let ms = c
                        .read_latency
                        .map(|l| format!("{:.3}", l.as_secs_f64() * 1e3));
                    m.extra = vec![ms.unwrap_or_default()];
                }
                m
            }
            Outcome::Skipped(reason) => {
                let m = core.row(q, &p.region, Status::Skipped(reason.clone()));
                core.report.skipped.push((p.point, reason));
                m
            }
        };
        // As a reader of the recording will see it, so that a resumed planning-mode session
        // replays exactly what its first run measured.
        let (q_file, p_file) = as_recorded(&m, core.rig.chain.joints());
        let measured = p_file.map(|p| Observation { q: q_file, p });
        if measured.is_some() {
            core.report.ok += 1;
        }
        core.write(m)?;
        Ok(measured)
    }
}

/// The recording: created, or (on a resume) cut back to the journal's length and appended to;
/// `extra` are its columns after the standard ones.
fn open_recording(
    rig: &Rig,
    csv: &Path,
    journal: Option<&Journal>,
    extra: &[String],
    fsync: bool,
) -> Result<RecordingWriter, SessionError> {
    let joints = rig.chain.joints();
    let io = |source| SessionError::Io {
        path: csv.to_path_buf(),
        source,
    };
    let writer = match journal {
        Some(j) => {
            let f = std::fs::OpenOptions::new()
                .write(true)
                .open(csv)
                .map_err(io)?;
            f.set_len(j.csv_bytes).map_err(io)?;
            RecordingWriter::open_append(csv, joints, extra)?.0
        }
        None => RecordingWriter::create(csv, joints, extra)?,
    };
    Ok(writer.sync_each_row(fsync))
}

/// True when the header of the recording at `csv` names `column`.
fn has_column(csv: &Path, column: &str) -> Result<bool, SessionError> {
    use std::io::BufRead;
    let io = |source| SessionError::Io {
        path: csv.to_path_buf(),
        source,
    };
    let mut header = String::new();
    std::io::BufReader::new(std::fs::File::open(csv).map_err(io)?)
        .read_line(&mut header)
        .map_err(io)?;
    Ok(header.trim_end().split(',').any(|c| c == column))
}
