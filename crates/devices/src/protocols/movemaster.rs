//! Mitsubishi Movemaster command language (RV-M1 / RV-M2 controllers, RS-232).
//!
//! Framing: every command and every reply is one line of printable ASCII
//! terminated by a carriage return (`\r`, 0x0D). Some hosts and terminal
//! programs add a line feed after the CR; [`LineFramer`] tolerates it.
//! Reference: the Movemaster EX RV-M1 / RV-M2 instruction manuals (command
//! descriptions of `NT`, `SP`, `MJ`, `DJ`, `WH`, `ER`, `RS`).
//!
//! Only the subset rigcal uses is modelled:
//!
//! | command | meaning | encoded by [`Command::encode`] |
//! |---|---|---|
//! | `NT` | nest: return to the mechanical origin | `NT\r` |
//! | `SP n[,H\|L]` | speed 0..=9, optional acceleration H/L | `SP 5\r`, `SP 5,H\r` |
//! | `MJ a1,..,a5` | relative joint move in degrees | `MJ +10.0,-5.5,+0.0,+0.0,+0.0\r` |
//! | `DJ j,a` | relative move of joint j (1..=5) by a degrees | `DJ 2,+10.0\r` |
//! | `MP x,y,z,p,r` | move to a Cartesian pose (mm, degrees) in the controller's frame, solved by the controller's own nominal inverse kinematics | `MP +250.0,+0.0,+400.0,-90.0,+0.0\r` |
//! | `WH` | where: read the Cartesian pose | `WH\r` |
//! | `ER` | read the error status | `ER\r` |
//! | `RS` | reset the error mode | `RS\r` |
//!
//! # Number format
//! Angles travel as decimal fixed-point numbers ([`Decimal`]). **Encoding**
//! always writes an explicit sign (`+` for zero and positive values), the
//! integer part without leading zeros and exactly as many decimal places as
//! the number's scale (one by default: `+0.0`, `-5.5`). A space separates the
//! mnemonic from its parameters. **Decoding** (used by the emulator) accepts
//! what the manuals show being typed: an optional `+`/`-` sign, no sign,
//! trailing zeros (`10.50`), no decimal point (`10`), a bare leading or
//! trailing point (`.5`, `5.`), no space or several spaces after the
//! mnemonic and spaces around the commas. Mnemonics are upper case. `MJ`
//! and `MP` require all five values. `MP` values are written with one decimal
//! (0.1 mm, 0.1°) by [`Command::move_pose`], the controller's resolution.
//!
//! # Replies
//! `WH` answers `x,y,z,pitch,roll` (mm and degrees), e.g.
//! `+250.0,+0.0,+400.0,-90.0,+0.0\r` ([`WhereReply`]); `ER` answers `0\r`
//! (no error), `1\r` (error mode I, hardware) or `2\r` (error mode II,
//! position/format) ([`ErrorStatus`]). Reply decoders require the CR
//! terminator (`decode`) or take a line already split by [`LineFramer`]
//! (`decode_body`).
//!
//! # Rounding without drift
//! `MJ`/`DJ` are relative moves with a finite resolution. Rounding every
//! increment independently accumulates error; [`quantise_increment`] instead
//! rounds the *absolute* target to the resolution grid and sends the
//! difference to the absolute position already commanded, in integer counts,
//! so the sum of all increments always equals the last rounded target.

use std::fmt;

use thiserror::Error;

/// Default maximum line length accepted by [`LineFramer`] (bytes, without CR).
pub const DEFAULT_MAX_LINE: usize = 128;
/// Largest number of decimal places a [`Decimal`] or [`Resolution`] may have.
pub const MAX_DECIMALS: u8 = 4;
/// Largest magnitude of a [`Decimal`] mantissa (exclusive bound is 10^9).
const MAX_MANTISSA: i64 = 999_999_999;

