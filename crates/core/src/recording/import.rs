//! Import of a foreign CSV (laser tracker, motion capture) as a recording of
//! spec/recordings.md: the caller names the joint, point and time columns and their units; the
//! result holds internal units (rad or mm, mm), joints in the rig's order, `seq` from row order,
//! and keeps every other column as an extra column.
//!
//! Every bad cell is an error with the file, line and column named: nothing is dropped.

use super::{Measurement, Recording, SessionInfo, Status};
use crate::kinematics::{JointKind, JointSpec, Robot};
use crate::rig::Rig;
use nalgebra::Vector3;
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

/// Angle unit of an imported file (revolute joints).
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

/// Which columns of the file hold what, and in which units.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ImportSpec {
    /// Joint columns, in the rig's joint order.
    pub joints: Vec<String>,
    /// The measured point's x, y and z columns.
    pub point: [String; 3],
    /// Time column (seconds). Without it `t_s` is left empty.
    pub time: Option<String>,
    /// Unit of lengths.
    pub length_unit: LengthUnit,
    /// Unit of revolute joint angles.
    pub angle_unit: AngleUnit,
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
    /// The header row could not be read.
    #[error("{}: line 1", path.display())]
    Header {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: csv::Error,
    },
    /// A named column is not in the header.
    #[error("{}: line 1: no column `{column}` (columns are {})", path.display(), columns.join(", "))]
    NoColumn {
        /// The file.
        path: PathBuf,
        /// The column asked for.
        column: String,
        /// The file's columns.
        columns: Vec<String>,
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
    #[error("{at}: `{text}` is not a number")]
    NotANumber {
        /// The cell.
        at: Box<CellAt>,
        /// The cell's text.
        text: String,
    },
    /// A joint value lies outside the rig's limits.
    #[error(
        "{at}: {} {unit} is outside joint {joint}'s limits {:.3}..{:.3} {unit}",
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
    /// Every other column, kept as an extra column.
    extra: Vec<usize>,
}

/// Imports the CSV at `path` (one header row) for a rig. The session sidecar names the rig's
/// file and says how the file was read (units, whether time effects can be considered).
pub fn import_csv(path: &Path, rig: &Rig, spec: &ImportSpec) -> Result<Recording, ImportError> {
    let specs = rig.chain.joints();
    if spec.joints.len() != specs.len() {
        return Err(ImportError::JointCount {
            given: spec.joints.len(),
            rig: rig.name.clone(),
            joints: specs.iter().map(|j| j.name.clone()).collect(),
        });
    }
    let file = std::fs::File::open(path).map_err(|source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut reader = csv::ReaderBuilder::new().from_reader(file);
    let headers: Vec<String> = reader
        .headers()
        .map_err(|source| ImportError::Header {
            path: path.to_path_buf(),
            source,
        })?
        .iter()
        .map(|h| h.trim().to_string())
        .collect();
    let cols = column_map(path, &headers, spec)?;
    let mut rec = Recording::new(specs);
    rec.extra_columns = cols.extra.iter().map(|&c| headers[c].clone()).collect();
    for (row, result) in reader.records().enumerate() {
        let record = result.map_err(|source| ImportError::Row {
            path: path.to_path_buf(),
            row: row as u64 + 2,
            source,
        })?;
        let cells = Cells {
            path,
            headers: &headers,
            line: record
                .position()
                .map(|p| p.line())
                .unwrap_or(row as u64 + 2),
            record: &record,
        };
        rec.rows
            .push(cells.measurement(row as u64 + 1, &cols, specs, spec)?);
    }
    rec.session = Some(session_info(path, rig, spec));
    Ok(rec)
}

/// Finds the spec's columns in the header; the rest are extra columns.
fn column_map(
    path: &Path,
    headers: &[String],
    spec: &ImportSpec,
) -> Result<ColumnMap, ImportError> {
    let find = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| ImportError::NoColumn {
                path: path.to_path_buf(),
                column: name.to_string(),
                columns: headers.to_vec(),
            })
    };
    let joints = spec
        .joints
        .iter()
        .map(|c| find(c))
        .collect::<Result<Vec<_>, _>>()?;
    let point = [
        find(&spec.point[0])?,
        find(&spec.point[1])?,
        find(&spec.point[2])?,
    ];
    let time = spec.time.as_deref().map(find).transpose()?;
    let used: Vec<usize> = joints
        .iter()
        .chain(&point)
        .chain(time.iter())
        .copied()
        .collect();
    let extra = (0..headers.len()).filter(|c| !used.contains(c)).collect();
    Ok(ColumnMap {
        joints,
        point,
        time,
        extra,
    })
}

/// One data row of the file, with what its errors must name.
struct Cells<'a> {
    path: &'a Path,
    headers: &'a [String],
    line: u64,
    record: &'a csv::StringRecord,
}

impl Cells<'_> {
    /// The row as a measurement in internal units.
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
        let p = Vector3::new(
            self.number(cols.point[0])? * mm,
            self.number(cols.point[1])? * mm,
            self.number(cols.point[2])? * mm,
        );
        Ok(Measurement {
            seq,
            t_s: cols.time.map(|c| self.number(c)).transpose()?,
            q,
            position: Some(p),
            status: Status::Ok,
            extra: cols
                .extra
                .iter()
                .map(|&c| self.record.get(c).unwrap_or("").to_string())
                .collect(),
            ..Default::default()
        })
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
        let t = self.record.get(c).unwrap_or("").trim();
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(ImportError::NotANumber {
                at: self.at(c),
                text: t.to_string(),
            }),
        }
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
        Err(ImportError::OutsideLimits {
            at: self.at(c),
            joint: joint.name.clone(),
            value: joint.kind.to_file_units(v),
            limits: [
                joint.kind.to_file_units(joint.min),
                joint.kind.to_file_units(joint.max),
            ],
            unit: joint.kind.unit(),
        })
    }
}

/// The sidecar of an imported recording: its rig file and how the file was read.
fn session_info(path: &Path, rig: &Rig, spec: &ImportSpec) -> SessionInfo {
    SessionInfo {
        rig: rig.source.path.as_ref().map(|p| p.display().to_string()),
        notes: Some(format!(
            "imported from {} ({}, {}){}",
            path.display(),
            spec.length_unit.name(),
            spec.angle_unit.name(),
            if spec.time.is_none() {
                "; no time column: time-dependent effects are not considered"
            } else {
                ""
            }
        )),
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
