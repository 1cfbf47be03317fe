//! What a TM means to the collector: limits and stale data from housekeeping, alarms
//! from events, the module configuration (docs/modules.md) and team status (docs/team.md), the
//! HK interval confirmed, the store's end report.

use crate::alarms::{Level, Severity, Source};
use crate::onboard;
use crate::pus::{Stage, Tm, TmBody};
use crate::robotcfg::{self, ModulesHk, ReportOutcome};

use super::{LinkState, Worker, ASK_AGAIN_MS};

impl Worker {
    /// Asks for the module report until one with the current hash is held, and for the
    /// team status at link-up, after a reboot and on every team event (at most one
    /// request each per [`ASK_AGAIN_MS`]).
    pub(super) fn ask_config(&mut self, now: i64) {
        if self.watch.state() != LinkState::Up || self.link.is_none() {
            return;
        }
        if !self.modules.report_current()
            && now - self.modules_asked_ms >= ASK_AGAIN_MS.max(self.global.lease_renew_ms as i64)
        {
            self.modules_asked_ms = now;
            if let Some(tc) = onboard::report_modules_tc(self.robot(), self.next_seq()) {
                self.send_tc(&tc, "modules");
            }
        }
        if self.team_due && now - self.team_asked_ms >= ASK_AGAIN_MS {
            self.team_due = false;
            self.team_asked_ms = now;
            if let Some(tc) = onboard::team_status_tc(self.robot(), self.next_seq()) {
                self.send_tc(&tc, "team");
            }
        }
    }

    /// The configuration hash changed: CONFIG_CHANGED (raised and cleared at once, like an
    /// event: it stays until acknowledged) and the new module report asked for.
    pub(super) fn config_changed(&mut self, change: Option<robotcfg::Change>, t_ms: i64) {
        self.publish_modules();
        let Some(c) = change else { return };
        tracing::warn!(
            robot = self.robot(),
            "robot {}: alarm CONFIG_CHANGED: {}",
            self.robot(),
            c.message
        );
        self.modules_asked_ms = i64::MIN / 2;
        self.alarm_event(
            Source::ConfigChange,
            Severity::Medium,
            t_ms,
            Some(f64::from(c.to)),
            &c.message,
        );
    }

    pub(super) fn publish_modules(&self) {
        if let Some(d) = &self.dash {
            d.hub.modules(self.cfg.number, self.modules.view().clone());
        }
    }

