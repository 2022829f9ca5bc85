//! Identification from pose measurements: the position *and* the orientation of the marker's
//! frame, as a 6-DoF probe (a laser tracker's T-Mac, a motion-capture rigid body) gives them.
//! Seed 000 fits positions only; this is the same least squares with three more rows per
//! measurement and three more unknowns.
//!
//! **Rows.** Per measurement 3 position rows, p_measured − p_modelled (mm), and, when the row has
//! an orientation, 3 orientation rows: r = log(R_modelledᵀ·R_measured), the rotation vector
//! (rad) that turns the modelled marker frame onto the measured one, about the modelled frame's
//! own axes — "measured relative to modelled", the sign of the position rows. Reports give a
//! row's orientation residual as the rotation vector of R_measuredᵀ·R_modelled (= −r) and its
//! length, the angle between the two frames, in degrees.
//!
//! **Weights.** Every row is divided by its σ, so the cost is Σ (residual/σ)². A block's σ
//! (position, orientation) is the one each row states (`sigma_x_mm…`, `sigma_rx_deg…`) when
//! every row of the block states one, else one σ for the whole block estimated from the
//! residuals of a first fit: the first fit uses the position rows alone (orientation then
//! only gives the marker rotation, in closed form), each later fit the σ of every block from
//! the last fit's residuals, σ̂² = RSS_block / (rows_block · (1 − unknowns/rows)), until the
//! ratio of the σ changes by under 1 % (a few rounds). [`Weighting`] says which was used.
//!
//! **Unknowns.** The layout parameters a [`Level`] fits that the poses determine (measurement
//! frame, marker point, kinematic parameters) and, when orientations are fitted, the marker
//! frame's rotation C relative to the tool frame: R_modelled = R_tool(q, e)·C. The marker frame
//! is then a full pose (its point from the layout's `marker.x/y/z`, its rotation C), the
//! measurement frame already is one. C is not a layout parameter (a rig file has no nominal for
//! it): it starts from the closed-form rotation nearest Σ R_toolᵀ·R_measured and is corrected
//! multiplicatively, C ← C·exp([φ]×) with φ about the marker's own axes, re-centred after
//! every step. It is fitted whether the rig's marker point is free or fixed.
//!
//! **Jacobian** (analytic). A layout parameter with angular column ω (measurement frame,
//! [`SerialChain::pose_and_param_jacobian`]) turns the modelled frame by b = R_modelledᵀ·ω
//! about its own axes, φ by its unit vectors. The residual then changes by −J_l⁻¹(r)·b, with
//! J_l⁻¹ the inverse left Jacobian of SO(3), so the modelled column is J_l⁻¹(r)·b: exact to first
//! order at any residual, not only near r = 0 (a test checks it against central differences).
//!
//! **Identifiability.** The basis is chosen as for positions ([`super::analyse_determined`]), on
//! the weighted stacked Jacobian (6 rows per measurement with an orientation) at the start,
//! columns in the order measurement frame, marker point, marker rotation, then the level's
//! kinematic candidates: orientation separates parameters positions cannot (a rotation of the
//! last link about the marker point, say) and makes the tool transform's rotation a
//! combination of the marker's pose.
//!
//! **Fit.** Levenberg–Marquardt with column scaling as [`super::fit`](mod@super::fit); the
//! covariance is σ̂²(JᵀJ)⁻¹ on the weighted rows, σ̂² = weighted RSS / (rows − unknowns) (≈ 1
//! when the σ are right).
//!
//! Units: mm and rad inside; mm and degrees in every report.

use super::dense::{gram, transpose_times};
use super::geometric::{absolute_frame, IdentifyError, Level};
use super::identifiability::{determined_factor, kappa_eq4, triangular_factor, Identifiability};
use super::{FitError, FitResult, HeldOutReport, ResidualStats};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, UnitQuaternion, Vector3};
use rigcal_core::kinematics::{
    ErrorParams, ParamId, ParamKind, ParamLayout, Robot, SerialChain, TransformId,
};
use rigcal_core::recording::{Observation, Recording};
use rigcal_core::rig::{FrameMode, Rig};
use std::fmt::Write;

/// A measured row: joints, the measured point and, when the instrument gives them, the
/// orientation of the marker's frame and the stated standard deviations (internal units).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseObservation {
    /// Joint values (rad or mm).
    pub q: Vec<f64>,
    /// Measured point (mm), measurement frame.
    pub p: Vector3<f64>,
    /// Measured orientation of the marker's frame in the measurement frame.
    pub orientation: Option<UnitQuaternion<f64>>,
    /// Stated σ of the point's x, y, z (mm).
    pub position_sigma: Option<Vector3<f64>>,
    /// Stated σ of a small rotation of the measured frame about its own x, y, z (rad).
    pub orientation_sigma: Option<Vector3<f64>>,
}

impl PoseObservation {
    /// The joints and point alone, as position identification reads them.
    pub fn position_only(&self) -> Observation {
        Observation {
            q: self.q.clone(),
            p: self.p,
        }
    }
}

/// The measured rows of a recording as pose observations, in the order of
/// [`Recording::observations`] (so outlier indices carry over).
pub fn pose_observations(rec: &Recording) -> Vec<PoseObservation> {
    rec.measured()
        .map(|(m, p)| PoseObservation {
            q: m.q.clone(),
            p,
            orientation: m.orientation,
            position_sigma: m.position_sigma,
            orientation_sigma: m.orientation_sigma,
        })
        .collect()
}

/// True when at least one measured row of the recording has an orientation.
pub fn has_orientation(rec: &Recording) -> bool {
    rec.measured().any(|(m, _)| m.orientation.is_some())
}

/// Orientation error statistics over rows (degrees): the angle between measured and modelled
/// marker frames.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct OrientationStats {
    /// Rows with an orientation.
    pub n: usize,
    /// Mean angle.
    pub mean_deg: f64,
    /// Root mean square angle.
    pub rms_deg: f64,
    /// Largest angle.
    pub max_deg: f64,
}

