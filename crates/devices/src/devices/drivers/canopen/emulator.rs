//! Emulated x-y-z table: three CiA 402 drives on one CAN bus, profile position mode.
//!
//! Each drive answers expedited SDOs (0x6040 controlword, 0x6041 statusword, 0x6060/0x6061
//! modes, 0x607A target, 0x6064 actual position, 0x6081/0x6083/0x6084 profile, 0x1017 heartbeat
//! period, 0x603F error code, and the mandatory CiA 301 objects 0x1000 device type (a 402 servo
//! drive, 0x00020192), 0x1001 error register and 0x1018 identity (sub 0–4); anything else aborts
//! with "object does not exist"), obeys NMT, produces heartbeats at its 0x1017 period, and sends EMCY on a fault.
//! Requests are processed one bus latency after they arrive, and the response carries the state
//! at that moment — so a position read returns where the axis is when the drive answers.
//!
//! Motion: a new set-point (rising edge of controlword bit 4 in *operation enabled*, absolute
//! target) starts a trapezoidal profile from where the axis is, with the profile velocity,
//! acceleration and deceleration; the drive raises set-point acknowledge (bit 12) until bit 4
//! falls, and target reached (bit 10) when the profile ends. Halt (bit 8) stops the axis where
//! it is. A fault stops the axis, raises bit 3 (and bit 13 for a following error) and sends an
//! EMCY; a rising edge of bit 7 clears it (to *switch on disabled*) and sends an EMCY "no error".
//! A quick stop (controlword `0x0002`) stops the axis where it is and leaves the drive in
//! *switch on disabled* (quick stop option code 2, the CiA 402 default), its set-point gone.
//! Touch probe 1 (CiA 402 0x60B8 function, 0x60B9 status, 0x60BA positive-edge position): first
//! event, triggered by the probe 1 input, positive edge (function `0x0011`; the other modes
//! abort with "value range exceeded"). Its input is the panel controller's touch output
//! ([`TouchEdge`](crate::devices::emulators::TouchEdge)s in the shared truth): armed (bit 0 or
//! bit 4 switched on) at a moment, the drive stores the first edge after it, its axis position
//! at the world's touch moment quantised to counts — however late the status is asked for,
//! so the latched height does not depend on bus, panel or pseudo-terminal latency. Switching
//! bit 0 or bit 4 off clears the stored status; the last value stays readable.
//! Faults a test injects ([`TableFaults`](crate::devices::emulators::faults::TableFaults)):
//! silent heartbeats, ignored or late SDOs, a seeded loss of SDO frames; the drives' last
//! controlwords are kept there for tests to look at.
//! Positions in counts on the wire; the true motion in mm goes to the shared [`TableTruth`](crate::devices::emulators::TableTruth).

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use crate::devices::drivers::canopen::settings::TableConfig;
use crate::devices::emulators::faults::TableFaultHandle;
use crate::devices::emulators::{lock, FrameEmulator, SharedTable};
use crate::devices::profile::Profile;
use crate::protocols::can::CanFrame;
use crate::protocols::canopen::{
    od, CanOpenMessage, Controlword, DriveState, EmcyErrorCode, Emergency, Heartbeat, NmtCommand,
    NmtState, NodeId, SdoAbortCode, SdoData, SdoRequest, SdoResponse, Statusword,
    TouchProbeFunction, TouchProbeStatus,
};

/// A drive's touch probe 1 (see the module docs).
#[derive(Debug, Clone, Copy)]
struct TouchProbe {
    /// 0x60B8 as last written.
    function: TouchProbeFunction,
    /// When it was armed for the next positive edge; `None` while switched off.
    armed_at: Option<Duration>,
    /// Whether a positive edge is stored since it was armed (0x60B9 bit 1).
    stored: bool,
    /// 0x60BA: the last positive-edge position (counts).
    positive_counts: i32,
}

impl TouchProbe {
    fn off() -> Self {
        TouchProbe {
            function: TouchProbeFunction::OFF,
            armed_at: None,
            stored: false,
            positive_counts: 0,
        }
    }

    /// 0x60B8 written at `now`: arms on switching the positive edge's sampling on, clears on
    /// switching it off.
    fn write(&mut self, f: TouchProbeFunction, now: Duration) {
        let was = self.function.probe1_enabled() && self.function.probe1_positive_edge();
        let is = f.probe1_enabled() && f.probe1_positive_edge();
        self.function = f;
        if !is {
            self.armed_at = None;
            self.stored = false;
        } else if !was {
            self.armed_at = Some(now);
            self.stored = false;
        }
    }

