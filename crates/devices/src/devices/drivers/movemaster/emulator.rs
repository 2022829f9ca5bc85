//! Emulated Movemaster controller (RV-M2): `NT`, `SP`, `MJ`, `DJ`, `MP`, `WH`, `ER`, `RS`, one
//! CR-terminated line each, executed one after the other.
//!
//! `MP x,y,z,p,r` is solved as the controller does: its own nominal inverse kinematics in its
//! own frame (the rig file's `controller_frame`; pose convention in
//! [`crate::devices::drivers::movemaster::controller`]), from the joints it is at; the pose arrives rounded to 0.1 mm /
//! 0.1° (the wire's one decimal) and the solution is rounded to the joint servo resolution
//! (`sim_servo_resolution_deg`). No solution, or one outside the joint limits: error mode II.
//!
//! Joint angles on the wire are controller degrees (controller angle = sign · q + offset, from
//! the rig file). A motion takes the largest joint increment divided by the joint speed of the
//! current speed level; a query (`WH`, `ER`) is answered when every earlier motion has finished,
//! plus the reply latency. A target outside the joint limits, or an undecodable line, puts the
//! controller in error mode II (position/format); `RS` clears mode II only. In error mode the
//! controller ignores every command but `ER`, `WH` and `RS`. `WH` answers the nominal
//! Cartesian pose of the commanded joints (x, y, z in the rig's world frame, pitch = elevation of
//! the pin, roll = q4: [`crate::devices::drivers::movemaster::controller`]), as the controller computes it from its encoders — not the true pose.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use crate::devices::drivers::movemaster::controller::{round_joints, ControllerKinematics};
use crate::devices::drivers::movemaster::settings::ArmConfig;
use crate::devices::emulators::faults::ArmFaultHandle;
use crate::devices::emulators::physics::SharedPhysics;
use crate::devices::emulators::{lock, ByteEmulator};
use crate::protocols::movemaster::{Command, ErrorStatus, LineFramer, WhereReply};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};
use rigcal_core::rig::{Instrument, Rig};

/// The emulated controller. Thirteen fields: its fixed settings and kinematics beside the state
/// a controller keeps (angles, error mode, speed level, busy time, queued replies).
#[derive(Debug)]
pub struct ArmEmulator {
    chain: SerialChain,
    controller: Option<ControllerKinematics>,
    pin_axis: nalgebra::Vector3<f64>,
    cfg: ArmConfig,
    limits: Vec<(f64, f64)>,
    physics: SharedPhysics,
    faults: ArmFaultHandle,
    framer: LineFramer,
    angles: [f64; 5],
    busy_until: Duration,
    error: ErrorStatus,
    speed: u8,
    out: VecDeque<(Duration, Vec<u8>)>,
}

impl ArmEmulator {
    /// A controller for `rig`'s arm with the `[devices.arm]` settings, powered on at the nest.
    pub fn new(rig: &Rig, cfg: &ArmConfig, physics: SharedPhysics) -> Self {
        let limits = rig
            .chain
            .joints()
            .iter()
            .zip(cfg.sign.iter().zip(&cfg.offset_deg))
            .map(|(j, (s, o))| {
                let a = s * j.min.to_degrees() + o;
                let b = s * j.max.to_degrees() + o;
                (a.min(b), a.max(b))
            })
            .collect();
        let pin_axis = match &rig.instrument {
            Instrument::TablePanel(t) => t.pin_axis,
            _ => nalgebra::Vector3::x(),
        };
        let controller =
            ControllerKinematics::new(rig.chain.clone(), cfg.controller_frame, pin_axis).ok();
        let mut e = ArmEmulator {
            chain: rig.chain.clone(),
            controller,
            pin_axis,
            cfg: cfg.clone(),
            limits,
            physics,
            faults: ArmFaultHandle::default(),
            framer: LineFramer::default(),
            angles: [0.0; 5],
            busy_until: Duration::ZERO,
            error: ErrorStatus::None,
            speed: 5,
            out: VecDeque::new(),
        };
        e.angles = e.nest_angles();
        e
    }

    /// The fault and log handle.
    pub fn faults(&self) -> ArmFaultHandle {
        Arc::clone(&self.faults)
    }

    fn nest_angles(&self) -> [f64; 5] {
        let mut a = [0.0; 5];
        for (k, slot) in a.iter_mut().enumerate() {
            let s = self.cfg.sign.get(k).copied().unwrap_or(1.0);
            let o = self.cfg.offset_deg.get(k).copied().unwrap_or(0.0);
            *slot = s * self.cfg.nest_deg.get(k).copied().unwrap_or(0.0) + o;
        }
        a
    }

    fn q_rad(&self, angles: &[f64; 5]) -> Vec<f64> {
        angles
            .iter()
            .enumerate()
            .map(|(k, a)| {
                let s = self.cfg.sign.get(k).copied().unwrap_or(1.0);
                let o = self.cfg.offset_deg.get(k).copied().unwrap_or(0.0);
                ((a - o) / s).to_radians()
            })
            .collect()
    }

    fn move_to(&mut self, target: [f64; 5], now: Duration) {
        let within = target
            .iter()
            .zip(&self.limits)
            .all(|(a, (lo, hi))| *a >= lo - 1e-9 && *a <= hi + 1e-9);
        if !within {
            self.error = ErrorStatus::Position;
            return;
        }
        let biggest = target
            .iter()
            .zip(&self.angles)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let speed = self.cfg.sim_joint_speed_deg_s * f64::from(self.speed + 1) / 10.0;
        let start = self.busy_until.max(now);
        self.busy_until = start + Duration::from_secs_f64(biggest / speed);
        self.angles = target;
        let q = self.q_rad(&target);
        lock(&self.physics).arm_commanded(&q, self.busy_until);
    }