impl OrientationStats {
    /// Statistics of angles given in radians.
    pub fn of_angles(angles_rad: &[f64]) -> Self {
        let n = angles_rad.len();
        if n == 0 {
            return Self::default();
        }
        let nf = n as f64;
        let deg: Vec<f64> = angles_rad.iter().map(|a| a.to_degrees()).collect();
        Self {
            n,
            mean_deg: deg.iter().sum::<f64>() / nf,
            rms_deg: (deg.iter().map(|d| d * d).sum::<f64>() / nf).sqrt(),
            max_deg: deg.iter().copied().fold(0.0, f64::max),
        }
    }

    /// Statistics of rotation vectors (rad): their lengths.
    pub fn of_vectors(v: &[Vector3<f64>]) -> Self {
        Self::of_angles(&v.iter().map(|r| r.norm()).collect::<Vec<_>>())
    }
}

/// Where a block's σ came from.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum BlockSigma {
    /// Each row's own stated σ.
    Stated,
    /// One σ for the block, estimated from the residuals of a first fit (mm or rad).
    Estimated(f64),
}

/// How the rows were weighted.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Weighting {
    /// Position rows.
    pub position: BlockSigma,
    /// Orientation rows; `None` when no orientation was fitted.
    pub orientation: Option<BlockSigma>,
    /// Rounds of σ estimation (0 when every block's σ was stated).
    pub rounds: usize,
}

impl Weighting {
    /// One line a person reads: which σ weighted which rows.
    pub fn text(&self) -> String {
        let block = |b: BlockSigma, unit: &str, scale: f64| match b {
            BlockSigma::Stated => "each row's stated σ".to_string(),
            BlockSigma::Estimated(s) => format!(
                "one σ = {:.4} {unit} estimated from the residuals of a first fit",
                s * scale
            ),
        };
        let mut s = format!("position rows: {}", block(self.position, "mm", 1.0));
        match self.orientation {
            Some(o) => {
                let _ = write!(
                    s,
                    "; orientation rows: {}",
                    block(o, "°", 1.0_f64.to_degrees())
                );
            }
            None => s.push_str("; no orientation rows"),
        }
        if self.rounds > 1 {
            let _ = write!(s, " ({} rounds)", self.rounds);
        }
        s
    }
}

/// Which σ to weight with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WeightChoice {
    /// The rows' stated σ where every row of a block states a usable one (1e-9 to 1e6 mm or
    /// rad), else one σ per block estimated from the residuals.
    #[default]
    StatedWhereGiven,
    /// One σ per block estimated from the residuals, ignoring stated ones.
    Estimated,
}

/// Settings of a pose fit.
#[derive(Debug, Clone)]
pub struct PoseOptions {
    /// Fit the orientation rows (and the marker rotation); `false` fits positions alone and
    /// gives the marker rotation in closed form, for comparison.
    pub use_orientation: bool,
    /// Which σ weight the rows.
    pub weights: WeightChoice,
    /// Iteration cap of each Levenberg–Marquardt run.
    pub max_iterations: usize,
}

impl Default for PoseOptions {
    fn default() -> Self {
        Self {
            use_orientation: true,
            weights: WeightChoice::default(),
            max_iterations: 100,
        }
    }
}

/// The outcome of a pose fit.
#[derive(Debug, Clone)]
pub struct PoseFit {
    /// The layout parameters: fitted ones (`free`) with σ and covariance; `after` and
    /// `residuals` are the position residuals (mm), `sigma0_mm` their σ̂ per coordinate.
    pub fit: FitResult,
    /// The marker frame's rotation relative to the tool frame (C, R_modelled = R_tool·C).
    pub marker_rotation: UnitQuaternion<f64>,
    /// σ of C about the marker's own x, y, z (rad); zero when the rotation was not fitted
    /// (closed form on positions-only fits).
    pub marker_rotation_sigma: Vector3<f64>,
    /// Orientation residuals before the fit (start values, C in closed form).
    pub orientation_before: OrientationStats,
    /// Orientation residuals after the fit.
    pub orientation: OrientationStats,
    /// Per measurement, the rotation vector of R_measuredᵀ·R_modelled (rad) when it has an
    /// orientation.
    pub orientation_residuals: Vec<Option<Vector3<f64>>>,
    /// How the rows were weighted.
    pub weighting: Weighting,
    /// σ̂ of the weighted rows (≈ 1 when the σ are right).
    pub variance_factor: f64,
    /// The analysis the basis came from (layout indices ≥ the layout's length are the marker
    /// rotation about x, y, z).
    pub identifiability: Identifiability,
}

/// A pose fit's figures on a held-out recording (frames as the model's, nothing refitted).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseHeldOut {
    /// The held-out recording's name.
    pub name: String,
    /// Position errors (mm): nominal kinematics through the fitted frame and marker, and the
    /// fitted model.
    pub position: HeldOutReport,
    /// Orientation errors of the fitted model with its marker rotation (degrees).
    pub orientation: Option<OrientationStats>,
}

/// The rotation nearest a matrix (Frobenius): U·diag(1, 1, det(U·Vᵀ))·Vᵀ of its SVD; the
/// identity when the SVD fails (a matrix that is not finite).
pub fn nearest_rotation(a: &Matrix3<f64>) -> UnitQuaternion<f64> {
    if a.iter().any(|v| !v.is_finite()) {
        return UnitQuaternion::identity();
    }
    let Some(svd) = a.try_svd(true, true, super::dense::SVD_EPSILON, 10_000) else {
        return UnitQuaternion::identity();
    };
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return UnitQuaternion::identity();
    };
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r))
}

