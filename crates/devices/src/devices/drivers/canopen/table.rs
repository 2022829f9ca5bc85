//! Driver for the x-y-z table: three CiA 402 drives on CANopen, profile position mode.
//!
//! Protocol: [`crate::protocols::canopen`] over any [`CanBus`] (SocketCAN, slcan, the in-process
//! simulated bus). Expedited SDOs only, one outstanding request at a time; an abort becomes
//! [`DeviceError::SdoAbort`]. Enabling sends NMT start, sets each drive's heartbeat period
//! (0x1017), profile position mode (0x6060 = 1, checked in 0x6061), the profile velocity,
//! acceleration and deceleration (0x6081/0x6083/0x6084), and walks the CiA 402 state machine
//! (shutdown → switch on → enable operation; fault reset on a rising edge of bit 7).
//!
//! A move per axis: write the target (0x607A), raise controlword bit 4, wait for the set-point
//! acknowledge (statusword bit 12), clear bit 4; then [`Table::wait_reached`] waits for target
//! reached (bit 10), which is already set before a move starts — hence the acknowledge first.
//! Fault (bit 3), following error (bit 13) and EMCY frames end the wait with a typed error.
//! Heartbeats are supervised as a master would (limit three periods) whenever the driver talks
//! to the bus: frames are drained and each node's last heartbeat time is checked. An SDO left
//! unanswered is sent again (up to [`SDO_ATTEMPTS`] times) before its timeout is an error. A
//! safe stop ([`Table::quick_stop`]) sends the CiA 402 quick stop command to every drive.
//!
//! With `touch_probe = true` (`[devices.table]`) the z drive latches the contact height: its
//! touch probe 1 (0x60B8) is checked at bring-up, armed before an approach (switched off, then
//! on for the first positive edge of its input), and its stored position (0x60BA) read once
//! its status (0x60B9) says a positive edge is stored ([`Table::arm_touch_probe`],
//! [`Table::latched_z`]).
//!
//! Units: mm on the trait, counts on the wire (counts per mm per axis from the rig file); times
//! on the driver's [`Clock`](crate::devices::clock::Clock).

// Axis index k addresses several per-axis arrays at once (node ids, units, heartbeat times).
#![allow(clippy::needless_range_loop)]

use std::time::Duration;

use crate::devices::clock::SharedClock;
use crate::devices::drivers::canopen::settings::TableConfig;
use crate::devices::traits::{DeviceError, DeviceName, Table};
use crate::protocols::canopen::{
    next_controlword_towards_enabled, od, CanOpenMessage, Controlword, DriveState, Nmt, NmtCommand,
    NodeId, SdoData, SdoRequest, SdoResponse, Statusword, TouchProbeFunction, TouchProbeStatus,
};
use crate::transports::{CanBus, TransportError};

const AXES: [char; 3] = ['x', 'y', 'z'];

/// The axis whose drive latches the contact height (its probe input wired to the panel).
const Z: usize = 2;

/// How often an SDO request is sent before its timeout counts: CAN loses a frame now and then
/// (a bus error, an overrun in a busy adapter), and at a few per cent of frames lost one
/// exchange in ten needs a repeat; five attempts leave about one failed exchange in 10⁵.
pub const SDO_ATTEMPTS: u32 = 5;

/// The CANopen table driver.
#[derive(Debug)]
pub struct CanOpenTable<B: CanBus> {
    bus: B,
    clock: SharedClock,
    cfg: TableConfig,
    nodes: [NodeId; 3],
    last_hb: [Option<Duration>; 3],
    supervising: bool,
    last_cw: [u16; 3],
    emcy: [Option<u16>; 3],
    target_mm: Option<[f64; 3]>,
    last_pos: Option<[f64; 3]>,
}

impl<B: CanBus> CanOpenTable<B> {
    /// A driver for the drives named in `[devices.table]`.
    pub fn new(bus: B, cfg: &TableConfig, clock: SharedClock) -> Result<Self, DeviceError> {
        let mut nodes = [NodeId::new(1).map_err(|e| cfg_err("table.node_ids", e))?; 3];
        for (slot, n) in nodes.iter_mut().zip(cfg.node_ids) {
            *slot = NodeId::new(n).map_err(|e| cfg_err("table.node_ids", e))?;
        }
        Ok(CanOpenTable {
            bus,
            clock,
            cfg: cfg.clone(),
            nodes,
            last_hb: [None; 3],
            supervising: false,
            last_cw: [0; 3],
            emcy: [None; 3],
            target_mm: None,
            last_pos: None,
        })
    }