    fn reply(&mut self, bytes: Vec<u8>, now: Duration) {
        let mut f = lock(&self.faults);
        if f.drop_replies > 0 {
            f.drop_replies -= 1;
            return;
        }
        let mut bytes = bytes;
        if f.garble_replies > 0 {
            f.garble_replies -= 1;
            if let Some(b) = bytes.first_mut() {
                *b = b'?';
            }
        }
        let at = self.busy_until.max(now)
            + Duration::from_secs_f64(self.cfg.sim_reply_ms / 1000.0)
            + f.extra_delay;
        self.out.push_back((at, bytes));
    }

    fn where_reply(&self) -> WhereReply {
        let q = self.q_rad(&self.angles);
        let [x, y, z, pitch, roll] = match &self.controller {
            Some(k) => k.pose(&q),
            None => {
                let e = ErrorParams::zeros(self.chain.layout());
                let p = self.chain.position(&q, &e);
                let pin = self.chain.tool_pose(&q, &e).rotation * self.pin_axis;
                [
                    p.x,
                    p.y,
                    p.z,
                    pin.z.clamp(-1.0, 1.0).asin().to_degrees(),
                    q.get(3).copied().unwrap_or(0.0).to_degrees(),
                ]
            }
        };
        WhereReply {
            x,
            y,
            z,
            pitch,
            roll,
        }
    }

    /// The controller angles an `MP` pose lands on, `None` when its kinematics find none.
    fn solve_pose(&self, pose: &[f64; 5]) -> Option<[f64; 5]> {
        let k = self.controller.as_ref()?;
        let seed = self.q_rad(&self.angles);
        let q = round_joints(
            &k.solve(pose, &seed).ok()?,
            self.cfg.sim_servo_resolution_deg,
        );
        let mut out = [0.0; 5];
        for (j, slot) in out.iter_mut().enumerate() {
            let s = self.cfg.sign.get(j).copied().unwrap_or(1.0);
            let o = self.cfg.offset_deg.get(j).copied().unwrap_or(0.0);
            *slot = s * q.get(j).copied().unwrap_or(0.0).to_degrees() + o;
        }
        Some(out)
    }

    /// Takes the injected error mode of the next move, if any; true when one was set.
    fn injected_error(&mut self) -> bool {
        let Some(code) = lock(&self.faults).error_on_next_move.take() else {
            return false;
        };
        self.error = if code == 1 {
            ErrorStatus::Hardware
        } else {
            ErrorStatus::Position
        };
        true
    }

    fn line(&mut self, line: &[u8], now: Duration) {
        lock(&self.faults)
            .received
            .push(String::from_utf8_lossy(line).into_owned());
        let cmd = match Command::decode(line) {
            Ok(c) => c,
            Err(_) => {
                self.error = ErrorStatus::Position;
                return;
            }
        };
        let in_error = self.error != ErrorStatus::None;
        match cmd {
            Command::ErrorRead => self.reply(self.error.encode(), now),
            Command::Where => self.reply(self.where_reply().encode(), now),
            Command::Reset => {
                if self.error == ErrorStatus::Position {
                    self.error = ErrorStatus::None;
                }
            }
            _ if in_error => {}
            Command::Nest => {
                let nest = self.nest_angles();
                self.move_to(nest, now);
            }
            Command::Speed { level, .. } => self.speed = level.get(),
            Command::MoveJoints(inc) => {
                if let Some(code) = lock(&self.faults).error_on_next_move.take() {
                    self.error = if code == 1 {
                        ErrorStatus::Hardware
                    } else {
                        ErrorStatus::Position
                    };
                    return;
                }
                let mut t = self.angles;
                for (a, d) in t.iter_mut().zip(inc) {
                    *a += d.to_f64();
                }
                self.move_to(t, now);
            }
            Command::MovePose(values) => {
                if self.injected_error() {
                    return;
                }
                match self.solve_pose(&values.map(|v| v.to_f64())) {
                    Some(t) => self.move_to(t, now),
                    None => self.error = ErrorStatus::Position,
                }
            }
            Command::MoveJoint { joint, angle } => {
                if let Some(code) = lock(&self.faults).error_on_next_move.take() {
                    self.error = if code == 1 {
                        ErrorStatus::Hardware
                    } else {
                        ErrorStatus::Position
                    };
                    return;
                }
                let mut t = self.angles;
                if let Some(a) = t.get_mut(usize::from(joint.get()).saturating_sub(1)) {
                    *a += angle.to_f64();
                }
                self.move_to(t, now);
            }
        }
    }
}

impl ByteEmulator for ArmEmulator {
    fn input(&mut self, bytes: &[u8], now: Duration) {
        for line in self.framer.push(bytes) {
            match line {
                Ok(l) => self.line(&l, now),
                Err(_) => self.error = ErrorStatus::Position,
            }
        }
    }

    fn output(&mut self, now: Duration) -> Vec<u8> {
        let mut out = Vec::new();
        while let Some((t, _)) = self.out.front() {
            if *t > now {
                break;
            }
            if let Some((_, b)) = self.out.pop_front() {
                out.extend(b);
            }
        }
        out
    }

    fn next_event(&mut self, _now: Duration, _horizon: Duration) -> Option<Duration> {
        self.out.front().map(|(t, _)| *t)
    }
}
