//! What every simulated back-end shares: an emulator speaks its device's protocol byte for byte
//! (or frame for frame), takes its physics from a [`RigPhysics`], and keeps time on a
//! [`Clock`](crate::devices::clock::Clock). The emulators themselves live with their drivers
//! ([`crate::devices::drivers`]); a simulated point sensor, which speaks no protocol yet, here.
//!
//! Each emulator is a state machine fed with input at a time and asked for the output due at a
//! time ([`ByteEmulator`], [`FrameEmulator`]). Two ways to run one:
//! - **polled** behind [`PolledSerial`] / [`PolledCan`]: the driver's own reads drive the
//!   emulator; while the driver waits, the link advances the clock to the emulator's next event
//!   (or to the end of the timeout). On a [`VirtualClock`](crate::devices::clock::VirtualClock)
//!   this is a deterministic discrete-event simulation; on real time it sleeps.
//! - **served** in a thread behind any [`ByteTransport`] (a pseudo-terminal, a pipe) with
//!   [`serve_bytes`], or behind a [`CanBus`] with [`serve_frames`]; the table speaks slcan on a
//!   byte transport through [`SlcanAdapter`].
//!
//! Fault injection is per emulator, through its shared handle of the device kind's
//! [`faults`].

pub mod faults;
pub mod physics;
pub mod sensor;

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use nalgebra::Vector3;

use crate::devices::clock::SharedClock;
use crate::protocols::can::CanFrame;
use crate::protocols::slcan::{SlcanDecoder, SlcanMessage};
use crate::transports::{ByteTransport, CanBus, TransportError};

pub use crate::devices::profile::Profile;
pub use physics::{NominalPhysics, PinState, RigPhysics, SharedPhysics};

/// An emulated byte-stream device.
pub trait ByteEmulator: Send + std::fmt::Debug {
    /// Bytes from the host, received at `now`.
    fn input(&mut self, bytes: &[u8], now: Duration);
    /// Bytes due for the host at or before `now`.
    fn output(&mut self, now: Duration) -> Vec<u8>;
    /// The earliest time after `now`, not later than `horizon`, at which output may become due.
    fn next_event(&mut self, now: Duration, horizon: Duration) -> Option<Duration>;
}

/// An emulated CAN device (or several on one bus).
pub trait FrameEmulator: Send + std::fmt::Debug {
    /// A frame from the bus, received at `now`.
    fn input(&mut self, frame: &CanFrame, now: Duration);
    /// Frames due on the bus at or before `now`.
    fn output(&mut self, now: Duration) -> Vec<CanFrame>;
    /// The earliest time after `now`, not later than `horizon`, at which output may become due.
    fn next_event(&mut self, now: Duration, horizon: Duration) -> Option<Duration>;
}

impl<E: ByteEmulator + ?Sized> ByteEmulator for Box<E> {
    fn input(&mut self, bytes: &[u8], now: Duration) {
        (**self).input(bytes, now)
    }
    fn output(&mut self, now: Duration) -> Vec<u8> {
        (**self).output(now)
    }
    fn next_event(&mut self, now: Duration, horizon: Duration) -> Option<Duration> {
        (**self).next_event(now, horizon)
    }
}

impl<E: FrameEmulator + ?Sized> FrameEmulator for Box<E> {
    fn input(&mut self, frame: &CanFrame, now: Duration) {
        (**self).input(frame, now)
    }
    fn output(&mut self, now: Duration) -> Vec<CanFrame> {
        (**self).output(now)
    }
    fn next_event(&mut self, now: Duration, horizon: Duration) -> Option<Duration> {
        (**self).next_event(now, horizon)
    }
}

/// Locks a mutex, ignoring poisoning (the data stays usable for simulations).
pub fn lock<T: ?Sized>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The smallest step the links take so that a zero-length event never stalls them.
const MIN_STEP: Duration = Duration::from_micros(1);

/// A [`ByteTransport`] whose far end is an emulator, driven by the reads.
#[derive(Debug)]
pub struct PolledSerial<E: ByteEmulator> {
    emulator: E,
    clock: SharedClock,
    pending: VecDeque<u8>,
}

impl<E: ByteEmulator> PolledSerial<E> {
    /// Connects to `emulator` on `clock`.
    pub fn new(emulator: E, clock: SharedClock) -> Self {
        PolledSerial {
            emulator,
            clock,
            pending: VecDeque::new(),
        }
    }
}

