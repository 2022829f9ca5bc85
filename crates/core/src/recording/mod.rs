//! Recordings (spec/recordings.md): `measurements.csv` with one row per arm move, and the
//! optional `session.toml` beside it. Files hold millimetres and degrees; a [`Measurement`]
//! holds internal units (joint values in rad or mm, positions in mm).
//!
//! Reading finds columns by name, keeps unknown columns, and rejects bad rows with the file,
//! line and column named: nothing is silently dropped. Writing appends and flushes row by row
//! so a session killed at any instant leaves valid CSV (at worst a torn last line, which
//! [`RecordingWriter::open_append`] detects and discards).
//!
//! [`import`] turns a foreign CSV (laser tracker, motion capture) into a recording.

pub mod import;

pub use import::{
    import_csv, import_file, AngleUnit, CellAt, ImportError, ImportInfo, ImportSpec, Imported,
    LengthUnit,
};

use crate::kinematics::JointSpec;
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The CSV file name inside a recording directory.
pub const MEASUREMENTS_CSV: &str = "measurements.csv";
/// The sidecar file name inside a recording directory.
pub const SESSION_TOML: &str = "session.toml";

/// What went wrong reading or writing a recording.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordingError {
    /// The file has a header but no measured row: nothing to fit.
    #[error("{path}: the recording has no measured rows (a header, but no row with status ok and x_mm, y_mm, z_mm)")]
    NoMeasuredRows {
        /// The file.
        path: PathBuf,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A required column is missing from the header.
    #[error("{path}: line 1: missing column `{column}` (the header needs seq, t_s, {joints}, x_mm, y_mm, z_mm)")]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The column.
        column: String,
        /// The joint columns this rig expects.
        joints: String,
    },
    /// A header names a column twice: which one holds the value is ambiguous.
    #[error("{path}: line 1: column `{column}` appears more than once; keep one")]
    DuplicateColumn {
        /// The file.
        path: PathBuf,
        /// The repeated column.
        column: String,
    },
    /// A value is missing, not a number, or out of range.
    #[error("{path}: line {line}, column {column} (`{name}`): {reason}")]
    BadValue {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based column.
        column: usize,
        /// Column name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// The CSV itself is malformed (a row with the wrong number of fields, bad UTF-8, …).
    #[error("{path}: line {line}: {reason}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// What is wrong.
        reason: String,
    },
    /// `session.toml` is not valid.
    #[error("{path}: {reason}")]
    Session {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        reason: String,
    },
}

/// What a row records.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Status {
    /// A measurement.
    #[default]
    Ok,
    /// A move without a measurement (registration, clearance, retries).
    Via,
    /// A point given up, with the reason.
    Skipped(String),
}

impl Status {
    fn parse(s: &str) -> Option<Status> {
        match s.trim() {
            "" | "ok" => Some(Status::Ok),
            "via" => Some(Status::Via),
            other => other
                .strip_prefix("skipped")
                .map(|r| Status::Skipped(r.trim_start_matches(':').trim().to_string())),
        }
    }

    fn as_text(&self) -> String {
        match self {
            Status::Ok => "ok".into(),
            Status::Via => "via".into(),
            Status::Skipped(r) => format!("skipped: {r}"),
        }
    }
}

/// One row of a recording, in internal units.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Measurement {
    /// Measurement number, increasing.
    pub seq: u64,
    /// Seconds since the session started (None in an import without time).
    pub t_s: Option<f64>,
    /// Commanded joint values (rad or mm).
    pub q: Vec<f64>,
    /// Measured point, world frame (mm); None on rows that are not `ok`.
    pub position: Option<Vector3<f64>>,
    /// Region id (`ref` marks a drift-reference pose).
    pub region: Option<String>,
    /// The same point in the table frame (mm).
    pub table: Option<Vector3<f64>>,
    /// Panel offset (mm).
    pub panel_uv: Option<[f64; 2]>,
    /// Temperature (°C).
    pub temp_c: Option<f64>,
    /// Payload (kg).
    pub load_kg: Option<f64>,
    /// Measured orientation of the marker's (probe's) frame in the measurement frame, when the
    /// instrument gives one (a 6-DoF probe). Files: `roll_deg, pitch_deg, yaw_deg`,
    /// R = Rz(yaw)·Ry(pitch)·Rx(roll) as in rig files.
    pub orientation: Option<UnitQuaternion<f64>>,
    /// Standard deviations of the measured position's x, y and z (mm), when the instrument
    /// states them. Files: `sigma_x_mm, sigma_y_mm, sigma_z_mm`.
    pub position_sigma: Option<Vector3<f64>>,
    /// Standard deviations of a small rotation of the measured frame about its own x, y and z
    /// axes (rad). Files: `sigma_rx_deg, sigma_ry_deg, sigma_rz_deg`.
    pub orientation_sigma: Option<Vector3<f64>>,
    /// What the row records.
    pub status: Status,
    /// Values of the recording's unknown columns, in [`Recording::extra_columns`] order.
    pub extra: Vec<String>,
}

/// `session.toml`: what made a recording. Every key is optional; unknown keys are kept.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SessionInfo {
    /// Rig file used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rig: Option<String>,
    /// Scenario file (simulated worlds).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scenario: Option<String>,
    /// Seed of the simulated world.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Start time (RFC 3339) or a description of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_time: Option<String>,
    /// The table-to-world registration applied to `x_mm…`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub registration: Option<RegistrationInfo>,
    /// Free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
    /// How a foreign file was imported (`rigcal import`): its dialect, units, and whether its
    /// times were kept or lost.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub import: Option<ImportInfo>,
    /// Keys this version does not know.
    #[serde(flatten)]
    pub extra: toml::Table,
}

/// A rigid registration in file units: world = R(rpy) · table + translation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct RegistrationInfo {
    /// Translation (mm).
    pub translation_mm: [f64; 3],
    /// Roll, pitch, yaw (deg; R = Rz(yaw)·Ry(pitch)·Rx(roll)).
    pub rpy_deg: [f64; 3],
    /// RMS residual of the registration fit (mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_mm: Option<f64>,
}

