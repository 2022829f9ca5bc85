//! `canopen`: the x-y-z table as three CiA 402 drives on CANopen, profile position mode.
//!
//! | file | holds |
//! |---|---|
//! | [`table`] | the driver ([`CanOpenTable`]) |
//! | [`emulator`] | the emulated drives ([`TableEmulator`]) |
//! | [`settings`] | `[devices.table]` ([`TableConfig`]) |
//!
//! The wire format is [`crate::protocols::canopen`]; the bus one of [`crate::transports`].

pub mod emulator;
pub mod settings;
pub mod table;

pub use emulator::TableEmulator;
pub use settings::TableConfig;
pub use table::CanOpenTable;

use crate::devices::clock::SharedClock;
use crate::devices::drivers::kinds::{Emulated, TableDriver};
use crate::devices::emulators::faults::TableFaultHandle;
use crate::devices::emulators::{FrameEmulator, SharedTable};
use crate::devices::keys::KeyError;
use crate::devices::traits::{DeviceError, Table};
use crate::transports::CanBus;

/// The registry's entry for the CANopen table.
#[derive(Debug, Clone, Copy)]
pub struct CanOpen;

impl TableDriver for CanOpen {
    fn name(&self) -> &'static str {
        settings::DRIVER
    }

    fn check(&self, cfg: &TableConfig) -> Result<(), KeyError> {
        cfg.validate()
    }

    fn open(
        &self,
        cfg: &TableConfig,
        bus: Box<dyn CanBus>,
        clock: SharedClock,
    ) -> Result<Box<dyn Table>, DeviceError> {
        Ok(Box::new(CanOpenTable::new(bus, cfg, clock)?))
    }

    fn emulator(
        &self,
        cfg: &TableConfig,
        truth: SharedTable,
    ) -> Emulated<dyn FrameEmulator, TableFaultHandle> {
        let e = TableEmulator::new(cfg, truth);
        Emulated {
            faults: e.faults(),
            emulator: Box::new(e),
        }
    }
}
