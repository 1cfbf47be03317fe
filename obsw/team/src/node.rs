//! Leader selection and limited authority: one robot's team state machine.
//!
//! `Node::on_event(now, rand, input) -> Effects`. Time is the robot's monotonic clock in ms,
//! `rand` a fresh random `u32` from the host (used only to draw election timeouts). The
//! effects of one call form a batch the host executes **in order**; a [`Effect::Persist`]
//! is always first in its batch and must be durable (written and flushed) before the host
//! executes any later effect of the batch. If the host crashes in between, the sends of
//! the batch are lost, which is safe: on restart [`Node::restore`] resumes from the
//! persisted term and vote.
//!
//! Rules (Raft's election, adapted; see docs/team.md):
//! - ground loss: no valid ground TC for `GROUND_LOSS_TIMEOUT_MS` → hold, arm the
//!   election timer; while the ground is seen a robot neither stands, votes nor obeys;
//! - a candidate increments its term, votes for itself and asks every robot; a vote needs
//!   the same term, no other vote in that term, the same plan (ID + hash) and a candidate
//!   progress at least the voter's, and no leader heard within `ELECTION_TIMEOUT_MIN_MS`;
//! - a quorum is a strict majority of the whole roster (a team of two needs both);
//! - the leader's directives are HOLD unless it holds a lease (a quorum acknowledged a
//!   heartbeat sent less than `LEADER_LEASE_MS` ago) and the ground's authorisation covers
//!   the next step; it steps down when no quorum acknowledged for `ELECTION_TIMEOUT_MIN_MS`;
//! - a follower executes a directive only from the leader of its current term, only
//!   while the ground is not seen, and a CONTINUE only within its own copy of the
//!   authorisation.

use crate::wire::{Body, Directive, Message, PlanRef, RobotId, TeamFunction};
use core::fmt;
use heapless::Vec;
use mib::team::{
    quorum, ELECTION_FIRST_BASE_MS, ELECTION_JITTER_MS, ELECTION_RANK_STAGGER_MS, ELECTION_TIMEOUT_MIN_MS,
    GROUND_LOSS_TIMEOUT_MS, HEARTBEAT_PERIOD_MS, LEADER_LEASE_MS, LEADER_QUORUM_CHECK_MS, MAX_AUTHORISATION_MS,
    MAX_AUTHORISED_STEPS, ROSTER_MAX, ROSTER_MIN, VOTE_RETRY_MS,
};

/// The team roster uploaded by the ground (fixed while the ground is away).
pub type Roster = Vec<RobotId, ROSTER_MAX>;

/// Most effects one call can produce (persist, a broadcast, a reply, an action, events).
pub const EFFECTS_MAX: usize = 12;
/// The effects of one call, in the order the host must execute them.
pub type Effects = Vec<Effect, EFFECTS_MAX>;

/// What must survive a reset: the current term and the vote cast in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Persisted {
    pub term: u32,
    pub voted_for: Option<RobotId>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Role {
    Follower,
    Candidate,
    Leader,
}

impl Role {
    pub const fn code(self) -> u8 {
        match self {
            Role::Follower => 0,
            Role::Candidate => 1,
            Role::Leader => 2,
        }
    }
}

/// The ground's advance permission to continue a plan without it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Authorisation {
    pub plan: PlanRef,
    /// First step (1-based) the team may execute.
    pub first_step: u16,
    /// Steps from `first_step` on (at most `MAX_AUTHORISED_STEPS`).
    pub max_steps: u8,
    /// On-board time (ms) after which the authorisation is void.
    pub expires_at: u64,
}

impl Authorisation {
    fn covers(&self, plan: PlanRef, step: u16, now: u64) -> Result<(), RefuseReason> {
        if self.plan != plan {
            return Err(RefuseReason::PlanMismatch);
        }
        if now >= self.expires_at {
            return Err(RefuseReason::Expired);
        }
        let last = u32::from(self.first_step) + u32::from(self.max_steps);
        if u32::from(step) < u32::from(self.first_step) || u32::from(step) >= last {
            return Err(RefuseReason::NotAuthorised);
        }
        Ok(())
    }
}

