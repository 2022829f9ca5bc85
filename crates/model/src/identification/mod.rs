//! Identification of kinematic error parameters from position measurements (seed 000 section 3.1).
//!
//! * [`identifiability`]: which parameters position measurements can separate, from the numerical
//!   rank of the identification Jacobian \[M\] (eq. 2) over a spread of poses; the basis is chosen
//!   by ordered Gram–Schmidt pivoting (frame and marker first when free, then the rig's preferred
//!   basis, then the rest), κ of eq. (4) reported on column-scaled \[M\].
//! * [`fit`](mod@fit): Levenberg–Marquardt with column scaling on the chosen parameters, with each
//!   parameter's standard deviation and residual statistics.
//! * [`incremental`]: refits without some rows (the outlier search's), starting from the last
//!   fit with the removed rows downdated out of its normal equations.
//! * [`outliers`]: robust detection and removal of measurements no model explains, each named
//!   with its row and size.
//! * [`registration`]: the rigid measurement frame (table to world), closed form then refined by
//!   the same fit with only the frame free — one mechanism for fixed and free frames.
//! * [`geometric`]: the sequence every geometric fit of a rig runs — Kabsch start for a free
//!   frame, analysis, fit — at a [`Level`] ([`identify_at`]); the diagnosis's standard model is
//!   this fit.
//! * [`pipeline`]: [`identify`], conventional calibration of a recording: the geometric fit with
//!   outliers removed and the fitted model checked on held-out recordings.
//! * [`pose`]: identification from pose measurements (a 6-DoF probe): orientation rows beside
//!   the position rows, weighted by stated or estimated σ, the marker frame a full pose.
//! * [`checks`]: what a fit reads is bounded (no absurd coordinate reaches a matrix) and what
//!   it returns is judged (a diverged fit is an error, never a model).
//!
//! Units: mm and rad inside.

pub mod checks;
pub(crate) mod dense;
pub mod fit;
pub mod geometric;
pub mod identifiability;
pub mod incremental;
pub mod outliers;
pub mod pipeline;
pub mod pose;
pub mod registration;
mod robot_at;
pub mod screen;

pub use checks::{check_fit, check_observations, check_recording, AbsurdValue, Diverged};
pub use fit::{errors, fit, FitError, FitOptions, FitResult, Observation, Prior, ResidualStats};
pub use geometric::{fit_geometry, identify_at, GeometricFit, IdentifyError, Level};
pub use identifiability::{
    analyse, analyse_determined, candidate_order, Identifiability, Undetermined, DETERMINED_TOL,
};
pub use pipeline::{
    identify, HeldOut, HeldOutReport, Identification, IdentifyOptions, StructureJudge,
};
pub use registration::{register, Registration};

use rand::RngExt;
use rigcal_core::kinematics::{JointKind, JointSpec};

/// `n` joint vectors drawn uniformly within the limits, held joints at their values.
pub fn random_poses<R: RngExt + ?Sized>(
    joints: &[JointSpec],
    held: &[Option<f64>],
    n: usize,
    rng: &mut R,
) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| {
            joints
                .iter()
                .enumerate()
                .map(|(j, s)| match held.get(j).copied().flatten() {
                    Some(v) => v,
                    None => rng.random_range(s.min..=s.max),
                })
                .collect()
        })
        .collect()
}

/// A short human label for a joint value in file units.
pub fn joint_label(spec: &JointSpec, v: f64) -> String {
    match spec.kind {
        JointKind::Revolute => format!("{:.2}°", v.to_degrees()),
        JointKind::Prismatic => format!("{v:.2} mm"),
    }
}
