//! The Movemaster's controller as a rig file describes it, for code past the entry points that
//! has a rig and no devices (the calibration's command-path floors, the CLI's `MP` columns).
//! Apart from the driver's other files because it reads the whole `[devices]` section, which
//! the registry of drivers is itself a part of.

use rigcal_core::rig::Rig;

use crate::devices::config::DevicesConfig;
use crate::devices::drivers::movemaster::controller::{ControllerKinematics, PoseError};

impl ControllerKinematics {
    /// The rig's arm controller (frame from `[devices.arm]`, pin axis from the instrument).
    pub fn of_rig(rig: &Rig) -> Result<Self, PoseError> {
        let frame = DevicesConfig::read_opt(rig)
            .as_ref()
            .map(|d| d.arm.controller_frame)
            .unwrap_or_default();
        Self::for_rig(rig, frame)
    }
}
