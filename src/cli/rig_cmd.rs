//! `rigcal rig`: rig-file tools. `rigcal rig from-urdf` writes a rig file from a URDF chain
//! ([`rigcal_core::kinematics::urdf::rig_file`]).

use anyhow::{Context, Result};
use rigcal_core::kinematics::urdf::{chain_from_urdf, rig_file, RigFileNames};
use rigcal_core::kinematics::Robot;
use rigcal_core::rig::Rig;
use std::path::{Path, PathBuf};

/// Arguments of `rigcal rig`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: RigCommand,
}

#[derive(Debug, clap::Subcommand)]
enum RigCommand {
    /// Write a rig file (five-parameter convention) whose forward kinematics equals a URDF's
    /// chain from --base to --tip. The measurement frame and the marker are left free, as for a
    /// laser tracker or motion capture.
    #[command(mut_args(super::help_of("out", "Output rig file")))]
    FromUrdf {
        /// The URDF file.
        urdf: PathBuf,
        /// Base link of the chain.
        #[arg(long)]
        base: String,
        /// Tip link (where the marker is fixed).
        #[arg(long)]
        tip: String,
        #[command(flatten)]
        out: super::OutArg,
    },
}

pub fn run(a: Args) -> Result<()> {
    match a.command {
        RigCommand::FromUrdf {
            urdf,
            base,
            tip,
            out,
        } => from_urdf(&urdf, &base, &tip, &out.out),
    }
}

/// `rigcal rig from-urdf`: converts, checks that the file loads, writes it.
fn from_urdf(urdf: &Path, base: &str, tip: &str, out: &Path) -> Result<()> {
    let text =
        std::fs::read_to_string(urdf).with_context(|| format!("cannot read {}", urdf.display()))?;
    let chain = chain_from_urdf(&text, base, tip).with_context(|| format!("{}", urdf.display()))?;
    let name = urdf
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "robot".into());
    let source = urdf.display().to_string();
    let names = RigFileNames {
        name: &name,
        source: &source,
        base,
        tip,
    };
    let parse = |t: &str| {
        Rig::parse(t, Some(out))
            .context("the generated rig file does not validate (a bug: please report it)")
    };
    let toml = rig_file(&names, &chain, |t| parse(t).map(|r| r.chain))?;
    let rig = parse(&toml)?;
    std::fs::write(out, &toml).with_context(|| format!("cannot write {}", out.display()))?;
    println!(
        "{} joints from `{base}` to `{tip}` → {}",
        rig.chain.dof(),
        out.display()
    );
    Ok(())
}
