//! `rigcal observability`: rank, identifiable basis and confounded parameters of a rig.

use super::RigArg;
use anyhow::Result;
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::Robot;
use rigcal_model::identification::{analyse, candidate_order, identifiability, random_poses};

/// Arguments of `rigcal observability`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    rig: RigArg,
    /// Number of random poses (uniform within the joint limits) to analyse over.
    #[arg(long, default_value_t = 100)]
    poses: usize,
    /// Seed of the random poses.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Move every joint, ignoring the rig's held joints (e.g. the RV-M2's wrist).
    #[arg(long)]
    all_joints: bool,
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    anyhow::ensure!(a.poses >= 2, "--poses must be at least 2");
    let held = if a.all_joints {
        vec![None; rig.chain.dof()]
    } else {
        rig.held().to_vec()
    };
    let poses = random_poses(
        rig.chain.joints(),
        &held,
        a.poses,
        &mut ChaCha8Rng::seed_from_u64(a.seed),
    );
    let cands = candidate_order(&rig);
    let result = analyse(&rig.chain, &poses, &cands);
    let layout = rig.chain.layout();
    let joints = rig.chain.joints();
    let moving: Vec<&str> = joints
        .iter()
        .zip(&held)
        .filter(|(_, h)| h.is_none())
        .map(|(j, _)| j.name.as_str())
        .collect();
    let held_list: Vec<String> = joints
        .iter()
        .zip(&held)
        .filter_map(|(j, h)| {
            h.map(|v| {
                format!(
                    "{} = {}",
                    j.name,
                    rigcal_model::identification::joint_label(j, v)
                )
            })
        })
        .collect();
    println!(
        "rig {} ({}): {} joints, {} error parameters",
        rig.name,
        rig.robot_name,
        joints.len(),
        layout.len()
    );
    println!(
        "moving: {}{}",
        moving.join(" "),
        if held_list.is_empty() {
            String::new()
        } else {
            format!("; held: {}", held_list.join(", "))
        }
    );
    println!(
        "measurement frame: {:?}, marker: {:?} (fixed ones are not candidates)",
        rig.calibration.measurement_frame, rig.calibration.marker
    );
    if !rig.calibration.basis_priority.is_empty() {
        println!("basis preference from the rig file: the rank is computed; the preference only picks among equivalent bases");
    }
    print!("{}", identifiability::report(layout, &result, cands.len()));
    Ok(())
}
