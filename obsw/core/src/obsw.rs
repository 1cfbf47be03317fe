//! The on-board software of one robot: TC acceptance, duplicate handling and routing
//! of each typed [`Request`] to its PUS service (`crate::services`), and the control
//! cycle (`tick`). The services live in their own files; this file only routes.

use mib::config;
use mib::params::{pid, NotSupplied, Supplied};
use mib_wire::{ev, EventArgs};

use mmic_domain::controller::TickOut;
use mmic_domain::SensorsA;

use crate::accept::{accept, Tc};
use crate::downlink::{Accepted, Downlink, New, Stage};
use crate::duplicates::Duplicates;
pub(crate) use crate::duplicates::Outcome;
use crate::failure::Failure;
use crate::request::Ctx;
use crate::robot::{Ports, Robot};
use crate::services::function::Running;
use crate::services::link::{LinkKeys, LinkSelect};
use crate::services::mode::ModeCmd;
use crate::services::modules::Modules;
use crate::services::plan::OnboardPlan;
use crate::services::scheduling::Schedule;
use crate::services::team::Team;
use crate::services::{Request, Services};
use crate::time::OnboardTime;
use crate::tm::{TmSink, TmStore};
use mib_wire::RequestId;

/// Something the platform's ground link did on its own, for [`Obsw::link_event`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkEvent {
    /// A TCP connection was refused (connection cap); `total` since boot.
    TcpRefused { total: u32 },
    /// A TCP client was disconnected (TM backlog bound); `total` since boot.
    TcpClientDropped { total: u32 },
    /// Space link: TC frames refused for `reason` (a `LINK_FRAME_REJECTED` reason code);
    /// `total` since boot.
    FrameRejected { reason: u8, total: u32 },
    /// Space link: a BC control frame was executed (`command` 0 Unlock, 1 Set V(R)).
    ControlFrame { command: u8, vr: u8, total: u32 },
}

/// Number of space-link HK parameters (`pid::LINK_AD_ACCEPTED..=pid::LINK_REJ_BD_CONTENT`).
pub const SPACE_LINK_PARAMS: usize = (pid::LINK_REJ_BD_CONTENT - pid::LINK_AD_ACCEPTED + 1) as usize;
/// Number of space-link state HK parameters (`pid::LINK_TM_SPI..=pid::LINK_STATE_BAD_SLOT`).
pub const SPACE_LINK_STATE_PARAMS: usize = (pid::LINK_STATE_BAD_SLOT - pid::LINK_TM_SPI + 1) as usize;

/// Start-up configuration of one robot's OBSW.
#[derive(Clone, Copy, Debug)]
pub struct Config {
    /// Robot number 1..=254 (APID 0x100 + N).
    pub robot: u8,
    /// Unix time in ms at `now_ms == 0`.
    pub epoch_unix_ms: u64,
}

/// Counters of the platform's I/O, kept by the host binary or the firmware and
/// reported in housekeeping structure PLATFORM_IO.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IoCounters {
    pub tc_dropped: u32,
    pub tm_dropped: u32,
    pub sensor_errors: u32,
    pub output_errors: u32,
    pub ab_bytes_dropped: u32,
    /// Deepest stack use since boot in bytes (the firmware's painted stack; 0 on the host).
    pub stack_high_water: u32,
}

impl IoCounters {
    /// The parameters the MIB names the platform's I/O the source of.
    pub fn param(&self, id: u16) -> Supplied {
        Ok(Some(i64::from(match id {
            pid::IO_TC_DROPPED => self.tc_dropped,
            pid::IO_TM_DROPPED => self.tm_dropped,
            pid::IO_SENSOR_ERRORS => self.sensor_errors,
            pid::IO_OUTPUT_ERRORS => self.output_errors,
            pid::IO_AB_BYTES_DROPPED => self.ab_bytes_dropped,
            pid::IO_STACK_HIGH_WATER => self.stack_high_water,
            _ => return Err(NotSupplied(id)),
        })))
    }
}

/// Counters reported in the OBSW housekeeping structure.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counters {
    pub tc_accepted: u32,
    pub tc_rejected: u32,
    pub tc_duplicate: u32,
    /// Domain events and reports lost to a full per-tick queue (HK EVENTS_DROPPED).
    pub events_dropped: u32,
    /// Lost since the last EVENT_QUEUE_OVERFLOW event.
    overflow_unreported: u32,
    /// Earliest time of the next EVENT_QUEUE_OVERFLOW event.
    overflow_next: u64,
}

impl Counters {
    /// A TC refused (at acceptance, as too long, or by its service's checks).
    fn rejected(&mut self) {
        self.tc_rejected = self.tc_rejected.wrapping_add(1);
    }

    /// Counts `dropped` events and reports lost to a full queue; returns the number to
    /// report in an EVENT_QUEUE_OVERFLOW now (those lost since the last one), at most
    /// once per throttle window.
    fn dropped(&mut self, now: u64, dropped: u32) -> Option<u16> {
        self.events_dropped = self.events_dropped.saturating_add(dropped);
        self.overflow_unreported = self.overflow_unreported.saturating_add(dropped);
        if self.overflow_unreported == 0 || now < self.overflow_next {
            return None;
        }
        let n = core::mem::take(&mut self.overflow_unreported);
        self.overflow_next = now + config::EVENT_THROTTLE_WINDOW_MS as u64;
        Some(u16::try_from(n).unwrap_or(u16::MAX))
    }

