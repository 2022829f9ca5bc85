//! The one switch point: a rig file (and a choice between its transports and an all-simulated
//! rig) in, the boxed devices out — arm plus table and panel, or arm plus a point sensor — each
//! wrapped in its safety limits.
//!
//! Transports per device come from `[devices]`: `sim` (an emulator behind a polled link), a
//! serial port path (arm, panel), `can0` / `socketcan:can0` or `slcan:/dev/ttyACM0` (table).
//! Nothing else differs between a dry run and the rig; no cargo feature chooses.
//!
//! Each device's driver comes from the registry ([`crate::devices::drivers`]) by the name the
//! rig file gives it; the factory opens the transport or the driver's emulator and wraps what
//! the driver returns, and names no driver itself.
//!
//! A session opens its rig with [`open_rig`]: the devices plus the opaque [`RigHook`] through
//! which a dry run's world learns what the protocols do not carry (see [`crate::devices::hook`]).

use std::sync::atomic::AtomicUsize;
use std::sync::{Arc, Mutex};

use crate::devices::clock::{RealClock, SharedClock, VirtualClock};
use crate::devices::command_path::CommandPath;
use crate::devices::config::{ArmConfig, DevicesConfig, TableConfig};
use crate::devices::drivers::{self, Emulated};
use crate::devices::emulators::faults::{ArmFaultHandle, PanelFaultHandle, TableFaultHandle};
use crate::devices::emulators::physics::{NominalPhysics, SharedPhysics};
use crate::devices::emulators::sensor::SimPointSensor;
use crate::devices::emulators::{
    ByteEmulator, FrameEmulator, PolledCan, PolledSerial, SharedTable, TableTruth,
};
use crate::devices::hook::{NoHook, RigHook};
use crate::devices::keys::KeyError;
use crate::devices::safety::{CartesianArm, LimitedArm, LimitedTable};
use crate::devices::traits::{Arm, DeviceError, DeviceName, Panel, PointSensor, Table};
use crate::transports::{
    ByteTransport, CanBus, FlowControl, Parity, SerialSettings, SerialTransport, SlcanBus,
};
use rigcal_core::rig::{Instrument, Rig, TablePanel};

/// The simulated world the emulators use.
#[derive(Clone)]
pub struct SimSetup {
    /// The physics (true arm, true table registration).
    pub physics: SharedPhysics,
    /// The clock shared by emulators and drivers.
    pub clock: SharedClock,
    /// Where the table stands at power-on (mm, table frame).
    pub table_start_mm: [f64; 3],
}

impl std::fmt::Debug for SimSetup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimSetup")
            .field("clock", &self.clock)
            .field("table_start_mm", &self.table_start_mm)
            .finish_non_exhaustive()
    }
}

impl SimSetup {
    /// The rig's nominal arm without errors, on a virtual clock, the table centred in x and y
    /// and at the bottom of z.
    pub fn nominal(rig: &Rig) -> Self {
        let start = match &rig.instrument {
            Instrument::TablePanel(t) => [t.travel_mm.x / 2.0, t.travel_mm.y / 2.0, 0.0],
            _ => [0.0; 3],
        };
        SimSetup {
            physics: NominalPhysics::nominal(rig).shared(),
            clock: VirtualClock::shared(),
            table_start_mm: start,
        }
    }
}

/// Which back-ends to use.
#[derive(Debug, Clone)]
pub enum Backend {
    /// What the rig file's `[devices]` says per device (`sim` entries use a nominal world on a
    /// virtual clock if every device is simulated, on real time otherwise).
    RigFile,
    /// Every device simulated in `SimSetup`'s world, whatever the rig file says.
    Simulated(SimSetup),
}

/// Handles to the emulators of a simulated rig: fault injection and inspection.
#[derive(Debug, Clone)]
pub struct SimControls {
    /// Arm faults and log.
    pub arm: Option<ArmFaultHandle>,
    /// Table faults and counters.
    pub table: Option<TableFaultHandle>,
    /// Panel faults and counters.
    pub panel: Option<PanelFaultHandle>,
    /// The table's true motion.
    pub table_truth: SharedTable,
    /// The physics.
    pub physics: SharedPhysics,
}

/// The devices of the rig's instrument.
pub enum InstrumentDevices {
    /// The x-y-z table (travel and ascending z enforced) and the touch panel.
    TablePanel {
        /// The table.
        table: Box<dyn Table>,
        /// The touch panel.
        panel: Box<dyn Panel>,
    },
    /// A point sensor (tracker, motion capture, ideal instrument).
    Sensor(Box<dyn PointSensor>),
}

