//! Reproductions of the papers rigcal is built on, beside the papers' numbers: the paper's
//! simulated robots, the schemes the product does not calibrate with, and the tables. Not part of
//! the calibration tool: nothing outside this tree (and the `rigcal reproduce` subcommand)
//! imports it; it uses the product's modules ([`rigcal_model::neural`], [`rigcal_core::kinematics`]) as a
//! user would.
//!
//! | module | holds |
//! |---|---|
//! | [`robots`] | seed 001's 2-DOF SCARA, Stewart platform and 3-DOF SCARA, nominal and simulated real |
//! | [`direct_schemes`] | seed 001's other direct schemes (1, 3, 5, 6, 7) for Table 5's comparison and Table 17 |
//! | [`evaluation`] | apparent and actual errors of a trained model, their statistics, FI (eq. 5) |
//! | [`seed001`] | Tables 4–8, 10–12, 16–18 and Fig. 7 |
//!
//! # Units
//! Millimetres and radians inside; millimetres in the printed tables (the Stewart platform's
//! orientation errors in mrad, as in the paper).

pub mod direct_schemes;
pub mod evaluation;
pub mod robots;
pub mod seed001;
