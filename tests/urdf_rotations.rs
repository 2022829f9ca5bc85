//! `rigcal rig from-urdf` converts every fixed rotation exactly: a base yaw of π (UR's
//! `base_link` convention), −π and π/2, and arbitrary roll-pitch-yaw rotations in fixed joints
//! and joint origins. The rig's tip frame is compared with the URDF's, computed here from the
//! same xyz/rpy numbers with hand-built matrices (not through rigcal's URDF reader), to 1e-9 mm
//! at q = 0 and at random joint values.
//!
//! Before the fix, the yaw of π gave wrist 2 d = −115.7 mm and α = 90.0155°, 231 mm off, and
//! the command exited 0.

use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::Rig;
use std::f64::consts::{FRAC_PI_2, PI};
use std::process::Command;

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Fixed,
    Revolute,
    Prismatic,
}

/// One URDF joint: its origin (m, rad) and axis.
#[derive(Clone)]
struct Joint {
    name: &'static str,
    kind: Kind,
    xyz: [f64; 3],
    rpy: [f64; 3],
    axis: [f64; 3],
}

fn joint(name: &'static str, kind: Kind, xyz: [f64; 3], rpy: [f64; 3]) -> Joint {
    Joint {
        name,
        kind,
        xyz,
        rpy,
        axis: [0.0, 0.0, 1.0],
    }
}

/// UR10 as in `ur_description` (CB series), with the base rotation `base_rpy` at
/// `shoulder_pan_joint`'s origin, ending in a fixed `tool0`.
fn ur10(base_rpy: [f64; 3]) -> Vec<Joint> {
    use Kind::*;
    vec![
        joint("shoulder_pan_joint", Revolute, [0.0, 0.0, 0.1273], base_rpy),
        joint(
            "shoulder_lift_joint",
            Revolute,
            [0.0; 3],
            [FRAC_PI_2, 0.0, 0.0],
        ),
        joint("elbow_joint", Revolute, [-0.612, 0.0, 0.0], [0.0; 3]),
        joint(
            "wrist_1_joint",
            Revolute,
            [-0.5723, 0.0, 0.163941],
            [0.0; 3],
        ),
        joint(
            "wrist_2_joint",
            Revolute,
            [0.0, -0.1157, 0.0],
            [FRAC_PI_2, 0.0, 0.0],
        ),
        joint(
            "wrist_3_joint",
            Revolute,
            [0.0, 0.0922, 0.0],
            [-FRAC_PI_2, 0.0, 0.0],
        ),
        joint("tool0_fixed", Fixed, [0.0; 3], [0.0; 3]),
    ]
}

/// The URDF text of a chain `l0 → l1 → … → lN`.
fn urdf(chain: &[Joint]) -> String {
    let mut s = String::from("<?xml version=\"1.0\"?>\n<robot name=\"test\">\n");
    for i in 0..=chain.len() {
        s += &format!("  <link name=\"l{i}\"/>\n");
    }
    for (i, j) in chain.iter().enumerate() {
        let kind = match j.kind {
            Kind::Fixed => "fixed",
            Kind::Revolute => "revolute",
            Kind::Prismatic => "prismatic",
        };
        // `{:?}` prints every f64 so that it reads back exactly.
        s += &format!(
            "  <joint name=\"{}\" type=\"{kind}\">\n    <parent link=\"l{i}\"/>\n    <child link=\"l{}\"/>\n    <origin xyz=\"{:?} {:?} {:?}\" rpy=\"{:?} {:?} {:?}\"/>\n",
            j.name, i + 1, j.xyz[0], j.xyz[1], j.xyz[2], j.rpy[0], j.rpy[1], j.rpy[2]
        );
        if j.kind != Kind::Fixed {
            let (lo, hi) = match j.kind {
                Kind::Prismatic => (0.0, 0.5),
                _ => (-2.0 * PI, 2.0 * PI),
            };
            s += &format!(
                "    <axis xyz=\"{:?} {:?} {:?}\"/>\n    <limit lower=\"{lo:?}\" upper=\"{hi:?}\" effort=\"1\" velocity=\"1\"/>\n",
                j.axis[0], j.axis[1], j.axis[2]
            );
        }
        s += "  </joint>\n";
    }
    s + "</robot>\n"
}

fn rx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

fn ry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

fn rz(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Rotation by `a` about unit axis `u` (Rodrigues).
fn about(u: Vector3<f64>, a: f64) -> Matrix3<f64> {
    let k = Matrix3::new(0.0, -u.z, u.y, u.z, 0.0, -u.x, -u.y, u.x, 0.0);
    Matrix3::identity() + k * a.sin() + k * k * (1.0 - a.cos())
}

fn homogeneous(r: Matrix3<f64>, t: Vector3<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&t);
    m
}