    fn transport(source: TransportError) -> DeviceError {
        DeviceError::Transport {
            device: DeviceName::Table,
            source,
        }
    }

    fn poll(&self) -> Duration {
        Duration::from_millis(self.cfg.poll_ms)
    }

    fn hb_limit(&self) -> Duration {
        Duration::from_millis(3 * u64::from(self.cfg.heartbeat_ms))
    }

    fn observe(
        &mut self,
        frame: &crate::protocols::can::CanFrame,
    ) -> Option<(NodeId, SdoResponse)> {
        match CanOpenMessage::decode(frame) {
            Ok(CanOpenMessage::Heartbeat(hb)) => {
                if let Some(k) = self.nodes.iter().position(|n| *n == hb.node) {
                    self.last_hb[k] = Some(self.clock.now());
                }
                None
            }
            Ok(CanOpenMessage::Emergency(e)) => {
                if let Some(k) = self.nodes.iter().position(|n| *n == e.node) {
                    let code = e.error_code.code();
                    if code != 0 {
                        tracing::warn!(
                            node = e.node.get(),
                            code = format_args!("{code:#06x}"),
                            "table: EMCY"
                        );
                        self.emcy[k] = Some(code);
                    }
                }
                None
            }
            Ok(CanOpenMessage::SdoResponse { node, response }) => Some((node, response)),
            _ => None,
        }
    }

    /// Reads every frame already received.
    fn drain(&mut self) -> Result<(), DeviceError> {
        for _ in 0..10_000 {
            match self.bus.recv(Duration::ZERO) {
                Ok(f) => {
                    self.observe(&f);
                }
                Err(TransportError::Timeout { .. }) => return Ok(()),
                Err(e) => return Err(Self::transport(e)),
            }
        }
        Ok(())
    }

    fn fault_error(&self, k: usize, statusword: u16) -> DeviceError {
        DeviceError::DriveFault {
            axis: AXES[k],
            node: self.nodes[k].get(),
            statusword,
            emcy_code: self.emcy[k],
            target_mm: self.target_mm.map(|t| t[k]),
            current_mm: self.last_pos.map(|p| p[k]),
        }
    }

    /// Drains the bus, then fails on an EMCY or a lost heartbeat.
    fn check_health(&mut self) -> Result<(), DeviceError> {
        self.drain()?;
        if let Some(k) = self.emcy.iter().position(Option::is_some) {
            return Err(self.fault_error(k, 0));
        }
        if self.supervising {
            let now = self.clock.now();
            for k in 0..3 {
                let last = self.last_hb[k].unwrap_or(Duration::ZERO);
                let silent_for = now.saturating_sub(last);
                if silent_for > self.hb_limit() {
                    return Err(DeviceError::HeartbeatLost {
                        axis: AXES[k],
                        node: self.nodes[k].get(),
                        silent_for,
                        limit: self.hb_limit(),
                    });
                }
            }
        }
        Ok(())
    }

    /// One SDO exchange with drive `k`: the request sent again while no answer comes, up to
    /// [`SDO_ATTEMPTS`] times (a lost frame on the bus, in either direction, costs one SDO
    /// timeout instead of the session), the bus drained before each repeat so that a late
    /// answer to an earlier attempt is not left for the next exchange. A repeated request is
    /// harmless: a write sets the same value again (a controlword written twice is no new
    /// edge), a read reads again.
    fn sdo(&mut self, k: usize, req: SdoRequest) -> Result<SdoResponse, DeviceError> {
        let mut attempt = 1;
        loop {
            match self.sdo_once(k, req) {
                Err(e @ DeviceError::Timeout { .. }) if attempt < SDO_ATTEMPTS => {
                    tracing::debug!("table: SDO lost ({e}); sending it again");
                    attempt += 1;
                    self.drain()?;
                }
                other => return other,
            }
        }
    }

