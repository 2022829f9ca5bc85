//! The rig's devices as the session's choreography holds them, and the moves it makes of them
//! on tokio: arm and table together (`try_join!`), each wait raced against the drives'
//! supervision alarm (`select!`), a fault cancelling the motion in progress — the table halted,
//! the arm no longer waited for (the controller has no stop: its driver reads the abandoned
//! move's reply before the next command).
//!
//! How the waits run on each clock is [`crate::devices::pace`]'s business: inline and in bounded
//! slices on the virtual clock (deterministic), on the devices' own threads on real time.

use std::future::Future;
use std::time::Duration;

use crate::devices::actor::DeviceActor;
use crate::devices::contact::{approach, Approach, Contact};
use crate::devices::pace::Pace;
use crate::devices::supervision::Alarm;
use crate::devices::{
    Arm, DeviceError, DeviceName, InstrumentDevices, Panel, PointSensor, RigDevices, Table,
};

/// Timeout of a single device exchange.
pub(crate) const IO: Duration = Duration::from_secs(2);
/// Timeout of an arm or table move.
pub(crate) const MOVE: Duration = Duration::from_secs(120);
/// While the arm moves beside it, the table is looked at this often (its drives' faults and
/// heartbeats are supervised besides); polled closely once the arm has arrived, when its end
/// is what the session waits for.
const BESIDE_ARM: Duration = Duration::from_millis(100);

/// The instrument's devices.
enum Instrument {
    TablePanel {
        table: DeviceActor<dyn Table>,
        panel: DeviceActor<dyn Panel>,
    },
    Sensor(DeviceActor<dyn PointSensor>),
}

/// The arm and its instrument as futures, with the clock's pace and the drives' alarm.
pub(crate) struct Motion {
    pub arm: DeviceActor<dyn Arm>,
    instrument: Instrument,
    pub pace: Pace,
    pub alarm: Alarm,
}

fn no_table() -> DeviceError {
    DeviceError::Config {
        key: "table".into(),
        reason: "the rig's instrument is a point sensor, not the table and panel".into(),
    }
}

impl Motion {
    /// Takes over the factory's devices: inline on a virtual clock, each on a thread of its
    /// own on real time. No supervision yet ([`Motion::supervise`]).
    pub fn new(devices: RigDevices) -> Result<Self, DeviceError> {
        let pace = Pace::new(devices.clock);
        let inline = pace.is_virtual();
        let arm = DeviceActor::for_clock(DeviceName::Arm, devices.arm, inline)?;
        let instrument = match devices.instrument {
            InstrumentDevices::TablePanel { table, panel } => Instrument::TablePanel {
                table: DeviceActor::for_clock(DeviceName::Table, table, inline)?,
                panel: DeviceActor::for_clock(DeviceName::Panel, panel, inline)?,
            },
            InstrumentDevices::Sensor(s) => {
                Instrument::Sensor(DeviceActor::for_clock(DeviceName::Sensor, s, inline)?)
            }
        };
        Ok(Motion {
            arm,
            instrument,
            pace,
            alarm: Alarm::never(),
        })
    }

    /// Starts the supervision task of the table's drives (one check every `period`); on the
    /// current runtime.
    pub fn supervise(&mut self, period: Duration) {
        if let Instrument::TablePanel { table, .. } = &self.instrument {
            self.alarm = Alarm::supervise(table.clone(), self.pace.clone(), period);
        }
    }

    /// True when the instrument is the table and panel.
    pub fn has_table(&self) -> bool {
        matches!(self.instrument, Instrument::TablePanel { .. })
    }

    /// The table, or a configuration error for a point-sensor rig.
    pub fn table(&self) -> Result<&DeviceActor<dyn Table>, DeviceError> {
        match &self.instrument {
            Instrument::TablePanel { table, .. } => Ok(table),
            Instrument::Sensor(_) => Err(no_table()),
        }
    }

    /// The panel, or a configuration error for a point-sensor rig.
    pub fn panel(&self) -> Result<&DeviceActor<dyn Panel>, DeviceError> {
        match &self.instrument {
            Instrument::TablePanel { panel, .. } => Ok(panel),
            Instrument::Sensor(_) => Err(no_table()),
        }
    }

    /// The point sensor, or a configuration error for a table rig.
    pub fn sensor(&self) -> Result<&DeviceActor<dyn PointSensor>, DeviceError> {
        match &self.instrument {
            Instrument::Sensor(s) => Ok(s),
            Instrument::TablePanel { .. } => Err(DeviceError::Config {
                key: "sensor".into(),
                reason: "the rig's instrument is the table and panel, not a point sensor".into(),
            }),
        }
    }

    /// `work`, unless the drives' alarm comes first (then its error): a fault cancels the wait.
    async fn guarded<T>(
        &self,
        work: impl Future<Output = Result<T, DeviceError>>,
    ) -> Result<T, DeviceError> {
        if !self.has_table() {
            return work.await;
        }
        tokio::select! {
            biased;
            e = self.alarm.raised() => Err(e),
            r = work => r,
        }
    }