    fn status(&self) -> TouchProbeStatus {
        TouchProbeStatus::probe1(self.function.probe1_enabled(), self.stored)
    }
}

/// Whether the emulated drives support the touch probe function `f`: probe 1 only, first
/// event, its own input, positive edge (or everything off).
fn supported_probe_function(f: TouchProbeFunction) -> bool {
    f.0 & 0xFF00 == 0
        && !f.probe1_continuous()
        && f.probe1_source() == 0
        && !f.probe1_negative_edge()
        && f.0 & 0x00C0 == 0
}

/// One emulated CiA 402 drive. Eighteen fields: the objects a drive holds (controlword, mode,
/// target, profile, heartbeat period, error code, touch probe) and its state machines (NMT,
/// CiA 402, fault).
#[derive(Debug)]
struct Drive {
    node: NodeId,
    axis: usize,
    cpm: f64,
    nmt: NmtState,
    state: DriveState,
    last_cw: u16,
    mode: i8,
    target: i32,
    vel: u32,
    acc: u32,
    dec: u32,
    hb_ms: u16,
    next_hb: Option<Duration>,
    ack: bool,
    following: bool,
    error_code: u16,
    fault_at: Option<(Duration, u16)>,
    probe: TouchProbe,
}

/// The three emulated drives.
#[derive(Debug)]
pub struct TableEmulator {
    drives: Vec<Drive>,
    truth: SharedTable,
    latency: Duration,
    faults: TableFaultHandle,
    requests: VecDeque<(Duration, NodeId, SdoRequest)>,
    out: VecDeque<(Duration, CanFrame)>,
}

impl TableEmulator {
    /// Drives with the `[devices.table]` node ids and units, their true motion in `truth`.
    pub fn new(cfg: &TableConfig, truth: SharedTable) -> Self {
        let start = lock(&truth).position(Duration::ZERO);
        let drives = cfg
            .node_ids
            .iter()
            .enumerate()
            .filter_map(|(axis, n)| NodeId::new(*n).ok().map(|node| (axis, node)))
            .map(|(axis, node)| {
                let cpm = cfg.counts_per_mm.get(axis).copied().unwrap_or(1000.0);
                Drive {
                    node,
                    axis,
                    cpm,
                    nmt: NmtState::PreOperational,
                    state: DriveState::SwitchOnDisabled,
                    last_cw: 0,
                    mode: 0,
                    target: (start[axis] * cpm).round() as i32,
                    vel: (cfg.profile_velocity_mm_s * cpm) as u32,
                    acc: (cfg.profile_acceleration_mm_s2 * cpm) as u32,
                    dec: (cfg.profile_deceleration_mm_s2 * cpm) as u32,
                    hb_ms: 0,
                    next_hb: None,
                    ack: false,
                    following: false,
                    error_code: 0,
                    fault_at: None,
                    probe: TouchProbe::off(),
                }
            })
            .collect();
        TableEmulator {
            drives,
            truth,
            latency: Duration::from_secs_f64(cfg.bus_latency_ms.max(0.0) / 1000.0),
            faults: TableFaultHandle::default(),
            requests: VecDeque::new(),
            out: VecDeque::new(),
        }
    }

    /// The fault and counter handle.
    pub fn faults(&self) -> TableFaultHandle {
        Arc::clone(&self.faults)
    }

    fn position_mm(&self, axis: usize, t: Duration) -> f64 {
        lock(&self.truth)
            .axes
            .get(axis)
            .map_or(0.0, |p| p.position(t))
    }

    fn reached(&self, d: &Drive, t: Duration) -> bool {
        lock(&self.truth)
            .axes
            .get(d.axis)
            .is_none_or(|p| t >= p.end())
    }

    fn statusword(&self, k: usize, t: Duration) -> u16 {
        let Some(d) = self.drives.get(k) else {
            return 0;
        };
        let mut s = Statusword::for_state(d.state).with_bit(9, true);
        let powered = matches!(
            d.state,
            DriveState::SwitchedOn | DriveState::OperationEnabled | DriveState::QuickStopActive
        );
        s = s.with_bit(4, powered);
        s = s.with_bit(10, self.reached(d, t));
        s = s.with_bit(12, d.ack);
        s = s.with_bit(13, d.following);
        s.0
    }

