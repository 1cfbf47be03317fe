//! Live operations: a [`Session`] holds the links to several robots, sends TCs with
//! per-APID sequence counts, tracks PUS 1 verification per TC, resends a TC until its
//! completion or failure report arrives (identical bytes, same sequence count, so the
//! OBSW's duplicate window answers again instead of executing twice; waits from
//! `mib::config::tc_retry_wait_ms`), follows the sequence count of every APID (duplicates
//! dropped, gaps listed), notices a lost link within `LINK_LOSS_MS`, archives everything
//! and keeps each robot's status (mode, state, battery, link quality). [`run_plan`]
//! executes a plan on top of it.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

pub mod policy;
pub mod runs;

use crossbeam_channel::Receiver;
use mib::config::{
    tc_retry_wait_ms, GROUND_HEARTBEAT_MS, LINK_LOSS_MS, LINK_QUALITY_WINDOW, TC_RETRY_INITIAL_MS, TC_RETRY_MAX,
};
use mib::events::eid;
use mib::params::pid;
use mib::tc::TcDef;
use serde::Serialize;

use crate::archive::{now_ms, ArchiveSender, Record};
use crate::link::{Incoming, Link, Transport};
use crate::plan::{state_name, Action, Plan};
use crate::pus::{self, BuiltTc, DecodeError, Event, Hk, SeqCounters, Stage, Tm, TmBody, Verification};

/// What one robot looks like from the ground.
#[derive(Clone, Debug)]
pub struct RobotStatus {
    pub robot: u8,
    pub addr: SocketAddr,
    pub mode: Option<u32>,
    pub state: Option<u8>,
    /// Last commanded target state (HK `TARGET_STATE`), shown while moving.
    pub target: Option<u8>,
    pub battery_v: Option<f64>,
    pub tm_count: u64,
    pub corrupt: u64,
    /// TM on this robot's link with another robot's APID (archived, not used).
    pub foreign: u64,
    /// Outcome of the last exchanges (TC sent → acceptance within the timeout).
    pub quality: VecDeque<bool>,
    pub last_tm: Option<Instant>,
    /// APID of the last TM with another robot's APID on this link.
    pub foreign_apid: Option<u16>,
    /// TM packets received again (same APID and sequence count): dropped, counted.
    pub duplicates: u64,
    /// Sequence-count tracking of this robot's APID.
    pub seq: SeqTrack,
    /// Why the link counts as lost (latched).
    pub lost: Option<String>,
    /// Which of the "robot does not answer" cases it was (latched with `lost`).
    pub lost_kind: Option<NoAnswer>,
    /// Since when the link is watched (for link loss before any TM).
    pub since: Instant,
    /// First TM sequence count of the run (from the start marker's reports).
    pub run_first_seq: Option<u16>,
    /// Sequence count of the oldest packet in the on-board store (last TM[15,19]).
    pub store_oldest: Option<u16>,
    /// Stored packets overwritten on board since boot (last TM[15,19]).
    pub store_overwritten: u32,
}

impl RobotStatus {
    fn new(robot: u8, addr: SocketAddr) -> Self {
        RobotStatus {
            robot,
            addr,
            mode: None,
            state: None,
            target: None,
            battery_v: None,
            tm_count: 0,
            corrupt: 0,
            foreign: 0,
            quality: VecDeque::with_capacity(LINK_QUALITY_WINDOW),
            last_tm: None,
            foreign_apid: None,
            duplicates: 0,
            seq: SeqTrack::default(),
            lost: None,
            lost_kind: None,
            since: Instant::now(),
            run_first_seq: None,
            store_oldest: None,
            store_overwritten: 0,
        }
    }
    fn exchange(&mut self, ok: bool) {
        if self.quality.len() == LINK_QUALITY_WINDOW {
            self.quality.pop_front();
        }
        self.quality.push_back(ok);
    }
    /// Success rate over the last `LINK_QUALITY_WINDOW` exchanges (0..=1).
    pub fn link_quality(&self) -> Option<f64> {
        if self.quality.is_empty() {
            None
        } else {
            Some(self.quality.iter().filter(|&&b| b).count() as f64 / self.quality.len() as f64)
        }
    }
    pub fn mode_name(&self) -> String {
        self.mode
            .map_or_else(|| "?".into(), |m| pus::mode_name(mib::modes::node::ROBOT, m))
    }
    pub fn state_name(&self) -> String {
        match (self.state, self.target) {
            (Some(s), _) => state_name(s),
            (None, Some(t)) => format!("moving to {}", state_name(t)),
            (None, None) => "?".into(),
        }
    }
    /// Which "does not answer" case a robot that stopped answering is in, with the
    /// operator's message. `closed`: its TCP connection closed.
    pub fn no_answer(&self, closed: bool) -> (NoAnswer, String) {
        let robot = self.robot;
        let apid = mib::apid::robot_apid(robot).unwrap_or(0);
        let addr = self.addr;
        match (self.last_tm, self.foreign_apid) {
            (None, Some(f)) => (
                NoAnswer::OtherApid(f),
                format!(
                    "robot {robot}: the replies from {addr} carry APID 0x{f:03X}{}, not robot {robot}'s 0x{apid:03X}: another robot answers at this address",
                    mib::apid::apid_robot(f).map_or(String::new(), |r| format!(" (robot {r})"))
                ),
            ),
            (None, None) if closed => (
                NoAnswer::NothingHeard,
                format!("robot {robot}: nothing heard from {addr}: the TCP connection closed before any TM (no OBSW there?)"),
            ),
            (None, None) => (
                NoAnswer::NothingHeard,
                format!(
                    "robot {robot}: nothing heard from {addr} in {:.1} s (no OBSW running there, wrong address, or link down)",
                    self.since.elapsed().as_secs_f64()
                ),
            ),
            (Some(_), _) if closed => (
                NoAnswer::Lost,
                format!("robot {robot}: heard, then lost: the OBSW at {addr} closed the TCP connection"),
            ),
            (Some(t), _) => (
                NoAnswer::Lost,
                format!(
                    "robot {robot}: heard, then lost: no TM from {addr} for {:.1} s (link down or OBSW stopped)",
                    t.elapsed().as_secs_f64()
                ),
            ),
        }
    }

    /// One-line status.
    pub fn line(&self) -> String {
        format!(
            "mode {} | state {} | battery {} | link {}",
            self.mode_name(),
            self.state_name(),
            self.battery_v.map_or_else(|| "?".into(), |v| format!("{v:.2} V")),
            self.link_quality().map_or_else(
                || "-".into(),
                |q| format!("{:.0}% of {}", q * 100.0, self.quality.len())
            )
        )
    }
}

/// The three ways a robot does not answer, the same for every verb (`run`, `send`,
/// `mode`, `ping`, `watch`); each has its own exit code (docs/operator-guide.md): 5 heard
/// then lost (the link-loss code), 7 another APID, 8 nothing heard.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum NoAnswer {
    /// Nothing at all heard from the robot's address within `LINK_LOSS_MS`.
    NothingHeard,
    /// Replies came, but only with another APID (another robot at that address):
    /// reported at the first such reply.
    OtherApid(u16),
    /// Heard, then no TM for `LINK_LOSS_MS` (or its TCP connection closed).
    Lost,
}

impl NoAnswer {
    /// The exit code of this case.
    pub fn exit_code(self) -> u8 {
        match self {
            NoAnswer::Lost => 5,
            NoAnswer::OtherApid(_) => 7,
            NoAnswer::NothingHeard => 8,
        }
    }
}

/// Sequence counts (14 bits) of one APID as they arrive: which were seen recently, which
/// are missing. Bounded: at most `SEQ_TRACK_WINDOW` counts behind the newest are
/// remembered; a gap older than that counts as unrecoverable.
#[derive(Clone, Debug, Default)]
pub struct SeqTrack {
    newest: Option<u16>,
    /// Missing counts (oldest first).
    pub missing: std::collections::BTreeSet<u16>,
    /// Recently received counts, to recognise duplicates.
    recent: VecDeque<u16>,
    /// Recent counts with the on-board time of their packet.
    recent_set: HashMap<u16, u64>,
    /// Missing counts given up because they fell out of the window.
    pub expired: u64,
    /// Missing counts that arrived later (late or replayed).
    pub filled: u64,
}

/// Label of the connection test that starts a run's TM accounting.
pub const START_LABEL: &str = "start marker";

/// Label of the store retrievals a session sends for TM gaps.
pub const GAP_LABEL: &str = "gap retrieval";
/// Most sequence ranges asked of one robot's store at a time.
pub const GAP_REQUESTS_MAX: usize = 16;
/// Gaps closer than this are asked in one range (the packets between come again and
/// are dropped as duplicates): fewer requests on a link that loses many packets.
pub const GAP_MERGE_DISTANCE: u16 = 16;

/// How long an accepted TC that no step waits for (a marker, a store retrieval) is
/// tracked for its completion: it is never resent, and a lost completion report is
/// recovered as a TM gap; after this it is forgotten (a retrieval is asked again).
pub const UNTAGGED_COMPLETION_WAIT: Duration = Duration::from_secs(5);

/// Sequence counts remembered behind the newest one.
pub const SEQ_TRACK_WINDOW: u16 = 4096;
const SEQ_MOD: u16 = 0x4000;

/// What a sequence count was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeqKind {
    /// The next one, or ahead (the counts in between are now missing).
    New,
    /// A missing count that arrived after all.
    Filled,
    /// Seen before.
    Duplicate,
}

impl SeqTrack {
    fn remember(&mut self, seq: u16, stamp: u64) {
        if self.recent_set.insert(seq, stamp).is_none() {
            self.recent.push_back(seq);
            if self.recent.len() > SEQ_TRACK_WINDOW as usize {
                if let Some(old) = self.recent.pop_front() {
                    self.recent_set.remove(&old);
                }
            }
        }
    }

    /// Takes one received sequence count with its packet's on-board time (`stamp`): the
    /// same count with another time is another packet (the OBSW restarted and counts
    /// again), which starts the tracking afresh.
    pub fn on_seq(&mut self, seq: u16, stamp: u64) -> SeqKind {
        let seq = seq % SEQ_MOD;
        if self.recent_set.get(&seq).is_some_and(|&t| t != stamp) {
            self.expired += self.missing.len() as u64;
            *self = SeqTrack {
                expired: self.expired,
                filled: self.filled,
                ..SeqTrack::default()
            };
        }
        let Some(newest) = self.newest else {
            self.newest = Some(seq);
            self.remember(seq, stamp);
            return SeqKind::New;
        };
        let ahead = seq.wrapping_sub(newest) % SEQ_MOD;
        if ahead != 0 && ahead < SEQ_MOD / 2 {
            // Ahead: everything in between is missing (a jump beyond the window, e.g. an
            // obsw restart, is not a gap to fill but counted as expired).
            if ahead > SEQ_TRACK_WINDOW {
                self.expired += (ahead - 1) as u64;
            } else {
                for k in 1..ahead {
                    self.missing.insert((newest + k) % SEQ_MOD);
                }
            }
            self.newest = Some(seq);
            self.remember(seq, stamp);
            // Forget gaps that fell out of the window.
            let behind = |m: u16| seq.wrapping_sub(m) % SEQ_MOD;
            let old: Vec<u16> = self
                .missing
                .iter()
                .copied()
                .filter(|&m| behind(m) > SEQ_TRACK_WINDOW)
                .collect();
            for m in old {
                self.missing.remove(&m);
                self.expired += 1;
            }
            return SeqKind::New;
        }
        if self.missing.remove(&seq) {
            self.filled += 1;
            self.remember(seq, stamp);
            return SeqKind::Filled;
        }
        if self.recent_set.contains_key(&seq) {
            return SeqKind::Duplicate;
        }
        // Older than anything remembered: cannot tell; take it as late.
        self.remember(seq, stamp);
        SeqKind::Filled
    }

    /// Newest count received.
    pub fn newest(&self) -> Option<u16> {
        self.newest
    }

    /// Missing counts at or before `cutoff` (in the 14-bit circle: at most half of it
    /// behind), as inclusive ranges.
    pub fn missing_upto(&self, cutoff: u16) -> Vec<(u16, u16)> {
        let mut out: Vec<(u16, u16)> = Vec::new();
        let mut ms: Vec<u16> = self
            .missing
            .iter()
            .copied()
            .filter(|&m| cutoff.wrapping_sub(m) % SEQ_MOD < SEQ_MOD / 2)
            .collect();
        // Oldest first relative to the cutoff.
        ms.sort_by_key(|&m| std::cmp::Reverse(cutoff.wrapping_sub(m) % SEQ_MOD));
        for m in ms {
            match out.last_mut() {
                Some((_, last)) if (*last + 1) % SEQ_MOD == m => *last = m,
                _ => out.push((m, m)),
            }
        }
        out
    }