/// Why an authorisation upload is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AuthError {
    TooManySteps(u8),
    NoSteps,
    ExpiryTooFar,
    AlreadyExpired,
}

impl fmt::Display for AuthError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AuthError::TooManySteps(n) => {
                write!(f, "{n} steps authorised, at most {MAX_AUTHORISED_STEPS}")
            }
            AuthError::NoSteps => write!(f, "authorisation of zero steps"),
            AuthError::ExpiryTooFar => write!(f, "authorisation expiry too far ahead"),
            AuthError::AlreadyExpired => write!(f, "authorisation already expired"),
        }
    }
}

impl core::error::Error for AuthError {}

/// Why a roster is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RosterError {
    TooSmall(usize),
    NotInRoster(RobotId),
    Duplicate(RobotId),
    BadRobot(RobotId),
}

impl fmt::Display for RosterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RosterError::TooSmall(n) => write!(f, "roster of {n}, at least {ROSTER_MIN}"),
            RosterError::NotInRoster(r) => write!(f, "robot {r} is not in its own roster"),
            RosterError::Duplicate(r) => write!(f, "robot {r} twice in the roster"),
            RosterError::BadRobot(r) => write!(f, "{r} is not a robot number"),
        }
    }
}

impl core::error::Error for RosterError {}

/// What the robot's executive should do (obsw executes these).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Action {
    /// Finish the current primitive, then hold in `target`.
    Hold(HoldTarget),
    /// Execute plan step `step` (function `function`) after its initial-state check.
    Continue {
        plan: PlanRef,
        step: u16,
        function: TeamFunction,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HoldTarget {
    /// Both grippers hold: STANDBY.
    Standby,
    /// Otherwise: SAFED.
    Safed,
}

/// Where a message goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dest {
    All,
    To(RobotId),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StepDownReason {
    GroundRegained,
    HigherTerm,
    QuorumLost,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RefuseReason {
    /// From a term older than the robot's current term.
    StaleTerm,
    /// The ground is seen: the ground commands, not the leader.
    GroundPresent,
    /// No authorisation, or the step is outside it.
    NotAuthorised,
    Expired,
    /// The directive's plan (or the step's function) differs from the robot's own plan.
    PlanMismatch,
    /// The robot is not at the step before the ordered one.
    WrongStep,
}

/// Events (PUS 5, IDs in `mib::team::eid`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TeamEvent {
    GroundLost,
    ElectionStarted {
        term: u32,
    },
    LeaderElected {
        term: u32,
        leader: RobotId,
    },
    SteppedDown {
        term: u32,
        reason: StepDownReason,
    },
    GroundRegained {
        term: u32,
    },
    DirectiveExecuted {
        term: u32,
        leader: RobotId,
        directive: Directive,
    },
    DirectiveRefused {
        term: u32,
        from: RobotId,
        reason: RefuseReason,
    },
}

impl TeamEvent {
    /// The MIB event ID.
    pub const fn id(&self) -> u16 {
        use mib::team::eid;
        match self {
            TeamEvent::GroundLost => eid::GROUND_LOST,
            TeamEvent::ElectionStarted { .. } => eid::ELECTION_STARTED,
            TeamEvent::LeaderElected { .. } => eid::LEADER_ELECTED,
            TeamEvent::SteppedDown { .. } => eid::STEPPED_DOWN,
            TeamEvent::GroundRegained { .. } => eid::GROUND_REGAINED,
            TeamEvent::DirectiveExecuted { .. } => eid::DIRECTIVE_EXECUTED,
            TeamEvent::DirectiveRefused { .. } => eid::DIRECTIVE_REFUSED,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Effect {
    /// Make the term and vote durable before executing the rest of the batch.
    Persist(Persisted),
    Send {
        to: Dest,
        msg: Message,
    },
    Act(Action),
    Event(TeamEvent),
}

/// Things the team logic counted instead of acting on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Counters {
    /// Messages from robots not in the roster (or from itself).
    pub foreign: u32,
    /// Messages older than the current term.
    pub stale: u32,
    /// Directives refused (events are raised once per term and reason).
    pub refused: u32,
    /// Effects lost because a batch was full (never expected: capacity is sized).
    pub effects_dropped: u32,
    /// Heartbeats of another leader in the robot's own leader term (never expected).
    pub rival_leader: u32,
}

/// Team status snapshot for the TM report.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TeamStatus {
    pub term: u32,
    pub role: Role,
    pub leader: Option<RobotId>,
    pub roster: Roster,
    pub ground_seen: bool,
    pub voted_for: Option<RobotId>,
    pub lease: bool,
    pub counters: Counters,
}

impl TeamStatus {
    /// Application data of the status report (`mib::team::STATUS_REPORT_LEN` bytes):
    /// term u32, role u8, leader u8 (0 = none), ground seen u8, roster length u8, roster
    /// padded with zeros.
    pub fn encode(&self) -> [u8; mib::team::STATUS_REPORT_LEN] {
        let mut b = [0u8; mib::team::STATUS_REPORT_LEN];
        b[0..4].copy_from_slice(&self.term.to_be_bytes());
        b[4] = self.role.code();
        b[5] = self.leader.unwrap_or(0);
        b[6] = u8::from(self.ground_seen);
        b[7] = self.roster.len() as u8;
        for (slot, r) in b[8..].iter_mut().zip(self.roster.iter()) {
            *slot = *r;
        }
        b
    }
}

/// Inputs of the team state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Input {
    /// Time passed.
    Tick,
    /// A valid ground TC was accepted (any service).
    GroundTc,
    /// A parsed, authenticated team message.
    Message(Message),
    /// The robot's plan, steps completed and the function of the next step (`None` when
    /// there is none or it is not a [`TeamFunction`], e.g. an unbolt: then only HOLD).
    Progress {
        plan: PlanRef,
        progress: u16,
        next: Option<TeamFunction>,
    },
    /// Whether both grippers hold (selects STANDBY or SAFED for a hold).
    Grippers { both_hold: bool },
}

/// One robot's team state machine.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Node {
    me: RobotId,
    roster: Roster,
    term: u32,
    voted_for: Option<RobotId>,
    role: Role,
    leader: Option<RobotId>,
    ground_seen: bool,
    ground_last: u64,
    election_deadline: u64,
    /// Follower: last valid heartbeat of the current term's leader (or boot).
    leader_contact: Option<u64>,
    /// Candidate: bit per roster index of granted votes.
    votes: u32,
    candidacy_start: u64,
    /// Leader: when it won the election.
    leader_since: u64,
    /// Candidate: next vote request; leader: next heartbeat.
    next_send: u64,
    /// Leader: send time of the latest acknowledged heartbeat per roster index.
    acks: [Option<u64>; ROSTER_MAX],
    plan: PlanRef,
    progress: u16,
    next_function: Option<TeamFunction>,
    auth: Option<Authorisation>,
    both_hold: bool,
    /// Last directive executed, with its term (a directive is executed once per term).
    executed: Option<(u32, Directive)>,
    /// Last refusal raised as an event (throttling).
    refused: Option<(u32, RefuseReason)>,
    counters: Counters,
}

