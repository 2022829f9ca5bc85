//! The three kinds of driver a rig file can name, one trait each, in the shape of probe-rs's
//! `ProbeFactory`: a name, the checks of its settings, a constructor over a real transport and
//! the emulator a dry run speaks to instead. The factory opens the transport the rig file names
//! (a serial port, a CAN interface) or puts the emulator behind a polled link, and hands either
//! to the same constructor, so a dry run drives the same driver code as the rig.

use rigcal_core::rig::{Rig, TablePanel};

use crate::devices::clock::SharedClock;
use crate::devices::drivers::canopen::settings::TableConfig;
use crate::devices::drivers::movemaster::settings::ArmConfig;
use crate::devices::drivers::penmount::settings::PanelConfig;
use crate::devices::emulators::faults::{ArmFaultHandle, PanelFaultHandle, TableFaultHandle};
use crate::devices::emulators::physics::SharedPhysics;
use crate::devices::emulators::{ByteEmulator, FrameEmulator, SharedTable};
use crate::devices::keys::KeyError;
use crate::devices::safety::CartesianSolver;
use crate::devices::traits::{Arm, DeviceError, Panel, Table};
use crate::transports::{ByteTransport, CanBus};

/// An emulator and the handle its faults are injected through.
#[derive(Debug)]
pub struct Emulated<E: ?Sized, F> {
    /// The emulator, to serve or to poll.
    pub emulator: Box<E>,
    /// Its faults and counters.
    pub faults: F,
}

/// An arm as its driver opened it.
pub struct OpenedArm {
    /// The driver.
    pub arm: Box<dyn Arm>,
    /// How its controller carries out a Cartesian move, for the joint-limit wrapper to check
    /// before anything is sent; `None` when the controller has no Cartesian command.
    pub cartesian: Option<Box<dyn CartesianSolver>>,
}

/// An arm driver: `[devices.arm] driver = "NAME"`, over a byte stream (a serial port, or an
/// emulator).
pub trait ArmDriver: Sync {
    /// The name in the rig file.
    fn name(&self) -> &'static str;
    /// Checks the keys of `[devices.arm]` this driver reads (transport and serial line are
    /// checked before); on failure the key (under `devices.`) and why.
    fn check(&self, cfg: &ArmConfig) -> Result<(), KeyError>;
    /// The driver for `rig`'s arm over `io`, on `clock`.
    fn open(
        &self,
        rig: &Rig,
        cfg: &ArmConfig,
        io: Box<dyn ByteTransport>,
        clock: SharedClock,
    ) -> Result<OpenedArm, DeviceError>;
    /// The controller's emulator for `rig`'s arm in `physics`' world, powered on.
    fn emulator(
        &self,
        rig: &Rig,
        cfg: &ArmConfig,
        physics: SharedPhysics,
    ) -> Emulated<dyn ByteEmulator, ArmFaultHandle>;
}

/// A table driver: `[devices.table] driver = "NAME"`, over a CAN bus (SocketCAN, slcan, or an
/// emulator).
pub trait TableDriver: Sync {
    /// The name in the rig file.
    fn name(&self) -> &'static str;
    /// Checks the keys of `[devices.table]` this driver reads (the transport is checked
    /// before); on failure the key (under `devices.`) and why.
    fn check(&self, cfg: &TableConfig) -> Result<(), KeyError>;
    /// The driver over `bus`, on `clock`.
    fn open(
        &self,
        cfg: &TableConfig,
        bus: Box<dyn CanBus>,
        clock: SharedClock,
    ) -> Result<Box<dyn Table>, DeviceError>;
    /// The drives' emulator, their true motion written to `truth`.
    fn emulator(
        &self,
        cfg: &TableConfig,
        truth: SharedTable,
    ) -> Emulated<dyn FrameEmulator, TableFaultHandle>;
}

/// A touch-panel driver: `[devices.panel] driver = "NAME"`, over a byte stream (a serial port,
/// or an emulator).
pub trait PanelDriver: Sync {
    /// The name in the rig file.
    fn name(&self) -> &'static str;
    /// Checks the keys of `[devices.panel]` this driver reads (transport and serial line are
    /// checked before); on failure the key (under `devices.`) and why.
    fn check(&self, cfg: &PanelConfig) -> Result<(), KeyError>;
    /// The driver for the rig's panel (size and counts from `[instrument]`) over `io`, on
    /// `clock`.
    fn open(
        &self,
        panel: &TablePanel,
        cfg: &PanelConfig,
        io: Box<dyn ByteTransport>,
        clock: SharedClock,
    ) -> Result<Box<dyn Panel>, DeviceError>;
    /// The controller's emulator: the pin from `physics`, the panel on the table's true
    /// motion `table`.
    fn emulator(
        &self,
        panel: &TablePanel,
        cfg: &PanelConfig,
        physics: SharedPhysics,
        table: SharedTable,
    ) -> Emulated<dyn ByteEmulator, PanelFaultHandle>;
}