/// The marker rotation C nearest the data for a chain at `e`: the rotation nearest
/// Σ R_toolᵀ·R_measured (exact least squares of ‖R_tool·C − R_measured‖_F over the rows).
pub fn closed_form_marker_rotation(
    chain: &SerialChain,
    e: &ErrorParams,
    obs: &[PoseObservation],
) -> UnitQuaternion<f64> {
    let mut sum = Matrix3::zeros();
    for o in obs {
        if let Some(m) = o.orientation {
            let tool = chain.tool_pose(&o.q, e).rotation;
            sum += (tool.inverse() * m).to_rotation_matrix().into_inner();
        }
    }
    nearest_rotation(&sum)
}

/// The orientation residual of one row as reports give it: the rotation vector of
/// R_measuredᵀ·R_modelled (rad), R_modelled = R_tool·C.
pub fn orientation_residual(
    chain: &SerialChain,
    e: &ErrorParams,
    marker_rotation: &UnitQuaternion<f64>,
    q: &[f64],
    measured: &UnitQuaternion<f64>,
) -> Vector3<f64> {
    let modelled = chain.tool_pose(q, e).rotation * marker_rotation;
    (measured.inverse() * modelled).scaled_axis()
}

/// J_l⁻¹(r), the inverse left Jacobian of SO(3): log(exp(δ)·exp(r)) ≈ r + J_l⁻¹(r)·δ.
/// J_l⁻¹ = I − ½[r]× + (1/θ² − (1 + cos θ)/(2θ sin θ))·[r]×², the coefficient 1/12 near θ = 0.
fn inverse_left_jacobian(r: &Vector3<f64>) -> Matrix3<f64> {
    let theta = r.norm();
    let k = r.cross_matrix();
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Matrix3::identity() - k * 0.5 + k * k * c
}

/// Per-row weights (1/σ per coordinate); orientation `None` where the row's orientation is
/// not fitted.
struct Weights {
    position: Vec<Vector3<f64>>,
    orientation: Vec<Option<Vector3<f64>>>,
}

/// A usable stated σ: every coordinate within [`STATED_SIGMA_RANGE`] (mm or rad). Outside it
/// no instrument's σ lies, and its square's reciprocal would overflow or vanish in the cost;
/// a block with such a row is weighted by an estimated σ instead.
fn usable(s: Option<Vector3<f64>>) -> Option<Vector3<f64>> {
    s.filter(|v| v.iter().all(|x| STATED_SIGMA_RANGE.contains(x)))
}

/// The stated σ taken as they are (mm or rad).
const STATED_SIGMA_RANGE: std::ops::RangeInclusive<f64> = 1e-9..=1e6;

/// The σ source of each block: stated when every row of the block states a usable one.
fn stated_blocks(obs: &[PoseObservation], choice: WeightChoice, orient: bool) -> (bool, bool) {
    if choice == WeightChoice::Estimated {
        return (false, false);
    }
    let position = obs.iter().all(|o| usable(o.position_sigma).is_some());
    let orientation = orient
        && obs
            .iter()
            .filter(|o| o.orientation.is_some())
            .all(|o| usable(o.orientation_sigma).is_some());
    (position, orientation)
}

impl Weights {
    /// Weights from the stated σ where `stated`, else the block's one σ (`None`: the block's
    /// rows are not fitted — orientation only).
    fn new(
        obs: &[PoseObservation],
        stated: (bool, bool),
        sigma_position: f64,
        sigma_orientation: Option<f64>,
    ) -> Self {
        let position = obs
            .iter()
            .map(|o| match (stated.0, usable(o.position_sigma)) {
                (true, Some(s)) => s.map(|v| 1.0 / v),
                _ => Vector3::repeat(1.0 / sigma_position),
            })
            .collect();
        let orientation = obs
            .iter()
            .map(|o| {
                let sigma = sigma_orientation?;
                o.orientation?;
                Some(match (stated.1, usable(o.orientation_sigma)) {
                    (true, Some(s)) => s.map(|v| 1.0 / v),
                    _ => Vector3::repeat(1.0 / sigma),
                })
            })
            .collect();
        Self {
            position,
            orientation,
        }
    }

    fn fits_orientation(&self) -> bool {
        self.orientation.iter().any(Option::is_some)
    }
}

/// The parameter state: layout parameters and the marker rotation.
#[derive(Debug, Clone)]
struct State {
    e: ErrorParams,
    c: UnitQuaternion<f64>,
}

/// One weighted least-squares problem on a chain.
struct PoseProblem<'a> {
    chain: &'a SerialChain,
    obs: &'a [PoseObservation],
    weights: Weights,
    /// Layout indices fitted.
    free: Vec<usize>,
    /// Whether the marker rotation is fitted (3 unknowns after `free`).
    rotation: bool,
}

/// Residuals of one row at a state: position (mm) and r = log(R_modelledᵀ·R_measured) (rad).
fn row_residual(
    chain: &SerialChain,
    s: &State,
    o: &PoseObservation,
) -> (Vector3<f64>, Option<Vector3<f64>>) {
    let p = o.p - chain.position(&o.q, &s.e);
    let r = o.orientation.map(|m| {
        let modelled = chain.tool_pose(&o.q, &s.e).rotation * s.c;
        (modelled.inverse() * m).scaled_axis()
    });
    (p, r)
}