/// The tip link's pose in the base link (mm) for joint values `q` (rad, or mm for prismatic
/// joints): URDF semantics, origin = Trans(xyz)·Rz(yaw)·Ry(pitch)·Rx(roll), then the motion.
fn urdf_fk(chain: &[Joint], q: &[f64]) -> Matrix4<f64> {
    let mut t = Matrix4::identity();
    let mut k = 0;
    for j in chain {
        let xyz = Vector3::from(j.xyz) * 1000.0;
        t *= homogeneous(rz(j.rpy[2]) * ry(j.rpy[1]) * rx(j.rpy[0]), xyz);
        let u = Vector3::from(j.axis).normalize();
        match j.kind {
            Kind::Fixed => {}
            Kind::Revolute => {
                t *= homogeneous(about(u, q[k]), Vector3::zeros());
                k += 1;
            }
            Kind::Prismatic => {
                t *= homogeneous(Matrix3::identity(), u * q[k]);
                k += 1;
            }
        }
    }
    t
}

/// Converts `chain` with the binary and checks the rig's tip frame (origin and points 1 m out
/// along each axis) against [`urdf_fk`] to 1e-9 mm at q = 0 and 300 random joint vectors.
fn converts_exactly(case: &str, chain: &[Joint]) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("{case}.urdf"));
    std::fs::write(&path, urdf(chain)).unwrap();
    let out = dir.path().join(format!("{case}.toml"));
    let tip = format!("l{}", chain.len());
    let o = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["rig", "from-urdf", path.to_str().unwrap(), "--base", "l0"])
        .args(["--tip", &tip, "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{case}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let rig = Rig::load(&out).unwrap();
    let e = ErrorParams::zeros(rig.chain.layout());
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let probes = [
        Vector4::new(0.0, 0.0, 0.0, 1.0),
        Vector4::new(1000.0, 0.0, 0.0, 1.0),
        Vector4::new(0.0, 1000.0, 0.0, 1.0),
        Vector4::new(0.0, 0.0, 1000.0, 1.0),
    ];
    let mut worst = 0.0f64;
    for k in 0..301 {
        let q: Vec<f64> = rig
            .chain
            .joints()
            .iter()
            .map(|j| match k {
                0 => 0.0f64.clamp(j.min, j.max),
                _ => rng.random_range(j.min..=j.max),
            })
            .collect();
        let rig_tip = rig.chain.frame().inverse() * rig.chain.tool_pose(&q, &e);
        let rig_m = rig_tip.to_homogeneous();
        let urdf_m = urdf_fk(chain, &q);
        for p in &probes {
            let d = (rig_m * p - urdf_m * p).norm();
            worst = worst.max(d);
            assert!(d < 1e-9, "{case}: {d:.3e} mm at q = {q:?}");
        }
    }
    eprintln!("{case}: largest difference {worst:.1e} mm");
}

#[test]
fn base_yaw_of_pi_as_ur_base_link() {
    converts_exactly("yaw_pi", &ur10([0.0, 0.0, PI]));
}

#[test]
fn base_yaw_of_minus_pi() {
    converts_exactly("yaw_minus_pi", &ur10([0.0, 0.0, -PI]));
}

#[test]
fn base_yaw_of_half_pi() {
    converts_exactly("yaw_half_pi", &ur10([0.0, 0.0, FRAC_PI_2]));
}

#[test]
fn yaw_of_pi_in_fixed_joints_before_and_after_the_moving_ones() {
    let mut chain = vec![joint(
        "world_to_base",
        Kind::Fixed,
        [0.1, -0.2, 0.05],
        [0.0, 0.0, PI],
    )];
    chain.extend(ur10([0.0, 0.0, PI]));
    let n = chain.len();
    chain[n - 1].rpy = [PI, 0.0, -PI];
    chain.push(joint("tcp", Kind::Fixed, [0.0, 0.0, 0.109], [0.0, 0.0, PI]));
    converts_exactly("fixed_pi", &chain);
}

#[test]
fn arbitrary_rotations_in_fixed_joints_and_origins() {
    let mut chain = vec![joint(
        "mount",
        Kind::Fixed,
        [0.3, 0.1, 0.7],
        [0.4, -1.1, 2.6],
    )];
    let mut arm = ur10([0.2, 0.35, -2.9]);
    arm[2].rpy = [-0.7, 0.25, 1.3];
    arm[3].rpy = [PI, FRAC_PI_2, -PI];
    arm[4].axis = [0.2, -0.3, 1.0];
    arm[6].rpy = [1.9, -0.6, 0.45];
    chain.extend(arm);
    chain.insert(
        4,
        Joint {
            axis: [0.0, 1.0, 0.0],
            ..joint(
                "slide",
                Kind::Prismatic,
                [0.01, 0.02, 0.03],
                [0.5, 0.6, -0.7],
            )
        },
    );
    converts_exactly("arbitrary", &chain);
}
