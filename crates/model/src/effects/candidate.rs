//! The diagnosis candidate interface: an effect as the diagnosis tests it, a small linear model
//! whose regressor columns span what the effect can do to the measured points, with the
//! recording's data it is built from ([`Data`]).
//!
//! Conventions: 3 rows per measurement (x, y, z, world, mm); joint values in radians (mm for
//! prismatic joints); time in seconds.

use super::kind::EffectKind;
use crate::identification::Observation;
use nalgebra::{DMatrix, Vector3};
use rigcal_core::kinematics::{ErrorParams, SerialChain};

/// What a candidate's index refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Index {
    /// A joint (0-based inside, 1-based in reports).
    Joint(usize),
    /// A world/table axis (0 x, 1 y, 2 z).
    Axis(usize),
    /// A pair of table axes.
    Axes(usize, usize),
}

/// Axis names.
pub const AXES: [&str; 3] = ["x", "y", "z"];

impl Index {
    /// "joint 2", "axis z", "axes x–y".
    pub fn label(&self) -> String {
        match *self {
            Index::Joint(j) => format!("joint {}", j + 1),
            Index::Axis(a) => format!("axis {}", AXES[a]),
            Index::Axes(a, b) => format!("axes {}–{}", AXES[a], AXES[b]),
        }
    }
}

/// One named parameter of a fitted effect: value and standard deviation in report units.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    /// Name with unit, e.g. `lost_motion_deg`.
    pub name: String,
    /// Value.
    pub value: f64,
    /// Standard deviation (NaN when not available).
    pub sigma: f64,
}

/// A piece of left-out physics the diagnosis can name: a small linear model whose regressor
/// columns (3 rows per measurement, mm per unit coefficient) span what it can do to the
/// measured points.
pub trait Candidate: Send + Sync + std::fmt::Debug {
    /// The kind it names.
    fn kind(&self) -> EffectKind;
    /// Which joint or axis.
    fn index(&self) -> Index;
    /// Harmonic order, for kinds that have one.
    fn order(&self) -> Option<u32> {
        None
    }
    /// A short label: "backlash on joint 2".
    fn label(&self) -> String {
        match self.order() {
            Some(n) => format!("{} (order {n}) on {}", self.kind(), self.index().label()),
            None => format!("{} on {}", self.kind(), self.index().label()),
        }
    }
    /// The regressor columns over the recording's measurements, or None when the recording
    /// cannot show this effect (no time, no table columns, a joint that never moves).
    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>>;
    /// A plain-language explanation.
    fn explanation(&self) -> String;
    /// Named parameters from the fitted coefficients and their covariance.
    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, d: &Data) -> Vec<Param>;
}

/// Everything a candidate may use: the recording's measurements and the fitted geometry.
#[derive(Debug, Clone)]
pub struct Data {
    /// The chain (with the fitted frame when the frame is free).
    pub chain: SerialChain,
    /// The fitted geometric error parameters.
    pub e: ErrorParams,
    /// Measurements (joint values, measured point).
    pub obs: Vec<Observation>,
    /// Time (s) of each measurement, when the recording has it for every measured row.
    pub t_s: Option<Vec<f64>>,
    /// Approach direction (−1, 0, +1) of each joint at each measurement.
    pub direction: Vec<Vec<i8>>,
    /// Table-frame coordinates of each measurement, when every measured row has them.
    pub table: Option<Vec<Vector3<f64>>>,
    /// Region of each measurement.
    pub region: Vec<Option<String>>,
    /// Joint Jacobian (3 × N, mm per rad) at each measurement.
    pub joint_jacobian: Vec<DMatrix<f64>>,
    /// Joints that move in the recording (0-based).
    pub moving: Vec<usize>,
    /// `seq` of each measurement.
    pub seq: Vec<u64>,
    /// CSV line of each measurement (1-based), when the recording was read from a file.
    pub line: Vec<Option<u64>>,
}

impl Data {
    /// Measurements.
    pub fn len(&self) -> usize {
        self.obs.len()
    }

    /// True without measurements.
    pub fn is_empty(&self) -> bool {
        self.obs.is_empty()
    }

    /// Columns `scale(i) · joint column j` stacked over measurements.
    pub fn joint_column(&self, j: usize, scale: impl Fn(usize) -> f64) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(3 * self.len(), 1);
        for i in 0..self.len() {
            let s = scale(i);
            for r in 0..3 {
                m[(3 * i + r, 0)] = s * self.joint_jacobian[i][(r, j)];
            }
        }
        m
    }

    /// Columns `scale(i) · unit vector of axis a` stacked over measurements.
    pub fn axis_column(&self, a: usize, scale: impl Fn(usize) -> f64) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(3 * self.len(), 1);
        for i in 0..self.len() {
            m[(3 * i + a, 0)] = scale(i);
        }
        m
    }
}
