//! Forward kinematics against spec/rig.md's check points, the analytic Jacobians against finite
//! differences, spherical coordinates against their closed form, and inverse kinematics.

use approx::assert_relative_eq;
use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{
    solve_position_ik, ErrorParams, IkError, IkOptions, Robot, SphericalFrame,
};
use rigcal_core::rig::Rig;
use std::path::Path;

fn rv_m2() -> Rig {
    Rig::load(Path::new("rigs/rv-m2.toml")).unwrap()
}

fn deg(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| x.to_radians()).collect()
}

#[test]
fn forward_kinematics_matches_the_spec_check_points() {
    let rig = rv_m2();
    let e = ErrorParams::zeros(rig.chain.layout());
    let p0 = rig.chain.position(&deg(&[0.0; 5]), &e);
    assert_relative_eq!(p0, Vector3::new(0.0, 725.0, 400.0), epsilon = 1e-9);
    let p1 = rig.chain.position(&deg(&[0.0, 90.0, -90.0, 0.0, 0.0]), &e);
    assert_relative_eq!(p1, Vector3::new(0.0, 475.0, 650.0), epsilon = 1e-9);
}

#[test]
fn forward_kinematics_matches_a_hand_derived_closed_form() {
    // With q4 = q5 = 0 the RV-M2's pin tip, derived by hand from Table I: radial reach
    // ρ = 120 + 250 cos q2 + 435 cos(q2 + q3), height 400 + 250 sin q2 + 435 sin(q2 + q3),
    // and azimuth q1 about the J1 axis at world (0, −80).
    let rig = rv_m2();
    let e = ErrorParams::zeros(rig.chain.layout());
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200 {
        let q: [f64; 3] = [
            rng.random_range(-2.6..2.6),
            rng.random_range(-0.5..1.7),
            rng.random_range(-2.0..0.0),
        ];
        let rho = 120.0 + 250.0 * q[1].cos() + 435.0 * (q[1] + q[2]).cos();
        let z = 400.0 + 250.0 * q[1].sin() + 435.0 * (q[1] + q[2]).sin();
        let expect = Vector3::new(rho * q[0].sin(), -80.0 + rho * q[0].cos(), z);
        let p = rig.chain.position(&[q[0], q[1], q[2], 0.0, 0.0], &e);
        assert_relative_eq!(p, expect, epsilon = 1e-9);
    }
}

fn random_params(n: usize, rng: &mut ChaCha8Rng) -> ErrorParams {
    let mut e = ErrorParams::zeros(&rigcal_core::kinematics::ParamLayout::new(vec![], 0));
    *e.as_vector_mut() = nalgebra::DVector::from_fn(n, |_, _| rng.random_range(-0.01..0.01));
    e
}

#[test]
fn parameter_jacobian_matches_central_differences() {
    for file in ["rigs/rv-m2.toml", "rigs/rv-m2-ideal.toml"] {
        let rig = Rig::load(Path::new(file)).unwrap();
        let chain = &rig.chain;
        let n = chain.layout().len();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for _ in 0..20 {
            let q: Vec<f64> = chain
                .joints()
                .iter()
                .map(|j| rng.random_range(j.min..j.max))
                .collect();
            let e = random_params(n, &mut rng);
            let (p, m) = chain.position_and_param_jacobian(&q, &e);
            assert_relative_eq!(p, chain.position(&q, &e), epsilon = 1e-12);
            let h = 1e-6;
            for k in 0..n {
                let mut ep = e.clone();
                let mut em = e.clone();
                ep.set(k, e.get(k) + h);
                em.set(k, e.get(k) - h);
                let fd = (chain.position(&q, &ep) - chain.position(&q, &em)) / (2.0 * h);
                let col = m.column(k);
                for r in 0..3 {
                    assert!(
                        (col[r] - fd[r]).abs() < 1e-5 * (1.0 + fd[r].abs()),
                        "param {} row {r}: {} vs {}",
                        chain.layout().name(chain.layout().ids()[k]),
                        col[r],
                        fd[r]
                    );
                }
            }
        }
    }
}