    /// The parameters the MIB names the OBSW's counters the source of.
    pub fn param(&self, id: u16) -> Supplied {
        Ok(Some(i64::from(match id {
            pid::TC_ACCEPTED => self.tc_accepted,
            pid::TC_REJECTED => self.tc_rejected,
            pid::TC_DUPLICATE => self.tc_duplicate,
            pid::EVENTS_DROPPED => self.events_dropped.min(u32::from(u16::MAX)),
            _ => return Err(NotSupplied(id)),
        })))
    }
}

/// What executing a request led to.
pub(crate) enum Exec {
    /// Finished: report start and completion now.
    Done,
    /// An action started; its completion comes from the controller.
    Action(Running<()>),
    /// A mode command started; its completion comes with the transition.
    Mode(ModeCmd<()>),
    /// A store downlink by range started; it completes after its end report, paced by
    /// the downlink's room (`services::storage`).
    Replay(crate::services::storage::Range),
}

/// Why a request did not start: its failure, and a fault to raise after the refusal
/// was reported (an initial-state mismatch is both).
pub(crate) struct Refused {
    pub failure: Failure,
    pub fault: Option<ev::InitialStateMismatch>,
}

impl From<Failure> for Refused {
    fn from(failure: Failure) -> Self {
        Refused { failure, fault: None }
    }
}

pub struct Obsw<S: TmStore> {
    apid: u16,
    pub(crate) dl: Downlink<S>,
    /// The robot: the controller, its actions, modes and FDIR (`crate::robot`).
    pub robot: Robot,
    seen: Duplicates,
    /// The components only the obsw reaches (`services::Services`).
    pub(crate) svc: Services,
    pub(crate) sched: Schedule,
    /// Store downlinks by range waiting for the downlink's room (`services::storage`).
    pub(crate) replays: crate::services::storage::Replays<S::Mark>,
    pub counters: Counters,
    /// Platform I/O counters; the host or firmware updates them.
    pub io: IoCounters,
    /// Space-link counters kept by the platform (the host's frame endpoint), reported in HK
    /// structure SPACE_LINK: entry `i` is parameter `pid::LINK_AD_ACCEPTED + i`.
    pub space_link: [u32; SPACE_LINK_PARAMS],
    /// The platform's link state for HK (SPACE_LINK): entry `i` is parameter
    /// `pid::LINK_TM_SPI + i` (TM SPI, TC SPI mask, state writes, bad slot at start).
    pub space_link_state: [u32; SPACE_LINK_STATE_PARAMS],
    pub(crate) last_now: u64,
    out: TickOut,
    /// The module set found at boot (docs/modules.md; `services::modules`).
    pub modules: Modules,
    /// Team coordination without the ground (service 211, `services::team`).
    pub team: Team,
    /// The on-board plan (service 18, `services::plan`).
    pub plan: OnboardPlan,
    /// Software update (service 213, `services::update`); the platform attaches its slots.
    pub update: crate::services::update::Update,
    /// Space link keys the platform holds (it sets them at start; `services::link`).
    pub link_keys: LinkKeys,
    /// An SPI selection (LINK_SPI_SELECT) for the platform to apply before its next input.
    pub link_select: Option<LinkSelect>,
}

impl<S: TmStore> Obsw<S> {
    pub fn new(cfg: Config, store: S) -> Self {
        let apid = mib::apid::robot_apid(cfg.robot).unwrap_or(mib::apid::APID_BASE + mib::apid::DEFAULT_ROBOT as u16);
        let mut o = Obsw {
            apid,
            dl: Downlink::new(apid, OnboardTime::new(cfg.epoch_unix_ms), store),
            robot: Robot::new(),
            seen: Duplicates::default(),
            svc: Services::new(),
            sched: Schedule::new(),
            replays: Default::default(),
            counters: Counters::default(),
            io: IoCounters::default(),
            space_link: [0; SPACE_LINK_PARAMS],
            space_link_state: [0; SPACE_LINK_STATE_PARAMS],
            last_now: 0,
            out: TickOut::new(),
            modules: Modules::default(),
            team: Team::new(cfg.robot, OnboardTime::new(cfg.epoch_unix_ms)),
            plan: OnboardPlan::new(cfg.robot),
            update: Default::default(),
            link_keys: LinkKeys::default(),
            link_select: None,
        };
        o.robot.apply_module_modes(&o.modules);
        o
    }

    pub fn apid(&self) -> u16 {
        self.apid
    }

    /// Announces the boot (event BOOT, `mib::config::reset_cause`).
    pub fn boot(&mut self, now: u64, reset_cause: u8, sink: &mut impl TmSink) {
        self.raise(now, ev::Boot { reset_cause }, sink);
    }

    /// Reports a panic recorded by the previous run (event PREVIOUS_PANIC).
    pub fn report_previous_panic(
        &mut self,
        now: u64,
        reset_cause: u8,
        line: u32,
        file_crc: u32,
        sink: &mut impl TmSink,
    ) {
        self.raise(
            now,
            ev::PreviousPanic {
                reset_cause,
                line,
                file_crc,
            },
            sink,
        );
    }

