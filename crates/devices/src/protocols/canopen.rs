//! CANopen application layer (CiA 301) and the CiA 402 drive profile.
//!
//! Framing: every message is one classic CAN frame with an 11-bit COB-ID
//! built from a function code and a node id (1..=127) per the CiA 301
//! predefined connection set:
//!
//! | COB-ID | message | payload |
//! |---|---|---|
//! | 0x000 | NMT command | `cs node` (node 0 = all) |
//! | 0x080 | SYNC | empty |
//! | 0x080 + node | EMCY | `code_lo code_hi reg m0 m1 m2 m3 m4` |
//! | 0x180/0x280/0x380/0x480 + node | TPDO1..4 | 0..8 bytes |
//! | 0x200/0x300/0x400/0x500 + node | RPDO1..4 | 0..8 bytes |
//! | 0x580 + node | SDO server → client | 8 bytes |
//! | 0x600 + node | SDO client → server | 8 bytes |
//! | 0x700 + node | heartbeat / boot-up | one state byte |
//!
//! References: CiA 301 v4.2 (NMT §7.2.8.3.1, heartbeat §7.2.8.3.2.2, SDO
//! expedited transfer §7.2.4.3, EMCY §7.2.7) and CiA 402 / IEC 61800-7-201
//! (statusword/controlword bit assignment and the drive state machine).
//!
//! Only *expedited* SDO transfers (≤ 4 bytes) are supported; segmented and
//! block transfers decode to [`CanOpenError::SegmentedNotSupported`] /
//! [`CanOpenError::UnsupportedCommandSpecifier`]. Both sides are provided:
//! the client (rigcal drivers) encodes [`SdoRequest`] and decodes
//! [`SdoResponse`]; the server (emulated drives) decodes requests and
//! encodes responses.

use std::fmt;

use thiserror::Error;

use super::can::{CanFrame, CanFrameError, CanId};

/// COB-ID of NMT commands.
const COB_NMT: u16 = 0x000;
/// Base COB-ID of EMCY (plus node id).
const COB_EMCY: u16 = 0x080;
/// Base COB-ID of SDO server → client (plus node id).
const COB_SDO_TX: u16 = 0x580;
/// Base COB-ID of SDO client → server (plus node id).
const COB_SDO_RX: u16 = 0x600;
/// Base COB-ID of heartbeat / boot-up (plus node id).
const COB_HEARTBEAT: u16 = 0x700;

/// Everything that can go wrong encoding or decoding CANopen messages.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum CanOpenError {
    /// A node id outside 1..=127.
    #[error("CANopen node id {node} is out of range 1..=127; check the drive's node-id setting")]
    InvalidNodeId {
        /// The rejected id.
        node: u8,
    },
    /// The frame's COB-ID does not belong to the message being decoded.
    #[error("COB-ID {cob_id:#05x} is not a {expected} frame")]
    WrongCobId {
        /// The frame's identifier.
        cob_id: u32,
        /// What was expected.
        expected: &'static str,
    },
    /// A frame had the wrong payload length for its message type.
    #[error("{what} needs {expected} data bytes, frame has {found}")]
    WrongLength {
        /// The message type.
        what: &'static str,
        /// Required length description.
        expected: &'static str,
        /// Actual length.
        found: usize,
    },
    /// An extended (29-bit) or remote frame where CANopen uses a standard data frame.
    #[error("{what} must be a standard-id data frame (got extended or RTR frame)")]
    NotStandardDataFrame {
        /// The message type.
        what: &'static str,
    },
    /// Unknown NMT command specifier.
    #[error("unknown NMT command specifier {cs:#04x} (expected 0x01, 0x02, 0x80, 0x81, 0x82)")]
    UnknownNmtCommand {
        /// The byte.
        cs: u8,
    },
    /// Unknown heartbeat state byte.
    #[error("unknown NMT state byte {state:#04x} in heartbeat (expected 0x00, 0x04, 0x05, 0x7F)")]
    UnknownNmtState {
        /// The byte.
        state: u8,
    },
    /// A segmented SDO transfer was started; only expedited transfers are supported.
    #[error("segmented SDO transfer for {index:#06x}:{sub} is not supported; use objects of at most 4 bytes")]
    SegmentedNotSupported {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// An SDO command specifier this codec does not handle (segment, block, reserved).
    #[error(
        "unsupported SDO command byte {command:#04x} (only expedited initiate/abort are supported)"
    )]
    UnsupportedCommandSpecifier {
        /// The command byte.
        command: u8,
    },
    /// SDO data of a length other than 1..=4 bytes.
    #[error("expedited SDO data must be 1..=4 bytes, got {len}")]
    BadSdoDataLength {
        /// The rejected length.
        len: usize,
    },
    /// A statusword matching no CiA 402 state pattern.
    #[error("statusword {statusword:#06x} matches no CiA 402 state")]
    UnknownDriveState {
        /// The statusword.
        statusword: u16,
    },
    /// A CAN frame could not be built (should not happen with validated inputs).
    #[error(transparent)]
    Frame(#[from] CanFrameError),
}

/// A CANopen node id, 1..=127.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(u8);

