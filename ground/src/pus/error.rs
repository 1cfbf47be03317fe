//! Why a packet does not decode ([`DecodeError`]) or a TC cannot be built ([`BuildError`]).

use std::fmt;

use mib::codec::ArgError;
use mib::config::MAX_PACKET_LEN;
use mib_wire::header::HeaderError;

/// Why a packet could not be decoded.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum DecodeError {
    /// Fewer bytes than the header or the length field promise.
    Truncated { need: usize, have: usize },
    /// Length field beyond the largest packet of this mission.
    TooLong { len: usize },
    /// CCSDS version not 0, no secondary header, or not PUS-C.
    NotPus { reason: &'static str },
    /// Packet error control does not match.
    Crc { received: u16, computed: u16 },
    /// Source or application data does not match its MIB definition.
    Data { what: String },
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Truncated { need, have } => {
                write!(f, "truncated packet: need {need} bytes, have {have}")
            }
            DecodeError::TooLong { len } => {
                write!(f, "packet length {len} exceeds {MAX_PACKET_LEN}")
            }
            DecodeError::NotPus { reason } => write!(f, "not a PUS-C packet: {reason}"),
            DecodeError::Crc { received, computed } => {
                write!(f, "CRC mismatch: received 0x{received:04X}, computed 0x{computed:04X}")
            }
            DecodeError::Data { what } => write!(f, "bad data field: {what}"),
        }
    }
}

impl std::error::Error for DecodeError {}

/// Why a TC could not be built.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum BuildError {
    /// Robot number outside the MIB's range.
    UnknownRobot(u8),
    /// Arguments refused by the MIB (count or range).
    Args { tc: &'static str, err: ArgError },
    /// Application data too long for a TC.
    TooLong(usize),
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::UnknownRobot(n) => write!(
                f,
                "robot {n} is not in the MIB (robots {}..={})",
                mib::apid::ROBOT_MIN,
                mib::apid::ROBOT_MAX
            ),
            BuildError::Args { tc, err } => match err {
                ArgError::Length { got, expected } => {
                    write!(f, "{tc}: {got} arguments given, {expected} expected")
                }
                ArgError::OutOfRange { index, value } => {
                    let def = mib::tc::by_name(tc);
                    match def.and_then(|d| d.args.get(*index as usize)) {
                        Some(a) => write!(f, "{tc}: argument {} = {value} outside {}..={}", a.name, a.min, a.max),
                        None => write!(f, "{tc}: argument {index} = {value} out of range"),
                    }
                }
            },
            BuildError::TooLong(n) => write!(f, "application data of {n} bytes is too long"),
        }
    }
}

impl std::error::Error for BuildError {}

pub(super) fn header_err(e: HeaderError) -> DecodeError {
    match e {
        HeaderError::Truncated { need, have } => DecodeError::Truncated { need, have },
        HeaderError::TooLong { len } => DecodeError::TooLong { len },
        HeaderError::NotPus { reason } => DecodeError::NotPus { reason },
        HeaderError::WrongType { is_tc: true } => DecodeError::NotPus {
            reason: "packet is a TC, TM expected",
        },
        HeaderError::WrongType { is_tc: false } => DecodeError::NotPus {
            reason: "packet is a TM, TC expected",
        },
        HeaderError::Crc { received, computed } => DecodeError::Crc { received, computed },
        // HeaderError is non_exhaustive (another crate): a new kind is still an error.
        other => DecodeError::Data {
            what: other.to_string(),
        },
    }
}

pub(super) fn data_err(what: impl Into<String>) -> DecodeError {
    DecodeError::Data { what: what.into() }
}
