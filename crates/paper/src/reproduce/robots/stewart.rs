//! The Stewart platform of seed 001 section 5 (Fig. 8): inverse kinematics in closed form
//! (eq. 6), direct kinematics by Newton–Raphson, and the simulated real platform with the
//! structural errors of Table 9.
//!
//! # Conventions and choices
//! Millimetres and radians inside. Joints Q = the six leg lengths (mm; prismatic, no stroke
//! limits: the paper gives none). Gripper pose
//! S = [x, y, z, ψ, θ, φ] with M_bg = Trans(x, y, z)·Rot(X, ψ)·Rot(Y, θ)·Rot(Z, φ); the platform
//! frame is M_bp = M_bg·Trans(Z, −z_pg), z_pg = 200 mm.
//! Base hinges B_i: a regular hexagon of radius 1000 mm in the base plane, B_i at 60°·i. Platform
//! hinges: an equilateral triangle of radius 500 mm in the platform plane, vertex k at
//! 30° + 120°·k; legs 2k and 2k+1 share vertex k (a 6-3 platform; the paper gives the two
//! polygons but not the pairing). Each leg has its own platform hinge point in the error model.
//! The workspace is missing from the text (conventions §10); we take x, y ∈ ±100 mm,
//! z ∈ [1000, 1200] mm, ψ, θ, φ ∈ ±5° (uniform).
//!
//! As a measured point, the platform is its gripper position (x, y, z) from the direct
//! kinematics; it carries no error parameters (its errors are the simulation's, calibrated by
//! networks only).

use nalgebra::{DMatrix, DVector, Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::RngExt;
use rigcal_core::kinematics::{
    no_error_parameters, ErrorParams, JointKind, JointSpec, KinematicsError, ParamLayout, Robot,
};
use std::sync::LazyLock;

/// Gripper offset from the platform (mm).
const Z_PG_MM: f64 = 200.0;
/// Base hinge circle radius (mm).
const BASE_RADIUS_MM: f64 = 1000.0;
/// Platform hinge circle radius (mm).
const PLATFORM_RADIUS_MM: f64 = 500.0;

/// Geometry of a Stewart platform (nominal or with errors).
#[derive(Debug, Clone, PartialEq)]
pub struct Stewart {
    /// Base hinges in the base frame (mm).
    pub base: [Vector3<f64>; 6],
    /// Platform hinges in the platform frame (mm), one per leg.
    pub platform: [Vector3<f64>; 6],
    /// Leg length offsets: the real length is the commanded one plus this (mm).
    pub leg_offset: [f64; 6],
    /// Gripper frame relative to the platform frame.
    pub platform_to_gripper: Isometry3<f64>,
}

impl Default for Stewart {
    fn default() -> Self {
        Self::nominal()
    }
}

/// The pose matrix M_bg of S = [x, y, z, ψ, θ, φ].
fn pose_matrix(s: &[f64]) -> Isometry3<f64> {
    let r = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), s[3])
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), s[4])
        * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), s[5]);
    Isometry3::from_parts(Translation3::new(s[0], s[1], s[2]), r)
}

impl Stewart {
    /// The nominal platform.
    pub fn nominal() -> Self {
        let base = std::array::from_fn(|i| {
            let a = (60.0 * i as f64).to_radians();
            Vector3::new(BASE_RADIUS_MM * a.cos(), BASE_RADIUS_MM * a.sin(), 0.0)
        });
        let platform = std::array::from_fn(|i| {
            let a = (30.0 + 120.0 * (i / 2) as f64).to_radians();
            Vector3::new(
                PLATFORM_RADIUS_MM * a.cos(),
                PLATFORM_RADIUS_MM * a.sin(),
                0.0,
            )
        });
        Self {
            base,
            platform,
            leg_offset: [0.0; 6],
            platform_to_gripper: Isometry3::translation(0.0, 0.0, Z_PG_MM),
        }
    }

