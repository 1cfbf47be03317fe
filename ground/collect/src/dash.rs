//! The operators' dashboard mounted on the collector (`ground collect --http`).
//!
//! One link per robot — the collector's own: each robot thread feeds the [`Hub`] with
//! its link state, last-heard time and every live decoded TM ([`to_hub`]). The hub
//! shows the collector's alarms, read from the archive's alarm table (the one
//! `ground alarms list` reads) by [`AlarmSync`]; acknowledge and shelve from the page
//! go to that table too. TCs from the page are handed to the robot's thread
//! ([`DashCmd`]), which numbers them with its own sequence counter and sends them over
//! its link; so do plan runs started from the page (`super::planrun`). Plots read the
//! archive's min/max decimation ([`ArchiveSeries`]).

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender};

use crate::alarms::Input;
use crate::archive::{now_ms, Alarm, Store};
use crate::pus::{Tm, TmBody};
use ground_dashboard::{
    node_mode, request_id, AlarmRecord, AlarmState, CommandError, Commander, ConfigState, EventRecord, Hub, PlanInfo,
    PlanStartError, Series, StageReport,
};

/// How long the page waits for the robot's thread to take a TC.
const SEND_TIMEOUT: Duration = Duration::from_secs(2);
/// How often the hub's alarms are read back from the archive.
const ALARM_SYNC_MS: u64 = 500;

/// A request from the page to a robot's thread.
pub enum DashCmd {
    /// Send a TC (MIB name, raw arguments); the reply is its request ID.
    Tc {
        name: String,
        args: Vec<i64>,
        reply: Sender<Result<String, String>>,
    },
    /// Send a plan step's TC (numbered by the thread like the page's); the reply is the
    /// TC as sent (`collect::planrun`).
    PlanTc {
        def: &'static mib::tc::TcDef,
        args: Vec<i64>,
        origin: String,
        /// The TC sent, and the kind of link it went out on (packet resends on a lab
        /// link; over frames COP-1 retransmits and says which TCs it delivered).
        reply: Sender<Result<(crate::pus::BuiltTc, crate::link::LinkKind), crate::ops::SendError>>,
    },
    /// Send these bytes again: a plan TC resent unchanged.
    Resend { bytes: Vec<u8> },
    /// Hand this plan run every verification report and event, and the link's loss.
    Follow(Sender<super::planrun::PlanInput>),
}

/// What a robot thread holds of the dashboard.
pub struct RobotDash {
    pub hub: Hub,
    pub cmds: Receiver<DashCmd>,
}

/// Hands one live decoded TM of `robot` to the hub: HK values (and the mode and
/// configuration state they carry), events, mode reports, and the verification stages
/// of TCs the hub knows (the collector's own subscription renewals are not shown).
pub fn to_hub(hub: &Hub, robot: u8, tm: &Tm) {
    let t = tm.time.unix_ms();
    match &tm.body {
        TmBody::Hk(hk) => {
            let values: Vec<(&str, f64)> = hk.values.iter().map(|v| (v.name, v.eng)).collect();
            hub.hk(robot, t, &values);
            for v in &hk.values {
                if v.id == mib::params::pid::MODE {
                    if let Some(n) = mib::modes::mode_name(mib::modes::NodeKind::Root, v.raw as u32) {
                        hub.mode(robot, "ROBOT", n);
                    }
                }
                if v.id == mib::params::pid::CONFIG_STATE {
                    hub.config(robot, ConfigState::from_mib(v.raw as u8));
                }
            }
            if hk.values.iter().any(|v| v.id == mib::params::pid::PLAN_STATE) {
                let raw: Vec<(u16, i64)> = hk.values.iter().map(|v| (v.id, v.raw)).collect();
                hub.onboard(robot, |p| p.apply_hk(t, &raw));
            }
        }
        TmBody::Event(ev) => {
            if ev.id == mib::events::eid::MODE_CHANGED {
                if let (Some(node), Some(to)) = (ev.param("node"), ev.param("to")) {
                    node_mode(hub, robot, node as u32, to as u32);
                }
            }
            hub.onboard(robot, |p| p.apply_event(t, ev.id, |k| ev.param(k)));
            hub.event(EventRecord {
                robot,
                t_ms: t,
                name: ev.name.to_string(),
                severity: ev.severity.to_string(),
                description: ev.description.to_string(),
                params: ev.params.iter().map(|f| (f.name.clone(), f.value)).collect(),
            });
        }
        TmBody::Report(r) => {
            // The other reports are not on the page (the module set and the team status
            // come through the robot's worker).
            match r.as_ref() {
                mib_wire::Tm::ModeReply(r) => node_mode(hub, robot, r.node, r.mode),
                mib_wire::Tm::PlanStatus(st) => hub.onboard(robot, |p| p.apply_status(t, st)),
                _ => {}
            }
        }
        TmBody::Verification(v) => {
            let id = request_id(robot, v.request.apid(), v.request.seq());
            if hub.command(&id).is_none() {
                return;
            }
            hub.tc_stage(robot, &id, StageReport::from_verification(v, t));
        }
        TmBody::Unknown { .. } => {}
    }
}