impl PoseProblem<'_> {
    fn unknowns(&self) -> usize {
        self.free.len() + if self.rotation { 3 } else { 0 }
    }

    fn rows(&self) -> usize {
        3 * self.obs.len() + 3 * self.weights.orientation.iter().flatten().count()
    }

    /// Weighted cost Σ (residual/σ)².
    fn cost(&self, s: &State) -> f64 {
        self.obs
            .iter()
            .enumerate()
            .map(|(k, o)| {
                let (p, r) = row_residual(self.chain, s, o);
                let mut c = p.component_mul(&self.weights.position[k]).norm_squared();
                if let (Some(r), Some(w)) = (r, self.weights.orientation[k]) {
                    c += r.component_mul(&w).norm_squared();
                }
                c
            })
            .sum()
    }

    /// The weighted Jacobian (modelled columns) and residual at `s`.
    fn linearise(&self, s: &State) -> (DMatrix<f64>, DVector<f64>) {
        let (m, n) = (self.rows(), self.unknowns());
        let p = self.free.len();
        let mut jac = DMatrix::zeros(m, n);
        let mut res = DVector::zeros(m);
        let mut row = 0;
        for (k, o) in self.obs.iter().enumerate() {
            let (point, tool, full) = self.chain.pose_and_param_jacobian(&o.q, &s.e);
            let wp = self.weights.position[k];
            let rp = (o.p - point).component_mul(&wp);
            res.fixed_rows_mut::<3>(row).copy_from(&rp);
            for (c, &i) in self.free.iter().enumerate() {
                let col = full.fixed_view::<3, 1>(0, i).component_mul(&wp);
                jac.fixed_view_mut::<3, 1>(row, c).copy_from(&col);
            }
            row += 3;
            let (Some(measured), Some(wo)) = (o.orientation, self.weights.orientation[k]) else {
                continue;
            };
            let modelled = tool * s.c;
            let r = (modelled.inverse() * measured).scaled_axis();
            res.fixed_rows_mut::<3>(row)
                .copy_from(&r.component_mul(&wo));
            let jl = inverse_left_jacobian(&r);
            let to_body = modelled.inverse().to_rotation_matrix().into_inner();
            let a = jl * to_body;
            for (c, &i) in self.free.iter().enumerate() {
                let omega: Vector3<f64> = full.fixed_view::<3, 1>(3, i).into_owned();
                let col = (a * omega).component_mul(&wo);
                jac.fixed_view_mut::<3, 1>(row, c).copy_from(&col);
            }
            if self.rotation {
                for axis in 0..3 {
                    let col = jl.column(axis).component_mul(&wo);
                    jac.fixed_view_mut::<3, 1>(row, p + axis).copy_from(&col);
                }
            }
            row += 3;
        }
        (jac, res)
    }

    fn step(&self, s: &State, dx: &DVector<f64>) -> State {
        let mut t = s.clone();
        for (k, &i) in self.free.iter().enumerate() {
            t.e.set(i, t.e.get(i) + dx[k]);
        }
        if self.rotation {
            let p = self.free.len();
            let phi = Vector3::new(dx[p], dx[p + 1], dx[p + 2]);
            t.c *= UnitQuaternion::from_scaled_axis(phi);
        }
        t
    }

    /// Levenberg–Marquardt from `start` (column-scaled, as [`super::fit`](mod@super::fit)):
    /// the state, the Jacobian and residual there, and the iterations taken.
    fn solve(
        &self,
        start: State,
        max_iterations: usize,
    ) -> (State, DMatrix<f64>, DVector<f64>, usize) {
        let n = self.unknowns();
        let mut s = start;
        let (mut jac, mut res) = self.linearise(&s);
        let mut cost = res.norm_squared();
        let mut lambda = 1e-4;
        let mut iterations = 0;
        for _ in 0..max_iterations {
            iterations += 1;
            let jtj = gram(&jac);
            let jtr = transpose_times(&jac, &res);
            let (d, a, g) = super::fit::scaled_normal_equations(&jtj, &jtr);
            let mut improved = false;
            let mut step_norm = 0.0;
            for _ in 0..12 {
                let Some(ds) = super::fit::damped_step(&a, &g, lambda) else {
                    lambda *= 10.0;
                    continue;
                };
                step_norm = ds.norm();
                let dx = DVector::from_fn(n, |k, _| ds[k] / d[k]);
                let trial = self.step(&s, &dx);
                let c_trial = self.cost(&trial);
                if c_trial <= cost {
                    // The decrease that rounding of the modelled coordinates can fake: a step
                    // that gains less has reached the minimum as far as doubles tell.
                    let gain = cost - c_trial;
                    s = trial;
                    cost = c_trial;
                    lambda = (lambda * 0.2).max(1e-12);
                    improved = gain > 1e-13 * cost.max(f64::MIN_POSITIVE);
                    break;
                }
                lambda *= 10.0;
            }
            (jac, res) = self.linearise(&s);
            cost = res.norm_squared();
            if !improved || step_norm < 1e-10 {
                break;
            }
        }
        (s, jac, res, iterations)
    }
}

/// A layout with the marker rotation's three parameters appended (`Δrx(marker)` …), so the
/// identifiability analysis can name them.
fn extended_layout(layout: &ParamLayout, n_joints: usize) -> ParamLayout {
    let mut ids = layout.ids().to_vec();
    for kind in [ParamKind::Rx, ParamKind::Ry, ParamKind::Rz] {
        ids.push(ParamId {
            transform: TransformId::Marker,
            kind,
        });
    }
    ParamLayout::new(ids, n_joints)
}

/// The level's candidates with the marker rotation (indices L, L+1, L+2) after the frame and
/// marker point.
fn pose_candidates(rig: &Rig, level: Level, rotation: bool) -> Vec<usize> {
    let layout = rig.chain.layout();
    let l = layout.len();
    let candidates = level.candidates(rig);
    if !rotation {
        return candidates;
    }
    let is_frame_or_marker = |i: usize| {
        matches!(
            layout.ids()[i].transform,
            TransformId::Frame | TransformId::Marker
        )
    };
    let split = candidates
        .iter()
        .position(|&i| !is_frame_or_marker(i))
        .unwrap_or(candidates.len());
    let mut out = candidates[..split].to_vec();
    out.extend([l, l + 1, l + 2]);
    out.extend_from_slice(&candidates[split..]);
    out
}

