//! `rigcal import`: a foreign CSV (laser tracker, motion capture) to a recording of
//! spec/recordings.md — millimetres and degrees, joints in the rig's order, `seq` from row order
//! ([`rigcal_core::recording::import`]). Files are read as they come: separator and decimal
//! comma detected, CRLF, BOM, no final line end; orientation (Euler angles in a named
//! convention), standard deviations and temperature kept; lost timestamps reported.

use super::{OutArg, RigArg};
use anyhow::{bail, Result};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::import::{
    Dialect, EulerConvention, OrientationSpec, TimeFormat as RecordingTimeFormat, TimeStatus,
};
use rigcal_core::recording::{import_file, ImportSpec};
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

/// How the time column is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum TimeFormat {
    /// YYYYMMDDhhmmss when every cell has 14 digits, ISO 8601 when every cell is a date-time,
    /// seconds otherwise.
    Auto,
    /// Seconds.
    Seconds,
    /// YYYYMMDDhhmmss (a local time).
    Yyyymmddhhmmss,
    /// ISO 8601 / RFC 3339 date-times.
    Iso8601,
}

impl From<TimeFormat> for RecordingTimeFormat {
    fn from(f: TimeFormat) -> Self {
        match f {
            TimeFormat::Auto => Self::Auto,
            TimeFormat::Seconds => Self::Seconds,
            TimeFormat::Yyyymmddhhmmss => Self::Compact,
            TimeFormat::Iso8601 => Self::Iso8601,
        }
    }
}

/// Separator and decimal mark of the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum DialectArg {
    /// Detected from the file.
    Auto,
    /// `,` separators, decimal point.
    Comma,
    /// `;` separators, decimal point.
    Semicolon,
    /// `;` separators, decimal comma (spreadsheet exports in many locales).
    SemicolonDecimalComma,
    /// Tab separators, decimal point.
    Tab,
    /// Tab separators, decimal comma.
    TabDecimalComma,
}

impl DialectArg {
    fn dialect(self) -> Option<Dialect> {
        match self {
            DialectArg::Auto => None,
            DialectArg::Comma => Some(Dialect::COMMA),
            DialectArg::Semicolon => Some(Dialect::SEMICOLON),
            DialectArg::SemicolonDecimalComma => Some(Dialect::SEMICOLON_DECIMAL_COMMA),
            DialectArg::Tab => Some(Dialect::TAB),
            DialectArg::TabDecimalComma => Some(Dialect::TAB_DECIMAL_COMMA),
        }
    }
}

/// Arguments of `rigcal import`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of("rig", "Rig file the joints belong to")))]
#[command(mut_args(super::help_of("out", "Output recording directory")))]
pub struct Args {
    /// The CSV to import (one header row). Separator (`,` `;` tab) and a decimal comma are
    /// detected; CRLF, a byte-order mark and a missing final line end are fine.
    file: PathBuf,
    #[command(flatten)]
    rig: RigArg,
    /// Joint columns, in the rig's joint order, separated by commas.
    #[arg(long, value_delimiter = ',', required = true)]
    joints: Vec<String>,
    /// The measured point's three columns (x,y,z), separated by commas.
    #[arg(long, value_delimiter = ',', required = true)]
    point: Vec<String>,
    /// Time column. Without it `t_s` is left empty and time effects are not considered. A
    /// column that is constant or not a time is reported as lost (t_s left empty).
    #[arg(long)]
    time: Option<String>,
    /// How the time column is written.
    #[arg(long, value_enum, default_value_t = TimeFormat::Auto)]
    time_format: TimeFormat,
    /// Unit of lengths (the point, its standard deviations, prismatic joints).
    #[arg(long, value_enum, default_value_t = LengthUnit::M)]
    length_unit: LengthUnit,
    /// Unit of revolute joint angles.
    #[arg(long, value_enum, default_value_t = AngleUnit::Rad)]
    angle_unit: AngleUnit,
    /// Separator and decimal mark, when detection should not decide.
    #[arg(long, value_enum, default_value_t = DialectArg::Auto)]
    dialect: DialectArg,
    /// The measured frame's orientation: three Euler-angle columns, in the order the
    /// convention applies them (needs --euler).
    #[arg(long, value_delimiter = ',', requires = "euler")]
    orientation: Vec<String>,
    /// Euler convention of --orientation: intrinsic-ORDER (rotating axes) or extrinsic-ORDER
    /// (fixed axes), ORDER three of x, y, z (intrinsic-xyz = scipy 'XYZ'; extrinsic-xyz =
    /// scipy 'xyz' = URDF rpy).
    #[arg(long, requires = "orientation")]
    euler: Option<EulerConvention>,
    /// Unit of the --orientation angles and their standard deviations [default: --angle-unit].
    #[arg(long, value_enum)]
    orientation_unit: Option<AngleUnit>,
    /// Standard deviations of the point's x, y, z (three columns, in --length-unit).
    #[arg(long, value_delimiter = ',')]
    point_sigma: Vec<String>,
    /// Standard deviations of the --orientation angles (three columns, same order and unit).
    #[arg(long, value_delimiter = ',', requires = "orientation")]
    orientation_sigma: Vec<String>,
    /// Temperature column (°C).
    #[arg(long)]
    temperature: Option<String>,
    /// Import even when the positions are not on the rig's scale (by default such a file is
    /// refused with the likely unit mistake).
    #[arg(long)]
    no_scale_check: bool,
    #[command(flatten)]
    out: OutArg,
}

