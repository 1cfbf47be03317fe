//! The on-board software: TC handling, PUS services, mode tree, FDIR and the robot
//! controller, as one bounded state machine driven by `handle_tc` and `tick`.

use mib::codec;
use mib::config;
use mib::events::{self, eid, EVENTS};
use mib::fdir::{Phase, FAULTS};
use mib::hk::{self, HK_STRUCTS};
use mib::modes::{module_mode, node, robot_mode, submode, NodeKind};
use mib::params::{self, pid};
use mib::robot::{Side, STATE_UNKNOWN};
use mib::tc::{function, service};
use mib::FailureCode;

use mmic_domain::controller::{Action, ActionReport, Controller, DomainEvent, ModuleModes, StartError, TickOut};
use mmic_domain::SensorsA;
use satrs::pus::verification::{
    FailParams, FailParamsWithStep, RequestId as SatrsRequestId, VerificationReportCreator, VerificationToken,
};
use satrs::spacepackets::ecss::{EcssEnumU16, EcssEnumU8};

use crate::accept::{accept, Ack, Rejection, RequestId, Tc, PRIMARY_LEN};
use crate::fdir::{self, Faults, Monitoring, Response, N_MONITORS};
use crate::modes::{Change, ModeTree, N_NODES};
use crate::time::OnboardTime;
use crate::tm::{TmSink, TmStore, TmWriter};

const N_HK: usize = HK_STRUCTS.len();
const N_EVENTS: usize = EVENTS.len();
const _: () = assert!(N_EVENTS <= 64, "event enable mask is a u64");

/// Start-up configuration of one robot's OBSW.
#[derive(Clone, Copy, Debug)]
pub struct Config {
    /// Robot number 1..=254 (APID 0x100 + N).
    pub robot: u8,
    /// Unix time in ms at `now_ms == 0`.
    pub epoch_unix_ms: u64,
}

/// Verification stages (TM[1,x]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Acceptance,
    Start,
    Progress(u8),
    Completion,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    Pending,
    Done,
    Failed(u16),
}

#[derive(Clone, Copy, Debug)]
struct Seen {
    req: RequestId,
    crc: u16,
    at: u64,
    outcome: Outcome,
}

#[derive(Clone, Copy, Debug)]
struct Running {
    /// `None` for actions the OBSW starts itself (homing when entering operational).
    req: Option<(RequestId, Ack)>,
    function: u16,
    reconfigure: bool,
}

#[derive(Clone, Copy, Debug)]
struct ModeCmd {
    req: RequestId,
    ack: Ack,
    target: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Entering {
    /// Waiting for the modules to confirm power.
    Powering,
    /// Homing after the hip check passed.
    Homing,
    /// Homing done: the robot node may take the mode.
    Ready,
}

#[derive(Clone, Copy, Debug)]
struct Transition {
    target: u32,
    started: u64,
    cause: u16,
    entering: Entering,
}

#[derive(Clone, Copy, Debug, Default)]
struct HkState {
    enabled: bool,
    interval: u32,
    next: u64,
}

#[derive(Clone, Copy, Debug, Default)]
struct Throttle {
    window_start: u64,
    count: u8,
}

struct Scheduled {
    release: u64,
    tc: heapless::Vec<u8, { config::MAX_SCHEDULED_TC_LEN }>,
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
}

/// Counters reported in the OBSW housekeeping structure.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counters {
    pub tc_accepted: u32,
    pub tc_rejected: u32,
    pub tc_duplicate: u32,
    pub store_dropped: u32,
    pub events_throttled: u32,
}

type Fail = (FailureCode, heapless::Vec<u8, 12>);

fn fail(code: FailureCode, data: &[u8]) -> Fail {
    let mut v = heapless::Vec::new();
    let _ = v.extend_from_slice(&data[..data.len().min(12)]);
    (code, v)
}

/// What executing a TC led to.
enum Exec {
    /// Finished: report start and completion now.
    Done,
    /// Started: completion comes later (action or mode transition).
    Async,
}

pub struct Obsw<S: TmStore> {
    apid: u16,
    tmw: TmWriter,
    verif: VerificationReportCreator,
    store: S,
    store_enabled: bool,
    pub ctrl: Controller,
    seen: heapless::Deque<Seen, { config::DUPLICATE_WINDOW }>,
    hk: [HkState; N_HK],
    ev_disabled: u64,
    throttle: [Throttle; N_EVENTS],
    time_exp: u8,
    next_time_report: u64,
    sched: heapless::Vec<Scheduled, { config::SCHEDULE_CAPACITY }>,
    sched_enabled: bool,
    pub monitoring: Monitoring,
    pub faults: Faults,
    pub modes: ModeTree,
    transition: Option<Transition>,
    mode_cmd: Option<ModeCmd>,
    running: Option<Running>,
    pub counters: Counters,
    /// Platform I/O counters; the host or firmware updates them.
    pub io: IoCounters,
    last_now: u64,
    out: TickOut,
}

impl<S: TmStore> Obsw<S> {
    pub fn new(cfg: Config, store: S) -> Self {
        let apid = mib::apid::robot_apid(cfg.robot).unwrap_or(mib::apid::APID_BASE + mib::apid::DEFAULT_ROBOT as u16);
        let mut hk = [HkState::default(); N_HK];
        for (s, d) in hk.iter_mut().zip(HK_STRUCTS) {
            *s = HkState {
                enabled: d.default_enabled,
                interval: d.default_interval_ms,
                next: d.default_interval_ms as u64,
            };
        }
        let tmw = TmWriter::new(apid, OnboardTime::new(cfg.epoch_unix_ms));
        let verif = VerificationReportCreator::new(tmw.apid_u11());
        let mut o = Obsw {
            apid,
            tmw,
            verif,
            store,
            store_enabled: true,
            ctrl: Controller::new(),
            seen: heapless::Deque::new(),
            hk,
            ev_disabled: 0,
            throttle: [Throttle::default(); N_EVENTS],
            time_exp: config::TIME_REPORT_DEFAULT_EXP,
            next_time_report: 1000u64 << config::TIME_REPORT_DEFAULT_EXP,
            sched: heapless::Vec::new(),
            sched_enabled: true,
            monitoring: Monitoring::new(),
            faults: Faults::default(),
            modes: ModeTree::new(),
            transition: None,
            mode_cmd: None,
            running: None,
            counters: Counters::default(),
            io: IoCounters::default(),
            last_now: 0,
            out: TickOut::new(),
        };
        o.apply_module_modes();
        o
    }

    pub fn apid(&self) -> u16 {
        self.apid
    }

    /// Announces the boot (event BOOT, `mib::config::reset_cause`).
    pub fn boot(&mut self, now: u64, reset_cause: u8, sink: &mut impl TmSink) {
        self.event(now, eid::BOOT, &[reset_cause as i64], sink);
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
        self.event(
            now,
            eid::PREVIOUS_PANIC,
            &[reset_cause as i64, line as i64, file_crc as i64],
            sink,
        );
    }

    /// Actual mode of the robot node.
    pub fn mode(&self) -> u32 {
        self.modes.root()
    }

