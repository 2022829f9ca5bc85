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
    /// SDO frames lost on the bus, requests and responses alike (heartbeats and EMCYs get
    /// through: the supervision is tested on its own with [`TableFaults::silent_heartbeat`]).
    pub sdo_loss: FrameLoss,
    /// Frames received from the host.
    pub frames_received: u64,
    /// Per drive (x, y, z): the last controlword written to it (0x6040), `None` before any.
    pub last_controlword: [Option<u16>; 3],
}

/// A seeded, repeatable loss of frames: each frame is lost with probability `rate`, drawn from
/// a generator of its own (a dry run with a loss schedule loses the same frames every time).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameLoss {
    /// Fraction of frames lost (0 to 1).
    pub rate: f64,
    /// The generator's state (its seed before the first draw).
    pub state: u64,
    /// Frames lost so far.
    pub lost: u64,
}

impl FrameLoss {
    /// A loss of `rate` (0 to 1) drawn from `seed`.
    pub fn new(rate: f64, seed: u64) -> Self {
        FrameLoss {
            rate,
            state: seed,
            lost: 0,
        }
    }

    /// Draws for one frame: true when it is lost.
    pub fn lose(&mut self) -> bool {
        if self.rate <= 0.0 {
            return false;
        }
        // SplitMix64: small, seedable, and good enough for a loss schedule.
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        let u = (z >> 11) as f64 / (1u64 << 53) as f64;
        let lost = u < self.rate;
        self.lost += u64::from(lost);
        lost
    }
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
