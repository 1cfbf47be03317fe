//! The plan executor: one robot's loaded plan, where it is, what it waits for.
//!
//! Time is passed in (ms of the robot's clock). The executor runs nothing itself:
//! [`Plan::poll`] hands out the next step's TC once it may start, the obsw runs it through
//! its TC path and reports the outcome with [`Plan::outcome`] (keyed by the TC's request
//! ID, its first four bytes). Order of a step's life:
//!
//! 1. the previous step of this robot completed (steps run in image order);
//! 2. every dependency is confirmed: the robot it names announced (over the authenticated
//!    team link) that it completed that step of the same plan ID. No announcement, no start:
//!    a lost link means the robot waits;
//! 3. the step starts: a TC step is handed out (and counts as running until its completion
//!    or failure), a wait step runs its time;
//! 4. completion: the next step; failure or timeout: the plan is suspended at that step
//!    (a resume runs it again, a skip passes it).

use mib::params::{pid, NotSupplied, Supplied};
use mib::plan::{cause, state, MAX_IMAGE_LEN, MAX_PEERS, PROGRESS_LEN, PROGRESS_PERIOD_MS};

use crate::image::{Dep, Image, ImageError, StepKind, StepView};

/// The plan's state (codes in `mib::plan::state`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum State {
    Empty,
    Loaded,
    Running,
    Suspended,
    Completed,
    Aborted,
}

/// The control TCs of a loaded plan (PUS 18 style).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Control {
    Suspend,
    Resume,
    Abort,
    Skip,
}

impl State {
    pub const fn code(self) -> u8 {
        match self {
            State::Empty => state::EMPTY,
            State::Loaded => state::LOADED,
            State::Running => state::RUNNING,
            State::Suspended => state::SUSPENDED,
            State::Completed => state::COMPLETED,
            State::Aborted => state::ABORTED,
        }
    }
    /// The state of a code (`None` for a code no state has).
    pub const fn from_code(c: u8) -> Option<State> {
        match c {
            state::EMPTY => Some(State::Empty),
            state::LOADED => Some(State::Loaded),
            state::RUNNING => Some(State::Running),
            state::SUSPENDED => Some(State::Suspended),
            state::COMPLETED => Some(State::Completed),
            state::ABORTED => Some(State::Aborted),
            _ => None,
        }
    }
    /// Whether `control` may act on a plan in this state: PLAN_SUSPEND while running,
    /// PLAN_RESUME and PLAN_SKIP while suspended (a skip also needs no step running),
    /// PLAN_ABORT once a plan is loaded. The one rule of the executor and of the ground's
    /// page.
    pub const fn accepts(self, control: Control) -> bool {
        match control {
            Control::Suspend => matches!(self, State::Running),
            Control::Resume | Control::Skip => matches!(self, State::Suspended),
            Control::Abort => !matches!(self, State::Empty),
        }
    }
    /// A plan in these states holds the robot's staging buffer: no new load.
    const fn busy(self) -> bool {
        matches!(self, State::Running | State::Suspended)
    }
}

/// Why a plan TC was refused (each one a failure code of the MIB's PUS 18 TCs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// PLAN_BUSY: a plan runs or is suspended.
    Busy(State),
    /// PLAN_TOO_LARGE: bytes would end at `end`, beyond the image or after a gap.
    TooLarge { end: u16 },
    /// PLAN_CHECKSUM: the staged bytes' length or CRC-32 is not the TC's.
    Checksum { expected: u32, computed: u32, staged: u16 },
    /// PLAN_INVALID: a `mib::plan::invalid` reason at an offset.
    Invalid { reason: u8, offset: u16 },
    /// PLAN_WRONG_ROBOT.
    WrongRobot(u8),
    /// PLAN_STEP_INVALID: a step's TC would be refused with `code`.
    StepInvalid { step: u8, code: u16 },
    /// PLAN_UNREACHABLE: a reconfiguration the map cannot do.
    Unreachable { step: u8, from: u8, to: u8 },
    /// PLAN_HAZARD_UNCONFIRMED.
    HazardUnconfirmed { step: u8 },
    /// PLAN_NOT_LOADED: no plan, or another plan ID.
    NotLoaded,
    /// PLAN_BAD_STATE.
    BadState(State),
    /// PLAN_STEP_MISMATCH: skip of a step that is not the next one.
    StepMismatch { next: u8, given: u8 },
}