impl<E: ByteEmulator> ByteTransport for PolledSerial<E> {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.emulator.input(bytes, self.clock.now());
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, TransportError> {
        if buf.is_empty() {
            return Ok(0);
        }
        let start = self.clock.now();
        let deadline = start + timeout;
        loop {
            let now = self.clock.now();
            self.pending.extend(self.emulator.output(now));
            if !self.pending.is_empty() {
                let n = buf.len().min(self.pending.len());
                for (slot, b) in buf.iter_mut().zip(self.pending.drain(..n)) {
                    *slot = b;
                }
                return Ok(n);
            }
            if now >= deadline {
                return Err(TransportError::Timeout {
                    waited: now.saturating_sub(start),
                });
            }
            match self.emulator.next_event(now, deadline) {
                Some(t) if t <= deadline => self.clock.advance_to(t.max(now + MIN_STEP)),
                _ => self.clock.advance_to(deadline),
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        let now = self.clock.now();
        self.emulator.output(now);
        self.pending.clear();
        Ok(())
    }
}

/// A [`CanBus`] whose other nodes are an emulator, driven by the receives.
#[derive(Debug)]
pub struct PolledCan<E: FrameEmulator> {
    emulator: E,
    clock: SharedClock,
    pending: VecDeque<CanFrame>,
}

impl<E: FrameEmulator> PolledCan<E> {
    /// Connects to `emulator` on `clock`.
    pub fn new(emulator: E, clock: SharedClock) -> Self {
        PolledCan {
            emulator,
            clock,
            pending: VecDeque::new(),
        }
    }
}

impl<E: FrameEmulator> CanBus for PolledCan<E> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), TransportError> {
        self.emulator.input(frame, self.clock.now());
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<CanFrame, TransportError> {
        let start = self.clock.now();
        let deadline = start + timeout;
        loop {
            let now = self.clock.now();
            self.pending.extend(self.emulator.output(now));
            if let Some(f) = self.pending.pop_front() {
                return Ok(f);
            }
            if now >= deadline {
                return Err(TransportError::Timeout {
                    waited: now.saturating_sub(start),
                });
            }
            match self.emulator.next_event(now, deadline) {
                Some(t) if t <= deadline => self.clock.advance_to(t.max(now + MIN_STEP)),
                _ => self.clock.advance_to(deadline),
            }
        }
    }
}

/// A running emulator thread; stops (and is joined) when dropped.
#[derive(Debug)]
pub struct Served {
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
}

impl Served {
    /// Asks the thread to stop and waits for it.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Longest a serving thread sleeps between looks at its stop flag and its clock.
const SERVE_TICK: Duration = Duration::from_millis(1);

/// Serves `emulator` on `io` (a pseudo-terminal, a pipe) in a thread, on real time.
pub fn serve_bytes<E, T>(mut emulator: E, mut io: T, clock: SharedClock) -> Served
where
    E: ByteEmulator + 'static,
    T: ByteTransport + 'static,
{
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let handle = std::thread::spawn(move || {
        let mut buf = [0u8; 256];
        while !flag.load(Ordering::SeqCst) {
            let now = clock.now();
            let out = emulator.output(now);
            if !out.is_empty() && io.write_all(&out).is_err() {
                return;
            }
            let wait = emulator
                .next_event(now, now + SERVE_TICK)
                .map_or(SERVE_TICK, |t| t.saturating_sub(now).min(SERVE_TICK));
            match io.read(&mut buf, wait) {
                Ok(n) => emulator.input(buf.get(..n).unwrap_or(&[]), clock.now()),
                Err(TransportError::Timeout { .. }) => {}
                Err(_) => return,
            }
        }
    });
    Served {
        stop,
        handle: Some(handle),
    }
}

/// Serves `emulator` on a CAN bus (e.g. a [`SimBusEndpoint`](crate::transports::SimBusEndpoint))
/// in a thread, on real time.
pub fn serve_frames<E, B>(mut emulator: E, mut bus: B, clock: SharedClock) -> Served
where
    E: FrameEmulator + 'static,
    B: CanBus + 'static,
{
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let handle = std::thread::spawn(move || {
        while !flag.load(Ordering::SeqCst) {
            let now = clock.now();
            for f in emulator.output(now) {
                if bus.send(&f).is_err() {
                    return;
                }
            }
            let wait = emulator
                .next_event(now, now + SERVE_TICK)
                .map_or(SERVE_TICK, |t| t.saturating_sub(now).min(SERVE_TICK));
            match bus.recv(wait) {
                Ok(f) => emulator.input(&f, clock.now()),
                Err(TransportError::Timeout { .. }) => {}
                Err(_) => return,
            }
        }
    });
    Served {
        stop,
        handle: Some(handle),
    }
}

/// An slcan USB-CAN adapter with the emulated drives behind it: decodes the host's slcan lines,
/// answers commands (`O`, `C`, `Sn`, `V`, `F`, `Zn`) with OK, passes frames to the drives
/// (acknowledging each with `z\r`), and encodes the drives' frames as slcan lines.
#[derive(Debug)]
pub struct SlcanAdapter<E: FrameEmulator> {
    drives: E,
    decoder: SlcanDecoder,
    open: bool,
    out: Vec<u8>,
}

impl<E: FrameEmulator> SlcanAdapter<E> {
    /// An adapter (channel closed) in front of `drives`.
    pub fn new(drives: E) -> Self {
        SlcanAdapter {
            drives,
            decoder: SlcanDecoder::default(),
            open: false,
            out: Vec::new(),
        }
    }
}

impl<E: FrameEmulator> ByteEmulator for SlcanAdapter<E> {
    fn input(&mut self, bytes: &[u8], now: Duration) {
        for msg in self.decoder.push(bytes) {
            let reply = match msg {
                Ok(SlcanMessage::Frame { frame, .. }) if self.open => {
                    self.drives.input(&frame, now);
                    SlcanMessage::TransmitAck {
                        extended: frame.is_extended(),
                    }
                }
                Ok(SlcanMessage::Open) => {
                    self.open = true;
                    SlcanMessage::Ok
                }
                Ok(SlcanMessage::Close) => {
                    self.open = false;
                    SlcanMessage::Ok
                }
                Ok(SlcanMessage::SetBitrate(_)) if !self.open => SlcanMessage::Ok,
                Ok(SlcanMessage::SetTimestamps(_)) => SlcanMessage::Ok,
                Ok(SlcanMessage::ReadVersion) => SlcanMessage::Version(*b"1010"),
                Ok(SlcanMessage::ReadStatusFlags) => SlcanMessage::StatusFlags(0),
                _ => SlcanMessage::Error,
            };
            self.out.extend(reply.encode());
        }
    }

