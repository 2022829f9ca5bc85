//! The simulated world, checked against hand computations and closed forms: each effect does what
//! it says, the paper scenario has the paper's error sizes, malformed scenarios are named, and
//! `rigcal simulate` is deterministic. Units: mm and degrees in the assertions' comments.

use approx::assert_relative_eq;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::Recording;
use rigcal_core::rig::{Instrument, Rig, TablePanel};
use rigcal_sim::world::{
    fig6_path, panel_report, pin_angle_ok, Backlash, DriftTarget, Effect, Harmonic,
    JointCompliance, MeasurementSettings, MissReason, MotionHistory, PointMass, RegistrationOffset,
    Scenario, TableScale, TableSquareness, ThermalDrift, Touch, TransmissionError, World,
};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn rig(name: &str) -> Rig {
    Rig::load(Path::new(&format!("rigs/{name}.toml"))).unwrap()
}

fn deg(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| x.to_radians()).collect()
}

/// A world on `rig` with no geometric error, these effects and no random error.
fn world_with(rig: &Rig, effects: Vec<Arc<dyn Effect>>) -> World {
    World::with_effects(
        rig.chain.clone(),
        ErrorParams::zeros(rig.chain.layout()),
        rig.instrument.clone(),
        effects,
        MeasurementSettings::noise_only(0.0),
        1,
    )
}

fn table_panel(rig: &Rig) -> TablePanel {
    match &rig.instrument {
        Instrument::TablePanel(tp) => tp.clone(),
        _ => panic!("not a table rig"),
    }
}

#[test]
fn backlash_is_zero_until_moved_and_flips_with_the_approach_direction() {
    let rig = rig("rv-m2-ideal");
    let b = 0.02f64.to_radians();
    let mut w = world_with(
        &rig,
        vec![Arc::new(Backlash {
            joint: 1,
            lost_motion: b,
        })],
    );
    let q = |q2: f64, q1: f64| deg(&[q1, q2, -30.0, 0.0, 0.0]);
    // First command: the joint has not moved, no lost motion.
    let a = w.move_arm(&q(30.0, 10.0), 0.0);
    assert_eq!(a.actual[1], a.commanded[1]);
    // Approached from below: stops b/2 short.
    let a = w.move_arm(&q(40.0, 10.0), 1.0);
    assert_relative_eq!(a.actual[1] - a.commanded[1], -b / 2.0, epsilon = 1e-15);
    // From above: b/2 beyond, on the other side.
    let a = w.move_arm(&q(35.0, 10.0), 2.0);
    assert_relative_eq!(a.actual[1] - a.commanded[1], b / 2.0, epsilon = 1e-15);
    // Only J1 moves: J2 keeps the side it last came from; J1 has no backlash.
    let a = w.move_arm(&q(35.0, 20.0), 3.0);
    assert_relative_eq!(a.actual[1] - a.commanded[1], b / 2.0, epsilon = 1e-15);
    assert_eq!(a.actual[0], a.commanded[0]);
}

fn compliance(kg: f64, stiffness: f64) -> JointCompliance {
    JointCompliance {
        masses: vec![PointMass {
            link: 1,
            kg,
            at_mm: Vector3::new(-125.0, 0.0, 0.0),
        }],
        stiffness: vec![(1, stiffness), (2, stiffness)],
    }
}

