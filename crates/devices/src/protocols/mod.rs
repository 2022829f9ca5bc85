//! Pure protocol codecs: bytes ⇄ typed messages, with no I/O and no clocks.
//!
//! Each sub-module names the protocol it implements, its framing and the
//! reference it follows:
//!
//! - [`can`]: the classic CAN 2.0A/2.0B data frame ([`can::CanFrame`]).
//! - [`movemaster`]: Mitsubishi Movemaster command language (RV-M1/RV-M2, RS-232).
//! - [`canopen`]: CANopen (CiA 301) NMT, heartbeat, expedited SDO, EMCY and the
//!   CiA 402 drive profile state machine.
//! - [`slcan`]: serial-line CAN (Lawicel ASCII protocol) spoken by USB-CAN adapters.
//! - [`penmount`]: PenMount 6000 serial touch controller packets.
//!
//! Transports that carry these bytes live in [`crate::transports`].

pub mod can;
pub mod canopen;
pub mod movemaster;
pub mod penmount;
pub mod slcan;
