//! A packet's place in its APID's sequence, and the one rule for the step from one packet
//! to the next: next, a gap, an obsw restart, or behind (a duplicate or a late packet).
//! The collector's and the CLI's tracker (`ground_ops::live::ApidTracker`) and the
//! archive's gap report (`ground_archive`'s `gaps`) decide with [`step`], so a live
//! ground and its archive never disagree on what is missing.

use mib::headers::SeqCount;

/// Sequence counts are 14 bits: the one type's modulus, `mib::headers::SeqCount::MODULUS`.
pub const SEQ_MOD: u16 = SeqCount::MODULUS;

/// A count at most this far ahead of the last one is "ahead"; further is "behind".
pub const SEQ_AHEAD: u32 = SEQ_MOD as u32 / 2;

/// A packet's place: sequence count and on-board time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pos {
    pub seq: u16,
    pub obt_ms: i64,
}

/// The step from one packet of an APID to the next one received.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// The next count.
    Next,
    /// Ahead (within half the 14-bit circle, not earlier on board): this many counts
    /// between are missing.
    Gap(u32),
    /// The obsw restarted (a BOOT event, or a count not ahead with a later on-board
    /// time): its counts start at 0 again, so this many of the new boot are missing.
    Restart(u32),
    /// The obsw restarted and went on from the counts its store (kept across the
    /// restart) still holds: a BOOT event ahead of the last count, not at 0. This many
    /// counts between are missing, and the store can still give them.
    Resumed(u32),
    /// The same count or behind, not later on board: a duplicate, or a late packet (one
    /// that fills a gap).
    Behind,
}

/// Counts from `from` forward to `to` (mod 2^14).
pub fn seq_ahead(from: u16, to: u16) -> u32 {
    u32::from(SeqCount::new(to).since(SeqCount::new(from)))
}

/// The step from `last` to `next`; `boot`: `next` is the obsw's BOOT event.
pub fn step(last: Pos, next: Pos, boot: bool) -> Step {
    let later = next.obt_ms > last.obt_ms;
    let d = seq_ahead(last.seq, next.seq);
    if boot && later {
        return if d > 0 && d < SEQ_AHEAD && next.seq != 0 {
            Step::Resumed(d - 1)
        } else {
            Step::Restart(u32::from(SeqCount::new(next.seq).get()))
        };
    }
    if d > 0 && d < SEQ_AHEAD && next.obt_ms >= last.obt_ms {
        return if d == 1 { Step::Next } else { Step::Gap(d - 1) };
    }
    if later {
        return Step::Restart(u32::from(SeqCount::new(next.seq).get()));
    }
    Step::Behind
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(seq: u16, obt_ms: i64) -> Pos {
        Pos { seq, obt_ms }
    }

    // verifies: OPS-LIVE-SEQ-01
    #[test]
    fn a_step_is_next_gap_restart_or_behind() {
        assert_eq!(step(p(7, 0), p(8, 0), false), Step::Next);
        assert_eq!(step(p(SEQ_MOD - 1, 0), p(0, 1), false), Step::Next, "the wrap");
        assert_eq!(step(p(7, 0), p(10, 5), false), Step::Gap(2));
        // Ahead but earlier on board: an old copy, not news.
        assert_eq!(step(p(7, 50), p(10, 5), false), Step::Behind);
        // The same count later on board, or a BOOT event: the obsw restarted.
        assert_eq!(step(p(7, 0), p(7, 9), false), Step::Restart(7));
        assert_eq!(step(p(7, 0), p(0, 9), true), Step::Restart(0));
        assert_eq!(
            step(p(9000, 0), p(0, 9), true),
            Step::Restart(0),
            "a store in RAM: its BOOT event is count 0"
        );
        // A BOOT event ahead: the obsw went on from its kept store's counts.
        assert_eq!(step(p(7, 0), p(8, 9), true), Step::Resumed(0));
        assert_eq!(step(p(7, 0), p(70, 9), true), Step::Resumed(62));
        // Behind and not later: a duplicate or a late packet.
        assert_eq!(step(p(7, 9), p(3, 2), false), Step::Behind);
        assert_eq!(step(p(7, 9), p(7, 9), false), Step::Behind);
        assert_eq!(seq_ahead(SEQ_MOD - 2, 1), 3);
    }
}
