//! Registration of a measurement frame (seed 000 section 7; conventions §1): the rigid transform
//! between the instrument's frame (the x-y-z table, a tracker) and the world, from points
//! measured at arbitrary poses with the nominal kinematics.
//!
//! A closed-form start (Kabsch: the rotation from the SVD of the cross-covariance of the centred
//! point sets) is refined by [`fit`] with only the six frame parameters free — the same fit that
//! identifies kinematic parameters, with the frame free instead of fixed.

use super::fit::{fit, FitError, FitOptions, Observation, ResidualStats};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain, TransformId};
use rigcal_core::recording::{Recording, RegistrationInfo};

/// A fitted registration.
#[derive(Debug, Clone)]
pub struct Registration {
    /// Maps instrument coordinates to world coordinates: world = T · instrument.
    pub world_from_instrument: Isometry3<f64>,
    /// Residuals of the fit (instrument frame, mm).
    pub stats: ResidualStats,
    /// Standard deviations of x y z (mm) and rz ry rx (rad) of the instrument frame.
    pub sigma: Vec<f64>,
    /// Points used.
    pub n: usize,
}

/// Fits the frame in which `obs` (points in the instrument's frame) were measured, for a chain
/// with error parameters `e` (usually nominal). Needs at least three poses that are not collinear.
pub fn register(
    chain: &SerialChain,
    e: &ErrorParams,
    obs: &[Observation],
) -> Result<Registration, FitError> {
    if obs.len() < 3 {
        return Err(FitError::TooFewObservations {
            observations: obs.len(),
            rows: 3 * obs.len(),
            unknowns: 6,
            needed: 3,
        });
    }
    let world = chain.with_frame(Isometry3::identity());
    let model: Vec<Vector3<f64>> = obs.iter().map(|o| world.position(&o.q, e)).collect();
    let measured: Vec<Vector3<f64>> = obs.iter().map(|o| o.p).collect();
    let start = kabsch(&model, &measured);
    let framed = world.with_frame(start);
    let free: Vec<usize> = framed
        .layout()
        .ids()
        .iter()
        .enumerate()
        .filter(|(_, id)| id.transform == TransformId::Frame)
        .map(|(i, _)| i)
        .collect();
    let result = fit(&framed, obs, e, &free, &FitOptions::default())?;
    let instrument_from_world = framed.frame_pose(&result.params);
    Ok(Registration {
        world_from_instrument: instrument_from_world.inverse(),
        stats: result.after,
        sigma: result.sigma,
        n: obs.len(),
    })
}

/// Why a recording could not be registered.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RegisterError {
    /// Too few measured rows carry table coordinates.
    #[error("{found} measured rows carry table coordinates; registration needs at least 3 (columns table_x_mm, table_y_mm, table_z_mm)")]
    TooFewTablePoints {
        /// Rows that carry them.
        found: usize,
    },
    /// A value read is not finite or beyond any measurement of the arm.
    #[error(transparent)]
    Absurd(#[from] Box<super::checks::AbsurdValue>),
    /// The fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
}

/// Registers a recording's table coordinates to the world with the nominal kinematics: the
/// frame of the measured rows that carry `table_x_mm, table_y_mm, table_z_mm`.
pub fn register_recording(
    chain: &SerialChain,
    rec: &Recording,
) -> Result<Registration, RegisterError> {
    super::checks::check_recording(chain, rec).map_err(Box::new)?;
    let obs = rec.table_observations();
    if obs.len() < 3 {
        return Err(RegisterError::TooFewTablePoints { found: obs.len() });
    }
    Ok(register(chain, &ErrorParams::zeros(chain.layout()), &obs)?)
}

impl Registration {
    /// The registration in file units, as a recording's `session.toml` stores it.
    pub fn info(&self) -> RegistrationInfo {
        let (xyz, rpy) = to_xyz_rpy(&self.world_from_instrument);
        RegistrationInfo {
            translation_mm: xyz,
            rpy_deg: rpy,
            rms_mm: Some(self.stats.rms_mm),
        }
    }

    /// A registered copy of a recording: world positions recomputed from the table
    /// coordinates of every row that has them, and the registration stored in its session.
    pub fn apply(&self, rec: &Recording) -> Recording {
        let mut out = rec.clone();
        for m in out.rows.iter_mut() {
            if let Some(t) = m.table {
                m.position = Some((self.world_from_instrument * Point3::from(t)).coords);
            }
        }
        let mut info = out.session.clone().unwrap_or_default();
        info.registration = Some(self.info());
        out.session = Some(info);
        out
    }
}

/// The rigid transform T minimising Σ |T·a_i − b_i|² (Kabsch/Umeyama without scale).
pub fn kabsch(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Isometry3<f64> {
    let n = a.len().min(b.len()).max(1) as f64;
    let ca = a.iter().sum::<Vector3<f64>>() / n;
    let cb = b.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (p, q) in a.iter().zip(b) {
        h += (p - ca) * (q - cb).transpose();
    }
    // A matrix that is not finite has no SVD (nalgebra's would never return): translation only.
    let finite = h.iter().all(|v| v.is_finite());
    let svd = finite
        .then(|| h.try_svd(true, true, super::dense::SVD_EPSILON, 10_000))
        .flatten();
    let (Some(u), Some(v_t)) = (svd.as_ref().and_then(|s| s.u), svd.and_then(|s| s.v_t)) else {
        return Isometry3::translation(cb.x - ca.x, cb.y - ca.y, cb.z - ca.z);
    };
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = cb - rot * ca;
    Isometry3::from_parts(Translation3::from(t), rot)
}

/// Translation (mm) and roll-pitch-yaw (deg) of a pose, for files.
pub fn to_xyz_rpy(t: &Isometry3<f64>) -> ([f64; 3], [f64; 3]) {
    let (r, p, y) = t.rotation.euler_angles();
    let v = t.translation.vector;
    (
        [v.x, v.y, v.z],
        [r.to_degrees(), p.to_degrees(), y.to_degrees()],
    )
}
