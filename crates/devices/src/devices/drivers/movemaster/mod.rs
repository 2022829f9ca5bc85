//! `movemaster`: the RV-M2 arm on its Mitsubishi Movemaster controller over RS-232, and
//! everything only this controller knows.
//!
//! | file | holds |
//! |---|---|
//! | [`arm`] | the driver ([`MovemasterArm`]): `NT`, `SP`, `MJ`/`DJ`, `MP`, `WH`, `ER`, `RS` |
//! | [`controller`] | the controller's Cartesian frame, pose convention and nominal inverse kinematics (`MP`, `WH`) |
//! | [`emulator`] | the emulated controller ([`ArmEmulator`]) |
//! | [`settings`] | `[devices.arm]` ([`ArmConfig`]) |
//!
//! The wire format is [`crate::protocols::movemaster`].

pub mod arm;
pub mod controller;
pub mod emulator;
mod rig;
pub mod settings;

pub use arm::MovemasterArm;
pub use controller::{ControllerFrame, ControllerKinematics, PoseError};
pub use emulator::ArmEmulator;
pub use settings::ArmConfig;

use rigcal_core::rig::Rig;

use crate::devices::clock::SharedClock;
use crate::devices::drivers::kinds::{ArmDriver, Emulated, OpenedArm};
use crate::devices::emulators::faults::ArmFaultHandle;
use crate::devices::emulators::physics::SharedPhysics;
use crate::devices::emulators::ByteEmulator;
use crate::devices::keys::KeyError;
use crate::devices::traits::DeviceError;
use crate::transports::ByteTransport;

/// The registry's entry for the Movemaster.
#[derive(Debug, Clone, Copy)]
pub struct Movemaster;

impl ArmDriver for Movemaster {
    fn name(&self) -> &'static str {
        settings::DRIVER
    }

    fn check(&self, cfg: &ArmConfig) -> Result<(), KeyError> {
        cfg.validate()
    }

    /// The driver with the rig's controller kinematics (frame from `[devices.arm]`, pin axis
    /// from the instrument) for its Cartesian moves and `WH` check, which the joint limits
    /// also check a Cartesian move's solution with.
    fn open(
        &self,
        rig: &Rig,
        cfg: &ArmConfig,
        io: Box<dyn ByteTransport>,
        clock: SharedClock,
    ) -> Result<OpenedArm, DeviceError> {
        let arm = MovemasterArm::new(io, rig.chain.clone(), cfg, clock)?;
        Ok(
            match ControllerKinematics::for_rig(rig, cfg.controller_frame) {
                Ok(k) => OpenedArm {
                    arm: Box::new(arm.with_controller(k.clone())),
                    cartesian: Some(Box::new(k)),
                },
                Err(_) => OpenedArm {
                    arm: Box::new(arm),
                    cartesian: None,
                },
            },
        )
    }

    fn emulator(
        &self,
        rig: &Rig,
        cfg: &ArmConfig,
        physics: SharedPhysics,
    ) -> Emulated<dyn ByteEmulator, ArmFaultHandle> {
        let e = ArmEmulator::new(rig, cfg, physics);
        Emulated {
            faults: e.faults(),
            emulator: Box::new(e),
        }
    }
}