    /// Reads the boot's otadata, runs the self-test of a new image and reports what it found
    /// (the platform calls it once, after `Update::attach`).
    #[cfg(feature = "update")]
    pub fn update_boot(&mut self, now: u64, sink: &mut impl TmSink) {
        self.update.boot_reported(now, &mut self.dl, sink);
    }

    /// What the platform's file service counted this period, or a transaction of it that
    /// began or ended (`services::files`): its HK parameters and events.
    pub fn files_report(&mut self, now: u64, r: crate::services::files::Report, sink: &mut impl TmSink) {
        self.svc.files.report(now, r, &mut self.dl, sink);
    }

    /// Reports what the platform's ground link did on its own (host TCP bounds): events
    /// `TCP_CONNECTION_REFUSED` / `TCP_CLIENT_DROPPED` with the totals since boot.
    pub fn link_event(&mut self, now: u64, ev: LinkEvent, sink: &mut impl TmSink) {
        match ev {
            LinkEvent::TcpRefused { total } => self.raise(now, ev::TcpConnectionRefused { refused: total }, sink),
            LinkEvent::TcpClientDropped { total } => self.raise(now, ev::TcpClientDropped { dropped: total }, sink),
            LinkEvent::FrameRejected { reason, total } => {
                self.raise(now, ev::LinkFrameRejected { reason, total }, sink)
            }
            LinkEvent::ControlFrame { command, vr, total } => {
                self.raise(now, ev::LinkControlFrame { command, vr, total }, sink)
            }
        }
    }

    /// Actual mode of the robot node.
    pub fn mode(&self) -> u32 {
        self.robot.modes.root()
    }

    /// The earliest time at which `tick` has periodic work (HK, time report, schedule).
    pub fn next_deadline(&self) -> u64 {
        let mut t = self.svc.next_deadline().unwrap_or(u64::MAX);
        if let Some(h) = self.svc.hk.next_deadline() {
            t = t.min(h);
        }
        if let Some(s) = self.sched.next_release() {
            t = t.min(s);
        }
        t
    }

    /// Parameter value for the state estimate shown to tests and the host.
    pub fn computed_state(&self) -> u8 {
        self.robot.computed_state()
    }

    // ------------------------------------------------------------------ output

    /// Emits an event report unless the event is disabled or throttled: the event's
    /// typed parameters (`mib_wire::ev`, named fields of the MIB's types) through the
    /// table codec. A reordered MIB parameter list cannot swap values: every field is
    /// named at the call.
    pub(crate) fn raise<E: EventArgs>(&mut self, now: u64, e: E, sink: &mut impl TmSink) {
        self.dl.raise(now, e, sink);
    }

    /// Raw value of MIB telemetry parameter `ID`, for tests and inspection: 0 when it has
    /// no valid value now (as housekeeping carries it). `ID` is a constant checked against
    /// the MIB's parameter table where the call is compiled, so a parameter the MIB does
    /// not define cannot be asked for (housekeeping and PUS 12, whose IDs are data, use
    /// [`Self::param_value`]); every parameter the MIB defines has exactly one source
    /// (checked by a test).
    ///
    /// ```no_run
    /// # use obsw_core::{obsw::Obsw, tm::RingStore};
    /// let _read: fn(&Obsw<RingStore<64>>) -> i64 = |o| o.param::<{ mib::params::pid::MODE }>();
    /// ```
    ///
    /// ```compile_fail,E0080
    /// # use obsw_core::{obsw::Obsw, tm::RingStore};
    /// let _read: fn(&Obsw<RingStore<64>>) -> i64 = |o| o.param::<{ u16::MAX }>();
    /// ```
    pub fn param<const ID: u16>(&self) -> i64 {
        const { assert!(mib_defines(ID), "the MIB defines no parameter with this ID") };
        self.param_value(ID).ok().flatten().unwrap_or(0)
    }

    /// Raw value of a MIB telemetry parameter; `None` when it has no valid value now or no
    /// component supplies it.
    pub fn param_opt(&self, id: u16) -> Option<i64> {
        self.param_value(id).ok().flatten()
    }

    /// Raw value of a MIB telemetry parameter from the one component its MIB row names
    /// (`mib::params::source`): `Ok(None)` when it has no valid value now (board B not
    /// heard yet, the module it measures absent); `Err` for an ID the MIB does not define.
    pub fn param_value(&self, id: u16) -> Supplied {
        let src = mib::params::source(id).ok_or(NotSupplied(id))?;
        let v = self.param_from(src, id)?;
        let absent = mib::params::module_of(id).is_some_and(|slot| self.modules.absent(slot));
        Ok(v.filter(|_| !absent))
    }

    /// The space-link parameters: the platform's counters and link state, each array
    /// laid out in parameter-ID order from its first parameter.
    pub(crate) fn space_link_param(&self, id: u16) -> Supplied {
        let counter = usize::from(id.wrapping_sub(pid::LINK_AD_ACCEPTED));
        let state = usize::from(id.wrapping_sub(pid::LINK_TM_SPI));
        (self.space_link.get(counter))
            .or_else(|| self.space_link_state.get(state))
            .map(|&v| Some(i64::from(v)))
            .ok_or(NotSupplied(id))
    }

