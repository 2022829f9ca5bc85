//! Compliance for any arm (issue 35, item 3): the payload a rig file states (`payload` in
//! `[robot]`: what the arm carries at the tool while recorded) loads every joint's gravity
//! torque, so the diagnosis's `deg_per_nm` is the joint's own compliance, not compliance
//! scaled by the share of the torque the link masses alone give.
//!
//! The arm is `tests/common/synthetic8.rs`'s 8-joint URDF (link masses from `<inertial>`), seen
//! by a tracker. Units: kg, mm, degrees in the assertions.

mod common;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::{Instrument, LinkMass, Rig};
use rigcal_model::diagnosis::{diagnose, Options};
use rigcal_model::effects::compliance::gravity_torque;
use rigcal_model::effects::EffectContext;
use rigcal_model::identification::random_poses;
use rigcal_sim::world::{Effect, JointCompliance, MeasurementSettings, PointMass, World};
use std::sync::Arc;

const PAYLOAD_KG: f64 = 3.0;
const PAYLOAD_COM_MM: [f64; 3] = [0.0, 0.0, 40.0];
const DEG_PER_NM: f64 = 0.005;
/// The joint that complies (0-based: joint 3).
const JOINT: usize = 2;

/// The rig of `synthetic8` with `payload = { kg, com_mm }` in `[robot]`, parsed from text.
fn rig_with_payload(dir: &std::path::Path) -> (Rig, Rig) {
    let (plain, path) = common::synthetic8::rig_in(dir);
    let text = std::fs::read_to_string(&path).expect("rig text");
    let with = text.replacen(
        "[robot]\n",
        &format!(
            "[robot]\npayload = {{ kg = {PAYLOAD_KG}, com_mm = [{}, {}, {}] }}\n",
            PAYLOAD_COM_MM[0], PAYLOAD_COM_MM[1], PAYLOAD_COM_MM[2]
        ),
        1,
    );
    assert_ne!(with, text, "the rig file has a [robot] section");
    (
        plain,
        Rig::parse(&with, Some(&path)).expect("rig with payload"),
    )
}

/// The payload folded into the last link loads every joint as the link mass and the payload
/// apart do: checked against the torque of the payload as a separate point (the model term's
/// `payload_kg` at the tool frame's origin, shifted by its centre's torque computed apart).
#[test]
fn a_rig_payload_loads_every_joint_as_a_separate_mass_would() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (plain, rig) = rig_with_payload(dir.path());
    let p = rig.payload.expect("payload parsed");
    assert_eq!(p.kg, PAYLOAD_KG);
    assert_eq!(plain.payload, None);
    let folded = rig.masses_with_payload();
    let n = rig.chain.dof();
    let e = ErrorParams::zeros(rig.chain.layout());
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    // The payload alone, as a mass on the last link with nothing else.
    let mut payload_only: Vec<Option<LinkMass>> = vec![
        Some(LinkMass {
            kg: 0.0,
            com_mm: Vector3::zeros()
        });
        n
    ];
    payload_only[n - 1] = Some(p);
    for q in random_poses(rig.chain.joints(), rig.held(), 10, &mut rng) {
        for j in 0..n {
            let torque = |m: &[Option<LinkMass>]| {
                let ctx = EffectContext {
                    chain: &rig.chain,
                    e: &e,
                    masses: m,
                    payload_kg: 0.0,
                };
                gravity_torque(&ctx, &q, j)
            };
            let apart = torque(&rig.link_masses) + torque(&payload_only);
            let together = torque(&folded);
            assert!(
                (apart - together).abs() < 1e-9 * apart.abs().max(1.0),
                "joint {}: {apart} vs {together}",
                j + 1
            );
        }
        // With the payload at the tool frame's origin the model term's own payload agrees.
        let at_origin = LinkMass {
            kg: PAYLOAD_KG,
            com_mm: Vector3::zeros(),
        };
        let mut r0 = rig.clone();
        r0.payload = Some(at_origin);
        let ctx = EffectContext {
            chain: &rig.chain,
            e: &e,
            masses: &rig.link_masses,
            payload_kg: PAYLOAD_KG,
        };
        let folded0 = r0.masses_with_payload();
        let ctx0 = EffectContext {
            chain: &rig.chain,
            e: &e,
            masses: &folded0,
            payload_kg: 0.0,
        };
        for j in 0..n {
            let (a, b) = (gravity_torque(&ctx, &q, j), gravity_torque(&ctx0, &q, j));
            assert!(
                (a - b).abs() < 1e-9 * a.abs().max(1.0),
                "joint {}: {a} vs {b}",
                j + 1
            );
        }
    }
    let bad = std::fs::read_to_string(dir.path().join("s8.toml"))
        .expect("text")
        .replacen("[robot]\n", "[robot]\npayload = { kg = -1.0 }\n", 1);
    let err = Rig::parse(&bad, None)
        .expect_err("negative payload refused")
        .to_string();
    assert!(err.contains("robot.payload.kg"), "{err}");
}

