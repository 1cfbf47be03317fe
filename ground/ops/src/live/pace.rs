//! When may the next store retrieval go? The one retrieval-pacing rule of every front end.

use std::collections::VecDeque;

use mib::ground_config::{STORE_REQUEST_MIN_GAP_MS, STORE_REQUEST_TIMEOUT_MS};

use crate::pus::{RequestId, Stage, Tm, TmBody};

/// One robot's store retrievals (a retrieval: the TC[15,128] ranges of one round, sent
/// together). At most one is in flight; it is in flight until each of its TCs has ended —
/// by the store's end report TM[15,19] (taken by its oldest TC still open: the store
/// answers in order) or by the TC's own completion or failure report — or until
/// [`STORE_REQUEST_TIMEOUT_MS`] after it went out, whichever comes first. The next goes no
/// earlier than [`STORE_REQUEST_MIN_GAP_MS`] after the last. The retrievals' own reports
/// can be lost and make new gaps: bounded this way they cannot snowball. When to look for
/// holes, and how many ranges a round asks for, stays the caller's plan.
///
/// Pure: the caller passes the time (ms, any clock that does not go back).
#[derive(Clone, Debug)]
pub struct RetrievalPacer {
    timeout_ms: i64,
    min_gap_ms: i64,
    /// When the last retrieval went out.
    last_sent_ms: Option<i64>,
    /// Request IDs of the last retrieval's TCs not ended yet, oldest first.
    open: VecDeque<RequestId>,
    /// Retrievals sent.
    pub sent: u64,
    /// Retrievals that ended by the timeout (an end report or outcome was lost).
    pub timed_out: u64,
}

impl Default for RetrievalPacer {
    /// The MIB's numbers ([`STORE_REQUEST_TIMEOUT_MS`], [`STORE_REQUEST_MIN_GAP_MS`]).
    fn default() -> Self {
        RetrievalPacer::new(STORE_REQUEST_TIMEOUT_MS, STORE_REQUEST_MIN_GAP_MS)
    }
}

impl RetrievalPacer {
    /// A pacer giving a retrieval up after `timeout_ms` and spacing them by `min_gap_ms`.
    pub fn new(timeout_ms: u32, min_gap_ms: u32) -> RetrievalPacer {
        RetrievalPacer {
            timeout_ms: i64::from(timeout_ms),
            min_gap_ms: i64::from(min_gap_ms),
            last_sent_ms: None,
            open: VecDeque::new(),
            sent: 0,
            timed_out: 0,
        }
    }

    /// True while the last retrieval is in flight (see [`RetrievalPacer`]).
    pub fn in_flight(&self, now_ms: i64) -> bool {
        !self.open.is_empty() && self.last_sent_ms.is_some_and(|t| now_ms - t < self.timeout_ms)
    }

    /// The oldest TC of the last retrieval not ended yet: the one the store's next end
    /// report answers.
    pub fn oldest_open(&self) -> Option<RequestId> {
        self.open.front().copied()
    }

    /// True if a retrieval may go now: none in flight, and the last one at least the
    /// least gap ago.
    pub fn may_send(&self, now_ms: i64) -> bool {
        !self.in_flight(now_ms) && self.last_sent_ms.is_none_or(|t| now_ms - t >= self.min_gap_ms)
    }

    /// A retrieval went out at `now_ms` with these TCs (their request IDs; a TC that
    /// could not be sent is not among them, the time counts anyway).
    pub fn on_sent(&mut self, now_ms: i64, requests: impl IntoIterator<Item = RequestId>) {
        if !self.open.is_empty() {
            self.timed_out += 1;
        }
        self.open = requests.into_iter().collect();
        self.last_sent_ms = Some(now_ms);
        self.sent += 1;
    }

    /// A TM of the robot's APID. `live`: not a packet replayed from the store (an old end
    /// report in a replay ends nothing; a TC's own reports end it however they come).
    pub fn on_tm(&mut self, tm: &Tm, live: bool) {
        if let TmBody::Verification(v) = &tm.body {
            if v.stage == Stage::Completion || !v.success {
                self.open.retain(|r| *r != v.request);
            }
        } else if live && matches!(tm.body.report(), Some(mib_wire::Tm::StoreDownlinkDone(_))) {
            self.open.pop_front();
        }
    }
}
