//! Service 211, team coordination without the ground (docs/team.md): the obsw hosts a
//! `mmic_team::Node` (leader selection with terms, quorum and lease; limited authority).
//!
//! - Every valid ground TC counts as ground contact (`Input::GroundTc`, fed at the next
//!   [`Obsw::team_poll`]).
//! - The platform calls [`Obsw::team_poll`] after every TC and every control period, and
//!   [`Obsw::team_packet`] for every packet received on the inter-robot link. Both execute
//!   the node's effects in order through a [`TeamLink`]: `Persist` first (the platform makes
//!   term and vote durable before it returns; a failed persist is treated as a reset: the
//!   rest of the batch is dropped and the node restarts from the last durable state), then
//!   sends (team packets: APID `TEAM_APID`, TM[211,1], the team message as source data),
//!   actions and events (PUS 5).
//! - HOLD: finish the running primitive, then STANDBY if both grippers hold, SAFED
//!   otherwise, through the same mode machinery as the FDIR's deferred mode changes.
//!   "Both grippers hold" = the controller computes a configuration state (a state is the
//!   pair of faces the two grippers hold).
//! - CONTINUE: the obsw has no on-board plan yet (plans run from the ground), so it never
//!   reports a plan or a next step to the node: a leader only ever orders HOLD and a
//!   follower's node never outputs CONTINUE. Should one arrive it is not executed, counted
//!   (`continue_not_executed`) and the robot holds.
//! - TCs: TEAM_AUTHORISE [211,3], TEAM_ROSTER [211,4], TEAM_STATUS_REQUEST [211,5]; the
//!   TEAM_STATUS report TM[211,2] also goes out every `STATUS_PERIOD_MS` while a roster is
//!   set.

use mib::events::eid;
use mib::modes::robot_mode;
use mib::params::{pid, NotSupplied, Source, Supplied};
use mib::robot::Side;
use mib::tc::service;
use mib::team::{
    PlanStep, MAX_AUTHORISED_STEPS, ROSTER_MAX, STATUS_PERIOD_MS, TEAM_APID, TEAM_SERVICE, TEAM_SUBSERVICE_MESSAGE,
    TEAM_SUBSERVICE_PLAN_STEP,
};
use mib_wire::{ev, tm};
use mmic_domain::controller::Action as DomainAction;
use mmic_team::node::{RefuseReason, StepDownReason};
use mmic_team::wire::MAX_LEN;
use mmic_team::TeamEvent;
use mmic_team::{
    Action, Authorisation, Dest, Directive, Effect, HoldTarget, Input, Message, Node, Persisted, PlanRef, TeamFunction,
};

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::obsw::{Exec, Obsw};
use crate::request::unknown;
use crate::robot::{Ports, Robot};
use crate::services::{Component, Contract};
use crate::time::OnboardTime;
use crate::tm::{TmSink, TmStore, TmWriter};

/// What the platform provides to the team logic: durable storage of the team record
/// (term, vote, roster, authorisation), and the inter-robot link.
pub trait TeamLink {
    /// Makes `r` durable (written and synced) before returning; false if that failed.
    fn persist(&mut self, r: &TeamRecord) -> bool;
    /// Sends one team packet to one robot of the roster or to every other one; returns the
    /// number of datagrams handed to the link.
    fn send(&mut self, to: Dest, packet: &[u8]) -> u32;
}

/// The ground's authorisation as stored: the expiry in Unix ms, so that it means the same
/// after a reset (on-board time restarts at 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoredAuth {
    pub plan: PlanRef,
    pub first_step: u16,
    pub max_steps: u8,
    pub expires_unix_ms: u64,
}

/// Everything of the team that survives a reset (the platform writes it whole, synced,
/// before `persist` returns).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TeamRecord {
    pub persisted: Persisted,
    /// Empty: no roster.
    pub roster: heapless::Vec<u8, ROSTER_MAX>,
    pub auth: Option<StoredAuth>,
    /// The uploaded, hash-checked plan of the authorisation.
    pub plan: Option<StoredPlan>,
}

/// Steps a plan holds (the most an authorisation allows).
pub const PLAN_CAPACITY: usize = MAX_AUTHORISED_STEPS as usize;

/// The plan as stored: its steps and how many were started since the upload.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StoredPlan {
    pub id: u16,
    pub steps: heapless::Vec<PlanStep, PLAN_CAPACITY>,
    /// Steps started on a CONTINUE since the upload (never more than the authorisation's).
    pub done: u8,
}

/// Why a CONTINUE was not executed (PLAN_STEP_REFUSED reason codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepRefusal {
    /// No hash-checked plan of that ID.
    NoPlan,
    /// Not the next step, beyond the authorised count, or expired.
    NotAuthorised,
    /// The robot is not in the step's initial state (or not holding: SAFED).
    InitialState,
    /// Another action or a mode transition runs.
    Busy,
    /// The step is not an action a team may run.
    Forbidden,
    /// The action refused to start (data in the failure the event names).
    Refused,
}

impl StepRefusal {
    pub const fn code(self) -> u8 {
        match self {
            StepRefusal::NoPlan => 0,
            StepRefusal::NotAuthorised => 1,
            StepRefusal::InitialState => 2,
            StepRefusal::Busy => 3,
            StepRefusal::Forbidden => 4,
            StepRefusal::Refused => 5,
        }
    }
}

/// The domain action of a plan step: team functions only (UNBOLT is refused by type,
/// `TeamFunction` has no such variant; STOP is no step).
pub fn step_action(s: &PlanStep) -> Option<(TeamFunction, DomainAction)> {
    let f = TeamFunction::from_code(s.function).ok()?;
    let side = |v: i32| match v {
        0 => Some(Side::A),
        1 => Some(Side::B),
        _ => None,
    };
    let u8_of = |v: i32| u8::try_from(v).ok();
    let u16_of = |v: i32| u16::try_from(v).ok();
    let [a0, a1] = s.args;
    let action = match f {
        TeamFunction::Reconfigure => DomainAction::Reconfigure {
            from: u8_of(a0)?,
            to: u8_of(a1)?,
        },
        TeamFunction::BoltFace => DomainAction::BoltFace {
            side: side(a0)?,
            pairs: u8_of(a1)?,
        },
        TeamFunction::Home => DomainAction::Home,
        TeamFunction::MoveArm => DomainAction::MoveArm {
            side: side(a0)?,
            pwm: u16_of(a1)?,
        },
        TeamFunction::MoveGripper => DomainAction::MoveGripper {
            side: side(a0)?,
            pwm: u16_of(a1)?,
        },
        TeamFunction::RotateHip => DomainAction::RotateHip {
            cdeg: i16::try_from(a0).ok()?,
        },
        TeamFunction::BoltPair => DomainAction::BoltPair {
            side: side(a0)?,
            pair: u8_of(a1)?,
        },
        TeamFunction::Stop => return None,
    };
    Some((f, action))
}

/// How the platform found the team record at start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadStatus {
    Restored,
    /// No record (first start).
    None,
    /// A record that could not be read: the robot starts from term 0 without roster or
    /// authorisation (the platform logs why).
    Corrupt,
}

impl LoadStatus {
    pub const fn code(self) -> u8 {
        match self {
            LoadStatus::Restored => 0,
            LoadStatus::None => 1,
            LoadStatus::Corrupt => 2,
        }
    }
}

/// Why an inter-robot packet was refused (HK TEAM parameter `TEAM_REJ_MALFORMED + code`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TeamReject {
    /// Authentic (or lab bare) but not a TM[211,1] of `TEAM_APID` with a valid team
    /// message, or no roster set.
    Malformed,
    /// Too short for the security header and MAC.
    Truncated,
    /// Not a peer, or a message whose sender is not the authenticated one.
    UnknownSender,
    /// AES-GCM tag mismatch.
    BadMac,
    /// Counter already seen or too far behind.
    Replay,
    /// The counter state could not be made durable.
    StoreFailed,
}

/// Number of [`TeamReject`] reasons.
pub const TEAM_REJECT_REASONS: usize = 6;

impl TeamReject {
    pub const fn code(self) -> u8 {
        match self {
            TeamReject::Malformed => 0,
            TeamReject::Truncated => 1,
            TeamReject::UnknownSender => 2,
            TeamReject::BadMac => 3,
            TeamReject::Replay => 4,
            TeamReject::StoreFailed => 5,
        }
    }
}

impl core::fmt::Display for TeamReject {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            TeamReject::Malformed => "not a valid team packet",
            TeamReject::Truncated => "too short for the security header and MAC",
            TeamReject::UnknownSender => "unknown sender",
            TeamReject::BadMac => "MAC verification failed",
            TeamReject::Replay => "replayed counter",
            TeamReject::StoreFailed => "counter state not durable",
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[211,3]: authorisation for a leader to order CONTINUE.
    Authorise(Authorisation, u32),
    /// TC[211,4]: roster (robot numbers in order, 0 = unused slot).
    Roster([u8; ROSTER_MAX]),
    /// TC[211,5]: report TM[211,2].
    Status,
    /// TC[211,6]: one step of the authorised plan (plan ID, step).
    PlanStep(u16, PlanStep),
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        match tc.subservice {
            3 => {
                let x = mib_wire::args::TeamAuthorise::of(&tc.args);
                Ok(Request::Authorise(
                    Authorisation {
                        plan: PlanRef {
                            id: x.plan_id,
                            hash: x.plan_hash,
                        },
                        first_step: x.first_step,
                        max_steps: x.max_steps,
                        expires_at: 0,
                    },
                    x.validity_s,
                ))
            }
            4 => {
                let x = mib_wire::args::TeamRoster::of(&tc.args);
                let r: [u8; ROSTER_MAX] = [
                    x.robot_1, x.robot_2, x.robot_3, x.robot_4, x.robot_5, x.robot_6, x.robot_7, x.robot_8,
                ];
                Ok(Request::Roster(r))
            }
            5 => Ok(Request::Status),
            TEAM_SUBSERVICE_PLAN_STEP => {
                let x = mib_wire::args::TeamPlanStep::of(&tc.args);
                Ok(Request::PlanStep(
                    x.plan_id,
                    PlanStep {
                        step: x.step,
                        function: x.function,
                        args: [x.arg0, x.arg1],
                        initial_state: x.initial_state,
                    },
                ))
            }
            _ => Err(unknown(tc)),
        }
    }
}

