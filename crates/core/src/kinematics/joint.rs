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
}
