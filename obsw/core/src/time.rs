//! On-board time. The core never reads a clock: callers pass `now_ms`, the monotonic
//! milliseconds since boot. The epoch (Unix milliseconds at boot) comes from the host
//! clock or from time correlation, and turns `now_ms` into CDS short time stamps.

use satrs::spacepackets::time::cds::{CdsBase, CdsTime};
use satrs::spacepackets::time::DAYS_CCSDS_TO_UNIX;

/// Days from the CCSDS epoch (1958-01-01) to the Unix epoch.
const CCSDS_TO_UNIX_DAYS: u64 = DAYS_CCSDS_TO_UNIX.unsigned_abs() as u64;
const MS_PER_DAY: u64 = 86_400_000;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OnboardTime {
    /// Unix time in ms at `now_ms == 0`.
    pub epoch_unix_ms: u64,
}

impl OnboardTime {
    pub const fn new(epoch_unix_ms: u64) -> Self {
        OnboardTime { epoch_unix_ms }
    }

    /// CDS short time stamp (16-bit days, ms of day) of `now_ms`.
    pub fn cds(&self, now_ms: u64) -> [u8; mib::config::TIMESTAMP_LEN] {
        let unix = self.epoch_unix_ms + now_ms;
        let days = (unix / MS_PER_DAY + CCSDS_TO_UNIX_DAYS).min(u16::MAX as u64) as u16;
        let ms = (unix % MS_PER_DAY) as u32;
        let mut out = [0u8; mib::config::TIMESTAMP_LEN];
        // A 7-byte buffer always fits a 16-bit-day CDS stamp.
        let _ = CdsTime::new_with_u16_days(days, ms).write_to_bytes(&mut out);
        out
    }

    /// The same time stamp as the wire crate's `CdsTime` (for report bodies).
    pub fn cds_time(&self, now_ms: u64) -> mib_wire::CdsTime {
        let b = self.cds(now_ms);
        mib_wire::CdsTime {
            pfield: b[0],
            days: u16::from_be_bytes([b[1], b[2]]),
            ms_of_day: u32::from_be_bytes([b[3], b[4], b[5], b[6]]),
        }
    }

    /// On-board `now_ms` of a CDS short time stamp, or `None` if it is malformed or
    /// before boot.
    pub fn from_cds(&self, stamp: &[u8]) -> Option<u64> {
        let t = CdsTime::from_bytes_with_u16_days(stamp).ok()?;
        let days = t.ccsds_days() as u64;
        let unix = days.checked_sub(CCSDS_TO_UNIX_DAYS)? * MS_PER_DAY + t.ms_of_day() as u64;
        unix.checked_sub(self.epoch_unix_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: PUS-PKT-04
    #[test]
    fn cds_round_trips_through_on_board_time() {
        let t = OnboardTime::new(1_790_000_000_000);
        for now in [0u64, 1, 999, 86_399_999, 86_400_000, 123_456_789] {
            assert_eq!(t.from_cds(&t.cds(now)), Some(now));
        }
        // 2026-09-21 is CCSDS day 4383 + 20717
        let stamp = t.cds(0);
        assert_eq!(
            u16::from_be_bytes([stamp[1], stamp[2]]) as u64,
            1_790_000_000_000 / MS_PER_DAY + 4383
        );
    }
    // verifies: PUS-11-02
    #[test]
    fn malformed_or_past_stamps_are_rejected() {
        let t = OnboardTime::new(1_790_000_000_000);
        assert_eq!(t.from_cds(&[0x40, 0, 0, 0, 0, 0, 0]), None);
        assert_eq!(t.from_cds(&[1, 2]), None);
    }
}