    /// Leg lengths for gripper pose `s` (eq. 6), before the length offsets.
    fn leg_lengths(&self, s: &[f64]) -> [f64; 6] {
        let m_bp = pose_matrix(s) * self.platform_to_gripper.inverse();
        std::array::from_fn(|i| {
            let p = m_bp * Point3::from(self.platform[i]);
            (p.coords - self.base[i]).norm()
        })
    }

    /// A random pose of the workspace (see the module docs).
    pub fn random_pose<R: RngExt + ?Sized>(rng: &mut R) -> Vec<f64> {
        let a = 5f64.to_radians();
        vec![
            rng.random_range(-100.0..100.0),
            rng.random_range(-100.0..100.0),
            rng.random_range(1000.0..1200.0),
            rng.random_range(-a..a),
            rng.random_range(-a..a),
            rng.random_range(-a..a),
        ]
    }

    /// The platform with errors `e` (48 values, see [`StewartErrors`]) added.
    pub fn perturbed(&self, e: &[f64; 48]) -> Self {
        let mut out = self.clone();
        for i in 0..6 {
            out.base[i] += Vector3::new(e[3 * i], e[3 * i + 1], e[3 * i + 2]);
            out.platform[i] += Vector3::new(e[18 + 3 * i], e[19 + 3 * i], e[20 + 3 * i]);
            out.leg_offset[i] += e[36 + i];
        }
        let d = Isometry3::from_parts(
            Translation3::new(e[42], e[43], e[44]),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), e[45])
                * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), e[46])
                * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), e[47]),
        );
        out.platform_to_gripper = self.platform_to_gripper * d;
        out
    }

    /// Direct kinematics by Newton–Raphson from `guess` (a pose), with the analytic Jacobian of
    /// the leg lengths; tolerance on the leg lengths in mm.
    pub fn direct(
        &self,
        q: &[f64],
        guess: &[f64],
        tolerance_mm: f64,
    ) -> Result<Vec<f64>, KinematicsError> {
        let mut s = guess.to_vec();
        let mut residual = f64::INFINITY;
        for _ in 0..50 {
            let l = self.leg_lengths(&s);
            let r = DVector::from_fn(6, |i, _| l[i] - self.leg_offset[i] - q[i]);
            residual = r.amax();
            if residual <= tolerance_mm {
                return Ok(s);
            }
            let j = self.leg_jacobian(&s);
            let ds = j.lu().solve(&r).ok_or(KinematicsError::NoConvergence {
                what: "Stewart direct kinematics (singular Jacobian)",
                iterations: 0,
                residual,
            })?;
            for k in 0..6 {
                s[k] -= ds[k];
            }
        }
        Err(KinematicsError::NoConvergence {
            what: "Stewart direct kinematics (Newton–Raphson)",
            iterations: 50,
            residual,
        })
    }

    /// ∂l/∂S (6 × 6), by central differences of the closed-form leg lengths.
    fn leg_jacobian(&self, s: &[f64]) -> DMatrix<f64> {
        let mut j = DMatrix::zeros(6, 6);
        for c in 0..6 {
            let h = if c < 3 { 1e-5 } else { 1e-8 };
            let mut sp = s.to_vec();
            let mut sm = s.to_vec();
            sp[c] += h;
            sm[c] -= h;
            let (lp, lm) = (self.leg_lengths(&sp), self.leg_lengths(&sm));
            for r in 0..6 {
                j[(r, c)] = (lp[r] - lm[r]) / (2.0 * h);
            }
        }
        j
    }
}

/// A home pose to start Newton–Raphson from.
pub fn home_pose() -> Vec<f64> {
    vec![0.0, 0.0, 1100.0, 0.0, 0.0, 0.0]
}

/// The six legs, prismatic, without stroke limits.
static LEGS: LazyLock<[JointSpec; 6]> = LazyLock::new(|| {
    std::array::from_fn(|i| JointSpec {
        name: format!("leg{}", i + 1),
        kind: JointKind::Prismatic,
        min: 0.0,
        max: f64::INFINITY,
    })
});