#[test]
fn compliance_deflects_by_gravity_torque_over_stiffness() {
    let rig = rig("rv-m2-ideal");
    let chain = &rig.chain;
    let e = ErrorParams::zeros(chain.layout());
    let k = 1.0e4; // N·m/rad
    let c = compliance(4.0, k);
    // q2 = 0: the upper arm is horizontal (the tip of q = 0 is at z = 400 like the base);
    // a 4 kg mass 125 mm from the J2 axis carries 4 · 9.81 · 0.125 = 4.905 N·m.
    for (q2, lever) in [
        (0.0, 1.0),
        (45.0, 45f64.to_radians().cos()),
        (-30.0, 30f64.to_radians().cos()),
    ] {
        let q = deg(&[20.0, q2, -40.0, 0.0, 0.0]);
        let d = c.deflections(chain, &e, &q);
        assert_relative_eq!(d[0].1.abs(), 4.905 * lever / k, max_relative = 1e-9);
        // J3 does not carry the upper arm.
        assert!(d[1].1.abs() < 1e-15);
        // The deflection lowers the mass: gravity wins against the spring.
        let mut bent = q.clone();
        bent[1] += d[0].1;
        let mass_z = |q: &[f64]| {
            (chain.frame_before_joint(q, &e, 2) * nalgebra::Point3::new(-125.0, 0.0, 0.0)).z
        };
        assert!(mass_z(&bent) < mass_z(&q));
    }
    // Upper arm straight up (q2 = 90°): no torque, no deflection.
    let up = deg(&[20.0, 90.0, -40.0, 0.0, 0.0]);
    assert!(c.deflections(chain, &e, &up)[0].1.abs() < 1e-12);
    // Double the mass, double the deflection.
    let q = deg(&[0.0, 20.0, -60.0, 0.0, 0.0]);
    let one = c.deflections(chain, &e, &q)[0].1;
    let two = compliance(8.0, k).deflections(chain, &e, &q)[0].1;
    assert_relative_eq!(two, 2.0 * one, max_relative = 1e-12);
    // Through the world: the actual J2 angle is the commanded one plus the deflection.
    let mut w = world_with(&rig, vec![Arc::new(c.clone())]);
    let a = w.move_arm(&q, 0.0);
    assert_relative_eq!(a.actual[1] - q[1], one, max_relative = 1e-12);
}

#[test]
fn transmission_error_repeats_every_360_over_n() {
    let rig = rig("rv-m2-ideal");
    let amp = 0.01f64.to_radians();
    let t = TransmissionError {
        joint: 0,
        harmonics: vec![Harmonic {
            order: 3,
            amplitude: amp,
            phase: 0.0,
        }],
    };
    let mut w = world_with(&rig, vec![Arc::new(t.clone())]);
    for q1 in [-100.0, -17.0, 5.0, 33.3] {
        let a = t.error_at(f64::to_radians(q1));
        let b = t.error_at(f64::to_radians(q1 + 120.0));
        assert_relative_eq!(a, b, epsilon = 1e-15);
    }
    // 3 · 30° = 90°: the full amplitude; 3 · 60° = 180°: zero.
    let a = w.move_arm(&deg(&[30.0, 40.0, -40.0, 0.0, 0.0]), 0.0);
    assert_relative_eq!(a.actual[0] - a.commanded[0], amp, max_relative = 1e-9);
    let a = w.move_arm(&deg(&[60.0, 40.0, -40.0, 0.0, 0.0]), 0.0);
    assert!((a.actual[0] - a.commanded[0]).abs() < 1e-15);
}

#[test]
fn thermal_drift_grows_with_time() {
    let rig = rig("rv-m2-ideal");
    let joint = ThermalDrift {
        target: DriftTarget::Joint(2),
        amplitude: 0.02f64.to_radians(),
        tau_s: 600.0,
    };
    let axis = ThermalDrift {
        target: DriftTarget::Axis(2),
        amplitude: 0.05,
        tau_s: 600.0,
    };
    let mut w = world_with(&rig, vec![Arc::new(joint), Arc::new(axis.clone())]);
    let q = deg(&[10.0, 40.0, -50.0, 0.0, 0.0]);
    let mut last = -1.0;
    for t in [0.0, 60.0, 600.0, 3600.0] {
        let a = w.move_arm(&q, t);
        let dq3 = a.actual[2] - q[2];
        let expect = 0.02f64.to_radians() * (1.0 - (-t / 600.0f64).exp());
        assert_relative_eq!(dq3, expect, epsilon = 1e-15);
        assert!(dq3 > last);
        last = dq3;
    }
    // At t = τ the tip has risen by 0.05 · (1 − 1/e) = 0.0316 mm along z (J3 unchanged).
    let mut only_axis = world_with(&rig, vec![Arc::new(axis)]);
    let dz = only_axis.move_arm(&q, 600.0).tip - only_axis.true_position(&q);
    assert_relative_eq!(dz.z, 0.05 * (1.0 - (-1.0f64).exp()), epsilon = 1e-12);
    assert!(dz.x.abs() < 1e-12 && dz.y.abs() < 1e-12);
}

