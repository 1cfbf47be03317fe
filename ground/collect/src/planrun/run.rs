//! One run's thread: the executor driven by the robots' reports, its TCs handed to the
//! robots' threads, and every change published to the hub.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};

use crate::dash::DashCmd;
use crate::link::LinkKind;
use crate::ops::book::{Due, Pending, TcBook, Verdict};
use crate::ops::{Effect, Executor, RunOptions, SendError, StepState, Update};
use crate::plan::Plan;
use crate::pus::{BuiltTc, TmBody};
use ground_dashboard::{request_id, Hub, PlanRun};

use super::PlanInput;

/// How long a run waits for a robot's thread to take a TC.
const SEND_TIMEOUT: Duration = Duration::from_secs(2);
/// The run's thread wakes at least this often (timeouts, resends).
const POLL: Duration = Duration::from_millis(50);

/// The page's view of a run: each step's state from the executor.
pub fn view(run: &mut PlanRun, exec: &Executor) {
    for (s, st) in run.steps.iter_mut().zip(&exec.state) {
        let (state, detail) = match st {
            StepState::Waiting => ("waiting", String::new()),
            StepState::Running { stage, progress, .. } if *progress > 0 => ("running", format!("{stage} {progress}")),
            StepState::Running { stage, .. } => ("running", stage.to_string()),
            StepState::Done { secs } => ("done", format!("completed in {secs:.1} s")),
            StepState::Failed(w) => ("failed", w.clone()),
            StepState::Blocked(w) => ("blocked", w.clone()),
        };
        s.state = state.into();
        s.detail = detail;
    }
}

/// How a finished run ended: `(state, detail)` for [`PlanRun`]. A lost link wins over
/// the failures it caused; otherwise the first failed step (its failure name is in its
/// reason), then the first blocked one.
pub fn outcome(run: &PlanRun, lost: Option<&str>) -> (String, String) {
    if let Some(why) = lost {
        return ("lost".into(), format!("link lost: {why}"));
    }
    for want in ["failed", "blocked"] {
        if let Some(s) = run.steps.iter().find(|s| s.state == want) {
            return ("failed".into(), format!("step {} {want}: {}", s.id, s.detail));
        }
    }
    ("done".into(), String::new())
}

/// One run: the executor, its TCs in flight, the robots' threads and the hub.
pub(super) struct Run {
    pub(super) plan: Plan,
    pub(super) run: PlanRun,
    pub(super) hub: Hub,
    pub(super) robots: BTreeMap<u8, Sender<DashCmd>>,
    pub(super) input: Receiver<PlanInput>,
    /// The run's TCs awaited: the one set of commanding rules (`ops::book`), as in
    /// `ground run`.
    pub(super) book: TcBook,
    /// The kind of each robot's link (lab link: packet resends; frames: what COP-1
    /// delivered), learned as TCs go out.
    pub(super) links: BTreeMap<u8, LinkKind>,
    pub(super) lost: Option<String>,
}

impl Run {
    pub(super) fn execute(mut self) -> PlanRun {
        let plan = self.plan.clone();
        let opts = RunOptions {
            // The collector's threads renew the lease and watch the links.
            ping_period: None,
            display: false,
            ..RunOptions::default()
        };
        let mut exec = Executor::new(&plan, &opts, &[], Instant::now());
        self.hub.plan(self.run.clone());
        loop {
            let fx = exec.on_tick(Instant::now());
            self.apply(&mut exec, fx);
            for u in self.tick(Instant::now()) {
                let fx = exec.on_update(Instant::now(), u);
                self.apply(&mut exec, fx);
            }
            self.publish(&exec);
            if exec.finished() {
                break;
            }
            let first = match self.input.recv_timeout(POLL) {
                Ok(m) => Some(m),
                Err(RecvTimeoutError::Timeout) => None,
                Err(RecvTimeoutError::Disconnected) => {
                    // The collector is stopping: its threads are gone.
                    for r in plan.robots.iter().map(|r| r.number) {
                        let why = format!("robot {r}: the collector stopped");
                        let fx = exec.on_update(Instant::now(), Update::LinkLost { robot: r, why });
                        self.apply(&mut exec, fx);
                    }
                    self.lost.get_or_insert("the collector stopped".into());
                    continue;
                }
            };
            for m in first
                .into_iter()
                .chain(self.input.try_iter().take(512).collect::<Vec<_>>())
            {
                self.input(&mut exec, m);
            }
        }
        view(&mut self.run, &exec);
        let (state, detail) = outcome(&self.run, self.lost.as_deref());
        self.run.state = state;
        self.run.detail = detail;
        self.hub.plan(self.run.clone());
        tracing::info!("plan run {}: {} {}", self.run.run_id, self.run.state, self.run.detail);
        self.run
    }

