//! [`RigPhysics`] on a scenario's full truth: the emulators run on a [`World`] (geometry,
//! joint-space effects, drift, the table's true map) instead of the nominal arm.
//!
//! Each arm command becomes [`World::move_arm`] at the command's arrival time (so the motion
//! history sees every move, as on the rig), scattered by the arm's repeatability with the draws
//! of the measurement the session is about to take ([`WorldPhysics::set_draws`]): draws are a
//! function of (seed, seq, attempt) only (conventions §7). Times: the emulators' clock plus a
//! session time offset ([`WorldPhysics::set_time_offset`]), so a resumed session continues the
//! world's time where the journal left it. The session reaches all three only through
//! [`WorldHook`], the opaque [`RigHook`] the factory hands it.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use nalgebra::Vector3;

use crate::world::{MotionHistory, Scenario, World};
use rigcal_core::rig::{Instrument, Rig};
use rigcal_devices::devices::clock::VirtualClock;
use rigcal_devices::devices::emulators::lock;
use rigcal_devices::devices::emulators::physics::{
    PinState, PinTimeline, RigPhysics, SharedPhysics,
};
use rigcal_devices::devices::factory::{OpenedRig, SimClock, SimSetup, SimWorld};
use rigcal_devices::devices::hook::{HookError, RigHook};
use rigcal_devices::devices::DeviceError;

/// A [`World`] as the emulators' physics.
#[derive(Debug, Clone)]
pub struct WorldPhysics {
    world: World,
    pin_axis: Vector3<f64>,
    pins: PinTimeline,
    seq: u64,
    attempt: u32,
    time_offset_s: f64,
}

/// A shared handle to a [`WorldPhysics`] (coerces to [`SharedPhysics`]).
pub type SharedWorld = Arc<Mutex<WorldPhysics>>;

impl WorldPhysics {
    /// Wraps a world (usually [`Scenario::world`]).
    pub fn new(world: World) -> Self {
        let pin_axis = match world.instrument() {
            Instrument::TablePanel(tp) => tp.pin_axis,
            _ => Vector3::x(),
        };
        WorldPhysics {
            world,
            pin_axis,
            pins: PinTimeline::default(),
            seq: 0,
            attempt: 0,
            time_offset_s: 0.0,
        }
    }

    /// The world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The draws the next arm command's repeatability scatter uses: measurement `seq`, attempt
    /// `attempt`.
    pub fn set_draws(&mut self, seq: u64, attempt: u32) {
        self.seq = seq;
        self.attempt = attempt;
    }

    /// World time (s) = emulator clock (s) + `offset_s`.
    pub fn set_time_offset(&mut self, offset_s: f64) {
        self.time_offset_s = offset_s;
    }

    /// The world's motion history (for a session journal).
    pub fn snapshot(&self) -> MotionHistory {
        self.world.snapshot()
    }

    /// Continues from a stored motion history.
    pub fn restore(&mut self, history: MotionHistory) {
        self.world.restore(history);
    }

    /// As a shared handle.
    pub fn shared(self) -> SharedWorld {
        Arc::new(Mutex::new(self))
    }
}

impl RigPhysics for WorldPhysics {
    fn arm_commanded(&mut self, q: &[f64], t_arrive: Duration) {
        let t_s = (t_arrive.as_secs_f64() + self.time_offset_s).max(0.0);
        let arm = self.world.move_arm(q, t_s);
        let draws = self.world.draws(self.seq, self.attempt);
        let pin = PinState {
            tip_mm: self.world.scattered_tip(&arm, &draws),
            direction: arm.tool.rotation * self.pin_axis,
        };
        self.pins.push(t_arrive, pin);
    }

    fn pin(&self, t: Duration) -> Option<PinState> {
        self.pins.at(t)
    }

    fn panel_centre_world(&self, table_mm: Vector3<f64>) -> Vector3<f64> {
        self.world.panel_centre(&table_mm).unwrap_or(table_mm)
    }

    fn sensor_reading(&self, t: Duration) -> Option<Vector3<f64>> {
        // The same draws as the arm's scatter: a function of (seed, seq, attempt) only.
        let draws = self.world.draws(self.seq, self.attempt);
        self.pin(t)
            .map(|p| p.tip_mm + draws.noise * self.world.settings().noise_mm)
    }
}

