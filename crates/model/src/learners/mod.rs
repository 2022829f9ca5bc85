//! Learners that generalise region-wise CEPs over the workspace (seed 000 section 5 and the
//! appendix): the FCMAC and, for the comparison the paper makes, Albus's plain CMAC.
//!
//! Both map a point of a three-dimensional division space to a vector of outputs (the CEPs).
//! Inputs are in the division space's internal units (rad, mm); outputs are trained in file
//! units scaled per output so a single tolerance applies (mm and degrees).

mod cmac;
mod fcmac;
mod positions;

pub use cmac::{Cmac, CmacConfig};
pub use fcmac::{Fcmac, FcmacConfig};
pub use positions::{PositionReport, PositionSample};

use crate::division::{DivisionSpace, RegionTree, Space};
use crate::identification::identifiability::stacked_jacobian;
use crate::identification::Observation;
use rigcal_core::kinematics::{ErrorModel, ErrorParams, Robot};
use serde::{Deserialize, Serialize};

/// A training pattern: an input point and the outputs wanted there.
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    /// Input (division-space coordinates).
    pub x: [f64; 3],
    /// Desired outputs.
    pub y: Vec<f64>,
}

/// How training went: whether the network reached the tolerance ε on every pattern (the
/// paper's "DIF within tolerance", appendix eq. (A5)), what it reached, and after how many
/// epochs. Stored in the model file with the network.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrainReport {
    /// Epochs run.
    pub epochs: usize,
    /// Largest |desired − produced| over patterns and outputs at the end (output units: mm
    /// for lengths, degrees for angles).
    pub max_error: f64,
    /// RMS of the same.
    pub rms_error: f64,
    /// Whether every output of every pattern is within the tolerance.
    pub converged: bool,
    /// The tolerance ε (output units); 0 in files written before it was recorded.
    #[serde(default)]
    pub tolerance: f64,
    /// The epoch cap.
    #[serde(default)]
    pub max_epochs: usize,
    /// Training stopped before the cap because the RMS error no longer fell: region-wise
    /// CEPs jump at region boundaries, and a smooth network cannot follow a jump to within ε.
    #[serde(default)]
    pub stalled: bool,
}

impl TrainReport {
    /// One line: reached or not, what it reached, after how many epochs.
    pub fn text(&self) -> String {
        let reached = format!(
            "pattern error max {:.4}, RMS {:.4} (mm or deg) after {} epochs",
            self.max_error, self.rms_error, self.epochs
        );
        if self.converged {
            format!("reached ε = {}: {reached}", self.tolerance)
        } else if self.stalled {
            format!(
                "did not reach ε = {}: {reached}, where the error stopped falling (the CEPs jump at region boundaries)",
                self.tolerance
            )
        } else {
            format!(
                "did not reach ε = {}: {reached}, the epoch cap",
                self.tolerance
            )
        }
    }
}

/// Relative fall of the RMS error over [`STALL_EPOCHS`] epochs below which training stops.
const STALL_FALL: f64 = 1e-3;
/// Epochs the stall test looks back.
const STALL_EPOCHS: usize = 5;

/// Follows a training run epoch by epoch and decides when it stops: the tolerance reached, the
/// error no longer falling, or the epoch cap.
pub(crate) struct Progress {
    tolerance: f64,
    max_epochs: usize,
    rms: Vec<f64>,
}

impl Progress {
    /// A run with tolerance ε and an epoch cap.
    pub(crate) fn new(tolerance: f64, max_epochs: usize) -> Self {
        Self {
            tolerance,
            max_epochs,
            rms: Vec::new(),
        }
    }

    /// Records an epoch's (max, RMS) error; returns the report and whether to stop.
    pub(crate) fn epoch(&mut self, max_error: f64, rms_error: f64) -> (TrainReport, bool) {
        self.rms.push(rms_error);
        let epochs = self.rms.len();
        let converged = max_error <= self.tolerance;
        let stalled = !converged
            && epochs > STALL_EPOCHS
            && self.rms[epochs - 1 - STALL_EPOCHS] - rms_error
                <= STALL_FALL * self.rms[epochs - 1 - STALL_EPOCHS];
        let report = TrainReport {
            epochs,
            max_error,
            rms_error,
            converged,
            tolerance: self.tolerance,
            max_epochs: self.max_epochs,
            stalled: stalled && epochs < self.max_epochs,
        };
        (report, converged || stalled || epochs >= self.max_epochs)
    }

