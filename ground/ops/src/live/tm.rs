//! What the tracker reads from TM: a packet's place, a restart, the store's end report.

use crate::pus::{Tm, TmBody};

use super::track::Pos;
use mib::headers::SeqCount;

/// A decoded TM's place in its APID's sequence: count and on-board time.
pub fn position(tm: &Tm) -> Pos {
    Pos {
        seq: tm.seq,
        obt_ms: tm.time.unix_ms(),
    }
}

/// The arguments of TC[15,9] `STORE_DOWNLINK_TIME` for the on-board times `from..=to`
/// (unix ms): start days, start ms of day, end days, end ms of day.
pub fn store_time_args(from: i64, to: i64) -> [i64; 4] {
    let (a, b) = (
        crate::pus::CdsShort::from_unix_ms(from),
        crate::pus::CdsShort::from_unix_ms(to),
    );
    [a.days.into(), a.ms_of_day.into(), b.days.into(), b.ms_of_day.into()]
}

/// The obsw's BOOT event: its sequence counts start again.
pub fn is_boot(tm: &Tm) -> bool {
    matches!(&tm.body, TmBody::Event(e) if e.id == mib::events::eid::BOOT)
}

/// The store's end report TM[15,19].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoreDone {
    pub packets: u32,
    /// The oldest packet still in the store (`None` when the store is empty).
    pub oldest: Option<Pos>,
    /// Stored packets overwritten since boot.
    pub overwritten: u32,
}

/// The CCSDS epoch (1958-01-01) in Unix ms.
const CCSDS_EPOCH_UNIX_MS: i64 = -4383 * 86_400_000;

/// Reads a TM[15,19] (`None` for other TM).
pub fn store_done(tm: &Tm) -> Option<StoreDone> {
    let Some(mib_wire::Tm::StoreDownlinkDone(d)) = tm.body.report() else {
        return None;
    };
    let oldest_ms = d.oldest_time.unix_ms();
    Some(StoreDone {
        packets: d.packets,
        // An empty store reports day 0, ms 0 (the CCSDS epoch) and count 0.
        oldest: (oldest_ms != CCSDS_EPOCH_UNIX_MS || d.oldest_seq > 0).then_some(Pos {
            seq: SeqCount::new(d.oldest_seq).get(),
            obt_ms: oldest_ms,
        }),
        overwritten: d.overwritten,
    })
}
