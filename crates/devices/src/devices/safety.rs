//! Safety wrappers: limits that wrap any device and refuse a command before a byte is sent.
//!
//! - [`LimitedArm`]: every joint within the rig's joint limits (radians inside, degrees in
//!   errors); a Cartesian move's target joints and the joints the controller's own inverse
//!   kinematics give for the pose as sent (its driver's [`CartesianSolver`]) both checked.
//! - [`CartesianArm`]: every move through the controller's Cartesian command.
//! - [`LimitedTable`]: every axis within the table travel 0..travel (mm, table frame), and z
//!   ascending within a pass: after [`Table::begin_pass`], no move may go lower than the highest
//!   z of the pass minus the rig file's `pass_retract_mm` (the z arm approaches from below).
//!
//! The two arm wrappers differ only in what they do with the moves: each is a [`GuardedArm`]
//! with its own [`MoveRule`], and every other call reaches the wrapped arm through the one
//! forwarding implementation there.

use std::sync::atomic::{AtomicUsize, Ordering as AtomicOrdering};
use std::sync::Arc;
use std::time::Duration;

use crate::devices::traits::{Arm, ArmPose, ArmStatus, DeviceError, DeviceName, Table};
use rigcal_core::kinematics::JointSpec;

/// How an arm controller carries out a Cartesian move, so that [`LimitedArm`] can check the
/// joints it will land on before anything is sent.
pub trait CartesianSolver: Send + std::fmt::Debug {
    /// The pose a Cartesian move to joints `q` (rad) is sent as (mm, deg, rounded as on the
    /// wire), and the joints (rad) the controller's inverse kinematics solve for it from `q`,
    /// or why there are none.
    fn solve_command(&self, q: &[f64]) -> ([f64; 5], Result<Vec<f64>, String>);
}

/// What an arm wrapper does with the moves; a [`GuardedArm`] passes every other call to the
/// wrapped arm unchanged.
pub trait MoveRule: Send {
    /// A joint move to `q` on `arm`: started ([`Arm::start_move`]) or, with `whole`, waited for
    /// to its end ([`Arm::move_to`]).
    fn joint_move<A: Arm + ?Sized>(
        &mut self,
        arm: &mut A,
        q: &[f64],
        timeout: Duration,
        whole: bool,
    ) -> Result<Vec<f64>, DeviceError>;
    /// A Cartesian move to joints `q` on `arm`, started ([`Arm::start_move_cartesian`]).
    fn cartesian_move<A: Arm + ?Sized>(
        &mut self,
        arm: &mut A,
        q: &[f64],
        timeout: Duration,
    ) -> Result<Vec<f64>, DeviceError>;
}

/// An [`Arm`] whose moves go through a [`MoveRule`].
#[derive(Debug)]
pub struct GuardedArm<A, R> {
    inner: A,
    rule: R,
}

impl<A: Arm, R: MoveRule> Arm for GuardedArm<A, R> {
    fn home(&mut self, timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        self.inner.home(timeout)
    }
    fn set_speed(&mut self, level: u8, timeout: Duration) -> Result<(), DeviceError> {
        self.inner.set_speed(level, timeout)
    }
    fn move_to(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        self.rule.joint_move(&mut self.inner, q, timeout, true)
    }
    fn start_move(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        self.rule.joint_move(&mut self.inner, q, timeout, false)
    }
    fn wait_moved(&mut self, slice: Duration) -> Result<bool, DeviceError> {
        self.inner.wait_moved(slice)
    }
    fn start_move_cartesian(
        &mut self,
        q: &[f64],
        timeout: Duration,
    ) -> Result<Vec<f64>, DeviceError> {
        self.rule.cartesian_move(&mut self.inner, q, timeout)
    }
    fn commanded(&self) -> Option<Vec<f64>> {
        self.inner.commanded()
    }
    fn where_pose(&mut self, timeout: Duration) -> Result<ArmPose, DeviceError> {
        self.inner.where_pose(timeout)
    }
    fn status(&mut self, timeout: Duration) -> Result<ArmStatus, DeviceError> {
        self.inner.status(timeout)
    }
    fn reset(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        self.inner.reset(timeout)
    }
    fn stop(&mut self, timeout: Duration) -> Result<bool, DeviceError> {
        self.inner.stop(timeout)
    }
}