    fn sdo_once(&mut self, k: usize, req: SdoRequest) -> Result<SdoResponse, DeviceError> {
        let node = self.nodes[k];
        let (index, sub, access) = match req {
            SdoRequest::Upload { index, sub } => (index, sub, "read"),
            SdoRequest::Download { index, sub, .. } => (index, sub, "write"),
            SdoRequest::Abort { index, sub, .. } => (index, sub, "abort"),
        };
        self.bus.send(&req.encode(node)).map_err(Self::transport)?;
        let start = self.clock.now();
        let deadline = start + Duration::from_millis(self.cfg.sdo_timeout_ms);
        loop {
            let remaining = deadline.saturating_sub(self.clock.now());
            let frame = match self.bus.recv(remaining) {
                Ok(f) => f,
                Err(TransportError::Timeout { .. }) => {
                    return Err(DeviceError::Timeout {
                        device: DeviceName::Table,
                        waiting_for: format!(
                            "the SDO {access} response of node {} for {index:#06x}:{sub}",
                            node.get()
                        ),
                        waited: self.clock.now().saturating_sub(start),
                        target: format!("{:?}", self.target_mm),
                        current: format!("{:?}", self.last_pos),
                    })
                }
                Err(e) => return Err(Self::transport(e)),
            };
            if let Some((from, resp)) = self.observe(&frame) {
                if from != node || resp.index() != index || resp.sub() != sub {
                    continue;
                }
                if let SdoResponse::Abort { code, .. } = resp {
                    return Err(DeviceError::SdoAbort {
                        node: node.get(),
                        access,
                        index,
                        sub,
                        code,
                        description: code.description(),
                    });
                }
                return Ok(resp);
            }
        }
    }

    fn read(&mut self, k: usize, index: u16) -> Result<SdoData, DeviceError> {
        match self.sdo(k, SdoRequest::Upload { index, sub: 0 })? {
            SdoResponse::UploadData { data, .. } => Ok(data),
            other => Err(DeviceError::Protocol {
                device: DeviceName::Table,
                request: format!("SDO read {index:#06x} of node {}", self.nodes[k].get()),
                detail: format!("unexpected response {other:?}"),
            }),
        }
    }

    fn write(&mut self, k: usize, index: u16, data: SdoData) -> Result<(), DeviceError> {
        match self.sdo(
            k,
            SdoRequest::Download {
                index,
                sub: 0,
                data,
            },
        )? {
            SdoResponse::DownloadAck { .. } => Ok(()),
            other => Err(DeviceError::Protocol {
                device: DeviceName::Table,
                request: format!("SDO write {index:#06x} of node {}", self.nodes[k].get()),
                detail: format!("unexpected response {other:?}"),
            }),
        }
    }

    fn write_cw(&mut self, k: usize, cw: u16) -> Result<(), DeviceError> {
        self.write(k, od::CONTROLWORD, SdoData::from_u16(cw))?;
        self.last_cw[k] = cw;
        Ok(())
    }

    /// Reads 0x1000 and refuses a node that is not a CiA 402 drive: enabling it with 402's
    /// controlword would mean anything to another device.
    fn check_device_type(&mut self, k: usize) -> Result<(), DeviceError> {
        let device_type = self.read(k, od::DEVICE_TYPE)?.to_u32();
        if device_type & 0xFFFF == od::PROFILE_CIA402 {
            return Ok(());
        }
        Err(DeviceError::Protocol {
            device: DeviceName::Table,
            request: format!("device type (0x1000) of node {}", self.nodes[k].get()),
            detail: format!(
                "{device_type:#010x}: profile {} in the low word, not a CiA 402 drive (402 = 0x0192); check the node IDs in [devices.table]",
                device_type & 0xFFFF
            ),
        })
    }

    fn statusword(&mut self, k: usize) -> Result<Statusword, DeviceError> {
        Ok(Statusword(self.read(k, od::STATUSWORD)?.to_u32() as u16))
    }

