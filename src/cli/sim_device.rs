//! `rigcal sim-device arm|table|panel --rig R --pty`: one device's emulator served on a
//! pseudo-terminal, so outside tools and HIL scripts can talk to it as to the hardware. Prints
//! the port path on the first line of stdout, then serves until killed. The table speaks slcan
//! there (an slcan adapter with the three drives behind it). Real time; the arm stands at its
//! nest and the table at its power-on position in a nominal world.

use anyhow::{bail, Context, Result};
use rigcal_core::rig::Rig;
use rigcal_devices::devices::clock::RealClock;
use rigcal_devices::devices::emulators::{serve_bytes, SlcanAdapter};
use rigcal_devices::devices::factory::{sim_emulators, SimSetup};
use rigcal_devices::transports::SerialTransport;
use serialport::{SerialPort, TTYPort};
use std::io::Write;
use std::path::PathBuf;

/// Which device to emulate.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Device {
    /// The Movemaster controller (RS-232 lines).
    Arm,
    /// The three CiA 402 drives behind an slcan adapter.
    Table,
    /// The PenMount 6000 controller.
    Panel,
}

/// Arguments of `rigcal sim-device`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The device to emulate.
    #[arg(value_enum)]
    device: Device,
    /// Rig file (TOML); `[devices]` gives the emulator's settings.
    #[arg(long)]
    rig: PathBuf,
    /// Serve on a new pseudo-terminal and print its path.
    #[arg(long)]
    pty: bool,
}

pub fn run(a: Args) -> Result<()> {
    if !a.pty {
        bail!("only --pty is supported: the emulator is served on a pseudo-terminal");
    }
    let rig = Rig::load(&a.rig)?;
    let cfg = rigcal_devices::config::DevicesConfig::read(&rig);
    let mut setup = SimSetup::nominal(&rig);
    setup.clock = RealClock::shared();
    let emus = sim_emulators(&rig, &cfg, &setup)?;
    let (master, slave) = TTYPort::pair().context("cannot create a pseudo-terminal pair")?;
    let path = slave.name().context("the pseudo-terminal has no name")?;
    let io = SerialTransport::from_port(Box::new(master));
    let clock = setup.clock.clone();
    let _served = match a.device {
        Device::Arm => serve_bytes(emus.arm, io, clock),
        Device::Panel => serve_bytes(emus.panel, io, clock),
        Device::Table => serve_bytes(SlcanAdapter::new(emus.table), io, clock),
    };
    let mut out = std::io::stdout().lock();
    writeln!(out, "{path}")?;
    out.flush()?;
    drop(out);
    // Keep the slave end open so the master does not see a hang-up between clients.
    let _keep = slave;
    loop {
        std::thread::sleep(std::time::Duration::from_secs(3600));
    }
}
