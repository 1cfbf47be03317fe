//! A plan's TCs resent until their outcome arrives ([`Resender`]).

use std::collections::HashMap;
use std::time::{Duration, Instant};

use mib::config::{tc_retry_wait_ms, TC_RETRY_MAX};

use crate::ops::Update;
use crate::pus::{BuiltTc, Stage, Verification};

/// What [`Resender`] asks of its driver.
#[derive(Clone, Debug, PartialEq)]
pub enum Resend {
    /// Send these bytes again (the same TC, the same sequence count).
    Bytes { robot: u8, bytes: Vec<u8> },
}

struct Sent {
    robot: u8,
    step: usize,
    tc: BuiltTc,
    first: Instant,
    last: Instant,
    sends: u32,
    accepted: bool,
    /// Every send was made and the TC was accepted: its outcome is awaited from the
    /// on-board store (which the collector asks for every hole), no more resends.
    exhausted: bool,
}

/// The plan's TCs waiting for their outcome, resent with identical bytes after
/// `mib::config::tc_retry_wait_ms` until it arrives — the rules of `ops::Session`
/// (a TM[1,2] for a damaged copy resends at once; an accepted TC is not given up while
/// its step runs). Pure: time comes in as `now`.
#[derive(Default)]
pub struct Resender {
    pending: HashMap<(u16, u16), Sent>,
}

impl Resender {
    /// `tc` of `step` went out to `robot` for the first time at `now`.
    pub fn sent(&mut self, step: usize, robot: u8, tc: BuiltTc, now: Instant) {
        self.pending.insert(
            (tc.apid, tc.seq),
            Sent {
                robot,
                step,
                tc,
                first: now,
                last: now,
                sends: 1,
                accepted: false,
                exhausted: false,
            },
        );
    }

    /// Stops tracking `tc` (its step ended without it).
    pub fn forget(&mut self, tc: &BuiltTc) {
        self.pending.remove(&(tc.apid, tc.seq));
    }

    /// TCs still waiting for their outcome.
    pub fn len(&self) -> usize {
        self.pending.len()
    }

    /// True when no TC waits.
    pub fn is_empty(&self) -> bool {
        self.pending.is_empty()
    }

    /// A verification report from `robot`: the executor's update, and a resend when it
    /// is about a damaged copy.
    pub fn on_verification(&mut self, robot: u8, v: Verification, now: Instant) -> (Option<Update>, Vec<Resend>) {
        let key = (v.request.apid(), v.request.seq());
        let Some(p) = self.pending.get_mut(&key) else {
            // Not a plan TC (the page's own, the collector's subscriptions).
            return (None, Vec::new());
        };
        // The ground builds every TC from the MIB and checks it as the OBSW's acceptance
        // does, so a TM[1,2] with one of those codes is about a copy damaged on the way.
        let damaged = !v.success
            && v.stage == Stage::Acceptance
            && v.failure
                .as_ref()
                .is_some_and(|f| mib::tc::ACCEPTANCE_FAILURES.iter().any(|c| c.code() == f.code));
        if damaged {
            let mut out = Vec::new();
            if p.sends < TC_RETRY_MAX + 1 {
                out.push(Resend::Bytes {
                    robot: p.robot,
                    bytes: p.tc.bytes.clone(),
                });
                p.sends += 1;
            }
            p.last = now;
            let u = Update::DamagedCopy {
                robot,
                tag: Some(p.step),
                tc: p.tc.def.name,
            };
            return (Some(u), out);
        }
        if v.stage == Stage::Acceptance {
            p.accepted = true;
        }
        let wants_completion = p.tc.bytes.get(6).is_some_and(|b| b & 0x01 != 0);
        let finished =
            !v.success || v.stage == Stage::Completion || (!wants_completion && v.stage == Stage::Acceptance);
        let u = Update::Verification {
            robot,
            tag: Some(p.step),
            tc: Some(p.tc.def.name),
            v,
            after: Some(now.saturating_duration_since(p.first)),
        };
        if finished {
            self.pending.remove(&key);
        }
        (Some(u), Vec::new())
    }

    /// Resends that are due at `now`, and TCs given up after their last send.
    pub fn on_tick(&mut self, now: Instant) -> (Vec<Update>, Vec<Resend>) {
        let (mut updates, mut resends, mut gone) = (Vec::new(), Vec::new(), Vec::new());
        for (key, p) in self.pending.iter_mut() {
            if p.exhausted || now < p.last + Duration::from_millis(tc_retry_wait_ms(p.sends - 1) as u64) {
                continue;
            }
            if p.sends > TC_RETRY_MAX {
                if p.accepted {
                    p.exhausted = true;
                } else {
                    gone.push(*key);
                }
                updates.push(Update::GaveUp {
                    robot: p.robot,
                    tag: Some(p.step),
                    tc: p.tc.def.name,
                    sends: p.sends,
                    accepted: p.accepted,
                });
                continue;
            }
            p.sends += 1;
            p.last = now;
            resends.push(Resend::Bytes {
                robot: p.robot,
                bytes: p.tc.bytes.clone(),
            });
            updates.push(Update::Resent {
                robot: p.robot,
                tag: Some(p.step),
                tc: p.tc.def.name,
                send: p.sends,
            });
        }
        for k in gone {
            self.pending.remove(&k);
        }
        (updates, resends)
    }
}