/// The basis of the weighted problem at the start (see the module docs).
fn pose_identifiability(
    problem: &PoseProblem<'_>,
    start: &State,
    candidates: &[usize],
    layout: &ParamLayout,
    n_joints: usize,
) -> Identifiability {
    let l = problem.chain.layout().len();
    let all = PoseProblem {
        chain: problem.chain,
        obs: problem.obs,
        weights: Weights {
            position: problem.weights.position.clone(),
            orientation: problem.weights.orientation.clone(),
        },
        free: candidates.iter().copied().filter(|&i| i < l).collect(),
        rotation: problem.rotation,
    };
    let (jac, _) = all.linearise(start);
    // Columns in candidate order: layout candidates as linearised, the rotation's after them.
    let p = all.free.len();
    let mut next = 0;
    let columns: Vec<DVector<f64>> = candidates
        .iter()
        .map(|&i| {
            if i < l {
                next += 1;
                jac.column(next - 1).into_owned()
            } else {
                jac.column(p + i - l).into_owned()
            }
        })
        .collect();
    let m = DMatrix::from_columns(&columns);
    // 3 rows per "pose" in the analysis's scale: count the rows, not the measurements.
    let poses = m.nrows() / 3;
    determined_factor(
        &triangular_factor(m),
        poses,
        candidates,
        &extended_layout(layout, n_joints),
    )
}

/// Fits a rig's parameters at `level` to pose observations (see the module docs): the rig's
/// chain and the fit with absolute frame parameters. Without any orientation in `obs` (or with
/// `use_orientation` false) it fits positions only, weighted alike, and gives the marker
/// rotation in closed form when orientations exist.
pub fn identify_pose(
    rig: &Rig,
    obs: &[PoseObservation],
    level: Level,
    opts: &PoseOptions,
) -> Result<(SerialChain, PoseFit), IdentifyError> {
    if obs.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    if level.candidates(rig).is_empty() {
        return Err(IdentifyError::NothingToFit { level });
    }
    let plain: Vec<Observation> = obs.iter().map(PoseObservation::position_only).collect();
    super::checks::check_observations(&rig.chain, &plain).map_err(Box::new)?;
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let free_frame = rig.calibration.measurement_frame == FrameMode::Free;
    let started = super::geometric::registered_start(rig, &plain);
    let orient = opts.use_orientation && obs.iter().any(|o| o.orientation.is_some());
    let stated = stated_blocks(obs, opts.weights, orient);
    let start = State {
        e: nominal.clone(),
        c: closed_form_marker_rotation(&started, &nominal, obs),
    };
    let before = ResidualStats::of(
        &obs.iter()
            .map(|o| row_residual(&started, &start, o).0)
            .collect::<Vec<_>>(),
    );
    let orientation_before = orientation_stats(&started, &start, obs);

    // Weights: stated, or estimated in rounds from the last fit's residuals; the first fit
    // takes positions alone whenever a σ is to be estimated (and when positions alone are
    // fitted, one round: a common σ does not move the solution).
    let estimate_p = !stated.0;
    let estimate_o = orient && !stated.1;
    let needs_estimate = orient && (estimate_p || estimate_o);
    let mut sigma_p = 1.0;
    let mut sigma_o: Option<f64> = (orient && !needs_estimate).then_some(1.0);
    let mut state = start.clone();
    let mut rounds = 0;
    let last = loop {
        rounds += 1;
        let round = fit_round(
            rig,
            level,
            &started,
            obs,
            stated,
            (sigma_p, sigma_o),
            &state,
            &start,
            opts,
        )?;
        state = round.state.clone();
        if !needs_estimate || rounds >= MAX_ROUNDS {
            break round;
        }
        let (new_p, new_o) = block_sigmas(&started, &state, obs, round.unknowns, true);
        let new_p = if estimate_p { new_p } else { sigma_p };
        let new_o = if estimate_o { new_o } else { Some(1.0) };
        let changed = |old: f64, new: f64| ((new - old) / old).abs() >= 0.01;
        let settled = sigma_o.is_some()
            && !changed(sigma_p, new_p)
            && !changed(sigma_o.unwrap_or(1.0), new_o.unwrap_or(1.0));
        if settled {
            break round;
        }
        sigma_p = new_p;
        sigma_o = new_o;
    };
    if !orient && estimate_p {
        sigma_p = block_sigmas(&started, &state, obs, last.unknowns, false).0;
    }
    let weighting = Weighting {
        position: if stated.0 {
            BlockSigma::Stated
        } else {
            BlockSigma::Estimated(sigma_p)
        },
        orientation: orient.then(|| {
            if stated.1 {
                BlockSigma::Stated
            } else {
                BlockSigma::Estimated(sigma_o.unwrap_or(f64::NAN))
            }
        }),
        rounds: if needs_estimate { rounds } else { 0 },
    };
    let mut pose = finish(
        &started,
        obs,
        last.state,
        Finish {
            free: last.free,
            rotation: last.rotation,
            identifiability: last.identifiability,
            jac: last.jac,
            res: last.res,
            iterations: last.iterations,
            before,
            orientation_before,
            weighting,
        },
    )?;
    if free_frame {
        absolute_frame(&started, &mut pose.fit);
        Ok((rig.chain.clone(), pose))
    } else {
        Ok((started, pose))
    }
}

/// One weighted fit: the state reached, what was fitted, and the Jacobian and residual there.
struct Round {
    state: State,
    free: Vec<usize>,
    rotation: bool,
    unknowns: usize,
    identifiability: Identifiability,
    jac: DMatrix<f64>,
    res: DVector<f64>,
    iterations: usize,
}

