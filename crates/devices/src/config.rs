//! The `[devices]` section of a rig file: how each device is reached and the numbers its driver,
//! its emulator and the session's procedures need. Degrees and millimetres, milliseconds for times.
//!
//! ```toml
//! [devices.arm]
//! transport = "sim"                 # or a serial port path, e.g. "/dev/ttyUSB0"
//! serial = { baud = 9600, data_bits = 7, parity = "even", stop_bits = 2, flow = "none" }
//! resolution_deg = 0.1
//! sign = [1, 1, 1, 1, 1]            # controller angle = sign · q + offset
//! offset_deg = [0, 0, 0, 0, 0]
//! nest_deg = [0, 90, -90, 0, 0]     # pose after NT, D-H joint angles
//! [devices.table]
//! transport = "sim"                 # "can0", "socketcan:can0", "slcan:/dev/ttyACM0"
//! node_ids = [1, 2, 3]
//! counts_per_mm = [1000, 1000, 1000]
//! [devices.panel]
//! transport = "sim"
//! latency_ms = 10
//! [devices.contact]                 # the session's contact procedure (table and panel)
//! max_disagreement_mm = 1.0
//! [devices.sensor]                  # the session's point-sensor procedure
//! read_timeout_ms = 2000
//! ```

use std::path::PathBuf;

use rigcal_core::rig::{Rig, RigError};
use serde::{Deserialize, Serialize};

use crate::transports::{Parity, SerialSettings, SlcanBusConfig};

/// Everything under `[devices]`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DevicesConfig {
    /// The arm.
    pub arm: ArmConfig,
    /// The table.
    pub table: TableConfig,
    /// The panel.
    pub panel: PanelConfig,
    /// The session's contact procedure on the table and panel.
    pub contact: ContactConfig,
    /// The session's procedure with a point sensor.
    pub sensor: SensorConfig,
}

/// `[devices.contact]`: the thresholds of the session's contact procedure (via pose, travel,
/// locating approach, back-off, final approach). Defaults are the values the session always
/// used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContactConfig {
    /// The approach starts this far below the nominal contact and ends as far above (mm).
    pub margin_mm: f64,
    /// Speed of the first, locating approach (mm/s).
    pub locate_speed_mm_s: f64,
    /// How far the table backs off below the located contact before the final approach (mm).
    pub backoff_mm: f64,
    /// Joint offset of the pre-approach (via) pose (deg), which sets the approach directions.
    pub via_delta_deg: f64,
    /// Before travelling in x-y the table drops this far below both the current and the next
    /// approach height (mm).
    pub clearance_mm: f64,
    /// A touch farther than this from the panel centre is a bad reading (mm).
    pub max_offset_mm: f64,
    /// The final touch may differ from the locating touch by this much in u and in v (mm).
    pub max_disagreement_mm: f64,
    /// Tolerance of the z checks (mm): a touch within it of the approach start means the pin
    /// was already on the panel; a final touch more than it below the back-off is wrong.
    pub z_tolerance_mm: f64,
}

impl Default for ContactConfig {
    fn default() -> Self {
        ContactConfig {
            margin_mm: 2.5,
            locate_speed_mm_s: 5.0,
            backoff_mm: 0.3,
            via_delta_deg: 0.5,
            clearance_mm: 2.0,
            max_offset_mm: 10.0,
            max_disagreement_mm: 1.0,
            z_tolerance_mm: 0.01,
        }
    }
}

/// `[devices.sensor]`: the session's procedure with a point sensor (via pose, target, one
/// reading).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    /// Joint offset of the pre-approach (via) pose (deg), which sets the approach directions.
    pub via_delta_deg: f64,
    /// Timeout of one reading (ms).
    pub read_timeout_ms: u64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            via_delta_deg: 0.5,
            read_timeout_ms: 2000,
        }
    }
}

/// `[devices.arm]`: the Movemaster controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ArmConfig {
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
    pub command_path: crate::devices::controller::CommandPath,
    /// The controller's Cartesian frame (`MP`, `WH`) relative to the world of the rig's
    /// kinematics: world = Rz(yaw) · controller + origin.
    pub controller_frame: crate::devices::controller::ControllerFrame,
    /// Emulator: the joint servo resolution (deg) a Cartesian move's solution is rounded to.
    pub sim_servo_resolution_deg: f64,
}

impl Default for ArmConfig {
    fn default() -> Self {
        ArmConfig {
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
            command_path: crate::devices::controller::CommandPath::Joint,
            controller_frame: crate::devices::controller::ControllerFrame::default(),
            sim_servo_resolution_deg: 0.001,
        }
    }
}

/// `[devices.table]`: three CiA 402 drives in profile position mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TableConfig {
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
}

impl Default for TableConfig {
    fn default() -> Self {
        TableConfig {
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
        }
    }
}