    /// Applies scheduled faults that are due.
    fn update(&mut self, now: Duration) {
        for k in 0..self.drives.len() {
            let Some((at, code)) = self.drives[k].fault_at else {
                continue;
            };
            if at > now {
                continue;
            }
            let axis = self.drives[k].axis;
            let p = self.position_mm(axis, at);
            lock(&self.truth).start(axis, Profile::still_from(at, p));
            let d = &mut self.drives[k];
            d.fault_at = None;
            d.state = DriveState::Fault;
            d.following = code == EmcyErrorCode::FollowingError.code();
            d.error_code = code;
            let emcy = Emergency {
                node: d.node,
                error_code: EmcyErrorCode::from_code(code),
                error_register: 0x01,
                manufacturer: [0; 5],
            };
            self.out.push_back((at, emcy.encode()));
        }
    }

    fn controlword(&mut self, k: usize, cw: u16, now: Duration) {
        let (axis, prev) = match self.drives.get(k) {
            Some(d) => (d.axis, d.last_cw),
            None => return,
        };
        let pos = self.position_mm(axis, now);
        let mut start_profile: Option<Profile> = None;
        let mut emcy_reset = None;
        {
            let d = &mut self.drives[k];
            d.last_cw = cw;
            let rising = |bit: u16| cw & bit != 0 && prev & bit == 0;
            if d.state == DriveState::Fault {
                if rising(Controlword::BIT_FAULT_RESET) {
                    d.state = DriveState::SwitchOnDisabled;
                    d.following = false;
                    d.error_code = 0;
                    emcy_reset = Some(d.node);
                }
            } else if cw & 0x0002 == 0 {
                d.state = DriveState::SwitchOnDisabled; // disable voltage
            } else if cw & 0x0006 == 0x0002 {
                d.state = DriveState::SwitchOnDisabled; // quick stop
                start_profile = Some(Profile::still(pos));
            } else if cw & 0x0087 == 0x0006 {
                d.state = DriveState::ReadyToSwitchOn; // shutdown
            } else if cw & 0x008F == 0x0007 {
                if matches!(
                    d.state,
                    DriveState::ReadyToSwitchOn | DriveState::OperationEnabled
                ) {
                    d.state = DriveState::SwitchedOn;
                }
            } else if cw & 0x008F == 0x000F && d.state == DriveState::SwitchedOn {
                d.state = DriveState::OperationEnabled;
            }
            if d.state == DriveState::OperationEnabled && d.mode == od::MODE_PROFILE_POSITION {
                if cw & Controlword::BIT_HALT != 0 {
                    start_profile = Some(Profile::still(pos));
                } else if rising(Controlword::BIT_NEW_SETPOINT) {
                    let to = f64::from(d.target) / d.cpm;
                    start_profile = Some(Profile::new(
                        now,
                        pos,
                        to,
                        f64::from(d.vel) / d.cpm,
                        f64::from(d.acc) / d.cpm,
                        f64::from(d.dec) / d.cpm,
                    ));
                    d.ack = true;
                    let mut f = lock(&self.faults);
                    if let Some(inj) = f.fault_on_next_move {
                        if inj.axis == axis {
                            f.fault_on_next_move = None;
                            d.fault_at = Some((now + inj.after, inj.emcy_code));
                        }
                    }
                }
            }
            if cw & Controlword::BIT_NEW_SETPOINT == 0 {
                d.ack = false;
            }
        }
        if let Some(p) = start_profile {
            lock(&self.truth).start(axis, p);
        }
        if let Some(node) = emcy_reset {
            let e = Emergency {
                node,
                error_code: EmcyErrorCode::NoError,
                error_register: 0,
                manufacturer: [0; 5],
            };
            self.out.push_back((now, e.encode()));
        }
    }

