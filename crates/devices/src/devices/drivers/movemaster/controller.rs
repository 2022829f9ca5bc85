//! The arm controller's own Cartesian kinematics: its frame, its pose convention and its nominal
//! inverse kinematics, as the Movemaster's `MP` and `WH` use them (conventions §8, §9b).
//!
//! Pose convention (RV-M2, five joints): `[x, y, z, pitch, roll]`, x y z the tool point (the pin
//! tip) in mm in the controller's frame; pitch the elevation of the pin axis in the arm's
//! vertical plane from its outward horizontal (deg, −180..180: a pin pointing straight down is
//! −90, one tilted 1° back towards the base −91, not −89 as an `asin` of the vertical component
//! would read it); roll the wrist joint J4 in D-H degrees. In the Table I chain J4 is the wrist
//! joint that turns the pin about the forearm without changing its elevation at the held pose
//! (it moves the tip sideways, as J1 does), while J5 tilts the pin in the arm's plane together
//! with J2 and J3; so J4 is what the fifth number must fix, and J1, J2, J3, J5 are solved for
//! the position and the pitch. (The real controller's own convention is to be checked on the
//! rig: the driver's `WH` check flags a disagreement.) The controller's frame is level: it
//! differs from the world of the rig's kinematics by a translation and a rotation about the
//! vertical (`[devices.arm] controller_frame`), so pitch is the same in both.
//!
//! The controller solves `MP` with the *nominal* kinematics (no error parameters): J4 from the
//! roll, J1, J2, J3, J5 by Newton from the joints it is at (the branch the arm is on), to well under a
//! micrometre. A compensated target therefore goes out as the nominal pose of the compensated
//! joints q^c ([`ControllerKinematics::pose`]): the controller lands on q^c to within the
//! rounding of the command (0.1 mm, 0.1°) and of its servo.

use nalgebra::{DMatrix, DVector, Vector3};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};
use rigcal_core::rig::{Instrument, Rig};
use serde::{Deserialize, Serialize};

use crate::devices::safety::CartesianSolver;

/// The controller's frame in the world: world = Rz(yaw) · controller + origin.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ControllerFrame {
    /// The controller frame's origin in the world (mm).
    pub origin_mm: [f64; 3],
    /// Its rotation about the world's vertical (deg).
    pub yaw_deg: f64,
}

impl ControllerFrame {
    /// True when every number is finite.
    pub fn is_finite(&self) -> bool {
        self.origin_mm.iter().all(|v| v.is_finite()) && self.yaw_deg.is_finite()
    }

    fn rotation(&self) -> nalgebra::Rotation3<f64> {
        nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), self.yaw_deg.to_radians())
    }

    /// A world point in the controller's frame.
    pub fn from_world(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation().inverse() * (p - Vector3::from(self.origin_mm))
    }

    /// A controller-frame point in the world.
    pub fn to_world(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation() * p + Vector3::from(self.origin_mm)
    }
}

/// Why the controller's nominal inverse kinematics found no solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PoseError {
    /// The chain is not the Movemaster's five joints.
    #[error("the controller's Cartesian kinematics need a 5-joint chain, this one has {0}")]
    WrongChain(usize),
    /// A value was NaN or infinite.
    #[error("pose {0:?} is not finite")]
    NotFinite([f64; 5]),
    /// Newton did not converge (out of reach, or a singular pose).
    #[error("no joint solution for pose ({:.1}, {:.1}, {:.1}) mm, pitch {:.1}°, roll {:.1}° near the current joints: {residual:.2e} left after {iterations} iterations (out of reach or singular)", pose[0], pose[1], pose[2], pose[3], pose[4])]
    NoSolution {
        /// The pose (mm, deg).
        pose: [f64; 5],
        /// What was left (mm and rad mixed, for the message).
        residual: f64,
        /// Iterations made.
        iterations: usize,
    },
}