    /// The earliest time at which `tick` has periodic work (HK, time report, schedule).
    pub fn next_deadline(&self) -> u64 {
        let mut t = self.next_time_report;
        for h in self.hk.iter().filter(|h| h.enabled) {
            t = t.min(h.next);
        }
        if self.sched_enabled {
            for s in &self.sched {
                t = t.min(s.release);
            }
        }
        t
    }

    // ------------------------------------------------------------------ output

    fn emit(&mut self, now: u64, svc: u8, sub: u8, data: &[u8], sink: &mut impl TmSink) {
        let mut buf = [0u8; config::MAX_PACKET_LEN];
        if let Some(n) = self.tmw.build(now, svc, sub, data, &mut buf) {
            self.send_raw(&buf[..n], sink);
        }
    }

    fn send_raw(&mut self, pkt: &[u8], sink: &mut impl TmSink) {
        sink.send_tm(pkt);
        self.tmw.sent = self.tmw.sent.wrapping_add(1);
        if self.store_enabled && self.store.push(pkt) {
            self.counters.store_dropped = self.counters.store_dropped.wrapping_add(1);
        }
    }

    fn verify(
        &mut self,
        now: u64,
        stage: Stage,
        req: RequestId,
        failure: Option<(FailureCode, &[u8])>,
        sink: &mut impl TmSink,
    ) {
        let stamp = self.tmw.time.cds(now);
        let seq = TmWriter::seq_u14(self.tmw.next_seq());
        let msg = self.tmw.next_msg_count(service::VERIFICATION);
        let rid = SatrsRequestId::from(req.raw());
        let mut src = [0u8; 64];
        let mut out = [0u8; config::MAX_PACKET_LEN];
        let code = failure.map(|(c, _)| EcssEnumU16::new(c.code()));
        let data = failure.map_or(&[][..], |(_, d)| d);
        let v = &self.verif;
        let tm = match (stage, &code) {
            (Stage::Acceptance, None) => v.acceptance_success(&mut src, &rid, seq, msg, &stamp),
            (Stage::Acceptance, Some(c)) => {
                v.acceptance_failure(&mut src, &rid, seq, msg, FailParams::new(&stamp, c, data))
            }
            (Stage::Start, None) => v.start_success(&mut src, &rid, seq, msg, &stamp),
            (Stage::Start, Some(c)) => v.start_failure(&mut src, &rid, seq, msg, FailParams::new(&stamp, c, data)),
            (Stage::Progress(s), None) => v.step_success(&mut src, &rid, seq, msg, &stamp, EcssEnumU8::new(s)),
            (Stage::Progress(s), Some(c)) => {
                let step = EcssEnumU8::new(s);
                v.step_failure(
                    &mut src,
                    VerificationToken::new_started_state(rid),
                    seq,
                    msg,
                    FailParamsWithStep::new(&stamp, &step, c, data),
                )
            }
            (Stage::Completion, None) => v.completion_success(&mut src, &rid, seq, msg, &stamp),
            (Stage::Completion, Some(c)) => {
                v.completion_failure(&mut src, &rid, seq, msg, FailParams::new(&stamp, c, data))
            }
        };
        if let Ok(n) = tm.and_then(|t| t.write_to_bytes(&mut out)) {
            self.send_raw(&out[..n], sink);
        }
    }

    /// Reports a failure at `stage`, raises the TC_REJECTED event and records the
    /// outcome for duplicate handling.
    fn refuse(
        &mut self,
        now: u64,
        stage: Stage,
        req: RequestId,
        (svc, sub): (u8, u8),
        f: &Fail,
        sink: &mut impl TmSink,
    ) {
        self.verify(now, stage, req, Some((f.0, &f.1)), sink);
        self.set_outcome(req, Outcome::Failed(f.0.code()));
        self.event(
            now,
            eid::TC_REJECTED,
            &[svc as i64, sub as i64, f.0.code() as i64],
            sink,
        );
    }

    /// Emits an event report unless the event is disabled or throttled.
    fn event(&mut self, now: u64, id: u16, args: &[i64], sink: &mut impl TmSink) {
        let Some(i) = EVENTS.iter().position(|e| e.id == id) else {
            return;
        };
        if self.ev_disabled & (1 << i) != 0 {
            return;
        }
        let t = &mut self.throttle[i];
        let throttled = !events::UNTHROTTLED.contains(&id);
        if now.saturating_sub(t.window_start) >= config::EVENT_THROTTLE_WINDOW_MS as u64 {
            *t = Throttle {
                window_start: now,
                count: 0,
            };
        }
        if throttled && t.count >= config::EVENT_THROTTLE_MAX {
            self.counters.events_throttled = self.counters.events_throttled.wrapping_add(1);
            return;
        }
        t.count += 1;
        let def = &EVENTS[i];
        let mut buf = [0u8; 64];
        if let Ok(n) = codec::encode_event(def, args, &mut buf) {
            self.emit(now, service::EVENT, def.severity.subservice(), &buf[..n], sink);
        }
    }

    fn hk_report(&mut self, now: u64, index: usize, sink: &mut impl TmSink) {
        let def = &HK_STRUCTS[index];
        let mut buf = [0u8; config::MAX_PACKET_LEN];
        if let Ok(n) = codec::encode_hk(def, |p| self.param(p), &mut buf) {
            self.emit(now, service::HOUSEKEEPING, 25, &buf[..n], sink);
        }
    }

    /// Raw value of any MIB telemetry parameter (0 when it has no valid value).
    pub fn param(&self, id: u16) -> i64 {
        self.param_opt(id).unwrap_or(0)
    }

    /// Raw value of any MIB telemetry parameter; `None` when it has no valid value.
    pub fn param_opt(&self, id: u16) -> Option<i64> {
        Some(match id {
            pid::MODE => self.modes.root() as i64,
            pid::FAULT_FLAGS => self.faults.active() as i64,
            pid::FAULT_LATCHED => self.faults.latched as i64,
            pid::FAULT_COUNT => self.faults.count as i64,
            pid::MON_ENABLED => self.monitoring.enabled_mask() as i64,
            pid::LAST_FAULT_EVENT => self.faults.last_event as i64,
            pid::PENDING_MODE => self.faults.pending_mode.map_or(255, |m| m as i64),
            pid::TC_ACCEPTED => self.counters.tc_accepted as i64,
            pid::TC_REJECTED => self.counters.tc_rejected as i64,
            pid::TC_DUPLICATE => self.counters.tc_duplicate as i64,
            pid::TM_SENT => self.tmw.sent as i64,
            pid::TM_STORED => self.store.len() as i64,
            pid::TM_STORE_DROPPED => self.counters.store_dropped as i64,
            pid::SCHED_COUNT => self.sched.len() as i64,
            pid::SCHED_ENABLED => self.sched_enabled as i64,
            pid::UPTIME_S => (self.last_now / 1000) as i64,
            pid::EVENTS_THROTTLED => self.counters.events_throttled as i64,
            pid::IO_TC_DROPPED => self.io.tc_dropped as i64,
            pid::IO_TM_DROPPED => self.io.tm_dropped as i64,
            pid::IO_SENSOR_ERRORS => self.io.sensor_errors as i64,
            pid::IO_OUTPUT_ERRORS => self.io.output_errors as i64,
            pid::IO_AB_BYTES_DROPPED => self.io.ab_bytes_dropped as i64,
            _ => return self.ctrl.param(id),
        })
    }