    // ------------------------------------------------------------------ TC path

    /// Handles one uplinked TC (raw space packet). Never panics, whatever the bytes.
    pub fn handle_tc(&mut self, now: u64, raw: &[u8], sink: &mut impl TmSink) {
        self.handle_tc_from(now, raw, true, sink);
    }

    /// A TC that COP-1 delivered (the packet of an AD or BD frame accepted by FARM-1 after
    /// SDLS): the link already gives exactly-once delivery (FARM-1 discards repeated AD
    /// frames, SDLS refuses replayed frames), so the packet duplicate window is not asked.
    /// It would be wrong here: a restarted ground (Yamcs) numbers its TCs from 1 again, and
    /// a new TC identical to one sent before the restart would be taken for a resend and
    /// not executed. The TC is still remembered, for its outcome.
    pub fn handle_tc_delivered_once(&mut self, now: u64, raw: &[u8], sink: &mut impl TmSink) {
        self.handle_tc_from(now, raw, false, sink);
    }

    /// A step of the on-board plan: the TC path of a ground TC, without the duplicate
    /// window (a plan run again after a new load must run its TCs again) and without
    /// counting as ground contact. False when acceptance refused the packet itself.
    pub(crate) fn handle_plan_tc(&mut self, now: u64, raw: &[u8], sink: &mut impl TmSink) -> bool {
        let pending = self.team.ground_tc;
        let accepted = self.handle_tc_from(now, raw, false, sink);
        self.team.ground_tc = pending;
        accepted
    }

    /// Returns false when acceptance refused the packet (before any request was made).
    fn handle_tc_from(&mut self, now: u64, raw: &[u8], duplicate_check: bool, sink: &mut impl TmSink) -> bool {
        self.last_now = self.last_now.max(now);
        let tc = match accept(raw, self.apid) {
            Ok(tc) => tc,
            Err(rej) => {
                self.counters.rejected();
                if let Some(req) = rej.req {
                    self.dl.fail(now, req, Stage::Acceptance, (&rej.failure).into(), sink);
                }
                self.tc_rejected_event(now, (rej.service, rej.subservice), &rej.failure, sink);
                return false;
            }
        };
        // Every valid ground TC is ground contact for the team logic.
        self.team.ground_tc = true;
        let crc = tc.crc();
        if let Some(prev) = self.seen.find(tc.req, crc, now).filter(|_| duplicate_check) {
            self.repeat(now, &tc, prev, sink);
            return true;
        }
        self.seen.remember(tc.req, crc, now);
        let token = New::new(tc.req, tc.ack);
        let ctx = Ctx {
            apid: self.apid,
            time: self.dl.tmw.time,
            now: self.last_now,
            sched_free: self.sched.free(),
        };
        let request = match Request::parse(&tc, &ctx) {
            Ok(r) => r,
            Err(f) => {
                self.counters.rejected();
                self.dl.reject(now, token, &f, sink);
                self.refused(now, &tc, Stage::Acceptance, f, sink);
                return true;
            }
        };
        self.counters.tc_accepted = self.counters.tc_accepted.wrapping_add(1);
        let token = self.dl.accept(now, token, sink);
        self.execute(now, &tc, request, token, sink);
        true
    }

    /// Refuses a frame longer than any packet (`config::MAX_PACKET_LEN`) that the
    /// platform could not take in whole (TCP or serial framing). `head` is what it kept
    /// of the frame's start: with the 4 bytes of a request ID the refusal is reported
    /// in a TM[1,2] FRAME_TOO_LONG; the TC_REJECTED event and the counter always.
    pub fn reject_frame(&mut self, now: u64, frame_len: usize, head: &[u8], sink: &mut impl TmSink) {
        self.last_now = self.last_now.max(now);
        self.counters.rejected();
        let f = Failure::frame_too_long(frame_len, config::MAX_PACKET_LEN);
        let ty = match head {
            [h0, h1, h2, h3, rest @ ..] => {
                let req = RequestId::from_bytes([*h0, *h1, *h2, *h3]);
                self.dl.fail(now, req, Stage::Acceptance, (&f).into(), sink);
                // Service and subservice, if the secondary header was kept.
                match rest {
                    [_, _, _, svc, sub, ..] => (*svc, *sub),
                    _ => (0, 0),
                }
            }
            _ => (0, 0),
        };
        self.tc_rejected_event(now, ty, &f, sink);
    }

    /// Runs an accepted request and reports its start and (for immediate requests)
    /// its completion.
    fn execute(&mut self, now: u64, tc: &Tc, request: Request, token: Accepted, sink: &mut impl TmSink) {
        let root = self.robot.modes.root();
        let result = if tc.def.modes.contains(root) {
            self.route(now, request, sink)
        } else {
            Err(Failure::not_allowed_in_mode(root).into())
        };
        match result {
            Ok(Exec::Done) => {
                let started = self.dl.start(now, token, sink);
                self.dl.complete(now, started, sink);
                self.set_outcome(tc.req, Outcome::Done);
            }
            Ok(Exec::Action(r)) => {
                let started = self.dl.start(now, token, sink);
                self.robot.running = Some(r.with_token(Some(started)));
            }
            Ok(Exec::Mode(m)) => {
                let started = self.dl.start(now, token, sink);
                let (robot, mut p) = self.robot(sink);
                robot.mode_command_started(now, m.with_token(started), &mut p);
            }
            Ok(Exec::Replay(range)) => {
                let started = self.dl.start(now, token, sink);
                self.replay_started(now, range, started, sink);
            }
            Err(Refused { failure, fault }) => {
                self.dl.fail_start(now, token, &failure, sink);
                self.refused(now, tc, Stage::Start, failure, sink);
                if let Some(e) = fault {
                    let (robot, mut p) = self.robot(sink);
                    robot.raise_fault(now, e, &mut p);
                }
            }
        }
    }

