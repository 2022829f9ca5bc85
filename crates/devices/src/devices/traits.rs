//! The device traits the session code uses — [`Arm`], [`Table`], [`Panel`] — and their error
//! type [`DeviceError`].
//!
//! Units: joint values in radians (internal units of the rig's chain), table positions in
//! millimetres in the table frame (the panel centre), panel offsets in millimetres along table
//! +x (u) and +y (v). Every call that waits takes a timeout and ends in
//! [`DeviceError::Timeout`], which carries what was awaited, the target and the last known state.
//! Traits are small, synchronous and object-safe; the factory hands them out as `Box<dyn …>`,
//! and nothing in them tells a simulated device from a real one.
//!
//! Long waits also come in slices ([`Arm::start_move`] + [`Arm::wait_moved`],
//! [`Table::poll_reached`], [`Panel::poll_touch`]), so that the session's
//! asynchronous choreography can wait on several devices at once and stop waiting when a fault
//! comes first. The defaults wait in one piece, so a device (or a test wrapper) that only
//! implements the plain calls still works, unsliced.

use std::time::Duration;

use thiserror::Error;

use crate::protocols::canopen::SdoAbortCode;
use crate::transports::TransportError;

/// Which device an error concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DeviceName {
    /// The RV-M2 arm.
    Arm,
    /// The x-y-z table.
    Table,
    /// The touch panel.
    Panel,
    /// A point sensor: a laser tracker, a motion-capture system, or the papers' ideal instrument.
    Sensor,
}

impl std::fmt::Display for DeviceName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            DeviceName::Arm => "arm",
            DeviceName::Table => "table",
            DeviceName::Panel => "panel",
            DeviceName::Sensor => "sensor",
        })
    }
}

/// Coarse classification of a [`DeviceError`], for callers that branch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum DeviceErrorKind {
    /// A wait ran out.
    Timeout,
    /// The byte or frame transport failed.
    Transport,
    /// The device answered something unintelligible.
    Protocol,
    /// The device reports a fault (error mode, drive fault, following error, lost heartbeat).
    DeviceFault,
    /// A safety wrapper refused the command before anything was sent.
    Refused,
    /// No contact where one was expected.
    Measurement,
    /// The device is not in a state that allows the call (not homed, not enabled).
    NotReady,
    /// The rig file's device settings are unusable.
    Config,
}