/// A tracker recording of the arm carrying the payload, joint 3 compliant: with the payload in
/// the rig file the diagnosis gives the compliance within its σ; without it, the torques it
/// assumes are short of the payload's and the compliance it gives is too large.
#[test]
fn a_rig_payload_gives_the_joint_compliance_the_arm_has() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (plain, rig) = rig_with_payload(dir.path());
    let mut masses: Vec<PointMass> = rig
        .link_masses
        .iter()
        .enumerate()
        .filter_map(|(k, m)| {
            m.map(|m| PointMass {
                link: k,
                kg: m.kg,
                at_mm: m.com_mm,
            })
        })
        .collect();
    masses.push(PointMass {
        link: rig.chain.dof() - 1,
        kg: PAYLOAD_KG,
        at_mm: Vector3::from(PAYLOAD_COM_MM),
    });
    let compliance: Arc<dyn Effect> = Arc::new(JointCompliance {
        masses,
        stiffness: vec![(JOINT, 1.0 / DEG_PER_NM.to_radians())],
    });
    let frame = Isometry3::from_parts(
        Translation3::new(1800.0, -400.0, 900.0),
        UnitQuaternion::identity(),
    );
    let world = World::with_effects(
        rig.chain.with_frame(frame),
        ErrorParams::zeros(rig.chain.layout()),
        Instrument::Tracker,
        vec![compliance],
        MeasurementSettings::noise_only(0.02),
        11,
    );
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let poses = random_poses(rig.chain.joints(), rig.held(), 150, &mut rng);
    let mut rec = world.record(&poses, 1);
    for row in &mut rec.rows {
        row.t_s = None;
    }
    let _ = rng.random::<f64>();
    let fitted = |r: &Rig| {
        let rep = diagnose(r, &rec, &Options::default()).expect("diagnose");
        let e = rep
            .effects
            .iter()
            .find(|e| e.kind.to_string() == "joint_compliance" && e.joint == Some(JOINT + 1))
            .unwrap_or_else(|| panic!("compliance named:\n{}", rep.text()));
        let v = serde_json::to_value(e).expect("json");
        let c = v["params"]["deg_per_nm"].as_f64().expect("deg_per_nm");
        let s = v["params_sigma"]["deg_per_nm"].as_f64().expect("σ");
        (c, s, rep.text())
    };
    let (c, s, text) = fitted(&rig);
    eprintln!("with the payload: {c} ± {s} °/(N·m)\n{text}");
    assert!(
        (c - DEG_PER_NM).abs() < 4.0 * s,
        "{c} ± {s} vs {DEG_PER_NM}"
    );
    let (c0, s0, _) = fitted(&plain);
    eprintln!("without it: {c0} ± {s0} °/(N·m)");
    assert!(c0 - DEG_PER_NM > 4.0 * s0, "{c0} ± {s0} vs {DEG_PER_NM}");
}
