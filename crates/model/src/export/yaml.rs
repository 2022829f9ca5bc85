//! `rigcal export urdf --format yaml`: a flat list of the corrected joint offsets and origins,
//! for tools that patch their own robot description (a xacro's properties, a controller's
//! offsets) rather than load a URDF.

use super::urdf::{ExportedJoint, UrdfExport};
use nalgebra::Isometry3;
use rigcal_core::kinematics::JointKind;
use std::fmt::Write as _;

/// The YAML text of an export: per joint its offset (deg or mm, added to the commanded value
/// to get the URDF's angle in the uncalibrated description) and its calibrated and nominal
/// origins (metres and radians, as in URDF); then the tracker and marker.
pub fn offsets_yaml(x: &UrdfExport, source: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# rigcal export: calibrated joint origins for {}",
        q(source)
    );
    let _ = writeln!(
        s,
        "# Origins in metres and radians (URDF xyz, fixed-axis rpy), relative to the parent link."
    );
    let _ = writeln!(s, "format: rigcal-urdf-offsets\nversion: 1");
    let _ = writeln!(s, "base: {}\ntip: {}", q(&x.base), q(&x.tip));
    let _ = writeln!(s, "joints:");
    for j in &x.joints {
        joint(&mut s, j);
    }
    let _ = writeln!(s, "tracker_to_base: {}", pose(&x.tracker));
    let m = x.marker_mm / 1000.0;
    let n = super::urdf::number;
    let _ = writeln!(s, "marker_in_tip_m: [{}, {}, {}]", n(m.x), n(m.y), n(m.z));
    s
}

fn joint(s: &mut String, j: &ExportedJoint) {
    let (key, unit) = match j.kind {
        JointKind::Revolute => ("offset_deg", "revolute"),
        JointKind::Prismatic => ("offset_mm", "prismatic"),
    };
    let _ = writeln!(
        s,
        "  - name: {}\n    type: {unit}\n    {key}: {}",
        q(&j.name),
        j.offset
    );
    let _ = writeln!(s, "    origin: {}", pose(&j.calibrated));
    let _ = writeln!(s, "    nominal_origin: {}", pose(&j.nominal));
}

/// `{xyz: [...], rpy: [...]}` in metres and radians.
fn pose(p: &Isometry3<f64>) -> String {
    let t = p.translation.vector / 1000.0;
    let (r, pi, y) = p.rotation.euler_angles();
    let n = super::urdf::number;
    format!(
        "{{xyz: [{}, {}, {}], rpy: [{}, {}, {}]}}",
        n(t.x),
        n(t.y),
        n(t.z),
        n(r),
        n(pi),
        n(y)
    )
}

/// A YAML double-quoted scalar (JSON's escaping is valid YAML).
fn q(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| format!("\"{}\"", s.escape_default()))
}