#[test]
fn table_scale_grows_with_travel_and_squareness_shears() {
    let rig = rig("rv-m2");
    let nominal = table_panel(&rig).table_to_world_mm;
    let s = 1000e-6;
    let w = world_with(&rig, vec![Arc::new(TableScale { axis: 0, scale: s })]);
    for x in [0.0, 100.0, 500.0, 800.0] {
        let r = Vector3::new(x, 250.0, 100.0);
        let err = w.panel_centre(&r).unwrap() - (r + nominal);
        // reading = true · (1 + s): true = x / 1.001, short by x · s / (1 + s).
        assert_relative_eq!(err.x, -x * s / (1.0 + s), epsilon = 1e-12);
        assert!(err.y.abs() < 1e-12 && err.z.abs() < 1e-12);
    }
    let g = 0.01f64.to_radians();
    let w = world_with(
        &rig,
        vec![Arc::new(TableSquareness {
            first: 0,
            second: 1,
            angle: g,
        })],
    );
    let at = |r: Vector3<f64>| w.panel_centre(&r).unwrap() - (r + nominal);
    // Along x nothing changes; 400 mm along y leans 400 · sin 0.01° = 0.0698 mm towards x.
    assert!(at(Vector3::new(300.0, 0.0, 50.0)).norm() < 1e-12);
    let e = at(Vector3::new(0.0, 400.0, 0.0));
    assert_relative_eq!(e.x, 400.0 * g.sin(), epsilon = 1e-12);
    assert_relative_eq!(e.y, 400.0 * (g.cos() - 1.0), epsilon = 1e-12);
    let off = RegistrationOffset {
        offset: Isometry3::from_parts(
            Translation3::new(0.3, -0.2, 0.1),
            UnitQuaternion::identity(),
        ),
    };
    let w = world_with(&rig, vec![Arc::new(off)]);
    let r = Vector3::new(10.0, 20.0, 30.0);
    let e = w.panel_centre(&r).unwrap() - (r + nominal);
    assert_relative_eq!(e, Vector3::new(0.3, -0.2, 0.1), epsilon = 1e-12);
}

#[test]
fn panel_quantisation_error_is_one_count_over_root_12() {
    let tp = table_panel(&rig("rv-m2"));
    // Hand computation: u = 0 lies in count 256, whose centre is 0.5 · 133/512 = 0.12988 mm.
    match panel_report(&tp, [0.0, 0.0], true) {
        Touch::Contact { counts, uv_mm } => {
            assert_eq!(counts, [256, 128]);
            assert_relative_eq!(uv_mm[0], 0.5 * 133.0 / 512.0, epsilon = 1e-12);
            assert_relative_eq!(uv_mm[1], 0.5 * 80.0 / 256.0, epsilon = 1e-12);
        }
        other => panic!("{other:?}"),
    }
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut su, mut sv, n) = (0.0, 0.0, 50_000);
    for _ in 0..n {
        let uv = [rng.random_range(-66.0..66.0), rng.random_range(-39.5..39.5)];
        let Touch::Contact { uv_mm, .. } = panel_report(&tp, uv, true) else {
            panic!("inside the panel")
        };
        su += (uv_mm[0] - uv[0]).powi(2);
        sv += (uv_mm[1] - uv[1]).powi(2);
    }
    let (ru, rv) = ((su / n as f64).sqrt(), (sv / n as f64).sqrt());
    // 133/512/√12 = 0.0750 mm, 80/256/√12 = 0.0902 mm.
    assert_relative_eq!(ru, 133.0 / 512.0 / 12f64.sqrt(), max_relative = 0.02);
    assert_relative_eq!(rv, 80.0 / 256.0 / 12f64.sqrt(), max_relative = 0.02);
    assert_eq!(
        panel_report(&tp, [67.0, 0.0], true),
        Touch::Missed(MissReason::NotOverPanel)
    );
}

