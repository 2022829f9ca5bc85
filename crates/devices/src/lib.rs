//! rigcal's rig: the bytes on the wire up to an automatic measurement session. Uses
//! `rigcal-core` and `rigcal-model` (registration, division regions); knows nothing of the
//! simulated world: a dry run's world reaches a session only through the opaque
//! [`devices::RigHook`].
//!
//! | module | holds |
//! |---|---|
//! | [`protocols`] | pure codecs: Movemaster, CANopen/CiA 402, slcan, PenMount |
//! | [`transports`] | bytes and frames: serial ports, slcan, SocketCAN, an in-process bus |
//! | [`devices`] | the `[devices]` section, arm, table and panel drivers by registry with their emulators, safety wrappers, the factory |
//! | [`config`] | [`devices::config`] under its short path |
//! | [`session`] | automatic measurement sessions: plan, run (tokio), journal and resume |

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod devices;
pub mod protocols;
pub mod session;
pub mod transports;

pub use devices::config;