    #[cfg(test)]
    fn on_seq_t(&mut self, seq: u16) -> SeqKind {
        self.on_seq(seq, seq as u64)
    }

    /// Expects every count from `first` on: counts between it and the newest that were
    /// not received become missing.
    pub fn expect_from(&mut self, first: u16) {
        let first = first % SEQ_MOD;
        let Some(newest) = self.newest else {
            // Nothing yet: the next packet is checked against `first`.
            self.newest = Some(first.wrapping_sub(1) % SEQ_MOD);
            return;
        };
        let behind = newest.wrapping_sub(first) % SEQ_MOD;
        if behind >= SEQ_TRACK_WINDOW {
            return;
        }
        for k in 0..=behind {
            let m = (first + k) % SEQ_MOD;
            if !self.recent_set.contains_key(&m) {
                self.missing.insert(m);
            }
        }
    }

    /// Missing counts as inclusive ranges (wrap-around split).
    pub fn missing_ranges(&self) -> Vec<(u16, u16)> {
        let mut out: Vec<(u16, u16)> = Vec::new();
        for &m in &self.missing {
            match out.last_mut() {
                Some((_, last)) if *last + 1 == m => *last = m,
                _ => out.push((m, m)),
            }
        }
        out
    }
}

/// A TC waiting for verification.
#[derive(Clone, Debug)]
pub struct Pending {
    pub robot: u8,
    pub tc: BuiltTc,
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
}

impl Pending {
    /// Resent while it waits for acceptance. After acceptance it is never resent: its
    /// completion is awaited on the step's own timeout, and a completion report lost on
    /// the way is a TM gap, filled from the on-board store.
    fn resendable(&self) -> bool {
        !self.exhausted && !self.accepted
    }
}