/// A joint vector and the point measured there (mm): what identification fits.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Joint values (rad or mm).
    pub q: Vec<f64>,
    /// Measured point (mm).
    pub p: Vector3<f64>,
}

/// A recording in memory.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// The joints, in the rig's order.
    pub joints: Vec<JointSpec>,
    /// Rows in the order taken.
    pub rows: Vec<Measurement>,
    /// Names of columns this format does not define, kept in order.
    pub extra_columns: Vec<String>,
    /// The sidecar, when present.
    pub session: Option<SessionInfo>,
    /// The CSV line (1-based, header = 1) of each row when read from a file; empty otherwise.
    pub lines: Vec<u64>,
}

impl Recording {
    /// An empty recording for these joints.
    pub fn new(joints: &[JointSpec]) -> Self {
        Self {
            joints: joints.to_vec(),
            ..Default::default()
        }
    }

    /// The rows that are measurements (`status` ok), with their positions.
    pub fn measured(&self) -> impl Iterator<Item = (&Measurement, Vector3<f64>)> {
        self.rows
            .iter()
            .filter(|m| m.status == Status::Ok)
            .filter_map(|m| m.position.map(|p| (m, p)))
    }

    /// The measured rows as observations (joint values, measured point), in row order.
    pub fn observations(&self) -> Vec<Observation> {
        self.measured()
            .map(|(m, p)| Observation { q: m.q.clone(), p })
            .collect()
    }

    /// The measurement rows (`status` ok) that carry table coordinates, as observations of the
    /// table point: what a registration fits.
    pub fn table_observations(&self) -> Vec<Observation> {
        self.rows
            .iter()
            .filter(|m| m.status == Status::Ok)
            .filter_map(|m| m.table.map(|p| Observation { q: m.q.clone(), p }))
            .collect()
    }

    /// Reads a recording directory (or a bare CSV file).
    pub fn read(path: &Path, joints: &[JointSpec]) -> Result<Recording, RecordingError> {
        let (csv_path, dir) = if path.is_dir() {
            (path.join(MEASUREMENTS_CSV), Some(path.to_path_buf()))
        } else {
            (path.to_path_buf(), None)
        };
        let file = File::open(&csv_path).map_err(|source| RecordingError::Io {
            path: csv_path.clone(),
            source,
        })?;
        let mut rec = read_csv(file, &csv_path, joints)?;
        if let Some(dir) = dir {
            rec.session = read_session_info(&dir)?;
        }
        Ok(rec)
    }

    /// Reads the first `len` bytes of a CSV file as a recording: a session's committed rows,
    /// without what it wrote after its last journal commit.
    pub fn read_prefix(
        csv: &Path,
        len: u64,
        joints: &[JointSpec],
    ) -> Result<Recording, RecordingError> {
        let file = File::open(csv).map_err(|source| RecordingError::Io {
            path: csv.to_path_buf(),
            source,
        })?;
        read_csv(std::io::Read::take(file, len), csv, joints)
    }

    /// Reads a recording that is to be fitted: as [`Recording::read`], and an error naming the
    /// file when it has no measured row (a session that measured nothing yet, say).
    pub fn read_measured(path: &Path, joints: &[JointSpec]) -> Result<Recording, RecordingError> {
        let rec = Self::read(path, joints)?;
        if rec.measured().next().is_none() {
            let path = if path.is_dir() {
                path.join(MEASUREMENTS_CSV)
            } else {
                path.to_path_buf()
            };
            return Err(RecordingError::NoMeasuredRows { path });
        }
        Ok(rec)
    }

    /// Writes the recording as a directory: `measurements.csv` and, when present, `session.toml`.
    pub fn write_dir(&self, dir: &Path) -> Result<(), RecordingError> {
        std::fs::create_dir_all(dir).map_err(|source| RecordingError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        let mut w = RecordingWriter::create_with(
            &dir.join(MEASUREMENTS_CSV),
            &self.joints,
            &self.extra_columns,
            PoseColumns::of(&self.rows),
        )?;
        for m in &self.rows {
            w.append(m)?;
        }
        if let Some(info) = &self.session {
            write_session(dir, info)?;
        }
        Ok(())
    }
}

/// Reads `session.toml` from a recording directory; `None` when there is none.
pub fn read_session_info(dir: &Path) -> Result<Option<SessionInfo>, RecordingError> {
    let path = dir.join(SESSION_TOML);
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(|source| RecordingError::Io {
        path: path.clone(),
        source,
    })?;
    toml::from_str(&text)
        .map(Some)
        .map_err(|e| RecordingError::Session {
            path,
            reason: e.to_string(),
        })
}

/// Writes `session.toml` into a recording directory, atomically (a temporary file renamed over
/// it): a process killed meanwhile leaves the old file or the new one, never a torn one (a
/// resumed session reads it back).
pub fn write_session(dir: &Path, info: &SessionInfo) -> Result<(), RecordingError> {
    let path = dir.join(SESSION_TOML);
    let text = toml::to_string_pretty(info).map_err(|e| RecordingError::Session {
        path: path.clone(),
        reason: e.to_string(),
    })?;
    let tmp = dir.join(format!("{SESSION_TOML}.tmp"));
    std::fs::write(&tmp, text).map_err(|source| RecordingError::Io {
        path: tmp.clone(),
        source,
    })?;
    std::fs::rename(&tmp, &path).map_err(|source| RecordingError::Io { path, source })
}

/// The orientation and standard-deviation columns, written after `status` when a recording has
/// them (a recording without them is written as before).
const POSE_COLUMNS: [&str; 9] = [
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "sigma_x_mm",
    "sigma_y_mm",
    "sigma_z_mm",
    "sigma_rx_deg",
    "sigma_ry_deg",
    "sigma_rz_deg",
];

/// Which of [`POSE_COLUMNS`]' three groups a recording file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PoseColumns {
    /// `roll_deg, pitch_deg, yaw_deg`.
    pub orientation: bool,
    /// `sigma_x_mm, sigma_y_mm, sigma_z_mm`.
    pub position_sigma: bool,
    /// `sigma_rx_deg, sigma_ry_deg, sigma_rz_deg`.
    pub orientation_sigma: bool,
}

