//! In-process simulated CAN bus for tests and emulators.
//!
//! Framing: frames are passed as [`CanFrame`] values through channels; no
//! bit timing, arbitration or error frames are modelled. Reference: CAN
//! broadcast semantics — a frame sent by one endpoint is delivered to every
//! *other* endpoint, in send order per sender.

use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use super::{CanBus, TransportError};
use crate::protocols::can::CanFrame;

#[derive(Debug, Default)]
struct Hub {
    next_id: u64,
    endpoints: Vec<(u64, Sender<CanFrame>)>,
}

/// The bus hub. Clone it freely; all clones are the same bus.
#[derive(Debug, Clone, Default)]
pub struct SimBus {
    hub: Arc<Mutex<Hub>>,
}

impl SimBus {
    /// A new, empty bus.
    pub fn new() -> Self {
        SimBus::default()
    }

    /// Attaches a new node to the bus. It receives frames sent after this call.
    pub fn endpoint(&self) -> SimBusEndpoint {
        let (tx, rx) = mpsc::channel();
        let mut hub = self.hub.lock().unwrap_or_else(PoisonError::into_inner);
        let id = hub.next_id;
        hub.next_id += 1;
        hub.endpoints.push((id, tx));
        SimBusEndpoint {
            id,
            hub: Arc::clone(&self.hub),
            rx,
        }
    }

    /// Number of endpoints currently attached.
    pub fn endpoint_count(&self) -> usize {
        self.hub
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .endpoints
            .len()
    }
}

/// One node on a [`SimBus`]. Detaches itself when dropped.
#[derive(Debug)]
pub struct SimBusEndpoint {
    id: u64,
    hub: Arc<Mutex<Hub>>,
    rx: Receiver<CanFrame>,
}

impl CanBus for SimBusEndpoint {
    /// Delivers `frame` to every other endpoint; never blocks.
    fn send(&mut self, frame: &CanFrame) -> Result<(), TransportError> {
        let mut hub = self.hub.lock().unwrap_or_else(PoisonError::into_inner);
        let me = self.id;
        hub.endpoints
            .retain(|(id, tx)| *id == me || tx.send(*frame).is_ok());
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<CanFrame, TransportError> {
        let start = Instant::now();
        match self.rx.recv_timeout(timeout) {
            Ok(f) => Ok(f),
            Err(RecvTimeoutError::Timeout) => Err(TransportError::Timeout {
                waited: start.elapsed(),
            }),
            // Our own sender lives in the hub, which we hold an Arc to.
            Err(RecvTimeoutError::Disconnected) => Err(TransportError::Closed),
        }
    }
}

impl Drop for SimBusEndpoint {
    fn drop(&mut self) {
        let mut hub = self.hub.lock().unwrap_or_else(PoisonError::into_inner);
        let me = self.id;
        hub.endpoints.retain(|(id, _)| *id != me);
    }
}
