//! The frame link's errors.

use std::fmt;

use mib::link::sdls::TC_SPIS;
use mmic_link::persist::PersistError;
use mmic_link::sdls::SdlsError;

/// What went wrong.
#[derive(Debug)]
#[non_exhaustive]
pub enum LinkError {
    /// Socket error.
    Io(std::io::Error),
    /// Key or state file.
    Persist(PersistError),
    /// A packet longer than a TC frame carries (or shorter than a packet header).
    PacketLength { len: usize, max: usize },
    /// SDLS refused to protect a frame (counter store failed or exhausted).
    Sdls(SdlsError),
    /// The same key for both directions (GCM nonces would repeat).
    SameKey,
    /// Not a TC SPI of the mission (`mib::link::sdls::TC_SPIS`).
    NotTcSpi(u16),
    /// A packet the robot takes in AD frames only (`mib::cfdp::is_bypass_file_data`).
    NotBypass,
}

impl fmt::Display for LinkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkError::Io(e) => write!(f, "frame link socket: {e}"),
            LinkError::Persist(e) => write!(f, "{e}"),
            LinkError::PacketLength { len, max } => {
                write!(f, "a packet of {len} bytes does not fit a TC frame (7..={max} bytes)")
            }
            LinkError::Sdls(e) => write!(f, "SDLS: {e}"),
            LinkError::SameKey => write!(f, "the TC and TM keys are the same: each direction needs its own"),
            LinkError::NotTcSpi(s) => write!(f, "SPI {s} is not a TC SPI (the mission's are {TC_SPIS:?})"),
            LinkError::NotBypass => write!(f, "only class 2 CFDP file data travels in BD frames"),
        }
    }
}

impl std::error::Error for LinkError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LinkError::Io(e) => Some(e),
            LinkError::Persist(e) => Some(e),
            LinkError::PacketLength { .. }
            | LinkError::Sdls(_)
            | LinkError::SameKey
            | LinkError::NotTcSpi(_)
            | LinkError::NotBypass => None,
        }
    }
}

impl From<std::io::Error> for LinkError {
    fn from(e: std::io::Error) -> Self {
        LinkError::Io(e)
    }
}

impl From<PersistError> for LinkError {
    fn from(e: PersistError) -> Self {
        LinkError::Persist(e)
    }
}
