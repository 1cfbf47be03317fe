//! One robot's worker: its own thread, its own link. Subscribes and renews the lease,
//! detects link loss, reconnects with capped backoff, follows sequence counts, asks the
//! on-board store for every hole, checks limits and events, and hands everything to the
//! sink. Nothing here waits on another robot.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender};
use serde::Serialize;

use crate::alarms::{Input, Level, LimitChecker, Severity, Source};
use crate::archive::now_ms;
use crate::link::{Incoming, Link, Transport};
use crate::pus::{self, BuiltTc, RequestId, Stage, Tm, TmBody};

use super::config::{Config, RobotCfg};
use super::dash::{self, DashCmd, RobotDash};
use super::onboard;
use super::planrun::PlanInput;
use super::robotcfg::{self, ConfigTracker, ModulesHk, ReportOutcome};
use super::store::{Health, SinkMsg};
use super::tracker::{ApidTracker, Pos, Verdict};

/// First pause between reconnection attempts; doubles up to the configured cap.
const BACKOFF_START_MS: i64 = 250;
/// Health written to the archive this often.
const HEALTH_MS: i64 = 2_000;
/// Store-range requests sent per round; the next round waits for the store's end report
/// (TM[15,19]) or [`STORE_REQUEST_TIMEOUT_MS`], so one robot has one replay in flight.
const MAX_RUNS_PER_REQUEST: usize = 1;
/// A store request whose end report did not come is given up after this long.
const STORE_REQUEST_TIMEOUT_MS: i64 = 2_000;
/// Least time between two rounds of store requests of one robot: the collector's own
/// requests produce TM whose loss makes holes, so their rate is bounded.
const STORE_REQUEST_MIN_GAP_MS: i64 = 500;
/// Holes closer than this (in sequence counts) are asked for in one range; the packets
/// between them come back as duplicates, which costs less than another request.
const MERGE_GAP: u32 = 64;
/// Subscription and HK-interval commands tried this many times per link-up before
/// waiting for the next renewal.
const HK_SET_TRIES: u32 = 10;
/// Least time between two requests for the module report or the team status.
const ASK_AGAIN_MS: i64 = 500;

/// Link state shown to operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LinkState {
    /// Not heard since the collector started.
    #[default]
    Connecting,
    Up,
    /// Lost: no TM for the loss timeout.
    Lost,
}

impl LinkState {
    pub fn name(self) -> &'static str {
        match self {
            LinkState::Connecting => "connecting",
            LinkState::Up => "up",
            LinkState::Lost => "LOST",
        }
    }
}

/// Live counters of one robot (shared with the display).
#[derive(Clone, Debug, Default, Serialize)]
pub struct RobotStatus {
    pub robot: u8,
    pub addr: String,
    pub link: LinkState,
    pub packets: u64,
    pub filled: u64,
    pub lost: u64,
    pub duplicates: u64,
    pub corrupt: u64,
    pub reboots: u64,
    pub holes: usize,
    pub store_requests: u64,
    pub reconnects: u64,
    pub last_rx_ms: Option<i64>,
    pub last_hk_ms: Option<i64>,
    /// Alarm conditions present now (parameters out of limits, link, stale).
    pub conditions: Vec<String>,
}

