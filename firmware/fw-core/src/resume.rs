//! On-board time across a reset of a board without a real-time clock. The boards count
//! milliseconds from boot; with an epoch of 0 every reset would start the on-board time
//! again at 1970-01-01 while the flash store still holds the previous run's packets with
//! later time stamps. Time would go backwards at each reset: the ground takes a sequence
//! count that goes back with a later on-board time for a restart whose counts began
//! again (and declares the outage's holes lost), and a retrieval by time range would mix
//! two runs. So the epoch goes on from the newest time stamp the store holds: the new
//! run's time begins one millisecond after it. The time spent in the reset itself is not
//! counted (the board cannot know it); time correlation (PUS 9) sets the true time.

use mib_wire::header::TmPacket;
use obsw_core::time::OnboardTime;
use obsw_core::tm::TmStore;

/// The epoch (Unix milliseconds at `now_ms == 0`) of a board whose store is `store`:
/// one millisecond after the newest time stamp of a stored packet, or 0 (1970) when the
/// store holds none.
pub fn epoch_after_store<S: TmStore>(store: &mut S) -> u64 {
    let unix = OnboardTime::new(0);
    let mut newest: Option<u64> = None;
    store.visit(&mut |p| {
        let Ok(t) = TmPacket::parse(p) else { return };
        let d = t.time.days.to_be_bytes();
        let m = t.time.ms_of_day.to_be_bytes();
        let stamp = [t.time.pfield, d[0], d[1], m[0], m[1], m[2], m[3]];
        if let Some(ms) = unix.from_cds(&stamp) {
            newest = Some(newest.map_or(ms, |n| n.max(ms)));
        }
    });
    newest.map_or(0, |n| n + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::config::MAX_PACKET_LEN;
    use obsw_core::tm::{RingStore, TmWriter};

    /// Unix milliseconds of a TM packet's time stamp.
    fn unix_ms(p: &[u8]) -> u64 {
        let mut store = RingStore::<2048>::default();
        store.push(p);
        epoch_after_store(&mut store) - 1
    }

    // verifies: FW-TIME-01
    #[test]
    fn the_epoch_after_a_reset_follows_the_newest_stored_packet() {
        let mut store = RingStore::<4096>::default();
        assert_eq!(epoch_after_store(&mut store), 0, "an empty store: the epoch of 1970");
        // A previous run (epoch E) stored packets up to 5 s after its boot, not in time
        // order (the flash store merges its two areas by time on reading).
        let e = 1_790_000_000_000;
        let mut w = TmWriter::new(0x101, OnboardTime::new(e));
        let mut buf = [0u8; MAX_PACKET_LEN];
        for now in [1_000u64, 5_000, 3_000] {
            let n = w.build(now, 17, 2, &[], &mut buf).expect("a TM packet");
            store.push(&buf[..n]);
        }
        let epoch = epoch_after_store(&mut store);
        assert_eq!(epoch, e + 5_001);
        // The new run's first packet is stamped after every stored one.
        let mut next = TmWriter::new(0x101, OnboardTime::new(epoch));
        let n = next.build(0, 17, 2, &[], &mut buf).expect("a TM packet");
        assert_eq!(unix_ms(&buf[..n]), e + 5_001);
        // A store of packets that are not TM gives no epoch from them.
        let mut junk = RingStore::<256>::default();
        junk.push(&[0x08, 0x01, 0xC0, 0x00, 0x00, 0x01, 0xFF]);
        assert_eq!(epoch_after_store(&mut junk), 0);
    }
}
