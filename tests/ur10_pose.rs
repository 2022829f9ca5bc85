//! Identification from pose measurements (position and orientation of a 6-DoF probe) on the
//! committed UR10 subset (tests/data/ur10-landgraf/, provenance there) and on a simulated UR10.
//!
//! * The orientation residuals the library reports equal an independent computation: the
//!   measured rotation built from the raw file's Euler angles (intrinsic X-Y-Z, scipy `'XYZ'`,
//!   R = Rx·Ry·Rz) with nalgebra's axis-angle rotations, the modelled one from the chain's
//!   tool pose and the fitted marker rotation, and the angle from the trace of R_measuredᵀ·R_modelled.
//! * On a simulated UR10 with a known geometric error, tracker frame, marker point and marker
//!   rotation, fitting the orientations as well predicts held-out poses at least as well as
//!   positions alone, and recovers the marker rotation.
//! * Stated σ that equal the simulated noise give a weighted σ̂ of 1, and the σ estimated per
//!   block from the residuals find the noise.
//! * A recording without orientations fits as the position-only identification does.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use rigcal_core::kinematics::{ErrorParams, Robot, TransformId};
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::identification::pose::{
    identify_pose, pose_observations, PoseObservation, PoseOptions,
};
use rigcal_model::identification::{identify_at, random_poses, Level};
use std::path::{Path, PathBuf};

mod common;
use common::ur10::{import, ok, rig as ur10_rig, s, DATA, JOINTS};

const SERIES_A: &str = "Series_A/measurements_grid.csv";

/// Series A's subset imported with its orientations, in `dir`.
fn import_a(dir: &Path, rig: &Path) -> PathBuf {
    import(dir, rig, "A", true)
}

/// The raw file's rows, read here without the importer: `;` fields, decimal commas, CRLF.
/// Per row the six joints (rad) and the measured rotation R = Rx(rx)·Ry(ry)·Rz(rz) (deg in
/// the file: intrinsic X-Y-Z).
fn raw_rows(path: &str) -> Vec<(Vec<f64>, Matrix3<f64>)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.split("\r\n").filter(|l| !l.trim().is_empty());
    let header: Vec<&str> = lines.next().unwrap().split(';').collect();
    let col = |name: &str| header.iter().position(|h| h.trim() == name).unwrap();
    let joints: Vec<usize> = JOINTS.iter().map(|j| col(j)).collect();
    let angles = [
        col("measurement_rx"),
        col("measurement_ry"),
        col("measurement_rz"),
    ];
    lines
        .map(|line| {
            let f: Vec<f64> = line
                .split(';')
                .map(|v| {
                    v.trim()
                        .replace(',', ".")
                        .parse::<f64>()
                        .unwrap_or(f64::NAN)
                })
                .collect();
            let q = joints.iter().map(|&c| f[c]).collect();
            let about = |axis: Vector3<f64>, deg: f64| {
                *Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), deg.to_radians())
                    .matrix()
            };
            let r = about(Vector3::x(), f[angles[0]])
                * about(Vector3::y(), f[angles[1]])
                * about(Vector3::z(), f[angles[2]]);
            (q, r)
        })
        .collect()
}

/// The angle of a rotation matrix from its trace (rad).
fn angle_of(r: &Matrix3<f64>) -> f64 {
    ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
}

/// The rotation vector of a rotation matrix from its skew part (angle well below π).
fn rotation_vector(r: &Matrix3<f64>) -> Vector3<f64> {
    let theta = angle_of(r);
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    ) / 2.0;
    if theta < 1e-12 {
        v
    } else {
        v * (theta / theta.sin())
    }
}

