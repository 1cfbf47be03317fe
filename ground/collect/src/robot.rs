//! One robot's worker: its own thread, its own link. Subscribes and renews the lease,
//! detects link loss, reconnects with capped backoff, follows sequence counts, asks the
//! on-board store for every hole, checks limits and events, and hands everything to the
//! sink. Nothing here waits on another robot.
//!
//! The worker's state and its loop are here; what it does on its clock is in `timers`,
//! with each TM received in `incoming` and `inspect`, the page's and plans' TCs in
//! `commands`, and its alarms, losses and health in `health`.

mod commands;
mod health;
mod incoming;
mod inspect;
mod timers;

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use mib::headers::SeqCount;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender};
use serde::Serialize;

use crate::alarms::{LimitChecker, Source};
use crate::archive::now_ms;
use crate::link::{Incoming, Link, Transport};
use crate::pus::RequestId;

use super::config::{Config, RobotCfg};
use super::dash::RobotDash;
use super::onboard;
use super::planrun::PlanInput;
use super::robotcfg::ConfigTracker;
use super::store::SinkMsg;
use super::tracker::{ApidTracker, GapPlan, LinkWatch, Pos, RetrievalPacer, Subscription};

/// [`mib::ground_config::GROUND_RECONNECT_FIRST_MS`]: first pause between reconnection attempts;
/// doubles up to the configured cap.
const BACKOFF_START_MS: i64 = mib::ground_config::GROUND_RECONNECT_FIRST_MS as i64;
/// [`mib::ground_config::COLLECTOR_HEALTH_MS`]: health written to the archive this often.
const HEALTH_MS: i64 = mib::ground_config::COLLECTOR_HEALTH_MS as i64;
/// [`mib::ground_config::GAP_REQUESTS_LIVE`]: one replay in flight per robot.
const MAX_RUNS_PER_REQUEST: usize = mib::ground_config::GAP_REQUESTS_LIVE;
/// [`mib::ground_config::HK_SET_TRIES`].
const HK_SET_TRIES: u32 = mib::ground_config::HK_SET_TRIES;
/// [`mib::ground_config::GROUND_ASK_AGAIN_MS`].
const ASK_AGAIN_MS: i64 = mib::ground_config::GROUND_ASK_AGAIN_MS as i64;

/// Link state shown to operators: the one of every front end ([`LinkWatch`]).
pub use ground_ops::live::LinkState;

/// Live counters of one robot (shared with the display).
#[derive(Clone, Debug, Default, Serialize)]
pub struct RobotStatus {
    pub robot: u8,
    pub addr: String,
    pub link: LinkState,
    /// The counts its link row in the archive keeps too.
    #[serde(flatten)]
    pub tm: crate::archive::TmCounts,
    pub holes: usize,
    pub store_requests: u64,
    /// Store retrievals ended by the pacing rule's timeout (`RetrievalPacer::timed_out`:
    /// neither their end report nor their outcome came).
    pub store_timeouts: u64,
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
    /// Another ground process holds the robot (said once until the link opens).
    held_elsewhere: bool,
    /// The page's single TCs awaited: the one set of commanding rules (`ops::book`):
    /// resent until accepted on a lab link, never after; over frames COP-1 delivers.
    page_tcs: crate::ops::TcBook,
    tx: Sender<Incoming>,
    rx: Receiver<Incoming>,
    /// Is the link up? The link-loss rule of every front end, at this robot's HK
    /// interval (never sooner than the configured `loss_timeout_ms`).
    watch: LinkWatch,
    /// Which store retrievals the holes need: the planner of every front end.
    gaps: GapPlan,
    started_ms: i64,
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
    /// Is a store retrieval in flight, may the next go? The pacing rule of every front
    /// end.
    pacer: RetrievalPacer,
    conditions: BTreeSet<Source>,
    last_health_ms: i64,
    st: RobotStatus,
    /// The dashboard this thread feeds, when `--http` is given.
    dash: Option<RobotDash>,
    /// The plan run following this robot (`collect::planrun`): it gets every
    /// verification report and event, and the link's loss.
    plan: Option<Sender<PlanInput>>,
    /// The robot's module configuration (docs/modules.md): hash, report, changes.
    modules: ConfigTracker,
    /// When the module report was last asked for (REPORT_MODULES).
    modules_asked_ms: i64,
    /// A team status report arrived since link-up or the last reboot (docs/team.md).
    team_known: bool,
    /// A team event arrived: ask for the team status.
    team_due: bool,
    /// When the team status was last asked for (TEAM_STATUS_REQUEST).
    team_asked_ms: i64,
    /// Over a UDP lab link, does the robot send to this collector? Re-subscribed every
    /// `SUBSCRIBE_RETRY_MS` until it does: the rule of every front end.
    subscription: Subscription,
    /// When bytes last went to the robot (a new TC or a resend).
    last_sent_ms: Option<i64>,
}