    fn counts(&self, k: usize, mm: f64) -> Result<i32, DeviceError> {
        let c = (mm * self.cfg.counts_per_mm[k]).round();
        if c.is_finite() && c.abs() < f64::from(i32::MAX) {
            Ok(c as i32)
        } else {
            Err(DeviceError::Refused {
                device: DeviceName::Table,
                what: format!("axis {}", AXES[k]),
                value: mm,
                min: f64::from(i32::MIN) / self.cfg.counts_per_mm[k],
                max: f64::from(i32::MAX) / self.cfg.counts_per_mm[k],
                why: "position does not fit the drive's 32-bit counts",
            })
        }
    }

    /// Reads the three actual positions with the three SDO requests on the bus at once (one
    /// per drive), so every axis is read one bus latency after the call. A request left
    /// unanswered is sent again, as [`Self::sdo`] does, up to [`SDO_ATTEMPTS`] times.
    fn read_positions(&mut self) -> Result<[f64; 3], DeviceError> {
        let mut got: [Option<f64>; 3] = [None; 3];
        let mut attempt = 1;
        loop {
            match self.read_positions_once(&mut got) {
                Err(e @ DeviceError::Timeout { .. }) if attempt < SDO_ATTEMPTS => {
                    tracing::debug!("table: position read lost ({e}); asking again");
                    attempt += 1;
                    self.drain()?;
                }
                Err(e) => return Err(e),
                Ok(()) => break,
            }
        }
        let p = [
            got[0].unwrap_or(f64::NAN),
            got[1].unwrap_or(f64::NAN),
            got[2].unwrap_or(f64::NAN),
        ];
        self.last_pos = Some(p);
        Ok(p)
    }

    /// Asks every drive whose position `got` lacks, and waits for their answers.
    fn read_positions_once(&mut self, got: &mut [Option<f64>; 3]) -> Result<(), DeviceError> {
        for k in 0..3 {
            if got[k].is_some() {
                continue;
            }
            let req = SdoRequest::Upload {
                index: od::POSITION_ACTUAL,
                sub: 0,
            };
            self.bus
                .send(&req.encode(self.nodes[k]))
                .map_err(Self::transport)?;
        }
        let start = self.clock.now();
        let deadline = start + Duration::from_millis(self.cfg.sdo_timeout_ms);
        while got.iter().any(Option::is_none) {
            let remaining = deadline.saturating_sub(self.clock.now());
            let frame = match self.bus.recv(remaining) {
                Ok(f) => f,
                Err(TransportError::Timeout { .. }) => {
                    return Err(self.timeout(
                        format!(
                            "the position reads (0x6064) of nodes {:?}, got {got:?}",
                            self.cfg.node_ids
                        ),
                        self.clock.now().saturating_sub(start),
                    ))
                }
                Err(e) => return Err(Self::transport(e)),
            };
            let Some((node, resp)) = self.observe(&frame) else {
                continue;
            };
            let Some(k) = self.nodes.iter().position(|n| *n == node) else {
                continue;
            };
            if resp.index() != od::POSITION_ACTUAL {
                continue;
            }
            match resp {
                SdoResponse::UploadData { data, .. } => {
                    got[k] = Some(f64::from(data.to_i32()) / self.cfg.counts_per_mm[k]);
                }
                SdoResponse::Abort { code, .. } => {
                    return Err(DeviceError::SdoAbort {
                        node: node.get(),
                        access: "read",
                        index: od::POSITION_ACTUAL,
                        sub: 0,
                        code,
                        description: code.description(),
                    })
                }
                SdoResponse::DownloadAck { .. } => {}
            }
        }
        Ok(())
    }

    fn timeout(&self, waiting_for: String, waited: Duration) -> DeviceError {
        DeviceError::Timeout {
            device: DeviceName::Table,
            waiting_for,
            waited,
            target: format!("{:?} mm", self.target_mm),
            current: format!("{:?} mm", self.last_pos),
        }
    }

