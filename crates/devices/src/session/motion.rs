//! The rig's devices as the session's choreography holds them, and the moves it makes of them
//! on tokio: arm and table together (`try_join!`), each wait raced against the drives'
//! supervision alarm (`select!`), a fault cancelling the motion in progress — the table halted,
//! the arm no longer waited for (the controller has no stop: its driver reads the abandoned
//! move's reply before the next command).
//!
//! A safe stop ([`Brakes`]) quick-stops the table's drives and stops the arm, from handles
//! held apart from the session's state.
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
use crate::session::options::StopRequest;

/// Timeout of a single device exchange.
pub(crate) const IO: Duration = Duration::from_secs(2);
/// Timeout of an arm or table move.
pub(crate) const MOVE: Duration = Duration::from_secs(120);
/// How long a safe stop waits for the arm to finish the move it is in (the Movemaster has no
/// stop command; an RV-M2 move at the session's speed takes a few seconds).
const ARM_AT_REST: Duration = Duration::from_secs(10);
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
    /// Once raised, no further motion is sent (the session then stops safely).
    pub stop: StopRequest,
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
            stop: StopRequest::new(),
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
        self.not_stopping(DeviceName::Table)?;
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
        self.not_stopping(DeviceName::Table)?;
        let (table, panel) = (self.table()?, self.panel()?);
        approach(table, panel, &self.alarm, &self.pace, a).await
    }

    /// One point-sensor reading (mm, sensor frame).
    pub async fn read_sensor(&self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        self.sensor()?.run(timeout, move |s| s.read(timeout)).await
    }

    /// `Err` once a stop was requested: no motion goes out after it (the session's stop
    /// branch then takes over at its next look).
    pub fn not_stopping(&self, device: DeviceName) -> Result<(), DeviceError> {
        match self.stop.reason() {
            None => Ok(()),
            Some(why) => Err(DeviceError::NotReady {
                device,
                detail: format!("no motion sent: the session is stopping ({why})"),
            }),
        }
    }

    /// The arm's move in slices (unguarded).
    async fn arm_motion(&self, q: Vec<f64>) -> Result<Vec<f64>, DeviceError> {
        self.not_stopping(DeviceName::Arm)?;
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

/// What a safe stop needs of the devices: clones of their handles, taken before anything can
/// go wrong, so that a stop can be made whatever state the session is in (bringing the rig up,
/// registering, measuring).
#[derive(Clone)]
pub(crate) struct Brakes {
    arm: DeviceActor<dyn Arm>,
    table: Option<DeviceActor<dyn Table>>,
}

impl Brakes {
    /// The brakes of `motion`'s devices.
    pub fn of(motion: &Motion) -> Self {
        Brakes {
            arm: motion.arm.clone(),
            table: motion.table().ok().cloned(),
        }
    }

    /// The safe stop: the table's drives quick-stopped first (theirs is the set-point that
    /// would otherwise stay active), then the arm stopped; what each did, for the message.
    pub async fn apply(&self) -> String {
        let mut said = Vec::new();
        if let Some(table) = &self.table {
            said.push(match table.run(IO, |t| t.quick_stop(IO)).await {
                Ok(p) => format!(
                    "the table's drives quick-stopped at ({:.3}, {:.3}, {:.3}) mm",
                    p[0], p[1], p[2]
                ),
                Err(e) => {
                    tracing::error!("table: quick stop not confirmed: {e}");
                    format!("the table did NOT confirm its quick stop ({e}): check that it stands still, or switch its drives off")
                }
            });
        }
        said.push(
            match self.arm.run(ARM_AT_REST, |a| a.stop(ARM_AT_REST)).await {
                Ok(true) => "the arm at rest".to_string(),
                Ok(false) => format!(
                    "the arm still finishing its last move after {ARM_AT_REST:?} (its controller has no stop command: use the drive unit's STOP switch if it must stop at once)"
                ),
                Err(e) => format!("the arm did not confirm it is at rest ({e})"),
            },
        );
        said.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::devices::emulators::faults::InjectedFault;
    use crate::devices::{open_rig, SimClock, SimControls};
    use rigcal_core::rig::Rig;

    fn rig() -> Rig {
        Rig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2.toml"
        )))
        .expect("the shipped rig file loads")
    }

    /// The rig's emulators (all `sim` in the rig file) with the arm homed, the table enabled
    /// and its drives supervised; the emulators' fault handles; a runtime for the clock.
    fn bring_up(clock: SimClock) -> (Motion, SimControls, tokio::runtime::Runtime) {
        let rig = rig();
        let opened = open_rig(&rig, None, clock).expect("the rig opens");
        assert_eq!(
            opened.devices.clock.is_virtual(),
            clock == SimClock::Virtual
        );
        let controls = opened.devices.sim.clone().expect("emulated devices");
        let mut motion = Motion::new(opened.devices).expect("the devices start");
        let rt = motion.pace.runtime().expect("runtime");
        rt.block_on(async {
            motion.arm.run(MOVE, |a| a.home(MOVE)).await.expect("home");
            let table = motion.table().expect("table rig");
            table.run(IO, |t| t.enable(IO)).await.expect("enable");
            motion.supervise(Duration::from_millis(100));
        });
        (motion, controls, rt)
    }

    fn deg(v: [f64; 5]) -> Vec<f64> {
        v.iter().map(|d| d.to_radians()).collect()
    }

    /// From the nest (0, 90, -90, 0, 0) the arm needs seconds for this move.
    const FAR: [f64; 5] = [80.0, 60.0, -60.0, 0.0, 0.0];

    #[test]
    fn a_table_fault_during_a_simultaneous_move_cancels_the_arms_wait() {
        let (motion, controls, rt) = bring_up(SimClock::Virtual);
        let table_faults = controls.table.clone().expect("table emulator");
        let arm_faults = controls.arm.clone().expect("arm emulator");
        rt.block_on(async {
            // The arm's end is never reported (a lost reply): its wait alone would last its
            // whole timeout. The table's drive x faults 50 ms into its move.
            arm_faults.lock().expect("faults").drop_replies = 1;
            table_faults.lock().expect("faults").fault_on_next_move = Some(InjectedFault {
                axis: 0,
                after: Duration::from_millis(50),
                emcy_code: 0x2310,
            });
            motion.table_speed(100.0).await.expect("speed");
            motion
                .start_table([600.0, 280.0, 0.0])
                .await
                .expect("start");
            let t0 = motion.pace.now();
            let e = motion.arm_and_table(&deg(FAR)).await.unwrap_err();
            let took = motion.pace.now() - t0;
            assert!(
                matches!(e, DeviceError::DriveFault { axis: 'x', .. }),
                "{e}"
            );
            assert!(
                took < Duration::from_millis(500),
                "the fault ended the wait after {took:?} (the arm's timeout is {MOVE:?})"
            );
            // Halted where the fault stopped it, far from the target.
            let x = controls.table_truth.lock().expect("truth").axes[0];
            assert_eq!(x.from, x.to, "the x axis stands still");
            assert!(x.to < 420.0, "x at {} mm", x.to);
        });
    }

    #[test]
    fn after_a_cancelled_wait_the_arm_finishes_its_move_before_the_next() {
        let (motion, controls, rt) = bring_up(SimClock::Virtual);
        let table_faults = controls.table.clone().expect("table emulator");
        rt.block_on(async {
            table_faults.lock().expect("faults").fault_on_next_move = Some(InjectedFault {
                axis: 1,
                after: Duration::from_millis(50),
                emcy_code: 0x8611,
            });
            motion
                .start_table([400.0, 380.0, 0.0])
                .await
                .expect("start");
            let t0 = motion.pace.now();
            assert!(motion.arm_and_table(&deg(FAR)).await.is_err());
            assert!(motion.pace.now() - t0 < Duration::from_millis(500));
            let table = motion.table().expect("table");
            table
                .run(IO * 5, |t| t.fault_reset(IO * 5))
                .await
                .expect("reset");
            motion.alarm.clear();
            // The next move goes out only after the abandoned one has ended (the controller
            // executes in order), and starts from where that one went.
            let q = motion.arm_to(&deg([80.0, 61.0, -60.0, 0.0, 0.0])).await;
            let q = q.expect("the arm moves on");
            assert!((q[1].to_degrees() - 61.0).abs() < 0.06, "{q:?}");
            assert!(
                motion.pace.now() - t0 > Duration::from_secs(1),
                "it waited for the first"
            );
        });
    }

    #[test]
    fn a_lost_heartbeat_aborts_the_approach_and_halts_the_table() {
        let (motion, controls, rt) = bring_up(SimClock::Virtual);
        let table_faults = controls.table.clone().expect("table emulator");
        rt.block_on(async {
            motion.table_speed(100.0).await.expect("speed");
            motion
                .start_table([100.0, 100.0, 0.0])
                .await
                .expect("start");
            motion.table_reached().await.expect("reached");
            // Away from the pin: no touch can end this approach, only its 5 s timeout.
            table_faults.lock().expect("faults").silent_heartbeat[2] = true;
            let t0 = motion.pace.now();
            let a = Approach {
                xy_mm: [100.0, 100.0],
                z_from_mm: 0.0,
                z_to_mm: 20.0,
                speed_mm_s: 5.0,
                timeout: Duration::from_secs(5),
                latch: false,
            };
            let e = motion.contact(&a).await.unwrap_err();
            let took = motion.pace.now() - t0;
            assert!(
                matches!(e, DeviceError::HeartbeatLost { axis: 'z', .. }),
                "{e}"
            );
            // Three periods of silence since the last heartbeat seen (the limit), then at most
            // a supervision period — not the approach's timeout.
            assert!(took < Duration::from_millis(600), "{took:?}");
            let z = controls.table_truth.lock().expect("truth").axes[2];
            assert_eq!(z.from, z.to, "z stands still");
            assert!(
                z.to < 5.0,
                "halted at z {} mm, far below the approach's end",
                z.to
            );
        });
    }

    #[test]
    fn on_real_time_the_devices_answer_from_their_threads() {
        let (motion, _controls, rt) = bring_up(SimClock::Real);
        rt.block_on(async {
            let started = std::time::Instant::now();
            motion.table_speed(100.0).await.expect("speed");
            motion
                .start_table([401.0, 280.0, 0.0])
                .await
                .expect("start");
            let (q, at) = motion
                .arm_and_table(&deg([0.5, 90.0, -90.0, 0.0, 0.0]))
                .await
                .expect("both moves");
            assert!((q[0].to_degrees() - 0.5).abs() < 0.06, "{q:?}");
            assert!((at[0] - 401.0).abs() < 0.01, "{at:?}");
            // Real time passed: the arm's reply alone takes the emulator's 5 ms.
            let took = started.elapsed();
            assert!(
                took > Duration::from_millis(10) && took < Duration::from_secs(5),
                "{took:?}"
            );
        });
    }
}
