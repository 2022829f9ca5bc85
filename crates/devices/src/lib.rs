//! rigcal's rig: the bytes on the wire up to an automatic measurement session. Uses
//! `rigcal-core` and `rigcal-model` (registration, division regions); knows nothing of the
//! simulated world: a dry run's world reaches a session only through the opaque
//! [`devices::RigHook`].
//!
//! | module | holds |
//! |---|---|
//! | [`protocols`] | pure codecs: Movemaster, CANopen/CiA 402, slcan, PenMount |
//! | [`transports`] | bytes and frames: serial ports, slcan, SocketCAN, an in-process bus |
//! | [`config`] | the rig file's `[devices]` section, read for the drivers |
//! | [`devices`] | arm, table and panel drivers, their emulators, safety wrappers, the factory |
//! | [`session`] | automatic measurement sessions: plan, run (tokio), journal and resume |

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod config;
pub mod devices;
pub mod protocols;
pub mod session;
pub mod transports;