impl NodeId {
    /// A node id 1..=127.
    pub fn new(node: u8) -> Result<Self, CanOpenError> {
        if (1..=127).contains(&node) {
            Ok(NodeId(node))
        } else {
            Err(CanOpenError::InvalidNodeId { node })
        }
    }
    /// The id 1..=127.
    pub fn get(self) -> u8 {
        self.0
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

fn std_frame(cob: u16, data: &[u8]) -> CanFrame {
    // COB-IDs built here are <= 0x77F and payloads <= 8 bytes.
    CanFrame::standard_masked(cob, data)
}

fn standard_data(frame: &CanFrame, what: &'static str) -> Result<u16, CanOpenError> {
    match frame.id() {
        CanId::Standard(id) if !frame.is_remote() => Ok(id),
        _ => Err(CanOpenError::NotStandardDataFrame { what }),
    }
}

fn node_from_cob(cob: u16, base: u16, what: &'static str) -> Result<NodeId, CanOpenError> {
    if cob <= base || cob > base + 127 {
        return Err(CanOpenError::WrongCobId {
            cob_id: u32::from(cob),
            expected: what,
        });
    }
    NodeId::new((cob - base) as u8)
}

// ---------------------------------------------------------------- NMT

/// NMT command specifier.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NmtCommand {
    /// 0x01: start remote node (→ operational).
    Start,
    /// 0x02: stop remote node (→ stopped).
    Stop,
    /// 0x80: enter pre-operational.
    EnterPreOperational,
    /// 0x81: reset node (application reset).
    ResetNode,
    /// 0x82: reset communication.
    ResetCommunication,
}

impl NmtCommand {
    /// The command specifier byte.
    pub fn code(self) -> u8 {
        match self {
            NmtCommand::Start => 0x01,
            NmtCommand::Stop => 0x02,
            NmtCommand::EnterPreOperational => 0x80,
            NmtCommand::ResetNode => 0x81,
            NmtCommand::ResetCommunication => 0x82,
        }
    }
    /// Parses a command specifier byte.
    pub fn from_code(cs: u8) -> Result<Self, CanOpenError> {
        Ok(match cs {
            0x01 => NmtCommand::Start,
            0x02 => NmtCommand::Stop,
            0x80 => NmtCommand::EnterPreOperational,
            0x81 => NmtCommand::ResetNode,
            0x82 => NmtCommand::ResetCommunication,
            cs => return Err(CanOpenError::UnknownNmtCommand { cs }),
        })
    }
}

/// An NMT command frame (COB-ID 0x000, `cs node`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Nmt {
    /// The command.
    pub command: NmtCommand,
    /// Addressed node; `None` = all nodes (node byte 0).
    pub node: Option<NodeId>,
}

impl Nmt {
    /// The CAN frame: id 0x000, data `[cs, node]`.
    pub fn encode(&self) -> CanFrame {
        std_frame(
            COB_NMT,
            &[self.command.code(), self.node.map_or(0, NodeId::get)],
        )
    }

    /// Decodes an NMT frame (id 0x000, exactly 2 bytes).
    pub fn decode(frame: &CanFrame) -> Result<Self, CanOpenError> {
        let id = standard_data(frame, "NMT")?;
        if id != COB_NMT {
            return Err(CanOpenError::WrongCobId {
                cob_id: u32::from(id),
                expected: "NMT (0x000)",
            });
        }
        let [cs, node] = *frame.data() else {
            return Err(CanOpenError::WrongLength {
                what: "NMT",
                expected: "2",
                found: frame.data().len(),
            });
        };
        let command = NmtCommand::from_code(cs)?;
        let node = if node == 0 {
            None
        } else {
            Some(NodeId::new(node)?)
        };
        Ok(Nmt { command, node })
    }
}

// ---------------------------------------------------------------- heartbeat

/// NMT state as reported by heartbeat / boot-up messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NmtState {
    /// 0x00: boot-up message.
    BootUp,
    /// 0x04: stopped.
    Stopped,
    /// 0x05: operational.
    Operational,
    /// 0x7F: pre-operational.
    PreOperational,
}

impl NmtState {
    /// The state byte.
    pub fn code(self) -> u8 {
        match self {
            NmtState::BootUp => 0x00,
            NmtState::Stopped => 0x04,
            NmtState::Operational => 0x05,
            NmtState::PreOperational => 0x7F,
        }
    }
    /// Parses a state byte.
    pub fn from_code(state: u8) -> Result<Self, CanOpenError> {
        Ok(match state {
            0x00 => NmtState::BootUp,
            0x04 => NmtState::Stopped,
            0x05 => NmtState::Operational,
            0x7F => NmtState::PreOperational,
            state => return Err(CanOpenError::UnknownNmtState { state }),
        })
    }
}

/// Heartbeat or boot-up message (COB-ID 0x700 + node, one state byte).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Heartbeat {
    /// Producing node.
    pub node: NodeId,
    /// Its NMT state.
    pub state: NmtState,
}

impl Heartbeat {
    /// The CAN frame.
    pub fn encode(&self) -> CanFrame {
        std_frame(
            COB_HEARTBEAT + u16::from(self.node.get()),
            &[self.state.code()],
        )
    }

    /// Decodes a heartbeat frame (id 0x701..=0x77F, exactly 1 byte).
    pub fn decode(frame: &CanFrame) -> Result<Self, CanOpenError> {
        let id = standard_data(frame, "heartbeat")?;
        let node = node_from_cob(id, COB_HEARTBEAT, "heartbeat (0x701..=0x77F)")?;
        let [state] = *frame.data() else {
            return Err(CanOpenError::WrongLength {
                what: "heartbeat",
                expected: "1",
                found: frame.data().len(),
            });
        };
        Ok(Heartbeat {
            node,
            state: NmtState::from_code(state)?,
        })
    }
}

// ---------------------------------------------------------------- SDO

/// SDO abort codes (CiA 301 §7.2.4.3.17).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum SdoAbortCode {
    /// 0x05030000 toggle bit not alternated.
    ToggleBitNotAlternated,
    /// 0x05040000 SDO protocol timed out.
    Timeout,
    /// 0x05040001 client/server command specifier not valid or unknown.
    InvalidCommandSpecifier,
    /// 0x05040005 out of memory.
    OutOfMemory,
    /// 0x06010000 unsupported access to an object.
    UnsupportedAccess,
    /// 0x06010001 attempt to read a write-only object.
    WriteOnly,
    /// 0x06010002 attempt to write a read-only object.
    ReadOnly,
    /// 0x06020000 object does not exist in the object dictionary.
    ObjectDoesNotExist,
    /// 0x06040041 object cannot be mapped to the PDO.
    CannotBeMapped,
    /// 0x06040042 number and length of mapped objects would exceed PDO length.
    PdoLengthExceeded,
    /// 0x06040043 general parameter incompatibility.
    ParameterIncompatible,
    /// 0x06040047 general internal incompatibility in the device.
    InternalIncompatible,
    /// 0x06060000 access failed due to a hardware error.
    HardwareError,
    /// 0x06070010 data type does not match, length of service parameter does not match.
    LengthMismatch,
    /// 0x06070012 data type does not match, length of service parameter too high.
    LengthTooHigh,
    /// 0x06070013 data type does not match, length of service parameter too low.
    LengthTooLow,
    /// 0x06090011 sub-index does not exist.
    SubIndexDoesNotExist,
    /// 0x06090030 value range of parameter exceeded (write access only).
    ValueRangeExceeded,
    /// 0x06090031 value of parameter written too high.
    ValueTooHigh,
    /// 0x06090032 value of parameter written too low.
    ValueTooLow,
    /// 0x08000000 general error.
    GeneralError,
    /// 0x08000020 data cannot be transferred or stored to the application.
    DataCannotBeStored,
    /// 0x08000021 ... because of local control.
    DataCannotBeStoredLocalControl,
    /// 0x08000022 ... because of the present device state.
    DataCannotBeStoredDeviceState,
    /// 0x08000023 object dictionary dynamic generation fails or no OD present.
    NoObjectDictionary,
    /// Any other (manufacturer-specific or newer) code.
    Other(u32),
}

