//! Import of a foreign CSV (laser tracker, motion capture) as a recording of
//! spec/recordings.md: the caller names the joint, point and time columns and their units; the
//! result holds internal units (rad or mm, mm), joints in the rig's order, `seq` from row order,
//! and keeps every other column as an extra column.
//!
//! Files are read as they come: the separator (`,`, `;`, tab) and a decimal comma are detected
//! ([`dialect`]), a UTF-8 byte-order mark, CRLF line ends, a missing final line end and NUL
//! padding are accepted. Optional columns carry what a 6-DoF instrument gives: the probe's
//! orientation as Euler angles in a convention the user names ([`euler`]), per-coordinate
//! standard deviations, the temperature. Timestamps are parsed where valid and reported as lost
//! where the column is constant or not a time ([`time`]). A recording whose scale does not fit
//! the rig (metres read as millimetres, radians as degrees) is refused ([`scale`]).
//!
//! Every bad cell is an error with the file, line and column named: nothing is dropped.

pub mod dialect;
pub mod euler;
pub mod scale;
pub mod time;

pub use dialect::Dialect;
pub use euler::EulerConvention;
pub use scale::{check_scale, DeclaredUnits, ScaleMismatch};
pub use time::{TimeFormat, TimeStatus};

use super::{LineIndex, Measurement, Recording, SessionInfo, Status};
use crate::kinematics::{JointKind, JointSpec, Robot};
use crate::rig::Rig;
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Length unit of an imported file (the point, prismatic joints).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LengthUnit {
    /// Metres (URDF's unit).
    #[default]
    M,
    /// Millimetres.
    Mm,
}

impl LengthUnit {
    /// Millimetres per unit.
    pub fn to_mm(self) -> f64 {
        match self {
            LengthUnit::M => 1000.0,
            LengthUnit::Mm => 1.0,
        }
    }

    /// The unit's name in a sentence ("metres").
    pub fn name(self) -> &'static str {
        match self {
            LengthUnit::M => "metres",
            LengthUnit::Mm => "millimetres",
        }
    }
}

/// Angle unit of an imported file (revolute joints, orientations).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AngleUnit {
    /// Radians (URDF's unit).
    #[default]
    Rad,
    /// Degrees.
    Deg,
}

impl AngleUnit {
    /// The value in radians.
    pub fn to_rad(self, v: f64) -> f64 {
        match self {
            AngleUnit::Rad => v,
            AngleUnit::Deg => v.to_radians(),
        }
    }

    /// The unit's name in a sentence ("radians").
    pub fn name(self) -> &'static str {
        match self {
            AngleUnit::Rad => "radians",
            AngleUnit::Deg => "degrees",
        }
    }
}

/// The orientation columns of a file and how to read them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OrientationSpec {
    /// The three angle columns, in the order the convention applies them.
    pub columns: [String; 3],
    /// Intrinsic or extrinsic, and the axis order.
    pub convention: EulerConvention,
    /// Degrees or radians.
    pub unit: AngleUnit,
}

/// Which columns of the file hold what, and in which units.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ImportSpec {
    /// Joint columns, in the rig's joint order.
    pub joints: Vec<String>,
    /// The measured point's x, y and z columns.
    pub point: [String; 3],
    /// Time column. Without it `t_s` is left empty.
    pub time: Option<String>,
    /// Unit of lengths.
    pub length_unit: LengthUnit,
    /// Unit of revolute joint angles.
    pub angle_unit: AngleUnit,
    /// Separator and decimal mark; None: detected from the file.
    pub dialect: Option<Dialect>,
    /// How the time column is written.
    pub time_format: TimeFormat,
    /// The measured frame's orientation, when the instrument gives one.
    pub orientation: Option<OrientationSpec>,
    /// Standard deviations of the point's x, y and z (in `length_unit`).
    pub point_sigma: Option<[String; 3]>,
    /// Standard deviations of the orientation angles (in the orientation's unit, in the order
    /// of its columns).
    pub orientation_sigma: Option<[String; 3]>,
    /// Temperature column (°C).
    pub temperature: Option<String>,
    /// Leaves out the check that the positions are on the rig's scale ([`check_scale`]).
    pub skip_scale_check: bool,
}