/// The devices of a rig: the arm and its instrument.
pub struct RigDevices {
    /// The arm (joint limits enforced).
    pub arm: Box<dyn Arm>,
    /// The instrument.
    pub instrument: InstrumentDevices,
    /// The clock the drivers use.
    pub clock: SharedClock,
    /// Emulator handles when any device is simulated.
    pub sim: Option<SimControls>,
}

fn no_table() -> DeviceError {
    DeviceError::Config {
        key: "table".into(),
        reason: "the rig's instrument is a point sensor, not the table and panel".into(),
    }
}

impl RigDevices {
    /// True when the instrument is the table and panel.
    pub fn has_table(&self) -> bool {
        matches!(self.instrument, InstrumentDevices::TablePanel { .. })
    }

    /// The table, or a configuration error for a point-sensor rig.
    pub fn table(&mut self) -> Result<&mut dyn Table, DeviceError> {
        match &mut self.instrument {
            InstrumentDevices::TablePanel { table, .. } => Ok(table.as_mut()),
            InstrumentDevices::Sensor(_) => Err(no_table()),
        }
    }

    /// The panel, or a configuration error for a point-sensor rig.
    pub fn panel(&mut self) -> Result<&mut dyn Panel, DeviceError> {
        self.table_and_panel().map(|(_, p)| p)
    }

    /// Table and panel at once (a contact needs both).
    pub fn table_and_panel(&mut self) -> Result<(&mut dyn Table, &mut dyn Panel), DeviceError> {
        match &mut self.instrument {
            InstrumentDevices::TablePanel { table, panel } => Ok((table.as_mut(), panel.as_mut())),
            InstrumentDevices::Sensor(_) => Err(no_table()),
        }
    }

    /// Arm and table at once (they move together).
    pub fn arm_and_table(&mut self) -> Result<(&mut dyn Arm, &mut dyn Table), DeviceError> {
        match &mut self.instrument {
            InstrumentDevices::TablePanel { table, .. } => Ok((self.arm.as_mut(), table.as_mut())),
            InstrumentDevices::Sensor(_) => Err(no_table()),
        }
    }

    /// Stops the table where it is, if the rig has one (after a fault; errors are moot then).
    pub fn halt_table(&mut self, timeout: std::time::Duration) {
        if let Ok(t) = self.table() {
            let _ = t.halt(timeout);
        }
    }

    /// The point sensor, or a configuration error for a table rig.
    pub fn sensor(&mut self) -> Result<&mut dyn PointSensor, DeviceError> {
        match &mut self.instrument {
            InstrumentDevices::Sensor(s) => Ok(s.as_mut()),
            InstrumentDevices::TablePanel { .. } => Err(DeviceError::Config {
                key: "sensor".into(),
                reason: "the rig's instrument is the table and panel, not a point sensor".into(),
            }),
        }
    }
}

