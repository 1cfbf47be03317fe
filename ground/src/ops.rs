//! Live operations: a [`Session`] holds the links to several robots, sends TCs with
//! per-APID sequence counts, tracks PUS 1 verification per TC, resends a TC that was
//! not accepted in time (same sequence count, so the OBSW suppresses the duplicate),
//! archives everything and keeps each robot's status (mode, state, battery, link
//! quality). [`run_plan`] executes a plan on top of it.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use crossbeam_channel::Receiver;
use mib::config::{GROUND_ACK_TIMEOUT_MS, GROUND_MAX_RESENDS, GROUND_PING_PERIOD_MS, LINK_QUALITY_WINDOW};
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
}

/// Links to several robots with verification tracking.
pub struct Session {
    links: BTreeMap<u8, Link>,
    rx: Receiver<Incoming>,
    seq: SeqCounters,
    pending: HashMap<(u16, u16), Pending>,
    archive: Option<ArchiveSender>,
    pub robots: BTreeMap<u8, RobotStatus>,
    pub ack_timeout: Duration,
    pub max_resends: u32,
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
            ack_timeout: Duration::from_millis(GROUND_ACK_TIMEOUT_MS as u64),
            max_resends: GROUND_MAX_RESENDS,
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
        let link = self.links.get(&robot).ok_or(OpsError::NoLink(robot))?;
        let apid = mib::apid::robot_apid(robot).ok_or(pus::BuildError::UnknownRobot(robot))?;
        // Check the arguments before using up a sequence count.
        pus::build_tc(robot, 0, def, args)?;
        let tc = pus::build_tc(robot, self.seq.next(apid), def, args)?;
        link.send(&tc.bytes).map_err(|err| OpsError::Send { robot, err })?;
        if let Some(a) = &self.archive {
            a.send(Record::Tc {
                t_ms: now_ms(),
                tc: tc.clone(),
                step: label.clone(),
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
            },
        );
        Ok(tc)
    }

    /// True if a TC of `robot` is still waiting for acceptance or completion.
    pub fn busy(&self, robot: u8) -> bool {
        self.pending.values().any(|p| p.robot == robot)
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
                .filter(|p| !p.accepted)
                .map(|p| p.last_sent + self.ack_timeout)
                .min();
            let until = next_resend.map_or(deadline, |r| r.min(deadline));
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
            if !out.is_empty() || Instant::now() >= deadline {
                return out;
            }
        }
    }

    fn check_resends(&mut self, out: &mut Vec<Update>) {
        let now = Instant::now();
        let mut gave_up = Vec::new();
        for (key, p) in self.pending.iter_mut() {
            if p.accepted || now < p.last_sent + self.ack_timeout {
                continue;
            }
            if let Some(r) = self.robots.get_mut(&p.robot) {
                r.exchange(false);
            }
            if p.sends > self.max_resends {
                gave_up.push(*key);
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
                    step: p.label.clone(),
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
                });
            }
        }
    }

    fn handle(&mut self, inc: Incoming, out: &mut Vec<Update>) {
        let decoded = pus::decode_tm(&inc.bytes);
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
            s.last_tm = Some(Instant::now());
            if tm.robot != Some(robot) && tm.apid != mib::apid::IDLE_APID {
                s.foreign += 1;
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
    /// Connection test (TC[17,1]) period per idle robot; `None` for no pings.
    pub ping_period: Option<Duration>,
    /// Show the indicatif progress display (else plain log lines).
    pub display: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            step_timeout: Duration::from_secs(120),
            ping_period: Some(Duration::from_millis(GROUND_PING_PERIOD_MS as u64)),
            display: true,
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
    pub resends: u32,
}

#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub plan: String,
    pub steps: Vec<StepOutcome>,
    pub done: usize,
    pub failed: usize,
    pub blocked: usize,
    pub bolts: BoltStats,
    pub unbolted_pairs: u32,
    pub faults: Vec<String>,
    pub links: Vec<LinkSummary>,
    pub seconds: f64,
}

