//! Each TM received: decoded, placed in its APID's sequence (duplicates dropped, reboots
//! noticed), inspected, handed to the dashboard and the following plan run, archived.

use crate::alarms::{LimitChecker, Severity, Source};
use crate::dash;
use crate::link::Incoming;
use crate::onboard;
use crate::planrun::PlanInput;
use crate::pus::{self, TmBody};
use crate::store::SinkMsg;
use crate::tracker::{ApidTracker, Pos, Verdict};

use super::{LinkState, Worker, BACKOFF_START_MS};

impl Worker {
    pub(super) fn on_incoming(&mut self, m: Incoming) {
        let now = m.t_ms;
        let tm = match pus::decode_tm(&m.bytes) {
            Ok(tm) => tm,
            Err(e) => {
                // Headers and CRC good, body not as the MIB says: delivered, archived
                // as it is (with its decode error), never asked for again.
                if let Some((apid, pos)) = onboard::intact_position(&m.bytes) {
                    self.heard(now);
                    tracing::warn!(robot = self.robot(), "undecodable TM kept as raw: {e}");
                    let v = self
                        .trackers
                        .entry(apid)
                        .or_insert_with(ApidTracker::following_boot)
                        .on_packet(pos, false, now);
                    if v != Verdict::Duplicate {
                        let _ = self.sink.send(SinkMsg::Tm {
                            t_ms: now,
                            robot: self.robot(),
                            raw: m.bytes,
                        });
                    }
                } else {
                    self.st.tm.corrupt += 1;
                    tracing::debug!(robot = self.robot(), "corrupt TM ({e})");
                }
                return;
            }
        };
        self.heard(now);
        self.subscription.on_tm(&tm);
        let pos = Pos {
            seq: tm.seq,
            obt_ms: tm.time.unix_ms(),
        };
        let boot = onboard::is_boot(&tm);
        let verdict = self
            .trackers
            .entry(tm.apid)
            .or_insert_with(ApidTracker::following_boot)
            .on_packet(pos, boot, now);
        match verdict {
            Verdict::Duplicate => return,
            Verdict::Reboot => {
                tracing::warn!(
                    robot = self.robot(),
                    "robot {}: obsw rebooted (APID 0x{:03X} count restarts at {})",
                    self.robot(),
                    tm.apid,
                    tm.seq
                );
                self.limits = LimitChecker::new();
                self.hk_confirmed = self.cfg.hk_interval_ms.is_none();
                self.hk_set = None;
                self.modes_known = false;
                self.team_known = false;
                self.modules.forget_report();
                self.next_send_ms = now;
            }
            Verdict::New | Verdict::Filled => {}
        }
        let live = verdict != Verdict::Filled;
        if tm.apid == self.apid {
            // The pacing rule's ends of a store retrieval (a replayed end report is not one).
            self.pacer.on_tm(&tm, live);
        }
        self.inspect(&tm, live, now);
        if let (true, Some(d)) = (live, &self.dash) {
            dash::to_hub(&d.hub, self.cfg.number, &tm);
        }
        // Replayed reports too (a plan TC's outcome may come from the on-board store);
        // events live only (an old fault replayed must not stop a plan started since).
        if let TmBody::Verification(v) = &tm.body {
            self.page_verification(v);
        }
        let for_plan = match tm.body {
            TmBody::Verification(_) => true,
            TmBody::Event(_) => live,
            TmBody::Hk(_) | TmBody::Report(_) | TmBody::Unknown { .. } => false,
        };
        if self.plan.is_some() && for_plan {
            let robot = self.robot();
            self.tell_plan(PlanInput::Tm { robot, tm: tm.clone() });
        }
        let _ = self.sink.send(SinkMsg::Tm {
            t_ms: now,
            robot: self.robot(),
            raw: m.bytes,
        });
    }

    pub(super) fn heard(&mut self, now: i64) {
        let came_up = self.watch.on_tm(now);
        if let Some(d) = &self.dash {
            d.hub.heard(self.cfg.number, now);
        }
        if let Some(was) = came_up {
            self.up_since_ms = now;
            self.backoff_ms = BACKOFF_START_MS;
            self.next_send_ms = now;
            self.hk_set = None;
            self.modules.forget_report();
            self.team_known = false;
            if was == LinkState::Lost {
                tracing::info!(robot = self.robot(), "robot {}: link restored", self.robot());
            } else {
                tracing::info!(robot = self.robot(), "robot {}: link up", self.robot());
            }
            self.condition(Source::LinkLoss, Severity::High, false, now, None, String::new());
        }
    }
}
