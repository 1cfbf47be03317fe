//! What the worker reports: alarm conditions (edges only), unrecoverable packets, and
//! its counters to the display and, every [`HEALTH_MS`], to the archive.

use crate::alarms::{Input, Severity, Source};
use crate::store::{Health, SinkMsg};

use super::{Worker, HEALTH_MS};

impl Worker {
    pub(super) fn report_lost(&mut self, now: i64) {
        for (apid, t) in self.trackers.iter_mut() {
            for run in t.take_lost() {
                tracing::warn!(
                    robot = self.cfg.number,
                    "robot {}: APID 0x{apid:03X} packets {}..={} ({}) unrecoverable: {}",
                    self.cfg.number,
                    run.first,
                    run.last,
                    run.count,
                    run.why.reason()
                );
                let _ = self.sink.send(SinkMsg::Lost {
                    robot: self.cfg.number,
                    apid: *apid,
                    run,
                    t_ms: now,
                });
            }
        }
    }

    pub(super) fn publish(&mut self, now: i64, force: bool) {
        let mut st = self.st.clone();
        st.link = self.watch.state();
        st.last_rx_ms = self.watch.last_heard_ms();
        st.last_hk_ms = self.last_hk_ms;
        st.holes = self.trackers.values().map(|t| t.holes()).sum();
        st.tm.packets = self.trackers.values().map(|t| t.new + t.filled).sum();
        st.tm.filled = self.trackers.values().map(|t| t.filled).sum();
        st.tm.lost = self.trackers.values().map(|t| t.lost_packets).sum();
        st.tm.duplicates = self.trackers.values().map(|t| t.duplicates).sum();
        st.tm.reboots = self.trackers.values().map(|t| t.reboots).sum();
        st.conditions = self.conditions.iter().map(|s| s.name().to_string()).collect();
        if force || now - self.last_health_ms >= HEALTH_MS {
            self.last_health_ms = now;
            let _ = self.sink.send(SinkMsg::Health(Health {
                robot: st.robot,
                addr: st.addr.clone(),
                link: st.link.name().to_string(),
                last_heard_ms: st.last_rx_ms,
                last_hk_ms: st.last_hk_ms,
                tm: st.tm,
                updated_ms: now,
            }));
        }
        if let Ok(mut s) = self.status.lock() {
            *s = st;
        }
    }

    /// Raises or clears an alarm condition (only edges reach the archive).
    pub(super) fn condition(
        &mut self,
        src: Source,
        sev: Severity,
        on: bool,
        t: i64,
        value: Option<f64>,
        message: String,
    ) {
        let changed = if on {
            self.conditions.insert(src.clone())
        } else {
            self.conditions.remove(&src)
        };
        if !changed {
            return;
        }
        if on {
            tracing::warn!(
                robot = self.robot(),
                "robot {}: alarm {} ({}): {message}",
                self.robot(),
                src,
                sev.name()
            );
        } else {
            tracing::info!(robot = self.robot(), "robot {}: {} back to normal", self.robot(), src);
        }
        let _ = self.sink.send(SinkMsg::Alarm {
            robot: self.robot(),
            source: src,
            severity: sev,
            input: if on { Input::Activate } else { Input::Clear },
            t_ms: t,
            value,
            message,
        });
    }

    /// An alarm raised and cleared at once, like an event: it stays in the archive until
    /// acknowledged (events of the configured severity, CONFIG_CHANGED).
    pub(super) fn alarm_event(&self, source: Source, severity: Severity, t_ms: i64, value: Option<f64>, message: &str) {
        for input in [Input::Activate, Input::Clear] {
            let _ = self.sink.send(SinkMsg::Alarm {
                robot: self.robot(),
                source: source.clone(),
                severity,
                input,
                t_ms,
                value,
                message: message.to_string(),
            });
        }
    }
}