/// The controller's nominal kinematics in its own frame.
#[derive(Debug, Clone)]
pub struct ControllerKinematics {
    chain: SerialChain,
    frame: ControllerFrame,
    pin_axis: Vector3<f64>,
}

/// The joint the pose's roll fixes (J4).
const ROLL_JOINT: usize = 3;
/// The joints Newton solves for the position and pitch (J1, J2, J3, J5).
const SOLVED: [usize; 4] = [0, 1, 2, 4];

/// Resolution of an `MP` pose: 0.1 mm and 0.1°.
const POSE_STEP: f64 = 0.1;

impl ControllerKinematics {
    /// The kinematics of `chain` (five joints) in `frame`; `pin_axis` is the tool axis whose
    /// elevation is the pitch.
    pub fn new(
        chain: SerialChain,
        frame: ControllerFrame,
        pin_axis: Vector3<f64>,
    ) -> Result<Self, PoseError> {
        if chain.dof() != 5 {
            return Err(PoseError::WrongChain(chain.dof()));
        }
        Ok(Self {
            chain,
            frame,
            pin_axis,
        })
    }

    /// The kinematics of `rig`'s arm controller in `frame`, the pin axis from the rig's
    /// instrument (the last link's x axis without a pin).
    pub fn for_rig(rig: &Rig, frame: ControllerFrame) -> Result<Self, PoseError> {
        let pin_axis = match &rig.instrument {
            Instrument::TablePanel(t) => t.pin_axis,
            _ => Vector3::x(),
        };
        Self::new(rig.chain.clone(), frame, pin_axis)
    }

    /// The controller's frame.
    pub fn frame(&self) -> &ControllerFrame {
        &self.frame
    }

    /// The nominal pose `[x, y, z, pitch, roll]` (mm, deg, controller frame) of joints `q` (rad).
    pub fn pose(&self, q: &[f64]) -> [f64; 5] {
        let e = ErrorParams::zeros(self.chain.layout());
        let p = self.frame.from_world(&self.chain.position(q, &e));
        let pin = self.chain.tool_pose(q, &e).rotation * self.pin_axis;
        [
            p.x,
            p.y,
            p.z,
            self.pitch_deg(q, &e, &pin),
            q.get(ROLL_JOINT).copied().unwrap_or(0.0).to_degrees(),
        ]
    }

    /// The pin's elevation in the arm's vertical plane from its outward horizontal (deg): an
    /// `asin` of the vertical component alone reads a pin 1° past vertical as 1° short of it,
    /// and Newton, started from the joints the arm is at, then lands on the mirror solution
    /// (J5 tens of degrees off the request, the same tip). Falls back to the `asin` where the
    /// arm's plane is undefined (J2 axis not horizontal, or the tip on the J1 axis).
    fn pitch_deg(&self, q: &[f64], e: &ErrorParams, pin: &Vector3<f64>) -> f64 {
        let elevation = || pin.z.clamp(-1.0, 1.0).asin().to_degrees();
        let shoulder = self.chain.frame_before_joint(q, e, 1);
        let across = shoulder.rotation * Vector3::z();
        let mut outward = Vector3::z().cross(&across);
        let waist = self.chain.frame_before_joint(q, e, 0).translation.vector;
        let mut radial = self.chain.position(q, e) - waist;
        radial.z = 0.0;
        if across.z.abs() > 0.1 || outward.norm() < 0.5 || radial.norm() < 1.0 {
            return elevation();
        }
        if outward.dot(&radial) < 0.0 {
            outward = -outward;
        }
        let horizontal = pin.dot(&outward.normalize());
        pin.z.atan2(horizontal).to_degrees()
    }

    /// The nominal world position of joints `q` (mm).
    pub fn world_position(&self, q: &[f64]) -> Vector3<f64> {
        self.chain
            .position(q, &ErrorParams::zeros(self.chain.layout()))
    }

    /// The pose as `MP` sends it: each value rounded to 0.1 mm / 0.1°.
    pub fn rounded(pose: &[f64; 5]) -> [f64; 5] {
        pose.map(|v| (v / POSE_STEP).round() * POSE_STEP)
    }