/// The dashboard's view of a collector alarm row.
fn alarm_record(r: &Alarm) -> AlarmRecord {
    let state = match r.state {
        crate::alarms::State::Active => AlarmState::Active,
        crate::alarms::State::Acknowledged => AlarmState::Acknowledged,
        crate::alarms::State::Shelved => AlarmState::Shelved,
        crate::alarms::State::Cleared | crate::alarms::State::Normal => AlarmState::Cleared,
    };
    AlarmRecord {
        id: r.id as u64,
        robot: r.robot,
        // The same names `ground alarms list` shows (V_BAT_A, LOW_BATTERY, LINK_LOSS, …).
        source: r.source.clone(),
        severity: r.severity.clone(),
        state,
        message: r.message.clone(),
        first_ms: r.first_ms,
        last_ms: r.last_ms,
        shelved_until_ms: r.shelved_until_ms,
    }
}

/// Why [`AlarmSync::sync`] could not read the archive's alarms.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AlarmSyncError {
    /// A thread panicked while it held the sync's state.
    #[error("alarm sync lock poisoned")]
    Poisoned,
    #[error(transparent)]
    Archive(#[from] crate::archive::ArchiveError),
}

/// An error and its sources, `: `-separated (as the log and the page show it).
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        text.push_str(": ");
        text.push_str(&s.to_string());
        source = s.source();
    }
    text
}

/// Keeps the hub's alarms equal to the open alarms of the archive's alarm table.
pub struct AlarmSync {
    archive: PathBuf,
    hub: Hub,
    /// Open alarm IDs last shown, and the connection kept between reads (reopened after
    /// an error).
    state: Mutex<(BTreeSet<u64>, Option<Store>)>,
}

impl AlarmSync {
    pub fn new(archive: PathBuf, hub: Hub) -> AlarmSync {
        AlarmSync {
            archive,
            hub,
            state: Mutex::new((BTreeSet::new(), None)),
        }
    }

    /// Reads the open alarms once and publishes what changed; alarms that closed since
    /// are shown cleared.
    pub fn sync(&self) -> Result<(), AlarmSyncError> {
        let Ok(mut guard) = self.state.lock() else {
            return Err(AlarmSyncError::Poisoned);
        };
        let (shown, conn) = &mut *guard;
        if conn.is_none() {
            *conn = Some(Store::open_existing(&self.archive.to_string_lossy())?);
        }
        let rows = match conn.as_mut().map(|c| c.alarms(None, false)) {
            Some(Ok(rows)) => rows,
            Some(Err(e)) => {
                *conn = None;
                return Err(e.into());
            }
            None => return Ok(()),
        };
        let mut now_open = BTreeSet::new();
        for r in &rows {
            let rec = alarm_record(r);
            now_open.insert(rec.id);
            if self.hub.alarm_by_id(rec.id).as_ref() != Some(&rec) {
                self.hub.alarm(rec);
            }
        }
        for id in shown.difference(&now_open) {
            if let Some(mut a) = self.hub.alarm_by_id(*id) {
                if a.state != AlarmState::Cleared {
                    a.state = AlarmState::Cleared;
                    self.hub.alarm(a);
                }
            }
        }
        *shown = now_open;
        Ok(())
    }

