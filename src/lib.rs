//! rigcal drives a robot-calibration measurement rig and turns what it measures into an accurate
//! robot (seed 000: variable D-H parameter model with FCMAC).
//!
//! Data flows one way: devices → recordings → model → report. Each row names a module; a
//! module uses only those above it in its layer (the rig file and the low-level numerics
//! first, then devices and sessions, then the calibration pipelines, then reports and the CLI).
//!
//! | module | holds |
//! |---|---|
//! | [`stats`] | distribution functions (F, χ²₃, erfc) and robust scales (median, MAD) |
//! | [`basis`] | smooth function bases (cubic B-splines, harmonics, Gaussian radial functions) linear in their coefficients |
//! | [`kinematics`] | the [`kinematics::Robot`] trait (pose map and measured point), serial chains, error parameters, IK, URDF |
//! | [`rig`] | rig files: chain, limits, calibration settings, instrument, the `[devices]` settings |
//! | [`protocols`] | pure codecs: Movemaster, CANopen/CiA 402, slcan, PenMount |
//! | [`transports`] | bytes and frames: serial ports, slcan, SocketCAN, an in-process bus |
//! | [`world`] | the simulated truth (read only by simulators and emulators) |
//! | [`devices`] | arm, table and panel drivers, their emulators, safety wrappers, the factory |
//! | [`recording`] | measurement recordings, their sidecar, CSV import |
//! | [`session`] | automatic measurement sessions: plan, run (tokio), journal and resume |
//! | [`identification`] | identifiability, least squares, registration, outliers, `identify` |
//! | [`division`] | recursive workspace division, measurement-location selection, CEPs per region |
//! | [`learners`] | CMAC and FCMAC: CEPs generalised over the workspace |
//! | [`neural`] | neuro-kinematic calibration (seed 001): the network, schemes 2 and 4, a network as a rig's error model |
//! | [`model`] | the versioned model file |
//! | [`compensation`] | joint commands that bring the modelled arm to a target |
//! | [`calibration`] | the variable D-H pipeline (division → learner → model), its evaluation along paths, the comparison with conventional and neural calibration |
//! | [`diagnosis`] | what physics a recording shows beyond the geometry: noise floor, candidate effects, selection, report |
//! | [`twin`] | the digital twin: a scenario compared with a recording point by point, diagnosed and rewritten; hybrid-compensated paths in a simulated world |
//! | [`export`] | the calibrated URDF and a flat list of corrected joint offsets |
//! | [`report`] | evaluation along paths, tables and plots |
//! | [`reproduce`] | not the calibration tool: the papers' robots, their other schemes and tables, beside the papers' numbers (`rigcal reproduce`) |
//! | [`cli`] | the `rigcal` command line: one module per subcommand (clap), the only place that uses `anyhow` |

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod basis;
pub mod calibration;
pub mod cli;
pub mod compensation;
pub mod devices;
pub mod diagnosis;
pub mod division;
pub mod export;
pub mod identification;
pub mod kinematics;
pub mod learners;
pub mod model;
pub mod neural;
pub mod protocols;
pub mod recording;
pub mod report;
pub mod reproduce;
pub mod rig;
pub mod session;
pub mod stats;
pub mod transports;
pub mod twin;
pub mod world;
