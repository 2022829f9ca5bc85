//! Transports: move bytes or CAN frames, know nothing of message meaning.
//!
//! - [`ByteTransport`] (byte streams): [`SerialTransport`] over a serial port
//!   or pseudo-terminal, [`PipeTransport`] in memory.
//! - [`CanBus`] (CAN frames): [`SlcanBus`] over any byte transport, the
//!   in-process [`SimBus`], [`SocketCanBus`] on Linux, and [`BridgedCanBus`] over an
//!   asynchronous socket on tokio ([`AsyncSocketCan`] on Linux).
//!
//! Every wait takes a timeout and ends in [`TransportError::Timeout`], which
//! reports how long was actually waited.

use std::time::Duration;

use thiserror::Error;

pub mod can_bridge;
pub mod can_bus;
pub mod serial;
pub mod sim_bus;
pub mod slcan_bus;
#[cfg(target_os = "linux")]
pub mod socketcan_bus;

pub use can_bridge::{AsyncFrames, BridgedCanBus};
pub use can_bus::CanBus;
pub use serial::{
    ByteTransport, FlowControl, Parity, PipeTransport, SerialSettings, SerialTransport,
};
pub use sim_bus::{SimBus, SimBusEndpoint};
pub use slcan_bus::{SlcanBus, SlcanBusConfig};
#[cfg(target_os = "linux")]
pub use socketcan_bus::{AsyncSocketCan, SocketCanBus};

/// Coarse classification of a [`TransportError`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum TransportErrorKind {
    /// Nothing arrived in time.
    Timeout,
    /// Operating-system I/O error.
    Io,
    /// The peer or channel is gone.
    Closed,
    /// The device answered, but negatively or unintelligibly.
    Protocol,
    /// The device could not be opened.
    Open,
    /// The configuration is invalid.
    InvalidSettings,
}

/// Errors of all transports.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TransportError {
    /// No data within the timeout.
    #[error("no data within {waited:?}; check cabling, power and baud rate, or raise the timeout")]
    Timeout {
        /// How long the call actually waited.
        waited: Duration,
    },
    /// Operating-system I/O error.
    #[error("I/O error: {source}")]
    Io {
        /// The underlying error.
        #[from]
        source: std::io::Error,
    },
    /// The other end has gone away (pipe dropped, pty closed, bus hub dropped).
    #[error("transport closed by the other end; reopen it")]
    Closed,
    /// The device answered, but negatively or in a way the transport cannot use
    /// (e.g. an slcan adapter replied BEL).
    #[error("device protocol error: {detail}")]
    Protocol {
        /// What happened.
        detail: String,
    },
    /// The device could not be opened.
    #[error("cannot open {target}: {detail}; check the path/interface name and permissions")]
    Open {
        /// Path or interface name.
        target: String,
        /// The reason reported by the OS or driver.
        detail: String,
    },
    /// A setting is outside what the transport supports.
    #[error("invalid setting {field} = {value}; allowed: {allowed}")]
    InvalidSettings {
        /// The setting.
        field: &'static str,
        /// The rejected value.
        value: String,
        /// What is allowed.
        allowed: &'static str,
    },
}

impl TransportError {
    /// The coarse kind.
    pub fn kind(&self) -> TransportErrorKind {
        match self {
            TransportError::Timeout { .. } => TransportErrorKind::Timeout,
            TransportError::Io { .. } => TransportErrorKind::Io,
            TransportError::Closed => TransportErrorKind::Closed,
            TransportError::Protocol { .. } => TransportErrorKind::Protocol,
            TransportError::Open { .. } => TransportErrorKind::Open,
            TransportError::InvalidSettings { .. } => TransportErrorKind::InvalidSettings,
        }
    }

    /// True if repeating the operation may succeed: timeouts, protocol-level
    /// rejections and transient I/O errors (interrupted, would block, timed out).
    pub fn is_retryable(&self) -> bool {
        match self {
            TransportError::Timeout { .. } | TransportError::Protocol { .. } => true,
            TransportError::Io { source } => matches!(
                source.kind(),
                std::io::ErrorKind::Interrupted
                    | std::io::ErrorKind::WouldBlock
                    | std::io::ErrorKind::TimedOut
            ),
            _ => false,
        }
    }
}