/// How a file was imported, as `session.toml` keeps it (`[import]`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ImportInfo {
    /// The file imported.
    pub source: String,
    /// Field separator (`,`, `;`, `tab`).
    pub separator: String,
    /// Decimal mark: `point` or `comma`.
    pub decimal: String,
    /// Unit of the lengths as read (`m`, `mm`).
    pub length_unit: String,
    /// Unit of the joint angles as read (`rad`, `deg`).
    pub angle_unit: String,
    /// The orientation columns and their convention, when imported.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation: Option<String>,
    /// The standard-deviation columns, when imported.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma: Option<String>,
    /// The temperature column, when imported.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_column: Option<String>,
    /// The time column, when one was named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_column: Option<String>,
    /// What became of the times: `none` (no column), `kept`, `partial` or `lost`.
    pub time: String,
    /// Why times were lost, or which rows have none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_note: Option<String>,
}

impl ImportInfo {
    /// Whether the file had a time column whose times could not be read (all or some rows).
    pub fn time_lost(&self) -> bool {
        matches!(self.time.as_str(), "lost" | "partial")
    }
}

/// An imported file: the recording and what a person should be told about it.
#[derive(Debug, Clone)]
pub struct Imported {
    /// The recording (its session says how the file was read).
    pub recording: Recording,
    /// The dialect the file was read in.
    pub dialect: Dialect,
    /// What became of the time column.
    pub time: TimeStatus,
    /// What was lost or guessed, for a person (each also logged as a warning).
    pub warnings: Vec<String>,
}

/// Why a file could not be imported.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// The spec names another number of joint columns than the rig has joints.
    #[error("{given} joint columns named; rig `{rig}` has {} joints ({})", joints.len(), joints.join(", "))]
    JointCount {
        /// Joint columns named.
        given: usize,
        /// The rig's name.
        rig: String,
        /// The rig's joint names.
        joints: Vec<String>,
    },
    /// The file could not be opened.
    #[error("cannot read {}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The separator or decimal mark could not be told.
    #[error("{}: cannot tell how the file is written: {reason}; name it with --dialect (comma, semicolon, semicolon-decimal-comma, tab, tab-decimal-comma)", path.display())]
    Dialect {
        /// The file.
        path: PathBuf,
        /// What was seen.
        reason: String,
    },
    /// The header row could not be read.
    #[error("{}: line 1", path.display())]
    Header {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: csv::Error,
    },
    /// A named column is not in the header.
    #[error(
        "{}: line 1: no column `{column}`{} (read with {dialect}; the file's {} columns are {})",
        path.display(),
        closest.as_ref().map(|c| format!("; did you mean `{c}`?")).unwrap_or_default(),
        columns.len(),
        columns.iter().map(|c| format!("`{c}`")).collect::<Vec<_>>().join(", ")
    )]
    NoColumn {
        /// The file.
        path: PathBuf,
        /// The column asked for.
        column: String,
        /// The file's column nearest in spelling, if one is near.
        closest: Option<String>,
        /// The file's columns.
        columns: Vec<String>,
        /// How the header was split ("`;` separators, decimal comma").
        dialect: String,
    },
    /// A row is not valid CSV (a wrong number of fields, bad UTF-8, …).
    #[error("{}: row {row}", path.display())]
    Row {
        /// The file.
        path: PathBuf,
        /// The row's number counting the header as 1.
        row: u64,
        /// The cause.
        source: csv::Error,
    },
    /// A cell that must hold a number does not.
    #[error("{at}: `{text}` is not a number{}", if *decimal_comma { " (read with a decimal comma)" } else { "" })]
    NotANumber {
        /// The cell.
        at: Box<CellAt>,
        /// The cell's text.
        text: String,
        /// Whether the file was read with a decimal comma.
        decimal_comma: bool,
    },
    /// A value that cannot be what its column says (a negative standard deviation, an angle in
    /// radians beyond ±2π).
    #[error("{at}: {reason}")]
    BadValue {
        /// The cell.
        at: Box<CellAt>,
        /// What is wrong, and the likely cause.
        reason: String,
    },
    /// A joint value lies outside the rig's limits.
    #[error(
        "{at}: {} {unit} is outside joint {joint}'s limits {:.3}..{:.3} {unit}{hint}",
        value, limits[0], limits[1]
    )]
    OutsideLimits {
        /// The cell.
        at: Box<CellAt>,
        /// The joint.
        joint: String,
        /// The value (file units of the rig: deg or mm).
        value: f64,
        /// The joint's limits (deg or mm).
        limits: [f64; 2],
        /// Their unit.
        unit: &'static str,
        /// The likely cause, when one is plain ("; were the joint angles degrees? …"), or empty.
        hint: String,
    },
    /// The recording's scale does not fit the rig (a wrong unit, most likely).
    #[error("{}: {mismatch}; nothing imported (--no-scale-check imports it anyway)", path.display())]
    Scale {
        /// The file.
        path: PathBuf,
        /// What does not fit and the likely cause.
        mismatch: ScaleMismatch,
    },
}

