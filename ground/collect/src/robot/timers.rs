//! What the worker does on its clock: link loss and stale housekeeping, subscription,
//! lease renewal and reconnection with backoff, HK interval and mode announcements, and
//! the on-board store asked for every hole.

use crate::alarms::{Severity, Source};
use crate::onboard;
use crate::planrun::PlanInput;

use super::{LinkState, Worker, BACKOFF_START_MS, HK_SET_TRIES, MAX_RUNS_PER_REQUEST};

impl Worker {
    pub(super) fn timers(&mut self, now: i64) {
        self.page_tick();
        // Over frames the robot is heard while its valid frames arrive (idle frames with
        // the CLCW included), whatever happens to its packets.
        if let Some(t) = self.link.as_ref().and_then(|l| l.last_heard_ms()) {
            if self.watch.last_heard_ms().is_none_or(|l| t > l) {
                self.heard(t);
            }
        }
        // Link loss: the rule of every front end (`ground_ops::live::LinkWatch`).
        let closed = self.link.as_ref().is_some_and(|l| l.closed());
        if let Some(loss) = self.watch.tick(now, closed) {
            let silent = loss.silent_ms;
            // Its subscription may be gone with it: once heard again, re-subscribed until
            // it streams.
            self.subscription.lapse();
            self.dash_link();
            self.backoff_ms = BACKOFF_START_MS;
            self.next_send_ms = now;
            tracing::warn!(
                robot = self.robot(),
                "robot {}: link lost (nothing heard for {} ms{})",
                self.robot(),
                silent,
                if loss.never_heard { ", never heard" } else { "" }
            );
            self.condition(
                Source::LinkLoss,
                Severity::High,
                true,
                now,
                None,
                format!("nothing heard (no TM, no valid frame) for {silent} ms"),
            );
            let why = format!("robot {}: nothing heard for {silent} ms", self.robot());
            self.tell_plan(PlanInput::LinkLost {
                robot: self.robot(),
                why,
            });
            self.condition(Source::StaleData, Severity::Medium, false, now, None, String::new());
        }
        // Stale: TM flows but no HK.
        let up = self.watch.state() == LinkState::Up;
        if up {
            let hk_since = self.last_hk_ms.unwrap_or(self.started_ms).max(self.up_since_ms);
            let stale_ms = self.global.stale_hk_intervals as i64 * self.hk_interval_ms as i64;
            if now - hk_since > stale_ms.max(i64::from(mib::ground_config::STALE_HK_MIN_MS)) {
                self.condition(
                    Source::StaleData,
                    Severity::Medium,
                    true,
                    now,
                    None,
                    format!("no housekeeping for {} ms", now - hk_since),
                );
            }
        }
        // Subscribe / renew / reconnect.
        if now >= self.next_send_ms {
            self.ensure_link();
            if let Some(tc) = onboard::subscribe_tc(self.robot(), self.next_seq()) {
                self.send_tc(&tc, "subscribe");
            }
            if !self.hk_confirmed && up {
                let tries = self.hk_set.map_or(0, |(_, n)| n);
                if tries < HK_SET_TRIES {
                    if let Some(tc) = onboard::hk_interval_tc(
                        self.robot(),
                        self.next_seq(),
                        mib::hk::sid::ROBOT_STATUS,
                        self.hk_interval_ms,
                    ) {
                        self.send_tc(&tc, "hk-interval");
                        self.hk_set = Some((tc.request_id(), tries + 1));
                    }
                }
            }
            if self.dash.is_some() && !self.modes_known && up {
                if let Some(tc) = onboard::mode_announce_tc(self.robot(), self.next_seq()) {
                    self.send_tc(&tc, "modes");
                }
            }
            if up && !self.team_known {
                self.team_due = true;
            }
            if up {
                self.next_send_ms = now + self.global.lease_renew_ms as i64;
            } else {
                self.next_send_ms = now + self.backoff_ms;
                self.backoff_ms = (self.backoff_ms * 2).min(self.global.max_backoff_ms as i64);
            }
        }
        // Over a UDP lab link, until the robot streams to this collector: a lost or damaged
        // subscription TC is tried again within SUBSCRIBE_RETRY_MS, not at the next lease
        // renewal or backoff step (the rule of every front end, `live::Subscription`).
        let subscribes = self.link.as_ref().is_some_and(crate::link::Link::subscribes);
        let lost = self.watch.state() == LinkState::Lost;
        if self
            .subscription
            .retry_due(subscribes, lost, self.last_sent_ms.map(|t| now - t))
        {
            if let Some(tc) = onboard::subscribe_tc(self.robot(), self.next_seq()) {
                self.send_tc(&tc, "subscribe");
            }
        }
        self.ask_config(now);
        // Holes → store requests (only while the link is up), when the pacing rule of
        // every front end lets one go (`ground_ops::live::RetrievalPacer`).
        if up && self.pacer.may_send(now) {
            let g = &self.global;
            let (settle, retry, tries) = (g.gap_settle_ms as i64, g.gap_retry_ms as i64, g.gap_max_tries);
            let mut requests = Vec::new();
            if let Some(t) = self.trackers.get_mut(&self.apid) {
                requests = t.due(now, settle, retry, tries, &self.gaps, MAX_RUNS_PER_REQUEST);
            }
            let asked = !requests.is_empty();
            let mut sent = Vec::new();
            let mut whole_sent = false;
            for (first, last) in requests {
                let seq = self.next_seq();
                let window = self.trackers.get(&self.apid).and_then(|t| t.window(first, last));
                let Some((tc, ranged)) = onboard::store_range_tc(self.robot(), seq, self.apid, (first, last), window)
                else {
                    continue;
                };
                if !ranged && whole_sent {
                    continue;
                }
                whole_sent |= !ranged;
                tracing::debug!(robot = self.robot(), "store request {first}..={last}");
                self.send_tc(&tc, "store-request");
                sent.push(tc.request_id());
                self.st.store_requests += 1;
            }
            if asked {
                self.pacer.on_sent(now, sent);
                self.st.store_timeouts = self.pacer.timed_out;
            }
        }
        self.report_lost(now);
        self.publish(now, false);
    }
}
