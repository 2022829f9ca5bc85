//! Driver for the RV-M2 on its Movemaster controller over RS-232.
//!
//! Protocol: [`crate::protocols::movemaster`], one CR-terminated command at a time; every
//! command is followed by `ER` and the next command waits for its reply, which also marks the
//! end of a motion (the controller executes in order). No pipelining.
//!
//! Units and conventions: the trait speaks D-H joint angles in radians; the wire speaks
//! controller degrees, controller angle = sign · q + offset per joint (rig file). `MJ`/`DJ` are
//! relative, so the driver tracks the absolute controller angles itself, from the nest pose
//! (rig file, D-H degrees) after `NT`; each increment is the difference of *rounded absolute*
//! targets (resolution from the rig file), so rounding never accumulates, and the joint values
//! reported as commanded are the rounded ones. After a move the driver reads `WH` (the
//! controller's Cartesian pose) and checks it against the nominal forward kinematics.
//!
//! Cartesian moves ([`Arm::start_move_cartesian`]) send `MP` with the nominal pose of the target
//! joints in the controller's frame (rig file), rounded to 0.1 mm / 0.1°; the driver solves the
//! controller's nominal inverse kinematics itself ([`ControllerKinematics`]) to know the joints
//! the arm lands on, which need not lie on the `MJ` grid: the off-grid part is kept beside the
//! counts, so later relative moves stay exact.
//!
//! A move may be waited for in slices ([`Arm::start_move`], then [`Arm::wait_moved`]). If the
//! caller stops waiting (a fault elsewhere cancelled the motion: the controller has no stop
//! command, so the arm goes on to its target), the move stays pending in the driver, and the
//! next command first reads its outstanding `ER` reply (within the move's own timeout), so a
//! reply is never taken for another command's. A safe stop ([`Arm::stop`]) therefore sends
//! nothing: it waits for the move in progress to end.

use std::collections::VecDeque;
use std::time::Duration;

use crate::devices::clock::SharedClock;
use crate::devices::drivers::movemaster::controller::ControllerKinematics;
use crate::devices::drivers::movemaster::settings::ArmConfig;
use crate::devices::traits::{Arm, ArmPose, ArmStatus, DeviceError, DeviceName};
use crate::protocols::movemaster::{
    quantise_joint_move, Command, Decimal, ErrorStatus, JointNumber, LineFramer, MovemasterError,
    Resolution, SpeedLevel, WhereReply,
};
use crate::transports::{ByteTransport, TransportError};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};

/// The Movemaster driver over any byte transport.
#[derive(Debug)]
pub struct MovemasterArm<T: ByteTransport> {
    io: T,
    clock: SharedClock,
    chain: SerialChain,
    cfg: ArmConfig,
    resolution: Resolution,
    framer: LineFramer,
    lines: VecDeque<Result<Vec<u8>, MovemasterError>>,
    commanded_counts: Option<[i64; 5]>,
    /// Controller angle − counts · resolution per joint (deg): non-zero after an `MP`.
    off_grid_deg: [f64; 5],
    controller: ControllerKinematics,
    pending: Option<PendingMove>,
}

/// A move whose `ER` reply (its end) has not been read yet.
#[derive(Debug)]
struct PendingMove {
    /// The move command as sent.
    command: String,
    /// The absolute counts it commands.
    counts: [i64; 5],
    /// The off-grid part it leaves (deg).
    off_grid_deg: [f64; 5],
    /// When it was sent and when its timeout runs out (clock time).
    started: Duration,
    deadline: Duration,
    /// Timeout of the `WH` check that follows.
    check_timeout: Duration,
}

fn text(cmd: &Command) -> String {
    String::from_utf8_lossy(&cmd.encode())
        .trim_end()
        .to_string()
}