impl PoseColumns {
    /// The groups any of `rows` carries.
    pub fn of(rows: &[Measurement]) -> Self {
        Self {
            orientation: rows.iter().any(|m| m.orientation.is_some()),
            position_sigma: rows.iter().any(|m| m.position_sigma.is_some()),
            orientation_sigma: rows.iter().any(|m| m.orientation_sigma.is_some()),
        }
    }

    fn groups(self) -> [bool; 3] {
        [
            self.orientation,
            self.position_sigma,
            self.orientation_sigma,
        ]
    }

    /// The column names, in order.
    fn names(self) -> impl Iterator<Item = &'static str> {
        self.groups()
            .into_iter()
            .zip(POSE_COLUMNS.chunks(3))
            .filter(|(on, _)| *on)
            .flat_map(|(_, c)| c.iter().copied())
    }
}

/// The optional columns, in the order they are written after `x_mm, y_mm, z_mm`.
const OPTIONAL: [&str; 9] = [
    "region",
    "table_x_mm",
    "table_y_mm",
    "table_z_mm",
    "panel_u_mm",
    "panel_v_mm",
    "temp_c",
    "load_kg",
    "status",
];

/// Whether header `i` is a pose column whose group of three is complete (and so is read, not
/// kept as an extra column).
fn cols_pose_member(headers: &[String], i: usize) -> bool {
    let Some(k) = POSE_COLUMNS.iter().position(|c| *c == headers[i]) else {
        return false;
    };
    let g = k / 3 * 3;
    (g..g + 3).all(|j| headers.iter().any(|h| h == POSE_COLUMNS[j]))
}

struct Columns {
    seq: usize,
    t_s: usize,
    q: Vec<usize>,
    xyz: [usize; 3],
    region: Option<usize>,
    table: Option<[usize; 3]>,
    panel: Option<[usize; 2]>,
    temp: Option<usize>,
    load: Option<usize>,
    status: Option<usize>,
    /// `roll_deg…`, `sigma_x_mm…`, `sigma_rx_deg…`, each group when all three are present.
    pose: [Option<[usize; 3]>; 3],
    extra: Vec<usize>,
}

/// Line numbers from byte offsets: the csv crate's own line count is one short after a CRLF
/// header, and a person looks for the line an editor shows.
struct LineIndex<'b> {
    bytes: &'b [u8],
    newlines: Vec<u64>,
}

impl<'b> LineIndex<'b> {
    fn of(bytes: &'b [u8]) -> Self {
        let newlines = bytes
            .iter()
            .enumerate()
            .filter(|(_, &b)| b == b'\n')
            .map(|(i, _)| i as u64)
            .collect();
        LineIndex { bytes, newlines }
    }

    /// The 1-based line of the first byte at or after `offset` that is not a line end (a
    /// record's position can point at the line ends before it: the rest of a CRLF, or blank
    /// lines).
    fn line_at(&self, offset: u64) -> u64 {
        let skip = self
            .bytes
            .iter()
            .skip(usize::try_from(offset).unwrap_or(usize::MAX))
            .take_while(|&&b| b == b'\r' || b == b'\n')
            .count() as u64;
        self.newlines.partition_point(|&n| n < offset + skip) as u64 + 1
    }

    /// The line of a record, or of an error, by its position.
    fn line_of(&self, position: Option<&csv::Position>) -> u64 {
        position.map_or(0, |p| self.line_at(p.byte()))
    }
}

fn read_csv<R: std::io::Read>(
    mut input: R,
    path: &Path,
    joints: &[JointSpec],
) -> Result<Recording, RecordingError> {
    let mut bytes = Vec::new();
    input
        .read_to_end(&mut bytes)
        .map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    let lines = LineIndex::of(&bytes);
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(false)
        .from_reader(bytes.as_slice());
    let headers = reader
        .headers()
        .map_err(|e| malformed(path, &e, &lines))?
        .iter()
        .map(|h| h.trim().to_string())
        .collect::<Vec<_>>();
    let joint_cols: Vec<String> = joints
        .iter()
        .enumerate()
        .map(|(i, j)| j.kind.column(i + 1))
        .collect();
    let find = |name: &str| headers.iter().position(|h| h == name);
    let require = |name: &str| {
        find(name).ok_or_else(|| RecordingError::MissingColumn {
            path: path.to_path_buf(),
            column: name.to_string(),
            joints: joint_cols.join(", "),
        })
    };
    let q = joint_cols
        .iter()
        .map(|c| require(c))
        .collect::<Result<Vec<_>, _>>()?;
    let cols = Columns {
        seq: require("seq")?,
        t_s: require("t_s")?,
        xyz: [require("x_mm")?, require("y_mm")?, require("z_mm")?],
        region: find("region"),
        table: match (find("table_x_mm"), find("table_y_mm"), find("table_z_mm")) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            _ => None,
        },
        panel: match (find("panel_u_mm"), find("panel_v_mm")) {
            (Some(a), Some(b)) => Some([a, b]),
            _ => None,
        },
        temp: find("temp_c"),
        load: find("load_kg"),
        status: find("status"),
        pose: [0, 3, 6].map(|k| {
            match (
                find(POSE_COLUMNS[k]),
                find(POSE_COLUMNS[k + 1]),
                find(POSE_COLUMNS[k + 2]),
            ) {
                (Some(a), Some(b), Some(c)) => Some([a, b, c]),
                _ => None,
            }
        }),
        extra: (0..headers.len())
            .filter(|&i| {
                let h = headers[i].as_str();
                !(h == "seq"
                    || h == "t_s"
                    || ["x_mm", "y_mm", "z_mm"].contains(&h)
                    || OPTIONAL.contains(&h)
                    || joint_cols.iter().any(|c| c == h))
            })
            .filter(|&i| {
                // A pose column is read only with the other two of its group.
                !cols_pose_member(&headers, i)
            })
            .collect(),
        q,
    };
    let mut rec = Recording::new(joints);
    rec.extra_columns = cols.extra.iter().map(|&i| headers[i].clone()).collect();
    let mut last_seq: Option<u64> = None;
    for result in reader.records() {
        let record = result.map_err(|e| malformed(path, &e, &lines))?;
        let line = lines.line_of(record.position());
        let row = RowReader {
            path,
            line,
            record: &record,
            headers: &headers,
        };
        let m = row.measurement(&cols, joints)?;
        if let Some(prev) = last_seq {
            if m.seq <= prev {
                return Err(row.bad(
                    cols.seq,
                    format!("seq {} does not increase (previous row has {prev})", m.seq),
                ));
            }
        }
        last_seq = Some(m.seq);
        rec.rows.push(m);
        rec.lines.push(line);
    }
    Ok(rec)
}