impl Robot for Stewart {
    fn joints(&self) -> &[JointSpec] {
        LEGS.as_slice()
    }
    fn pose_len(&self) -> usize {
        6
    }
    fn pose_is_angle(&self, i: usize) -> bool {
        i >= 3
    }
    /// Direct kinematics by Newton–Raphson from [`home_pose`], to 1e-10 mm on the legs.
    fn forward(&self, q: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        self.direct(q, &home_pose(), 1e-10)
    }
    /// Closed form (eq. 6): one solution, whatever the guess.
    fn inverse(&self, s: &[f64], _guess: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        let l = self.leg_lengths(s);
        Ok((0..6).map(|i| l[i] - self.leg_offset[i]).collect())
    }
    fn layout(&self) -> &ParamLayout {
        no_error_parameters()
    }
    /// The gripper position; NaN where the direct kinematics does not converge
    /// ([`Robot::forward`] says why).
    fn position(&self, q: &[f64], _e: &ErrorParams) -> Vector3<f64> {
        match self.forward(q) {
            Ok(s) => Vector3::new(s[0], s[1], s[2]),
            Err(_) => Vector3::repeat(f64::NAN),
        }
    }
    fn position_and_param_jacobian(
        &self,
        q: &[f64],
        e: &ErrorParams,
    ) -> (Vector3<f64>, DMatrix<f64>) {
        (self.position(q, e), DMatrix::zeros(3, 0))
    }
    /// The position rows of [`Robot::pose_jacobian`]; NaN where the direct kinematics does not
    /// converge.
    fn joint_jacobian(&self, q: &[f64], _e: &ErrorParams) -> DMatrix<f64> {
        match self.pose_jacobian(q) {
            Ok(j) => j.rows(0, 3).into_owned(),
            Err(_) => DMatrix::from_element(3, 6, f64::NAN),
        }
    }
}

/// Table 9: constant-error ranges and random-error amplitudes, per kind of parameter.
/// The 48 error values are: base hinges (6 × xyz), platform hinges (6 × xyz), leg lengths (6),
/// gripper offset (x y z ψ θ φ); mm and rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StewartErrors {
    /// Hinge position (mm).
    pub hinge: f64,
    /// Leg length (mm).
    pub leg: f64,
    /// Gripper position (mm).
    pub gripper: f64,
    /// Gripper orientation (rad).
    pub gripper_angle: f64,
}

impl StewartErrors {
    /// The constant-error ranges δL_c of Table 9.
    pub fn table9_constant() -> Self {
        Self {
            hinge: 1.0,
            leg: 3.0,
            gripper: 0.1,
            gripper_angle: 0.25e-3,
        }
    }

    /// The random-error amplitudes δL_r of Table 9.
    pub fn table9_random() -> Self {
        Self {
            hinge: 0.02,
            leg: 0.02,
            gripper: 0.01,
            gripper_angle: 0.02e-3,
        }
    }

    /// Every amplitude times `f`.
    pub fn scaled(&self, f: f64) -> Self {
        Self {
            hinge: self.hinge * f,
            leg: self.leg * f,
            gripper: self.gripper * f,
            gripper_angle: self.gripper_angle * f,
        }
    }

    /// The amplitude of each of the 48 values.
    pub fn amplitudes(&self) -> [f64; 48] {
        std::array::from_fn(|k| match k {
            0..=35 => self.hinge,
            36..=41 => self.leg,
            42..=44 => self.gripper,
            _ => self.gripper_angle,
        })
    }

    /// A uniform draw within ± the amplitudes.
    pub fn draw<R: RngExt + ?Sized>(&self, rng: &mut R) -> [f64; 48] {
        let a = self.amplitudes();
        std::array::from_fn(|k| {
            if a[k] > 0.0 {
                rng.random_range(-a[k]..a[k])
            } else {
                0.0
            }
        })
    }
}