    /// Limits, events, store end reports, HK-interval confirmation.
    pub(super) fn inspect(&mut self, tm: &Tm, live: bool, now: i64) {
        match &tm.body {
            TmBody::Hk(h) => {
                if let (true, Some(m)) = (live && tm.apid == self.apid, ModulesHk::of(h)) {
                    let change = self.modules.on_hk(m, tm.time.unix_ms());
                    self.config_changed(change, tm.time.unix_ms());
                }
                if live && tm.apid == self.apid && h.sid == mib::hk::sid::ROBOT_STATUS {
                    self.last_hk_ms = Some(now);
                    self.condition(Source::StaleData, Severity::Medium, false, now, None, String::new());
                } else if live && tm.apid == self.apid && self.last_hk_ms.is_none() {
                    self.last_hk_ms = Some(now);
                }
                if live && self.global.limits && tm.apid == self.apid {
                    for v in &h.values {
                        if let Some(ch) = self.limits.check(v.id, v.eng, |id| h.raw(id)) {
                            let src = Source::Param(ch.param.to_string());
                            let msg = format!(
                                "{} = {:.3} {} ({} limit {:.3})",
                                ch.param,
                                ch.value,
                                ch.unit,
                                match ch.to.max(ch.from) {
                                    Level::Hard => "hard",
                                    _ => "soft",
                                },
                                ch.limit
                            );
                            match ch.to.severity() {
                                Some(sev) => {
                                    // A change of level re-raises at the new severity.
                                    self.conditions.remove(&src);
                                    self.condition(src, sev, true, tm.time.unix_ms(), Some(ch.value), msg);
                                }
                                None => {
                                    self.condition(src, Severity::Low, false, tm.time.unix_ms(), Some(ch.value), msg)
                                }
                            }
                        }
                    }
                }
            }
            TmBody::Event(e) => {
                // Raised at boot, so often retrieved from the store (not live): the newest
                // one names the replaced slot.
                if let (true, Some(slot)) = (
                    e.id == mib::events::eid::MODULE_REPLACED && tm.apid == self.apid,
                    e.param("slot"),
                ) {
                    self.modules.on_replaced(slot, tm.time.unix_ms());
                    self.publish_modules();
                }
                if live && tm.apid == self.apid {
                    if robotcfg::is_team_event(e.id) {
                        self.team_due = true;
                    }
                    if e.id == mib::events::eid::CONFIG_INVALID || e.id == mib::events::eid::MODULE_REPLACED {
                        // Discovery has finished: its report says why.
                        self.modules_asked_ms = i64::MIN / 2;
                        self.modules.forget_report();
                    }
                }
                let sev = mib::events::by_id(e.id).map(|d| d.severity);
                let min = self.global.event_min_severity;
                if let Some(s) = sev.filter(|s| s.subservice() >= min.subservice()) {
                    let alarm_sev = Severity::of_event(s).unwrap_or(Severity::Low);
                    let src = Source::Event(e.name.to_string());
                    let t = tm.time.unix_ms();
                    tracing::warn!(robot = self.robot(), "robot {}: event {e}", self.robot());
                    self.alarm_event(src, alarm_sev, t, None, &e.to_string());
                }
            }
            TmBody::Verification(v) => {
                if let Some((rid, _)) = self.hk_set {
                    if v.request == rid && v.stage == Stage::Completion && v.success {
                        self.hk_confirmed = true;
                        tracing::info!(
                            robot = self.robot(),
                            "robot {}: HK interval {} ms set",
                            self.robot(),
                            self.hk_interval_ms
                        );
                    }
                }
            }
            TmBody::Report(r) => self.inspect_report(tm, r, live),
            TmBody::Unknown { .. } => {}
        }
    }

    /// The reports the worker follows: the modes and the team status known, the module
    /// report, the store's end report. The others change nothing here.
    fn inspect_report(&mut self, tm: &Tm, r: &mib_wire::Tm, live: bool) {
        use mib_wire::Tm as W;
        let ours = live && tm.apid == self.apid;
        match r {
            W::ModeReply(_) if ours => self.modes_known = true,
            W::TeamStatus(_) if ours => {
                self.team_known = true;
                if let (Some(v), Some(d)) = (robotcfg::team_view(&tm.body, tm.time.unix_ms()), &self.dash) {
                    d.hub.team(self.cfg.number, v);
                }
            }
            W::ModuleReport(_) if ours => {
                let body = onboard::module_report(tm).unwrap_or_default();
                let t = tm.time.unix_ms();
                match self.modules.on_report(&body, t) {
                    Ok(ReportOutcome::NotDiscovered) => {}
                    Ok(ReportOutcome::Report(change)) => {
                        tracing::info!(
                            robot = self.robot(),
                            "robot {}: module report: configuration {} {} ({})",
                            self.robot(),
                            self.modules.view().config,
                            self.modules.view().hash,
                            self.modules.view().status
                        );
                        self.config_changed(change, t);
                    }
                    Err(e) => tracing::warn!(robot = self.robot(), "robot {}: {e}", self.robot()),
                }
                self.publish_modules();
            }
            W::StoreDownlinkDone(_) => {
                if let Some(done) = onboard::store_done(tm) {
                    if let (Some(oldest), Some(t)) = (done.oldest, self.trackers.get_mut(&self.apid)) {
                        t.store_oldest(oldest);
                    }
                }
            }
            _ => {}
        }
    }
}
