//! Time for drivers and emulators: real time, or a shared virtual clock.
//!
//! Units: a clock reads a [`Duration`] since its own epoch (the clock's creation). Drivers measure
//! motion deadlines and poll intervals on the clock; emulators stamp every reply and every
//! physical event on it. With a [`VirtualClock`] nothing waits for real: whoever waits (a driver
//! polling, a simulated link waiting for the next emulator event) advances the clock, so a
//! five-second table move takes microseconds and a timeout fires at once — deterministically.
//!
//! An asynchronous wait that must not move the clock itself (the session's supervision task,
//! a timeout branch of a `select!`) registers a [`Waker`] with [`Clock::wake_at`]: the virtual
//! clock wakes it when some device's wait carries the clock past that moment.

use std::sync::{Arc, Mutex, PoisonError};
use std::task::Waker;
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
    /// Wakes `waker` once the clock reads `t` or later; true if registered. Only a virtual
    /// clock takes wakers: real time is waited on with the runtime's own timers.
    fn wake_at(&self, _t: Duration, _waker: &Waker) -> bool {
        false
    }
    /// The earliest moment a registered waker waits for (virtual clock only).
    fn next_wake(&self) -> Option<Duration> {
        None
    }
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
    state: Mutex<VirtualState>,
}

#[derive(Debug, Default)]
struct VirtualState {
    now: Duration,
    /// Wakers waiting for a moment, and the earliest of those moments (the common case of an
    /// advance with nothing due costs one comparison).
    timers: Vec<(Duration, Waker)>,
    earliest: Option<Duration>,
}

impl VirtualState {
    /// Sets the time and takes the wakers now due.
    fn set(&mut self, t: Duration) -> Vec<Waker> {
        self.now = t;
        match self.earliest {
            Some(e) if e <= t => {}
            _ => return Vec::new(),
        }
        let mut due = Vec::new();
        self.timers.retain(|(at, w)| {
            if *at <= t {
                due.push(w.clone());
                false
            } else {
                true
            }
        });
        self.earliest = self.timers.iter().map(|(at, _)| *at).min();
        due
    }
}

impl VirtualClock {
    /// A virtual clock at zero.
    pub fn new() -> Self {
        VirtualClock::default()
    }

    /// A virtual clock at `t` (e.g. continued from a session journal).
    pub fn starting_at(t: Duration) -> Self {
        VirtualClock {
            state: Mutex::new(VirtualState {
                now: t,
                ..VirtualState::default()
            }),
        }
    }

    /// As a [`SharedClock`].
    pub fn shared() -> SharedClock {
        Arc::new(VirtualClock::new())
    }

    fn state(&self) -> std::sync::MutexGuard<'_, VirtualState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl Clock for VirtualClock {
    fn now(&self) -> Duration {
        self.state().now
    }
    fn sleep(&self, d: Duration) {
        let due = {
            let mut s = self.state();
            let t = s.now + d;
            s.set(t)
        };
        due.into_iter().for_each(Waker::wake);
    }
    fn advance_to(&self, t: Duration) {
        let due = {
            let mut s = self.state();
            if t <= s.now {
                return;
            }
            s.set(t)
        };
        due.into_iter().for_each(Waker::wake);
    }
    fn is_virtual(&self) -> bool {
        true
    }
    fn next_wake(&self) -> Option<Duration> {
        self.state().earliest
    }
    fn wake_at(&self, t: Duration, waker: &Waker) -> bool {
        let mut s = self.state();
        if t <= s.now {
            drop(s);
            waker.wake_by_ref();
            return true;
        }
        // A wait polled again registers again: keep one entry per waker and moment.
        if !s
            .timers
            .iter()
            .any(|(at, w)| *at == t && w.will_wake(waker))
        {
            s.timers.push((t, waker.clone()));
            s.earliest = Some(s.earliest.map_or(t, |e| e.min(t)));
        }
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
    fn virtual_clock_wakes_registered_wakers_when_it_passes_their_moment() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        use std::task::Wake;
        struct Count(AtomicUsize);
        impl Wake for Count {
            fn wake(self: Arc<Self>) {
                self.0.fetch_add(1, Ordering::SeqCst);
            }
        }
        let count = Arc::new(Count(AtomicUsize::new(0)));
        let waker = Waker::from(Arc::clone(&count));
        let c = VirtualClock::new();
        assert!(c.wake_at(Duration::from_millis(10), &waker));
        assert!(
            c.wake_at(Duration::from_millis(10), &waker),
            "registered once"
        );
        c.sleep(Duration::from_millis(9));
        assert_eq!(count.0.load(Ordering::SeqCst), 0);
        c.advance_to(Duration::from_millis(10));
        assert_eq!(count.0.load(Ordering::SeqCst), 1);
        c.advance_to(Duration::from_millis(20));
        assert_eq!(count.0.load(Ordering::SeqCst), 1, "woken once");
        assert!(!RealClock::new().wake_at(Duration::ZERO, &waker));
    }

    #[test]
    fn real_clock_advances() {
        let c = RealClock::new();
        let a = c.now();
        c.sleep(Duration::from_millis(2));
        assert!(c.now() >= a + Duration::from_millis(2));
    }
}