#[test]
fn the_15_degree_rule() {
    let tp = table_panel(&rig("rv-m2"));
    // A rotation by θ about y turns the pin (tool x) to (cos θ, 0, −sin θ): θ below horizontal.
    let pose = |down: f64| {
        Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_euler_angles(0.0, f64::to_radians(down), 0.0),
        )
    };
    assert!(pin_angle_ok(&pose(20.0), &tp.pin_axis, tp.min_pin_angle));
    assert!(pin_angle_ok(&pose(90.0), &tp.pin_axis, tp.min_pin_angle));
    assert!(!pin_angle_ok(&pose(10.0), &tp.pin_axis, tp.min_pin_angle));
    assert!(!pin_angle_ok(&pose(-30.0), &tp.pin_axis, tp.min_pin_angle));
}

#[test]
fn a_table_measurement_reads_the_true_tip_to_within_quantisation() {
    let rig = rig("rv-m2");
    let mut w = world_with(&rig, vec![]);
    // Forearm pointing down by 30°: a pose the rig can measure.
    let q = deg(&[0.0, 30.0, -90.0, 0.0, 0.0]);
    let r = w.measure_at(&q, 0.0, 1, 0);
    assert_eq!(r.missed, None, "{r:?}");
    let p = r.position.unwrap();
    let d = p - r.tip;
    assert!(
        d.x.abs() <= 133.0 / 1024.0 + 1e-9 && d.y.abs() <= 80.0 / 512.0 + 1e-9,
        "{d}"
    );
    assert!(d.z.abs() < 1e-9);
    let uv = r.panel_uv.unwrap();
    assert_relative_eq!(
        r.table.unwrap().x - uv[0] + -400.0,
        p.x - uv[0],
        epsilon = 1e-9
    );
    // Pin pointing up (q3 = 0, upper arm up): the panel cannot register it.
    let up = deg(&[0.0, 60.0, -10.0, 0.0, 0.0]);
    let miss = w.measure_at(&up, 1.0, 2, 0);
    assert!(matches!(
        miss.missed,
        Some(MissReason::PinAngle | MissReason::OutOfTravel)
    ));
    assert_eq!(miss.position, None);
}

#[test]
fn paper_scenario_has_the_papers_error_sizes() {
    let sc = Scenario::load(Path::new("sim/paper-sim.toml"), None).unwrap();
    let w = sc.world();
    let split = w.error_split(&fig6_path(101, w.chain().dof()));
    let (lo, hi) = split.total_range();
    let share = split.share();
    println!(
        "Fig. 6 path: {lo:.3}–{hi:.3} mm, mean {:.3} mm, non-geometric share {:.2} %",
        split.mean_total(),
        100.0 * share
    );
    assert!(lo >= 0.4 && hi <= 1.2, "{lo}–{hi}");
    assert!((0.08..=0.10).contains(&share), "{share}");
    // The noisy variant: the mean noise vector length σ·√(8/π) is about 3 % of the mean error.
    let noisy = Scenario::load(Path::new("sim/paper-sim-noise.toml"), None).unwrap();
    let ratio = noisy.measurement.noise_mm * (8.0 / std::f64::consts::PI).sqrt()
        / noisy.world().error_split(&fig6_path(101, 5)).mean_total();
    assert!((0.02..=0.04).contains(&ratio), "{ratio}");
    assert_eq!(noisy.truth, sc.truth);
}

