//! rigcal's simulated world: the truth a dry run measures. Read only by simulators, the
//! emulators' world hook and the digital twin; no session or identification depends on it.
//!
//! | module | holds |
//! |---|---|
//! | [`world`] | scenarios: the simulated truth (geometry, physics effects, instrument), simulated recordings |
//! | [`emulation`] | the emulators' physics on a scenario's world, and a rig opened on it |
//! | [`twin`] | the digital twin: a scenario compared with a recording point by point, diagnosed and rewritten; hybrid-compensated paths in a simulated world |

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod emulation;
pub mod twin;
pub mod world;