/// Everything that can go wrong encoding or decoding Movemaster lines.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum MovemasterError {
    /// The line was empty (only a terminator or nothing at all).
    #[error("empty Movemaster line; expected a command or reply")]
    Empty,
    /// The line contained a byte that is not printable ASCII.
    #[error("byte {byte:#04x} at offset {offset} is not printable ASCII; check the baud rate / framing (default 9600 7E2)")]
    NotAscii {
        /// The offending byte.
        byte: u8,
        /// Its offset in the line.
        offset: usize,
    },
    /// A reply line was not terminated by CR.
    #[error("reply line is not terminated by CR; read until the CR arrives before decoding")]
    MissingTerminator,
    /// The mnemonic is not one of the supported commands.
    #[error(
        "unknown or unsupported Movemaster command {mnemonic:?}; supported: NT SP MJ DJ MP WH ER RS"
    )]
    UnknownCommand {
        /// The first two characters of the line (or the whole line if shorter).
        mnemonic: String,
    },
    /// A command or reply had the wrong number of comma-separated fields.
    #[error("{what} expects {expected} field(s), got {found}")]
    WrongFieldCount {
        /// What was being decoded (e.g. "MJ", "WH reply").
        what: &'static str,
        /// Number of fields required.
        expected: usize,
        /// Number of fields found.
        found: usize,
    },
    /// A field was not a number of the accepted form.
    #[error(
        "field {field} of {what} is not a valid number: {text:?} (expected [+|-]digits[.digits])"
    )]
    BadNumber {
        /// What was being decoded.
        what: &'static str,
        /// Zero-based field index.
        field: usize,
        /// The text of the field.
        text: String,
    },
    /// A value is outside the range the command or reply allows.
    #[error("{what} value {value} is out of range; allowed: {allowed}")]
    OutOfRange {
        /// What the value is (e.g. "speed", "joint number", "error code").
        what: &'static str,
        /// The rejected value as text.
        value: String,
        /// The allowed range, for the message.
        allowed: &'static str,
    },
    /// A number has more decimal places than supported.
    #[error("{text:?} has more than {max} decimal places")]
    TooManyDecimals {
        /// The number's text.
        text: String,
        /// The maximum number of decimal places.
        max: u8,
    },
    /// A floating-point input was NaN or infinite.
    #[error("{what} is not finite ({value}); check the kinematics that produced it")]
    NotFinite {
        /// What the value is.
        what: &'static str,
        /// The value as text (`NaN`, `inf`, `-inf`).
        value: String,
    },
    /// A line exceeded the framer's maximum length; bytes are discarded up to the next CR.
    #[error(
        "line longer than {max} bytes; discarding up to the next CR (noise or wrong baud rate?)"
    )]
    LineTooLong {
        /// The configured maximum.
        max: usize,
    },
}

/// Resolution of joint angles on the wire, as a number of decimal places
/// (1 by default, i.e. 0.1°). The rig file sets it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub struct Resolution {
    decimals: u8,
}

impl Default for Resolution {
    fn default() -> Self {
        Resolution { decimals: 1 }
    }
}

impl TryFrom<u8> for Resolution {
    type Error = MovemasterError;
    fn try_from(decimals: u8) -> Result<Self, Self::Error> {
        Resolution::new(decimals)
    }
}

impl From<Resolution> for u8 {
    fn from(r: Resolution) -> u8 {
        r.decimals
    }
}

impl Resolution {
    /// A resolution of `decimals` decimal places (0..=4).
    pub fn new(decimals: u8) -> Result<Self, MovemasterError> {
        if decimals > MAX_DECIMALS {
            return Err(MovemasterError::OutOfRange {
                what: "resolution decimals",
                value: decimals.to_string(),
                allowed: "0..=4",
            });
        }
        Ok(Resolution { decimals })
    }

    /// Number of decimal places.
    pub fn decimals(self) -> u8 {
        self.decimals
    }

    /// Size of one count in degrees (e.g. 0.1).
    pub fn step_deg(self) -> f64 {
        1.0 / pow10(self.decimals) as f64
    }