impl SdoAbortCode {
    const TABLE: [(SdoAbortCode, u32, &'static str); 25] = [
        (
            SdoAbortCode::ToggleBitNotAlternated,
            0x0503_0000,
            "toggle bit not alternated",
        ),
        (SdoAbortCode::Timeout, 0x0504_0000, "SDO protocol timed out"),
        (
            SdoAbortCode::InvalidCommandSpecifier,
            0x0504_0001,
            "command specifier not valid or unknown",
        ),
        (SdoAbortCode::OutOfMemory, 0x0504_0005, "out of memory"),
        (
            SdoAbortCode::UnsupportedAccess,
            0x0601_0000,
            "unsupported access to an object",
        ),
        (
            SdoAbortCode::WriteOnly,
            0x0601_0001,
            "attempt to read a write-only object",
        ),
        (
            SdoAbortCode::ReadOnly,
            0x0601_0002,
            "attempt to write a read-only object",
        ),
        (
            SdoAbortCode::ObjectDoesNotExist,
            0x0602_0000,
            "object does not exist in the object dictionary",
        ),
        (
            SdoAbortCode::CannotBeMapped,
            0x0604_0041,
            "object cannot be mapped to the PDO",
        ),
        (
            SdoAbortCode::PdoLengthExceeded,
            0x0604_0042,
            "mapped objects would exceed the PDO length",
        ),
        (
            SdoAbortCode::ParameterIncompatible,
            0x0604_0043,
            "general parameter incompatibility",
        ),
        (
            SdoAbortCode::InternalIncompatible,
            0x0604_0047,
            "general internal incompatibility in the device",
        ),
        (
            SdoAbortCode::HardwareError,
            0x0606_0000,
            "access failed due to a hardware error",
        ),
        (
            SdoAbortCode::LengthMismatch,
            0x0607_0010,
            "data type does not match, length of service parameter does not match",
        ),
        (
            SdoAbortCode::LengthTooHigh,
            0x0607_0012,
            "data type does not match, length of service parameter too high",
        ),
        (
            SdoAbortCode::LengthTooLow,
            0x0607_0013,
            "data type does not match, length of service parameter too low",
        ),
        (
            SdoAbortCode::SubIndexDoesNotExist,
            0x0609_0011,
            "sub-index does not exist",
        ),
        (
            SdoAbortCode::ValueRangeExceeded,
            0x0609_0030,
            "value range of parameter exceeded",
        ),
        (
            SdoAbortCode::ValueTooHigh,
            0x0609_0031,
            "value of parameter written too high",
        ),
        (
            SdoAbortCode::ValueTooLow,
            0x0609_0032,
            "value of parameter written too low",
        ),
        (SdoAbortCode::GeneralError, 0x0800_0000, "general error"),
        (
            SdoAbortCode::DataCannotBeStored,
            0x0800_0020,
            "data cannot be transferred or stored to the application",
        ),
        (
            SdoAbortCode::DataCannotBeStoredLocalControl,
            0x0800_0021,
            "data cannot be transferred or stored because of local control",
        ),
        (
            SdoAbortCode::DataCannotBeStoredDeviceState,
            0x0800_0022,
            "data cannot be transferred or stored because of the present device state",
        ),
        (
            SdoAbortCode::NoObjectDictionary,
            0x0800_0023,
            "object dictionary dynamic generation fails or no object dictionary is present",
        ),
    ];

    /// The 32-bit abort code.
    pub fn code(self) -> u32 {
        if let SdoAbortCode::Other(c) = self {
            return c;
        }
        Self::TABLE
            .iter()
            .find(|(k, _, _)| *k == self)
            .map_or(0, |(_, c, _)| *c)
    }

    /// Classifies a 32-bit abort code.
    pub fn from_code(code: u32) -> Self {
        Self::TABLE
            .iter()
            .find(|(_, c, _)| *c == code)
            .map_or(SdoAbortCode::Other(code), |(k, _, _)| *k)
    }

    /// The meaning of the code as given by CiA 301.
    pub fn description(self) -> &'static str {
        Self::TABLE
            .iter()
            .find(|(k, _, _)| *k == self)
            .map_or("unknown / manufacturer-specific abort code", |(_, _, d)| *d)
    }
}

impl fmt::Display for SdoAbortCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#010x} ({})", self.code(), self.description())
    }
}

/// 1..=4 bytes of expedited SDO data, little-endian as on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SdoData {
    bytes: [u8; 4],
    len: u8,
}

impl SdoData {
    /// Data from 1..=4 raw bytes.
    pub fn new(bytes: &[u8]) -> Result<Self, CanOpenError> {
        if bytes.is_empty() || bytes.len() > 4 {
            return Err(CanOpenError::BadSdoDataLength { len: bytes.len() });
        }
        let mut b = [0u8; 4];
        for (slot, v) in b.iter_mut().zip(bytes) {
            *slot = *v;
        }
        Ok(SdoData {
            bytes: b,
            len: bytes.len() as u8,
        })
    }
    /// One byte (UNSIGNED8 / INTEGER8 objects).
    pub fn from_u8(v: u8) -> Self {
        SdoData {
            bytes: [v, 0, 0, 0],
            len: 1,
        }
    }
    /// Two bytes (UNSIGNED16, e.g. controlword).
    pub fn from_u16(v: u16) -> Self {
        let [a, b] = v.to_le_bytes();
        SdoData {
            bytes: [a, b, 0, 0],
            len: 2,
        }
    }
    /// Four bytes (UNSIGNED32).
    pub fn from_u32(v: u32) -> Self {
        SdoData {
            bytes: v.to_le_bytes(),
            len: 4,
        }
    }
    /// Four bytes (INTEGER32, e.g. target position).
    pub fn from_i32(v: i32) -> Self {
        SdoData::from_u32(v as u32)
    }
    /// One byte (INTEGER8, e.g. modes of operation).
    pub fn from_i8(v: i8) -> Self {
        SdoData::from_u8(v as u8)
    }
    /// The data bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.bytes.get(..usize::from(self.len)).unwrap_or(&[])
    }
    /// Number of bytes (1..=4).
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }
    /// Always false (expedited data has at least one byte); present for API symmetry.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The value zero-extended to `u32`.
    pub fn to_u32(&self) -> u32 {
        u32::from_le_bytes(self.bytes)
    }
    /// The value sign-extended from its length to `i32`.
    pub fn to_i32(&self) -> i32 {
        let shift = 32 - 8 * u32::from(self.len.clamp(1, 4));
        ((self.to_u32() << shift) as i32) >> shift
    }
}