    /// Bring-up with `touch_probe = true`: the z drive's probe switched off (0x60B8 = 0) and
    /// its status read back, so a drive without the touch probe objects is refused before
    /// any contact, naming the rig file's key.
    fn check_touch_probe(&mut self) -> Result<(), DeviceError> {
        let node = self.nodes[Z].get();
        let missing = |e: DeviceError| {
            DeviceError::Config {
            key: "table.touch_probe".into(),
            reason: format!(
                "true, but the z drive (node {node}) does not offer the CiA 402 touch probe (0x60B8/0x60B9): {e}; set touch_probe = false, or use a drive with the latch"
            ),
        }
        };
        self.write(
            Z,
            od::TOUCH_PROBE_FUNCTION,
            SdoData::from_u16(TouchProbeFunction::OFF.0),
        )
        .map_err(|e| match e {
            e @ DeviceError::SdoAbort { .. } => missing(e),
            e => e,
        })?;
        let status = self.probe_status().map_err(|e| match e {
            e @ DeviceError::SdoAbort { .. } => missing(e),
            e => e,
        })?;
        if status.probe1_enabled() {
            return Err(self.probe_protocol(
                "0x60B9 still says probe 1 is enabled after it was switched off".into(),
            ));
        }
        Ok(())
    }

    fn probe_status(&mut self) -> Result<TouchProbeStatus, DeviceError> {
        Ok(TouchProbeStatus(
            self.read(Z, od::TOUCH_PROBE_STATUS)?.to_u32() as u16,
        ))
    }

    fn probe_protocol(&self, detail: String) -> DeviceError {
        DeviceError::Protocol {
            device: DeviceName::Table,
            request: format!("touch probe of the z drive (node {})", self.nodes[Z].get()),
            detail,
        }
    }

    fn enable_drives(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        let start = self.clock.now();
        for k in 0..3 {
            loop {
                let sw = self.statusword(k)?;
                let state = sw.state().map_err(|e| DeviceError::Protocol {
                    device: DeviceName::Table,
                    request: "statusword".into(),
                    detail: e.to_string(),
                })?;
                if state == DriveState::OperationEnabled {
                    break;
                }
                if self.clock.now().saturating_sub(start) > timeout {
                    return Err(self.timeout(
                        format!(
                            "axis {} to reach operation enabled (state {state:?})",
                            AXES[k]
                        ),
                        self.clock.now().saturating_sub(start),
                    ));
                }
                if let Some(cw) = next_controlword_towards_enabled(state) {
                    if cw & Controlword::BIT_FAULT_RESET != 0
                        && self.last_cw[k] & Controlword::BIT_FAULT_RESET != 0
                    {
                        self.write_cw(k, 0)?; // the reset acts on a rising edge
                    }
                    self.write_cw(k, cw)?;
                } else {
                    self.clock.sleep(self.poll());
                }
            }
        }
        Ok(())
    }
}

impl<B: CanBus> CanOpenTable<B> {
    /// Polls the drives until every axis has reached its target (the actual position) or
    /// `within` has passed (`None`); faults end it with their error.
    fn poll_until(&mut self, within: Duration) -> Result<Option<[f64; 3]>, DeviceError> {
        let start = self.clock.now();
        loop {
            self.check_health()?;
            let mut all = true;
            for k in 0..3 {
                let sw = self.statusword(k)?;
                if sw.fault() {
                    self.drain()?;
                    return Err(self.fault_error(k, sw.0));
                }
                if sw.following_error() {
                    return Err(DeviceError::FollowingError {
                        axis: AXES[k],
                        node: self.nodes[k].get(),
                        target_mm: self.target_mm.map_or(f64::NAN, |t| t[k]),
                        current_mm: self.last_pos.map(|p| p[k]),
                    });
                }
                all &= sw.target_reached();
            }
            if all {
                return self.read_positions().map(Some);
            }
            // The poll interval before the check, so that the slices of a longer wait keep
            // the same cadence as one wait.
            self.clock.sleep(self.poll());
            if self.clock.now().saturating_sub(start) > within {
                return Ok(None);
            }
        }
    }

    /// The timeout of a wait for the target that began at `start`, with the last position.
    fn not_reached(&mut self, start: Duration) -> DeviceError {
        let _ = self.read_positions();
        self.timeout(
            "every axis to reach its target (statusword bit 10)".into(),
            self.clock.now().saturating_sub(start),
        )
    }
}

fn cfg_err(key: &str, e: impl std::fmt::Display) -> DeviceError {
    DeviceError::Config {
        key: key.into(),
        reason: e.to_string(),
    }
}

