//! The TCs a ground awaits the verification of, and the rules that command them: one
//! book for every front end (`ground send`/`run`/`watch`/`demo` through
//! [`super::Session`], the collector's plan runs and its page's single TCs), so the
//! rules cannot drift apart again. Pure: time comes in as `now`, the caller sends.
//!
//! The rules:
//! - A TC waits for acceptance on the MIB's schedule (`mib::ground_config::tc_retry_wait_ms`,
//!   scaled to the book's first wait). Until acceptance it is resent with the same bytes
//!   and sequence count — on a lab link; over frames COP-1 retransmits the frame, so the
//!   waits run on the same schedule without a packet resend.
//! - After acceptance it is never resent: its completion is awaited on its own timeout
//!   (the caller's), and a lost completion report is a TM gap the on-board store fills.
//! - A TM[1,2] whose code is one of the acceptance checks the ground made when it built
//!   the TC is about a copy damaged on the way: the same bytes go out again at once (lab
//!   links; over frames the frame check already caught that).
//! - A TC ends with its completion report or any failure; a TC that does not ask for
//!   completion ends with acceptance. After its last send it is given up: its outcome is
//!   then unknown if it was accepted (or, over frames, its frame acknowledged).

use std::collections::HashMap;
use std::time::{Duration, Instant};

use mib::ground_config::{tc_retry_wait_ms, TC_RETRY_INITIAL_MS, TC_RETRY_MAX};

use crate::pus::{BuiltTc, Stage, Verification};

/// A TC waiting for verification.
#[derive(Clone, Debug)]
pub struct Pending {
    pub robot: u8,
    pub tc: BuiltTc,
    /// The caller's handle (a plan step).
    pub tag: Option<usize>,
    pub label: Option<String>,
    pub first_sent: Instant,
    pub last_sent: Instant,
    pub sends: u32,
    pub accepted: bool,
    /// Most sends of this TC (1 for a connection test).
    pub max_sends: u32,
    /// Never resent (a TC adopted from an interrupted run: its outcome is asked of the
    /// on-board store).
    pub exhausted: bool,
    /// Over frames: `sends` counts waits, the packet went to the link once.
    pub waits_only: bool,
    /// The robot's newest TM sequence count when the TC went out: its reports come after
    /// it, so a gap after it is asked of the store first.
    pub tm_seq_at_send: Option<u16>,
}

impl Pending {
    /// A TC sent for the first time at `now` (`max_sends`: `None` for the MIB's).
    pub fn sent(robot: u8, tc: BuiltTc, tag: Option<usize>, label: Option<String>, now: Instant) -> Pending {
        Pending {
            robot,
            tc,
            tag,
            label,
            first_sent: now,
            last_sent: now,
            sends: 1,
            accepted: false,
            max_sends: TC_RETRY_MAX + 1,
            exhausted: false,
            waits_only: false,
            tm_seq_at_send: None,
        }
    }

    /// Resent while it waits for acceptance, never after.
    fn resendable(&self) -> bool {
        !self.exhausted && !self.accepted
    }

    /// The TC asks for a completion report (its ack flags, in the secondary header).
    fn wants_completion(&self) -> bool {
        self.tc.bytes.get(6).is_some_and(|b| b & 0x01 != 0)
    }
}

/// A verification report as the book reads it.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Not a TC of this book (another ground's, or one forgotten).
    Unknown,
    /// A TM[1,2] for a copy damaged on the way, not the TC's verdict; `resend`: the bytes
    /// to send again now (`None` when its sends are used up).
    DamagedCopy {
        robot: u8,
        tag: Option<usize>,
        tc: &'static str,
        resend: Option<Vec<u8>>,
    },
    /// A report of one of the book's TCs.
    Report {
        robot: u8,
        tag: Option<usize>,
        tc: &'static str,
        /// Time from its first send.
        after: Duration,
        /// This report is its first acceptance-stage report (the robot answered it).
        newly_accepted: bool,
        /// The TC ended (completion, failure, or acceptance of a TC without completion
        /// report); it left the book.
        finished: bool,
    },
}

/// Something due at a tick.
#[derive(Clone, Debug)]
pub enum Due {
    /// Send these bytes again (lab links): send number `send`.
    Resend {
        robot: u8,
        tag: Option<usize>,
        tc: BuiltTc,
        label: Option<String>,
        send: u32,
    },
    /// A wait ended without an answer over frames (COP-1 retransmits, nothing to send).
    Waited { robot: u8 },
    /// Its last wait ended: the TC left the book.
    GaveUp(Pending),
}

impl Due {
    pub fn robot(&self) -> u8 {
        match self {
            Due::Resend { robot, .. } | Due::Waited { robot } => *robot,
            Due::GaveUp(p) => p.robot,
        }
    }
}