    // ------------------------------------------------------------------ TC path

    /// Handles one uplinked TC (raw space packet). Never panics, whatever the bytes.
    pub fn handle_tc(&mut self, now: u64, raw: &[u8], sink: &mut impl TmSink) {
        self.last_now = self.last_now.max(now);
        let tc = match accept(raw, self.apid) {
            Ok(tc) => tc,
            Err(rej) => return self.rejected(now, &rej, sink),
        };
        let crc = u16::from_be_bytes([tc.raw[tc.raw.len() - 2], tc.raw[tc.raw.len() - 1]]);
        if let Some(prev) = self.find_seen(tc.req, crc, now) {
            // A ground retry: acknowledge again, never execute twice.
            self.counters.tc_duplicate = self.counters.tc_duplicate.wrapping_add(1);
            if tc.ack.acceptance() {
                self.verify(now, Stage::Acceptance, tc.req, None, sink);
            }
            match prev {
                Outcome::Done if tc.ack.completion() => self.verify(now, Stage::Completion, tc.req, None, sink),
                Outcome::Failed(c) => {
                    let code = FailureCode::from_code(c);
                    self.verify(now, Stage::Completion, tc.req, Some((code, &[])), sink)
                }
                _ => {}
            }
            return;
        }
        if let Err(f) = self.validate(&tc) {
            self.counters.tc_rejected = self.counters.tc_rejected.wrapping_add(1);
            self.remember(tc.req, crc, now);
            return self.refuse(now, Stage::Acceptance, tc.req, (tc.service, tc.subservice), &f, sink);
        }
        self.counters.tc_accepted = self.counters.tc_accepted.wrapping_add(1);
        self.remember(tc.req, crc, now);
        if tc.ack.acceptance() {
            self.verify(now, Stage::Acceptance, tc.req, None, sink);
        }
        match self.execute(now, &tc, sink) {
            Ok(Exec::Done) => {
                if tc.ack.start() {
                    self.verify(now, Stage::Start, tc.req, None, sink);
                }
                if tc.ack.completion() {
                    self.verify(now, Stage::Completion, tc.req, None, sink);
                }
                self.set_outcome(tc.req, Outcome::Done);
            }
            Ok(Exec::Async) => {
                if tc.ack.start() {
                    self.verify(now, Stage::Start, tc.req, None, sink);
                }
            }
            Err(f) => self.refuse(now, Stage::Start, tc.req, (tc.service, tc.subservice), &f, sink),
        }
    }

    fn rejected(&mut self, now: u64, rej: &Rejection, sink: &mut impl TmSink) {
        self.counters.tc_rejected = self.counters.tc_rejected.wrapping_add(1);
        if let Some(req) = rej.req {
            self.verify(now, Stage::Acceptance, req, Some((rej.code, rej.data())), sink);
        }
        self.event(
            now,
            eid::TC_REJECTED,
            &[rej.service as i64, rej.subservice as i64, rej.code.code() as i64],
            sink,
        );
    }

    fn find_seen(&self, req: RequestId, crc: u16, now: u64) -> Option<Outcome> {
        self.seen
            .iter()
            .find(|s| s.req == req && s.crc == crc && now.saturating_sub(s.at) <= config::DUPLICATE_MAX_AGE_MS as u64)
            .map(|s| s.outcome)
    }

    fn remember(&mut self, req: RequestId, crc: u16, now: u64) {
        if self.seen.is_full() {
            self.seen.pop_front();
        }
        let _ = self.seen.push_back(Seen {
            req,
            crc,
            at: now,
            outcome: Outcome::Pending,
        });
    }

    fn set_outcome(&mut self, req: RequestId, outcome: Outcome) {
        if let Some(s) = self.seen.iter_mut().rev().find(|s| s.req == req) {
            s.outcome = outcome;
        }
    }

    /// Acceptance checks that need the MIB's tables beyond the argument ranges.
    fn validate(&self, tc: &Tc) -> Result<(), Fail> {
        let a = &tc.args;
        let u16a = |i: usize| a[i] as u16;
        match (tc.service, tc.subservice) {
            (service::HOUSEKEEPING, _) if hk::by_sid(u16a(0)).is_none() => {
                Err(fail(FailureCode::UNKNOWN_SID, &u16a(0).to_be_bytes()))
            }
            (service::EVENT, 5 | 6) if events::by_id(u16a(0)).is_none() => {
                Err(fail(FailureCode::UNKNOWN_EVENT, &u16a(0).to_be_bytes()))
            }
            (service::MONITORING, 1 | 2 | 7) => {
                let Some(m) = mib::fdir::monitor_by_id(u16a(0)) else {
                    return Err(fail(FailureCode::UNKNOWN_MONITOR, &u16a(0).to_be_bytes()));
                };
                if tc.subservice == 7 && a[1] > a[2] {
                    let mut d = [0u8; 6];
                    d[..2].copy_from_slice(&m.param.to_be_bytes());
                    d[2..].copy_from_slice(&(a[1] as i32).to_be_bytes());
                    return Err(fail(FailureCode::PARAM_OUT_OF_RANGE, &d));
                }
                Ok(())
            }
            (service::EVENT_ACTION, 4 | 5) if mib::fdir::fault_by_event(u16a(0)).is_none() => {
                Err(fail(FailureCode::UNKNOWN_ACTION_LINK, &u16a(0).to_be_bytes()))
            }
            (service::PARAMETER, _) => {
                let Some(t) = mib::tunables::by_id(u16a(0)) else {
                    return Err(fail(FailureCode::UNKNOWN_PARAMETER, &u16a(0).to_be_bytes()));
                };
                if tc.subservice == 3 && (a[1] < t.min as i64 || a[1] > t.max as i64) {
                    let mut d = [0u8; 6];
                    d[..2].copy_from_slice(&t.id.to_be_bytes());
                    d[2..].copy_from_slice(&(a[1] as i32).to_be_bytes());
                    return Err(fail(FailureCode::PARAM_OUT_OF_RANGE, &d));
                }
                Ok(())
            }
            (service::MODE, _) => {
                let n = a[0] as u32;
                if ModeTree::index(n).is_none() {
                    return Err(fail(FailureCode::UNKNOWN_MODE_TARGET, &n.to_be_bytes()));
                }
                if tc.subservice == 1 && (n != node::ROBOT || !mib::modes::is_commandable_root_mode(a[1] as u32)) {
                    let mut d = [0u8; 8];
                    d[..4].copy_from_slice(&n.to_be_bytes());
                    d[4..].copy_from_slice(&(a[1] as u32).to_be_bytes());
                    return Err(fail(FailureCode::INVALID_MODE, &d));
                }
                Ok(())
            }
            (service::SCHEDULING, 4) => self.validate_schedule(tc),
            _ => Ok(()),
        }
    }