/// SDO client → server message (COB-ID 0x600 + node).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SdoRequest {
    /// Initiate upload (read) `0x40 idx_lo idx_hi sub 0 0 0 0`.
    Upload {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Expedited download (write) `0x2F/0x2B/0x27/0x23 idx sub data`.
    Download {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// 1..=4 bytes.
        data: SdoData,
    },
    /// Abort transfer `0x80 idx sub code`.
    Abort {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Abort code.
        code: SdoAbortCode,
    },
}

/// SDO server → client message (COB-ID 0x580 + node).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SdoResponse {
    /// Expedited upload response `0x4F/0x4B/0x47/0x43 idx sub data`.
    UploadData {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// 1..=4 bytes.
        data: SdoData,
    },
    /// Download acknowledge `0x60 idx sub 0 0 0 0`.
    DownloadAck {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Abort `0x80 idx sub code`.
    Abort {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Abort code.
        code: SdoAbortCode,
    },
}

impl SdoResponse {
    /// Object index this response refers to.
    pub fn index(&self) -> u16 {
        match *self {
            SdoResponse::UploadData { index, .. }
            | SdoResponse::DownloadAck { index, .. }
            | SdoResponse::Abort { index, .. } => index,
        }
    }
    /// Sub-index this response refers to.
    pub fn sub(&self) -> u8 {
        match *self {
            SdoResponse::UploadData { sub, .. }
            | SdoResponse::DownloadAck { sub, .. }
            | SdoResponse::Abort { sub, .. } => sub,
        }
    }
}

fn sdo_payload(cmd: u8, index: u16, sub: u8, data: [u8; 4]) -> [u8; 8] {
    let [lo, hi] = index.to_le_bytes();
    let [d0, d1, d2, d3] = data;
    [cmd, lo, hi, sub, d0, d1, d2, d3]
}

/// Expedited command byte: base | n<<2 | e | s with n = 4 - len.
fn expedited_cmd(base: u8, len: usize) -> u8 {
    base | (((4 - len.clamp(1, 4)) as u8) << 2) | 0x03
}

fn split_sdo(data: &[u8], what: &'static str) -> Result<(u8, u16, u8, [u8; 4]), CanOpenError> {
    let [cmd, lo, hi, sub, d0, d1, d2, d3] = *data else {
        return Err(CanOpenError::WrongLength {
            what,
            expected: "8",
            found: data.len(),
        });
    };
    Ok((cmd, u16::from_le_bytes([lo, hi]), sub, [d0, d1, d2, d3]))
}

/// Data of an expedited transfer from command byte bits e, s, n.
fn expedited_data(cmd: u8, index: u16, sub: u8, d: [u8; 4]) -> Result<SdoData, CanOpenError> {
    let e = cmd & 0x02 != 0;
    let s = cmd & 0x01 != 0;
    if !e {
        return Err(CanOpenError::SegmentedNotSupported { index, sub });
    }
    // Size not indicated (s = 0): all four bytes are taken (CiA 301 leaves the size unspecified).
    let len = if s {
        4 - usize::from((cmd >> 2) & 0x03)
    } else {
        4
    };
    SdoData::new(d.get(..len).unwrap_or(&d))
}

impl SdoRequest {
    /// The 8 payload bytes.
    pub fn encode_payload(&self) -> [u8; 8] {
        match *self {
            SdoRequest::Upload { index, sub } => sdo_payload(0x40, index, sub, [0; 4]),
            SdoRequest::Download { index, sub, data } => {
                sdo_payload(expedited_cmd(0x20, data.len()), index, sub, data.bytes)
            }
            SdoRequest::Abort { index, sub, code } => {
                sdo_payload(0x80, index, sub, code.code().to_le_bytes())
            }
        }
    }

    /// The frame to node `node` (COB-ID 0x600 + node).
    pub fn encode(&self, node: NodeId) -> CanFrame {
        std_frame(COB_SDO_RX + u16::from(node.get()), &self.encode_payload())
    }

    /// Decodes the 8 payload bytes (server side).
    pub fn decode_payload(data: &[u8]) -> Result<Self, CanOpenError> {
        let (cmd, index, sub, d) = split_sdo(data, "SDO request")?;
        match cmd >> 5 {
            // ccs 1: initiate download.
            1 => Ok(SdoRequest::Download {
                index,
                sub,
                data: expedited_data(cmd, index, sub, d)?,
            }),
            // ccs 2: initiate upload.
            2 => Ok(SdoRequest::Upload { index, sub }),
            // ccs 4: abort.
            4 => Ok(SdoRequest::Abort {
                index,
                sub,
                code: SdoAbortCode::from_code(u32::from_le_bytes(d)),
            }),
            _ => Err(CanOpenError::UnsupportedCommandSpecifier { command: cmd }),
        }
    }

    /// Decodes a client → server frame; returns the addressed node and the request.
    pub fn decode(frame: &CanFrame) -> Result<(NodeId, Self), CanOpenError> {
        let id = standard_data(frame, "SDO request")?;
        let node = node_from_cob(id, COB_SDO_RX, "SDO request (0x601..=0x67F)")?;
        Ok((node, SdoRequest::decode_payload(frame.data())?))
    }
}