fn check_roster(me: RobotId, roster: &[RobotId]) -> Result<Roster, RosterError> {
    if roster.len() < ROSTER_MIN || roster.len() > ROSTER_MAX {
        return Err(RosterError::TooSmall(roster.len()));
    }
    let mut out = Roster::new();
    for (i, r) in roster.iter().enumerate() {
        if mib::apid::robot_apid(*r).is_none() {
            return Err(RosterError::BadRobot(*r));
        }
        if roster[..i].contains(r) {
            return Err(RosterError::Duplicate(*r));
        }
        // Length checked above: the push cannot fail.
        out.push(*r).map_err(|_| RosterError::TooSmall(roster.len()))?;
    }
    if !roster.contains(&me) {
        return Err(RosterError::NotInRoster(me));
    }
    Ok(out)
}

struct Out {
    effects: Effects,
    dropped: u32,
}

impl Out {
    fn push(&mut self, e: Effect) {
        if self.effects.push(e).is_err() {
            self.dropped += 1;
        }
    }
}

impl Node {
    /// A robot starting fresh (term 0, no vote). Boot counts as ground contact.
    pub fn new(me: RobotId, roster: &[RobotId], now: u64) -> Result<Node, RosterError> {
        Node::restore(me, roster, Persisted::default(), now)
    }

