//! Seeded discrete-event simulation of a team of robots losing the ground, shared by the
//! CI test (`tests/sim.rs`) and the example `team_sim`. The same scenarios drive the team
//! protocol ([`TeamRobot`]) and the paper's Floodmax ([`FloodRobot`]) through one interface
//! ([`Robot`]).
//!
//! Network: every copy of a message is lost with probability `loss`, delayed uniformly in
//! `0..=max_delay` ms (so reordered), duplicated with probability `dup` (the copy has its
//! own delay); partitions drop every message across the cut. Crashes stop a robot for a
//! while; it restarts from its persisted term and vote. A batch with a Persist may crash
//! the robot right after the persist (before any send of the batch).
#![allow(dead_code)]

use mmic_team::node::{Authorisation, Persisted};
use mmic_team::wire::{Body, Directive, Message, PlanRef, RobotId, TeamFunction};
use mmic_team::{floodmax, Action, Dest, Effect, Input, Node, Role, TeamEvent};
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

/// splitmix64: small, seeded, good enough for a simulation.
#[derive(Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }
    pub fn chance(&mut self, p: f64) -> bool {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 <= p && p > 0.0
    }
    /// Uniform in `lo..=hi`.
    pub fn range(&mut self, lo: u64, hi: u64) -> u64 {
        lo + self.next_u64() % (hi - lo + 1)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scenario {
    pub name: &'static str,
    pub loss: f64,
    pub dup: f64,
    pub max_delay: u64,
    pub partitions: bool,
    pub crashes: bool,
    /// Probability that a batch holding a Persist crashes the robot right after the persist.
    pub crash_after_persist: f64,
    /// Target time to a leader (ms after the first detection) and the share of runs that
    /// must meet it; `None` for the fault scenario (reported, no target).
    pub target: Option<(u64, f64)>,
    /// Once a leader is agreed, kill it for good; the time reported is then from the kill
    /// until the others agree on a new live leader (docs/team.md: within 6 s).
    pub kill_leader: bool,
}

/// No loss; duplication, reordering and 0–500 ms delay.
pub const LOSS_FREE: Scenario = Scenario {
    name: "loss-free",
    loss: 0.0,
    dup: 0.05,
    max_delay: 500,
    partitions: false,
    crashes: false,
    crash_after_persist: 0.0,
    target: Some((3_500, 0.99)),
    kill_leader: false,
};
/// 20 % loss; duplication, reordering and 0–500 ms delay.
pub const LOSS_20: Scenario = Scenario {
    name: "20 % loss",
    loss: 0.2,
    dup: 0.05,
    max_delay: 500,
    partitions: false,
    crashes: false,
    crash_after_persist: 0.0,
    target: Some((10_000, 0.99)),
    kill_leader: false,
};
/// 20 % loss, duplication, delay, one partition, crashes (including after a persist).
pub const FAULTS: Scenario = Scenario {
    name: "faults",
    loss: 0.2,
    dup: 0.05,
    max_delay: 500,
    partitions: true,
    crashes: true,
    crash_after_persist: 0.05,
    target: None,
    kill_leader: false,
};
/// Loss-free; the first agreed leader is killed and never comes back.
pub const LEADER_KILLED: Scenario = Scenario {
    name: "leader killed",
    loss: 0.0,
    dup: 0.05,
    max_delay: 500,
    partitions: false,
    crashes: false,
    crash_after_persist: 0.0,
    target: Some((6_000, 0.99)),
    kill_leader: true,
};

pub const SCENARIOS: [Scenario; 4] = [LOSS_FREE, LOSS_20, FAULTS, LEADER_KILLED];

pub const PLAN: PlanRef = PlanRef {
    id: 3,
    hash: 0x5EED_CAFE,
};
pub const PLAN_STEPS: u16 = 10;
/// Time a plan step takes once ordered.
pub const STEP_MS: u64 = 400;

/// What a robot asks the world to do after one input.
pub struct Outbox<M> {
    pub persisted: Option<Persisted>,
    /// `None` = every other robot.
    pub sends: Vec<(Option<RobotId>, M)>,
    /// (term, leader, step) of executed directives (step 0 = HOLD).
    pub executed: Vec<(u32, RobotId, u16)>,
    /// Step a leader ordered in a heartbeat it sent (CONTINUE).
    pub ordered_continue: bool,
}

impl<M> Default for Outbox<M> {
    fn default() -> Self {
        Outbox {
            persisted: None,
            sends: Vec::new(),
            executed: Vec::new(),
            ordered_continue: false,
        }
    }
}

/// The simulation interface both protocols implement.
pub trait Robot: Sized {
    type Msg: Copy;
    const NAME: &'static str;
    /// Whether the protocol has terms (else "two leaders" means two at the same time).
    const TERMS: bool;
    fn boot(me: RobotId, roster: &[RobotId], now: u64, restore: Option<Persisted>) -> Self;
    fn input(&mut self, now: u64, rand: u32, input: SimInput<Self::Msg>) -> Outbox<Self::Msg>;
    fn next_deadline(&self) -> u64;
    /// `Some(term)` when the robot believes it is the leader.
    fn leading(&self) -> Option<u32>;
    /// The (term, leader) the robot follows, itself included.
    fn view(&self) -> Option<(u32, RobotId)>;
    /// Holds a valid lease now (for the lease-overlap check; Floodmax: never).
    fn lease(&self, now: u64) -> bool;
    /// Term (for traces).
    fn term(&self) -> u32 {
        0
    }
}

#[derive(Clone, Copy)]
pub enum SimInput<M> {
    Tick,
    Ground,
    Msg(M),
    Progress(u16),
}

// ------------------------------------------------------------------------------------
// The team protocol
// ------------------------------------------------------------------------------------

pub struct TeamRobot {
    pub node: Node,
}

/// Team messages travel as bytes (emit on send, parse on receipt).
#[derive(Clone, Copy)]
pub struct Bytes {
    len: u8,
    buf: [u8; mmic_team::wire::MAX_LEN],
}

fn next_function(progress: u16) -> Option<TeamFunction> {
    (progress < PLAN_STEPS).then_some(TeamFunction::BoltPair)
}

impl Robot for TeamRobot {
    type Msg = Bytes;
    const NAME: &'static str = "team (terms, quorum, lease)";
    const TERMS: bool = true;

    fn boot(me: RobotId, roster: &[RobotId], now: u64, restore: Option<Persisted>) -> Self {
        let mut node = Node::restore(me, roster, restore.unwrap_or_default(), now).expect("valid roster");
        node.authorise(
            now,
            Authorisation {
                plan: PLAN,
                first_step: 1,
                max_steps: mib::team::MAX_AUTHORISED_STEPS,
                expires_at: now + 20 * 60 * 1_000,
            },
        )
        .expect("valid authorisation");
        TeamRobot { node }
    }

    fn input(&mut self, now: u64, rand: u32, input: SimInput<Bytes>) -> Outbox<Bytes> {
        let input = match input {
            SimInput::Tick => Input::Tick,
            SimInput::Ground => Input::GroundTc,
            SimInput::Progress(p) => Input::Progress {
                plan: PLAN,
                progress: p,
                next: next_function(p),
            },
            SimInput::Msg(b) => match Message::parse(&b.buf[..usize::from(b.len)]) {
                Ok(m) => Input::Message(m),
                Err(e) => panic!("simulated link delivered a malformed message: {e}"),
            },
        };
        let mut out = Outbox::default();
        for e in self.node.on_event(now, rand, input) {
            match e {
                Effect::Persist(p) => out.persisted = Some(p),
                Effect::Send { to, msg } => {
                    let mut buf = [0u8; mmic_team::wire::MAX_LEN];
                    let len = msg.emit(&mut buf).expect("buffer sized for every message");
                    let to = match to {
                        Dest::All => None,
                        Dest::To(r) => Some(r),
                    };
                    if let Body::LeaderHeartbeat {
                        directive: Directive::Continue { .. },
                        ..
                    } = msg.body
                    {
                        out.ordered_continue = true;
                    }
                    out.sends.push((to, Bytes { len: len as u8, buf }));
                }
                Effect::Event(TeamEvent::DirectiveExecuted {
                    term,
                    leader,
                    directive,
                }) => {
                    let step = match directive {
                        Directive::Hold => 0,
                        Directive::Continue { step, .. } => step,
                    };
                    out.executed.push((term, leader, step));
                }
                Effect::Act(Action::Continue { .. } | Action::Hold(_)) | Effect::Event(_) => {}
            }
        }
        out
    }

    fn next_deadline(&self) -> u64 {
        self.node.next_deadline()
    }
    fn leading(&self) -> Option<u32> {
        (self.node.role() == Role::Leader).then_some(self.node.term())
    }
    fn view(&self) -> Option<(u32, RobotId)> {
        self.node.leader().map(|l| (self.node.term(), l))
    }
    fn lease(&self, now: u64) -> bool {
        self.node.status(now).lease
    }
    fn term(&self) -> u32 {
        self.node.term()
    }
}

// ------------------------------------------------------------------------------------
// The paper's Floodmax
// ------------------------------------------------------------------------------------

pub struct FloodRobot {
    me: RobotId,
    f: floodmax::Floodmax,
}

impl Robot for FloodRobot {
    type Msg = (RobotId, RobotId);
    const NAME: &'static str = "Floodmax (paper)";
    const TERMS: bool = false;

    fn boot(me: RobotId, _roster: &[RobotId], now: u64, _restore: Option<Persisted>) -> Self {
        // Fully connected team: diameter 1.
        FloodRobot {
            me,
            f: floodmax::Floodmax::new(me, 1, now),
        }
    }

    fn input(&mut self, now: u64, _rand: u32, input: SimInput<Self::Msg>) -> Outbox<Self::Msg> {
        let input = match input {
            SimInput::Tick | SimInput::Progress(_) => floodmax::FloodInput::Tick,
            SimInput::Ground => floodmax::FloodInput::GroundTc,
            SimInput::Msg((from, maxid)) => floodmax::FloodInput::Message { from, maxid },
        };
        let mut out = Outbox::default();
        if let Some(e) = self.f.on_event(now, input) {
            match e {
                floodmax::FloodEffect::Broadcast { maxid } => out.sends.push((None, (self.me, maxid))),
                floodmax::FloodEffect::Decided { .. } => {}
            }
        }
        out
    }

    fn next_deadline(&self) -> u64 {
        self.f.next_deadline()
    }
    fn leading(&self) -> Option<u32> {
        (self.f.leader() == floodmax::Leader::True).then_some(0)
    }
    fn view(&self) -> Option<(u32, RobotId)> {
        self.f.decided().then_some((0, self.f.maxid()))
    }
    fn lease(&self, _now: u64) -> bool {
        false
    }
}

// ------------------------------------------------------------------------------------
// The world
// ------------------------------------------------------------------------------------

#[derive(Clone, Copy)]
enum Ev<M> {
    Tick(usize),
    Ground(usize),
    Deliver { to: usize, from: usize, msg: M },
    Crash(usize, u64),
    Restart(usize),
    StepDone(usize, u16),
}

/// Outcome of one run.
#[derive(Clone, Debug, Default)]
pub struct RunResult {
    /// Two leaders in one term (Floodmax: two robots leading at the same time).
    pub two_leaders: u32,
    /// Directives executed that did not come from the recorded leader of their term.
    pub foreign_directives: u32,
    /// A CONTINUE ordered while another robot held a lease.
    pub lease_overlaps: u32,
    /// Time from the first ground-loss detection until every robot that is up follows one
    /// leader that is up and leads; `None` if never within the horizon. In the
    /// leader-killed scenario: from the kill until the survivors agree again.
    pub time_to_leader: Option<u64>,
    /// Agreement on one live leader at the end of the run.
    pub agreed_at_end: bool,
    pub crashes_after_persist: u32,
    pub messages: u64,
}

impl RunResult {
    pub fn violations(&self) -> u32 {
        self.two_leaders + self.foreign_directives + self.lease_overlaps
    }
}

struct World<R: Robot> {
    n: usize,
    roster: Vec<RobotId>,
    robots: Vec<Option<R>>,
    persisted: Vec<Persisted>,
    progress: Vec<u16>,
    tick_at: Vec<u64>,
    queue: BinaryHeap<Reverse<(u64, u64, usize)>>,
    events: Vec<Option<Ev<R::Msg>>>,
    seq: u64,
    rng: Rng,
    sc: Scenario,
    /// (start, end, side of each robot)
    partition: Option<(u64, u64, Vec<bool>)>,
    leaders: HashMap<u32, RobotId>,
    res: RunResult,
    trace: bool,
}

impl<R: Robot> World<R> {
    fn push(&mut self, t: u64, ev: Ev<R::Msg>) {
        self.seq += 1;
        self.events.push(Some(ev));
        self.queue.push(Reverse((t, self.seq, self.events.len() - 1)));
    }

    fn cut(&self, now: u64, a: usize, b: usize) -> bool {
        match &self.partition {
            Some((s, e, side)) => now >= *s && now < *e && side[a] != side[b],
            None => false,
        }
    }

    fn schedule_tick(&mut self, i: usize, now: u64) {
        if let Some(r) = &self.robots[i] {
            let d = r.next_deadline().max(now);
            if d != u64::MAX && (d < self.tick_at[i] || self.tick_at[i] <= now) {
                self.tick_at[i] = d;
                self.push(d, Ev::Tick(i));
            }
        }
    }

    fn feed(&mut self, i: usize, now: u64, input: SimInput<R::Msg>) {
        let rand = self.rng.next_u32();
        let Some(r) = self.robots[i].as_mut() else {
            return;
        };
        let before = r.leading();
        let view_before = r.view();
        let term_before = r.term();
        let out = r.input(now, rand, input);
        let leading = r.leading();
        if self.trace && (before != leading || view_before != r.view() || term_before != r.term()) {
            println!(
                "{now} robot {} term {} leading {:?} view {:?}",
                self.roster[i],
                r.term(),
                leading,
                r.view()
            );
        }
        if let Some(p) = out.persisted {
            self.persisted[i] = p;
            if !out.sends.is_empty() && self.rng.chance(self.sc.crash_after_persist) {
                // Crash after the persist, before any send of the batch.
                self.res.crashes_after_persist += 1;
                let down = self.rng.range(500, 3_000);
                self.crash(i, now, down);
                return;
            }
        }
        if let (Some(term), true) = (leading, R::TERMS) {
            if before != Some(term) {
                let me = self.roster[i];
                match self.leaders.get(&term) {
                    Some(l) if *l != me => self.res.two_leaders += 1,
                    Some(_) => {}
                    None => {
                        self.leaders.insert(term, me);
                    }
                }
            }
        }
        if !R::TERMS {
            let n_lead = self.robots.iter().flatten().filter(|r| r.leading().is_some()).count();
            if n_lead >= 2 && self.res.two_leaders == 0 {
                self.res.two_leaders = 1;
            }
        }
        if out.ordered_continue {
            for (j, other) in self.robots.iter().enumerate() {
                if j != i {
                    if let Some(o) = other {
                        if o.lease(now) {
                            self.res.lease_overlaps += 1;
                        }
                    }
                }
            }
        }
        for (term, leader, step) in out.executed {
            if self.leaders.get(&term) != Some(&leader) {
                self.res.foreign_directives += 1;
            }
            if step > 0 {
                self.push(now + STEP_MS, Ev::StepDone(i, step));
            }
        }
        for (to, msg) in out.sends {
            for j in 0..self.n {
                if j == i || to.is_some_and(|t| t != self.roster[j]) {
                    continue;
                }
                self.res.messages += 1;
                if self.rng.chance(self.sc.loss) || self.cut(now, i, j) {
                    continue;
                }
                let copies = if self.rng.chance(self.sc.dup) { 2 } else { 1 };
                for _ in 0..copies {
                    let d = self.rng.range(0, self.sc.max_delay);
                    self.push(now + d, Ev::Deliver { to: j, from: i, msg });
                }
            }
        }
        self.schedule_tick(i, now);
    }

    fn crash(&mut self, i: usize, now: u64, down: u64) {
        self.robots[i] = None;
        self.push(now + down, Ev::Restart(i));
    }

    /// Every robot that is up follows one leader that is up and leads in that term.
    fn agreed(&self) -> bool {
        let mut agreed: Option<(u32, RobotId)> = None;
        for r in self.robots.iter().flatten() {
            let Some(v) = r.view() else { return false };
            if agreed.is_some_and(|a| a != v) {
                return false;
            }
            agreed = Some(v);
        }
        let Some((term, l)) = agreed else {
            return false;
        };
        let Some(li) = self.roster.iter().position(|x| *x == l) else {
            return false;
        };
        self.robots[li].as_ref().and_then(|r| r.leading()) == Some(term)
    }
}

/// Run one seeded scenario with `n` robots.
pub fn run<R: Robot>(n: usize, sc: Scenario, seed: u64) -> RunResult {
    let mut rng = Rng::new(seed);
    let roster: Vec<RobotId> = (1..=n as RobotId).collect();
    let mut w: World<R> = World {
        n,
        robots: roster.iter().map(|r| Some(R::boot(*r, &roster, 0, None))).collect(),
        roster,
        persisted: vec![Persisted::default(); n],
        progress: vec![0; n],
        tick_at: vec![u64::MAX; n],
        queue: BinaryHeap::new(),
        events: Vec::new(),
        seq: 0,
        rng: rng.clone(),
        sc,
        partition: None,
        leaders: HashMap::new(),
        res: RunResult::default(),
        trace: std::env::var_os("TEAM_SIM_TRACE").is_some(),
    };
    // The ground's last TC reaches each robot at a different time in [9 s, 10 s).
    let mut first_detect = u64::MAX;
    for i in 0..n {
        let g = 10_000 - rng.range(1, 1_000);
        first_detect = first_detect.min(g + mib::team::GROUND_LOSS_TIMEOUT_MS);
        // A ground TC every second from boot until the last one.
        for k in 0..=g / 1_000 {
            w.push(g - k * 1_000, Ev::Ground(i));
        }
        w.feed(i, 0, SimInput::Progress(0));
    }
    let horizon = if sc.crashes || sc.partitions {
        first_detect + 30_000
    } else {
        first_detect + 40_000
    };
    if sc.partitions {
        let start = first_detect + rng.range(0, 8_000) - 2_000.min(first_detect);
        let end = start + rng.range(1_000, 6_000);
        let mut side: Vec<bool> = (0..n).map(|_| rng.chance(0.5)).collect();
        if side.iter().all(|s| *s) || side.iter().all(|s| !*s) {
            side[0] = !side[0];
        }
        w.partition = Some((start, end, side));
    }
    if sc.crashes {
        let crashes = 1 + n / 4;
        for _ in 0..crashes {
            let i = rng.range(0, n as u64 - 1) as usize;
            let at = first_detect - 2_000 + rng.range(0, 10_000);
            let down = rng.range(500, 4_000);
            w.push(at, Ev::Crash(i, down));
        }
    }
    w.rng = Rng::new(rng.next_u64());
    let stop_early = !(sc.crashes || sc.partitions);
    let mut killed_at: Option<u64> = None;
    while let Some(Reverse((t, _, k))) = w.queue.pop() {
        if t > horizon {
            break;
        }
        let Some(ev) = w.events[k].take() else {
            continue;
        };
        match ev {
            Ev::Tick(i) => {
                if w.tick_at[i] == t {
                    w.tick_at[i] = u64::MAX;
                    w.feed(i, t, SimInput::Tick);
                }
            }
            Ev::Ground(i) => {
                if w.trace {
                    println!("{t} ground TC to robot {}", w.roster[i]);
                }
                w.feed(i, t, SimInput::Ground)
            }
            Ev::Deliver { to, from, msg } => {
                if !w.cut(t, from, to) {
                    w.feed(to, t, SimInput::Msg(msg));
                }
            }
            Ev::Crash(i, down) => {
                if w.robots[i].is_some() {
                    w.crash(i, t, down);
                }
            }
            Ev::Restart(i) => {
                w.robots[i] = Some(R::boot(w.roster[i], &w.roster, t, Some(w.persisted[i])));
                w.tick_at[i] = u64::MAX;
                let p = w.progress[i];
                w.feed(i, t, SimInput::Progress(p));
            }
            Ev::StepDone(i, step) => {
                if w.robots[i].is_some() && step > w.progress[i] {
                    w.progress[i] = step;
                    w.feed(i, t, SimInput::Progress(step));
                }
            }
        }
        if t >= first_detect && w.res.time_to_leader.is_none() && w.agreed() {
            match (sc.kill_leader, killed_at) {
                (true, None) => {
                    // Kill the agreed leader; it never restarts.
                    let leader = w.robots.iter().flatten().find_map(|r| r.view());
                    if let Some((_, l)) = leader {
                        if let Some(li) = w.roster.iter().position(|x| *x == l) {
                            w.crash(li, t, u64::MAX / 4);
                            killed_at = Some(t);
                        }
                    }
                }
                (true, Some(k)) => w.res.time_to_leader = Some(t - k),
                (false, _) => w.res.time_to_leader = Some(t - first_detect),
            }
        }
        let since = killed_at.unwrap_or(first_detect);
        if stop_early && w.res.time_to_leader.is_some_and(|d| t >= since + d + 2_000) {
            break;
        }
    }
    w.res.agreed_at_end = w.agreed();
    w.res
}

/// Aggregate of many runs.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    pub runs: u64,
    pub violations: u64,
    pub runs_with_two_leaders: u64,
    pub foreign_directives: u64,
    pub lease_overlaps: u64,
    pub crashes_after_persist: u64,
    pub times: Vec<u64>,
    pub never: u64,
    pub agreed_at_end: u64,
}

