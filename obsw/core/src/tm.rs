//! Telemetry output: the sink the host or firmware provides, the on-board store
//! (PUS 15) and the writer that stamps every packet with the per-APID sequence count,
//! the per-service message counter and the CDS time.

use arbitrary_int::{u11, u14};
use mib_wire::header::{emit_tm, TmHeader};

use crate::time::OnboardTime;
use mib::config::MAX_PACKET_LEN;
use mib::headers::SeqCount;

/// Where finished TM packets go (sockets on the host, the UART on the firmware).
pub trait TmSink {
    fn send_tm(&mut self, packet: &[u8]);
    /// A packet replayed from the on-board store (PUS 15 downlink). On the space link it
    /// goes on the replay virtual channel (`mib::link::tm_vc::REPLAY`), so that a replay
    /// neither delays nor is mistaken for realtime TM; a sink without channels sends it
    /// like any other packet.
    fn send_replay(&mut self, packet: &[u8]) {
        self.send_tm(packet);
    }
    /// A CFDP PDU packet (`mib::cfdp::APID`, no PUS header). On the space link it goes on
    /// the files virtual channel (`mib::link::tm_vc::FILES`), which a ground processes as
    /// file PDUs rather than PUS TM; a sink without channels sends it like any other packet.
    fn send_file(&mut self, packet: &[u8]) {
        self.send_tm(packet);
    }
    /// Bytes of replayed packets the downlink takes now without dropping any (nor the
    /// realtime TM of the period): a PUS 15 downlink sends what fits and goes on next
    /// period. A sink that never drops has no limit.
    fn replay_room(&self) -> usize {
        usize::MAX
    }
}

/// A sink that collects packets (tests, recorders).
#[cfg(test)]
impl TmSink for std::vec::Vec<std::vec::Vec<u8>> {
    fn send_tm(&mut self, packet: &[u8]) {
        self.push(packet.to_vec());
    }
}

/// Stored packets of one robot's TM stream, one after another in the store, described by
/// their bounds ([`TmStore::skip`]): every packet of the stretch has a time stamp in
/// `from..=to` and, when `seqs` is given, a sequence count on the arc `seqs.0 ..= seqs.1`
/// (modulo 2^14, wrapping) of APID `apid`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stretch {
    pub apid: u16,
    /// CDS time stamps (days, ms of day) of the first and the last packet.
    pub from: (u16, u32),
    pub to: (u16, u32),
    /// The first and last sequence count, when the store can bound the counts between
    /// (fewer than 2^14 of the stream's packets between them).
    pub seqs: Option<(u16, u16)>,
}

/// What a [`TmStore::skip`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Skipped<M> {
    /// Where a visit goes on: after the last packet ruled out (`after` as given when none).
    pub after: Option<M>,
    /// Stored packets read.
    pub reads: usize,
    /// True when it stopped on a stretch not ruled out or at the newest packet; false when
    /// its reads ran out first.
    pub done: bool,
}

/// The on-board TM store (PUS 15): keeps packets while nobody downlinks them.
pub trait TmStore {
    /// A stored packet's place, handed to [`TmStore::visit_after`]'s visitor with the
    /// packet: a later visit goes on after it without reading the packets before it again.
    type Mark: Copy + core::fmt::Debug + PartialEq;
    /// Stored packets a paced downlink reads in a control period ([`TmStore::visit_after`]'s
    /// `most`): unbounded where reading costs little (RAM).
    const READS_PER_PERIOD: usize = usize::MAX;
    /// Stores a packet; returns how many packets are lost for it: older packets
    /// overwritten to make room, or 1 if this one could not be stored.
    fn push(&mut self, packet: &[u8]) -> u32;
    /// Calls `f` with every stored packet, oldest first, leaving the store's content
    /// unchanged (PUS 15 downlinks by range read the store; nothing is removed).
    fn visit(&mut self, f: &mut dyn FnMut(&[u8]));
    /// Calls `f` with the packets stored after the one `after` marks (all of them for
    /// `None`), oldest first, each with its mark, until `f` returns false or it has been
    /// called `most` times: a paced downlink reads a bounded slice each control period and
    /// goes on from the last packet it took. Packets older than a marked packet that is no
    /// longer stored were overwritten before it, so the visit then starts from the oldest
    /// packet. Returns true when it went through to the newest packet.
    fn visit_after(
        &mut self,
        after: Option<Self::Mark>,
        most: usize,
        f: &mut dyn FnMut(&[u8], Self::Mark) -> bool,
    ) -> bool;
    /// Passes over stored packets that `excludes` rules out without reading each of them:
    /// from the packet `after` marks (the oldest for `None`), the store offers stretches of
    /// stored packets in order ([`Stretch`]: what it can vouch for about the packets in
    /// one), each ending on a packet; while `excludes` rules a stretch out, the mark moves
    /// to its last packet. Reads at most `most` stored packets. A store whose reading costs
    /// little (RAM) offers none: a downlink then reads every packet.
    fn skip(
        &mut self,
        after: Option<Self::Mark>,
        most: usize,
        excludes: &mut dyn FnMut(&Stretch) -> bool,
    ) -> Skipped<Self::Mark> {
        let _ = (most, excludes);
        Skipped {
            after,
            reads: 0,
            done: true,
        }
    }
    /// Called once at the end of every control period: a store whose giving up of old
    /// packets costs (the flash store) gives up, ahead of need, a few packets its next
    /// writes would overwrite anyway, so that no single write pays for many. Returns how
    /// many it gave up (counted as overwritten).
    fn end_period(&mut self) -> u32 {
        0
    }
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn clear(&mut self);
}

