//! Serial-line CAN ("slcan"): the Lawicel CANUSB/CAN232 ASCII protocol spoken
//! by most USB-CAN adapters (CANable, USBtin, Lawicel and clones).
//!
//! Framing: every message is a line of ASCII terminated by CR (`\r`), except
//! the error reply, which is a single BEL (`\x07`). Reference: Lawicel
//! "CAN232 / CANUSB ASCII command set" and the Linux `slcan` line discipline
//! (`drivers/net/can/slcan/`).
//!
//! | bytes | direction | [`SlcanMessage`] |
//! |---|---|---|
//! | `tIIILDD..\r` | both | standard data frame (`Frame`) |
//! | `TIIIIIIIILDD..\r` | both | extended data frame |
//! | `rIIIL\r` / `RIIIIIIIIL\r` | both | remote frames |
//! | `O\r` / `C\r` | host → adapter | open / close the channel |
//! | `S0\r`..`S8\r` | host → adapter | bit rate ([`Bitrate`]) |
//! | `F\r` / `V\r` | host → adapter | read status flags / version |
//! | `Z0\r` / `Z1\r` | host → adapter | timestamps off / on |
//! | `\r` | adapter → host | OK |
//! | `\x07` | adapter → host | error |
//! | `z\r` / `Z\r` | adapter → host | standard / extended frame transmitted |
//! | `Fxx\r` | adapter → host | status flags (2 hex digits) |
//! | `Vxxxx\r` | adapter → host | version (4 characters) |
//!
//! Encoding writes upper-case hex; decoding accepts both cases. With
//! timestamps on, the adapter appends 4 hex digits (milliseconds, 0..=0xEA5F)
//! after the data of a received frame; the decoder accepts a frame with or
//! without them.
//!
//! [`SlcanDecoder`] splits a byte stream on CR and BEL, decodes each line,
//! resynchronises after garbage (reporting how many bytes it dropped) and caps
//! the line length.

use thiserror::Error;

use super::can::{CanFrame, CanFrameError, CanId};

/// Longest valid line: `T` + 8 id + 1 dlc + 16 data + 4 timestamp (30) plus CR.
pub const MAX_MESSAGE_LEN: usize = 31;
/// Default line cap of [`SlcanDecoder`] (bytes before the terminator).
pub const DEFAULT_MAX_LINE: usize = 64;

const CR: u8 = b'\r';
const BEL: u8 = 0x07;

/// Everything that can go wrong decoding slcan messages.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum SlcanError {
    /// No bytes at all.
    #[error("empty slcan message")]
    Empty,
    /// The message is not terminated by CR (and is not a lone BEL).
    #[error("slcan message not terminated by CR")]
    MissingTerminator,
    /// The first byte is no known command or reply.
    #[error("unknown slcan message starting with {byte:#04x}")]
    UnknownCommand {
        /// The first byte.
        byte: u8,
    },
    /// A message had the wrong length for its kind.
    #[error("slcan {what} has {found} characters before CR, expected {expected}")]
    BadLength {
        /// Message kind.
        what: &'static str,
        /// Expected length description.
        expected: &'static str,
        /// Characters found.
        found: usize,
    },
    /// A non-hex character where a hex digit is required.
    #[error("byte {byte:#04x} at offset {offset} is not a hex digit")]
    BadHex {
        /// Offset in the message.
        offset: usize,
        /// The byte.
        byte: u8,
    },
    /// A data length code other than `0`..=`8`.
    #[error("slcan DLC {byte:#04x} is not a digit 0..=8")]
    BadDlc {
        /// The DLC character.
        byte: u8,
    },
    /// `Sn` with n outside 0..=8.
    #[error("slcan bit-rate code {code:#04x} is not S0..S8")]
    BadBitrate {
        /// The code character.
        code: u8,
    },
    /// The frame identifier or payload is invalid (e.g. standard id above 0x7FF).
    #[error(transparent)]
    Frame(#[from] CanFrameError),
    /// A line exceeded the decoder's cap; bytes are dropped up to the next CR/BEL.
    #[error(
        "slcan line longer than {max} bytes; dropping up to the next CR or BEL (wrong baud rate?)"
    )]
    LineTooLong {
        /// The cap.
        max: usize,
    },
    /// The decoder dropped bytes that formed no valid message.
    #[error("dropped {count} byte(s) of garbage from the slcan stream: {cause}")]
    Discarded {
        /// Number of bytes dropped.
        count: usize,
        /// Why they could not be decoded.
        cause: Box<SlcanError>,
    },
}