#[test]
fn orientation_residuals_equal_an_independent_computation_from_the_raw_file() {
    let dir = tempfile::tempdir().unwrap();
    let rig_path = ur10_rig(dir.path());
    let rec_path = import_a(dir.path(), &rig_path);
    let rig = Rig::load(&rig_path).unwrap();
    let rec = Recording::read(&rec_path, rig.chain.joints()).unwrap();
    let obs = pose_observations(&rec);
    let (chain, pose) = identify_pose(&rig, &obs, Level::Full, &PoseOptions::default()).unwrap();
    let raw = raw_rows(&format!("{DATA}/{SERIES_A}"));
    assert_eq!(raw.len(), obs.len());
    let c = *pose.marker_rotation.to_rotation_matrix().matrix();
    let mut angles = Vec::new();
    for (k, (q, measured)) in raw.iter().enumerate() {
        // The recording keeps joints to 1e-8 rad; the computation here uses the raw values.
        let off = q
            .iter()
            .zip(&obs[k].q)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            off < 1e-7,
            "row {k}: joints differ from the import's by {off} rad"
        );
        let tool = *chain
            .tool_pose(q, &pose.fit.params)
            .rotation
            .to_rotation_matrix()
            .matrix();
        let relative = measured.transpose() * tool * c;
        let by_hand = rotation_vector(&relative);
        let reported = pose.orientation_residuals[k].expect("every row has an orientation");
        // The recording keeps the angles to 1e-6° (2e-8 rad): the two readings agree to that.
        assert!(
            (reported - by_hand).norm() < 1e-7,
            "row {k}: library {reported:?} rad, by hand {by_hand:?} rad"
        );
        angles.push(angle_of(&relative).to_degrees());
    }
    let n = angles.len() as f64;
    let mean = angles.iter().sum::<f64>() / n;
    let rms = (angles.iter().map(|a| a * a).sum::<f64>() / n).sqrt();
    let max = angles.iter().copied().fold(0.0, f64::max);
    let o = pose.orientation;
    assert_eq!(o.n, 99);
    for (library, hand) in [(o.mean_deg, mean), (o.rms_deg, rms), (o.max_deg, max)] {
        assert!((library - hand).abs() < 1e-5, "{library}° vs {hand}°");
    }
    // A fit worth the name: tenths of a millimetre and hundredths of a degree on real data,
    // the probe turned −90° about the flange axis (as the data's README found).
    assert!(pose.fit.after.rms_mm < 0.5 && o.rms_deg < 0.1, "{o:?}");
    let (_, _, yaw) = pose.marker_rotation.euler_angles();
    assert!(
        (yaw.to_degrees() + 90.0).abs() < 0.5,
        "marker yaw {}°",
        yaw.to_degrees()
    );
}

#[test]
fn identify_reports_position_and_orientation_apart() {
    let dir = tempfile::tempdir().unwrap();
    let rig = ur10_rig(dir.path());
    let rec = import_a(dir.path(), &rig);
    let model = dir.path().join("model.json");
    let args = [
        "identify",
        "--rig",
        s(&rig),
        "--recording",
        s(&rec),
        "--level",
        "full",
        "--out",
        s(&model),
    ];
    let text = ok(&args);
    assert!(text.contains("position residual (mm):"), "{text}");
    assert!(text.contains("orientation residual (°):"), "{text}");
    assert!(
        text.contains("estimated from the residuals of a first fit"),
        "{text}"
    );
    let mut position_only = args.to_vec();
    position_only.push("--position-only");
    let text = ok(&position_only);
    assert!(
        text.contains("orientation residual (°, not fitted: --position-only"),
        "{text}"
    );
}

/// A simulated UR10 measurement campaign: `n` random poses, measured with Gaussian noise of
/// `noise_mm` per coordinate and `noise_deg` per axis of a small rotation.
struct Campaign {
    truth: ErrorParams,
    marker_rotation: UnitQuaternion<f64>,
    obs: Vec<PoseObservation>,
}