/// One APID's tracker after a collector restart, from its newest archived positions
/// (oldest first, at most [`crate::RESUME_WINDOW`]). The last one is where it resumes;
/// holes among them (packets still being retrieved, or queued for the archive, when the
/// last run stopped) are retrieved again. Fewer than the window: the archive holds no
/// older packet of this APID, so the counts of the first one's boot before it are holes
/// too, as for a packet first heard with an empty archive
/// ([`ApidTracker::following_boot`]) — the last run may have been stopped before the
/// store gave them (the boot's first packets, sent before any ground subscribed, come
/// only from the store). A full window may have older packets before it: nothing before
/// its first is asked for.
pub(crate) fn resumed_tracker(positions: Vec<Pos>, now: i64) -> ApidTracker {
    let whole = positions.len() < crate::RESUME_WINDOW;
    let mut positions = positions.into_iter();
    let mut t = if whole {
        ApidTracker::following_boot()
    } else {
        ApidTracker::resume(positions.next())
    };
    for p in positions {
        t.on_packet(p, false, now);
    }
    // What was declared lost before the restart is not declared again.
    t.take_lost();
    t.reset_counters();
    t
}

impl Worker {
    /// `history`: per APID the newest archived positions, oldest first, at most
    /// [`crate::RESUME_WINDOW`] (see [`resumed_tracker`]).
    pub fn new(
        cfg: RobotCfg,
        global: Arc<Config>,
        sink: Sender<SinkMsg>,
        status: Arc<Mutex<RobotStatus>>,
        stop: Arc<AtomicBool>,
        history: Vec<(u16, Vec<Pos>)>,
    ) -> Worker {
        let apid = onboard::apid(cfg.number).unwrap_or(0);
        let now = now_ms();
        let trackers = history
            .into_iter()
            .map(|(a, positions)| (a, resumed_tracker(positions, now)))
            .collect();
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
            tc_seq: crate::ops::first_tc_seq(None),
            link: None,
            held_elsewhere: false,
            page_tcs: crate::ops::TcBook::default(),
            tx,
            rx,
            watch: LinkWatch::new(hk_interval_ms, now).with_floor(global.loss_timeout_ms),
            gaps: GapPlan::default(),
            started_ms: now,
            last_hk_ms: None,
            up_since_ms: now,
            backoff_ms: BACKOFF_START_MS,
            next_send_ms: now,
            hk_interval_ms,
            hk_set: None,
            hk_confirmed: cfg.hk_interval_ms.is_none(),
            modes_known: false,
            pacer: RetrievalPacer::default(),
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
            subscription: Subscription::default(),
            last_sent_ms: None,
            cfg,
            global,
            sink,
            status,
            stop,
        }
    }

    /// Starts from the configuration hash last archived for this robot: a robot that
    /// comes back with another one raises CONFIG_CHANGED even across a collector restart.
    /// Numbers this robot's TCs from `seq` on ([`crate::ops::first_tc_seq`] of the
    /// collector's archive: the rule of every front end).
    pub fn with_first_seq(mut self, seq: u16) -> Worker {
        self.tc_seq = seq;
        self
    }

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
            // Up to when the link's reader listened, read before its packets are taken
            // (`LinkWatch::on_listened`: the worker's own stall is not the robot's silence).
            let listened = self.link.as_ref().and_then(|l| l.listened_ms());
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
            if let Some(t) = listened {
                self.watch.on_listened(t);
            }
            let now = now_ms();
            self.timers(now);
        }
        self.publish(now_ms(), true);
        // Dropping the link joins its reader thread.
        self.link = None;
    }

    fn next_seq(&mut self) -> u16 {
        let s = self.tc_seq;
        self.tc_seq = SeqCount::new(self.tc_seq).next().get();
        s
    }

    fn send(&mut self, bytes: &[u8]) {
        if let Some(l) = &self.link {
            self.last_sent_ms = Some(now_ms());
            if let Err(e) = l.send(bytes) {
                tracing::debug!(robot = self.cfg.number, "send: {e}");
            }
        }
    }

    /// Sends a new TC and archives it (`label`: what sent it, the archive's step column).
    pub(super) fn send_tc(&mut self, tc: &crate::pus::BuiltTc, label: &str) {
        self.send(&tc.bytes);
        self.archive_tc(tc, label);
    }

    /// Archives a TC this thread numbered.
    pub(super) fn archive_tc(&self, tc: &crate::pus::BuiltTc, label: &str) {
        let _ = self.sink.send(SinkMsg::Tc {
            t_ms: now_ms(),
            tc: tc.clone(),
            label: Some(format!("collect:{label}")),
        });
    }

    fn ensure_link(&mut self) {
        let tcp_dead = self.cfg.transport == Transport::Tcp && self.watch.state() != LinkState::Up;
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
            Ok(l) => {
                self.link = Some(l);
                self.held_elsewhere = false;
            }
            // Another ground process commands the robot (ground::robot_lock): said once.
            Err(e) if e.kind() == std::io::ErrorKind::AddrInUse => {
                if !std::mem::replace(&mut self.held_elsewhere, true) {
                    tracing::warn!(robot = self.robot(), "{e}");
                }
            }
            Err(e) => tracing::debug!(robot = self.robot(), "connect {}: {e}", self.cfg.addr),
        }
    }
}

#[cfg(test)]
mod tests;