    /// The report of a run with no epoch (no patterns, or a cap of zero).
    pub(crate) fn untrained(&self) -> TrainReport {
        TrainReport {
            epochs: 0,
            max_error: f64::NAN,
            rms_error: f64::NAN,
            converged: false,
            tolerance: self.tolerance,
            max_epochs: self.max_epochs,
            stalled: false,
        }
    }
}

/// A trained learner.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Learner {
    /// Fuzzy CMAC.
    Fcmac(Fcmac),
    /// Albus CMAC.
    Cmac(Cmac),
}

impl Learner {
    /// The outputs at `x`.
    pub fn predict(&self, x: &[f64; 3]) -> Vec<f64> {
        match self {
            Learner::Fcmac(f) => f.predict(x),
            Learner::Cmac(c) => c.predict(x),
        }
    }
}

/// Training patterns from a region tree: a lattice of `grid[d]` points per input dimension over
/// the whole workspace, each asking for the CEPs (scaled to file units) of the leaf it falls in
/// (its [`learner_cep`](crate::division::RegionNode::learner_cep) where the division set them);
/// points in a leaf whose CEPs were not identified from its own measurements (an unmeasurable
/// region, whatever it borrowed from its neighbours) are left out, so the learner must
/// generalise there. A lattice at half the sensor spacing reaches every association cell.
pub fn patterns_from_tree(tree: &RegionTree, scale: &[f64], grid: [usize; 3]) -> Vec<Pattern> {
    let mut out = Vec::new();
    let f = tree.full;
    let at =
        |d: usize, k: usize| f.lo[d] + (f.hi[d] - f.lo[d]) * k as f64 / (grid[d].max(2) - 1) as f64;
    for i in 0..grid[0] {
        for j in 0..grid[1] {
            for k in 0..grid[2] {
                let x = [at(0, i), at(1, j), at(2, k)];
                let leaf = tree.root.leaf_at(&x, &f);
                let cep = leaf.learner_cep.as_ref().or(leaf.cep.as_ref());
                let (Some(cep), true) = (cep, leaf.is_measured()) else {
                    continue;
                };
                out.push(Pattern {
                    x,
                    y: cep.iter().zip(scale).map(|(v, s)| v * s).collect(),
                });
            }
        }
    }
    out
}

/// A learner as an error model: CEPs at the division-space coordinates of a pose.
pub struct LearnedModel {
    learner: Learner,
    space: DivisionSpace,
    basis: Vec<usize>,
    scale: Vec<f64>,
    n_params: usize,
}

impl LearnedModel {
    /// Joins a trained learner with its space; `scale` converts internal units to the learner's
    /// output units (e.g. 180/π for angles, 1 for mm).
    pub fn new(
        learner: Learner,
        space: DivisionSpace,
        basis: Vec<usize>,
        scale: Vec<f64>,
        n_params: usize,
    ) -> Self {
        Self {
            learner,
            space,
            basis,
            scale,
            n_params,
        }
    }

    /// The CEPs (internal units, basis order) at a pose.
    pub fn cep_at(&self, q: &[f64]) -> Vec<f64> {
        let y = self.learner.predict(&self.space.coords(q));
        y.iter().zip(&self.scale).map(|(v, s)| v / s).collect()
    }
}

impl ErrorModel for LearnedModel {
    fn params_at(&self, q: &[f64]) -> ErrorParams {
        crate::division::tree_expand(&self.basis, self.n_params, &self.cep_at(q))
    }
}

/// Which learner generalises the region-wise CEPs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LearnerKind {
    /// None: compensation uses the CEPs of the region a target falls in.
    None,
    /// Albus's CMAC.
    Cmac,
    /// The fuzzy CMAC of seed 000 (default).
    Fcmac,
    /// Not a CEP learner: a neural network learns the direct kinematics' correction
    /// (seed 001); `rigcal calibrate` writes a neural model instead.
    #[serde(rename = "nn-direct")]
    NnDirect,
    /// Not a CEP learner: a neural network learns the inverse kinematics' correction.
    #[serde(rename = "nn-inverse")]
    NnInverse,
}

