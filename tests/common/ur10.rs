//! The UR10 laser-tracker subsets (`tests/data/ur10-landgraf/`, provenance there) as the tests
//! use them: the rig from the shipped URDF and a series imported with the ordinary options.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The committed subsets.
pub const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/ur10-landgraf");
/// The URDF's joints, base to flange.
pub const JOINTS: [&str; 6] = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
];
/// Each series' file in its directory `Series_X`.
pub const SERIES: [(&str, &str); 4] = [
    ("A", "measurements_grid.csv"),
    ("B", "measurements_joint_configurations.csv"),
    ("C", "measurements_random_poses.csv"),
    ("D", "measurements_iso_cubes.csv"),
];

/// Runs rigcal, asserting success; its standard output and error.
pub fn ok(args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "rigcal {args:?} failed:\n{text}");
    text
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The rig from the shipped URDF (`base_link` to `tool0`), written in `dir`.
pub fn rig(dir: &Path) -> PathBuf {
    let rig = dir.join("ur10.toml");
    ok(&[
        "rig",
        "from-urdf",
        &format!("{DATA}/ur10.urdf"),
        "--base",
        "base_link",
        "--tip",
        "tool0",
        "--out",
        s(&rig),
    ]);
    rig
}

/// Series `name` (`A`…`D`) imported for `rig` into `dir/rec-NAME`: the probe's position in mm,
/// the joints in radians, and with `orientation` the probe's orientation (intrinsic xyz, deg).
pub fn import(dir: &Path, rig: &Path, name: &str, orientation: bool) -> PathBuf {
    let file = SERIES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, f)| *f)
        .unwrap_or_else(|| panic!("no series {name}"));
    let out = dir.join(format!("rec-{name}"));
    let (csv, joints) = (format!("{DATA}/Series_{name}/{file}"), JOINTS.join(","));
    let mut args = vec![
        "import",
        &csv,
        "--rig",
        s(rig),
        "--joints",
        &joints,
        "--point",
        "measurement_x,measurement_y,measurement_z",
        "--length-unit",
        "mm",
        "--angle-unit",
        "rad",
    ];
    if orientation {
        args.extend([
            "--orientation",
            "measurement_rx,measurement_ry,measurement_rz",
            "--euler",
            "intrinsic-xyz",
            "--orientation-unit",
            "deg",
        ]);
    }
    args.extend(["--out", s(&out)]);
    ok(&args);
    out
}
