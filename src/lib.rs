//! rigcal drives a robot-calibration measurement rig and turns what it measures into an accurate
//! robot (seed 000: variable D-H parameter model with FCMAC).
//!
//! Data flows one way: devices → recordings → model → report.
//!
//! | module | holds |
//! |---|---|
//! | [`rig`] | rig files: chain, limits, calibration settings, instrument |
//! | [`kinematics`] | the [`kinematics::Robot`] trait (pose map and measured point), serial chains, error parameters, IK |
//! | [`recording`] | measurement recordings and their sidecar |
//! | [`stats`] | distribution functions (F, χ²₃, erfc) and robust scales (median, MAD) |
//! | [`identification`] | identifiability, least squares, registration |
//! | [`compensation`] | joint commands that bring the modelled arm to a target |
//! | [`calibration`] | the variable D-H pipeline (division → learner → model), its evaluation along paths, the comparison with conventional and neural calibration |
//! | [`model`] | the versioned model file |
//! | [`neural`] | neuro-kinematic calibration (seed 001): the network, schemes 2 and 4, a network as a rig's error model |
//! | [`world`] | the simulated truth (read only by simulators and emulators) |
//! | [`protocols`] | pure codecs: Movemaster, CANopen/CiA 402, slcan, PenMount |
//! | [`transports`] | bytes and frames: serial ports, slcan, SocketCAN, an in-process bus |
//! | [`devices`] | arm, table and panel drivers, their emulators, safety wrappers, the factory |
//! | [`reproduce`] | not the calibration tool: the papers' robots, their other schemes and tables, beside the papers' numbers (`rigcal reproduce`) |
pub mod calibration;
pub mod cli;
pub mod compensation;
pub mod devices;
pub mod diagnosis;
pub mod division;
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
pub mod world;