/// CAN bit rates selectable with `S0`..`S8`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Bitrate {
    /// S0: 10 kbit/s.
    #[serde(rename = "10k")]
    K10,
    /// S1: 20 kbit/s.
    #[serde(rename = "20k")]
    K20,
    /// S2: 50 kbit/s.
    #[serde(rename = "50k")]
    K50,
    /// S3: 100 kbit/s.
    #[serde(rename = "100k")]
    K100,
    /// S4: 125 kbit/s.
    #[serde(rename = "125k")]
    K125,
    /// S5: 250 kbit/s.
    #[serde(rename = "250k")]
    K250,
    /// S6: 500 kbit/s.
    #[serde(rename = "500k")]
    K500,
    /// S7: 800 kbit/s.
    #[serde(rename = "800k")]
    K800,
    /// S8: 1 Mbit/s.
    #[serde(rename = "1M")]
    M1,
}

impl Bitrate {
    const ALL: [Bitrate; 9] = [
        Bitrate::K10,
        Bitrate::K20,
        Bitrate::K50,
        Bitrate::K100,
        Bitrate::K125,
        Bitrate::K250,
        Bitrate::K500,
        Bitrate::K800,
        Bitrate::M1,
    ];
    /// The digit n of `Sn` (0..=8).
    pub fn code(self) -> u8 {
        Self::ALL.iter().position(|b| *b == self).unwrap_or(0) as u8
    }
    /// The bit rate for `Sn`.
    pub fn from_code(n: u8) -> Option<Self> {
        Self::ALL.get(usize::from(n)).copied()
    }
    /// Bits per second.
    pub fn bits_per_second(self) -> u32 {
        match self {
            Bitrate::K10 => 10_000,
            Bitrate::K20 => 20_000,
            Bitrate::K50 => 50_000,
            Bitrate::K100 => 100_000,
            Bitrate::K125 => 125_000,
            Bitrate::K250 => 250_000,
            Bitrate::K500 => 500_000,
            Bitrate::K800 => 800_000,
            Bitrate::M1 => 1_000_000,
        }
    }
    /// The bit rate with exactly `bps` bits per second, if slcan has one.
    pub fn from_bits_per_second(bps: u32) -> Option<Self> {
        Self::ALL
            .iter()
            .copied()
            .find(|b| b.bits_per_second() == bps)
    }
}

/// Any message a host or an adapter can send.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SlcanMessage {
    /// A CAN frame (to transmit, or received), with the adapter timestamp if present.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// Timestamp in ms (only when the adapter has timestamps on).
        timestamp: Option<u16>,
    },
    /// `O\r`: open the channel.
    Open,
    /// `C\r`: close the channel.
    Close,
    /// `Sn\r`: set the bit rate (channel must be closed).
    SetBitrate(Bitrate),
    /// `F\r`: read status flags.
    ReadStatusFlags,
    /// `V\r`: read the version.
    ReadVersion,
    /// `Z0\r` / `Z1\r`: timestamps off / on.
    SetTimestamps(bool),
    /// `\r`: command accepted.
    Ok,
    /// `\x07` (BEL): command rejected.
    Error,
    /// `z\r` (standard) / `Z\r` (extended): frame transmitted.
    TransmitAck {
        /// True for `Z\r`.
        extended: bool,
    },
    /// `Fxx\r`: status flags byte.
    StatusFlags(u8),
    /// `Vxxxx\r`: hardware and software version characters.
    Version([u8; 4]),
}

fn push_hex(out: &mut Vec<u8>, value: u32, digits: usize) {
    out.extend_from_slice(format!("{value:0digits$X}").as_bytes());
}

