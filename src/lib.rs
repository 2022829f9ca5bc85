//! rigcal: robot calibration.
pub mod kinematics;
