//! One device's emulator served on a pseudo-terminal (`rigcal sim-device`), so that outside
//! tools and HIL scripts talk to it as to the hardware. The table speaks slcan there (an slcan
//! adapter with the three drives behind it). Real time; the arm stands at its nest and the
//! table at its power-on position in a nominal world.

use crate::devices::clock::RealClock;
use crate::devices::config::DevicesConfig;
use crate::devices::emulators::{serve_bytes, Served, SlcanAdapter};
use crate::devices::factory::{sim_emulators, SimSetup};
use crate::devices::DeviceError;
use crate::transports::SerialTransport;
use rigcal_core::rig::Rig;
use serialport::{SerialPort, TTYPort};

/// Which device's emulator to serve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EmulatedDevice {
    /// The arm's controller (RS-232 lines).
    Arm,
    /// The table's drives behind an slcan adapter.
    Table,
    /// The panel's controller.
    Panel,
}

/// Why an emulator could not be served on a pseudo-terminal.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PtyError {
    /// The emulators could not be built from the rig file.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// The system gave no pseudo-terminal pair.
    #[error("cannot create a pseudo-terminal pair")]
    Pair(#[source] serialport::Error),
    /// The pseudo-terminal's device has no path.
    #[error("the pseudo-terminal has no name")]
    NoName,
}

/// An emulator served on a pseudo-terminal: the port to open, and what keeps it served (the
/// serving thread stops when this is dropped).
#[derive(Debug)]
pub struct PtyServed {
    /// The path of the port (the pseudo-terminal's other end).
    pub path: String,
    _served: Served,
    // The other end stays open, so the served end sees no hang-up between clients.
    _port: TTYPort,
}

/// Serves `device`'s emulator (the driver and settings of `rig`'s `[devices]`) on a new
/// pseudo-terminal, on real time.
pub fn serve_on_pty(rig: &Rig, device: EmulatedDevice) -> Result<PtyServed, PtyError> {
    let cfg = DevicesConfig::read(rig);
    let mut setup = SimSetup::nominal(rig);
    setup.clock = RealClock::shared();
    let emus = sim_emulators(rig, &cfg, &setup)?;
    let (master, port) = TTYPort::pair().map_err(PtyError::Pair)?;
    let path = port.name().ok_or(PtyError::NoName)?;
    let io = SerialTransport::from_port(Box::new(master));
    let clock = setup.clock.clone();
    let served = match device {
        EmulatedDevice::Arm => serve_bytes(emus.arm.emulator, io, clock),
        EmulatedDevice::Panel => serve_bytes(emus.panel.emulator, io, clock),
        EmulatedDevice::Table => serve_bytes(SlcanAdapter::new(emus.table.emulator), io, clock),
    };
    Ok(PtyServed {
        path,
        _served: served,
        _port: port,
    })
}