/// The TCs awaited, by request ID (APID, sequence count).
#[derive(Debug)]
pub struct TcBook {
    pending: HashMap<(u16, u16), Pending>,
    /// The first wait for acceptance; later ones follow the MIB's schedule scaled to it.
    pub first_wait: Duration,
}

impl Default for TcBook {
    fn default() -> TcBook {
        TcBook {
            pending: HashMap::new(),
            first_wait: Duration::from_millis(TC_RETRY_INITIAL_MS as u64),
        }
    }
}

impl TcBook {
    /// Awaits `p` (replacing a TC of the same request ID).
    pub fn insert(&mut self, p: Pending) {
        self.pending.insert((p.tc.apid, p.tc.seq), p);
    }

    pub fn get(&self, apid: u16, seq: u16) -> Option<&Pending> {
        self.pending.get(&(apid, seq))
    }

    /// Stops awaiting `tc` (its step ended without it).
    pub fn forget(&mut self, tc: &BuiltTc) -> Option<Pending> {
        self.pending.remove(&(tc.apid, tc.seq))
    }

    pub fn contains(&self, tc: &BuiltTc) -> bool {
        self.pending.contains_key(&(tc.apid, tc.seq))
    }

    pub fn values(&self) -> impl Iterator<Item = &Pending> {
        self.pending.values()
    }

    pub fn len(&self) -> usize {
        self.pending.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pending.is_empty()
    }

    /// Drops the TCs `keep` says no to.
    pub fn retain(&mut self, mut keep: impl FnMut(&Pending) -> bool) {
        self.pending.retain(|_, p| keep(p));
    }

    /// When the current wait of `p` ends.
    fn due_at(&self, p: &Pending) -> Instant {
        let first = self.first_wait.as_millis() as u64;
        // The MIB's schedule, scaled to this book's first wait.
        let ms = tc_retry_wait_ms(p.sends.saturating_sub(1)) as u64 * first / TC_RETRY_INITIAL_MS.max(1) as u64;
        p.last_sent + Duration::from_millis(ms)
    }

    /// When the next wait ends (`None`: nothing waits for acceptance).
    pub fn next_due(&self) -> Option<Instant> {
        self.pending
            .values()
            .filter(|p| p.resendable())
            .map(|p| self.due_at(p))
            .min()
    }

    /// A verification report from `robot`. `resends_packets`: the robot's link is a lab
    /// link (false over frames).
    pub fn on_verification(&mut self, robot: u8, v: &Verification, now: Instant, resends_packets: bool) -> Verdict {
        let key = (v.request.apid(), v.request.seq());
        let Some(p) = self.pending.get_mut(&key) else {
            return Verdict::Unknown;
        };
        // The ground builds every TC from the MIB and checks it as the OBSW's acceptance
        // does (CRC, length, version, APID, service, argument lengths and ranges): a
        // TM[1,2] with one of those codes is about a copy damaged on the way (the order of
        // the on-board checks lets a flipped header bit show as any of them).
        let damaged = !v.success
            && v.stage == Stage::Acceptance
            && v.failure
                .as_ref()
                .is_some_and(|f| mib::tc::ACCEPTANCE_FAILURES.iter().any(|c| c.code() == f.code));
        if damaged && resends_packets {
            // Resent at once (same bytes); it counts as a send, so a TC that only ever
            // gets such answers ends after its sends.
            let resend = (p.sends < p.max_sends).then(|| {
                p.sends += 1;
                p.tc.bytes.clone()
            });
            p.last_sent = now;
            return Verdict::DamagedCopy {
                robot,
                tag: p.tag,
                tc: p.tc.def.name,
                resend,
            };
        }
        // Any acceptance-stage report answers the TC (a refusal ends it just below).
        let newly_accepted = v.stage == Stage::Acceptance && !p.accepted;
        if v.stage == Stage::Acceptance {
            p.accepted = true;
        }
        let finished =
            !v.success || v.stage == Stage::Completion || (!p.wants_completion() && v.stage == Stage::Acceptance);
        let verdict = Verdict::Report {
            robot: p.robot,
            tag: p.tag,
            tc: p.tc.def.name,
            after: now.saturating_duration_since(p.first_sent),
            newly_accepted,
            finished,
        };
        if finished {
            self.pending.remove(&key);
        }
        verdict
    }

