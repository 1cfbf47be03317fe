//! Plan execution as a pure state machine ([`Executor`]), tested on a mock clock.

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

use mib::events::eid;
use mib::ground_config::{GROUND_HEARTBEAT_MS, TC_RETRY_INITIAL_MS};
use mib::tc::TcDef;

use crate::plan::{Action, Plan};
use crate::pus::{BuiltTc, Stage};

use super::*;

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
    pub fn terminal(&self) -> bool {
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
    /// The robots were started (booted) for this run (`ground demo`): their TM is
    /// accounted from their first packet after boot, and what went out before the ground
    /// listened is fetched from the on-board store, instead of from the start marker.
    pub tm_from_boot: bool,
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
            tm_from_boot: false,
        }
    }
}

/// Why a step's TC was not sent ([`Executor::on_sent`]): by the CLI's [`Session`] or by
/// the thread of the collector that follows the robot.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SendError {
    /// The session's (no link, arguments, I/O).
    #[error(transparent)]
    Session(#[from] super::OpsError),
    /// The TC cannot be built from these arguments.
    #[error(transparent)]
    Build(#[from] crate::pus::BuildError),
    /// The robot's link is not open (reconnecting).
    #[error("robot {0}: no link (reconnecting)")]
    NoLink(u8),
    /// The link refused the bytes.
    #[error("sending to robot {robot}: {error}")]
    Io { robot: u8, error: std::io::Error },
    /// No page to show the TC in (a collector without `--http`).
    #[error("no dashboard")]
    NoPage,
    /// The collector running the plan does not follow this robot.
    #[error("robot {0} is not followed by this collector")]
    NotFollowed(u8),
    /// The collector's thread of this robot has stopped.
    #[error("robot {0}: the collector's thread has stopped")]
    WorkerStopped(u8),
    /// The collector's thread of this robot did not take the TC in time.
    #[error("robot {0}: the collector did not take the TC")]
    NotTaken(u8),
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
    pub(crate) plan: &'p Plan,
    opts: RunOptions,
    pub state: Vec<StepState>,
    sends: HashMap<usize, u32>,
    bolts: BoltStats,
    unbolted: u32,
    faults: Vec<String>,
    pub(crate) lost: Vec<String>,
    pub(crate) resumed: usize,
    start: Instant,
    last_heartbeat: HashMap<u8, Instant>,
    /// Interrupted: no new step starts; the steps in flight are awaited until then.
    halted: Option<Instant>,
    /// Steps the robots run from their on-board plan: their TCs (never sent by the
    /// ground), tracked from the moment the step may start as if the ground had sent it.
    on_board: HashMap<usize, BuiltTc>,
    /// When each on-board step was accepted, by the robot's clock (Unix ms): its duration
    /// in the summary is the robot's, whenever its reports reach the ground.
    board_start: HashMap<usize, i64>,
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
            on_board: HashMap::new(),
            board_start: HashMap::new(),
        }
    }

    /// Step `step` runs on board with TC `tc` (in the robot's plan): the executor never
    /// sends it; it runs from when its dependencies completed (or from its first report,
    /// should that come earlier: the robot saw them complete first).
    pub fn run_on_board(&mut self, step: usize, tc: BuiltTc) {
        self.on_board.insert(step, tc);
    }

    fn start_on_board(&mut self, i: usize, now: Instant, fx: &mut Vec<Effect>) {
        let (Some(tc), Some(s)) = (self.on_board.get(&i), self.plan.steps.get(i)) else {
            return;
        };
        fx.push(Effect::Log(format!(
            "  on board {} robot {}: {} (seq {})",
            s.id,
            s.robot,
            s.action.describe(),
            tc.seq
        )));
        self.state[i] = StepState::Running {
            tc: Some(tc.clone()),
            since: now,
            stage: "on board",
            progress: 0,
        };
        self.sends.insert(i, 1);
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
            if self.on_board.contains_key(&i) {
                self.start_on_board(i, now, &mut fx);
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
    pub fn on_sent(&mut self, step: usize, sent: Result<BuiltTc, SendError>, now: Instant) -> Vec<Effect> {
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
                tag: Some(i),
                v,
                after,
                at_ms,
                ..
            } if i < n => {
                // On board a step starts when the robot accepts its TC; the start report has
                // the same time and is the one heard when the acceptance was lost (else the
                // step's time came out 0.0 s: from the completion to itself).
                let starts = matches!(v.stage, Stage::Acceptance | Stage::Start);
                if let Some(at) = at_ms.filter(|_| self.on_board.contains_key(&i) && starts) {
                    let t = self.board_start.entry(i).or_insert(at);
                    *t = (*t).min(at);
                }
                if self.state[i] == StepState::Waiting && self.halted.is_none() {
                    self.start_on_board(i, now, &mut fx);
                }
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
                        // (A step on board is accepted when the robot starts it, not when sent.)
                        let late = after.filter(|a| a.as_millis() > TC_RETRY_INITIAL_MS as u128);
                        if let Some(a) = late.filter(|_| !self.on_board.contains_key(&i)) {
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
                        let on_board = at_ms
                            .zip(self.board_start.get(&i))
                            .map(|(end, start)| (end - start) as f64 / 1000.0);
                        let secs = on_board.unwrap_or_else(|| now.saturating_duration_since(*since).as_secs_f64());
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
    pub(crate) fn robot_line(&self, r: u8) -> String {
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
                frames: session.frame_stats(r.robot),
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