impl SdoResponse {
    /// The 8 payload bytes.
    pub fn encode_payload(&self) -> [u8; 8] {
        match *self {
            SdoResponse::UploadData { index, sub, data } => {
                sdo_payload(expedited_cmd(0x40, data.len()), index, sub, data.bytes)
            }
            SdoResponse::DownloadAck { index, sub } => sdo_payload(0x60, index, sub, [0; 4]),
            SdoResponse::Abort { index, sub, code } => {
                sdo_payload(0x80, index, sub, code.code().to_le_bytes())
            }
        }
    }

    /// The frame from node `node` (COB-ID 0x580 + node).
    pub fn encode(&self, node: NodeId) -> CanFrame {
        std_frame(COB_SDO_TX + u16::from(node.get()), &self.encode_payload())
    }

    /// Decodes the 8 payload bytes (client side).
    pub fn decode_payload(data: &[u8]) -> Result<Self, CanOpenError> {
        let (cmd, index, sub, d) = split_sdo(data, "SDO response")?;
        match cmd >> 5 {
            // scs 2: initiate upload response.
            2 => Ok(SdoResponse::UploadData {
                index,
                sub,
                data: expedited_data(cmd, index, sub, d)?,
            }),
            // scs 3: initiate download response.
            3 => Ok(SdoResponse::DownloadAck { index, sub }),
            4 => Ok(SdoResponse::Abort {
                index,
                sub,
                code: SdoAbortCode::from_code(u32::from_le_bytes(d)),
            }),
            _ => Err(CanOpenError::UnsupportedCommandSpecifier { command: cmd }),
        }
    }

    /// Decodes a server → client frame; returns the responding node and the response.
    pub fn decode(frame: &CanFrame) -> Result<(NodeId, Self), CanOpenError> {
        let id = standard_data(frame, "SDO response")?;
        let node = node_from_cob(id, COB_SDO_TX, "SDO response (0x581..=0x5FF)")?;
        Ok((node, SdoResponse::decode_payload(frame.data())?))
    }
}

// ---------------------------------------------------------------- EMCY

/// EMCY error codes (CiA 301 table 21, CiA 402 additions).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum EmcyErrorCode {
    /// 0x0000 error reset or no error.
    NoError,
    /// 0x1000 generic error.
    Generic,
    /// 0x2310 continuous over-current (device output side).
    OverCurrent,
    /// 0x3210 DC link over-voltage.
    DcLinkOverVoltage,
    /// 0x4310 drive temperature.
    DriveTemperature,
    /// 0x5530 data storage (EEPROM / flash) error.
    DataStorage,
    /// 0x7300 sensor (encoder) error.
    Sensor,
    /// 0x8110 CAN overrun (objects lost).
    CanOverrun,
    /// 0x8130 life guard or heartbeat error.
    HeartbeatError,
    /// 0x8611 following error.
    FollowingError,
    /// Any other code.
    Other(u16),
}

impl EmcyErrorCode {
    const TABLE: [(EmcyErrorCode, u16); 10] = [
        (EmcyErrorCode::NoError, 0x0000),
        (EmcyErrorCode::Generic, 0x1000),
        (EmcyErrorCode::OverCurrent, 0x2310),
        (EmcyErrorCode::DcLinkOverVoltage, 0x3210),
        (EmcyErrorCode::DriveTemperature, 0x4310),
        (EmcyErrorCode::DataStorage, 0x5530),
        (EmcyErrorCode::Sensor, 0x7300),
        (EmcyErrorCode::CanOverrun, 0x8110),
        (EmcyErrorCode::HeartbeatError, 0x8130),
        (EmcyErrorCode::FollowingError, 0x8611),
    ];
    /// The 16-bit code.
    pub fn code(self) -> u16 {
        if let EmcyErrorCode::Other(c) = self {
            return c;
        }
        Self::TABLE
            .iter()
            .find(|(k, _)| *k == self)
            .map_or(0, |(_, c)| *c)
    }
    /// Classifies a 16-bit code.
    pub fn from_code(code: u16) -> Self {
        Self::TABLE
            .iter()
            .find(|(_, c)| *c == code)
            .map_or(EmcyErrorCode::Other(code), |(k, _)| *k)
    }
}

/// Emergency message (COB-ID 0x080 + node, 8 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Emergency {
    /// Producing node.
    pub node: NodeId,
    /// Error code (bytes 0..2, little-endian).
    pub error_code: EmcyErrorCode,
    /// Error register (object 0x1001), byte 2.
    pub error_register: u8,
    /// Manufacturer-specific bytes 3..8.
    pub manufacturer: [u8; 5],
}

impl Emergency {
    /// The CAN frame.
    pub fn encode(&self) -> CanFrame {
        let [lo, hi] = self.error_code.code().to_le_bytes();
        let [m0, m1, m2, m3, m4] = self.manufacturer;
        std_frame(
            COB_EMCY + u16::from(self.node.get()),
            &[lo, hi, self.error_register, m0, m1, m2, m3, m4],
        )
    }

    /// Decodes an EMCY frame (id 0x081..=0x0FF, exactly 8 bytes).
    pub fn decode(frame: &CanFrame) -> Result<Self, CanOpenError> {
        let id = standard_data(frame, "EMCY")?;
        let node = node_from_cob(id, COB_EMCY, "EMCY (0x081..=0x0FF)")?;
        let [lo, hi, reg, m0, m1, m2, m3, m4] = *frame.data() else {
            return Err(CanOpenError::WrongLength {
                what: "EMCY",
                expected: "8",
                found: frame.data().len(),
            });
        };
        Ok(Emergency {
            node,
            error_code: EmcyErrorCode::from_code(u16::from_le_bytes([lo, hi])),
            error_register: reg,
            manufacturer: [m0, m1, m2, m3, m4],
        })
    }
}

// ---------------------------------------------------------------- classification

/// Direction of a PDO, seen from the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PdoDirection {
    /// Transmit PDO (drive → master), COB-IDs 0x180/0x280/0x380/0x480 + node.
    Transmit,
    /// Receive PDO (master → drive), COB-IDs 0x200/0x300/0x400/0x500 + node.
    Receive,
}