    /// A robot restarting from its persisted term and vote. It neither stands nor votes
    /// before `ELECTION_TIMEOUT_MIN_MS` after boot (it may have acknowledged a leader just
    /// before the reset) and counts boot as ground contact.
    pub fn restore(me: RobotId, roster: &[RobotId], persisted: Persisted, now: u64) -> Result<Node, RosterError> {
        let roster = check_roster(me, roster)?;
        Ok(Node {
            me,
            roster,
            term: persisted.term,
            voted_for: persisted.voted_for,
            role: Role::Follower,
            leader: None,
            ground_seen: true,
            ground_last: now,
            election_deadline: u64::MAX,
            leader_contact: Some(now),
            votes: 0,
            candidacy_start: 0,
            leader_since: 0,
            next_send: 0,
            acks: [None; ROSTER_MAX],
            plan: PlanRef::default(),
            progress: 0,
            next_function: None,
            auth: None,
            both_hold: false,
            executed: None,
            refused: None,
            counters: Counters::default(),
        })
    }

    pub fn me(&self) -> RobotId {
        self.me
    }
    pub fn term(&self) -> u32 {
        self.term
    }
    pub fn role(&self) -> Role {
        self.role
    }
    pub fn leader(&self) -> Option<RobotId> {
        self.leader
    }
    pub fn ground_seen(&self) -> bool {
        self.ground_seen
    }
    pub fn persisted(&self) -> Persisted {
        Persisted {
            term: self.term,
            voted_for: self.voted_for,
        }
    }
    pub fn counters(&self) -> Counters {
        self.counters
    }
    /// The counters, zeroed (for a report of increments, or a ground reset).
    pub fn take_counters(&mut self) -> Counters {
        core::mem::take(&mut self.counters)
    }

    /// The earliest time at which `on_event(Tick)` may do something (for hosts that sleep).
    pub fn next_deadline(&self) -> u64 {
        let ground = if self.ground_seen {
            self.ground_last.saturating_add(GROUND_LOSS_TIMEOUT_MS)
        } else {
            u64::MAX
        };
        let own = match self.role {
            Role::Follower => self.election_deadline,
            Role::Candidate => self.election_deadline.min(self.next_send),
            Role::Leader => self.next_send,
        };
        ground.min(own)
    }

    /// Status snapshot for the team status TM report.
    pub fn status(&self, now: u64) -> TeamStatus {
        TeamStatus {
            term: self.term,
            role: self.role,
            leader: self.leader,
            roster: self.roster.clone(),
            ground_seen: self.ground_seen,
            voted_for: self.voted_for,
            lease: self.role == Role::Leader && self.lease_held(now),
            counters: self.counters,
        }
    }

    /// Store the ground's authorisation (called for a validated ground TC, which is also
    /// ground contact: the host passes `Input::GroundTc` for it as for any TC).
    pub fn authorise(&mut self, now: u64, auth: Authorisation) -> Result<(), AuthError> {
        if auth.max_steps == 0 {
            return Err(AuthError::NoSteps);
        }
        if auth.max_steps > MAX_AUTHORISED_STEPS {
            return Err(AuthError::TooManySteps(auth.max_steps));
        }
        if auth.expires_at <= now {
            return Err(AuthError::AlreadyExpired);
        }
        if auth.expires_at - now > MAX_AUTHORISATION_MS {
            return Err(AuthError::ExpiryTooFar);
        }
        self.auth = Some(auth);
        Ok(())
    }