/// Byte ring buffer store with `N` bytes of capacity (no heap). Each packet is kept as
/// a 2-byte length followed by its bytes; when full, the oldest packets are dropped.
/// Packets are numbered in the order stored (the numbers are the store's marks).
pub struct RingStore<const N: usize> {
    buf: heapless::Deque<u8, N>,
    count: usize,
    /// The number of the oldest packet held (wrapping).
    first: u32,
}

impl<const N: usize> Default for RingStore<N> {
    fn default() -> Self {
        RingStore {
            buf: heapless::Deque::new(),
            count: 0,
            first: 0,
        }
    }
}

impl<const N: usize> RingStore<N> {
    fn drop_oldest(&mut self) {
        let (Some(hi), Some(lo)) = (self.buf.pop_front(), self.buf.pop_front()) else {
            return;
        };
        for _ in 0..u16::from_be_bytes([hi, lo]) {
            self.buf.pop_front();
        }
        self.count -= 1;
        self.first = self.first.wrapping_add(1);
    }
}

impl<const N: usize> TmStore for RingStore<N> {
    /// The packet's number.
    type Mark = u32;
    fn push(&mut self, packet: &[u8]) -> u32 {
        let need = packet.len() + 2;
        if need > N || packet.len() > u16::MAX as usize {
            return 1;
        }
        let mut overwritten = 0;
        while N - self.buf.len() < need {
            self.drop_oldest();
            overwritten += 1;
        }
        for b in (packet.len() as u16).to_be_bytes().iter().chain(packet) {
            // Space was made above, so this cannot fail.
            let _ = self.buf.push_back(*b);
        }
        self.count += 1;
        overwritten
    }
    fn visit(&mut self, f: &mut dyn FnMut(&[u8])) {
        self.visit_after(None, usize::MAX, &mut |p, _| {
            f(p);
            true
        });
    }
    fn visit_after(&mut self, after: Option<u32>, most: usize, f: &mut dyn FnMut(&[u8], u32) -> bool) -> bool {
        // Packets up to the marked one are passed over (all of them are in RAM); a mark
        // older than the oldest packet (or beyond the newest, after a clear) starts from
        // the oldest.
        let skip = after
            .map(|m| m.wrapping_sub(self.first) as usize)
            .filter(|&k| k < self.count)
            .map_or(0, |k| k + 1);
        let mut it = self.buf.iter().copied();
        let mut number = self.first;
        let mut called = 0;
        let mut pkt = [0u8; MAX_PACKET_LEN];
        while let (Some(hi), Some(lo)) = (it.next(), it.next()) {
            let len = u16::from_be_bytes([hi, lo]) as usize;
            let this = number;
            number = number.wrapping_add(1);
            if (this.wrapping_sub(self.first) as usize) < skip {
                it.by_ref().take(len).for_each(drop);
                continue;
            }
            let mut n = 0;
            for b in it.by_ref().take(len) {
                if let Some(slot) = pkt.get_mut(n) {
                    *slot = b;
                }
                n += 1;
            }
            if called == most {
                return false;
            }
            called += 1;
            // `push` keeps only packets of at most MAX_PACKET_LEN bytes from the TM
            // writer; a longer record could only come from a larger store user.
            if let Some(p) = pkt.get(..n) {
                if !f(p, this) {
                    return false;
                }
            }
        }
        true
    }
    fn len(&self) -> usize {
        self.count
    }
    fn clear(&mut self) {
        self.buf.clear();
        self.first = self.first.wrapping_add(self.count as u32);
        self.count = 0;
    }
}

/// Stamps and serialises TM. One instance per APID keeps the sequence count continuous.
pub struct TmWriter {
    apid: u16,
    seq: SeqCount,
    msg_counters: [u16; 256],
    pub time: OnboardTime,
    pub sent: u32,
}

impl TmWriter {
    pub fn new(apid: u16, time: OnboardTime) -> Self {
        TmWriter {
            apid,
            seq: SeqCount::default(),
            msg_counters: [0; 256],
            time,
            sent: 0,
        }
    }
    pub fn apid(&self) -> u16 {
        self.apid
    }
    /// The next packet takes the sequence count after `seq`.
    pub fn continue_after(&mut self, seq: u16) {
        self.seq = SeqCount::new(seq).next();
    }
    /// Next sequence count (14 bit, wraps) and advances it.
    pub fn next_seq(&mut self) -> u16 {
        let s = self.seq;
        self.seq = s.next();
        s.get()
    }
    /// Next message-type counter of a service (PUS-C), advancing it.
    pub fn next_msg_count(&mut self, service: u8) -> u16 {
        let c = &mut self.msg_counters[service as usize];
        let v = *c;
        *c = c.wrapping_add(1);
        v
    }
    pub fn apid_u11(&self) -> u11 {
        u11::new(self.apid & 0x7FF)
    }
    pub fn seq_u14(seq: u16) -> u14 {
        u14::new(SeqCount::new(seq).get())
    }