    /// Rounds `deg` to the nearest count (half away from zero).
    pub fn to_counts(self, deg: f64) -> Result<i64, MovemasterError> {
        if !deg.is_finite() {
            return Err(MovemasterError::NotFinite {
                what: "angle",
                value: deg.to_string(),
            });
        }
        let scaled = (deg * pow10(self.decimals) as f64).round();
        if scaled.abs() > MAX_MANTISSA as f64 {
            return Err(MovemasterError::OutOfRange {
                what: "angle",
                value: deg.to_string(),
                allowed: "|angle| * 10^decimals <= 999999999",
            });
        }
        // |scaled| <= MAX_MANTISSA, integral: the cast is exact.
        Ok(scaled as i64)
    }

    /// Degrees represented by `counts`.
    pub fn counts_to_deg(self, counts: i64) -> f64 {
        counts as f64 / pow10(self.decimals) as f64
    }
}

fn pow10(d: u8) -> i64 {
    10i64.pow(u32::from(d.min(MAX_DECIMALS)))
}

/// A decimal fixed-point number as written on the wire: `mantissa / 10^scale`.
///
/// Equality is by value: `+10.0` equals `10` and `10.00`.
#[derive(Debug, Clone, Copy)]
pub struct Decimal {
    mantissa: i64,
    scale: u8,
}

impl PartialEq for Decimal {
    fn eq(&self, other: &Self) -> bool {
        let s = self.scale.max(other.scale);
        i128::from(self.mantissa) * i128::from(pow10(s - self.scale))
            == i128::from(other.mantissa) * i128::from(pow10(s - other.scale))
    }
}
impl Eq for Decimal {}

impl Decimal {
    /// `mantissa / 10^scale`; rejects |mantissa| > 999 999 999 and scale > 4.
    pub fn new(mantissa: i64, scale: u8) -> Result<Self, MovemasterError> {
        if scale > MAX_DECIMALS {
            return Err(MovemasterError::OutOfRange {
                what: "decimal scale",
                value: scale.to_string(),
                allowed: "0..=4",
            });
        }
        if mantissa.unsigned_abs() > MAX_MANTISSA as u64 {
            return Err(MovemasterError::OutOfRange {
                what: "number",
                value: mantissa.to_string(),
                allowed: "|mantissa| <= 999999999",
            });
        }
        Ok(Decimal { mantissa, scale })
    }

    /// `counts` steps of `resolution` (e.g. 55 counts at 0.1° = 5.5°).
    pub fn from_counts(counts: i64, resolution: Resolution) -> Result<Self, MovemasterError> {
        Decimal::new(counts, resolution.decimals())
    }

    /// Rounds `deg` to `resolution` (half away from zero).
    pub fn from_f64(value: f64, resolution: Resolution) -> Result<Self, MovemasterError> {
        Decimal::from_counts(resolution.to_counts(value)?, resolution)
    }

    /// Zero with the given scale.
    pub fn zero(resolution: Resolution) -> Self {
        Decimal {
            mantissa: 0,
            scale: resolution.decimals(),
        }
    }

    /// Number of decimal places.
    pub fn scale(self) -> u8 {
        self.scale
    }

    /// The value as `f64`.
    pub fn to_f64(self) -> f64 {
        self.mantissa as f64 / pow10(self.scale) as f64
    }

    /// The value in counts of `resolution`, if it is exactly representable.
    pub fn to_counts(self, resolution: Resolution) -> Option<i64> {
        let r = resolution.decimals();
        if r >= self.scale {
            self.mantissa.checked_mul(pow10(r - self.scale))
        } else {
            let div = pow10(self.scale - r);
            (self.mantissa % div == 0).then_some(self.mantissa / div)
        }
    }

    fn write_to(self, out: &mut Vec<u8>) {
        let sign = if self.mantissa < 0 { '-' } else { '+' };
        let abs = self.mantissa.unsigned_abs();
        let div = pow10(self.scale) as u64;
        let text = if self.scale == 0 {
            format!("{sign}{abs}")
        } else {
            format!(
                "{sign}{}.{:0width$}",
                abs / div,
                abs % div,
                width = usize::from(self.scale)
            )
        };
        out.extend_from_slice(text.as_bytes());
    }

