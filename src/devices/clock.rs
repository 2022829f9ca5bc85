//! Time for drivers and emulators: real time, or a shared virtual clock.
//!
//! Units: a clock reads a [`Duration`] since its own epoch (the clock's creation). Drivers measure
//! motion deadlines and poll intervals on the clock; emulators stamp every reply and every
//! physical event on it. With a [`VirtualClock`] nothing waits for real: whoever waits (a driver
//! polling, a simulated link waiting for the next emulator event) advances the clock, so a
//! five-second table move takes microseconds and a timeout fires at once — deterministically.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

/// A source of time that can also be waited on.
pub trait Clock: Send + Sync + std::fmt::Debug {
    /// Time since the clock's epoch.
    fn now(&self) -> Duration;
    /// Waits `d` (real clock) or advances the clock by `d` (virtual clock).
    fn sleep(&self, d: Duration);
    /// Waits until `t` (real) or sets the clock to `t` if it is later (virtual).
    fn advance_to(&self, t: Duration);
    /// True for a virtual clock.
    fn is_virtual(&self) -> bool;
}

/// A clock shared by drivers and emulators.
pub type SharedClock = Arc<dyn Clock>;

/// Wall-clock time (monotonic).
#[derive(Debug, Clone, Copy)]
pub struct RealClock {
    epoch: Instant,
}

impl RealClock {
    /// A real clock whose epoch is now.
    pub fn new() -> Self {
        RealClock {
            epoch: Instant::now(),
        }
    }

    /// As a [`SharedClock`].
    pub fn shared() -> SharedClock {
        Arc::new(RealClock::new())
    }
}

impl Default for RealClock {
    fn default() -> Self {
        RealClock::new()
    }
}

impl Clock for RealClock {
    fn now(&self) -> Duration {
        self.epoch.elapsed()
    }
    fn sleep(&self, d: Duration) {
        std::thread::sleep(d);
    }
    fn advance_to(&self, t: Duration) {
        let now = self.now();
        if t > now {
            std::thread::sleep(t - now);
        }
    }
    fn is_virtual(&self) -> bool {
        false
    }
}

/// A virtual clock: starts at zero and moves only when advanced.
#[derive(Debug, Default)]
pub struct VirtualClock {
    now: Mutex<Duration>,
}

impl VirtualClock {
    /// A virtual clock at zero.
    pub fn new() -> Self {
        VirtualClock::default()
    }

    /// A virtual clock at `t` (e.g. continued from a session journal).
    pub fn starting_at(t: Duration) -> Self {
        VirtualClock { now: Mutex::new(t) }
    }

    /// As a [`SharedClock`].
    pub fn shared() -> SharedClock {
        Arc::new(VirtualClock::new())
    }
}

impl Clock for VirtualClock {
    fn now(&self) -> Duration {
        *self.now.lock().unwrap_or_else(PoisonError::into_inner)
    }
    fn sleep(&self, d: Duration) {
        let mut now = self.now.lock().unwrap_or_else(PoisonError::into_inner);
        *now += d;
    }
    fn advance_to(&self, t: Duration) {
        let mut now = self.now.lock().unwrap_or_else(PoisonError::into_inner);
        if t > *now {
            *now = t;
        }
    }
    fn is_virtual(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn virtual_clock_moves_only_when_advanced() {
        let c = VirtualClock::new();
        assert_eq!(c.now(), Duration::ZERO);
        c.sleep(Duration::from_millis(5));
        c.advance_to(Duration::from_millis(3));
        assert_eq!(c.now(), Duration::from_millis(5));
        c.advance_to(Duration::from_secs(2));
        assert_eq!(c.now(), Duration::from_secs(2));
        assert!(c.is_virtual());
    }

    #[test]
    fn real_clock_advances() {
        let c = RealClock::new();
        let a = c.now();
        c.sleep(Duration::from_millis(2));
        assert!(c.now() >= a + Duration::from_millis(2));
    }
}
