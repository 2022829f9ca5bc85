//! `rigcal export urdf`: the calibrated URDF, parsed back by urdf-rs with its forward kinematics
//! computed here from the parsed joints alone, has the model's forward kinematics from
//! `<base>_tracker` to `<tip>_marker` to 1e-6 mm at random poses, for random errors in every
//! parameter (measurement frame, base, links, tool, marker); every byte outside the rewritten
//! origins is kept. On the synthetic 8-joint chain, a branched fixture (base below the root, a
//! joint without `<origin>`, a continuous and a prismatic joint, a fixed flange) and the TIAGo
//! Pro URDF (tests/data/tiago-pro, from ../shared/data/tiago-pro).

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::Rig;
use rigcal_model::identification::ResidualStats;
use rigcal_model::model::{FitSummary, ModelBody, ModelFile, ParamEntry, Provenance};
use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

mod common;

fn rigcal(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let o = rigcal(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A rig from the URDF and a constant model with random errors in every parameter.
fn rig_and_model(dir: &Path, urdf: &Path, base: &str, tip: &str, seed: u64) -> (Rig, ErrorParams) {
    let rig_path = dir.join("rig.toml");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    ok(&[
        "rig",
        "from-urdf",
        &s(urdf),
        "--base",
        base,
        "--tip",
        tip,
        "--out",
        &s(&rig_path),
    ]);
    let rig = Rig::load(&rig_path).unwrap();
    let layout = rig.chain.layout();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut e = ErrorParams::zeros(layout);
    let mut parameters = Vec::new();
    for (i, id) in layout.ids().iter().enumerate() {
        let frame = matches!(id.transform, rigcal_core::kinematics::TransformId::Frame);
        let v = match (frame, id.kind.is_angle()) {
            (true, true) => rng.random_range(-2.0..2.0),
            (true, false) => rng.random_range(-2000.0..2000.0),
            (false, true) => rng.random_range(-0.5f64..0.5).to_radians(),
            (false, false) => rng.random_range(-3.0..3.0),
        };
        e.set(i, v);
        parameters.push(ParamEntry {
            name: layout.name(*id),
            value: id.kind.to_file_units(v),
            unit: id.kind.unit().into(),
            sigma: None,
        });
    }
    // The model file holds what was written, in file units: read the parameters back as the
    // export will.
    let file = ModelFile::new(
        &rig,
        Provenance::default(),
        ModelBody::Constant {
            parameters,
            fit: FitSummary {
                kappa_eq4: 1.0,
                before: ResidualStats::default(),
                after: ResidualStats::default(),
                sigma0_mm: 0.0,
                iterations: 0,
            },
        },
    );
    let model = dir.join("model.json");
    file.save(&model).unwrap();
    let loaded = ModelFile::load(&model).unwrap();
    let e = loaded.errors.params_at(&vec![0.0; rig.chain.dof()]);
    (rig, e)
}

/// Pose (mm) of every link in the root's frame at joint values `q` (by joint name; others 0),
/// straight from the parsed URDF.
fn link_poses(robot: &urdf_rs::Robot, q: &HashMap<String, f64>) -> HashMap<String, Isometry3<f64>> {
    let by_child: HashMap<&str, &urdf_rs::Joint> = robot
        .joints
        .iter()
        .map(|j| (j.child.link.as_str(), j))
        .collect();
    let mut out = HashMap::new();
    for l in &robot.links {
        let mut t = Isometry3::identity();
        let mut link = l.name.as_str();
        while let Some(j) = by_child.get(link) {
            let o = &j.origin;
            let origin = Isometry3::from_parts(
                Translation3::new(o.xyz[0] * 1000.0, o.xyz[1] * 1000.0, o.xyz[2] * 1000.0),
                UnitQuaternion::from_euler_angles(o.rpy[0], o.rpy[1], o.rpy[2]),
            );
            let axis =
                Unit::new_normalize(Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]));
            let v = q.get(&j.name).copied().unwrap_or(0.0);
            let motion = match j.joint_type {
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                    Isometry3::from_parts(
                        Translation3::identity(),
                        UnitQuaternion::from_axis_angle(&axis, v),
                    )
                }
                // The rig's prismatic values are mm.
                urdf_rs::JointType::Prismatic => Isometry3::from_parts(
                    Translation3::from(axis.into_inner() * v),
                    UnitQuaternion::identity(),
                ),
                _ => Isometry3::identity(),
            };
            t = origin * motion * t;
            link = j.parent.link.as_str();
        }
        out.insert(l.name.clone(), t);
    }
    out
}

/// Everything but the `<origin>` elements and the block the export adds.
fn without_origins(text: &str) -> String {
    let mut s = text.to_string();
    let block = "  <!-- rigcal: the fitted measurement frame and marker -->";
    if let Some(i) = s.find(block) {
        let end = s[i..].find("</robot>").unwrap() + i;
        s.replace_range(i..end, "");
    }
    let mut out = String::new();
    let mut rest = s.as_str();
    while let Some(i) = rest.find("<origin ") {
        out.push_str(&rest[..i]);
        let tail = &rest[i..];
        let close = tail.find('>').unwrap();
        let end = if tail[..=close].ends_with("/>") {
            close + 1
        } else {
            tail.find("</origin>").unwrap() + "</origin>".len()
        };
        rest = &tail[end..];
    }
    out.push_str(rest);
    out
}