    /// The joints (rad) the controller's nominal inverse kinematics give for `pose`, found by
    /// Newton from `seed` (the joints the arm is at).
    pub fn solve(&self, pose: &[f64; 5], seed: &[f64]) -> Result<Vec<f64>, PoseError> {
        if pose.iter().any(|v| !v.is_finite()) || seed.iter().any(|v| !v.is_finite()) {
            return Err(PoseError::NotFinite(*pose));
        }
        let mut q: Vec<f64> = (0..5)
            .map(|k| seed.get(k).copied().unwrap_or(0.0))
            .collect();
        q[ROLL_JOINT] = pose[4].to_radians();
        let residual = |q: &[f64]| -> DVector<f64> {
            let p = self.pose(q);
            DVector::from_vec(vec![
                p[0] - pose[0],
                p[1] - pose[1],
                p[2] - pose[2],
                // Pitch in mm-sized units (deg · 10) so one tolerance fits both.
                (p[3] - pose[3]) * 10.0,
            ])
        };
        let mut r = residual(&q);
        let mut iterations = 0;
        while r.norm() > 1e-9 && iterations < 60 {
            iterations += 1;
            let h = 1e-7;
            let mut jac = DMatrix::zeros(4, 4);
            for (c, &j) in SOLVED.iter().enumerate() {
                let mut qp = q.clone();
                qp[j] += h;
                let mut qm = q.clone();
                qm[j] -= h;
                let d = (residual(&qp) - residual(&qm)) / (2.0 * h);
                jac.set_column(c, &d);
            }
            let Ok(dq) = jac.svd(true, true).solve(&r, 1e-12) else {
                break;
            };
            // A damped step keeps Newton on the branch the seed is on.
            let scale = (0.3 / dq.amax()).min(1.0);
            for (c, &j) in SOLVED.iter().enumerate() {
                q[j] -= scale * dq[c];
            }
            r = residual(&q);
        }
        // A NaN residual is no solution either.
        if r.norm().is_nan() || r.norm() > 1e-6 {
            return Err(PoseError::NoSolution {
                pose: *pose,
                residual: r.norm(),
                iterations,
            });
        }
        Ok(q)
    }

    /// Where the controller lands for a Cartesian command of `q`'s nominal pose: the pose rounded
    /// to 0.1 mm / 0.1°, solved from `q`, each joint rounded to `servo_step_deg` (0: not rounded).
    pub fn landing(&self, q: &[f64], servo_step_deg: f64) -> Result<Vec<f64>, PoseError> {
        let pose = Self::rounded(&self.pose(q));
        let solved = self.solve(&pose, q)?;
        Ok(round_joints(&solved, servo_step_deg))
    }
}

impl CartesianSolver for ControllerKinematics {
    /// `MP`'s pose of `q` (rounded as sent) and the joints the controller solves for it from `q`.
    fn solve_command(&self, q: &[f64]) -> ([f64; 5], Result<Vec<f64>, String>) {
        let pose = Self::rounded(&self.pose(q));
        (pose, self.solve(&pose, q).map_err(|e| e.to_string()))
    }
}

/// Joints (rad) rounded to a step in degrees (0: unchanged).
pub fn round_joints(q: &[f64], step_deg: f64) -> Vec<f64> {
    if step_deg <= 0.0 {
        return q.to_vec();
    }
    let step = step_deg.to_radians();
    q.iter().map(|v| (v / step).round() * step).collect()
}

