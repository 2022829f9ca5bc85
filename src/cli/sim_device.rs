//! `rigcal sim-device arm|table|panel --rig R --pty`: one device's emulator served on a
//! pseudo-terminal ([`rigcal_devices::devices::sim_device`]). Prints the port path on the first
//! line of stdout, then serves until killed.

use anyhow::{bail, Result};
use rigcal_devices::devices::sim_device::{serve_on_pty, EmulatedDevice};
use std::io::Write;
use std::path::PathBuf;

super::options::value_enum! {
    /// Which device to emulate.
    Device => EmulatedDevice {
        /// The Movemaster controller (RS-232 lines).
        Arm,
        /// The three CiA 402 drives behind an slcan adapter.
        Table,
        /// The PenMount 6000 controller.
        Panel,
    }
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
    let rig = rigcal_devices::config::load_rig(&a.rig)?;
    let served = serve_on_pty(&rig, a.device.into())?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", served.path)?;
    out.flush()?;
    drop(out);
    loop {
        std::thread::sleep(std::time::Duration::from_secs(3600));
    }
}
