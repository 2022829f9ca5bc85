//! The papers rigcal builds on, as experiments: not the calibration tool itself.
//!
//! | module | holds |
//! |---|---|
//! | [`paper_regime`] | seed 000, section 6: Figs. 6, 7 and 8 in the paper's regime |
//! | [`sec7`] | seed 000, section 7: the experiment on the (emulated) rig |
//! | [`reproduce`] | seed 001: the papers' robots, their other schemes and tables, beside the papers' numbers (`rigcal reproduce`) |

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod paper_regime;
pub mod reproduce;
pub mod sec7;