/// Everything that can go wrong talking to a rig device.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum DeviceError {
    /// Nothing (or not the awaited state) arrived in time.
    #[error("{device}: timed out after {waited:?} waiting for {waiting_for} (target {target}, last state {current}); check cabling and power, or raise the timeout")]
    Timeout {
        /// The device.
        device: DeviceName,
        /// What was awaited.
        waiting_for: String,
        /// How long was waited (clock time).
        waited: Duration,
        /// The target of the operation.
        target: String,
        /// The last state seen.
        current: String,
    },
    /// The transport failed.
    #[error("{device}: transport failed: {source}")]
    Transport {
        /// The device.
        device: DeviceName,
        /// The cause.
        source: TransportError,
    },
    /// A reply could not be understood (garbled, wrong framing, unexpected answer).
    #[error("{device}: unintelligible reply to {request}: {detail}; retry, and check baud rate and framing if it persists")]
    Protocol {
        /// The device.
        device: DeviceName,
        /// What was asked.
        request: String,
        /// What went wrong.
        detail: String,
    },
    /// The Movemaster controller entered an error mode (`ER` ≠ 0) after a command.
    #[error("arm controller in error mode {code} ({meaning}) after `{command}`; joints last commanded {joints_deg:?} deg; {advice}")]
    ArmErrorMode {
        /// The command that caused it, as sent.
        command: String,
        /// The `ER` code (1 hardware, 2 position/format).
        code: u8,
        /// Meaning of the code.
        meaning: &'static str,
        /// Joints last commanded successfully (D-H degrees), if known.
        joints_deg: Option<Vec<f64>>,
        /// What to do.
        advice: &'static str,
    },
    /// A reset was refused because it is not safe.
    #[error("{device}: reset refused: {reason}")]
    ResetNotSafe {
        /// The device.
        device: DeviceName,
        /// Why.
        reason: String,
    },
    /// A drive answered an SDO with an abort.
    #[error("table drive node {node}: SDO {access} of {index:#06x}:{sub} aborted: {code:?} ({description})")]
    SdoAbort {
        /// Node id.
        node: u8,
        /// `read` or `write`.
        access: &'static str,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Abort code.
        code: SdoAbortCode,
        /// CiA 301 description.
        description: &'static str,
    },
    /// A drive is in fault (statusword bit 3) or sent an emergency.
    #[error("table axis {axis} (node {node}) fault: statusword {statusword:#06x}, EMCY {emcy_code:?}; target {target_mm:?} mm, at {current_mm:?} mm; clear the cause, then fault-reset")]
    DriveFault {
        /// Axis letter.
        axis: char,
        /// Node id.
        node: u8,
        /// Statusword seen (0 if only an EMCY arrived).
        statusword: u16,
        /// EMCY error code, if one arrived.
        emcy_code: Option<u16>,
        /// Target of the move (mm), if moving.
        target_mm: Option<f64>,
        /// Last known position (mm).
        current_mm: Option<f64>,
    },
    /// A drive reports a following error (statusword bit 13).
    #[error("table axis {axis} (node {node}) following error: target {target_mm:.3} mm, at {current_mm:?} mm; reduce speed/acceleration or check the mechanics")]
    FollowingError {
        /// Axis letter.
        axis: char,
        /// Node id.
        node: u8,
        /// Target (mm).
        target_mm: f64,
        /// Last known position (mm).
        current_mm: Option<f64>,
    },
    /// A drive's heartbeat stopped.
    #[error("table axis {axis} (node {node}): no heartbeat for {silent_for:?} (limit {limit:?}); check the drive's power and the CAN bus")]
    HeartbeatLost {
        /// Axis letter.
        axis: char,
        /// Node id.
        node: u8,
        /// Time since the last heartbeat.
        silent_for: Duration,
        /// Supervision limit.
        limit: Duration,
    },
    /// The panel reported no touch during an approach.
    #[error("no touch while the table rose from z {z_from_mm:.3} to {z_to_mm:.3} mm (reached {reached_mm:?}); the pin missed the panel or the panel is disconnected")]
    MissedTouch {
        /// Approach start (mm).
        z_from_mm: f64,
        /// Approach end (mm).
        z_to_mm: f64,
        /// Where the table was when the wait ended.
        reached_mm: Option<[f64; 3]>,
    },
    /// A safety wrapper refused a command before any byte was sent.
    #[error("{device}: refused {what} = {value:.3} outside {min:.3}..{max:.3} ({why}); nothing was sent")]
    Refused {
        /// The device.
        device: DeviceName,
        /// Joint or axis.
        what: String,
        /// Requested value (deg or mm).
        value: f64,
        /// Smallest allowed.
        min: f64,
        /// Largest allowed.
        max: f64,
        /// Which rule.
        why: &'static str,
    },
    /// The arm's own Cartesian pose (`WH`) disagrees with the nominal forward kinematics.
    #[error("arm `WH` reports ({reported:?}) mm but the nominal kinematics give ({expected:?}) mm, {distance_mm:.2} mm apart (tolerance {tolerance_mm} mm); check the joint signs/offsets and the nest pose in the rig file")]
    PoseMismatch {
        /// Nominal position of the commanded joints (mm).
        expected: [f64; 3],
        /// The controller's report (mm).
        reported: [f64; 3],
        /// Distance (mm).
        distance_mm: f64,
        /// Tolerance (mm).
        tolerance_mm: f64,
    },
    /// The controller's nominal inverse kinematics have no solution for a Cartesian target, or
    /// its solution leaves the joint limits: refused before any byte was sent.
    #[error("arm: refused the Cartesian move to ({:.1}, {:.1}, {:.1}) mm, pitch {:.1}°, roll {:.1}° (controller frame): {detail}; nothing was sent", pose[0], pose[1], pose[2], pose[3], pose[4])]
    PoseRefused {
        /// The pose as it would have been sent (mm, deg).
        pose: [f64; 5],
        /// Why.
        detail: String,
    },
    /// A reading came too late to be trusted: while it was on its way the device kept moving
    /// at the approach speed, further than the rig's overshoot budget allows.
    #[error("{device}: the reading took {latency:?} after the touch; at the approach speed that is {error_mm:.4} mm of overshoot, more than the budget of {budget_mm} mm ([devices.panel] max_overshoot_mm); the contact is repeated; if it persists check the bus load and the drives' response times")]
    LateReading {
        /// The device whose reading was late.
        device: DeviceName,
        /// The reading's measured latency (request to answer).
        latency: Duration,
        /// The overshoot it causes (mm).
        error_mm: f64,
        /// The budget (mm).
        budget_mm: f64,
    },
    /// The device is not in a state that allows the call.
    #[error("{device}: not ready: {detail}")]
    NotReady {
        /// The device.
        device: DeviceName,
        /// What is missing and what to do.
        detail: String,
    },
    /// The device settings are unusable.
    #[error("device settings: `devices.{key}`: {reason}")]
    Config {
        /// The key under `[devices]`.
        key: String,
        /// What is wrong.
        reason: String,
    },
}

