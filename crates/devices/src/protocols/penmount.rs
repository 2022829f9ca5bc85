//! PenMount 6000 serial touch controller packets.
//!
//! Framing: fixed 6-byte packets, no delimiter; the header byte and a
//! checksum provide synchronisation.
//!
//! Reference: the Linux kernel driver `drivers/input/touchscreen/penmount.c`.
//! What this module takes from it, exactly:
//!
//! - Packet size 6 for the 6000 (`pm_connect()`, `case 1: pm->packetsize = 6;
//!   pm->parse_packet = pm_parse_6000`).
//! - Header test in `pm_parse_6000()`: `(data[0] & 0xbf) == 0x30`, i.e. the
//!   header is `0x30` (not touched) or `0x70` (touched); the touch flag is
//!   bit 6 of byte 0 (`input_report_key(dev, BTN_TOUCH, data[0] & 0x40)`).
//! - Coordinates in `pm_parse_6000()`: `ABS_X = data[2] * 256 + data[1]`,
//!   `ABS_Y = data[4] * 256 + data[3]` — little-endian 16-bit values, low
//!   byte first.
//! - Checksum in `pm_checkpacket()`: `data[5] == (unsigned char)~(sum of
//!   data[0..5] & 0xff)`, i.e. the **one's complement** of the byte sum
//!   modulo 256 (not the plain sum).
//!
//! What is ours, not the kernel's: the kernel drops a packet with a bad
//! checksum and restarts at the next byte that passes the header test;
//! [`PenMountDecoder`] instead shifts by one byte after a bad checksum (the
//! packet's tail may contain the next header) and keeps counters. The
//! range limits x 0..=511, y 0..=255 are those of the rig's panel (the kernel
//! declares 0..=0x3FF for the 6000).

use thiserror::Error;

/// Packet length in bytes.
const PACKET_LEN: usize = 6;
/// Largest raw x count the rig's panel reports.
const MAX_X: u16 = 511;
/// Largest raw y count the rig's panel reports.
const MAX_Y: u16 = 255;
/// Header byte mask from `pm_parse_6000()`.
const HEADER_MASK: u8 = 0xBF;
/// Header byte value after masking.
const HEADER_VALUE: u8 = 0x30;
/// Touch flag in the header byte.
const TOUCH_BIT: u8 = 0x40;

/// Which coordinate a range error refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// Horizontal.
    X,
    /// Vertical.
    Y,
}

/// Everything that can go wrong building or decoding PenMount packets.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum PenMountError {
    /// Byte 0 does not match the 6000 header pattern.
    #[error("byte {byte:#04x} is not a PenMount 6000 header (expected 0x30 or 0x70)")]
    BadHeader {
        /// The byte.
        byte: u8,
    },
    /// The checksum byte does not match.
    #[error("PenMount checksum mismatch: packet has {found:#04x}, computed {expected:#04x}")]
    BadChecksum {
        /// Computed checksum.
        expected: u8,
        /// Byte 5 of the packet.
        found: u8,
    },
    /// A coordinate is outside the panel's range.
    #[error(
        "PenMount {axis:?} = {value} is outside 0..={max}; check the panel model / calibration"
    )]
    OutOfRange {
        /// The axis.
        axis: Axis,
        /// The value.
        value: u16,
        /// The allowed maximum.
        max: u16,
    },
    /// The slice is not exactly 6 bytes.
    #[error("PenMount packet must be 6 bytes, got {len}")]
    WrongLength {
        /// The length given.
        len: usize,
    },
}

/// One touch report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PenMountPacket {
    /// Pen/finger down.
    pub touch: bool,
    /// Raw x count, 0..=511.
    pub x: u16,
    /// Raw y count, 0..=255.
    pub y: u16,
}

/// The kernel's `pm_checkpacket()` checksum: `!(sum of bytes 0..5) mod 256`.
pub fn checksum(first_five: &[u8; 5]) -> u8 {
    !first_five.iter().fold(0u8, |a, b| a.wrapping_add(*b))
}

/// True if `byte` passes the 6000 header test `(byte & 0xBF) == 0x30`.
fn is_header(byte: u8) -> bool {
    byte & HEADER_MASK == HEADER_VALUE
}

impl PenMountPacket {
    /// A packet, validating the panel's range.
    pub fn new(touch: bool, x: u16, y: u16) -> Result<Self, PenMountError> {
        let p = PenMountPacket { touch, x, y };
        p.validate()?;
        Ok(p)
    }