    fn output(&mut self, now: Duration) -> Vec<u8> {
        let mut out = std::mem::take(&mut self.out);
        for f in self.drives.output(now) {
            if self.open {
                out.extend(SlcanMessage::frame(f).encode());
            }
        }
        out
    }

    fn next_event(&mut self, now: Duration, horizon: Duration) -> Option<Duration> {
        if !self.out.is_empty() {
            return Some(now);
        }
        self.drives.next_event(now, horizon)
    }
}

/// The table's true axis motion, shared by the table emulator (which writes it) and the panel
/// emulator (which reads where the panel is). Table frame, mm.
///
/// The panel emulator evaluates contacts lazily, for moments that may lie before the table's
/// latest move began, so each axis keeps its recent profiles: the position at `t` comes from the
/// last profile started at or before `t`.
///
/// It also carries the panel controller's touch output as the drives' touch-probe inputs see
/// it ([`TouchEdge`]): the panel emulator records each contact's start, the drives latch from
/// it (CiA 402 touch probe, `[devices.table] touch_probe`). The emulated wiring reaches every
/// drive's probe 1 input; the driver uses the z drive's.
#[derive(Debug, Clone)]
pub struct TableTruth {
    /// Per axis x, y, z: the current profile.
    pub axes: [Profile; 3],
    /// Per axis, earlier profiles (oldest first), at most [`HISTORY`] of them.
    past: [VecDeque<Profile>; 3],
    /// The touch output's recent positive edges (oldest first), at most [`HISTORY`] of them.
    touches: VecDeque<TouchEdge>,
}

/// A positive edge of the panel controller's touch output: the moment the pin touched, on the
/// emulators' clock, and where the table stood then (mm, table frame). The z is the exact
/// contact height of the world (where the true panel centre rises to the true pin tip), found
/// from the geometry, not from when anyone looked: it is the same whatever the bus, panel or
/// pseudo-terminal latencies, in-process and served alike.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TouchEdge {
    /// When the contact began (emulators' clock).
    pub at: Duration,
    /// The table's position then (mm, table frame).
    pub table_mm: [f64; 3],
}

/// Motions an emulated device remembers for lazily evaluated past moments.
pub const HISTORY: usize = 64;

impl TableTruth {
    /// Standing at `p`.
    pub fn at(p: [f64; 3]) -> Self {
        TableTruth {
            axes: [
                Profile::still(p[0]),
                Profile::still(p[1]),
                Profile::still(p[2]),
            ],
            past: Default::default(),
            touches: VecDeque::new(),
        }
    }

    /// The touch output rose: a contact began (the panel emulator calls this).
    pub fn touch_began(&mut self, edge: TouchEdge) {
        self.touches.push_back(edge);
        if self.touches.len() > HISTORY {
            self.touches.pop_front();
        }
    }

    /// The touch output's first positive edge after `after` and not after `until`: what a
    /// probe armed at `after` has latched by `until`.
    pub fn first_touch(&self, after: Duration, until: Duration) -> Option<TouchEdge> {
        self.touches
            .iter()
            .find(|e| e.at > after && e.at <= until)
            .copied()
    }

    /// Starts `profile` on `axis` (0 x, 1 y, 2 z), keeping the current one for past moments.
    pub fn start(&mut self, axis: usize, profile: Profile) {
        if let (Some(slot), Some(past)) = (self.axes.get_mut(axis), self.past.get_mut(axis)) {
            past.push_back(std::mem::replace(slot, profile));
            if past.len() > HISTORY {
                past.pop_front();
            }
        }
    }

    fn axis_at(&self, axis: usize, t: Duration) -> f64 {
        let current = &self.axes[axis];
        if t >= current.t0 {
            return current.position(t);
        }
        self.past[axis]
            .iter()
            .rev()
            .find(|p| p.t0 <= t)
            .or(self.past[axis].front())
            .unwrap_or(current)
            .position(t)
    }

    /// The table position at `t` (mm).
    pub fn position(&self, t: Duration) -> Vector3<f64> {
        Vector3::new(self.axis_at(0, t), self.axis_at(1, t), self.axis_at(2, t))
    }
}

/// The shared [`TableTruth`].
pub type SharedTable = Arc<Mutex<TableTruth>>;
