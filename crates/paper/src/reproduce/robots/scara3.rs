//! The 3-DOF SCARA of seed 001 section 6 (Fig. 9, Tables 13–16): the nominal robot is the rig
//! file `rigs/scara3.toml` (a [`HeldChain`] of its serial chain); the simulated
//! real robot adds Table 13's geometric errors, Table 14's compliances and the gripper force of
//! eq. (13) with Table 15's coefficients.
//!
//! # Conventions and choices
//! Millimetres and radians inside; the force law takes metres and gives newtons, compliances are
//! in m/N and rad/(N·m) as in the tables. Joints Q = [q1, q2 (rad), q3 (mm)]; S = [x, y, z] (mm).
//! The real chain is
//! Tx(X0)·Ty(Y0)·Rx(χ0)·Ry(ψ0) · Rz(q1+θ1)·Tx(a1)·Rx(α1)·Ry(ψ1) · Rz(q2+θ2)·Tx(a2)·Rx(α2)·Ry(ψ2) ·
//! Tz(q3+d). The paper leaves the compliance law out (conventions §10); ours: the force F of
//! eq. (13) (we read Table 15's "x_2" in F_y as x²) acts at the gripper, evaluated at the
//! nominal gripper position; it turns joint 1 by K_θ1·τ1 and joint 2 by K_θ2·τ2 (τ the torques
//! about the vertical joint axes), extends the prismatic joint by K_d·F_z, and deflects the
//! gripper by K_xy·(F_x, F_y) and K_z·F_z. Random errors (δL_r) are drawn uniformly in
//! ± the amplitude for every parameter and every pose. "δL_c/2" halves the geometric errors of
//! Table 13 only: compliance and forces stay, which is what keeps Table 16's random component
//! E_r the same in both rows.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::RngExt;
use rigcal_core::kinematics::{wrap, HeldChain};
use rigcal_core::rig::Rig;

/// The rig file of the nominal robot.
const RIG_TOML: &str = include_str!("../../../../../rigs/scara3.toml");

/// Number of error values: 13 geometric, 5 compliance, 8 force coefficients.
pub const N_ERRORS: usize = 26;

/// The nominal robot from `rigs/scara3.toml`.
pub fn nominal() -> Result<(Rig, HeldChain), rigcal_core::rig::RigError> {
    let rig = Rig::parse(RIG_TOML, Some(std::path::Path::new("rigs/scara3.toml")))?;
    let k = HeldChain::new(rig.chain.clone(), rig.held());
    Ok((rig, k))
}

/// Table 13–15 constant errors δL_c (mm, rad, m/N, rad/(N·m), force coefficients).
fn constant_errors() -> [f64; N_ERRORS] {
    let m = 1e-3; // mrad
    [
        2.5,
        -2.2,
        2.3 * m,
        -1.7 * m,
        -1.7 * m,
        0.4,
        0.1 * m,
        -0.3 * m,
        0.7 * m,
        -0.4,
        0.2 * m,
        1.7 * m,
        0.1,
        1e-5,
        1e-5,
        1e-5,
        1e-5,
        1e-4,
        3.0,
        -6.0,
        12.0,
        -15.0,
        30.0,
        3.0,
        6.0,
        -18.0,
    ]
}

/// Random amplitudes δL_r of Tables 13–15.
fn random_amplitudes() -> [f64; N_ERRORS] {
    std::array::from_fn(|k| match k {
        0..=12 => {
            if [2, 3, 4, 6, 7, 8, 10, 11].contains(&k) {
                0.02e-3
            } else {
                0.02
            }
        }
        13..=17 => 1e-6,
        _ => 2.0,
    })
}

/// The simulated real 3-DOF SCARA.
#[derive(Debug, Clone, PartialEq)]
pub struct Scara3Real {
    /// Constant error values.
    pub constant: [f64; N_ERRORS],
}

impl Scara3Real {
    /// With Table 13's geometric errors scaled by `geometric_scale` (1 or ½), compliance and
    /// forces as in Tables 14–15.
    pub fn new(geometric_scale: f64) -> Self {
        let mut c = constant_errors();
        for v in c.iter_mut().take(13) {
            *v *= geometric_scale;
        }
        Self { constant: c }
    }

    /// The gripper position at `q` with the constant errors plus a random draw `r`.
    pub fn position(&self, q: &[f64], r: &[f64; N_ERRORS]) -> Vector3<f64> {
        let e: [f64; N_ERRORS] = std::array::from_fn(|k| self.constant[k] + r[k]);
        // Force at the nominal gripper position (m → N).
        let (c1, c2) = (q[0].cos(), (q[0] + q[1]).cos());
        let (s1, s2) = (q[0].sin(), (q[0] + q[1]).sin());
        let (x, y, z) = (
            (330.0 * c1 + 330.0 * c2) * 1e-3,
            (330.0 * s1 + 330.0 * s2) * 1e-3,
            q[2] * 1e-3,
        );
        let c = &e[18..26];
        let f = [
            c[0] * x + c[1] * x * y + c[2] * z,
            c[3] * x * x + c[4] * x * z,
            c[5] + c[6] * z + c[7] * x * y,
        ];
        let (xj, yj) = (0.330 * c1, 0.330 * s1);
        let t1 = x * f[1] - y * f[0];
        let t2 = (x - xj) * f[1] - (y - yj) * f[0];
        let (kxy, kz, kt1, kt2, kd) = (e[13], e[14], e[15], e[16], e[17]);
        let rx = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a);
        let ry = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::y_axis(), a);
        let rz = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a);
        let tr = |x: f64, y: f64, z: f64| {
            Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::identity())
        };
        let rot = |u: UnitQuaternion<f64>| Isometry3::from_parts(Translation3::identity(), u);
        let m = tr(e[0], e[1], 0.0)
            * rot(rx(e[2]) * ry(e[3]))
            * rot(rz(q[0] + e[4] + kt1 * t1))
            * tr(330.0 + e[5], 0.0, 0.0)
            * rot(rx(e[6]) * ry(e[7]))
            * rot(rz(q[1] + e[8] + kt2 * t2))
            * tr(330.0 + e[9], 0.0, 0.0)
            * rot(rx(e[10]) * ry(e[11]))
            * tr(0.0, 0.0, q[2] + e[12] + kd * f[2] * 1e3);
        let p = m * Point3::origin();
        p.coords + Vector3::new(kxy * f[0], kxy * f[1], kz * f[2]) * 1e3
    }

    /// A uniform random draw within ± `scale` × the amplitudes of Tables 13–15.
    pub fn draw<R: RngExt + ?Sized>(scale: f64, rng: &mut R) -> [f64; N_ERRORS] {
        let a = random_amplitudes();
        std::array::from_fn(|k| {
            let v = a[k] * scale;
            if v > 0.0 {
                rng.random_range(-v..v)
            } else {
                0.0
            }
        })
    }
}

/// Joint values of a random pose uniform in the torus workspace (R 130..530 mm, z 0..300 mm),
/// elbow q2 > 0, by the closed-form nominal inverse kinematics.
pub fn random_joints<R: RngExt + ?Sized>(rng: &mut R) -> Vec<f64> {
    let r = rng.random_range(130.0f64 * 130.0..530.0 * 530.0).sqrt();
    let phi = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let z = rng.random_range(0.0..300.0);
    let c = ((r * r - 2.0 * 330.0 * 330.0) / (2.0 * 330.0 * 330.0)).clamp(-1.0, 1.0);
    let q2 = c.acos();
    let q1 = phi - (330.0 * q2.sin()).atan2(330.0 + 330.0 * q2.cos());
    vec![wrap(q1), q2, z]
}
