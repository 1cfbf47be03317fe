//! Sequence-count follower of one APID: says for each packet whether it is new, fills a
//! hole, or is a duplicate; keeps the holes to retrieve from the on-board store; tells an
//! obsw reboot (sequence counts restart, on-board time goes on) from a gap or from
//! duplicates. Pure: no I/O, times passed in.

use std::collections::BTreeMap;

/// Sequence counts are 14 bits.
pub const SEQ_MOD: u32 = 1 << 14;
/// A count at most this far ahead of the last one is "ahead"; further is "behind".
pub const AHEAD: u32 = SEQ_MOD / 2;
/// Most sequence counts asked for in one store request: the replay of one request stays
/// a short burst however long the outage was.
pub const MAX_RANGE: u32 = 256;
/// Most holes followed at once per APID. More than the host store holds cannot be
/// retrieved anyway; the excess is reported unrecoverable at once.
pub const MAX_MISSING: usize = 2 * mib::config::TM_STORE_CAPACITY;

/// A packet's place: sequence count and on-board time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pos {
    pub seq: u16,
    pub obt_ms: i64,
}

/// Why a hole can no longer be filled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lost {
    /// The robot rebooted: its store (in RAM) started empty.
    Rebooted,
    /// Older than the oldest packet still in the on-board store.
    Overwritten,
    /// Requested `tries` times from the store and never received.
    NotDelivered,
    /// More holes at once than can be followed.
    TooMany,
}

impl Lost {
    pub fn reason(self) -> &'static str {
        match self {
            Lost::Rebooted => "robot rebooted",
            Lost::Overwritten => "store overwritten",
            Lost::NotDelivered => "not delivered by the store after retries",
            Lost::TooMany => "too many holes at once",
        }
    }
}

/// What a packet is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Next or ahead of the last one (holes before it, if any, are now followed).
    New,
    /// Fills a hole.
    Filled,
    /// Already received.
    Duplicate,
    /// First packet of a new boot of the obsw (sequence counts restarted).
    Reboot,
}

/// A run of holes that became unrecoverable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LostRun {
    pub first: u16,
    pub last: u16,
    pub count: u32,
    /// On-board times around the run (last packet before it, first after it).
    pub after_obt_ms: i64,
    pub before_obt_ms: i64,
    pub why: Lost,
}

#[derive(Clone, Copy, Debug)]
struct Hole {
    after_obt_ms: i64,
    before_obt_ms: i64,
    tries: u32,
    last_request_ms: Option<i64>,
    found_ms: i64,
}

/// Follows one APID.
#[derive(Clone, Debug, Default)]
pub struct ApidTracker {
    last: Option<Pos>,
    holes: BTreeMap<u16, Hole>,
    lost: Vec<LostRun>,
    pub new: u64,
    pub filled: u64,
    pub duplicates: u64,
    pub reboots: u64,
    pub lost_packets: u64,
}

fn ahead(from: u16, to: u16) -> u32 {
    (to as u32 + SEQ_MOD - from as u32) % SEQ_MOD
}

impl ApidTracker {
    /// Starts from the last archived position (after a collector restart).
    pub fn resume(last: Option<Pos>) -> ApidTracker {
        ApidTracker {
            last,
            ..Default::default()
        }
    }

    /// Zeroes the counters (after replaying archived history).
    pub fn reset_counters(&mut self) {
        self.new = 0;
        self.filled = 0;
        self.duplicates = 0;
        self.reboots = 0;
        self.lost_packets = 0;
    }

    pub fn last(&self) -> Option<Pos> {
        self.last
    }

    pub fn holes(&self) -> usize {
        self.holes.len()
    }

    /// Runs that became unrecoverable since the last call.
    pub fn take_lost(&mut self) -> Vec<LostRun> {
        std::mem::take(&mut self.lost)
    }

    /// Classifies a packet. `boot` is true for the obsw's BOOT event.
    pub fn on_packet(&mut self, p: Pos, boot: bool, now_ms: i64) -> Verdict {
        let Some(last) = self.last else {
            // Nothing archived before: what this boot of the obsw sent before the first
            // packet heard is asked of the store too (what it no longer holds is
            // reported overwritten).
            if !boot && p.seq > 0 {
                let before = Pos {
                    seq: (SEQ_MOD - 1) as u16,
                    obt_ms: i64::MIN,
                };
                self.add_holes(before, p, now_ms);
            }
            self.last = Some(p);
            self.new += 1;
            return if boot {
                self.reboots += 1;
                Verdict::Reboot
            } else {
                Verdict::New
            };
        };
        let d = ahead(last.seq, p.seq);
        if boot && p.obt_ms > last.obt_ms {
            return self.reboot(p, now_ms);
        }
        if d == 0 {
            if p.obt_ms > last.obt_ms {
                return self.reboot(p, now_ms);
            }
            self.duplicates += 1;
            return Verdict::Duplicate;
        }
        if d < AHEAD && p.obt_ms >= last.obt_ms {
            self.add_holes(last, p, now_ms);
            self.last = Some(p);
            self.new += 1;
            return Verdict::New;
        }
        if let Some(h) = self.holes.get(&p.seq) {
            if p.obt_ms >= h.after_obt_ms && p.obt_ms <= h.before_obt_ms {
                self.holes.remove(&p.seq);
                self.filled += 1;
                return Verdict::Filled;
            }
        }
        if p.obt_ms > last.obt_ms {
            return self.reboot(p, now_ms);
        }
        self.duplicates += 1;
        Verdict::Duplicate
    }

