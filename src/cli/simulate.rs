//! `rigcal simulate`: a recording of given or random poses, measured in a scenario's truth world.
//!
//! Poses are taken in the order given, `seconds_per_point` apart (scenario `[measurement]`);
//! every random draw depends on (seed, seq, attempt) only, so a seed gives the same bytes.
//! Files: mm and degrees.

use crate::identification::random_poses;
use crate::kinematics::Robot;
use crate::recording::{read_poses, RegistrationInfo, SessionInfo};
use crate::rig::{Instrument, Rig};
use crate::world::{setup_rng, Scenario};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

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
    /// Measure N poses drawn uniformly within the joint limits (held joints at their values).
    #[arg(long)]
    random: Option<usize>,
    /// Overrides the scenario's seed.
    #[arg(long)]
    seed: Option<u64>,
    #[command(flatten)]
    out: super::OutArg,
}

/// Index of the setup generator that draws `--random` poses (apart from the effects').
const POSES_STREAM: usize = usize::MAX - 1;

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    let scenario = Scenario::load(&a.scenario, a.seed)?;
    check_same_rig(&rig, &scenario, &a.rig.rig)?;
    let poses = match (&a.poses, a.random) {
        (Some(path), None) => read_poses(path, rig.chain.joints())
            .with_context(|| format!("reading poses from {}", path.display()))?,
        (None, Some(n)) => {
            let mut rng = setup_rng(scenario.seed, POSES_STREAM);
            random_poses(rig.chain.joints(), rig.held(), n, &mut rng)
        }
        _ => bail!("give exactly one of --poses FILE and --random N"),
    };
    let world = scenario.world();
    let mut rec = world.record(&poses, 1);
    rec.session = Some(session_info(&rig, &scenario, &a));
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

fn check_same_rig(rig: &Rig, scenario: &Scenario, rig_path: &Path) -> Result<()> {
    if rig.name != scenario.rig.name || rig.instrument != scenario.rig.instrument {
        bail!(
            "scenario {} assumes rig {} (`{}`), but --rig {} is `{}`",
            scenario.path.display(),
            scenario.rig_path.display(),
            scenario.rig.name,
            rig_path.display(),
            rig.name
        );
    }
    Ok(())
}

fn session_info(rig: &Rig, scenario: &Scenario, a: &Args) -> SessionInfo {
    // The simulated session measures through the nominal registration, as a session before any
    // registration step would.
    let registration = match &rig.instrument {
        Instrument::TablePanel(tp) => Some(RegistrationInfo {
            translation_mm: tp.table_to_world_mm.into(),
            rpy_deg: [0.0; 3],
            rms_mm: None,
        }),
        _ => None,
    };
    SessionInfo {
        rig: Some(a.rig.rig.display().to_string()),
        scenario: Some(a.scenario.display().to_string()),
        seed: Some(scenario.seed),
        registration,
        notes: Some(format!(
            "rigcal simulate: {}",
            if scenario.description.is_empty() {
                "simulated session"
            } else {
                &scenario.description
            }
        )),
        ..Default::default()
    }
}
