//! `penmount`: the PenMount 6000 touch panel on the table's z arm, over a serial line.
//!
//! | file | holds |
//! |---|---|
//! | [`panel`] | the driver ([`PenMountPanel`]) |
//! | [`emulator`] | the emulated controller ([`PanelEmulator`]) |
//! | [`settings`] | `[devices.panel]` ([`PanelConfig`]) |
//!
//! The wire format is [`crate::protocols::penmount`].

pub mod emulator;
pub mod panel;
pub mod settings;

pub use emulator::PanelEmulator;
pub use panel::PenMountPanel;
pub use settings::PanelConfig;

use rigcal_core::rig::TablePanel;

use crate::devices::clock::SharedClock;
use crate::devices::drivers::kinds::{Emulated, PanelDriver};
use crate::devices::emulators::faults::PanelFaultHandle;
use crate::devices::emulators::physics::SharedPhysics;
use crate::devices::emulators::{ByteEmulator, SharedTable};
use crate::devices::keys::KeyError;
use crate::devices::traits::{DeviceError, Panel};
use crate::transports::ByteTransport;

/// The registry's entry for the PenMount panel.
#[derive(Debug, Clone, Copy)]
pub struct PenMount;

impl PanelDriver for PenMount {
    fn name(&self) -> &'static str {
        settings::DRIVER
    }

    fn check(&self, cfg: &PanelConfig) -> Result<(), KeyError> {
        cfg.validate()
    }

    fn open(
        &self,
        panel: &TablePanel,
        cfg: &PanelConfig,
        io: Box<dyn ByteTransport>,
        clock: SharedClock,
    ) -> Result<Box<dyn Panel>, DeviceError> {
        Ok(Box::new(PenMountPanel::new(
            io,
            panel.panel_size_mm,
            panel.panel_counts,
            cfg,
            clock,
        )))
    }

    fn emulator(
        &self,
        panel: &TablePanel,
        cfg: &PanelConfig,
        physics: SharedPhysics,
        table: SharedTable,
    ) -> Emulated<dyn ByteEmulator, PanelFaultHandle> {
        let e = PanelEmulator::new(panel, cfg, physics, table);
        Emulated {
            faults: e.faults(),
            emulator: Box::new(e),
        }
    }
}