/// A state change to report (event PLAN_STATE_CHANGED).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Change {
    pub plan_id: u32,
    pub state: State,
    /// The next step (the one that failed, for a suspension by a step).
    pub step: u8,
    /// A `mib::plan::cause`.
    pub cause: u8,
}

/// What [`Plan::poll`] asks of the obsw.
#[derive(Debug, PartialEq, Eq)]
pub enum Poll<'a> {
    /// Nothing to do now.
    Idle,
    /// Run this TC as step `step` (its outcome comes back through [`Plan::outcome`]).
    RunTc { step: u8, tc: &'a [u8] },
    /// The next step started to wait for another robot's step (report once).
    Waiting { step: u8, on: Dep },
    /// The plan changed state (a wait step ended the plan, a step timed out).
    Changed(Change),
}

/// The loaded plan's header, for the PLAN_LOADED event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Loaded {
    pub plan_id: u32,
    pub steps: u8,
    pub crc: u32,
}

/// What survives a reset: the image and how far it got (the platform stores it before a
/// step starts, so a step never runs twice after a reset).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Progress {
    pub state: State,
    pub next: u8,
    pub done: u8,
}

/// Counters of HK PLAN.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Counters {
    pub progress_sent: u32,
    pub progress_received: u32,
    pub progress_ignored: u32,
}

/// A step in flight.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Running {
    /// The TC with this request ID (first four bytes) runs; it must end by `deadline`.
    Tc { step: u8, req: u32, deadline: u64 },
    /// A wait step ends at `until`.
    Wait { step: u8, until: u64 },
}

/// One robot's on-board plan. (Clone, Eq and Hash for the model checker, which explores
/// copies of whole robots.)
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Plan {
    me: u8,
    staging: [u8; MAX_IMAGE_LEN],
    staged: usize,
    image: [u8; MAX_IMAGE_LEN],
    len: usize,
    plan_id: u32,
    steps: u8,
    state: State,
    /// Steps completed (skipped ones included); the next step to run has this index.
    done: u8,
    running: Option<Running>,
    /// Other robots' announced progress of this plan: (robot, steps done).
    peers: heapless::Vec<(u8, u8), MAX_PEERS>,
    /// The dependency the next step waits for (reported once per wait).
    waiting: Option<Dep>,
    next_announce: u64,
    /// Progress changed since the last durable record.
    dirty: bool,
    pub counters: Counters,
}

impl Default for Plan {
    fn default() -> Self {
        Plan::new(0)
    }
}

impl Plan {
    pub const fn new(me: u8) -> Self {
        Plan {
            me,
            staging: [0; MAX_IMAGE_LEN],
            staged: 0,
            image: [0; MAX_IMAGE_LEN],
            len: 0,
            plan_id: 0,
            steps: 0,
            state: State::Empty,
            done: 0,
            running: None,
            peers: heapless::Vec::new(),
            waiting: None,
            next_announce: 0,
            dirty: false,
            counters: Counters {
                progress_sent: 0,
                progress_received: 0,
                progress_ignored: 0,
            },
        }
    }

    pub fn state(&self) -> State {
        self.state
    }
    pub fn plan_id(&self) -> u32 {
        self.plan_id
    }
    pub fn done(&self) -> u8 {
        self.done
    }