pub struct Worker {
    cfg: RobotCfg,
    global: Arc<Config>,
    sink: Sender<SinkMsg>,
    status: Arc<Mutex<RobotStatus>>,
    stop: Arc<AtomicBool>,
    apid: u16,
    trackers: BTreeMap<u16, ApidTracker>,
    limits: LimitChecker,
    tc_seq: u16,
    link: Option<Link>,
    tx: Sender<Incoming>,
    rx: Receiver<Incoming>,
    state: LinkState,
    started_ms: i64,
    last_rx_ms: Option<i64>,
    last_hk_ms: Option<i64>,
    /// When the link last came up: housekeeping is expected from then on.
    up_since_ms: i64,
    backoff_ms: i64,
    next_send_ms: i64,
    hk_interval_ms: u32,
    hk_set: Option<(RequestId, u32)>,
    hk_confirmed: bool,
    /// A mode report has arrived since start or the last reboot (the dashboard's mode
    /// tree is asked for with MODE_ANNOUNCE until then).
    modes_known: bool,
    last_store_request_ms: i64,
    /// A store request whose end report has not come yet.
    store_in_flight: bool,
    conditions: BTreeSet<Source>,
    last_health_ms: i64,
    st: RobotStatus,
    /// The dashboard this thread feeds, when `--http` is given.
    dash: Option<RobotDash>,
    /// The plan run following this robot (`collect::planrun`): it gets every
    /// verification report and event, and the link's loss.
    plan: Option<Sender<PlanInput>>,
    /// The robot's module configuration (issue 24): hash, report, changes.
    modules: ConfigTracker,
    /// When the module report was last asked for (REPORT_MODULES).
    modules_asked_ms: i64,
    /// A team status report arrived since link-up or the last reboot (issue 25).
    team_known: bool,
    /// A team event arrived: ask for the team status.
    team_due: bool,
    /// When the team status was last asked for (TEAM_STATUS_REQUEST).
    team_asked_ms: i64,
}