/// Counters of the team hosting (besides the node's own).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TeamCounters {
    /// Inter-robot packets that were not a valid team packet.
    pub bad_packets: u32,
    /// Persists the platform could not make durable (each treated as a reset).
    pub persist_failed: u32,
    /// Effects dropped after a failed persist.
    pub effects_dropped: u32,
    /// CONTINUE orders not executed (no on-board plan; the robot held instead).
    pub continue_not_executed: u32,
    /// Team packets that did not fit a packet buffer (never expected).
    pub send_failed: u32,
    /// Inter-robot datagrams sent.
    pub pkt_sent: u32,
    /// Inter-robot packets accepted and given to the node.
    pub pkt_received: u32,
    /// Inter-robot packets refused, by [`TeamReject::code`].
    pub rejected: [u32; TEAM_REJECT_REASONS],
    /// ELECTION_STARTED raised.
    pub elections: u32,
    /// DIRECTIVE_EXECUTED raised.
    pub dir_executed: u32,
    /// Refusals and foreign messages counted by nodes that were replaced (new roster,
    /// restart after a failed persist), so that the HK counts stay monotonic.
    pub refused_before: u32,
    pub foreign_before: u32,
}

/// The team state kept by the obsw.
pub struct Team {
    me: u8,
    node: Option<Node>,
    roster: heapless::Vec<u8, ROSTER_MAX>,
    /// Last term and vote the platform made durable (restored at boot).
    durable: Persisted,
    /// The ground's authorisation (kept here so that a new roster keeps it).
    auth: Option<Authorisation>,
    pub(crate) ground_tc: bool,
    both_hold: Option<bool>,
    next_status: u64,
    pub(crate) tmw: TmWriter,
    pub counters: TeamCounters,
    /// Roster or authorisation changed and not yet durable (written at the next poll).
    dirty: bool,
    /// Last time a TEAM_PACKET_REJECTED was raised per reason (one per control period).
    reject_reported: [Option<u64>; TEAM_REJECT_REASONS],
    /// Steps of the authorised plan uploaded so far (slot = step - first step).
    slots: [Option<PlanStep>; PLAN_CAPACITY],
    /// The plan, once every authorised step is uploaded and the hash matches.
    plan: Option<StoredPlan>,
    /// The node must be told the plan progress at the next poll.
    progress_dirty: bool,
    /// A step waiting for the robot to be idle and OPERATIONAL (true: OPERATIONAL was
    /// asked for, from STANDBY).
    step_pending: Option<(u16, bool)>,
    /// The step whose action runs, with the fault count at its start.
    step_running: Option<(u16, u32)>,
    /// A hold ordered while an action ran: applied when it has ended.
    hold_after_run: bool,
}

impl Team {
    /// The parameters the MIB names the team the source of.
    pub fn param(&self, id: u16) -> Supplied {
        let c = &self.counters;
        let node = self.node.as_ref();
        let nc = node.map(Node::counters).unwrap_or_default();
        let rej = |r: TeamReject| i64::from(c.rejected[usize::from(r.code())]);
        Ok(Some(match id {
            pid::TEAM_TERM => i64::from(node.map_or(self.durable.term, Node::term)),
            pid::TEAM_ROLE => i64::from(node.map_or(0, |n| n.role().code())),
            pid::TEAM_LEADER => i64::from(node.and_then(Node::leader).unwrap_or(0)),
            pid::TEAM_GROUND_SEEN => i64::from(node.is_none_or(Node::ground_seen)),
            pid::TEAM_PKT_SENT => i64::from(c.pkt_sent),
            pid::TEAM_PKT_RECEIVED => i64::from(c.pkt_received),
            pid::TEAM_REJ_MALFORMED => i64::from(c.bad_packets).wrapping_add(rej(TeamReject::Malformed)),
            pid::TEAM_REJ_TRUNCATED => rej(TeamReject::Truncated),
            pid::TEAM_REJ_UNKNOWN_SENDER => {
                rej(TeamReject::UnknownSender) + i64::from(c.foreign_before.wrapping_add(nc.foreign))
            }
            pid::TEAM_REJ_BAD_MAC => rej(TeamReject::BadMac),
            pid::TEAM_REJ_REPLAY => rej(TeamReject::Replay),
            pid::TEAM_REJ_STORE_FAILED => rej(TeamReject::StoreFailed),
            pid::TEAM_ELECTIONS => i64::from(c.elections),
            pid::TEAM_DIR_EXECUTED => i64::from(c.dir_executed),
            pid::TEAM_DIR_REFUSED => i64::from(c.refused_before.wrapping_add(nc.refused)),
            pid::TEAM_PERSIST_FAILED => i64::from(c.persist_failed),
            pid::TEAM_STEPS_EXECUTED => i64::from(self.plan.as_ref().map_or(0, |p| p.done)),
            _ => return Err(NotSupplied(id)),
        }))
    }

    pub fn new(me: u8, time: OnboardTime) -> Self {
        Team {
            me,
            node: None,
            roster: heapless::Vec::new(),
            durable: Persisted::default(),
            auth: None,
            ground_tc: false,
            both_hold: None,
            next_status: 0,
            tmw: TmWriter::new(TEAM_APID, time),
            counters: TeamCounters::default(),
            dirty: false,
            reject_reported: [None; TEAM_REJECT_REASONS],
            slots: [None; PLAN_CAPACITY],
            plan: None,
            progress_dirty: false,
            step_pending: None,
            step_running: None,
            hold_after_run: false,
        }
    }

    /// The plan step `step` of the loaded plan, if it is the next one to run and within
    /// the authorisation (count; the expiry is the node's and the caller's check).
    fn next_step(&self) -> Option<PlanStep> {
        let (a, p) = (self.auth?, self.plan.as_ref()?);
        if p.id != a.plan.id || p.done >= a.max_steps {
            return None;
        }
        p.steps.get(usize::from(p.done)).copied()
    }

    /// What the node must know of the plan: its reference, the progress (steps done,
    /// counted from the plan's start) and the next step's function.
    fn progress_input(&self) -> Option<Input> {
        let (a, p) = (self.auth?, self.plan.as_ref()?);
        let next = self.next_step().and_then(|s| step_action(&s)).map(|(f, _)| f);
        Some(Input::Progress {
            plan: a.plan,
            progress: a.first_step.saturating_sub(1).saturating_add(u16::from(p.done)),
            next,
        })
    }

    /// The record as it must be durable now (the platform writes it whole).
    pub fn record(&self) -> TeamRecord {
        let epoch = self.tmw.time.epoch_unix_ms;
        TeamRecord {
            persisted: self.durable,
            roster: if self.node.is_some() {
                self.roster.clone()
            } else {
                heapless::Vec::new()
            },
            auth: self.auth.map(|a| StoredAuth {
                plan: a.plan,
                first_step: a.first_step,
                max_steps: a.max_steps,
                expires_unix_ms: epoch.saturating_add(a.expires_at),
            }),
            plan: self.plan.clone(),
        }
    }

    /// Replaces the node, keeping its counters' totals.
    fn set_node(&mut self, node: Option<Node>) {
        if let Some(old) = &self.node {
            let c = old.counters();
            self.counters.refused_before = self.counters.refused_before.wrapping_add(c.refused);
            self.counters.foreign_before = self.counters.foreign_before.wrapping_add(c.foreign);
        }
        self.node = node;
    }

    /// The node, once a roster is set.
    pub fn node(&self) -> Option<&Node> {
        self.node.as_ref()
    }
}

fn step_down_code(r: StepDownReason) -> u8 {
    match r {
        StepDownReason::GroundRegained => 0,
        StepDownReason::HigherTerm => 1,
        StepDownReason::QuorumLost => 2,
    }
}

fn refuse_code(r: RefuseReason) -> u8 {
    match r {
        RefuseReason::StaleTerm => 0,
        RefuseReason::GroundPresent => 1,
        RefuseReason::NotAuthorised => 2,
        RefuseReason::Expired => 3,
        RefuseReason::PlanMismatch => 4,
        RefuseReason::WrongStep => 5,
    }
}

fn directive_args(d: Directive) -> (u8, u16) {
    match d {
        Directive::Hold => (1, 0),
        Directive::Continue { step, .. } => (2, step),
    }
}

impl Team {
    /// Restores the team record at start (term, vote, roster, authorisation; an expired
    /// authorisation or a roster the node refuses is dropped) and raises TEAM_STATE_LOADED.
    pub(crate) fn restore<S: TmStore>(
        &mut self,
        now: u64,
        status: LoadStatus,
        r: &TeamRecord,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) {
        self.durable = r.persisted;
        let epoch = self.tmw.time.epoch_unix_ms;
        self.auth = r.auth.and_then(|a| {
            let expires_at = a.expires_unix_ms.checked_sub(epoch)?;
            (expires_at > now).then_some(Authorisation {
                plan: a.plan,
                first_step: a.first_step,
                max_steps: a.max_steps,
                expires_at,
            })
        });
        // The plan only with its (unexpired) authorisation, and only if it still hashes to it.
        self.plan = r.plan.clone().filter(|p| {
            self.auth.is_some_and(|a| {
                a.plan.id == p.id
                    && p.steps.len() == usize::from(a.max_steps)
                    && mib::team::plan_hash(p.id, &p.steps) == a.plan.hash
            })
        });
        self.progress_dirty = self.plan.is_some();
        if !r.roster.is_empty() {
            // A stored roster was accepted once; should the node refuse it now, the
            // robot starts without one (the event says roster 0).
            let _ = self.set_roster(now, &r.roster);
        }
        let roster = if self.node.is_some() { self.roster.len() } else { 0 };
        let plan = self.auth.map_or(0, |a| a.plan.id);
        self.dirty = false;
        let e = ev::TeamStateLoaded {
            status: status.code(),
            term: self.durable.term,
            roster: u8::try_from(roster).unwrap_or(u8::MAX),
            plan,
        };
        dl.raise(now, e, sink);
    }

    /// An inter-robot packet refused before the node saw it (by the platform's
    /// authentication, or here): counted, and TEAM_PACKET_REJECTED at most once per
    /// reason and control period (the event service throttles further).
    pub(crate) fn rejected<S: TmStore>(
        &mut self,
        now: u64,
        reason: TeamReject,
        sender: u8,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) {
        let i = usize::from(reason.code());
        let c = &mut self.counters.rejected[i];
        *c = c.wrapping_add(1);
        let total = *c;
        let period = u64::from(mib::config::CONTROL_PERIOD_MS);
        if self.reject_reported[i].is_some_and(|t| now < t + period) {
            return;
        }
        self.reject_reported[i] = Some(now);
        let e = ev::TeamPacketRejected {
            reason: reason.code(),
            sender,
            total,
        };
        dl.raise(now, e, sink);
    }

    /// Sets the team roster (ground TC TEAM_ROSTER, or the platform's configuration).
    /// The node starts from the durable term and vote; boot and upload count as ground
    /// contact.
    pub fn set_roster(&mut self, now: u64, roster: &[u8]) -> Result<(), mmic_team::node::RosterError> {
        let node = Node::restore(self.me, roster, self.durable, now)?;
        self.set_node(Some(node));
        self.dirty = true;
        self.progress_dirty = true;
        self.roster.clear();
        for r in roster.iter().take(ROSTER_MAX) {
            // At most ROSTER_MAX (checked by the node above).
            let _ = self.roster.push(*r);
        }
        if let (Some(a), Some(n)) = (self.auth, self.node.as_mut()) {
            // Was accepted when uploaded; an expired one is simply not re-applied.
            let _ = n.authorise(now, a);
        }
        self.next_status = now;
        Ok(())
    }