fn round_trip(urdf_text: &str, base: &str, tip: &str, changed: usize) {
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("in.urdf");
    std::fs::write(&urdf, urdf_text).unwrap();
    let (rig, e) = rig_and_model(dir.path(), &urdf, base, tip, 7);
    let out = dir.path().join("out.urdf");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    ok(&[
        "export",
        "urdf",
        "--model",
        &s(&dir.path().join("model.json")),
        "--urdf",
        &s(&urdf),
        "--out",
        &s(&out),
    ]);
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(
        without_origins(&text),
        without_origins(urdf_text),
        "only origins change"
    );
    let before = urdf_text.matches("<origin").count();
    let differing = text.matches("<origin").count() - before;
    // The two added fixed joints carry an origin each, and joints without one get one.
    assert!((2..=2 + changed).contains(&differing), "{differing}");
    let robot = urdf_rs::read_from_string(&text).unwrap();
    let tracker = format!("{base}_tracker");
    let marker = format!("{tip}_marker");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut worst = 0.0f64;
    for _ in 0..200 {
        let q: Vec<f64> = rig
            .chain
            .joints()
            .iter()
            .map(|j| rng.random_range(j.min..=j.max))
            .collect();
        let named = rig
            .chain
            .joints()
            .iter()
            .zip(&q)
            .map(|(j, v)| (j.name.clone(), *v))
            .collect();
        let poses = link_poses(&robot, &named);
        let p = (poses[&tracker].inverse() * poses[&marker])
            .translation
            .vector;
        let expect = rig.chain.position(&q, &e);
        worst = worst.max((p - expect).norm());
    }
    assert!(worst < 1e-6, "worst {worst} mm");
    let yaml = dir.path().join("offsets.yaml");
    ok(&[
        "export",
        "urdf",
        "--model",
        &s(&dir.path().join("model.json")),
        "--urdf",
        &s(&urdf),
        "--out",
        &s(&yaml),
        "--format",
        "yaml",
    ]);
    let y = std::fs::read_to_string(&yaml).unwrap();
    for j in rig.chain.joints() {
        assert!(y.contains(&format!("  - name: \"{}\"", j.name)), "{y}");
    }
    let layout = rig.chain.layout();
    let first = &rig.chain.joints()[0];
    let kind = match first.kind {
        rigcal_core::kinematics::JointKind::Revolute => rigcal_core::kinematics::ParamKind::Theta,
        rigcal_core::kinematics::JointKind::Prismatic => rigcal_core::kinematics::ParamKind::D,
    };
    let id = rigcal_core::kinematics::ParamId {
        transform: rigcal_core::kinematics::TransformId::Link(1),
        kind,
    };
    let offset = kind.to_file_units(e.get(layout.index_of(id).unwrap()));
    let key = if kind == rigcal_core::kinematics::ParamKind::Theta {
        "offset_deg"
    } else {
        "offset_mm"
    };
    assert!(y.contains(&format!("{key}: {offset}")), "{offset} in {y}");
}

#[test]
fn the_synthetic_chain_exports_with_the_models_kinematics() {
    round_trip(&common::synthetic8::urdf(), "base", "marker", 9);
}

#[test]
fn a_branched_urdf_keeps_its_other_bytes_and_the_models_kinematics() {
    let text = std::fs::read_to_string("tests/fixtures/branched.urdf").unwrap();
    round_trip(&text, "pedestal", "flange", 4);
    // The tracker cannot be the parent of a link that has one: it hangs off the base.
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("in.urdf");
    std::fs::write(&urdf, &text).unwrap();
    rig_and_model(dir.path(), &urdf, "pedestal", "flange", 1);
    let out = dir.path().join("out.urdf");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    ok(&[
        "export",
        "urdf",
        "--model",
        &s(&dir.path().join("model.json")),
        "--urdf",
        &s(&urdf),
        "--out",
        &s(&out),
    ]);
    let robot = urdf_rs::read_from_string(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let j = robot
        .joints
        .iter()
        .find(|j| j.name == "pedestal_tracker_joint")
        .unwrap();
    assert_eq!(j.parent.link, "pedestal");
    assert_eq!(j.child.link, "pedestal_tracker");
}

#[test]
fn the_tiago_pro_arm_exports_with_the_models_kinematics() {
    let text = std::fs::read_to_string("tests/data/tiago-pro/tiago_pro_local.urdf").unwrap();
    round_trip(&text, "base_footprint", "arm_right_tool_link", 9);
}

#[test]
fn a_urdf_of_another_robot_is_refused_with_the_joint_named() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("in.urdf");
    std::fs::write(&urdf, common::synthetic8::urdf()).unwrap();
    rig_and_model(dir.path(), &urdf, "base", "marker", 2);
    let other =
        common::synthetic8::urdf().replace("<origin xyz=\"0.3 0 0\"", "<origin xyz=\"0.31 0 0\"");
    assert_ne!(
        other,
        common::synthetic8::urdf(),
        "the fixture's j3 origin is as written here"
    );
    let moved = dir.path().join("other.urdf");
    std::fs::write(&moved, other).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let o = rigcal(&[
        "export",
        "urdf",
        "--model",
        &s(&dir.path().join("model.json")),
        "--urdf",
        &s(&moved),
        "--out",
        &s(&dir.path().join("x.urdf")),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("does not describe this rig"), "{err}");
}