/// One fit with block σ `sigmas` (position mm, orientation rad; `None`: orientation rows not
/// fitted) where the rows state none: the basis of the weighted problem at `start`, then
/// Levenberg–Marquardt from `from` (the marker rotation from the closed form when it is not
/// fitted).
#[allow(clippy::too_many_arguments)]
fn fit_round(
    rig: &Rig,
    level: Level,
    started: &SerialChain,
    obs: &[PoseObservation],
    stated: (bool, bool),
    sigmas: (f64, Option<f64>),
    from: &State,
    start: &State,
    opts: &PoseOptions,
) -> Result<Round, IdentifyError> {
    let weights = Weights::new(obs, stated, sigmas.0, sigmas.1);
    let rotation = weights.fits_orientation();
    let candidates = pose_candidates(rig, level, rotation);
    let mut problem = PoseProblem {
        chain: started,
        obs,
        weights,
        free: Vec::new(),
        rotation,
    };
    let identifiability = pose_identifiability(
        &problem,
        start,
        &candidates,
        rig.chain.layout(),
        rig.chain.joints().len(),
    );
    let l = rig.chain.layout().len();
    problem.free = identifiability
        .basis
        .iter()
        .copied()
        .filter(|&i| i < l)
        .collect();
    problem.rotation = rotation && (l..l + 3).all(|i| identifiability.basis.contains(&i));
    check_size(&problem)?;
    let (solved, jac, res, iterations) = problem.solve(from.clone(), opts.max_iterations);
    let state = if problem.rotation {
        solved
    } else {
        State {
            c: closed_form_marker_rotation(started, &solved.e, obs),
            e: solved.e,
        }
    };
    Ok(Round {
        state,
        unknowns: problem.unknowns(),
        free: problem.free,
        rotation: problem.rotation,
        identifiability,
        jac,
        res,
        iterations,
    })
}

/// Most rounds of σ estimation.
const MAX_ROUNDS: usize = 6;

/// Refuses fewer equations than unknowns + 1.
fn check_size(problem: &PoseProblem<'_>) -> Result<(), IdentifyError> {
    let (rows, unknowns) = (problem.rows(), problem.unknowns());
    if rows < unknowns + 1 {
        return Err(IdentifyError::Fit(FitError::TooFewObservations {
            observations: problem.obs.len(),
            rows,
            unknowns,
            needed: unknowns / 6 + 1,
        }));
    }
    Ok(())
}

/// Per-block σ of a fit's unweighted residuals, σ̂² = RSS_block / (rows_block·(1 − unknowns /
/// rows)): (position mm, orientation rad when fitted).
fn block_sigmas(
    chain: &SerialChain,
    s: &State,
    obs: &[PoseObservation],
    unknowns: usize,
    orient: bool,
) -> (f64, Option<f64>) {
    let (mut rss_p, mut rss_o, mut n_o) = (0.0, 0.0, 0usize);
    for o in obs {
        let (p, r) = row_residual(chain, s, o);
        rss_p += p.norm_squared();
        if let Some(r) = r {
            rss_o += r.norm_squared();
            n_o += 1;
        }
    }
    let rows_p = 3 * obs.len();
    let rows_o = if orient { 3 * n_o } else { 0 };
    let rows = (rows_p + rows_o) as f64;
    let keep = (1.0 - unknowns as f64 / rows).max(1e-3);
    let floor = |s: f64| s.max(1e-12);
    let sp = floor((rss_p / (rows_p as f64 * keep)).sqrt());
    let so = (rows_o > 0).then(|| floor((rss_o / (rows_o as f64 * keep)).sqrt()));
    (sp, so)
}

/// Orientation statistics of every row with an orientation at a state.
fn orientation_stats(chain: &SerialChain, s: &State, obs: &[PoseObservation]) -> OrientationStats {
    let angles: Vec<f64> = obs
        .iter()
        .filter_map(|o| row_residual(chain, s, o).1.map(|r| r.norm()))
        .collect();
    OrientationStats::of_angles(&angles)
}

/// What [`finish`] needs from the last fit.
struct Finish {
    free: Vec<usize>,
    rotation: bool,
    identifiability: Identifiability,
    jac: DMatrix<f64>,
    res: DVector<f64>,
    iterations: usize,
    before: ResidualStats,
    orientation_before: OrientationStats,
    weighting: Weighting,
}

/// σ, covariance, κ and residuals at the solution.
fn finish(
    chain: &SerialChain,
    obs: &[PoseObservation],
    s: State,
    f: Finish,
) -> Result<PoseFit, IdentifyError> {
    let p = f.free.len();
    let n = f.jac.ncols();
    let kappa = kappa_eq4(&f.jac);
    let jtj = gram(&f.jac);
    let Some(inv) = jtj
        .try_inverse()
        .filter(|m| m.iter().all(|v| v.is_finite()))
    else {
        return Err(IdentifyError::Fit(FitError::Singular { kappa }));
    };
    let dof = f.jac.nrows().saturating_sub(n).max(1) as f64;
    let s2 = f.res.norm_squared() / dof;
    let covariance = inv * s2;
    let sigma_of = |k: usize| covariance[(k, k)].max(0.0).sqrt();
    let marker_rotation_sigma = if f.rotation {
        Vector3::new(sigma_of(p), sigma_of(p + 1), sigma_of(p + 2))
    } else {
        Vector3::zeros()
    };
    let mut positions = Vec::with_capacity(obs.len());
    let mut orientation_residuals = Vec::with_capacity(obs.len());
    for o in obs {
        let (e, r) = row_residual(chain, &s, o);
        positions.push(e);
        // Reports give R_measuredᵀ·R_modelled's rotation vector: the fit's r negated.
        orientation_residuals.push(r.map(|r| -r));
    }
    let angles: Vec<f64> = orientation_residuals
        .iter()
        .flatten()
        .map(|r| r.norm())
        .collect();
    let rss: f64 = positions.iter().map(|e| e.norm_squared()).sum();
    let keep = (1.0 - n as f64 / f.jac.nrows().max(1) as f64).max(1e-3);
    let sigma0_mm = (rss / (3.0 * obs.len() as f64 * keep)).sqrt();
    let l = chain.layout().len();
    let mut undetermined = f.identifiability.undetermined.clone();
    undetermined.retain(|u| u.param < l);
    for u in &mut undetermined {
        u.combination.retain(|(i, _)| *i < l);
    }
    let fit = FitResult {
        params: s.e,
        free: f.free,
        sigma: (0..p).map(sigma_of).collect(),
        covariance: covariance.view((0, 0), (p, p)).into_owned(),
        kappa,
        before: f.before,
        after: ResidualStats::of(&positions),
        sigma0_mm,
        iterations: f.iterations,
        residuals: positions,
        undetermined,
    };
    Ok(PoseFit {
        fit,
        marker_rotation: s.c,
        marker_rotation_sigma,
        orientation_before: f.orientation_before,
        orientation: OrientationStats::of_angles(&angles),
        orientation_residuals,
        weighting: f.weighting,
        variance_factor: s2.sqrt(),
        identifiability: f.identifiability,
    })
}

