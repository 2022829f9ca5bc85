//! What a test or a dry run may inject into an emulated device of each kind, and what the
//! emulator counts: the contract the session's recovery is tested against, whichever driver's
//! emulator honours it (the shipped ones: the Movemaster's, the CANopen drives', the PenMount's).
//! Each emulator shares its faults through a handle (`Arc<Mutex<…>>`) that the factory hands
//! out in [`SimControls`](crate::devices::factory::SimControls).

use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Faults to inject into an emulated arm controller, and a log of what it received.
#[derive(Debug, Clone, Default)]
pub struct ArmFaults {
    /// Replies to drop (not sent at all).
    pub drop_replies: u32,
    /// Replies to garble (a byte flipped, the line end kept).
    pub garble_replies: u32,
    /// Extra delay added to every reply.
    pub extra_delay: Duration,
    /// The next move command puts the controller in this error mode instead of moving (1
    /// hardware, 2 position/format: the Movemaster's `ER` codes).
    pub error_on_next_move: Option<u8>,
    /// Every command line received, as text (for tests: what reached the controller).
    pub received: Vec<String>,
}

/// Shared handle to an emulated arm's [`ArmFaults`].
pub type ArmFaultHandle = Arc<Mutex<ArmFaults>>;

/// A drive fault to inject into an emulated table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InjectedFault {
    /// Axis 0..=2 (x, y, z).
    pub axis: usize,
    /// How long after the next move starts the fault strikes.
    pub after: Duration,
    /// The drive's error code (a CANopen EMCY code: 0x8611 following error, 0x2310
    /// over-current, …).
    pub emcy_code: u16,
}

/// Faults to inject into an emulated table, and counters of what its drives received.
#[derive(Debug, Clone, Default)]
pub struct TableFaults {
    /// The next move of an axis faults.
    pub fault_on_next_move: Option<InjectedFault>,
    /// Per axis: stop producing heartbeats.
    pub silent_heartbeat: [bool; 3],
    /// Ignore requests (no response at all; SDOs on CANopen).
    pub ignore_sdo: bool,
    /// Extra delay on every response.
    pub extra_delay: Duration,
    /// Frames received from the host.
    pub frames_received: u64,
}

/// Shared handle to an emulated table's [`TableFaults`].
pub type TableFaultHandle = Arc<Mutex<TableFaults>>;

/// Faults to inject into an emulated touch panel, and counters.
#[derive(Debug, Clone, Default)]
pub struct PanelFaults {
    /// The next contact produces no packets.
    pub miss_next_touch: bool,
    /// Bytes sent before the next packet.
    pub garbage_before_next: Vec<u8>,
    /// The next packet goes out with a wrong checksum.
    pub corrupt_next_packet: bool,
    /// Packets sent.
    pub packets_sent: u64,
    /// Time of the last contact onset (emulator clock), for tests of the latency rule.
    pub last_contact_at: Option<Duration>,
    /// The table's z at the last contact onset (mm).
    pub last_contact_table_z: Option<f64>,
}

/// Shared handle to an emulated panel's [`PanelFaults`].
pub type PanelFaultHandle = Arc<Mutex<PanelFaults>>;
