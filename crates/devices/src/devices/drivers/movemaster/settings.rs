//! `[devices.arm]` as the Movemaster driver and its emulator read it. Degrees and millimetres,
//! milliseconds for times.
//!
//! ```toml
//! [devices.arm]
//! driver = "movemaster"             # the default
//! transport = "sim"                 # or a serial port path, e.g. "/dev/ttyUSB0"
//! serial = { baud = 9600, data_bits = 7, parity = "even", stop_bits = 2, flow = "none" }
//! resolution_deg = 0.1
//! sign = [1, 1, 1, 1, 1]            # controller angle = sign · q + offset
//! offset_deg = [0, 0, 0, 0, 0]
//! nest_deg = [0, 90, -90, 0, 0]     # pose after NT, D-H joint angles
//! ```

use serde::{Deserialize, Serialize};

use crate::devices::command_path::CommandPath;
use crate::devices::drivers::movemaster::controller::ControllerFrame;
use crate::devices::keys::{bad, non_negative, positive, KeyError};
use crate::protocols::movemaster::MAX_DECIMALS;
use crate::transports::SerialSettings;

/// The driver's name in the rig file, and the arm's driver when the rig file names none.
pub const DRIVER: &str = "movemaster";

/// `[devices.arm]`: the arm's driver and the Movemaster controller's settings (the only arm
/// driver so far). Fourteen fields: one per key of the section, which serde reads flat.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ArmConfig {
    /// The arm's driver by its registry name (`movemaster`, the default).
    pub driver: String,
    /// `sim` or a serial port path.
    pub transport: String,
    /// Serial line settings (default 9600 7E2, no flow control).
    pub serial: SerialSettings,
    /// Joint resolution of `MJ`/`DJ` (deg): a power of ten, 1 down to 0.0001.
    pub resolution_deg: f64,
    /// Per joint: controller angle = sign · q + offset (sign ±1).
    pub sign: Vec<f64>,
    /// Per joint: controller zero (deg).
    pub offset_deg: Vec<f64>,
    /// The pose after `NT`, in D-H joint angles (deg).
    pub nest_deg: Vec<f64>,
    /// Speed level set after homing (0..=9).
    pub speed: u8,
    /// How far `WH` may stray from the nominal forward kinematics (mm); 0 disables the check.
    pub where_tolerance_mm: f64,
    /// Emulator: joint speed at level 9 (deg/s); lower levels scale linearly.
    pub sim_joint_speed_deg_s: f64,
    /// Emulator: reply latency of the controller (ms).
    pub sim_reply_ms: f64,
    /// How compensated moves reach the controller: `joint` (`MJ`, the default) or `cartesian`
    /// (`MP`, through the controller's own nominal inverse kinematics).
    pub command_path: CommandPath,
    /// The controller's Cartesian frame (`MP`, `WH`) relative to the world of the rig's
    /// kinematics: world = Rz(yaw) · controller + origin.
    pub controller_frame: ControllerFrame,
    /// Emulator: the joint servo resolution (deg) a Cartesian move's solution is rounded to.
    pub sim_servo_resolution_deg: f64,
}

impl Default for ArmConfig {
    fn default() -> Self {
        ArmConfig {
            driver: DRIVER.into(),
            transport: "sim".into(),
            serial: SerialSettings::default(),
            resolution_deg: 0.1,
            sign: vec![1.0; 5],
            offset_deg: vec![0.0; 5],
            nest_deg: vec![0.0, 90.0, -90.0, 0.0, 0.0],
            speed: 5,
            where_tolerance_mm: 1.0,
            sim_joint_speed_deg_s: 60.0,
            sim_reply_ms: 5.0,
            command_path: CommandPath::Joint,
            controller_frame: ControllerFrame::default(),
            sim_servo_resolution_deg: 0.001,
        }
    }
}

impl ArmConfig {
    /// Number of decimals of the resolution (0.1 → 1).
    pub fn resolution_decimals(&self) -> Option<u8> {
        (0..=MAX_DECIMALS)
            .find(|&k| (self.resolution_deg - 10f64.powi(-i32::from(k))).abs() < 1e-12)
    }

    /// Checks the Movemaster's keys (the section's own — transport, serial line — are checked
    /// before); on failure the key (under `devices.`) and why.
    pub fn validate(&self) -> Result<(), KeyError> {
        if self.resolution_decimals().is_none() {
            return Err(bad(
                "arm.resolution_deg",
                "must be a power of ten from 1 down to 0.0001 (the Movemaster's is 0.1)",
            ));
        }
        for (key, v) in [
            ("arm.sign", &self.sign),
            ("arm.offset_deg", &self.offset_deg),
            ("arm.nest_deg", &self.nest_deg),
        ] {
            if v.len() != 5 {
                return Err(bad(
                    key,
                    format!("needs 5 values (one per RV-M2 joint), got {}", v.len()),
                ));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Err(bad(key, "must hold finite numbers"));
            }
        }
        if self.sign.iter().any(|s| *s != 1.0 && *s != -1.0) {
            return Err(bad("arm.sign", "each sign must be 1 or -1"));
        }
        if self.speed > 9 {
            return Err(bad("arm.speed", "must lie in 0..=9"));
        }
        non_negative("arm.where_tolerance_mm", self.where_tolerance_mm)?;
        positive("arm.sim_joint_speed_deg_s", self.sim_joint_speed_deg_s)?;
        non_negative("arm.sim_reply_ms", self.sim_reply_ms)?;
        non_negative(
            "arm.sim_servo_resolution_deg",
            self.sim_servo_resolution_deg,
        )?;
        if !self.controller_frame.is_finite() {
            return Err(bad(
                "arm.controller_frame",
                "origin_mm and yaw_deg must be finite",
            ));
        }
        Ok(())
    }
}
