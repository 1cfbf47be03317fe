//! A small feed that fills a [`Hub`] straight from `obsw` links and implements
//! [`Commander`] over them — for the example binary only (`examples/dashboard_demo.rs`).
//! `ground collect --http` does not use it: there the collector's robot threads feed
//! the hub (`collect::dash`). It is deliberately minimal: no renewal of the downlink
//! lease, no reconnects, no gap filling, no archive, alarms without persistence or hysteresis,
//! no plans (the collector does all of that properly). It only uses `link::Link`,
//! `pus::build_tc` and `pus::decode_tm`.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crossbeam_channel::RecvTimeoutError;

use super::{
    AlarmRecord, AlarmState, CommandError, Commander, ConfigState, EventRecord, Hub, LimitState, LinkState, PlanInfo,
    PlanStartError, StageReport,
};
use crate::link::{Incoming, Link, Transport};
use crate::pus::{self, TmBody};

/// No TM for this long counts as a link loss (the collector's rule: max(3 HK intervals, 3 s)).
const LOSS_MS: i64 = 3000;

struct Shared {
    hub: Hub,
    links: HashMap<u8, Link>,
    seq: Mutex<pus::SeqCounters>,
    /// (robot, source) → alarm ID.
    alarm_ids: Mutex<HashMap<(u8, String), u64>>,
    next_alarm: Mutex<u64>,
    stop: AtomicBool,
}

/// Feeds a hub from live links and sends the page's commands over them.
#[derive(Clone)]
pub struct LinkFeed {
    shared: Arc<Shared>,
}

fn now_ms() -> i64 {
    chrono::Utc::now().timestamp_millis()
}

impl LinkFeed {
    /// Opens a link to each robot, asks for its mode tree and starts following it.
    pub fn start(hub: Hub, robots: &[(u8, SocketAddr)]) -> std::io::Result<LinkFeed> {
        let (tx, rx) = crossbeam_channel::bounded::<Incoming>(4096);
        let mut links = HashMap::new();
        for &(robot, addr) in robots {
            hub.add_robot(robot);
            links.insert(robot, Link::open(robot, addr, Transport::Udp, tx.clone())?);
        }
        let feed = LinkFeed {
            shared: Arc::new(Shared {
                hub,
                links,
                seq: Mutex::new(pus::SeqCounters::new()),
                alarm_ids: Mutex::new(HashMap::new()),
                next_alarm: Mutex::new(1),
                stop: AtomicBool::new(false),
            }),
        };
        for &(robot, _) in robots {
            // Any TC makes the OBSW send TM to us; MODE_ANNOUNCE also fills the mode tree.
            feed.send(robot, "MODE_ANNOUNCE", &[mib::modes::node::ROBOT as i64], "feed")
                .map_err(|e| std::io::Error::other(e.0))?;
        }
        let f = feed.clone();
        std::thread::Builder::new()
            .name("dashboard-feed".into())
            .spawn(move || f.run(&rx))?;
        Ok(feed)
    }

    /// Stops following the links.
    pub fn stop(&self) {
        self.shared.stop.store(true, Ordering::Relaxed);
    }

    fn hub(&self) -> &Hub {
        &self.shared.hub
    }

    fn send(&self, robot: u8, name: &str, args: &[i64], origin: &str) -> Result<String, CommandError> {
        let def = mib::tc::by_name(name).ok_or_else(|| CommandError(format!("no TC named {name}")))?;
        let link = self
            .shared
            .links
            .get(&robot)
            .ok_or_else(|| CommandError(format!("no link to robot {robot}")))?;
        let apid = mib::apid::robot_apid(robot).ok_or_else(|| CommandError(format!("robot {robot} has no APID")))?;
        let seq = self
            .shared
            .seq
            .lock()
            .map_err(|_| CommandError("lock".into()))?
            .next(apid);
        let tc = pus::build_tc(robot, seq, def, args).map_err(|e| CommandError(e.to_string()))?;
        let id = super::tc_sent(self.hub(), robot, &tc, def, args, origin);
        link.send(&tc.bytes)
            .map_err(|e| CommandError(format!("sending to robot {robot}: {e}")))?;
        Ok(id)
    }

