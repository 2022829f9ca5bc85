//! `rigcal register`: the table-to-world registration from a recording's table coordinates.

use crate::identification::registration::to_xyz_rpy;
use crate::identification::{register, Observation};
use crate::kinematics::{ErrorParams, Robot};
use crate::recording::{write_session, RegistrationInfo, SessionInfo};
use crate::rig::Rig;
use anyhow::{bail, Result};
use nalgebra::Point3;
use std::path::PathBuf;

/// Arguments of `rigcal register`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Rig file (TOML).
    #[arg(long)]
    rig: PathBuf,
    /// Recording whose rows carry table_x_mm, table_y_mm, table_z_mm.
    #[arg(long)]
    recording: PathBuf,
    /// Write a registered copy of the recording here: x_mm… recomputed from the table
    /// coordinates, and the registration stored in its session.toml.
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let mut rec = super::identify::read_recording(&rig, &a.recording)?;
    let obs: Vec<Observation> = rec
        .rows
        .iter()
        .filter(|m| m.status == crate::recording::Status::Ok)
        .filter_map(|m| {
            m.table.map(|t| Observation {
                q: m.q.clone(),
                p: t,
            })
        })
        .collect();
    if obs.len() < 3 {
        bail!("{} measured rows carry table coordinates; registration needs at least 3 (columns table_x_mm, table_y_mm, table_z_mm)", obs.len());
    }
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let reg = register(&rig.chain, &nominal, &obs)?;
    let (xyz, rpy) = to_xyz_rpy(&reg.world_from_instrument);
    println!(
        "registration from {} points (nominal kinematics): world = R · table + t",
        reg.n
    );
    println!(
        "  t   = ({:+.4}, {:+.4}, {:+.4}) mm   σ ({:.4}, {:.4}, {:.4}) mm",
        xyz[0], xyz[1], xyz[2], reg.sigma[0], reg.sigma[1], reg.sigma[2]
    );
    println!(
        "  rpy = ({:+.5}, {:+.5}, {:+.5}) deg",
        rpy[0], rpy[1], rpy[2]
    );
    println!(
        "  residual: RMS {:.4} mm, max {:.4} mm (what the nominal kinematics cannot explain; identification absorbs it)",
        reg.stats.rms_mm, reg.stats.max_mm
    );
    if let Some(out) = a.out {
        for m in rec.rows.iter_mut() {
            if let Some(t) = m.table {
                m.position = Some((reg.world_from_instrument * Point3::from(t)).coords);
            }
        }
        let mut info = rec.session.clone().unwrap_or_else(SessionInfo::default);
        info.registration = Some(RegistrationInfo {
            translation_mm: xyz,
            rpy_deg: rpy,
            rms_mm: Some(reg.stats.rms_mm),
        });
        rec.session = Some(info.clone());
        rec.write_dir(&out)?;
        write_session(&out, &info)?;
        println!("registered recording written to {}", out.display());
    }
    Ok(())
}