/// The fitted model on a held-out recording, frames as fitted (a recording registered to the
/// training one): position errors beside nominal kinematics through the fitted frame and
/// marker, and orientation errors with the fitted marker rotation.
pub fn pose_heldout(
    chain: &SerialChain,
    pose: &PoseFit,
    name: &str,
    rec: &Recording,
) -> Result<PoseHeldOut, IdentifyError> {
    let obs = pose_observations(rec);
    if obs.is_empty() {
        return Err(IdentifyError::HeldOutEmpty { name: name.into() });
    }
    let fitted = &pose.fit.params;
    let mut nominal = fitted.clone();
    for (k, id) in chain.layout().ids().iter().enumerate() {
        if !matches!(id.transform, TransformId::Frame | TransformId::Marker) {
            nominal.set(k, 0.0);
        }
    }
    let errors = |e: &ErrorParams| -> Vec<Vector3<f64>> {
        obs.iter().map(|o| o.p - chain.position(&o.q, e)).collect()
    };
    let angles: Vec<f64> = obs
        .iter()
        .filter_map(|o| {
            o.orientation.map(|m| {
                orientation_residual(chain, fitted, &pose.marker_rotation, &o.q, &m).norm()
            })
        })
        .collect();
    Ok(PoseHeldOut {
        name: name.into(),
        position: HeldOutReport {
            name: name.into(),
            points: obs.len(),
            nominal: ResidualStats::of(&errors(&nominal)),
            fitted: ResidualStats::of(&errors(fitted)),
        },
        orientation: (!angles.is_empty()).then(|| OrientationStats::of_angles(&angles)),
    })
}

/// An identification refitted with the recording's orientations: the pose fit at `level` on
/// the rows the position pipeline kept (its outliers stay out), which replaces the fit, the
/// chain and the held-out reports of `id`; returns the pose fit and, per held-out recording,
/// its position and orientation figures. The outlier search itself stays on positions.
pub fn refit_with_orientation(
    rig: &Rig,
    rec: &Recording,
    id: &mut super::Identification,
    level: Level,
    heldout: &[super::HeldOut],
    opts: &PoseOptions,
) -> Result<(PoseFit, Vec<PoseHeldOut>), IdentifyError> {
    let kept: Vec<PoseObservation> = pose_observations(rec)
        .into_iter()
        .enumerate()
        .filter(|(i, _)| !id.outliers.iter().any(|o| o.index == *i))
        .map(|(_, o)| o)
        .collect();
    let (chain, pose) = identify_pose(rig, &kept, level, opts)?;
    super::check_fit(rig, &chain, &pose.fit)?;
    let held = heldout
        .iter()
        .map(|h| pose_heldout(&chain, &pose, &h.name, &h.recording))
        .collect::<Result<Vec<_>, _>>()?;
    id.chain = chain;
    id.fit = pose.fit.clone();
    id.heldout = held.iter().map(|h| h.position.clone()).collect();
    Ok((pose, held))
}

/// The orientation residuals of a fit that did not use orientations (positions alone): the
/// marker rotation in closed form for the fitted kinematics, and the statistics over the rows
/// `kept` (indices into [`pose_observations`]); `None` without orientations.
pub fn orientation_of_position_fit(
    chain: &SerialChain,
    e: &ErrorParams,
    rec: &Recording,
    kept: impl Fn(usize) -> bool,
) -> Option<(UnitQuaternion<f64>, OrientationStats)> {
    let obs: Vec<PoseObservation> = pose_observations(rec)
        .into_iter()
        .enumerate()
        .filter(|(i, o)| kept(*i) && o.orientation.is_some())
        .map(|(_, o)| o)
        .collect();
    if obs.is_empty() {
        return None;
    }
    let c = closed_form_marker_rotation(chain, e, &obs);
    let angles: Vec<f64> = obs
        .iter()
        .filter_map(|o| {
            o.orientation
                .map(|m| orientation_residual(chain, e, &c, &o.q, &m).norm())
        })
        .collect();
    Some((c, OrientationStats::of_angles(&angles)))
}

/// The held-out orientation figures of a pose fit, one line per recording.
pub fn pose_heldout_text(held: &[PoseHeldOut]) -> String {
    let mut s = String::new();
    for h in held {
        if let Some(o) = h.orientation {
            let _ = writeln!(
                s,
                "held-out {} ({} rows): orientation mean {:.4}°, RMS {:.4}°, max {:.4}° (fitted model, its frame and marker rotation)",
                h.name, o.n, o.mean_deg, o.rms_deg, o.max_deg
            );
        }
    }
    s
}

