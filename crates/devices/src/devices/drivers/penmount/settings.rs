//! `[devices.panel]` as the PenMount driver and its emulator read it. Millimetres, milliseconds
//! for times.
//!
//! ```toml
//! [devices.panel]
//! driver = "penmount"               # the default
//! transport = "sim"                 # or a serial port path, e.g. "/dev/ttyUSB1"
//! latency_ms = 10
//! ```

use serde::{Deserialize, Serialize};

use crate::devices::keys::{bad, non_negative, positive, KeyError};
use crate::transports::{FlowControl, Parity, SerialSettings};

/// The driver's name in the rig file, and the panel's driver when the rig file names none.
pub const DRIVER: &str = "penmount";

/// `[devices.panel]`: the panel's driver and the PenMount 6000 controller's settings (the only
/// panel driver so far).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PanelConfig {
    /// The panel's driver by its registry name (`penmount`, the default).
    pub driver: String,
    /// `sim` or a serial port path.
    pub transport: String,
    /// Serial line settings (default 19200 8N1).
    pub serial: SerialSettings,
    /// Time from the physical touch to the first packet's last byte (ms).
    pub latency_ms: f64,
    /// Reverse the u axis (u along table −x).
    pub flip_u: bool,
    /// Reverse the v axis.
    pub flip_v: bool,
    /// Added to u after conversion (mm).
    pub shift_u_mm: f64,
    /// Added to v after conversion (mm).
    pub shift_v_mm: f64,
    /// Largest overshoot allowed between the touch and the position read (mm).
    pub max_overshoot_mm: f64,
    /// Emulator: packet period while touched (ms).
    pub sim_report_ms: f64,
}

impl Default for PanelConfig {
    fn default() -> Self {
        PanelConfig {
            driver: DRIVER.into(),
            transport: "sim".into(),
            serial: SerialSettings {
                baud: 19_200,
                data_bits: 8,
                parity: Parity::None,
                stop_bits: 1,
                flow: FlowControl::None,
            },
            latency_ms: 10.0,
            flip_u: false,
            flip_v: false,
            shift_u_mm: 0.0,
            shift_v_mm: 0.0,
            max_overshoot_mm: 0.005,
            sim_report_ms: 10.0,
        }
    }
}

impl PanelConfig {
    /// Checks the controller's keys (the section's transport and serial line are checked
    /// before); on failure the key (under `devices.`) and why.
    pub fn validate(&self) -> Result<(), KeyError> {
        non_negative("panel.latency_ms", self.latency_ms)?;
        if !(self.shift_u_mm.is_finite() && self.shift_v_mm.is_finite()) {
            return Err(bad("panel.shift_u_mm", "shifts must be finite"));
        }
        positive("panel.max_overshoot_mm", self.max_overshoot_mm)?;
        positive("panel.sim_report_ms", self.sim_report_ms)?;
        Ok(())
    }
}
