//! What the emulators ask of the simulated world, and a nominal implementation.
//!
//! Frames and units: world frame of the rig file (mm); table positions are the panel centre in
//! the table frame (mm); joint values in radians; times on the emulators' [`Clock`](crate::devices::clock::Clock).
//! The emulators never look inside the world: the arm emulator tells it what was commanded and
//! when the motion ends, the panel emulator asks where the pin tip really is and where the panel
//! centre really is for a table position.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use nalgebra::Vector3;

use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain};
use rigcal_core::rig::{Instrument, Rig};

/// The pin as it really is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinState {
    /// Tip position (world mm).
    pub tip_mm: Vector3<f64>,
    /// Pin direction (world, unit).
    pub direction: Vector3<f64>,
}

/// The pin's recent states with the times they were reached. The panel emulator evaluates
/// contacts lazily, possibly for moments before the latest arm command arrived, so `at(t)` is
/// the state of the last command arrived by `t` (before the first arrival: the first state).
#[derive(Debug, Clone, Default)]
pub struct PinTimeline {
    states: std::collections::VecDeque<(Duration, PinState)>,
}

impl PinTimeline {
    /// The arm reaches `pin` at `arrive` (commands arrive in time order).
    pub fn push(&mut self, arrive: Duration, pin: PinState) {
        self.states.push_back((arrive, pin));
        if self.states.len() > super::HISTORY {
            self.states.pop_front();
        }
    }

    /// The pin at `t`; `None` before any command.
    pub fn at(&self, t: Duration) -> Option<PinState> {
        self.states
            .iter()
            .rev()
            .find(|(arrive, _)| *arrive <= t)
            .or(self.states.front())
            .map(|(_, p)| *p)
    }
}

/// The simulated world as the emulators see it.
pub trait RigPhysics: Send {
    /// The arm was commanded to joint values `q` (rad, as the controller executes them); the
    /// motion ends at `t_arrive`.
    fn arm_commanded(&mut self, q: &[f64], t_arrive: Duration);
    /// The true pin tip and direction at time `t`; `None` before any command.
    fn pin(&self, t: Duration) -> Option<PinState>;
    /// The true panel centre (world mm) when the table's axes stand at `table_mm` (table frame).
    fn panel_centre_world(&self, table_mm: Vector3<f64>) -> Vector3<f64>;
    /// What a point sensor reads at time `t` (sensor frame, mm): the true tip plus the
    /// instrument's noise; `None` before any command. Without noise, the tip itself.
    fn sensor_reading(&self, t: Duration) -> Option<Vector3<f64>> {
        self.pin(t).map(|p| p.tip_mm)
    }
}

impl std::fmt::Debug for dyn RigPhysics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("RigPhysics")
    }
}

/// The handle the three emulators share.
pub type SharedPhysics = Arc<Mutex<dyn RigPhysics>>;

/// The rig's nominal chain with given true geometric errors, a perfect table at the nominal
/// registration, and an arm that jumps to its target when the motion ends.
#[derive(Debug, Clone)]
pub struct NominalPhysics {
    chain: SerialChain,
    truth: ErrorParams,
    table_to_world: Vector3<f64>,
    pin_axis: Vector3<f64>,
    pins: PinTimeline,
}

impl NominalPhysics {
    /// From a rig and the arm's true error parameters.
    pub fn new(rig: &Rig, truth: ErrorParams) -> Self {
        let (table_to_world, pin_axis) = match &rig.instrument {
            Instrument::TablePanel(t) => (t.table_to_world_mm, t.pin_axis),
            _ => (Vector3::zeros(), Vector3::x()),
        };
        NominalPhysics {
            chain: rig.chain.clone(),
            truth,
            table_to_world,
            pin_axis,
            pins: PinTimeline::default(),
        }
    }

    /// A rig's arm without errors.
    pub fn nominal(rig: &Rig) -> Self {
        NominalPhysics::new(rig, ErrorParams::zeros(rig.chain.layout()))
    }

    /// As a [`SharedPhysics`].
    pub fn shared(self) -> SharedPhysics {
        Arc::new(Mutex::new(self))
    }
}

impl RigPhysics for NominalPhysics {
    fn arm_commanded(&mut self, q: &[f64], t_arrive: Duration) {
        if q.len() != self.chain.dof() {
            return;
        }
        let pose = self.chain.tool_pose(q, &self.truth);
        let pin = PinState {
            tip_mm: self.chain.position(q, &self.truth),
            direction: pose.rotation * self.pin_axis,
        };
        self.pins.push(t_arrive, pin);
    }

    fn pin(&self, t: Duration) -> Option<PinState> {
        self.pins.at(t)
    }

    fn panel_centre_world(&self, table_mm: Vector3<f64>) -> Vector3<f64> {
        table_mm + self.table_to_world
    }
}