    fn run(&self, rx: &crossbeam_channel::Receiver<Incoming>) {
        let mut last: HashMap<u8, i64> = HashMap::new();
        while !self.shared.stop.load(Ordering::Relaxed) {
            match rx.recv_timeout(Duration::from_millis(200)) {
                Ok(inc) => {
                    last.insert(inc.robot, inc.t_ms);
                    self.packet(&inc);
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            let now = now_ms();
            for &robot in self.shared.links.keys() {
                let silent = last.get(&robot).is_none_or(|t| now - t > LOSS_MS);
                if silent && last.contains_key(&robot) {
                    self.hub().link(robot, LinkState::Lost);
                    self.raise(robot, "LINK", "high", "no TM for 3 s", now);
                } else if !silent {
                    self.clear(robot, "LINK", now);
                }
            }
        }
    }

    fn packet(&self, inc: &Incoming) {
        let tm = match pus::decode_tm(&inc.bytes) {
            Ok(tm) => tm,
            Err(e) => {
                self.hub().event(EventRecord {
                    robot: inc.robot,
                    t_ms: inc.t_ms,
                    name: "GROUND_DECODE_ERROR".into(),
                    severity: "low".into(),
                    description: e.to_string(),
                    params: Vec::new(),
                });
                return;
            }
        };
        let robot = tm.robot.unwrap_or(inc.robot);
        let t = tm.time.unix_ms();
        self.hub().heard(robot, inc.t_ms);
        match tm.body {
            TmBody::Hk(hk) => {
                let values: Vec<(&str, f64)> = hk.values.iter().map(|v| (v.name, v.eng)).collect();
                // The MIB says in which root modes each parameter's limits apply (V_REG's
                // only with the regulator powered).
                let mode = hk.raw(mib::params::pid::MODE).and_then(|m| u32::try_from(m).ok());
                self.hub().hk(robot, t, &values);
                for v in &hk.values {
                    if v.id == mib::params::pid::MODE {
                        if let Some(n) = mib::modes::mode_name(mib::modes::NodeKind::Root, v.raw as u32) {
                            self.hub().mode(robot, "ROBOT", n);
                        }
                    }
                    if v.id == mib::params::pid::CONFIG_STATE {
                        self.hub().config(robot, ConfigState::from_mib(v.raw as u8));
                    }
                    let param = mib::params::by_id(v.id);
                    let limits = param.and_then(|p| p.limits);
                    let applies = param.is_some_and(|p| match mode {
                        Some(m) => mib::params::limits_apply(p, m),
                        None => mib::params::limits_always_apply(p),
                    });
                    match LimitState::check(limits.as_ref(), v.eng) {
                        LimitState::Hard if applies => {
                            let msg = format!("{} = {:.3} {} outside the hard limits", v.name, v.eng, v.unit);
                            self.raise(robot, v.name, "high", &msg, t);
                        }
                        LimitState::Ok | LimitState::Soft => self.clear(robot, v.name, t),
                        LimitState::Hard | LimitState::None => {}
                    }
                }
            }
            TmBody::Event(ev) => {
                if ev.id == mib::events::eid::MODE_CHANGED {
                    if let (Some(node), Some(to)) = (ev.param("node"), ev.param("to")) {
                        self.node_mode(robot, node as u32, to as u32);
                    }
                }
                if matches!(ev.severity, "medium" | "high") {
                    self.raise(robot, ev.name, ev.severity, ev.description, t);
                }
                self.hub().event(EventRecord {
                    robot,
                    t_ms: t,
                    name: ev.name.to_string(),
                    severity: ev.severity.to_string(),
                    description: ev.description.to_string(),
                    params: ev.params.iter().map(|f| (f.name.clone(), f.value)).collect(),
                });
            }
            TmBody::ModeReply { node, mode, .. } => self.node_mode(robot, node, mode),
            TmBody::Verification(v) => {
                let id = super::request_id(robot, v.request.apid(), v.request.seq());
                self.hub().tc_stage(robot, &id, StageReport::from_verification(&v, t));
            }
            TmBody::DisabledEvents { .. }
            | TmBody::TimeReport { .. }
            | TmBody::MonDefinitions { .. }
            | TmBody::MonTransition { .. }
            | TmBody::StoreDownlinkDone { .. }
            | TmBody::PingReply
            | TmBody::EaDefinitions { .. }
            | TmBody::ParamValue { .. }
            | TmBody::ModeCantReach { .. }
            | TmBody::Unknown { .. } => {}
        }
    }

    fn node_mode(&self, robot: u8, node: u32, mode: u32) {
        super::node_mode(self.hub(), robot, node, mode);
    }

    fn raise(&self, robot: u8, source: &str, severity: &str, message: &str, t: i64) {
        let Ok(mut ids) = self.shared.alarm_ids.lock() else {
            return;
        };
        let key = (robot, source.to_string());
        let existing = ids.get(&key).and_then(|id| self.hub().alarm_by_id(*id));
        let rec = match existing {
            Some(mut a) if a.state != AlarmState::Cleared => {
                // A standing condition refreshes its alarm once a second, not per report.
                if t - a.last_ms < 1000 {
                    return;
                }
                a.last_ms = t;
                a.message = message.to_string();
                a
            }
            _ => {
                let Ok(mut n) = self.shared.next_alarm.lock() else {
                    return;
                };
                let id = *n;
                *n += 1;
                ids.insert(key, id);
                AlarmRecord {
                    id,
                    robot,
                    source: source.to_string(),
                    severity: severity.to_string(),
                    state: AlarmState::Active,
                    message: message.to_string(),
                    first_ms: t,
                    last_ms: t,
                    shelved_until_ms: None,
                }
            }
        };
        self.hub().alarm(rec);
    }

    fn clear(&self, robot: u8, source: &str, t: i64) {
        let Ok(ids) = self.shared.alarm_ids.lock() else { return };
        let Some(id) = ids.get(&(robot, source.to_string())) else {
            return;
        };
        if let Some(mut a) = self.hub().alarm_by_id(*id) {
            // Event alarms stay until acknowledged; condition alarms clear by themselves.
            if a.state != AlarmState::Cleared && mib::events::by_name(source).is_none() {
                a.state = AlarmState::Cleared;
                a.last_ms = t;
                self.hub().alarm(a);
            }
        }
    }
}

impl Commander for LinkFeed {
    fn send_tc(&self, robot: u8, name: &str, args: &[i64]) -> Result<String, CommandError> {
        self.send(robot, name, args, "page")
    }

    fn ack_alarm(&self, id: u64) -> Result<(), CommandError> {
        let mut a = self
            .hub()
            .alarm_by_id(id)
            .ok_or_else(|| CommandError(format!("no alarm {id}")))?;
        match a.state {
            AlarmState::Active | AlarmState::Shelved => {
                a.state = AlarmState::Acknowledged;
                a.shelved_until_ms = None;
                self.hub().alarm(a);
                Ok(())
            }
            AlarmState::Acknowledged => Ok(()),
            AlarmState::Cleared => Err(CommandError(format!("alarm {id} is cleared"))),
        }
    }

    fn shelve_alarm(&self, id: u64, for_ms: i64) -> Result<(), CommandError> {
        let mut a = self
            .hub()
            .alarm_by_id(id)
            .ok_or_else(|| CommandError(format!("no alarm {id}")))?;
        a.state = AlarmState::Shelved;
        a.shelved_until_ms = Some(now_ms() + for_ms);
        self.hub().alarm(a);
        Ok(())
    }

    fn plans(&self) -> Vec<PlanInfo> {
        Vec::new()
    }

    fn start_plan(&self, name: &str, _confirmed: bool) -> Result<String, PlanStartError> {
        Err(PlanStartError::Unknown(format!(
            "no plan \"{name}\": this feed runs no plans (`ground collect --http` does)"
        )))
    }
}