    /// Records a failed request and raises TC_REJECTED.
    fn refused(&mut self, now: u64, tc: &Tc, stage: Stage, f: Failure, sink: &mut impl TmSink) {
        self.tc_rejected_event(now, (tc.service, tc.subservice), &f, sink);
        self.set_outcome(tc.req, Outcome::Failed(stage, (&f).into()));
    }

    pub(crate) fn tc_rejected_event(&mut self, now: u64, (svc, sub): (u8, u8), f: &Failure, sink: &mut impl TmSink) {
        let e = ev::TcRejected {
            service: svc,
            subservice: sub,
            code: f.code().code(),
        };
        self.raise(now, e, sink);
    }

    // ------------------------------------------------------------------ duplicates

    /// A ground retry: the same reports again, never a second execution.
    fn repeat(&mut self, now: u64, tc: &Tc, prev: Outcome, sink: &mut impl TmSink) {
        self.counters.tc_duplicate = self.counters.tc_duplicate.wrapping_add(1);
        let accepted = !matches!(prev, Outcome::Failed(Stage::Acceptance, _));
        if accepted && tc.ack.acceptance() {
            self.dl.repeat_acceptance(now, tc.req, sink);
        }
        match prev {
            Outcome::Done if tc.ack.completion() => self.dl.repeat_completion(now, tc.req, sink),
            Outcome::Done | Outcome::Pending => {}
            Outcome::Failed(stage, f) => self.dl.fail(now, tc.req, stage, f, sink),
        }
    }

    /// Counts events and reports a full queue dropped, and raises EVENT_QUEUE_OVERFLOW
    /// (with the count since the last one) at most once per throttle window.
    fn count_dropped(&mut self, now: u64, dropped: u32, sink: &mut impl TmSink) {
        if let Some(dropped) = self.counters.dropped(now, dropped) {
            self.raise(now, ev::EventQueueOverflow { dropped }, sink);
        }
    }

    /// Records what became of request `req`: the duplicate window keeps it, and the
    /// on-board plan learns the outcome of its step's TC here.
    pub(crate) fn set_outcome(&mut self, req: RequestId, outcome: Outcome) {
        crate::robot::record_outcome(&mut self.plan, &mut self.seen, &mut self.counters, req, outcome);
    }

    /// The robot with its ports for one call: the downlink and `sink`, the plan, the
    /// request outcomes and the module set (`crate::robot::Ports`).
    pub(crate) fn robot<'a, K: TmSink>(&'a mut self, sink: &'a mut K) -> (&'a mut Robot, Ports<'a, S, K>) {
        let (_, robot, p) = self.team(sink);
        (robot, p)
    }

    /// The team with the robot and the ports (`services::team`: the team's join).
    pub(crate) fn team<'a, K: TmSink>(&'a mut self, sink: &'a mut K) -> (&'a mut Team, &'a mut Robot, Ports<'a, S, K>) {
        let Obsw {
            team,
            robot,
            dl,
            plan,
            seen,
            counters,
            modules,
            ..
        } = self;
        let p = Ports {
            dl,
            sink,
            plan,
            seen,
            counters,
            modules,
        };
        (team, robot, p)
    }

    // ------------------------------------------------------------------ periodic

    /// One control cycle: runs the controller with the latest sensor readings and the
    /// bytes board B sent, then verification, events, FDIR, modes, HK, time reports
    /// and the schedule. Returns the actuator commands and bytes for board B.
    ///
    /// The one place the period's order is fixed, each step seeing what the one before
    /// left: the controller; events it lost to a full queue; the robot's action reports
    /// and domain events (`Robot::period_start`: completions, faults and their mode
    /// changes); module discovery (the powers of absent modules, before the transition
    /// reads them); the continuous monitors and the transition (`Robot::period_end`); HK
    /// (values after all of the above); store replays; the services' own periodic work;
    /// released scheduled TCs; the on-board plan (a step's TC through the TC path).
    pub fn tick(&mut self, now: u64, sensors: &SensorsA, link_rx: &[u8], sink: &mut impl TmSink) -> &TickOut {
        self.last_now = self.last_now.max(now);
        let mut out = core::mem::take(&mut self.out);
        out.clear();
        self.robot.ctrl.tick(now, sensors, link_rx, &mut out);
        self.count_dropped(now, out.dropped, sink);
        let (robot, mut p) = self.robot(sink);
        robot.period_start(now, &out, &mut p);
        self.modules.tick(now, &mut self.robot, &mut self.dl, sink);
        let (robot, mut p) = self.robot(sink);
        robot.period_end(now, &mut p);
        self.hk_tick(now, sink);
        self.replay_tick(now, sink);
        self.svc.tick(now, &mut self.dl, sink);
        self.release_schedule(now, sink);
        self.plan_tick(now, sink);
        self.dl.end_period();
        self.out = out;
        &self.out
    }
}