fn malformed(path: &Path, e: &csv::Error, lines: &LineIndex) -> RecordingError {
    let line = lines.line_of(e.position());
    let reason = match e.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => {
            format!("row has {len} fields, the header has {expected_len}")
        }
        csv::ErrorKind::Utf8 { .. } => "not valid UTF-8".to_string(),
        _ => e.to_string(),
    };
    RecordingError::Malformed {
        path: path.to_path_buf(),
        line,
        reason,
    }
}

struct RowReader<'a> {
    path: &'a Path,
    line: u64,
    record: &'a csv::StringRecord,
    headers: &'a [String],
}

impl RowReader<'_> {
    fn bad(&self, col: usize, reason: impl Into<String>) -> RecordingError {
        RecordingError::BadValue {
            path: self.path.to_path_buf(),
            line: self.line,
            column: col + 1,
            name: self.headers.get(col).cloned().unwrap_or_default(),
            reason: reason.into(),
        }
    }

    fn text(&self, col: usize) -> &str {
        self.record.get(col).unwrap_or("").trim()
    }

    fn number(&self, col: usize) -> Result<Option<f64>, RecordingError> {
        let t = self.text(col);
        if t.is_empty() {
            return Ok(None);
        }
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            Ok(_) => Err(self.bad(col, format!("`{t}` is not a finite number"))),
            Err(_) => Err(self.bad(col, format!("`{t}` is not a number"))),
        }
    }

    fn required(&self, col: usize) -> Result<f64, RecordingError> {
        self.number(col)?
            .ok_or_else(|| self.bad(col, "value missing"))
    }

    fn measurement(
        &self,
        cols: &Columns,
        joints: &[JointSpec],
    ) -> Result<Measurement, RecordingError> {
        let seq_text = self.text(cols.seq);
        let seq = seq_text
            .parse::<u64>()
            .map_err(|_| self.bad(cols.seq, format!("`{seq_text}` is not a whole number ≥ 0")))?;
        let status = match cols.status {
            Some(c) => Status::parse(self.text(c)).ok_or_else(|| {
                self.bad(
                    c,
                    format!("`{}` is not ok, via or skipped: REASON", self.text(c)),
                )
            })?,
            None => Status::Ok,
        };
        let mut q = Vec::with_capacity(joints.len());
        for (spec, &c) in joints.iter().zip(&cols.q) {
            let v = spec.kind.from_file_units(self.required(c)?);
            // A row holds what the arm reported, which may lie a hair past a limit.
            if !spec.within_reading(v) {
                return Err(self.bad(
                    c,
                    format!(
                        "{} {} is outside joint {}'s limits {}..{} {}",
                        self.text(c),
                        spec.kind.unit(),
                        spec.name,
                        spec.kind.to_file_units(spec.min),
                        spec.kind.to_file_units(spec.max),
                        spec.kind.unit()
                    ),
                ));
            }
            q.push(v);
        }
        let xyz = [
            self.number(cols.xyz[0])?,
            self.number(cols.xyz[1])?,
            self.number(cols.xyz[2])?,
        ];
        let position = match (status == Status::Ok, xyz) {
            (_, [Some(x), Some(y), Some(z)]) => Some(Vector3::new(x, y, z)),
            (false, [None, None, None]) => None,
            _ => {
                let k = xyz.iter().position(Option::is_none).unwrap_or(0);
                return Err(self.bad(cols.xyz[k], "value missing in a measured (ok) row"));
            }
        };
        let triple = |c: Option<[usize; 3]>| -> Result<Option<Vector3<f64>>, RecordingError> {
            let Some(c) = c else { return Ok(None) };
            match [self.number(c[0])?, self.number(c[1])?, self.number(c[2])?] {
                [Some(a), Some(b), Some(d)] => Ok(Some(Vector3::new(a, b, d))),
                [None, None, None] => Ok(None),
                v => Err(self.bad(
                    c[v.iter().position(Option::is_none).unwrap_or(0)],
                    "this value is missing while the other two of its group (table point, \
                     orientation or standard deviations) are present",
                )),
            }
        };
        let panel_uv = match cols.panel {
            Some(c) => match (self.number(c[0])?, self.number(c[1])?) {
                (Some(u), Some(v)) => Some([u, v]),
                (None, None) => None,
                _ => return Err(self.bad(c[0], "panel u and v must both be present or both empty")),
            },
            None => None,
        };
        let opt = |c: Option<usize>| c.map(|c| self.number(c)).transpose().map(Option::flatten);
        let [orientation, position_sigma, orientation_sigma] =
            [0, 1, 2].map(|k| triple(cols.pose[k]));
        let deg = |v: Option<Vector3<f64>>| v.map(|v| v.map(f64::to_radians));
        let orientation =
            deg(orientation?).map(|r| UnitQuaternion::from_euler_angles(r.x, r.y, r.z));
        Ok(Measurement {
            seq,
            t_s: self.number(cols.t_s)?,
            q,
            position,
            region: cols
                .region
                .map(|c| self.text(c).to_string())
                .filter(|s| !s.is_empty()),
            table: triple(cols.table)?,
            panel_uv,
            temp_c: opt(cols.temp)?,
            load_kg: opt(cols.load)?,
            orientation,
            position_sigma: position_sigma?,
            orientation_sigma: deg(orientation_sigma?),
            status,
            extra: cols
                .extra
                .iter()
                .map(|&c| self.text(c).to_string())
                .collect(),
        })
    }
}