    /// Election timeout: base + roster rank * stagger + random jitter.
    fn timeout(&self, base: u64, rand: u32) -> u64 {
        let rank = self.index(self.me).unwrap_or(0) as u64;
        base + rank * ELECTION_RANK_STAGGER_MS + u64::from(rand) % ELECTION_JITTER_MS
    }

    fn election_timeout(&self, rand: u32) -> u64 {
        self.timeout(ELECTION_TIMEOUT_MIN_MS, rand)
    }

    /// A leader (or a granted vote) was heard less than `ELECTION_TIMEOUT_MIN_MS` ago.
    fn sticky(&self, now: u64) -> bool {
        self.leader_contact
            .is_some_and(|t| now.saturating_sub(t) < ELECTION_TIMEOUT_MIN_MS)
    }

    fn index(&self, r: RobotId) -> Option<usize> {
        self.roster.iter().position(|x| *x == r)
    }

    fn quorum(&self) -> usize {
        quorum(self.roster.len())
    }

    fn header(&self, body: Body) -> Message {
        Message {
            term: self.term,
            sender: self.me,
            plan: self.plan,
            progress: self.progress,
            body,
        }
    }

    fn hold_target(&self) -> HoldTarget {
        if self.both_hold {
            HoldTarget::Standby
        } else {
            HoldTarget::Safed
        }
    }

    /// Handle one input. See the module documentation for the batch contract.
    pub fn on_event(&mut self, now: u64, rand: u32, input: Input) -> Effects {
        let before = self.persisted();
        let mut out = Out {
            effects: Effects::new(),
            dropped: 0,
        };
        match input {
            Input::Tick => self.tick(now, rand, &mut out),
            Input::GroundTc => self.ground_tc(now, &mut out),
            Input::Message(m) => self.message(now, rand, m, &mut out),
            Input::Progress { plan, progress, next } => {
                self.plan = plan;
                self.progress = progress;
                self.next_function = next;
            }
            Input::Grippers { both_hold } => self.both_hold = both_hold,
        }
        // Check the timers after every input, so that a host feeding only messages still
        // runs them.
        if !matches!(input, Input::Tick) {
            self.tick(now, rand, &mut out);
        }
        let after = self.persisted();
        let mut effects = Effects::new();
        if after != before {
            // First in the batch: durable before any send of the batch.
            if effects.push(Effect::Persist(after)).is_err() {
                out.dropped += 1;
            }
        }
        for e in out.effects {
            if effects.push(e).is_err() {
                out.dropped += 1;
            }
        }
        self.counters.effects_dropped = self.counters.effects_dropped.saturating_add(out.dropped);
        effects
    }

    fn ground_tc(&mut self, now: u64, out: &mut Out) {
        self.ground_last = now;
        if self.ground_seen {
            return;
        }
        self.ground_seen = true;
        out.push(Effect::Event(TeamEvent::GroundRegained { term: self.term }));
        if self.role == Role::Leader {
            out.push(Effect::Event(TeamEvent::SteppedDown {
                term: self.term,
                reason: StepDownReason::GroundRegained,
            }));
        }
        // Obedience ends: no leader, no election, back to the ground's commands.
        self.role = Role::Follower;
        self.leader = None;
        self.election_deadline = u64::MAX;
    }

