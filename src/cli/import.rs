//! `rigcal import`: a foreign CSV (laser tracker, motion capture) to a recording of
//! spec/recordings.md — millimetres and degrees, joints in the rig's order, `seq` from row order.

use crate::kinematics::{JointKind, Robot};
use crate::recording::{Measurement, Recording, SessionInfo, Status};
use crate::rig::Rig;
use anyhow::{bail, Context, Result};
use nalgebra::Vector3;
use std::path::PathBuf;

/// Length unit of the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LengthUnit {
    /// Metres (URDF's unit).
    M,
    /// Millimetres.
    Mm,
}

/// Angle unit of the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AngleUnit {
    /// Radians (URDF's unit).
    Rad,
    /// Degrees.
    Deg,
}

/// Arguments of `rigcal import`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The CSV to import (one header row).
    file: PathBuf,
    /// Rig file the joints belong to.
    #[arg(long)]
    rig: PathBuf,
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
    /// Output recording directory.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
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
    if a.point.len() != 3 {
        bail!("--point needs three columns (x,y,z), got {}", a.point.len());
    }
    let file = std::fs::File::open(&a.file)
        .with_context(|| format!("cannot read {}", a.file.display()))?;
    let mut reader = csv::ReaderBuilder::new().from_reader(file);
    let headers: Vec<String> = reader
        .headers()
        .with_context(|| format!("{}: line 1", a.file.display()))?
        .iter()
        .map(|h| h.trim().to_string())
        .collect();
    let find = |name: &str| {
        headers.iter().position(|h| h == name).ok_or_else(|| {
            anyhow::anyhow!(
                "{}: line 1: no column `{name}` (columns are {})",
                a.file.display(),
                headers.join(", ")
            )
        })
    };
    let q_cols = a
        .joints
        .iter()
        .map(|c| find(c))
        .collect::<Result<Vec<_>>>()?;
    let p_cols = a
        .point
        .iter()
        .map(|c| find(c))
        .collect::<Result<Vec<_>>>()?;
    let t_col = a.time.as_deref().map(find).transpose()?;
    let used: Vec<usize> = q_cols
        .iter()
        .chain(&p_cols)
        .chain(t_col.iter())
        .copied()
        .collect();
    let extra_cols: Vec<usize> = (0..headers.len()).filter(|c| !used.contains(c)).collect();
    let length = match a.length_unit {
        LengthUnit::M => 1000.0,
        LengthUnit::Mm => 1.0,
    };
    let mut rec = Recording::new(specs);
    rec.extra_columns = extra_cols.iter().map(|&c| headers[c].clone()).collect();
    for (row, result) in reader.records().enumerate() {
        let record = result.with_context(|| format!("{}: row {}", a.file.display(), row + 2))?;
        let line = record
            .position()
            .map(|p| p.line())
            .unwrap_or(row as u64 + 2);
        let num = |c: usize| -> Result<f64> {
            let t = record.get(c).unwrap_or("").trim();
            match t.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => bail!(
                    "{}: line {line}, column {} (`{}`): `{t}` is not a number",
                    a.file.display(),
                    c + 1,
                    headers[c]
                ),
            }
        };
        let mut q = Vec::with_capacity(specs.len());
        for (spec, &c) in specs.iter().zip(&q_cols) {
            let raw = num(c)?;
            let v = match (spec.kind, a.angle_unit) {
                (JointKind::Revolute, AngleUnit::Rad) => raw,
                (JointKind::Revolute, AngleUnit::Deg) => raw.to_radians(),
                (JointKind::Prismatic, _) => raw * length,
            };
            if !spec.within(v) {
                bail!(
                    "{}: line {line}, column {} (`{}`): {} {} is outside joint {}'s limits {:.3}..{:.3} {}",
                    a.file.display(),
                    c + 1,
                    headers[c],
                    spec.kind.to_file_units(v),
                    spec.kind.unit(),
                    spec.name,
                    spec.kind.to_file_units(spec.min),
                    spec.kind.to_file_units(spec.max),
                    spec.kind.unit()
                );
            }
            q.push(v);
        }
        let p = Vector3::new(
            num(p_cols[0])? * length,
            num(p_cols[1])? * length,
            num(p_cols[2])? * length,
        );
        rec.rows.push(Measurement {
            seq: row as u64 + 1,
            t_s: t_col.map(num).transpose()?,
            q,
            position: Some(p),
            status: Status::Ok,
            extra: extra_cols
                .iter()
                .map(|&c| record.get(c).unwrap_or("").to_string())
                .collect(),
            ..Default::default()
        });
    }
    rec.session = Some(SessionInfo {
        rig: Some(a.rig.display().to_string()),
        notes: Some(format!(
            "imported from {} ({}, {}){}",
            a.file.display(),
            match a.length_unit {
                LengthUnit::M => "metres",
                LengthUnit::Mm => "millimetres",
            },
            match a.angle_unit {
                AngleUnit::Rad => "radians",
                AngleUnit::Deg => "degrees",
            },
            if a.time.is_none() {
                "; no time column: time-dependent effects are not considered"
            } else {
                ""
            }
        )),
        ..Default::default()
    });
    rec.write_dir(&a.out)?;
    println!(
        "{} rows imported to {}{}",
        rec.rows.len(),
        a.out.display(),
        if a.time.is_none() {
            " (no time column: t_s left empty)"
        } else {
            ""
        }
    );
    Ok(())
}
