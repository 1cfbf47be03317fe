//! The destination handler's record of the file data not yet received (its lost segment
//! store), kept as sorted, disjoint gaps.
//!
//! cfdp-rs 0.3's own heapless list takes every gap it is given and finds gaps by binary
//! search, so it needs them sorted and never overlapping, and its destination handler
//! does not keep to that: a gap is recorded again when the handler's procedure stopped
//! half way (its immediate NAK found the outbox full: the end of the data seen is not
//! moved on, and the next segment records a second gap from the same start), and the end
//! of the file is recorded again on each repeated EOF while its last segment is missing.
//! The overlapping gaps were each asked for in every NAK and each removed only in part: a
//! 256 KiB `get` through the lossy relay took 117 s instead of 3. Here a gap is merged
//! into the ones it touches, and received data is cut out of every gap it overlaps.
//!
//! The gaps are kept in order by inserting each in its place, not by the list's
//! `coalesce_lost_segments`, which sorts: on board that sort (`core::slice::sort`, about
//! 7 KB of flash) was linked for this alone.

use ::cfdp::lost_segments::{LostSegmentError, LostSegmentStore};
use heapless::Vec;
use mib::cfdp as m;

/// The gaps of the incoming file (at most `MAX_LOST_SEGMENTS`, inline): each `(start,
/// end)` with `start < end`, in order of start, none overlapping or touching another.
#[derive(Debug, Default)]
pub struct Gaps(Vec<(u32, u32), { m::MAX_LOST_SEGMENTS }>);

/// A segment as the store keeps it; the list's errors for one it cannot take.
fn checked(seg: (u64, u64)) -> Result<(u32, u32), LostSegmentError> {
    if seg.0 == seg.1 {
        return Err(LostSegmentError::EmptySegment);
    }
    if seg.0 > seg.1 {
        return Err(LostSegmentError::StartLargerThanEnd(seg.0, seg.1));
    }
    match (u32::try_from(seg.0), u32::try_from(seg.1)) {
        (Ok(s), Ok(e)) => Ok((s, e)),
        _ => Err(LostSegmentError::LargeFileSegmentNotSupported),
    }
}

fn widen(g: &(u32, u32)) -> (u64, u64) {
    (u64::from(g.0), u64::from(g.1))
}

impl Gaps {
    pub fn new() -> Self {
        Gaps(Vec::new())
    }
}

impl LostSegmentStore for Gaps {
    type Iter<'a> = core::iter::Map<core::slice::Iter<'a, (u32, u32)>, fn(&(u32, u32)) -> (u64, u64)>;