/// Appends rows to `measurements.csv`, flushing (and syncing) each before returning.
pub struct RecordingWriter {
    file: File,
    path: PathBuf,
    joints: Vec<JointSpec>,
    extra_columns: Vec<String>,
    pose: PoseColumns,
    sync: bool,
}

impl RecordingWriter {
    /// Creates (or truncates) a CSV and writes its header.
    pub fn create(
        path: &Path,
        joints: &[JointSpec],
        extra_columns: &[String],
    ) -> Result<Self, RecordingError> {
        Self::create_with(path, joints, extra_columns, PoseColumns::default())
    }

    /// As [`RecordingWriter::create`], with orientation and standard-deviation columns.
    pub fn create_with(
        path: &Path,
        joints: &[JointSpec],
        extra_columns: &[String],
        pose: PoseColumns,
    ) -> Result<Self, RecordingError> {
        let file = File::create(path).map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut w = Self {
            file,
            path: path.to_path_buf(),
            joints: joints.to_vec(),
            extra_columns: extra_columns.to_vec(),
            pose,
            sync: false,
        };
        let header = header_with(joints, extra_columns, pose);
        w.write_line(&header)?;
        Ok(w)
    }

    /// Opens an existing CSV for appending after a crash: a torn last line (no trailing newline)
    /// is cut off. Returns the writer and whether a torn line was discarded.
    pub fn open_append(
        path: &Path,
        joints: &[JointSpec],
        extra_columns: &[String],
    ) -> Result<(Self, bool), RecordingError> {
        let io = |source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .map_err(io)?;
        let mut keep = 0u64;
        let mut torn = false;
        {
            let mut reader = BufReader::new(&mut file);
            let mut buf = Vec::new();
            loop {
                buf.clear();
                let n = reader.read_until(b'\n', &mut buf).map_err(io)?;
                if n == 0 {
                    break;
                }
                if buf.last() == Some(&b'\n') {
                    keep += n as u64;
                } else {
                    torn = true;
                }
            }
        }
        file.set_len(keep).map_err(io)?;
        file.seek(SeekFrom::End(0)).map_err(io)?;
        Ok((
            Self {
                file,
                path: path.to_path_buf(),
                joints: joints.to_vec(),
                extra_columns: extra_columns.to_vec(),
                pose: PoseColumns::default(),
                sync: false,
            },
            torn,
        ))
    }

    /// Makes every append also `fsync` the file (for sessions on the rig).
    pub fn sync_each_row(mut self, on: bool) -> Self {
        self.sync = on;
        self
    }

    /// Appends one row and flushes it to the operating system (and disk, with sync on).
    pub fn append(&mut self, m: &Measurement) -> Result<(), RecordingError> {
        let line = row_text_with(m, &self.joints, self.pose, self.extra_columns.len());
        self.write_line(&line)
    }

    fn write_line(&mut self, line: &str) -> Result<(), RecordingError> {
        let io = |source| RecordingError::Io {
            path: self.path.clone(),
            source,
        };
        let mut bytes = String::with_capacity(line.len() + 1);
        bytes.push_str(line);
        bytes.push('\n');
        self.file.write_all(bytes.as_bytes()).map_err(io)?;
        self.file.flush().map_err(io)?;
        if self.sync {
            self.file.sync_data().map_err(io)?;
        }
        Ok(())
    }
}

/// The header line for these joints.
pub fn header(joints: &[JointSpec], extra: &[String]) -> String {
    header_with(joints, extra, PoseColumns::default())
}

/// The header line for these joints, with the orientation and standard-deviation columns
/// `pose` asks for.
pub fn header_with(joints: &[JointSpec], extra: &[String], pose: PoseColumns) -> String {
    let mut cols: Vec<String> = vec!["seq".into(), "t_s".into()];
    cols.extend(joints.iter().enumerate().map(|(i, j)| j.kind.column(i + 1)));
    cols.extend(["x_mm", "y_mm", "z_mm"].map(String::from));
    cols.extend(OPTIONAL.map(String::from));
    cols.extend(pose.names().map(String::from));
    cols.extend(extra.iter().map(|c| csv_field(c)));
    cols.join(",")
}

/// The joints and position of `m` exactly as [`Recording::read`] will return them from the
/// file [`RecordingWriter`] writes (joints to 10⁻⁶ deg or mm, positions to 10⁻⁵ mm): what a
/// consumer of a live session sees is then what a later reader of its recording sees.
pub fn as_recorded(m: &Measurement, joints: &[JointSpec]) -> (Vec<f64>, Option<Vector3<f64>>) {
    let round = |v: f64, digits: usize| -> f64 { format!("{v:.digits$}").parse().unwrap_or(v) };
    let q = joints
        .iter()
        .zip(&m.q)
        .map(|(spec, v)| {
            spec.kind
                .from_file_units(round(spec.kind.to_file_units(*v), 6))
        })
        .collect();
    let p = m
        .position
        .map(|p| Vector3::new(round(p.x, 5), round(p.y, 5), round(p.z, 5)));
    (q, p)
}

#[cfg(test)]
fn row_text(m: &Measurement, joints: &[JointSpec], n_extra: usize) -> String {
    row_text_with(m, joints, PoseColumns::default(), n_extra)
}

