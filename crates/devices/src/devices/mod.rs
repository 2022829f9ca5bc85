//! Rig devices: the RV-M2 arm (Movemaster over RS-232), the x-y-z table (three CiA 402 drives
//! on CANopen) and the PenMount touch panel (serial), each behind a small trait.
//!
//! | module | holds |
//! |---|---|
//! | [`traits`] | [`Arm`], [`Table`], [`Panel`], [`PointSensor`] and [`DeviceError`] |
//! | [`arm_movemaster`], [`table_canopen`], [`panel_penmount`] | drivers over any transport |
//! | [`safety`] | joint limits, table travel, ascending z: refused before a byte is sent |
//! | [`contact`] | the contact measurement (blocking, and the session's asynchronous approach) and the approach-speed rule |
//! | [`actor`], [`pace`] | devices as futures: inline on the virtual clock, on their own threads on real time; slices and waits per clock |
//! | [`supervision`] | the task that supervises the drives' heartbeats and faults, and its alarm |
//! | [`factory`] | the one switch point: rig file (and a scenario) → the boxed devices and the hook |
//! | [`hook`] | the session's opaque side channel to a simulated world (nothing on the rig) |
//! | [`clock`] | real time and a shared virtual clock |
//! | [`profile`] | trapezoidal motion profiles (the drives', the emulator's, the estimate's) |
//! | [`emulators`] | simulated back-ends speaking each protocol, with fault injection; a simulated point sensor |
//!
//! Units: joints in radians, table and panel in millimetres, times as [`std::time::Duration`]
//! on a [`clock::Clock`]. The session code cannot tell simulated devices from real ones: what a
//! dry run's world needs besides the protocols goes through the opaque [`hook::RigHook`].

pub mod actor;
pub mod arm_movemaster;
pub mod clock;
pub mod contact;
pub mod controller;
pub mod emulators;
pub mod factory;
pub mod hook;
pub mod pace;
pub mod panel_penmount;
pub mod profile;
pub mod safety;
pub mod supervision;
pub mod table_canopen;
pub mod traits;

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