    /// Parses `[+|-]digits[.digits]` (also `.5`, `5.`), surrounding spaces allowed.
    fn parse(text: &[u8], what: &'static str, field: usize) -> Result<Self, MovemasterError> {
        let bad = || MovemasterError::BadNumber {
            what,
            field,
            text: String::from_utf8_lossy(text).into_owned(),
        };
        let t = trim_spaces(text);
        let (neg, rest) = match t.split_first() {
            Some((b'+', r)) => (false, r),
            Some((b'-', r)) => (true, r),
            _ => (false, t),
        };
        let (int_part, frac_part) = match rest.iter().position(|&b| b == b'.') {
            Some(p) => (
                rest.get(..p).unwrap_or_default(),
                rest.get(p + 1..).unwrap_or_default(),
            ),
            None => (rest, &[][..]),
        };
        if int_part.is_empty() && frac_part.is_empty() {
            return Err(bad());
        }
        if !int_part.iter().chain(frac_part).all(u8::is_ascii_digit) {
            return Err(bad());
        }
        if frac_part.len() > usize::from(MAX_DECIMALS) {
            return Err(MovemasterError::TooManyDecimals {
                text: String::from_utf8_lossy(t).into_owned(),
                max: MAX_DECIMALS,
            });
        }
        let mut mantissa: i64 = 0;
        for &d in int_part.iter().chain(frac_part) {
            mantissa = mantissa
                .checked_mul(10)
                .and_then(|m| m.checked_add(i64::from(d - b'0')))
                .filter(|m| *m <= MAX_MANTISSA)
                .ok_or_else(|| MovemasterError::OutOfRange {
                    what,
                    value: String::from_utf8_lossy(t).into_owned(),
                    allowed: "at most 9 significant digits",
                })?;
        }
        if neg {
            mantissa = -mantissa;
        }
        // frac_part.len() <= MAX_DECIMALS checked above.
        Decimal::new(mantissa, frac_part.len() as u8)
    }
}

impl fmt::Display for Decimal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut v = Vec::new();
        self.write_to(&mut v);
        f.write_str(&String::from_utf8_lossy(&v))
    }
}

/// Speed level for `SP` (0 = slowest .. 9 = fastest).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SpeedLevel(u8);

impl SpeedLevel {
    /// A speed level 0..=9.
    pub fn new(level: u8) -> Result<Self, MovemasterError> {
        if level > 9 {
            return Err(MovemasterError::OutOfRange {
                what: "speed",
                value: level.to_string(),
                allowed: "0..=9",
            });
        }
        Ok(SpeedLevel(level))
    }
    /// The level 0..=9.
    pub fn get(self) -> u8 {
        self.0
    }
}

/// Acceleration/deceleration time option of `SP n,H|L`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Acceleration {
    /// `H`: high acceleration (short acceleration time).
    High,
    /// `L`: low acceleration (long acceleration time).
    Low,
}

/// Joint number for `DJ` (1 = waist, 2 = shoulder, 3 = elbow, 4 = wrist pitch, 5 = wrist roll).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct JointNumber(u8);

impl JointNumber {
    /// A joint number 1..=5.
    pub fn new(joint: u8) -> Result<Self, MovemasterError> {
        if !(1..=5).contains(&joint) {
            return Err(MovemasterError::OutOfRange {
                what: "joint number",
                value: joint.to_string(),
                allowed: "1..=5",
            });
        }
        Ok(JointNumber(joint))
    }
    /// The joint number 1..=5.
    pub fn get(self) -> u8 {
        self.0
    }
}

/// A host → controller command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Command {
    /// `NT`: return to the mechanical origin (needed after power-on).
    Nest,
    /// `SP n[,H|L]`: set the speed level and optionally the acceleration.
    Speed {
        /// Speed level 0..=9.
        level: SpeedLevel,
        /// Optional acceleration option.
        accel: Option<Acceleration>,
    },
    /// `MJ a1,a2,a3,a4,a5`: relative joint move, degrees (waist..roll).
    MoveJoints([Decimal; 5]),
    /// `DJ j,a`: relative move of one joint by `angle` degrees.
    MoveJoint {
        /// Joint 1..=5.
        joint: JointNumber,
        /// Increment in degrees.
        angle: Decimal,
    },
    /// `MP x,y,z,p,r`: absolute Cartesian move to x, y, z (mm), pitch, roll (deg) in the
    /// controller's frame, solved by the controller's nominal inverse kinematics.
    MovePose([Decimal; 5]),
    /// `WH`: request the current Cartesian pose.
    Where,
    /// `ER`: request the error status.
    ErrorRead,
    /// `RS`: reset the error mode.
    Reset,
}