    /// Walks the activities of a TC[11,4]: count, then per activity a CDS short release
    /// time and a complete TC for this robot.
    fn validate_schedule(&self, tc: &Tc) -> Result<(), Fail> {
        let count = tc.args[0] as usize;
        if self.sched.len() + count > config::SCHEDULE_CAPACITY {
            return Err(fail(
                FailureCode::SCHEDULE_FULL,
                &(config::SCHEDULE_CAPACITY as u16).to_be_bytes(),
            ));
        }
        let mut rest = tc.rest;
        for _ in 0..count {
            let Some((release, inner, tail)) = split_activity(rest) else {
                return Err(fail(
                    FailureCode::SCHEDULED_TC_INVALID,
                    &FailureCode::MALFORMED_PACKET.code().to_be_bytes(),
                ));
            };
            let Some(at) = self.tmw.time.from_cds(release) else {
                return Err(fail(FailureCode::RELEASE_TIME_PASSED, &0u32.to_be_bytes()));
            };
            if at <= self.last_now {
                return Err(fail(
                    FailureCode::RELEASE_TIME_PASSED,
                    &(at.min(u32::MAX as u64) as u32).to_be_bytes(),
                ));
            }
            if inner.len() > config::MAX_SCHEDULED_TC_LEN {
                return Err(fail(
                    FailureCode::SCHEDULED_TC_INVALID,
                    &FailureCode::MALFORMED_PACKET.code().to_be_bytes(),
                ));
            }
            if let Err(r) = accept(inner, self.apid) {
                return Err(fail(FailureCode::SCHEDULED_TC_INVALID, &r.code.code().to_be_bytes()));
            }
            rest = tail;
        }
        if !rest.is_empty() {
            return Err(fail(
                FailureCode::SCHEDULED_TC_INVALID,
                &FailureCode::BAD_ARG_LENGTH.code().to_be_bytes(),
            ));
        }
        Ok(())
    }

