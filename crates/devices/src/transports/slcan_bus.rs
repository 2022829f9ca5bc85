//! [`CanBus`] over an slcan (Lawicel ASCII) USB-CAN adapter.
//!
//! Framing: slcan lines over any [`ByteTransport`], encoded and decoded by
//! [`crate::protocols::slcan`]. Reference: Lawicel CAN232/CANUSB command set.
//!
//! Opening sends `Sn\r` (bit rate) and `O\r` and requires a `\r` (OK) for
//! each; a BEL becomes [`TransportError::Protocol`]. Sending a frame waits
//! (optionally) for the adapter's `z\r`/`Z\r` (or `\r`) acknowledgement.
//! Frames received while waiting for an acknowledgement are queued and
//! returned by later [`CanBus::recv`] calls.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use super::{ByteTransport, CanBus, TransportError};
use crate::protocols::can::CanFrame;
use crate::protocols::slcan::{Bitrate, SlcanDecoder, SlcanMessage};

/// Settings of an [`SlcanBus`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlcanBusConfig {
    /// CAN bit rate (`S0`..`S8`).
    pub bitrate: Bitrate,
    /// How long to wait for each command / transmit acknowledgement.
    #[serde(with = "millis")]
    pub ack_timeout: Duration,
    /// Wait for `z\r`/`Z\r` after each transmitted frame (Lawicel behaviour).
    /// Disable for firmwares that send nothing on transmit.
    pub wait_transmit_ack: bool,
}

impl Default for SlcanBusConfig {
    fn default() -> Self {
        SlcanBusConfig {
            bitrate: Bitrate::K500,
            ack_timeout: Duration::from_millis(500),
            wait_transmit_ack: true,
        }
    }
}

mod millis {
    use std::time::Duration;

    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(u64::try_from(d.as_millis()).unwrap_or(u64::MAX))
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Duration, D::Error> {
        u64::deserialize(d).map(Duration::from_millis)
    }
}

/// A CAN bus reached through an slcan adapter on `T`.
#[derive(Debug)]
pub struct SlcanBus<T: ByteTransport> {
    io: T,
    config: SlcanBusConfig,
    decoder: SlcanDecoder,
    inbox: VecDeque<SlcanMessage>,
    frames: VecDeque<CanFrame>,
}

fn is_ok(m: &SlcanMessage) -> bool {
    matches!(m, SlcanMessage::Ok)
}

fn is_transmit_ack(m: &SlcanMessage) -> bool {
    matches!(m, SlcanMessage::Ok | SlcanMessage::TransmitAck { .. })
}

impl<T: ByteTransport> SlcanBus<T> {
    /// Discards stale input, closes a channel left open, sets the bit rate and opens the channel.
    pub fn open(io: T, config: SlcanBusConfig) -> Result<Self, TransportError> {
        let mut bus = SlcanBus {
            io,
            config,
            decoder: SlcanDecoder::default(),
            inbox: VecDeque::new(),
            frames: VecDeque::new(),
        };
        bus.io.clear_input()?;
        // A channel left open (by a process killed while it used the adapter) refuses a new
        // bitrate with BEL, as real adapters do: close it first, as python-can's slcan does.
        // An adapter whose channel is already closed may answer that with BEL too.
        match bus.command(&SlcanMessage::Close) {
            Ok(()) | Err(TransportError::Protocol { .. }) => {}
            Err(e) => return Err(e),
        }
        // Frames the old channel still delivered are not this bus's.
        bus.frames.clear();
        bus.command(&SlcanMessage::SetBitrate(config.bitrate))?;
        bus.command(&SlcanMessage::Open)?;
        Ok(bus)
    }

    /// Sends `C\r` and waits for OK.
    pub fn close(&mut self) -> Result<(), TransportError> {
        self.command(&SlcanMessage::Close)
    }

    /// Sends a command and waits for `\r`; BEL → [`TransportError::Protocol`].
    pub fn command(&mut self, msg: &SlcanMessage) -> Result<(), TransportError> {
        self.io.write_all(&msg.encode())?;
        self.wait_for(is_ok, msg).map(|_| ())
    }

    /// The settings in use.
    pub fn config(&self) -> &SlcanBusConfig {
        &self.config
    }

    /// Bytes the decoder has discarded as garbage so far.
    pub fn discarded_bytes(&self) -> u64 {
        self.decoder.discarded_bytes()
    }

    /// Gives back the byte transport (the channel is left as it is).
    pub fn into_inner(self) -> T {
        self.io
    }

    /// Reads once (up to `remaining`) and decodes into the inbox.
    fn fill(&mut self, remaining: Duration, started: Instant) -> Result<(), TransportError> {
        let mut chunk = [0u8; 128];
        let n = match self.io.read(&mut chunk, remaining) {
            Ok(n) => n,
            Err(TransportError::Timeout { .. }) => {
                return Err(TransportError::Timeout {
                    waited: started.elapsed(),
                })
            }
            Err(e) => return Err(e),
        };
        for item in self.decoder.push(chunk.get(..n).unwrap_or(&[])) {
            match item {
                Ok(m) => self.inbox.push_back(m),
                Err(e) => tracing::warn!(error = %e, "slcan: dropped input"),
            }
        }
        Ok(())
    }

    fn wait_for(
        &mut self,
        accept: fn(&SlcanMessage) -> bool,
        sent: &SlcanMessage,
    ) -> Result<SlcanMessage, TransportError> {
        let started = Instant::now();
        loop {
            while let Some(m) = self.inbox.pop_front() {
                match m {
                    SlcanMessage::Frame { frame, .. } => self.frames.push_back(frame),
                    SlcanMessage::Error => {
                        return Err(TransportError::Protocol {
                            detail: format!(
                                "slcan adapter rejected {:?} with BEL (channel closed/open in the wrong state, \
                                 transmit buffer full or bus-off)",
                                String::from_utf8_lossy(&sent.encode()).trim_end()
                            ),
                        })
                    }
                    m if accept(&m) => return Ok(m),
                    other => tracing::debug!(?other, "slcan: ignoring unexpected message"),
                }
            }
            let remaining = self.config.ack_timeout.saturating_sub(started.elapsed());
            self.fill(remaining, started)?;
        }
    }
}

impl<T: ByteTransport> CanBus for SlcanBus<T> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), TransportError> {
        let msg = SlcanMessage::frame(*frame);
        self.io.write_all(&msg.encode())?;
        if self.config.wait_transmit_ack {
            self.wait_for(is_transmit_ack, &msg)?;
        }
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<CanFrame, TransportError> {
        let started = Instant::now();
        loop {
            while let Some(m) = self.inbox.pop_front() {
                match m {
                    SlcanMessage::Frame { frame, .. } => self.frames.push_back(frame),
                    other => tracing::debug!(?other, "slcan: ignoring non-frame message"),
                }
            }
            if let Some(f) = self.frames.pop_front() {
                return Ok(f);
            }
            let remaining = timeout.saturating_sub(started.elapsed());
            self.fill(remaining, started)?;
        }
    }
}
