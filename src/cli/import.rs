//! `rigcal import`: a foreign CSV (laser tracker, motion capture) to a recording of
//! spec/recordings.md — millimetres and degrees, joints in the rig's order, `seq` from row order
//! ([`rigcal_core::recording::import`]).

use super::{OutArg, RigArg};
use anyhow::{bail, Result};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{import_csv, ImportSpec};
use rigcal_core::recording::{AngleUnit as RecordingAngleUnit, LengthUnit as RecordingLengthUnit};
use std::path::PathBuf;

super::options::value_enum! {
    /// Length unit of the input.
    LengthUnit => RecordingLengthUnit {
        /// Metres (URDF's unit).
        M,
        /// Millimetres.
        Mm,
    }
}

super::options::value_enum! {
    /// Angle unit of the input.
    AngleUnit => RecordingAngleUnit {
        /// Radians (URDF's unit).
        Rad,
        /// Degrees.
        Deg,
    }
}

/// Arguments of `rigcal import`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of("rig", "Rig file the joints belong to")))]
#[command(mut_args(super::help_of("out", "Output recording directory")))]
pub struct Args {
    /// The CSV to import (one header row).
    file: PathBuf,
    #[command(flatten)]
    rig: RigArg,
    /// Joint columns, in the rig's joint order, separated by commas.
    #[arg(long, value_delimiter = ',', required = true)]
    joints: Vec<String>,
    /// The measured point's three columns (x,y,z), separated by commas.
    #[arg(long, value_delimiter = ',', required = true)]
    point: Vec<String>,
    /// Time column (seconds). Without it `t_s` is left empty and time effects are not considered.
    #[arg(long)]
    time: Option<String>,
    /// Unit of lengths (the point, prismatic joints).
    #[arg(long, value_enum, default_value_t = LengthUnit::M)]
    length_unit: LengthUnit,
    /// Unit of revolute joint angles.
    #[arg(long, value_enum, default_value_t = AngleUnit::Rad)]
    angle_unit: AngleUnit,
    #[command(flatten)]
    out: OutArg,
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    let specs = rig.chain.joints();
    if a.joints.len() != specs.len() {
        bail!(
            "--joints names {} columns; rig `{}` has {} joints ({})",
            a.joints.len(),
            rig.name,
            specs.len(),
            specs
                .iter()
                .map(|j| j.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let Ok(point) = <[String; 3]>::try_from(a.point.clone()) else {
        bail!("--point needs three columns (x,y,z), got {}", a.point.len());
    };
    let spec = ImportSpec {
        joints: a.joints,
        point,
        time: a.time,
        length_unit: a.length_unit.into(),
        angle_unit: a.angle_unit.into(),
    };
    let rec = import_csv(&a.file, &rig, &spec)?;
    rec.write_dir(&a.out.out)?;
    println!(
        "{} rows imported to {}{}",
        rec.rows.len(),
        a.out.out.display(),
        if spec.time.is_none() {
            " (no time column: t_s left empty)"
        } else {
            ""
        }
    );
    Ok(())
}
