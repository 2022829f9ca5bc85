//! Byte-stream transports: RS-232 serial ports (and pseudo-terminals) via the
//! `serialport` crate, and an in-memory pipe.
//!
//! Framing: none — these carry raw bytes; codecs in [`crate::protocols`]
//! frame them. Reference: POSIX termios semantics as exposed by
//! `serialport` 4 (`SerialPort::set_timeout` bounds each blocking read).

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use serialport::SerialPort;

use super::TransportError;

/// A bidirectional byte stream with timed reads.
pub trait ByteTransport: Send {
    /// Writes all of `bytes` (and flushes).
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError>;

    /// Waits up to `timeout` for data; returns at least one byte, or
    /// [`TransportError::Timeout`] reporting the time waited. An empty `buf`
    /// returns `Ok(0)` immediately.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, TransportError>;

    /// Discards input already received. The default drains with zero-timeout
    /// reads (at most 1 MiB).
    fn clear_input(&mut self) -> Result<(), TransportError> {
        let mut scratch = [0u8; 256];
        let mut total = 0usize;
        while total < (1 << 20) {
            match self.read(&mut scratch, Duration::ZERO) {
                Ok(n) => total += n.max(1),
                Err(TransportError::Timeout { .. }) => return Ok(()),
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

impl<T: ByteTransport + ?Sized> ByteTransport for Box<T> {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        (**self).write_all(bytes)
    }
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, TransportError> {
        (**self).read(buf, timeout)
    }
    fn clear_input(&mut self) -> Result<(), TransportError> {
        (**self).clear_input()
    }
}

/// Parity setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Parity {
    /// No parity bit.
    None,
    /// Even parity (the Movemaster default).
    #[default]
    Even,
    /// Odd parity.
    Odd,
}

/// Flow control setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FlowControl {
    /// No flow control.
    #[default]
    None,
    /// RTS/CTS.
    Hardware,
    /// XON/XOFF.
    Software,
}

/// Serial line settings, embedded in the rig file. Defaults: 9600 baud, 7 data
/// bits, even parity, 2 stop bits, no flow control (7E2, the Movemaster default).
///
/// ```toml
/// baud = 9600
/// data_bits = 7
/// parity = "even"      # none | even | odd
/// stop_bits = 2
/// flow = "none"        # none | hardware | software
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SerialSettings {
    /// Baud rate.
    pub baud: u32,
    /// Data bits, 5..=8.
    pub data_bits: u8,
    /// Parity.
    pub parity: Parity,
    /// Stop bits, 1 or 2.
    pub stop_bits: u8,
    /// Flow control.
    pub flow: FlowControl,
}

impl Default for SerialSettings {
    fn default() -> Self {
        SerialSettings {
            baud: 9600,
            data_bits: 7,
            parity: Parity::Even,
            stop_bits: 2,
            flow: FlowControl::None,
        }
    }
}

impl SerialSettings {
    /// Checks ranges (baud > 0, data bits 5..=8, stop bits 1 or 2).
    pub fn validate(&self) -> Result<(), TransportError> {
        if self.baud == 0 {
            return Err(TransportError::InvalidSettings {
                field: "baud",
                value: self.baud.to_string(),
                allowed: "> 0",
            });
        }
        self.serial_data_bits()?;
        self.serial_stop_bits()?;
        Ok(())
    }

    fn serial_data_bits(&self) -> Result<serialport::DataBits, TransportError> {
        Ok(match self.data_bits {
            5 => serialport::DataBits::Five,
            6 => serialport::DataBits::Six,
            7 => serialport::DataBits::Seven,
            8 => serialport::DataBits::Eight,
            n => {
                return Err(TransportError::InvalidSettings {
                    field: "data_bits",
                    value: n.to_string(),
                    allowed: "5, 6, 7 or 8",
                })
            }
        })
    }

    fn serial_stop_bits(&self) -> Result<serialport::StopBits, TransportError> {
        Ok(match self.stop_bits {
            1 => serialport::StopBits::One,
            2 => serialport::StopBits::Two,
            n => {
                return Err(TransportError::InvalidSettings {
                    field: "stop_bits",
                    value: n.to_string(),
                    allowed: "1 or 2",
                })
            }
        })
    }
}

fn serial_error(e: serialport::Error) -> TransportError {
    TransportError::Io {
        source: std::io::Error::from(e),
    }
}

/// A [`ByteTransport`] over a `serialport` port (real UART or pseudo-terminal).
pub struct SerialTransport {
    port: Box<dyn SerialPort>,
    current_timeout: Option<Duration>,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport")
            .field("port", &self.port.name())
            .finish()
    }
}