impl Command {
    /// `MP` to the pose `[x, y, z, pitch, roll]` (mm, deg), each rounded to one decimal
    /// (0.1 mm, 0.1°: the controller's resolution), half away from zero.
    pub fn move_pose(pose: &[f64; 5]) -> Result<Command, MovemasterError> {
        let res = Resolution::default();
        let mut values = [Decimal::zero(res); 5];
        for (slot, v) in values.iter_mut().zip(pose) {
            *slot = Decimal::from_f64(*v, res)?;
        }
        Ok(Command::MovePose(values))
    }

    /// The exact bytes of the command, CR included (see the module doc for the format).
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(48);
        match self {
            Command::Nest => out.extend_from_slice(b"NT"),
            Command::Speed { level, accel } => {
                out.extend_from_slice(format!("SP {}", level.get()).as_bytes());
                match accel {
                    Some(Acceleration::High) => out.extend_from_slice(b",H"),
                    Some(Acceleration::Low) => out.extend_from_slice(b",L"),
                    None => {}
                }
            }
            Command::MoveJoints(angles) => {
                out.extend_from_slice(b"MJ ");
                for (i, a) in angles.iter().enumerate() {
                    if i > 0 {
                        out.push(b',');
                    }
                    a.write_to(&mut out);
                }
            }
            Command::MoveJoint { joint, angle } => {
                out.extend_from_slice(format!("DJ {},", joint.get()).as_bytes());
                angle.write_to(&mut out);
            }
            Command::MovePose(values) => {
                out.extend_from_slice(b"MP ");
                for (i, v) in values.iter().enumerate() {
                    if i > 0 {
                        out.push(b',');
                    }
                    v.write_to(&mut out);
                }
            }
            Command::Where => out.extend_from_slice(b"WH"),
            Command::ErrorRead => out.extend_from_slice(b"ER"),
            Command::Reset => out.extend_from_slice(b"RS"),
        }
        out.push(b'\r');
        out
    }

    /// Parses one command line; a trailing `\r` (or `\r\n`) is optional.
    pub fn decode(line: &[u8]) -> Result<Command, MovemasterError> {
        let body = strip_optional_terminator(line);
        check_ascii(body)?;
        let body = trim_spaces(body);
        if body.is_empty() {
            return Err(MovemasterError::Empty);
        }
        let (mnemonic, args) = body.split_at(body.len().min(2));
        let args = trim_spaces(args);
        let no_args = |cmd: Command, what: &'static str| {
            if args.is_empty() {
                Ok(cmd)
            } else {
                Err(MovemasterError::WrongFieldCount {
                    what,
                    expected: 0,
                    found: split_fields(args).len(),
                })
            }
        };
        match mnemonic {
            b"NT" => no_args(Command::Nest, "NT"),
            b"WH" => no_args(Command::Where, "WH"),
            b"ER" => no_args(Command::ErrorRead, "ER"),
            b"RS" => no_args(Command::Reset, "RS"),
            b"SP" => {
                let fields = split_fields(args);
                let (level, accel) = match fields.as_slice() {
                    [level] => (level, None),
                    [level, accel] => (level, Some(trim_spaces(accel))),
                    _ => {
                        return Err(MovemasterError::WrongFieldCount {
                            what: "SP",
                            expected: 1,
                            found: fields.len(),
                        })
                    }
                };
                let level = SpeedLevel::new(parse_small_uint(level, "SP", 0)?)?;
                let accel = match accel {
                    None => None,
                    Some(b"H") => Some(Acceleration::High),
                    Some(b"L") => Some(Acceleration::Low),
                    Some(other) => {
                        return Err(MovemasterError::OutOfRange {
                            what: "SP acceleration",
                            value: String::from_utf8_lossy(other).into_owned(),
                            allowed: "H or L",
                        })
                    }
                };
                Ok(Command::Speed { level, accel })
            }
            b"MJ" => {
                let fields = split_fields(args);
                if fields.len() != 5 {
                    return Err(MovemasterError::WrongFieldCount {
                        what: "MJ",
                        expected: 5,
                        found: fields.len(),
                    });
                }
                let mut angles = [Decimal::zero(Resolution::default()); 5];
                for (i, (slot, f)) in angles.iter_mut().zip(&fields).enumerate() {
                    *slot = Decimal::parse(f, "MJ", i)?;
                }
                Ok(Command::MoveJoints(angles))
            }
            b"MP" => {
                let fields = split_fields(args);
                if fields.len() != 5 {
                    return Err(MovemasterError::WrongFieldCount {
                        what: "MP",
                        expected: 5,
                        found: fields.len(),
                    });
                }
                let mut values = [Decimal::zero(Resolution::default()); 5];
                for (i, (slot, f)) in values.iter_mut().zip(&fields).enumerate() {
                    *slot = Decimal::parse(f, "MP", i)?;
                }
                Ok(Command::MovePose(values))
            }
            b"DJ" => {
                let fields = split_fields(args);
                let [joint, angle] = fields.as_slice() else {
                    return Err(MovemasterError::WrongFieldCount {
                        what: "DJ",
                        expected: 2,
                        found: fields.len(),
                    });
                };
                let joint = JointNumber::new(parse_small_uint(joint, "DJ", 0)?)?;
                let angle = Decimal::parse(angle, "DJ", 1)?;
                Ok(Command::MoveJoint { joint, angle })
            }
            other => Err(MovemasterError::UnknownCommand {
                mnemonic: String::from_utf8_lossy(other).into_owned(),
            }),
        }
    }
}