/// The rule of [`LimitedArm`]: the rig's joint limits, and the controller's Cartesian solutions
/// checked against them.
#[derive(Debug)]
pub struct JointLimits {
    joints: Vec<JointSpec>,
    cartesian: Option<Box<dyn CartesianSolver>>,
}

/// An [`Arm`] that refuses targets outside the joint limits.
pub type LimitedArm<A> = GuardedArm<A, JointLimits>;

impl<A: Arm> GuardedArm<A, JointLimits> {
    /// Wraps `inner` with the limits of `joints`.
    pub fn new(inner: A, joints: Vec<JointSpec>) -> Self {
        GuardedArm {
            inner,
            rule: JointLimits {
                joints,
                cartesian: None,
            },
        }
    }

    /// Also checks Cartesian moves through the controller's own inverse kinematics.
    pub fn with_cartesian(mut self, solver: Box<dyn CartesianSolver>) -> Self {
        self.rule.cartesian = Some(solver);
        self
    }
}

impl JointLimits {
    /// The joints a Cartesian move of `q` makes the controller solve for, checked.
    fn check_cartesian(&self, q: &[f64]) -> Result<(), DeviceError> {
        self.check(q)?;
        let Some(k) = &self.cartesian else {
            return Ok(());
        };
        let (pose, solved) = k.solve_command(q);
        let solved = solved.map_err(|detail| DeviceError::PoseRefused { pose, detail })?;
        self.check(&solved).map_err(|e| DeviceError::PoseRefused {
            pose,
            detail: format!("the controller's solution: {e}"),
        })
    }

    fn check(&self, q: &[f64]) -> Result<(), DeviceError> {
        if q.len() != self.joints.len() {
            return Err(DeviceError::Config {
                key: "arm".into(),
                reason: format!("{} joint values for {} joints", q.len(), self.joints.len()),
            });
        }
        for (spec, v) in self.joints.iter().zip(q) {
            if !(v.is_finite() && spec.within(*v)) {
                return Err(DeviceError::Refused {
                    device: DeviceName::Arm,
                    what: format!("joint {}", spec.name),
                    value: spec.kind.to_file_units(*v),
                    min: spec.kind.to_file_units(spec.min),
                    max: spec.kind.to_file_units(spec.max),
                    why: "joint limits of the rig file",
                });
            }
        }
        Ok(())
    }
}

impl MoveRule for JointLimits {
    fn joint_move<A: Arm + ?Sized>(
        &mut self,
        arm: &mut A,
        q: &[f64],
        timeout: Duration,
        whole: bool,
    ) -> Result<Vec<f64>, DeviceError> {
        self.check(q)?;
        if whole {
            arm.move_to(q, timeout)
        } else {
            arm.start_move(q, timeout)
        }
    }

    fn cartesian_move<A: Arm + ?Sized>(
        &mut self,
        arm: &mut A,
        q: &[f64],
        timeout: Duration,
    ) -> Result<Vec<f64>, DeviceError> {
        self.check_cartesian(q)?;
        arm.start_move_cartesian(q, timeout)
    }
}

/// The rule of [`CartesianArm`]: every move through the controller's Cartesian command, a
/// refused pose through the joint command when a fallback counter is given.
#[derive(Debug)]
pub struct CartesianCommands {
    joint_fallbacks: Option<Arc<AtomicUsize>>,
}

/// An [`Arm`] whose every move goes through the controller's Cartesian command: a session run
/// over it commands poses (`MP`) instead of joints, as a compensated path on a `cartesian` rig
/// is measured. Built [`with_joint_fallback`](Self::with_joint_fallback), a move whose `MP`
/// solution the joint limits refuse before anything is sent (a pose within a few thousandths of
/// a degree of a limit, rounded out of it) goes through the joint command (`MJ`) to the same
/// joints instead, and is counted.
pub type CartesianArm<A> = GuardedArm<A, CartesianCommands>;

impl<A: Arm> GuardedArm<A, CartesianCommands> {
    /// Wraps `inner`: every move through `MP`, a refused pose an error.
    pub fn new(inner: A) -> Self {
        GuardedArm {
            inner,
            rule: CartesianCommands {
                joint_fallbacks: None,
            },
        }
    }

    /// Wraps `inner`: every move through `MP`, a refused pose through `MJ`, counted in
    /// `fallbacks` (shared with the caller).
    pub fn with_joint_fallback(inner: A, fallbacks: Arc<AtomicUsize>) -> Self {
        GuardedArm {
            inner,
            rule: CartesianCommands {
                joint_fallbacks: Some(fallbacks),
            },
        }
    }
}