impl<B: CanBus> Table for CanOpenTable<B> {
    fn enable(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        self.bus
            .send(
                &Nmt {
                    command: NmtCommand::Start,
                    node: None,
                }
                .encode(),
            )
            .map_err(Self::transport)?;
        for k in 0..3 {
            self.check_device_type(k)?;
        }
        for k in 0..3 {
            self.write(
                k,
                od::PRODUCER_HEARTBEAT_TIME,
                SdoData::from_u16(self.cfg.heartbeat_ms),
            )?;
            self.last_hb[k] = Some(self.clock.now());
            self.write(
                k,
                od::MODES_OF_OPERATION,
                SdoData::from_i8(od::MODE_PROFILE_POSITION),
            )?;
            let mode = self.read(k, od::MODES_OF_OPERATION_DISPLAY)?.to_i32();
            if mode != i32::from(od::MODE_PROFILE_POSITION) {
                return Err(DeviceError::Protocol {
                    device: DeviceName::Table,
                    request: format!("mode of axis {}", AXES[k]),
                    detail: format!("0x6061 shows mode {mode}, expected 1 (profile position)"),
                });
            }
            let cpm = self.cfg.counts_per_mm[k];
            let v = (self.cfg.profile_velocity_mm_s * cpm).round() as u32;
            let a = (self.cfg.profile_acceleration_mm_s2 * cpm).round() as u32;
            let d = (self.cfg.profile_deceleration_mm_s2 * cpm).round() as u32;
            self.write(k, od::PROFILE_VELOCITY, SdoData::from_u32(v.max(1)))?;
            self.write(k, od::PROFILE_ACCELERATION, SdoData::from_u32(a.max(1)))?;
            self.write(k, od::PROFILE_DECELERATION, SdoData::from_u32(d.max(1)))?;
        }
        if self.cfg.touch_probe {
            self.check_touch_probe()?;
        }
        self.supervising = true;
        self.enable_drives(timeout)?;
        self.read_positions()?;
        self.check_health()
    }

    fn set_speed(&mut self, mm_per_s: f64, _timeout: Duration) -> Result<(), DeviceError> {
        if !(mm_per_s.is_finite() && mm_per_s > 0.0) {
            return Err(DeviceError::Config {
                key: "table.profile_velocity_mm_s".into(),
                reason: format!("a speed must be positive, got {mm_per_s}"),
            });
        }
        for k in 0..3 {
            let v = (mm_per_s * self.cfg.counts_per_mm[k]).round().max(1.0) as u32;
            self.write(k, od::PROFILE_VELOCITY, SdoData::from_u32(v))?;
        }
        Ok(())
    }

    fn start_move(&mut self, target_mm: [f64; 3], timeout: Duration) -> Result<(), DeviceError> {
        self.check_health()?;
        self.target_mm = Some(target_mm);
        let start = self.clock.now();
        let run = Controlword::ENABLE_OPERATION
            .with_change_set_immediately(true)
            .0;
        for k in 0..3 {
            let c = self.counts(k, target_mm[k])?;
            self.write(k, od::TARGET_POSITION, SdoData::from_i32(c))?;
            self.write_cw(k, Controlword(run).with_new_setpoint(true).0)?;
            loop {
                let sw = self.statusword(k)?;
                if sw.fault() {
                    self.drain()?;
                    return Err(self.fault_error(k, sw.0));
                }
                if sw.setpoint_acknowledge() {
                    break;
                }
                let waited = self.clock.now().saturating_sub(start);
                if waited > timeout {
                    return Err(self.timeout(
                        format!(
                            "axis {} to acknowledge the set-point (statusword {:#06x})",
                            AXES[k], sw.0
                        ),
                        waited,
                    ));
                }
                self.clock.sleep(self.poll());
            }
            self.write_cw(k, run)?;
        }
        Ok(())
    }

    fn wait_reached(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        let start = self.clock.now();
        match self.poll_until(timeout)? {
            Some(p) => Ok(p),
            None => Err(self.not_reached(start)),
        }
    }

