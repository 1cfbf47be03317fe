//! The CDS short time stamp of every TM packet.

use std::fmt;

use mib::config::TIMESTAMP_LEN;
use serde::Serialize;

use super::CDS_PFIELD;

/// A CDS short time stamp (p-field, days since 1958-01-01, ms of day).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct CdsShort {
    pub days: u16,
    pub ms_of_day: u32,
}

impl CdsShort {
    pub fn parse(b: &[u8]) -> Option<CdsShort> {
        let t = mib_wire::CdsTime::parse(b.get(..TIMESTAMP_LEN)?).ok()?;
        Some(CdsShort::from_wire(&t))
    }
    pub fn from_wire(t: &mib_wire::CdsTime) -> CdsShort {
        CdsShort {
            days: t.days,
            ms_of_day: t.ms_of_day,
        }
    }
    fn wire(self) -> mib_wire::CdsTime {
        mib_wire::CdsTime {
            pfield: CDS_PFIELD,
            days: self.days,
            ms_of_day: self.ms_of_day,
        }
    }
    pub fn to_bytes(self) -> [u8; TIMESTAMP_LEN] {
        self.wire().to_bytes()
    }
    /// Milliseconds since the Unix epoch.
    pub fn unix_ms(self) -> i64 {
        self.wire().unix_ms()
    }
    pub fn from_unix_ms(ms: i64) -> CdsShort {
        CdsShort::from_wire(&mib_wire::CdsTime::from_unix_ms(ms))
    }
    pub fn now() -> CdsShort {
        CdsShort::from_unix_ms(chrono::Utc::now().timestamp_millis())
    }
}

impl fmt::Display for CdsShort {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match chrono::DateTime::from_timestamp_millis(self.unix_ms()) {
            Some(t) => write!(f, "{}", t.format("%Y-%m-%dT%H:%M:%S%.3fZ")),
            None => write!(f, "days {} ms {}", self.days, self.ms_of_day),
        }
    }
}