fn row_text_with(
    m: &Measurement,
    joints: &[JointSpec],
    pose: PoseColumns,
    n_extra: usize,
) -> String {
    let mut s = String::new();
    let _ = write!(s, "{},", m.seq);
    if let Some(t) = m.t_s {
        let _ = write!(s, "{t:.3}");
    }
    for (spec, v) in joints.iter().zip(&m.q) {
        let _ = write!(s, ",{:.6}", spec.kind.to_file_units(*v));
    }
    push_opt_vec(&mut s, m.position.as_ref());
    s.push(',');
    if let Some(r) = &m.region {
        s.push_str(&csv_field(r));
    }
    push_opt_vec(&mut s, m.table.as_ref());
    match m.panel_uv {
        Some([u, v]) => {
            let _ = write!(s, ",{u:.5},{v:.5}");
        }
        None => s.push_str(",,"),
    }
    for v in [m.temp_c, m.load_kg] {
        s.push(',');
        if let Some(v) = v {
            let _ = write!(s, "{v}");
        }
    }
    s.push(',');
    s.push_str(&csv_field(&m.status.as_text()));
    push_pose(&mut s, m, pose);
    for k in 0..n_extra {
        s.push(',');
        s.push_str(&csv_field(m.extra.get(k).map(String::as_str).unwrap_or("")));
    }
    s
}

/// The orientation (deg, 6 decimals: 2e-8 rad) and standard deviations (mm, deg, 8 decimals)
/// `pose` asks for; empty fields where a row has none.
fn push_pose(s: &mut String, m: &Measurement, pose: PoseColumns) {
    let rpy = m.orientation.map(|r| {
        let (a, b, c) = r.euler_angles();
        Vector3::new(a, b, c).map(f64::to_degrees)
    });
    let values = [
        rpy,
        m.position_sigma,
        m.orientation_sigma.map(|v| v.map(f64::to_degrees)),
    ];
    for ((on, v), digits) in pose.groups().into_iter().zip(values).zip([6, 8, 8]) {
        if !on {
            continue;
        }
        match v {
            Some(v) => {
                let _ = write!(s, ",{:.digits$},{:.digits$},{:.digits$}", v.x, v.y, v.z);
            }
            None => s.push_str(",,,"),
        }
    }
}

fn push_opt_vec(s: &mut String, v: Option<&Vector3<f64>>) {
    match v {
        Some(p) => {
            let _ = write!(s, ",{:.5},{:.5},{:.5}", p.x, p.y, p.z);
        }
        None => s.push_str(",,,"),
    }
}