/// Reply to `WH`: Cartesian pose of the hand (mm, degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WhereReply {
    /// X in mm.
    pub x: f64,
    /// Y in mm.
    pub y: f64,
    /// Z in mm.
    pub z: f64,
    /// Wrist pitch in degrees.
    pub pitch: f64,
    /// Wrist roll in degrees.
    pub roll: f64,
}

impl WhereReply {
    /// Encodes as the controller does: five signed values with one decimal,
    /// e.g. `+250.0,+0.0,+400.0,-90.0,+0.0\r`. Values are rounded to 0.1;
    /// non-finite values and magnitudes above 99 999 999.9 are written as `+0.0`.
    pub fn encode(&self) -> Vec<u8> {
        let res = Resolution::default();
        let mut out = Vec::with_capacity(48);
        for (i, v) in [self.x, self.y, self.z, self.pitch, self.roll]
            .into_iter()
            .enumerate()
        {
            if i > 0 {
                out.push(b',');
            }
            Decimal::from_f64(v, res)
                .unwrap_or_else(|_| Decimal::zero(res))
                .write_to(&mut out);
        }
        out.push(b'\r');
        out
    }

    /// Decodes a complete reply line, which must end with CR (CR LF accepted).
    pub fn decode(line: &[u8]) -> Result<Self, MovemasterError> {
        WhereReply::decode_body(strip_required_terminator(line)?)
    }

    /// Decodes a reply line already split off by [`LineFramer`] (no CR).
    pub fn decode_body(body: &[u8]) -> Result<Self, MovemasterError> {
        check_ascii(body)?;
        if trim_spaces(body).is_empty() {
            return Err(MovemasterError::Empty);
        }
        let fields = split_fields(body);
        if fields.len() != 5 {
            return Err(MovemasterError::WrongFieldCount {
                what: "WH reply",
                expected: 5,
                found: fields.len(),
            });
        }
        let mut v = [0.0f64; 5];
        for (i, (slot, f)) in v.iter_mut().zip(&fields).enumerate() {
            *slot = Decimal::parse(f, "WH reply", i)?.to_f64();
        }
        let [x, y, z, pitch, roll] = v;
        Ok(WhereReply {
            x,
            y,
            z,
            pitch,
            roll,
        })
    }
}