impl std::fmt::Debug for RigDevices {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RigDevices")
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

/// The emulators of a rig's three devices (each its driver's, from the registry) with their
/// fault handles, sharing one world.
#[derive(Debug)]
pub struct SimEmulators {
    /// The arm's controller.
    pub arm: Emulated<dyn ByteEmulator, ArmFaultHandle>,
    /// The table's drives.
    pub table: Emulated<dyn FrameEmulator, TableFaultHandle>,
    /// The panel's controller.
    pub panel: Emulated<dyn ByteEmulator, PanelFaultHandle>,
    /// The table's true motion.
    pub table_truth: SharedTable,
}

/// The rig's table-and-panel instrument, or a configuration error.
pub fn table_panel(rig: &Rig) -> Result<&TablePanel, DeviceError> {
    match &rig.instrument {
        Instrument::TablePanel(t) => Ok(t),
        _ => Err(DeviceError::Config {
            key: "table".into(),
            reason: "the rig's instrument is not kind = \"table_panel\"; the devices need the table and panel".into(),
        }),
    }
}

/// A registry lookup's error as a device error.
fn unknown(e: KeyError) -> DeviceError {
    let (key, reason) = e;
    DeviceError::Config { key, reason }
}

/// Builds the emulators of `rig`'s three devices (their drivers named in `cfg`) in `setup`'s
/// world.
pub fn sim_emulators(
    rig: &Rig,
    cfg: &DevicesConfig,
    setup: &SimSetup,
) -> Result<SimEmulators, DeviceError> {
    let tp = table_panel(rig)?;
    let arm_driver = drivers::arm(&cfg.arm.driver).map_err(unknown)?;
    let table_driver = drivers::table(&cfg.table.driver).map_err(unknown)?;
    let panel_driver = drivers::panel(&cfg.panel.driver).map_err(unknown)?;
    let truth: SharedTable = Arc::new(Mutex::new(TableTruth::at(setup.table_start_mm)));
    Ok(SimEmulators {
        arm: arm_driver.emulator(rig, &cfg.arm, Arc::clone(&setup.physics)),
        table: table_driver.emulator(&cfg.table, Arc::clone(&truth)),
        panel: panel_driver.emulator(
            tp,
            &cfg.panel,
            Arc::clone(&setup.physics),
            Arc::clone(&truth),
        ),
        table_truth: truth,
    })
}

fn open_serial(
    device: &str,
    path: &str,
    s: &SerialSettings,
) -> Result<SerialTransport, DeviceError> {
    SerialTransport::open(path, s).map_err(|source| DeviceError::Transport {
        device: match device {
            "arm" => DeviceName::Arm,
            "panel" => DeviceName::Panel,
            _ => DeviceName::Table,
        },
        source,
    })
}

fn open_can(t: &TableConfig) -> Result<Box<dyn CanBus>, DeviceError> {
    let tr = t.transport.trim();
    let err = |source| DeviceError::Transport {
        device: DeviceName::Table,
        source,
    };
    if let Some(path) = tr.strip_prefix("slcan:") {
        let line = SerialSettings {
            baud: t.slcan_baud,
            data_bits: 8,
            parity: Parity::None,
            stop_bits: 1,
            flow: FlowControl::None,
        };
        let io = open_serial("table", path, &line)?;
        return Ok(Box::new(SlcanBus::open(io, t.slcan).map_err(err)?));
    }
    let ifname = tr.strip_prefix("socketcan:").unwrap_or(tr);
    #[cfg(target_os = "linux")]
    {
        // socketcan's tokio socket on an I/O thread; the driver (on its own device thread)
        // talks to it through the blocking bridge.
        let name = ifname.to_string();
        Ok(Box::new(
            crate::transports::BridgedCanBus::spawn(ifname, move || {
                crate::transports::AsyncSocketCan::open(&name)
            })
            .map_err(err)?,
        ))
    }
    #[cfg(not(target_os = "linux"))]
    {
        Err(DeviceError::Config {
            key: "table.transport".into(),
            reason: format!("SocketCAN ({ifname}) exists only on Linux; use \"slcan:PORT\""),
        })
    }
}

/// Which clock simulated devices run on (real devices always run on real time).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SimClock {
    /// A virtual clock: nothing waits for real, the run is deterministic.
    #[default]
    Virtual,
    /// Real time (e.g. to watch a dry run, or beside outside tools).
    Real,
}

/// What the factory hands a session: the devices and the side channel to the rig.
#[derive(Debug)]
pub struct OpenedRig {
    /// The arm and its instrument, each in its safety limits.
    pub devices: RigDevices,
    /// What the session tells the rig besides commands: nothing on the real rig.
    pub hook: Box<dyn RigHook>,
}

impl OpenedRig {
    /// The same rig with every arm move through the controller's Cartesian command (`MP`) when
    /// `path` is [`CommandPath::Cartesian`] (a rig file's `command_path = "cartesian"`: the
    /// controller is used that way there); a move whose `MP` solution the joint limits refuse
    /// goes through `MJ` to the same joints and is counted in `fallbacks`
    /// ([`CartesianArm::with_joint_fallback`]). Unchanged for [`CommandPath::Joint`].
    pub fn on_command_path(self, path: CommandPath, fallbacks: &Arc<AtomicUsize>) -> Self {
        if path != CommandPath::Cartesian {
            return self;
        }
        let OpenedRig { devices, hook } = self;
        let arm = Box::new(CartesianArm::with_joint_fallback(
            devices.arm,
            Arc::clone(fallbacks),
        ));
        OpenedRig {
            devices: RigDevices { arm, ..devices },
            hook,
        }
    }
}

/// A simulated world for the emulators: their setup and the session's hook into it (the
/// simulation layer builds one from a scenario; the devices layer never sees the world itself).
pub struct SimWorld {
    /// Physics, clock and the table's start.
    pub setup: SimSetup,
    /// What the session tells the world besides the protocols.
    pub hook: Box<dyn RigHook>,
}

