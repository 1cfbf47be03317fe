//! PUS 15 on-board storage: every TM packet is also kept in the store (a ring that
//! overwrites the oldest packets, counted) until it is deleted. The ground asks for
//! what it misses by range — a time span (ECSS TC[15,9]) or, mission-specific, an
//! APID and sequence-count range (TC[15,128]). Replayed packets are the stored bytes:
//! they keep their original sequence count and time. TM[15,19] ends each downlink
//! with what was sent and what is gone (the oldest packet still stored, the count of
//! overwritten packets): anything older than that oldest packet is unrecoverable.

use mib_wire::tm;

use crate::accept::Tc;
use crate::failure::Failure;
use crate::obsw::Obsw;
use crate::request::unknown;
use crate::tm::{TmSink, TmStore};

/// A CDS short time (days since 1958, ms of day), ordered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Cds {
    pub days: u16,
    pub ms: u32,
}

/// Which stored packets a downlink sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Range {
    /// Time stamp in [start, end].
    Time { start: Cds, end: Cds },
    /// APID `apid`, sequence count in [first, last] modulo 2^14 (wraps when first > last).
    Seq { apid: u16, first: u16, last: u16 },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[15,1]
    Enable,
    /// TC[15,2]
    Disable,
    /// TC[15,9] and TC[15,128]: downlink a range, then TM[15,19].
    Downlink(Range),
    /// TC[15,11]
    Delete,
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        use mib_wire::args::{StoreDownlinkSeq, StoreDownlinkTime};
        Ok(match tc.subservice {
            1 => Request::Enable,
            2 => Request::Disable,
            9 => {
                let x = StoreDownlinkTime::of(&tc.args);
                Request::Downlink(Range::Time {
                    start: Cds {
                        days: x.start_days,
                        ms: x.start_ms,
                    },
                    end: Cds {
                        days: x.end_days,
                        ms: x.end_ms,
                    },
                })
            }
            11 => Request::Delete,
            128 => {
                let x = StoreDownlinkSeq::of(&tc.args);
                Request::Downlink(Range::Seq {
                    apid: x.apid,
                    first: x.first_seq,
                    last: x.last_seq,
                })
            }
            _ => return Err(unknown(tc)),
        })
    }
}

/// APID, sequence count and time of a stored TM packet (headers as the wire crate
/// reads them; the store holds only packets the TM writer made, so no CRC check).
fn identify(p: &[u8]) -> Option<(u16, u16, Cds)> {
    use mib_wire::header::{PRIMARY_HEADER_LEN, TM_SEC_HEADER_LEN};
    let h = mib_wire::header::Primary::parse(p).ok()?;
    let at = PRIMARY_HEADER_LEN + TM_SEC_HEADER_LEN;
    let t = mib_wire::CdsTime::parse(p.get(at..at + mib::config::TIMESTAMP_LEN)?).ok()?;
    Some((
        h.apid,
        h.seq_count,
        Cds {
            days: t.days,
            ms: t.ms_of_day,
        },
    ))
}

impl Range {
    fn contains(&self, apid: u16, seq: u16, t: Cds) -> bool {
        match *self {
            Range::Time { start, end } => start <= t && t <= end,
            Range::Seq { apid: a, first, last } => {
                a == apid
                    && if first <= last {
                        (first..=last).contains(&seq)
                    } else {
                        seq >= first || seq <= last
                    }
            }
        }
    }
    /// Packets that count for "oldest still stored": the request's APID, or all.
    fn same_stream(&self, apid: u16) -> bool {
        match *self {
            Range::Time { .. } => true,
            Range::Seq { apid: a, .. } => a == apid,
        }
    }
}

impl<S: TmStore> Obsw<S> {
    pub(crate) fn storage_request(&mut self, now: u64, r: Request, sink: &mut impl TmSink) -> Result<(), Failure> {
        match r {
            Request::Enable => self.dl.store_enabled = true,
            Request::Disable => self.dl.store_enabled = false,
            Request::Downlink(range) => self.downlink_range(now, range, sink)?,
            Request::Delete => self.dl.store.clear(),
        }
        Ok(())
    }