fn campaign(rig: &Rig, seed: u64, n: usize, noise_mm: f64, noise_deg: f64) -> Campaign {
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let layout = rig.chain.layout();
    let mut truth = ErrorParams::zeros(layout);
    let frame = Isometry3::from_parts(
        Translation3::new(2600.0, -1500.0, -1300.0),
        UnitQuaternion::from_euler_angles(-0.6_f64.to_radians(), 0.1_f64.to_radians(), 2.6),
    );
    for (i, id) in layout.ids().iter().enumerate() {
        let v = match id.transform {
            TransformId::Frame => continue,
            // Every transform fixed to the flange (the last link's and the tool's) moves the
            // probe as a change of its pose does: the fit takes them as the marker's pose, so
            // they stay at nominal here and the marker rotation has one meaning.
            TransformId::Tool => 0.0,
            TransformId::Link(j) if j == rig.chain.joints().len() => 0.0,
            TransformId::Marker => match id.kind {
                rigcal_core::kinematics::ParamKind::Z => 93.0,
                _ => rng.random_range(-0.5..0.5),
            },
            _ if id.kind.is_angle() => rng.random_range(-0.03..0.03_f64).to_radians(),
            _ => rng.random_range(-0.3..0.3),
        };
        truth.set(i, v);
    }
    let truth_chain = rig.chain.with_frame(frame);
    let marker_rotation = UnitQuaternion::from_euler_angles(0.0007, -0.0016, -1.5703);
    let position_noise = Normal::new(0.0, noise_mm).unwrap();
    let turn_noise = Normal::new(0.0, noise_deg.to_radians()).unwrap();
    let poses = random_poses(rig.chain.joints(), rig.held(), n, &mut rng);
    let obs = poses
        .into_iter()
        .map(|q| {
            let noise = Vector3::from_fn(|_, _| position_noise.sample(&mut rng));
            let turn = Vector3::from_fn(|_, _| turn_noise.sample(&mut rng));
            let r = truth_chain.tool_pose(&q, &truth).rotation
                * marker_rotation
                * UnitQuaternion::from_scaled_axis(turn);
            PoseObservation {
                p: truth_chain.position(&q, &truth) + noise,
                q,
                orientation: Some(r),
                position_sigma: None,
                orientation_sigma: None,
            }
        })
        .collect();
    Campaign {
        truth: {
            // The truth as the fit reports it: absolute frame parameters for the rig's chain.
            let mut t = truth;
            let (roll, pitch, yaw) = frame.rotation.euler_angles();
            let v = frame.translation.vector;
            for (i, id) in layout.ids().iter().enumerate() {
                if id.transform == TransformId::Frame {
                    use rigcal_core::kinematics::ParamKind::*;
                    let x = match id.kind {
                        X => v.x,
                        Y => v.y,
                        Z => v.z,
                        Rx => roll,
                        Ry => pitch,
                        Rz => yaw,
                        _ => continue,
                    };
                    t.set(i, x);
                }
            }
            t
        },
        marker_rotation,
        obs,
    }
}

/// RMS position error (mm) of a fitted parameter set against the truth over `poses`.
fn prediction_rms(rig: &Rig, truth: &ErrorParams, fitted: &ErrorParams, poses: &[Vec<f64>]) -> f64 {
    let sum: f64 = poses
        .iter()
        .map(|q| (rig.chain.position(q, truth) - rig.chain.position(q, fitted)).norm_squared())
        .sum();
    (sum / poses.len() as f64).sqrt()
}

#[test]
fn orientation_rows_recover_a_simulated_error_and_the_marker_rotation() {
    let dir = tempfile::tempdir().unwrap();
    let rig = Rig::load(&ur10_rig(dir.path())).unwrap();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(99);
    let fresh = random_poses(rig.chain.joints(), rig.held(), 300, &mut rng);
    let mut ratios = Vec::new();
    // Five campaigns of 40 poses, tracker noise 0.02 mm and 0.003° (fixed before the run).
    for seed in 1..=5 {
        let c = campaign(&rig, seed, 40, 0.02, 0.003);
        let with = identify_pose(&rig, &c.obs, Level::Full, &PoseOptions::default()).unwrap();
        let without = identify_pose(
            &rig,
            &c.obs,
            Level::Full,
            &PoseOptions {
                use_orientation: false,
                ..Default::default()
            },
        )
        .unwrap();
        let rms_with = prediction_rms(&rig, &c.truth, &with.1.fit.params, &fresh);
        let rms_without = prediction_rms(&rig, &c.truth, &without.1.fit.params, &fresh);
        ratios.push(rms_with / rms_without);
        // The marker rotation, within 5 σ of its stated uncertainty and under 0.01°.
        // C_true = C_fitted·exp([φ]×), φ about the marker's own axes (as its σ).
        let local = (with.1.marker_rotation.inverse() * c.marker_rotation).scaled_axis();
        let sigma = with.1.marker_rotation_sigma;
        for k in 0..3 {
            assert!(
                local[k].abs() < 5.0 * sigma[k] + 1e-9 && local[k].abs().to_degrees() < 0.01,
                "seed {seed}: marker rotation off by {}° about axis {k} (σ {}°)",
                local[k].to_degrees(),
                sigma[k].to_degrees()
            );
        }
        // Fitted orientations predict fresh poses' orientations to the noise's order.
        let worst = fresh
            .iter()
            .map(|q| {
                let truth = rig.chain.tool_pose(q, &c.truth).rotation * c.marker_rotation;
                let fitted =
                    rig.chain.tool_pose(q, &with.1.fit.params).rotation * with.1.marker_rotation;
                truth.angle_to(&fitted).to_degrees()
            })
            .fold(0.0, f64::max);
        assert!(
            worst < 0.01,
            "seed {seed}: orientation off by {worst}° on a fresh pose"
        );
        eprintln!(
            "seed {seed}: held-out position RMS {rms_with:.4} mm with orientation, {rms_without:.4} mm without; worst orientation {worst:.4}°"
        );
    }
    ratios.sort_by(f64::total_cmp);
    assert!(
        ratios[2] < 1.0 && ratios[4] < 1.05,
        "with/without orientation, held-out RMS ratios {ratios:?}"
    );
}