fn csv_field(v: &str) -> String {
    if v.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", v.replace('"', "\"\""))
    } else {
        v.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::JointKind;

    /// Rows: ok with a point and a table point, via, ok without a point, skipped, ok.
    fn mixed() -> Recording {
        let mut rec = Recording::new(&joints());
        let row = |seq: u64, status: Status, p: Option<[f64; 3]>| Measurement {
            seq,
            q: vec![0.1 * seq as f64, 10.0 * seq as f64],
            position: p.map(Vector3::from),
            status,
            ..Default::default()
        };
        rec.rows = vec![
            Measurement {
                table: Some(Vector3::new(7.0, 8.0, 9.0)),
                ..row(1, Status::Ok, Some([1.0, 2.0, 3.0]))
            },
            row(2, Status::Via, None),
            Measurement {
                table: Some(Vector3::new(1.0, 1.0, 1.0)),
                ..row(3, Status::Ok, None)
            },
            row(4, Status::Skipped("out of reach".into()), None),
            row(5, Status::Ok, Some([4.0, 5.0, 6.0])),
        ];
        rec
    }

    #[test]
    fn observations_are_the_measured_rows_in_order() {
        let rec = mixed();
        let obs = rec.observations();
        assert_eq!(
            obs,
            vec![
                Observation {
                    q: vec![0.1, 10.0],
                    p: Vector3::new(1.0, 2.0, 3.0)
                },
                Observation {
                    q: vec![0.5, 50.0],
                    p: Vector3::new(4.0, 5.0, 6.0)
                },
            ]
        );
        // A registration fits table points, which a row may carry without a world point.
        let table: Vec<Vector3<f64>> = rec.table_observations().iter().map(|o| o.p).collect();
        assert_eq!(
            table,
            vec![Vector3::new(7.0, 8.0, 9.0), Vector3::new(1.0, 1.0, 1.0)]
        );
    }

    #[test]
    fn commands_csv_is_in_file_units_and_reads_back_as_poses() {
        let text = commands_csv(
            &joints(),
            [[0.5f64.to_radians(), 12.25].as_slice(), &[-1.0, 0.0]],
        );
        assert_eq!(
            text,
            "q1_deg,q2_mm\n0.500000,12.250000\n-57.295780,0.000000\n"
        );
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("poses.csv");
        std::fs::write(&path, &text).expect("write");
        let poses = read_poses(&path, &joints()).expect("read");
        assert!((poses[0][0] - 0.5f64.to_radians()).abs() < 1e-9);
        assert_eq!(poses[1][1], 0.0);
        std::fs::write(&path, "x_mm,y_mm,z_mm\n1,2,3\n").expect("write");
        let e = read_poses(&path, &joints()).expect_err("positions are not poses");
        assert!(
            e.to_string().ends_with(
                "line 2: a poses file needs joint columns (q1_deg…), not x_mm,y_mm,z_mm"
            ),
            "{e}"
        );
    }

    fn joints() -> Vec<JointSpec> {
        vec![
            JointSpec {
                name: "J1".into(),
                kind: JointKind::Revolute,
                min: (-150f64).to_radians(),
                max: 150f64.to_radians(),
            },
            JointSpec {
                name: "lift".into(),
                kind: JointKind::Prismatic,
                min: 0.0,
                max: 500.0,
            },
        ]
    }

    #[test]
    fn row_text_is_literal() {
        let m = Measurement {
            seq: 7,
            t_s: Some(12.5),
            q: vec![30f64.to_radians(), 100.25],
            position: Some(Vector3::new(1.0, -2.5, 3.125)),
            region: Some("r3".into()),
            status: Status::Ok,
            ..Default::default()
        };
        assert_eq!(header(&joints(), &[]), "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm,region,table_x_mm,table_y_mm,table_z_mm,panel_u_mm,panel_v_mm,temp_c,load_kg,status");
        assert_eq!(
            row_text(&m, &joints(), 0),
            "7,12.500,30.000000,100.250000,1.00000,-2.50000,3.12500,r3,,,,,,,,ok"
        );
    }

    #[test]
    fn reads_back_what_it_writes_and_keeps_unknown_columns() {
        let text = "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm,operator,status\n1,0.5,10,20,1,2,3,ann,ok\n2,,11,21,,,,bob,via\n3,1.5,12,22,,,,,skipped: no contact\n";
        let rec = read_csv(text.as_bytes(), Path::new("r.csv"), &joints()).unwrap();
        assert_eq!(rec.rows.len(), 3);
        assert_eq!(rec.extra_columns, vec!["operator"]);
        assert_eq!(rec.rows[1].status, Status::Via);
        assert_eq!(rec.rows[2].status, Status::Skipped("no contact".into()));
        assert_eq!(rec.rows[0].extra, vec!["ann"]);
        assert!((rec.rows[0].q[0] - 10f64.to_radians()).abs() < 1e-15);
        assert_eq!(rec.measured().count(), 1);
    }

    /// A session at seed 123 of a tuning run recorded a `via` row at q2 = -30.000214° against
    /// a limit of -30° (the arm's report of a pose commanded at its limit) and could not read
    /// its own recording back. A hair past a limit is a reading; a tenth of a degree is not.
    #[test]
    fn a_reading_a_hair_past_a_limit_is_kept_and_a_tenth_of_a_degree_is_refused() {
        let hair = "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n1,0,-150.000214,500.004,1,2,3\n";
        let rec = read_csv(hair.as_bytes(), Path::new("r.csv"), &joints()).unwrap();
        assert!((rec.rows[0].q[0] - (-150.000214f64).to_radians()).abs() < 1e-12);
        for (row, column) in [
            ("1,0,-150.1,20,1,2,3", "line 2, column 3 (`q1_deg`)"),
            ("1,0,10,500.02,1,2,3", "line 2, column 4 (`q2_mm`)"),
        ] {
            let text = format!("seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n{row}\n");
            let err = read_csv(text.as_bytes(), Path::new("r.csv"), &joints())
                .unwrap_err()
                .to_string();
            assert!(
                err.contains(column) && err.contains("outside joint"),
                "{err}"
            );
        }
    }

    #[test]
    fn bad_rows_name_line_and_column() {
        let cases = [
            (
                "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n1,0,10,20,1,2,abc\n",
                "line 2, column 7 (`z_mm`)",
                "not a number",
            ),
            (
                "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n1,0,10,20,1,2,3\n2,0,170,20,1,2,3\n",
                "line 3, column 3 (`q1_deg`)",
                "outside joint J1",
            ),
            (
                "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n2,0,10,20,1,2,3\n2,0,10,20,1,2,3\n",
                "line 3, column 1 (`seq`)",
                "does not increase",
            ),
            (
                "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n1,0,10,20,1,,3\n",
                "line 2, column 6 (`y_mm`)",
                "missing",
            ),
            (
                "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n1,0,NaN,20,1,2,3\n",
                "line 2, column 3",
                "not a finite number",
            ),
            (
                "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n1,0,10,20,1,2\n",
                "line 2",
                "6 fields",
            ),
            (
                "seq,t_s,q1_deg,x_mm,y_mm,z_mm\n",
                "missing column `q2_mm`",
                "",
            ),
        ];
        for (text, place, what) in cases {
            let e = read_csv(text.as_bytes(), Path::new("r.csv"), &joints())
                .unwrap_err()
                .to_string();
            assert!(e.contains(place) && e.contains(what), "{e}");
            assert!(e.starts_with("r.csv"), "{e}");
            // The same file written with CRLF line ends names the same line.
            let crlf = text.replace('\n', "\r\n");
            let e = read_csv(crlf.as_bytes(), Path::new("r.csv"), &joints())
                .unwrap_err()
                .to_string();
            assert!(e.contains(place) && e.contains(what), "CRLF: {e}");
        }
    }

    #[test]
    fn rows_keep_their_file_lines_with_either_line_end() {
        let text = "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm\n1,0,10,20,1,2,3\n\n2,0,10,20,1,2,3\n";
        for t in [text.to_string(), text.replace('\n', "\r\n")] {
            let rec = read_csv(t.as_bytes(), Path::new("r.csv"), &joints()).unwrap();
            assert_eq!(rec.lines, vec![2, 4], "{t:?}");
        }
    }

    #[test]
    fn orientation_and_sigmas_round_trip_only_when_present() {
        let dir = tempfile::tempdir().unwrap();
        let mut rec = mixed();
        // An ok row without a point does not read back (nothing to do with these columns).
        rec.rows
            .retain(|m| m.status != Status::Ok || m.position.is_some());
        let r = UnitQuaternion::from_euler_angles(0.3, -1.2, 2.9);
        rec.rows[0].orientation = Some(r);
        rec.rows[0].position_sigma = Some(Vector3::new(0.01, 0.02, 0.005));
        rec.rows[0].orientation_sigma = Some(Vector3::new(1e-5, 2e-5, 3e-5));
        rec.write_dir(dir.path()).unwrap();
        let back = Recording::read(dir.path(), &joints()).unwrap();
        let m = &back.rows[0];
        assert!(m.orientation.unwrap().angle_to(&r) < 1e-7);
        assert!((m.position_sigma.unwrap() - Vector3::new(0.01, 0.02, 0.005)).norm() < 1e-8);
        assert!((m.orientation_sigma.unwrap() - Vector3::new(1e-5, 2e-5, 3e-5)).norm() < 1e-9);
        assert_eq!(back.rows[3].orientation, None);
        assert_eq!(back.rows[3].position_sigma, None);
        assert!(back.extra_columns.is_empty(), "{:?}", back.extra_columns);
        // Without them the file is written as before.
        let plain = tempfile::tempdir().unwrap();
        mixed().write_dir(plain.path()).unwrap();
        let text = std::fs::read_to_string(plain.path().join(MEASUREMENTS_CSV)).unwrap();
        assert_eq!(text.lines().next(), Some(header(&joints(), &[]).as_str()));
        // A group missing a column stays an extra column.
        let text = "seq,t_s,q1_deg,q2_mm,x_mm,y_mm,z_mm,roll_deg,pitch_deg\n1,0,10,20,1,2,3,4,5\n";
        let rec = read_csv(text.as_bytes(), Path::new("r.csv"), &joints()).unwrap();
        assert_eq!(rec.extra_columns, vec!["roll_deg", "pitch_deg"]);
        assert_eq!(rec.rows[0].orientation, None);
    }

    #[test]
    fn torn_last_line_is_discarded_on_append() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.csv");
        std::fs::write(&path, "seq,t_s\n1,0\n2,0.5\n3,1.").unwrap();
        let (mut w, torn) = RecordingWriter::open_append(&path, &[], &[]).unwrap();
        assert!(torn);
        w.write_line("3,1.0").unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "seq,t_s\n1,0\n2,0.5\n3,1.0\n"
        );
    }
}