impl RunSummary {
    pub fn success(&self) -> bool {
        self.failed == 0 && self.blocked == 0
    }
    /// Human-readable summary.
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
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
        for l in &self.links {
            let _ = writeln!(
                s,
                "link robot {}: quality {} over {} exchanges, {} TM, {} corrupt, {} resends",
                l.robot,
                l.quality.map_or("-".into(), |q| format!("{:.0}%", q * 100.0)),
                l.exchanges,
                l.tm,
                l.corrupt,
                l.resends
            );
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
            eprintln!("{line}");
        }
    }
}

/// Executes a plan: each step is sent once every step it depends on has completed.
pub fn run_plan(plan: &Plan, session: &mut Session, opts: &RunOptions) -> RunSummary {
    let start = Instant::now();
    let n = plan.steps.len();
    let mut state: Vec<StepState> = vec![StepState::Waiting; n];
    let mut sends: HashMap<usize, u32> = HashMap::new();
    let mut bolts = BoltStats::default();
    let mut unbolted = 0u32;
    let mut faults: Vec<String> = Vec::new();
    let mut last_ping: HashMap<u8, Instant> = HashMap::new();
    let mut ping_tc: HashMap<u8, BuiltTc> = HashMap::new();
    let robots: Vec<u8> = plan.robots.iter().map(|r| r.number).collect();
    let disp = Display::new(plan, &robots, opts.display);
    let ping = mib::tc::by_name("PING");

    let block_dependents = |state: &mut Vec<StepState>, i: usize, why: &str, disp: &Display| {
        for d in plan.dependents(i) {
            if state[d] == StepState::Waiting {
                state[d] = StepState::Blocked(format!("waits for \"{}\", which {why}", plan.steps[i].id));
                disp.log(format!(
                    "  blocked  {} (waits for {})",
                    plan.steps[d].id, plan.steps[i].id
                ));
            }
        }
    };

    loop {
        // Start every step whose dependencies have completed.
        for i in 0..n {
            if state[i] != StepState::Waiting {
                continue;
            }
            let s = &plan.steps[i];
            if !s.deps.iter().all(|&d| matches!(state[d], StepState::Done { .. })) {
                continue;
            }
            match s.action.tc() {
                None => {
                    state[i] = StepState::Running {
                        tc: None,
                        since: Instant::now(),
                        stage: "waiting",
                        progress: 0,
                    };
                    disp.log(format!(
                        "  start    {} robot {}: {}",
                        s.id,
                        s.robot,
                        s.action.describe()
                    ));
                }
                Some((def, args)) => {
                    // Drop a connection test still in flight so it does not hold the robot.
                    if let Some(p) = ping_tc.remove(&s.robot) {
                        session.forget(&p);
                    }
                    match session.send(s.robot, def, &args, Some(i), Some(s.id.clone())) {
                        Ok(tc) => {
                            sends.insert(i, 1);
                            disp.log(format!(
                                "  send     {} robot {}: {} (seq {})",
                                s.id,
                                s.robot,
                                s.action.describe(),
                                tc.seq
                            ));
                            state[i] = StepState::Running {
                                tc: Some(tc),
                                since: Instant::now(),
                                stage: "sent",
                                progress: 0,
                            };
                        }
                        Err(e) => {
                            let why = format!("could not be sent: {e}");
                            disp.log(format!("  FAILED   {} {why}", s.id));
                            state[i] = StepState::Failed(why.clone());
                            block_dependents(&mut state, i, "failed", &disp);
                        }
                    }
                }
            }
        }
        if state.iter().all(StepState::terminal) {
            break;
        }

        let updates = session.poll(Duration::from_millis(50));
        for u in updates {
            match u {
                Update::Verification {
                    tag: Some(i), v, after, ..
                } if i < n => {
                    let s = &plan.steps[i];
                    let StepState::Running {
                        since, stage, progress, ..
                    } = &mut state[i]
                    else {
                        continue;
                    };
                    if !v.success {
                        let why = failure_words(&v);
                        disp.log(format!("  FAILED   {} robot {}: {why}", s.id, s.robot));
                        state[i] = StepState::Failed(why);
                        block_dependents(&mut state, i, "failed", &disp);
                        continue;
                    }
                    match v.stage {
                        Stage::Acceptance => {
                            *stage = "accepted";
                            if let Some(a) = after {
                                if a > session.ack_timeout {
                                    disp.log(format!("  accepted {} after {:.2} s", s.id, a.as_secs_f64()));
                                }
                            }
                        }
                        Stage::Start => *stage = "started",
                        Stage::Progress => {
                            *stage = "progress";
                            *progress = v.step.unwrap_or(*progress + 1);
                        }
                        Stage::Completion => {
                            let secs = since.elapsed().as_secs_f64();
                            disp.log(format!("  done     {} robot {} in {secs:.1} s", s.id, s.robot));
                            state[i] = StepState::Done { secs };
                            disp.total.inc(1);
                        }
                    }
                }
                Update::Verification {
                    robot, tag: None, v, ..
                } => {
                    if let Some(p) = ping_tc.get(&robot) {
                        if v.request.seq() == p.seq && (v.stage == Stage::Completion || !v.success) {
                            ping_tc.remove(&robot);
                        }
                    }
                }
                Update::Resent {
                    robot,
                    tag: Some(i),
                    tc,
                    send,
                } if i < n => {
                    sends.insert(i, send);
                    disp.log(format!(
                        "  resend   {} robot {robot}: {tc} not accepted within {} ms (send {send})",
                        plan.steps[i].id,
                        session.ack_timeout.as_millis()
                    ));
                }
                Update::GaveUp {
                    robot,
                    tag,
                    tc,
                    sends: k,
                } => {
                    if let Some(i) = tag.filter(|&i| i < n) {
                        let why = format!(
                            "no acceptance of {tc} from robot {robot} after {k} sends (link down or OBSW not running)"
                        );
                        disp.log(format!("  FAILED   {}: {why}", plan.steps[i].id));
                        state[i] = StepState::Failed(why);
                        block_dependents(&mut state, i, "failed", &disp);
                    } else {
                        ping_tc.remove(&robot);
                    }
                }
                Update::Event { robot, event } => {
                    match event.id {
                        eid::BOLT_PAIR_DONE => match event.param("attempts") {
                            Some(1) => bolts.first += 1,
                            Some(2) => bolts.second += 1,
                            Some(3) => bolts.third += 1,
                            _ => bolts.later += 1,
                        },
                        eid::BOLT_FAILURE => bolts.failed += 1,
                        eid::UNBOLT_PAIR_DONE => unbolted += 1,
                        _ => {}
                    }
                    if event.fault {
                        let line = format!("robot {robot}: {event}");
                        disp.log(format!("  FAULT    {line}"));
                        faults.push(line);
                        // Steps of this robot not yet sent, and everything after them,
                        // stop; the running one finishes per its verification.
                        for i in 0..n {
                            if plan.steps[i].robot == robot && state[i] == StepState::Waiting {
                                state[i] = StepState::Blocked(format!(
                                    "robot {robot} reported fault {}: {}",
                                    event.name, event.description
                                ));
                                block_dependents(&mut state, i, "was stopped by a fault", &disp);
                            }
                        }
                    } else if matches!(event.severity, "medium" | "high") {
                        disp.log(format!("  event    robot {robot}: {event}"));
                    }
                }
                Update::Corrupt { robot, error } => {
                    disp.log(format!("  corrupt  TM from robot {robot}: {error}"));
                }
                Update::Foreign {
                    robot,
                    apid,
                    service,
                    subservice,
                } => {
                    disp.log(format!(
                        "  skipped  TM[{service},{subservice}] of APID 0x{apid:03X} on robot {robot}'s link"
                    ));
                }
                _ => {}
            }
        }

        // Wait steps and step timeouts.
        for i in 0..n {
            if let StepState::Running { tc, since, .. } = &state[i] {
                let s = &plan.steps[i];
                let limit = s.timeout_s.map_or(opts.step_timeout, Duration::from_secs_f64);
                match (&s.action, tc) {
                    (Action::Wait { seconds }, None) if since.elapsed().as_secs_f64() >= *seconds => {
                        let secs = since.elapsed().as_secs_f64();
                        disp.log(format!("  done     {} (waited {secs:.1} s)", s.id));
                        state[i] = StepState::Done { secs };
                        disp.total.inc(1);
                    }
                    (_, Some(tc)) if since.elapsed() > limit => {
                        let tc = tc.clone();
                        session.forget(&tc);
                        let why = format!("no completion of {} within {:.0} s", tc.def.name, limit.as_secs_f64());
                        disp.log(format!("  FAILED   {}: {why}", s.id));
                        state[i] = StepState::Failed(why);
                        block_dependents(&mut state, i, "failed", &disp);
                    }
                    _ => {}
                }
            }
        }

        // Connection tests for idle robots.
        if let (Some(period), Some(ping)) = (opts.ping_period, ping) {
            for &r in &robots {
                let idle = !session.busy(r);
                let due = last_ping.get(&r).is_none_or(|t| t.elapsed() >= period);
                if idle && due {
                    last_ping.insert(r, Instant::now());
                    if let Ok(tc) = session.send(r, ping, &[], None, Some("ping".into())) {
                        ping_tc.insert(r, tc);
                    }
                }
            }
        }

        // Display.
        for (&r, bar) in &disp.robots {
            let cur = (0..n).find(|&i| plan.steps[i].robot == r && matches!(state[i], StepState::Running { .. }));
            let done = (0..n)
                .filter(|&i| plan.steps[i].robot == r && state[i].terminal())
                .count();
            let total = (0..n).filter(|&i| plan.steps[i].robot == r).count();
            let step = match cur {
                Some(i) => match &state[i] {
                    StepState::Running { stage, progress, .. } if *progress > 0 => {
                        format!("{} {stage} {progress}", plan.steps[i].id)
                    }
                    StepState::Running { stage, .. } => format!("{} {stage}", plan.steps[i].id),
                    _ => String::new(),
                },
                None => "idle".into(),
            };
            let st = session.robots.get(&r).map(|s| s.line()).unwrap_or_default();
            bar.set_message(format!("{done}/{total} | {step} | {st}"));
            bar.tick();
        }
    }
    disp.total.finish();
    for b in disp.robots.values() {
        b.finish();
    }
    let _ = disp.mp.clear();

    let steps: Vec<StepOutcome> = plan
        .steps
        .iter()
        .zip(&state)
        .map(|(s, st)| {
            let (result, reason, seconds) = match st {
                StepState::Done { secs } => ("done", None, Some(*secs)),
                StepState::Failed(w) => ("FAILED", Some(w.clone()), None),
                StepState::Blocked(w) => ("blocked", Some(w.clone()), None),
                _ => ("?", None, None),
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
            resends: plan
                .steps
                .iter()
                .enumerate()
                .filter(|(_, s)| s.robot == r.robot)
                .map(|(i, _)| sends.get(&i).copied().unwrap_or(1).saturating_sub(1))
                .sum(),
        })
        .collect();
    RunSummary {
        plan: plan.name.clone(),
        done: state.iter().filter(|s| matches!(s, StepState::Done { .. })).count(),
        failed: state.iter().filter(|s| matches!(s, StepState::Failed(_))).count(),
        blocked: state.iter().filter(|s| matches!(s, StepState::Blocked(_))).count(),
        steps,
        bolts,
        unbolted_pairs: unbolted,
        faults,
        links,
        seconds: start.elapsed().as_secs_f64(),
    }
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
