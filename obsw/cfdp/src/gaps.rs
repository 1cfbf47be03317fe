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

use ::cfdp::lost_segments::{LostSegmentError, LostSegmentStore, LostSegmentsListHeapless};
use mib::cfdp as m;

type List = LostSegmentsListHeapless<{ m::MAX_LOST_SEGMENTS }, u32>;

/// The gaps of the incoming file (at most `MAX_LOST_SEGMENTS`, inline).
#[derive(Debug, Default)]
pub struct Gaps(List);

impl Gaps {
    pub fn new() -> Self {
        Gaps(List::new())
    }

    /// The first gap that overlaps `seg`, cut to `seg`.
    fn overlap(&self, seg: (u64, u64)) -> Option<(u64, u64)> {
        self.0
            .iter()
            .find(|&(s, e)| s < seg.1 && e > seg.0)
            .map(|(s, e)| (s.max(seg.0), e.min(seg.1)))
    }
}

impl LostSegmentStore for Gaps {
    type Iter<'a> = <List as LostSegmentStore>::Iter<'a>;

    fn iter(&self) -> Self::Iter<'_> {
        self.0.iter()
    }
    fn number_of_segments(&self) -> usize {
        self.0.number_of_segments()
    }
    fn supports_large_file_size(&self) -> bool {
        self.0.supports_large_file_size()
    }
    fn capacity(&self) -> Option<usize> {
        LostSegmentStore::capacity(&self.0)
    }
    fn reset(&mut self) {
        LostSegmentStore::reset(&mut self.0)
    }
    fn segment_in_store(&self, segment: (u64, u64)) -> bool {
        self.0.segment_in_store(segment)
    }

    /// Merged with the gaps it overlaps or touches; nothing when already recorded.
    fn add_lost_segment(&mut self, seg: (u64, u64)) -> Result<(), LostSegmentError> {
        if seg.0 < seg.1 && self.0.segment_in_store(seg) {
            return Ok(());
        }
        self.0.add_lost_segment(seg)?;
        self.0.coalesce_lost_segments()
    }

    /// Cut out of every gap it overlaps (each gap's part on its own, so the list's removal
    /// only ever sees a part inside one gap). Whether anything was removed.
    fn remove_lost_segment(&mut self, seg: (u64, u64)) -> Result<bool, LostSegmentError> {
        if seg.0 >= seg.1 {
            // The list's own error for an empty or reversed segment.
            return self.0.remove_lost_segment(seg);
        }
        let mut removed = false;
        while let Some(part) = self.overlap(seg) {
            if !self.0.remove_lost_segment(part)? {
                break;
            }
            removed = true;
        }
        Ok(removed)
    }

    fn coalesce_lost_segments(&mut self) -> Result<(), LostSegmentError> {
        self.0.coalesce_lost_segments()
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
}