/// Where a bad cell is: "FILE: line L, column C (`NAME`)".
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CellAt {
    /// The file.
    pub path: PathBuf,
    /// 1-based line.
    pub line: u64,
    /// 1-based column.
    pub column: usize,
    /// Column name.
    pub name: String,
}

impl std::fmt::Display for CellAt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: line {}, column {} (`{}`)",
            self.path.display(),
            self.line,
            self.column,
            self.name
        )
    }
}

/// The column indices of the spec in a header.
struct ColumnMap {
    joints: Vec<usize>,
    point: [usize; 3],
    time: Option<usize>,
    orientation: Option<[usize; 3]>,
    point_sigma: Option<[usize; 3]>,
    orientation_sigma: Option<[usize; 3]>,
    temperature: Option<usize>,
    /// Every other column, kept as an extra column.
    extra: Vec<usize>,
}

/// Imports the CSV at `path` (one header row) for a rig. The session sidecar names the rig's
/// file and says how the file was read (units, whether time effects can be considered).
/// What [`import_file`] returns as warnings is logged here (tracing, level warn).
pub fn import_csv(path: &Path, rig: &Rig, spec: &ImportSpec) -> Result<Recording, ImportError> {
    let imported = import_file(path, rig, spec)?;
    for w in &imported.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    Ok(imported.recording)
}