    /// Drive `k`'s probe, armed and with nothing stored yet, stores the touch output's first
    /// edge after its arming that came by `now`: the axis position at the edge, in counts.
    fn latch_probe(&mut self, k: usize, now: Duration) {
        let Some(d) = self.drives.get(k) else { return };
        let (Some(armed), false) = (d.probe.armed_at, d.probe.stored) else {
            return;
        };
        let Some(edge) = lock(&self.truth).first_touch(armed, now) else {
            return;
        };
        let d = &mut self.drives[k];
        let mm = edge.table_mm.get(d.axis).copied().unwrap_or(0.0);
        d.probe.positive_counts = (mm * d.cpm).round() as i32;
        d.probe.stored = true;
    }

    fn sdo(&mut self, node: NodeId, req: SdoRequest, now: Duration) -> SdoResponse {
        let Some(k) = self.drives.iter().position(|d| d.node == node) else {
            return SdoResponse::Abort {
                index: 0,
                sub: 0,
                code: SdoAbortCode::GeneralError,
            };
        };
        let axis = self.drives[k].axis;
        match req {
            SdoRequest::Upload { index, sub } => {
                if matches!(index, od::TOUCH_PROBE_STATUS | od::TOUCH_PROBE_1_POSITIVE) {
                    self.latch_probe(k, now);
                }
                let d = &self.drives[k];
                let data = match index {
                    od::STATUSWORD => Some(SdoData::from_u16(self.statusword(k, now))),
                    od::CONTROLWORD => Some(SdoData::from_u16(d.last_cw)),
                    od::MODES_OF_OPERATION | od::MODES_OF_OPERATION_DISPLAY => {
                        Some(SdoData::from_i8(d.mode))
                    }
                    od::POSITION_ACTUAL => Some(SdoData::from_i32(
                        (self.position_mm(axis, now) * d.cpm).round() as i32,
                    )),
                    od::TARGET_POSITION => Some(SdoData::from_i32(d.target)),
                    od::PROFILE_VELOCITY => Some(SdoData::from_u32(d.vel)),
                    od::PROFILE_ACCELERATION => Some(SdoData::from_u32(d.acc)),
                    od::PROFILE_DECELERATION => Some(SdoData::from_u32(d.dec)),
                    od::PRODUCER_HEARTBEAT_TIME => Some(SdoData::from_u16(d.hb_ms)),
                    od::ERROR_CODE => Some(SdoData::from_u16(d.error_code)),
                    od::ERROR_REGISTER => Some(SdoData::from_u8(u8::from(d.error_code != 0))),
                    od::DEVICE_TYPE => Some(SdoData::from_u32(EMULATED_DEVICE_TYPE)),
                    od::IDENTITY => identity(sub, node),
                    od::TOUCH_PROBE_FUNCTION => Some(SdoData::from_u16(d.probe.function.0)),
                    od::TOUCH_PROBE_STATUS => Some(SdoData::from_u16(d.probe.status().0)),
                    od::TOUCH_PROBE_1_POSITIVE => Some(SdoData::from_i32(d.probe.positive_counts)),
                    _ => None,
                };
                match data {
                    Some(data) => SdoResponse::UploadData { index, sub, data },
                    None => SdoResponse::Abort {
                        index,
                        sub,
                        code: SdoAbortCode::ObjectDoesNotExist,
                    },
                }
            }
            SdoRequest::Download { index, sub, data } => {
                let ok = SdoResponse::DownloadAck { index, sub };
                let v = data.to_u32();
                match index {
                    od::CONTROLWORD => {
                        self.controlword(k, v as u16, now);
                        if let Some(slot) = lock(&self.faults).last_controlword.get_mut(axis) {
                            *slot = Some(v as u16);
                        }
                        ok
                    }
                    od::MODES_OF_OPERATION => {
                        let m = data.to_i32() as i8;
                        if m == od::MODE_PROFILE_POSITION || m == 0 {
                            self.drives[k].mode = m;
                            ok
                        } else {
                            SdoResponse::Abort {
                                index,
                                sub,
                                code: SdoAbortCode::ValueRangeExceeded,
                            }
                        }
                    }
                    od::TARGET_POSITION => {
                        self.drives[k].target = data.to_i32();
                        ok
                    }
                    od::PROFILE_VELOCITY | od::PROFILE_ACCELERATION | od::PROFILE_DECELERATION
                        if v == 0 =>
                    {
                        SdoResponse::Abort {
                            index,
                            sub,
                            code: SdoAbortCode::ValueTooLow,
                        }
                    }
                    od::PROFILE_VELOCITY => {
                        self.drives[k].vel = v;
                        ok
                    }
                    od::PROFILE_ACCELERATION => {
                        self.drives[k].acc = v;
                        ok
                    }
                    od::PROFILE_DECELERATION => {
                        self.drives[k].dec = v;
                        ok
                    }
                    od::PRODUCER_HEARTBEAT_TIME => {
                        let d = &mut self.drives[k];
                        d.hb_ms = v as u16;
                        d.next_hb =
                            (d.hb_ms > 0).then(|| now + Duration::from_millis(u64::from(d.hb_ms)));
                        ok
                    }
                    od::TOUCH_PROBE_FUNCTION => {
                        let f = TouchProbeFunction(v as u16);
                        if supported_probe_function(f) {
                            self.drives[k].probe.write(f, now);
                            ok
                        } else {
                            SdoResponse::Abort {
                                index,
                                sub,
                                code: SdoAbortCode::ValueRangeExceeded,
                            }
                        }
                    }
                    od::STATUSWORD
                    | od::POSITION_ACTUAL
                    | od::MODES_OF_OPERATION_DISPLAY
                    | od::TOUCH_PROBE_STATUS
                    | od::TOUCH_PROBE_1_POSITIVE => SdoResponse::Abort {
                        index,
                        sub,
                        code: SdoAbortCode::ReadOnly,
                    },
                    _ => SdoResponse::Abort {
                        index,
                        sub,
                        code: SdoAbortCode::ObjectDoesNotExist,
                    },
                }
            }
            SdoRequest::Abort { index, sub, .. } => SdoResponse::Abort {
                index,
                sub,
                code: SdoAbortCode::GeneralError,
            },
        }
    }