impl MoveRule for CartesianCommands {
    /// Started as a pose; `whole`, its end waited for as [`Arm::move_cartesian`] does.
    fn joint_move<A: Arm + ?Sized>(
        &mut self,
        arm: &mut A,
        q: &[f64],
        timeout: Duration,
        whole: bool,
    ) -> Result<Vec<f64>, DeviceError> {
        let done = self.cartesian_move(arm, q, timeout)?;
        if whole {
            while !arm.wait_moved(timeout)? {}
        }
        Ok(done)
    }

    fn cartesian_move<A: Arm + ?Sized>(
        &mut self,
        arm: &mut A,
        q: &[f64],
        timeout: Duration,
    ) -> Result<Vec<f64>, DeviceError> {
        match (arm.start_move_cartesian(q, timeout), &self.joint_fallbacks) {
            (Err(DeviceError::PoseRefused { .. }), Some(n)) => {
                n.fetch_add(1, AtomicOrdering::Relaxed);
                arm.start_move(q, timeout)
            }
            (other, _) => other,
        }
    }
}

/// A [`Table`] that refuses targets outside its travel or below the pass's ascending z.
#[derive(Debug)]
pub struct LimitedTable<T> {
    inner: T,
    travel_mm: [f64; 3],
    retract_mm: f64,
    pass_top_z: Option<f64>,
}

impl<T: Table> LimitedTable<T> {
    /// Wraps `inner` with travel 0..`travel_mm` per axis and the pass rule.
    pub fn new(inner: T, travel_mm: [f64; 3], retract_mm: f64) -> Self {
        LimitedTable {
            inner,
            travel_mm,
            retract_mm,
            pass_top_z: None,
        }
    }

    fn check(&self, target: &[f64; 3]) -> Result<(), DeviceError> {
        for (k, (v, t)) in target.iter().zip(self.travel_mm).enumerate() {
            if !(v.is_finite() && (0.0..=t).contains(v)) {
                return Err(DeviceError::Refused {
                    device: DeviceName::Table,
                    what: format!("axis {}", ['x', 'y', 'z'][k]),
                    value: *v,
                    min: 0.0,
                    max: t,
                    why: "table travel of the rig file",
                });
            }
        }
        if let Some(top) = self.pass_top_z {
            let floor = top - self.retract_mm;
            if target[2] < floor {
                return Err(DeviceError::Refused {
                    device: DeviceName::Table,
                    what: "axis z".into(),
                    value: target[2],
                    min: floor,
                    max: self.travel_mm[2],
                    why: "z must ascend within a pass (start a new pass to go lower)",
                });
            }
        }
        Ok(())
    }
}

impl<T: Table> Table for LimitedTable<T> {
    fn enable(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        self.inner.enable(timeout)
    }
    fn set_speed(&mut self, mm_per_s: f64, timeout: Duration) -> Result<(), DeviceError> {
        self.inner.set_speed(mm_per_s, timeout)
    }
    fn start_move(&mut self, target_mm: [f64; 3], timeout: Duration) -> Result<(), DeviceError> {
        self.check(&target_mm)?;
        self.inner.start_move(target_mm, timeout)?;
        self.pass_top_z = Some(
            self.pass_top_z
                .map_or(target_mm[2], |z| z.max(target_mm[2])),
        );
        Ok(())
    }
    fn wait_reached(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.wait_reached(timeout)
    }
    fn poll_reached(
        &mut self,
        slice: Duration,
        left: Duration,
    ) -> Result<Option<[f64; 3]>, DeviceError> {
        self.inner.poll_reached(slice, left)
    }
    fn supervise(&mut self) -> Result<(), DeviceError> {
        self.inner.supervise()
    }
    fn position(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.position(timeout)
    }
    fn halt(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.halt(timeout)
    }
    fn quick_stop(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.quick_stop(timeout)
    }
    fn fault_reset(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        self.inner.fault_reset(timeout)
    }
    fn latency(&self) -> Duration {
        self.inner.latency()
    }
    fn begin_pass(&mut self) {
        self.pass_top_z = None;
        self.inner.begin_pass();
    }
    fn arm_touch_probe(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        self.inner.arm_touch_probe(timeout)
    }
    fn latched_z(&mut self, timeout: Duration) -> Result<Option<f64>, DeviceError> {
        self.inner.latched_z(timeout)
    }
}
