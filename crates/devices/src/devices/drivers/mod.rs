//! The drivers a rig file can name, by registry: one folder per driver with everything only it
//! knows (its driver, its settings, its emulator; the Movemaster's controller kinematics), one
//! line per driver in the lists below. The pure codecs they speak stay in
//! [`crate::protocols`], a layer without I/O of its own.
//!
//! | driver | device | folder |
//! |---|---|---|
//! | `movemaster` | the RV-M2 arm on its Movemaster controller (RS-232) | [`movemaster`] |
//! | `canopen` | the x-y-z table: three CiA 402 drives on CANopen | [`canopen`] |
//! | `penmount` | the PenMount 6000 touch panel (serial) | [`penmount`] |
//!
//! The rig file names each device's driver (`[devices.arm] driver = "movemaster"`); without a
//! name the device has the driver above, so rig files written before the registry still read.

pub mod canopen;
pub mod kinds;
pub mod movemaster;
pub mod penmount;

pub use kinds::{ArmDriver, Emulated, OpenedArm, PanelDriver, TableDriver};

use crate::devices::keys::{bad, KeyError};

/// The arm drivers.
static ARM_DRIVERS: &[&dyn ArmDriver] = &[&movemaster::Movemaster];

/// The table drivers.
static TABLE_DRIVERS: &[&dyn TableDriver] = &[&canopen::CanOpen];

/// The touch-panel drivers.
static PANEL_DRIVERS: &[&dyn PanelDriver] = &[&penmount::PenMount];

/// The arm driver named `name`; an unknown name is an error on `arm.driver` that lists the
/// known ones.
pub fn arm(name: &str) -> Result<&'static dyn ArmDriver, KeyError> {
    find("arm", name, ARM_DRIVERS, |d| d.name())
}

/// The table driver named `name` (see [`arm`]).
pub fn table(name: &str) -> Result<&'static dyn TableDriver, KeyError> {
    find("table", name, TABLE_DRIVERS, |d| d.name())
}

/// The touch-panel driver named `name` (see [`arm`]).
pub fn panel(name: &str) -> Result<&'static dyn PanelDriver, KeyError> {
    find("panel", name, PANEL_DRIVERS, |d| d.name())
}

fn find<D: ?Sized>(
    device: &str,
    name: &str,
    list: &'static [&'static D],
    name_of: fn(&D) -> &'static str,
) -> Result<&'static D, KeyError> {
    list.iter()
        .copied()
        .find(|d| name_of(d) == name)
        .ok_or_else(|| {
            let known: Vec<&str> = list.iter().map(|d| name_of(d)).collect();
            bad(
                &format!("{device}.driver"),
                format!(
                    "unknown {device} driver `{name}`; the known ones: {}",
                    known.join(", ")
                ),
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_find_their_drivers_and_an_unknown_one_lists_the_known() {
        assert_eq!(arm("movemaster").map(|d| d.name()), Ok("movemaster"));
        assert_eq!(table("canopen").map(|d| d.name()), Ok("canopen"));
        assert_eq!(panel("penmount").map(|d| d.name()), Ok("penmount"));
        let (key, reason) = arm("ur5").err().unwrap();
        assert_eq!(key, "arm.driver");
        assert!(
            reason.contains("`ur5`") && reason.contains("movemaster"),
            "{reason}"
        );
        assert_eq!(table("cia").err().unwrap().0, "table.driver");
    }
}