    fn downlink_range(&mut self, now: u64, range: Range, sink: &mut impl TmSink) -> Result<(), Failure> {
        if !self.dl.store_enabled {
            return Err(Failure::store_disabled());
        }
        let mut sent: u32 = 0;
        let mut oldest: Option<(u16, Cds)> = None;
        self.dl.store.visit(&mut |p| {
            let Some((apid, seq, t)) = identify(p) else { return };
            if oldest.is_none() && range.same_stream(apid) {
                oldest = Some((seq, t));
            }
            if range.contains(apid, seq, t) {
                sink.send_replay(p);
                sent += 1;
            }
        });
        // An empty store reports time and sequence count 0.
        let (oldest_seq, t) = oldest.unwrap_or((0, Cds { days: 0, ms: 0 }));
        let r = tm::StoreDownlinkDone {
            packets: sent,
            oldest_time: mib_wire::CdsTime {
                pfield: mib_wire::header::CDS_PFIELD,
                days: t.days,
                ms_of_day: t.ms,
            },
            oldest_seq,
            overwritten: self.dl.store_dropped,
        };
        self.emit_tm(now, r, sink);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obsw::tests::{failure, kind, obsw, of, send, TestObsw, APID};
    use mib::FailureCode;

    fn end(pkts: &[Vec<u8>]) -> tm::StoreDownlinkDone {
        tm::StoreDownlinkDone::parse(kind(&of(pkts, 15, 19)[0]).2).expect("TM[15,19] parses")
    }

    fn seq(p: &[u8]) -> u16 {
        mib::headers::SeqCount::new(u16::from_be_bytes([p[2], p[3]])).get()
    }

    fn by_seq(o: &mut TestObsw, now: u64, tc_seq: u16, first: u16, last: u16) -> Vec<Vec<u8>> {
        let mut app = APID.to_be_bytes().to_vec();
        app.extend_from_slice(&first.to_be_bytes());
        app.extend_from_slice(&last.to_be_bytes());
        send(o, now, tc_seq, 15, 128, &app)
    }

    /// Replayed packets in a downlink's output: those sent before its own reports.
    fn replayed(pkts: &[Vec<u8>], live_from: u16) -> Vec<Vec<u8>> {
        pkts.iter().filter(|p| seq(p) < live_from).cloned().collect()
    }

    // verifies: PUS-15-01
    #[test]
    fn a_sequence_range_replays_exactly_those_packets_unchanged() {
        let mut o = obsw();
        let mut all = Vec::new();
        for i in 0..5 {
            all.extend(send(&mut o, 10 * i as u64, i, 17, 1, &[]));
        }
        // 5 pings x (1,1 17,2 1,3 1,7) = sequence counts 0..=19.
        let pkts = by_seq(&mut o, 100, 9, 4, 7);
        let r = replayed(&pkts, 20);
        assert_eq!(
            r,
            all[4..8].to_vec(),
            "the stored bytes: original sequence count and time"
        );
        let end = kind(&of(&pkts, 15, 19)[0]).2.to_vec();
        assert_eq!(u32::from_be_bytes(end[..4].try_into().unwrap()), 4);
        assert_eq!(u16::from_be_bytes([end[10], end[11]]), 0, "oldest stored is seq 0");
        assert_eq!(
            u32::from_be_bytes(end[12..16].try_into().unwrap()),
            0,
            "nothing overwritten"
        );
        // The store is unchanged: the same range again.
        assert_eq!(replayed(&by_seq(&mut o, 200, 10, 4, 7), 20), all[4..8].to_vec());
    }

    // verifies: PUS-15-01
    #[test]
    fn a_time_span_replays_the_packets_stamped_inside_it() {
        let mut o = obsw();
        send(&mut o, 1000, 1, 17, 1, &[]);
        let mid = send(&mut o, 2000, 2, 17, 1, &[]);
        send(&mut o, 3000, 3, 17, 1, &[]);
        let cds = |t: u64| {
            let s = o.dl.tmw.time.cds(t);
            (
                u16::from_be_bytes([s[1], s[2]]),
                u32::from_be_bytes([s[3], s[4], s[5], s[6]]),
            )
        };
        let (sd, sm) = cds(1500);
        let (ed, em) = cds(2500);
        let mut app = sd.to_be_bytes().to_vec();
        app.extend_from_slice(&sm.to_be_bytes());
        app.extend_from_slice(&ed.to_be_bytes());
        app.extend_from_slice(&em.to_be_bytes());
        let pkts = send(&mut o, 4000, 4, 15, 9, &app);
        assert_eq!(replayed(&pkts, 12), mid);
    }

    // verifies: PUS-15-01, PUS-15-02
    #[test]
    fn the_end_report_says_what_was_overwritten_and_a_disabled_store_refuses() {
        let mut o = obsw();
        // Fill the 8 KiB test store well past its capacity with pings.
        for i in 0..200u16 {
            send(&mut o, i as u64, i, 17, 1, &[]);
        }
        let pkts = by_seq(&mut o, 500, 300, 0, 3);
        assert!(replayed(&pkts, 800).is_empty(), "the first packets are gone");
        let e = end(&pkts);
        let (oldest, overwritten) = (e.oldest_seq, e.overwritten);
        assert!(
            oldest > 3 && overwritten as u16 == oldest,
            "oldest {oldest}, overwritten {overwritten}"
        );
        send(&mut o, 600, 301, 15, 2, &[]);
        let pkts = by_seq(&mut o, 700, 302, 0, 3);
        assert_eq!(
            failure(&of(&pkts, 1, 4)[0]),
            (FailureCode::STORE_DISABLED.code(), vec![])
        );
    }

    // verifies: PUS-15-01
    #[test]
    fn a_sequence_range_wraps_through_16383() {
        let r = Range::Seq {
            apid: APID,
            first: 16380,
            last: 2,
        };
        let t = Cds { days: 0, ms: 0 };
        assert!(r.contains(APID, 16383, t) && r.contains(APID, 0, t) && r.contains(APID, 2, t));
        assert!(!r.contains(APID, 3, t) && !r.contains(APID, 16379, t) && !r.contains(APID + 1, 0, t));
    }
}