/// As [`import_csv`], with what a person should be told: the dialect read, the fate of the
/// time column, and warnings.
pub fn import_file(path: &Path, rig: &Rig, spec: &ImportSpec) -> Result<Imported, ImportError> {
    let specs = rig.chain.joints();
    if spec.joints.len() != specs.len() {
        return Err(ImportError::JointCount {
            given: spec.joints.len(),
            rig: rig.name.clone(),
            joints: specs.iter().map(|j| j.name.clone()).collect(),
        });
    }
    let raw = std::fs::read(path).map_err(|source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bytes = dialect::strip_bom(&raw);
    let dialect = match spec.dialect {
        Some(d) => d,
        None => dialect::detect(bytes).map_err(|u| ImportError::Dialect {
            path: path.to_path_buf(),
            reason: u.reason,
        })?,
    };
    let lines = LineIndex::of(bytes);
    let mut reader = csv::ReaderBuilder::new()
        .delimiter(dialect.separator)
        .from_reader(bytes);
    let headers: Vec<String> = reader
        .headers()
        .map_err(|source| ImportError::Header {
            path: path.to_path_buf(),
            source,
        })?
        .iter()
        .map(|h| dialect::clean(h).to_string())
        .collect();
    let cols = column_map(path, &headers, spec, &dialect)?;
    let mut rec = Recording::new(specs);
    rec.extra_columns = cols.extra.iter().map(|&c| headers[c].clone()).collect();
    let mut time_cells: Vec<String> = Vec::new();
    for (row, result) in reader.records().enumerate() {
        let record = result.map_err(|source| ImportError::Row {
            path: path.to_path_buf(),
            row: row as u64 + 2,
            source,
        })?;
        let cells = Cells {
            path,
            headers: &headers,
            line: lines.line_of(record.position()),
            record: &record,
            dialect: &dialect,
        };
        rec.rows
            .push(cells.measurement(row as u64 + 1, &cols, specs, spec)?);
        rec.lines.push(cells.line);
        if let Some(c) = cols.time {
            time_cells.push(record.get(c).unwrap_or("").to_string());
        }
    }
    let time = match cols.time {
        Some(_) => {
            let refs: Vec<&str> = time_cells.iter().map(String::as_str).collect();
            let column = time::read_times(&refs, spec.time_format, &dialect);
            for (m, t) in rec.rows.iter_mut().zip(column.t_s) {
                m.t_s = t;
            }
            column.status
        }
        None => TimeStatus::NoColumn,
    };
    if !spec.skip_scale_check {
        let declared = DeclaredUnits {
            length: spec.length_unit,
            angle: spec.angle_unit,
            orientation: spec
                .orientation
                .as_ref()
                .map_or(spec.angle_unit, |o| o.unit),
        };
        check_scale(&rec, &rig.chain, Some(declared)).map_err(|mismatch| ImportError::Scale {
            path: path.to_path_buf(),
            mismatch,
        })?;
    }
    let warnings = warnings(spec, &headers, &time);
    rec.session = Some(session_info(path, rig, spec, &dialect, &time));
    Ok(Imported {
        recording: rec,
        dialect,
        time,
        warnings,
    })
}

/// What a person should hear about the time column.
fn warnings(spec: &ImportSpec, headers: &[String], time: &TimeStatus) -> Vec<String> {
    let mut out = Vec::new();
    let column = spec.time.as_deref().unwrap_or("");
    match time {
        TimeStatus::Lost { reason } => out.push(format!(
            "times lost: column `{column}`: {reason}; t_s is left empty and time-dependent \
             effects (drift, warm-up) cannot be considered"
        )),
        TimeStatus::Partial {
            lost_rows,
            rows,
            example,
            ..
        } => out.push(format!(
            "column `{column}`: {lost_rows} of {rows} rows hold no valid time (first: \
             `{example}`); their t_s is left empty"
        )),
        TimeStatus::NoColumn => {
            if let Some(h) = headers.iter().find(|h| looks_like_time(h)) {
                out.push(format!(
                    "no time column named: column `{h}` looks like one (--time {h} reads it); \
                     time-dependent effects are not considered"
                ));
            }
        }
        TimeStatus::Kept { .. } => {}
    }
    out
}

/// A header a time column usually has.
fn looks_like_time(h: &str) -> bool {
    matches!(
        h.to_ascii_lowercase().as_str(),
        "time" | "timestamp" | "time_s" | "t_s" | "datetime" | "date_time" | "date"
    )
}

/// The header nearest to `name` in spelling (case ignored), if near enough to suggest.
fn closest(name: &str, headers: &[String]) -> Option<String> {
    let want = name.to_lowercase();
    headers
        .iter()
        .map(|h| (edit_distance(&want, &h.to_lowercase()), h))
        .min_by_key(|(d, _)| *d)
        .filter(|(d, h)| *d <= (want.chars().count().max(h.chars().count()) / 3).max(2))
        .map(|(_, h)| h.clone())
}

/// Levenshtein distance in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let cost = usize::from(ca != cb);
            let next = (row[j + 1] + 1).min(row[j] + 1).min(prev + cost);
            prev = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

/// Finds the spec's columns in the header; the rest are extra columns.
fn column_map(
    path: &Path,
    headers: &[String],
    spec: &ImportSpec,
    dialect: &Dialect,
) -> Result<ColumnMap, ImportError> {
    let find = |name: &str| {
        headers
            .iter()
            .position(|h| h == name.trim())
            .ok_or_else(|| ImportError::NoColumn {
                path: path.to_path_buf(),
                column: name.to_string(),
                closest: closest(name, headers),
                columns: headers.to_vec(),
                dialect: dialect.describe(),
            })
    };
    let three = |c: &[String; 3]| -> Result<[usize; 3], ImportError> {
        Ok([find(&c[0])?, find(&c[1])?, find(&c[2])?])
    };
    let joints = spec
        .joints
        .iter()
        .map(|c| find(c))
        .collect::<Result<Vec<_>, _>>()?;
    let point = three(&spec.point)?;
    let time = spec.time.as_deref().map(find).transpose()?;
    let orientation = spec
        .orientation
        .as_ref()
        .map(|o| three(&o.columns))
        .transpose()?;
    let point_sigma = spec.point_sigma.as_ref().map(three).transpose()?;
    let orientation_sigma = spec.orientation_sigma.as_ref().map(three).transpose()?;
    let temperature = spec.temperature.as_deref().map(find).transpose()?;
    let used: Vec<usize> = joints
        .iter()
        .chain(&point)
        .chain(time.iter())
        .chain(orientation.iter().flatten())
        .chain(point_sigma.iter().flatten())
        .chain(orientation_sigma.iter().flatten())
        .chain(temperature.iter())
        .copied()
        .collect();
    let extra = (0..headers.len()).filter(|c| !used.contains(c)).collect();
    Ok(ColumnMap {
        joints,
        point,
        time,
        orientation,
        point_sigma,
        orientation_sigma,
        temperature,
        extra,
    })
}

/// A row's orientation and the standard deviation of a small rotation about its own axes (rad).
type Pose = (Option<UnitQuaternion<f64>>, Option<Vector3<f64>>);

/// One data row of the file, with what its errors must name.
struct Cells<'a> {
    path: &'a Path,
    headers: &'a [String],
    line: u64,
    record: &'a csv::StringRecord,
    dialect: &'a Dialect,
}