    /// Earliest time the team logic has work (node timers, status report).
    pub fn next_deadline(&self) -> u64 {
        match &self.node {
            Some(n) => n.next_deadline().min(self.next_status),
            None => u64::MAX,
        }
    }
}

/// A packet of the inter-robot link, by what it is for.
enum Packet<'p> {
    /// The on-board plan's progress announcement of another robot (its source data).
    Progress(&'p [u8]),
    /// A team message for the node.
    Message(Message),
    /// Refused (the reason, the sender it names).
    Refused(TeamReject, u8),
}

/// The team's own requests (service 211): authorisation, roster, status report, plan
/// steps. What the node decides joins the robot's modes and actions (`Obsw::team_poll`).
impl Component for Team {
    const CONTRACT: Contract = Contract::new("team", Some(service::TEAM), &[Source::Team]);
    type Request<'a> = Request;
    type Output = ();
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<(), Failure> {
        match r {
            Request::Authorise(mut a, validity_s) => {
                a.expires_at = now.saturating_add(u64::from(validity_s) * 1000);
                if let Some(n) = self.node.as_mut() {
                    n.authorise(now, a)
                        .map_err(|_| Failure::arg_out_of_range(4, validity_s as i32))?;
                }
                if self.auth.map(|o| (o.plan, o.first_step, o.max_steps)) != Some((a.plan, a.first_step, a.max_steps)) {
                    // Another authorisation: its steps must be uploaded anew.
                    self.slots = [None; PLAN_CAPACITY];
                    self.plan = None;
                }
                self.auth = Some(a);
                self.dirty = true;
            }
            Request::Roster(slots) => {
                let mut roster: heapless::Vec<u8, ROSTER_MAX> = heapless::Vec::new();
                for r in slots.iter().filter(|r| **r != 0) {
                    // At most ROSTER_MAX slots.
                    let _ = roster.push(*r);
                }
                self.set_roster(now, &roster)
                    .map_err(|_| Failure::arg_out_of_range(0, i32::from(slots[0])))?;
            }
            Request::Status => self.status(now, dl, sink),
            Request::PlanStep(id, step) => self.plan_step(now, id, step, dl, sink)?,
        }
        Ok(())
    }
}

impl Team {
    /// Emits the TEAM_STATUS report TM[211,2].
    fn status<S: TmStore>(&self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let mut r = tm::TeamStatus {
            term: self.durable.term,
            role: 0,
            leader: 0,
            ground_seen: 1,
            lease: 0,
            voted_for: 0,
            auth_plan: 0,
            auth_first_step: 0,
            auth_steps: 0,
            auth_left_s: 0,
            refused: 0,
            foreign: 0,
            roster: heapless::Vec::new(),
        };
        if let Some(n) = &self.node {
            let s = n.status(now);
            r.term = s.term;
            r.role = s.role.code();
            r.leader = s.leader.unwrap_or(0);
            r.ground_seen = u8::from(s.ground_seen);
            r.lease = u8::from(s.lease);
            r.voted_for = s.voted_for.unwrap_or(0);
            r.refused = s.counters.refused;
            r.foreign = s.counters.foreign;
            for robot in s.roster.iter() {
                // Same capacity (ROSTER_MAX).
                let _ = r.roster.push(tm::TeamStatusRoster { robot: *robot });
            }
        }
        if let Some(a) = self.auth {
            r.auth_plan = a.plan.id;
            r.auth_first_step = a.first_step;
            r.auth_steps = a.max_steps;
            r.auth_left_s = (a.expires_at.saturating_sub(now) / 1000).min(u64::from(u32::MAX)) as u32;
        }
        dl.emit_tm(now, &r, sink);
    }

    /// TC[211,6]: one step of the authorised plan. When every authorised step is there,
    /// their hash must be the authorisation's plan hash: the plan is loaded (PLAN_UPLOADED,
    /// the node learns the plan) or every step is dropped (PLAN_HASH_MISMATCH).
    fn plan_step<S: TmStore>(
        &mut self,
        now: u64,
        id: u16,
        s: PlanStep,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<(), Failure> {
        let not_authorised = Failure::plan_not_authorised(id, s.step);
        let a = self.auth.filter(|a| a.plan.id == id).ok_or(not_authorised.clone())?;
        let i = s.step.checked_sub(a.first_step).map(usize::from);
        let Some(i) = i.filter(|i| *i < usize::from(a.max_steps)) else {
            return Err(not_authorised);
        };
        if step_action(&s).is_none() {
            return Err(Failure::plan_forbidden_function(s.function));
        }
        self.slots[i] = Some(s);
        let n = usize::from(a.max_steps);
        if self.slots[..n].iter().all(Option::is_some) {
            let mut steps: heapless::Vec<PlanStep, PLAN_CAPACITY> = heapless::Vec::new();
            for s in self.slots[..n].iter().flatten() {
                // n <= PLAN_CAPACITY (MAX_AUTHORISED_STEPS, checked by the node).
                let _ = steps.push(*s);
            }
            self.slots = [None; PLAN_CAPACITY];
            let hash = mib::team::plan_hash(id, &steps);
            if hash != a.plan.hash {
                self.plan = None;
                return Err(Failure::plan_hash_mismatch(a.plan.hash, hash));
            }
            self.plan = Some(StoredPlan { id, steps, done: 0 });
            self.dirty = true;
            self.progress_dirty = true;
            let e = ev::PlanUploaded {
                plan: id,
                first_step: a.first_step,
                steps: a.max_steps,
                hash,
            };
            dl.raise(now, e, sink);
        }
        Ok(())
    }

    /// The node's events as PUS 5 events.
    fn event<S: TmStore>(&mut self, now: u64, ev: TeamEvent, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        match ev {
            TeamEvent::GroundLost => {
                let term = self.node.as_ref().map_or(0, |n| n.term());
                dl.raise(now, ev::GroundLost { term }, sink)
            }
            TeamEvent::ElectionStarted { term } => {
                self.counters.elections = self.counters.elections.wrapping_add(1);
                dl.raise(now, ev::ElectionStarted { term }, sink)
            }
            TeamEvent::LeaderElected { term, leader } => dl.raise(now, ev::LeaderElected { term, leader }, sink),
            TeamEvent::SteppedDown { term, reason } => {
                let reason = step_down_code(reason);
                dl.raise(now, ev::SteppedDown { term, reason }, sink)
            }
            TeamEvent::GroundRegained { term } => dl.raise(now, ev::GroundRegained { term }, sink),
            TeamEvent::DirectiveExecuted {
                term,
                leader,
                directive: d,
            } => {
                self.counters.dir_executed = self.counters.dir_executed.wrapping_add(1);
                let (directive, step) = directive_args(d);
                let e = ev::DirectiveExecuted {
                    term,
                    leader,
                    directive,
                    step,
                };
                dl.raise(now, e, sink)
            }
            TeamEvent::DirectiveRefused { term, from, reason } => {
                let reason = refuse_code(reason);
                dl.raise(
                    now,
                    ev::DirectiveRefused {
                        term,
                        sender: from,
                        reason,
                    },
                    sink,
                )
            }
        }
    }

    /// A plan step not executed (CONTINUE_NOT_EXECUTED, PLAN_STEP_REFUSED).
    fn step_refused<S: TmStore>(
        &mut self,
        now: u64,
        plan: u16,
        step: u16,
        why: StepRefusal,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) {
        let c = &mut self.counters;
        c.continue_not_executed = c.continue_not_executed.wrapping_add(1);
        let e = ev::PlanStepRefused {
            plan,
            step,
            reason: why.code(),
        };
        dl.raise(now, e, sink);
    }

    /// A CONTINUE of the node (the leader's, checked by the node against this robot's
    /// own authorisation): run the step if it is the next uploaded one, within the
    /// authorised count, and the robot is in the step's initial state. From STANDBY (a
    /// hold with both grippers holding) the robot first returns to OPERATIONAL; the step
    /// starts when it is there (checked again then).
    fn accept_continue(
        &mut self,
        now: u64,
        plan: PlanRef,
        step: u16,
        function: TeamFunction,
    ) -> Result<(), StepRefusal> {
        let auth = self.auth.ok_or(StepRefusal::NotAuthorised)?;
        if self.plan.as_ref().is_none_or(|p| p.id != plan.id) || auth.plan != plan {
            return Err(StepRefusal::NoPlan);
        }
        let next = self.next_step().ok_or(StepRefusal::NotAuthorised)?;
        if next.step != step || now >= auth.expires_at {
            return Err(StepRefusal::NotAuthorised);
        }
        match step_action(&next) {
            Some((f, _)) if f == function => {}
            _ => return Err(StepRefusal::Forbidden),
        }
        if self.step_pending.is_some() || self.step_running.is_some() {
            return Err(StepRefusal::Busy);
        }
        // Started at the next poll, once the robot is idle (a hold may still be under way).
        self.step_pending = Some((step, false));
        Ok(())
    }

    /// Counts the next step as done, durably, before it moves: a reset never lets a robot
    /// start more than the authorised count. The plan's ID.
    fn count_step(&mut self, link: &mut impl TeamLink) -> Result<u16, StepRefusal> {
        let mut r = self.record();
        if let Some(p) = r.plan.as_mut() {
            p.done = p.done.saturating_add(1);
        }
        if !link.persist(&r) {
            let c = &mut self.counters;
            c.persist_failed = c.persist_failed.wrapping_add(1);
            return Err(StepRefusal::Refused);
        }
        // Counted from here on, whether the action starts or not.
        self.plan = r.plan;
        Ok(self.plan.as_ref().map_or(0, |p| p.id))
    }

    /// Writes the roster and authorisation when they changed. On failure they hold in
    /// RAM until a reset; the ground sees the count in HK TEAM_PERSIST_FAILED.
    fn persist_changes(&mut self, link: &mut impl TeamLink) {
        if core::mem::take(&mut self.dirty) && !link.persist(&self.record()) {
            self.counters.persist_failed = self.counters.persist_failed.wrapping_add(1);
        }
    }

    /// The node's term and vote made durable before its other effects. A failed write
    /// is treated as a reset: the `rest` effects of the batch are dropped (false), the
    /// node restarts from what is durable.
    fn persist(&mut self, now: u64, p: Persisted, rest: usize, link: &mut impl TeamLink) -> bool {
        let mut r = self.record();
        r.persisted = p;
        if link.persist(&r) {
            self.durable = p;
            return true;
        }
        let c = &mut self.counters;
        c.persist_failed = c.persist_failed.wrapping_add(1);
        c.effects_dropped = c.effects_dropped.wrapping_add(rest as u32);
        let roster = self.roster.clone();
        let node = Node::restore(self.me, &roster, self.durable, now).ok();
        self.set_node(node);
        false
    }

    /// What a packet of the inter-robot link is. Parsed by the MIB's checked header
    /// reader: spacepackets' `PusTmReader::new` panics on a packet shorter than its
    /// headers and time stamp, or of another PUS version (0.17.0), and this is input
    /// from another process.
    fn packet<'p>(&mut self, from: Option<u8>, packet: &'p [u8]) -> Packet<'p> {
        let tm = mib_wire::header::TmPacket::parse(packet)
            .ok()
            .filter(|tm| tm.primary.apid == TEAM_APID && tm.service == TEAM_SERVICE);
        // Plan progress announcements belong to the on-board plan, roster or not.
        if let Some(tm) = tm.filter(|tm| tm.subservice == mib::plan::TEAM_SUBSERVICE_PROGRESS) {
            return Packet::Progress(tm.source);
        }
        let msg = match tm {
            Some(tm) if tm.subservice == TEAM_SUBSERVICE_MESSAGE => Message::parse(tm.source).ok(),
            _ => None,
        };
        match (msg, self.node.is_some()) {
            (Some(m), true) if from.is_some_and(|f| f != m.sender) => {
                Packet::Refused(TeamReject::UnknownSender, m.sender)
            }
            (Some(m), true) => {
                self.counters.pkt_received = self.counters.pkt_received.wrapping_add(1);
                Packet::Message(m)
            }
            _ => Packet::Refused(TeamReject::Malformed, from.unwrap_or(0)),
        }
    }

    fn send(&mut self, now: u64, to: Dest, msg: &Message, link: &mut impl TeamLink) {
        let mut body = [0u8; MAX_LEN];
        let mut out = [0u8; mib::config::MAX_PACKET_LEN];
        let packet = match msg.emit(&mut body) {
            Ok(n) => self
                .tmw
                .build(now, TEAM_SERVICE, TEAM_SUBSERVICE_MESSAGE, &body[..n], &mut out),
            Err(_) => None,
        };
        match packet {
            Some(n) => {
                let sent = link.send(to, &out[..n]);
                self.counters.pkt_sent = self.counters.pkt_sent.wrapping_add(sent);
            }
            None => self.counters.send_failed = self.counters.send_failed.wrapping_add(1),
        }
    }
}

