//! Is the TM complete? The one sequence-count tracker of one APID, for every front end:
//! says for each packet whether it is new, fills a hole, or is a duplicate; keeps the
//! holes to retrieve from the on-board store; tells an obsw restart (sequence counts
//! restart, on-board time goes on) from a gap or from duplicates; says which holes can no
//! longer be had and why. Pure: no I/O, times passed in.

use std::collections::{BTreeMap, HashSet, VecDeque};

use mib::headers::SeqCount;

pub use crate::pus::seq::Pos;
use crate::pus::seq::{seq_ahead as ahead, step, Step, SEQ_AHEAD as AHEAD};

use super::gaps::GapPlan;

/// The first TM sequence count of an obsw after boot: every APID counts from 0.
pub const BOOT_FIRST_SEQ: u16 = 0;
/// The count before a boot's first (0): 16383, where the 14-bit circle wraps.
const BEFORE_ZERO: u16 = SeqCount::new(BOOT_FIRST_SEQ).prev().get();
/// Most holes followed at once per APID. More than the host store holds cannot be
/// retrieved anyway; the excess is reported unrecoverable at once.
pub const MAX_MISSING: usize = 2 * mib::config::TM_STORE_CAPACITY;
/// Counts received that are remembered behind the newest (to find the ones missing when
/// a range is expected after the fact, [`ApidTracker::expect_from`]): what the on-board
/// store can still give.
pub const RECENT_WINDOW: usize = mib::config::TM_STORE_CAPACITY;

/// Why a hole can no longer be filled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lost {
    /// The robot rebooted and its counts started again at 0 (a store in RAM, started
    /// empty).
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
    /// The first packet heard without history also makes holes of the counts before it
    /// in its boot ([`ApidTracker::following_boot`]).
    from_boot: bool,
    /// Counts expected from here on before anything was heard
    /// ([`ApidTracker::expect_from`]).
    expect: Option<u16>,
    /// The first packet heard.
    first: Option<Pos>,
    /// Counts before the first packet heard with an on-board time from here on are taken
    /// when they come (from the store) ([`ApidTracker::accept_before_first`]).
    before_first_from: Option<i64>,
    /// Counts received recently (at most [`RECENT_WINDOW`]).
    recent: VecDeque<u16>,
    recent_set: HashSet<u16>,
    pub new: u64,
    pub filled: u64,
    pub duplicates: u64,
    pub reboots: u64,
    pub lost_packets: u64,
}

impl ApidTracker {
    /// Follows an APID from the first packet heard on; the counts before it are not
    /// expected (a CLI session: it expects what its run sends,
    /// [`ApidTracker::expect_from`]).
    pub fn new() -> ApidTracker {
        ApidTracker::default()
    }

    /// Follows an APID whose whole boot is wanted: the counts of this boot before the
    /// first packet heard are holes too (a collector archiving everything).
    pub fn following_boot() -> ApidTracker {
        ApidTracker {
            from_boot: true,
            ..Default::default()
        }
    }

    /// Starts from the last archived position (after a collector restart); with none,
    /// as [`ApidTracker::following_boot`].
    pub fn resume(last: Option<Pos>) -> ApidTracker {
        ApidTracker {
            last,
            from_boot: true,
            ..Default::default()
        }
    }

    fn remember(&mut self, seq: u16) {
        if self.recent_set.insert(seq) {
            self.recent.push_back(seq);
            if self.recent.len() > RECENT_WINDOW {
                if let Some(old) = self.recent.pop_front() {
                    self.recent_set.remove(&old);
                }
            }
        }
    }

    /// The first packet heard (`None` before any).
    pub fn first(&self) -> Option<Pos> {
        self.first
    }

    /// Takes the packets before the first one heard whose on-board time is at or after
    /// `obt_from_ms` (and not after the first one's) when they come, as filling: the
    /// reports of a TC sent before anything was heard, asked of the store by time. They
    /// are not holes: what the span held is not known before the store answers.
    pub fn accept_before_first(&mut self, obt_from_ms: i64) {
        self.before_first_from = Some(self.before_first_from.map_or(obt_from_ms, |f| f.min(obt_from_ms)));
    }

