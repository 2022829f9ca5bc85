//! rigcal: robot calibration.
pub mod protocols;
pub mod transports;