impl<S: TmStore> Obsw<S> {
    /// Restores the team record at start (`Team::restore`) and raises TEAM_STATE_LOADED.
    pub fn team_restore(&mut self, now: u64, status: LoadStatus, r: &TeamRecord, sink: &mut impl TmSink) {
        self.team.restore(now, status, r, &mut self.dl, sink);
    }

    /// An inter-robot packet refused before the node saw it (`Team::rejected`).
    pub fn team_rejected(&mut self, now: u64, reason: TeamReject, sender: u8, sink: &mut impl TmSink) {
        self.team.rejected(now, reason, sender, &mut self.dl, sink);
    }

    /// Sets the team roster (`Team::set_roster`).
    pub fn team_set_roster(&mut self, now: u64, roster: &[u8]) -> Result<(), mmic_team::node::RosterError> {
        self.team.set_roster(now, roster)
    }

    /// Emits the TEAM_STATUS report TM[211,2] (`Team::status`).
    pub fn team_status(&mut self, now: u64, sink: &mut impl TmSink) {
        self.team.status(now, &mut self.dl, sink);
    }

    /// Earliest time the team logic has work (`Team::next_deadline`).
    pub fn team_next_deadline(&self) -> u64 {
        self.team.next_deadline()
    }

    /// Feeds pending ground contact, the grippers and the time to the node, executes its
    /// effects and sends the periodic status report (`Team::poll`). Call after every TC
    /// and control period. `rand` comes from the platform (election jitter).
    pub fn team_poll(&mut self, now: u64, rand: u32, link: &mut impl TeamLink, sink: &mut impl TmSink) {
        let (team, robot, mut p) = self.team(sink);
        team.poll(now, rand, robot, link, &mut p);
    }

    /// A packet from the inter-robot link: a TM[211,1] of APID `TEAM_APID` whose source
    /// data is a team message. `from` is the sender the platform authenticated (`None`
    /// in the lab's bare mode); a message claiming another sender is refused
    /// (UNKNOWN_SENDER). Anything else is counted (MALFORMED) and ignored.
    pub fn team_packet(
        &mut self,
        now: u64,
        rand: u32,
        from: Option<u8>,
        packet: &[u8],
        link: &mut impl TeamLink,
        sink: &mut impl TmSink,
    ) {
        let (team, robot, mut p) = self.team(sink);
        team.on_packet(now, rand, from, packet, robot, link, &mut p);
    }

    /// Runs a TC the obsw released itself (PUS 11 schedule): it is not ground contact.
    pub(crate) fn handle_onboard_tc(&mut self, now: u64, raw: &[u8], sink: &mut impl TmSink) {
        let pending = self.team.ground_tc;
        self.handle_tc(now, raw, sink);
        self.team.ground_tc = pending;
    }
}

