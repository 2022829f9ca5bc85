//! How asynchronous device waits run on each clock.
//!
//! The session's choreography runs on tokio ([`Pace::runtime`]), but the drivers stay
//! synchronous: a long wait (an arm move, a table move, an approach) is a loop of short device
//! calls, one *slice* each ([`Pace::slice_until`]), with a yield between slices so that the
//! other waits of the same `try_join!` or `select!` make progress too.
//!
//! - **Virtual clock** (a dry run): our own [`VirtualClock`](super::clock::VirtualClock), not
//!   tokio's paused clock. The emulators are discrete-event simulations driven by the drivers'
//!   reads, which advance the shared clock to the next event; tokio's clock knows nothing of
//!   them. So every device call runs inline on a current-thread runtime (without timers: a
//!   real-time wait there would be a bug, and panics), each slice advances the virtual clock by
//!   at most [`VIRTUAL_SLICE`] and never past the next moment another wait is due, and
//!   `select!` with `biased;` polls its branches in a fixed order:
//!   the same run, slice for slice, every time — which is what kill-and-resume and the
//!   byte-identical recordings rely on. A wait that must not move the clock (a timeout branch,
//!   the supervision task's period) is woken by the virtual clock when a device wait passes it.
//! - **Real time**: each device runs on its own thread behind a channel
//!   ([`DeviceActor`](super::actor::DeviceActor)); the same futures await those threads, and
//!   timeouts and periods are tokio timers.

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use crate::devices::clock::SharedClock;

/// Longest slice of a device wait on the virtual clock. A slice also ends where the next
/// timed wait is due (a supervision check, a timeout, another device's next look), so no wait
/// carries the clock past a moment another one is waiting for.
pub const VIRTUAL_SLICE: Duration = Duration::from_millis(100);
/// Longest slice of a device wait on real time: how long a device thread is busy with one
/// wait before it takes the next request (a halt, a supervision check).
const REAL_SLICE: Duration = Duration::from_millis(20);

/// The clock the devices keep, and how waits on it are made.
#[derive(Debug, Clone)]
pub struct Pace {
    clock: SharedClock,
    slice: Duration,
}

impl Pace {
    /// Waits on `clock` (virtual or real).
    pub fn new(clock: SharedClock) -> Self {
        let slice = if clock.is_virtual() {
            VIRTUAL_SLICE
        } else {
            REAL_SLICE
        };
        Pace { clock, slice }
    }

    /// The devices' clock.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// Time on the devices' clock.
    pub fn now(&self) -> Duration {
        self.clock.now()
    }

    /// True on a virtual clock.
    pub fn is_virtual(&self) -> bool {
        self.clock.is_virtual()
    }

    /// The longest slice of a wait.
    pub fn slice(&self) -> Duration {
        self.slice
    }

    /// The next slice of a wait: at most [`Pace::slice`], and on a virtual clock not past the
    /// next moment a timed wait is due.
    pub fn next_slice(&self) -> Duration {
        let now = self.now();
        match self.clock.next_wake() {
            Some(t) if t > now => self.slice.min(t - now),
            _ => self.slice,
        }
    }

    /// The next slice of a wait that ends at `deadline` (clock time): [`Pace::next_slice`],
    /// never past the deadline (zero once it has passed).
    pub fn slice_until(&self, deadline: Duration) -> Duration {
        deadline.saturating_sub(self.now()).min(self.next_slice())
    }

    /// Lets the other waits of the same task, and other tasks, run.
    pub async fn yield_now(&self) {
        tokio::task::yield_now().await;
    }

    /// Waits `d` with nothing else to watch (a retry's backoff): advances a virtual clock,
    /// sleeps on real time.
    pub async fn pause(&self, d: Duration) {
        if self.is_virtual() {
            self.clock.sleep(d);
            self.yield_now().await;
        } else {
            tokio::time::sleep(d).await;
        }
    }

    /// Waits until the clock reads `t` without moving it: on a virtual clock the devices' waits
    /// move it (and wake this one); on real time, a tokio timer.
    pub async fn until(&self, t: Duration) {
        if self.is_virtual() {
            VirtualUntil {
                clock: &self.clock,
                t,
            }
            .await;
        } else {
            tokio::time::sleep(t.saturating_sub(self.now())).await;
        }
    }

    /// The runtime for waits on this clock: current-thread without timers on a virtual clock
    /// (deterministic); one worker with timers and I/O on real time, so supervision runs while
    /// the session's own thread computes.
    pub fn runtime(&self) -> std::io::Result<tokio::runtime::Runtime> {
        if self.is_virtual() {
            tokio::runtime::Builder::new_current_thread().build()
        } else {
            tokio::runtime::Builder::new_multi_thread()
                .worker_threads(1)
                .thread_name("rigcal-session")
                .enable_all()
                .build()
        }
    }
}

/// Ready once a virtual clock reads `t`; woken by the clock.
struct VirtualUntil<'a> {
    clock: &'a SharedClock,
    t: Duration,
}

impl Future for VirtualUntil<'_> {
    type Output = ();

    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        if self.clock.now() >= self.t {
            return Poll::Ready(());
        }
        if !self.clock.wake_at(self.t, cx.waker()) {
            // Not a virtual clock after all: look again at the next turn rather than never.
            cx.waker().wake_by_ref();
        }
        Poll::Pending
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::devices::clock::VirtualClock;
    use std::sync::Arc;

    #[test]
    fn a_virtual_wait_ends_when_another_wait_carries_the_clock_past_it() {
        let clock: SharedClock = Arc::new(VirtualClock::new());
        let pace = Pace::new(Arc::clone(&clock));
        let rt = pace.runtime().expect("runtime");
        let order = rt.block_on(async {
            let timeout = async {
                pace.until(Duration::from_millis(25)).await;
                "timeout"
            };
            let work = async {
                loop {
                    // A device wait: one slice at a time.
                    clock.sleep(pace.slice_until(Duration::from_secs(1)));
                    pace.yield_now().await;
                }
            };
            tokio::select! {
                biased;
                t = timeout => t,
                () = work => "work",
            }
        });
        assert_eq!(order, "timeout");
        assert_eq!(
            clock.now(),
            Duration::from_millis(25),
            "the slice ends where the timeout is due"
        );
    }
}