    fn before_first(&self, p: Pos) -> bool {
        match (self.first, self.before_first_from) {
            (Some(first), Some(from)) => {
                (1..AHEAD).contains(&ahead(p.seq, first.seq))
                    && (from..=first.obt_ms).contains(&p.obt_ms)
                    && !self.recent_set.contains(&p.seq)
            }
            _ => false,
        }
    }

    /// Newest count received.
    pub fn newest(&self) -> Option<u16> {
        self.last.map(|p| p.seq)
    }

    /// True if `seq` is a hole now.
    pub fn is_missing(&self, seq: u16) -> bool {
        self.holes.contains_key(&seq)
    }

    /// The holes (counts), in count order.
    pub fn missing(&self) -> impl Iterator<Item = u16> + '_ {
        self.holes.keys().copied()
    }

    /// Expects every count from `first` on: counts between it and the newest that were
    /// not received (as far as [`RECENT_WINDOW`] remembers) become holes; with nothing
    /// heard yet, the first packet makes holes of the counts from `first` before it.
    pub fn expect_from(&mut self, first: u16) {
        let first = SeqCount::new(first);
        let Some(last) = self.last else {
            self.expect = Some(first.get());
            return;
        };
        let behind = SeqCount::new(last.seq).since(first);
        if behind as usize >= RECENT_WINDOW {
            return;
        }
        for k in 0..=behind {
            let seq = first.add(k).get();
            if !self.recent_set.contains(&seq) && !self.holes.contains_key(&seq) && self.holes.len() < MAX_MISSING {
                self.holes.insert(
                    seq,
                    Hole {
                        after_obt_ms: i64::MIN,
                        before_obt_ms: last.obt_ms,
                        tries: 0,
                        last_request_ms: None,
                        found_ms: i64::MIN / 2,
                    },
                );
            }
        }
    }

    /// The on-board time window of the holes among the counts `first..=last` (mod 2^14):
    /// from the packet heard before the earliest to the packet heard after the latest.
    /// The store's packets of that window are exactly the stream's between those two
    /// (time stamps do not go back), so a retrieval by time (TC[15,9]) gets the holes and
    /// no older packet that happens to carry the same count: a store holding more than
    /// 2^14 packets holds every count more than once. `None` when a hole's window is not
    /// known (holes expected before the first packet heard) or none is in the range.
    pub fn window(&self, first: u16, last: u16) -> Option<(i64, i64)> {
        let n = SeqCount::new(last).since(SeqCount::new(first));
        let mut w: Option<(i64, i64)> = None;
        for k in 0..=n {
            let Some(h) = self.holes.get(&SeqCount::new(first).add(k).get()) else {
                continue;
            };
            if h.after_obt_ms == i64::MIN || h.after_obt_ms > h.before_obt_ms {
                return None;
            }
            w = Some(w.map_or((h.after_obt_ms, h.before_obt_ms), |(a, b)| {
                (a.min(h.after_obt_ms), b.max(h.before_obt_ms))
            }));
        }
        w
    }

    /// Holes as inclusive ranges in count order (a run across the wrap is split).
    pub fn missing_ranges(&self) -> Vec<(u16, u16)> {
        let mut out: Vec<(u16, u16)> = Vec::new();
        for &m in self.holes.keys() {
            match out.last_mut() {
                Some((_, last)) if *last + 1 == m => *last = m,
                _ => out.push((m, m)),
            }
        }
        out
    }

    /// Holes at or before `cutoff` (at most half the 14-bit circle behind it), oldest
    /// first, as inclusive ranges.
    pub fn missing_upto(&self, cutoff: u16) -> Vec<(u16, u16)> {
        let mut ms: Vec<u16> = self
            .holes
            .keys()
            .copied()
            .filter(|&m| ahead(m, cutoff) < AHEAD)
            .collect();
        ms.sort_by_key(|&m| std::cmp::Reverse(ahead(m, cutoff)));
        ranges_of(&ms)
    }

    /// Holes after `from` (up to half the 14-bit circle ahead of it), oldest first, as
    /// inclusive ranges: the TM sent since a TC went out, where its reports are.
    pub fn missing_after(&self, from: u16) -> Vec<(u16, u16)> {
        let mut ms: Vec<u16> = self
            .holes
            .keys()
            .copied()
            .filter(|&m| (1..AHEAD).contains(&ahead(from, m)))
            .collect();
        ms.sort_by_key(|&m| ahead(from, m));
        ranges_of(&ms)
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
            // packet heard is asked of the store too when the whole boot is wanted (what
            // it no longer holds is reported overwritten), else what was expected.
            let before = match self.expect.take() {
                Some(first) if ahead(first, p.seq) < AHEAD => Some(SeqCount::new(first).prev().get()),
                Some(_) => None,
                None => (self.from_boot && !boot && p.seq > 0).then_some(BEFORE_ZERO),
            };
            if let Some(seq) = before {
                self.add_holes(Pos { seq, obt_ms: i64::MIN }, p, now_ms);
            }
            self.remember(p.seq);
            self.last = Some(p);
            self.first = Some(p);
            self.new += 1;
            return if boot {
                self.reboots += 1;
                Verdict::Reboot
            } else {
                Verdict::New
            };
        };
        // The one rule of the step (`ground_pus::seq::step`, the archive's too); holes
        // are this tracker's.
        match step(last, p, boot) {
            Step::Restart(_) => self.reboot(p, now_ms),
            // The store was kept: the holes before the restart can still be filled.
            Step::Resumed(_) => {
                self.add_holes(last, p, now_ms);
                self.remember(p.seq);
                self.last = Some(p);
                self.new += 1;
                self.reboots += 1;
                Verdict::Reboot
            }
            Step::Next | Step::Gap(_) => {
                self.add_holes(last, p, now_ms);
                self.remember(p.seq);
                self.last = Some(p);
                self.new += 1;
                Verdict::New
            }
            Step::Behind => {
                let fills = self
                    .holes
                    .get(&p.seq)
                    .is_some_and(|h| p.obt_ms >= h.after_obt_ms && p.obt_ms <= h.before_obt_ms);
                if fills || self.before_first(p) {
                    self.holes.remove(&p.seq);
                    self.remember(p.seq);
                    self.filled += 1;
                    Verdict::Filled
                } else {
                    self.duplicates += 1;
                    Verdict::Duplicate
                }
            }
        }
    }

    fn reboot(&mut self, p: Pos, now_ms: i64) -> Verdict {
        let old: Vec<u16> = self.holes.keys().copied().collect();
        self.declare(&old, Lost::Rebooted);
        self.reboots += 1;
        self.new += 1;
        // Counts restart at 0 with the boot: what came before this packet is a hole.
        self.recent.clear();
        self.recent_set.clear();
        let start_obt_ms = self.last.map_or(p.obt_ms, |l| l.obt_ms);
        if p.seq > 0 {
            let before = Pos {
                seq: BEFORE_ZERO,
                obt_ms: start_obt_ms,
            };
            self.add_holes(before, p, now_ms);
        }
        self.remember(p.seq);
        self.last = Some(p);
        Verdict::Reboot
    }

    fn add_holes(&mut self, after: Pos, before: Pos, now_ms: i64) {
        let after_seq = SeqCount::new(after.seq);
        let n = SeqCount::new(before.seq).since(after_seq).saturating_sub(1);
        let mut too_many = Vec::new();
        for k in 1..=n {
            let seq = after_seq.add(k).get();
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

    /// The store retrievals due for the holes, as [`GapPlan::round`] plans them: holes
    /// found at least `settle_ms` ago and not requested in the last `retry_ms`. Each hole
    /// asked for counts one try; holes already tried `max_tries` times are declared not
    /// delivered. At most `max_runs` ranges.
    pub fn due(
        &mut self,
        now_ms: i64,
        settle_ms: i64,
        retry_ms: i64,
        max_tries: u32,
        plan: &GapPlan,
        max_runs: usize,
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
                now_ms.saturating_sub(h.found_ms) >= settle_ms
                    && h.last_request_ms.is_none_or(|t| now_ms - t >= retry_ms)
            })
            .map(|(s, _)| *s)
            .collect();
        let runs: Vec<(u16, u16)> = runs(&ready).into_iter().map(|(a, b, _)| (a, b)).collect();
        let out = plan.round(&runs, max_runs);
        for &(first, last) in &out {
            let mut s = first;
            loop {
                if let Some(h) = self.holes.get_mut(&s) {
                    h.tries += 1;
                    h.last_request_ms = Some(now_ms);
                }
                if s == last {
                    break;
                }
                s = SeqCount::new(s).next().get();
            }
        }
        out
    }

    /// The store's end report said its oldest packet of this APID has `oldest` (and
    /// `overwritten` packets were lost since boot): holes older than it are gone.
    /// Judged by time where the hole's window is known: its packets were stamped before
    /// the packet heard after it, so when that is older than the oldest stored packet
    /// they are gone. Counts alone cannot tell once the store holds more than 2^14
    /// packets (a full store does); by count only for holes without a window.
    pub fn store_oldest(&mut self, oldest: Pos) {
        let Some(last) = self.last else { return };
        let back_oldest = ahead(oldest.seq, last.seq);
        let gone: Vec<u16> = self
            .holes
            .iter()
            .filter(
                |(s, h)| match gone_by_time(**s, h.after_obt_ms, h.before_obt_ms, oldest) {
                    Some(gone) => gone,
                    None => ahead(**s, last.seq) > back_oldest,
                },
            )
            .map(|(s, _)| *s)
            .collect();
        self.declare(&gone, Lost::Overwritten);
    }

    /// True when the store's oldest packet (`oldest`, from its end report) is younger
    /// than the holes `first..=last`: they were overwritten. By time where the holes'
    /// window is known ([`ApidTracker::window`]), else by count.
    pub fn overwritten(&self, first: u16, last: u16, oldest: Pos) -> bool {
        let by_time = self
            .window(first, last)
            .and_then(|(after, before)| gone_by_time(last, after, before, oldest));
        by_time.unwrap_or_else(|| {
            oldest.seq != last && SeqCount::new(oldest.seq).since(SeqCount::new(last)) < SeqCount::MODULUS / 2
        })
    }
}