#[test]
fn a_recording_without_orientation_fits_as_the_position_identification() {
    let dir = tempfile::tempdir().unwrap();
    let rig_path = ur10_rig(dir.path());
    let rec_path = import_a(dir.path(), &rig_path);
    let rig = Rig::load(&rig_path).unwrap();
    let rec = Recording::read(&rec_path, rig.chain.joints()).unwrap();
    let obs: Vec<PoseObservation> = pose_observations(&rec)
        .into_iter()
        .map(|o| PoseObservation {
            orientation: None,
            ..o
        })
        .collect();
    let plain: Vec<_> = obs.iter().map(PoseObservation::position_only).collect();
    let (chain, reference) = identify_at(&rig, &plain, Level::Full).unwrap();
    let (pose_chain, pose) =
        identify_pose(&rig, &obs, Level::Full, &PoseOptions::default()).unwrap();
    assert_eq!(pose.fit.free, reference.free);
    assert!(pose.weighting.orientation.is_none());
    let worst = plain
        .iter()
        .map(|o| {
            (chain.position(&o.q, &reference.params) - pose_chain.position(&o.q, &pose.fit.params))
                .norm()
        })
        .fold(0.0, f64::max);
    // Equal to the two fits' convergence (κ 4·10⁴ on these 99 rows leaves flat directions).
    assert!(worst < 1e-5, "the fits' points differ by {worst} mm");
    assert!((pose.fit.after.rms_mm - reference.after.rms_mm).abs() < 1e-7);
}

#[test]
fn stated_sigmas_weight_the_rows_and_estimated_ones_find_the_noise() {
    use rigcal_model::identification::pose::{BlockSigma, WeightChoice};
    let dir = tempfile::tempdir().unwrap();
    let rig = Rig::load(&ur10_rig(dir.path())).unwrap();
    let (noise_mm, noise_deg) = (0.02, 0.003);
    let mut c = campaign(&rig, 7, 60, noise_mm, noise_deg);
    for o in &mut c.obs {
        o.position_sigma = Some(Vector3::repeat(noise_mm));
        o.orientation_sigma = Some(Vector3::repeat(noise_deg.to_radians()));
    }
    let (_, stated) = identify_pose(&rig, &c.obs, Level::Full, &PoseOptions::default()).unwrap();
    assert_eq!(stated.weighting.position, BlockSigma::Stated);
    assert_eq!(stated.weighting.orientation, Some(BlockSigma::Stated));
    // The stated σ are the noise's: the weighted residual's σ̂ is 1 to its sampling spread
    // (about 5 % on 360 rows).
    assert!(
        (stated.variance_factor - 1.0).abs() < 0.15,
        "σ̂ {}",
        stated.variance_factor
    );
    let (_, estimated) = identify_pose(
        &rig,
        &c.obs,
        Level::Full,
        &PoseOptions {
            weights: WeightChoice::Estimated,
            ..Default::default()
        },
    )
    .unwrap();
    let (BlockSigma::Estimated(sp), Some(BlockSigma::Estimated(so))) = (
        estimated.weighting.position,
        estimated.weighting.orientation,
    ) else {
        panic!("{:?}", estimated.weighting);
    };
    assert!((sp / noise_mm - 1.0).abs() < 0.2, "σ position {sp} mm");
    assert!(
        (so.to_degrees() / noise_deg - 1.0).abs() < 0.2,
        "σ orientation {}°",
        so.to_degrees()
    );
}