/// The learners' sizes, the paper's by default (seed 000, conventions §5): an FCMAC of 39
/// sensors (17 on the input of the first joint's coordinate, 11 on each other) with c = (3, 3,
/// 3), 2057 association cells; a CMAC at the same resolution with three layers.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LearnerSettings {
    /// FCMAC sensors per input (the CMAC's cells too) [default: 17 on the first joint's
    /// coordinate, 11 on the others: 17,11,11 for joint, 11,17,11 for Cartesian division].
    pub sensors: Option<[usize; 3]>,
    /// FCMAC sensors an input excites per dimension (the paper's c).
    pub c: [usize; 3],
    /// CMAC layers (its generalisation width, as c is the FCMAC's).
    pub cmac_layers: usize,
    /// What the FCMAC is trained to reproduce: the regions' CEPs (the paper's (A5)), or, after
    /// that, the measured points themselves (the same network made right where the instrument
    /// measured; see `learners::positions`).
    #[serde(default = "FcmacTraining::paper")]
    pub training: FcmacTraining,
    /// Where the FCMAC's association cells start before training (the paper does not say;
    /// rigcal's default is each cell at its region's CEPs).
    #[serde(default)]
    pub init: FcmacInit,
}

/// Where the FCMAC's weights start before (A5). Seed 000 does not state its initialisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FcmacInit {
    /// Each cell at the CEPs of the region at its centre, an unmeasurable region's borrowed
    /// ones included (rigcal's default): cells no pattern reaches answer with the regions.
    #[default]
    Ceps,
    /// Every cell at the conventional calibration's CEPs: cells no pattern reaches answer with
    /// the whole-workspace fit.
    Conventional,
    /// Every cell at zero (Albus's usual start): cells no pattern reaches answer with the
    /// nominal arm.
    Zero,
}

/// What the FCMAC's training reproduces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FcmacTraining {
    /// The regions' CEPs, pattern by pattern (seed 000's appendix, (A5)).
    Ceps,
    /// The CEPs, then the measured points: conjugate gradients on the position error, stopped
    /// where a held-out fifth of the measurements is predicted best (the default).
    Positions,
}

impl FcmacTraining {
    /// The paper's training, which settings written before the choice existed used.
    fn paper() -> Self {
        Self::Ceps
    }
}

impl Default for LearnerSettings {
    fn default() -> Self {
        Self {
            sensors: None,
            c: [3, 3, 3],
            cmac_layers: 3,
            training: FcmacTraining::Positions,
            init: FcmacInit::Ceps,
        }
    }
}

/// Learner settings that cannot make a network.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SettingsError {
    /// An input with fewer than two sensors has no spacing to place them by.
    #[error("FCMAC sensors {sensors:?}: every input needs at least 2")]
    TooFewSensors {
        /// The sensor counts.
        sensors: [usize; 3],
    },
    /// c outside 1..=sensors on some input.
    #[error("FCMAC c = {c:?} with sensors {sensors:?}: each c must be at least 1 and at most its input's sensors")]
    BadC {
        /// The excited counts.
        c: [usize; 3],
        /// The sensor counts.
        sensors: [usize; 3],
    },
    /// A CMAC needs at least one layer.
    #[error("CMAC layers {0}: at least 1")]
    NoLayers(usize),
}

impl LearnerSettings {
    /// Sensors per input for a division space: the settings' own, or the paper's
    /// ([`FcmacConfig::paper`]).
    pub fn sensors_for(&self, space: Space) -> [usize; 3] {
        self.sensors
            .unwrap_or_else(|| FcmacConfig::paper(first_joint_input(space)).cells)
    }

    /// The FCMAC these settings make for a division space.
    pub fn fcmac_config(&self, space: Space) -> FcmacConfig {
        FcmacConfig {
            cells: self.sensors_for(space),
            c: self.c,
            ..FcmacConfig::paper(first_joint_input(space))
        }
    }

    /// The CMAC these settings make for a division space.
    pub fn cmac_config(&self, space: Space) -> CmacConfig {
        CmacConfig {
            layers: self.cmac_layers,
            ..CmacConfig::matching(self.sensors_for(space))
        }
    }

    /// Checks that the settings make a network.
    pub fn check(&self) -> Result<(), SettingsError> {
        let sensors = self.sensors_for(Space::Joint);
        if sensors.iter().any(|&n| n < 2) {
            return Err(SettingsError::TooFewSensors { sensors });
        }
        if self.c.iter().zip(&sensors).any(|(&c, &n)| c == 0 || c > n) {
            return Err(SettingsError::BadC { c: self.c, sensors });
        }
        if self.cmac_layers == 0 {
            return Err(SettingsError::NoLayers(self.cmac_layers));
        }
        Ok(())
    }
}

