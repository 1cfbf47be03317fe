//! The live fleet picture and the replayable stream of its changes.
//!
//! Every change the feed reports updates the picture and becomes one message with a
//! sequence number (the SSE event ID). The last `replay` messages are kept in a ring
//! so that a page that reconnects with `Last-Event-ID` gets exactly what it missed;
//! one that fell further behind gets a `reset` and reloads the snapshot. Both are
//! taken under one lock, so a snapshot plus the messages after its `last_id` is the
//! complete picture.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};

use serde::Serialize;
use serde_json::{json, Value};
use tokio::sync::broadcast;

use super::{
    AlarmRecord, AlarmState, CommandRecord, ConfigState, EventRecord, LimitState, LinkState, ModuleView, OnBoardView,
    PlanRun, StageReport, TeamView,
};

/// Messages kept for replay after a reconnect (at 50 robots × 10 Hz HK this is about
/// 16 s of outage; at the demo's two robots several minutes).
pub const DEFAULT_REPLAY: usize = 8192;
/// Live samples kept per robot and parameter to extend archive plots.
pub const DEFAULT_LIVE_SAMPLES: usize = 1024;
/// Events kept for the page's list.
const EVENT_HISTORY: usize = 2000;
/// Commands kept for the command history.
const COMMAND_HISTORY: usize = 1000;
/// Cleared alarms kept (active, acknowledged and shelved ones are all kept).
const CLEARED_ALARMS: usize = 500;
/// Broadcast capacity per subscriber; a page further behind than this gets a reset.
const BROADCAST_CAP: usize = 4096;

#[derive(Clone, Debug, Serialize)]
struct HkCell {
    value: f64,
    unit: &'static str,
    limit: LimitState,
    t_ms: i64,
}

#[derive(Clone, Debug, Serialize)]
struct RobotView {
    robot: u8,
    link: LinkState,
    last_heard_ms: Option<i64>,
    mode: Option<String>,
    /// Mode of every mode-tree node heard of, by node name.
    modes: BTreeMap<String, String>,
    config: Option<ConfigState>,
    hk: BTreeMap<String, HkCell>,
    hk_t_ms: Option<i64>,
    /// Module set and configuration state (None until the collector heard of them).
    modules: Option<ModuleView>,
    /// Team status (None until a TEAM_STATUS report arrived).
    team: Option<TeamView>,
    /// The on-board plan (None until its HK, report or event arrived).
    onboard: Option<OnBoardView>,
    /// `last_heard_ms` as last published to the page.
    #[serde(skip)]
    published_heard_ms: Option<i64>,
}

/// The page learns that a robot is still heard at least this often (ms) while only frames
/// (no HK message, which carries its own time) prove it: its "heard … s ago" stays true.
const HEARD_PUBLISH_MS: i64 = 1000;

impl RobotView {
    fn new(robot: u8) -> RobotView {
        RobotView {
            robot,
            link: LinkState::Connecting,
            last_heard_ms: None,
            mode: None,
            modes: BTreeMap::new(),
            config: None,
            hk: BTreeMap::new(),
            hk_t_ms: None,
            modules: None,
            team: None,
            onboard: None,
            published_heard_ms: None,
        }
    }
}

/// Counters of what the hub could not use (nothing dropped silently).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct HubStats {
    /// Messages published since start.
    pub published: u64,
    /// HK values whose name is not a MIB parameter (kept, without unit or limits).
    pub unknown_params: u64,
    /// Stage reports for a request ID the hub never saw sent (kept as a new record).
    pub orphan_stages: u64,
    /// Non-finite HK values (shown, not plotted).
    pub non_finite: u64,
    /// Times a page was sent a reset because it fell behind the replay ring.
    pub resets: u64,
}

struct State {
    robots: BTreeMap<u8, RobotView>,
    live: HashMap<(u8, String), VecDeque<(i64, f64)>>,
    events: VecDeque<EventRecord>,
    alarms: BTreeMap<u64, AlarmRecord>,
    commands: VecDeque<CommandRecord>,
    plans: BTreeMap<String, PlanRun>,
    ring: VecDeque<(u64, Arc<str>)>,
    next_id: u64,
    stats: HubStats,
}