impl SerialTransport {
    /// Opens `path` with `settings`.
    pub fn open(path: &str, settings: &SerialSettings) -> Result<Self, TransportError> {
        settings.validate()?;
        let parity = match settings.parity {
            Parity::None => serialport::Parity::None,
            Parity::Even => serialport::Parity::Even,
            Parity::Odd => serialport::Parity::Odd,
        };
        let flow = match settings.flow {
            FlowControl::None => serialport::FlowControl::None,
            FlowControl::Hardware => serialport::FlowControl::Hardware,
            FlowControl::Software => serialport::FlowControl::Software,
        };
        let port = serialport::new(path, settings.baud)
            .data_bits(settings.serial_data_bits()?)
            .stop_bits(settings.serial_stop_bits()?)
            .parity(parity)
            .flow_control(flow)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| TransportError::Open {
                target: path.to_string(),
                detail: e.to_string(),
            })?;
        Ok(SerialTransport::from_port(port))
    }

    /// Wraps an already open port (e.g. one end of `serialport::TTYPort::pair()`).
    pub fn from_port(port: Box<dyn SerialPort>) -> Self {
        SerialTransport {
            port,
            current_timeout: None,
        }
    }

    fn set_timeout(&mut self, timeout: Duration) -> Result<(), TransportError> {
        if self.current_timeout != Some(timeout) {
            self.port.set_timeout(timeout).map_err(serial_error)?;
            self.current_timeout = Some(timeout);
        }
        Ok(())
    }
}

impl ByteTransport for SerialTransport {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        let start = Instant::now();
        let res = Write::write_all(&mut self.port, bytes).and_then(|()| self.port.flush());
        match res {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Err(TransportError::Timeout {
                waited: start.elapsed(),
            }),
            Err(source) => Err(TransportError::Io { source }),
        }
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, TransportError> {
        if buf.is_empty() {
            return Ok(0);
        }
        let start = Instant::now();
        loop {
            let remaining = timeout.saturating_sub(start.elapsed());
            self.set_timeout(remaining)?;
            match self.port.read(buf) {
                Ok(0) => return Err(TransportError::Closed),
                Ok(n) => return Ok(n),
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                    ) =>
                {
                    return Err(TransportError::Timeout {
                        waited: start.elapsed(),
                    })
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {
                    if start.elapsed() >= timeout {
                        return Err(TransportError::Timeout {
                            waited: start.elapsed(),
                        });
                    }
                }
                Err(source) => return Err(TransportError::Io { source }),
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        self.port
            .clear(serialport::ClearBuffer::Input)
            .map_err(serial_error)
    }
}

/// One end of an in-memory byte pipe (see [`PipeTransport::pair`]).
#[derive(Debug)]
pub struct PipeTransport {
    tx: Sender<Vec<u8>>,
    rx: Receiver<Vec<u8>>,
    pending: VecDeque<u8>,
}

impl PipeTransport {
    /// Two connected ends: bytes written to one are read from the other.
    /// Dropping one end makes the other report [`TransportError::Closed`]
    /// once buffered data is consumed.
    pub fn pair() -> (PipeTransport, PipeTransport) {
        let (tx_a, rx_b) = mpsc::channel();
        let (tx_b, rx_a) = mpsc::channel();
        (
            PipeTransport {
                tx: tx_a,
                rx: rx_a,
                pending: VecDeque::new(),
            },
            PipeTransport {
                tx: tx_b,
                rx: rx_b,
                pending: VecDeque::new(),
            },
        )
    }
}

impl ByteTransport for PipeTransport {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        if bytes.is_empty() {
            return Ok(());
        }
        self.tx
            .send(bytes.to_vec())
            .map_err(|_| TransportError::Closed)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, TransportError> {
        if buf.is_empty() {
            return Ok(0);
        }
        if self.pending.is_empty() {
            let start = Instant::now();
            match self.rx.recv_timeout(timeout) {
                Ok(chunk) => self.pending.extend(chunk),
                Err(RecvTimeoutError::Timeout) => {
                    return Err(TransportError::Timeout {
                        waited: start.elapsed(),
                    })
                }
                Err(RecvTimeoutError::Disconnected) => return Err(TransportError::Closed),
            }
        }
        let n = buf.len().min(self.pending.len());
        for (slot, b) in buf.iter_mut().zip(self.pending.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        self.pending.clear();
        while self.rx.try_recv().is_ok() {}
        Ok(())
    }
}
