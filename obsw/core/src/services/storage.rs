//! PUS 15 on-board storage: every TM packet is also kept in the store (a ring that
//! overwrites the oldest packets, counted) until it is deleted. The ground asks for
//! what it misses by range — a time span (ECSS TC[15,9]) or, mission-specific, an
//! APID and sequence-count range (TC[15,128]). Replayed packets are the stored bytes:
//! they keep their original sequence count and time. TM[15,19] ends each downlink
//! with what was sent and what is gone (the oldest packet still stored, the count of
//! overwritten packets): anything older than that oldest packet is unrecoverable.
//!
//! A downlink is paced by the room the downlink has ([`TmSink::replay_room`]) and by the
//! packets it may read in a control period ([`TmStore::READS_PER_PERIOD`]; the flash
//! store's is `mib::memory::store::REPLAY_READS_PER_PERIOD`):
//! each period it reads a bounded slice of the store, sends what fits and keeps the
//! store's mark of the last packet it took ([`TmStore::visit_after`]), where the next
//! period goes on without reading the store again from its oldest packet; so a range longer
//! than the downlink's queues loses nothing, and a range deep in a full flash store costs
//! each period a bounded share of its CPU. Before reading on, and after
//! [`SKIP_AFTER_MISSES`] packets out of the range in a row, it asks the store to pass over
//! what the range rules out ([`TmStore::skip`]: the flash store offers whole pages by the
//! time stamps and sequence counts of their first packets), so a range behind a full store
//! is reached in a page read per page, not a packet read per packet (PUS-15-10). The
//! request completes (TM[1,7]) after its end
//! report; requests wait in order ([`REPLAY_QUEUE`]), and one asked again while it waits or
//! runs is not queued twice.
use mib::tc::service;
use mib_wire::{tm, RequestId};

