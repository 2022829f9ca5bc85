//! The `[devices]` section of a rig file: each device's driver, how it is reached and the
//! numbers its driver, its emulator and the session's procedures need. Degrees and millimetres,
//! milliseconds for times. A device section's keys are its driver's settings, kept with the
//! driver ([`crate::devices::drivers`]); the session's own sections (`contact`, `sensor`) are
//! here.
//!
//! ```toml
//! [devices.arm]
//! driver = "movemaster"             # the default; an unknown name is an error listing the known
//! transport = "sim"                 # or a serial port path, e.g. "/dev/ttyUSB0"
//! serial = { baud = 9600, data_bits = 7, parity = "even", stop_bits = 2, flow = "none" }
//! resolution_deg = 0.1
//! sign = [1, 1, 1, 1, 1]            # controller angle = sign · q + offset
//! offset_deg = [0, 0, 0, 0, 0]
//! nest_deg = [0, 90, -90, 0, 0]     # pose after NT, D-H joint angles
//! [devices.table]
//! driver = "canopen"                # three CiA 402 drives, the default
//! transport = "sim"                 # "can0", "socketcan:can0", "slcan:/dev/ttyACM0"
//! node_ids = [1, 2, 3]
//! counts_per_mm = [1000, 1000, 1000]
//! [devices.panel]
//! driver = "penmount"               # the default
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

use crate::devices::drivers;
use crate::devices::keys::{bad, non_negative, positive, KeyError};

pub use crate::devices::drivers::canopen::settings::TableConfig;
pub use crate::devices::drivers::movemaster::settings::ArmConfig;
pub use crate::devices::drivers::penmount::settings::PanelConfig;

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
    /// A rehearsal only: the Unix socket of the simulated world behind emulators served on
    /// pseudo-terminals (`rigcal sim-device rig --pty --write-rig` writes it), through which
    /// the session's hook reaches that world. Never set on a real rig.
    pub world: Option<String>,
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

fn transport(key: &str, t: &str, can: bool) -> Result<(), KeyError> {
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

/// Loads a rig file and checks its `[devices]` section ([`DevicesConfig::of_rig`]): the rig
/// as every command loads it, so a mistyped or out-of-range device setting is refused at load
/// (with file, key and line) rather than replaced by its default later.
pub fn load_rig(path: &std::path::Path) -> Result<Rig, RigError> {
    let rig = Rig::load(path)?;
    DevicesConfig::of_rig(&rig)?;
    Ok(rig)
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

    /// The section as [`Self::of_rig`] reads it, for code that runs once the rig is open: rigs
    /// are loaded through [`load_rig`] and the factory checks the section with `of_rig` before
    /// it opens a device, so past those the section is known to read; `None` when the rig file
    /// has no `[devices]`.
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

    /// Checks ranges and consistency, each device's keys by its driver; on failure returns the
    /// key (under `devices.`) and why.
    pub fn validate(&self) -> Result<(), KeyError> {
        let a = &self.arm;
        let arm = drivers::arm(&a.driver)?;
        transport("arm.transport", &a.transport, false)?;
        a.serial
            .validate()
            .map_err(|e| bad("arm.serial", e.to_string()))?;
        arm.check(a)?;

        let t = &self.table;
        let table = drivers::table(&t.driver)?;
        transport("table.transport", &t.transport, true)?;
        table.check(t)?;

        let p = &self.panel;
        let panel = drivers::panel(&p.driver)?;
        transport("panel.transport", &p.transport, false)?;
        p.serial
            .validate()
            .map_err(|e| bad("panel.serial", e.to_string()))?;
        panel.check(p)?;

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
    fn a_device_without_a_driver_has_the_shipped_one_and_an_unknown_one_is_refused() {
        let c: DevicesConfig = toml::from_str("[arm]\ntransport = \"sim\"\n").unwrap();
        assert_eq!(
            [&c.arm.driver, &c.table.driver, &c.panel.driver],
            ["movemaster", "canopen", "penmount"]
        );
        let c: DevicesConfig = toml::from_str("[table]\ndriver = \"ethercat\"\n").unwrap();
        let (key, reason) = c.validate().unwrap_err();
        assert_eq!(key, "table.driver");
        assert!(
            reason.contains("`ethercat`") && reason.contains("canopen"),
            "{reason}"
        );
    }

    /// The shipped rig file names its drivers; without the names it reads as before, with an
    /// unknown one its error names the key and the known drivers.
    #[test]
    fn rig_files_name_their_drivers() {
        let path = std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2.toml"
        ));
        let text = std::fs::read_to_string(path).unwrap();
        let shipped = DevicesConfig::of_rig(&Rig::parse(&text, Some(path)).unwrap()).unwrap();
        assert_eq!(shipped.arm.driver, "movemaster");
        let unnamed: String = text
            .lines()
            .filter(|l| !l.starts_with("driver = "))
            .map(|l| format!("{l}\n"))
            .collect();
        let rig = Rig::parse(&unnamed, Some(path)).unwrap();
        assert_eq!(DevicesConfig::of_rig(&rig).unwrap(), shipped);
        let unknown = text.replace("driver = \"movemaster\"", "driver = \"ur5\"");
        let e = DevicesConfig::of_rig(&Rig::parse(&unknown, Some(path)).unwrap())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`devices.arm.driver`") && e.contains("`ur5`") && e.contains("movemaster"),
            "{e}"
        );
    }

    #[test]
    fn unknown_keys_are_rejected() {
        let e = toml::from_str::<DevicesConfig>("[arm]\nbaud = 9600\n").unwrap_err();
        assert!(e.to_string().contains("baud"), "{e}");
    }
}