    /// Syncs every [`ALARM_SYNC_MS`] until `stop`.
    pub fn spawn(self: Arc<Self>, stop: Arc<AtomicBool>) -> std::io::Result<std::thread::JoinHandle<()>> {
        std::thread::Builder::new()
            .name("dashboard-alarms".into())
            .spawn(move || {
                let mut logged = false;
                while !stop.load(Ordering::Relaxed) {
                    match self.sync() {
                        Ok(()) => logged = false,
                        Err(e) if !logged => {
                            tracing::debug!("dashboard alarms: {}", error_chain(&e));
                            logged = true;
                        }
                        Err(_) => {}
                    }
                    std::thread::sleep(Duration::from_millis(ALARM_SYNC_MS));
                }
            })
    }
}

/// The page's commands, carried out by the collector.
pub struct CollectCommander {
    robots: BTreeMap<u8, Sender<DashCmd>>,
    archive: PathBuf,
    alarms: Arc<AlarmSync>,
    plans: Option<super::planrun::PlanBook>,
}

impl CollectCommander {
    pub fn new(robots: BTreeMap<u8, Sender<DashCmd>>, archive: PathBuf, alarms: Arc<AlarmSync>) -> CollectCommander {
        CollectCommander {
            robots,
            archive,
            alarms,
            plans: None,
        }
    }

    /// Offers `plans` (the configuration's `plans = [...]`) on the page, run through the
    /// robots' threads with progress to `hub`.
    pub fn with_plans(mut self, plans: Vec<super::config::PlanCfg>, hub: Hub) -> CollectCommander {
        self.plans = Some(super::planrun::PlanBook::new(plans, hub, self.robots.clone()));
        self
    }

    fn alarm_input(&self, id: u64, input: Input) -> Result<(), CommandError> {
        let mut c = Store::open_existing(&self.archive.to_string_lossy()).map_err(|e| CommandError(e.to_string()))?;
        c.alarm_input(id as i64, input, now_ms())
            .map_err(|e| CommandError(e.to_string()))?;
        self.alarms.sync().map_err(|e| CommandError(error_chain(&e)))
    }
}

impl Commander for CollectCommander {
    fn send_tc(&self, robot: u8, name: &str, args: &[i64]) -> Result<String, CommandError> {
        let tx = self
            .robots
            .get(&robot)
            .ok_or_else(|| CommandError(format!("robot {robot} is not followed by this collector")))?;
        let (reply, answer) = crossbeam_channel::bounded(1);
        tx.send(DashCmd::Tc {
            name: name.to_string(),
            args: args.to_vec(),
            reply,
        })
        .map_err(|_| CommandError(format!("robot {robot}: the collector's thread has stopped")))?;
        match answer.recv_timeout(SEND_TIMEOUT) {
            Ok(r) => r.map_err(CommandError),
            Err(_) => Err(CommandError(format!(
                "robot {robot}: the collector did not take the TC"
            ))),
        }
    }

    fn ack_alarm(&self, id: u64) -> Result<(), CommandError> {
        self.alarm_input(id, Input::Ack)
    }

    fn shelve_alarm(&self, id: u64, for_ms: i64) -> Result<(), CommandError> {
        self.alarm_input(
            id,
            Input::Shelve {
                until_ms: now_ms() + for_ms,
            },
        )
    }

    fn plans(&self) -> Vec<PlanInfo> {
        self.plans.as_ref().map(|p| p.list()).unwrap_or_default()
    }

