//! The command line: one module per subcommand (clap derive). The only place that uses `anyhow`.

mod calibrate;
mod compare;
mod compensate;
mod demo;
mod diagnose;
mod evaluate;
mod export;
mod identify;
mod import;
mod observability;
mod options;
mod plan;
mod progress;
mod register;
mod reproduce;
mod rig_cmd;
mod session;
mod sim_device;
mod simulate;

use anyhow::Context as _;
use clap::{Parser, Subcommand};
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// rigcal — calibrate a robot arm from position measurements.
///
/// Files hold millimetres and degrees. Start with `rigcal demo` for a full simulated run, or
/// `rigcal observability --rig rigs/rv-m2.toml` to see what a rig can identify.
#[derive(Debug, Parser)]
#[command(name = "rigcal", version, propagate_version = true)]
pub struct Cli {
    #[command(flatten)]
    verbosity: Verbosity,
    #[command(subcommand)]
    command: Command,
}

/// `-v`: how much the log says (every subcommand takes it).
#[derive(Debug, Clone, Copy, clap::Args)]
#[group(skip)]
pub(crate) struct Verbosity {
    /// More log output (-v info, -vv debug). RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
}

/// `--rig FILE`. A command whose rig plays a particular part says so with
/// `#[command(mut_args(super::help_of("rig", "…")))]`.
#[derive(Debug, Clone, clap::Args)]
#[group(skip)]
pub(crate) struct RigArg {
    /// Rig file (TOML).
    #[arg(long)]
    pub rig: PathBuf,
}

impl RigArg {
    /// Loads the rig file.
    pub fn load(&self) -> anyhow::Result<Rig> {
        Ok(rigcal_devices::config::load_rig(&self.rig)?)
    }
}

/// `--recording DIR|CSV`, the recording a command reads.
#[derive(Debug, Clone, clap::Args)]
#[group(skip)]
pub(crate) struct RecordingArg {
    /// Recording: a directory with measurements.csv, or a CSV file.
    #[arg(long)]
    pub recording: PathBuf,
}

impl RecordingArg {
    /// Reads the recording for a rig.
    pub fn read(&self, rig: &Rig) -> anyhow::Result<Recording> {
        Ok(rigcal_calibration::read_recording(rig, &self.recording)?)
    }
}

/// `--out PATH`, what a command writes. Each command names what it writes with
/// `#[command(mut_args(super::help_of("out", "…")))]`.
#[derive(Debug, Clone, clap::Args)]
#[group(skip)]
pub(crate) struct OutArg {
    /// Where to write the output.
    #[arg(long)]
    pub out: PathBuf,
}

/// Sets the help text of argument `id`, for an option group whose part differs between
/// commands. (`mut_args` rather than `mut_arg`: it keeps the arguments in their order, so the
/// usage line does too.)
pub(crate) fn help_of(id: &'static str, help: &'static str) -> impl FnMut(clap::Arg) -> clap::Arg {
    move |a| if a.get_id() == id { a.help(help) } else { a }
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The whole job on simulated devices: a dry-run session of the paper's scenario, the
    /// variable D-H calibration and the Fig. 6/7 evaluation, then a session on the real rig's
    /// constraints with its identification, evaluation and diagnosis; files and plots in --out.
    Demo(demo::Args),
    /// Which error parameters position measurements can identify for a rig, and why not the rest.
    Observability(observability::Args),
    /// Identify the kinematic error parameters from a recording (conventional calibration).
    Identify(identify::Args),
    /// Rig-file tools: `rigcal rig from-urdf ROBOT.urdf --base LINK --tip LINK --out RIG.toml`.
    Rig(rig_cmd::Args),
    /// Turn a tracker or motion-capture CSV into a recording (mm, degrees, the rig's joint order).
    Import(import::Args),
    /// Fit the rigid transform between the instrument's frame and the world.
    Register(register::Args),
    /// Joint commands that bring the calibrated arm to target positions.
    Compensate(compensate::Args),
    /// The variable D-H parameter model: recursive workspace division, CEPs per region and an
    /// FCMAC (or CMAC) that generalises them — offline, planning on a simulated world, or planning
    /// through a measurement session; with --learner nn-*, seed 001's neural network.
    Calibrate(calibrate::Args),
    /// Position error along paths of a simulated arm with each model, CEP traces and plots.
    Evaluate(evaluate::Args),
    /// Take a calibration home: `rigcal export urdf --model M --urdf IN.urdf --out OUT.urdf`.
    Export(export::Args),
    /// Name the physics the geometric model leaves out of a recording (or say it does not know).
    Diagnose(diagnose::Args),
    /// Simulate a measurement session in a scenario's truth world and write its recording.
    Simulate(simulate::Args),
    /// Plan a measurement session: points per region, checked and ordered, with a rig-time
    /// estimate.
    Plan(plan::Args),
    /// Run (or resume) an automatic measurement session on the rig, or a dry run on emulators.
    Session(session::Args),
    /// Serve emulators on pseudo-terminals: one device, or the whole rig on one world (`rig`).
    SimDevice(sim_device::Args),
    /// Conventional calibration, the variable D-H model with FCMAC and a neural network on the
    /// same recording and validation set, side by side.
    Compare(compare::Args),
    /// Reproduce a paper's tables beside its numbers: `rigcal reproduce seed001 --table 5`.
    Reproduce(reproduce::Args),
}

/// Runs the command line and returns the process exit code.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbosity.verbose);
    match dispatch(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            let mut said = e.to_string();
            for cause in e.chain().skip(1) {
                // Typed errors often repeat their source in their own message: say it once.
                let text = cause.to_string();
                if !said.contains(&text) {
                    eprintln!("  caused by: {text}");
                }
                said = text;
            }
            ExitCode::FAILURE
        }
    }
}

fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Demo(a) => demo::run(a),
        Command::Observability(a) => observability::run(a),
        Command::Identify(a) => identify::run(a),
        Command::Register(a) => register::run(a),
        Command::Import(a) => import::run(a),
        Command::Rig(a) => rig_cmd::run(a),
        Command::Compensate(a) => compensate::run(a),
        Command::Calibrate(a) => calibrate::run(a),
        Command::Evaluate(a) => evaluate::run(a),
        Command::Export(a) => export::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::SimDevice(a) => sim_device::run(a),
        Command::Plan(a) => plan::run(a),
        Command::Session(a) => session::run(a),
        Command::Compare(a) => compare::run(a),
        Command::Reproduce(a) => reproduce::run(a),
    }
}

fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    // Colour only on a terminal: logs redirected to a file stay free of escape codes.
    use std::io::IsTerminal;
    let ansi = std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none();
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(ansi)
        .with_writer(std::io::stderr)
        .with_target(false)
        .try_init();
}

/// Writes an HTML report and says where.
pub(crate) fn write_report(path: &Path, html: &str) -> anyhow::Result<()> {
    std::fs::write(path, html).with_context(|| format!("cannot write {}", path.display()))?;
    println!("report written to {}", path.display());
    Ok(())
}