    fn tick(&mut self, now: u64, rand: u32, out: &mut Out) {
        if self.ground_seen {
            if now.saturating_sub(self.ground_last) < GROUND_LOSS_TIMEOUT_MS {
                return;
            }
            self.ground_seen = false;
            self.election_deadline = now + self.timeout(ELECTION_FIRST_BASE_MS, rand);
            out.push(Effect::Event(TeamEvent::GroundLost));
            // Each robot holds on its own until a leader (if any) says otherwise.
            out.push(Effect::Act(Action::Hold(self.hold_target())));
        }
        match self.role {
            Role::Follower => {
                if now >= self.election_deadline {
                    if self.sticky(now) {
                        // Never stand within an election timeout of hearing a leader or
                        // granting a vote (that leader's lease may still run).
                        self.election_deadline = self.leader_contact.unwrap_or(now) + self.election_timeout(rand);
                    } else {
                        self.start_election(now, rand, out);
                    }
                }
            }
            Role::Candidate => {
                if now >= self.election_deadline {
                    self.start_election(now, rand, out);
                } else if now >= self.next_send {
                    self.next_send = now + VOTE_RETRY_MS;
                    let m = self.header(Body::RequestVote);
                    out.push(Effect::Send { to: Dest::All, msg: m });
                }
            }
            Role::Leader => {
                // Check quorum: step down when no quorum acknowledged for an election
                // timeout (a new leader may be elected elsewhere by then).
                if now.saturating_sub(self.leader_since) >= LEADER_QUORUM_CHECK_MS
                    && self.acked_within(now, LEADER_QUORUM_CHECK_MS) < self.quorum()
                {
                    self.role = Role::Follower;
                    self.leader = None;
                    self.leader_contact = None;
                    self.election_deadline = now + self.election_timeout(rand);
                    out.push(Effect::Event(TeamEvent::SteppedDown {
                        term: self.term,
                        reason: StepDownReason::QuorumLost,
                    }));
                    return;
                }
                if now >= self.next_send {
                    self.next_send = now + HEARTBEAT_PERIOD_MS;
                    self.send_heartbeat(now, out);
                }
            }
        }
    }

    fn start_election(&mut self, now: u64, rand: u32, out: &mut Out) {
        self.term = self.term.saturating_add(1);
        self.voted_for = Some(self.me);
        self.role = Role::Candidate;
        self.leader = None;
        self.votes = 0;
        if let Some(i) = self.index(self.me) {
            self.votes |= 1 << i;
        }
        self.candidacy_start = now;
        self.election_deadline = now + self.election_timeout(rand);
        self.next_send = now + VOTE_RETRY_MS;
        out.push(Effect::Event(TeamEvent::ElectionStarted { term: self.term }));
        let m = self.header(Body::RequestVote);
        out.push(Effect::Send { to: Dest::All, msg: m });
    }

    /// Robots (the leader included) that acknowledged a heartbeat sent within `window`.
    fn acked_within(&self, now: u64, window: u64) -> usize {
        let mut n = 0;
        for (i, r) in self.roster.iter().enumerate() {
            if *r == self.me {
                n += 1;
            } else if let Some(t) = self.acks[i] {
                if now.saturating_sub(t) < window {
                    n += 1;
                }
            }
        }
        n
    }

    fn lease_held(&self, now: u64) -> bool {
        self.acked_within(now, LEADER_LEASE_MS) >= self.quorum()
    }

    /// The directive the leader gives now: CONTINUE the next step only with a lease and
    /// within its own authorisation; HOLD otherwise.
    fn leader_directive(&self, now: u64) -> Directive {
        if !self.lease_held(now) {
            return Directive::Hold;
        }
        let (Some(auth), Some(function)) = (self.auth, self.next_function) else {
            return Directive::Hold;
        };
        let step = self.progress.saturating_add(1);
        match auth.covers(self.plan, step, now) {
            Ok(()) => Directive::Continue { step, function },
            Err(_) => Directive::Hold,
        }
    }

    fn send_heartbeat(&mut self, now: u64, out: &mut Out) {
        let directive = self.leader_directive(now);
        let m = self.header(Body::LeaderHeartbeat {
            stamp: now as u32,
            directive,
        });
        out.push(Effect::Send { to: Dest::All, msg: m });
        // The leader is a robot of the team too: it obeys its own directive.
        self.obey(now, self.me, m.plan, directive, out);
    }