impl<T: ByteTransport> MovemasterArm<T> {
    /// A driver for `chain` (five joints) with the `[devices.arm]` settings.
    pub fn new(
        io: T,
        chain: SerialChain,
        cfg: &ArmConfig,
        clock: SharedClock,
    ) -> Result<Self, DeviceError> {
        if chain.dof() != 5 {
            return Err(DeviceError::Config {
                key: "arm".into(),
                reason: format!(
                    "the Movemaster drives 5 joints, the rig's chain has {}",
                    chain.dof()
                ),
            });
        }
        let resolution = cfg
            .resolution_decimals()
            .and_then(|d| Resolution::new(d).ok())
            .ok_or_else(|| DeviceError::Config {
                key: "arm.resolution_deg".into(),
                reason: "must be a power of ten from 1 down to 0.0001".into(),
            })?;
        let controller =
            ControllerKinematics::new(chain.clone(), cfg.controller_frame, nalgebra::Vector3::x())
                .map_err(|e| DeviceError::Config {
                    key: "arm".into(),
                    reason: e.to_string(),
                })?;
        Ok(MovemasterArm {
            io,
            clock,
            chain,
            cfg: cfg.clone(),
            resolution,
            framer: LineFramer::default(),
            lines: VecDeque::new(),
            commanded_counts: None,
            off_grid_deg: [0.0; 5],
            controller,
            pending: None,
        })
    }

    /// Uses `controller` (the rig's frame and pin axis) for Cartesian moves and the `WH` check.
    pub fn with_controller(mut self, controller: ControllerKinematics) -> Self {
        self.controller = controller;
        self
    }

    fn sign(&self, k: usize) -> f64 {
        self.cfg.sign.get(k).copied().unwrap_or(1.0)
    }

    fn offset(&self, k: usize) -> f64 {
        self.cfg.offset_deg.get(k).copied().unwrap_or(0.0)
    }

    fn counts_to_q(&self, counts: &[i64; 5]) -> Vec<f64> {
        counts
            .iter()
            .enumerate()
            .map(|(k, c)| {
                let deg = self.resolution.counts_to_deg(*c) + self.off_grid_deg[k];
                ((deg - self.offset(k)) / self.sign(k)).to_radians()
            })
            .collect()
    }

    fn controller_deg(&self, q: &[f64]) -> [f64; 5] {
        let mut out = [0.0; 5];
        for (k, slot) in out.iter_mut().enumerate() {
            *slot = self.sign(k) * q.get(k).copied().unwrap_or(0.0).to_degrees() + self.offset(k);
        }
        out
    }

    fn transport(&self, source: TransportError) -> DeviceError {
        DeviceError::Transport {
            device: DeviceName::Arm,
            source,
        }
    }

    fn send(&mut self, cmd: &Command) -> Result<(), DeviceError> {
        tracing::debug!(command = %text(cmd), "arm: send");
        self.io
            .write_all(&cmd.encode())
            .map_err(|e| self.transport(e))
    }

    fn current(&self) -> String {
        match &self.commanded_counts {
            Some(c) => format!(
                "{:?} deg (D-H)",
                self.counts_to_q(c)
                    .iter()
                    .map(|q| q.to_degrees())
                    .collect::<Vec<_>>()
            ),
            None => "not homed".into(),
        }
    }

    /// Reads one reply line, waiting at most `timeout` (clock time).
    fn read_line(&mut self, request: &str, timeout: Duration) -> Result<Vec<u8>, DeviceError> {
        let start = self.clock.now();
        match self.next_line(timeout)? {
            Some(Ok(line)) => Ok(line),
            Some(Err(e)) => Err(DeviceError::Protocol {
                device: DeviceName::Arm,
                request: request.into(),
                detail: e.to_string(),
            }),
            None => Err(DeviceError::Timeout {
                device: DeviceName::Arm,
                waiting_for: format!("the reply to `{request}`"),
                waited: self.clock.now().saturating_sub(start),
                target: request.into(),
                current: self.current(),
            }),
        }
    }

    /// The next reply line within `timeout` (clock time), `None` if none came (cheap: a slice
    /// of a longer wait ends so); a garbled line as the framer's error.
    #[allow(clippy::type_complexity)]
    fn next_line(
        &mut self,
        timeout: Duration,
    ) -> Result<Option<Result<Vec<u8>, MovemasterError>>, DeviceError> {
        let deadline = self.clock.now() + timeout;
        let mut buf = [0u8; 64];
        loop {
            if let Some(line) = self.lines.pop_front() {
                return Ok(Some(line));
            }
            let remaining = deadline.saturating_sub(self.clock.now());
            match self.io.read(&mut buf, remaining) {
                Ok(n) => {
                    let lines = self.framer.push(buf.get(..n).unwrap_or(&[]));
                    self.lines.extend(lines);
                }
                Err(TransportError::Timeout { .. }) => return Ok(None),
                Err(e) => return Err(self.transport(e)),
            }
            if self.lines.is_empty() && self.clock.now() >= deadline {
                return Ok(None);
            }
        }
    }