fn three(flag: &str, cols: Vec<String>) -> Result<Option<[String; 3]>> {
    if cols.is_empty() {
        return Ok(None);
    }
    let n = cols.len();
    match <[String; 3]>::try_from(cols) {
        Ok(c) => Ok(Some(c)),
        Err(_) => bail!("{flag} needs three columns (x,y,z), got {n}"),
    }
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
    let Some(point) = three("--point", a.point)? else {
        bail!("--point needs three columns (x,y,z)");
    };
    let orientation = match (three("--orientation", a.orientation)?, a.euler) {
        (Some(columns), Some(convention)) => Some(OrientationSpec {
            columns,
            convention,
            unit: a.orientation_unit.unwrap_or(a.angle_unit).into(),
        }),
        _ => None,
    };
    let spec = ImportSpec {
        joints: a.joints,
        point,
        time: a.time,
        length_unit: a.length_unit.into(),
        angle_unit: a.angle_unit.into(),
        dialect: a.dialect.dialect(),
        time_format: a.time_format.into(),
        orientation,
        point_sigma: three("--point-sigma", a.point_sigma)?,
        orientation_sigma: three("--orientation-sigma", a.orientation_sigma)?,
        temperature: a.temperature,
        skip_scale_check: a.no_scale_check,
    };
    let imported = import_file(&a.file, &rig, &spec)?;
    let rec = &imported.recording;
    rec.write_dir(&a.out.out)?;
    for w in &imported.warnings {
        eprintln!("warning: {w}");
    }
    let time = match &imported.time {
        TimeStatus::NoColumn => " (no time column: t_s left empty)".to_string(),
        TimeStatus::Kept { start: Some(s), .. } => format!(" (times from {s})"),
        TimeStatus::Kept { .. } => String::new(),
        TimeStatus::Partial { lost_rows, .. } => format!(" ({lost_rows} rows without a time)"),
        TimeStatus::Lost { .. } => " (times lost: t_s left empty)".to_string(),
    };
    let mut kept = Vec::new();
    if spec.orientation.is_some() {
        kept.push("orientation");
    }
    if spec.point_sigma.is_some() || spec.orientation_sigma.is_some() {
        kept.push("standard deviations");
    }
    if spec.temperature.is_some() {
        kept.push("temperature");
    }
    println!(
        "{} rows imported to {} (read with {}){}{time}",
        rec.rows.len(),
        a.out.out.display(),
        imported.dialect.describe(),
        if kept.is_empty() {
            String::new()
        } else {
            format!("; kept: {}", kept.join(", "))
        },
    );
    Ok(())
}