fn hex_value(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b - b'0'),
        b'A'..=b'F' => Some(b - b'A' + 10),
        b'a'..=b'f' => Some(b - b'a' + 10),
        _ => None,
    }
}

/// Parses `text` (at `offset` within the message) as hex.
fn parse_hex(text: &[u8], offset: usize) -> Result<u32, SlcanError> {
    text.iter().enumerate().try_fold(0u32, |acc, (i, &b)| {
        hex_value(b)
            .map(|v| (acc << 4) | u32::from(v))
            .ok_or(SlcanError::BadHex {
                offset: offset + i,
                byte: b,
            })
    })
}

impl SlcanMessage {
    /// The exact bytes (CR-terminated, or a lone BEL for [`SlcanMessage::Error`]).
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(MAX_MESSAGE_LEN);
        match *self {
            SlcanMessage::Frame { frame, timestamp } => {
                let letter = match (frame.is_extended(), frame.is_remote()) {
                    (false, false) => b't',
                    (true, false) => b'T',
                    (false, true) => b'r',
                    (true, true) => b'R',
                };
                out.push(letter);
                push_hex(
                    &mut out,
                    frame.raw_id(),
                    if frame.is_extended() { 8 } else { 3 },
                );
                out.push(b'0' + frame.dlc());
                for &b in frame.data() {
                    push_hex(&mut out, u32::from(b), 2);
                }
                if let Some(ts) = timestamp {
                    push_hex(&mut out, u32::from(ts), 4);
                }
            }
            SlcanMessage::Open => out.push(b'O'),
            SlcanMessage::Close => out.push(b'C'),
            SlcanMessage::SetBitrate(b) => out.extend_from_slice(&[b'S', b'0' + b.code()]),
            SlcanMessage::ReadStatusFlags => out.push(b'F'),
            SlcanMessage::ReadVersion => out.push(b'V'),
            SlcanMessage::SetTimestamps(on) => {
                out.extend_from_slice(if on { b"Z1" } else { b"Z0" })
            }
            SlcanMessage::Ok => {}
            SlcanMessage::Error => return vec![BEL],
            SlcanMessage::TransmitAck { extended } => out.push(if extended { b'Z' } else { b'z' }),
            SlcanMessage::StatusFlags(f) => {
                out.push(b'F');
                push_hex(&mut out, u32::from(f), 2);
            }
            SlcanMessage::Version(v) => {
                out.push(b'V');
                out.extend_from_slice(&v);
            }
        }
        out.push(CR);
        out
    }

    /// Builds the message for transmitting `frame` (no timestamp).
    pub fn frame(frame: CanFrame) -> Self {
        SlcanMessage::Frame {
            frame,
            timestamp: None,
        }
    }

    /// Decodes one complete message: a CR-terminated line or a lone BEL.
    pub fn decode(msg: &[u8]) -> Result<Self, SlcanError> {
        if msg.is_empty() {
            return Err(SlcanError::Empty);
        }
        if msg == [BEL] {
            return Ok(SlcanMessage::Error);
        }
        let body = msg
            .strip_suffix(&[CR])
            .ok_or(SlcanError::MissingTerminator)?;
        let Some((&first, rest)) = body.split_first() else {
            return Ok(SlcanMessage::Ok);
        };
        let exact = |m: SlcanMessage, what: &'static str| {
            if rest.is_empty() {
                Ok(m)
            } else {
                Err(SlcanError::BadLength {
                    what,
                    expected: "1",
                    found: body.len(),
                })
            }
        };
        match first {
            b't' | b'T' | b'r' | b'R' => decode_frame(first, rest),
            b'O' => exact(SlcanMessage::Open, "open command"),
            b'C' => exact(SlcanMessage::Close, "close command"),
            b'z' => exact(
                SlcanMessage::TransmitAck { extended: false },
                "transmit ack",
            ),
            b'S' => match rest {
                [c] => c
                    .checked_sub(b'0')
                    .and_then(Bitrate::from_code)
                    .map(SlcanMessage::SetBitrate)
                    .ok_or(SlcanError::BadBitrate { code: *c }),
                _ => Err(SlcanError::BadLength {
                    what: "bit-rate command",
                    expected: "2",
                    found: body.len(),
                }),
            },
            b'F' => match rest {
                [] => Ok(SlcanMessage::ReadStatusFlags),
                [_, _] => Ok(SlcanMessage::StatusFlags(parse_hex(rest, 1)? as u8)),
                _ => Err(SlcanError::BadLength {
                    what: "status flags",
                    expected: "1 or 3",
                    found: body.len(),
                }),
            },
            b'V' => match *rest {
                [] => Ok(SlcanMessage::ReadVersion),
                [a, b, c, d] if rest.iter().all(u8::is_ascii_alphanumeric) => {
                    Ok(SlcanMessage::Version([a, b, c, d]))
                }
                [_, _, _, _] => Err(SlcanError::BadHex {
                    offset: 1 + rest
                        .iter()
                        .position(|b| !b.is_ascii_alphanumeric())
                        .unwrap_or(0),
                    byte: rest
                        .iter()
                        .copied()
                        .find(|b| !b.is_ascii_alphanumeric())
                        .unwrap_or(0),
                }),
                _ => Err(SlcanError::BadLength {
                    what: "version",
                    expected: "1 or 5",
                    found: body.len(),
                }),
            },
            b'Z' => match rest {
                [] => Ok(SlcanMessage::TransmitAck { extended: true }),
                [b'0'] => Ok(SlcanMessage::SetTimestamps(false)),
                [b'1'] => Ok(SlcanMessage::SetTimestamps(true)),
                [b] => Err(SlcanError::BadHex {
                    offset: 1,
                    byte: *b,
                }),
                _ => Err(SlcanError::BadLength {
                    what: "timestamp command",
                    expected: "1 or 2",
                    found: body.len(),
                }),
            },
            byte => Err(SlcanError::UnknownCommand { byte }),
        }
    }
}

