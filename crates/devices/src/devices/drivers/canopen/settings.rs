//! `[devices.table]` as the CANopen driver and its emulator read it: three CiA 402 drives in
//! profile position mode. Millimetres, milliseconds for times.
//!
//! ```toml
//! [devices.table]
//! driver = "canopen"                # the default
//! transport = "sim"                 # "can0", "socketcan:can0", "slcan:/dev/ttyACM0"
//! node_ids = [1, 2, 3]
//! counts_per_mm = [1000, 1000, 1000]
//! touch_probe = false               # true: the z drive latches the contact height (see below)
//! ```
//!
//! `touch_probe = true` needs the panel controller's touch output wired to the z drive's touch
//! probe 1 input, and a drive with the CiA 402 touch probe objects (0x60B8–0x60BA): the contact
//! height is then the position the drive latched at the touch's positive edge, not the
//! position read after the touch packet came (conventions §8). The drive's objects are checked
//! at bring-up; the wiring only shows in use (a touch packet without a latched edge costs the
//! contact, with a message naming the wiring).

use serde::{Deserialize, Serialize};

use crate::devices::keys::{bad, non_negative, positive, KeyError};
use crate::transports::SlcanBusConfig;

/// The driver's name in the rig file, and the table's driver when the rig file names none.
pub const DRIVER: &str = "canopen";

/// `[devices.table]`: the table's driver and the settings of its three CiA 402 drives (the
/// only table driver so far). Fifteen fields: one per key of the section, which serde reads
/// flat.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TableConfig {
    /// The table's driver by its registry name (`canopen`, the default).
    pub driver: String,
    /// `sim`, `can0` / `socketcan:can0`, or `slcan:/dev/ttyACM0`.
    pub transport: String,
    /// slcan adapter settings (serial line of the adapter is 8N1 at `slcan_baud`).
    pub slcan: SlcanBusConfig,
    /// Baud rate of the slcan adapter's serial line.
    pub slcan_baud: u32,
    /// CANopen node ids of the x, y, z drives.
    pub node_ids: [u8; 3],
    /// Position units: counts per mm, per axis.
    pub counts_per_mm: [f64; 3],
    /// Profile velocity for ordinary moves (mm/s).
    pub profile_velocity_mm_s: f64,
    /// Profile acceleration (mm/s²).
    pub profile_acceleration_mm_s2: f64,
    /// Profile deceleration (mm/s²).
    pub profile_deceleration_mm_s2: f64,
    /// Heartbeat producer period written to 0x1017 (ms); supervised at three periods.
    pub heartbeat_ms: u16,
    /// Latency of a position read over the bus (ms): SDO request to response.
    pub bus_latency_ms: f64,
    /// Timeout of one SDO exchange (ms).
    pub sdo_timeout_ms: u64,
    /// Interval between status polls while waiting (ms).
    pub poll_ms: u64,
    /// Within a pass, how far below the highest z so far a move may go (mm).
    pub pass_retract_mm: f64,
    /// The z drive latches the contact height with its CiA 402 touch probe 1 (positive edge of
    /// its probe input, wired to the panel controller's touch output) instead of the session
    /// reading the position after the touch packet (see the module docs). Default false.
    pub touch_probe: bool,
}

impl Default for TableConfig {
    fn default() -> Self {
        TableConfig {
            driver: DRIVER.into(),
            transport: "sim".into(),
            slcan: SlcanBusConfig::default(),
            slcan_baud: 115_200,
            node_ids: [1, 2, 3],
            counts_per_mm: [1000.0; 3],
            profile_velocity_mm_s: 100.0,
            profile_acceleration_mm_s2: 500.0,
            profile_deceleration_mm_s2: 500.0,
            heartbeat_ms: 100,
            bus_latency_ms: 2.0,
            sdo_timeout_ms: 200,
            poll_ms: 2,
            pass_retract_mm: 10.0,
            touch_probe: false,
        }
    }
}

impl TableConfig {
    /// Checks the drives' keys (the section's transport is checked before); on failure the key
    /// (under `devices.`) and why.
    pub fn validate(&self) -> Result<(), KeyError> {
        for (k, n) in self.node_ids.iter().enumerate() {
            if !(1..=127).contains(n) {
                return Err(bad(&format!("table.node_ids[{k}]"), "must lie in 1..=127"));
            }
        }
        let n = self.node_ids;
        if n[0] == n[1] || n[1] == n[2] || n[0] == n[2] {
            return Err(bad(
                "table.node_ids",
                "the three drives need distinct node ids",
            ));
        }
        for (k, c) in self.counts_per_mm.iter().enumerate() {
            positive(&format!("table.counts_per_mm[{k}]"), *c)?;
        }
        positive("table.profile_velocity_mm_s", self.profile_velocity_mm_s)?;
        positive(
            "table.profile_acceleration_mm_s2",
            self.profile_acceleration_mm_s2,
        )?;
        positive(
            "table.profile_deceleration_mm_s2",
            self.profile_deceleration_mm_s2,
        )?;
        if self.heartbeat_ms == 0 {
            return Err(bad(
                "table.heartbeat_ms",
                "must be positive: rigcal supervises the drives' heartbeats",
            ));
        }
        non_negative("table.bus_latency_ms", self.bus_latency_ms)?;
        if self.sdo_timeout_ms == 0 {
            return Err(bad("table.sdo_timeout_ms", "must be positive"));
        }
        if self.poll_ms == 0 {
            return Err(bad("table.poll_ms", "must be positive"));
        }
        non_negative("table.pass_retract_mm", self.pass_retract_mm)?;
        if self.slcan_baud == 0 {
            return Err(bad("table.slcan_baud", "must be positive"));
        }
        Ok(())
    }
}