/// `[devices.panel]`: the PenMount 6000 controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PanelConfig {
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
            transport: "sim".into(),
            serial: SerialSettings {
                baud: 19_200,
                data_bits: 8,
                parity: Parity::None,
                stop_bits: 1,
                flow: crate::transports::FlowControl::None,
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

fn bad(key: &str, reason: impl Into<String>) -> (String, String) {
    (key.to_string(), reason.into())
}

fn positive(key: &str, v: f64) -> Result<(), (String, String)> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(key, "must be a positive number"))
    }
}

fn non_negative(key: &str, v: f64) -> Result<(), (String, String)> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(bad(key, "must be zero or positive"))
    }
}

fn transport(key: &str, t: &str, can: bool) -> Result<(), (String, String)> {
    let t = t.trim();
    if t.is_empty() {
        return Err(bad(key, "must not be empty: \"sim\" or a device path"));
    }
    if can && t.starts_with("slcan:") && t.len() == "slcan:".len() {
        return Err(bad(
            key,
            "slcan needs a serial port: \"slcan:/dev/ttyACM0\"",
        ));
    }
    Ok(())
}

impl ArmConfig {
    /// Number of decimals of the resolution (0.1 → 1).
    pub fn resolution_decimals(&self) -> Option<u8> {
        (0..=crate::protocols::movemaster::MAX_DECIMALS)
            .find(|&k| (self.resolution_deg - 10f64.powi(-i32::from(k))).abs() < 1e-12)
    }
}