/// Any CAN frame classified by the CANopen predefined connection set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum CanOpenMessage {
    /// NMT command (0x000).
    Nmt(Nmt),
    /// SYNC (0x080, no data).
    Sync,
    /// EMCY (0x081..=0x0FF).
    Emergency(Emergency),
    /// Heartbeat / boot-up (0x701..=0x77F).
    Heartbeat(Heartbeat),
    /// SDO client → server (0x601..=0x67F).
    SdoRequest {
        /// Addressed server.
        node: NodeId,
        /// The request.
        request: SdoRequest,
    },
    /// SDO server → client (0x581..=0x5FF).
    SdoResponse {
        /// Responding server.
        node: NodeId,
        /// The response.
        response: SdoResponse,
    },
    /// A default-connection-set PDO (payload uninterpreted).
    Pdo {
        /// Transmit or receive PDO.
        direction: PdoDirection,
        /// PDO number 1..=4.
        number: u8,
        /// Node id from the COB-ID.
        node: NodeId,
        /// The frame (payload in [`CanFrame::data`]).
        frame: CanFrame,
    },
    /// Anything else (TIME, extended ids, RTR frames, unassigned COB-IDs).
    Other(CanFrame),
}

impl CanOpenMessage {
    /// Classifies a frame. Frames in a known COB-ID range with a malformed
    /// payload yield the specific decode error; unknown frames yield `Other`.
    pub fn decode(frame: &CanFrame) -> Result<Self, CanOpenError> {
        let id = match frame.id() {
            CanId::Standard(id) if !frame.is_remote() => id,
            _ => return Ok(CanOpenMessage::Other(*frame)),
        };
        let func = id & 0x780;
        let node = (id & 0x7F) as u8;
        Ok(match (func, node) {
            (0x000, 0) => CanOpenMessage::Nmt(Nmt::decode(frame)?),
            (0x080, 0) => {
                if frame.data().is_empty() {
                    CanOpenMessage::Sync
                } else {
                    return Err(CanOpenError::WrongLength {
                        what: "SYNC",
                        expected: "0",
                        found: frame.data().len(),
                    });
                }
            }
            (0x080, _) => CanOpenMessage::Emergency(Emergency::decode(frame)?),
            (0x700, n) if n != 0 => CanOpenMessage::Heartbeat(Heartbeat::decode(frame)?),
            (0x600, n) if n != 0 => {
                let (node, request) = SdoRequest::decode(frame)?;
                CanOpenMessage::SdoRequest { node, request }
            }
            (0x580, n) if n != 0 => {
                let (node, response) = SdoResponse::decode(frame)?;
                CanOpenMessage::SdoResponse { node, response }
            }
            (0x180 | 0x280 | 0x380 | 0x480 | 0x200 | 0x300 | 0x400 | 0x500, n) if n != 0 => {
                let direction = if (func >> 7) % 2 == 1 {
                    PdoDirection::Transmit
                } else {
                    PdoDirection::Receive
                };
                let number = match func {
                    0x180 | 0x200 => 1,
                    0x280 | 0x300 => 2,
                    0x380 | 0x400 => 3,
                    _ => 4,
                };
                CanOpenMessage::Pdo {
                    direction,
                    number,
                    node: NodeId::new(n)?,
                    frame: *frame,
                }
            }
            _ => CanOpenMessage::Other(*frame),
        })
    }
}

// ---------------------------------------------------------------- CiA 402

/// Object dictionary indices used by rigcal (CiA 301 / CiA 402).
pub mod od {
    /// 0x1000 device type (UNSIGNED32): the device profile number in the low word (402 for a
    /// drive), additional information in the high word.
    pub const DEVICE_TYPE: u16 = 0x1000;
    /// The device profile number of a CiA 402 drive, as 0x1000's low word.
    pub const PROFILE_CIA402: u32 = 402;
    /// 0x1018 identity (RECORD): sub 0 the highest sub-index (4), 1 vendor ID, 2 product code,
    /// 3 revision number, 4 serial number (each UNSIGNED32).
    pub const IDENTITY: u16 = 0x1018;
    /// 0x1001 error register (UNSIGNED8).
    pub const ERROR_REGISTER: u16 = 0x1001;
    /// 0x1017 producer heartbeat time in ms (UNSIGNED16).
    pub const PRODUCER_HEARTBEAT_TIME: u16 = 0x1017;
    /// 0x603F error code (UNSIGNED16).
    pub const ERROR_CODE: u16 = 0x603F;
    /// 0x6040 controlword (UNSIGNED16).
    pub const CONTROLWORD: u16 = 0x6040;
    /// 0x6041 statusword (UNSIGNED16).
    pub const STATUSWORD: u16 = 0x6041;
    /// 0x6060 modes of operation (INTEGER8).
    pub const MODES_OF_OPERATION: u16 = 0x6060;
    /// 0x6061 modes of operation display (INTEGER8).
    pub const MODES_OF_OPERATION_DISPLAY: u16 = 0x6061;
    /// 0x6064 position actual value (INTEGER32).
    pub const POSITION_ACTUAL: u16 = 0x6064;
    /// 0x607A target position (INTEGER32).
    pub const TARGET_POSITION: u16 = 0x607A;
    /// 0x6081 profile velocity (UNSIGNED32).
    pub const PROFILE_VELOCITY: u16 = 0x6081;
    /// 0x6083 profile acceleration (UNSIGNED32).
    pub const PROFILE_ACCELERATION: u16 = 0x6083;
    /// 0x6084 profile deceleration (UNSIGNED32).
    pub const PROFILE_DECELERATION: u16 = 0x6084;
    /// Value of 0x6060 selecting profile position mode.
    pub const MODE_PROFILE_POSITION: i8 = 1;
    /// 0x60B8 touch probe function (UNSIGNED16): see [`super::TouchProbeFunction`].
    pub const TOUCH_PROBE_FUNCTION: u16 = 0x60B8;
    /// 0x60B9 touch probe status (UNSIGNED16): see [`super::TouchProbeStatus`].
    pub const TOUCH_PROBE_STATUS: u16 = 0x60B9;
    /// 0x60BA touch probe 1 positive-edge position value (INTEGER32, position units: counts).
    pub const TOUCH_PROBE_1_POSITIVE: u16 = 0x60BA;
    /// 0x60BB touch probe 1 negative-edge position value (INTEGER32, counts).
    pub const TOUCH_PROBE_1_NEGATIVE: u16 = 0x60BB;
}