    fn poll_reached(
        &mut self,
        slice: Duration,
        left: Duration,
    ) -> Result<Option<[f64; 3]>, DeviceError> {
        let start = self.clock.now();
        match self.poll_until(slice.min(left))? {
            Some(p) => Ok(Some(p)),
            None if left <= slice => Err(self.not_reached(start)),
            None => Ok(None),
        }
    }

    fn supervise(&mut self) -> Result<(), DeviceError> {
        self.check_health()
    }

    fn position(&mut self, _timeout: Duration) -> Result<[f64; 3], DeviceError> {
        self.read_positions()
    }

    fn halt(&mut self, _timeout: Duration) -> Result<[f64; 3], DeviceError> {
        for k in 0..3 {
            self.write_cw(k, Controlword::ENABLE_OPERATION.with_halt(true).0)?;
        }
        self.read_positions()
    }

    /// The CiA 402 quick stop command (controlword `0x0002`) to every drive, each tried even
    /// when another does not answer (the first error is returned after all were tried): the
    /// drives stop on their quick-stop ramp and go to *switch on disabled*, the set-point gone.
    fn quick_stop(&mut self, _timeout: Duration) -> Result<[f64; 3], DeviceError> {
        let mut first_error = None;
        for k in 0..3 {
            if let Err(e) = self.write_cw(k, Controlword::QUICK_STOP.0) {
                tracing::warn!("table axis {}: quick stop not acknowledged: {e}", AXES[k]);
                first_error.get_or_insert(e);
            }
        }
        self.target_mm = None;
        if let Some(e) = first_error {
            return Err(e);
        }
        self.read_positions()
    }

    fn fault_reset(&mut self, timeout: Duration) -> Result<(), DeviceError> {
        self.drain()?;
        for k in 0..3 {
            let sw = self.statusword(k)?;
            if sw.fault() {
                if self.last_cw[k] & Controlword::BIT_FAULT_RESET != 0 {
                    self.write_cw(k, 0)?;
                }
                self.write_cw(k, Controlword::FAULT_RESET.0)?;
            }
        }
        self.emcy = [None; 3];
        self.target_mm = None;
        self.enable_drives(timeout)?;
        self.drain()?;
        self.emcy = [None; 3];
        Ok(())
    }

    fn latency(&self) -> Duration {
        Duration::from_secs_f64(self.cfg.bus_latency_ms.max(0.0) / 1000.0)
    }

    /// Switches the z drive's probe 1 off (clearing a stored edge) and on again for the first
    /// positive edge of its input, and checks 0x60B9 says enabled and nothing stored.
    fn arm_touch_probe(&mut self, _timeout: Duration) -> Result<(), DeviceError> {
        if !self.cfg.touch_probe {
            return Err(DeviceError::Config {
                key: "table.touch_probe".into(),
                reason: "false: the rig file does not say the z drive's probe input is wired to the panel's touch output".into(),
            });
        }
        self.write(
            Z,
            od::TOUCH_PROBE_FUNCTION,
            SdoData::from_u16(TouchProbeFunction::OFF.0),
        )?;
        let armed = TouchProbeFunction::probe1_first_positive_edge();
        self.write(Z, od::TOUCH_PROBE_FUNCTION, SdoData::from_u16(armed.0))?;
        let status = self.probe_status()?;
        if !status.probe1_enabled() || status.probe1_positive_stored() {
            return Err(self.probe_protocol(format!(
                "armed with 0x60B8 = {:#06x}, but 0x60B9 = {:#06x} (expected probe 1 enabled, no edge stored)",
                armed.0, status.0
            )));
        }
        Ok(())
    }

    fn latched_z(&mut self, _timeout: Duration) -> Result<Option<f64>, DeviceError> {
        let status = self.probe_status()?;
        if !status.probe1_enabled() {
            return Err(self.probe_protocol(format!(
                "0x60B9 = {:#06x}: probe 1 is switched off (was it armed?)",
                status.0
            )));
        }
        if !status.probe1_positive_stored() {
            return Ok(None);
        }
        let counts = self.read(Z, od::TOUCH_PROBE_1_POSITIVE)?.to_i32();
        Ok(Some(f64::from(counts) / self.cfg.counts_per_mm[Z]))
    }
}