/// The `MP` poses of compensated joint commands as CSV columns beside the joints: each line of
/// `joints_csv` (header first) gets `mp_x_mm,mp_y_mm,mp_z_mm,mp_pitch_deg,mp_roll_deg`, the
/// nominal pose of the command in the controller's frame, one decimal as `MP` sends it.
pub fn with_pose_columns(
    joints_csv: &str,
    controller: &ControllerKinematics,
    commands: &[Vec<f64>],
) -> String {
    let mut out = String::with_capacity(joints_csv.len() * 2);
    for (k, line) in joints_csv.lines().enumerate() {
        out.push_str(line);
        if k == 0 {
            out.push_str(",mp_x_mm,mp_y_mm,mp_z_mm,mp_pitch_deg,mp_roll_deg");
        } else if let Some(q) = commands.get(k - 1) {
            let pose = ControllerKinematics::rounded(&controller.pose(q));
            for v in pose {
                out.push_str(&format!(",{v:.1}"));
            }
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kin(frame: ControllerFrame) -> ControllerKinematics {
        let rig = rigcal_core::rig::Rig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2.toml"
        )))
        .unwrap();
        ControllerKinematics::new(rig.chain, frame, Vector3::x()).unwrap()
    }

    #[test]
    fn solve_inverts_pose_in_a_shifted_turned_frame() {
        let frame = ControllerFrame {
            origin_mm: [-400.0, 170.0, 350.0],
            yaw_deg: 90.0,
        };
        let k = kin(frame);
        let q = vec![0.3, 0.9, -1.2, 0.2, 0.1];
        let pose = k.pose(&q);
        // The origin moves the frame: the world point minus the origin, turned back by the yaw.
        let w = k.world_position(&q);
        assert!((pose[0] - (w.y - 170.0)).abs() < 1e-9);
        assert!((pose[1] - -(w.x + 400.0)).abs() < 1e-9);
        assert!((pose[2] - (w.z - 350.0)).abs() < 1e-9);
        let seed = vec![0.25, 0.85, -1.1, 0.25, 0.0];
        let back = k.solve(&pose, &seed).unwrap();
        for (a, b) in back.iter().zip(&q) {
            assert!((a - b).abs() < 1e-8, "{back:?} vs {q:?}");
        }
    }

    #[test]
    fn landing_is_within_the_command_rounding() {
        let k = kin(ControllerFrame::default());
        let q = vec![0.1, 1.2, -1.5, 0.0, 0.0];
        let land = k.landing(&q, 0.0).unwrap();
        let d = (k.world_position(&land) - k.world_position(&q)).norm();
        // 0.05 mm per axis at most.
        assert!(d <= 0.05 * 3f64.sqrt() + 1e-9, "{d}");
    }

    /// A pin a few degrees past vertical is not read as one as far short of it (as an `asin` of
    /// its vertical component would): the two poses differ in pitch, and the pose of the one,
    /// solved from the joints of the other, lands back on the one.
    #[test]
    fn a_pin_past_vertical_is_not_its_mirror() {
        let rig = rigcal_core::rig::Rig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2.toml"
        )))
        .unwrap();
        let k = ControllerKinematics::of_rig(&rig).unwrap();
        let at = |j5_deg: f64| {
            vec![
                0.68f64.to_radians(),
                15.8f64.to_radians(),
                (-103.5f64).to_radians(),
                0.0,
                j5_deg.to_radians(),
            ]
        };
        // The J5 that points the pin straight down, by bisection on the pitch.
        let (mut lo, mut hi) = (-60.0, 60.0);
        let below = |j5: f64| k.pose(&at(j5))[3] < -90.0;
        assert_ne!(
            below(lo),
            below(hi),
            "the pin passes vertical in the bracket"
        );
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if below(mid) == below(lo) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let vertical = 0.5 * (lo + hi);
        for delta in [-8.0, -3.0, 3.0, 8.0] {
            let q = at(vertical + delta);
            let mirror = at(vertical - delta);
            let (p, m) = (k.pose(&q), k.pose(&mirror));
            assert!((p[3] - m[3]).abs() > 1.5 * delta.abs(), "{p:?} {m:?}");
            let back = k.solve(&p, &mirror).unwrap();
            for (a, b) in back.iter().zip(&q) {
                assert!((a - b).abs() < 1e-6, "δ {delta}: {back:?} vs {q:?}");
            }
        }
    }
}