/// Something that happened on the links.
#[derive(Clone, Debug)]
pub enum Update {
    Verification {
        robot: u8,
        tag: Option<usize>,
        tc: Option<&'static str>,
        v: Verification,
        /// Time from the first send of the TC.
        after: Option<Duration>,
    },
    Event {
        robot: u8,
        event: Event,
    },
    Hk {
        robot: u8,
        hk: Hk,
    },
    Tm {
        robot: u8,
        tm: Tm,
    },
    Resent {
        robot: u8,
        tag: Option<usize>,
        tc: &'static str,
        send: u32,
    },
    GaveUp {
        robot: u8,
        tag: Option<usize>,
        tc: &'static str,
        sends: u32,
        /// The TC was accepted (so it may have executed): its outcome is unknown.
        accepted: bool,
    },
    /// A TM[1,2] for a copy of a TC that was damaged on the way (CRC or length): not the
    /// TC's verdict; the TC is resent.
    DamagedCopy {
        robot: u8,
        tag: Option<usize>,
        tc: &'static str,
    },
    /// No TM from the robot for `LINK_LOSS_MS`, or its TCP connection closed.
    LinkLost {
        robot: u8,
        why: String,
    },
    Corrupt {
        robot: u8,
        error: DecodeError,
    },
    /// A TM whose APID is not the link's robot's (archived, otherwise ignored).
    Foreign {
        robot: u8,
        apid: u16,
        service: u8,
        subservice: u8,
    },
}

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OpsError {
    #[error("robot {0} has no link (give --robot {0}=HOST:PORT)")]
    NoLink(u8),
    #[error("cannot open link to robot {robot} at {addr}: {err}")]
    Connect {
        robot: u8,
        addr: SocketAddr,
        err: std::io::Error,
    },
    #[error("sending to robot {robot}: {err}")]
    Send { robot: u8, err: std::io::Error },
    #[error(transparent)]
    Build(#[from] pus::BuildError),
    #[error("the MIB has no PING telecommand")]
    NoPing,
}

/// Links to several robots with verification tracking.
pub struct Session {
    links: BTreeMap<u8, Link>,
    rx: Receiver<Incoming>,
    seq: SeqCounters,
    pending: HashMap<(u16, u16), Pending>,
    archive: Option<ArchiveSender>,
    pub robots: BTreeMap<u8, RobotStatus>,
    /// First wait for a report before resending (later waits grow, see
    /// `mib::config::tc_retry_wait_ms`).
    pub ack_timeout: Duration,
    /// Resends of a TC after the first send.
    pub max_resends: u32,
    /// Report a robot's link as lost after this long without TM (`None`: never).
    pub link_loss: Option<Duration>,
    /// When each robot last got a new TC (not a resend).
    last_new_tc: HashMap<u8, Instant>,
    /// The run this session's TCs belong to (`ground run`): archived with every TC as
    /// `LABEL@RUN_ID` in the TC's step column (see [`runs`]).
    pub run_id: Option<String>,
}

impl Session {
    /// Opens a link per robot. `first_seq` gives the starting sequence count per APID
    /// (e.g. from the archive), otherwise a time-derived value is used.
    pub fn connect(
        robots: &[(u8, SocketAddr)],
        transport: Transport,
        archive: Option<ArchiveSender>,
        first_seq: impl Fn(u16) -> Option<u16>,
    ) -> Result<Session, OpsError> {
        let (tx, rx) = crossbeam_channel::unbounded();
        let mut links = BTreeMap::new();
        let mut status = BTreeMap::new();
        let mut seq = SeqCounters::new();
        for &(robot, addr) in robots {
            let apid = mib::apid::robot_apid(robot).ok_or(pus::BuildError::UnknownRobot(robot))?;
            let link =
                Link::open(robot, addr, transport, tx.clone()).map_err(|err| OpsError::Connect { robot, addr, err })?;
            links.insert(robot, link);
            status.insert(robot, RobotStatus::new(robot, addr));
            let start = first_seq(apid).unwrap_or_else(|| {
                let n = std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.subsec_nanos() ^ d.as_secs() as u32);
                (n % 0x4000) as u16
            });
            seq.set(apid, start);
        }
        Ok(Session {
            links,
            rx,
            seq,
            pending: HashMap::new(),
            archive,
            robots: status,
            ack_timeout: Duration::from_millis(TC_RETRY_INITIAL_MS as u64),
            max_resends: TC_RETRY_MAX,
            link_loss: None,
            last_new_tc: HashMap::new(),
            run_id: None,
        })
    }

    /// Builds and sends a TC; verification reports come back through [`Session::poll`]
    /// with `tag`.
    pub fn send(
        &mut self,
        robot: u8,
        def: &'static TcDef,
        args: &[i64],
        tag: Option<usize>,
        label: Option<String>,
    ) -> Result<BuiltTc, OpsError> {
        self.send_limited(robot, def, args, tag, label, None)
    }

    /// Sends a connection test that is not resent (a heartbeat: the next one follows).
    pub fn send_heartbeat(&mut self, robot: u8) -> Result<BuiltTc, OpsError> {
        let def = mib::tc::by_name("PING").ok_or(OpsError::NoPing)?;
        self.send_limited(robot, def, &[], None, Some("heartbeat".into()), Some(1))
    }

    fn send_limited(
        &mut self,
        robot: u8,
        def: &'static TcDef,
        args: &[i64],
        tag: Option<usize>,
        label: Option<String>,
        max_sends: Option<u32>,
    ) -> Result<BuiltTc, OpsError> {
        let link = self.links.get(&robot).ok_or(OpsError::NoLink(robot))?;
        let apid = mib::apid::robot_apid(robot).ok_or(pus::BuildError::UnknownRobot(robot))?;
        // Check the arguments before using up a sequence count.
        pus::build_tc(robot, 0, def, args)?;
        let tc = pus::build_tc(robot, self.seq.next(apid), def, args)?;
        link.send(&tc.bytes).map_err(|err| OpsError::Send { robot, err })?;
        self.last_new_tc.insert(robot, Instant::now());
        if let Some(a) = &self.archive {
            a.send(Record::Tc {
                t_ms: now_ms(),
                tc: tc.clone(),
                step: runs::archived_label(label.as_deref(), self.run_id.as_deref()),
                attempt: 1,
            });
        }
        let now = Instant::now();
        self.pending.insert(
            (tc.apid, tc.seq),
            Pending {
                robot,
                tc: tc.clone(),
                tag,
                label,
                first_sent: now,
                last_sent: now,
                sends: 1,
                accepted: false,
                max_sends: max_sends.unwrap_or(self.max_resends + 1),
                exhausted: false,
            },
        );
        Ok(tc)
    }

    /// Tracks a TC that an earlier, interrupted session of the same run sent (same
    /// request ID), without sending it again: its reports, live or replayed from the
    /// on-board store, come back through [`Session::poll`] with `tag`. It is never resent.
    pub fn adopt(&mut self, robot: u8, tc: BuiltTc, tag: Option<usize>, label: Option<String>, accepted: bool) {
        let now = Instant::now();
        self.pending.insert(
            (tc.apid, tc.seq),
            Pending {
                robot,
                tc,
                tag,
                label,
                first_sent: now,
                last_sent: now,
                sends: 1,
                accepted,
                max_sends: 1,
                exhausted: true,
            },
        );
    }

    /// True if the TC with this request ID is still waiting for its outcome.
    pub fn is_pending(&self, tc: &BuiltTc) -> bool {
        self.pending.contains_key(&(tc.apid, tc.seq))
    }

    /// Whether the TC with this request ID was accepted (`None`: not tracked).
    pub fn accepted(&self, tc: &BuiltTc) -> Option<bool> {
        self.pending.get(&(tc.apid, tc.seq)).map(|p| p.accepted)
    }

    /// True if a TC of `robot` is still waiting for acceptance or completion.
    pub fn busy(&self, robot: u8) -> bool {
        self.pending.values().any(|p| p.robot == robot)
    }

    /// True if a TC of `robot` other than a heartbeat is waiting for its outcome.
    pub fn commanding(&self, robot: u8) -> bool {
        self.pending.values().any(|p| p.robot == robot && p.max_sends > 1)
    }

    /// Waits with when the wait after send `sends` of `p` ends.
    fn resend_due(&self, p: &Pending) -> Instant {
        let first = self.ack_timeout.as_millis() as u64;
        // The MIB's schedule, scaled to this session's first wait.
        let ms = tc_retry_wait_ms(p.sends.saturating_sub(1)) as u64 * first / TC_RETRY_INITIAL_MS.max(1) as u64;
        p.last_sent + Duration::from_millis(ms)
    }

    /// Forgets a pending TC (e.g. after its step timed out).
    pub fn forget(&mut self, tc: &BuiltTc) {
        self.pending.remove(&(tc.apid, tc.seq));
    }

    /// Waits up to `max_wait` for traffic; handles resends. Returns what happened.
    pub fn poll(&mut self, max_wait: Duration) -> Vec<Update> {
        let mut out = Vec::new();
        let deadline = Instant::now() + max_wait;
        loop {
            let now = Instant::now();
            let next_resend = self
                .pending
                .values()
                .filter(|p| p.resendable())
                .map(|p| self.resend_due(p))
                .min();
            let until = next_resend.map_or(deadline, |r| r.min(deadline));
            let until = until.min(now + Duration::from_millis(100));
            let wait = until.saturating_duration_since(now);
            match self.rx.recv_timeout(wait) {
                Ok(inc) => {
                    self.handle(inc, &mut out);
                    // Drain what is already there without waiting.
                    while let Ok(inc) = self.rx.try_recv() {
                        self.handle(inc, &mut out);
                    }
                }
                Err(crossbeam_channel::RecvTimeoutError::Timeout) => {}
                Err(crossbeam_channel::RecvTimeoutError::Disconnected) => {
                    std::thread::sleep(wait);
                }
            }
            self.check_resends(&mut out);
            self.check_links(&mut out);
            if !out.is_empty() || Instant::now() >= deadline {
                return out;
            }
        }
    }

    /// Link loss: a closed TCP connection, or no TM for `link_loss`.
    fn check_links(&mut self, out: &mut Vec<Update>) {
        let Some(limit) = self.link_loss else { return };
        let mut lost = Vec::new();
        for (robot, s) in self.robots.iter_mut() {
            if s.lost.is_some() {
                continue;
            }
            let closed = self.links.get(robot).is_some_and(|l| l.closed());
            let silent = s.last_tm.map_or(s.since.elapsed(), |t| t.elapsed());
            // Replies with another APID and none with ours: the wrong robot, said at once.
            let wrong = s.last_tm.is_none() && s.foreign_apid.is_some();
            if !closed && !wrong && silent < limit {
                continue;
            }
            let (kind, why) = s.no_answer(closed);
            s.lost_kind = Some(kind);
            s.lost = Some(why.clone());
            out.push(Update::LinkLost { robot: *robot, why });
            lost.push(*robot);
        }
        // Nothing more is resent to a robot that does not answer; its steps end with the
        // link loss.
        self.pending.retain(|_, p| !lost.contains(&p.robot));
    }

    /// True if `robot` got a new TC within `period` (its answers check the link as a
    /// heartbeat would).
    pub fn sent_within(&self, robot: u8, period: Duration) -> bool {
        self.last_new_tc.get(&robot).is_some_and(|t| t.elapsed() < period)
    }

    /// True while a store retrieval of `robot` is waiting for its outcome.
    pub fn retrieving(&self, robot: u8) -> bool {
        self.pending
            .values()
            .any(|p| p.robot == robot && p.label.as_deref() == Some(GAP_LABEL))
    }

    /// Asks `robot`'s on-board store for every missing TM at or before `cutoff` (all
    /// missing if `None`), by APID and sequence range (TC[15,128]); at most
    /// `GAP_REQUESTS_MAX` ranges at a time. Returns the ranges asked for.
    pub fn request_gaps(&mut self, robot: u8, cutoff: Option<u16>, max_ranges: usize) -> Vec<(u16, u16)> {
        let Some(st) = self.robots.get(&robot) else {
            return Vec::new();
        };
        let Some(def) = mib::tc::by_name("STORE_DOWNLINK_SEQ") else {
            return Vec::new();
        };
        let apid = mib::apid::robot_apid(robot).unwrap_or(0);
        let ranges = match cutoff.or(st.seq.newest()) {
            Some(c) => st.seq.missing_upto(c),
            None => Vec::new(),
        };
        let mut merged: Vec<(u16, u16)> = Vec::new();
        for (a, b) in ranges {
            match merged.last_mut() {
                Some((_, last)) if a.wrapping_sub(*last) % SEQ_MOD <= GAP_MERGE_DISTANCE => *last = b,
                _ => merged.push((a, b)),
            }
        }
        let ranges: Vec<(u16, u16)> = merged.into_iter().take(max_ranges.min(GAP_REQUESTS_MAX)).collect();
        for &(a, b) in &ranges {
            let args = [apid as i64, a as i64, b as i64];
            // A failed send shows as a retrieval without result: asked again later.
            let _ = self.send(robot, def, &args, None, Some(GAP_LABEL.into()));
        }
        ranges
    }

    /// Starts watching every robot's link for loss (`LINK_LOSS_MS` without TM).
    pub fn watch_links(&mut self) {
        self.link_loss = Some(Duration::from_millis(LINK_LOSS_MS as u64));
        for s in self.robots.values_mut() {
            s.since = Instant::now();
        }
    }

    fn check_resends(&mut self, out: &mut Vec<Update>) {
        let now = Instant::now();
        self.pending.retain(|_, p| {
            p.tag.is_some() || !p.accepted || now.saturating_duration_since(p.last_sent) < UNTAGGED_COMPLETION_WAIT
        });
        let mut gave_up = Vec::new();
        let due: Vec<((u16, u16), Instant)> = self
            .pending
            .iter()
            .filter(|(_, p)| p.resendable())
            .map(|(k, p)| (*k, self.resend_due(p)))
            .collect();
        for (key, at) in due {
            let Some(p) = self.pending.get_mut(&key) else { continue };
            if now < at {
                continue;
            }
            if let Some(r) = self.robots.get_mut(&p.robot) {
                r.exchange(false);
            }
            if p.sends >= p.max_sends {
                gave_up.push(key);
                continue;
            }
            if let Some(link) = self.links.get(&p.robot) {
                // A failing send is the same as a lost packet: the next timeout retries.
                let _ = link.send(&p.tc.bytes);
            }
            p.sends += 1;
            p.last_sent = now;
            if let Some(a) = &self.archive {
                a.send(Record::Tc {
                    t_ms: now_ms(),
                    tc: p.tc.clone(),
                    step: runs::archived_label(p.label.as_deref(), self.run_id.as_deref()),
                    attempt: p.sends,
                });
            }
            out.push(Update::Resent {
                robot: p.robot,
                tag: p.tag,
                tc: p.tc.def.name,
                send: p.sends,
            });
        }
        for k in gave_up {
            if let Some(p) = self.pending.remove(&k) {
                out.push(Update::GaveUp {
                    robot: p.robot,
                    tag: p.tag,
                    tc: p.tc.def.name,
                    sends: p.sends,
                    accepted: p.accepted,
                });
            }
        }
    }

    fn handle(&mut self, inc: Incoming, out: &mut Vec<Update>) {
        let decoded = pus::decode_tm(&inc.bytes);
        // A packet received again (same APID, sequence count and on-board time) is
        // counted, neither archived nor acted on twice.
        if let (Ok(tm), Some(s)) = (&decoded, self.robots.get_mut(&inc.robot)) {
            if tm.robot == Some(inc.robot) {
                let stamp = tm.time.to_bytes().iter().fold(0u64, |a, b| (a << 8) | *b as u64);
                if s.seq.on_seq(tm.seq, stamp) == SeqKind::Duplicate {
                    s.duplicates += 1;
                    s.last_tm = Some(Instant::now());
                    return;
                }
            }
        }
        if let Some(a) = &self.archive {
            a.send(Record::Tm {
                t_ms: inc.t_ms,
                link_robot: Some(inc.robot),
                raw: inc.bytes,
                decoded: decoded.clone(),
            });
        }
        let robot = inc.robot;
        let st = self.robots.get_mut(&robot);
        let tm = match decoded {
            Ok(tm) => tm,
            Err(error) => {
                if let Some(s) = st {
                    s.corrupt += 1;
                }
                out.push(Update::Corrupt { robot, error });
                return;
            }
        };
        if let Some(s) = st {
            s.tm_count += 1;
            if tm.robot == Some(robot) {
                s.last_tm = Some(Instant::now());
            }
            if tm.robot != Some(robot) && tm.apid != mib::apid::IDLE_APID {
                s.foreign += 1;
                s.foreign_apid = Some(tm.apid);
                out.push(Update::Foreign {
                    robot,
                    apid: tm.apid,
                    service: tm.service,
                    subservice: tm.subservice,
                });
                return;
            }
        }
        match tm.body {
            TmBody::Verification(v) => {
                let key = (v.request.apid(), v.request.seq());
                let mut tag = None;
                let mut name = None;
                let mut after = None;
                let mut finished = false;
                // The ground builds every TC from the MIB and checks it as the OBSW's
                // acceptance does (CRC, length, version, APID, service, argument lengths and
                // ranges): a TM[1,2] with one of those codes is about a copy damaged on the
                // way (the order of the on-board checks lets a flipped header bit show as
                // any of them), not about the TC.
                let damaged = !v.success
                    && v.stage == Stage::Acceptance
                    && v.failure
                        .as_ref()
                        .is_some_and(|f| mib::tc::ACCEPTANCE_FAILURES.iter().any(|c| c.code() == f.code));
                if damaged {
                    if let Some(p) = self.pending.get_mut(&key) {
                        // Resend at once (same bytes); it counts as a send, so a TC that
                        // only ever gets such answers ends after its sends.
                        if p.sends < p.max_sends {
                            if let Some(link) = self.links.get(&p.robot) {
                                let _ = link.send(&p.tc.bytes);
                            }
                            p.sends += 1;
                        }
                        p.last_sent = Instant::now();
                        out.push(Update::DamagedCopy {
                            robot,
                            tag: p.tag,
                            tc: p.tc.def.name,
                        });
                    }
                    return;
                }
                if let Some(p) = self
                    .pending
                    .get(&key)
                    .filter(|p| p.label.as_deref() == Some(START_LABEL))
                {
                    // A start marker's reports follow each other on board: TM[1,1] has
                    // the first count of the run, TM[1,7] two more (TM[17,2] between).
                    let first = match v.stage {
                        Stage::Acceptance => Some(tm.seq),
                        Stage::Completion => Some(tm.seq.wrapping_sub(2) % SEQ_MOD),
                        Stage::Start | Stage::Progress => None,
                    };
                    if let (Some(f), Some(s)) = (first, self.robots.get_mut(&p.robot)) {
                        s.run_first_seq.get_or_insert(f);
                    }
                }
                if let Some(p) = self.pending.get_mut(&key) {
                    tag = p.tag;
                    name = Some(p.tc.def.name);
                    after = Some(p.first_sent.elapsed());
                    if v.stage == Stage::Acceptance && !p.accepted {
                        p.accepted = true;
                        if let Some(s) = self.robots.get_mut(&p.robot) {
                            s.exchange(true);
                        }
                    }
                    // A TC is finished by its completion report or any failure; TCs
                    // that do not ask for completion finish with acceptance.
                    let wants_completion = p.tc.bytes.get(6).is_some_and(|b| b & 0x01 != 0);
                    finished = !v.success
                        || v.stage == Stage::Completion
                        || (!wants_completion && v.stage == Stage::Acceptance);
                }
                if finished {
                    self.pending.remove(&key);
                }
                out.push(Update::Verification {
                    robot,
                    tag,
                    tc: name,
                    v,
                    after,
                });
            }
            TmBody::StoreDownlinkDone {
                oldest_seq,
                overwritten,
                ..
            } => {
                if let Some(s) = self.robots.get_mut(&robot) {
                    s.store_oldest = Some(oldest_seq);
                    s.store_overwritten = overwritten;
                }
                out.push(Update::Tm {
                    robot,
                    tm: Tm { body: tm.body, ..tm },
                });
            }
            TmBody::Hk(hk) => {
                if hk.sid == mib::hk::sid::ROBOT_STATUS {
                    if let Some(s) = self.robots.get_mut(&robot) {
                        s.mode = hk.raw(pid::MODE).map(|m| m as u32);
                        s.state = hk
                            .raw(pid::CONFIG_STATE)
                            .filter(|&v| v != mib::robot::STATE_UNKNOWN as i64)
                            .map(|v| v as u8);
                        s.target = hk
                            .raw(pid::TARGET_STATE)
                            .filter(|&v| v != mib::robot::STATE_UNKNOWN as i64)
                            .map(|v| v as u8);
                        s.battery_v = hk.eng(pid::V_BAT_A);
                    }
                }
                out.push(Update::Hk { robot, hk });
            }
            TmBody::Event(event) => {
                if let Some(s) = self.robots.get_mut(&robot) {
                    if event.id == eid::MODE_CHANGED && event.param("node") == Some(mib::modes::node::ROBOT as i64) {
                        s.mode = event.param("to").map(|m| m as u32);
                    }
                    if event.id == eid::STATE_REACHED {
                        s.state = event.param("state").map(|v| v as u8);
                    }
                }
                out.push(Update::Event { robot, event });
            }
            TmBody::ModeReply { node, mode, .. } => {
                if node == mib::modes::node::ROBOT {
                    if let Some(s) = self.robots.get_mut(&robot) {
                        s.mode = Some(mode);
                    }
                }
                out.push(Update::Tm {
                    robot,
                    tm: Tm {
                        body: TmBody::ModeReply { node, mode, submode: 0 },
                        ..tm
                    },
                });
            }
            body => out.push(Update::Tm {
                robot,
                tm: Tm { body, ..tm },
            }),
        }
    }
}

/// Words for a verification failure.
pub fn failure_words(v: &Verification) -> String {
    match &v.failure {
        Some(f) => format!("{} failed: {f}", v.stage.name()),
        None => format!("{} failed", v.stage.name()),
    }
}

// ---------------------------------------------------------------------------
// Plan execution

/// State of one step during a run.
#[derive(Clone, Debug, PartialEq)]
pub enum StepState {
    Waiting,
    Running {
        tc: Option<BuiltTc>,
        since: Instant,
        stage: &'static str,
        progress: u8,
    },
    Done {
        secs: f64,
    },
    Failed(String),
    Blocked(String),
}

impl StepState {
    fn terminal(&self) -> bool {
        matches!(
            self,
            StepState::Done { .. } | StepState::Failed(_) | StepState::Blocked(_)
        )
    }
}