/// Whether the hole `seq`, heard around at on-board times `after..=before`, is older than
/// the store's oldest packet `oldest`: by time when `oldest` lies outside the window, by
/// count inside it (the window's counts are a short run: no second packet with the same
/// count lies in it); `None` when the window is not known.
fn gone_by_time(seq: u16, after: i64, before: i64, oldest: Pos) -> Option<bool> {
    if after == i64::MIN || after > before {
        return None;
    }
    Some(if before < oldest.obt_ms {
        true
    } else if after > oldest.obt_ms {
        false
    } else {
        (1..AHEAD).contains(&ahead(seq, oldest.seq))
    })
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
        if f0 == 0 && ll == BEFORE_ZERO {
            let (_, l0, n0) = out.remove(0);
            if let Some(last) = out.last_mut() {
                last.1 = l0;
                last.2 += n0;
            }
        }
    }
    out
}

/// Sorted counts (in the order wanted) as inclusive ranges of consecutive counts.
fn ranges_of(ms: &[u16]) -> Vec<(u16, u16)> {
    let mut out: Vec<(u16, u16)> = Vec::new();
    for &m in ms {
        match out.last_mut() {
            Some((_, last)) if SeqCount::new(*last).next().get() == m => *last = m,
            _ => out.push((m, m)),
        }
    }
    out
}