impl DevicesConfig {
    /// The rig file's `[devices]` section, read and checked; the defaults where the rig file
    /// has none. Errors name the file and the key (`devices.arm.resolution_deg`), and a
    /// mistyped or unknown key its line and column.
    pub fn of_rig(rig: &Rig) -> Result<DevicesConfig, RigError> {
        let path = rig
            .source
            .path
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("<{}>", rig.name)));
        let Some(section) = &rig.devices else {
            return Ok(DevicesConfig::default());
        };
        let cfg =
            Self::read_section(&rig.source.text, section).map_err(|message| RigError::Parse {
                path: path.clone(),
                message,
            })?;
        cfg.validate().map_err(|(key, reason)| RigError::Invalid {
            path,
            key: format!("devices.{key}"),
            reason,
        })?;
        Ok(cfg)
    }

    /// The section as [`Self::of_rig`] reads it, for code that runs once the rig is open (the
    /// entry points — the factory, the planner, the session — call `of_rig` first and stop on
    /// its errors); `None` when the rig file has no `[devices]`.
    pub fn read_opt(rig: &Rig) -> Option<DevicesConfig> {
        let section = rig.devices.as_ref()?;
        Some(
            DevicesConfig::deserialize(toml::Value::Table(section.clone())).unwrap_or_else(|e| {
                tracing::warn!(%e, "the rig's [devices] section does not read; its defaults used");
                DevicesConfig::default()
            }),
        )
    }

    /// [`Self::read_opt`], the defaults when the rig file has no `[devices]`.
    pub fn read(rig: &Rig) -> DevicesConfig {
        Self::read_opt(rig).unwrap_or_default()
    }

    /// The section from the rig file's text when there is one (so an error carries its line
    /// and column), else from the table the rig holds.
    fn read_section(text: &str, section: &toml::Table) -> Result<DevicesConfig, String> {
        #[derive(Deserialize)]
        struct OnlyDevices {
            #[serde(default)]
            devices: Option<DevicesConfig>,
        }
        if !text.trim().is_empty() {
            if let Some(cfg) = toml::from_str::<OnlyDevices>(text)
                .map_err(|e| e.to_string())?
                .devices
            {
                return Ok(cfg);
            }
        }
        DevicesConfig::deserialize(toml::Value::Table(section.clone())).map_err(|e| e.to_string())
    }

    /// Checks ranges and consistency; on failure returns the key (under `devices.`) and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let a = &self.arm;
        transport("arm.transport", &a.transport, false)?;
        a.serial
            .validate()
            .map_err(|e| bad("arm.serial", e.to_string()))?;
        if a.resolution_decimals().is_none() {
            return Err(bad(
                "arm.resolution_deg",
                "must be a power of ten from 1 down to 0.0001 (the Movemaster's is 0.1)",
            ));
        }
        for (key, v) in [
            ("arm.sign", &a.sign),
            ("arm.offset_deg", &a.offset_deg),
            ("arm.nest_deg", &a.nest_deg),
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
        if a.sign.iter().any(|s| *s != 1.0 && *s != -1.0) {
            return Err(bad("arm.sign", "each sign must be 1 or -1"));
        }
        if a.speed > 9 {
            return Err(bad("arm.speed", "must lie in 0..=9"));
        }
        non_negative("arm.where_tolerance_mm", a.where_tolerance_mm)?;
        positive("arm.sim_joint_speed_deg_s", a.sim_joint_speed_deg_s)?;
        non_negative("arm.sim_reply_ms", a.sim_reply_ms)?;
        non_negative("arm.sim_servo_resolution_deg", a.sim_servo_resolution_deg)?;
        if !a.controller_frame.is_finite() {
            return Err(bad(
                "arm.controller_frame",
                "origin_mm and yaw_deg must be finite",
            ));
        }

        let t = &self.table;
        transport("table.transport", &t.transport, true)?;
        for (k, n) in t.node_ids.iter().enumerate() {
            if !(1..=127).contains(n) {
                return Err(bad(&format!("table.node_ids[{k}]"), "must lie in 1..=127"));
            }
        }
        if t.node_ids[0] == t.node_ids[1]
            || t.node_ids[1] == t.node_ids[2]
            || t.node_ids[0] == t.node_ids[2]
        {
            return Err(bad(
                "table.node_ids",
                "the three drives need distinct node ids",
            ));
        }
        for (k, c) in t.counts_per_mm.iter().enumerate() {
            positive(&format!("table.counts_per_mm[{k}]"), *c)?;
        }
        positive("table.profile_velocity_mm_s", t.profile_velocity_mm_s)?;
        positive(
            "table.profile_acceleration_mm_s2",
            t.profile_acceleration_mm_s2,
        )?;
        positive(
            "table.profile_deceleration_mm_s2",
            t.profile_deceleration_mm_s2,
        )?;
        if t.heartbeat_ms == 0 {
            return Err(bad(
                "table.heartbeat_ms",
                "must be positive: rigcal supervises the drives' heartbeats",
            ));
        }
        non_negative("table.bus_latency_ms", t.bus_latency_ms)?;
        if t.sdo_timeout_ms == 0 {
            return Err(bad("table.sdo_timeout_ms", "must be positive"));
        }
        if t.poll_ms == 0 {
            return Err(bad("table.poll_ms", "must be positive"));
        }
        non_negative("table.pass_retract_mm", t.pass_retract_mm)?;
        if t.slcan_baud == 0 {
            return Err(bad("table.slcan_baud", "must be positive"));
        }

        let p = &self.panel;
        transport("panel.transport", &p.transport, false)?;
        p.serial
            .validate()
            .map_err(|e| bad("panel.serial", e.to_string()))?;
        non_negative("panel.latency_ms", p.latency_ms)?;
        if !(p.shift_u_mm.is_finite() && p.shift_v_mm.is_finite()) {
            return Err(bad("panel.shift_u_mm", "shifts must be finite"));
        }
        positive("panel.max_overshoot_mm", p.max_overshoot_mm)?;
        positive("panel.sim_report_ms", p.sim_report_ms)?;

        let c = &self.contact;
        positive("contact.margin_mm", c.margin_mm)?;
        positive("contact.locate_speed_mm_s", c.locate_speed_mm_s)?;
        positive("contact.backoff_mm", c.backoff_mm)?;
        non_negative("contact.via_delta_deg", c.via_delta_deg)?;
        non_negative("contact.clearance_mm", c.clearance_mm)?;
        positive("contact.max_offset_mm", c.max_offset_mm)?;
        positive("contact.max_disagreement_mm", c.max_disagreement_mm)?;
        non_negative("contact.z_tolerance_mm", c.z_tolerance_mm)?;

        let s = &self.sensor;
        non_negative("sensor.via_delta_deg", s.via_delta_deg)?;
        if s.read_timeout_ms == 0 {
            return Err(bad("sensor.read_timeout_ms", "must be positive"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        assert_eq!(DevicesConfig::default().validate(), Ok(()));
        assert_eq!(ArmConfig::default().resolution_decimals(), Some(1));
    }

    #[test]
    fn bad_values_name_their_key() {
        let mut c = DevicesConfig::default();
        c.arm.resolution_deg = 0.3;
        assert_eq!(c.validate().unwrap_err().0, "arm.resolution_deg");
        let mut c = DevicesConfig::default();
        c.table.node_ids = [1, 1, 3];
        assert_eq!(c.validate().unwrap_err().0, "table.node_ids");
        let mut c = DevicesConfig::default();
        c.arm.sign = vec![1.0, 1.0, 2.0, 1.0, 1.0];
        assert_eq!(c.validate().unwrap_err().0, "arm.sign");
        let mut c = DevicesConfig::default();
        c.contact.max_disagreement_mm = 0.0;
        assert_eq!(c.validate().unwrap_err().0, "contact.max_disagreement_mm");
    }

    #[test]
    fn unknown_keys_are_rejected() {
        let e = toml::from_str::<DevicesConfig>("[arm]\nbaud = 9600\n").unwrap_err();
        assert!(e.to_string().contains("baud"), "{e}");
    }
}