    fn read_status(&mut self, after: &str, timeout: Duration) -> Result<ErrorStatus, DeviceError> {
        self.request_status()?;
        let line = self.read_line(&format!("ER after {after}"), timeout)?;
        decode_status(after, &line)
    }

    /// Drops what the controller sent so far and asks for its error state (`ER`).
    fn request_status(&mut self) -> Result<(), DeviceError> {
        self.io.clear_input().map_err(|e| self.transport(e))?;
        self.framer = LineFramer::default();
        self.lines.clear();
        self.send(&Command::ErrorRead)
    }

    /// Sends `cmd`, then `ER`, and waits for its reply (the end of any motion).
    fn command(&mut self, cmd: &Command, timeout: Duration) -> Result<(), DeviceError> {
        let t = text(cmd);
        self.send(cmd)?;
        let status = self.read_status(&t, timeout)?;
        self.outcome(t, status)
    }

    /// A pending move's end: reads its `ER` reply, waiting at most `slice`; `Ok(false)` while
    /// the reply has not come and the move's timeout has not run out.
    fn finish_pending(&mut self, slice: Duration) -> Result<bool, DeviceError> {
        let Some(deadline) = self.pending.as_ref().map(|p| p.deadline) else {
            return Ok(true);
        };
        let left = deadline.saturating_sub(self.clock.now());
        let line = self.next_line(slice.min(left));
        if matches!(line, Ok(None)) && self.clock.now() < deadline {
            return Ok(false);
        }
        let Some(p) = self.pending.take() else {
            return Ok(true);
        };
        let request = format!("ER after {}", p.command);
        let line = match line? {
            Some(Ok(line)) => line,
            Some(Err(e)) => {
                return Err(DeviceError::Protocol {
                    device: DeviceName::Arm,
                    request,
                    detail: e.to_string(),
                })
            }
            None => {
                return Err(DeviceError::Timeout {
                    device: DeviceName::Arm,
                    waiting_for: format!("the reply to `{request}`"),
                    waited: self.clock.now().saturating_sub(p.started),
                    target: request,
                    current: self.current(),
                })
            }
        };
        let status = decode_status(&p.command, &line)?;
        self.outcome(p.command, status)?;
        self.commanded_counts = Some(p.counts);
        self.off_grid_deg = p.off_grid_deg;
        let done = self.counts_to_q(&p.counts);
        self.check_where(&done, p.check_timeout)?;
        Ok(true)
    }

    /// Finishes a move whose wait was abandoned before the next command goes out.
    fn settle(&mut self) -> Result<(), DeviceError> {
        while !self.finish_pending(Duration::MAX)? {}
        Ok(())
    }

    /// The controller's error state after `command`: an error mode becomes its error.
    fn outcome(&mut self, command: String, status: ErrorStatus) -> Result<(), DeviceError> {
        match status {
            ErrorStatus::None => Ok(()),
            status => {
                let joints_deg = self
                    .commanded_counts
                    .as_ref()
                    .map(|c| self.counts_to_q(c).iter().map(|q| q.to_degrees()).collect());
                if status == ErrorStatus::Hardware {
                    // Where the arm is is unknown now: it must be homed again.
                    self.commanded_counts = None;
                }
                Err(error_mode(command, status, joints_deg))
            }
        }
    }

    fn check_where(&mut self, q: &[f64], timeout: Duration) -> Result<(), DeviceError> {
        if self.cfg.where_tolerance_mm <= 0.0 {
            return Ok(());
        }
        let pose = self.where_pose(timeout)?;
        let e = ErrorParams::zeros(self.chain.layout());
        // `WH` speaks the controller's frame.
        let p = self
            .controller
            .frame()
            .from_world(&self.chain.position(q, &e));
        let r = nalgebra::Vector3::from(pose.xyz_mm);
        let d = (p - r).norm();
        if d > self.cfg.where_tolerance_mm {
            return Err(DeviceError::PoseMismatch {
                expected: [p.x, p.y, p.z],
                reported: pose.xyz_mm,
                distance_mm: d,
                tolerance_mm: self.cfg.where_tolerance_mm,
            });
        }
        Ok(())
    }
}

fn decode_status(after: &str, line: &[u8]) -> Result<ErrorStatus, DeviceError> {
    ErrorStatus::decode_body(line).map_err(|e| DeviceError::Protocol {
        device: DeviceName::Arm,
        request: format!("ER after {after}"),
        detail: e.to_string(),
    })
}