    fn heartbeats(&mut self, now: Duration) {
        let silent = lock(&self.faults).silent_heartbeat;
        for d in &mut self.drives {
            let Some(next) = d.next_hb else { continue };
            if next > now {
                continue;
            }
            let period = Duration::from_millis(u64::from(d.hb_ms.max(1)));
            let mut n = next + period;
            if n <= now {
                n = now + period;
            }
            d.next_hb = Some(n);
            if !silent.get(d.axis).copied().unwrap_or(false) {
                let hb = Heartbeat {
                    node: d.node,
                    state: d.nmt,
                };
                self.out.push_back((next, hb.encode()));
            }
        }
    }
}

impl FrameEmulator for TableEmulator {
    fn input(&mut self, frame: &CanFrame, now: Duration) {
        self.update(now);
        let (ignore, delay, lost) = {
            let mut f = lock(&self.faults);
            f.frames_received += 1;
            let sdo = matches!(
                CanOpenMessage::decode(frame),
                Ok(CanOpenMessage::SdoRequest { .. })
            );
            (f.ignore_sdo, f.extra_delay, sdo && f.sdo_loss.lose())
        };
        if lost {
            return;
        }
        match CanOpenMessage::decode(frame) {
            Ok(CanOpenMessage::Nmt(nmt)) => {
                for d in &mut self.drives {
                    if nmt.node.is_none() || nmt.node == Some(d.node) {
                        d.nmt = match nmt.command {
                            NmtCommand::Start => NmtState::Operational,
                            NmtCommand::Stop => NmtState::Stopped,
                            _ => NmtState::PreOperational,
                        };
                    }
                }
            }
            Ok(CanOpenMessage::SdoRequest { node, request }) => {
                let ours = self
                    .drives
                    .iter()
                    .any(|d| d.node == node && d.nmt != NmtState::Stopped);
                if ours && !ignore {
                    self.requests
                        .push_back((now + self.latency + delay, node, request));
                }
            }
            _ => {}
        }
    }

    fn output(&mut self, now: Duration) -> Vec<CanFrame> {
        self.update(now);
        while let Some((t, _, _)) = self.requests.front() {
            if *t > now {
                break;
            }
            let Some((t, node, req)) = self.requests.pop_front() else {
                break;
            };
            self.update(t);
            let resp = self.sdo(node, req, t);
            if !lock(&self.faults).sdo_loss.lose() {
                self.out.push_back((t, resp.encode(node)));
            }
        }
        self.heartbeats(now);
        let mut due: Vec<(Duration, CanFrame)> = Vec::new();
        let mut keep = VecDeque::new();
        for (t, f) in self.out.drain(..) {
            if t <= now {
                due.push((t, f));
            } else {
                keep.push_back((t, f));
            }
        }
        self.out = keep;
        due.sort_by_key(|(t, _)| *t);
        due.into_iter().map(|(_, f)| f).collect()
    }

