//! The papers rigcal builds on, as experiments: not the calibration tool itself.
//!
//! | module | holds |
//! |---|---|
//! | [`preset`] | seed 000's settings, each with the section of the paper it comes from |
//! | [`paper_regime`] | seed 000, section 6: Figs. 6, 7 and 8 in the paper's regime |
//! | [`sec7`] | seed 000, section 7: the experiment on the (emulated) rig |
//! | [`demo`] | `rigcal demo`: sections 6 and 7 at the preset's settings, the summary |
//! | [`extras`] | what the paper has and the demo lacked: CMAC and FCMAC on equal training, ten paths (the noise run's σ is [`paper_regime::noise_sigma_mm`], the rig's CEP plot [`sec7::rig_cep_plot`]) |
//! | [`seeds`] | `rigcal demo --seeds`: section 6's claims over many seeds, pass rates, medians, worst |
//! | [`reproduce`] | seed 001: the papers' robots, their other schemes and tables, beside the papers' numbers (`rigcal reproduce`) |

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod demo;
pub mod extras;
pub mod paper_regime;
pub mod preset;
pub mod reproduce;
pub mod sec7;
pub mod seeds;
