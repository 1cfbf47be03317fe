//! Why a packet does not decode ([`DecodeError`]) or a TC cannot be built ([`BuildError`]).

use std::fmt;

use mib::config::MAX_PACKET_LEN;
use mib_wire::codec::ArgError;
use mib_wire::header::HeaderError;

/// Why a packet could not be decoded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum DecodeError {
    /// Fewer bytes than the header or the length field promise.
    #[error("truncated packet: need {need} bytes, have {have}")]
    Truncated { need: usize, have: usize },
    /// Length field beyond the largest packet of this mission.
    #[error("packet length {len} exceeds {MAX_PACKET_LEN}")]
    TooLong { len: usize },
    /// CCSDS version not 0, no secondary header, or not PUS-C.
    #[error("not a PUS-C packet: {reason}")]
    NotPus { reason: &'static str },
    /// Packet error control does not match.
    #[error("CRC mismatch: received 0x{received:04X}, computed 0x{computed:04X}")]
    Crc { received: u16, computed: u16 },
    /// Source or application data does not match its MIB definition.
    #[error("bad data field: {what}")]
    Data { what: String },
}

/// Why a TC could not be built.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum BuildError {
    /// Robot number outside the MIB's range.
    #[error("robot {0} is not in the MIB (robots {min}..={max})", min = mib::apid::ROBOT_MIN, max = mib::apid::ROBOT_MAX)]
    UnknownRobot(u8),
    /// Arguments refused by the MIB (count or range).
    #[error("{}", ArgsRefused { tc, err })]
    Args { tc: &'static str, err: ArgError },
    /// Application data too long for a TC.
    #[error("application data of {0} bytes is too long")]
    TooLong(usize),
}

/// [`BuildError::Args`]'s text: the argument named from the MIB where it can be.
struct ArgsRefused<'a> {
    tc: &'a str,
    err: &'a ArgError,
}

impl fmt::Display for ArgsRefused<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let tc = self.tc;
        match self.err {
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
        }
    }
}

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