    fn validate(&self) -> Result<(), PenMountError> {
        if self.x > MAX_X {
            return Err(PenMountError::OutOfRange {
                axis: Axis::X,
                value: self.x,
                max: MAX_X,
            });
        }
        if self.y > MAX_Y {
            return Err(PenMountError::OutOfRange {
                axis: Axis::Y,
                value: self.y,
                max: MAX_Y,
            });
        }
        Ok(())
    }

    /// The 6 wire bytes: header, x lo, x hi, y lo, y hi, checksum.
    /// (Fields are public, so out-of-range values are encoded as given; the
    /// decoder will reject them.)
    pub fn encode(&self) -> [u8; 6] {
        let header = HEADER_VALUE | if self.touch { TOUCH_BIT } else { 0 };
        let [xl, xh] = self.x.to_le_bytes();
        let [yl, yh] = self.y.to_le_bytes();
        let five = [header, xl, xh, yl, yh];
        [header, xl, xh, yl, yh, checksum(&five)]
    }

    /// Decodes exactly one 6-byte packet.
    pub fn decode(bytes: &[u8]) -> Result<Self, PenMountError> {
        let [h, xl, xh, yl, yh, sum] = *bytes else {
            return Err(PenMountError::WrongLength { len: bytes.len() });
        };
        if !is_header(h) {
            return Err(PenMountError::BadHeader { byte: h });
        }
        let expected = checksum(&[h, xl, xh, yl, yh]);
        if expected != sum {
            return Err(PenMountError::BadChecksum {
                expected,
                found: sum,
            });
        }
        let p = PenMountPacket {
            touch: h & TOUCH_BIT != 0,
            x: u16::from_le_bytes([xl, xh]),
            y: u16::from_le_bytes([yl, yh]),
        };
        p.validate()?;
        Ok(p)
    }
}

/// Counters kept by [`PenMountDecoder`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PenMountStats {
    /// Packets decoded and returned.
    pub good: u64,
    /// Candidate packets rejected for a bad checksum.
    pub bad_checksum: u64,
    /// Packets with a good checksum but coordinates outside the panel range (dropped).
    pub out_of_range: u64,
    /// Bytes dropped from the stream (not part of a returned packet).
    pub discarded_bytes: u64,
}

/// Streaming decoder: feed arbitrary chunks, get whole packets.
///
/// Bytes that fail the header test are dropped. A 6-byte candidate with a bad
/// checksum drops only its first byte, then scanning resumes at the next
/// header. Out-of-range packets (good checksum) are dropped whole.
#[derive(Debug, Clone, Default)]
pub struct PenMountDecoder {
    buf: Vec<u8>,
    stats: PenMountStats,
}

impl PenMountDecoder {
    /// A fresh decoder.
    pub fn new() -> Self {
        PenMountDecoder::default()
    }

    /// The counters so far.
    pub fn stats(&self) -> PenMountStats {
        self.stats
    }

    /// Bytes of an incomplete packet currently buffered.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Feeds bytes; returns the packets they complete, in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<PenMountPacket> {
        self.buf.extend_from_slice(bytes);
        let mut out = Vec::new();
        let mut pos = 0;
        loop {
            // Skip to the next header candidate.
            let skip = self
                .buf
                .get(pos..)
                .unwrap_or(&[])
                .iter()
                .position(|&b| is_header(b))
                .unwrap_or(self.buf.len().saturating_sub(pos));
            self.stats.discarded_bytes += skip as u64;
            pos += skip;
            let Some(candidate) = self.buf.get(pos..pos + PACKET_LEN) else {
                break;
            };
            match PenMountPacket::decode(candidate) {
                Ok(p) => {
                    self.stats.good += 1;
                    out.push(p);
                    pos += PACKET_LEN;
                }
                Err(PenMountError::OutOfRange { .. }) => {
                    self.stats.out_of_range += 1;
                    self.stats.discarded_bytes += PACKET_LEN as u64;
                    pos += PACKET_LEN;
                }
                Err(_) => {
                    self.stats.bad_checksum += 1;
                    self.stats.discarded_bytes += 1;
                    pos += 1;
                }
            }
        }
        self.buf.drain(..pos.min(self.buf.len()));
        out
    }
}