    fn reboot(&mut self, p: Pos, now_ms: i64) -> Verdict {
        let old: Vec<u16> = self.holes.keys().copied().collect();
        self.declare(&old, Lost::Rebooted);
        self.reboots += 1;
        self.new += 1;
        // Counts restart at 0 with the boot: what came before this packet is a hole.
        let start = Pos {
            seq: 0,
            obt_ms: self.last.map_or(p.obt_ms, |l| l.obt_ms),
        };
        if p.seq > 0 {
            let before = Pos {
                seq: (SEQ_MOD as u16).wrapping_sub(1) & 0x3FFF,
                obt_ms: start.obt_ms,
            };
            self.add_holes(before, p, now_ms);
        }
        self.last = Some(p);
        Verdict::Reboot
    }

    fn add_holes(&mut self, after: Pos, before: Pos, now_ms: i64) {
        let n = ahead(after.seq, before.seq).saturating_sub(1);
        let mut too_many = Vec::new();
        for k in 1..=n {
            let seq = ((after.seq as u32 + k) % SEQ_MOD) as u16;
            if self.holes.len() >= MAX_MISSING {
                too_many.push(seq);
                continue;
            }
            self.holes.insert(
                seq,
                Hole {
                    after_obt_ms: after.obt_ms,
                    before_obt_ms: before.obt_ms,
                    tries: 0,
                    last_request_ms: None,
                    found_ms: now_ms,
                },
            );
        }
        if !too_many.is_empty() {
            self.push_lost(&too_many, after.obt_ms, before.obt_ms, Lost::TooMany);
        }
    }

    fn push_lost(&mut self, seqs: &[u16], after: i64, before: i64, why: Lost) {
        for run in runs(seqs) {
            self.lost_packets += run.2 as u64;
            self.lost.push(LostRun {
                first: run.0,
                last: run.1,
                count: run.2,
                after_obt_ms: after,
                before_obt_ms: before,
                why,
            });
        }
    }

    /// Declares holes unrecoverable.
    fn declare(&mut self, seqs: &[u16], why: Lost) {
        let mut by_span: BTreeMap<(i64, i64), Vec<u16>> = BTreeMap::new();
        for s in seqs {
            if let Some(h) = self.holes.remove(s) {
                by_span.entry((h.after_obt_ms, h.before_obt_ms)).or_default().push(*s);
            }
        }
        for ((a, b), v) in by_span {
            self.push_lost(&v, a, b, why);
        }
    }

    /// Contiguous runs of holes due for a store request: found at least `settle_ms`
    /// ago, not requested in the last `retry_ms`. Each returned run counts as one try;
    /// holes that were already tried `max_tries` times are declared not delivered.
    /// At most `max_runs` runs; runs at most `merge_gap` counts apart are asked for as
    /// one range (the packets between them come back as duplicates).
    pub fn due(
        &mut self,
        now_ms: i64,
        settle_ms: i64,
        retry_ms: i64,
        max_tries: u32,
        max_runs: usize,
        merge_gap: u32,
    ) -> Vec<(u16, u16)> {
        let exhausted: Vec<u16> = self
            .holes
            .iter()
            .filter(|(_, h)| h.tries >= max_tries && h.last_request_ms.is_some_and(|t| now_ms - t >= retry_ms))
            .map(|(s, _)| *s)
            .collect();
        self.declare(&exhausted, Lost::NotDelivered);
        let ready: Vec<u16> = self
            .holes
            .iter()
            .filter(|(_, h)| {
                now_ms - h.found_ms >= settle_ms && h.last_request_ms.is_none_or(|t| now_ms - t >= retry_ms)
            })
            .map(|(s, _)| *s)
            .collect();
        let mut merged: Vec<(u16, u16)> = Vec::new();
        for (first, last, _) in runs(&ready) {
            match merged.last_mut() {
                Some((_, l)) if ahead(*l, first) <= merge_gap => *l = last,
                _ => merged.push((first, last)),
            }
        }
        let mut out = Vec::new();
        for (first, mut last) in merged.into_iter().take(max_runs) {
            // A long range is asked for in pieces (the rest stays due).
            if ahead(first, last) >= MAX_RANGE {
                last = ((first as u32 + MAX_RANGE - 1) % SEQ_MOD) as u16;
            }
            let mut s = first;
            loop {
                if let Some(h) = self.holes.get_mut(&s) {
                    h.tries += 1;
                    h.last_request_ms = Some(now_ms);
                }
                if s == last {
                    break;
                }
                s = ((s as u32 + 1) % SEQ_MOD) as u16;
            }
            out.push((first, last));
        }
        out
    }

