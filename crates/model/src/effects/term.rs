//! The model term interface: what an effect needs to know about the arm when a model file
//! carries it (the fitted geometry, the link masses, the payload), so compensation can undo it.
//!
//! A model term is a joint error Δq_j = Σ_k c_k · b_k(q, s), linear in its coefficients c with
//! basis functions b of the commanded joints q and the approach directions s; each effect file
//! gives its basis, the model file ([`crate::model::effects`]) its coefficients.

use rigcal_core::kinematics::{ErrorParams, SerialChain};
use rigcal_core::rig::LinkMass;

/// What an effect needs to know about the arm: its chain and geometry, the link masses and the
/// payload.
#[derive(Debug, Clone, Copy)]
pub struct EffectContext<'a> {
    /// The chain.
    pub chain: &'a SerialChain,
    /// The geometric error parameters.
    pub e: &'a ErrorParams,
    /// The rig's link masses (see [`rigcal_core::rig::Rig::link_masses`]).
    pub masses: &'a [Option<LinkMass>],
    /// Payload at the tool frame's origin (kg).
    pub payload_kg: f64,
}