impl Cells<'_> {
    /// The row as a measurement in internal units (its time is set once the whole column is
    /// read).
    fn measurement(
        &self,
        seq: u64,
        cols: &ColumnMap,
        specs: &[JointSpec],
        spec: &ImportSpec,
    ) -> Result<Measurement, ImportError> {
        let q = specs
            .iter()
            .zip(&cols.joints)
            .map(|(joint, &c)| self.joint(c, joint, spec))
            .collect::<Result<Vec<_>, _>>()?;
        let mm = spec.length_unit.to_mm();
        let p = self.triple(cols.point)? * mm;
        let (orientation, orientation_sigma) = match (&spec.orientation, cols.orientation) {
            (Some(o), Some(c)) => self.orientation(o, c, cols.orientation_sigma)?,
            _ => (None, None),
        };
        let position_sigma = match cols.point_sigma {
            Some(c) => Some(self.sigmas(c)? * mm),
            None => None,
        };
        Ok(Measurement {
            seq,
            t_s: None,
            q,
            position: Some(p),
            temp_c: cols.temperature.map(|c| self.number(c)).transpose()?,
            orientation,
            position_sigma,
            orientation_sigma,
            status: Status::Ok,
            extra: cols.extra.iter().map(|&c| self.extra(c)).collect(),
            ..Default::default()
        })
    }

    /// An extra column's text; a number with a decimal comma gets a decimal point, so the
    /// recording reads as one dialect.
    fn extra(&self, c: usize) -> String {
        let t = dialect::clean(self.record.get(c).unwrap_or(""));
        if self.dialect.decimal_comma && self.dialect.number(t).is_some() {
            t.replacen(',', ".", 1)
        } else {
            t.to_string()
        }
    }

    /// Where column `c` of this row is.
    fn at(&self, c: usize) -> Box<CellAt> {
        Box::new(CellAt {
            path: self.path.to_path_buf(),
            line: self.line,
            column: c + 1,
            name: self.headers[c].clone(),
        })
    }

    /// A finite number in column `c`.
    fn number(&self, c: usize) -> Result<f64, ImportError> {
        let t = self.record.get(c).unwrap_or("");
        self.dialect
            .number(t)
            .ok_or_else(|| ImportError::NotANumber {
                at: self.at(c),
                text: dialect::clean(t).to_string(),
                decimal_comma: self.dialect.decimal_comma,
            })
    }

    fn triple(&self, c: [usize; 3]) -> Result<Vector3<f64>, ImportError> {
        Ok(Vector3::new(
            self.number(c[0])?,
            self.number(c[1])?,
            self.number(c[2])?,
        ))
    }

    /// Three standard deviations, each ≥ 0.
    fn sigmas(&self, c: [usize; 3]) -> Result<Vector3<f64>, ImportError> {
        let v = self.triple(c)?;
        if let Some(k) = (0..3).find(|&k| v[k] < 0.0) {
            return Err(ImportError::BadValue {
                at: self.at(c[k]),
                reason: format!("{} is negative: a standard deviation is ≥ 0", v[k]),
            });
        }
        Ok(v)
    }

    /// The measured frame's orientation and the standard deviation of a small rotation about
    /// its own axes (rad).
    fn orientation(
        &self,
        o: &OrientationSpec,
        c: [usize; 3],
        sigma: Option<[usize; 3]>,
    ) -> Result<Pose, ImportError> {
        let raw = self.triple(c)?;
        if o.unit == AngleUnit::Rad {
            if let Some(k) = (0..3).find(|&k| raw[k].abs() > 2.0 * std::f64::consts::PI + 1e-6) {
                return Err(ImportError::BadValue {
                    at: self.at(c[k]),
                    reason: format!(
                        "{} is beyond ±2π for an angle in radians: were the orientation angles \
                         degrees? use --orientation-unit deg",
                        raw[k]
                    ),
                });
            }
        }
        let a = raw.map(|v| o.unit.to_rad(v));
        let angles = [a.x, a.y, a.z];
        let body = match sigma {
            Some(s) => {
                let s = self.sigmas(s)?.map(|v| o.unit.to_rad(v));
                Some(o.convention.body_sigma(angles, [s.x, s.y, s.z]))
            }
            None => None,
        };
        Ok((Some(o.convention.rotation(angles)), body))
    }

    /// A joint value in column `c`, converted to internal units and checked against the limits.
    fn joint(&self, c: usize, joint: &JointSpec, spec: &ImportSpec) -> Result<f64, ImportError> {
        let raw = self.number(c)?;
        let v = match joint.kind {
            JointKind::Revolute => spec.angle_unit.to_rad(raw),
            JointKind::Prismatic => raw * spec.length_unit.to_mm(),
        };
        if joint.within(v) {
            return Ok(v);
        }
        // A value that fits once read in the other unit names its likely cause.
        let hint = match joint.kind {
            JointKind::Revolute
                if spec.angle_unit == AngleUnit::Rad
                    && raw.abs() > 2.0 * std::f64::consts::PI
                    && joint.within(raw.to_radians()) =>
            {
                "; were the joint angles degrees? use --angle-unit deg"
            }
            JointKind::Prismatic if spec.length_unit == LengthUnit::M && joint.within(raw) => {
                "; were the lengths millimetres? use --length-unit mm"
            }
            _ => "",
        }
        .to_string();
        Err(ImportError::OutsideLimits {
            at: self.at(c),
            joint: joint.name.clone(),
            value: joint.kind.to_file_units(v),
            limits: [
                joint.kind.to_file_units(joint.min),
                joint.kind.to_file_units(joint.max),
            ],
            unit: joint.kind.unit(),
            hint,
        })
    }
}

