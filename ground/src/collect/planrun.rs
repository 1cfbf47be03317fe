//! Plan runs started from the dashboard under `ground collect --http`.
//!
//! A run is the pure plan [`Executor`] (`ops`, the one `ground run` uses) driven by
//! a thread of its own. Each step's TC goes out through the robot's collector thread
//! ([`DashCmd::PlanTc`]): its link and its TC sequence counter, the same as the page's
//! single TCs, so a request ID is never used twice on an APID. That thread hands the
//! run every verification report and event it receives and tells it when the link is
//! lost ([`PlanInput`]). [`Resender`] resends a TC with identical bytes on the MIB's
//! retry schedule until its outcome arrives, as `ground run`'s session does; the
//! collector's thread already renews the downlink lease, watches the link and asks the
//! on-board store for every hole, so the run sends no heartbeats of its own. Every
//! change of the run is published to the hub ([`Hub::plan`]), which streams it to the
//! page.
//!
//! [`PlanBook`] is what the dashboard's commander holds: the configured plans
//! (`plans = [...]`, `config::PlanCfg`), which robots are busy, and the start checks
//! (unknown plan, robot not followed, hazardous TCs not confirmed, robot busy).

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use mib::config::{tc_retry_wait_ms, TC_RETRY_MAX};

use crate::dashboard::{request_id, Hub, PlanInfo, PlanRun, PlanStartError, PlanStep};
use crate::ops::{Effect, Executor, RunOptions, StepState, Update};
use crate::plan::Plan;
use crate::pus::{BuiltTc, Stage, Tm, TmBody, Verification};

use super::config::PlanCfg;
use super::dash::DashCmd;

/// How long a run waits for a robot's thread to take a TC.
const SEND_TIMEOUT: Duration = Duration::from_secs(2);
/// The run's thread wakes at least this often (timeouts, resends).
const POLL: Duration = Duration::from_millis(50);

/// What a robot's collector thread hands a plan run that follows it.
#[derive(Clone, Debug)]
pub enum PlanInput {
    /// A verification report or an event (live or replayed from the on-board store).
    Tm { robot: u8, tm: Tm },
    /// The collector declared the robot's link lost.
    LinkLost { robot: u8, why: String },
}

/// What [`Resender`] asks of its driver.
#[derive(Clone, Debug, PartialEq)]
pub enum Resend {
    /// Send these bytes again (the same TC, the same sequence count).
    Bytes { robot: u8, bytes: Vec<u8> },
}

struct Sent {
    robot: u8,
    step: usize,
    tc: BuiltTc,
    first: Instant,
    last: Instant,
    sends: u32,
    accepted: bool,
    /// Every send was made and the TC was accepted: its outcome is awaited from the
    /// on-board store (which the collector asks for every hole), no more resends.
    exhausted: bool,
}

/// The plan's TCs waiting for their outcome, resent with identical bytes after
/// `mib::config::tc_retry_wait_ms` until it arrives — the rules of `ops::Session`
/// (a TM[1,2] for a damaged copy resends at once; an accepted TC is not given up while
/// its step runs). Pure: time comes in as `now`.
#[derive(Default)]
pub struct Resender {
    pending: HashMap<(u16, u16), Sent>,
}

impl Resender {
    /// `tc` of `step` went out to `robot` for the first time at `now`.
    pub fn sent(&mut self, step: usize, robot: u8, tc: BuiltTc, now: Instant) {
        self.pending.insert(
            (tc.apid, tc.seq),
            Sent {
                robot,
                step,
                tc,
                first: now,
                last: now,
                sends: 1,
                accepted: false,
                exhausted: false,
            },
        );
    }

    /// Stops tracking `tc` (its step ended without it).
    pub fn forget(&mut self, tc: &BuiltTc) {
        self.pending.remove(&(tc.apid, tc.seq));
    }

    /// TCs still waiting for their outcome.
    pub fn len(&self) -> usize {
        self.pending.len()
    }

    /// True when no TC waits.
    pub fn is_empty(&self) -> bool {
        self.pending.is_empty()
    }