#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Longest a step may run before it fails (unless the step gives `timeout`).
    pub step_timeout: Duration,
    /// Heartbeat (TC[17,1]) period per robot while the plan runs; `None` for no
    /// heartbeats and no link-loss watch.
    pub ping_period: Option<Duration>,
    /// Show the indicatif progress display (else plain log lines).
    pub display: bool,
    /// Set by the first Ctrl-C / SIGTERM: no new step is sent; the steps in flight get
    /// `grace` to finish, then the run ends with its summary.
    pub stop: Option<Arc<AtomicBool>>,
    /// Longest wait for the steps in flight after `stop`.
    pub grace: Duration,
}

/// How long an interrupted run waits for the steps in flight by default.
pub const INTERRUPT_GRACE: Duration = Duration::from_secs(10);

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            step_timeout: Duration::from_secs(120),
            ping_period: Some(Duration::from_millis(GROUND_HEARTBEAT_MS as u64)),
            display: true,
            stop: None,
            grace: INTERRUPT_GRACE,
        }
    }
}

/// Fastener pairs by the attempt that locked them (paper statistics).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct BoltStats {
    pub first: u32,
    pub second: u32,
    pub third: u32,
    pub later: u32,
    pub failed: u32,
}

#[derive(Clone, Debug, Serialize)]
pub struct StepOutcome {
    pub id: String,
    pub robot: u8,
    pub action: String,
    pub result: String,
    pub reason: Option<String>,
    pub seconds: Option<f64>,
}

#[derive(Clone, Debug, Serialize)]
pub struct LinkSummary {
    pub robot: u8,
    pub quality: Option<f64>,
    pub exchanges: usize,
    pub tm: u64,
    pub corrupt: u64,
    /// TM packets received twice (same APID and sequence count), acted on once.
    pub duplicates: u64,
    /// Sequence counts never received (inclusive ranges).
    pub tm_missing: Vec<(u16, u16)>,
    /// Sequence counts that arrived after later ones (late or replayed).
    pub tm_late: u64,
    /// Why the link was lost, if it was.
    pub lost: Option<String>,
    pub resends: u32,
}

#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub plan: String,
    /// The run's ID (archived with every TC it sent); `--resume` continues it.
    pub run_id: Option<String>,
    /// The operator interrupted the run (Ctrl-C or SIGTERM).
    pub interrupted: bool,
    /// Steps still running on board when the run ended (after an interruption).
    pub in_flight: usize,
    pub steps: Vec<StepOutcome>,
    pub done: usize,
    pub failed: usize,
    pub blocked: usize,
    /// Steps completed in an earlier run (`--resume`), not sent again.
    pub resumed: usize,
    pub bolts: BoltStats,
    pub unbolted_pairs: u32,
    pub faults: Vec<String>,
    pub link_lost: Vec<String>,
    pub links: Vec<LinkSummary>,
    /// Completeness of each robot's TM at the end (after gap retrieval).
    pub tm: Vec<TmCompleteness>,
    pub seconds: f64,
}

impl RunSummary {
    fn lost_lines(&self) -> Vec<String> {
        self.link_lost.clone()
    }
    pub fn success(&self) -> bool {
        self.failed == 0 && self.blocked == 0 && self.link_lost.is_empty() && !self.interrupted
    }
    /// Human-readable summary.
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        if let Some(r) = &self.run_id {
            let _ = writeln!(s, "run {r}");
        }
        let _ = writeln!(
            s,
            "plan {}: {} of {} steps done, {} failed, {} blocked, in {:.1} s",
            self.plan,
            self.done,
            self.steps.len(),
            self.failed,
            self.blocked,
            self.seconds
        );
        if self.interrupted {
            let _ = writeln!(
                s,
                "INTERRUPTED: no new step was sent after the interruption; {} step(s) still running on board{}",
                self.in_flight,
                self.run_id.as_ref().map_or(String::new(), |r| format!(
                    "; continue with `ground run PLAN --resume {r}`"
                ))
            );
        }
        for o in &self.steps {
            let _ = writeln!(
                s,
                "  {:<8} {:<22} robot {:<3} {:<34} {}",
                o.result,
                o.id,
                o.robot,
                o.action,
                o.reason
                    .clone()
                    .unwrap_or_else(|| o.seconds.map_or(String::new(), |t| format!("{t:.1} s")))
            );
        }
        let b = &self.bolts;
        let _ = writeln!(
            s,
            "bolts per attempt: 1st {}, 2nd {}, 3rd {}, later {}, failed {}; pairs unbolted {}",
            b.first, b.second, b.third, b.later, b.failed, self.unbolted_pairs
        );
        if self.faults.is_empty() {
            let _ = writeln!(s, "faults: none");
        } else {
            let _ = writeln!(s, "faults:");
            for f in &self.faults {
                let _ = writeln!(s, "  {f}");
            }
        }
        if self.resumed > 0 {
            let _ = writeln!(s, "resumed: {} steps completed in an earlier run", self.resumed);
        }
        for l in &self.lost_lines() {
            let _ = writeln!(s, "LINK LOST: {l}");
        }
        for l in &self.links {
            let _ = writeln!(
                s,
                "link robot {}: quality {} over {} exchanges, {} TM ({} duplicates dropped, {} late), {} corrupt, {} resends",
                l.robot,
                l.quality.map_or("-".into(), |q| format!("{:.0}%", q * 100.0)),
                l.exchanges,
                l.tm,
                l.duplicates,
                l.tm_late,
                l.corrupt,
                l.resends
            );
        }
        for c in &self.tm {
            let _ = writeln!(s, "{}", c.line());
        }
        s
    }
}

struct Display {
    mp: indicatif::MultiProgress,
    total: indicatif::ProgressBar,
    robots: BTreeMap<u8, indicatif::ProgressBar>,
    visible: bool,
}

