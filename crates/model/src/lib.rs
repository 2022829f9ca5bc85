//! rigcal's calibration methods: from recordings to a model of the arm, and what that model
//! does. Uses only `rigcal-core`; knows nothing of devices or of the simulated world (each
//! effect's truth term is in [`effects`]; the world that runs them is `rigcal_sim::world`).
//!
//! Modules in layer order (a module uses only those above it):
//!
//! | module | holds |
//! |---|---|
//! | [`identification`] | identifiability, least squares, registration, outliers, `identify` |
//! | [`compensation`] | joint commands that bring the modelled arm to a target |
//! | [`division`] | recursive workspace division, measurement-location selection, CEPs per region |
//! | [`learners`] | CMAC and FCMAC: CEPs generalised over the workspace |
//! | [`neural`] | neuro-kinematic calibration (seed 001): the network, schemes 2 and 4, a network as a rig's error model |
//! | [`effects`] | one home per physics effect: its simulated truth, scenario entry, diagnosis candidate and model term; the effect kinds and their registry |
//! | [`model`] | the versioned model file, its effects and the hybrid compensation with them |
//! | [`diagnosis`] | what physics a recording shows beyond the geometry: noise floor, candidate effects, selection, report; held-out sessions |
//! | [`export`] | the calibrated URDF and a flat list of corrected joint offsets |
//! | [`report`] | evaluation along paths, tables and plots |

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod compensation;
pub mod diagnosis;
pub mod division;
pub mod effects;
pub mod export;
pub mod identification;
pub mod learners;
pub mod model;
pub mod neural;
pub mod report;