/// A compensation target: a position, or joint values whose nominal position is the target.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// World position (mm).
    Position(Vector3<f64>),
    /// Joint values (rad or mm).
    Joints(Vec<f64>),
}

/// Reads a poses CSV: one column per joint (`q1_deg…`), one pose per row, in row order.
pub fn read_poses(path: &Path, joints: &[JointSpec]) -> Result<Vec<Vec<f64>>, RecordingError> {
    read_targets(path, joints)?
        .into_iter()
        .map(|(line, t)| match t {
            Target::Joints(q) => Ok(q),
            Target::Position(_) => Err(RecordingError::Malformed {
                path: path.to_path_buf(),
                line,
                reason: "a poses file needs joint columns (q1_deg…), not x_mm,y_mm,z_mm".into(),
            }),
        })
        .collect()
}

/// Reads a targets CSV: columns `x_mm,y_mm,z_mm`, or one column per joint (`q1_deg…`). Returns
/// each target with its line number.
pub fn read_targets(
    path: &Path,
    joints: &[JointSpec],
) -> Result<Vec<(u64, Target)>, RecordingError> {
    let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let lines = LineIndex::of(&bytes);
    let mut reader = csv::ReaderBuilder::new().from_reader(bytes.as_slice());
    let headers: Vec<String> = reader
        .headers()
        .map_err(|e| malformed(path, &e, &lines))?
        .iter()
        .map(|h| h.trim().to_string())
        .collect();
    if let Some(column) = duplicated(&headers) {
        return Err(RecordingError::DuplicateColumn {
            path: path.to_path_buf(),
            column,
        });
    }
    let find = |n: &str| headers.iter().position(|h| h == n);
    let joint_cols: Vec<String> = joints
        .iter()
        .enumerate()
        .map(|(i, j)| j.kind.column(i + 1))
        .collect();
    let xyz = [find("x_mm"), find("y_mm"), find("z_mm")];
    let q: Vec<Option<usize>> = joint_cols.iter().map(|c| find(c)).collect();
    let by_position = xyz.iter().all(Option::is_some);
    if !by_position && q.iter().any(Option::is_none) {
        return Err(RecordingError::MissingColumn {
            path: path.to_path_buf(),
            column: "x_mm,y_mm,z_mm (or every joint column)".into(),
            joints: joint_cols.join(", "),
        });
    }
    let mut out = Vec::new();
    for result in reader.records() {
        let record = result.map_err(|e| malformed(path, &e, &lines))?;
        let line = lines.line_of(record.position());
        let row = RowReader {
            path,
            line,
            record: &record,
            headers: &headers,
        };
        let target = if by_position {
            let v: Vec<f64> = xyz
                .iter()
                .flatten()
                .map(|&c| row.required(c))
                .collect::<Result<_, _>>()?;
            Target::Position(Vector3::new(v[0], v[1], v[2]))
        } else {
            let mut values = Vec::new();
            for (spec, c) in joints.iter().zip(q.iter().flatten()) {
                let v = spec.kind.from_file_units(row.required(*c)?);
                if !spec.within(v) {
                    return Err(row.bad(*c, format!("outside joint {}'s limits", spec.name)));
                }
                values.push(v);
            }
            Target::Joints(values)
        };
        out.push((line, target));
    }
    Ok(out)
}

/// The first header name that appears more than once, if any.
fn duplicated(headers: &[String]) -> Option<String> {
    headers
        .iter()
        .enumerate()
        .find(|(k, h)| headers[..*k].contains(h))
        .map(|(_, h)| h.clone())
}

/// The text of a joint-commands CSV: a header of joint columns (`q1_deg…`) and one row per
/// command (rad or mm inside), in file units with six decimals. [`read_targets`] reads it back.
pub fn commands_csv<'a>(
    joints: &[JointSpec],
    commands: impl IntoIterator<Item = &'a [f64]>,
) -> String {
    let header: Vec<String> = joints
        .iter()
        .enumerate()
        .map(|(i, j)| j.kind.column(i + 1))
        .collect();
    let mut out = header.join(",");
    out.push('\n');
    for q in commands {
        let fields: Vec<String> = joints
            .iter()
            .zip(q)
            .map(|(j, v)| format!("{:.6}", j.kind.to_file_units(*v)))
            .collect();
        let _ = writeln!(out, "{}", fields.join(","));
    }
    out
}