    fn become_leader(&mut self, now: u64, out: &mut Out) {
        self.role = Role::Leader;
        self.leader = Some(self.me);
        self.leader_since = now;
        self.acks = [None; ROSTER_MAX];
        // Voters granted at or after the candidacy started: that is their first ack.
        for i in 0..self.roster.len() {
            if self.votes & (1 << i) != 0 {
                self.acks[i] = Some(self.candidacy_start);
            }
        }
        out.push(Effect::Event(TeamEvent::LeaderElected {
            term: self.term,
            leader: self.me,
        }));
        self.next_send = now + HEARTBEAT_PERIOD_MS;
        self.send_heartbeat(now, out);
    }

    /// Adopt a higher term seen in a message: follower, no vote, no leader yet.
    fn adopt_term(&mut self, term: u32, out: &mut Out) {
        if self.role == Role::Leader {
            out.push(Effect::Event(TeamEvent::SteppedDown {
                term: self.term,
                reason: StepDownReason::HigherTerm,
            }));
        }
        self.term = term;
        self.voted_for = None;
        self.role = Role::Follower;
        self.leader = None;
    }

    fn message(&mut self, now: u64, rand: u32, m: Message, out: &mut Out) {
        if m.sender == self.me || self.index(m.sender).is_none() {
            self.counters.foreign = self.counters.foreign.saturating_add(1);
            return;
        }
        match m.body {
            Body::RequestVote => self.request_vote(now, rand, m, out),
            Body::Vote { candidate, granted } => {
                if m.term > self.term {
                    self.adopt_term(m.term, out);
                    if !self.ground_seen {
                        self.election_deadline = now + self.election_timeout(rand);
                    }
                    return;
                }
                if m.term < self.term {
                    self.counters.stale = self.counters.stale.saturating_add(1);
                    return;
                }
                if self.role == Role::Candidate && granted && candidate == self.me {
                    if let Some(i) = self.index(m.sender) {
                        self.votes |= 1 << i;
                    }
                    if self.votes.count_ones() as usize >= self.quorum() {
                        self.become_leader(now, out);
                    }
                }
            }
            Body::LeaderHeartbeat { stamp, directive } => self.heartbeat(now, rand, m, stamp, directive, out),
            Body::HeartbeatAck { stamp, ok } => {
                if m.term > self.term {
                    self.adopt_term(m.term, out);
                    if !self.ground_seen {
                        self.election_deadline = now + self.election_timeout(rand);
                    }
                    return;
                }
                if m.term < self.term || !ok || self.role != Role::Leader {
                    self.counters.stale = self.counters.stale.saturating_add(1);
                    return;
                }
                // Reconstruct the send time from the 32-bit stamp (ages < 49 days).
                let age = u64::from((now as u32).wrapping_sub(stamp));
                let Some(sent) = now.checked_sub(age) else {
                    return;
                };
                if let Some(i) = self.index(m.sender) {
                    if self.acks[i].is_none_or(|t| t < sent) {
                        self.acks[i] = Some(sent);
                    }
                }
            }
        }
    }

    fn request_vote(&mut self, now: u64, rand: u32, m: Message, out: &mut Out) {
        if self.ground_seen || self.role == Role::Leader {
            // The ground commands this robot: it takes no part in elections. A leader
            // holds a quorum acknowledged within an election timeout (else it would have
            // stepped down): it ignores candidates until it learns a higher term.
            return;
        }
        let repeat = m.term == self.term && self.voted_for == Some(m.sender);
        if self.sticky(now) && self.role != Role::Candidate && !repeat {
            // A leader (or boot, or a vote granted) too recently: that leader's lease may
            // still run. Ignore the request without adopting its term (a repeated request
            // of the candidate it voted for is answered again: the vote may have been lost).
            return;
        }
        if m.term < self.term {
            self.counters.stale = self.counters.stale.saturating_add(1);
            let reply = self.header(Body::Vote {
                candidate: m.sender,
                granted: false,
            });
            out.push(Effect::Send {
                to: Dest::To(m.sender),
                msg: reply,
            });
            return;
        }
        if m.term > self.term {
            self.adopt_term(m.term, out);
        }
        let free = self.voted_for.is_none() || self.voted_for == Some(m.sender);
        let granted = free && m.plan == self.plan && m.progress >= self.progress;
        if granted && self.voted_for.is_none() {
            self.voted_for = Some(m.sender);
            // The candidate may win and count this vote in its lease (from the start of its
            // candidacy): no other vote (nor own candidacy) before an election timeout. A
            // repeated grant to the same candidate changes nothing.
            self.leader_contact = Some(now);
            self.election_deadline = now + self.election_timeout(rand);
        }
        let reply = self.header(Body::Vote {
            candidate: m.sender,
            granted,
        });
        out.push(Effect::Send {
            to: Dest::To(m.sender),
            msg: reply,
        });
    }