/// Reply to `ER`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorStatus {
    /// `0`: no error.
    None,
    /// `1`: error mode I (hardware error); needs the controller reset.
    Hardware,
    /// `2`: error mode II (position out of range / command format error); cleared by `RS`.
    Position,
}

impl ErrorStatus {
    /// The numeric code 0, 1 or 2.
    pub fn code(self) -> u8 {
        match self {
            ErrorStatus::None => 0,
            ErrorStatus::Hardware => 1,
            ErrorStatus::Position => 2,
        }
    }

    /// `0\r`, `1\r` or `2\r`.
    pub fn encode(self) -> Vec<u8> {
        vec![b'0' + self.code(), b'\r']
    }

    /// Decodes a complete reply line, which must end with CR (CR LF accepted).
    pub fn decode(line: &[u8]) -> Result<Self, MovemasterError> {
        ErrorStatus::decode_body(strip_required_terminator(line)?)
    }

    /// Decodes a reply line already split off by [`LineFramer`] (no CR).
    pub fn decode_body(body: &[u8]) -> Result<Self, MovemasterError> {
        check_ascii(body)?;
        let t = trim_spaces(body);
        if t.is_empty() {
            return Err(MovemasterError::Empty);
        }
        let fields = split_fields(t);
        if fields.len() != 1 {
            return Err(MovemasterError::WrongFieldCount {
                what: "ER reply",
                expected: 1,
                found: fields.len(),
            });
        }
        match parse_small_uint(t, "ER reply", 0)? {
            0 => Ok(ErrorStatus::None),
            1 => Ok(ErrorStatus::Hardware),
            2 => Ok(ErrorStatus::Position),
            n => Err(MovemasterError::OutOfRange {
                what: "error code",
                value: n.to_string(),
                allowed: "0, 1 or 2",
            }),
        }
    }
}

/// One quantised relative step produced by [`quantise_increment`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QuantisedStep {
    /// The increment to send, in counts of the resolution.
    pub increment_counts: i64,
    /// The increment to send, as a wire number.
    pub increment: Decimal,
    /// The new absolute commanded position, in counts (old + increment).
    pub commanded_counts: i64,
}

/// Relative increment towards an absolute target without accumulating rounding.
///
/// `target_abs_deg` is the desired absolute joint angle; `commanded_abs_counts`
/// is the absolute position already commanded, in counts of `resolution`
/// (the running sum of all increments sent, starting from the nest position).
/// The target is rounded to the grid *as an absolute value* and the increment
/// is the exact integer difference, so after any sequence of moves the sum of
/// increments equals the rounded last target.
pub fn quantise_increment(
    target_abs_deg: f64,
    commanded_abs_counts: i64,
    resolution: Resolution,
) -> Result<QuantisedStep, MovemasterError> {
    let target = resolution.to_counts(target_abs_deg)?;
    let increment_counts =
        target
            .checked_sub(commanded_abs_counts)
            .ok_or(MovemasterError::OutOfRange {
                what: "increment",
                value: format!("{target} - {commanded_abs_counts}"),
                allowed: "fits in i64",
            })?;
    let increment = Decimal::from_counts(increment_counts, resolution)?;
    Ok(QuantisedStep {
        increment_counts,
        increment,
        commanded_counts: target,
    })
}

/// [`quantise_increment`] for all five joints: returns the `MJ` command and the
/// new absolute commanded counts.
pub fn quantise_joint_move(
    targets_abs_deg: &[f64; 5],
    commanded_abs_counts: &[i64; 5],
    resolution: Resolution,
) -> Result<(Command, [i64; 5]), MovemasterError> {
    let mut angles = [Decimal::zero(resolution); 5];
    let mut commanded = *commanded_abs_counts;
    for ((angle, cmd), target) in angles
        .iter_mut()
        .zip(commanded.iter_mut())
        .zip(targets_abs_deg)
    {
        let step = quantise_increment(*target, *cmd, resolution)?;
        *angle = step.increment;
        *cmd = step.commanded_counts;
    }
    Ok((Command::MoveJoints(angles), commanded))
}

