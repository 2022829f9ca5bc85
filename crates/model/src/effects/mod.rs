//! One home per physics effect: each file holds, for one kind of non-geometric physics, its
//! simulated truth (what the simulated world adds), its scenario entry (the `[[effects]]` table
//! it is read from and written to), its diagnosis candidate (regressor columns, plain-language
//! explanation, reported parameters with σ) and, where a model file carries it, its model term
//! (the basis compensation undoes, with σ propagation).
//!
//! | file | truth | scenario entry | candidate | model term |
//! |---|---|---|---|---|
//! | [`trig_joint`] | eq. (6) joint errors | read | — | — |
//! | [`compliance`] | gravity compliance | read, written | yes | yes |
//! | [`backlash`] | lost motion | read, written | yes | yes |
//! | [`transmission`] | cyclic gear error | read, written | yes | yes |
//! | [`drift`] | warm-up drift | read, written | yes | — |
//! | [`table_scale`] | table axis scale | read | yes | — |
//! | [`table_squareness`] | table axes' squareness | read | yes | — |
//! | [`registration_offset`] | table registration | read | — (absorbed) | — |
//! | [`discrepancy`] | flagged smooth term | read, written | shapes (in the diagnosis) | — |
//!
//! The interfaces the effect files implement: [`kind`] ([`EffectKind`]: the names), [`truth`]
//! ([`Effect`], called by `rigcal_sim::world` only), [`entry`] (scenario tables, the registry
//! entry), [`candidate`] ([`Candidate`] and the recording's [`Data`], used by
//! [`crate::diagnosis`]) and [`term`] ([`EffectContext`], used by [`crate::model::effects`]).
//! [`registry`] ties the kinds to their files. The world's motion history, instrument and
//! scenario files stay in `rigcal_sim::world`; a truth sees only what [`JointContext`] gives it.
//!
//! Adding an effect: its file here (with a `mod` line below), its variant in [`kind`] and its
//! line in [`registry`] (the compiler asks for it); the scenario reader and the diagnosis then
//! know it. The enum is apart from the registry so that no effect file imports a file that
//! imports it. Two vocabularies stay lists of their own: a model file carries only the kinds of
//! [`crate::model::effects::EffectSpec`] and [`crate::model::effects::ModelEffect`] (its file
//! format), and the twin writes only the kinds it maps (`rigcal_sim::twin::learn`).
//!
//! Units: radians and millimetres inside; degrees and millimetres in files.

pub mod backlash;
pub mod candidate;
pub mod compliance;
pub mod discrepancy;
pub mod drift;
pub mod entry;
pub mod kind;
pub mod registration_offset;
pub mod registry;
pub mod table_scale;
pub mod table_squareness;
pub mod term;
pub mod transmission;
pub mod trig_joint;
pub mod truth;

pub use backlash::Backlash;
pub use candidate::{Candidate, Data, Index, Param, AXES};
pub use compliance::{JointCompliance, PointMass};
pub use discrepancy::Discrepancy;
pub use drift::{DriftTarget, ThermalDrift};
pub use entry::{float, setup_rng, EntryError, Masses, NewEffect, ParseCtx};
pub use kind::EffectKind;
pub use registration_offset::RegistrationOffset;
pub use registry::{candidates, parse_effect};
pub use table_scale::TableScale;
pub use table_squareness::TableSquareness;
pub use term::EffectContext;
pub use transmission::{Harmonic, TransmissionError};
pub use trig_joint::{error_split, fig6_path, ErrorSplit, TrigJointErrors};
pub use truth::{Effect, JointContext, TableMap};
