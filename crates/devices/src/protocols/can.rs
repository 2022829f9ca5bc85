//! Classic CAN 2.0 frames (ISO 11898-1): 11-bit (2.0A) or 29-bit (2.0B)
//! identifier, 0..=8 data bytes, optional remote transmission request (RTR).
//!
//! Framing: a [`CanFrame`] is the logical frame as seen by a CAN controller
//! driver (identifier, DLC, payload); bit stuffing, CRC and ACK live in
//! hardware and are not modelled. The constructor validates the identifier
//! range and the payload length, so every `CanFrame` value is a frame a
//! controller could put on the wire.

use std::fmt;

use thiserror::Error;

/// Largest standard (11-bit) identifier.
const MAX_STANDARD_ID: u16 = 0x7FF;
/// Largest extended (29-bit) identifier.
const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;
/// Largest payload of a classic CAN frame, in bytes.
const MAX_DATA_LEN: usize = 8;

/// Why a [`CanFrame`] or [`CanId`] could not be built.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum CanFrameError {
    /// The identifier does not fit the chosen identifier format.
    #[error(
        "CAN identifier {id:#x} does not fit a {bits}-bit identifier (max {max:#x}); \
         use an extended identifier or a smaller id"
    )]
    IdTooLarge {
        /// The rejected identifier.
        id: u32,
        /// Width of the identifier format (11 or 29).
        bits: u8,
        /// The largest identifier of that format.
        max: u32,
    },
    /// More than 8 payload bytes were given.
    #[error("CAN payload of {len} bytes exceeds the classic CAN maximum of 8; split the data")]
    TooManyBytes {
        /// The rejected payload length.
        len: usize,
    },
    /// A remote frame was requested with a data length code above 8.
    #[error("remote frame DLC {dlc} exceeds 8")]
    DlcTooLarge {
        /// The rejected DLC.
        dlc: u8,
    },
}

/// A validated CAN identifier.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CanId {
    /// Standard 11-bit identifier (0..=0x7FF).
    Standard(u16),
    /// Extended 29-bit identifier (0..=0x1FFF_FFFF).
    Extended(u32),
}

impl CanId {
    /// Builds a standard (11-bit) identifier, rejecting values above 0x7FF.
    pub fn standard(id: u16) -> Result<Self, CanFrameError> {
        if id > MAX_STANDARD_ID {
            return Err(CanFrameError::IdTooLarge {
                id: u32::from(id),
                bits: 11,
                max: u32::from(MAX_STANDARD_ID),
            });
        }
        Ok(CanId::Standard(id))
    }

    /// Builds an extended (29-bit) identifier, rejecting values above 0x1FFF_FFFF.
    pub fn extended(id: u32) -> Result<Self, CanFrameError> {
        if id > MAX_EXTENDED_ID {
            return Err(CanFrameError::IdTooLarge {
                id,
                bits: 29,
                max: MAX_EXTENDED_ID,
            });
        }
        Ok(CanId::Extended(id))
    }

    /// The numeric identifier.
    pub fn raw(self) -> u32 {
        match self {
            CanId::Standard(id) => u32::from(id),
            CanId::Extended(id) => id,
        }
    }

    /// True for a 29-bit identifier.
    pub fn is_extended(self) -> bool {
        matches!(self, CanId::Extended(_))
    }

    /// Checks the stored value against its format (variants are public, so a
    /// hand-built `CanId::Standard(0xFFFF)` must still be rejected).
    fn validate(self) -> Result<Self, CanFrameError> {
        match self {
            CanId::Standard(id) => CanId::standard(id),
            CanId::Extended(id) => CanId::extended(id),
        }
    }
}

impl fmt::Display for CanId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CanId::Standard(id) => write!(f, "{id:03X}"),
            CanId::Extended(id) => write!(f, "{id:08X}x"),
        }
    }
}

/// A classic CAN data or remote frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: CanId,
    data: [u8; MAX_DATA_LEN],
    dlc: u8,
    rtr: bool,
}

impl CanFrame {
    /// Builds a data frame; fails if the id is out of range or `data` has more than 8 bytes.
    pub fn new(id: CanId, data: &[u8]) -> Result<Self, CanFrameError> {
        let id = id.validate()?;
        if data.len() > MAX_DATA_LEN {
            return Err(CanFrameError::TooManyBytes { len: data.len() });
        }
        let mut buf = [0u8; MAX_DATA_LEN];
        for (slot, b) in buf.iter_mut().zip(data) {
            *slot = *b;
        }
        Ok(CanFrame {
            id,
            data: buf,
            // data.len() <= 8 was checked above.
            dlc: data.len() as u8,
            rtr: false,
        })
    }

    /// Builds a data frame with a standard (11-bit) identifier.
    pub fn new_standard(id: u16, data: &[u8]) -> Result<Self, CanFrameError> {
        CanFrame::new(CanId::standard(id)?, data)
    }

    /// Builds a data frame with an extended (29-bit) identifier.
    pub fn new_extended(id: u32, data: &[u8]) -> Result<Self, CanFrameError> {
        CanFrame::new(CanId::extended(id)?, data)
    }

    /// Builds a remote (RTR) frame requesting `dlc` bytes (0..=8); it carries no data.
    pub fn new_remote(id: CanId, dlc: u8) -> Result<Self, CanFrameError> {
        let id = id.validate()?;
        if usize::from(dlc) > MAX_DATA_LEN {
            return Err(CanFrameError::DlcTooLarge { dlc });
        }
        Ok(CanFrame {
            id,
            data: [0; MAX_DATA_LEN],
            dlc,
            rtr: true,
        })
    }

    /// Infallible constructor for codecs: masks the id to 11 bits and keeps at
    /// most 8 bytes. Only for ids and payloads the caller built itself.
    pub(crate) fn standard_masked(id: u16, data: &[u8]) -> CanFrame {
        let len = data.len().min(MAX_DATA_LEN);
        let mut buf = [0u8; MAX_DATA_LEN];
        for (slot, b) in buf.iter_mut().zip(data) {
            *slot = *b;
        }
        CanFrame {
            id: CanId::Standard(id & MAX_STANDARD_ID),
            data: buf,
            dlc: len as u8,
            rtr: false,
        }
    }

    /// The frame identifier.
    pub fn id(&self) -> CanId {
        self.id
    }

    /// The numeric identifier (11 or 29 bits).
    pub fn raw_id(&self) -> u32 {
        self.id.raw()
    }

    /// True for a 29-bit identifier.
    pub fn is_extended(&self) -> bool {
        self.id.is_extended()
    }

    /// True for a remote transmission request.
    pub fn is_remote(&self) -> bool {
        self.rtr
    }

    /// Data length code: payload length, or the requested length of a remote frame.
    pub fn dlc(&self) -> u8 {
        self.dlc
    }

    /// The payload (empty for a remote frame).
    pub fn data(&self) -> &[u8] {
        if self.rtr {
            &[]
        } else {
            self.data.get(..usize::from(self.dlc)).unwrap_or(&[])
        }
    }
}

impl fmt::Display for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} [{}]", self.id, self.dlc)?;
        if self.rtr {
            return write!(f, " RTR");
        }
        for b in self.data() {
            write!(f, " {b:02X}")?;
        }
        Ok(())
    }
}
