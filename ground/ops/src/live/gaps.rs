//! Which store retrievals to send for a robot's TM gaps: one merge distance and one set of
//! request limits for every front end, from the MIB.

use mib::ground_config::{GAP_MERGE_DISTANCE, GAP_RANGE_MAX, GAP_REQUESTS_MAX};
use mib::headers::SeqCount;

/// Turns missing sequence ranges (inclusive, oldest first) into store retrievals
/// (TC[15,128] ranges): gaps at most [`GapPlan::merge_distance`] counts apart become one
/// range (the packets between come again and are dropped as duplicates), no range is
/// longer than [`GapPlan::range_max`] (the rest is asked for in a later round), and at
/// most [`GapPlan::requests_max`] ranges go out per round.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GapPlan {
    pub merge_distance: u16,
    pub range_max: u16,
    pub requests_max: usize,
}

impl Default for GapPlan {
    /// The MIB's numbers ([`GAP_MERGE_DISTANCE`], [`GAP_RANGE_MAX`], [`GAP_REQUESTS_MAX`]).
    fn default() -> Self {
        GapPlan {
            merge_distance: GAP_MERGE_DISTANCE,
            range_max: GAP_RANGE_MAX,
            requests_max: GAP_REQUESTS_MAX,
        }
    }
}

/// Counts from `from` forward to `to` (mod 2^14).
fn ahead(from: u16, to: u16) -> u16 {
    SeqCount::new(to).since(SeqCount::new(from))
}

impl GapPlan {
    /// Gaps closer than the merge distance as one range each, oldest first.
    pub fn merge(&self, ranges: &[(u16, u16)]) -> Vec<(u16, u16)> {
        let mut merged: Vec<(u16, u16)> = Vec::new();
        for &(a, b) in ranges {
            match merged.last_mut() {
                Some((_, last)) if ahead(*last, a) <= self.merge_distance => *last = b,
                _ => merged.push((a, b)),
            }
        }
        merged
    }

    /// The retrievals of one round for these gaps (oldest first): merged, each cut to
    /// [`GapPlan::range_max`] counts, at most `max_ranges` (and never more than
    /// [`GapPlan::requests_max`]).
    pub fn round(&self, ranges: &[(u16, u16)], max_ranges: usize) -> Vec<(u16, u16)> {
        self.merge(ranges)
            .into_iter()
            .take(max_ranges.min(self.requests_max))
            .map(|(a, b)| {
                let most = self.range_max.max(1);
                if ahead(a, b) >= most {
                    (a, SeqCount::new(a).add(most - 1).get())
                } else {
                    (a, b)
                }
            })
            .collect()
    }
}