fn error_mode(command: String, status: ErrorStatus, joints_deg: Option<Vec<f64>>) -> DeviceError {
    let (code, meaning, advice) = match status {
        ErrorStatus::Hardware => (
            1,
            "hardware error",
            "the driver will not reset it: have the operator clear the cause and reset the controller, then home again",
        ),
        _ => (
            2,
            "position out of range or command format",
            "the move was not executed; `reset` clears it",
        ),
    };
    DeviceError::ArmErrorMode {
        command,
        code,
        meaning,
        joints_deg,
        advice,
    }
}

impl<T: ByteTransport> Arm for MovemasterArm<T> {
    fn home(&mut self, timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        // Homing is how the session recovers from a lost reply: an abandoned move that never
        // ends must not stop it.
        if let Err(e) = self.settle() {
            tracing::warn!("arm: the abandoned move before homing did not end cleanly: {e}");
        }
        self.command(&Command::Nest, timeout)?;
        let nest: Vec<f64> = self.cfg.nest_deg.iter().map(|d| d.to_radians()).collect();
        let deg = self.controller_deg(&nest);
        let mut counts = [0i64; 5];
        for (c, d) in counts.iter_mut().zip(deg) {
            *c = self
                .resolution
                .to_counts(d)
                .map_err(|e| DeviceError::Config {
                    key: "arm.nest_deg".into(),
                    reason: e.to_string(),
                })?;
        }
        self.commanded_counts = Some(counts);
        self.off_grid_deg = [0.0; 5];
        let q = self.counts_to_q(&counts);
        if let Ok(level) = SpeedLevel::new(self.cfg.speed) {
            self.command(&Command::Speed { level, accel: None }, timeout)?;
        }
        Ok(q)
    }

    fn set_speed(&mut self, level: u8, timeout: Duration) -> Result<(), DeviceError> {
        let level = SpeedLevel::new(level).map_err(|e| DeviceError::Config {
            key: "arm.speed".into(),
            reason: e.to_string(),
        })?;
        self.settle()?;
        self.command(&Command::Speed { level, accel: None }, timeout)
    }

    fn move_to(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        let done = self.start_move(q, timeout)?;
        while !self.wait_moved(timeout)? {}
        Ok(done)
    }

    fn start_move(&mut self, q: &[f64], timeout: Duration) -> Result<Vec<f64>, DeviceError> {
        self.settle()?;
        let Some(old) = self.commanded_counts else {
            return Err(DeviceError::NotReady {
                device: DeviceName::Arm,
                detail: "joint positions unknown: home the arm (NT) first".into(),
            });
        };
        if q.len() != 5 {
            return Err(DeviceError::Config {
                key: "arm".into(),
                reason: format!("a move needs 5 joint values, got {}", q.len()),
            });
        }
        let mut target = self.controller_deg(q);
        for (t, o) in target.iter_mut().zip(self.off_grid_deg) {
            *t -= o;
        }
        let (mut cmd, counts) =
            quantise_joint_move(&target, &old, self.resolution).map_err(|e| {
                DeviceError::Protocol {
                    device: DeviceName::Arm,
                    request: "MJ".into(),
                    detail: e.to_string(),
                }
            })?;
        let moving: Vec<usize> = (0..5).filter(|&k| counts[k] != old[k]).collect();
        if moving.is_empty() {
            return Ok(self.counts_to_q(&old));
        }
        if let [k] = moving.as_slice() {
            let joint = JointNumber::new(*k as u8 + 1).map_err(|e| DeviceError::Config {
                key: "arm".into(),
                reason: e.to_string(),
            })?;
            let angle =
                Decimal::from_counts(counts[*k] - old[*k], self.resolution).map_err(|e| {
                    DeviceError::Protocol {
                        device: DeviceName::Arm,
                        request: "DJ".into(),
                        detail: e.to_string(),
                    }
                })?;
            cmd = Command::MoveJoint { joint, angle };
        }
        let command = text(&cmd);
        self.send(&cmd)?;
        self.request_status()?;
        let started = self.clock.now();
        self.pending = Some(PendingMove {
            command,
            counts,
            off_grid_deg: self.off_grid_deg,
            started,
            deadline: started + timeout,
            check_timeout: timeout,
        });
        Ok(self.counts_to_q(&counts))
    }