    fn next_event(&mut self, _now: Duration, _horizon: Duration) -> Option<Duration> {
        let req = self.requests.front().map(|(t, _, _)| *t);
        let out = self.out.iter().map(|(t, _)| *t).min();
        let hb = self.drives.iter().filter_map(|d| d.next_hb).min();
        let fault = self
            .drives
            .iter()
            .filter_map(|d| d.fault_at.map(|f| f.0))
            .min();
        [req, out, hb, fault].into_iter().flatten().min()
    }
}

/// 0x1000 of every emulated drive: a CiA 402 servo drive (additional information 0x0002 in the
/// high word, profile 402 = 0x0192 in the low word).
const EMULATED_DEVICE_TYPE: u32 = 0x0002_0192;

/// Vendor ID the emulated drives report in 0x1018 (not a CiA-assigned ID: no real vendor).
const EMULATED_VENDOR_ID: u32 = 0x0000_0000;

/// Product code the emulated drives report in 0x1018.
const EMULATED_PRODUCT_CODE: u32 = 0x0000_0402;

/// Revision number the emulated drives report in 0x1018 (major 1, minor 0).
const EMULATED_REVISION: u32 = 0x0001_0000;

/// Sub-index `sub` of the identity object 0x1018 of drive `node` (the serial number is the node
/// ID); `None` for a sub-index the record does not have.
fn identity(sub: u8, node: NodeId) -> Option<SdoData> {
    match sub {
        0 => Some(SdoData::from_u8(4)),
        1 => Some(SdoData::from_u32(EMULATED_VENDOR_ID)),
        2 => Some(SdoData::from_u32(EMULATED_PRODUCT_CODE)),
        3 => Some(SdoData::from_u32(EMULATED_REVISION)),
        4 => Some(SdoData::from_u32(u32::from(node.get()))),
        _ => None,
    }
}

#[cfg(test)]
mod mandatory_objects {
    use super::*;
    use crate::devices::emulators::TableTruth;
    use std::sync::Mutex;

    fn upload(e: &mut TableEmulator, node: NodeId, index: u16, sub: u8) -> Option<u32> {
        match e.sdo(node, SdoRequest::Upload { index, sub }, Duration::ZERO) {
            SdoResponse::UploadData { data, .. } => Some(data.to_u32()),
            _ => None,
        }
    }

    #[test]
    fn every_drive_answers_device_type_error_register_and_identity() {
        let cfg = TableConfig::default();
        let truth: SharedTable = Arc::new(Mutex::new(TableTruth::at([0.0; 3])));
        let mut e = TableEmulator::new(&cfg, truth);
        for id in cfg.node_ids {
            let node = NodeId::new(id).unwrap();
            let device_type = upload(&mut e, node, od::DEVICE_TYPE, 0).unwrap();
            assert_eq!(device_type & 0xFFFF, 0x0192, "node {id}: {device_type:#x}");
            assert_eq!(upload(&mut e, node, od::ERROR_REGISTER, 0), Some(0));
            assert_eq!(upload(&mut e, node, od::IDENTITY, 0), Some(4));
            assert_eq!(
                upload(&mut e, node, od::IDENTITY, 2),
                Some(EMULATED_PRODUCT_CODE)
            );
            assert_eq!(upload(&mut e, node, od::IDENTITY, 4), Some(u32::from(id)));
            assert_eq!(upload(&mut e, node, od::IDENTITY, 5), None);
        }
    }
}

#[cfg(test)]
mod touch_probe {
    use super::*;
    use crate::devices::emulators::{TableTruth, TouchEdge};
    use std::sync::Mutex;

    const S: Duration = Duration::from_secs(1);

    fn drive() -> (TableEmulator, SharedTable, NodeId) {
        let cfg = TableConfig::default();
        let truth: SharedTable = Arc::new(Mutex::new(TableTruth::at([0.0; 3])));
        let e = TableEmulator::new(&cfg, Arc::clone(&truth));
        (e, truth, NodeId::new(cfg.node_ids[2]).unwrap())
    }