impl std::fmt::Debug for SimWorld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimWorld")
            .field("setup", &self.setup)
            .finish_non_exhaustive()
    }
}

/// The rig's devices for a session: emulators on a simulated world (on `clock`), or what the
/// rig file's `[devices]` says when there is none (its `sim` entries on a nominal world, on
/// `clock` when every device is simulated, on real time beside real devices). The world must be
/// for this rig (the caller checks names and instruments).
pub fn open_rig(
    rig: &Rig,
    world: Option<SimWorld>,
    clock: SimClock,
) -> Result<OpenedRig, DeviceError> {
    match world {
        Some(SimWorld { mut setup, hook }) => {
            if clock == SimClock::Real {
                setup.clock = RealClock::shared();
            }
            Ok(OpenedRig {
                devices: open_devices(rig, Backend::Simulated(setup))?,
                hook,
            })
        }
        None => {
            let cfg = DevicesConfig::read(rig);
            let all_sim = match &rig.instrument {
                Instrument::TablePanel(_) => {
                    is_sim(&cfg.arm.transport)
                        && is_sim(&cfg.table.transport)
                        && is_sim(&cfg.panel.transport)
                }
                Instrument::Ideal | Instrument::Tracker => is_sim(&cfg.arm.transport),
            };
            let backend = if all_sim && clock == SimClock::Real {
                let mut setup = SimSetup::nominal(rig);
                setup.clock = RealClock::shared();
                Backend::Simulated(setup)
            } else {
                Backend::RigFile
            };
            Ok(OpenedRig {
                devices: open_devices(rig, backend)?,
                hook: Box::new(NoHook),
            })
        }
    }
}

fn is_sim(t: &str) -> bool {
    t.trim() == "sim"
}

/// Opens the rig's devices: the arm and its instrument (table and panel, or a point sensor).
pub fn open_devices(rig: &Rig, backend: Backend) -> Result<RigDevices, DeviceError> {
    // The one check of `[devices]` before any device opens: the drivers below read it without
    // checking again.
    crate::config::DevicesConfig::of_rig(rig).map_err(|e| DeviceError::Config {
        key: "devices".into(),
        reason: e.to_string(),
    })?;
    match &rig.instrument {
        Instrument::TablePanel(_) => open_table_rig(rig, backend),
        Instrument::Ideal | Instrument::Tracker => open_sensor_rig(rig, backend),
    }
}

/// The rig file's arm driver over its emulator (`Some`) or the rig file's serial port, in the
/// joint limits (which also check a Cartesian move's solution when the controller has one).
fn open_arm(
    rig: &Rig,
    cfg: &ArmConfig,
    emulator: Option<Box<dyn ByteEmulator>>,
    clock: &SharedClock,
) -> Result<Box<dyn Arm>, DeviceError> {
    let driver = drivers::arm(&cfg.driver).map_err(unknown)?;
    let io: Box<dyn ByteTransport> = match emulator {
        Some(e) => Box::new(PolledSerial::new(e, Arc::clone(clock))),
        None => Box::new(open_serial("arm", &cfg.transport, &cfg.serial)?),
    };
    let opened = driver.open(rig, cfg, io, Arc::clone(clock))?;
    use rigcal_core::kinematics::Robot;
    let limited = LimitedArm::new(opened.arm, rig.chain.joints().to_vec());
    Ok(match opened.cartesian {
        Some(k) => Box::new(limited.with_cartesian(k)),
        None => Box::new(limited),
    })
}

/// A rig measured by a point sensor. No tracker driver exists yet: the sensor is simulated, so
/// the arm must be too (a real arm beside a simulated sensor would measure nothing real).
fn open_sensor_rig(rig: &Rig, backend: Backend) -> Result<RigDevices, DeviceError> {
    let cfg = DevicesConfig::read(rig);
    cfg.validate()
        .map_err(|(key, reason)| DeviceError::Config { key, reason })?;
    let setup = match backend {
        Backend::Simulated(setup) => setup,
        Backend::RigFile if is_sim(&cfg.arm.transport) => SimSetup::nominal(rig),
        Backend::RigFile => {
            return Err(DeviceError::Config {
                key: "arm.transport".into(),
                reason: "the rig measures with a point sensor (tracker or ideal instrument), for which rigcal has no hardware driver yet; run a dry run (--sim SCENARIO or arm transport \"sim\")".into(),
            })
        }
    };
    let clock = Arc::clone(&setup.clock);
    let mut controls = SimControls {
        arm: None,
        table: None,
        panel: None,
        table_truth: Arc::new(Mutex::new(TableTruth::at(setup.table_start_mm))),
        physics: Arc::clone(&setup.physics),
    };
    let emulated = drivers::arm(&cfg.arm.driver).map_err(unknown)?.emulator(
        rig,
        &cfg.arm,
        Arc::clone(&setup.physics),
    );
    controls.arm = Some(emulated.faults);
    let arm = open_arm(rig, &cfg.arm, Some(emulated.emulator), &clock)?;
    let sensor = SimPointSensor::new(Arc::clone(&setup.physics), Arc::clone(&clock));
    Ok(RigDevices {
        arm,
        instrument: InstrumentDevices::Sensor(Box::new(sensor)),
        clock,
        sim: Some(controls),
    })
}

