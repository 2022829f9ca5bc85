//! rigcal's foundation: what every other layer reads. No device I/O here, only files.
//!
//! Layers of the workspace (each crate uses only those before it; the compiler enforces it):
//! `rigcal-core` → `rigcal-model` → `rigcal-devices` → `rigcal-sim` → `rigcal-calibration` →
//! `rigcal-paper` → the `rigcal` binary.
//!
//! | module | holds |
//! |---|---|
//! | [`stats`] | distribution functions (F, χ²₃, erfc) and robust scales (median, MAD) |
//! | [`basis`] | smooth function bases (cubic B-splines, harmonics, Gaussian radial functions) linear in their coefficients |
//! | [`kinematics`] | the [`kinematics::Robot`] trait (pose map and measured point), serial chains, error parameters, IK, URDF |
//! | [`rig`] | rig files: chain, limits, calibration settings, instrument; the `[devices]` section kept for the devices layer |
//! | [`recording`] | measurement recordings, their sidecar, CSV import |

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod basis;
pub mod kinematics;
pub mod recording;
pub mod rig;
pub mod stats;