/// A CiA 402 touch probe function word (object 0x60B8): which probe latches the position on
/// which edge of which input. Bit layout of probe 1 (probe 2 is the same in bits 8–15), per
/// CiA 402 / IEC 61800-7-201 as drive manuals reproduce it (e.g. the MOONS' EtherCAT drive
/// manual §3.10 "Touch probe" and Beckhoff's EP7211 "Touch Probe" page):
///
/// | bit | 0 | 1 |
/// |---|---|---|
/// | 0 | probe 1 switched off | probe 1 enabled |
/// | 1 | trigger on the first event | continuous |
/// | 2–3 | `00` the probe 1 input, `01` the encoder's zero impulse, `10` the source in 0x60D0 sub 1, `11` reserved | |
/// | 4 | no sampling at the positive edge | sample at the positive edge (0x60BA) |
/// | 5 | no sampling at the negative edge | sample at the negative edge (0x60BB) |
/// | 6–7 | reserved | |
///
/// In first-event mode a stored edge is kept until the probe is re-armed: switching bit 0 off
/// clears the status bits (0x60B9), and switching it on again samples the next edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TouchProbeFunction(pub u16);

impl TouchProbeFunction {
    /// Everything off: 0x0000.
    pub const OFF: TouchProbeFunction = TouchProbeFunction(0x0000);
    /// Bit 0: probe 1 enabled.
    pub const BIT_PROBE1_ENABLE: u16 = 1 << 0;
    /// Bit 1: probe 1 continuous (every edge) instead of the first event only.
    pub const BIT_PROBE1_CONTINUOUS: u16 = 1 << 1;
    /// Bits 2–3: probe 1's trigger source (`00` = its input).
    pub const MASK_PROBE1_SOURCE: u16 = 0b11 << 2;
    /// Bit 4: probe 1 samples at the positive edge.
    pub const BIT_PROBE1_POSITIVE: u16 = 1 << 4;
    /// Bit 5: probe 1 samples at the negative edge.
    pub const BIT_PROBE1_NEGATIVE: u16 = 1 << 5;

    /// Probe 1 enabled, first event only, triggered by its own input, sampling the positive
    /// edge: 0x0011. What rigcal writes to latch a contact.
    pub fn probe1_first_positive_edge() -> Self {
        TouchProbeFunction(Self::BIT_PROBE1_ENABLE | Self::BIT_PROBE1_POSITIVE)
    }
    /// Bit 0.
    pub fn probe1_enabled(self) -> bool {
        self.0 & Self::BIT_PROBE1_ENABLE != 0
    }
    /// Bit 1.
    pub fn probe1_continuous(self) -> bool {
        self.0 & Self::BIT_PROBE1_CONTINUOUS != 0
    }
    /// Bits 2–3 as a number (0: the probe 1 input).
    pub fn probe1_source(self) -> u16 {
        (self.0 & Self::MASK_PROBE1_SOURCE) >> 2
    }
    /// Bit 4.
    pub fn probe1_positive_edge(self) -> bool {
        self.0 & Self::BIT_PROBE1_POSITIVE != 0
    }
    /// Bit 5.
    pub fn probe1_negative_edge(self) -> bool {
        self.0 & Self::BIT_PROBE1_NEGATIVE != 0
    }
}

/// A CiA 402 touch probe status word (object 0x60B9), probe 1 in bits 0–7 (probe 2 the same
/// in bits 8–15; same sources as [`TouchProbeFunction`]):
///
/// | bit | 0 | 1 |
/// |---|---|---|
/// | 0 | probe 1 switched off | probe 1 enabled |
/// | 1 | no positive edge stored | a positive-edge position stored (in 0x60BA) |
/// | 2 | no negative edge stored | a negative-edge position stored (in 0x60BB) |
/// | 3–5 | reserved | |
/// | 6–7 | manufacturer-specific | |
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TouchProbeStatus(pub u16);

impl TouchProbeStatus {
    /// Bit 0: probe 1 enabled.
    pub const BIT_PROBE1_ENABLED: u16 = 1 << 0;
    /// Bit 1: probe 1's positive-edge position stored.
    pub const BIT_PROBE1_POSITIVE_STORED: u16 = 1 << 1;
    /// Bit 2: probe 1's negative-edge position stored.
    pub const BIT_PROBE1_NEGATIVE_STORED: u16 = 1 << 2;

    /// The status of probe 1 (nothing of probe 2), for emulators.
    pub fn probe1(enabled: bool, positive_stored: bool) -> Self {
        let mut w = 0;
        if enabled {
            w |= Self::BIT_PROBE1_ENABLED;
        }
        if positive_stored {
            w |= Self::BIT_PROBE1_POSITIVE_STORED;
        }
        TouchProbeStatus(w)
    }
    /// Bit 0.
    pub fn probe1_enabled(self) -> bool {
        self.0 & Self::BIT_PROBE1_ENABLED != 0
    }
    /// Bit 1.
    pub fn probe1_positive_stored(self) -> bool {
        self.0 & Self::BIT_PROBE1_POSITIVE_STORED != 0
    }
    /// Bit 2.
    pub fn probe1_negative_stored(self) -> bool {
        self.0 & Self::BIT_PROBE1_NEGATIVE_STORED != 0
    }
}

/// CiA 402 power drive system state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DriveState {
    /// `xxxx xxxx x0xx 0000` (mask 0x4F = 0x00).
    NotReadyToSwitchOn,
    /// `x1xx 0000` (mask 0x4F = 0x40).
    SwitchOnDisabled,
    /// `x01x 0001` (mask 0x6F = 0x21).
    ReadyToSwitchOn,
    /// `x01x 0011` (mask 0x6F = 0x23).
    SwitchedOn,
    /// `x01x 0111` (mask 0x6F = 0x27).
    OperationEnabled,
    /// `x00x 0111` (mask 0x6F = 0x07).
    QuickStopActive,
    /// `x0xx 1111` (mask 0x4F = 0x0F).
    FaultReactionActive,
    /// `x0xx 1000` (mask 0x4F = 0x08).
    Fault,
}

/// A CiA 402 statusword (object 0x6041).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Statusword(pub u16);