    fn input(&mut self, exec: &mut Executor, m: PlanInput) {
        let now = Instant::now();
        let update = match m {
            PlanInput::LinkLost { robot, why } => {
                if !self.plan.robots.iter().any(|r| r.number == robot) {
                    return;
                }
                self.lost.get_or_insert(why.clone());
                Some(Update::LinkLost { robot, why })
            }
            PlanInput::Tm { robot, tm } => match tm.body {
                TmBody::Verification(v) => {
                    let lab = self.links.get(&robot).is_some_and(LinkKind::resends_packets);
                    match self.book.on_verification(robot, &v, now, lab) {
                        // Not a plan TC (the page's own, the collector's subscriptions).
                        Verdict::Unknown => None,
                        Verdict::DamagedCopy { robot, tag, tc, resend } => {
                            if let Some(bytes) = resend {
                                self.resend(robot, bytes);
                            }
                            Some(Update::DamagedCopy { robot, tag, tc })
                        }
                        Verdict::Report { tag, tc, after, .. } => Some(Update::Verification {
                            robot,
                            tag,
                            tc: Some(tc),
                            v,
                            after: Some(after),
                            at_ms: Some(tm.time.unix_ms()),
                        }),
                    }
                }
                TmBody::Event(event) => Some(Update::Event { robot, event }),
                _ => None,
            },
        };
        if let Some(u) = update {
            let fx = exec.on_update(now, u);
            self.apply(exec, fx);
        }
    }

    /// The waits that ended: resends (lab links), TCs given up.
    pub(super) fn tick(&mut self, now: Instant) -> Vec<Update> {
        let links = &self.links;
        let due = self
            .book
            .on_tick(now, |r| links.get(&r).is_some_and(LinkKind::resends_packets));
        let mut out = Vec::new();
        for d in due {
            out.extend(Update::of_due(&d, |r, apid, seq| {
                links.get(&r).is_some_and(|k| k.delivered(apid, seq))
            }));
            if let Due::Resend { robot, tc, .. } = d {
                self.resend(robot, tc.bytes);
            }
        }
        out
    }

    fn resend(&self, robot: u8, bytes: Vec<u8>) {
        if let Some(tx) = self.robots.get(&robot) {
            // A resend that cannot be handed over is a lost packet: the next one
            // follows on the schedule.
            let _ = tx.try_send(DashCmd::Resend { bytes });
        }
    }

    fn apply(&mut self, exec: &mut Executor, fx: Vec<Effect>) {
        let mut queue: std::collections::VecDeque<Effect> = fx.into();
        while let Some(e) = queue.pop_front() {
            match e {
                Effect::Send { step, robot, def, args } => {
                    let sent = self.send(robot, def, args).map(|(tc, kind)| {
                        self.links.insert(robot, kind);
                        let label = Some(format!("plan {}", self.run.plan));
                        self.book
                            .insert(Pending::sent(robot, tc.clone(), Some(step), label, Instant::now()));
                        if let Some(s) = self.run.steps.get_mut(step) {
                            s.request_id = Some(request_id(robot, tc.apid, tc.seq));
                        }
                        tc
                    });
                    queue.extend(exec.on_sent(step, sent, Instant::now()));
                }
                Effect::Forget(tc) => {
                    self.book.forget(&tc);
                }
                // Not asked for (no ping period): the collector's thread renews the lease.
                Effect::Heartbeat(_) => {}
                // The collector's thread asks the on-board store for every hole itself,
                // and hands the run the replayed reports.
                Effect::Retrieve(_) => {}
                Effect::Log(line) => tracing::info!("plan run {}: {}", self.run.run_id, line.trim()),
                Effect::Finished => {}
            }
        }
    }

    fn send(&self, robot: u8, def: &'static mib::tc::TcDef, args: Vec<i64>) -> Result<(BuiltTc, LinkKind), SendError> {
        let tx = self.robots.get(&robot).ok_or(SendError::NotFollowed(robot))?;
        let (reply, answer) = crossbeam_channel::bounded(1);
        tx.send(DashCmd::PlanTc {
            def,
            args,
            origin: format!("plan {}", self.run.plan),
            reply,
        })
        .map_err(|_| SendError::WorkerStopped(robot))?;
        answer
            .recv_timeout(SEND_TIMEOUT)
            .map_err(|_| SendError::NotTaken(robot))?
    }

    fn publish(&mut self, exec: &Executor) {
        let before = self.run.clone();
        view(&mut self.run, exec);
        if self.run != before {
            self.hub.plan(self.run.clone());
        }
    }
}
