//! A time span asked of the on-board store (TC[15,9]) for a TC's reports sent before the
//! first TM heard ([`super::Session::awaited_span`]): asked once, and again only while
//! the packets the store said it held have not all come — each ask replays the whole span,
//! so asking it every gap round while the TC waits would only send duplicates down.
//!
//! Pure: no I/O; the session feeds it the packets, the end report and the asks.

use std::collections::BTreeSet;

use mib::ground_config::GAP_MAX_TRIES;

use crate::pus::RequestId;

/// One robot's span asked of the store by on-board time (Unix ms, inclusive).
#[derive(Clone, Debug)]
pub struct SpanAsk {
    from_ms: i64,
    to_ms: i64,
    /// Times it was asked.
    asks: u32,
    /// The last TC[15,9] sent for it: its end report tells how many packets the span held.
    request: Option<RequestId>,
    /// Packets (APID, count) with a time stamp in the span received, from the first heard
    /// (the span ends at its time stamp) on; bounded by the span's packets.
    seen: BTreeSet<(u16, u16)>,
    /// Packets the store sent for it, from the end report of its last ask.
    held: Option<u32>,
}

impl SpanAsk {
    /// A span not asked yet; `first_heard` (APID, count) is the packet that ends it, heard.
    pub fn new(from_ms: i64, to_ms: i64, first_heard: (u16, u16)) -> SpanAsk {
        SpanAsk {
            from_ms,
            to_ms,
            asks: 0,
            request: None,
            seen: BTreeSet::from([first_heard]),
            held: None,
        }
    }

    /// True if this span contains `[from_ms, to_ms]` (a later TC's span lies inside the
    /// oldest one's: it went out later, the first TM heard is the same).
    pub fn covers(&self, from_ms: i64, to_ms: i64) -> bool {
        self.from_ms <= from_ms && to_ms <= self.to_ms
    }

    /// True when every packet the store said the span held has come.
    pub fn complete(&self) -> bool {
        self.held.is_some_and(|n| self.seen.len() >= n as usize)
    }

    /// True if the span should be asked (again): never asked, or its packets did not all
    /// come (the retrieval, its end report or some of its replay lost) and it was asked
    /// fewer than [`GAP_MAX_TRIES`] times — the bound of a hole asked by count.
    pub fn wanted(&self) -> bool {
        !self.complete() && self.asks < GAP_MAX_TRIES
    }

    /// Times asked.
    pub fn asks(&self) -> u32 {
        self.asks
    }

    /// It was asked with this TC[15,9] (`None`: the send failed; the ask counts anyway).
    pub fn on_asked(&mut self, request: Option<RequestId>) {
        self.asks += 1;
        self.request = request;
    }

    /// A packet of the robot came that is not new (replayed, or heard before): a new one
    /// was made after the ask, not kept in the store it answers from.
    pub fn on_packet(&mut self, apid: u16, seq: u16, obt_ms: i64) {
        if (self.from_ms..=self.to_ms).contains(&obt_ms) {
            self.seen.insert((apid, seq));
        }
    }

    /// A live store end report (TM[15,19]) of `packets` came while `answers` was the
    /// oldest retrieval TC still open (the store answers in order).
    pub fn on_end_report(&mut self, answers: Option<RequestId>, packets: u32) {
        if answers.is_some() && answers == self.request {
            self.held = Some(packets);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const APID: u16 = 0x101;

    // verifies: OPS-LIVE-GAP-02
    #[test]
    fn a_span_is_asked_again_only_until_the_packets_its_store_held_have_come() {
        let rid = |n: u16| RequestId::from_words(0x1000 | n, 0xc000 | n);
        let mut s = SpanAsk::new(1_000, 2_000, (APID, 18));
        assert!(s.wanted() && s.covers(1_500, 2_000) && !s.covers(900, 2_000));
        s.on_asked(Some(rid(1)));
        // Its end report lost: asked again.
        assert!(s.wanted());
        s.on_asked(Some(rid(2)));
        // The store held 3 (16, 17 and the first heard); 17 came, 16 was lost: again.
        s.on_packet(APID, 17, 1_990);
        s.on_packet(APID, 19, 2_001); // after the span: not one of its packets
        s.on_end_report(Some(rid(1)), 3); // an older ask's report is not this one's
        assert!(s.wanted());
        s.on_end_report(Some(rid(2)), 3);
        assert!(!s.complete() && s.wanted());
        s.on_asked(Some(rid(3)));
        s.on_packet(APID, 16, 1_400);
        s.on_end_report(Some(rid(3)), 3);
        assert!(s.complete() && !s.wanted(), "every packet came: never asked again");
        // Bounded when they never all come.
        let mut t = SpanAsk::new(1_000, 2_000, (APID, 18));
        for k in 0..GAP_MAX_TRIES {
            assert!(t.wanted());
            t.on_asked(Some(rid(k as u16)));
        }
        assert!(!t.wanted() && t.asks() == GAP_MAX_TRIES);
    }
}