    fn read(e: &mut TableEmulator, node: NodeId, index: u16, at: Duration) -> u32 {
        match e.sdo(node, SdoRequest::Upload { index, sub: 0 }, at) {
            SdoResponse::UploadData { data, .. } => data.to_u32(),
            other => panic!("read {index:#06x}: {other:?}"),
        }
    }

    fn write(e: &mut TableEmulator, node: NodeId, index: u16, v: u16, at: Duration) -> bool {
        let data = SdoData::from_u16(v);
        let req = SdoRequest::Download {
            index,
            sub: 0,
            data,
        };
        matches!(e.sdo(node, req, at), SdoResponse::DownloadAck { .. })
    }

    fn edge(truth: &SharedTable, at: Duration, z: f64) {
        lock(truth).touch_began(TouchEdge {
            at,
            table_mm: [100.0, 50.0, z],
        });
    }

    fn status(e: &mut TableEmulator, node: NodeId, at: Duration) -> TouchProbeStatus {
        TouchProbeStatus(read(e, node, od::TOUCH_PROBE_STATUS, at) as u16)
    }

    #[test]
    fn an_armed_probe_stores_the_first_edge_after_its_arming_however_late_it_is_asked() {
        let (mut e, truth, z) = drive();
        assert_eq!(status(&mut e, z, Duration::ZERO), TouchProbeStatus(0));
        edge(&truth, S / 2, 7.0); // before the arming: not latched
        assert!(write(&mut e, z, od::TOUCH_PROBE_FUNCTION, 0x0011, S));
        assert_eq!(read(&mut e, z, od::TOUCH_PROBE_FUNCTION, S), 0x0011);
        let st = status(&mut e, z, S + S / 2);
        assert!(
            st.probe1_enabled() && !st.probe1_positive_stored(),
            "{st:?}"
        );
        // The touch at 2 s, at 12.3456 mm: 12346 counts at 1000 counts/mm, whether the
        // status is asked 1 ms or 150 ms after it (the position is the world's at the edge).
        edge(&truth, 2 * S, 12.3456);
        edge(&truth, 3 * S, 20.0); // a later edge: first event only
        for late in [1, 20, 150] {
            let at = 2 * S + Duration::from_millis(late);
            assert!(status(&mut e, z, at).probe1_positive_stored());
            assert_eq!(
                read(&mut e, z, od::TOUCH_PROBE_1_POSITIVE, at) as i32,
                12346
            );
        }
        assert_eq!(
            read(&mut e, z, od::TOUCH_PROBE_1_POSITIVE, 4 * S) as i32,
            12346
        );
        // Re-armed (off, then on): the status is cleared, the value kept until the next edge.
        assert!(write(&mut e, z, od::TOUCH_PROBE_FUNCTION, 0x0000, 5 * S));
        assert_eq!(status(&mut e, z, 5 * S), TouchProbeStatus(0));
        assert!(write(&mut e, z, od::TOUCH_PROBE_FUNCTION, 0x0011, 5 * S));
        assert_eq!(status(&mut e, z, 6 * S), TouchProbeStatus(0x0001));
        assert_eq!(
            read(&mut e, z, od::TOUCH_PROBE_1_POSITIVE, 6 * S) as i32,
            12346
        );
        edge(&truth, 7 * S, -0.0014);
        assert_eq!(status(&mut e, z, 8 * S), TouchProbeStatus(0x0003));
        assert_eq!(
            read(&mut e, z, od::TOUCH_PROBE_1_POSITIVE, 8 * S) as i32,
            -1
        );
    }

    #[test]
    fn unsupported_probe_modes_and_writes_to_the_read_only_objects_are_refused() {
        let (mut e, _, z) = drive();
        // Continuous (bit 1), the zero impulse (bits 2–3 = 01), the negative edge (bit 5),
        // probe 2 (bit 8): the emulated drives latch probe 1's first positive edge only.
        for f in [0x0013, 0x0015, 0x0031, 0x0111] {
            assert!(
                !write(&mut e, z, od::TOUCH_PROBE_FUNCTION, f, S),
                "{f:#06x}"
            );
        }
        assert!(!write(&mut e, z, od::TOUCH_PROBE_STATUS, 0x0003, S));
        assert!(!write(&mut e, z, od::TOUCH_PROBE_1_POSITIVE, 5, S));
        assert_eq!(read(&mut e, z, od::TOUCH_PROBE_FUNCTION, S), 0);
    }
}
