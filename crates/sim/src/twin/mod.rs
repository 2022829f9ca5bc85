//! The digital twin (issue 18 items 4 and 5): a scenario compared with a recording point by
//! point, the difference diagnosed, and the scenario rewritten with what was found
//! ([`learn`](mod@learn)); hybrid-compensated paths measured in a simulated world ([`hybrid`]).
//!
//! This is the one place where recordings meet the simulated world outside the simulators:
//! the diagnosis and compensation it calls see only recordings, rig files and model files.

pub mod hybrid;
pub mod learn;

pub use learn::{learn, model_with_named_effects, Twin, TwinError, TwinOptions};