#[test]
fn joint_jacobian_matches_central_differences() {
    let rig = rv_m2();
    let chain = &rig.chain;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let e = random_params(chain.layout().len(), &mut rng);
    for _ in 0..20 {
        let q: Vec<f64> = chain
            .joints()
            .iter()
            .map(|j| rng.random_range(j.min..j.max))
            .collect();
        let jq = chain.joint_jacobian(&q, &e);
        for k in 0..q.len() {
            let h = 1e-6;
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[k] += h;
            qm[k] -= h;
            let fd = (chain.position(&qp, &e) - chain.position(&qm, &e)) / (2.0 * h);
            assert_relative_eq!(
                Vector3::new(jq[(0, k)], jq[(1, k)], jq[(2, k)]),
                fd,
                epsilon = 1e-5
            );
        }
    }
}

#[test]
fn spherical_coordinates_follow_the_conventions() {
    let rig = rv_m2();
    let sf = SphericalFrame::of(&rig.chain);
    assert_relative_eq!(sf.origin(), Vector3::new(0.0, -80.0, 400.0), epsilon = 1e-9);
    let e = ErrorParams::zeros(rig.chain.layout());
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    for _ in 0..100 {
        let q: [f64; 5] = [
            rng.random_range(-2.6..2.6),
            rng.random_range(-0.5..1.7),
            rng.random_range(-2.0..0.0),
            0.0,
            0.0,
        ];
        let p = rig.chain.position(&q, &e);
        let s = sf.to_spherical(&p);
        // azimuth = atan2(x, y + 80) = q1; elevation above the horizontal through the J1 origin.
        assert_relative_eq!(s.azimuth, p.x.atan2(p.y + 80.0), epsilon = 1e-12);
        assert_relative_eq!(s.azimuth, q[0], epsilon = 1e-9);
        let rho = p.x.hypot(p.y + 80.0);
        assert_relative_eq!(s.elevation, (p.z - 400.0).atan2(rho), epsilon = 1e-12);
        assert_relative_eq!(sf.to_world(&s), p, epsilon = 1e-9);
    }
}

#[test]
fn inverse_kinematics_recovers_reachable_targets_and_refuses_others() {
    let rig = rv_m2();
    let e = ErrorParams::zeros(rig.chain.layout());
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let opts = IkOptions::default();
    for _ in 0..100 {
        let q: Vec<f64> = vec![
            rng.random_range(-2.5..2.5),
            rng.random_range(-0.4..1.6),
            rng.random_range(-2.0..-0.1),
            0.0,
            0.0,
        ];
        let target = rig.chain.position(&q, &e);
        let sol = solve_position_ik(&rig.chain, &e, &target, rig.held(), None, &opts).unwrap();
        assert!((rig.chain.position(&sol, &e) - target).norm() < 1e-6);
    }
    let far = Vector3::new(0.0, 2000.0, 400.0);
    match solve_position_ik(&rig.chain, &e, &far, rig.held(), None, &opts) {
        Err(IkError::Unreachable { closest_mm, .. }) => assert!(closest_mm > 1000.0),
        other => panic!("expected unreachable, got {other:?}"),
    }
    // Straight behind the base (azimuth 180°) needs q1 = ±180°, outside ±150°.
    let behind = Vector3::new(0.0, -80.0 - 600.0, 400.0);
    match solve_position_ik(&rig.chain, &e, &behind, rig.held(), None, &opts) {
        Err(IkError::JointLimit { joint: 1, .. }) => {}
        other => panic!("expected a joint-1 limit, got {other:?}"),
    }
}

/// The one-pass frames before every joint equal the per-joint ones exactly (same products in
/// the same order), on every rig of `rigs/` with random errors and joint values.
#[test]
fn frames_before_every_joint_in_one_pass_equal_the_frame_before_each_joint() {
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    for file in ["rigs/rv-m2.toml", "rigs/tiago-pro.toml", "rigs/scara3.toml"] {
        let rig = Rig::load(Path::new(file)).unwrap();
        let chain = &rig.chain;
        let n = chain.joints().len();
        for _ in 0..20 {
            let q: Vec<f64> = chain
                .joints()
                .iter()
                .map(|j| rng.random_range(j.min..j.max))
                .collect();
            let e = random_params(chain.layout().len(), &mut rng);
            let all = chain.frames_before_joints(&q, &e);
            assert_eq!(all.len(), n + 1, "{file}");
            for (j, f) in all.iter().enumerate() {
                assert_eq!(*f, chain.frame_before_joint(&q, &e, j), "{file}, joint {j}");
            }
        }
    }
}