    fn iter(&self) -> Self::Iter<'_> {
        self.0.iter().map(widen as fn(&(u32, u32)) -> (u64, u64))
    }
    fn number_of_segments(&self) -> usize {
        self.0.len()
    }
    fn supports_large_file_size(&self) -> bool {
        false
    }
    fn capacity(&self) -> Option<usize> {
        Some(self.0.capacity())
    }
    fn reset(&mut self) {
        self.0.clear()
    }
    fn segment_in_store(&self, seg: (u64, u64)) -> bool {
        self.0.iter().map(widen).any(|(s, e)| s <= seg.0 && seg.1 <= e)
    }

    /// Merged with the gaps it overlaps or touches; nothing when already recorded. Full
    /// only when it touches no gap and every place is taken.
    fn add_lost_segment(&mut self, seg: (u64, u64)) -> Result<(), LostSegmentError> {
        let (mut s, mut e) = checked(seg)?;
        // The first gap that ends at or after the new one's start, and the run from it of
        // those starting at or before its end: the gaps it overlaps or touches.
        let first = self.0.iter().position(|g| g.1 >= s).unwrap_or(self.0.len());
        let run = self.0[first..].iter().take_while(|g| g.0 <= e).count();
        if run == 0 {
            return self.0.insert(first, (s, e)).map_err(|_| LostSegmentError::StoreFull);
        }
        let last = first + run - 1;
        s = s.min(self.0[first].0);
        e = e.max(self.0[last].1);
        self.0[first] = (s, e);
        let len = self.0.len();
        self.0.copy_within(last + 1.., first + 1);
        self.0.truncate(len - (run - 1));
        Ok(())
    }

    /// Cut out of every gap it overlaps. Whether anything was removed; full (nothing
    /// changed) when it would split a gap in two and every place is taken.
    fn remove_lost_segment(&mut self, seg: (u64, u64)) -> Result<bool, LostSegmentError> {
        let (s, e) = checked(seg)?;
        let mut removed = false;
        let mut i = 0;
        while let Some(&(gs, ge)) = self.0.get(i) {
            if ge <= s {
                i += 1;
                continue;
            }
            if gs >= e {
                break;
            }
            match (gs < s, ge > e) {
                // Inside the gap: the parts on either side of it stay.
                (true, true) => {
                    self.0.insert(i + 1, (e, ge)).map_err(|_| LostSegmentError::StoreFull)?;
                    self.0[i].1 = s;
                    return Ok(true);
                }
                (true, false) => {
                    self.0[i].1 = s;
                    i += 1;
                }
                (false, true) => {
                    self.0[i].0 = e;
                    return Ok(true);
                }
                (false, false) => {
                    self.0.remove(i);
                }
            }
            removed = true;
        }
        Ok(removed)
    }

    /// Nothing to do: the gaps are merged as they are added.
    fn coalesce_lost_segments(&mut self) -> Result<(), LostSegmentError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gaps(g: &Gaps) -> std::vec::Vec<(u64, u64)> {
        g.iter().collect()
    }

    // verifies: FILE-CFDP-05
    #[test]
    fn a_gap_recorded_twice_or_overlapping_is_kept_once_and_data_received_closes_it() {
        let mut g = Gaps::new();
        // The handler's stopped procedure: the same start recorded with growing ends, the
        // end of the file recorded on two EOFs.
        for end in [2000, 3000, 4000] {
            g.add_lost_segment((1000, end)).unwrap();
        }
        g.add_lost_segment((9000, 10000)).unwrap();
        g.add_lost_segment((9000, 10000)).unwrap();
        g.add_lost_segment((500, 1000)).unwrap();
        assert_eq!(gaps(&g), [(500, 4000), (9000, 10000)]);
        // Data received: one request per gap, every byte of it cut out.
        assert!(g.remove_lost_segment((1000, 2000)).unwrap());
        assert_eq!(gaps(&g), [(500, 1000), (2000, 4000), (9000, 10000)]);
        assert!(g.remove_lost_segment((0, 3000)).unwrap(), "overlaps two gaps in part");
        assert_eq!(gaps(&g), [(3000, 4000), (9000, 10000)]);
        assert!(!g.remove_lost_segment((4000, 9000)).unwrap(), "between gaps");
        assert!(g.remove_lost_segment((3000, 10000)).unwrap());
        assert!(g.is_empty());
        assert!(g.remove_lost_segment((5, 5)).is_err());
    }

    /// The gaps a map of missing bytes has: its runs, in order, none touching.
    fn runs(missing: &[bool]) -> std::vec::Vec<(u64, u64)> {
        let mut out = std::vec::Vec::new();
        for (i, &m) in missing.iter().enumerate() {
            match (m, out.last_mut()) {
                (true, Some((_, e))) if *e == i as u64 => *e += 1,
                (true, _) => out.push((i as u64, i as u64 + 1)),
                (false, _) => {}
            }
        }
        out
    }

    proptest::proptest! {
        // verifies: FILE-CFDP-05
        #[test]
        fn the_gaps_are_exactly_the_bytes_recorded_missing_and_not_received_since(
            ops in proptest::collection::vec((proptest::bool::ANY, 0u64..64, 1u64..16), 1..60)
        ) {
            let mut g = Gaps::new();
            let mut missing = [false; 80];
            for (add, s, len) in ops {
                let e = s + len;
                if add {
                    g.add_lost_segment((s, e)).unwrap();
                    missing[s as usize..e as usize].fill(true);
                } else {
                    let was = missing[s as usize..e as usize].contains(&true);
                    proptest::prop_assert_eq!(g.remove_lost_segment((s, e)).unwrap(), was);
                    missing[s as usize..e as usize].fill(false);
                }
                proptest::prop_assert_eq!(gaps(&g), runs(&missing));
                proptest::prop_assert_eq!(g.number_of_segments(), runs(&missing).len());
            }
        }
    }

    // verifies: FILE-CFDP-05
    #[test]
    fn a_full_store_still_takes_a_gap_that_merges_and_refuses_a_split_unchanged() {
        let mut g = Gaps::new();
        let n = m::MAX_LOST_SEGMENTS as u64;
        for i in 0..n {
            g.add_lost_segment((10 * i, 10 * i + 5)).unwrap();
        }
        assert_eq!(
            g.add_lost_segment((10 * n, 10 * n + 5)),
            Err(LostSegmentError::StoreFull)
        );
        g.add_lost_segment((3, 12)).unwrap();
        assert_eq!(g.number_of_segments(), m::MAX_LOST_SEGMENTS - 1);
        assert_eq!(g.iter().next(), Some((0, 15)));
        g.add_lost_segment((1000 * n, 1000 * n + 1)).unwrap();
        let before = gaps(&g);
        assert_eq!(g.remove_lost_segment((5, 6)), Err(LostSegmentError::StoreFull));
        assert_eq!(gaps(&g), before);
        assert_eq!(
            g.add_lost_segment((1 << 32, (1 << 32) + 1)),
            Err(LostSegmentError::LargeFileSegmentNotSupported)
        );
        assert_eq!(
            g.add_lost_segment((7, 3)),
            Err(LostSegmentError::StartLargerThanEnd(7, 3))
        );
    }
}