    fn start_plan(&self, name: &str, confirmed: bool) -> Result<String, PlanStartError> {
        match &self.plans {
            Some(p) => p.start(name, confirmed),
            None => Err(PlanStartError::Unknown(format!(
                "no plan named \"{name}\": this collector offers no plans"
            ))),
        }
    }
}

/// Plots from the archive's min/max-per-column decimation.
pub struct ArchiveSeries {
    store: Mutex<Option<crate::archive::read::Store>>,
    archive: PathBuf,
}

impl ArchiveSeries {
    pub fn new(archive: PathBuf) -> ArchiveSeries {
        ArchiveSeries {
            store: Mutex::new(None),
            archive,
        }
    }
}

impl Series for ArchiveSeries {
    fn decimate(&self, robot: u8, param: &str, t0_ms: i64, t1_ms: i64, columns: usize) -> Vec<(i64, f64, f64)> {
        let Ok(mut guard) = self.store.lock() else {
            return Vec::new();
        };
        if guard.is_none() {
            match crate::archive::read::Store::open(&self.archive.to_string_lossy()) {
                Ok(s) => *guard = Some(s),
                Err(e) => {
                    tracing::debug!("dashboard series: {e}");
                    return Vec::new();
                }
            }
        }
        let Some(s) = guard.as_mut() else {
            return Vec::new();
        };
        match s.decimate(robot, param, t0_ms, t1_ms, columns) {
            Ok(cols) => cols.into_iter().map(|c| (c.t_ms, c.min, c.max)).collect(),
            Err(e) => {
                tracing::debug!("dashboard series {param}: {e}");
                // Reopen next time (the archive may have been replaced or pruned).
                *guard = None;
                Vec::new()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::alarms::{Severity, Source};
    use crate::archive::AlarmUpdate;

    // verifies: GND-02, GND-13, GND-18
    #[test]
    fn the_page_shows_and_acknowledges_the_archived_alarms() {
        let dir = std::env::temp_dir().join(format!("collect-dash-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.db");
        let mut c = Store::open(path.to_str().unwrap()).unwrap();
        let src = Source::Param("V_BAT_A".into());
        let up = |input, t_ms, value, message| AlarmUpdate {
            robot: 1,
            source: &src,
            severity: Severity::Medium,
            input,
            t_ms,
            value: Some(value),
            message,
        };
        let id = c
            .apply_alarm(&up(Input::Activate, 1_000, 10.3, "low"))
            .unwrap()
            .unwrap();
        let hub = Hub::new();
        let sync = Arc::new(AlarmSync::new(path.clone(), hub.clone()));
        sync.sync().unwrap();
        let a = hub.alarm_by_id(id as u64).expect("archived alarm on the page");
        assert_eq!(
            (a.state, a.source.as_str(), a.severity.as_str()),
            (AlarmState::Active, "V_BAT_A", "medium")
        );

        // Acknowledged from the page: the archive's record changes, the hub follows.
        let cmd = CollectCommander::new(BTreeMap::new(), path.clone(), sync.clone());
        cmd.ack_alarm(id as u64).unwrap();
        let rows = c.alarms(None, true).unwrap();
        assert_eq!(rows[0].state, crate::alarms::State::Acknowledged);
        assert_eq!(hub.alarm_by_id(id as u64).unwrap().state, AlarmState::Acknowledged);
        let e = cmd.ack_alarm(id as u64).unwrap_err();
        assert!(e.0.contains("nothing to acknowledge"), "{e}");

        // The condition goes: the alarm closes in the archive and shows cleared.
        c.apply_alarm(&up(Input::Clear, 2_000, 12.0, "ok")).unwrap();
        sync.sync().unwrap();
        assert_eq!(hub.alarm_by_id(id as u64).unwrap().state, AlarmState::Cleared);

        // No robot, no plans: clear errors.
        assert!(cmd.send_tc(3, "PING", &[]).unwrap_err().0.contains("robot 3"));
        assert!(matches!(cmd.start_plan("x", true), Err(PlanStartError::Unknown(_))));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