    fn loaded(&self) -> Option<Image<'_>> {
        (self.len > 0)
            .then(|| Image::parse(&self.image[..self.len]).ok())
            .flatten()
    }

    fn change(&mut self, state: State, cause: u8) -> Change {
        self.state = state;
        self.dirty = true;
        Change {
            plan_id: self.plan_id,
            state,
            step: self.done,
            cause,
        }
    }

    // ------------------------------------------------------------------ TCs

    /// PLAN_LOAD: `data` at `offset` of the staging buffer. Offset 0 starts a new image;
    /// a chunk must start at or before the end of the bytes staged so far (no gap).
    pub fn load(&mut self, offset: u16, data: &[u8]) -> Result<(), Refusal> {
        if self.state.busy() {
            return Err(Refusal::Busy(self.state));
        }
        let (off, end) = (usize::from(offset), usize::from(offset) + data.len());
        if end > MAX_IMAGE_LEN || off > self.staged && off != 0 {
            return Err(Refusal::TooLarge {
                end: end.min(u16::MAX as usize) as u16,
            });
        }
        if off == 0 {
            self.staged = 0;
        }
        self.staging[off..end].copy_from_slice(data);
        self.staged = self.staged.max(end);
        Ok(())
    }

    /// PLAN_COMMIT: checks the staged image (`len` bytes, trailer CRC `crc`) and, with
    /// `check` for each step (the obsw's acceptance, map and hazard checks), makes it the
    /// loaded plan. On any refusal the loaded plan stays as it was.
    pub fn commit(
        &mut self,
        len: u16,
        crc: u32,
        mut check: impl FnMut(&StepView<'_>) -> Result<(), Refusal>,
    ) -> Result<Loaded, Refusal> {
        if self.state.busy() {
            return Err(Refusal::Busy(self.state));
        }
        let n = usize::from(len);
        let staged = self.staged as u16;
        let bytes = &self.staging[..self.staged];
        let trailer = match (n == bytes.len(), bytes.len().checked_sub(4)) {
            (true, Some(t)) => Some(u32::from_be_bytes([bytes[t], bytes[t + 1], bytes[t + 2], bytes[t + 3]])),
            _ => None,
        };
        if trailer != Some(crc) {
            let computed = trailer.map_or(0, |_| crate::image::crc32(&bytes[..n - 4]));
            return Err(Refusal::Checksum {
                expected: crc,
                computed,
                staged,
            });
        }
        let img = Image::parse(bytes).map_err(|e| match e {
            ImageError::Checksum { computed, .. } => Refusal::Checksum {
                expected: crc,
                computed,
                staged,
            },
            ImageError::Invalid { reason, offset } => Refusal::Invalid { reason, offset },
        })?;
        if img.robot != self.me {
            return Err(Refusal::WrongRobot(img.robot));
        }
        for s in img.iter() {
            check(&s)?;
        }
        let loaded = Loaded {
            plan_id: img.plan_id,
            steps: img.steps(),
            crc,
        };
        self.image[..n].copy_from_slice(&self.staging[..n]);
        self.len = n;
        self.plan_id = loaded.plan_id;
        self.steps = loaded.steps;
        self.state = State::Loaded;
        self.done = 0;
        self.running = None;
        self.waiting = None;
        self.peers.clear();
        self.dirty = true;
        Ok(loaded)
    }

    /// PLAN_START of plan `plan_id` (the loaded one).
    pub fn start(&mut self, plan_id: u32) -> Result<Change, Refusal> {
        if self.len == 0 || plan_id != self.plan_id {
            return Err(Refusal::NotLoaded);
        }
        match self.state {
            State::Loaded => Ok(self.change(State::Running, cause::COMMAND)),
            s => Err(Refusal::BadState(s)),
        }
    }

    /// PLAN_SUSPEND: no new step starts; the running one finishes (its outcome counts).
    pub fn suspend(&mut self) -> Result<Change, Refusal> {
        if !self.state.accepts(Control::Suspend) {
            return Err(Refusal::BadState(self.state));
        }
        Ok(self.change(State::Suspended, cause::COMMAND))
    }

    /// PLAN_RESUME: continues at the next step (a failed one runs again).
    pub fn resume(&mut self) -> Result<Change, Refusal> {
        if !self.state.accepts(Control::Resume) {
            return Err(Refusal::BadState(self.state));
        }
        self.waiting = None;
        Ok(self.change(State::Running, cause::COMMAND))
    }

    /// PLAN_ABORT: nothing new starts. Returns the change and whether a TC step was
    /// running (the obsw stops its action as a ground STOP would).
    pub fn abort(&mut self) -> Result<(Change, bool), Refusal> {
        if self.len == 0 {
            return Err(Refusal::NotLoaded);
        }
        let tc_running = matches!(self.running.take(), Some(Running::Tc { .. }));
        self.waiting = None;
        Ok((self.change(State::Aborted, cause::COMMAND), tc_running))
    }

    /// PLAN_SKIP of step `step`: only the next step of a suspended plan, with nothing
    /// running. The step counts as completed (also for other robots' dependencies).
    pub fn skip(&mut self, step: u8) -> Result<Change, Refusal> {
        if !self.state.accepts(Control::Skip) || self.running.is_some() {
            return Err(Refusal::BadState(self.state));
        }
        if step != self.done {
            return Err(Refusal::StepMismatch {
                next: self.done,
                given: step,
            });
        }
        self.done += 1;
        self.next_announce = 0;
        if self.done >= self.steps {
            return Ok(self.change(State::Completed, cause::DONE));
        }
        Ok(self.change(State::Suspended, cause::COMMAND))
    }

    /// The PLAN_STATUS report's source data (layout: the MIB's TM PLAN_STATUS).
    pub fn status(&self) -> [u8; mib::plan::STATUS_LEN] {
        let mut b = [0u8; mib::plan::STATUS_LEN];
        b[..4].copy_from_slice(&self.plan_id.to_be_bytes());
        let w = self.waiting.unwrap_or(Dep { robot: 0, step: 0 });
        b[4..].copy_from_slice(&[self.state.code(), self.steps, self.done, self.done, w.robot, w.step]);
        b
    }

    /// The parameters the MIB names the plan the source of.
    pub fn param(&self, id: u16) -> Supplied {
        let w = self.waiting.unwrap_or(Dep { robot: 0, step: 0 });
        let c = &self.counters;
        Ok(Some(match id {
            pid::PLAN_STATE => i64::from(self.state.code()),
            pid::PLAN_ID => i64::from(self.plan_id),
            pid::PLAN_STEPS => i64::from(self.steps),
            pid::PLAN_NEXT_STEP => i64::from(self.done),
            pid::PLAN_DONE => i64::from(self.done),
            pid::PLAN_WAIT_ROBOT => i64::from(w.robot),
            pid::PLAN_WAIT_STEP => i64::from(w.step),
            pid::PLAN_PROGRESS_SENT => i64::from(c.progress_sent),
            pid::PLAN_PROGRESS_RECEIVED => i64::from(c.progress_received),
            pid::PLAN_PROGRESS_IGNORED => i64::from(c.progress_ignored),
            _ => return Err(NotSupplied(id)),
        }))
    }

    // ------------------------------------------------------------------ execution

    /// How many steps of its image robot `robot` announced completed (this robot: its own).
    fn progress_of(&self, robot: u8) -> Option<u8> {
        if robot == self.me {
            return Some(self.done);
        }
        self.peers.iter().find(|(r, _)| *r == robot).map(|&(_, d)| d)
    }

    /// What to do at `now`: start the next step if it may, end a wait, time out a step.
    pub fn poll(&mut self, now: u64) -> Poll<'_> {
        if self.state != State::Running {
            return Poll::Idle;
        }
        match self.running {
            Some(Running::Tc { deadline, .. }) if now >= deadline => {
                self.running = None;
                return Poll::Changed(self.change(State::Suspended, cause::STEP_TIMEOUT));
            }
            Some(Running::Tc { .. }) => return Poll::Idle,
            Some(Running::Wait { until, .. }) if now >= until => {
                self.running = None;
                return match self.completed() {
                    Some(c) => Poll::Changed(c),
                    None => Poll::Idle,
                };
            }
            Some(Running::Wait { .. }) => return Poll::Idle,
            None => {}
        }
        // What the next step is, owned, so that the image is not borrowed below.
        let Some((index, deps, timeout_s, wait, span)) = self.loaded().and_then(|img| {
            let s = img.step(self.done)?;
            let (wait, span) = match s.kind {
                StepKind::Wait { ms } => (Some(ms), (0, 0)),
                StepKind::Tc(tc) => (None, (tc.as_ptr() as usize - self.image.as_ptr() as usize, tc.len())),
            };
            Some((s.index, s.deps.clone(), s.timeout_s, wait, span))
        }) else {
            return Poll::Idle;
        };
        let missing = deps
            .iter()
            .copied()
            .find(|d| self.progress_of(d.robot).is_none_or(|p| p <= d.step));
        if let Some(d) = missing {
            let first = self.waiting != Some(d);
            self.waiting = Some(d);
            return if first {
                Poll::Waiting { step: index, on: d }
            } else {
                Poll::Idle
            };
        }
        self.waiting = None;
        let timeout = match timeout_s {
            0 => mib::plan::DEFAULT_STEP_TIMEOUT_S,
            t => t,
        };
        if let Some(ms) = wait {
            self.running = Some(Running::Wait {
                step: index,
                until: now + u64::from(ms),
            });
            return Poll::Idle;
        }
        let tc = &self.image[span.0..span.0 + span.1];
        self.running = Some(Running::Tc {
            step: index,
            req: u32::from_be_bytes([tc[0], tc[1], tc[2], tc[3]]),
            deadline: now + u64::from(timeout) * 1000,
        });
        Poll::RunTc {
            step: index,
            tc: &self.image[span.0..span.0 + span.1],
        }
    }

    /// The step in flight completed: the next one, or the plan is done.
    fn completed(&mut self) -> Option<Change> {
        self.done += 1;
        self.next_announce = 0;
        self.dirty = true;
        (self.done >= self.steps).then(|| self.change(State::Completed, cause::DONE))
    }

    /// The outcome of the TC with request ID `req` (first four bytes): `ok` = completed.
    /// Anything but the running step's TC is not the plan's business (`None`).
    pub fn outcome(&mut self, req: u32, ok: bool) -> Option<Change> {
        let Some(Running::Tc { req: r, .. }) = self.running else {
            return None;
        };
        if r != req {
            return None;
        }
        self.running = None;
        if ok {
            return self.completed();
        }
        // A suspension by the operator while the step ran still reports the failure.
        Some(self.change(State::Suspended, cause::STEP_FAILED))
    }

    /// A fault was raised by FDIR: a running plan is suspended (the robot holds as FDIR
    /// says; the running action's own outcome still arrives and counts).
    pub fn fault(&mut self) -> Option<Change> {
        (self.state == State::Running).then(|| self.change(State::Suspended, cause::FAULT))
    }

    /// The step currently running, if any (0-based).
    pub fn running_step(&self) -> Option<u8> {
        self.running.map(|r| match r {
            Running::Tc { step, .. } | Running::Wait { step, .. } => step,
        })
    }

    // ------------------------------------------------------------------ team

    /// A progress announcement (source data of a TM[211,7]) received from robot `from`
    /// (authenticated by the platform; `None` in the lab's bare mode). Progress only
    /// grows: a duplicate or late announcement changes nothing. Returns whether it was
    /// accepted (of this plan, from a robot the plan waits for, consistent sender).
    pub fn peer_progress(&mut self, from: Option<u8>, data: &[u8]) -> bool {
        let ok = self.take_progress(from, data);
        let c = &mut self.counters;
        if ok {
            c.progress_received = c.progress_received.wrapping_add(1);
        } else {
            c.progress_ignored = c.progress_ignored.wrapping_add(1);
        }
        ok
    }

    fn take_progress(&mut self, from: Option<u8>, data: &[u8]) -> bool {
        let [p0, p1, p2, p3, robot, done] = *data else {
            return false;
        };
        let plan_id = u32::from_be_bytes([p0, p1, p2, p3]);
        if self.len == 0 || plan_id != self.plan_id || robot == self.me || from.is_some_and(|f| f != robot) {
            return false;
        }
        let wanted = self
            .loaded()
            .is_some_and(|img| img.iter().any(|s| s.deps.iter().any(|d| d.robot == robot)));
        if !wanted {
            return false;
        }
        if let Some(p) = self.peers.iter_mut().find(|(r, _)| *r == robot) {
            p.1 = p.1.max(done);
            return true;
        }
        self.peers.push((robot, done)).is_ok()
    }

    /// The progress announcement to send now, if one is due: after each completed step at
    /// once, else every `PROGRESS_PERIOD_MS` while a plan is loaded and has started.
    pub fn announcement(&mut self, now: u64) -> Option<[u8; PROGRESS_LEN]> {
        if self.len == 0 || matches!(self.state, State::Empty | State::Loaded) || now < self.next_announce {
            return None;
        }
        self.next_announce = now + PROGRESS_PERIOD_MS;
        let mut b = [0u8; PROGRESS_LEN];
        b[..4].copy_from_slice(&self.plan_id.to_be_bytes());
        b[4] = self.me;
        b[5] = self.done;
        Some(b)
    }

    /// Counts announcements handed to the link (one per destination).
    pub fn sent(&mut self, n: u32) {
        self.counters.progress_sent = self.counters.progress_sent.wrapping_add(n);
    }

    // ------------------------------------------------------------------ durability

    /// The record to store when progress changed since the last call (`None`: nothing
    /// new). The platform stores it before the next step starts.
    pub fn take_record(&mut self) -> Option<(&[u8], Progress)> {
        if !core::mem::take(&mut self.dirty) {
            return None;
        }
        let p = Progress {
            state: self.state,
            next: self.done,
            done: self.done,
        };
        Some((&self.image[..self.len], p))
    }

    /// Restores a stored record after a reset. A plan that was running comes back
    /// suspended (cause RESTART): the step in flight at the reset has an unknown outcome,
    /// so the ground decides (resume runs it again, skip passes it). Returns the change
    /// to report, or `None` when the record is no valid image of this robot.
    pub fn restore(&mut self, image: &[u8], p: Progress) -> Option<Change> {
        let img = Image::parse(image).ok()?;
        if img.robot != self.me || image.len() > MAX_IMAGE_LEN || p.done > img.steps() {
            return None;
        }
        let (plan_id, steps) = (img.plan_id, img.steps());
        self.image[..image.len()].copy_from_slice(image);
        self.len = image.len();
        self.plan_id = plan_id;
        self.steps = steps;
        self.done = p.done;
        self.running = None;
        self.state = p.state;
        let state = match p.state {
            State::Running => State::Suspended,
            s => s,
        };
        Some(self.change(state, cause::RESTART))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::{emit, StepRepr};
    use mib::plan::MAX_DEPS;

    fn tc(seq: u8) -> [u8; 13] {
        [0x19, 0x01, 0xC0, seq, 0x00, 0x06, 0x2F, 17, 1, 0, 0, 0xAB, 0xCD]
    }

    fn deps(d: &[(u8, u8)]) -> heapless::Vec<Dep, MAX_DEPS> {
        d.iter().map(|&(robot, step)| Dep { robot, step }).collect()
    }

    /// Robot 1's image: step 0 a TC, step 1 a TC after robot 2's step 0, step 2 a wait.
    fn image(robot: u8) -> Vec<u8> {
        let (a, b) = (tc(1), tc(2));
        let steps = [
            StepRepr {
                index: 0,
                confirmed: false,
                timeout_s: 5,
                deps: deps(&[]),
                kind: StepKind::Tc(&a),
            },
            StepRepr {
                index: 1,
                confirmed: false,
                timeout_s: 5,
                deps: deps(&[(2, 0)]),
                kind: StepKind::Tc(&b),
            },
            StepRepr {
                index: 2,
                confirmed: false,
                timeout_s: 0,
                deps: deps(&[]),
                kind: StepKind::Wait { ms: 100 },
            },
        ];
        let mut out = [0u8; MAX_IMAGE_LEN];
        let n = emit(robot, 7, &steps, &mut out).unwrap();
        out[..n].to_vec()
    }

    fn loaded() -> Plan {
        let mut p = Plan::new(1);
        let img = image(1);
        p.load(0, &img[..10]).unwrap();
        p.load(10, &img[10..]).unwrap();
        let crc = u32::from_be_bytes(img[img.len() - 4..].try_into().unwrap());
        p.commit(img.len() as u16, crc, |_| Ok(())).unwrap();
        p
    }

    fn req(seq: u8) -> u32 {
        u32::from_be_bytes([0x19, 0x01, 0xC0, seq])
    }

    // verifies: PLAN-EXEC-01
    #[test]
    fn steps_run_in_order_and_a_dependency_waits_for_the_other_robots_announcement() {
        let mut p = loaded();
        assert_eq!(p.poll(0), Poll::Idle, "not started");
        p.start(7).unwrap();
        assert!(matches!(p.poll(10), Poll::RunTc { step: 0, .. }));
        assert_eq!(p.poll(20), Poll::Idle, "one step at a time");
        assert_eq!(p.outcome(req(9), true), None, "another TC's outcome");
        assert_eq!(p.outcome(req(1), true), None);
        assert_eq!(
            p.poll(30),
            Poll::Waiting {
                step: 1,
                on: Dep { robot: 2, step: 0 }
            }
        );
        // No announcement, no start, however long.
        for t in 0..100 {
            assert_eq!(p.poll(40 + t), Poll::Idle);
        }
        assert_eq!(p.param(pid::PLAN_WAIT_ROBOT), Ok(Some(2)));
        // Robot 2 announces it has done 0 steps (still running its step 0): still waiting.
        assert!(p.peer_progress(Some(2), &[0, 0, 0, 7, 2, 0]));
        assert_eq!(p.poll(200), Poll::Idle);
        // Announcement of another plan, a forged sender, a robot not waited for: ignored.
        assert!(!p.peer_progress(Some(2), &[0, 0, 0, 8, 2, 1]));
        assert!(!p.peer_progress(Some(3), &[0, 0, 0, 7, 2, 1]));
        assert!(!p.peer_progress(Some(3), &[0, 0, 0, 7, 3, 1]));
        assert!(!p.peer_progress(Some(2), &[0, 0, 7, 2, 1]));
        assert_eq!(p.poll(210), Poll::Idle);
        assert!(p.peer_progress(Some(2), &[0, 0, 0, 7, 2, 1]));
        assert!(matches!(p.poll(220), Poll::RunTc { step: 1, .. }));
        // A late, lower announcement changes nothing.
        assert!(p.peer_progress(Some(2), &[0, 0, 0, 7, 2, 0]));
        assert_eq!(p.outcome(req(2), true), None);
        assert_eq!(p.poll(230), Poll::Idle, "wait step started");
        assert_eq!(p.poll(300), Poll::Idle);
        let done = p.poll(330);
        assert!(
            matches!(
                done,
                Poll::Changed(Change {
                    state: State::Completed,
                    step: 3,
                    ..
                })
            ),
            "{done:?}"
        );
        assert_eq!(p.counters.progress_ignored, 4);
    }

    // verifies: PLAN-EXEC-02
    #[test]
    fn a_failed_step_suspends_the_plan_resume_runs_it_again_and_skip_passes_it() {
        let mut p = loaded();
        p.start(7).unwrap();
        let _ = p.poll(0);
        let c = p.outcome(req(1), false).unwrap();
        assert_eq!((c.state, c.step, c.cause), (State::Suspended, 0, cause::STEP_FAILED));
        assert_eq!(p.poll(10), Poll::Idle, "suspended: nothing starts");
        assert_eq!(p.load(0, &[1]), Err(Refusal::Busy(State::Suspended)));
        assert_eq!(p.skip(1), Err(Refusal::StepMismatch { next: 0, given: 1 }));
        p.resume().unwrap();
        assert!(matches!(p.poll(20), Poll::RunTc { step: 0, .. }), "the same step again");
        assert_eq!(p.skip(0), Err(Refusal::BadState(State::Running)));
        // A timeout suspends too.
        assert!(matches!(
            p.poll(20 + 5_000),
            Poll::Changed(Change {
                state: State::Suspended,
                cause: cause::STEP_TIMEOUT,
                ..
            })
        ));
        p.skip(0).unwrap();
        assert_eq!(p.done(), 1);
        assert_eq!(
            p.announcement(6_000).map(|a| a[5]),
            Some(1),
            "a skipped step counts as done"
        );
        // A fault suspends a running plan; abort ends it.
        p.resume().unwrap();
        assert_eq!(p.fault().map(|c| c.cause), Some(cause::FAULT));
        assert_eq!(p.resume().map(|c| c.state), Ok(State::Running));
        let (c, _) = p.abort().unwrap();
        assert_eq!(c.state, State::Aborted);
        assert_eq!(p.poll(7_000), Poll::Idle);
        assert_eq!(p.start(7), Err(Refusal::BadState(State::Aborted)));
    }

    // verifies: PLAN-LOAD-01
    #[test]
    fn a_commit_refuses_a_wrong_length_crc_robot_or_a_step_the_checker_refuses() {
        let img = image(1);
        let crc = u32::from_be_bytes(img[img.len() - 4..].try_into().unwrap());
        let mut p = Plan::new(1);
        p.load(0, &img).unwrap();
        assert!(matches!(
            p.commit(img.len() as u16 - 1, crc, |_| Ok(())),
            Err(Refusal::Checksum { .. })
        ));
        assert!(matches!(
            p.commit(img.len() as u16, crc ^ 1, |_| Ok(())),
            Err(Refusal::Checksum { .. })
        ));
        // A chunk lost in the middle: a gap is refused at load, a corrupted byte at commit.
        assert_eq!(p.load(900, &[0; 10]), Err(Refusal::TooLarge { end: 910 }));
        assert_eq!(p.load(1020, &[0; 10]), Err(Refusal::TooLarge { end: 1030 }));
        let mut bad = img.clone();
        bad[20] ^= 0x40;
        p.load(0, &bad).unwrap();
        assert!(matches!(
            p.commit(img.len() as u16, crc, |_| Ok(())),
            Err(Refusal::Checksum { .. })
        ));
        // Robot 2's image on robot 1.
        let other = image(2);
        let ocrc = u32::from_be_bytes(other[other.len() - 4..].try_into().unwrap());
        p.load(0, &other).unwrap();
        assert_eq!(
            p.commit(other.len() as u16, ocrc, |_| Ok(())),
            Err(Refusal::WrongRobot(2))
        );
        p.load(0, &img).unwrap();
        let refuse = |s: &StepView| {
            if s.index == 1 {
                Err(Refusal::HazardUnconfirmed { step: 1 })
            } else {
                Ok(())
            }
        };
        assert_eq!(
            p.commit(img.len() as u16, crc, refuse),
            Err(Refusal::HazardUnconfirmed { step: 1 })
        );
        assert_eq!(p.state(), State::Empty, "nothing loaded");
        assert_eq!(p.start(7), Err(Refusal::NotLoaded));
    }

    // verifies: PLAN-EXEC-03
    #[test]
    fn a_plan_restored_after_a_reset_never_runs_the_step_in_flight_again_by_itself() {
        let mut p = loaded();
        p.start(7).unwrap();
        let _ = p.poll(0);
        let (img, prog) = p.take_record().map(|(i, g)| (i.to_vec(), g)).unwrap();
        assert_eq!(
            prog,
            Progress {
                state: State::Running,
                next: 0,
                done: 0
            }
        );
        let mut q = Plan::new(1);
        let c = q.restore(&img, prog).unwrap();
        assert_eq!((c.state, c.cause), (State::Suspended, cause::RESTART));
        assert_eq!(q.poll(10), Poll::Idle);
        assert!(Plan::new(2).restore(&img, prog).is_none(), "another robot's record");
    }
}