impl DeviceError {
    /// The coarse kind.
    pub fn kind(&self) -> DeviceErrorKind {
        match self {
            DeviceError::Timeout { .. } | DeviceError::LateReading { .. } => {
                DeviceErrorKind::Timeout
            }
            DeviceError::Transport { source, .. } => match source.kind() {
                crate::transports::TransportErrorKind::Timeout => DeviceErrorKind::Timeout,
                _ => DeviceErrorKind::Transport,
            },
            DeviceError::Protocol { .. } | DeviceError::SdoAbort { .. } => {
                DeviceErrorKind::Protocol
            }
            DeviceError::ArmErrorMode { .. }
            | DeviceError::DriveFault { .. }
            | DeviceError::FollowingError { .. }
            | DeviceError::HeartbeatLost { .. }
            | DeviceError::PoseMismatch { .. } => DeviceErrorKind::DeviceFault,
            DeviceError::Refused { .. } | DeviceError::PoseRefused { .. } => {
                DeviceErrorKind::Refused
            }
            DeviceError::MissedTouch { .. } => DeviceErrorKind::Measurement,
            DeviceError::ResetNotSafe { .. } | DeviceError::NotReady { .. } => {
                DeviceErrorKind::NotReady
            }
            DeviceError::Config { .. } => DeviceErrorKind::Config,
        }
    }

    /// True if repeating the operation may succeed without anyone intervening: timeouts,
    /// garbled replies, retryable transport errors and a missed touch. Faults, refusals and
    /// configuration errors need a decision first.
    pub fn is_retryable(&self) -> bool {
        match self {
            DeviceError::Timeout { .. }
            | DeviceError::LateReading { .. }
            | DeviceError::Protocol { .. }
            | DeviceError::MissedTouch { .. } => true,
            DeviceError::Transport { source, .. } => source.is_retryable(),
            _ => false,
        }
    }
}

/// The controller's Cartesian pose as `WH` reports it (mm, degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmPose {
    /// Position (mm).
    pub xyz_mm: [f64; 3],
    /// Pitch (deg).
    pub pitch_deg: f64,
    /// Roll (deg).
    pub roll_deg: f64,
}

/// The arm controller's error state (`ER`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmStatus {
    /// No error.
    Ok,
    /// Error mode I: hardware; needs the operator.
    HardwareError,
    /// Error mode II: position out of range or command format; `RS` clears it.
    PositionError,
}