fn decode_frame(letter: u8, rest: &[u8]) -> Result<SlcanMessage, SlcanError> {
    let extended = letter.is_ascii_uppercase();
    let remote = letter == b'r' || letter == b'R';
    let id_len = if extended { 8 } else { 3 };
    let what = "frame";
    let too_short = || SlcanError::BadLength {
        what,
        expected: "id + dlc (+ data) (+ 4-digit timestamp)",
        found: rest.len() + 1,
    };
    let id_text = rest.get(..id_len).ok_or_else(too_short)?;
    let raw_id = parse_hex(id_text, 1)?;
    let dlc_byte = *rest.get(id_len).ok_or_else(too_short)?;
    let dlc = match dlc_byte {
        b'0'..=b'8' => dlc_byte - b'0',
        _ => return Err(SlcanError::BadDlc { byte: dlc_byte }),
    };
    let id = if extended {
        CanId::extended(raw_id)?
    } else {
        // 3 hex digits fit in u16.
        CanId::standard(raw_id as u16)?
    };
    let data_chars = if remote { 0 } else { 2 * usize::from(dlc) };
    let after_dlc = rest.get(id_len + 1..).unwrap_or(&[]);
    let (data_text, ts_text) = match after_dlc.len().checked_sub(data_chars) {
        Some(0) | Some(4) => after_dlc.split_at(data_chars),
        _ => {
            return Err(SlcanError::BadLength {
                what,
                expected: "id + dlc + 2*dlc data digits (+ 4-digit timestamp)",
                found: rest.len() + 1,
            })
        }
    };
    let data_offset = 1 + id_len + 1;
    let mut data = [0u8; 8];
    for (i, (slot, pair)) in data.iter_mut().zip(data_text.chunks(2)).enumerate() {
        *slot = parse_hex(pair, data_offset + 2 * i)? as u8;
    }
    let frame = if remote {
        CanFrame::new_remote(id, dlc)?
    } else {
        CanFrame::new(id, data.get(..usize::from(dlc)).unwrap_or(&[]))?
    };
    let timestamp = if ts_text.is_empty() {
        None
    } else {
        Some(parse_hex(ts_text, data_offset + data_chars)? as u16)
    };
    Ok(SlcanMessage::Frame { frame, timestamp })
}

