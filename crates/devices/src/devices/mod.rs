//! Rig devices: the RV-M2 arm (Movemaster over RS-232), the x-y-z table (three CiA 402 drives
//! on CANopen) and the PenMount touch panel (serial), each behind a small trait, each driver
//! named by the rig file and found in a registry.
//!
//! | module | holds |
//! |---|---|
//! | [`traits`] | [`Arm`], [`Table`], [`Panel`], [`PointSensor`] and [`DeviceError`] |
//! | [`config`] | the rig file's `[devices]` section, read and checked (each device's keys by its driver) |
//! | [`drivers`] | the registry, and one folder per driver: driver, settings, emulator (and the Movemaster's controller kinematics) |
//! | [`command_path`] | joint or Cartesian commands for compensated moves ([`CommandPath`]) |
//! | [`safety`] | joint limits, table travel, ascending z: refused before a byte is sent |
//! | [`contact`] | the contact measurement (blocking, and the session's asynchronous approach) and the approach-speed rule |
//! | [`actor`], [`pace`] | devices as futures: inline on the virtual clock, on their own threads on real time; slices and waits per clock |
//! | [`supervision`] | the task that supervises the drives' heartbeats and faults, and its alarm |
//! | [`factory`] | the one switch point: rig file (and a scenario) → the boxed devices and the hook |
//! | [`hook`] | the session's opaque side channel to a simulated world (nothing on the rig) |
//! | [`clock`] | real time and a shared virtual clock |
//! | [`profile`] | trapezoidal motion profiles (the drives', the emulator's, the estimate's) |
//! | [`emulators`] | what the simulated back-ends share (polled and served links, faults, physics), and a simulated point sensor |
//! | `sim_device` | one device's emulator served on a pseudo-terminal (`rigcal sim-device`; Unix) |
//!
//! Units: joints in radians, table and panel in millimetres, times as [`std::time::Duration`]
//! on a [`clock::Clock`]. The session code cannot tell simulated devices from real ones: what a
//! dry run's world needs besides the protocols goes through the opaque [`hook::RigHook`].

pub mod actor;
pub mod clock;
pub mod command_path;
pub mod config;
pub mod contact;
pub mod drivers;
pub mod emulators;
pub mod factory;
pub mod hook;
mod keys;
pub mod pace;
pub mod profile;
pub mod safety;
#[cfg(unix)]
pub mod sim_device;
pub mod supervision;
pub mod traits;

pub use command_path::CommandPath;
pub use factory::{
    open_devices, open_rig, Backend, InstrumentDevices, OpenedRig, RigDevices, SimClock,
    SimControls, SimSetup, SimWorld,
};
pub use hook::{HookError, NoHook, RigHook};
pub use traits::{
    Arm, ArmPose, ArmStatus, DeviceError, DeviceErrorKind, DeviceName, Panel, PanelStats,
    PointSensor, Table, Touch,
};
#[cfg(any(test, feature = "mock"))]
pub use traits::{MockArm, MockPanel, MockPointSensor, MockTable};
