//! What a session tells a rig besides device commands, behind one opaque trait object.
//!
//! A session cannot tell simulated devices from real ones, yet a dry run needs three things
//! the devices' protocols do not carry: which measurement's random draws the simulated world
//! uses next (conventions §7: draws are a function of seed, seq and attempt), the session's time
//! base (so a resumed session continues the world's time), and the world's state for the
//! journal (motion history for backlash and drift). The factory hands the session a
//! [`RigHook`] beside the devices: on the real rig it is [`NoHook`], which does nothing; on
//! emulators of a scenario's world it is the world's hook
//! (`rigcal_sim::emulation::WorldHook`, a layer above this one). The session journals
//! [`RigHook::snapshot`] as opaque JSON and gives it back on a resume.

/// A journalled snapshot the rig cannot take back.
#[derive(Debug, thiserror::Error)]
#[error("the journal's rig state cannot be restored: {reason}")]
pub struct HookError {
    /// Why.
    pub reason: String,
}

/// The session's side channel to the rig (see the module docs). Every method defaults to doing
/// nothing, as on the real rig.
pub trait RigHook: Send {
    /// The session is about to command the arm for measurement `seq`, attempt `attempt`.
    fn before_measurement(&mut self, _seq: u64, _attempt: u32) {}
    /// Session time (s) = the devices' clock (s) + `session_minus_clock_s` from now on.
    fn time_base(&mut self, _session_minus_clock_s: f64) {}
    /// The rig's state worth journalling (none on the real rig).
    fn snapshot(&self) -> Option<serde_json::Value> {
        None
    }
    /// Continues from a journalled [`RigHook::snapshot`].
    fn restore(&mut self, _snapshot: &serde_json::Value) -> Result<(), HookError> {
        Ok(())
    }
}

impl std::fmt::Debug for dyn RigHook {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("RigHook")
    }
}

/// The hook of real devices (and of emulators on a nominal world): nothing to tell them.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoHook;

impl RigHook for NoHook {}
