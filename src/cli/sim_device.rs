//! `rigcal sim-device arm|table|panel|rig --rig R --pty`: emulators served on pseudo-terminals
//! ([`rigcal_devices::devices::sim_device`]). One device: prints its port path on the first
//! line of stdout. `rig`: the whole rig on one shared simulated world (a scenario's with
//! `--sim`), one line per port (`arm PATH`, `table slcan:PATH`, `panel PATH`, `world SOCKET`)
//! and, with `--write-rig`, a last line `rig FILE` once that rig file is written. Then serves
//! until killed.

use anyhow::{bail, Context, Result};
use rigcal_devices::devices::sim_device::{
    rehearsal_rig_text, serve_on_pty, serve_rig_on_ptys, EmulatedDevice,
};
use rigcal_devices::devices::{NoHook, SimSetup, SimWorld};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// What to emulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Device {
    /// The Movemaster controller (RS-232 lines), alone on a nominal world.
    Arm,
    /// The three CiA 402 drives behind an slcan adapter, alone on a nominal world.
    Table,
    /// The PenMount 6000 controller, alone on a nominal world.
    Panel,
    /// All three on one shared world (a rehearsal of a session through the real transports).
    Rig,
}

/// Arguments of `rigcal sim-device`.
#[derive(Debug, clap::Args)]
#[command(after_help = "\
A rehearsal through the real serial and slcan transports:
  rigcal sim-device rig --rig rigs/rv-m2.toml --sim sim/rig-realistic.toml --pty --write-rig out/pty-rig.toml &
  rigcal session --rig out/pty-rig.toml --out out/rehearsal --points 300 --seed 31
Kill the session at any moment and resume it with --resume while the server runs: its points and
readings are those of `rigcal session --rig rigs/rv-m2.toml --sim sim/rig-realistic.toml --seed 31`
(times differ; so do readings of time-dependent effects such as drift, which follow real time).")]
pub struct Args {
    /// The device to emulate, or `rig` for all three on one world.
    #[arg(value_enum)]
    device: Device,
    /// Rig file (TOML); `[devices]` gives the emulators' settings.
    #[arg(long)]
    rig: PathBuf,
    /// Serve on new pseudo-terminals and print their paths.
    #[arg(long)]
    pty: bool,
    /// `rig` only: the world is this scenario's truth (sim/*.toml), as in `rigcal session
    /// --sim`; default a nominal world.
    #[arg(long)]
    sim: Option<PathBuf>,
    /// `rig` only: overrides the scenario's own seed (as `rigcal session --sim-seed`).
    #[arg(long, requires = "sim")]
    sim_seed: Option<u64>,
    /// `rig` only: write a rig file whose `[devices]` point at the served ports (and the
    /// world's socket), for `rigcal session --rig FILE`.
    #[arg(long, value_name = "FILE")]
    write_rig: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    if !a.pty {
        bail!("only --pty is supported: the emulators are served on pseudo-terminals");
    }
    if a.device != Device::Rig && (a.sim.is_some() || a.write_rig.is_some()) {
        bail!("--sim and --write-rig are for `sim-device rig` (one device alone has a nominal world and no rig file of its own)");
    }
    let rig = rigcal_devices::config::load_rig(&a.rig)?;
    let device = match a.device {
        Device::Arm => EmulatedDevice::Arm,
        Device::Table => EmulatedDevice::Table,
        Device::Panel => EmulatedDevice::Panel,
        Device::Rig => return serve_rig(&a, &rig),
    };
    let served = serve_on_pty(&rig, device)?;
    print_lines(std::slice::from_ref(&served.path))?;
    serve_forever()?;
    drop(served);
    Ok(())
}

/// The whole rig on one world until killed.
fn serve_rig(a: &Args, rig: &rigcal_core::rig::Rig) -> Result<()> {
    let scenario = rigcal_calibration::dry_run_scenario(rig, &a.rig, a.sim.as_deref(), a.sim_seed)?;
    let world = match &scenario {
        Some(s) => rigcal_sim::emulation::sim_world(s),
        None => SimWorld {
            setup: SimSetup::nominal(rig),
            hook: Box::new(NoHook),
        },
    };
    let socket = std::env::temp_dir().join(format!("rigcal-world-{}.sock", std::process::id()));
    // A file left by an earlier process of the same id (killed, so it could not remove it).
    let _ = std::fs::remove_file(&socket);
    let served = serve_rig_on_ptys(rig, world, &socket)?;
    let mut lines = vec![
        format!("arm {}", served.arm.path),
        format!("table slcan:{}", served.table.path),
        format!("panel {}", served.panel.path),
        format!("world {}", served.world.path.display()),
    ];
    if let Some(file) = &a.write_rig {
        write_atomically(file, &rehearsal_rig_text(rig, &served)?)?;
        lines.push(format!("rig {}", file.display()));
    }
    print_lines(&lines)?;
    serve_forever()?;
    // Stops the emulators and removes the world's socket file.
    drop(served);
    Ok(())
}

/// Writes `text` to `path` through a temporary file beside it, so a reader never sees half.
fn write_atomically(path: &Path, text: &str) -> Result<()> {
    let tmp = path.with_extension("toml.part");
    std::fs::write(&tmp, text).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path)
        .with_context(|| format!("cannot move {} to {}", tmp.display(), path.display()))
}

fn print_lines(lines: &[String]) -> Result<()> {
    let mut out = std::io::stdout().lock();
    for l in lines {
        writeln!(out, "{l}")?;
    }
    out.flush()?;
    Ok(())
}

/// Set by SIGTERM or SIGINT: the served ports close and the world's socket file goes.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn request_stop(_signal: libc::c_int) {
    // An atomic store is async-signal-safe.
    STOP.store(true, Ordering::SeqCst);
}

/// Serves (the caller holds what is served) until SIGTERM or SIGINT.
fn serve_forever() -> Result<()> {
    let handler = request_stop as extern "C" fn(libc::c_int) as libc::sighandler_t;
    // SAFETY: the handler only stores to an atomic.
    unsafe {
        libc::signal(libc::SIGTERM, handler);
        libc::signal(libc::SIGINT, handler);
    }
    while !STOP.load(Ordering::SeqCst) {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    Ok(())
}