#[test]
fn paper_fig6_scenario_reads_eq6_as_gear_harmonics_at_a_share_of_8_to_10_percent() {
    let sc = Scenario::load(Path::new("sim/paper-fig6.toml"), None).unwrap();
    let literal = Scenario::load(Path::new("sim/paper-sim.toml"), None).unwrap();
    assert_eq!(sc.truth, literal.truth, "the same pinned geometric errors");
    let w = sc.world();
    // Δq_i = 0.008° · sin(k_i q_i + φ_i), k = (4, 5, 6), φ = (30°, 70°, 110°), by hand at
    // q = (60°, 60°, −35°): sin 270° = −1, sin 370° = sin 10°, sin(−100°).
    let q = deg(&[60.0, 60.0, -35.0, 0.0, 0.0]);
    let mut h = MotionHistory::default();
    h.record(&q, 0.0);
    let actual = w.actual_joints(&q, 0.0, &h);
    let expected = [
        -0.008,
        0.008 * 10f64.to_radians().sin(),
        0.008 * (-100f64).to_radians().sin(),
    ];
    for j in 0..3 {
        assert_relative_eq!(
            (actual[j] - q[j]).to_degrees(),
            expected[j],
            epsilon = 1e-12
        );
    }
    let split = w.error_split(&fig6_path(101, w.chain().dof()));
    let (lo, hi) = split.total_range();
    assert!(lo >= 0.4 && hi <= 1.2, "{lo}–{hi}");
    let share = split.share();
    assert!(
        (0.091..=0.093).contains(&share),
        "the file says 9.2 %: {share}"
    );
}

#[test]
fn every_shipped_scenario_loads() {
    let mut n = 0;
    for entry in std::fs::read_dir("sim").unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let sc = Scenario::load(&path, None).unwrap_or_else(|e| panic!("{e}"));
            let mut w = sc.world();
            let r = w.measure_at(&deg(&[0.0, 30.0, -90.0, 0.0, 0.0]), 0.0, 1, 0);
            assert!(r.tip.iter().all(|v| v.is_finite()));
            n += 1;
        }
    }
    assert!(n >= 3);
}

fn write_scenario(dir: &Path, body: &str, rig: &str) -> PathBuf {
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("rigs").join(rig);
    let path = dir.join("bad.toml");
    std::fs::write(
        &path,
        format!("rig = {:?}\n{body}", rig.display().to_string()),
    )
    .unwrap();
    path
}

#[test]
fn malformed_scenarios_name_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("seed = 1\n[[effects]]\nkind = \"gear_wobble\"\n", "rv-m2-ideal.toml", "effects[0].kind", "unknown effect kind `gear_wobble`"),
        (
            "seed = 1\n[[effects]]\nkind = \"joint_compliance\"\nmasses = [{ link = 2, kg = 3.0, at_mm = [-125.0, 0.0, 0.0] }]\njoints = [{ joint = 2, stiffness_nm_per_rad = -5.0 }]\n",
            "rv-m2-ideal.toml",
            "effects[0].joints[0].stiffness_nm_per_rad",
            "must be positive",
        ),
        ("[geometric]\nvalues = { a1 = 0.1 }\n", "rv-m2-ideal.toml", "", "missing field `seed`"),
        ("seed = 1\n[[effects]]\nkind = \"backlash\"\njoint = 2\n", "rv-m2-ideal.toml", "effects[0]", "missing field `lost_motion_deg`"),
        ("seed = 1\n[geometric]\nvalues = { theta9 = 0.1 }\n", "rv-m2-ideal.toml", "geometric.values.theta9", "not a parameter"),
        ("seed = 1\n[[effects]]\nkind = \"backlash\"\njoint = 6\nlost_motion_deg = 0.01\n", "rv-m2-ideal.toml", "effects[0].joint", "out of range 1..5"),
        ("seed = 1\n[[effects]]\nkind = \"table_scale\"\naxis = \"x\"\nscale_ppm = 50.0\n", "rv-m2-ideal.toml", "effects[0].kind", "table_panel"),
        ("seed = 1\n[[effects]]\nkind = \"table_scale\"\naxis = \"w\"\nscale_ppm = 50.0\n", "rv-m2.toml", "effects[0].axis", "not an axis"),
        ("seed = 1\n[measurement]\nquantize = true\n", "rv-m2.toml", "", "unknown field `quantize`"),
        ("seed = 1\n[[effects]]\nkind = \"backlash\"\njoint = 1\nlost_motion_deg = 0.01\nside = 2\n", "rv-m2.toml", "effects[0]", "unknown field `side`"),
    ];
    for (body, rig, key, what) in cases {
        let path = write_scenario(dir.path(), body, rig);
        let e = Scenario::load(&path, None).unwrap_err().to_string();
        assert!(e.contains(&path.display().to_string()), "{e}");
        assert!(e.contains(what), "{e}");
        if !key.is_empty() {
            assert!(e.contains(&format!("`{key}`")), "{e}");
        }
    }
}