    /// Builds a TM packet into `out` and returns its length.
    pub fn build(
        &mut self,
        now_ms: u64,
        service: u8,
        subservice: u8,
        data: &[u8],
        out: &mut [u8; MAX_PACKET_LEN],
    ) -> Option<usize> {
        self.build_with(now_ms, service, subservice, out, |d| {
            let n = data.len();
            let have = d.len();
            d.get_mut(..n)
                .ok_or(mib_wire::Error::BufferTooShort { need: n, have })?
                .copy_from_slice(data);
            Ok(n)
        })
    }

    /// Builds a TM packet whose source data `body` writes, through the wire crate's header
    /// code (`mib_wire::header::emit_tm`: the same headers and CRC the ground reads), and
    /// returns its length.
    pub fn build_with(
        &mut self,
        now_ms: u64,
        service: u8,
        subservice: u8,
        out: &mut [u8],
        body: impl FnOnce(&mut [u8]) -> Result<usize, mib_wire::Error>,
    ) -> Option<usize> {
        let time = self.time.cds_time(now_ms);
        let h = TmHeader {
            apid: self.apid,
            seq_count: self.next_seq(),
            service,
            subservice,
            msg_counter: self.next_msg_count(service),
            dest_id: mib::config::GROUND_ID,
            time,
        };
        emit_tm(&h, out, body).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use satrs::spacepackets::ecss::tm::PusTmReader;
    use satrs::spacepackets::CcsdsPacket;

    // verifies: PUS-PKT-03
    #[test]
    fn tm_sequence_count_is_continuous_and_packets_parse() {
        let mut w = TmWriter::new(0x101, OnboardTime::new(1_790_000_000_000));
        let mut buf = [0u8; MAX_PACKET_LEN];
        for i in 0..5u16 {
            let n = w.build(10, 17, 2, &[], &mut buf).unwrap();
            let tm = PusTmReader::new(&buf[..n], 7).unwrap();
            assert_eq!(tm.seq_count().value(), i);
            assert_eq!(tm.apid().value(), 0x101);
            assert_eq!((tm.service_type_id(), tm.message_subtype_id()), (17, 2));
        }
    }

    // verifies: PUS-15-01
    #[test]
    fn ring_store_keeps_order_and_overwrites_oldest_when_full() {
        let mut s: RingStore<64> = RingStore::default();
        assert_eq!(s.push(&[1; 20]), 0);
        assert_eq!(s.push(&[2; 20]), 0);
        assert_eq!(s.push(&[3; 18]), 0);
        assert_eq!(s.len(), 3);
        // 22 + 22 + 20 = 64: full; the next push drops the oldest.
        assert_eq!(s.push(&[4; 10]), 1);
        assert_eq!(s.len(), 3);
        let mut seen = Vec::new();
        s.visit(&mut |p| seen.push((p[0], p.len())));
        assert_eq!(seen, [(2, 20), (3, 18), (4, 10)], "oldest first, store unchanged");
        assert_eq!(s.len(), 3);
        assert_eq!(s.push(&[9; 100]), 1, "a packet larger than the store is refused");
    }

    // verifies: PUS-15-09
    #[test]
    fn ring_store_visits_go_on_after_their_mark_or_from_the_oldest_once_it_is_gone() {
        let mut s: RingStore<64> = RingStore::default();
        for b in 1..=4u8 {
            s.push(&[b; 10]);
        }
        let visit = |s: &mut RingStore<64>, after, most| {
            let mut seen = Vec::new();
            let ended = s.visit_after(after, most, &mut |p, m| {
                seen.push((p[0], m));
                true
            });
            (seen, ended)
        };
        // Two at a time, each going on after the last one taken.
        let (first, ended) = visit(&mut s, None, 2);
        assert_eq!(
            (first.iter().map(|x| x.0).collect::<Vec<_>>(), ended),
            (vec![1, 2], false)
        );
        let (next, ended) = visit(&mut s, Some(first[1].1), 2);
        assert_eq!(
            (next.iter().map(|x| x.0).collect::<Vec<_>>(), ended),
            (vec![3, 4], true)
        );
        // Packets 1 and 2 overwritten: after packet 1's mark, from the oldest (3).
        s.push(&[5; 20]);
        s.push(&[6; 10]);
        let (again, _) = visit(&mut s, Some(first[0].1), 10);
        assert_eq!(again.iter().map(|x| x.0).collect::<Vec<_>>(), vec![3, 4, 5, 6]);
        // After a clear, an old mark reads what is stored since.
        s.clear();
        s.push(&[7; 10]);
        let (cleared, ended) = visit(&mut s, Some(next[1].1), 10);
        assert_eq!(
            (cleared.iter().map(|x| x.0).collect::<Vec<_>>(), ended),
            (vec![7], true)
        );
    }
}
