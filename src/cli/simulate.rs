//! `rigcal simulate`: a recording of given or random poses, measured in a scenario's truth world.
//!
//! Poses are taken in the order given, `seconds_per_point` apart (scenario `[measurement]`);
//! every random draw depends on (seed, seq, attempt) only, so a seed gives the same bytes.
//! Files: mm and degrees.

use anyhow::{bail, Context, Result};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::read_poses;
use rigcal_sim::world::{check_same_rig, random_session_poses, simulate_session, Scenario};
use std::path::PathBuf;

/// Arguments of `rigcal simulate`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("which").required(true).args(["poses", "random"])))]
#[command(mut_args(super::help_of(
    "rig",
    "The rig file the session runs on (must be the scenario's rig)"
)))]
#[command(mut_args(super::help_of("out", "Directory for measurements.csv and session.toml")))]
pub struct Args {
    #[command(flatten)]
    rig: super::RigArg,
    /// The scenario file (sim/*.toml): the truth to simulate.
    #[arg(long)]
    scenario: PathBuf,
    /// CSV of poses with joint columns q1_deg…, measured in that order.
    #[arg(long)]
    poses: Option<PathBuf>,
    /// Measure N poses drawn uniformly within the joint limits (held joints at their values);
    /// N from 1 to 1000000.
    #[arg(long, value_parser = super::plan::point_count)]
    random: Option<usize>,
    /// Overrides the scenario's seed.
    #[arg(long)]
    seed: Option<u64>,
    #[command(flatten)]
    out: super::OutArg,
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    let scenario = Scenario::load(&a.scenario, a.seed)?;
    check_same_rig(&rig, &a.rig.rig, &scenario)?;
    let poses = match (&a.poses, a.random) {
        (Some(path), None) => read_poses(path, rig.chain.joints())
            .with_context(|| format!("reading poses from {}", path.display()))?,
        (None, Some(n)) => random_session_poses(&rig, &scenario, n),
        _ => bail!("give exactly one of --poses FILE and --random N"),
    };
    let rec = simulate_session(&rig, &a.rig.rig, &scenario, &poses)?;
    rec.write_dir(&a.out.out)?;
    let measured = rec.measured().count();
    println!(
        "simulated {} poses on {} with {} (seed {}): {} measured, {} skipped → {}",
        poses.len(),
        rig.name,
        a.scenario.display(),
        scenario.seed,
        measured,
        poses.len() - measured,
        a.out.out.display()
    );
    Ok(())
}