use crate::accept::Tc;
use crate::downlink::{Downlink, Started};
use crate::failure::Failure;
use crate::obsw::Obsw;
use crate::request::unknown;
use crate::services::{Component, Contract};
use crate::tm::{Stretch, TmSink, TmStore};

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
            Range::Seq { apid: a, first, last } => a == apid && on_arc(first, last, seq),
        }
    }
    /// True when no packet of `s` is in the range ([`TmStore::skip`]).
    fn excludes(&self, s: &Stretch) -> bool {
        let cds = |(days, ms)| Cds { days, ms };
        match *self {
            Range::Time { start, end } => cds(s.to) < start || cds(s.from) > end,
            Range::Seq { apid, first, last } => match s.seqs {
                // Two arcs of counts modulo 2^14 meet when either begins on the other.
                Some((a, b)) if s.apid == apid => !(on_arc(a, b, first) || on_arc(first, last, a)),
                _ => false,
            },
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

/// Packets out of its range a downlink reads in a row before it asks the store to pass
/// over what it can rule out ([`TmStore::skip`]; the MIB's number).
const SKIP_AFTER_MISSES: u32 = mib::memory::store::SKIP_AFTER_MISSES;

/// True when the count `x` lies on the arc `from..=to` of the 14-bit circle (wrapping
/// through 16383 when `from > to`).
fn on_arc(from: u16, to: u16, x: u16) -> bool {
    use mib::headers::SeqCount;
    let start = SeqCount::new(from);
    SeqCount::new(x).since(start) <= SeqCount::new(to).since(start)
}

/// Downlinks waiting or running: the ground asks for at most this many ranges in one
/// round (`mib::ground_config::GAP_REQUESTS_MAX`). A request beyond them (rounds that
/// time out on the ground while the robot still replays) runs at once, unpaced: what
/// the downlink cannot take is dropped and counted there (`IO_TM_DROPPED`).
pub const REPLAY_QUEUE: usize = mib::ground_config::GAP_REQUESTS_MAX;

/// One downlink by range: its request, what it has sent, where it goes on (the store's
/// mark of the last packet it read and took, sent or outside the range).
struct Replay<M> {
    range: Range,
    token: Started,
    sent: u32,
    after: Option<M>,
    /// Every packet of the store read: the end report waits for the oldest packet's
    /// lookup, in the next period when this one's reads are spent.
    read_all: bool,
    /// Passing over what the store can rule out ([`TmStore::skip`]) before reading on:
    /// at the start and after [`SKIP_AFTER_MISSES`] packets out of the range in a row.
    skipping: bool,
    /// Packets out of the range read in a row since the last one in it (over periods).
    misses: u32,
}

/// The downlinks by range waiting for the downlink's room, oldest first.
pub struct Replays<M> {
    queue: heapless::Deque<Replay<M>, REPLAY_QUEUE>,
    /// The time of the control period that read the store for them: one slice a period
    /// (a TC that starts a downlink and the tick after it share the period's time).
    read_at: Option<u64>,
}

impl<M> Default for Replays<M> {
    fn default() -> Self {
        Replays {
            queue: heapless::Deque::new(),
            read_at: None,
        }
    }
}

impl<M> Replays<M> {
    /// Downlinks waiting or running (the first one runs).
    pub fn len(&self) -> usize {
        self.queue.len()
    }
    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }
}

/// The store is the downlink's (every TM is kept there as it is sent); the component's
/// own state is the downlinks by range waiting for the downlink's room. A downlink by
/// range comes back as the output: it completes after its end report, so the obsw starts
/// it once its start is reported (`Exec::Replay`, [`Replays::start`]).
impl<M> Component for Replays<M> {
    const CONTRACT: Contract = Contract::new("storage", Some(service::STORAGE), &[]);
    type Request<'a> = Request;
    type Output = Option<Range>;
    fn handle<S: TmStore>(
        &mut self,
        _now: u64,
        r: Request,
        dl: &mut Downlink<S>,
        _sink: &mut impl TmSink,
    ) -> Result<Option<Range>, Failure> {
        match r {
            Request::Enable => dl.store_enabled = true,
            Request::Disable => dl.store_enabled = false,
            Request::Downlink(range) => {
                if !dl.store_enabled {
                    return Err(Failure::store_disabled());
                }
                return Ok(Some(range));
            }
            Request::Delete => dl.store.clear(),
        }
        Ok(None)
    }
}

/// The requests whose downlink ended (TM[15,19] and TM[1,7] sent) in one call, for the
/// obsw to record their outcome: at most the queue and one beyond it.
pub(crate) type Ended = heapless::Vec<RequestId, { REPLAY_QUEUE + 1 }>;

impl<M> Replays<M> {
    /// A downlink by range has started: it waits behind the others (or, asked again
    /// while it waits or runs, completes at once: the one queued sends the packets), then
    /// goes as far as the downlink's room allows now.
    pub(crate) fn start<S: TmStore<Mark = M>>(
        &mut self,
        now: u64,
        range: Range,
        token: Started,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Ended {
        let mut ended = Ended::new();
        if self.queue.iter().any(|r| r.range == range) {
            dl.complete(now, token, sink);
            return ended;
        }
        let replay = Replay {
            range,
            token,
            sent: 0,
            after: None,
            read_all: false,
            skipping: true,
            misses: 0,
        };
        if let Err(mut replay) = self.queue.push_back(replay) {
            // Beyond the queue: all at once, whatever the room and the reads.
            let (mut unlimited, mut reads) = (usize::MAX, usize::MAX);
            let oldest = dl.replay_step(&mut replay, &mut unlimited, &mut reads, sink).flatten();
            Self::done(now, replay, oldest, dl, sink, &mut ended);
            return ended;
        }
        self.tick(now, dl, sink, &mut ended);
        ended
    }

    /// Each control period: the downlinks by range go on as far as the downlink's room
    /// ([`TmSink::replay_room`]) and the period's reads of the store
    /// ([`TmStore::READS_PER_PERIOD`], once a period) allow, oldest first.
    pub(crate) fn tick<S: TmStore<Mark = M>>(
        &mut self,
        now: u64,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
        ended: &mut Ended,
    ) {
        if self.queue.is_empty() || self.read_at == Some(now) {
            return;
        }
        self.read_at = Some(now);
        let mut room = sink.replay_room();
        let mut reads = S::READS_PER_PERIOD;
        while let Some(r) = self.queue.front_mut() {
            if reads == 0 {
                return;
            }
            let Some(oldest) = dl.replay_step(r, &mut room, &mut reads, sink) else {
                return;
            };
            if let Some(r) = self.queue.pop_front() {
                Self::done(now, r, oldest, dl, sink, ended);
            }
        }
    }

    /// The end report, TM[15,19], then the request's completion.
    fn done<S: TmStore<Mark = M>>(
        now: u64,
        r: Replay<M>,
        oldest: Option<(u16, Cds)>,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
        ended: &mut Ended,
    ) {
        // An empty store reports time and sequence count 0.
        let (oldest_seq, t) = oldest.unwrap_or((0, Cds { days: 0, ms: 0 }));
        let report = tm::StoreDownlinkDone {
            packets: r.sent,
            oldest_time: mib_wire::CdsTime {
                pfield: mib_wire::header::CDS_PFIELD,
                days: t.days,
                ms_of_day: t.ms,
            },
            oldest_seq,
            overwritten: dl.store_dropped,
        };
        dl.emit_tm(now, &report, sink);
        // At most the queue's length plus the one beyond it end in one call.
        let _ = ended.push(r.token.req);
        dl.complete(now, r.token, sink);
    }
}

impl<S: TmStore> Obsw<S> {
    /// A downlink by range has started (`Replays::start`); the outcome of those that
    /// ended is recorded.
    pub(crate) fn replay_started(&mut self, now: u64, range: Range, token: Started, sink: &mut impl TmSink) {
        let ended = self.replays.start(now, range, token, &mut self.dl, sink);
        self.replays_ended(&ended);
    }

    /// Each control period (`Replays::tick`).
    pub(crate) fn replay_tick(&mut self, now: u64, sink: &mut impl TmSink) {
        let mut ended = Ended::new();
        self.replays.tick(now, &mut self.dl, sink, &mut ended);
        self.replays_ended(&ended);
    }

    fn replays_ended(&mut self, ended: &Ended) {
        for req in ended {
            self.set_outcome(*req, crate::duplicates::Outcome::Done);
        }
    }
}

impl<S: TmStore> Downlink<S> {
    /// Reads at most `reads` packets of the store after `r`'s mark (what it reads is
    /// subtracted) and sends those of its range while they fit in `room` bytes (likewise).
    /// `Some(oldest)` when the range is done — the oldest packet of its stream still stored
    /// — `None` when the room or the reads ran out first.
    fn replay_step(
        &mut self,
        r: &mut Replay<S::Mark>,
        room: &mut usize,
        reads: &mut usize,
        sink: &mut impl TmSink,
    ) -> Option<Option<(u16, Cds)>> {
        while !r.read_all {
            let range = r.range;
            if r.skipping {
                let s = self.store.skip(r.after, *reads, &mut |s| range.excludes(s));
                *reads = reads.saturating_sub(s.reads);
                r.after = s.after;
                if !s.done {
                    return None;
                }
                r.skipping = false;
            }
            let (mut sent, mut after, mut read, mut misses) = (0u32, r.after, 0usize, r.misses);
            let ended = self.store.visit_after(r.after, *reads, &mut |p, mark| {
                match identify(p) {
                    Some((apid, seq, t)) if range.contains(apid, seq, t) => {
                        if p.len() > *room {
                            return false;
                        }
                        *room -= p.len();
                        sink.send_replay(p);
                        sent += 1;
                        misses = 0;
                    }
                    Some(_) | None => misses += 1,
                }
                after = Some(mark);
                read += 1;
                misses < SKIP_AFTER_MISSES
            });
            *reads = reads.saturating_sub(read);
            r.sent = r.sent.wrapping_add(sent);
            r.after = after;
            r.misses = misses;
            if misses >= SKIP_AFTER_MISSES && !ended {
                r.skipping = true;
                r.misses = 0;
                continue;
            }
            if !ended {
                return None;
            }
            r.read_all = true;
        }
        if *reads == 0 {
            return None;
        }
        // The oldest packet of the range's stream: the store's first packet (one stream
        // per robot), looked for among the reads left.
        let (mut oldest, mut read) = (None, 0usize);
        self.store.visit_after(None, *reads, &mut |p, _| {
            read += 1;
            match identify(p) {
                Some((apid, seq, t)) if r.range.same_stream(apid) => {
                    oldest = Some((seq, t));
                    false
                }
                _ => true,
            }
        });
        *reads = reads.saturating_sub(read);
        Some(oldest)
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

    /// A downlink with a small queue: `room` bytes of replays per period, every packet
    /// kept in order.
    struct SmallQueue {
        out: Vec<Vec<u8>>,
        room: usize,
        replayed: usize,
    }

    impl TmSink for SmallQueue {
        fn send_tm(&mut self, packet: &[u8]) {
            self.out.push(packet.to_vec());
        }
        fn send_replay(&mut self, packet: &[u8]) {
            // More than the room is what a real queue would drop.
            assert!(packet.len() <= self.room, "replayed beyond the room");
            self.room -= packet.len();
            self.replayed += 1;
            self.out.push(packet.to_vec());
        }
        fn replay_room(&self) -> usize {
            self.room
        }
    }

    // verifies: PUS-15-07
    #[test]
    fn a_replay_longer_than_the_downlink_queue_goes_on_each_period_and_drops_nothing() {
        let mut o = obsw();
        let mut all = Vec::new();
        for i in 0..40u16 {
            all.extend(send(&mut o, 10 * u64::from(i), i, 17, 1, &[]));
        }
        // 40 pings x 4 reports = counts 0..=159; ask for 100 of them.
        let (first, last) = (20u16, 119u16);
        let per_period = 3 * all[first as usize].len();
        let mut q = SmallQueue {
            out: Vec::new(),
            room: per_period,
            replayed: 0,
        };
        let mut app = APID.to_be_bytes().to_vec();
        app.extend_from_slice(&first.to_be_bytes());
        app.extend_from_slice(&last.to_be_bytes());
        let raw = crate::accept::tests::tc_bytes(APID, 500, 15, 128, &app);
        o.handle_tc(1000, &raw, &mut q);
        assert_eq!(q.replayed, 3, "the first period sends what fits");
        assert_eq!(o.replays.len(), 1, "the rest waits");
        assert!(of(&q.out, 15, 19).is_empty(), "no end report yet");
        // A ping while the replay runs: stored behind the range, not replayed.
        send(&mut o, 1005, 501, 17, 1, &[]);
        let sensors = mmic_domain::SensorsA::default();
        let mut periods = 1;
        while !o.replays.is_empty() {
            q.room = per_period;
            let now = 1010 + 10 * periods;
            o.tick(now, &sensors, &[], &mut q);
            periods += 1;
            assert!(periods < 100, "the replay does not end");
        }
        let live_from = all.len() as u16;
        let replayed: Vec<Vec<u8>> = q.out.iter().filter(|p| seq(p) < live_from).cloned().collect();
        assert_eq!(
            replayed,
            all[first as usize..=last as usize].to_vec(),
            "each once, in order"
        );
        assert_eq!(periods, 34, "100 packets at 3 a period");
        assert_eq!(end(&q.out).packets, 100);
        // The completion follows the end report.
        let pos = |svc: u8, sub: u8| {
            q.out
                .iter()
                .position(|p| seq(p) >= live_from && (kind(p).0, kind(p).1) == (svc, sub))
                .unwrap()
        };
        assert!(pos(15, 19) < pos(1, 7));
    }

    // verifies: PUS-15-07
    #[test]
    fn a_range_asked_again_while_it_replays_is_sent_once() {
        let mut o = obsw();
        for i in 0..10u16 {
            send(&mut o, u64::from(i), i, 17, 1, &[]);
        }
        let mut q = SmallQueue {
            out: Vec::new(),
            room: 0,
            replayed: 0,
        };
        let mut app = APID.to_be_bytes().to_vec();
        app.extend_from_slice(&0u16.to_be_bytes());
        app.extend_from_slice(&9u16.to_be_bytes());
        for tc_seq in [100, 101] {
            let raw = crate::accept::tests::tc_bytes(APID, tc_seq, 15, 128, &app);
            o.handle_tc(100, &raw, &mut q);
        }
        // 10 pings x 4 reports: counts 0..=39 stored, the replay's own reports after them.
        let completions = |q: &SmallQueue| of(&q.out, 1, 7).iter().filter(|p| seq(p) >= 40).count();
        assert_eq!(o.replays.len(), 1, "the second request completes at once");
        assert_eq!(completions(&q), 1);
        q.room = usize::MAX;
        o.tick(200, &mmic_domain::SensorsA::default(), &[], &mut q);
        assert_eq!((q.replayed, end(&q.out).packets), (10, 10));
        assert_eq!(completions(&q), 2);
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

    // verifies: PUS-15-10
    #[test]
    fn a_range_rules_out_a_stretch_only_when_they_cannot_meet() {
        let t = |ms| Cds { days: 1, ms };
        let stretch = |from, to, seqs| Stretch {
            apid: APID,
            from: (1, from),
            to: (1, to),
            seqs,
        };
        let time = Range::Time {
            start: t(100),
            end: t(200),
        };
        assert!(time.excludes(&stretch(10, 99, None)));
        assert!(time.excludes(&stretch(201, 300, None)));
        assert!(!time.excludes(&stretch(10, 100, None)));
        assert!(!time.excludes(&stretch(200, 300, None)));
        assert!(!time.excludes(&stretch(150, 160, None)));
        let seq = |first, last| Range::Seq {
            apid: APID,
            first,
            last,
        };
        // Arcs modulo 2^14, either of which may wrap through 16383.
        assert!(seq(100, 200).excludes(&stretch(0, 0, Some((201, 300)))));
        assert!(seq(100, 200).excludes(&stretch(0, 0, Some((16_000, 99)))));
        assert!(!seq(100, 200).excludes(&stretch(0, 0, Some((16_000, 100)))));
        assert!(!seq(100, 200).excludes(&stretch(0, 0, Some((150, 160)))));
        assert!(!seq(100, 200).excludes(&stretch(0, 0, Some((50, 300)))));
        assert!(!seq(16_300, 10).excludes(&stretch(0, 0, Some((5, 20)))));
        assert!(seq(16_300, 10).excludes(&stretch(0, 0, Some((11, 16_299)))));
        // Counts not known, or another APID: never ruled out by count.
        assert!(!seq(100, 200).excludes(&stretch(0, 0, None)));
        let other = Stretch {
            apid: APID + 1,
            ..stretch(0, 0, Some((300, 400)))
        };
        assert!(!seq(100, 200).excludes(&other));
    }

    /// A sink that keeps replayed packets apart from live TM.
    #[derive(Default)]
    struct Replayed {
        replayed: Vec<Vec<u8>>,
    }
    impl TmSink for Replayed {
        fn send_tm(&mut self, _packet: &[u8]) {}
        fn send_replay(&mut self, packet: &[u8]) {
            self.replayed.push(packet.to_vec());
        }
    }

    // verifies: PUS-15-10, PUS-15-01
    #[test]
    fn a_downlink_behind_a_full_flash_store_passes_over_what_it_can_rule_out_and_sends_exactly_its_range() {
        use crate::flash_store::{tests::TestFlash, MibFlashStore};
        use crate::obsw::Config;
        use core::cell::RefCell;
        use mib::memory::store;
        const EPOCH: u64 = 1_790_000_000_000;
        let flash = RefCell::new(TestFlash::new(store::SIZE as usize / 4096));
        let mut st = MibFlashStore::open(&flash, 0).expect("store opens");
        // A stream of more than 2^14 packets in phases that defeat a count taken alone:
        // HK with an event every tenth packet, 1 s apart; 16 185 HK packets 10 ms apart and
        // no report (one report page spans them all: its counts wrap in between, and the
        // counts of its first and next page's first packet are then only 100 apart, while
        // its own packets span 230); a burst of events; HK again.
        let mut w = crate::tm::TmWriter::new(APID, crate::time::OnboardTime::new(EPOCH));
        let mut buf = [0u8; mib::config::MAX_PACKET_LEN];
        let mut ms = 0u64;
        let mut stamps = Vec::new();
        let mut push = |st: &mut MibFlashStore<'_, TestFlash>, event: bool, step: u64| {
            let (svc, sub, data) = if event {
                (5, 1, &[7u8; 12][..])
            } else {
                (3, 25, &[1u8; 24][..])
            };
            let n = w.build(ms, svc, sub, data, &mut buf).expect("TM builds");
            assert_eq!(st.push(&buf[..n]), 0, "nothing overwritten");
            stamps.push(ms);
            ms += step;
        };
        for i in 0..3000 {
            push(&mut st, i % 10 == 9, 1000);
        }
        for _ in 0..16_185 {
            push(&mut st, false, 10);
        }
        for _ in 0..1500 {
            push(&mut st, true, 10);
        }
        for i in 0..3000 {
            push(&mut st, i % 10 == 9, 1000);
        }
        let last_ms = ms - 1000;
        let total = stamps.len();
        let mut o = Obsw::new(
            Config {
                robot: 1,
                epoch_unix_ms: EPOCH,
            },
            st,
        );
        let cds = |ms: u64| {
            let t = crate::time::OnboardTime::new(EPOCH).cds_time(ms);
            Cds {
                days: t.days,
                ms: t.ms_of_day,
            }
        };
        let ranges = [
            // By sequence count: the newest, inside the dense HK (every count there twice),
            // across the wrap, in the burst of events, the oldest.
            Range::Seq {
                apid: APID,
                first: ((total - 200) % 16384) as u16,
                last: ((total - 1) % 16384) as u16,
            },
            Range::Seq {
                apid: APID,
                first: 2900,
                last: 2990,
            },
            Range::Seq {
                apid: APID,
                first: 9000,
                last: 9255,
            },
            Range::Seq {
                apid: APID,
                first: 16300,
                last: 60,
            },
            Range::Seq {
                apid: APID,
                first: 4200,
                last: 4300,
            },
            Range::Seq {
                apid: APID,
                first: 0,
                last: 255,
            },
            // By time: the newest, the middle of the dense HK, the oldest, an hour ahead.
            Range::Time {
                start: cds(last_ms - 100_000),
                end: cds(last_ms),
            },
            Range::Time {
                start: cds(stamps[10_000]),
                end: cds(stamps[10_300]),
            },
            Range::Time {
                start: cds(0),
                end: cds(60_000),
            },
            Range::Time {
                start: cds(last_ms + 3_600_000),
                end: cds(last_ms + 3_610_000),
            },
        ];
        let mut now = last_ms + 1000;
        for (k, range) in ranges.iter().enumerate() {
            let range = *range;
            // What the range holds, read packet by packet.
            let mut expect = Vec::new();
            o.store_mut().visit(&mut |p| {
                if identify(p).is_some_and(|(a, q, t)| range.contains(a, q, t)) {
                    expect.push(p.to_vec());
                }
            });
            let app: Vec<u8> = match range {
                Range::Seq { apid, first, last } => [apid, first, last].iter().flat_map(|x| x.to_be_bytes()).collect(),
                Range::Time { start, end } => [start, end]
                    .iter()
                    .flat_map(|t| t.days.to_be_bytes().into_iter().chain(t.ms.to_be_bytes()))
                    .collect(),
            };
            let sub = if matches!(range, Range::Seq { .. }) { 128 } else { 9 };
            let mut sink = Replayed::default();
            let raw = crate::accept::tests::tc_bytes(APID, 100 + k as u16, 15, sub, &app);
            o.handle_tc(now, &raw, &mut sink);
            let mut periods = 0u32;
            while o.replays_pending() > 0 && periods < 20_000 {
                now += 10;
                periods += 1;
                o.tick(now, &mmic_domain::SensorsA::default(), &[], &mut sink);
            }
            println!("{range:?}: {} packets in {periods} periods", expect.len());
            assert_eq!(o.replays_pending(), 0, "{range:?} ended");
            assert_eq!(
                sink.replayed.len(),
                expect.len(),
                "{range:?}: every packet of the range, once"
            );
            assert!(sink.replayed == expect, "{range:?}: the range's packets, in order");
            // Read at 10 packets a period the store would take over 2 500 periods; passing
            // over pages, a range takes a few periods per page it cannot rule out.
            assert!(periods < 400, "{range:?}: {periods} periods");
        }
    }
}