    /// The waits that ended by `now`: resends (lab links), waits over frames, TCs given
    /// up. `resends_packets(robot)`: that robot's link is a lab link.
    pub fn on_tick(&mut self, now: Instant, resends_packets: impl Fn(u8) -> bool) -> Vec<Due> {
        let due: Vec<(u16, u16)> = self
            .pending
            .iter()
            .filter(|(_, p)| p.resendable() && now >= self.due_at(p))
            .map(|(k, _)| *k)
            .collect();
        let mut out = Vec::new();
        for key in due {
            let Some(p) = self.pending.get_mut(&key) else { continue };
            if p.sends >= p.max_sends {
                if let Some(p) = self.pending.remove(&key) {
                    out.push(Due::GaveUp(p));
                }
                continue;
            }
            p.sends += 1;
            p.last_sent = now;
            if resends_packets(p.robot) {
                out.push(Due::Resend {
                    robot: p.robot,
                    tag: p.tag,
                    tc: p.tc.clone(),
                    label: p.label.clone(),
                    send: p.sends,
                });
            } else {
                p.waits_only = true;
                out.push(Due::Waited { robot: p.robot });
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pus;

    fn tc(seq: u16, name: &str) -> BuiltTc {
        let def = mib::tc::by_name(name).unwrap();
        pus::build_tc(1, seq, def, &[0; 8][..def.args.len()]).unwrap()
    }

    fn report(tc: &BuiltTc, stage: Stage, success: bool, code: Option<u16>) -> Verification {
        Verification {
            request: tc.request_id(),
            stage,
            success,
            step: None,
            failure: code.map(|c| pus::Failure::from_code(c, &[])),
        }
    }

    // verifies: OPS-ENGINE-01
    #[test]
    fn a_tc_is_resent_until_accepted_and_never_after() {
        let t0 = Instant::now();
        let mut b = TcBook::default();
        let ping = tc(7, "PING");
        b.insert(Pending::sent(1, ping.clone(), Some(3), None, t0));
        assert!(b.on_tick(t0, |_| true).is_empty(), "nothing due before the first wait");
        let t1 = t0 + Duration::from_millis(TC_RETRY_INITIAL_MS as u64);
        let due = b.on_tick(t1, |_| true);
        assert!(
            matches!(
                &due[..],
                [Due::Resend {
                    send: 2,
                    tag: Some(3),
                    ..
                }]
            ),
            "{due:?}"
        );
        // Accepted: no resend any more, however long the completion takes.
        let v = b.on_verification(1, &report(&ping, Stage::Acceptance, true, None), t1, true);
        assert!(
            matches!(
                v,
                Verdict::Report {
                    newly_accepted: true,
                    finished: false,
                    ..
                }
            ),
            "{v:?}"
        );
        assert!(b.on_tick(t1 + Duration::from_secs(600), |_| true).is_empty());
        assert!(b.next_due().is_none());
        let v = b.on_verification(1, &report(&ping, Stage::Completion, true, None), t1, true);
        assert!(matches!(v, Verdict::Report { finished: true, .. }), "{v:?}");
        assert!(b.is_empty());
        // Another ground's report: not ours.
        assert_eq!(
            b.on_verification(1, &report(&tc(99, "PING"), Stage::Acceptance, true, None), t1, true),
            Verdict::Unknown
        );
    }

    // verifies: OPS-ENGINE-01
    #[test]
    fn over_frames_the_waits_run_without_a_packet_resend_and_the_tc_is_given_up_after_its_last() {
        let t0 = Instant::now();
        let mut b = TcBook::default();
        let ping = tc(8, "PING");
        b.insert(Pending::sent(1, ping.clone(), None, None, t0));
        let mut t = t0;
        let mut waited = 0;
        let gave_up = loop {
            t += Duration::from_secs(5);
            match b.on_tick(t, |_| false).pop() {
                Some(Due::Waited { robot: 1 }) => waited += 1,
                Some(Due::GaveUp(p)) => break p,
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(waited, TC_RETRY_MAX, "one wait per resend a lab link would make");
        assert!(gave_up.waits_only && !gave_up.accepted);
        assert!(b.is_empty());
    }

    // verifies: OPS-ENGINE-01
    #[test]
    fn a_damaged_copy_is_resent_at_once_on_a_lab_link_and_is_a_verdict_over_frames() {
        let t0 = Instant::now();
        let crc = mib::tc::ACCEPTANCE_FAILURES[0].code();
        let mut b = TcBook::default();
        let ping = tc(9, "PING");
        b.insert(Pending::sent(1, ping.clone(), None, None, t0));
        let v = b.on_verification(1, &report(&ping, Stage::Acceptance, false, Some(crc)), t0, true);
        assert!(
            matches!(&v, Verdict::DamagedCopy { resend: Some(bytes), .. } if *bytes == ping.bytes),
            "{v:?}"
        );
        assert!(b.contains(&ping), "still awaited");
        // Over frames a failure report is the TC's verdict.
        let v = b.on_verification(1, &report(&ping, Stage::Acceptance, false, Some(crc)), t0, false);
        assert!(matches!(v, Verdict::Report { finished: true, .. }), "{v:?}");
        assert!(b.is_empty());
    }
}