    fn heartbeat(&mut self, now: u64, rand: u32, m: Message, stamp: u32, directive: Directive, out: &mut Out) {
        if m.term < self.term {
            self.counters.stale = self.counters.stale.saturating_add(1);
            self.refuse(m.term, m.sender, RefuseReason::StaleTerm, out);
            // Tell the stale leader about the newer term.
            let reply = self.header(Body::HeartbeatAck { stamp, ok: false });
            out.push(Effect::Send {
                to: Dest::To(m.sender),
                msg: reply,
            });
            return;
        }
        if m.term > self.term {
            self.adopt_term(m.term, out);
        }
        if self.role == Role::Leader {
            // Two leaders in one term cannot happen (one vote per term, majority quorum);
            // counted, never obeyed.
            self.counters.rival_leader = self.counters.rival_leader.saturating_add(1);
            return;
        }
        if self.ground_seen {
            self.refuse(m.term, m.sender, RefuseReason::GroundPresent, out);
            return;
        }
        self.role = Role::Follower;
        if self.leader != Some(m.sender) {
            self.leader = Some(m.sender);
            out.push(Effect::Event(TeamEvent::LeaderElected {
                term: self.term,
                leader: m.sender,
            }));
        }
        self.leader_contact = Some(now);
        self.election_deadline = now + self.election_timeout(rand);
        let reply = self.header(Body::HeartbeatAck { stamp, ok: true });
        out.push(Effect::Send {
            to: Dest::To(m.sender),
            msg: reply,
        });
        self.obey(now, m.sender, m.plan, directive, out);
    }

    /// Execute a directive of the current term's leader (itself included) if the robot's
    /// own rules allow it.
    fn obey(&mut self, now: u64, leader: RobotId, plan: PlanRef, directive: Directive, out: &mut Out) {
        if self.executed == Some((self.term, directive)) {
            return;
        }
        let action = match directive {
            Directive::Hold => Action::Hold(self.hold_target()),
            Directive::Continue { step, function } => {
                if step <= self.progress {
                    // Already done here: nothing to do, nothing to refuse.
                    return;
                }
                let check = if plan != self.plan || Some(function) != self.next_function {
                    Err(RefuseReason::PlanMismatch)
                } else if step != self.progress.saturating_add(1) {
                    Err(RefuseReason::WrongStep)
                } else {
                    match self.auth {
                        Some(a) => a.covers(self.plan, step, now),
                        None => Err(RefuseReason::NotAuthorised),
                    }
                };
                if let Err(reason) = check {
                    self.refuse(self.term, leader, reason, out);
                    return;
                }
                Action::Continue {
                    plan: self.plan,
                    step,
                    function,
                }
            }
        };
        self.executed = Some((self.term, directive));
        out.push(Effect::Act(action));
        out.push(Effect::Event(TeamEvent::DirectiveExecuted {
            term: self.term,
            leader,
            directive,
        }));
    }

    fn refuse(&mut self, term: u32, from: RobotId, reason: RefuseReason, out: &mut Out) {
        self.counters.refused = self.counters.refused.saturating_add(1);
        if self.refused != Some((term, reason)) {
            self.refused = Some((term, reason));
            out.push(Effect::Event(TeamEvent::DirectiveRefused { term, from, reason }));
        }
    }
}

#[cfg(test)]
#[path = "node_tests.rs"]
mod tests;