/// A device's emulator when the device is `simulated`, its fault handle put in `faults` (a real
/// device has none).
fn simulated<E: ?Sized, F>(
    emulated: Option<Emulated<E, F>>,
    simulated: bool,
    faults: Option<&mut Option<F>>,
) -> Option<Box<E>> {
    let e = emulated.filter(|_| simulated)?;
    if let Some(slot) = faults {
        *slot = Some(e.faults);
    }
    Some(e.emulator)
}

/// The RV-M2 rig: arm, table and panel, each from the rig file or simulated.
fn open_table_rig(rig: &Rig, backend: Backend) -> Result<RigDevices, DeviceError> {
    let cfg = DevicesConfig::read(rig);
    cfg.validate()
        .map_err(|(key, reason)| DeviceError::Config { key, reason })?;
    let tp = table_panel(rig)?.clone();
    let (sim_arm, sim_table, sim_panel, setup) = match backend {
        Backend::Simulated(setup) => (true, true, true, setup),
        Backend::RigFile => {
            let (a, t, p) = (
                is_sim(&cfg.arm.transport),
                is_sim(&cfg.table.transport),
                is_sim(&cfg.panel.transport),
            );
            let mut setup = SimSetup::nominal(rig);
            if !(a && t && p) {
                setup.clock = RealClock::shared();
            }
            (a, t, p, setup)
        }
    };
    let clock = Arc::clone(&setup.clock);
    let any_sim = sim_arm || sim_table || sim_panel;
    let emus = if any_sim {
        Some(sim_emulators(rig, &cfg, &setup)?)
    } else {
        None
    };
    let mut controls = emus.as_ref().map(|e| SimControls {
        arm: None,
        table: None,
        panel: None,
        table_truth: Arc::clone(&e.table_truth),
        physics: Arc::clone(&setup.physics),
    });
    let (emu_arm, emu_table, emu_panel) = match emus {
        Some(e) => (Some(e.arm), Some(e.table), Some(e.panel)),
        None => (None, None, None),
    };
    let emu_arm = simulated(emu_arm, sim_arm, controls.as_mut().map(|c| &mut c.arm));
    let emu_table = simulated(
        emu_table,
        sim_table,
        controls.as_mut().map(|c| &mut c.table),
    );
    let emu_panel = simulated(
        emu_panel,
        sim_panel,
        controls.as_mut().map(|c| &mut c.panel),
    );

    let arm = open_arm(rig, &cfg.arm, emu_arm, &clock)?;
    let table_driver = drivers::table(&cfg.table.driver).map_err(unknown)?;
    let bus: Box<dyn CanBus> = match emu_table {
        Some(e) => Box::new(PolledCan::new(e, Arc::clone(&clock))),
        None => open_can(&cfg.table)?,
    };
    let table = table_driver.open(&cfg.table, bus, Arc::clone(&clock))?;
    let panel_driver = drivers::panel(&cfg.panel.driver).map_err(unknown)?;
    let io: Box<dyn ByteTransport> = match emu_panel {
        Some(e) => Box::new(PolledSerial::new(e, Arc::clone(&clock))),
        None => Box::new(open_serial(
            "panel",
            &cfg.panel.transport,
            &cfg.panel.serial,
        )?),
    };
    let panel = panel_driver.open(&tp, &cfg.panel, io, Arc::clone(&clock))?;
    Ok(RigDevices {
        arm,
        instrument: InstrumentDevices::TablePanel {
            table: Box::new(LimitedTable::new(
                table,
                [tp.travel_mm.x, tp.travel_mm.y, tp.travel_mm.z],
                cfg.table.pass_retract_mm,
            )),
            panel,
        },
        clock,
        sim: controls,
    })
}