/// The pose fit's figures as `rigcal identify` prints them: weighting, marker rotation, and the
/// position (mm) and orientation (degrees) residuals apart.
pub fn pose_fit_text(pose: &PoseFit) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "pose fit: {}", pose.weighting.text());
    let (r, p, y) = pose.marker_rotation.euler_angles();
    let sd = pose.marker_rotation_sigma.map(f64::to_degrees);
    if pose.weighting.orientation.is_some() {
        let _ = writeln!(
            s,
            "  marker rotation on the tool frame (rpy, R = Rz·Ry·Rx): {:.4}° {:.4}° {:.4}° (σ about the marker's x, y, z: {:.4}° {:.4}° {:.4}°)",
            r.to_degrees(),
            p.to_degrees(),
            y.to_degrees(),
            sd.x,
            sd.y,
            sd.z
        );
    }
    let a = &pose.fit.after;
    let b = &pose.fit.before;
    let _ = writeln!(
        s,
        "  position residual (mm):      mean {:.4}  RMS {:.4}  max {:.4}  (start: RMS {:.4}) over {} points",
        a.mean_mm, a.rms_mm, a.max_mm, b.rms_mm, a.n
    );
    if pose.orientation.n > 0 {
        let o = &pose.orientation;
        let ob = &pose.orientation_before;
        let _ = writeln!(
            s,
            "  orientation residual (°):    mean {:.4}  RMS {:.4}  max {:.4}  (start: RMS {:.4}) over {} rows{}",
            o.mean_deg,
            o.rms_deg,
            o.max_deg,
            ob.rms_deg,
            o.n,
            if pose.weighting.orientation.is_none() {
                ", not fitted: marker rotation in closed form"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        s,
        "  weighted σ̂ {:.3} (1 when the σ are right); κ (eq. 4, weighted columns) {:.1}",
        pose.variance_factor, pose.fit.kappa
    );
    let stated = matches!(pose.weighting.position, BlockSigma::Stated)
        || matches!(pose.weighting.orientation, Some(BlockSigma::Stated));
    if stated && pose.variance_factor > STATED_SIGMA_TOO_SMALL {
        let _ = writeln!(
            s,
            "  note: the residuals are {:.0} times the stated σ: the model's own error, not the instrument's, weighs the rows; --estimate-weights weights each block by its residuals instead",
            pose.variance_factor
        );
    }
    s
}

/// A weighted σ̂ above this says the stated σ leave out most of what the residuals hold.
const STATED_SIGMA_TOO_SMALL: f64 = 3.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inverse_left_jacobian_linearises_the_logarithm() {
        let r = Vector3::new(0.3, -0.2, 0.5);
        let x = UnitQuaternion::from_scaled_axis(r);
        let jl = inverse_left_jacobian(&r);
        let h = 1e-6;
        for k in 0..3 {
            let mut d = Vector3::zeros();
            d[k] = h;
            let plus = (UnitQuaternion::from_scaled_axis(d) * x).scaled_axis();
            let minus = (UnitQuaternion::from_scaled_axis(-d) * x).scaled_axis();
            let numeric = (plus - minus) / (2.0 * h);
            assert!(
                (numeric - jl.column(k)).norm() < 1e-8,
                "{k}: {numeric} vs {}",
                jl.column(k)
            );
        }
        // Near zero the series and the closed form agree.
        let small = Vector3::new(1e-5, 2e-5, -1e-5);
        let series = inverse_left_jacobian(&small);
        assert!((series - Matrix3::identity() + small.cross_matrix() * 0.5).norm() < 1e-9);
    }

    fn tiago() -> Rig {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../rigs/tiago-pro.toml");
        Rig::load(std::path::Path::new(path)).unwrap()
    }

    /// Rows whose measured poses are off the model's by up to half a degree and a millimetre.
    fn rows(rig: &Rig, e: &ErrorParams, c: &UnitQuaternion<f64>, n: usize) -> Vec<PoseObservation> {
        use rand::SeedableRng;
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(3);
        let poses = super::super::random_poses(rig.chain.joints(), rig.held(), n, &mut rng);
        poses
            .into_iter()
            .enumerate()
            .map(|(k, q)| {
                let t = k as f64;
                let turn = Vector3::new((t * 1.3).sin(), (t * 0.7).cos(), (t * 2.1).sin()) * 0.008;
                let m = rig.chain.tool_pose(&q, e).rotation
                    * c
                    * UnitQuaternion::from_scaled_axis(turn);
                PoseObservation {
                    p: rig.chain.position(&q, e) + Vector3::new(t.sin(), t.cos(), 0.5),
                    q,
                    orientation: Some(m),
                    position_sigma: None,
                    orientation_sigma: None,
                }
            })
            .collect()
    }

    #[test]
    fn the_orientation_columns_equal_central_differences_of_the_residual() {
        let rig = tiago();
        let layout = rig.chain.layout();
        let mut e = ErrorParams::zeros(layout);
        for i in 0..layout.len() {
            e.set(i, 0.002 * ((i as f64) * 1.7).sin());
        }
        let c = UnitQuaternion::from_euler_angles(0.4, -1.1, 2.0);
        let obs = rows(&rig, &e, &c, 6);
        let weights = Weights::new(&obs, (false, false), 0.05, Some(2e-4));
        let problem = PoseProblem {
            chain: &rig.chain,
            obs: &obs,
            weights,
            free: (0..layout.len()).collect(),
            rotation: true,
        };
        // Off the data's parameters, so the residuals are not small.
        let mut at = State {
            e: e.clone(),
            c: c * UnitQuaternion::from_euler_angles(0.01, 0.0, -0.01),
        };
        at.e.set(10, at.e.get(10) + 0.01);
        let (jac, res) = problem.linearise(&at);
        assert!(res.iter().map(|v| v.abs()).fold(0.0, f64::max) > 10.0);
        let n = problem.unknowns();
        let mut worst: f64 = 0.0;
        for k in 0..n {
            let h = 1e-6;
            let mut dx = DVector::zeros(n);
            dx[k] = h;
            let (_, plus) = problem.linearise(&problem.step(&at, &dx));
            let (_, minus) = problem.linearise(&problem.step(&at, &(-dx)));
            // r(x + δ) ≈ r − J·δ: the modelled column is minus the residual's derivative.
            let numeric = (minus - plus) / (2.0 * h);
            let scale = jac.column(k).norm().max(1.0);
            worst = worst.max((numeric - jac.column(k)).norm() / scale);
        }
        assert!(worst < 1e-5, "largest relative column difference {worst:e}");
    }
}