    /// A verification report from `robot`: the executor's update, and a resend when it
    /// is about a damaged copy.
    pub fn on_verification(&mut self, robot: u8, v: Verification, now: Instant) -> (Option<Update>, Vec<Resend>) {
        let key = (v.request.apid(), v.request.seq());
        let Some(p) = self.pending.get_mut(&key) else {
            // Not a plan TC (the page's own, the collector's subscriptions).
            return (None, Vec::new());
        };
        // The ground builds every TC from the MIB and checks it as the OBSW's acceptance
        // does, so a TM[1,2] with one of those codes is about a copy damaged on the way.
        let damaged = !v.success
            && v.stage == Stage::Acceptance
            && v.failure
                .as_ref()
                .is_some_and(|f| mib::tc::ACCEPTANCE_FAILURES.iter().any(|c| c.code() == f.code));
        if damaged {
            let mut out = Vec::new();
            if p.sends < TC_RETRY_MAX + 1 {
                out.push(Resend::Bytes {
                    robot: p.robot,
                    bytes: p.tc.bytes.clone(),
                });
                p.sends += 1;
            }
            p.last = now;
            let u = Update::DamagedCopy {
                robot,
                tag: Some(p.step),
                tc: p.tc.def.name,
            };
            return (Some(u), out);
        }
        if v.stage == Stage::Acceptance {
            p.accepted = true;
        }
        let wants_completion = p.tc.bytes.get(6).is_some_and(|b| b & 0x01 != 0);
        let finished =
            !v.success || v.stage == Stage::Completion || (!wants_completion && v.stage == Stage::Acceptance);
        let u = Update::Verification {
            robot,
            tag: Some(p.step),
            tc: Some(p.tc.def.name),
            v,
            after: Some(now.saturating_duration_since(p.first)),
        };
        if finished {
            self.pending.remove(&key);
        }
        (Some(u), Vec::new())
    }

    /// Resends that are due at `now`, and TCs given up after their last send.
    pub fn on_tick(&mut self, now: Instant) -> (Vec<Update>, Vec<Resend>) {
        let (mut updates, mut resends, mut gone) = (Vec::new(), Vec::new(), Vec::new());
        for (key, p) in self.pending.iter_mut() {
            if p.exhausted || now < p.last + Duration::from_millis(tc_retry_wait_ms(p.sends - 1) as u64) {
                continue;
            }
            if p.sends > TC_RETRY_MAX {
                if p.accepted {
                    p.exhausted = true;
                } else {
                    gone.push(*key);
                }
                updates.push(Update::GaveUp {
                    robot: p.robot,
                    tag: Some(p.step),
                    tc: p.tc.def.name,
                    sends: p.sends,
                    accepted: p.accepted,
                });
                continue;
            }
            p.sends += 1;
            p.last = now;
            resends.push(Resend::Bytes {
                robot: p.robot,
                bytes: p.tc.bytes.clone(),
            });
            updates.push(Update::Resent {
                robot: p.robot,
                tag: Some(p.step),
                tc: p.tc.def.name,
                send: p.sends,
            });
        }
        for k in gone {
            self.pending.remove(&k);
        }
        (updates, resends)
    }
}

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
struct Run {
    plan: Plan,
    run: PlanRun,
    hub: Hub,
    robots: BTreeMap<u8, Sender<DashCmd>>,
    input: Receiver<PlanInput>,
    resender: Resender,
    lost: Option<String>,
}