impl Summary {
    pub fn add(&mut self, r: &RunResult) {
        self.runs += 1;
        self.violations += u64::from(r.violations());
        self.runs_with_two_leaders += u64::from(r.two_leaders > 0);
        self.foreign_directives += u64::from(r.foreign_directives);
        self.lease_overlaps += u64::from(r.lease_overlaps);
        self.crashes_after_persist += u64::from(r.crashes_after_persist);
        match r.time_to_leader {
            Some(t) => self.times.push(t),
            None => self.never += 1,
        }
        self.agreed_at_end += u64::from(r.agreed_at_end);
    }
    pub fn merge(&mut self, o: Summary) {
        self.runs += o.runs;
        self.violations += o.violations;
        self.runs_with_two_leaders += o.runs_with_two_leaders;
        self.foreign_directives += o.foreign_directives;
        self.lease_overlaps += o.lease_overlaps;
        self.crashes_after_persist += o.crashes_after_persist;
        self.times.extend(o.times);
        self.never += o.never;
        self.agreed_at_end += o.agreed_at_end;
    }
    /// Percentile `p` (0..=100) of the time to a leader, counting runs without one as
    /// infinite (`None` when the percentile falls among those).
    pub fn percentile(&self, p: f64) -> Option<u64> {
        let k = ((p / 100.0) * self.runs as f64).ceil().max(1.0) as usize - 1;
        self.times.get(k).copied()
    }
    /// Share of runs with a leader agreed within `ms`.
    pub fn within(&self, ms: u64) -> f64 {
        self.times.iter().filter(|t| **t <= ms).count() as f64 / self.runs.max(1) as f64
    }
}

/// Seed of run `k` for `n` robots in scenario `s` (distinct streams per cell).
pub fn seed(n: usize, s: usize, k: u64) -> u64 {
    (n as u64) << 48 ^ (s as u64) << 40 ^ k
}

/// Run `runs` seeds of one cell on `threads` threads.
pub fn sweep<R: Robot>(n: usize, s: usize, runs: u64, threads: u64) -> Summary {
    let sc = SCENARIOS[s];
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|th| {
                scope.spawn(move || {
                    let mut sum = Summary::default();
                    let mut k = th;
                    while k < runs {
                        sum.add(&run::<R>(n, sc, seed(n, s, k)));
                        k += threads;
                    }
                    sum
                })
            })
            .collect();
        let mut total = Summary::default();
        for h in handles {
            total.merge(h.join().expect("simulation thread"));
        }
        total.times.sort_unstable();
        total
    })
}