/// The sidecar of an imported recording: its rig file and how the file was read.
fn session_info(
    path: &Path,
    rig: &Rig,
    spec: &ImportSpec,
    dialect: &Dialect,
    time: &TimeStatus,
) -> SessionInfo {
    let unit = |l: LengthUnit| if l == LengthUnit::M { "m" } else { "mm" };
    let angle = |a: AngleUnit| if a == AngleUnit::Rad { "rad" } else { "deg" };
    let (start, time_note) = match time {
        TimeStatus::Kept { start, .. } => (start.clone(), None),
        TimeStatus::Partial {
            start,
            lost_rows,
            rows,
            example,
            ..
        } => (
            start.clone(),
            Some(format!(
                "{lost_rows} of {rows} rows hold no valid time (first: `{example}`)"
            )),
        ),
        TimeStatus::Lost { reason } => (None, Some(reason.clone())),
        TimeStatus::NoColumn => (None, None),
    };
    let info = ImportInfo {
        source: path.display().to_string(),
        separator: dialect.separator_name(),
        decimal: if dialect.decimal_comma { "comma" } else { "point" }.into(),
        length_unit: unit(spec.length_unit).into(),
        angle_unit: angle(spec.angle_unit).into(),
        orientation: spec.orientation.as_ref().map(|o| {
            format!(
                "{} as {} Euler angles in {}; stored as roll_deg, pitch_deg, yaw_deg (R = Rz·Ry·Rx)",
                o.columns.join(","),
                o.convention,
                o.unit.name()
            )
        }),
        sigma: match (&spec.point_sigma, &spec.orientation_sigma) {
            (None, None) => None,
            (p, o) => Some(
                [p.as_ref().map(|c| c.join(",")), o.as_ref().map(|c| c.join(","))]
                    .into_iter()
                    .flatten()
                    .collect::<Vec<_>>()
                    .join(" and "),
            ),
        },
        temperature_column: spec.temperature.clone(),
        time_column: spec.time.clone(),
        time: time.keyword().into(),
        time_note,
    };
    let time_words = match time {
        TimeStatus::Kept { .. } => "",
        TimeStatus::Partial { .. } => "; some rows have no time",
        TimeStatus::NoColumn => "; no time column: time-dependent effects are not considered",
        TimeStatus::Lost { .. } => "; times lost: time-dependent effects are not considered",
    };
    SessionInfo {
        rig: rig.source.path.as_ref().map(|p| p.display().to_string()),
        start_time: start,
        notes: Some(format!(
            "imported from {} ({}, {}){time_words}",
            path.display(),
            spec.length_unit.name(),
            spec.angle_unit.name(),
        )),
        import: Some(info),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig() -> Rig {
        Rig::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2-ideal.toml"
        )))
        .expect("the shipped rig loads")
    }

    fn spec() -> ImportSpec {
        ImportSpec {
            joints: ["a1", "a2", "a3", "a4", "a5"].map(String::from).to_vec(),
            point: ["mx", "my", "mz"].map(String::from),
            time: Some("time".into()),
            ..ImportSpec::default()
        }
    }

    fn write(dir: &Path, text: &str) -> PathBuf {
        let path = dir.join("tracker.csv");
        std::fs::write(&path, text).expect("write the input");
        path
    }

    #[test]
    fn converts_units_orders_joints_and_keeps_other_columns() {
        let dir = tempfile::tempdir().expect("tempdir");
        // Joint columns out of the rig's order in the file.
        let path = write(
            dir.path(),
            "a2,time,a1,a3,a4,a5,mx,my,mz,operator\n0.2,0.5,0.1,-0.3,0,0,0.1,0.725,0.4,ann\n",
        );
        let rec = import_csv(&path, &rig(), &spec()).expect("import");
        assert_eq!(rec.extra_columns, vec!["operator".to_string()]);
        let m = &rec.rows[0];
        assert_eq!(m.seq, 1);
        assert_eq!(m.t_s, Some(0.5));
        assert_eq!(m.q, vec![0.1, 0.2, -0.3, 0.0, 0.0]);
        let p = m.position.expect("a measured point");
        assert!((p - Vector3::new(100.0, 725.0, 400.0)).norm() < 1e-9, "{p}");
        assert_eq!(m.extra, vec!["ann".to_string()]);
        let notes = rec.session.and_then(|s| s.notes).unwrap_or_default();
        assert!(notes.contains("(metres, radians)"), "{notes}");

        let mm_deg = ImportSpec {
            length_unit: LengthUnit::Mm,
            angle_unit: AngleUnit::Deg,
            time: None,
            ..spec()
        };
        let rec = import_csv(&path, &rig(), &mm_deg).expect("import");
        let m = &rec.rows[0];
        assert_eq!(m.t_s, None);
        assert!((m.q[0] - 0.1f64.to_radians()).abs() < 1e-15);
        assert_eq!(m.position, Some(Vector3::new(0.1, 0.725, 0.4)));
        assert_eq!(rec.extra_columns, vec!["time", "operator"]);
        let notes = rec.session.and_then(|s| s.notes).unwrap_or_default();
        assert!(
            notes.contains("time-dependent effects are not considered"),
            "{notes}"
        );
    }

    #[test]
    fn bad_cells_are_named_with_line_and_column() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = write(
            dir.path(),
            "time,a1,a2,a3,a4,a5,mx,my,mz\n0.5,0.1,0.2,-0.3,0,0,0.1,oops,0.4\n",
        );
        let e = import_csv(&path, &rig(), &spec()).expect_err("not a number");
        assert!(
            matches!(&e, ImportError::NotANumber { at, .. } if (at.line, at.column) == (2, 8)),
            "{e}"
        );
        assert!(e
            .to_string()
            .ends_with("line 2, column 8 (`my`): `oops` is not a number"));
        let path = write(
            dir.path(),
            "time,a1,a2,a3,a4,a5,mx,my,mz\n0.5,3.0,0.2,-0.3,0,0,0.1,0.7,0.4\n",
        );
        let e = import_csv(&path, &rig(), &spec()).expect_err("outside the limits");
        assert!(
            matches!(&e, ImportError::OutsideLimits { at, .. } if at.column == 2),
            "{e}"
        );
        let wrong = ImportSpec {
            point: ["mx", "my", "nz"].map(String::from),
            ..spec()
        };
        let e = import_csv(&path, &rig(), &wrong).expect_err("no such column");
        assert!(
            matches!(&e, ImportError::NoColumn { column, .. } if column == "nz"),
            "{e}"
        );
        let short = ImportSpec {
            joints: vec!["a1".into()],
            ..spec()
        };
        let e = import_csv(&path, &rig(), &short).expect_err("too few joints");
        assert!(matches!(e, ImportError::JointCount { given: 1, .. }), "{e}");
    }
}