impl Display {
    fn new(plan: &Plan, robots: &[u8], want: bool) -> Display {
        use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
        let target = if want {
            ProgressDrawTarget::stderr_with_hz(10)
        } else {
            ProgressDrawTarget::hidden()
        };
        let mp = MultiProgress::with_draw_target(target);
        let total = mp.add(ProgressBar::new(plan.steps.len() as u64));
        total.set_style(
            ProgressStyle::with_template("{prefix:>9} [{bar:30}] {pos}/{len} steps {elapsed} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        total.set_prefix(plan.name.clone());
        let mut bars = BTreeMap::new();
        for &r in robots {
            let b = mp.add(ProgressBar::new_spinner());
            b.set_style(
                ProgressStyle::with_template("{prefix:>9} {spinner} {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            );
            b.set_prefix(format!("robot {r}"));
            bars.insert(r, b);
        }
        let visible = !mp.is_hidden();
        Display {
            mp,
            total,
            robots: bars,
            visible,
        }
    }
    fn log(&self, line: String) {
        if self.visible {
            let _ = self.mp.println(line);
        } else {
            // A closed stderr must not stop a run.
            use std::io::Write as _;
            let _ = writeln!(std::io::stderr().lock(), "{line}");
        }
    }
}

/// What the executor asks its driver to do.
#[derive(Clone, Debug)]
pub enum Effect {
    /// Send the TC of step `step` and report the result with [`Executor::on_sent`].
    Send {
        step: usize,
        robot: u8,
        def: &'static TcDef,
        args: Vec<i64>,
    },
    /// Stop tracking a TC (its step ended without it).
    Forget(BuiltTc),
    /// Send a connection test to keep the lease and check the link.
    Heartbeat(u8),
    /// Ask the robot's on-board store for its missing TM (a TC's outcome is among it).
    Retrieve(u8),
    /// A line for the operator.
    Log(String),
    /// One more step finished (for the progress display).
    Finished,
}

/// Plan execution as a pure state machine: it sees time only through the `now` it is
/// given, and acts only through the [`Effect`]s it returns, so it is tested with a mock
/// clock and no sockets. [`run_plan`] drives it with a [`Session`].
pub struct Executor<'p> {
    plan: &'p Plan,
    opts: RunOptions,
    pub state: Vec<StepState>,
    sends: HashMap<usize, u32>,
    bolts: BoltStats,
    unbolted: u32,
    faults: Vec<String>,
    lost: Vec<String>,
    resumed: usize,
    start: Instant,
    last_heartbeat: HashMap<u8, Instant>,
    /// Interrupted: no new step starts; the steps in flight are awaited until then.
    halted: Option<Instant>,
}

impl<'p> Executor<'p> {
    /// A run of `plan` starting at `now`; steps in `done` completed in an earlier run
    /// (`--resume`) and are not sent again.
    pub fn new(plan: &'p Plan, opts: &RunOptions, done: &[usize], now: Instant) -> Executor<'p> {
        let mut state = vec![StepState::Waiting; plan.steps.len()];
        let mut resumed = 0;
        let n = state.len();
        for &i in done.iter().filter(|&&i| i < n) {
            state[i] = StepState::Done { secs: 0.0 };
            resumed += 1;
        }
        Executor {
            plan,
            opts: opts.clone(),
            state,
            sends: HashMap::new(),
            bolts: BoltStats::default(),
            unbolted: 0,
            faults: Vec::new(),
            lost: Vec::new(),
            resumed,
            start: now,
            last_heartbeat: HashMap::new(),
            halted: None,
        }
    }

    /// The operator interrupted the run at `now`: no new step starts; the steps in
    /// flight get until `now + grace` to finish.
    pub fn interrupt(&mut self, now: Instant, grace: Duration) -> Vec<Effect> {
        if self.halted.is_some() {
            return Vec::new();
        }
        self.halted = Some(now + grace);
        let running: Vec<&str> = self
            .plan
            .steps
            .iter()
            .zip(&self.state)
            .filter(|(_, st)| matches!(st, StepState::Running { .. }))
            .map(|(s, _)| s.id.as_str())
            .collect();
        vec![Effect::Log(if running.is_empty() {
            "  INTERRUPTED: no step in flight; no new step is sent".to_string()
        } else {
            format!(
                "  INTERRUPTED: no new step is sent; waiting up to {:.0} s for {} (Ctrl-C again to quit at once)",
                grace.as_secs_f64(),
                running.join(", ")
            )
        })]
    }

    /// True once an interrupted run has nothing left to wait for: no step in flight, or
    /// its grace time is over.
    pub fn stopped(&self, now: Instant) -> bool {
        self.halted
            .is_some_and(|t| now >= t || !self.state.iter().any(|s| matches!(s, StepState::Running { .. })))
    }

    /// Takes over a step whose TC an earlier session of this run sent (`--resume`): it
    /// runs from `now` on, its outcome comes from the TC's reports.
    pub fn adopt(&mut self, step: usize, tc: BuiltTc, stage: &'static str, now: Instant) {
        if let Some(st) = self.state.get_mut(step) {
            *st = StepState::Running {
                tc: Some(tc),
                since: now,
                stage,
                progress: 0,
            };
            self.sends.insert(step, 1);
        }
    }

    /// A step adopted by [`Executor::adopt`] whose TC is known never to have reached the
    /// robot: it is sent again (as a new TC) like a step not yet started.
    pub fn requeue(&mut self, step: usize) {
        if let Some(st) = self.state.get_mut(step) {
            *st = StepState::Waiting;
        }
    }

    /// Fails a step with `why` (and blocks what depends on it).
    pub fn fail_step(&mut self, step: usize, why: String) -> Vec<Effect> {
        let mut fx = Vec::new();
        if step < self.state.len() {
            self.fail(step, why, &mut fx);
        }
        fx
    }

    /// True when every step is done, failed or blocked.
    pub fn finished(&self) -> bool {
        self.state.iter().all(StepState::terminal)
    }

    fn block_dependents(&mut self, i: usize, why: &str, fx: &mut Vec<Effect>) {
        for d in self.plan.dependents(i) {
            if self.state[d] == StepState::Waiting {
                self.state[d] = StepState::Blocked(format!("waits for \"{}\", which {why}", self.plan.steps[i].id));
                fx.push(Effect::Log(format!(
                    "  blocked  {} (waits for {})",
                    self.plan.steps[d].id, self.plan.steps[i].id
                )));
            }
        }
    }

    fn fail(&mut self, i: usize, why: String, fx: &mut Vec<Effect>) {
        if let StepState::Running { tc: Some(tc), .. } = &self.state[i] {
            fx.push(Effect::Forget(tc.clone()));
        }
        fx.push(Effect::Log(format!("  FAILED   {}: {why}", self.plan.steps[i].id)));
        self.state[i] = StepState::Failed(why);
        self.block_dependents(i, "failed", fx);
    }

    /// Starts every step whose dependencies have completed; heartbeats; timeouts.
    pub fn on_tick(&mut self, now: Instant) -> Vec<Effect> {
        let mut fx = Vec::new();
        let n = self.plan.steps.len();
        for i in 0..n {
            if self.state[i] != StepState::Waiting || self.halted.is_some() {
                continue;
            }
            let s = &self.plan.steps[i];
            if !s.deps.iter().all(|&d| matches!(self.state[d], StepState::Done { .. })) {
                continue;
            }
            self.state[i] = StepState::Running {
                tc: None,
                since: now,
                stage: if s.action.tc().is_some() { "sending" } else { "waiting" },
                progress: 0,
            };
            match s.action.tc() {
                None => fx.push(Effect::Log(format!(
                    "  start    {} robot {}: {}",
                    s.id,
                    s.robot,
                    s.action.describe()
                ))),
                Some((def, args)) => fx.push(Effect::Send {
                    step: i,
                    robot: s.robot,
                    def,
                    args,
                }),
            }
        }
        // Wait steps and step timeouts.
        for i in 0..n {
            let StepState::Running { tc, since, .. } = &self.state[i] else {
                continue;
            };
            let s = &self.plan.steps[i];
            let limit = s.timeout_s.map_or(self.opts.step_timeout, Duration::from_secs_f64);
            let ran = now.saturating_duration_since(*since);
            match (&s.action, tc) {
                (Action::Wait { seconds }, None) if ran.as_secs_f64() >= *seconds => {
                    let secs = ran.as_secs_f64();
                    fx.push(Effect::Log(format!("  done     {} (waited {secs:.1} s)", s.id)));
                    self.state[i] = StepState::Done { secs };
                    fx.push(Effect::Finished);
                }
                (_, Some(tc)) if ran > limit => {
                    let why = format!("no completion of {} within {:.0} s", tc.def.name, limit.as_secs_f64());
                    self.fail(i, why, &mut fx);
                }
                _ => {}
            }
        }
        // Heartbeats while the plan runs.
        if let Some(period) = self.opts.ping_period {
            if !self.finished() {
                for r in self.plan.robots.iter().map(|r| r.number) {
                    let due = self
                        .last_heartbeat
                        .get(&r)
                        .is_none_or(|t| now.saturating_duration_since(*t) >= period);
                    if due {
                        self.last_heartbeat.insert(r, now);
                        fx.push(Effect::Heartbeat(r));
                    }
                }
            }
        }
        fx
    }

    /// The result of an [`Effect::Send`].
    pub fn on_sent(&mut self, step: usize, sent: Result<BuiltTc, String>, now: Instant) -> Vec<Effect> {
        let mut fx = Vec::new();
        let Some(s) = self.plan.steps.get(step) else { return fx };
        match sent {
            Ok(tc) => {
                self.sends.insert(step, 1);
                fx.push(Effect::Log(format!(
                    "  send     {} robot {}: {} (seq {})",
                    s.id,
                    s.robot,
                    s.action.describe(),
                    tc.seq
                )));
                self.state[step] = StepState::Running {
                    tc: Some(tc),
                    since: now,
                    stage: "sent",
                    progress: 0,
                };
            }
            Err(e) => self.fail(step, format!("could not be sent: {e}"), &mut fx),
        }
        fx
    }

    /// Takes one update from the session.
    pub fn on_update(&mut self, now: Instant, u: Update) -> Vec<Effect> {
        let mut fx = Vec::new();
        let n = self.plan.steps.len();
        match u {
            Update::Verification {
                tag: Some(i), v, after, ..
            } if i < n => {
                let StepState::Running {
                    since, stage, progress, ..
                } = &mut self.state[i]
                else {
                    return fx;
                };
                let s = &self.plan.steps[i];
                if !v.success {
                    let why = format!("robot {}: {}", s.robot, failure_words(&v));
                    self.fail(i, why, &mut fx);
                    return fx;
                }
                match v.stage {
                    Stage::Acceptance => {
                        *stage = "accepted";
                        if let Some(a) = after.filter(|a| a.as_millis() > TC_RETRY_INITIAL_MS as u128) {
                            fx.push(Effect::Log(format!(
                                "  accepted {} after {:.2} s",
                                s.id,
                                a.as_secs_f64()
                            )));
                        }
                    }
                    Stage::Start => *stage = "started",
                    Stage::Progress => {
                        *stage = "progress";
                        *progress = v.step.unwrap_or(*progress + 1);
                    }
                    Stage::Completion => {
                        let secs = now.saturating_duration_since(*since).as_secs_f64();
                        fx.push(Effect::Log(format!(
                            "  done     {} robot {} in {secs:.1} s",
                            s.id, s.robot
                        )));
                        self.state[i] = StepState::Done { secs };
                        fx.push(Effect::Finished);
                    }
                }
            }
            Update::Resent {
                robot,
                tag: Some(i),
                tc,
                send,
            } if i < n => {
                self.sends.insert(i, send);
                fx.push(Effect::Log(format!(
                    "  resend   {} robot {robot}: {tc}, no acceptance yet (send {send}, same bytes)",
                    self.plan.steps[i].id
                )));
            }
            Update::DamagedCopy {
                robot,
                tag: Some(i),
                tc,
            } if i < n => {
                *self.sends.entry(i).or_insert(1) += 1;
                fx.push(Effect::Log(format!(
                    "  resend   {} robot {robot}: a copy of {tc} arrived damaged (CRC), sent again",
                    self.plan.steps[i].id
                )));
            }
            Update::GaveUp {
                robot,
                tag: Some(i),
                tc,
                sends: k,
                accepted,
            } if i < n => {
                if accepted {
                    // Still running (the step timeout bounds it): the outcome is asked of
                    // the on-board store.
                    if let StepState::Running { stage, .. } = &mut self.state[i] {
                        *stage = "outcome asked of the store";
                    }
                    fx.push(Effect::Log(format!(
                        "  store    {} robot {robot}: {tc} accepted, no outcome after {k} sends; asking the on-board store",
                        self.plan.steps[i].id
                    )));
                    fx.push(Effect::Retrieve(robot));
                } else {
                    let why =
                        format!("no report of {tc} from robot {robot} after {k} sends (link down or OBSW not running)");
                    self.fail(i, why, &mut fx);
                }
            }
            Update::LinkLost { robot, why } => {
                fx.push(Effect::Log(format!("  LINK     {why}")));
                self.lost.push(why.clone());
                for i in 0..n {
                    if self.plan.steps[i].robot != robot {
                        continue;
                    }
                    match self.state[i] {
                        StepState::Running { .. } => self.fail(i, format!("link lost: {why}"), &mut fx),
                        StepState::Waiting => {
                            self.state[i] = StepState::Blocked(format!("link lost: {why}"));
                            self.block_dependents(i, "could not run (link lost)", &mut fx);
                        }
                        StepState::Done { .. } | StepState::Failed(_) | StepState::Blocked(_) => {}
                    }
                }
            }
            Update::Event { robot, event } => {
                match event.id {
                    eid::BOLT_PAIR_DONE => match event.param("attempts") {
                        Some(1) => self.bolts.first += 1,
                        Some(2) => self.bolts.second += 1,
                        Some(3) => self.bolts.third += 1,
                        _ => self.bolts.later += 1,
                    },
                    eid::BOLT_FAILURE => self.bolts.failed += 1,
                    eid::UNBOLT_PAIR_DONE => self.unbolted += 1,
                    _ => {}
                }
                if event.fault {
                    let line = format!("robot {robot}: {event}");
                    fx.push(Effect::Log(format!("  FAULT    {line}")));
                    self.faults.push(line);
                    // Steps of this robot not yet sent, and everything after them,
                    // stop; the running one finishes per its verification.
                    for i in 0..n {
                        if self.plan.steps[i].robot == robot && self.state[i] == StepState::Waiting {
                            self.state[i] = StepState::Blocked(format!(
                                "robot {robot} reported fault {}: {}",
                                event.name, event.description
                            ));
                            self.block_dependents(i, "was stopped by a fault", &mut fx);
                        }
                    }
                } else if matches!(event.severity, "medium" | "high") {
                    fx.push(Effect::Log(format!("  event    robot {robot}: {event}")));
                }
            }
            Update::Corrupt { robot, error } => {
                fx.push(Effect::Log(format!("  corrupt  TM from robot {robot}: {error}")));
            }
            Update::Foreign {
                robot,
                apid,
                service,
                subservice,
            } => {
                fx.push(Effect::Log(format!(
                    "  skipped  TM[{service},{subservice}] of APID 0x{apid:03X} on robot {robot}'s link"
                )));
            }
            Update::Verification { .. }
            | Update::Resent { .. }
            | Update::DamagedCopy { .. }
            | Update::GaveUp { .. }
            | Update::Hk { .. }
            | Update::Tm { .. } => {}
        }
        fx
    }

    /// One-line status of `robot`'s current step, for the display.
    fn robot_line(&self, r: u8) -> String {
        let steps = &self.plan.steps;
        let n = steps.len();
        let cur = (0..n).find(|&i| steps[i].robot == r && matches!(self.state[i], StepState::Running { .. }));
        let done = (0..n)
            .filter(|&i| steps[i].robot == r && self.state[i].terminal())
            .count();
        let total = (0..n).filter(|&i| steps[i].robot == r).count();
        let step = match cur.map(|i| (i, &self.state[i])) {
            Some((i, StepState::Running { stage, progress, .. })) if *progress > 0 => {
                format!("{} {stage} {progress}", steps[i].id)
            }
            Some((i, StepState::Running { stage, .. })) => format!("{} {stage}", steps[i].id),
            _ => "idle".into(),
        };
        format!("{done}/{total} | {step}")
    }

    /// The summary of the run, with the session's link figures.
    pub fn summary(&self, session: &Session, now: Instant) -> RunSummary {
        let plan = self.plan;
        let steps: Vec<StepOutcome> = plan
            .steps
            .iter()
            .zip(&self.state)
            .map(|(s, st)| {
                let (result, reason, seconds) = match st {
                    StepState::Done { secs } => ("done", None, Some(*secs)),
                    StepState::Failed(w) => ("FAILED", Some(w.clone()), None),
                    StepState::Blocked(w) => ("blocked", Some(w.clone()), None),
                    StepState::Running { .. } if self.halted.is_some() => (
                        "RUNNING",
                        Some(
                            "still running on board when the run was interrupted: `--resume` resolves its outcome"
                                .into(),
                        ),
                        None,
                    ),
                    StepState::Waiting if self.halted.is_some() => {
                        ("not sent", Some("the run was interrupted".into()), None)
                    }
                    StepState::Waiting | StepState::Running { .. } => ("unfinished", None, None),
                };
                StepOutcome {
                    id: s.id.clone(),
                    robot: s.robot,
                    action: s.action.describe(),
                    result: result.into(),
                    reason,
                    seconds,
                }
            })
            .collect();
        let links = session
            .robots
            .values()
            .map(|r| LinkSummary {
                robot: r.robot,
                quality: r.link_quality(),
                exchanges: r.quality.len(),
                tm: r.tm_count,
                corrupt: r.corrupt,
                duplicates: r.duplicates,
                tm_missing: r.seq.missing_ranges(),
                tm_late: r.seq.filled,
                lost: r.lost.clone(),
                resends: plan
                    .steps
                    .iter()
                    .enumerate()
                    .filter(|(_, s)| s.robot == r.robot)
                    .map(|(i, _)| self.sends.get(&i).copied().unwrap_or(1).saturating_sub(1))
                    .sum(),
            })
            .collect();
        RunSummary {
            plan: plan.name.clone(),
            run_id: session.run_id.clone(),
            interrupted: self.halted.is_some(),
            in_flight: self
                .state
                .iter()
                .filter(|s| matches!(s, StepState::Running { tc: Some(_), .. }))
                .count(),
            done: self
                .state
                .iter()
                .filter(|s| matches!(s, StepState::Done { .. }))
                .count(),
            failed: self.state.iter().filter(|s| matches!(s, StepState::Failed(_))).count(),
            blocked: self.state.iter().filter(|s| matches!(s, StepState::Blocked(_))).count(),
            resumed: self.resumed,
            steps,
            bolts: self.bolts.clone(),
            unbolted_pairs: self.unbolted,
            faults: self.faults.clone(),
            link_lost: self.lost.clone(),
            links,
            tm: Vec::new(),
            seconds: now.saturating_duration_since(self.start).as_secs_f64(),
        }
    }
}

/// What `--resume` hands to [`run_plan`]: the state of the run's earlier session(s).
#[derive(Clone, Debug, Default)]
pub struct Resume {
    /// Steps completed earlier: not sent again.
    pub done: Vec<usize>,
    /// Steps whose TC was sent earlier but whose outcome the archive does not show.
    pub in_flight: Vec<InFlight>,
    /// Per robot, the last TM sequence count of its APID in the archive: the on-board
    /// store is asked for everything after it before anything is sent.
    pub last_seq: Vec<(u8, u16)>,
}

/// A step whose TC an earlier session sent, outcome unknown.
#[derive(Clone, Debug)]
pub struct InFlight {
    pub step: usize,
    pub tc: BuiltTc,
    /// The archive has its acceptance report.
    pub accepted: bool,
}

/// Executes a plan: each step is sent once every step it depends on has completed.
/// `resume` holds what earlier sessions of the same run did (`--resume`).
pub fn run_plan(plan: &Plan, session: &mut Session, opts: &RunOptions, resume: &Resume) -> RunSummary {
    let robots: Vec<u8> = plan.robots.iter().map(|r| r.number).collect();
    let disp = Display::new(plan, &robots, opts.display);
    let mut exec = Executor::new(plan, opts, &resume.done, Instant::now());
    let mut last_gap_check = Instant::now();
    disp.total.inc(exec.resumed as u64);
    if exec.resumed > 0 {
        disp.log(format!(
            "  resume   {} steps completed earlier in this run are not sent again",
            exec.resumed
        ));
    }
    let stop_asked = || opts.stop.as_ref().is_some_and(|f| f.load(Ordering::SeqCst));
    // TCs of the earlier session whose outcome is unknown: tracked again (never resent),
    // and the TM the ground missed since is asked of the on-board store first.
    for f in &resume.in_flight {
        let Some(st) = plan.steps.get(f.step) else { continue };
        session.adopt(st.robot, f.tc.clone(), Some(f.step), Some(st.id.clone()), f.accepted);
        exec.adopt(f.step, f.tc.clone(), "outcome asked of the store", Instant::now());
        disp.log(format!(
            "  resume   {} robot {}: {} (seq {}) was sent before the interruption, {}; resolving its outcome before anything is sent",
            st.id,
            st.robot,
            f.tc.def.name,
            f.tc.seq,
            if f.accepted { "accepted, no completion archived" } else { "no report archived" }
        ));
        if let Some((_, last)) = resume.last_seq.iter().find(|(r, _)| *r == st.robot) {
            if let Some(s) = session.robots.get_mut(&st.robot) {
                if s.seq.newest().is_none() {
                    s.seq.expect_from(last.wrapping_add(1) % SEQ_MOD);
                }
            }
        }
    }
    // Every session of a run starts with a start marker per robot: it names the run in
    // the archive (see `runs`) and, answered, starts the TM accounting.
    let watch = opts.ping_period.is_some() || !resume.in_flight.is_empty();
    if watch {
        session.watch_links();
    }
    let early = start_markers(session, &robots, watch, &stop_asked);
    let apply = |fx: Vec<Effect>, exec: &mut Executor, session: &mut Session| {
        let mut queue: VecDeque<Effect> = fx.into();
        while let Some(e) = queue.pop_front() {
            match e {
                Effect::Send { step, robot, def, args } => {
                    let label = Some(plan.steps[step].id.clone());
                    let sent = session
                        .send(robot, def, &args, Some(step), label)
                        .map_err(|e| e.to_string());
                    queue.extend(exec.on_sent(step, sent, Instant::now()));
                }
                Effect::Forget(tc) => session.forget(&tc),
                Effect::Heartbeat(r) => {
                    // Not when another TC just went out: every TC enters the OBSW's
                    // duplicate window, which must keep the plan's TCs for their whole
                    // retry span. A failed send shows as silence: the link-loss check
                    // reports it.
                    let period = opts.ping_period.unwrap_or_default();
                    if !session.sent_within(r, period) {
                        let _ = session.send_heartbeat(r);
                    }
                }
                Effect::Retrieve(r) => {
                    if !session.retrieving(r) {
                        session.request_gaps(r, None, 1);
                    }
                }
                Effect::Log(line) => disp.log(line),
                Effect::Finished => disp.total.inc(1),
            }
        }
    };
    for u in early {
        let fx = exec.on_update(Instant::now(), u);
        apply(fx, &mut exec, session);
    }
    if !resume.in_flight.is_empty() {
        let fx = resolve_in_flight(session, &mut exec, resume, &stop_asked);
        apply(fx, &mut exec, session);
    }
    loop {
        if stop_asked() {
            let fx = exec.interrupt(Instant::now(), opts.grace);
            apply(fx, &mut exec, session);
        }
        let fx = exec.on_tick(Instant::now());
        apply(fx, &mut exec, session);
        if exec.finished() || exec.stopped(Instant::now()) {
            break;
        }
        for u in session.poll(Duration::from_millis(50)) {
            let fx = exec.on_update(Instant::now(), u);
            apply(fx, &mut exec, session);
        }
        // TM gaps are filled from the on-board store while the plan runs.
        if last_gap_check.elapsed() >= GAP_CHECK_PERIOD {
            last_gap_check = Instant::now();
            for &r in &robots {
                let lost = session.robots.get(&r).is_some_and(|s| s.lost.is_some());
                if !lost && !session.retrieving(r) {
                    // One range per period while plan TCs may still be resent (the
                    // duplicate window holds a bounded number of TCs); the rest at the end.
                    session.request_gaps(r, None, 1);
                }
            }
        }
        for (&r, bar) in &disp.robots {
            let st = session.robots.get(&r).map(|s| s.line()).unwrap_or_default();
            bar.set_message(format!("{} | {st}", exec.robot_line(r)));
            bar.tick();
        }
    }
    // An interrupted run ends at once: the TM it missed is filled by the next session.
    let tm = if opts.ping_period.is_some() && !stop_asked() {
        complete_tm(session, &robots, &disp)
    } else {
        Vec::new()
    };
    disp.total.finish();
    for b in disp.robots.values() {
        b.finish();
    }
    let _ = disp.mp.clear();
    let mut summary = exec.summary(session, Instant::now());
    summary.tm = tm;
    summary
}

/// Starts every robot's TM accounting: a connection test (resent until answered) whose
/// reports give the first sequence count of the run; every TM from there on is expected.
/// Returns what happened meanwhile (a link found lost, reports of adopted TCs).
fn start_markers(session: &mut Session, robots: &[u8], wait: bool, stop: &dyn Fn() -> bool) -> Vec<Update> {
    let mut seen = Vec::new();
    let Some(ping) = mib::tc::by_name("PING") else {
        return seen;
    };
    let mut markers = Vec::new();
    for &r in robots {
        if let Ok(m) = session.send(r, ping, &[], None, Some(START_LABEL.into())) {
            markers.push((r, m));
        }
    }
    let t0 = Instant::now();
    let limit = Duration::from_millis(mib::config::TC_RETRY_SPAN_MS as u64);
    while wait
        && t0.elapsed() < limit
        && !stop()
        && markers.iter().any(|(r, m)| {
            // Answered once accepted: its first report gives the run's first count.
            session.accepted(m) == Some(false) && session.robots.get(r).is_some_and(|s| s.lost.is_none())
        })
    {
        seen.extend(session.poll(Duration::from_millis(50)));
    }
    for (r, _) in markers {
        if let Some(s) = session.robots.get_mut(&r) {
            if let Some(f) = s.run_first_seq {
                s.seq.expect_from(f);
            }
        }
    }
    seen
}

/// Resolves the TCs of an interrupted session (`--resume`) before anything is sent: the
/// on-board store is asked for every TM the ground missed since its last archived one,
/// until none is missing. Then a TC with a report ends as it says; one accepted without
/// completion is still running on board (its completion is awaited); one with no report
/// at all in a complete TM stream never reached the robot and is sent again as a new TC;
/// one whose TM cannot be completed (overwritten, not answered) fails as "outcome
/// unknown" and is never sent again.
fn resolve_in_flight(
    session: &mut Session,
    exec: &mut Executor,
    resume: &Resume,
    stop: &dyn Fn() -> bool,
) -> Vec<Effect> {
    let in_flight = &resume.in_flight;
    let mut fx = Vec::new();
    let robots: Vec<u8> = {
        let mut r: Vec<u8> = in_flight
            .iter()
            .filter_map(|f| exec.plan.steps.get(f.step))
            .map(|s| s.robot)
            .collect();
        r.dedup();
        r
    };
    let expired0: HashMap<u8, u64> = robots
        .iter()
        .map(|&r| (r, session.robots.get(&r).map_or(0, |s| s.seq.expired)))
        .collect();
    let t0 = Instant::now();
    let limit = Duration::from_millis(mib::config::TC_RETRY_SPAN_MS as u64);
    let mut idle_rounds = 0;
    loop {
        let open: Vec<u8> = robots
            .iter()
            .copied()
            .filter(|&r| {
                session
                    .robots
                    .get(&r)
                    .is_some_and(|s| s.lost.is_none() && !s.seq.missing.is_empty())
                    && in_flight.iter().any(|f| session.is_pending(&f.tc))
            })
            .collect();
        if open.is_empty() || t0.elapsed() >= limit || stop() || idle_rounds >= GAP_ROUNDS_IDLE_MAX {
            break;
        }
        let before: usize = open
            .iter()
            .map(|r| session.robots.get(r).map_or(0, |s| s.seq.missing.len()))
            .sum();
        for &r in &open {
            if !session.retrieving(r) {
                session.request_gaps(r, None, GAP_REQUESTS_MAX);
            }
        }
        let round = Instant::now();
        while round.elapsed() < Duration::from_secs(3) && open.iter().any(|&r| session.retrieving(r)) {
            for u in session.poll(Duration::from_millis(50)) {
                fx.extend(exec.on_update(Instant::now(), u));
            }
        }
        let settle = Instant::now();
        while settle.elapsed() < Duration::from_millis(300) {
            for u in session.poll(Duration::from_millis(50)) {
                fx.extend(exec.on_update(Instant::now(), u));
            }
        }
        let after: usize = open
            .iter()
            .map(|r| session.robots.get(r).map_or(0, |s| s.seq.missing.len()))
            .sum();
        idle_rounds = if after < before { 0 } else { idle_rounds + 1 };
    }
    for f in in_flight {
        if !session.is_pending(&f.tc) {
            continue; // ended by its reports (or the link loss)
        }
        let Some(step) = exec.plan.steps.get(f.step) else {
            continue;
        };
        let r = step.robot;
        // Complete: every count from the last archived one up to the newest received,
        // the newest ahead of it (a robot that restarted counts from 0 again: its TM
        // does not continue the archive's, and the TC's fate is unknown).
        let last = resume.last_seq.iter().find(|(x, _)| *x == r).map(|(_, q)| *q);
        let complete = session.robots.get(&r).is_some_and(|s| {
            let ahead = match (s.seq.newest(), last) {
                (Some(n), Some(l)) => (1..SEQ_TRACK_WINDOW).contains(&(n.wrapping_sub(l) % SEQ_MOD)),
                (Some(_), None) => true,
                (None, _) => false,
            };
            s.lost.is_none()
                && ahead
                && s.seq.missing.is_empty()
                && s.seq.expired == expired0.get(&r).copied().unwrap_or(0)
        });
        match (complete, session.accepted(&f.tc).unwrap_or(f.accepted)) {
            (true, true) => fx.push(Effect::Log(format!(
                "  resume   {}: accepted and still running on board; its completion is awaited",
                step.id
            ))),
            (true, false) => {
                session.forget(&f.tc);
                exec.requeue(f.step);
                fx.push(Effect::Log(format!(
                    "  resume   {}: its TC (seq {}) never reached the robot (no report in the complete TM since): sent as a new TC",
                    step.id, f.tc.seq
                )));
            }
            (false, _) => {
                session.forget(&f.tc);
                fx.extend(exec.fail_step(
                    f.step,
                    format!(
                        "outcome unknown: {} (seq {}) may have executed, and the robot's TM since the interruption cannot be completed (store overwritten, robot restarted or not answering); not sent again: check the robot, then send the step by hand",
                        f.tc.def.name, f.tc.seq
                    ),
                ));
            }
        }
    }
    fx
}

/// How often a running plan asks the stores for missing TM.
const GAP_CHECK_PERIOD: Duration = Duration::from_secs(2);
/// Retrieval rounds at the end of a run that bring nothing back before the rest counts
/// as not recovered.
const GAP_ROUNDS_IDLE_MAX: u32 = 8;
/// Retrieval rounds at the end of a run at most.
const GAP_ROUNDS_MAX: u32 = 40;

/// The state of a robot's TM at the end of a run.
#[derive(Clone, Debug, Serialize)]
pub struct TmCompleteness {
    pub robot: u8,
    /// Every sequence count from this one (the start marker's first report) ...
    pub from: Option<u16>,
    /// ... up to this one (the end marker's report) was checked.
    pub upto: Option<u16>,
    /// Missing counts overwritten in the on-board store (unrecoverable).
    pub overwritten: Vec<(u16, u16)>,
    /// Missing counts still not received after the retrieval rounds.
    pub not_received: Vec<(u16, u16)>,
    /// Store retrievals sent at the end of the run.
    pub retrievals: u32,
}

impl TmCompleteness {
    pub fn complete(&self) -> bool {
        self.upto.is_some() && self.overwritten.is_empty() && self.not_received.is_empty()
    }
    /// One line for the summary.
    pub fn line(&self) -> String {
        let count = |v: &[(u16, u16)]| -> u32 { v.iter().map(|(a, b)| (b.wrapping_sub(*a) & 0x3FFF) as u32 + 1).sum() };
        let list = |v: &[(u16, u16)]| -> String {
            let mut l: Vec<String> = v
                .iter()
                .take(8)
                .map(|(a, b)| if a == b { format!("{a}") } else { format!("{a}-{b}") })
                .collect();
            if v.len() > 8 {
                l.push("...".into());
            }
            l.join(", ")
        };
        match self.upto {
            None => format!("TM robot {}: completeness unknown (no end marker answered)", self.robot),
            Some(u) if self.complete() => format!(
                "TM robot {}: complete from seq {} up to seq {u} ({} store retrievals at the end)",
                self.robot,
                self.from.map_or("?".into(), |f| f.to_string()),
                self.retrievals
            ),
            Some(u) => format!(
                "TM robot {}: up to seq {u}: {} packets unrecoverable (overwritten on board: {}), {} not received after {} retrievals ({})",
                self.robot,
                count(&self.overwritten),
                list(&self.overwritten),
                count(&self.not_received),
                self.retrievals,
                list(&self.not_received)
            ),
        }
    }
}

/// Ends a run's TM: an end marker (a connection test, resent until answered) fixes how
/// far the TM must be complete; then every gap up to it is asked of the on-board store
/// until it is filled, found overwritten, or `GAP_ROUNDS_MAX` rounds passed.
fn complete_tm(session: &mut Session, robots: &[u8], disp: &Display) -> Vec<TmCompleteness> {
    let mut out = Vec::new();
    let Some(ping) = mib::tc::by_name("PING") else {
        return out;
    };
    for &r in robots {
        let mut c = TmCompleteness {
            robot: r,
            from: session.robots.get(&r).and_then(|s| s.run_first_seq),
            upto: None,
            overwritten: Vec::new(),
            not_received: Vec::new(),
            retrievals: 0,
        };
        if session.robots.get(&r).is_none_or(|s| s.lost.is_some()) {
            out.push(c);
            continue;
        }
        let marker = session.send(r, ping, &[], None, Some("end marker".into()));
        let limit = Duration::from_millis(mib::config::TC_RETRY_SPAN_MS as u64);
        if let Ok(m) = &marker {
            let t0 = Instant::now();
            while t0.elapsed() < limit && session.accepted(m) == Some(false) {
                session.poll(Duration::from_millis(50));
                if session.robots.get(&r).is_some_and(|s| s.lost.is_some()) {
                    break;
                }
            }
        }
        let upto = session.robots.get(&r).and_then(|s| s.seq.newest());
        c.upto = upto;
        let Some(cut) = upto else {
            out.push(c);
            continue;
        };
        let mut rounds = 0;
        let mut idle_rounds = 0;
        let mut before = usize::MAX;
        loop {
            let missing = session
                .robots
                .get(&r)
                .map(|s| s.seq.missing_upto(cut))
                .unwrap_or_default();
            let count = session.robots.get(&r).map_or(0, |s| s.seq.missing.len());
            if count >= before {
                idle_rounds += 1;
            } else {
                idle_rounds = 0;
            }
            before = count;
            if missing.is_empty() || rounds >= GAP_ROUNDS_MAX || idle_rounds >= GAP_ROUNDS_IDLE_MAX {
                break;
            }
            let t0 = Instant::now();
            while t0.elapsed() < limit && session.retrieving(r) {
                session.poll(Duration::from_millis(50));
            }
            let asked = session.request_gaps(r, Some(cut), GAP_REQUESTS_MAX);
            if asked.is_empty() {
                break;
            }
            rounds += 1;
            c.retrievals += asked.len() as u32;
            disp.log(format!(
                "  gaps     robot {r}: {} ranges missing, retrieval round {rounds}",
                missing.len()
            ));
            let t0 = Instant::now();
            while t0.elapsed() < limit && session.retrieving(r) {
                session.poll(Duration::from_millis(50));
            }
            // Replays still on their way.
            let settle = Instant::now();
            while settle.elapsed() < Duration::from_millis(300) {
                session.poll(Duration::from_millis(50));
            }
        }
        if let Some(s) = session.robots.get(&r) {
            for (a, b) in s.seq.missing_upto(cut) {
                // Older than the oldest packet still stored: overwritten on board.
                let gone = s
                    .store_oldest
                    .is_some_and(|o| o != b && o.wrapping_sub(b) % SEQ_MOD < SEQ_MOD / 2);
                if gone {
                    c.overwritten.push((a, b));
                } else {
                    c.not_received.push((a, b));
                }
            }
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pus::{build_tm, CdsShort};
    use std::net::UdpSocket;

    /// A minimal fake OBSW speaking real PUS: answers each TC with TM[1,1] and TM[1,7],
    /// after first sending a TM of another robot's APID; ignores the first `drop` TCs.
    fn fake_obsw(drop: usize) -> (SocketAddr, std::thread::JoinHandle<Vec<(u16, u16)>>) {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        s.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
        let addr = s.local_addr().unwrap();
        let h = std::thread::spawn(move || {
            let mut seen = Vec::new();
            let mut buf = [0u8; 2048];
            let t = CdsShort::now().to_bytes();
            while let Ok((n, from)) = s.recv_from(&mut buf) {
                let Ok(tc) = pus::decode_tc(&buf[..n]) else { continue };
                seen.push((tc.apid, tc.seq));
                if seen.len() <= drop {
                    continue;
                }
                let rid = [buf[0], buf[1], buf[2], buf[3]];
                let other = build_tm(0x1FE, 0, 17, 2, 0, &t, &[]);
                let acc = build_tm(tc.apid, 1, 1, 1, 0, &t, &rid);
                let done = build_tm(tc.apid, 2, 1, 7, 0, &t, &rid);
                for p in [other, acc, done] {
                    s.send_to(&p, from).unwrap();
                }
                if seen.len() > drop {
                    break;
                }
            }
            seen
        });
        (addr, h)
    }

    // verifies: GND-01
    #[test]
    fn session_resends_with_the_same_count_and_skips_foreign_apids() {
        let (addr, fake) = fake_obsw(1);
        let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(100)).unwrap();
        s.ack_timeout = Duration::from_millis(150);
        let tc = s
            .send(1, mib::tc::by_name("PING").unwrap(), &[], Some(7), None)
            .unwrap();
        assert_eq!(tc.seq, 100);
        let mut stages = Vec::new();
        let mut resent = 0;
        let mut foreign = 0;
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(3) && !stages.contains(&Stage::Completion) {
            for u in s.poll(Duration::from_millis(50)) {
                match u {
                    Update::Verification { tag: Some(7), v, .. } => stages.push(v.stage),
                    Update::Resent { send, .. } => resent = send,
                    Update::Foreign { apid, .. } => foreign += (apid == 0x1FE) as u32,
                    _ => {}
                }
            }
        }
        assert_eq!(stages, vec![Stage::Acceptance, Stage::Completion]);
        assert_eq!((resent, foreign), (2, 1));
        assert!(!s.busy(1));
        let st = &s.robots[&1];
        // one exchange timed out, the resend was accepted
        assert_eq!(st.link_quality(), Some(0.5));
        assert_eq!(st.foreign, 1);
        assert_eq!(fake.join().unwrap(), vec![(0x101, 100), (0x101, 100)]);
    }

    // verifies: MMIC-VAL-02
    #[test]
    fn seq_track_finds_gaps_duplicates_and_late_packets_across_the_wrap() {
        let mut t = SeqTrack::default();
        assert_eq!(t.on_seq_t(0x3FFD), SeqKind::New);
        assert_eq!(t.on_seq_t(0x3FFE), SeqKind::New);
        // 0x3FFF, 0 and 1 lost; 2 arrives.
        assert_eq!(t.on_seq_t(2), SeqKind::New);
        assert_eq!(t.missing_ranges(), vec![(0, 1), (0x3FFF, 0x3FFF)]);
        assert_eq!(t.on_seq_t(2), SeqKind::Duplicate);
        assert_eq!(t.on_seq_t(0x3FFE), SeqKind::Duplicate);
        assert_eq!(t.on_seq_t(0), SeqKind::Filled);
        assert_eq!(t.on_seq_t(0), SeqKind::Duplicate);
        assert_eq!(t.missing_ranges(), vec![(1, 1), (0x3FFF, 0x3FFF)]);
        // A gap falls out of the window: expired, not kept for ever.
        assert_eq!(t.on_seq_t(2 + SEQ_TRACK_WINDOW), SeqKind::New);
        assert_eq!(t.on_seq_t(3 + SEQ_TRACK_WINDOW), SeqKind::New);
        assert!(t.expired >= 2, "{t:?}");
        assert_eq!(t.filled, 1);
        // The same count with another on-board time: the OBSW restarted, not a duplicate.
        let newest = t.newest().unwrap();
        assert_eq!(t.on_seq(newest, 1), SeqKind::New);
        assert!(t.missing.is_empty());
        assert_eq!(t.missing_upto(newest), vec![]);
    }

    fn plan(src: &str) -> Plan {
        crate::plan::parse(src).unwrap_or_else(|e| panic!("{e:?}"))
    }

    const TWO_STEPS: &str = r#"
name = "t"
[[robot]]
number = 1
initial_state = "Xneg"
[[step]]
id = "ping1"
robot = 1
action = "command"
tc = "PING"
[[step]]
id = "ping2"
robot = 1
action = "command"
tc = "PING"
timeout = 5
"#;

    /// A verification update for `tc` as the session would give it.
    fn verification(tc: &BuiltTc, step: usize, subservice: u8) -> Update {
        let t = CdsShort::now().to_bytes();
        let rid = &tc.bytes[..4];
        let mut data = rid.to_vec();
        if subservice.is_multiple_of(2) {
            data.extend_from_slice(&mib::failure::FailureCode::NOT_ALLOWED_IN_MODE.code().to_be_bytes());
            data.push(0); // mode: standby
        }
        let tm = pus::decode_tm(&build_tm(tc.apid, 9, 1, subservice, 0, &t, &data)).unwrap();
        let TmBody::Verification(v) = tm.body else {
            panic!("not a verification")
        };
        Update::Verification {
            robot: 1,
            tag: Some(step),
            tc: Some(tc.def.name),
            v,
            after: None,
        }
    }

    fn sends(fx: &[Effect]) -> Vec<usize> {
        fx.iter()
            .filter_map(|e| match e {
                Effect::Send { step, .. } => Some(*step),
                _ => None,
            })
            .collect()
    }

    // verifies: GND-05
    #[test]
    fn executor_runs_steps_in_order_with_a_mock_clock() {
        let pl = plan(TWO_STEPS);
        let opts = RunOptions {
            step_timeout: Duration::from_secs(60),
            ping_period: Some(Duration::from_secs(1)),
            display: false,
            ..RunOptions::default()
        };
        let t0 = Instant::now();
        let mut ex = Executor::new(&pl, &opts, &[], t0);
        let fx = ex.on_tick(t0);
        assert_eq!(sends(&fx), vec![0], "only the first step: the second depends on it");
        assert!(fx.iter().any(|e| matches!(e, Effect::Heartbeat(1))));
        let ping = mib::tc::by_name("PING").unwrap();
        let tc0 = pus::build_tc(1, 10, ping, &[]).unwrap();
        ex.on_sent(0, Ok(tc0.clone()), t0);
        // Nothing new before the completion, and no heartbeat before its period.
        let fx = ex.on_tick(t0 + Duration::from_millis(500));
        assert!(sends(&fx).is_empty() && !fx.iter().any(|e| matches!(e, Effect::Heartbeat(_))));
        assert!(ex
            .on_update(t0 + Duration::from_millis(600), verification(&tc0, 0, 1))
            .is_empty());
        let fx = ex.on_update(t0 + Duration::from_millis(700), verification(&tc0, 0, 7));
        assert!(fx.iter().any(|e| matches!(e, Effect::Finished)));
        assert_eq!(ex.state[0], StepState::Done { secs: 0.7 });
        let fx = ex.on_tick(t0 + Duration::from_millis(1100));
        assert_eq!(sends(&fx), vec![1]);
        assert!(fx.iter().any(|e| matches!(e, Effect::Heartbeat(1))));
        let tc1 = pus::build_tc(1, 11, ping, &[]).unwrap();
        ex.on_sent(1, Ok(tc1.clone()), t0 + Duration::from_millis(1100));
        // Step 2's own timeout (5 s) passes on the mock clock: it fails and its TC is
        // forgotten.
        let fx = ex.on_tick(t0 + Duration::from_millis(6200));
        assert!(
            fx.iter().any(|e| matches!(e, Effect::Forget(tc) if tc.seq == 11)),
            "{fx:?}"
        );
        assert!(matches!(&ex.state[1], StepState::Failed(w) if w.contains("within 5 s")));
        assert!(ex.finished());
        let fx = ex.on_tick(t0 + Duration::from_secs(60));
        assert!(fx.is_empty(), "no heartbeat after the end: {fx:?}");
    }

    // verifies: GND-09
    #[test]
    fn executor_stops_a_robot_on_link_loss_and_resumes_past_done_steps() {
        let pl = plan(TWO_STEPS);
        let opts = RunOptions {
            display: false,
            ..RunOptions::default()
        };
        let t0 = Instant::now();
        let mut ex = Executor::new(&pl, &opts, &[], t0);
        ex.on_tick(t0);
        let ping = mib::tc::by_name("PING").unwrap();
        ex.on_sent(0, Ok(pus::build_tc(1, 10, ping, &[]).unwrap()), t0);
        let fx = ex.on_update(
            t0,
            Update::LinkLost {
                robot: 1,
                why: "robot 1: no TM".into(),
            },
        );
        assert!(fx.iter().any(|e| matches!(e, Effect::Forget(_))));
        assert!(matches!(&ex.state[0], StepState::Failed(w) if w.contains("link lost")));
        assert!(matches!(&ex.state[1], StepState::Blocked(_)));
        assert_eq!(ex.lost.len(), 1);

        // Resumed with the first step done: only the second is sent.
        let mut ex = Executor::new(&pl, &opts, &[0], t0);
        assert_eq!(sends(&ex.on_tick(t0)), vec![1]);
        assert_eq!(ex.resumed, 1);
    }

    // verifies: OPS-RUN-02
    #[test]
    fn an_interrupted_executor_sends_nothing_new_and_waits_a_bounded_time() {
        let pl = plan(TWO_STEPS);
        let opts = RunOptions {
            display: false,
            ping_period: None,
            ..RunOptions::default()
        };
        let t0 = Instant::now();
        let mut ex = Executor::new(&pl, &opts, &[], t0);
        ex.on_tick(t0);
        let tc0 = pus::build_tc(1, 10, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
        ex.on_sent(0, Ok(tc0.clone()), t0);
        let fx = ex.interrupt(t0 + Duration::from_millis(100), Duration::from_secs(2));
        assert!(
            fx.iter().any(|e| matches!(e, Effect::Log(l) if l.contains("ping1"))),
            "{fx:?}"
        );
        assert!(
            !ex.stopped(t0 + Duration::from_secs(1)),
            "the step in flight is awaited"
        );
        assert!(ex.stopped(t0 + Duration::from_millis(2200)), "for a bounded time");
        // Its completion still counts; the next step is never sent.
        ex.on_update(t0 + Duration::from_millis(500), verification(&tc0, 0, 7));
        assert!(ex.stopped(t0 + Duration::from_millis(600)));
        assert!(sends(&ex.on_tick(t0 + Duration::from_secs(1))).is_empty());
        assert_eq!(ex.state[1], StepState::Waiting);
    }

    // verifies: OPS-RUN-03
    #[test]
    fn an_adopted_step_ends_by_its_reports_or_is_requeued() {
        let pl = plan(TWO_STEPS);
        let opts = RunOptions {
            display: false,
            ping_period: None,
            ..RunOptions::default()
        };
        let t0 = Instant::now();
        let mut ex = Executor::new(&pl, &opts, &[], t0);
        let tc0 = pus::build_tc(1, 10, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
        ex.adopt(0, tc0.clone(), "outcome asked of the store", t0);
        assert!(
            sends(&ex.on_tick(t0)).is_empty(),
            "nothing sent while its outcome is unknown"
        );
        ex.on_update(t0, verification(&tc0, 0, 7));
        assert!(matches!(ex.state[0], StepState::Done { .. }));
        assert_eq!(sends(&ex.on_tick(t0)), vec![1]);
        let mut ex = Executor::new(&pl, &opts, &[], t0);
        ex.adopt(0, tc0, "outcome asked of the store", t0);
        ex.requeue(0);
        assert_eq!(sends(&ex.on_tick(t0)), vec![0], "never arrived: sent as a new TC");
    }

    // verifies: GND-06
    #[test]
    fn executor_failure_report_fails_the_step_and_blocks_dependents() {
        let pl = plan(TWO_STEPS);
        let opts = RunOptions {
            display: false,
            ping_period: None,
            ..RunOptions::default()
        };
        let t0 = Instant::now();
        let mut ex = Executor::new(&pl, &opts, &[], t0);
        ex.on_tick(t0);
        let tc0 = pus::build_tc(1, 10, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
        ex.on_sent(0, Ok(tc0.clone()), t0);
        ex.on_update(t0, verification(&tc0, 0, 4));
        assert!(matches!(&ex.state[0], StepState::Failed(w) if w.contains("NOT_ALLOWED_IN_MODE")));
        assert!(matches!(&ex.state[1], StepState::Blocked(_)));
        assert!(ex.finished());
    }

    /// A fake OBSW that answers every copy of a TC like the real one's duplicate window:
    /// the first `corrupt` copies get TM[1,2] CRC_MISMATCH (damaged on the way), the
    /// next `lose` copies are lost on the way, then TM[1,1] + TM[1,7].
    fn lossy_obsw(corrupt: usize, lose: usize) -> (SocketAddr, std::thread::JoinHandle<Vec<Vec<u8>>>) {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let addr = s.local_addr().unwrap();
        let h = std::thread::spawn(move || {
            let mut copies = Vec::new();
            let mut buf = [0u8; 2048];
            let t = CdsShort::now().to_bytes();
            let mut seq = 0;
            while let Ok((n, from)) = s.recv_from(&mut buf) {
                copies.push(buf[..n].to_vec());
                let k = copies.len();
                let rid = [buf[0], buf[1], buf[2], buf[3]];
                let mut out = Vec::new();
                if k <= corrupt {
                    let mut d = rid.to_vec();
                    d.extend_from_slice(&mib::failure::FailureCode::CRC_MISMATCH.code().to_be_bytes());
                    d.extend_from_slice(&[0, 1, 0, 2]);
                    out.push((1, 2, d));
                } else if k > corrupt + lose {
                    out.push((1, 1, rid.to_vec()));
                    out.push((1, 7, rid.to_vec()));
                }
                for (sv, sub, d) in out {
                    seq += 1;
                    s.send_to(&build_tm(0x101, seq, sv, sub, 0, &t, &d), from).unwrap();
                }
                if k > corrupt + lose {
                    break;
                }
            }
            copies
        });
        (addr, h)
    }

    // verifies: GND-01
    #[test]
    fn a_tc_is_resent_identically_until_its_acceptance_and_a_damaged_copy_is_no_verdict() {
        let (addr, fake) = lossy_obsw(1, 2);
        let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(200)).unwrap();
        s.ack_timeout = Duration::from_millis(60);
        let tc = s
            .send(1, mib::tc::by_name("PING").unwrap(), &[], Some(3), None)
            .unwrap();
        let mut stages = Vec::new();
        let mut damaged = 0;
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(5) && !stages.contains(&Stage::Completion) {
            for u in s.poll(Duration::from_millis(20)) {
                match u {
                    Update::Verification { tag: Some(3), v, .. } => {
                        assert!(v.success, "a damaged copy's TM[1,2] is not the TC's verdict");
                        stages.push(v.stage);
                    }
                    Update::DamagedCopy { tag: Some(3), .. } => damaged += 1,
                    Update::GaveUp { .. } => panic!("gave up"),
                    _ => {}
                }
            }
        }
        assert_eq!(damaged, 1);
        assert_eq!(stages.last(), Some(&Stage::Completion));
        assert!(!s.busy(1));
        let copies = fake.join().unwrap();
        assert_eq!(copies.len(), 4, "1 damaged + 2 lost + 1 accepted and complete");
        assert!(
            copies.iter().all(|c| *c == tc.bytes),
            "every copy identical (same seq, same bytes)"
        );
    }

    // verifies: OPS-LINK-01
    #[test]
    fn an_accepted_tc_is_not_resent_while_its_completion_is_awaited() {
        // A fake that accepts at once and completes after 800 ms: with a first wait of
        // 60 ms the old rule resent it ("no outcome yet") about eight times.
        let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        sock.set_read_timeout(Some(Duration::from_millis(1500))).unwrap();
        let addr = sock.local_addr().unwrap();
        let fake = std::thread::spawn(move || {
            let t = CdsShort::now().to_bytes();
            let mut buf = [0u8; 2048];
            let mut copies = 0;
            let mut from = None;
            let t0 = Instant::now();
            while t0.elapsed() < Duration::from_millis(1500) {
                let Ok((n, f)) = sock.recv_from(&mut buf) else { break };
                copies += 1;
                let rid = [buf[0], buf[1], buf[2], buf[3]];
                if from.is_none() {
                    from = Some((f, rid));
                    sock.send_to(&build_tm(0x101, 1, 1, 1, 0, &t, &rid), f).unwrap();
                    sock.set_read_timeout(Some(Duration::from_millis(800))).unwrap();
                }
                let _ = n;
            }
            if let Some((f, rid)) = from {
                sock.send_to(&build_tm(0x101, 2, 1, 7, 0, &t, &rid), f).unwrap();
            }
            copies
        });
        let mut s = Session::connect(&[(1, addr)], Transport::Udp, None, |_| Some(300)).unwrap();
        s.ack_timeout = Duration::from_millis(60);
        s.send(1, mib::tc::by_name("PING").unwrap(), &[], Some(1), None)
            .unwrap();
        let (mut done, mut resent) = (false, 0);
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(4) && !done {
            for u in s.poll(Duration::from_millis(20)) {
                match u {
                    Update::Verification { tag: Some(1), v, .. } => done |= v.stage == Stage::Completion,
                    Update::Resent { .. } => resent += 1,
                    _ => {}
                }
            }
        }
        assert!(done, "completion awaited and received");
        assert_eq!(resent, 0);
        assert_eq!(fake.join().unwrap(), 1, "one copy on the wire");
        assert_eq!(s.robots[&1].link_quality(), Some(1.0));
    }

    // verifies: GND-01, DD-ROBUST-02
    #[test]
    fn the_retry_span_fits_in_the_obsw_duplicate_window() {
        let total: u32 = (0..=TC_RETRY_MAX).map(tc_retry_wait_ms).sum();
        assert_eq!(total, mib::config::TC_RETRY_SPAN_MS);
        const { assert!(mib::config::TC_RETRY_SPAN_MS <= mib::config::DUPLICATE_MAX_AGE_MS) };
        assert!(tc_retry_wait_ms(1) > tc_retry_wait_ms(0), "backoff");
        assert_eq!(tc_retry_wait_ms(100), mib::config::TC_RETRY_CAP_MS);
    }

    // verifies: MMIC-VAL-02
    #[test]
    fn link_quality_is_over_the_last_window_of_exchanges() {
        let mut r = RobotStatus::new(1, "127.0.0.1:1".parse().unwrap());
        assert_eq!(r.link_quality(), None);
        for i in 0..(LINK_QUALITY_WINDOW + 50) {
            r.exchange(i >= 50 + LINK_QUALITY_WINDOW / 2);
        }
        assert_eq!(r.quality.len(), LINK_QUALITY_WINDOW);
        assert_eq!(r.link_quality(), Some(0.5));
    }
}
