//! Error parameters: one vector indexed by (transform, kind), shared by identification, division,
//! learners and compensation.
//!
//! Units inside: millimetres for lengths, radians for angles. Names in files: `theta1`, `d1`,
//! `a0`, `alpha2`, `beta2`, `frame.x`, `frame.rz`, `marker.y`; transform 0 is the base
//! (World-J1), transform i the link of joint i, transform N+1 the tool (seed 000 numbering:
//! Δθ0 … Δa3).

use nalgebra::DVector;
use serde::{Deserialize, Serialize};
use std::fmt;

/// Which transform of the chain a parameter belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum TransformId {
    /// The measurement frame F (instrument relative to world).
    Frame,
    /// The base transform (World-J1), numbered 0.
    Base,
    /// The link transform of joint i (1-based), numbered i.
    Link(usize),
    /// The tool transform (Flange-Tool), numbered N+1.
    Tool,
    /// The marker point on the last link.
    Marker,
}

/// The kind of an error parameter: the elementary motion it perturbs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ParamKind {
    /// Rotation about local z (five-parameter θ).
    Theta,
    /// Translation along local z (five-parameter d).
    D,
    /// Translation along local x (five-parameter a).
    A,
    /// Rotation about local x (five-parameter α).
    Alpha,
    /// Rotation about local y (five-parameter β).
    Beta,
    /// Translation along x of a pose transform.
    X,
    /// Translation along y of a pose transform.
    Y,
    /// Translation along z of a pose transform.
    Z,
    /// Rotation about x of a pose transform.
    Rx,
    /// Rotation about y of a pose transform.
    Ry,
    /// Rotation about z of a pose transform.
    Rz,
}

impl ParamKind {
    /// True for angles (radians inside, degrees in files).
    pub fn is_angle(self) -> bool {
        matches!(
            self,
            ParamKind::Theta
                | ParamKind::Alpha
                | ParamKind::Beta
                | ParamKind::Rx
                | ParamKind::Ry
                | ParamKind::Rz
        )
    }

    fn file_name(self) -> &'static str {
        match self {
            ParamKind::Theta => "theta",
            ParamKind::D => "d",
            ParamKind::A => "a",
            ParamKind::Alpha => "alpha",
            ParamKind::Beta => "beta",
            ParamKind::X => "x",
            ParamKind::Y => "y",
            ParamKind::Z => "z",
            ParamKind::Rx => "rx",
            ParamKind::Ry => "ry",
            ParamKind::Rz => "rz",
        }
    }

    fn symbol(self) -> &'static str {
        match self {
            ParamKind::Theta => "Δθ",
            ParamKind::D => "Δd",
            ParamKind::A => "Δa",
            ParamKind::Alpha => "Δα",
            ParamKind::Beta => "Δβ",
            ParamKind::X => "Δx",
            ParamKind::Y => "Δy",
            ParamKind::Z => "Δz",
            ParamKind::Rx => "Δrx",
            ParamKind::Ry => "Δry",
            ParamKind::Rz => "Δrz",
        }
    }

    /// The unit used in files and on screen.
    pub fn unit(self) -> &'static str {
        if self.is_angle() {
            "deg"
        } else {
            "mm"
        }
    }

    /// Converts an internal value (rad or mm) to the file unit (deg or mm).
    pub fn to_file_units(self, v: f64) -> f64 {
        if self.is_angle() {
            v.to_degrees()
        } else {
            v
        }
    }

    /// Converts a file value (deg or mm) to internal units (rad or mm).
    pub fn from_file_units(self, v: f64) -> f64 {
        if self.is_angle() {
            v.to_radians()
        } else {
            v
        }
    }
}

/// One error parameter: a transform and a kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct ParamId {
    /// The transform it belongs to.
    pub transform: TransformId,
    /// The elementary motion it perturbs.
    pub kind: ParamKind,
}

/// The ordered list of a chain's error parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamLayout {
    ids: Vec<ParamId>,
    n_joints: usize,
}

impl ParamLayout {
    /// A layout from its parameters, for a chain of `n_joints` joints.
    pub fn new(ids: Vec<ParamId>, n_joints: usize) -> Self {
        Self { ids, n_joints }
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True when the layout holds no parameter.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The parameters in order.
    pub fn ids(&self) -> &[ParamId] {
        &self.ids
    }

    /// Position of a parameter in the layout.
    pub fn index_of(&self, id: ParamId) -> Option<usize> {
        self.ids.iter().position(|&p| p == id)
    }

    /// The file name of a parameter (`theta0`, `d1`, `frame.x`, `marker.z`; the tool is N+1).
    pub fn name(&self, id: ParamId) -> String {
        let kind = id.kind.file_name();
        match id.transform {
            TransformId::Frame => format!("frame.{kind}"),
            TransformId::Marker => format!("marker.{kind}"),
            TransformId::Base => format!("{kind}0"),
            TransformId::Link(i) => format!("{kind}{i}"),
            TransformId::Tool => format!("{kind}{}", self.n_joints + 1),
        }
    }

    /// The display name of a parameter (`Δθ0`, `Δd1`, `Δx(frame)`).
    pub fn symbol(&self, id: ParamId) -> String {
        let s = id.kind.symbol();
        match id.transform {
            TransformId::Frame => format!("{s}(frame)"),
            TransformId::Marker => format!("{s}(marker)"),
            TransformId::Base => format!("{s}0"),
            TransformId::Link(i) => format!("{s}{i}"),
            TransformId::Tool => format!("{s}{}", self.n_joints + 1),
        }
    }

    /// Looks a parameter up by its file name.
    pub fn find(&self, name: &str) -> Option<ParamId> {
        self.ids.iter().copied().find(|&id| self.name(id) == name)
    }
}

/// Values of every error parameter of a layout (internal units).
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorParams {
    values: DVector<f64>,
}

impl ErrorParams {
    /// All zero: the nominal robot.
    pub fn zeros(layout: &ParamLayout) -> Self {
        Self {
            values: DVector::zeros(layout.len()),
        }
    }

    /// From a vector in layout order.
    pub fn from_vector(values: DVector<f64>) -> Self {
        Self { values }
    }

    /// Mutable values in layout order.
    pub fn as_vector_mut(&mut self) -> &mut DVector<f64> {
        &mut self.values
    }

    /// The value at a layout index.
    pub fn get(&self, i: usize) -> f64 {
        self.values[i]
    }

    /// Sets the value at a layout index.
    pub fn set(&mut self, i: usize, v: f64) {
        self.values[i] = v;
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// True when there are no parameters.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }
}

impl fmt::Display for ParamKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.file_name())
    }
}

/// Error parameters as a function of the pose: constant for conventional calibration, per region
/// for the variable D-H model, smooth for a learner. Compensation and evaluation ask it for the
/// parameters at the joint values they are considering.
pub trait ErrorModel: Send + Sync {
    /// The error parameters that hold at joint values `q` (internal units).
    fn params_at(&self, q: &[f64]) -> ErrorParams;
}

impl ErrorModel for ErrorParams {
    fn params_at(&self, _q: &[f64]) -> ErrorParams {
        self.clone()
    }
}