    fn execute(&mut self, now: u64, tc: &Tc, sink: &mut impl TmSink) -> Result<Exec, Fail> {
        let root = self.modes.root();
        if !tc.def.modes.contains(root) {
            return Err(fail(FailureCode::NOT_ALLOWED_IN_MODE, &[root as u8]));
        }
        let a = tc.args;
        let u16a = |i: usize| a[i] as u16;
        match (tc.service, tc.subservice) {
            (service::TEST, 1) => self.emit(now, service::TEST, 2, &[], sink),
            (service::HOUSEKEEPING, sub) => {
                let i = HK_STRUCTS.iter().position(|h| h.sid == u16a(0)).unwrap_or(0);
                match sub {
                    5 => {
                        self.hk[i].enabled = true;
                        self.hk[i].next = now + self.hk[i].interval as u64;
                    }
                    6 => self.hk[i].enabled = false,
                    27 => self.hk_report(now, i, sink),
                    _ => {
                        self.hk[i].interval = a[1] as u32;
                        self.hk[i].next = now + a[1] as u64;
                    }
                }
            }
            (service::EVENT, 5 | 6) => {
                let i = EVENTS.iter().position(|e| e.id == u16a(0)).unwrap_or(0);
                if tc.subservice == 5 {
                    self.ev_disabled &= !(1 << i);
                } else {
                    self.ev_disabled |= 1 << i;
                }
            }
            (service::EVENT, _) => {
                let mut buf = [0u8; 2 + 2 * N_EVENTS];
                let mut n = 2;
                let disabled = EVENTS
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| self.ev_disabled & (1 << i) != 0);
                for (_, e) in disabled {
                    buf[n..n + 2].copy_from_slice(&e.id.to_be_bytes());
                    n += 2;
                }
                buf[..2].copy_from_slice(&(((n - 2) / 2) as u16).to_be_bytes());
                self.emit(now, service::EVENT, 8, &buf[..n], sink);
            }
            (service::FUNCTION, _) => return self.function(now, tc, sink),
            (service::TIME, 1) => {
                self.time_exp = a[0] as u8;
                self.next_time_report = now + (1000u64 << self.time_exp);
                self.time_report(now, sink);
            }
            (service::TIME, _) => self.time_report(now, sink),
            (service::SCHEDULING, 1) => self.sched_enabled = true,
            (service::SCHEDULING, 2) => self.sched_enabled = false,
            (service::SCHEDULING, 3) => self.sched.clear(),
            (service::SCHEDULING, _) => self.insert_schedule(tc)?,
            (service::MONITORING, 1 | 2) => {
                if let Some(m) = self.monitoring.get_mut(u16a(0)) {
                    m.enabled = tc.subservice == 1;
                    m.state = fdir::check::OK;
                }
            }
            (service::MONITORING, 7) => {
                if let Some(m) = self.monitoring.get_mut(u16a(0)) {
                    m.def.low = a[1] as i32;
                    m.def.high = a[2] as i32;
                    m.def.persistence = a[3] as u16;
                }
            }
            (service::MONITORING, _) => self.report_monitors(now, sink),
            (service::STORAGE, 1) => self.store_enabled = true,
            (service::STORAGE, 2) => self.store_enabled = false,
            (service::STORAGE, 9) => self.downlink_store(now, sink)?,
            (service::STORAGE, _) => self.store.clear(),
            (service::EVENT_ACTION, 4 | 5) => {
                self.faults.set_link_enabled(u16a(0), tc.subservice == 4);
            }
            (service::EVENT_ACTION, _) => self.report_links(now, sink),
            (service::PARAMETER, 1) => self.report_tunable(now, u16a(0), sink),
            (service::PARAMETER, _) => {
                // Range and ID were checked at acceptance against the same MIB table.
                let _ = self.ctrl.set_tunable(u16a(0), a[1] as i32);
                self.report_tunable(now, u16a(0), sink);
            }
            (service::MODE, 1) => return self.mode_command(now, tc, sink),
            (service::MODE, 3) => self.mode_reply(now, a[0] as u32, sink),
            (service::MODE, _) => {
                for n in ModeTree::subtree(a[0] as u32) {
                    self.mode_reply(now, n, sink);
                }
            }
            _ => return Err(fail(FailureCode::UNKNOWN_SUBSERVICE, &[tc.service, tc.subservice])),
        }
        Ok(Exec::Done)
    }

    fn time_report(&mut self, now: u64, sink: &mut impl TmSink) {
        let mut d = [0u8; 1 + config::TIMESTAMP_LEN];
        d[0] = self.time_exp;
        d[1..].copy_from_slice(&self.tmw.time.cds(now));
        self.emit(now, service::TIME, 2, &d, sink);
    }

    fn report_tunable(&mut self, now: u64, id: u16, sink: &mut impl TmSink) {
        let Some(v) = self.ctrl.tunable(id) else { return };
        let mut d = [0u8; 6];
        d[..2].copy_from_slice(&id.to_be_bytes());
        d[2..].copy_from_slice(&v.to_be_bytes());
        self.emit(now, service::PARAMETER, 2, &d, sink);
    }

    fn report_monitors(&mut self, now: u64, sink: &mut impl TmSink) {
        let mut buf = [0u8; 2 + 17 * N_MONITORS];
        buf[..2].copy_from_slice(&(N_MONITORS as u16).to_be_bytes());
        let mut n = 2;
        for m in &self.monitoring.mons {
            buf[n..n + 2].copy_from_slice(&m.def.id.to_be_bytes());
            buf[n + 2..n + 4].copy_from_slice(&m.def.param.to_be_bytes());
            buf[n + 4] = m.enabled as u8;
            buf[n + 5..n + 9].copy_from_slice(&m.def.low.to_be_bytes());
            buf[n + 9..n + 13].copy_from_slice(&m.def.high.to_be_bytes());
            buf[n + 13..n + 15].copy_from_slice(&m.def.persistence.to_be_bytes());
            buf[n + 15..n + 17].copy_from_slice(&m.def.event.to_be_bytes());
            n += 17;
        }
        self.emit(now, service::MONITORING, 9, &buf[..n], sink);
    }

    fn report_links(&mut self, now: u64, sink: &mut impl TmSink) {
        let mut buf = [0u8; 2 + 8 * FAULTS.len()];
        buf[..2].copy_from_slice(&(FAULTS.len() as u16).to_be_bytes());
        let mut n = 2;
        for (i, f) in FAULTS.iter().enumerate() {
            buf[n..n + 2].copy_from_slice(&f.event.to_be_bytes());
            buf[n + 2] = self.faults.link_enabled(i) as u8;
            buf[n + 3..n + 7].copy_from_slice(&f.mode.to_be_bytes());
            buf[n + 7] = (f.timing == mib::fdir::Timing::AfterMotion) as u8;
            n += 8;
        }
        self.emit(now, service::EVENT_ACTION, 9, &buf[..n], sink);
    }

    fn downlink_store(&mut self, now: u64, sink: &mut impl TmSink) -> Result<(), Fail> {
        if !self.store_enabled {
            return Err(fail(FailureCode::STORE_DISABLED, &[]));
        }
        let mut buf = [0u8; config::MAX_PACKET_LEN];
        let mut count: u32 = 0;
        while let Some(n) = self.store.pop(&mut buf) {
            sink.send_tm(&buf[..n]);
            count += 1;
        }
        // Nothing downlinked is stored again: disable while reporting the end.
        self.store_enabled = false;
        self.emit(now, service::STORAGE, 19, &count.to_be_bytes(), sink);
        self.store_enabled = true;
        Ok(())
    }

    fn insert_schedule(&mut self, tc: &Tc) -> Result<(), Fail> {
        let mut rest = tc.rest;
        for _ in 0..tc.args[0] {
            let Some((release, inner, tail)) = split_activity(rest) else {
                break;
            };
            let at = self.tmw.time.from_cds(release).unwrap_or(0);
            let mut v = heapless::Vec::new();
            let _ = v.extend_from_slice(inner);
            if self.sched.push(Scheduled { release: at, tc: v }).is_err() {
                return Err(fail(
                    FailureCode::SCHEDULE_FULL,
                    &(config::SCHEDULE_CAPACITY as u16).to_be_bytes(),
                ));
            }
            rest = tail;
        }
        Ok(())
    }

    fn mode_reply(&mut self, now: u64, n: u32, sink: &mut impl TmSink) {
        let Some(ms) = self.modes.mode_and_submode(n) else {
            return;
        };
        let mut d = [0u8; 10];
        d[..4].copy_from_slice(&n.to_be_bytes());
        d[4..8].copy_from_slice(&ms.mode().to_be_bytes());
        d[8..].copy_from_slice(&ms.submode().to_be_bytes());
        self.emit(
            now,
            service::MODE,
            satrs::pus::mode::Subservice::TmModeReply as u8,
            &d,
            sink,
        );
    }

    // ------------------------------------------------------------------ actions

    fn function(&mut self, now: u64, tc: &Tc, sink: &mut impl TmSink) -> Result<Exec, Fail> {
        let f = tc.def.function;
        let a = tc.args;
        let side = |v: i64| Side::from_u8(v as u8).unwrap_or(Side::A);
        match f {
            function::ASSEMBLY_FAULT => {
                self.fault(now, eid::ASSEMBLY_SYSTEM_FAULT, &[a[0]], sink);
                return Ok(Exec::Done);
            }
            function::STOP => {
                if let Some(r) = self.running.take() {
                    self.ctrl.abort();
                    self.finish_running(
                        now,
                        &r,
                        Some(fail(FailureCode::ABORTED_BY_COMMAND, &r.function.to_be_bytes())),
                        sink,
                    );
                }
                return Ok(Exec::Done);
            }
            _ => {}
        }
        if self.running.is_some() || self.transition.is_some() {
            let busy = self.running.map_or(0, |r| r.function);
            return Err(fail(FailureCode::BUSY, &busy.to_be_bytes()));
        }
        let action = match f {
            function::RECONFIGURE => Action::Reconfigure {
                from: a[0] as u8,
                to: a[1] as u8,
            },
            function::BOLT_FACE => Action::BoltFace {
                side: side(a[0]),
                pairs: a[1] as u8,
            },
            function::UNBOLT_FACE => Action::UnboltFace {
                side: side(a[0]),
                pairs: a[1] as u8,
            },
            function::HOME => Action::Home,
            function::MOVE_ARM => Action::MoveArm {
                side: side(a[0]),
                pwm: a[1] as u16,
            },
            function::MOVE_GRIPPER => Action::MoveGripper {
                side: side(a[0]),
                pwm: a[1] as u16,
            },
            function::ROTATE_HIP => Action::RotateHip { cdeg: a[0] as i16 },
            function::BOLT_PAIR => Action::BoltPair {
                side: side(a[0]),
                pair: a[1] as u8,
            },
            function::UNBOLT_PAIR => Action::UnboltPair {
                side: side(a[0]),
                pair: a[1] as u8,
            },
            other => return Err(fail(FailureCode::UNKNOWN_FUNCTION, &other.to_be_bytes())),
        };
        let reconfigure = f == function::RECONFIGURE;
        if reconfigure {
            // Paper: idle overcurrent is checked at the start of every reconfiguration.
            if let Some(ev) = self.idle_check(now, sink) {
                return Err(fail(FailureCode::ABORTED_BY_FAULT, &ev.to_be_bytes()));
            }
        }
        match self.ctrl.start(action, now) {
            Ok(_) => {
                self.running = Some(Running {
                    req: Some((tc.req, tc.ack)),
                    function: f,
                    reconfigure,
                });
                self.modes.submode = submode::BUSY;
                Ok(Exec::Async)
            }
            Err(StartError::NotPowered) => Err(fail(FailureCode::NOT_ALLOWED_IN_MODE, &[self.modes.root() as u8])),
            Err(StartError::InitialStateMismatch { believed, computed }) => {
                // Report the refusal first, then let FDIR act on the fault.
                let fl = fail(FailureCode::INITIAL_STATE_MISMATCH, &[believed, computed]);
                self.refuse(now, Stage::Start, tc.req, (tc.service, tc.subservice), &fl, sink);
                self.fault(
                    now,
                    eid::INITIAL_STATE_MISMATCH,
                    &[believed as i64, computed as i64],
                    sink,
                );
                Ok(Exec::Async)
            }
            Err(e) => {
                let (code, data, len) = e.failure();
                Err(fail(code, &data[..len as usize]))
            }
        }
    }

    /// Runs the idle-phase monitors once; returns the fault event if one fired.
    fn idle_check(&mut self, now: u64, sink: &mut impl TmSink) -> Option<u16> {
        self.run_monitors(now, |p| p == Phase::Idle, sink)
    }

    /// Ends the running action with a completion report (success if `failure` is None).
    fn finish_running(&mut self, now: u64, r: &Running, failure: Option<Fail>, sink: &mut impl TmSink) {
        self.modes.submode = submode::IDLE;
        if let Some((req, ack)) = r.req {
            match &failure {
                None => {
                    if ack.completion() {
                        self.verify(now, Stage::Completion, req, None, sink);
                    }
                    self.set_outcome(req, Outcome::Done);
                }
                Some(f) => {
                    self.verify(now, Stage::Completion, req, Some((f.0, &f.1)), sink);
                    self.set_outcome(req, Outcome::Failed(f.0.code()));
                }
            }
        } else if self.transition.is_some_and(|t| t.entering == Entering::Homing) {
            // Homing for entry into operational.
            match failure {
                None => {
                    if let Some(t) = self.transition.as_mut() {
                        t.entering = Entering::Ready;
                    }
                }
                Some(f) => {
                    // A homing aborted by a fault carries the fault's event ID.
                    let event = if f.0 == FailureCode::ABORTED_BY_FAULT && f.1.len() >= 2 {
                        u16::from_be_bytes([f.1[0], f.1[1]])
                    } else {
                        0
                    };
                    self.transition_failed(now, f.0, event, sink);
                }
            }
        }
        if let Some(m) = self.faults.pending_mode.take() {
            let cause = self.faults.last_event;
            self.set_mode(now, m, cause, sink);
        }
    }

    // ------------------------------------------------------------------ modes

    fn mode_command(&mut self, now: u64, tc: &Tc, sink: &mut impl TmSink) -> Result<Exec, Fail> {
        let target = tc.args[1] as u32;
        if target == robot_mode::OPERATIONAL {
            if let Some(ev) = self.faults.first_active_event() {
                return Err(fail(FailureCode::FAULT_NOT_CLEARED, &ev.to_be_bytes()));
            }
        }
        if let Some(prev) = self.mode_cmd.take() {
            self.fail_mode_cmd(now, prev, FailureCode::ABORTED_BY_COMMAND, 0, sink);
        }
        if target == self.modes.root() && self.transition.is_none() {
            self.mode_reply(now, node::ROBOT, sink);
            return Ok(Exec::Done);
        }
        self.mode_cmd = Some(ModeCmd {
            req: tc.req,
            ack: tc.ack,
            target,
        });
        self.set_mode(now, target, 0, sink);
        Ok(Exec::Async)
    }

    /// Starts a transition of the robot node (by command, cause 0, or by FDIR, cause =
    /// fault event). A running action is aborted unless the target is operational.
    fn set_mode(&mut self, now: u64, target: u32, cause: u16, sink: &mut impl TmSink) {
        if target != robot_mode::OPERATIONAL {
            if let Some(r) = self.running.take() {
                self.ctrl.abort();
                let f = if cause != 0 {
                    fail(FailureCode::ABORTED_BY_FAULT, &cause.to_be_bytes())
                } else {
                    fail(FailureCode::ABORTED_BY_COMMAND, &r.function.to_be_bytes())
                };
                if r.req.is_some() {
                    self.finish_running(now, &r, Some(f), sink);
                }
                self.modes.submode = submode::IDLE;
            }
        }
        if cause != 0 {
            // FDIR takes over: a pending mode command loses.
            if let Some(c) = self.mode_cmd.take() {
                if c.target != target {
                    self.fail_mode_cmd(now, c, FailureCode::ABORTED_BY_FAULT, cause, sink);
                } else {
                    self.mode_cmd = Some(c);
                }
            }
        }
        self.modes.command(target);
        self.transition = Some(Transition {
            target,
            started: now,
            cause,
            entering: Entering::Powering,
        });
        self.apply_module_modes();
        self.progress_transition(now, sink);
    }

    fn apply_module_modes(&mut self) {
        let m = &self.modes;
        self.ctrl.set_module_modes(ModuleModes {
            arm_a: m.commanded(node::ARM_A),
            grip_a: m.commanded(node::GRIPPER_A),
            bolter_a: m.commanded(node::BOLTER_A),
            arm_b: m.commanded(node::ARM_B),
            grip_b: m.commanded(node::GRIPPER_B),
            bolter_b: m.commanded(node::BOLTER_B),
            hip: m.commanded(node::HIP),
        });
    }

    /// True when the hardware shows that a module is in `mode`.
    fn module_confirms(&self, n: &mib::modes::NodeDef, mode: u32) -> bool {
        if mode == module_mode::OFF {
            return true;
        }
        let v_reg_min = params::by_id(pid::V_REG)
            .and_then(|p| p.limits)
            .map_or(0, |l| params::CAL_VOLT.raw(l.hard_lo));
        let powered = self.ctrl.param(pid::V_REG).unwrap_or(0) >= v_reg_min;
        if n.parent != Some(node::SIDE_B) {
            return powered;
        }
        // Board B keeps driving its servos at their last set point when A's commands
        // stop, so side B holds position even with the A-B link down (what safed after
        // a communication loss needs); anything else needs B's acknowledgement.
        mode == module_mode::HOLD || self.ctrl.param(pid::B_LINK_OK).unwrap_or(0) == 1
    }

    fn progress_transition(&mut self, now: u64, sink: &mut impl TmSink) {
        let Some(t) = self.transition else { return };
        let mut changes: heapless::Vec<Change, N_NODES> = heapless::Vec::new();
        let root_ready = t.target != robot_mode::OPERATIONAL || t.entering == Entering::Ready;
        {
            let this = &*self;
            let confirmed: heapless::Vec<(u32, bool), N_NODES> = mib::modes::NODES
                .iter()
                .map(|n| (n.id, this.module_confirms(n, this.modes.commanded(n.id))))
                .collect();
            self.modes.update(
                |n, _| confirmed.iter().any(|(id, ok)| *id == n.id && *ok),
                root_ready,
                &mut changes,
            );
        }
        for c in &changes {
            self.event(
                now,
                eid::MODE_CHANGED,
                &[c.node as i64, c.from as i64, c.to as i64, t.cause as i64],
                sink,
            );
        }
        if t.target == robot_mode::OPERATIONAL && t.entering == Entering::Powering {
            let children_done = mib::modes::NODES
                .iter()
                .filter(|n| n.kind != NodeKind::Root)
                .all(|n| self.modes.get(n.id).is_some_and(|m| m.actual == m.commanded));
            if children_done {
                // Paper: hip mismatch is checked when entering operational, then
                // entering operational sends every actuator home.
                if self
                    .run_monitors(now, |p| p == Phase::EnteringOperational, sink)
                    .is_some()
                {
                    return;
                }
                match self.ctrl.start(Action::Home, now) {
                    Ok(_) => {
                        self.running = Some(Running {
                            req: None,
                            function: function::HOME,
                            reconfigure: false,
                        });
                        if let Some(t) = self.transition.as_mut() {
                            t.entering = Entering::Homing;
                        }
                    }
                    Err(_) => return self.transition_failed(now, FailureCode::BUSY, 0, sink),
                }
                return;
            }
        }
        if !self.modes.in_transition() {
            self.transition = None;
            self.mode_reply(now, node::ROBOT, sink);
            if let Some(c) = self.mode_cmd.take() {
                if c.target == self.modes.root() {
                    if c.ack.completion() {
                        self.verify(now, Stage::Completion, c.req, None, sink);
                    }
                    self.set_outcome(c.req, Outcome::Done);
                } else {
                    self.mode_cmd = Some(c);
                }
            }
            if t.target == robot_mode::OPERATIONAL {
                // Recovery done: one-shot faults and latches are cleared.
                self.faults.oneshot = 0;
                self.faults.latched = self.faults.monitored;
            } else if t.cause != 0 {
                // The fault has been dealt with by its mode change.
                self.clear_oneshot(now, t.cause, sink);
            }
            return;
        }
        let entering_homing = t.entering == Entering::Homing;
        if !entering_homing && now.saturating_sub(t.started) > config::MODE_TRANSITION_TIMEOUT_MS as u64 {
            self.transition_failed(now, FailureCode::TIMEOUT, 0, sink);
        }
    }

    fn clear_oneshot(&mut self, now: u64, event: u16, sink: &mut impl TmSink) {
        if let Some(f) = mib::fdir::fault_by_event(event) {
            if self.faults.oneshot & (1 << f.bit) != 0 {
                self.faults.oneshot &= !(1 << f.bit);
                self.event(now, eid::FAULT_CLEARED, &[event as i64], sink);
            }
        }
    }

    /// A transition that cannot complete: report it and fall back to standby.
    /// Completes a mode command with MODE_CHANGE_FAILED: node, target mode, the reason
    /// (a failure code) and the fault event behind it (0 if none).
    fn fail_mode_cmd(&mut self, now: u64, c: ModeCmd, reason: FailureCode, event: u16, sink: &mut impl TmSink) {
        let mut d = [0u8; 12];
        d[..4].copy_from_slice(&node::ROBOT.to_be_bytes());
        d[4..8].copy_from_slice(&c.target.to_be_bytes());
        d[8..10].copy_from_slice(&reason.code().to_be_bytes());
        d[10..].copy_from_slice(&event.to_be_bytes());
        self.verify(
            now,
            Stage::Completion,
            c.req,
            Some((FailureCode::MODE_CHANGE_FAILED, &d)),
            sink,
        );
        self.set_outcome(c.req, Outcome::Failed(FailureCode::MODE_CHANGE_FAILED.code()));
    }

    fn transition_failed(&mut self, now: u64, reason: FailureCode, event: u16, sink: &mut impl TmSink) {
        let Some(t) = self.transition.take() else { return };
        let mut d = [0u8; 12];
        d[..4].copy_from_slice(&node::ROBOT.to_be_bytes());
        d[4..8].copy_from_slice(&t.target.to_be_bytes());
        d[8..10].copy_from_slice(&0u16.to_be_bytes());
        d[10..12].copy_from_slice(&reason.code().to_be_bytes());
        self.emit(
            now,
            service::MODE,
            satrs::pus::mode::Subservice::TmCantReachMode as u8,
            &d,
            sink,
        );
        self.event(
            now,
            eid::MODE_CHANGE_FAILED,
            &[node::ROBOT as i64, t.target as i64, reason.code() as i64],
            sink,
        );
        if let Some(c) = self.mode_cmd.take() {
            self.fail_mode_cmd(now, c, reason, event, sink);
        }
        if t.target != robot_mode::STANDBY {
            self.set_mode(now, robot_mode::STANDBY, t.cause, sink);
        } else {
            let mut ch = heapless::Vec::new();
            self.modes.settle(&mut ch);
        }
    }

    // ------------------------------------------------------------------ FDIR

    /// Raises a fault event and applies its event-action link.
    fn fault(&mut self, now: u64, event: u16, args: &[i64], sink: &mut impl TmSink) {
        self.fault_inner(now, event, args, false, sink);
    }

    fn fault_inner(&mut self, now: u64, event: u16, args: &[i64], monitored: bool, sink: &mut impl TmSink) {
        self.event(now, event, args, sink);
        let bit = mib::fdir::fault_by_event(event).map_or(0, |f| 1u32 << f.bit);
        if !monitored && self.faults.oneshot & bit != 0 {
            // Already active and being dealt with (e.g. every command left unacknowledged
            // by a silent board B): reported, not counted or acted on again.
            return;
        }
        match self.faults.raise(event, monitored) {
            Response::None => {}
            // Standby already has every module unpowered and the robot resting on its
            // grippers: a fault never powers the servos up just to hold (safed).
            Response::Now(m) if m == robot_mode::SAFED && self.modes.root_target() == robot_mode::STANDBY => {
                self.clear_oneshot(now, event, sink);
            }
            Response::Now(m) => self.set_mode(now, m, event, sink),
            Response::AfterMotion(m) => {
                if self.running.is_some() {
                    self.faults.pending_mode = Some(match self.faults.pending_mode {
                        Some(p) if p == robot_mode::SAFED => p,
                        _ => m,
                    });
                } else if self.modes.root_target() != m {
                    self.set_mode(now, m, event, sink);
                } else {
                    self.clear_oneshot(now, event, sink);
                }
            }
        }
    }

    /// Runs the monitors of the accepted phases; emits TM[12,12] for each transition
    /// and raises the fault of each new violation. Returns the last fault event raised.
    fn run_monitors(&mut self, now: u64, phases: impl Fn(Phase) -> bool, sink: &mut impl TmSink) -> Option<u16> {
        let mut tr: heapless::Vec<fdir::Transition, N_MONITORS> = heapless::Vec::new();
        {
            let this = &*self;
            // A parameter without a valid value (board B never heard) is not checked.
            let mut vals = [None; N_MONITORS];
            for (v, m) in vals.iter_mut().zip(this.monitoring.mons.iter()) {
                *v = this.param_opt(m.def.param);
            }
            let ids: [u16; N_MONITORS] = core::array::from_fn(|i| this.monitoring.mons[i].def.param);
            self.monitoring.check(
                phases,
                |p| ids.iter().position(|x| *x == p).and_then(|i| vals[i]),
                &mut tr,
            );
        }
        self.faults.monitored = self.monitoring.violated_fault_bits();
        let mut raised = None;
        for t in &tr {
            let mut d = [0u8; 13];
            d[..2].copy_from_slice(&t.monitor.to_be_bytes());
            d[2..4].copy_from_slice(&t.param.to_be_bytes());
            d[4..8].copy_from_slice(&(t.value.clamp(i32::MIN as i64, i32::MAX as i64) as i32).to_be_bytes());
            d[8..12].copy_from_slice(&t.limit.to_be_bytes());
            d[12] = t.state;
            self.emit(now, service::MONITORING, 12, &d, sink);
            if t.state != fdir::check::OK {
                let args: [i64; 3] = if t.event == eid::HIP_MISMATCH {
                    [self.param(pid::HIP_ANGLE), self.param(pid::HIP_ANGLE) - t.value, 0]
                } else {
                    [t.param as i64, t.value, t.limit as i64]
                };
                let continuous = mib::fdir::monitor_by_id(t.monitor).is_some_and(|m| fdir::is_continuous(m.phase));
                self.fault_inner(now, t.event, &args, continuous, sink);
                raised = Some(t.event);
            } else if mib::fdir::monitor_by_id(t.monitor).is_some_and(|m| fdir::is_continuous(m.phase))
                && self.faults.monitored & mib::fdir::fault_by_event(t.event).map_or(0, |f| 1 << f.bit) == 0
            {
                self.event(now, eid::FAULT_CLEARED, &[t.event as i64], sink);
            }
        }
        raised
    }

    // ------------------------------------------------------------------ periodic

    /// One control cycle: runs the controller with the latest sensor readings and the
    /// bytes board B sent, then verification, events, FDIR, modes, HK, time reports
    /// and the schedule. Returns the actuator commands and bytes for board B.
    pub fn tick(&mut self, now: u64, sensors: &SensorsA, link_rx: &[u8], sink: &mut impl TmSink) -> &TickOut {
        self.last_now = self.last_now.max(now);
        let mut out = core::mem::take(&mut self.out);
        out.clear();
        self.ctrl.tick(now, sensors, link_rx, &mut out);
        for r in out.reports.clone().iter() {
            self.on_report(now, r, sink);
        }
        for e in out.events.clone().iter() {
            self.on_domain_event(now, e, sink);
        }
        self.run_monitors(now, fdir::is_continuous, sink);
        self.progress_transition(now, sink);
        for i in 0..N_HK {
            let h = self.hk[i];
            if h.enabled && now >= h.next {
                self.hk_report(now, i, sink);
                let next = h.next + h.interval as u64;
                self.hk[i].next = if next <= now { now + h.interval as u64 } else { next };
            }
        }
        if now >= self.next_time_report {
            self.time_report(now, sink);
            self.next_time_report = now + (1000u64 << self.time_exp);
        }
        self.release_schedule(now, sink);
        self.out = out;
        &self.out
    }

    fn release_schedule(&mut self, now: u64, sink: &mut impl TmSink) {
        if !self.sched_enabled {
            return;
        }
        while let Some(i) = self.sched.iter().position(|s| s.release <= now) {
            let s = self.sched.swap_remove(i);
            self.handle_tc(now, &s.tc, sink);
        }
    }

    fn on_report(&mut self, now: u64, r: &ActionReport, sink: &mut impl TmSink) {
        let Some(run) = self.running else { return };
        match r {
            ActionReport::Step { n } => {
                if let Some((req, ack)) = run.req {
                    if ack.progress() {
                        self.verify(now, Stage::Progress(*n), req, None, sink);
                    }
                }
            }
            ActionReport::Completed => {
                self.running = None;
                self.finish_running(now, &run, None, sink);
                if run.reconfigure {
                    // Paper: idle overcurrent is checked at the end of a reconfiguration too.
                    self.idle_check(now, sink);
                }
            }
            ActionReport::Failed { code, data, len } => {
                self.running = None;
                let f = fail(*code, &data[..(*len as usize).min(data.len())]);
                self.finish_running(now, &run, Some(f), sink);
            }
        }
    }

    fn on_domain_event(&mut self, now: u64, e: &DomainEvent, sink: &mut impl TmSink) {
        let s = |v: Side| v as i64;
        match *e {
            DomainEvent::PrimitiveDone { primitive, state } => {
                self.event(now, eid::PRIMITIVE_DONE, &[primitive as i64, state as i64], sink)
            }
            DomainEvent::StateReached { state } => self.event(now, eid::STATE_REACHED, &[state as i64], sink),
            DomainEvent::BoltPairDone { side, pair, attempts } => {
                self.event(now, eid::BOLT_PAIR_DONE, &[s(side), pair as i64, attempts as i64], sink)
            }
            DomainEvent::BoltAttemptFailed { side, pair, attempt } => self.event(
                now,
                eid::BOLT_ATTEMPT_FAILED,
                &[s(side), pair as i64, attempt as i64],
                sink,
            ),
            DomainEvent::UnboltPairDone { side, pair, attempts } => self.event(
                now,
                eid::UNBOLT_PAIR_DONE,
                &[s(side), pair as i64, attempts as i64],
                sink,
            ),
            DomainEvent::BoltFailure { side, pair, attempts } => {
                self.fault(now, eid::BOLT_FAILURE, &[s(side), pair as i64, attempts as i64], sink)
            }
            DomainEvent::UnboltFailure { side, pair, attempts } => {
                self.fault(now, eid::UNBOLT_FAILURE, &[s(side), pair as i64, attempts as i64], sink)
            }
            DomainEvent::ArmNotContracted { side } => self.fault(now, eid::ARM_NOT_CONTRACTED, &[s(side)], sink),
            DomainEvent::CommLossNoAck { command, retries } => {
                self.fault(now, eid::COMM_LOSS_NO_ACK, &[command as i64, retries as i64], sink)
            }
            // The state computed after a primitive is not the one planned: the robot is
            // not where the ground believes, the same hazard as an initial-state mismatch.
            DomainEvent::StateMismatch { expected, computed } => self.fault(
                now,
                eid::INITIAL_STATE_MISMATCH,
                &[expected as i64, computed as i64],
                sink,
            ),
            _ => {}
        }
    }

    /// Parameter value for the state estimate shown to tests and the host.
    pub fn computed_state(&self) -> u8 {
        self.ctrl.computed_state().unwrap_or(STATE_UNKNOWN)
    }
}

/// Splits one TC[11,4] activity: 7-byte CDS release time, then a TC whose length comes
/// from its own primary header.
fn split_activity(data: &[u8]) -> Option<(&[u8], &[u8], &[u8])> {
    let t = config::TIMESTAMP_LEN;
    if data.len() < t + PRIMARY_LEN {
        return None;
    }
    let (release, rest) = data.split_at(t);
    let len = PRIMARY_LEN + u16::from_be_bytes([rest[4], rest[5]]) as usize + 1;
    if rest.len() < len {
        return None;
    }
    let (tc, tail) = rest.split_at(len);
    Some((release, tc, tail))
}