    /// Moves the arm to `q` and waits for the end of the motion; returns the joints commanded.
    pub async fn arm_to(&self, q: &[f64]) -> Result<Vec<f64>, DeviceError> {
        self.guarded(self.arm_motion(q.to_vec())).await
    }

    /// Sets the table's speed (mm/s).
    pub async fn table_speed(&self, mm_s: f64) -> Result<(), DeviceError> {
        self.table()?.run(IO, move |t| t.set_speed(mm_s, IO)).await
    }

    /// Starts a table move to `target` (mm).
    pub async fn start_table(&self, target: [f64; 3]) -> Result<(), DeviceError> {
        self.table()?
            .run(IO, move |t| t.start_move(target, IO))
            .await
    }

    /// Waits for the table to reach its target; a fault halts it.
    pub async fn table_reached(&self) -> Result<[f64; 3], DeviceError> {
        let r = self.guarded(self.table_wait(self.table()?)).await;
        if r.is_err() {
            self.halt_table().await;
        }
        r
    }

    /// Moves the arm to `q` while the table goes on to the target it was started to (both at
    /// once); the first failure of either, or a drive alarm, ends both: the table halted, the
    /// arm no longer waited for.
    pub async fn arm_and_table(&self, q: &[f64]) -> Result<(Vec<f64>, [f64; 3]), DeviceError> {
        let table = self.table()?;
        let arrived = tokio::sync::Notify::new();
        let arm = async {
            let done = self.arm_motion(q.to_vec()).await?;
            arrived.notify_one();
            Ok(done)
        };
        // Polled in a fixed order, the table's look first: on the virtual clock it then looks
        // exactly when due, whatever else woke the task.
        let both = async {
            tokio::try_join!(biased; self.table_beside_arm(table, &arrived), arm)
                .map(|(at, done)| (done, at))
        };
        let r = self.guarded(both).await;
        if r.is_err() {
            self.halt_table().await;
        }
        r
    }

    /// Starts a new pass of ascending z.
    pub async fn begin_pass(&self) -> Result<(), DeviceError> {
        self.table()?.call(IO, |t| t.begin_pass()).await
    }

    /// Stops the table where it is, if the rig has one (after a fault; errors are moot then).
    pub async fn halt_table(&self) {
        if let Ok(t) = self.table() {
            let _ = t.run(IO, |t| t.halt(IO)).await;
        }
    }

    /// One contact (see [`approach`]).
    pub async fn contact(&self, a: &Approach) -> Result<Contact, DeviceError> {
        let (table, panel) = (self.table()?, self.panel()?);
        approach(table, panel, &self.alarm, &self.pace, a).await
    }

    /// One point-sensor reading (mm, sensor frame).
    pub async fn read_sensor(&self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        self.sensor()?.run(timeout, move |s| s.read(timeout)).await
    }

    /// The arm's move in slices (unguarded).
    async fn arm_motion(&self, q: Vec<f64>) -> Result<Vec<f64>, DeviceError> {
        let done = self.arm.run(MOVE, move |a| a.start_move(&q, MOVE)).await?;
        loop {
            let slice = self.pace.next_slice();
            // The last slice also checks the pose (WH), within the move's own timeout.
            if self.arm.run(MOVE, move |a| a.wait_moved(slice)).await? {
                return Ok(done);
            }
            self.pace.yield_now().await;
        }
    }

    /// The table's wait for its target while the arm moves (unguarded): a look every
    /// [`BESIDE_ARM`] from the start, until the arm has arrived (`arrived`), then the close
    /// wait. The looks keep to that schedule whatever else cuts the arm's slices (on the
    /// virtual clock, the supervision task's checks), so a resumed session looks when the
    /// uninterrupted one did.
    async fn table_beside_arm(
        &self,
        table: &DeviceActor<dyn Table>,
        arrived: &tokio::sync::Notify,
    ) -> Result<[f64; 3], DeviceError> {
        let start = self.pace.now();
        let deadline = start + MOVE;
        let mut next = start + BESIDE_ARM;
        loop {
            tokio::select! {
                biased;
                () = arrived.notified() => return self.table_wait(table).await,
                () = self.pace.until(next) => {}
            }
            let left = deadline.saturating_sub(self.pace.now());
            // One look at the drives: a status round, no waiting.
            if let Some(p) = table
                .run(left + IO, move |t| t.poll_reached(Duration::ZERO, left))
                .await?
            {
                return Ok(p);
            }
            let now = self.pace.now();
            while next <= now {
                next += BESIDE_ARM;
            }
        }
    }

    /// The table's wait for its target in slices (unguarded).
    async fn table_wait(&self, table: &DeviceActor<dyn Table>) -> Result<[f64; 3], DeviceError> {
        let deadline = self.pace.now() + MOVE;
        loop {
            let left = deadline.saturating_sub(self.pace.now());
            let slice = self.pace.slice_until(deadline);
            if let Some(p) = table
                .run(left + IO, move |t| t.poll_reached(slice, left))
                .await?
            {
                return Ok(p);
            }
            self.pace.yield_now().await;
        }
    }
}