/// A simulated rig running on `scenario`'s truth on a virtual clock, the table centred in x and
/// y at the bottom of z. Returns the setup and the world handle (draws, time base, motion
/// history).
pub fn setup_from_scenario(scenario: &Scenario) -> (SimSetup, SharedWorld) {
    let world = WorldPhysics::new(scenario.world()).shared();
    let mut setup = SimSetup::nominal(&scenario.rig);
    let physics: SharedPhysics = world.clone();
    setup.physics = physics;
    setup.clock = Arc::new(VirtualClock::new());
    (setup, world)
}

/// `scenario`'s world for the emulators, with the session's hook into it.
pub fn sim_world(scenario: &Scenario) -> SimWorld {
    let (setup, world) = setup_from_scenario(scenario);
    SimWorld {
        setup,
        hook: Box::new(WorldHook(world)),
    }
}

/// The rig's devices for a session: emulators on `scenario`'s world (on `clock`), or what the
/// rig file's `[devices]` says when there is no scenario ([`rigcal_devices::devices::open_rig`]).
/// The scenario must be for this rig (the caller checks names and instruments).
///
/// A rehearsal's rig file (`[devices] world`, written by `rigcal sim-device rig --pty
/// --write-rig`) also names the socket of the world behind its served emulators: the session's
/// hook is then that world's ([`RemoteHook`](rigcal_devices::devices::sim_device::RemoteHook)),
/// so draws, time base and motion history reach it as they reach an in-process world.
pub fn open_rig(
    rig: &Rig,
    scenario: Option<&Scenario>,
    clock: SimClock,
) -> Result<OpenedRig, DeviceError> {
    let mut opened = rigcal_devices::devices::open_rig(rig, scenario.map(sim_world), clock)?;
    if scenario.is_none() {
        if let Some(hook) = served_world_hook(rig, &opened)? {
            opened.hook = hook;
        }
    }
    Ok(opened)
}

/// The hook of the served world a rehearsal's rig file names, if it names one.
#[cfg(unix)]
fn served_world_hook(
    rig: &Rig,
    opened: &OpenedRig,
) -> Result<Option<Box<dyn RigHook>>, DeviceError> {
    use rigcal_devices::devices::sim_device::RemoteHook;
    let cfg = rigcal_devices::config::DevicesConfig::read(rig);
    let Some(path) = cfg.world else {
        return Ok(None);
    };
    let hook = RemoteHook::connect(
        std::path::Path::new(&path),
        Arc::clone(&opened.devices.clock),
    )
    .map_err(|e| DeviceError::Config {
        key: "devices.world".into(),
        reason: e.reason,
    })?;
    Ok(Some(Box::new(hook)))
}

/// No served worlds off Unix (emulators are served on pseudo-terminals only there).
#[cfg(not(unix))]
fn served_world_hook(
    rig: &Rig,
    _opened: &OpenedRig,
) -> Result<Option<Box<dyn RigHook>>, DeviceError> {
    match rigcal_devices::config::DevicesConfig::read(rig).world {
        Some(_) => Err(DeviceError::Config {
            key: "devices.world".into(),
            reason: "served simulated worlds (rehearsals) exist only on Unix".into(),
        }),
        None => Ok(None),
    }
}

/// The session's [`RigHook`] on a simulated world: draws, time base and motion history go to
/// the [`WorldPhysics`] the emulators share.
#[derive(Debug, Clone)]
pub struct WorldHook(pub SharedWorld);

impl RigHook for WorldHook {
    fn before_measurement(&mut self, seq: u64, attempt: u32) {
        lock(&self.0).set_draws(seq, attempt);
    }

    fn time_base(&mut self, session_minus_clock_s: f64) {
        lock(&self.0).set_time_offset(session_minus_clock_s);
    }

    fn snapshot(&self) -> Option<serde_json::Value> {
        // A motion history is plain numbers and maps: it always serialises.
        serde_json::to_value(lock(&self.0).snapshot()).ok()
    }

    fn restore(&mut self, snapshot: &serde_json::Value) -> Result<(), HookError> {
        let history: MotionHistory =
            serde_json::from_value(snapshot.clone()).map_err(|e| HookError {
                reason: format!("not a simulated world's motion history ({e})"),
            })?;
        lock(&self.0).restore(history);
        Ok(())
    }
}