    /// The store's end report said its oldest packet of this APID has `oldest` (and
    /// `overwritten` packets were lost since boot): holes older than it are gone.
    pub fn store_oldest(&mut self, oldest: Pos) {
        let Some(last) = self.last else { return };
        let back_oldest = ahead(oldest.seq, last.seq);
        let gone: Vec<u16> = self
            .holes
            .iter()
            .filter(|(s, _)| ahead(**s, last.seq) > back_oldest)
            .map(|(s, _)| *s)
            .collect();
        self.declare(&gone, Lost::Overwritten);
    }
}

/// Contiguous runs (mod 2^14) of sorted sequence counts: (first, last, count).
fn runs(seqs: &[u16]) -> Vec<(u16, u16, u32)> {
    let mut out: Vec<(u16, u16, u32)> = Vec::new();
    for &s in seqs {
        match out.last_mut() {
            Some((_, l, n)) if ahead(*l, s) == 1 => {
                *l = s;
                *n += 1;
            }
            _ => out.push((s, s, 1)),
        }
    }
    // A run ending at 16383 continues one starting at 0 (wrap).
    if out.len() >= 2 {
        let (f0, _, _) = out[0];
        let (_, ll, _) = out[out.len() - 1];
        if f0 == 0 && ll as u32 == SEQ_MOD - 1 {
            let (_, l0, n0) = out.remove(0);
            if let Some(last) = out.last_mut() {
                last.1 = l0;
                last.2 += n0;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(seq: u16, obt: i64) -> Pos {
        Pos { seq, obt_ms: obt }
    }

    // verifies: GND-12
    #[test]
    fn in_order_packets_are_new_and_repeats_duplicates() {
        let mut t = ApidTracker::default();
        for s in 0..10 {
            assert_eq!(
                t.on_packet(p(s, 100 + s as i64), s == 0, 0),
                if s == 0 { Verdict::Reboot } else { Verdict::New }
            );
        }
        assert_eq!(t.on_packet(p(9, 109), false, 0), Verdict::Duplicate);
        assert_eq!(t.on_packet(p(4, 104), false, 0), Verdict::Duplicate);
        assert_eq!(t.holes(), 0);
    }

    // verifies: GND-12, GND-02
    #[test]
    fn lost_packets_become_holes_requested_by_range_and_filled_once() {
        let mut t = ApidTracker::resume(Some(p(10, 1000)));
        assert_eq!(t.on_packet(p(15, 1500), false, 0), Verdict::New);
        assert_eq!(t.holes(), 4);
        assert!(t.due(100, 200, 1000, 3, 8, 0).is_empty(), "settling");
        assert_eq!(t.due(300, 200, 1000, 3, 8, 0), vec![(11, 14)]);
        assert!(t.due(400, 200, 1000, 3, 8, 0).is_empty(), "just requested");
        assert_eq!(t.on_packet(p(12, 1200), false, 500), Verdict::Filled);
        assert_eq!(t.on_packet(p(12, 1200), false, 500), Verdict::Duplicate);
        assert_eq!(t.due(1300, 200, 1000, 3, 8, 0), vec![(11, 11), (13, 14)]);
        assert_eq!(t.filled, 1);
    }

    // verifies: GND-12
    #[test]
    fn first_packet_without_history_asks_for_the_earlier_packets_of_the_boot() {
        let mut t = ApidTracker::default();
        assert_eq!(t.on_packet(p(5, 500), false, 0), Verdict::New);
        assert_eq!(t.due(10, 0, 0, 3, 8, 0), vec![(0, 4)]);
        assert_eq!(t.on_packet(p(0, 100), true, 20), Verdict::Filled);
    }

    // verifies: GND-12
    #[test]
    fn nearby_holes_are_asked_for_in_one_range() {
        let fill = |t: &mut ApidTracker| {
            t.on_packet(p(2, 2), false, 0);
            for s in 100..=200u16 {
                t.on_packet(p(s, s as i64), false, 0);
            }
            t.on_packet(p(202, 202), false, 0);
        };
        let mut t = ApidTracker::resume(Some(p(0, 0)));
        fill(&mut t);
        assert_eq!(t.due(0, 0, 0, 3, 8, 64), vec![(1, 99), (201, 201)]);
        let mut t = ApidTracker::resume(Some(p(0, 0)));
        fill(&mut t);
        assert_eq!(t.due(0, 0, 0, 3, 8, 0), vec![(1, 1), (3, 99), (201, 201)]);
    }

    // verifies: GND-12
    #[test]
    fn a_long_outage_is_asked_for_in_bounded_pieces() {
        let mut t = ApidTracker::resume(Some(p(0, 0)));
        t.on_packet(p(1000, 1000), false, 0);
        assert_eq!(t.due(0, 0, 100, 3, 1, 64), vec![(1, MAX_RANGE as u16)]);
        assert_eq!(
            t.due(1, 0, 100, 3, 1, 64),
            vec![(MAX_RANGE as u16 + 1, 2 * MAX_RANGE as u16)]
        );
    }

    // verifies: GND-12, PUS-PKT-03
    #[test]
    fn wrap_of_the_sequence_count_is_not_a_gap() {
        let mut t = ApidTracker::resume(Some(p(16382, 1)));
        assert_eq!(t.on_packet(p(16383, 2), false, 0), Verdict::New);
        assert_eq!(t.on_packet(p(0, 3), false, 0), Verdict::New);
        assert_eq!(t.on_packet(p(2, 4), false, 0), Verdict::New);
        assert_eq!(t.due(1000, 0, 0, 3, 8, 0), vec![(1, 1)]);
        // A gap across the wrap is one run.
        let mut t = ApidTracker::resume(Some(p(16380, 1)));
        t.on_packet(p(3, 9), false, 0);
        assert_eq!(t.due(1000, 0, 0, 3, 8, 0), vec![(16381, 2)]);
    }

    // verifies: GND-12, PUS-PKT-03
    #[test]
    fn reboot_restarting_counts_is_neither_a_16k_gap_nor_duplicates() {
        let mut t = ApidTracker::resume(Some(p(5000, 10_000)));
        t.on_packet(p(5002, 10_200), false, 0);
        assert_eq!(t.holes(), 1);
        // BOOT event with count 0, later on-board time.
        assert_eq!(t.on_packet(p(0, 20_000), true, 0), Verdict::Reboot);
        assert_eq!(t.holes(), 0);
        let lost = t.take_lost();
        assert_eq!(lost.len(), 1);
        assert_eq!((lost[0].first, lost[0].why), (5001, Lost::Rebooted));
        for s in 1..5 {
            assert_eq!(t.on_packet(p(s, 20_000 + s as i64), false, 0), Verdict::New);
        }
        assert_eq!(t.duplicates, 0);
    }

    // verifies: GND-12
    #[test]
    fn reboot_seen_without_its_boot_event_leaves_the_first_counts_as_holes() {
        let mut t = ApidTracker::resume(Some(p(7000, 10_000)));
        assert_eq!(t.on_packet(p(3, 30_000), false, 0), Verdict::Reboot);
        assert_eq!(t.due(10, 0, 0, 3, 8, 0), vec![(0, 2)]);
        assert_eq!(t.on_packet(p(0, 29_000), true, 0), Verdict::Filled);
    }

    // verifies: GND-12
    #[test]
    fn holes_never_delivered_are_declared_after_the_retries() {
        let mut t = ApidTracker::resume(Some(p(1, 1)));
        t.on_packet(p(3, 3), false, 0);
        assert_eq!(t.due(0, 0, 10, 2, 8, 0), vec![(2, 2)]);
        assert_eq!(t.due(10, 0, 10, 2, 8, 0), vec![(2, 2)]);
        assert!(t.due(20, 0, 10, 2, 8, 0).is_empty());
        let lost = t.take_lost();
        assert_eq!((lost[0].first, lost[0].count, lost[0].why), (2, 1, Lost::NotDelivered));
        assert_eq!(t.lost_packets, 1);
    }

    // verifies: GND-12
    #[test]
    fn holes_older_than_the_store_are_overwritten() {
        let mut t = ApidTracker::resume(Some(p(100, 100)));
        t.on_packet(p(200, 200), false, 0);
        t.store_oldest(p(150, 150));
        let lost = t.take_lost();
        assert_eq!(
            (lost[0].first, lost[0].last, lost[0].why),
            (101, 149, Lost::Overwritten)
        );
        assert_eq!(t.due(0, 0, 0, 3, 8, 0), vec![(150, 199)]);
    }

    // verifies: GND-12
    #[test]
    fn a_stale_copy_from_before_a_reboot_is_a_duplicate() {
        let mut t = ApidTracker::resume(Some(p(10, 50_000)));
        t.on_packet(p(12, 50_200), false, 0);
        // An old-boot packet with count 11 but a time outside the hole's span.
        assert_eq!(t.on_packet(p(11, 10_000), false, 0), Verdict::Duplicate);
        assert_eq!(t.on_packet(p(11, 50_100), false, 0), Verdict::Filled);
    }
}
