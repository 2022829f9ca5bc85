//! The synthetic 8-joint chain of the any-robot issue, written as a URDF: a prismatic lift, then
//! seven revolute joints (j3 and j4 parallel), the marker well off the last axis. `urdf_fk` is
//! its forward kinematics straight from the URDF's joint origins and axes (mm), independent of
//! rigcal's kinematics.
#![allow(dead_code)]

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use rigcal_core::rig::Rig;
use std::f64::consts::FRAC_PI_2;
use std::path::Path;
use std::process::Command;

/// (name, type, parent, child, xyz (m), rpy (rad), axis, limits)
pub type J = (
    &'static str,
    &'static str,
    &'static str,
    &'static str,
    [f64; 3],
    [f64; 3],
    [f64; 3],
    [f64; 2],
);

pub const JOINTS: [J; 9] = [
    (
        "lift",
        "prismatic",
        "base",
        "l1",
        [0.1, 0.0, 0.2],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.5],
    ),
    (
        "j1",
        "revolute",
        "l1",
        "l2",
        [0.0, 0.0, 0.15],
        [0.0, 0.0, 0.3],
        [0.0, 0.0, 1.0],
        [-2.5, 2.5],
    ),
    (
        "j2",
        "revolute",
        "l2",
        "l3",
        [0.05, 0.0, 0.1],
        [FRAC_PI_2, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [-2.0, 2.0],
    ),
    (
        "j3",
        "revolute",
        "l3",
        "l4",
        [0.3, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [-2.5, 2.5],
    ),
    (
        "j4",
        "revolute",
        "l4",
        "l5",
        [0.25, 0.02, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [-2.5, 2.5],
    ),
    (
        "j5",
        "revolute",
        "l5",
        "l6",
        [0.0, 0.1, 0.0],
        [-FRAC_PI_2, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [-2.5, 2.5],
    ),
    (
        "j6",
        "revolute",
        "l6",
        "l7",
        [0.0, 0.0, 0.12],
        [FRAC_PI_2, 0.2, 0.0],
        [0.0, 1.0, 0.0],
        [-2.5, 2.5],
    ),
    (
        "j7",
        "revolute",
        "l7",
        "l8",
        [0.0, 0.08, 0.0],
        [0.0, 0.0, 0.0],
        [0.3, 0.0, 1.0],
        [-3.0, 3.0],
    ),
    (
        "marker_mount",
        "fixed",
        "l8",
        "marker",
        [0.12, 0.05, 0.03],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0],
    ),
];

/// A link's `<inertial>`: kg and the centre of mass in the link frame (m).
pub type Inertial = Option<(f64, [f64; 3])>;

/// Links with their `<inertial>`.
pub const LINKS: [(&str, Inertial); 10] = [
    ("base", None),
    ("l1", Some((4.0, [0.0, 0.0, 0.05]))),
    ("l2", Some((3.0, [0.02, 0.0, 0.05]))),
    ("l3", Some((3.0, [0.15, 0.0, 0.01]))),
    ("l4", Some((2.0, [0.12, 0.01, 0.0]))),
    ("l5", Some((0.8, [0.0, 0.05, 0.0]))),
    ("l6", Some((0.6, [0.0, 0.0, 0.06]))),
    ("l7", Some((0.5, [0.0, 0.04, 0.0]))),
    ("l8", Some((0.4, [0.05, 0.02, 0.0]))),
    ("marker", Some((0.2, [0.0, 0.0, 0.0]))),
];

/// World pose (mm) at `q` of the frame of `link` (URDF semantics), and the link's centre of mass
/// in world coordinates (mm) when it has one.
pub fn urdf_link(q: &[f64], link: &str) -> (Isometry3<f64>, Option<Vector3<f64>>) {
    let mut t = Isometry3::identity();
    let mut k = 0;
    for (_, ty, _, child, xyz, rpy, axis, _) in JOINTS {
        t *= Isometry3::from_parts(
            Translation3::new(xyz[0] * 1000.0, xyz[1] * 1000.0, xyz[2] * 1000.0),
            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        );
        let ax = Unit::new_normalize(Vector3::from(axis));
        match ty {
            "revolute" => {
                t *= UnitQuaternion::from_axis_angle(&ax, q[k]);
                k += 1;
            }
            "prismatic" => {
                t *= Translation3::from(ax.into_inner() * q[k]);
                k += 1;
            }
            _ => {}
        }
        if child == link {
            let com = LINKS
                .iter()
                .find(|(l, _)| *l == link)
                .and_then(|(_, m)| *m)
                .map(|(_, c)| {
                    (t * nalgebra::Point3::new(c[0] * 1000.0, c[1] * 1000.0, c[2] * 1000.0)).coords
                });
            return (t, com);
        }
    }
    (t, None)
}

pub fn urdf() -> String {
    let mut s = String::from("<?xml version=\"1.0\"?>\n<robot name=\"synthetic8\">\n");
    for (l, mass) in LINKS {
        match mass {
            Some((kg, c)) => {
                s += &format!(
                    "  <link name=\"{l}\">\n    <inertial>\n      <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n      <mass value=\"{kg}\"/>\n      <inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/>\n    </inertial>\n  </link>\n",
                    c[0], c[1], c[2]
                );
            }
            None => s += &format!("  <link name=\"{l}\"/>\n"),
        }
    }
    for (name, ty, parent, child, xyz, rpy, axis, lim) in JOINTS {
        s += &format!(
            "  <joint name=\"{name}\" type=\"{ty}\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    <origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/>\n    <axis xyz=\"{} {} {}\"/>\n    <limit lower=\"{}\" upper=\"{}\" effort=\"1\" velocity=\"1\"/>\n  </joint>\n",
            xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2], axis[0], axis[1], axis[2], lim[0], lim[1]
        );
    }
    s + "</robot>\n"
}

/// The URDF's forward kinematics, straight from its definition (mm).
pub fn urdf_fk(q: &[f64]) -> Vector3<f64> {
    let mut t = Isometry3::identity();
    let mut k = 0;
    for (_, ty, _, _, xyz, rpy, axis, _) in JOINTS {
        t *= Isometry3::from_parts(
            Translation3::new(xyz[0] * 1000.0, xyz[1] * 1000.0, xyz[2] * 1000.0),
            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        );
        let ax = Unit::new_normalize(Vector3::from(axis));
        match ty {
            "revolute" => {
                t *= UnitQuaternion::from_axis_angle(&ax, q[k]);
                k += 1;
            }
            "prismatic" => {
                t *= Translation3::from(ax.into_inner() * q[k]);
                k += 1;
            }
            _ => {}
        }
    }
    t.translation.vector
}

/// Writes the URDF into `dir`, converts it with `rigcal rig from-urdf` (frame and marker free,
/// tracker instrument) and loads the rig file.
pub fn rig_in(dir: &Path) -> (Rig, std::path::PathBuf) {
    let urdf_path = dir.join("synthetic8.urdf");
    std::fs::write(&urdf_path, urdf()).expect("write urdf");
    let rig_path = dir.join("s8.toml");
    let o = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["rig", "from-urdf"])
        .arg(&urdf_path)
        .args(["--base", "base", "--tip", "marker", "--out"])
        .arg(&rig_path)
        .output()
        .expect("run rigcal");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (Rig::load(&rig_path).expect("rig"), rig_path)
}