/// Byte-stream decoder: splits on CR and BEL, decodes, resynchronises.
///
/// A line that does not decode is retried from each later byte that can
/// start a message (`t T r R O C S F V Z z`); the bytes skipped are reported
/// as [`SlcanError::Discarded`] before the message recovered from the tail.
/// If nothing decodes, the whole line including its CR is discarded — it is
/// deliberately *not* read as an OK reply. Bytes before a BEL are discarded.
/// A line longer than the cap yields [`SlcanError::LineTooLong`] once and
/// bytes are dropped until the next CR or BEL.
#[derive(Debug, Clone)]
pub struct SlcanDecoder {
    buf: Vec<u8>,
    max_len: usize,
    discarding: bool,
    discarded: u64,
}

impl Default for SlcanDecoder {
    fn default() -> Self {
        SlcanDecoder::new(DEFAULT_MAX_LINE)
    }
}

impl SlcanDecoder {
    /// A decoder capping lines at `max_len` bytes (at least [`MAX_MESSAGE_LEN`]).
    pub fn new(max_len: usize) -> Self {
        SlcanDecoder {
            buf: Vec::new(),
            max_len: max_len.max(MAX_MESSAGE_LEN),
            discarding: false,
            discarded: 0,
        }
    }

    /// Total bytes dropped as garbage or over-long lines so far.
    pub fn discarded_bytes(&self) -> u64 {
        self.discarded
    }

    /// Bytes of an incomplete message currently buffered.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Feeds bytes; returns the messages and errors they complete, in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Result<SlcanMessage, SlcanError>> {
        let mut out = Vec::new();
        for &b in bytes {
            match b {
                CR | BEL if self.discarding => {
                    self.discarding = false;
                    if b == BEL {
                        out.push(Ok(SlcanMessage::Error));
                    } else {
                        self.discarded += 1;
                    }
                }
                CR => {
                    let mut line = std::mem::take(&mut self.buf);
                    line.push(CR);
                    self.decode_line(&line, &mut out);
                }
                BEL => {
                    if !self.buf.is_empty() {
                        let count = self.buf.len();
                        self.discarded += count as u64;
                        self.buf.clear();
                        out.push(Err(SlcanError::Discarded {
                            count,
                            cause: Box::new(SlcanError::MissingTerminator),
                        }));
                    }
                    out.push(Ok(SlcanMessage::Error));
                }
                _ if self.discarding => self.discarded += 1,
                _ if self.buf.len() >= self.max_len => {
                    self.discarded += self.buf.len() as u64 + 1;
                    self.buf.clear();
                    self.discarding = true;
                    out.push(Err(SlcanError::LineTooLong { max: self.max_len }));
                }
                _ => self.buf.push(b),
            }
        }
        out
    }

    fn decode_line(&mut self, line: &[u8], out: &mut Vec<Result<SlcanMessage, SlcanError>>) {
        let first_err = match SlcanMessage::decode(line) {
            Ok(m) => {
                out.push(Ok(m));
                return;
            }
            Err(e) => e,
        };
        let body_len = line.len().saturating_sub(1);
        for start in 1..body_len {
            let starts_message = line.get(start).is_some_and(|b| {
                matches!(
                    b,
                    b't' | b'T' | b'r' | b'R' | b'O' | b'C' | b'S' | b'F' | b'V' | b'Z' | b'z'
                )
            });
            if !starts_message {
                continue;
            }
            if let Ok(m) = SlcanMessage::decode(line.get(start..).unwrap_or(&[])) {
                self.discarded += start as u64;
                out.push(Err(SlcanError::Discarded {
                    count: start,
                    cause: Box::new(first_err),
                }));
                out.push(Ok(m));
                return;
            }
        }
        self.discarded += line.len() as u64;
        out.push(Err(SlcanError::Discarded {
            count: line.len(),
            cause: Box::new(first_err),
        }));
    }
}