impl<S: TmStore> Obsw<S> {
    /// Reports every enabled HK structure whose interval elapsed.
    pub(crate) fn hk_tick(&mut self, now: u64, sink: &mut impl TmSink) {
        for i in 0..mib::hk::HK_STRUCTS.len() {
            if self.svc.hk.take_due(now, i) {
                self.hk_report(now, i, sink);
            }
        }
    }

    /// One HK report: the structure's parameters, each from the one component its MIB
    /// row names ([`Self::param_value`]).
    pub(crate) fn hk_report(&mut self, now: u64, index: usize, sink: &mut impl TmSink) {
        // One table-driven loop over the structure's parameters for every SID (the wire
        // crate's codec), not the typed `mib_wire::Hk` per structure: 4.5 KB of flash on
        // board A (mib/wire/README.md, "One codec").
        // A parameter without a valid value now travels as 0. One that no component
        // supplies cannot be in a structure (a test asks every component for every HK
        // parameter); were one there, the report would not be sent rather than carry a 0
        // nobody measured.
        let mut body = [0u8; config::MAX_PACKET_LEN];
        let mut supplied = true;
        let value = |p| match self.param_value(p) {
            Ok(v) => v.unwrap_or(0),
            Err(_) => {
                supplied = false;
                0
            }
        };
        let def = &mib::hk::HK_STRUCTS[index];
        if let Ok(n) = mib_wire::codec::encode_hk(def, value, &mut body) {
            if supplied {
                use mib_wire::tm::HkReport;
                self.dl
                    .emit(now, HkReport::SERVICE, HkReport::SUBSERVICE, &body[..n], sink);
            }
        }
    }

    /// One control period of the on-board plan; a step's TC goes through the TC path
    /// (`services::plan`).
    pub(crate) fn plan_tick(&mut self, now: u64, sink: &mut impl TmSink) {
        let mut buf = [0u8; mib::plan::MAX_STEP_TC_LEN];
        let Some(n) = self.plan.tick(now, &mut buf, &mut self.dl, sink) else {
            return;
        };
        let raw = &buf[..n];
        if !self.handle_plan_tc(now, raw, sink) {
            self.plan.step_refused(now, raw, &mut self.dl, sink);
        }
        self.plan.report_pending(now, &mut self.dl, sink);
    }

    /// The PUS 15 store (a platform's measurements and checks of it).
    pub fn store_mut(&mut self) -> &mut S {
        &mut self.dl.store
    }

    /// PUS 15 downlinks by range waiting or running.
    pub fn replays_pending(&self) -> usize {
        self.replays.len()
    }

    /// Restores a plan the platform stored (`Plan::take_record`) at start; reports the
    /// state it comes back in. False when the record is no valid image of this robot.
    pub fn plan_restore(
        &mut self,
        now: u64,
        image: &[u8],
        p: mmic_plan::exec::Progress,
        sink: &mut impl TmSink,
    ) -> bool {
        self.plan.restore(now, image, p, &mut self.dl, sink)
    }

    /// Sends the plan's progress announcement to every robot of the team link when due
    /// (the platform calls it every control period it has a team link).
    pub fn plan_team(&mut self, now: u64, link: &mut impl crate::services::team::TeamLink) {
        self.plan.announce(now, &mut self.team.tmw, link);
    }

    /// Runs every scheduled TC whose release time has come through the TC path.
    pub(crate) fn release_schedule(&mut self, now: u64, sink: &mut impl TmSink) {
        while let Some(tc) = self.sched.take_released(now) {
            self.handle_onboard_tc(now, &tc, sink);
        }
    }
}

impl Tc<'_> {
    /// The packet error control field (with the request ID it identifies a retry).
    fn crc(&self) -> u16 {
        let n = self.raw.len();
        u16::from_be_bytes([self.raw[n - 2], self.raw[n - 1]])
    }
}

/// Whether the MIB's parameter table has `id` (a `const fn`, for [`Obsw::param`]'s check
/// at compile time).
const fn mib_defines(id: u16) -> bool {
    let mut i = 0;
    while i < mib::params::PARAMS.len() {
        if mib::params::PARAMS[i].id == id {
            return true;
        }
        i += 1;
    }
    false
}

#[cfg(test)]
pub(crate) mod tests {
    //! Helpers for the services' unit tests: an OBSW, TCs and report look-ups.
    use super::*;
    use crate::accept::tests::tc_bytes;
    use crate::tm::RingStore;
    use mib::events::eid;
    use mib::params::Source;

    pub type TestObsw = Obsw<RingStore<8192>>;
    pub const APID: u16 = 0x101;

    pub fn obsw() -> TestObsw {
        Obsw::new(
            Config {
                robot: 1,
                epoch_unix_ms: 1_790_000_000_000,
            },
            RingStore::default(),
        )
    }