#[test]
fn motion_history_snapshot_resumes_the_same_draws() {
    let sc = Scenario::load(Path::new("sim/rig-realistic.toml"), None).unwrap();
    let poses: Vec<Vec<f64>> = (0..10)
        .map(|k| {
            deg(&[
                -20.0 + 4.0 * k as f64,
                30.0 + (k % 3) as f64,
                -90.0 + k as f64,
                0.0,
                0.0,
            ])
        })
        .collect();
    let mut whole = sc.world();
    let all: Vec<_> = poses
        .iter()
        .enumerate()
        .map(|(k, q)| whole.measure_at(q, 5.0 * k as f64, k as u64 + 1, 0))
        .collect();
    let mut first = sc.world();
    for (k, q) in poses.iter().enumerate().take(5) {
        first.measure_at(q, 5.0 * k as f64, k as u64 + 1, 0);
    }
    let journal = serde_json::to_string(&first.snapshot()).unwrap();
    let mut resumed = sc.world();
    resumed.restore(serde_json::from_str::<MotionHistory>(&journal).unwrap());
    for (k, q) in poses.iter().enumerate().skip(5) {
        let r = resumed.measure_at(q, 5.0 * k as f64, k as u64 + 1, 0);
        assert_eq!(r, all[k]);
    }
    // Backlash makes the history matter: a fresh world measures pose 6 differently.
    let fresh = sc.world().measure_at(&poses[5], 25.0, 6, 0);
    assert_ne!(fresh.arm.actual, all[5].arm.actual);
}

fn simulate(args: &[&str]) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .arg("simulate")
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn simulate_is_deterministic_and_writes_table_columns() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str| {
        let out = dir.path().join(name);
        simulate(&[
            "--rig",
            "rigs/rv-m2.toml",
            "--scenario",
            "sim/rig-realistic.toml",
            "--random",
            "300",
            "--seed",
            "5",
            "--out",
            out.to_str().unwrap(),
        ]);
        out
    };
    let (a, b) = (run("a"), run("b"));
    for f in ["measurements.csv", "session.toml"] {
        assert_eq!(
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap()
        );
    }
    let rig = rig("rv-m2");
    let rec = Recording::read(&a, rig.chain.joints()).unwrap();
    assert_eq!(rec.rows.len(), 300);
    assert_eq!(rec.session.as_ref().unwrap().seed, Some(5));
    let measured: Vec<_> = rec.measured().collect();
    assert!(!measured.is_empty());
    for (m, p) in measured {
        let (t, uv) = (m.table.unwrap(), m.panel_uv.unwrap());
        assert_relative_eq!(p, t + Vector3::new(-400.0, 170.0, -50.0), epsilon = 2e-5);
        assert!(uv[0].abs() < 66.5 && uv[1].abs() < 40.0);
    }

    // A poses file on the ideal rig: rows in the file's order.
    let poses = dir.path().join("poses.csv");
    std::fs::write(
        &poses,
        "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg\n60,60,-35,0,0\n125,90,-10,0,0\n",
    )
    .unwrap();
    let out = dir.path().join("paper");
    simulate(&[
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--scenario",
        "sim/paper-sim.toml",
        "--poses",
        poses.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let rec = Recording::read(&out, rig.chain.joints()).unwrap();
    assert_eq!(rec.rows.len(), 2);
    assert_relative_eq!(rec.rows[1].q[0], 125f64.to_radians(), epsilon = 1e-9);
    let sc = Scenario::load(Path::new("sim/paper-sim.toml"), None).unwrap();
    let truth = sc.world().true_position(&rec.rows[0].q);
    assert_relative_eq!(rec.rows[0].position.unwrap(), truth, epsilon = 1e-4);
}