impl Worker {
    pub fn new(
        cfg: RobotCfg,
        global: Arc<Config>,
        sink: Sender<SinkMsg>,
        status: Arc<Mutex<RobotStatus>>,
        stop: Arc<AtomicBool>,
        history: Vec<(u16, Vec<Pos>)>,
    ) -> Worker {
        let apid = onboard::apid(cfg.number).unwrap_or(0);
        let mut trackers = BTreeMap::new();
        let now = now_ms();
        for (a, positions) in history {
            let mut positions = positions.into_iter();
            let mut t = ApidTracker::resume(positions.next());
            for p in positions {
                t.on_packet(p, false, now);
            }
            // Holes found in the archive are retrieved; what was declared lost before
            // the restart is not declared again.
            t.take_lost();
            t.reset_counters();
            trackers.insert(a, t);
        }
        let (tx, rx) = crossbeam_channel::unbounded();
        let hk_interval_ms = cfg
            .hk_interval_ms
            .unwrap_or_else(|| mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).map_or(1000, |h| h.default_interval_ms));
        let st = RobotStatus {
            robot: cfg.number,
            addr: cfg.addr.to_string(),
            ..Default::default()
        };
        Worker {
            apid,
            trackers,
            limits: LimitChecker::new(),
            tc_seq: ((now / 500) % 16384) as u16,
            link: None,
            tx,
            rx,
            state: LinkState::Connecting,
            started_ms: now,
            last_rx_ms: None,
            last_hk_ms: None,
            up_since_ms: now,
            backoff_ms: BACKOFF_START_MS,
            next_send_ms: now,
            hk_interval_ms,
            hk_set: None,
            hk_confirmed: cfg.hk_interval_ms.is_none(),
            modes_known: false,
            last_store_request_ms: i64::MIN / 2,
            store_in_flight: false,
            conditions: BTreeSet::new(),
            last_health_ms: 0,
            st,
            dash: None,
            plan: None,
            modules: ConfigTracker::new(None),
            modules_asked_ms: i64::MIN / 2,
            team_known: false,
            team_due: false,
            team_asked_ms: i64::MIN / 2,
            cfg,
            global,
            sink,
            status,
            stop,
        }
    }

    /// Starts from the configuration hash last archived for this robot: a robot that
    /// comes back with another one raises CONFIG_CHANGED even across a collector restart.
    pub fn with_config_hash(mut self, hash: Option<u32>) -> Worker {
        self.modules = ConfigTracker::new(hash);
        self
    }

    /// Feeds `dash`'s hub and takes its TCs (`ground collect --http`).
    pub fn with_dashboard(mut self, dash: RobotDash) -> Worker {
        dash.hub.add_robot(self.cfg.number);
        self.dash = Some(dash);
        self
    }

    /// Sends the page's TCs, numbered with this thread's own sequence counter.
    fn dash_commands(&mut self) {
        let Some(d) = &self.dash else { return };
        let cmds: Vec<DashCmd> = d.cmds.try_iter().take(64).collect();
        for c in cmds {
            match c {
                // The page's answer channel may be gone (it timed out): nothing to tell.
                DashCmd::Tc { name, args, reply } => {
                    let r = mib::tc::by_name(&name)
                        .ok_or_else(|| format!("no TC named {name}"))
                        .and_then(|def| self.dash_tc(def, &args, "page"))
                        .map(|tc| crate::dashboard::request_id(self.robot(), tc.apid, tc.seq));
                    let _ = reply.send(r);
                }
                DashCmd::PlanTc {
                    def,
                    args,
                    origin,
                    reply,
                } => {
                    let r = self.dash_tc(def, &args, &origin);
                    let _ = reply.send(r);
                }
                DashCmd::Resend { bytes } => self.send(&bytes),
                DashCmd::Follow(tx) => self.plan = Some(tx),
            }
        }
    }

    /// Numbers a TC of the page or a plan with this thread's sequence counter, shows it
    /// in the dashboard's history and sends it.
    fn dash_tc(&mut self, def: &'static mib::tc::TcDef, args: &[i64], origin: &str) -> Result<BuiltTc, String> {
        if self.link.is_none() {
            return Err(format!("robot {}: no link (reconnecting)", self.robot()));
        }
        // Check the arguments before using up a sequence count.
        pus::build_tc(self.robot(), 0, def, args).map_err(|e| e.to_string())?;
        if def.name == "ACCEPT_CONFIG" {
            // The robot's configuration state changes: its module report is asked for
            // again (after ASK_AGAIN_MS, the TC executed by then) instead of waiting up to
            // 10 s for the MODULES housekeeping.
            self.modules.forget_report();
            self.modules_asked_ms = now_ms();
        }
        let seq = self.next_seq();
        let tc = pus::build_tc(self.robot(), seq, def, args).map_err(|e| e.to_string())?;
        match &self.dash {
            Some(d) => crate::dashboard::tc_sent(&d.hub, self.robot(), &tc, def, args, origin),
            None => return Err("no dashboard".into()),
        };
        match &self.link {
            Some(l) => l
                .send(&tc.bytes)
                .map_err(|e| format!("sending to robot {}: {e}", self.robot()))?,
            None => return Err(format!("robot {}: no link", self.robot())),
        }
        Ok(tc)
    }

    /// Hands the following plan run `msg`; a run that ended stops being followed.
    fn tell_plan(&mut self, msg: PlanInput) {
        if let Some(tx) = &self.plan {
            if tx.send(msg).is_err() {
                self.plan = None;
            }
        }
    }

    fn dash_link(&self) {
        if let Some(d) = &self.dash {
            d.hub.link(
                self.cfg.number,
                match self.state {
                    LinkState::Connecting => crate::dashboard::LinkState::Connecting,
                    LinkState::Up => crate::dashboard::LinkState::Up,
                    LinkState::Lost => crate::dashboard::LinkState::Lost,
                },
            );
        }
    }

    fn robot(&self) -> u8 {
        self.cfg.number
    }

    /// Runs until the stop flag is set.
    pub fn run(mut self) {
        tracing::info!(
            robot = self.robot(),
            "following robot {} at {} ({:?})",
            self.robot(),
            self.cfg.addr,
            self.cfg.transport
        );
        while !self.stop.load(Ordering::Relaxed) {
            match self.rx.recv_timeout(Duration::from_millis(50)) {
                Ok(first) => {
                    self.on_incoming(first);
                    // Bounded drain so timers still run under a flood.
                    for _ in 0..512 {
                        match self.rx.try_recv() {
                            Ok(m) => self.on_incoming(m),
                            Err(_) => break,
                        }
                    }
                }
                Err(crossbeam_channel::RecvTimeoutError::Timeout) => {}
                Err(crossbeam_channel::RecvTimeoutError::Disconnected) => break,
            }
            self.dash_commands();
            let now = now_ms();
            self.timers(now);
        }
        self.publish(now_ms(), true);
        // Dropping the link joins its reader thread.
        self.link = None;
    }

    fn next_seq(&mut self) -> u16 {
        let s = self.tc_seq;
        self.tc_seq = (self.tc_seq + 1) & 0x3FFF;
        s
    }

    fn send(&mut self, bytes: &[u8]) {
        if let Some(l) = &self.link {
            if let Err(e) = l.send(bytes) {
                tracing::debug!(robot = self.cfg.number, "send: {e}");
            }
        }
    }

    fn ensure_link(&mut self) {
        let tcp_dead = self.cfg.transport == Transport::Tcp && self.state != LinkState::Up;
        if self.link.is_some() && !tcp_dead {
            return;
        }
        if self.link.is_some() {
            // TCP: reconnect from scratch.
            self.link = None;
            self.st.reconnects += 1;
        }
        match Link::open_with(
            self.robot(),
            self.cfg.addr,
            self.cfg.transport,
            self.cfg.frames.as_ref(),
            self.tx.clone(),
        ) {
            Ok(l) => self.link = Some(l),
            Err(e) => tracing::debug!(robot = self.robot(), "connect {}: {e}", self.cfg.addr),
        }
    }

    fn timers(&mut self, now: i64) {
        // Link loss: no TM for max(3 HK intervals, 3 s).
        let loss_ms = self.global.loss_ms(self.hk_interval_ms);
        let silent_since = self.last_rx_ms.unwrap_or(self.started_ms);
        if self.state != LinkState::Lost && now - silent_since > loss_ms {
            let was = self.state;
            self.state = LinkState::Lost;
            self.dash_link();
            self.backoff_ms = BACKOFF_START_MS;
            self.next_send_ms = now;
            tracing::warn!(
                robot = self.robot(),
                "robot {}: link lost (no TM for {} ms{})",
                self.robot(),
                now - silent_since,
                if was == LinkState::Connecting {
                    ", never heard"
                } else {
                    ""
                }
            );
            self.condition(
                Source::LinkLoss,
                Severity::High,
                true,
                now,
                None,
                format!("no TM for {} ms", now - silent_since),
            );
            let why = format!("robot {}: no TM for {} ms", self.robot(), now - silent_since);
            self.tell_plan(PlanInput::LinkLost {
                robot: self.robot(),
                why,
            });
            self.condition(Source::StaleData, Severity::Medium, false, now, None, String::new());
        }
        // Stale: TM flows but no HK.
        if self.state == LinkState::Up {
            let hk_since = self.last_hk_ms.unwrap_or(self.started_ms).max(self.up_since_ms);
            let stale_ms = self.global.stale_hk_intervals as i64 * self.hk_interval_ms as i64;
            if now - hk_since > stale_ms.max(1000) {
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
                self.send(&tc.bytes);
            }
            if !self.hk_confirmed && self.state == LinkState::Up {
                let tries = self.hk_set.map_or(0, |(_, n)| n);
                if tries < HK_SET_TRIES {
                    if let Some(tc) = onboard::hk_interval_tc(
                        self.robot(),
                        self.next_seq(),
                        mib::hk::sid::ROBOT_STATUS,
                        self.hk_interval_ms,
                    ) {
                        self.send(&tc.bytes);
                        self.hk_set = Some((tc.request_id(), tries + 1));
                    }
                }
            }
            if self.dash.is_some() && !self.modes_known && self.state == LinkState::Up {
                if let Some(tc) = onboard::mode_announce_tc(self.robot(), self.next_seq()) {
                    self.send(&tc.bytes);
                }
            }
            if self.state == LinkState::Up && !self.team_known {
                self.team_due = true;
            }
            if self.state == LinkState::Up {
                self.next_send_ms = now + self.global.lease_renew_ms as i64;
            } else {
                self.next_send_ms = now + self.backoff_ms;
                self.backoff_ms = (self.backoff_ms * 2).min(self.global.max_backoff_ms as i64);
            }
        }
        self.ask_config(now);
        // Holes → store requests (only while the link is up).
        if self.store_in_flight && now - self.last_store_request_ms >= STORE_REQUEST_TIMEOUT_MS {
            self.store_in_flight = false;
        }
        if self.state == LinkState::Up
            && !self.store_in_flight
            && now - self.last_store_request_ms >= STORE_REQUEST_MIN_GAP_MS
        {
            let g = &self.global;
            let (settle, retry, tries) = (g.gap_settle_ms as i64, g.gap_retry_ms as i64, g.gap_max_tries);
            let mut requests = Vec::new();
            if let Some(t) = self.trackers.get_mut(&self.apid) {
                requests = t.due(now, settle, retry, tries, MAX_RUNS_PER_REQUEST, MERGE_GAP);
            }
            if !requests.is_empty() {
                self.last_store_request_ms = now;
                self.store_in_flight = true;
            }
            let mut whole_sent = false;
            for (first, last) in requests {
                let seq = self.next_seq();
                let Some((tc, ranged)) = onboard::store_range_tc(self.robot(), seq, self.apid, first, last) else {
                    continue;
                };
                if !ranged && whole_sent {
                    continue;
                }
                whole_sent |= !ranged;
                tracing::debug!(robot = self.robot(), "store request {first}..={last}");
                self.send(&tc.bytes);
                self.st.store_requests += 1;
            }
        }
        self.report_lost(now);
        self.publish(now, false);
    }

    fn report_lost(&mut self, now: i64) {
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

    fn publish(&mut self, now: i64, force: bool) {
        let mut st = self.st.clone();
        st.link = self.state;
        st.last_rx_ms = self.last_rx_ms;
        st.last_hk_ms = self.last_hk_ms;
        st.holes = self.trackers.values().map(|t| t.holes()).sum();
        st.packets = self.trackers.values().map(|t| t.new + t.filled).sum();
        st.filled = self.trackers.values().map(|t| t.filled).sum();
        st.lost = self.trackers.values().map(|t| t.lost_packets).sum();
        st.duplicates = self.trackers.values().map(|t| t.duplicates).sum();
        st.reboots = self.trackers.values().map(|t| t.reboots).sum();
        st.conditions = self.conditions.iter().map(|s| s.name().to_string()).collect();
        if force || now - self.last_health_ms >= HEALTH_MS {
            self.last_health_ms = now;
            let _ = self.sink.send(SinkMsg::Health(Health {
                robot: st.robot,
                addr: st.addr.clone(),
                link: st.link.name().to_string(),
                last_heard_ms: st.last_rx_ms,
                last_hk_ms: st.last_hk_ms,
                packets: st.packets,
                filled: st.filled,
                lost: st.lost,
                duplicates: st.duplicates,
                corrupt: st.corrupt,
                reboots: st.reboots,
                updated_ms: now,
            }));
        }
        if let Ok(mut s) = self.status.lock() {
            *s = st;
        }
    }

    /// Raises or clears an alarm condition (only edges reach the archive).
    fn condition(&mut self, src: Source, sev: Severity, on: bool, t: i64, value: Option<f64>, message: String) {
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

    fn on_incoming(&mut self, m: Incoming) {
        let now = m.t_ms;
        let tm = match pus::decode_tm(&m.bytes) {
            Ok(tm) => tm,
            Err(e) => {
                // Headers and CRC good, body not as the MIB says: delivered, archived
                // as it is (with its decode error), never asked for again.
                if let Some((apid, pos)) = onboard::intact_position(&m.bytes) {
                    self.heard(now);
                    tracing::warn!(robot = self.robot(), "undecodable TM kept as raw: {e}");
                    let v = self.trackers.entry(apid).or_default().on_packet(pos, false, now);
                    if v != Verdict::Duplicate {
                        let _ = self.sink.send(SinkMsg::Tm {
                            t_ms: now,
                            robot: self.robot(),
                            raw: m.bytes,
                        });
                    }
                } else {
                    self.st.corrupt += 1;
                    tracing::debug!(robot = self.robot(), "corrupt TM ({e})");
                }
                return;
            }
        };
        self.heard(now);
        let pos = Pos {
            seq: tm.seq,
            obt_ms: tm.time.unix_ms(),
        };
        let boot = onboard::is_boot(&tm);
        let verdict = self.trackers.entry(tm.apid).or_default().on_packet(pos, boot, now);
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
        self.inspect(&tm, live, now);
        if let (true, Some(d)) = (live, &self.dash) {
            dash::to_hub(&d.hub, self.cfg.number, &tm);
        }
        // Replayed reports too (a plan TC's outcome may come from the on-board store);
        // events live only (an old fault replayed must not stop a plan started since).
        let for_plan = match tm.body {
            TmBody::Verification(_) => true,
            TmBody::Event(_) => live,
            _ => false,
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

    /// Asks for the module report until one with the current hash is held, and for the
    /// team status at link-up, after a reboot and on every team event (at most one
    /// request each per [`ASK_AGAIN_MS`]).
    fn ask_config(&mut self, now: i64) {
        if self.state != LinkState::Up || self.link.is_none() {
            return;
        }
        if !self.modules.report_current()
            && now - self.modules_asked_ms >= ASK_AGAIN_MS.max(self.global.lease_renew_ms as i64)
        {
            self.modules_asked_ms = now;
            if let Some(tc) = onboard::report_modules_tc(self.robot(), self.next_seq()) {
                self.send(&tc.bytes);
            }
        }
        if self.team_due && now - self.team_asked_ms >= ASK_AGAIN_MS {
            self.team_due = false;
            self.team_asked_ms = now;
            if let Some(tc) = onboard::team_status_tc(self.robot(), self.next_seq()) {
                self.send(&tc.bytes);
            }
        }
    }

    /// The configuration hash changed: CONFIG_CHANGED (raised and cleared at once, like an
    /// event: it stays until acknowledged) and the new module report asked for.
    fn config_changed(&mut self, change: Option<robotcfg::Change>, t_ms: i64) {
        self.publish_modules();
        let Some(c) = change else { return };
        tracing::warn!(
            robot = self.robot(),
            "robot {}: alarm CONFIG_CHANGED: {}",
            self.robot(),
            c.message
        );
        self.modules_asked_ms = i64::MIN / 2;
        for input in [Input::Activate, Input::Clear] {
            let _ = self.sink.send(SinkMsg::Alarm {
                robot: self.robot(),
                source: Source::ConfigChange,
                severity: Severity::Medium,
                input,
                t_ms,
                value: Some(f64::from(c.to)),
                message: c.message.clone(),
            });
        }
    }

    fn publish_modules(&self) {
        if let Some(d) = &self.dash {
            d.hub.modules(self.cfg.number, self.modules.view().clone());
        }
    }

    fn heard(&mut self, now: i64) {
        self.last_rx_ms = Some(now);
        if let Some(d) = &self.dash {
            d.hub.heard(self.cfg.number, now);
        }
        if self.state != LinkState::Up {
            let was = self.state;
            self.state = LinkState::Up;
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

    /// Limits, events, store end reports, HK-interval confirmation.
    fn inspect(&mut self, tm: &Tm, live: bool, now: i64) {
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
                    for input in [Input::Activate, Input::Clear] {
                        let _ = self.sink.send(SinkMsg::Alarm {
                            robot: self.robot(),
                            source: src.clone(),
                            severity: alarm_sev,
                            input,
                            t_ms: t,
                            value: None,
                            message: e.to_string(),
                        });
                    }
                }
            }
            TmBody::ModeReply { .. } => {
                if live && tm.apid == self.apid {
                    self.modes_known = true;
                }
            }
            TmBody::TeamStatus { .. } => {
                if live && tm.apid == self.apid {
                    self.team_known = true;
                    if let (Some(v), Some(d)) = (robotcfg::team_view(&tm.body, tm.time.unix_ms()), &self.dash) {
                        d.hub.team(self.cfg.number, v);
                    }
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
            TmBody::Unknown { .. } if live && tm.apid == self.apid && onboard::module_report(tm).is_some() => {
                let body = onboard::module_report(tm).unwrap_or_default().to_vec();
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
            _ => {
                if let Some(done) = onboard::store_done(tm) {
                    self.store_in_flight = false;
                    if let (Some(oldest), Some(t)) = (done.oldest, self.trackers.get_mut(&self.apid)) {
                        t.store_oldest(oldest);
                    }
                }
            }
        }
        let _ = now;
    }
}
