//! A joint of a robot: revolute or prismatic, its name and limits, and its units in files
//! (degrees or mm) and inside (rad or mm).

/// Revolute or prismatic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotates about its axis; values in radians inside, degrees in files.
    Revolute,
    /// Slides along its axis; values in millimetres.
    Prismatic,
}

impl JointKind {
    /// The recording column of joint `i` (1-based): `q{i}_deg` or `q{i}_mm`.
    pub fn column(self, i: usize) -> String {
        match self {
            JointKind::Revolute => format!("q{i}_deg"),
            JointKind::Prismatic => format!("q{i}_mm"),
        }
    }

    /// Internal value (rad or mm) to file units (deg or mm).
    pub fn to_file_units(self, v: f64) -> f64 {
        match self {
            JointKind::Revolute => v.to_degrees(),
            JointKind::Prismatic => v,
        }
    }

    /// File value (deg or mm) to internal units (rad or mm).
    pub fn from_file_units(self, v: f64) -> f64 {
        match self {
            JointKind::Revolute => v.to_radians(),
            JointKind::Prismatic => v,
        }
    }

    /// The unit in files: `deg` or `mm`.
    pub fn unit(self) -> &'static str {
        match self {
            JointKind::Revolute => "deg",
            JointKind::Prismatic => "mm",
        }
    }
}

/// A joint: its name, kind and limits (internal units).
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpec {
    /// Name from the rig file (`J1`, `lift`, …).
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Lower limit (rad or mm).
    pub min: f64,
    /// Upper limit (rad or mm).
    pub max: f64,
}

impl JointSpec {
    /// True when `v` lies within the limits (with a tolerance for rounding in files).
    pub fn within(&self, v: f64) -> bool {
        let tol = match self.kind {
            JointKind::Revolute => 1e-9,
            JointKind::Prismatic => 1e-7,
        };
        v >= self.min - tol && v <= self.max + tol
    }

    /// True when a joint *reading* `v` (what the arm reported, not a command) lies within the
    /// limits or at most [`READING_TOLERANCE_DEG`] / [`READING_TOLERANCE_MM`] past one. An arm
    /// commanded to its limit can report a hair beyond it (encoder counts, servo settling, the
    /// controller's rounding): a recording holding such a reading is the arm's truth, and
    /// refusing it would make the session's own recording unreadable. Anything further past
    /// is a unit, sign or column error and is still refused.
    pub fn within_reading(&self, v: f64) -> bool {
        let tol = match self.kind {
            JointKind::Revolute => READING_TOLERANCE_DEG.to_radians(),
            JointKind::Prismatic => READING_TOLERANCE_MM,
        };
        v >= self.min - tol && v <= self.max + tol
    }
}

/// How far past a revolute joint's limit a reading may lie (degrees): ten times the
/// Movemaster's 0.001° servo resolution, far below any unit or sign error.
pub const READING_TOLERANCE_DEG: f64 = 0.01;
/// How far past a prismatic joint's limit a reading may lie (mm).
pub const READING_TOLERANCE_MM: f64 = 0.01;