impl Statusword {
    /// The drive state per the CiA 402 table.
    pub fn state(self) -> Result<DriveState, CanOpenError> {
        let w = self.0;
        Ok(match (w & 0x4F, w & 0x6F) {
            (0x00, _) => DriveState::NotReadyToSwitchOn,
            (0x40, _) => DriveState::SwitchOnDisabled,
            (0x0F, _) => DriveState::FaultReactionActive,
            (0x08, _) => DriveState::Fault,
            (_, 0x21) => DriveState::ReadyToSwitchOn,
            (_, 0x23) => DriveState::SwitchedOn,
            (_, 0x27) => DriveState::OperationEnabled,
            (_, 0x07) => DriveState::QuickStopActive,
            _ => return Err(CanOpenError::UnknownDriveState { statusword: w }),
        })
    }
    /// A canonical statusword for `state` (only the state bits set), for emulators.
    pub fn for_state(state: DriveState) -> Self {
        Statusword(match state {
            DriveState::NotReadyToSwitchOn => 0x0000,
            DriveState::SwitchOnDisabled => 0x0040,
            DriveState::ReadyToSwitchOn => 0x0021,
            DriveState::SwitchedOn => 0x0023,
            DriveState::OperationEnabled => 0x0027,
            DriveState::QuickStopActive => 0x0007,
            DriveState::FaultReactionActive => 0x000F,
            DriveState::Fault => 0x0008,
        })
    }
    fn bit(self, n: u8) -> bool {
        self.0 & (1 << n) != 0
    }
    /// Bit 3: fault.
    pub fn fault(self) -> bool {
        self.bit(3)
    }
    /// Bit 7: warning.
    pub fn warning(self) -> bool {
        self.bit(7)
    }
    /// Bit 9: remote (controlword processed).
    pub fn remote(self) -> bool {
        self.bit(9)
    }
    /// Bit 10: target reached.
    pub fn target_reached(self) -> bool {
        self.bit(10)
    }
    /// Bit 12 in profile position mode: set-point acknowledge.
    pub fn setpoint_acknowledge(self) -> bool {
        self.bit(12)
    }
    /// Bit 13 in profile position mode: following error.
    pub fn following_error(self) -> bool {
        self.bit(13)
    }
    /// Returns a copy with bit `n` (0..=15) set to `on`.
    pub fn with_bit(self, n: u8, on: bool) -> Self {
        let mask = 1u16.checked_shl(u32::from(n)).unwrap_or(0);
        Statusword(if on { self.0 | mask } else { self.0 & !mask })
    }
}

/// A CiA 402 controlword (object 0x6040).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Controlword(pub u16);

impl Controlword {
    /// Shutdown (transitions 2, 6, 8): 0x0006.
    pub const SHUTDOWN: Controlword = Controlword(0x0006);
    /// Switch on (transition 3): 0x0007.
    pub const SWITCH_ON: Controlword = Controlword(0x0007);
    /// Enable operation (transition 4): 0x000F.
    pub const ENABLE_OPERATION: Controlword = Controlword(0x000F);
    /// Disable voltage (transitions 7, 9, 10, 12): 0x0000.
    pub const DISABLE_VOLTAGE: Controlword = Controlword(0x0000);
    /// Quick stop (transitions 7, 10, 11): 0x0002.
    pub const QUICK_STOP: Controlword = Controlword(0x0002);
    /// Fault reset (transition 15, acts on the rising edge of bit 7): 0x0080.
    pub const FAULT_RESET: Controlword = Controlword(0x0080);
    /// Bit 4: new set-point (profile position mode).
    pub const BIT_NEW_SETPOINT: u16 = 1 << 4;
    /// Bit 5: change set immediately.
    const BIT_CHANGE_SET_IMMEDIATELY: u16 = 1 << 5;
    /// Bit 6: target is relative (1) or absolute (0).
    const BIT_RELATIVE: u16 = 1 << 6;
    /// Bit 7: fault reset.
    pub const BIT_FAULT_RESET: u16 = 1 << 7;
    /// Bit 8: halt.
    pub const BIT_HALT: u16 = 1 << 8;

    fn with(self, mask: u16, on: bool) -> Self {
        Controlword(if on { self.0 | mask } else { self.0 & !mask })
    }
    /// Sets/clears bit 4 (new set-point).
    pub fn with_new_setpoint(self, on: bool) -> Self {
        self.with(Self::BIT_NEW_SETPOINT, on)
    }
    /// Sets/clears bit 5 (change set immediately).
    pub fn with_change_set_immediately(self, on: bool) -> Self {
        self.with(Self::BIT_CHANGE_SET_IMMEDIATELY, on)
    }
    /// Sets bit 6 for a relative target, clears it for an absolute one.
    pub fn with_relative(self, relative: bool) -> Self {
        self.with(Self::BIT_RELATIVE, relative)
    }
    /// Sets/clears bit 8 (halt).
    pub fn with_halt(self, on: bool) -> Self {
        self.with(Self::BIT_HALT, on)
    }
    /// True if bit 6 (relative) is set.
    pub fn relative(self) -> bool {
        self.0 & Self::BIT_RELATIVE != 0
    }
    /// True if bit 7 (fault reset) is set.
    pub fn fault_reset(self) -> bool {
        self.0 & Self::BIT_FAULT_RESET != 0
    }
}

/// Next controlword on the path to *operation enabled*, or `None` when no
/// command should be sent now.
///
/// | state | returns |
/// |---|---|
/// | not ready to switch on | `None` (the drive leaves it by itself) |
/// | switch on disabled | `0x0006` shutdown |
/// | ready to switch on | `0x0007` switch on |
/// | switched on | `0x000F` enable operation |
/// | operation enabled | `None` (done) |
/// | quick stop active | `0x0000` disable voltage (back to switch on disabled, then the normal path) |
/// | fault reaction active | `None` (wait for *fault*) |
/// | fault | `0x0080` fault reset |
///
/// Fault reset acts on the rising edge of bit 7: if the previous controlword
/// sent already had bit 7 set, the caller must first send one with bit 7
/// clear (e.g. `0x0000`).
pub fn next_controlword_towards_enabled(state: DriveState) -> Option<u16> {
    match state {
        DriveState::NotReadyToSwitchOn
        | DriveState::OperationEnabled
        | DriveState::FaultReactionActive => None,
        DriveState::SwitchOnDisabled => Some(Controlword::SHUTDOWN.0),
        DriveState::ReadyToSwitchOn => Some(Controlword::SWITCH_ON.0),
        DriveState::SwitchedOn => Some(Controlword::ENABLE_OPERATION.0),
        DriveState::QuickStopActive => Some(Controlword::DISABLE_VOLTAGE.0),
        DriveState::Fault => Some(Controlword::FAULT_RESET.0),
    }
}