    /// Sends a TC and returns every packet it produced. Every failure report for it must
    /// carry a code of the TC's MIB failure list ([`failures_are_listed`]).
    pub fn send(o: &mut TestObsw, now: u64, seq: u16, svc: u8, sub: u8, app: &[u8]) -> Vec<Vec<u8>> {
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let raw = tc_bytes(APID, seq, svc, sub, app);
        o.handle_tc(now, &raw, &mut sink);
        failures_are_listed(&raw, &sink);
        sink
    }

    /// Panics when a failure report among `pkts` answers the TC `raw` with a code that is
    /// neither an acceptance failure nor in the TC's MIB failure list (what the ICD and
    /// Yamcs show operators). Bytes that are no MIB TC are not checked.
    pub fn failures_are_listed(raw: &[u8], pkts: &[Vec<u8>]) {
        let Ok(tc) = mib_wire::header::TcPacket::parse(raw) else {
            return;
        };
        let function = match tc.app_data {
            [hi, lo, ..] if tc.service == mib::tc::service::FUNCTION => Some(u16::from_be_bytes([*hi, *lo])),
            _ => None,
        };
        let Some(def) = mib::tc::lookup(tc.service, tc.subservice, function) else {
            return;
        };
        for p in pkts {
            let (svc, sub, data) = kind(p);
            if svc == 1 && sub % 2 == 0 && data.get(..4) == raw.get(..4) {
                // TM[1,6] carries the step before the code.
                let code = if sub == 6 {
                    u16::from_be_bytes([data[5], data[6]])
                } else {
                    failure(p).0
                };
                assert!(
                    def.may_fail_with(code),
                    "TM[1,{sub}] answers {} with {} ({code}), not in its MIB failure list",
                    def.name,
                    mib::FailureCode::from_code(code).name()
                );
            }
        }
    }

    // verifies: PUS-1-05
    #[test]
    #[should_panic(expected = "answers PING with MODULE_ABSENT (40), not in its MIB failure list")]
    fn a_failure_code_outside_the_tcs_list_is_caught_by_the_test_helper() {
        // A PING answered with a code its list lacks (made by hand: the OBSW does not).
        let mut o = obsw();
        let raw = tc_bytes(APID, 1, 17, 1, &[]);
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let token = crate::downlink::Token::new(mib_wire::RequestId::of_tc(&raw).unwrap(), crate::accept::Ack::ALL);
        o.dl.reject(10, token, &crate::failure::Failure::module_absent(5), &mut sink);
        failures_are_listed(&raw, &sink);
    }

    /// (service, subservice, source data) of a TM packet.
    pub fn kind(p: &[u8]) -> (u8, u8, &[u8]) {
        (p[7], p[8], &p[20..p.len() - 2])
    }

    /// The packets of one type.
    pub fn of(pkts: &[Vec<u8>], svc: u8, sub: u8) -> Vec<Vec<u8>> {
        pkts.iter()
            .filter(|p| kind(p).0 == svc && kind(p).1 == sub)
            .cloned()
            .collect()
    }

    /// Failure code and data of a TM[1,2/4/6/8] (after the 4-byte request ID).
    pub fn failure(p: &[u8]) -> (u16, Vec<u8>) {
        let d = kind(p).2;
        (u16::from_be_bytes([d[4], d[5]]), d[6..].to_vec())
    }

    // verifies: PUS-17-01, PUS-1-01
    #[test]
    fn a_ping_gets_acceptance_start_completion_and_a_reply() {
        let mut o = obsw();
        let pkts = send(&mut o, 10, 1, 17, 1, &[]);
        let kinds: Vec<(u8, u8)> = pkts.iter().map(|p| (kind(p).0, kind(p).1)).collect();
        assert_eq!(kinds, [(1, 1), (17, 2), (1, 3), (1, 7)]);
    }

    // verifies: DD-ROBUST-02
    #[test]
    fn a_retry_is_answered_again_but_not_executed_again() {
        let mut o = obsw();
        let sid = mib::hk::HK_STRUCTS[0].sid.to_be_bytes();
        assert_eq!(of(&send(&mut o, 10, 1, 3, 27, &sid), 3, 25).len(), 1);
        let again = send(&mut o, 20, 1, 3, 27, &sid);
        assert_eq!(of(&again, 3, 25).len(), 0, "not executed twice");
        assert_eq!((of(&again, 1, 1).len(), of(&again, 1, 7).len()), (1, 1));
        assert_eq!(o.counters.tc_duplicate, 1);
    }

    // verifies: YAMCS-LINK-02
    #[test]
    fn a_tc_delivered_by_cop1_is_executed_even_when_identical_to_an_earlier_one() {
        let mut o = obsw();
        let sid = mib::hk::HK_STRUCTS[0].sid.to_be_bytes();
        let raw = tc_bytes(APID, 1, 3, 27, &sid);
        for now in [10, 20] {
            let mut sink: Vec<Vec<u8>> = Vec::new();
            o.handle_tc_delivered_once(now, &raw, &mut sink);
            assert_eq!(of(&sink, 3, 25).len(), 1, "executed at {now}");
            assert_eq!((of(&sink, 1, 1).len(), of(&sink, 1, 7).len()), (1, 1));
        }
        assert_eq!(o.counters.tc_duplicate, 0);
    }

