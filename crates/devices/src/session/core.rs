//! The session core: the recording and its row numbers, the session's time base, the journal
//! commit, the registration — what every procedure writes through, whatever the instrument.
//!
//! Session time (the rows' `t_s`, the journal's clock) is the devices' clock plus an offset, so
//! a resumed session continues the time where its journal left it; the rig's hook learns the
//! same offset (a dry run's world keeps its time with it).

use std::path::PathBuf;

use nalgebra::Isometry3;

use crate::devices::clock::SharedClock;
use crate::devices::contact::Contact;
use crate::devices::RigHook;
use crate::session::error::SessionError;
use crate::session::journal::{Journal, JournalError};
use crate::session::options::SessionOptions;
use crate::session::report::SessionReport;
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::{
    write_session, Measurement, RecordingWriter, RegistrationInfo, Status,
};
use rigcal_core::rig::Rig;

/// How one point ended.
#[derive(Debug)]
pub(crate) enum Outcome {
    /// A contact on the table rig.
    Measured(Contact),
    /// A point sensor's reading (sensor frame, mm).
    Seen([f64; 3]),
    /// Given up, with the reason for the `skipped:` row.
    Skipped(String),
}

/// The transform that brings the instrument's points into the world frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Registration {
    /// World from table (identity for a point sensor).
    pub world_from_instrument: Isometry3<f64>,
    /// What session.toml holds (none for a point sensor).
    pub info: Option<RegistrationInfo>,
}

/// The session core (see the module docs). Fifteen fields: what a point's rows and the
/// journal need of the session (rig, options, recording, time base, registration, where the
/// devices stand, the report), held in one place so the procedures borrow one thing.
pub(crate) struct SessionCore<'a> {
    pub rig: &'a Rig,
    pub opts: SessionOptions,
    hook: Box<dyn RigHook>,
    clock: SharedClock,
    writer: RecordingWriter,
    csv: PathBuf,
    /// The next row's `seq`.
    pub seq: u64,
    rows: u64,
    /// Session time (s) = clock (s) + this.
    offset_s: f64,
    pub registration: Registration,
    /// The arm's last commanded joints and the table's last known position, for the journal.
    pub arm_q: Option<Vec<f64>>,
    pub table_at: Option<[f64; 3]>,
    pub report: SessionReport,
    /// Points given up in a row for a device's silence (a timeout, a missed touch, a late
    /// reading): the device-loss rule of [`crate::session::recovery`] counts them.
    pub silent_points: u32,
    /// The recording has the `latency_ms` column (a table-and-panel session's, since the
    /// column was added; a resumed older recording keeps its own columns).
    pub latency_column: bool,
}

impl<'a> SessionCore<'a> {
    /// A core writing `writer` (the recording at `csv`), timed by `clock`.
    pub fn new(
        rig: &'a Rig,
        opts: SessionOptions,
        hook: Box<dyn RigHook>,
        clock: SharedClock,
        writer: RecordingWriter,
        csv: PathBuf,
    ) -> Self {
        SessionCore {
            rig,
            opts,
            hook,
            clock,
            writer,
            csv,
            seq: 1,
            rows: 0,
            offset_s: 0.0,
            registration: Registration {
                world_from_instrument: Isometry3::identity(),
                info: None,
            },
            arm_q: None,
            table_at: None,
            report: SessionReport::default(),
            silent_points: 0,
            latency_column: false,
        }
    }

    /// Session time now (s).
    pub fn now_s(&self) -> f64 {
        self.clock.now().as_secs_f64() + self.offset_s
    }

    /// Starts the session's time at zero now.
    pub fn start_time(&mut self) {
        self.continue_time(0.0);
    }

    /// Continues the session's time from `session_s` now (a resume).
    fn continue_time(&mut self, session_s: f64) {
        self.offset_s = session_s - self.clock.now().as_secs_f64();
        self.hook.time_base(self.offset_s);
    }

    /// The arm is about to be commanded for the next row's measurement, attempt `attempt`.
    pub fn before_measurement(&mut self, attempt: u32) {
        self.hook.before_measurement(self.seq, attempt);
    }

    /// Takes back the journal's counters and the rig's state (resume).
    pub fn restore(&mut self, j: &Journal) -> Result<(), SessionError> {
        if let Some(state) = &j.rig_state {
            self.hook
                .restore(state)
                .map_err(|e| JournalError::Corrupt {
                    path: Journal::path(&self.opts.dir),
                    reason: e.to_string(),
                })?;
        }
        self.continue_time(j.clock_s);
        self.seq = j.next_seq;
        self.rows = j.rows;
        Ok(())
    }

    /// A row at the next `seq`, stamped now.
    pub fn row(&self, q: Vec<f64>, region: &str, status: Status) -> Measurement {
        Measurement {
            seq: self.seq,
            t_s: Some(self.now_s()),
            q,
            region: Some(region.to_string()),
            status,
            ..Default::default()
        }
    }

    /// Appends (and flushes) a row.
    pub fn write(&mut self, m: Measurement) -> Result<(), SessionError> {
        self.writer.append(&m)?;
        self.rows += 1;
        self.seq += 1;
        Ok(())
    }

    /// The `via` row of a move the arm ended at `q`.
    pub fn via_row(&mut self, q: Vec<f64>, region: &str) -> Result<(), SessionError> {
        self.arm_q = Some(q.clone());
        let m = self.row(q, region, Status::Via);
        self.write(m)?;
        self.report.via += 1;
        Ok(())
    }

    /// Saves the journal: the state after the last finished point.
    pub fn commit(&mut self, next_point: usize, finished: bool) -> Result<(), SessionError> {
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
            registration: self.registration.info,
            csv_bytes,
            rows: self.rows,
            finished,
            procedure: self.opts.procedure,
        };
        j.save_with(&self.opts.dir, self.opts.fsync)?;
        Ok(())
    }

    /// Uses `world_from_instrument` for the rows' `x_mm…`, with what session.toml says of it.
    pub fn register(
        &mut self,
        world_from_instrument: Isometry3<f64>,
        info: Option<RegistrationInfo>,
    ) {
        self.registration = Registration {
            world_from_instrument,
            info,
        };
    }

    /// Writes session.toml: the options' information and the registration.
    pub fn write_info(&self) -> Result<(), SessionError> {
        let mut info = self.opts.info.clone();
        info.registration = self.registration.info;
        write_session(&self.opts.dir, &info)?;
        Ok(())
    }

    /// The table position under the nominal tip at `q` through the session's registration (the
    /// plan's targets use the rig file's nominal table pose, which the registration corrects);
    /// `None` before a registration.
    pub fn registered_table_target(&self, q: &[f64]) -> Option<[f64; 3]> {
        self.registration.info?;
        let tip = self
            .rig
            .chain
            .position(q, &ErrorParams::zeros(self.rig.chain.layout()));
        let t = self.registration.world_from_instrument.inverse() * nalgebra::Point3::from(tip);
        Some([t.x, t.y, t.z])
    }
}
