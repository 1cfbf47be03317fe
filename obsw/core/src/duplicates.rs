//! The duplicate window: the TCs seen lately, by request ID and packet CRC, with what
//! became of each, so that a ground resend is answered with the same reports and never
//! executed twice.

use mib::config;
use mib_wire::RequestId;

use crate::downlink::Stage;
use crate::failure::SentFailure;

/// What became of a request (kept for duplicate TCs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    Pending,
    Done,
    /// The failure as sent (compact: the window keeps up to `DUPLICATE_WINDOW`).
    Failed(Stage, SentFailure),
}

// The duplicate window must recognise every resend of a TC: the ground resends the same
// bytes for at most `TC_RETRY_SPAN_MS` (its retry schedule), so a TC is remembered at
// least that long, and the window holds more entries than the heartbeat pings the
// ground sends in that span (the rest is for other TCs: see docs/architecture.md).
const _: () = assert!(config::DUPLICATE_MAX_AGE_MS >= mib::ground_config::TC_RETRY_SPAN_MS);
const _: () = assert!(
    config::DUPLICATE_WINDOW as u32 > mib::ground_config::TC_RETRY_SPAN_MS / mib::ground_config::GROUND_HEARTBEAT_MS
);

#[derive(Clone, Debug)]
struct Seen {
    /// The request ID as its 32-bit key (`RequestId::raw`): 4 bytes per entry in the
    /// firmware's static RAM instead of the 8 of the unpacked `RequestId`.
    key: u32,
    crc: u16,
    at: u64,
    outcome: Outcome,
}

/// The last `config::DUPLICATE_WINDOW` TCs; when full, the oldest is forgotten.
#[derive(Default)]
pub(crate) struct Duplicates {
    seen: heapless::Deque<Seen, { config::DUPLICATE_WINDOW }>,
}

impl Duplicates {
    /// The outcome of an earlier TC with the same request ID and CRC, if it is recent
    /// enough (`config::DUPLICATE_MAX_AGE_MS`) to be a resend.
    pub(crate) fn find(&self, req: RequestId, crc: u16, now: u64) -> Option<Outcome> {
        self.seen
            .iter()
            .find(|s| {
                s.key == req.raw() && s.crc == crc && now.saturating_sub(s.at) <= config::DUPLICATE_MAX_AGE_MS as u64
            })
            .map(|s| s.outcome.clone())
    }

    /// Remembers a new TC, its outcome pending.
    pub(crate) fn remember(&mut self, req: RequestId, crc: u16, now: u64) {
        if self.seen.is_full() {
            self.seen.pop_front();
        }
        // Space was made above.
        let _ = self.seen.push_back(Seen {
            key: req.raw(),
            crc,
            at: now,
            outcome: Outcome::Pending,
        });
    }

    /// Records what became of the latest TC with request ID `req`.
    pub(crate) fn set_outcome(&mut self, req: RequestId, outcome: Outcome) {
        if let Some(s) = self.seen.iter_mut().rev().find(|s| s.key == req.raw()) {
            s.outcome = outcome;
        }
    }
}