/// Splits a byte stream into CR-terminated lines (without the CR).
///
/// A LF directly after a CR is dropped. A line longer than the maximum
/// yields one [`MovemasterError::LineTooLong`]; bytes are then discarded
/// (and counted) until the next CR, after which framing resumes.
#[derive(Debug, Clone)]
pub struct LineFramer {
    buf: Vec<u8>,
    max_len: usize,
    discarding: bool,
    after_cr: bool,
    discarded: u64,
}

impl Default for LineFramer {
    fn default() -> Self {
        LineFramer::new(DEFAULT_MAX_LINE)
    }
}

impl LineFramer {
    /// A framer accepting lines of at most `max_len` bytes (at least 1).
    pub fn new(max_len: usize) -> Self {
        LineFramer {
            buf: Vec::new(),
            max_len: max_len.max(1),
            discarding: false,
            after_cr: false,
            discarded: 0,
        }
    }

    /// Feeds bytes; returns every line (or overflow error) completed by them, in order.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Result<Vec<u8>, MovemasterError>> {
        let mut out = Vec::new();
        for &b in bytes {
            if b == b'\r' {
                if self.discarding {
                    self.discarding = false;
                } else {
                    out.push(Ok(std::mem::take(&mut self.buf)));
                }
                self.after_cr = true;
                continue;
            }
            if b == b'\n' && self.after_cr {
                self.after_cr = false;
                continue;
            }
            self.after_cr = false;
            if self.discarding {
                self.discarded += 1;
                continue;
            }
            if self.buf.len() >= self.max_len {
                self.discarded += self.buf.len() as u64 + 1;
                self.buf.clear();
                self.discarding = true;
                out.push(Err(MovemasterError::LineTooLong { max: self.max_len }));
                continue;
            }
            self.buf.push(b);
        }
        out
    }

    /// Bytes of a partial line currently buffered.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Total bytes discarded because of over-long lines.
    pub fn discarded_bytes(&self) -> u64 {
        self.discarded
    }

    /// Drops any partial line (e.g. after a timeout) and leaves discard mode.
    pub fn reset(&mut self) {
        self.buf.clear();
        self.discarding = false;
        self.after_cr = false;
    }
}

fn strip_optional_terminator(line: &[u8]) -> &[u8] {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    line.strip_suffix(b"\r").unwrap_or(line)
}

fn strip_required_terminator(line: &[u8]) -> Result<&[u8], MovemasterError> {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    line.strip_suffix(b"\r")
        .ok_or(MovemasterError::MissingTerminator)
}

fn check_ascii(body: &[u8]) -> Result<(), MovemasterError> {
    match body.iter().position(|b| !(0x20..0x7F).contains(b)) {
        Some(offset) => Err(MovemasterError::NotAscii {
            byte: body.get(offset).copied().unwrap_or(0),
            offset,
        }),
        None => Ok(()),
    }
}

fn trim_spaces(mut t: &[u8]) -> &[u8] {
    while let Some((b' ', r)) = t.split_first() {
        t = r;
    }
    while let Some((b' ', r)) = t.split_last() {
        t = r;
    }
    t
}

fn split_fields(args: &[u8]) -> Vec<&[u8]> {
    if args.is_empty() {
        return Vec::new();
    }
    args.split(|&b| b == b',').collect()
}

fn parse_small_uint(text: &[u8], what: &'static str, field: usize) -> Result<u8, MovemasterError> {
    let t = trim_spaces(text);
    let bad = || MovemasterError::BadNumber {
        what,
        field,
        text: String::from_utf8_lossy(text).into_owned(),
    };
    if t.is_empty() || t.len() > 3 || !t.iter().all(u8::is_ascii_digit) {
        return Err(bad());
    }
    let v = t.iter().fold(0u16, |acc, d| acc * 10 + u16::from(d - b'0'));
    u8::try_from(v).map_err(|_| MovemasterError::OutOfRange {
        what,
        value: v.to_string(),
        allowed: "0..=255",
    })
}
