//! Sequence-count tracking of one APID: duplicates, gaps, late packets.

use std::collections::{HashMap, VecDeque};

/// Sequence counts (14 bits) of one APID as they arrive: which were seen recently, which
/// are missing. Bounded: at most `SEQ_TRACK_WINDOW` counts behind the newest are
/// remembered; a gap older than that counts as unrecoverable.
#[derive(Clone, Debug, Default)]
pub struct SeqTrack {
    newest: Option<u16>,
    /// Missing counts (oldest first).
    pub missing: std::collections::BTreeSet<u16>,
    /// Recently received counts, to recognise duplicates.
    recent: VecDeque<u16>,
    /// Recent counts with the on-board time of their packet.
    recent_set: HashMap<u16, u64>,
    /// Missing counts given up because they fell out of the window.
    pub expired: u64,
    /// Missing counts that arrived later (late or replayed).
    pub filled: u64,
}

/// Sequence counts remembered behind the newest one.
pub const SEQ_TRACK_WINDOW: u16 = 4096;
pub(crate) const SEQ_MOD: u16 = 0x4000;

/// What a sequence count was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeqKind {
    /// The next one, or ahead (the counts in between are now missing).
    New,
    /// A missing count that arrived after all.
    Filled,
    /// Seen before.
    Duplicate,
}

impl SeqTrack {
    fn remember(&mut self, seq: u16, stamp: u64) {
        if self.recent_set.insert(seq, stamp).is_none() {
            self.recent.push_back(seq);
            if self.recent.len() > SEQ_TRACK_WINDOW as usize {
                if let Some(old) = self.recent.pop_front() {
                    self.recent_set.remove(&old);
                }
            }
        }
    }

    /// Takes one received sequence count with its packet's on-board time (`stamp`): the
    /// same count with another time is another packet (the OBSW restarted and counts
    /// again), which starts the tracking afresh.
    pub fn on_seq(&mut self, seq: u16, stamp: u64) -> SeqKind {
        let seq = seq % SEQ_MOD;
        if self.recent_set.get(&seq).is_some_and(|&t| t != stamp) {
            self.expired += self.missing.len() as u64;
            *self = SeqTrack {
                expired: self.expired,
                filled: self.filled,
                ..SeqTrack::default()
            };
        }
        let Some(newest) = self.newest else {
            self.newest = Some(seq);
            self.remember(seq, stamp);
            return SeqKind::New;
        };
        let ahead = seq.wrapping_sub(newest) % SEQ_MOD;
        if ahead != 0 && ahead < SEQ_MOD / 2 {
            // Ahead: everything in between is missing (a jump beyond the window, e.g. an
            // obsw restart, is not a gap to fill but counted as expired).
            if ahead > SEQ_TRACK_WINDOW {
                self.expired += (ahead - 1) as u64;
            } else {
                for k in 1..ahead {
                    self.missing.insert((newest + k) % SEQ_MOD);
                }
            }
            self.newest = Some(seq);
            self.remember(seq, stamp);
            // Forget gaps that fell out of the window.
            let behind = |m: u16| seq.wrapping_sub(m) % SEQ_MOD;
            let old: Vec<u16> = self
                .missing
                .iter()
                .copied()
                .filter(|&m| behind(m) > SEQ_TRACK_WINDOW)
                .collect();
            for m in old {
                self.missing.remove(&m);
                self.expired += 1;
            }
            return SeqKind::New;
        }
        if self.missing.remove(&seq) {
            self.filled += 1;
            self.remember(seq, stamp);
            return SeqKind::Filled;
        }
        if self.recent_set.contains_key(&seq) {
            return SeqKind::Duplicate;
        }
        // Older than anything remembered: cannot tell; take it as late.
        self.remember(seq, stamp);
        SeqKind::Filled
    }

    /// Newest count received.
    pub fn newest(&self) -> Option<u16> {
        self.newest
    }

    /// Missing counts at or before `cutoff` (in the 14-bit circle: at most half of it
    /// behind), as inclusive ranges.
    pub fn missing_upto(&self, cutoff: u16) -> Vec<(u16, u16)> {
        let mut out: Vec<(u16, u16)> = Vec::new();
        let mut ms: Vec<u16> = self
            .missing
            .iter()
            .copied()
            .filter(|&m| cutoff.wrapping_sub(m) % SEQ_MOD < SEQ_MOD / 2)
            .collect();
        // Oldest first relative to the cutoff.
        ms.sort_by_key(|&m| std::cmp::Reverse(cutoff.wrapping_sub(m) % SEQ_MOD));
        for m in ms {
            match out.last_mut() {
                Some((_, last)) if (*last + 1) % SEQ_MOD == m => *last = m,
                _ => out.push((m, m)),
            }
        }
        out
    }

    /// Missing counts after `from` (up to half the 14-bit circle ahead of it), oldest
    /// first, as inclusive ranges: the TM sent since a TC went out, where its reports are.
    pub fn missing_after(&self, from: u16) -> Vec<(u16, u16)> {
        let ahead = |m: u16| m.wrapping_sub(from) % SEQ_MOD;
        let mut ms: Vec<u16> = self
            .missing
            .iter()
            .copied()
            .filter(|&m| (1..SEQ_MOD / 2).contains(&ahead(m)))
            .collect();
        ms.sort_by_key(|&m| ahead(m));
        let mut out: Vec<(u16, u16)> = Vec::new();
        for m in ms {
            match out.last_mut() {
                Some((_, last)) if (*last + 1) % SEQ_MOD == m => *last = m,
                _ => out.push((m, m)),
            }
        }
        out
    }

    #[cfg(test)]
    pub(crate) fn on_seq_t(&mut self, seq: u16) -> SeqKind {
        self.on_seq(seq, seq as u64)
    }

    /// Expects every count from `first` on: counts between it and the newest that were
    /// not received become missing.
    pub fn expect_from(&mut self, first: u16) {
        let first = first % SEQ_MOD;
        let Some(newest) = self.newest else {
            // Nothing yet: the next packet is checked against `first`.
            self.newest = Some(first.wrapping_sub(1) % SEQ_MOD);
            return;
        };
        let behind = newest.wrapping_sub(first) % SEQ_MOD;
        if behind >= SEQ_TRACK_WINDOW {
            return;
        }
        for k in 0..=behind {
            let m = (first + k) % SEQ_MOD;
            if !self.recent_set.contains_key(&m) {
                self.missing.insert(m);
            }
        }
    }

    /// Missing counts as inclusive ranges (wrap-around split).
    pub fn missing_ranges(&self) -> Vec<(u16, u16)> {
        let mut out: Vec<(u16, u16)> = Vec::new();
        for &m in &self.missing {
            match out.last_mut() {
                Some((_, last)) if *last + 1 == m => *last = m,
                _ => out.push((m, m)),
            }
        }
        out
    }
}