/// A point sensor — a laser tracker, a motion-capture system, or the papers' ideal instrument:
/// reads where the marker on the last link is, in the sensor's own frame (mm). The arm must be
/// at rest; the reading is the marker's position at the moment of the call.
#[cfg_attr(any(test, feature = "mock"), mockall::automock)]
pub trait PointSensor: Send {
    /// Reads the marker position (mm, sensor frame); a marker out of view is a retryable
    /// [`DeviceError::Timeout`].
    fn read(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError>;
    /// Time from the call to the reading (settling plus averaging).
    fn latency(&self) -> Duration;
}

/// A robot arm moved joint by joint.
#[cfg_attr(any(test, feature = "mock"), mockall::automock)]
pub trait Arm: Send {
    /// Returns to the mechanical origin (nest) and starts tracking joints from the nest pose.
    /// Returns the nest pose (rad).
    fn home(&mut self, timeout: Duration) -> Result<Vec<f64>, DeviceError>;
    /// Sets the speed level 0..=9.
    fn set_speed(&mut self, level: u8, timeout: Duration) -> Result<(), DeviceError>;
    /// Moves to absolute joint values `q` (rad) and waits until the motion is complete.
    /// Returns the joint values actually commanded (after the controller's resolution).
    fn move_to(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError>;
    /// Starts a move to `q` (rad) whose end [`Arm::wait_moved`] awaits, `timeout` counting
    /// from now; returns the joint values commanded. A move whose wait was abandoned is
    /// finished (its reply awaited) before the arm takes the next command. Default: the whole
    /// [`Arm::move_to`].
    fn start_move(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        self.move_to(q, timeout)
    }
    /// Waits at most `slice` for the move begun by [`Arm::start_move`] to end: `Ok(true)` once
    /// it has (checked as [`Arm::move_to`] checks it), `Ok(false)` while it is under way, a
    /// [`DeviceError::Timeout`] when the move's own timeout has run out. Default: done.
    fn wait_moved(&mut self, _slice: Duration) -> Result<bool, DeviceError> {
        Ok(true)
    }
    /// Starts a Cartesian move to joints `q` (rad): the controller is sent the nominal pose of
    /// `q` in its own frame (`MP` on the Movemaster, 0.1 mm / 0.1°) and solves it with its own
    /// nominal inverse kinematics; [`Arm::wait_moved`] awaits the end. Returns the joints the
    /// controller lands on (before its servo rounding). Default: refused, the controller has
    /// no Cartesian command (a [`DeviceError::Config`] on `arm.command_path`).
    fn start_move_cartesian(
        &mut self,
        _q: &[f64],
        _timeout: Duration,
    ) -> Result<Vec<f64>, DeviceError> {
        Err(DeviceError::Config {
            key: "arm.command_path".into(),
            reason: "this arm's controller has no Cartesian command: use command_path = \"joint\""
                .into(),
        })
    }
    /// [`Arm::start_move_cartesian`] and its wait in one piece.
    fn move_cartesian(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        let done = self.start_move_cartesian(q, timeout)?;
        while !self.wait_moved(timeout)? {}
        Ok(done)
    }
    /// The joint values last commanded (rad); `None` before homing or after a hardware error.
    fn commanded(&self) -> Option<Vec<f64>>;
    /// Reads the controller's Cartesian pose.
    fn where_pose(&mut self, timeout: Duration) -> Result<ArmPose, DeviceError>;
    /// Reads the error state.
    fn status(&mut self, timeout: Duration) -> Result<ArmStatus, DeviceError>;
    /// Clears a position/format error; refuses a hardware error ([`DeviceError::ResetNotSafe`]).
    fn reset(&mut self, timeout: Duration) -> Result<(), DeviceError>;
    /// A safe stop (the session was asked to stop): sends the controller's stop command if it
    /// has one, sends no further motion, and waits at most `timeout` for the arm to be at rest.
    /// True once it is known at rest, false if it may still be finishing a move on its own.
    /// Default: nothing in progress (the plain calls return at the end of their motion).
    fn stop(&mut self, _timeout: Duration) -> Result<bool, DeviceError> {
        Ok(true)
    }
}

/// The x-y-z measurement table: the panel centre's position in the table frame (mm).
#[cfg_attr(any(test, feature = "mock"), mockall::automock)]
pub trait Table: Send {
    /// Brings the drives up (NMT start, heartbeats, enable operation, profile position mode).
    fn enable(&mut self, timeout: Duration) -> Result<(), DeviceError>;
    /// Sets the profile velocity of every axis (mm/s).
    fn set_speed(&mut self, mm_per_s: f64, timeout: Duration) -> Result<(), DeviceError>;
    /// Starts a move to `target_mm` and returns once every drive has acknowledged it.
    fn start_move(&mut self, target_mm: [f64; 3], timeout: Duration) -> Result<(), DeviceError>;
    /// Waits until every axis has reached the target; returns the actual position.
    fn wait_reached(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError>;
    /// Waits at most `slice` for every axis to reach its target: the position once they have,
    /// `None` while they have not and `left` (the rest of the whole wait, `slice` included) is
    /// not used up, the [`Table::wait_reached`] timeout error when it is. Default: the whole
    /// `wait_reached(left)`.
    fn poll_reached(
        &mut self,
        _slice: Duration,
        left: Duration,
    ) -> Result<Option<[f64; 3]>, DeviceError> {
        self.wait_reached(left).map(Some)
    }
    /// Checks the drives without waiting: reads what the bus already holds and fails on an
    /// emergency (EMCY) or a heartbeat silent for longer than its limit. The session's
    /// supervision task calls it once a heartbeat period. Default: nothing to check.
    fn supervise(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }
    /// Reads the actual position (mm).
    fn position(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError>;
    /// Stops every axis where it is; returns the position.
    fn halt(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError>;
    /// A safe stop (the session was asked to stop, or ends on a fault): every axis stops and
    /// is left without a set-point that a later command could resume (CiA 402: the quick stop
    /// command, the drives then *switch on disabled*); returns the position. The next
    /// [`Table::enable`] brings the drives back. Default: [`Table::halt`].
    fn quick_stop(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        self.halt(timeout)
    }
    /// Clears drive faults (rising edge of controlword bit 7) and enables again.
    fn fault_reset(&mut self, timeout: Duration) -> Result<(), DeviceError>;
    /// Bus latency of a position read (from the rig file), for the approach-speed rule.
    fn latency(&self) -> Duration;
    /// Starts a new pass of ascending z (the safety wrapper forgets the previous z).
    fn begin_pass(&mut self) {}
    /// Arms the z drive's touch-probe latch for the contact to come: the next positive edge of
    /// its probe input (the panel controller's touch output, wired to it) stores the z
    /// position in the drive, whatever the bus and panel latencies (CiA 402 touch probe 1,
    /// first event; a position stored before is cleared). Only where the rig file says
    /// `[devices.table] touch_probe = true`. Default: refused, the table has no latch.
    fn arm_touch_probe(&mut self, _timeout: Duration) -> Result<(), DeviceError> {
        Err(no_touch_probe())
    }
    /// The z position (mm) the z drive latched at the first positive edge of its probe input
    /// since [`Table::arm_touch_probe`]; `None` while it has stored none. Default: refused, the
    /// table has no latch.
    fn latched_z(&mut self, _timeout: Duration) -> Result<Option<f64>, DeviceError> {
        Err(no_touch_probe())
    }
}

/// The error of a table without a touch-probe latch asked for one.
fn no_touch_probe() -> DeviceError {
    DeviceError::Config {
        key: "table.touch_probe".into(),
        reason: "this table (its driver, or a wrapper around it) has no touch-probe latch; set touch_probe = false".into(),
    }
}

/// A touch as the panel reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touch {
    /// Raw counts (x, y).
    pub counts: [u16; 2],
    /// Offset from the panel centre along table +x (mm).
    pub u_mm: f64,
    /// Offset from the panel centre along table +y (mm).
    pub v_mm: f64,
}

/// Counters of the panel's byte stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PanelStats {
    /// Valid packets.
    pub good: u64,
    /// Packets dropped for a bad checksum.
    pub bad_checksum: u64,
    /// Packets dropped as out of range.
    pub out_of_range: u64,
    /// Bytes dropped while resynchronising.
    pub discarded_bytes: u64,
}

/// The touch panel on the table's z arm.
#[cfg_attr(any(test, feature = "mock"), mockall::automock)]
pub trait Panel: Send {
    /// Drops everything received so far.
    fn clear(&mut self) -> Result<(), DeviceError>;
    /// Waits for the first valid packet with the touch flag set.
    fn wait_touch(&mut self, timeout: Duration) -> Result<Touch, DeviceError>;
    /// Waits at most `slice` for a touch (a slice of a longer wait): `None` if none came.
    /// Default: [`Panel::wait_touch`] with its timeout as `None`.
    fn poll_touch(&mut self, slice: Duration) -> Result<Option<Touch>, DeviceError> {
        match self.wait_touch(slice) {
            Ok(t) => Ok(Some(t)),
            Err(DeviceError::Timeout { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    }
    /// Waits at most `timeout` for the pin to be seen lifted off the panel: true once the
    /// last packet received reports no touch (or none since the last [`Panel::clear`] reported
    /// one), false if the panel still reports a touch. A touched panel keeps reporting for its
    /// latency after the pin lifts, so a contact's packets can still be on their way when the
    /// table has left; only after the release packet can none of them follow. Default: true (a
    /// panel that cannot tell).
    fn wait_lifted(&mut self, timeout: Duration) -> Result<bool, DeviceError> {
        let _ = timeout;
        Ok(true)
    }
    /// Stream counters (bad packets are counted and dropped, never measured).
    fn stats(&self) -> PanelStats;
    /// The panel's reporting latency (from the rig file), for the approach-speed rule.
    fn latency(&self) -> Duration;
}

impl<A: Arm + ?Sized> Arm for Box<A> {
    fn home(&mut self, timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        (**self).home(timeout)
    }
    fn set_speed(&mut self, level: u8, timeout: Duration) -> Result<(), DeviceError> {
        (**self).set_speed(level, timeout)
    }
    fn move_to(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        (**self).move_to(q, timeout)
    }
    fn start_move(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        (**self).start_move(q, timeout)
    }
    fn wait_moved(&mut self, slice: Duration) -> Result<bool, DeviceError> {
        (**self).wait_moved(slice)
    }
    fn start_move_cartesian(
        &mut self,
        q: &[f64],
        timeout: Duration,
    ) -> Result<Vec<f64>, DeviceError> {
        (**self).start_move_cartesian(q, timeout)
    }
    fn move_cartesian(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        (**self).move_cartesian(q, timeout)
    }
    fn commanded(&self) -> Option<Vec<f64>> {
        (**self).commanded()
    }
    fn where_pose(&mut self, timeout: Duration) -> Result<ArmPose, DeviceError> {
        (**self).where_pose(timeout)
    }
    fn status(&mut self, timeout: Duration) -> Result<ArmStatus, DeviceError> {
        (**self).status(timeout)
    }
    fn reset(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        (**self).reset(timeout)
    }
    fn stop(&mut self, timeout: Duration) -> Result<bool, DeviceError> {
        (**self).stop(timeout)
    }
}

impl<T: Table + ?Sized> Table for Box<T> {
    fn enable(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        (**self).enable(timeout)
    }
    fn set_speed(&mut self, mm_per_s: f64, timeout: Duration) -> Result<(), DeviceError> {
        (**self).set_speed(mm_per_s, timeout)
    }
    fn start_move(&mut self, target_mm: [f64; 3], timeout: Duration) -> Result<(), DeviceError> {
        (**self).start_move(target_mm, timeout)
    }
    fn wait_reached(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        (**self).wait_reached(timeout)
    }
    fn poll_reached(
        &mut self,
        slice: Duration,
        left: Duration,
    ) -> Result<Option<[f64; 3]>, DeviceError> {
        (**self).poll_reached(slice, left)
    }
    fn supervise(&mut self) -> Result<(), DeviceError> {
        (**self).supervise()
    }
    fn position(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        (**self).position(timeout)
    }
    fn halt(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        (**self).halt(timeout)
    }
    fn quick_stop(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        (**self).quick_stop(timeout)
    }
    fn fault_reset(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        (**self).fault_reset(timeout)
    }
    fn latency(&self) -> Duration {
        (**self).latency()
    }
    fn begin_pass(&mut self) {
        (**self).begin_pass()
    }
    fn arm_touch_probe(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        (**self).arm_touch_probe(timeout)
    }
    fn latched_z(&mut self, timeout: Duration) -> Result<Option<f64>, DeviceError> {
        (**self).latched_z(timeout)
    }
}

impl<P: Panel + ?Sized> Panel for Box<P> {
    fn clear(&mut self) -> Result<(), DeviceError> {
        (**self).clear()
    }
    fn wait_lifted(&mut self, timeout: Duration) -> Result<bool, DeviceError> {
        (**self).wait_lifted(timeout)
    }
    fn wait_touch(&mut self, timeout: Duration) -> Result<Touch, DeviceError> {
        (**self).wait_touch(timeout)
    }
    fn poll_touch(&mut self, slice: Duration) -> Result<Option<Touch>, DeviceError> {
        (**self).poll_touch(slice)
    }
    fn stats(&self) -> PanelStats {
        (**self).stats()
    }
    fn latency(&self) -> Duration {
        (**self).latency()
    }
}