impl Run {
    fn execute(mut self) -> PlanRun {
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
            let (updates, resends) = self.resender.on_tick(Instant::now());
            self.resend(resends);
            for u in updates {
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
                    let (u, resends) = self.resender.on_verification(robot, v, now);
                    self.resend(resends);
                    u
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

    fn resend(&self, resends: Vec<Resend>) {
        for Resend::Bytes { robot, bytes } in resends {
            if let Some(tx) = self.robots.get(&robot) {
                // A resend that cannot be handed over is a lost packet: the next one
                // follows on the schedule.
                let _ = tx.try_send(DashCmd::Resend { bytes });
            }
        }
    }

    fn apply(&mut self, exec: &mut Executor, fx: Vec<Effect>) {
        let mut queue: std::collections::VecDeque<Effect> = fx.into();
        while let Some(e) = queue.pop_front() {
            match e {
                Effect::Send { step, robot, def, args } => {
                    let sent = self.send(robot, def, args);
                    if let Ok(tc) = &sent {
                        self.resender.sent(step, robot, tc.clone(), Instant::now());
                        if let Some(s) = self.run.steps.get_mut(step) {
                            s.request_id = Some(request_id(robot, tc.apid, tc.seq));
                        }
                    }
                    queue.extend(exec.on_sent(step, sent, Instant::now()));
                }
                Effect::Forget(tc) => self.resender.forget(&tc),
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

    fn send(&self, robot: u8, def: &'static mib::tc::TcDef, args: Vec<i64>) -> Result<BuiltTc, String> {
        let tx = self
            .robots
            .get(&robot)
            .ok_or_else(|| format!("robot {robot} is not followed by this collector"))?;
        let (reply, answer) = crossbeam_channel::bounded(1);
        tx.send(DashCmd::PlanTc {
            def,
            args,
            origin: format!("plan {}", self.run.plan),
            reply,
        })
        .map_err(|_| format!("robot {robot}: the collector's thread has stopped"))?;
        answer
            .recv_timeout(SEND_TIMEOUT)
            .map_err(|_| format!("robot {robot}: the collector did not take the TC"))?
    }

    fn publish(&mut self, exec: &Executor) {
        let before = self.run.clone();
        view(&mut self.run, exec);
        if self.run != before {
            self.hub.plan(self.run.clone());
        }
    }
}

/// The plans the collector offers and the runs it has going.
pub struct PlanBook {
    plans: Vec<PlanCfg>,
    hub: Hub,
    robots: BTreeMap<u8, Sender<DashCmd>>,
    /// Robot → run ID of the plan it is running.
    busy: Arc<Mutex<BTreeMap<u8, String>>>,
    runs: AtomicU64,
}

impl PlanBook {
    pub fn new(plans: Vec<PlanCfg>, hub: Hub, robots: BTreeMap<u8, Sender<DashCmd>>) -> PlanBook {
        PlanBook {
            plans,
            hub,
            robots,
            busy: Arc::new(Mutex::new(BTreeMap::new())),
            runs: AtomicU64::new(1),
        }
    }

    fn load(&self, cfg: &PlanCfg) -> Result<Plan, String> {
        crate::plan::load(&cfg.path).map_err(|e| format!("plan {}: {e}", cfg.path.display()))
    }

    /// The configured plans as they are on disk now (a file that no longer reads is
    /// left out and logged).
    pub fn list(&self) -> Vec<PlanInfo> {
        self.plans
            .iter()
            .filter_map(|c| match self.load(c) {
                Ok(p) => Some(PlanInfo::of(&c.name, &p)),
                Err(e) => {
                    tracing::warn!("{e}");
                    None
                }
            })
            .collect()
    }

    /// Starts plan `name`; returns its run ID.
    pub fn start(&self, name: &str, confirmed: bool) -> Result<String, PlanStartError> {
        let cfg = self.plans.iter().find(|c| c.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.plans.iter().map(|c| c.name.as_str()).collect();
            PlanStartError::Unknown(format!(
                "no plan named \"{name}\" (this collector offers: {}; list plan files with `plans = [...]` in its configuration)",
                if names.is_empty() { "none".into() } else { names.join(", ") }
            ))
        })?;
        let plan = self.load(cfg).map_err(PlanStartError::Refused)?;
        if let Some(r) = plan.robots.iter().find(|r| !self.robots.contains_key(&r.number)) {
            return Err(PlanStartError::Refused(format!(
                "plan {name} commands robot {}, which this collector does not follow",
                r.number
            )));
        }
        if let Some((r, st)) = plan
            .robots
            .iter()
            .map(|r| (r.number, self.hub.link_state(r.number)))
            .find(|(_, st)| *st != Some(crate::dashboard::LinkState::Up))
        {
            let st = match st {
                Some(crate::dashboard::LinkState::Lost) => "lost",
                Some(crate::dashboard::LinkState::Connecting) | None => "not up yet",
                Some(crate::dashboard::LinkState::Up) => "up",
            };
            return Err(PlanStartError::Refused(format!(
                "plan {name} not started: robot {r}'s link is {st}"
            )));
        }
        let info = PlanInfo::of(name, &plan);
        if !info.hazards.is_empty() && !confirmed {
            return Err(PlanStartError::NeedsConfirmation(format!(
                "plan {name} sends hazardous TCs ({}): resend with \"confirm\": true",
                info.hazards.join("; ")
            )));
        }
        let run_id = format!("{name}-{}", self.runs.fetch_add(1, Ordering::Relaxed));
        {
            let Ok(mut busy) = self.busy.lock() else {
                return Err(PlanStartError::Refused("plan bookkeeping lock poisoned".into()));
            };
            if let Some((r, other)) = info.robots.iter().find_map(|r| busy.get(r).map(|o| (r, o))) {
                return Err(PlanStartError::Busy(format!(
                    "robot {r} is running plan run {other}: one plan per robot at a time"
                )));
            }
            for r in &info.robots {
                busy.insert(*r, run_id.clone());
            }
        }
        let release = {
            let busy = self.busy.clone();
            let id = run_id.clone();
            move || {
                if let Ok(mut b) = busy.lock() {
                    b.retain(|_, v| *v != id);
                }
            }
        };
        let release = Arc::new(release);
        // The robots' threads hand the run what they receive from now on.
        let (tx, input) = crossbeam_channel::unbounded();
        let mut robots = BTreeMap::new();
        for r in &info.robots {
            if let Some(cmd) = self.robots.get(r) {
                if cmd.send(DashCmd::Follow(tx.clone())).is_err() {
                    release();
                    return Err(PlanStartError::Refused(format!(
                        "robot {r}: the collector's thread has stopped"
                    )));
                }
                robots.insert(*r, cmd.clone());
            }
        }
        drop(tx);
        let run = Run {
            run: PlanRun {
                run_id: run_id.clone(),
                plan: name.to_string(),
                state: "running".into(),
                detail: String::new(),
                started_ms: crate::archive::now_ms(),
                steps: plan
                    .steps
                    .iter()
                    .map(|s| PlanStep {
                        id: s.id.clone(),
                        robot: s.robot,
                        label: s.action.describe(),
                        state: "waiting".into(),
                        request_id: None,
                        detail: String::new(),
                    })
                    .collect(),
            },
            plan,
            hub: self.hub.clone(),
            robots,
            input,
            resender: Resender::default(),
            lost: None,
        };
        tracing::info!("plan run {run_id}: started from the dashboard");
        let done = release.clone();
        std::thread::Builder::new()
            .name(format!("plan-{run_id}"))
            .spawn(move || {
                run.execute();
                done();
            })
            .map_err(|e| {
                release();
                PlanStartError::Refused(format!("starting the plan: {e}"))
            })?;
        Ok(run_id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pus::{build_tm, CdsShort};
    use mib::failure::FailureCode;

    fn ping(seq: u16) -> BuiltTc {
        crate::pus::build_tc(1, seq, mib::tc::by_name("PING").unwrap(), &[]).unwrap()
    }

    /// A PUS 1 report (`subservice`) about `tc`, failing with `code` if even.
    fn report(tc: &BuiltTc, subservice: u8, code: FailureCode) -> Verification {
        let mut data = tc.bytes[..4].to_vec();
        if subservice == 5 || subservice == 6 {
            data.push(2); // progress step
        }
        if subservice.is_multiple_of(2) {
            data.extend_from_slice(&code.code().to_be_bytes());
            data.extend(std::iter::repeat_n(0, mib::layout::fields_len(code.data())));
        }
        let raw = build_tm(tc.apid, 9, 1, subservice, 0, &CdsShort::now().to_bytes(), &data);
        match crate::pus::decode_tm(&raw).unwrap().body {
            TmBody::Verification(v) => v,
            other => panic!("not a verification: {other:?}"),
        }
    }

    // verifies: GND-19
    #[test]
    fn resends_identical_bytes_on_the_mib_schedule_until_accepted_then_waits_for_the_outcome() {
        let t0 = Instant::now();
        let mut r = Resender::default();
        let tc = ping(42);
        r.sent(3, 1, tc.clone(), t0);
        let first = Duration::from_millis(tc_retry_wait_ms(0) as u64);
        assert_eq!(r.on_tick(t0 + first - Duration::from_millis(1)).1, vec![]);
        let (u, re) = r.on_tick(t0 + first);
        assert_eq!(
            re,
            vec![Resend::Bytes {
                robot: 1,
                bytes: tc.bytes.clone()
            }]
        );
        assert!(matches!(
            u[..],
            [Update::Resent {
                tag: Some(3),
                send: 2,
                ..
            }]
        ));
        // The next wait is the MIB's second one, counted from the resend.
        let second = Duration::from_millis(tc_retry_wait_ms(1) as u64);
        assert!(second > first);
        assert!(r.on_tick(t0 + first + second - Duration::from_millis(1)).1.is_empty());
        assert_eq!(r.on_tick(t0 + first + second).1.len(), 1);

        // Accepted: the executor gets the report with its step; completion ends it.
        let (u, re) = r.on_verification(1, report(&tc, 1, FailureCode::CRC_MISMATCH), t0 + first * 3);
        assert!(re.is_empty());
        assert!(matches!(u, Some(Update::Verification { tag: Some(3), .. })));
        assert_eq!(r.len(), 1);
        let (u, _) = r.on_verification(1, report(&tc, 7, FailureCode::CRC_MISMATCH), t0 + first * 4);
        assert!(matches!(u, Some(Update::Verification { tag: Some(3), .. })));
        assert!(r.is_empty());
        // Reports of other TCs (the page's, the collector's) are not the run's.
        assert!(r
            .on_verification(1, report(&ping(7), 1, FailureCode::CRC_MISMATCH), t0)
            .0
            .is_none());
    }

    // verifies: GND-19
    #[test]
    fn a_damaged_copy_is_resent_at_once_and_a_silent_tc_is_given_up_after_its_sends() {
        let t0 = Instant::now();
        let mut r = Resender::default();
        let tc = ping(9);
        r.sent(0, 1, tc.clone(), t0);
        let (u, re) = r.on_verification(1, report(&tc, 2, FailureCode::CRC_MISMATCH), t0);
        assert!(matches!(u, Some(Update::DamagedCopy { tag: Some(0), .. })));
        assert_eq!(re.len(), 1);
        // Never answered: every send is made, then the TC is given up (not accepted).
        let mut t = t0;
        let mut sends = 2;
        let mut gave_up = false;
        for _ in 0..100 {
            t += Duration::from_millis(mib::config::TC_RETRY_CAP_MS as u64);
            let (u, re) = r.on_tick(t);
            sends += re.len() as u32;
            if let Some(Update::GaveUp { accepted, sends: k, .. }) = u.last() {
                assert!(!accepted);
                assert_eq!(*k, TC_RETRY_MAX + 1);
                gave_up = true;
                break;
            }
        }
        assert!(gave_up);
        assert_eq!(sends, TC_RETRY_MAX + 1);
        assert!(r.is_empty());

        // A failure that is the TC's verdict ends it and reaches the executor.
        let tc = ping(10);
        r.sent(1, 1, tc.clone(), t0);
        let (u, re) = r.on_verification(1, report(&tc, 4, FailureCode::NOT_ALLOWED_IN_MODE), t0);
        assert!(re.is_empty());
        assert!(matches!(u, Some(Update::Verification { v, .. }) if !v.success));
        assert!(r.is_empty());
    }

    // verifies: GND-19, GND-18
    #[test]
    fn starts_are_checked_unknown_hazard_link_and_one_plan_per_robot() {
        let dir = std::env::temp_dir().join(format!("planbook-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let plan = |name: &str, tc: &str| {
            let path = dir.join(format!("{name}.toml"));
            std::fs::write(
                &path,
                format!("name = \"{name}\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"s\"\nrobot = 1\naction = \"command\"\ntc = \"{tc}\"\n"),
            )
            .unwrap();
            PlanCfg {
                name: name.into(),
                path,
            }
        };
        let hub = Hub::new();
        hub.add_robot(1);
        let (tx, rx) = crossbeam_channel::bounded(64);
        let book = PlanBook::new(
            vec![plan("ping", "PING"), plan("clear", "STORE_DELETE")],
            hub.clone(),
            BTreeMap::from([(1, tx)]),
        );
        assert!(matches!(book.start("nope", true), Err(PlanStartError::Unknown(m)) if m.contains("ping, clear")));
        assert!(matches!(book.start("ping", false), Err(PlanStartError::Refused(m)) if m.contains("not up yet")));
        hub.link(1, crate::dashboard::LinkState::Up);
        let hazards = &book.list()[1].hazards;
        assert_eq!(hazards.len(), 1, "{hazards:?}");
        assert!(matches!(
            book.start("clear", false),
            Err(PlanStartError::NeedsConfirmation(_))
        ));
        let run = book.start("ping", false).unwrap();
        // The run follows the robot's thread, then hands it its TC.
        assert!(matches!(
            rx.recv_timeout(Duration::from_secs(5)),
            Ok(DashCmd::Follow(_))
        ));
        // Held unanswered: a dropped reply channel would end the run before the check.
        let tc = rx.recv_timeout(Duration::from_secs(5));
        assert!(matches!(&tc, Ok(DashCmd::PlanTc { def, .. }) if def.name == "PING"));
        assert!(matches!(book.start("clear", true), Err(PlanStartError::Busy(m)) if m.contains(&run)));
        // The robot's thread is gone: the run ends failed and the robot is free again.
        drop((tc, rx));
        let end = Instant::now() + Duration::from_secs(10);
        while book.busy.lock().unwrap().contains_key(&1) {
            assert!(Instant::now() < end, "robot 1 still busy");
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn run(states: &[&str], details: &[&str]) -> PlanRun {
        PlanRun {
            run_id: "p-1".into(),
            plan: "p".into(),
            state: "running".into(),
            detail: String::new(),
            started_ms: 0,
            steps: states
                .iter()
                .zip(details)
                .enumerate()
                .map(|(i, (s, d))| PlanStep {
                    id: format!("s{i}"),
                    robot: 1,
                    label: String::new(),
                    state: s.to_string(),
                    request_id: None,
                    detail: d.to_string(),
                })
                .collect(),
        }
    }

    // verifies: GND-19
    #[test]
    fn a_run_ends_done_failed_with_the_failing_step_or_lost() {
        assert_eq!(
            outcome(&run(&["done", "done"], &["", ""]), None),
            ("done".into(), String::new())
        );
        let r = run(
            &["done", "failed", "blocked"],
            &["", "robot 1: start failed: INITIAL_STATE_MISMATCH (…)", "waits for s1"],
        );
        assert_eq!(
            outcome(&r, None),
            (
                "failed".into(),
                "step s1 failed: robot 1: start failed: INITIAL_STATE_MISMATCH (…)".into()
            )
        );
        assert_eq!(outcome(&r, Some("robot 1: no TM for 3000 ms")).0, "lost");
        let r = run(&["blocked"], &["robot 1 reported fault LOW_BATTERY"]);
        assert_eq!(
            outcome(&r, None).1,
            "step s0 blocked: robot 1 reported fault LOW_BATTERY"
        );
    }

    // verifies: GND-19
    #[test]
    fn the_page_sees_each_steps_stage_and_progress() {
        let plan = crate::plan::parse(
            "name = \"p\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"a\"\nrobot = 1\naction = \"command\"\ntc = \"PING\"\n[[step]]\nid = \"b\"\nrobot = 1\naction = \"wait\"\nseconds = 1\n",
        )
        .unwrap();
        let opts = RunOptions {
            ping_period: None,
            display: false,
            ..RunOptions::default()
        };
        let t0 = Instant::now();
        let mut exec = Executor::new(&plan, &opts, &[], t0);
        let mut r = run(&["waiting", "waiting"], &["", ""]);
        let fx = exec.on_tick(t0);
        assert!(matches!(fx[..], [Effect::Send { step: 0, .. }]));
        exec.on_sent(0, Ok(ping(5)), t0);
        view(&mut r, &exec);
        assert_eq!(
            (r.steps[0].state.as_str(), r.steps[0].detail.as_str()),
            ("running", "sent")
        );
        assert_eq!(r.steps[1].state, "waiting");
        let v = report(&ping(5), 5, FailureCode::CRC_MISMATCH);
        exec.on_update(
            t0,
            Update::Verification {
                robot: 1,
                tag: Some(0),
                tc: None,
                v,
                after: None,
            },
        );
        view(&mut r, &exec);
        assert_eq!(r.steps[0].detail, "progress 2");
        exec.on_sent(0, Err("no link".into()), t0);
        view(&mut r, &exec);
        assert_eq!(r.steps[0].state, "failed");
        assert!(r.steps[0].detail.contains("no link"), "{}", r.steps[0].detail);
        assert_eq!(r.steps[1].state, "blocked");
    }
}