/// The team's join with the robot: the node's decisions (hold, continue a step) on the
/// robot's modes and actions, and ground contact from the TC path. The robot and the rest
/// of the obsw come as ports for one call (`crate::robot::Ports`: the plan, the downlink).
impl Team {
    /// Feeds pending ground contact, the grippers and the time to the node, executes its
    /// effects and sends the periodic status report.
    pub(crate) fn poll<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        rand: u32,
        robot: &mut Robot,
        link: &mut impl TeamLink,
        p: &mut Ports<S, K>,
    ) {
        if self.node.is_none() {
            self.ground_tc = false;
            return;
        }
        self.persist_changes(link);
        if core::mem::take(&mut self.ground_tc) {
            self.input(now, rand, Input::GroundTc, robot, link, p);
        }
        self.steps(now, robot, link, p);
        if core::mem::take(&mut self.progress_dirty) {
            if let Some(progress) = self.progress_input() {
                self.input(now, rand, progress, robot, link, p);
            }
        }
        let both_hold = robot.computed_state() != mib::robot::STATE_UNKNOWN;
        if self.both_hold != Some(both_hold) {
            self.both_hold = Some(both_hold);
            self.input(now, rand, Input::Grippers { both_hold }, robot, link, p);
        }
        self.input(now, rand, Input::Tick, robot, link, p);
        if now >= self.next_status {
            self.next_status = now + STATUS_PERIOD_MS;
            self.status(now, p.dl, p.sink);
        }
    }

    /// A packet from the inter-robot link ([`Obsw::team_packet`]).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn on_packet<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        rand: u32,
        from: Option<u8>,
        packet: &[u8],
        robot: &mut Robot,
        link: &mut impl TeamLink,
        p: &mut Ports<S, K>,
    ) {
        match self.packet(from, packet) {
            Packet::Progress(source) => {
                p.plan.plan.peer_progress(from, source);
            }
            Packet::Message(m) => self.input(now, rand, Input::Message(m), robot, link, p),
            Packet::Refused(reason, sender) => self.rejected(now, reason, sender, p.dl, p.sink),
        }
    }

    fn input<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        rand: u32,
        input: Input,
        robot: &mut Robot,
        link: &mut impl TeamLink,
        p: &mut Ports<S, K>,
    ) {
        let Some(node) = self.node.as_mut() else { return };
        let effects = node.on_event(now, rand, input);
        for (i, e) in effects.iter().enumerate() {
            match *e {
                Effect::Persist(record) => {
                    if !self.persist(now, record, effects.len() - i - 1, link) {
                        return;
                    }
                }
                Effect::Send { to, msg } => self.send(now, to, &msg, link),
                Effect::Act(a) => self.act(now, a, robot, link, p),
                Effect::Event(ev) => self.event(now, ev, p.dl, p.sink),
            }
        }
    }

    fn act<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        a: Action,
        robot: &mut Robot,
        link: &mut impl TeamLink,
        p: &mut Ports<S, K>,
    ) {
        if matches!(a, Action::Hold(_)) {
            // A hold cancels a step that has not started yet.
            if let Some((step, _)) = self.step_pending.take() {
                let plan = self.plan.as_ref().map_or(0, |p| p.id);
                self.step_refused(now, plan, step, StepRefusal::Refused, p.dl, p.sink);
            }
        }
        if p.plan.plan.state() == mmic_plan::State::Running {
            // An on-board plan the ground started is the ground's approval of its steps: a
            // hold for ground loss (the robot's own or a leader's) does not stop it, and a
            // leader's step never interleaves with it (FDIR still suspends it).
            if let Action::Continue { plan, step, .. } = a {
                self.step_refused(now, plan.id, step, StepRefusal::Busy, p.dl, p.sink);
            }
            return;
        }
        let target = match a {
            Action::Hold(HoldTarget::Standby) => robot_mode::STANDBY,
            Action::Hold(HoldTarget::Safed) => robot_mode::SAFED,
            Action::Continue { plan, step, function } => {
                match self.continue_step(now, plan, step, function, robot, link, p) {
                    Ok(()) => return,
                    Err(why) => {
                        self.step_refused(now, plan.id, step, why, p.dl, p.sink);
                        Self::hold_target(robot)
                    }
                }
            }
        };
        // The running motion finishes first; STANDBY or SAFED is chosen when it has ended
        // (mid-motion no gripper pair holds, so choosing now would always say SAFED).
        if robot.running.is_some() {
            self.hold_after_run = true;
        } else if robot.modes.root_target() != target {
            robot.set_mode(now, target, eid::GROUND_LOST, p);
        }
    }

    fn hold_target(robot: &Robot) -> u32 {
        if robot.computed_state() != mib::robot::STATE_UNKNOWN {
            robot_mode::STANDBY
        } else {
            robot_mode::SAFED
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn continue_step<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        plan: PlanRef,
        step: u16,
        function: TeamFunction,
        robot: &mut Robot,
        link: &mut impl TeamLink,
        p: &mut Ports<S, K>,
    ) -> Result<(), StepRefusal> {
        self.accept_continue(now, plan, step, function)?;
        self.steps(now, robot, link, p);
        Ok(())
    }

    /// Starts plan step `s` (the next one, checked). The step is counted, durably, before
    /// it moves: a reset never lets a robot start more than the authorised count.
    fn start_step<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        s: PlanStep,
        robot: &mut Robot,
        link: &mut impl TeamLink,
        p: &mut Ports<S, K>,
    ) -> Result<(), StepRefusal> {
        if robot.computed_state() != s.initial_state {
            return Err(StepRefusal::InitialState);
        }
        let Some((_, action)) = step_action(&s) else {
            return Err(StepRefusal::Forbidden);
        };
        let plan = self.count_step(link)?;
        match robot.function_request(now, crate::services::function::Request::Start(action), p) {
            Ok(Exec::Action(r)) => {
                robot.running = Some(r.with_token(None));
                self.step_running = Some((s.step, robot.faults.count));
                let leader = self.node.as_ref().and_then(Node::leader).unwrap_or(0);
                let e = ev::PlanStepExecuted {
                    plan,
                    step: s.step,
                    function: s.function,
                    leader,
                };
                p.dl.raise(now, e, p.sink);
                Ok(())
            }
            Ok(_) => Err(StepRefusal::Refused),
            Err(refused) => {
                if let Some(e) = refused.fault {
                    robot.raise_fault(now, e, p);
                }
                Err(StepRefusal::Refused)
            }
        }
    }

    /// Runs a pending step once the robot is OPERATIONAL; ends a running step (the node
    /// learns the progress; after the last authorised step the robot holds).
    fn steps<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        robot: &mut Robot,
        link: &mut impl TeamLink,
        p: &mut Ports<S, K>,
    ) {
        if let Some((_, faults)) = self.step_running {
            if robot.running.is_none() {
                self.step_running = None;
                let ok = robot.faults.count == faults && robot.modes.root() == robot_mode::OPERATIONAL;
                if ok {
                    self.progress_dirty = true;
                    if self.next_step().is_none() {
                        // The authorisation is used up: the robot holds.
                        self.hold_after_run = true;
                    }
                }
            }
        }
        if self.hold_after_run && robot.running.is_none() {
            self.hold_after_run = false;
            // Unless the ground is back (it commands again) or the FDIR or a command
            // already chose the mode.
            let ground = self.ground_tc || self.node.as_ref().is_none_or(Node::ground_seen);
            if !ground
                && robot.transition.is_none()
                && robot.modes.root() == robot_mode::OPERATIONAL
                && robot.modes.root_target() == robot_mode::OPERATIONAL
                && robot.faults.pending_mode.is_none()
            {
                let target = Self::hold_target(robot);
                robot.set_mode(now, target, eid::GROUND_LOST, p);
            }
        }
        if let Some((step, up)) = self.step_pending {
            let plan = self.plan.as_ref().map_or(0, |p| p.id);
            let expired = self.auth.is_none_or(|a| now >= a.expires_at);
            let ground = self.ground_tc || self.node.as_ref().is_none_or(Node::ground_seen);
            if ground {
                // The ground is back (or never left): its first valid TC ends obedience,
                // a step that has not started yet never starts.
                self.step_pending = None;
                self.step_refused(now, plan, step, StepRefusal::Refused, p.dl, p.sink);
            } else if up && robot.modes.root_target() != robot_mode::OPERATIONAL {
                // The FDIR took over on the way up.
                self.step_pending = None;
                self.step_refused(now, plan, step, StepRefusal::Refused, p.dl, p.sink);
            } else if expired {
                self.step_pending = None;
                self.step_refused(now, plan, step, StepRefusal::NotAuthorised, p.dl, p.sink);
            } else if robot.transition.is_none() && robot.running.is_none() {
                let root = robot.modes.root();
                if root == robot_mode::STANDBY && !up && robot.computed_state() != mib::robot::STATE_UNKNOWN {
                    // Holding in STANDBY: back to OPERATIONAL first (the step's state is
                    // checked again when it starts).
                    self.step_pending = Some((step, true));
                    robot.set_mode(now, robot_mode::OPERATIONAL, eid::PLAN_STEP_EXECUTED, p);
                } else {
                    self.step_pending = None;
                    let started = match (root, self.next_step()) {
                        (robot_mode::OPERATIONAL, Some(s)) if s.step == step => self.start_step(now, s, robot, link, p),
                        (robot_mode::OPERATIONAL, _) => Err(StepRefusal::NotAuthorised),
                        _ => Err(StepRefusal::InitialState),
                    };
                    if let Err(why) = started {
                        self.step_refused(now, plan, step, why, p.dl, p.sink);
                        let target = Self::hold_target(robot);
                        if robot.modes.root_target() != target {
                            robot.set_mode(now, target, eid::GROUND_LOST, p);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accept::tests::tc_bytes;
    use crate::obsw::tests::{kind, of, TestObsw};
    use crate::obsw::Config;
    use crate::tm::RingStore;
    use std::vec::Vec;

    /// The team's join acting on the node's decision `a` (what `Team::input` does with an
    /// `Effect::Act`), with the obsw's robot and ports.
    fn team_act(o: &mut TestObsw, now: u64, a: Action, link: &mut impl TeamLink, sink: &mut Vec<Vec<u8>>) {
        let (team, robot, mut p) = o.team(sink);
        team.act(now, a, robot, link, &mut p);
    }

    /// A link that records persists and sends in order; `fail_persist` makes persists fail.
    #[derive(Default)]
    struct RecordingLink {
        log: Vec<&'static str>,
        sent: Vec<(Dest, Vec<u8>)>,
        records: Vec<TeamRecord>,
        fail_persist: bool,
    }

    impl TeamLink for RecordingLink {
        fn persist(&mut self, r: &TeamRecord) -> bool {
            self.log.push("persist");
            self.records.push(r.clone());
            !self.fail_persist
        }
        fn send(&mut self, to: Dest, packet: &[u8]) -> u32 {
            self.log.push("send");
            self.sent.push((to, packet.to_vec()));
            // The in-memory teams here are of three robots.
            match to {
                Dest::All => 2,
                Dest::To(_) => 1,
            }
        }
    }

    fn robot(n: u8) -> TestObsw {
        Obsw::new(
            Config {
                robot: n,
                epoch_unix_ms: 1_790_000_000_000,
            },
            RingStore::default(),
        )
    }

    fn events(pkts: &[Vec<u8>], id: u16) -> Vec<Vec<u8>> {
        pkts.iter()
            .filter(|p| kind(p).0 == 5 && kind(p).2[..2] == id.to_be_bytes())
            .map(|p| kind(p).2[2..].to_vec())
            .collect()
    }

    fn roster_tc(o: &mut TestObsw, now: u64, robots: &[u8]) -> Vec<Vec<u8>> {
        let mut app = [0u8; 8];
        app[..robots.len()].copy_from_slice(robots);
        let mut sink = Vec::new();
        let apid = o.apid();
        o.handle_tc(now, &tc_bytes(apid, 1, 211, 4, &app), &mut sink);
        sink
    }

    /// Runs three robots on a lossless in-memory link from `from` to `to` ms (10 ms steps).
    fn run(team: &mut [TestObsw], links: &mut [RecordingLink], sinks: &mut [Vec<Vec<u8>>], from: u64, to: u64) {
        let mut now = from;
        let mut rand = 12345u32;
        while now < to {
            for i in 0..team.len() {
                rand = rand.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                team[i].team_poll(now, rand, &mut links[i], &mut sinks[i]);
            }
            for i in 0..team.len() {
                for (dest, pkt) in core::mem::take(&mut links[i].sent) {
                    for j in 0..team.len() {
                        let me = (j + 1) as u8;
                        if j != i && (dest == Dest::All || dest == Dest::To(me)) {
                            team[j].team_packet(now, rand, Some((i + 1) as u8), &pkt, &mut links[j], &mut sinks[j]);
                        }
                    }
                }
            }
            now += 10;
        }
    }

    // verifies: TEAM-OBSW-01, TEAM-OBSW-02, TEAM-OBSW-03
    #[test]
    fn three_robots_elect_a_leader_hold_and_obey_the_ground_again() {
        let mut team: Vec<TestObsw> = (1..=3).map(robot).collect();
        let mut links: Vec<RecordingLink> = (0..3).map(|_| RecordingLink::default()).collect();
        let mut sinks: Vec<Vec<Vec<u8>>> = vec![Vec::new(); 3];
        for o in team.iter_mut() {
            let r = roster_tc(o, 0, &[1, 2, 3]);
            assert_eq!(of(&r, 1, 7).len(), 1, "roster accepted");
        }
        run(&mut team, &mut links, &mut sinks, 0, 12_000);
        for (i, s) in sinks.iter().enumerate() {
            assert_eq!(events(s, eid::GROUND_LOST).len(), 1, "robot {}", i + 1);
            let elected = events(s, eid::LEADER_ELECTED);
            assert!(!elected.is_empty(), "robot {} knows a leader", i + 1);
            // The robot holds: no computed state in a fresh controller, so SAFED.
            assert_eq!(team[i].robot.modes.root_target(), robot_mode::SAFED);
            assert!(!of(s, 211, 2).is_empty(), "status reports");
        }
        let leaders: Vec<u8> = team
            .iter()
            .filter(|o| o.team.node().unwrap().role() == mmic_team::Role::Leader)
            .map(|o| o.team.node().unwrap().me())
            .collect();
        assert_eq!(leaders.len(), 1, "one leader: {leaders:?}");
        // Persist always came before the sends of its batch: the first entry is a persist.
        for l in &links {
            if let Some(first) = l.log.iter().position(|e| *e == "send") {
                assert!(l.log[..first].contains(&"persist"));
            }
        }
        // The ground comes back to robot 1 and 2: they stop obeying at once.
        for (i, o) in team.iter_mut().enumerate().take(2) {
            let mut s = Vec::new();
            let apid = o.apid();
            o.handle_tc(12_000, &tc_bytes(apid, 7, 17, 1, &[]), &mut s);
            o.team_poll(12_000, 1, &mut links[i], &mut s);
            assert_eq!(events(&s, eid::GROUND_REGAINED).len(), 1);
            assert!(o.team.node().unwrap().ground_seen());
        }
        // Status on request: term and roster.
        let mut s = Vec::new();
        let apid = team[0].apid();
        team[0].handle_tc(12_010, &tc_bytes(apid, 8, 211, 5, &[]), &mut s);
        let st = tm::TeamStatus::parse(kind(&of(&s, 211, 2)[0]).2).unwrap();
        assert_eq!(st.roster.iter().map(|r| r.robot).collect::<Vec<_>>(), [1, 2, 3]);
        assert_eq!(st.ground_seen, 1);
        assert!(st.term >= 1);
    }

    /// The TEAM HK report (SID 24) of `o`, decoded by the MIB.
    fn team_hk(o: &mut TestObsw, now: u64) -> mib_wire::hk::Team {
        let mut s = Vec::new();
        let apid = o.apid();
        o.handle_tc(
            now,
            &tc_bytes(apid, (now / 10) as u16, 3, 27, &mib::hk::sid::TEAM.to_be_bytes()),
            &mut s,
        );
        let hk = of(&s, 3, 25);
        assert_eq!(
            hk.len(),
            1,
            "one TEAM HK report: {:?}",
            s.iter()
                .map(|p| (kind(p).0, kind(p).1, kind(p).2.to_vec()))
                .collect::<Vec<_>>()
        );
        let data = kind(&hk[0]).2;
        assert_eq!(data.len(), mib::hk::by_sid(mib::hk::sid::TEAM).unwrap().data_len());
        mib_wire::hk::Team::parse(&data[2..]).unwrap()
    }

    // verifies: TEAM-HK-01
    #[test]
    fn the_team_hk_counts_packets_elections_directives_and_rejections() {
        let mut team: Vec<TestObsw> = (1..=3).map(robot).collect();
        let mut links: Vec<RecordingLink> = (0..3).map(|_| RecordingLink::default()).collect();
        let mut sinks: Vec<Vec<Vec<u8>>> = vec![Vec::new(); 3];
        for o in team.iter_mut() {
            roster_tc(o, 0, &[1, 2, 3]);
        }
        run(&mut team, &mut links, &mut sinks, 0, 12_000);
        let hk: Vec<_> = team.iter_mut().map(|o| team_hk(o, 12_000)).collect();
        let leader = team
            .iter()
            .position(|o| o.team.node().unwrap().role() == mmic_team::Role::Leader)
            .unwrap();
        let sent: u32 = hk.iter().map(|h| h.team_pkt_sent).sum();
        let received: u32 = hk.iter().map(|h| h.team_pkt_received).sum();
        assert!(sent > 50, "heartbeats and acks for ~6 s: {sent}");
        assert_eq!(
            sent, received,
            "lossless in-memory link: every packet sent was accepted"
        );
        for (i, h) in hk.iter().enumerate() {
            assert_eq!(h.team_term, team[i].team.node().unwrap().term());
            assert_eq!(h.team_leader, (leader + 1) as u8, "robot {}", i + 1);
            assert_eq!(h.team_ground_seen, 0);
            assert_eq!(h.team_role, if i == leader { 2 } else { 0 });
            if i != leader {
                assert!(h.team_dir_executed >= 1, "follower {} executed HOLD", i + 1);
            }
        }
        assert!(hk[leader].team_elections >= 1);
        assert_eq!(links[leader].sent.len(), 0);
        // Rejections: junk (malformed), a message claiming another sender than the
        // authenticated one, and the platform's authentication refusals.
        let o = &mut team[0];
        let mut s = Vec::new();
        let mut l = RecordingLink::default();
        o.team_packet(12_000, 1, Some(2), b"junk", &mut l, &mut s);
        let pkt = vote_request_packet(3);
        let len = pkt.len();
        o.team_packet(12_010, 1, Some(2), &pkt[..len], &mut l, &mut s);
        o.team_rejected(12_020, TeamReject::BadMac, 9, &mut s);
        o.team_rejected(12_020, TeamReject::BadMac, 9, &mut s);
        o.team_rejected(12_030, TeamReject::Replay, 2, &mut s);
        let ev = events(&s, eid::TEAM_PACKET_REJECTED);
        // MALFORMED, UNKNOWN_SENDER, BAD_MAC (the second one in the same period is
        // counted, not evented), REPLAY.
        assert_eq!(ev.len(), 4, "{ev:?}");
        assert_eq!(ev[2], [3, 9, 0, 0, 0, 1]);
        let h = team_hk(&mut team[0], 12_040);
        assert_eq!(
            (
                h.team_rej_malformed,
                h.team_rej_unknown_sender,
                h.team_rej_bad_mac,
                h.team_rej_replay
            ),
            (1, 1, 2, 1)
        );
        assert!(l.sent.is_empty(), "nothing answered a refused packet");
    }

    /// A team packet (TM[211,1]) carrying a vote request from `sender`.
    fn vote_request_packet(sender: u8) -> Vec<u8> {
        let mut body = [0u8; MAX_LEN];
        let n = Message {
            term: 1,
            sender,
            plan: PlanRef::default(),
            progress: 0,
            body: mmic_team::Body::RequestVote,
        }
        .emit(&mut body)
        .unwrap();
        let mut pkt = [0u8; mib::config::MAX_PACKET_LEN];
        let len = TmWriter::new(TEAM_APID, OnboardTime::new(0))
            .build(0, TEAM_SERVICE, TEAM_SUBSERVICE_MESSAGE, &body[..n], &mut pkt)
            .unwrap();
        pkt[..len].to_vec()
    }

    // verifies: TEAM-ROBUST-02
    #[test]
    fn a_team_packet_of_any_short_length_or_another_pus_version_is_counted_never_a_panic() {
        let mut o = robot(1);
        let o = &mut o;
        let (mut s, mut l) = (Vec::new(), RecordingLink::default());
        let pkt = vote_request_packet(2);
        let len = pkt.len();
        let mut refused = 0;
        for cut in 0..len {
            // Cut short, with the packet length field saying what is there.
            let mut p = pkt[..cut].to_vec();
            if cut >= 6 {
                p[4..6].copy_from_slice(&((cut as u16).saturating_sub(7)).to_be_bytes());
            }
            o.team_packet(12_000 + cut as u64, 1, Some(2), &p, &mut l, &mut s);
            refused += 1;
        }
        // Another PUS version (spacepackets' reader panicked on it).
        let mut p = pkt[..len].to_vec();
        p[6] = 0x10;
        o.team_packet(13_000, 1, Some(2), &p, &mut l, &mut s);
        refused += 1;
        let h = team_hk(o, 14_000);
        assert_eq!(h.team_rej_malformed, refused, "every packet counted as malformed");
        assert!(l.sent.is_empty(), "nothing answered a refused packet");
    }

    // verifies: TEAM-PERSIST-03
    #[test]
    fn roster_and_authorisation_are_persisted_and_restored_after_a_reset() {
        let mut o = robot(1);
        roster_tc(&mut o, 0, &[1, 2, 3]);
        let mut app = Vec::new();
        app.extend_from_slice(&7u16.to_be_bytes());
        app.extend_from_slice(&0xDEAD_BEEFu32.to_be_bytes());
        app.extend_from_slice(&1u16.to_be_bytes());
        app.push(3);
        app.extend_from_slice(&600u32.to_be_bytes());
        let mut s = Vec::new();
        o.handle_tc(10, &tc_bytes(0x101, 3, 211, 3, &app), &mut s);
        assert_eq!(of(&s, 1, 7).len(), 1);
        let mut link = RecordingLink::default();
        o.team_poll(20, 1, &mut link, &mut s);
        let rec = link.records.last().expect("written at the next poll").clone();
        assert_eq!(rec.roster.as_slice(), [1, 2, 3]);
        let a = rec.auth.unwrap();
        assert_eq!((a.plan.id, a.first_step, a.max_steps), (7, 1, 3));
        assert_eq!(a.expires_unix_ms, 1_790_000_000_000 + 10 + 600_000);
        // A reset 100 s later (new epoch): the roster is back, the authorisation keeps its
        // absolute expiry (500 s left), and TEAM_STATE_LOADED says so.
        let mut o2: TestObsw = Obsw::new(
            Config {
                robot: 1,
                epoch_unix_ms: 1_790_000_100_000,
            },
            RingStore::default(),
        );
        let mut s = Vec::new();
        o2.team_restore(0, LoadStatus::Restored, &rec, &mut s);
        assert_eq!(o2.team.node().unwrap().status(0).roster.as_slice(), [1, 2, 3]);
        let ev = events(&s, eid::TEAM_STATE_LOADED);
        assert_eq!(ev, [vec![0, 0, 0, 0, 0, 3, 0, 7]]);
        s.clear();
        o2.team_status(0, &mut s);
        let st = tm::TeamStatus::parse(kind(&of(&s, 211, 2)[0]).2).unwrap();
        assert_eq!((st.auth_plan, st.auth_steps, st.auth_left_s), (7, 3, 500));
        // An expired authorisation is not restored; a corrupt record starts empty.
        let mut o3: TestObsw = Obsw::new(
            Config {
                robot: 1,
                epoch_unix_ms: 1_790_001_000_000,
            },
            RingStore::default(),
        );
        let mut s = Vec::new();
        o3.team_restore(0, LoadStatus::Restored, &rec, &mut s);
        assert!(o3.team.record().auth.is_none());
        let mut o4 = robot(1);
        let mut s = Vec::new();
        o4.team_restore(0, LoadStatus::Corrupt, &TeamRecord::default(), &mut s);
        assert!(o4.team.node().is_none());
        assert_eq!(events(&s, eid::TEAM_STATE_LOADED), [vec![2, 0, 0, 0, 0, 0, 0, 0]]);
    }

    fn authorise_tc(o: &mut TestObsw, now: u64, seq: u16, plan: u16, hash: u32, first: u16, steps: u8) -> Vec<Vec<u8>> {
        let mut app = Vec::new();
        app.extend_from_slice(&plan.to_be_bytes());
        app.extend_from_slice(&hash.to_be_bytes());
        app.extend_from_slice(&first.to_be_bytes());
        app.push(steps);
        app.extend_from_slice(&600u32.to_be_bytes());
        let mut s = Vec::new();
        let apid = o.apid();
        o.handle_tc(now, &tc_bytes(apid, seq, 211, 3, &app), &mut s);
        s
    }

    fn step_tc(o: &mut TestObsw, now: u64, seq: u16, plan: u16, st: PlanStep) -> Vec<Vec<u8>> {
        let mut app = Vec::new();
        app.extend_from_slice(&plan.to_be_bytes());
        app.extend_from_slice(&st.step.to_be_bytes());
        app.extend_from_slice(&st.function.to_be_bytes());
        app.extend_from_slice(&st.args[0].to_be_bytes());
        app.extend_from_slice(&st.args[1].to_be_bytes());
        app.push(st.initial_state);
        let mut s = Vec::new();
        let apid = o.apid();
        o.handle_tc(now, &tc_bytes(apid, seq, 211, 6, &app), &mut s);
        s
    }

    fn failure_code(s: &[Vec<u8>]) -> Option<u16> {
        [2u8, 4, 8]
            .iter()
            .find_map(|sub| of(s, 1, *sub).first().cloned())
            .as_ref()
            .map(|p| u16::from_be_bytes([kind(p).2[4], kind(p).2[5]]))
    }

    const STEPS: [PlanStep; 2] = [
        PlanStep {
            step: 1,
            function: mib::tc::function::RECONFIGURE,
            args: [0, 1],
            initial_state: 0,
        },
        PlanStep {
            step: 2,
            function: mib::tc::function::RECONFIGURE,
            args: [1, 0],
            initial_state: 1,
        },
    ];

    // verifies: TEAM-PLAN-01, TEAM-AUTH-03
    #[test]
    fn plan_steps_are_stored_only_inside_the_authorisation_and_must_match_its_hash() {
        use mib::FailureCode as F;
        let mut o = robot(1);
        roster_tc(&mut o, 0, &[1, 2, 3]);
        let hash = mib::team::plan_hash(7, &STEPS);
        // No authorisation yet.
        let s = step_tc(&mut o, 10, 2, 7, STEPS[0]);
        assert_eq!(failure_code(&s), Some(F::PLAN_NOT_AUTHORISED.code()), "{s:?}");
        assert_eq!(of(&authorise_tc(&mut o, 20, 3, 7, hash, 1, 2), 1, 7).len(), 1);
        // Another plan, a step outside [first, first + K), UNBOLT: refused.
        assert_eq!(
            failure_code(&step_tc(&mut o, 30, 4, 8, STEPS[0])),
            Some(F::PLAN_NOT_AUTHORISED.code())
        );
        let outside = PlanStep { step: 3, ..STEPS[0] };
        assert_eq!(
            failure_code(&step_tc(&mut o, 30, 5, 7, outside)),
            Some(F::PLAN_NOT_AUTHORISED.code())
        );
        for f in [
            mib::tc::function::UNBOLT_FACE,
            mib::tc::function::UNBOLT_PAIR,
            mib::tc::function::STOP,
        ] {
            let unbolt = PlanStep {
                function: f,
                ..STEPS[0]
            };
            assert_eq!(
                failure_code(&step_tc(&mut o, 30, 6 + f, 7, unbolt)),
                Some(F::PLAN_FORBIDDEN_FUNCTION.code()),
                "function {f}"
            );
        }
        // Steps that do not hash to the authorised hash: all dropped.
        assert_eq!(of(&step_tc(&mut o, 40, 40, 7, STEPS[0]), 1, 7).len(), 1);
        let altered = PlanStep {
            args: [1, 2],
            ..STEPS[1]
        };
        assert_eq!(
            failure_code(&step_tc(&mut o, 40, 41, 7, altered)),
            Some(F::PLAN_HASH_MISMATCH.code())
        );
        assert!(o.team.record().plan.is_none());
        // The right steps, in any order: loaded, evented, in the record, told to the node.
        assert_eq!(of(&step_tc(&mut o, 50, 42, 7, STEPS[1]), 1, 7).len(), 1);
        let s = step_tc(&mut o, 50, 43, 7, STEPS[0]);
        assert_eq!(of(&s, 1, 7).len(), 1);
        assert_eq!(events(&s, eid::PLAN_UPLOADED).len(), 1);
        let rec = o.team.record();
        assert_eq!(rec.plan.as_ref().unwrap().steps.as_slice(), STEPS);
        let mut link = RecordingLink::default();
        let mut s = Vec::new();
        o.team_poll(60, 1, &mut link, &mut s);
        assert_eq!(link.records.last().unwrap().plan, rec.plan, "durable at the next poll");
        // A new authorisation needs a new upload.
        authorise_tc(&mut o, 70, 50, 7, hash, 2, 2);
        assert!(o.team.record().plan.is_none());
    }

    // verifies: TEAM-PLAN-02
    #[test]
    fn a_continue_outside_the_plan_or_in_the_wrong_state_is_refused_and_the_robot_holds() {
        let mut o = robot(1);
        roster_tc(&mut o, 0, &[1, 2, 3]);
        let hash = mib::team::plan_hash(7, &STEPS);
        authorise_tc(&mut o, 10, 2, 7, hash, 1, 2);
        let plan = PlanRef { id: 7, hash };
        let mut s = Vec::new();
        let mut link = RecordingLink::default();
        let f = TeamFunction::Reconfigure;
        // Before the upload: no plan.
        team_act(
            &mut o,
            20,
            Action::Continue {
                plan,
                step: 1,
                function: f,
            },
            &mut link,
            &mut s,
        );
        step_tc(&mut o, 30, 3, 7, STEPS[0]);
        step_tc(&mut o, 30, 4, 7, STEPS[1]);
        // Step 2 before step 1: not the next step.
        team_act(
            &mut o,
            40,
            Action::Continue {
                plan,
                step: 2,
                function: f,
            },
            &mut link,
            &mut s,
        );
        // Step 1 while the ground is seen (its TCs just came): never started.
        let step1 = Action::Continue {
            plan,
            step: 1,
            function: f,
        };
        team_act(&mut o, 50, step1, &mut link, &mut s);
        assert!(o.team.step_pending.is_none());
        // The ground falls silent: the robot holds (boot transition, default sensors: no
        // computed state, so SAFED); step 1 then waits until the robot is idle and is
        // refused: SAFED, not in the step's initial state.
        let mut t = 60;
        while t < 6_000 {
            o.tick(t, &mmic_domain::SensorsA::default(), &[], &mut s);
            o.team_poll(t, 1, &mut link, &mut s);
            t += 10;
        }
        assert!(!o.team.node().unwrap().ground_seen());
        team_act(&mut o, t, step1, &mut link, &mut s);
        while t < 9_000 && o.team.step_pending.is_some() {
            o.tick(t, &mmic_domain::SensorsA::default(), &[], &mut s);
            o.team_poll(t, 1, &mut link, &mut s);
            t += 10;
        }
        let refused: Vec<u8> = events(&s, eid::PLAN_STEP_REFUSED).iter().map(|p| p[4]).collect();
        assert_eq!(
            refused,
            [
                StepRefusal::NoPlan.code(),
                StepRefusal::NotAuthorised.code(),
                StepRefusal::Refused.code(),
                StepRefusal::InitialState.code()
            ]
        );
        assert!(events(&s, eid::PLAN_STEP_EXECUTED).is_empty());
        assert_eq!(o.team.record().plan.unwrap().done, 0, "nothing counted");
        assert_eq!(o.robot.modes.root_target(), robot_mode::SAFED, "the robot holds");
    }

    /// One robot with the simulator, one control period at a time (as the host runs it).
    struct Rig {
        o: TestObsw,
        sim: mmic_sim::Sim,
        now: u64,
        link_rx: Vec<u8>,
        link: RecordingLink,
        log: Vec<Vec<u8>>,
        seq: u16,
    }

    impl Rig {
        fn start() -> Rig {
            let mut r = Rig {
                o: robot(1),
                sim: mmic_sim::Sim::new(mmic_sim::SimConfig::default()),
                now: 0,
                link_rx: Vec::new(),
                link: RecordingLink::default(),
                log: Vec::new(),
                seq: 0,
            };
            r.o.boot(0, mib::config::reset_cause::POWER_ON, &mut r.log);
            r
        }
        fn tick(&mut self) {
            self.now += u64::from(mib::config::CONTROL_PERIOD_MS);
            let sensors = self.sim.sensors_a();
            let out = self.o.tick(self.now, &sensors, &self.link_rx, &mut self.log);
            let (act, tx) = (out.actuators, out.link_tx.clone());
            self.link_rx.clear();
            self.sim
                .step(mib::config::CONTROL_PERIOD_MS, &act, &tx, &mut self.link_rx);
            self.o.team_poll(self.now, 7, &mut self.link, &mut self.log);
        }
        fn send(&mut self, name: &str, args: &[i64]) {
            let def = mib::tc::by_name(name).unwrap();
            let mut app = [0u8; 64];
            let n = mib_wire::codec::encode_args(def, args, &mut app).unwrap();
            self.seq += 1;
            let apid = self.o.apid();
            let raw = tc_bytes(apid, self.seq, def.service, def.subservice, &app[..n]);
            self.o.handle_tc(self.now, &raw, &mut self.log);
        }
        fn run_until(&mut self, max_ms: u64, done: impl Fn(&Rig) -> bool) -> bool {
            let end = self.now + max_ms;
            while self.now < end {
                if done(self) {
                    return true;
                }
                self.tick();
            }
            done(self)
        }
    }

    // verifies: TEAM-OBSW-02
    #[test]
    fn a_hold_during_a_motion_picks_standby_or_safed_when_the_motion_ends_and_the_ground_cancels_it() {
        for ground_returns in [false, true] {
            let mut r = Rig::start();
            r.send("TEAM_ROSTER", &[1, 2, 3, 0, 0, 0, 0, 0]);
            r.send(
                "MODE_SET",
                &[mib::modes::node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0],
            );
            assert!(
                r.run_until(120_000, |r| r.o.robot.modes.root() == robot_mode::OPERATIONAL
                    && r.o.robot.transition.is_none())
            );
            r.send("RECONFIGURE", &[0, 1]);
            assert!(r.o.robot.running.is_some(), "the motion runs");
            // A hold (the leader's, or the robot's own) arrives mid-motion, when no gripper
            // pair holds (the node would say SAFED).
            let mut s = Vec::new();
            team_act(&mut r.o, r.now, Action::Hold(HoldTarget::Safed), &mut r.link, &mut s);
            assert_eq!(
                r.o.robot.modes.root_target(),
                robot_mode::OPERATIONAL,
                "not while it moves"
            );
            if ground_returns {
                // The ground is back during the motion (a PING every second).
                while r.o.robot.running.is_some() && r.now < 120_000 {
                    r.send("PING", &[]);
                    r.run_until(1_000, |r| r.o.robot.running.is_none());
                }
                r.run_until(500, |_| false);
                assert!(r.o.team.node().unwrap().ground_seen());
                assert_eq!(
                    r.o.robot.modes.root_target(),
                    robot_mode::OPERATIONAL,
                    "the ground commands again: no deferred hold"
                );
            } else {
                // The ground stays away: the robot also raises GROUND_LOST mid-motion.
                assert!(r.run_until(120_000, |r| r.o.robot.running.is_none()), "the motion ends");
                r.run_until(50, |_| false);
                assert!(!r.o.team.node().unwrap().ground_seen());
                assert!(!events(&r.log, eid::GROUND_LOST).is_empty());
                assert_eq!(r.o.computed_state(), 1, "the reconfiguration reached state 1");
                assert_eq!(
                    r.o.robot.modes.root_target(),
                    robot_mode::STANDBY,
                    "both grippers hold at the end: STANDBY, not SAFED"
                );
            }
        }
    }

    /// Loads, commits and starts on board a plan `id` of one step: a wait of `ms`.
    fn start_onboard_wait(r: &mut Rig, id: u32, ms: u32, timeout_s: u16) {
        let steps = [mmic_plan::StepRepr {
            index: 0,
            confirmed: false,
            timeout_s,
            deps: heapless::Vec::new(),
            kind: mmic_plan::StepKind::Wait { ms },
        }];
        let mut out = [0u8; mib::plan::MAX_IMAGE_LEN];
        let n = mmic_plan::image::emit(1, id, &steps, &mut out).unwrap();
        let img = &out[..n];
        let p = &mut r.o.plan.plan;
        p.load(0, img).unwrap();
        let crc = u32::from_be_bytes(img[n - 4..].try_into().unwrap());
        p.commit(n as u16, crc, |_| Ok(())).unwrap();
        p.start(id).unwrap();
    }

    // verifies: PLAN-TEAM-03
    #[test]
    fn a_running_on_board_plan_continues_through_a_ground_loss_hold_and_a_suspended_one_holds() {
        let mut r = Rig::start();
        r.send("TEAM_ROSTER", &[1, 2, 3, 0, 0, 0, 0, 0]);
        r.send(
            "MODE_SET",
            &[mib::modes::node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0],
        );
        assert!(
            r.run_until(120_000, |r| r.o.robot.modes.root() == robot_mode::OPERATIONAL
                && r.o.robot.transition.is_none())
        );
        // A running on-board plan (its state as PLAN_START leaves it).
        start_onboard_wait(&mut r, 7, 60_000, 10);
        // A hold (the robot's own for ground loss, or a leader's): the plan runs on, the
        // robot stays operational.
        let mut s = Vec::new();
        team_act(&mut r.o, r.now, Action::Hold(HoldTarget::Standby), &mut r.link, &mut s);
        r.run_until(1_000, |_| false);
        assert_eq!(r.o.robot.modes.root_target(), robot_mode::OPERATIONAL);
        assert_eq!(r.o.plan.plan.state(), mmic_plan::State::Running);
        // Suspended, it is no longer running: the team's hold applies as to an idle robot.
        r.o.plan.plan.suspend().unwrap();
        team_act(&mut r.o, r.now, Action::Hold(HoldTarget::Standby), &mut r.link, &mut s);
        assert_eq!(r.o.robot.modes.root_target(), robot_mode::STANDBY);
    }

    // verifies: PLAN-TEAM-03
    #[test]
    fn a_leaders_continue_while_an_on_board_plan_runs_is_refused_busy_and_the_same_continue_runs_once_it_is_suspended()
    {
        let mut r = Rig::start();
        r.send("TEAM_ROSTER", &[1, 2, 3, 0, 0, 0, 0, 0]);
        // The leader's plan, authorised and uploaded: its step 1 is one this robot may run.
        let hash = mib::team::plan_hash(7, &STEPS);
        r.send("TEAM_AUTHORISE", &[7, i64::from(hash), 1, 2, 600]);
        for st in &STEPS {
            let a = [
                7,
                i64::from(st.step),
                i64::from(st.function),
                i64::from(st.args[0]),
                i64::from(st.args[1]),
                i64::from(st.initial_state),
            ];
            r.send("TEAM_PLAN_STEP", &a);
        }
        r.send(
            "MODE_SET",
            &[mib::modes::node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0],
        );
        assert!(
            r.run_until(120_000, |r| r.o.robot.modes.root() == robot_mode::OPERATIONAL
                && r.o.robot.transition.is_none())
        );
        // An on-board plan the ground started: one long wait, well within its timeout.
        start_onboard_wait(&mut r, 9, 300_000, 600);
        // The ground goes away: the plan runs on and the robot stays operational.
        assert!(r.run_until(8_000, |r| !r.o.team.node().unwrap().ground_seen()));
        r.run_until(500, |_| false);
        assert_eq!(r.o.plan.plan.state(), mmic_plan::State::Running);
        assert_eq!(r.o.robot.modes.root(), robot_mode::OPERATIONAL);
        assert_eq!(r.o.computed_state(), STEPS[0].initial_state);
        let step1 = Action::Continue {
            plan: PlanRef { id: 7, hash },
            step: 1,
            function: TeamFunction::Reconfigure,
        };
        // The leader's CONTINUE: refused BUSY, nothing pending, nothing counted or moved.
        let mut s = Vec::new();
        team_act(&mut r.o, r.now, step1, &mut r.link, &mut s);
        r.log.extend(s);
        let refused: Vec<u8> = events(&r.log, eid::PLAN_STEP_REFUSED).iter().map(|p| p[4]).collect();
        assert_eq!(refused, [StepRefusal::Busy.code()]);
        assert!(r.o.team.step_pending.is_none());
        r.run_until(2_000, |_| false);
        assert!(events(&r.log, eid::PLAN_STEP_EXECUTED).is_empty());
        assert!(r.o.robot.running.is_none(), "no motion");
        assert_eq!(r.o.team.record().plan.unwrap().done, 0, "nothing counted");
        assert_eq!(r.o.plan.plan.state(), mmic_plan::State::Running);
        // Suspended, the plan no longer runs: the same CONTINUE is the leader's to give.
        r.o.plan.plan.suspend().unwrap();
        let mut s = Vec::new();
        team_act(&mut r.o, r.now, step1, &mut r.link, &mut s);
        r.log.extend(s);
        assert!(r.run_until(5_000, |r| !events(&r.log, eid::PLAN_STEP_EXECUTED).is_empty()));
        assert_eq!(events(&r.log, eid::PLAN_STEP_REFUSED).len(), 1, "refused once, before");
        assert_eq!(r.o.team.record().plan.unwrap().done, 1);
    }

    // verifies: TEAM-PLAN-02, TEAM-PERSIST-03
    #[test]
    fn a_continue_from_standby_runs_the_step_after_counting_it_durably_and_a_failed_write_moves_nothing() {
        for fail in [false, true] {
            let mut r = Rig::start();
            r.send("TEAM_ROSTER", &[1, 2, 3, 0, 0, 0, 0, 0]);
            let hash = mib::team::plan_hash(7, &STEPS);
            r.send("TEAM_AUTHORISE", &[7, i64::from(hash), 1, 2, 600]);
            for st in &STEPS {
                let a = [
                    7,
                    i64::from(st.step),
                    i64::from(st.function),
                    i64::from(st.args[0]),
                    i64::from(st.args[1]),
                    i64::from(st.initial_state),
                ];
                r.send("TEAM_PLAN_STEP", &a);
            }
            assert_eq!(events(&r.log, eid::PLAN_UPLOADED).len(), 1);
            // The ground goes away: GROUND_LOST, the robot holds in STANDBY (state 0).
            assert!(r.run_until(8_000, |r| !r.o.team.node().unwrap().ground_seen()));
            r.run_until(2_000, |_| false);
            assert_eq!(r.o.robot.modes.root(), robot_mode::STANDBY);
            assert_eq!(r.o.computed_state(), 0);
            r.link.fail_persist = fail;
            let plan = PlanRef { id: 7, hash };
            let step1 = Action::Continue {
                plan,
                step: 1,
                function: TeamFunction::Reconfigure,
            };
            let mut s = Vec::new();
            team_act(&mut r.o, r.now, step1, &mut r.link, &mut s);
            r.log.extend(s);
            // Back to OPERATIONAL (homing), then the step starts.
            r.run_until(120_000, |r| {
                r.o.robot.running.is_some() && r.o.team.step_running.is_some() || r.o.team.step_pending.is_none()
            });
            if fail {
                assert!(r.o.team.step_running.is_none(), "nothing moves without a durable count");
                assert_eq!(events(&r.log, eid::PLAN_STEP_REFUSED).len(), 1);
                assert!(events(&r.log, eid::PLAN_STEP_EXECUTED).is_empty());
                assert_eq!(r.o.team.record().plan.unwrap().done, 0);
            } else {
                let ev = events(&r.log, eid::PLAN_STEP_EXECUTED);
                assert_eq!(ev.len(), 1);
                // plan 7, step 1, RECONFIGURE.
                assert_eq!(ev[0][..4], [0, 7, 0, 1]);
                // The count was durable before the action started.
                assert_eq!(r.link.records.last().unwrap().plan.as_ref().unwrap().done, 1);
                // It ends in state 1; the node then knows progress 1 (next: step 2).
                assert!(r.run_until(120_000, |r| r.o.robot.running.is_none()));
                r.run_until(50, |_| false);
                assert_eq!(r.o.computed_state(), 1);
                assert_eq!(r.o.team.plan.as_ref().unwrap().done, 1);
                // Step 1 again (a stale order): not the next step, refused.
                let mut s = Vec::new();
                team_act(&mut r.o, r.now, step1, &mut r.link, &mut s);
                assert_eq!(events(&s, eid::PLAN_STEP_REFUSED).len(), 1);
            }
        }
    }

    // verifies: TEAM-OBSW-01
    #[test]
    fn a_scheduled_tc_is_not_ground_contact() {
        let mut o = robot(1);
        roster_tc(&mut o, 0, &[1, 2, 3]);
        // A PING scheduled at 4 s (before the 5 s ground-loss timeout ends).
        let mut app = vec![1u8];
        app.extend_from_slice(&o.dl.tmw.time.cds(4_000));
        app.extend_from_slice(&tc_bytes(0x101, 77, 17, 1, &[]));
        let mut sink = Vec::new();
        o.handle_tc(0, &tc_bytes(0x101, 2, 11, 4, &app), &mut sink);
        assert_eq!(o.sched.len(), 1);
        let mut link = RecordingLink::default();
        let mut now = 0;
        while now <= 5_200 {
            o.release_schedule(now, &mut sink);
            o.team_poll(now, 7, &mut link, &mut sink);
            now += 10;
        }
        assert_eq!(o.sched.len(), 0, "the scheduled ping ran");
        assert_eq!(
            events(&sink, eid::GROUND_LOST).len(),
            1,
            "ground lost 5 s after the last ground TC"
        );
    }

    // verifies: TEAM-OBSW-01
    #[test]
    fn a_failed_persist_sends_nothing_of_its_batch() {
        let mut o = robot(1);
        roster_tc(&mut o, 0, &[1, 2, 3]);
        let mut link = RecordingLink {
            fail_persist: true,
            ..RecordingLink::default()
        };
        let mut sink = Vec::new();
        let mut now = 0;
        while now < 20_000 {
            o.team_poll(now, 7, &mut link, &mut sink);
            now += 10;
        }
        assert!(link.log.contains(&"persist"), "it tried to stand");
        assert!(link.sent.is_empty(), "no vote request without a durable term");
        assert!(o.team.counters.persist_failed > 0);
        assert_eq!(o.team.node().unwrap().term(), 0, "restarted from the durable term");
    }

    // verifies: TEAM-OBSW-03
    #[test]
    fn a_roster_without_this_robot_and_a_bad_authorisation_are_refused() {
        let mut o = robot(1);
        let r = roster_tc(&mut o, 0, &[2, 3]);
        assert_eq!(of(&r, 1, 4).len(), 1);
        assert!(o.team.node().is_none());
        assert!(of(&roster_tc(&mut o, 0, &[1, 2]), 1, 7).len() == 1);
        let mut app = Vec::new();
        app.extend_from_slice(&7u16.to_be_bytes());
        app.extend_from_slice(&0xDEAD_BEEFu32.to_be_bytes());
        app.extend_from_slice(&1u16.to_be_bytes());
        app.push(5); // more than MAX_AUTHORISED_STEPS
        app.extend_from_slice(&60u32.to_be_bytes());
        let mut s = Vec::new();
        o.handle_tc(10, &tc_bytes(0x101, 3, 211, 3, &app), &mut s);
        assert_eq!(of(&s, 1, 2).len(), 1, "max_steps out of its MIB range");
        app[8] = 4;
        s.clear();
        o.handle_tc(10, &tc_bytes(0x101, 4, 211, 3, &app), &mut s);
        assert_eq!(of(&s, 1, 7).len(), 1);
        s.clear();
        o.team_status(20, &mut s);
        let st = tm::TeamStatus::parse(kind(&of(&s, 211, 2)[0]).2).unwrap();
        assert_eq!((st.auth_plan, st.auth_steps, st.auth_left_s), (7, 4, 59));
    }
}
