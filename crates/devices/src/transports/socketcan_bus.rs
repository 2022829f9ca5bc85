//! [`CanBus`] over Linux SocketCAN (`can0`, `vcan0`, ...).
//!
//! Framing: one kernel `struct can_frame` per frame through a raw CAN socket,
//! via the `socketcan` crate (v4). Reference: Linux
//! `Documentation/networking/can.rst`. Error frames received from the kernel
//! are reported as [`TransportError::Protocol`].
//!
//! Two forms: [`SocketCanBus`], blocking, and [`AsyncSocketCan`], socketcan's tokio socket,
//! which the rig's table uses behind a [`BridgedCanBus`](super::BridgedCanBus).

use std::time::{Duration, Instant};

use socketcan::{EmbeddedFrame, ExtendedId, Id, Socket, StandardId};

use super::{CanBus, TransportError};
use crate::protocols::can::{CanFrame, CanId};

/// A raw SocketCAN socket bound to one interface.
#[derive(Debug)]
pub struct SocketCanBus {
    socket: socketcan::CanSocket,
    interface: String,
}

impl SocketCanBus {
    /// Opens the interface `ifname` (it must exist and be up).
    pub fn open(ifname: &str) -> Result<Self, TransportError> {
        let socket = socketcan::CanSocket::open(ifname).map_err(|e| TransportError::Open {
            target: ifname.to_string(),
            detail: e.to_string(),
        })?;
        Ok(SocketCanBus {
            socket,
            interface: ifname.to_string(),
        })
    }

    /// The interface name.
    pub fn interface(&self) -> &str {
        &self.interface
    }
}

fn to_socketcan(frame: &CanFrame) -> Result<socketcan::CanFrame, TransportError> {
    let id = match frame.id() {
        CanId::Standard(id) => StandardId::new(id).map(Id::Standard),
        CanId::Extended(id) => ExtendedId::new(id).map(Id::Extended),
    }
    .ok_or_else(|| TransportError::Protocol {
        detail: format!("identifier {} not representable in SocketCAN", frame.id()),
    })?;
    let built = if frame.is_remote() {
        socketcan::CanFrame::new_remote(id, usize::from(frame.dlc()))
    } else {
        socketcan::CanFrame::new(id, frame.data())
    };
    built.ok_or_else(|| TransportError::Protocol {
        detail: format!("frame {frame} not representable in SocketCAN"),
    })
}

fn from_socketcan(frame: &socketcan::CanFrame) -> Result<CanFrame, TransportError> {
    if let socketcan::CanFrame::Error(e) = frame {
        return Err(TransportError::Protocol {
            detail: format!("SocketCAN error frame: {e:?}"),
        });
    }
    let id = match frame.id() {
        Id::Standard(id) => CanId::Standard(id.as_raw()),
        Id::Extended(id) => CanId::Extended(id.as_raw()),
    };
    let built = if frame.is_remote_frame() {
        CanFrame::new_remote(id, u8::try_from(frame.dlc()).unwrap_or(u8::MAX))
    } else {
        CanFrame::new(id, frame.data())
    };
    built.map_err(|e| TransportError::Protocol {
        detail: format!("invalid frame from SocketCAN: {e}"),
    })
}

/// A SocketCAN socket on tokio (socketcan's `tokio` feature), for a
/// [`BridgedCanBus`](super::BridgedCanBus).
#[derive(Debug)]
pub struct AsyncSocketCan {
    socket: socketcan::tokio::CanSocket,
}

impl AsyncSocketCan {
    /// Opens the interface `ifname` (it must exist and be up); must be called inside a tokio
    /// runtime with I/O enabled (the bridge's I/O thread).
    pub fn open(ifname: &str) -> Result<Self, TransportError> {
        let socket =
            socketcan::tokio::CanSocket::open(ifname).map_err(|e| TransportError::Open {
                target: ifname.to_string(),
                detail: e.to_string(),
            })?;
        Ok(AsyncSocketCan { socket })
    }
}

impl super::AsyncFrames for AsyncSocketCan {
    async fn read(&self) -> Result<CanFrame, TransportError> {
        let f = self
            .socket
            .read_frame()
            .await
            .map_err(|source| TransportError::Io { source })?;
        from_socketcan(&f)
    }

    async fn write(&self, frame: CanFrame) -> Result<(), TransportError> {
        let f = to_socketcan(&frame)?;
        self.socket
            .write_frame(f)
            .await
            .map_err(|source| TransportError::Io { source })
    }
}

impl CanBus for SocketCanBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), TransportError> {
        let f = to_socketcan(frame)?;
        self.socket
            .write_frame(&f)
            .map_err(|source| TransportError::Io { source })
    }

    fn recv(&mut self, timeout: Duration) -> Result<CanFrame, TransportError> {
        let started = Instant::now();
        match self.socket.read_frame_timeout(timeout) {
            Ok(f) => from_socketcan(&f),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                Err(TransportError::Timeout {
                    waited: started.elapsed(),
                })
            }
            Err(source) => Err(TransportError::Io { source }),
        }
    }
}
