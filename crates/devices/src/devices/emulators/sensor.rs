//! A simulated point sensor (laser tracker, motion capture, or the papers' ideal instrument).
//!
//! No tracker protocol is implemented yet, so this back-end implements [`PointSensor`] directly
//! instead of speaking bytes to a driver: it waits its latency on the shared clock and reads the
//! physics' [`RigPhysics::sensor_reading`](super::physics::RigPhysics::sensor_reading) — the
//! marker as the world has it, in the sensor's frame, with the instrument's noise. A real
//! tracker's driver implements the same trait, and the session cannot tell them apart.

use std::time::Duration;

use crate::devices::clock::SharedClock;
use crate::devices::emulators::{lock, SharedPhysics};
use crate::devices::traits::{DeviceError, DeviceName, PointSensor};

/// Settling and averaging time of one reading.
pub const SENSOR_LATENCY: Duration = Duration::from_millis(200);

/// A point sensor reading a simulated world.
#[derive(Debug)]
pub struct SimPointSensor {
    physics: SharedPhysics,
    clock: SharedClock,
    latency: Duration,
}

impl SimPointSensor {
    /// A sensor on `physics`, timed by `clock`.
    pub fn new(physics: SharedPhysics, clock: SharedClock) -> Self {
        SimPointSensor {
            physics,
            clock,
            latency: SENSOR_LATENCY,
        }
    }
}

impl PointSensor for SimPointSensor {
    fn read(&mut self, timeout: Duration) -> Result<[f64; 3], DeviceError> {
        let wait = self.latency.min(timeout);
        self.clock.sleep(wait);
        let now = self.clock.now();
        match lock(&self.physics).sensor_reading(now) {
            Some(p) if wait >= self.latency => Ok([p.x, p.y, p.z]),
            _ => Err(DeviceError::Timeout {
                device: DeviceName::Sensor,
                waiting_for: "a marker reading".into(),
                waited: wait,
                target: "the marker on the last link".into(),
                current: "no reading (marker not seen yet, or the timeout is shorter than the sensor's latency)".into(),
            }),
        }
    }

    fn latency(&self) -> Duration {
        self.latency
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::devices::clock::VirtualClock;
    use crate::devices::emulators::physics::NominalPhysics;
    use rigcal_core::kinematics::{ErrorParams, Robot};
    use rigcal_core::rig::Rig;
    use std::sync::Arc;

    #[test]
    fn reads_the_nominal_tip_after_its_latency() {
        let rig = Rig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2-ideal.toml"
        )))
        .expect("rig");
        let q = vec![0.3, 0.9, -0.4, 0.0, 0.0];
        let physics = NominalPhysics::nominal(&rig).shared();
        let clock: SharedClock = Arc::new(VirtualClock::new());
        let mut s = SimPointSensor::new(Arc::clone(&physics), Arc::clone(&clock));
        assert!(matches!(
            s.read(Duration::from_secs(1)),
            Err(DeviceError::Timeout { .. })
        ));
        lock(&physics).arm_commanded(&q, clock.now());
        let p = s.read(Duration::from_secs(1)).expect("reading");
        let want = rig
            .chain
            .position(&q, &ErrorParams::zeros(rig.chain.layout()));
        assert!((nalgebra::Vector3::from(p) - want).norm() < 1e-9);
        assert!(
            s.read(Duration::from_millis(10)).is_err(),
            "timeout below the latency"
        );
    }
}
