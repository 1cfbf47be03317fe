//! Everything the collector needs to know about the obsw's side of the link, in one
//! place: how to subscribe and renew the lease, how to ask the on-board store for a
//! range, how to read the store's end report, how to recognise a reboot.
//!
//! The TCs are looked up by MIB name at run time, so the collector uses store retrieval
//! by sequence-count range (TC[15,128] `STORE_DOWNLINK_SEQ`) when the MIB has it and
//! falls back to the whole-store downlink otherwise; the archive keeps each packet once
//! either way.

use mib::tc::TcDef;

use crate::pus::{self, BuiltTc, Tm, TmBody};

use super::tracker::Pos;

/// How often the lease of the downlink subscription is renewed (every accepted TC
/// renews it; a ping is the cheapest). A third of the obsw's lease, so two renewals
/// may be lost in a row.
pub const LEASE_RENEW_MS: i64 = 1_000;

/// On-board APID of a robot.
pub fn apid(robot: u8) -> Option<u16> {
    mib::apid::robot_apid(robot)
}

fn def(name: &str) -> Option<&'static TcDef> {
    mib::tc::by_name(name)
}

/// The TC that subscribes to (or renews) the downlink: a connection test.
pub fn subscribe_tc(robot: u8, seq: u16) -> Option<BuiltTc> {
    pus::build_tc(robot, seq, def("PING")?, &[]).ok()
}

/// Sets the collection interval of a housekeeping structure.
pub fn hk_interval_tc(robot: u8, seq: u16, sid: u16, interval_ms: u32) -> Option<BuiltTc> {
    pus::build_tc(robot, seq, def("HK_SET_INTERVAL")?, &[sid as i64, interval_ms as i64]).ok()
}

/// Asks the on-board store for the packets of `apid` with sequence counts
/// `first..=last` (mod 2^14). `true` in the result: a range request; `false`: the MIB
/// has no range retrieval and the whole store is asked for.
pub fn store_range_tc(robot: u8, seq: u16, apid: u16, first: u16, last: u16) -> Option<(BuiltTc, bool)> {
    if let Some(d) = def("STORE_DOWNLINK_SEQ") {
        return pus::build_tc(robot, seq, d, &[apid as i64, first as i64, last as i64])
            .ok()
            .map(|t| (t, true));
    }
    let d = def("STORE_DOWNLINK")?;
    pus::build_tc(robot, seq, d, &[]).ok().map(|t| (t, false))
}

/// Whether this TM is the obsw's BOOT event (its sequence counts restart).
pub fn is_boot(tm: &Tm) -> bool {
    matches!(&tm.body, TmBody::Event(e) if e.id == mib::events::eid::BOOT)
}

/// The store's end report TM[15,19]: packets sent and, when the MIB's layout has them,
/// the oldest packet still stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoreDone {
    pub packets: Option<i64>,
    pub oldest: Option<Pos>,
    pub overwritten: Option<i64>,
}

/// Reads a TM[15,19] (`None` for other TM).
pub fn store_done(tm: &Tm, _raw: &[u8]) -> Option<StoreDone> {
    let TmBody::StoreDownlinkDone {
        packets,
        oldest_time,
        oldest_seq,
        overwritten,
    } = &tm.body
    else {
        return None;
    };
    let oldest = (*packets > 0 || oldest_time.days > 0 || oldest_time.ms_of_day > 0).then_some(Pos {
        seq: oldest_seq & 0x3FFF,
        obt_ms: oldest_time.unix_ms(),
    });
    Some(StoreDone {
        packets: Some(i64::from(*packets)),
        oldest,
        overwritten: Some(i64::from(*overwritten)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subscription_and_store_requests_build_from_the_mib() {
        let t = subscribe_tc(1, 5).unwrap();
        assert_eq!((t.def.service, t.def.subservice, t.seq), (17, 1, 5));
        let (t, _) = store_range_tc(1, 6, 0x101, 10, 20).unwrap();
        assert_eq!(t.def.service, 15);
        let h = hk_interval_tc(2, 7, 1, 100).unwrap();
        assert_eq!(h.args, vec![1, 100]);
    }

    #[test]
    fn store_end_report_is_read_with_the_mib_layout() {
        let ts = pus::CdsShort::from_unix_ms(1_000_000).to_bytes();
        // packets u32, oldest time (CDS short), oldest seq u16, overwritten u32.
        let mut data = vec![0, 0, 0, 7];
        data.extend_from_slice(&ts);
        data.extend_from_slice(&42u16.to_be_bytes());
        data.extend_from_slice(&3u32.to_be_bytes());
        let raw = pus::build_tm(0x101, 9, 15, 19, 0, &ts, &data);
        let tm = pus::decode_tm(&raw).unwrap();
        let d = store_done(&tm, &raw).unwrap();
        assert_eq!(d.packets, Some(7));
        assert_eq!(
            d.oldest,
            Some(Pos {
                seq: 42,
                obt_ms: 1_000_000
            })
        );
        assert_eq!(d.overwritten, Some(3));
    }
}
