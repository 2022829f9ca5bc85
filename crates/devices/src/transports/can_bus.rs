//! The [`CanBus`] trait: send and receive classic CAN frames with timeouts.
//!
//! Framing: one [`CanFrame`] per call; the back-end decides how frames travel
//! (slcan ASCII over a serial line, Linux SocketCAN, or an in-process hub).
//! Reference: CAN 2.0 broadcast semantics — every frame is seen by every
//! other node; a node does not receive its own frames.

use std::time::Duration;

use super::TransportError;
use crate::protocols::can::CanFrame;

/// A CAN interface.
pub trait CanBus: Send {
    /// Queues `frame` for transmission (waiting at most the back-end's own
    /// acknowledgement timeout).
    fn send(&mut self, frame: &CanFrame) -> Result<(), TransportError>;

    /// Waits up to `timeout` for the next received frame.
    fn recv(&mut self, timeout: Duration) -> Result<CanFrame, TransportError>;
}

impl<T: CanBus + ?Sized> CanBus for Box<T> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), TransportError> {
        (**self).send(frame)
    }
    fn recv(&mut self, timeout: Duration) -> Result<CanFrame, TransportError> {
        (**self).recv(timeout)
    }
}