/// The input that carries the first joint's coordinate: q1 in joint space, the azimuth (which
/// equals q1) in Cartesian space.
fn first_joint_input(space: Space) -> usize {
    match space {
        Space::Joint => 0,
        Space::Cartesian => 1,
    }
}

/// The measurements a division used, for an FCMAC trained on positions
/// ([`FcmacTraining::Positions`]).
pub struct Measured<'a> {
    /// The robot, nominal kinematics plus the error parameters of its layout.
    pub robot: &'a dyn Robot,
    /// The division space (the learner's input).
    pub space: &'a DivisionSpace,
    /// Layout indices of the CEPs.
    pub basis: &'a [usize],
    /// The conventional calibration's parameters (the linearisation point).
    pub conventional: &'a ErrorParams,
    /// The measurements.
    pub observations: &'a [Observation],
}

impl Measured<'_> {
    /// Samples for an FCMAC whose outputs are CEPs scaled by `scale`: each measurement's input,
    /// derivative at the conventional parameters (mm per output unit) and residual at the
    /// network's current outputs.
    pub fn samples(&self, net: &Fcmac, scale: &[f64]) -> Vec<PositionSample> {
        let n = self.robot.layout().len();
        let poses: Vec<Vec<f64>> = self.observations.iter().map(|o| o.q.clone()).collect();
        let m = stacked_jacobian(self.robot, self.conventional, &poses, self.basis);
        self.observations
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let x = self.space.coords(&o.q);
                let cep: Vec<f64> = net
                    .predict(&x)
                    .iter()
                    .zip(scale)
                    .map(|(v, s)| v / s)
                    .collect();
                let e = crate::division::tree_expand(self.basis, n, &cep);
                let p = self.robot.position(&o.q, &e);
                let d = o.p - p;
                PositionSample {
                    x,
                    jacobian: [0, 1, 2].map(|r| {
                        (0..scale.len())
                            .map(|k| m[(3 * i + r, k)] / scale[k])
                            .collect()
                    }),
                    residual: [d.x, d.y, d.z],
                }
            })
            .collect()
    }
}

/// Trains a learner of `kind` with `settings` on the leaves of `tree`; weights start at `init`
/// (conventional CEPs, internal units; an FCMAC starts as `settings.init` says); `scale`
/// converts CEPs to output units. An FCMAC set to train on positions does so on `measured`
/// after its CEP training (without it, CEPs only).
pub fn train(
    kind: LearnerKind,
    settings: &LearnerSettings,
    tree: &RegionTree,
    init: &[f64],
    scale: &[f64],
    measured: Option<&Measured<'_>>,
) -> Option<Learner> {
    let init_scaled: Vec<f64> = init.iter().zip(scale).map(|(v, s)| v * s).collect();
    match kind {
        LearnerKind::None | LearnerKind::NnDirect | LearnerKind::NnInverse => None,
        LearnerKind::Fcmac => {
            let config = settings.fcmac_config(tree.space);
            let patterns = patterns_from_tree(tree, scale, config.cells.map(|n| 2 * n - 1));
            // Each cell starts at the CEPs of the region at its centre (an unmeasurable region's
            // borrowed ones included), so cells no pattern reaches answer with the region-wise
            // model rather than the whole workspace's.
            let start = |x: &[f64; 3]| -> Vec<f64> {
                match &tree.root.lookup(x, &tree.full).and_then(|n| n.cep.as_ref()) {
                    Some(cep) => cep.iter().zip(scale).map(|(v, s)| v * s).collect(),
                    None => init_scaled.clone(),
                }
            };
            let mut f = match settings.init {
                FcmacInit::Ceps => Fcmac::starting_at(config, tree.full, &init_scaled, start),
                FcmacInit::Conventional => Fcmac::new(config, tree.full, &init_scaled),
                FcmacInit::Zero => Fcmac::new(config, tree.full, &vec![0.0; init_scaled.len()]),
            };
            f.train(&patterns);
            if let (FcmacTraining::Positions, Some(m)) = (settings.training, measured) {
                let samples = m.samples(&f, scale);
                f.train_on_positions(&samples);
            }
            Some(Learner::Fcmac(f))
        }
        LearnerKind::Cmac => {
            let config = settings.cmac_config(tree.space);
            let patterns = patterns_from_tree(tree, scale, config.cells.map(|n| 2 * n + 1));
            let mut c = Cmac::new(config, tree.full, &init_scaled);
            c.train(&patterns);
            Some(Learner::Cmac(c))
        }
    }
}