struct Inner {
    state: Mutex<State>,
    tx: broadcast::Sender<(u64, Arc<str>)>,
    replay: usize,
    live_samples: usize,
}

/// The live fleet picture, shared by the feed and the server (cheap to clone).
#[derive(Clone)]
pub struct Hub {
    inner: Arc<Inner>,
}

impl Default for Hub {
    fn default() -> Self {
        Hub::new()
    }
}

/// What a subscriber gets: the missed messages, then the live receiver.
pub(crate) enum Resume {
    Replay(Vec<(u64, Arc<str>)>, broadcast::Receiver<(u64, Arc<str>)>),
    /// The client is too far behind: reload the snapshot.
    Reset(u64, broadcast::Receiver<(u64, Arc<str>)>),
}

impl Hub {
    pub fn new() -> Hub {
        Hub::with_capacity(DEFAULT_REPLAY, DEFAULT_LIVE_SAMPLES)
    }

    /// A hub that keeps `replay` messages for reconnects and `live_samples` samples per
    /// parameter for plots.
    pub fn with_capacity(replay: usize, live_samples: usize) -> Hub {
        let (tx, _) = broadcast::channel(BROADCAST_CAP);
        Hub {
            inner: Arc::new(Inner {
                state: Mutex::new(State {
                    robots: BTreeMap::new(),
                    live: HashMap::new(),
                    events: VecDeque::new(),
                    alarms: BTreeMap::new(),
                    commands: VecDeque::new(),
                    plans: BTreeMap::new(),
                    ring: VecDeque::new(),
                    next_id: 1,
                    stats: HubStats::default(),
                }),
                tx,
                replay: replay.max(1),
                live_samples: live_samples.max(1),
            }),
        }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while holding the lock leaves consistent data (every update is a
        // plain field write), so a poisoned lock is still usable.
        self.inner.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn publish(&self, st: &mut State, msg: Value) {
        let id = st.next_id;
        st.next_id += 1;
        st.stats.published += 1;
        let text: Arc<str> = Arc::from(msg.to_string());
        if st.ring.len() == self.inner.replay {
            st.ring.pop_front();
        }
        st.ring.push_back((id, text.clone()));
        // No receiver is not an error: the message is in the ring for the next page.
        let _no_page_connected = self.inner.tx.send((id, text));
    }

    fn robot(st: &mut State, robot: u8) -> &mut RobotView {
        st.robots.entry(robot).or_insert_with(|| RobotView::new(robot))
    }

    fn publish_robot(&self, st: &mut State, robot: u8) {
        let Some(r) = st.robots.get_mut(&robot) else { return };
        r.published_heard_ms = r.last_heard_ms;
        let msg = json!({"type": "robot", "robot": robot, "link": r.link, "last_heard_ms": r.last_heard_ms,
            "mode": r.mode, "modes": r.modes, "config": r.config});
        self.publish(st, msg);
    }

    /// Declares a robot (shown as connecting until heard).
    pub fn add_robot(&self, robot: u8) {
        let mut st = self.lock();
        if !st.robots.contains_key(&robot) {
            Self::robot(&mut st, robot);
            self.publish_robot(&mut st, robot);
        }
    }

    /// Link state of a robot changed.
    pub fn link(&self, robot: u8, state: LinkState) {
        let mut st = self.lock();
        let r = Self::robot(&mut st, robot);
        if r.link != state {
            r.link = state;
            self.publish_robot(&mut st, robot);
        }
    }

    /// A robot was heard at `t_ms` (a TM, or over the space link a valid frame; marks the
    /// link up). Publishes when the link state changes, and at least every
    /// [`HEARD_PUBLISH_MS`] while heard: the page ages `last_heard_ms` itself and every HK
    /// message carries its time, but on a lossy link frames may be all that is heard.
    pub fn heard(&self, robot: u8, t_ms: i64) {
        let mut st = self.lock();
        let r = Self::robot(&mut st, robot);
        let heard = r.last_heard_ms.map_or(t_ms, |t| t.max(t_ms));
        r.last_heard_ms = Some(heard);
        let stale = r.published_heard_ms.is_none_or(|p| heard - p >= HEARD_PUBLISH_MS);
        if r.link != LinkState::Up || stale {
            r.link = LinkState::Up;
            self.publish_robot(&mut st, robot);
        }
    }

    /// Mode of a mode-tree node, by MIB names. The root node ("ROBOT") is the robot's
    /// mode.
    pub fn mode(&self, robot: u8, node: &str, mode: &str) {
        let mut st = self.lock();
        let r = Self::robot(&mut st, robot);
        let root = mib::modes::NODES.iter().find(|n| n.parent.is_none()).map(|n| n.name);
        let changed_root = root == Some(node) && r.mode.as_deref() != Some(mode);
        if changed_root {
            r.mode = Some(mode.to_string());
        }
        let changed = r.modes.get(node).map(String::as_str) != Some(mode);
        if changed {
            r.modes.insert(node.to_string(), mode.to_string());
        }
        if changed || changed_root {
            self.publish_robot(&mut st, robot);
        }
    }

    /// Configuration state of a robot.
    pub fn config(&self, robot: u8, state: ConfigState) {
        let mut st = self.lock();
        let r = Self::robot(&mut st, robot);
        if r.config.as_ref() != Some(&state) {
            r.config = Some(state);
            self.publish_robot(&mut st, robot);
        }
    }

    /// Module set and configuration state of a robot (published when it changed).
    pub fn modules(&self, robot: u8, view: ModuleView) {
        let mut st = self.lock();
        let r = Self::robot(&mut st, robot);
        if r.modules.as_ref() != Some(&view) {
            let msg = json!({"type": "modules", "robot": robot, "modules": &view});
            r.modules = Some(view);
            self.publish(&mut st, msg);
        }
    }

    /// Team status of a robot (published when it changed).
    pub fn team(&self, robot: u8, view: TeamView) {
        let mut st = self.lock();
        let r = Self::robot(&mut st, robot);
        if r.team.as_ref() != Some(&view) {
            let msg = json!({"type": "team", "robot": robot, "team": &view});
            r.team = Some(view);
            self.publish(&mut st, msg);
        }
    }

    /// Updates the on-board plan of a robot with `f` (which returns whether it took
    /// anything); published when the view changed.
    pub fn onboard(&self, robot: u8, f: impl FnOnce(&mut OnBoardView) -> bool) {
        let mut st = self.lock();
        let r = Self::robot(&mut st, robot);
        let mut view = r.onboard.clone().unwrap_or_default();
        if !f(&mut view) || r.onboard.as_ref() == Some(&view) {
            return;
        }
        let msg = json!({"type": "onboard", "robot": robot, "onboard": &view});
        r.onboard = Some(view);
        self.publish(&mut st, msg);
    }

    /// The on-board plan of a robot as last reported (`None`: nothing heard of it yet).
    pub fn onboard_view(&self, robot: u8) -> Option<OnBoardView> {
        self.lock().robots.get(&robot).and_then(|r| r.onboard.clone())
    }

    /// Housekeeping values of one report, engineering values by MIB parameter name.
    /// Units and limit states come from the MIB.
    pub fn hk(&self, robot: u8, t_ms: i64, values: &[(&str, f64)]) {
        let mut st = self.lock();
        let cap = self.inner.live_samples;
        let mut out = Vec::with_capacity(values.len());
        let mut unknown = 0;
        let mut non_finite = 0;
        // The robot state that decides which limits apply (root mode, a condition such
        // as "no primitive running"): this report's values, else the last known ones.
        let known: HashMap<u16, i64> = {
            let last = &Self::robot(&mut st, robot).hk;
            let raw = |name: &str, v: f64| {
                let p = mib::params::by_name(name)?;
                v.is_finite().then(|| (p.id, p.calib.raw(v)))
            };
            last.iter()
                .filter_map(|(n, c)| raw(n, c.value))
                .chain(values.iter().filter_map(|&(n, v)| raw(n, v)))
                .collect()
        };
        let ctx = |id: u16| known.get(&id).copied();
        for &(name, value) in values {
            let def = mib::params::by_name(name);
            let (unit, limit) = match def {
                Some(p) => (p.unit, LimitState::of(p, value, ctx)),
                None => {
                    unknown += 1;
                    ("", LimitState::None)
                }
            };
            if value.is_finite() {
                let ring = st.live.entry((robot, name.to_string())).or_default();
                if ring.len() == cap {
                    ring.pop_front();
                }
                // Samples arrive in time order per robot; a late one is placed in order.
                let at = ring.partition_point(|s| s.0 <= t_ms);
                ring.insert(at, (t_ms, value));
            } else {
                non_finite += 1;
            }
            let r = Self::robot(&mut st, robot);
            r.hk.insert(
                name.to_string(),
                HkCell {
                    value,
                    unit,
                    limit,
                    t_ms,
                },
            );
            out.push(json!([name, finite_or_null(value), limit]));
        }
        st.stats.unknown_params += unknown;
        st.stats.non_finite += non_finite;
        let r = Self::robot(&mut st, robot);
        r.hk_t_ms = Some(r.hk_t_ms.map_or(t_ms, |t| t.max(t_ms)));
        self.publish(&mut st, json!({"type": "hk", "robot": robot, "t_ms": t_ms, "v": out}));
    }

    /// An event report.
    pub fn event(&self, ev: EventRecord) {
        let mut st = self.lock();
        if st.events.len() == EVENT_HISTORY {
            st.events.pop_front();
        }
        let msg = json!({"type": "event", "event": &ev});
        st.events.push_back(ev);
        self.publish(&mut st, msg);
    }

    /// An alarm was raised or changed (upsert by ID).
    pub fn alarm(&self, alarm: AlarmRecord) {
        let mut st = self.lock();
        let msg = json!({"type": "alarm", "alarm": &alarm});
        st.alarms.insert(alarm.id, alarm);
        let cleared: Vec<u64> = st
            .alarms
            .values()
            .filter(|a| a.state == AlarmState::Cleared)
            .map(|a| a.id)
            .collect();
        if cleared.len() > CLEARED_ALARMS {
            for id in &cleared[..cleared.len() - CLEARED_ALARMS] {
                st.alarms.remove(id);
            }
        }
        self.publish(&mut st, msg);
    }

    /// One alarm by ID.
    pub fn alarm_by_id(&self, id: u64) -> Option<AlarmRecord> {
        self.lock().alarms.get(&id).cloned()
    }

    /// Every alarm the hub holds.
    pub fn alarms(&self) -> Vec<AlarmRecord> {
        self.lock().alarms.values().cloned().collect()
    }

    /// A TC was sent. Idempotent: a second call for the same request ID keeps the
    /// stages already received.
    pub fn tc_sent(&self, rec: CommandRecord) {
        let mut st = self.lock();
        let msg;
        if let Some(c) = st.commands.iter_mut().find(|c| c.request_id == rec.request_id) {
            c.robot = rec.robot;
            c.name = rec.name;
            c.args = rec.args;
            c.sent_ms = rec.sent_ms;
            c.origin = rec.origin;
            msg = json!({"type": "tc", "tc": &*c});
        } else {
            if st.commands.len() == COMMAND_HISTORY {
                st.commands.pop_front();
            }
            msg = json!({"type": "tc", "tc": &rec});
            st.commands.push_back(rec);
        }
        self.publish(&mut st, msg);
    }

    /// A PUS 1 report for a TC. A report for a request never sent through the hub
    /// starts a record of its own (counted in `orphan_stages`).
    pub fn tc_stage(&self, robot: u8, request_id: &str, report: StageReport) {
        let mut st = self.lock();
        let idx = match st.commands.iter().position(|c| c.request_id == request_id) {
            Some(i) => i,
            None => {
                st.stats.orphan_stages += 1;
                if st.commands.len() == COMMAND_HISTORY {
                    st.commands.pop_front();
                }
                st.commands.push_back(CommandRecord {
                    request_id: request_id.to_string(),
                    robot,
                    name: "?".into(),
                    args: Vec::new(),
                    sent_ms: report.t_ms,
                    origin: "unknown".into(),
                    stages: Vec::new(),
                });
                st.commands.len() - 1
            }
        };
        let c = &mut st.commands[idx];
        c.stages.push(report);
        let msg = json!({"type": "tc", "tc": &*c});
        self.publish(&mut st, msg);
    }

    /// One command record by request ID.
    pub fn command(&self, request_id: &str) -> Option<CommandRecord> {
        self.lock()
            .commands
            .iter()
            .find(|c| c.request_id == request_id)
            .cloned()
    }

    /// A plan run started or progressed (upsert by run ID).
    pub fn plan(&self, run: PlanRun) {
        let mut st = self.lock();
        let msg = json!({"type": "plan", "plan": &run});
        st.plans.insert(run.run_id.clone(), run);
        self.publish(&mut st, msg);
    }

    /// Live samples of a parameter in `[t0_ms, t1_ms)`, in time order.
    pub fn live_samples(&self, robot: u8, param: &str, t0_ms: i64, t1_ms: i64) -> Vec<(i64, f64)> {
        let st = self.lock();
        match st.live.get(&(robot, param.to_string())) {
            Some(r) => r.iter().filter(|s| s.0 >= t0_ms && s.0 < t1_ms).copied().collect(),
            None => Vec::new(),
        }
    }

    /// Counters.
    pub fn stats(&self) -> HubStats {
        self.lock().stats.clone()
    }

    /// The whole picture as JSON, with the ID of the last message it includes.
    /// The link state of `robot` as last reported (`None` for a robot not added).
    pub fn link_state(&self, robot: u8) -> Option<LinkState> {
        self.lock().robots.get(&robot).map(|r| r.link)
    }

    pub fn snapshot(&self) -> Value {
        let st = self.lock();
        let robots: Vec<&RobotView> = st.robots.values().collect();
        let events: Vec<&EventRecord> = st.events.iter().rev().take(500).collect();
        let commands: Vec<&CommandRecord> = st.commands.iter().rev().take(200).collect();
        json!({
            "last_id": st.next_id - 1,
            "robots": robots,
            "events": events,
            "alarms": st.alarms.values().collect::<Vec<_>>(),
            "commands": commands,
            "plans": st.plans.values().collect::<Vec<_>>(),
            "stats": st.stats,
        })
    }

    /// Subscribes for messages after `last_id`.
    pub(crate) fn subscribe(&self, last_id: Option<u64>) -> Resume {
        let mut st = self.lock();
        let rx = self.inner.tx.subscribe();
        let newest = st.next_id - 1;
        let Some(last) = last_id else {
            return Resume::Replay(Vec::new(), rx);
        };
        if last >= newest {
            return Resume::Replay(Vec::new(), rx);
        }
        let oldest = st.ring.front().map_or(st.next_id, |m| m.0);
        if last + 1 < oldest {
            st.stats.resets += 1;
            return Resume::Reset(newest, rx);
        }
        let missed = st.ring.iter().filter(|m| m.0 > last).cloned().collect();
        Resume::Replay(missed, rx)
    }

    /// Counts a reset sent to a page that lagged behind the live stream.
    pub(crate) fn count_reset(&self) {
        self.lock().stats.resets += 1;
    }

    /// ID of the newest message.
    pub fn last_id(&self) -> u64 {
        self.lock().next_id - 1
    }
}

fn finite_or_null(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ids(r: &Resume) -> Vec<u64> {
        match r {
            Resume::Replay(m, _) => m.iter().map(|m| m.0).collect(),
            Resume::Reset(..) => vec![u64::MAX],
        }
    }

    // verifies: GND-16
    #[test]
    fn reconnect_replays_exactly_what_was_missed() {
        let hub = Hub::with_capacity(10, 16);
        for i in 0..5 {
            hub.hk(1, i, &[("V_BAT_A", 12.0)]);
        }
        assert_eq!(ids(&hub.subscribe(Some(2))), vec![3, 4, 5]);
        assert_eq!(ids(&hub.subscribe(Some(5))), Vec::<u64>::new());
        assert_eq!(ids(&hub.subscribe(None)), Vec::<u64>::new());
    }

    // verifies: GND-16
    #[test]
    fn a_client_behind_the_ring_gets_a_reset() {
        let hub = Hub::with_capacity(4, 16);
        for i in 0..10 {
            hub.hk(1, i, &[("V_BAT_A", 12.0)]);
        }
        // Ring holds 7..=10: a client at 6 can still resume, one at 5 cannot.
        assert_eq!(ids(&hub.subscribe(Some(6))), vec![7, 8, 9, 10]);
        assert_eq!(ids(&hub.subscribe(Some(5))), vec![u64::MAX]);
        assert_eq!(hub.stats().resets, 1);
    }

    // verifies: GND-16
    #[test]
    fn hk_gets_units_and_limit_states_from_the_mib() {
        let hub = Hub::new();
        hub.hk(2, 100, &[("V_BAT_A", 9.0), ("I_BAT", 0.5), ("NOT_A_PARAM", 1.0)]);
        let s = hub.snapshot();
        let hk = &s["robots"][0]["hk"];
        assert_eq!(hk["V_BAT_A"]["unit"], "V");
        assert_eq!(hk["V_BAT_A"]["limit"], "hard");
        assert_eq!(hk["I_BAT"]["limit"], "ok");
        assert_eq!(hk["NOT_A_PARAM"]["limit"], "none");
        assert_eq!(hub.stats().unknown_params, 1);
        assert_eq!(hub.live_samples(2, "V_BAT_A", 0, 1000), vec![(100, 9.0)]);
        // V_REG at 0 V is no limit violation in STANDBY (MODE 0), one in OPERATIONAL; a
        // report without MODE is judged in the robot's last reported mode.
        hub.hk(2, 200, &[("MODE", 0.0), ("V_REG", 0.0)]);
        assert_eq!(hub.snapshot()["robots"][0]["hk"]["V_REG"]["limit"], "off");
        hub.hk(2, 300, &[("MODE", 1.0), ("V_REG", 0.0)]);
        assert_eq!(hub.snapshot()["robots"][0]["hk"]["V_REG"]["limit"], "hard");
        hub.hk(2, 400, &[("V_REG", 0.0)]);
        assert_eq!(hub.snapshot()["robots"][0]["hk"]["V_REG"]["limit"], "hard");
    }

    // verifies: ALM-MODVIEW-01, ALM-TEAMVIEW-01
    #[test]
    fn module_and_team_views_are_published_when_they_change_and_in_the_snapshot() {
        let hub = Hub::new();
        hub.add_robot(4);
        let id0 = hub.last_id();
        let view = ModuleView {
            hash: "0x8e67d216".into(),
            config: "LOCOMOTION_ONLY".into(),
            ..Default::default()
        };
        hub.modules(4, view.clone());
        hub.modules(4, view.clone());
        let team = TeamView {
            term: 2,
            role: "LEADER".into(),
            leader: Some(4),
            roster: vec![4, 5],
            ..Default::default()
        };
        hub.team(4, team.clone());
        hub.team(4, team);
        assert_eq!(hub.last_id(), id0 + 2, "one message per change");
        let s = hub.snapshot();
        assert_eq!(s["robots"][0]["modules"]["config"], "LOCOMOTION_ONLY");
        assert_eq!(s["robots"][0]["team"]["leader"], 4);
        let Resume::Replay(msgs, _) = hub.subscribe(Some(id0)) else {
            panic!("reset")
        };
        let kinds: Vec<String> = msgs
            .iter()
            .map(|(_, m)| {
                serde_json::from_str::<Value>(m).unwrap()["type"]
                    .as_str()
                    .unwrap()
                    .to_string()
            })
            .collect();
        assert_eq!(kinds, vec!["modules", "team"]);
    }

    // verifies: GND-18, PUS-1-03
    #[test]
    fn stages_accumulate_on_the_sent_command_and_orphans_are_counted() {
        let hub = Hub::new();
        let rec = CommandRecord {
            request_id: "r1".into(),
            robot: 1,
            name: "PING".into(),
            args: vec![],
            sent_ms: 5,
            origin: "page".into(),
            stages: vec![],
        };
        hub.tc_sent(rec.clone());
        let ok = |stage| StageReport {
            stage,
            step: None,
            t_ms: 6,
            success: true,
            failure: None,
        };
        hub.tc_stage(1, "r1", ok(super::super::Stage::Acceptance));
        hub.tc_sent(rec);
        hub.tc_stage(1, "r1", ok(super::super::Stage::Completion));
        let c = hub.command("r1").unwrap();
        assert_eq!(c.stages.len(), 2);
        assert!(c.finished());
        hub.tc_stage(1, "r9", ok(super::super::Stage::Acceptance));
        assert_eq!(hub.stats().orphan_stages, 1);
    }
}