    fn start_move_cartesian(
        &mut self,
        q: &[f64],
        timeout: Duration,
    ) -> Result<Vec<f64>, DeviceError> {
        self.settle()?;
        let Some(at) = self.commanded() else {
            return Err(DeviceError::NotReady {
                device: DeviceName::Arm,
                detail: "joint positions unknown: home the arm (NT) first".into(),
            });
        };
        if q.len() != 5 {
            return Err(DeviceError::Config {
                key: "arm".into(),
                reason: format!("a move needs 5 joint values, got {}", q.len()),
            });
        }
        let pose = ControllerKinematics::rounded(&self.controller.pose(q));
        let cmd = Command::move_pose(&pose).map_err(|e| DeviceError::Protocol {
            device: DeviceName::Arm,
            request: "MP".into(),
            detail: e.to_string(),
        })?;
        // The controller solves from where it is, as the driver does here.
        let landed = self
            .controller
            .solve(&pose, &at)
            .map_err(|e| DeviceError::PoseRefused {
                pose,
                detail: e.to_string(),
            })?;
        let exact = self.controller_deg(&landed);
        let mut counts = [0i64; 5];
        let mut off_grid = [0.0; 5];
        for k in 0..5 {
            counts[k] = self
                .resolution
                .to_counts(exact[k])
                .map_err(|e| DeviceError::Protocol {
                    device: DeviceName::Arm,
                    request: "MP".into(),
                    detail: e.to_string(),
                })?;
            off_grid[k] = exact[k] - self.resolution.counts_to_deg(counts[k]);
        }
        let command = text(&cmd);
        self.send(&cmd)?;
        self.request_status()?;
        let started = self.clock.now();
        self.pending = Some(PendingMove {
            command,
            counts,
            off_grid_deg: off_grid,
            started,
            deadline: started + timeout,
            check_timeout: timeout,
        });
        Ok(landed)
    }

    fn wait_moved(&mut self, slice: Duration) -> Result<bool, DeviceError> {
        self.finish_pending(slice)
    }

    /// The Movemaster's command language has no stop over RS-232 (the drive unit's STOP switch
    /// and emergency stop are the operator's): the controller finishes the move it is in. So
    /// this sends no further motion and waits, at most `timeout`, for the move in progress to
    /// end (its `ER` reply, then the `WH` check), so that the arm is known at rest where the
    /// driver says it is.
    fn stop(&mut self, timeout: Duration) -> Result<bool, DeviceError> {
        let until = self.clock.now() + timeout;
        while self.pending.is_some() {
            let left = until.saturating_sub(self.clock.now());
            if left.is_zero() {
                return Ok(false);
            }
            if self.finish_pending(left)? {
                break;
            }
        }
        Ok(true)
    }

    fn commanded(&self) -> Option<Vec<f64>> {
        self.commanded_counts.as_ref().map(|c| self.counts_to_q(c))
    }

    fn where_pose(&mut self, timeout: Duration) -> Result<ArmPose, DeviceError> {
        self.settle()?;
        self.io.clear_input().map_err(|e| self.transport(e))?;
        self.framer = LineFramer::default();
        self.lines.clear();
        self.send(&Command::Where)?;
        let line = self.read_line("WH", timeout)?;
        let w = WhereReply::decode_body(&line).map_err(|e| DeviceError::Protocol {
            device: DeviceName::Arm,
            request: "WH".into(),
            detail: e.to_string(),
        })?;
        Ok(ArmPose {
            xyz_mm: [w.x, w.y, w.z],
            pitch_deg: w.pitch,
            roll_deg: w.roll,
        })
    }

    fn status(&mut self, timeout: Duration) -> Result<ArmStatus, DeviceError> {
        self.settle()?;
        Ok(match self.read_status("status query", timeout)? {
            ErrorStatus::None => ArmStatus::Ok,
            ErrorStatus::Hardware => ArmStatus::HardwareError,
            ErrorStatus::Position => ArmStatus::PositionError,
        })
    }

    fn reset(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        self.settle()?;
        match self.read_status("reset", timeout)? {
            ErrorStatus::None => Ok(()),
            ErrorStatus::Hardware => Err(DeviceError::ResetNotSafe {
                device: DeviceName::Arm,
                reason: "error mode I (hardware): the cause must be cleared by the operator, and the arm homed again".into(),
            }),
            ErrorStatus::Position => self.command(&Command::Reset, timeout),
        }
    }
}