    // verifies: DD-ROBUST-02
    #[test]
    fn a_retry_of_a_refused_tc_repeats_the_same_failure_at_the_same_stage() {
        let mut o = obsw();
        // HK_ENABLE of an unknown SID: refused at acceptance with the SID as data.
        let first = send(&mut o, 10, 2, 3, 5, &[0x7F, 0x7F]);
        let again = send(&mut o, 20, 2, 3, 5, &[0x7F, 0x7F]);
        for pkts in [&first, &again] {
            let f = of(pkts, 1, 2);
            assert_eq!(f.len(), 1);
            assert_eq!(failure(&f[0]), (mib::FailureCode::UNKNOWN_SID.code(), vec![0x7F, 0x7F]));
            assert!(of(pkts, 1, 1).is_empty());
        }
    }

    // verifies: PUS-1-02, DD-ROBUST-01
    #[test]
    fn an_oversize_frame_is_refused_with_frame_too_long_for_its_request() {
        let mut o = obsw();
        let ping = tc_bytes(APID, 9, 17, 1, &[]);
        let mut sink: Vec<Vec<u8>> = Vec::new();
        o.reject_frame(5, 5000, &ping, &mut sink);
        let f = of(&sink, 1, 2);
        assert_eq!(&kind(&f[0]).2[..4], &ping[..4], "request ID of the frame");
        let mut data = 5000u32.to_be_bytes().to_vec();
        data.extend_from_slice(&(config::MAX_PACKET_LEN as u32).to_be_bytes());
        assert_eq!(failure(&f[0]), (mib::FailureCode::FRAME_TOO_LONG.code(), data));
        assert_eq!(o.counters.tc_rejected, 1);
        // Without a request ID: the event only.
        sink.clear();
        o.reject_frame(6, 5000, &[], &mut sink);
        assert!(of(&sink, 1, 2).is_empty());
        assert_eq!(
            of(&sink, 5, 1).len() + of(&sink, 5, 2).len() + of(&sink, 5, 3).len() + of(&sink, 5, 4).len(),
            1
        );
    }

    // verifies: DD-ROBUST-01
    #[test]
    fn a_full_event_queue_is_counted_and_reported_once_per_window() {
        let mut o = obsw();
        let mut sink: Vec<Vec<u8>> = Vec::new();
        o.count_dropped(100, 3, &mut sink);
        o.count_dropped(200, 2, &mut sink);
        let ev = |s: &Vec<Vec<u8>>| {
            s.iter()
                .filter(|p| p[7] == 5 && p[20..22] == eid::EVENT_QUEUE_OVERFLOW.to_be_bytes())
                .map(|p| u16::from_be_bytes([p[22], p[23]]))
                .collect::<Vec<_>>()
        };
        assert_eq!(ev(&sink), [3], "one event in the window, with the count so far");
        o.count_dropped(100 + config::EVENT_THROTTLE_WINDOW_MS as u64, 0, &mut sink);
        assert_eq!(ev(&sink), [3, 2], "the rest once the window passed");
        assert_eq!(o.param::<{ pid::EVENTS_DROPPED }>(), 5);
    }

    /// The components that answer parameter `id` (rather than refusing it).
    fn suppliers(o: &TestObsw, id: u16) -> Vec<Source> {
        Source::ALL
            .into_iter()
            .filter(|&s| o.param_from(s, id).is_ok())
            .collect()
    }

    // verifies: PUS-3-05
    #[test]
    fn every_hk_parameter_has_exactly_one_source_and_only_it_supplies_the_parameter() {
        let o = obsw();
        for h in mib::hk::HK_STRUCTS {
            for &id in h.params {
                let src = mib::params::source(id);
                assert!(src.is_some(), "SID {}: parameter {id} has no source", h.sid);
                assert_eq!(suppliers(&o, id), Vec::from_iter(src), "SID {}: parameter {id}", h.sid);
            }
        }
        // The other telemetry parameters (monitored, or in events) too.
        for p in mib::params::PARAMS {
            assert_eq!(
                suppliers(&o, p.id),
                Vec::from_iter(mib::params::source(p.id)),
                "{}",
                p.name
            );
        }
        // What is no parameter: an error from every component and from the OBSW, not 0.
        let unknown = (0..=u16::MAX).find(|&id| mib::params::by_id(id).is_none()).unwrap();
        assert_eq!(suppliers(&o, unknown), []);
        assert_eq!(o.param_value(unknown), Err(NotSupplied(unknown)));
        assert_eq!(o.param_opt(unknown), None);
        // Obsw::param cannot be asked for it: its compile_fail example.
        assert!(!mib_defines(unknown) && mib_defines(pid::MODE));
    }

    // verifies: PUS-1-02, MMIC-MODE-01
    #[test]
    fn a_command_not_allowed_in_the_mode_reports_the_real_mode() {
        let mut o = obsw();
        // RECONFIGURE in standby.
        let pkts = send(&mut o, 10, 3, 8, 1, &[0, 1, 0, 1]);
        let f = of(&pkts, 1, 4);
        assert_eq!(
            failure(&f[0]),
            (
                mib::FailureCode::NOT_ALLOWED_IN_MODE.code(),
                vec![mib::modes::robot_mode::STANDBY as u8]
            )
        );
    }
}
