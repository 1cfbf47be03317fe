//! Everything that leaves the OBSW goes through [`Downlink`]: service reports (stamped
//! by the [`TmWriter`]), PUS 1 verification reports (request ID, step, failure code and
//! data, through the same TM writer; driven by typestate tokens), PUS 5 events (enable mask
//! and throttling) and the copy kept in the on-board store.
//!
//! Verification follows the request's life: [`Downlink::accept`] turns a fresh token
//! into an accepted one, [`Downlink::start`] an accepted one into a started one, and
//! [`Downlink::complete`] / [`Downlink::fail_completion`] consume the started token.
//! Each failure consumes the token of its stage, so no report can be written for a
//! stage the request is not in, and none twice. The tokens are sat-rs's
//! `VerificationToken<TcStateAccepted/Started>`; only this module advances them.
//!
//! A request cannot be completed twice (the started token is moved):
//!
//! ```compile_fail,E0382
//! use obsw_core::downlink::{Downlink, Started};
//! use obsw_core::tm::{RingStore, TmSink};
//! struct S;
//! impl TmSink for S { fn send_tm(&mut self, _: &[u8]) {} }
//! fn twice(dl: &mut Downlink<RingStore<64>>, t: Started) {
//!     dl.complete(0, t, &mut S);
//!     dl.complete(0, t, &mut S);
//! }
//! ```
//!
//! nor completed before it was started (an accepted token is not a started one):
//!
//! ```compile_fail,E0308
//! use obsw_core::downlink::{Accepted, Downlink};
//! use obsw_core::tm::{RingStore, TmSink};
//! struct S;
//! impl TmSink for S { fn send_tm(&mut self, _: &[u8]) {} }
//! fn skip_start(dl: &mut Downlink<RingStore<64>>, t: Accepted) {
//!     dl.complete(0, t, &mut S);
//! }
//! ```

use mib::config;
use mib::events::{self, EVENTS};
use mib::params::{pid, NotSupplied, Supplied};
use mib::tc::service;
use mib_wire::RequestId;
use satrs::pus::verification::{
    RequestId as SatrsRequestId, TcStateAccepted, TcStateNone, TcStateStarted, VerificationToken,
};

use crate::accept::Ack;
use crate::failure::{Failure, SentFailure};
use crate::time::OnboardTime;
use crate::tm::{TmSink, TmStore, TmWriter};

const N_EVENTS: usize = EVENTS.len();
const _: () = assert!(N_EVENTS <= 64, "event enable mask is a u64");

/// A service report of the wire crate. Implemented per report kind the core sends, so
/// that only those kinds' emit code is linked (flash on the firmware).
pub trait Report {
    const SERVICE: u8;
    const SUBSERVICE: u8;
    fn emit(&self, buf: &mut [u8]) -> Result<usize, mib_wire::Error>;
}

macro_rules! reports {
    ($($t:ident),* $(,)?) => {$(
        impl Report for mib_wire::tm::$t {
            const SERVICE: u8 = mib_wire::tm::$t::SERVICE;
            const SUBSERVICE: u8 = mib_wire::tm::$t::SUBSERVICE;
            fn emit(&self, buf: &mut [u8]) -> Result<usize, mib_wire::Error> {
                mib_wire::tm::$t::emit(self, buf)
            }
        }
    )*};
}

reports!(
    PingReply,
    HkReport,
    DisabledEvents,
    TimeReport,
    MonDefinitions,
    MonTransition,
    StoreDownlinkDone,
    EaDefinitions,
    ParamValue,
    ModeReply,
    ModeCantReach,
    ModuleReport,
    TeamStatus,
    PlanStatus,
);

/// A request's verification token with the acknowledgement flags the TC asked for.
/// Not `Copy` or `Clone`: each stage consumes the token of the stage before, so a
/// request is completed (or failed) once.
#[derive(Debug, PartialEq, Eq)]
pub struct Token<State> {
    tok: VerificationToken<State>,
    pub ack: Ack,
    pub req: RequestId,
}

pub type New = Token<TcStateNone>;
pub type Accepted = Token<TcStateAccepted>;
pub type Started = Token<TcStateStarted>;

impl New {
    /// The token of a TC that has just arrived.
    pub fn new(req: RequestId, ack: Ack) -> Self {
        Token {
            // The one conversion to sat-rs's request ID, whose verification tokens
            // order the stages; both are the same 32 bits (packet ID, sequence control).
            tok: VerificationToken::<TcStateNone>::new(SatrsRequestId::from(req.raw())),
            ack,
            req,
        }
    }
}

/// The verification stage a failure was reported at (kept for duplicate TCs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    Acceptance,
    Start,
    Completion,
}

#[derive(Clone, Copy, Debug, Default)]
struct Throttle {
    window_start: u64,
    count: u8,
}

/// Event reporting state (PUS 5): enable mask, throttling and counters.
pub struct Events {
    disabled: u64,
    throttle: [Throttle; N_EVENTS],
    pub throttled: u32,
}

impl Default for Events {
    fn default() -> Self {
        Events {
            disabled: 0,
            throttle: [Throttle::default(); N_EVENTS],
            throttled: 0,
        }
    }
}

/// Index of an event in `mib::events::EVENTS`; only made from a defined event ID.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EventIndex(usize);

impl EventIndex {
    pub fn of(id: u16) -> Option<Self> {
        EVENTS.iter().position(|e| e.id == id).map(EventIndex)
    }
}

impl Events {
    pub fn set_enabled(&mut self, e: EventIndex, enabled: bool) {
        if enabled {
            self.disabled &= !(1 << e.0);
        } else {
            self.disabled |= 1 << e.0;
        }
    }
    pub fn is_enabled(&self, e: EventIndex) -> bool {
        self.disabled & (1 << e.0) == 0
    }
    /// True when the event may be reported now (enabled and not throttled); counts it.
    fn admit(&mut self, now: u64, e: EventIndex) -> bool {
        if !self.is_enabled(e) {
            return false;
        }
        let id = EVENTS[e.0].id;
        let t = &mut self.throttle[e.0];
        if now.saturating_sub(t.window_start) >= config::EVENT_THROTTLE_WINDOW_MS as u64 {
            *t = Throttle {
                window_start: now,
                count: 0,
            };
        }
        if !events::UNTHROTTLED.contains(&id) && t.count >= config::EVENT_THROTTLE_MAX {
            self.throttled = self.throttled.wrapping_add(1);
            return false;
        }
        t.count = t.count.saturating_add(1);
        true
    }
}

/// The TM path of one robot.
pub struct Downlink<S: TmStore> {
    pub tmw: TmWriter,
    pub store: S,
    pub store_enabled: bool,
    pub store_dropped: u32,
    pub events: Events,
}

impl<S: TmStore> Downlink<S> {
    /// The sequence count goes on from the newest packet of `apid` in the store (kept
    /// across a reset): a restart leaves a gap of counts the ground can ask for, never a
    /// second packet with a count the store still holds.
    pub fn new(apid: u16, time: OnboardTime, mut store: S) -> Self {
        let mut tmw = TmWriter::new(apid, time);
        let mut newest = None;
        store.visit(&mut |p| {
            if let Ok(h) = mib_wire::header::Primary::parse(p) {
                if h.apid == apid {
                    newest = Some(h.seq_count);
                }
            }
        });
        if let Some(seq) = newest {
            tmw.continue_after(seq);
        }
        Downlink {
            tmw,
            store,
            store_enabled: true,
            store_dropped: 0,
            events: Events::default(),
        }
    }

    /// The parameters the MIB names the downlink the source of.
    pub fn param(&self, id: u16) -> Supplied {
        Ok(Some(match id {
            pid::TM_SENT => i64::from(self.tmw.sent),
            pid::TM_STORED => self.store.len() as i64,
            pid::TM_STORE_DROPPED => i64::from(self.store_dropped),
            pid::EVENTS_THROTTLED => i64::from(self.events.throttled),
            _ => return Err(NotSupplied(id)),
        }))
    }

    /// Stamps and sends a service report.
    pub fn emit(&mut self, now: u64, svc: u8, sub: u8, data: &[u8], sink: &mut impl TmSink) {
        let mut buf = [0u8; config::MAX_PACKET_LEN];
        if let Some(n) = self.tmw.build(now, svc, sub, data, &mut buf) {
            self.send_raw(&buf[..n], sink);
        }
    }

    /// Stamps and sends a service report built by the wire crate (`mib_wire::tm`): the
    /// body is laid out by the MIB's field list, never by hand.
    pub fn emit_tm<R: Report>(&mut self, now: u64, r: &R, sink: &mut impl TmSink) {
        let mut body = [0u8; config::MAX_PACKET_LEN];
        // Every report of the core fits a packet (MAX_PACKET_LEN bounds its body).
        if let Ok(n) = r.emit(&mut body) {
            self.emit(now, R::SERVICE, R::SUBSERVICE, &body[..n], sink);
        }
    }

    /// Sends a finished packet and keeps a copy in the store.
    pub fn send_raw(&mut self, pkt: &[u8], sink: &mut impl TmSink) {
        sink.send_tm(pkt);
        self.tmw.sent = self.tmw.sent.wrapping_add(1);
        if self.store_enabled {
            self.store_dropped = self.store_dropped.wrapping_add(self.store.push(pkt));
        }
    }

    /// The end of a control period: the store may free ahead of need (what it gives up
    /// is counted as overwritten).
    pub fn end_period(&mut self) {
        self.store_dropped = self.store_dropped.wrapping_add(self.store.end_period());
    }

    /// Emits a typed event (`mib_wire::ev`: every field named at the call) unless it is
    /// disabled or throttled.
    pub fn raise<E: mib_wire::EventArgs>(&mut self, now: u64, e: E, sink: &mut impl TmSink) {
        self.event(now, E::ID, e.values().as_ref(), sink);
    }

    /// Emits an event report unless the event is disabled or throttled.
    pub fn event(&mut self, now: u64, id: u16, args: &[i64], sink: &mut impl TmSink) {
        let Some(e) = EventIndex::of(id) else { return };
        if !self.events.admit(now, e) {
            return;
        }
        let def = &EVENTS[e.0];
        let mut buf = [0u8; config::EVENT_DATA_MAX];
        if let Ok(n) = mib_wire::codec::encode_event(def, args, &mut buf) {
            self.emit(now, service::EVENT, def.severity.subservice(), &buf[..n], sink);
        }
    }

    // ------------------------------------------------------------ verification

    /// A PUS 1 report, TM[1,`sub`]: the request ID, the step (progress reports), the
    /// failure code and data (failure reports), through the TM writer's header code.
    fn report(
        &mut self,
        now: u64,
        sub: u8,
        req: RequestId,
        step: Option<u8>,
        fail: Option<SentFailure>,
        sink: &mut impl TmSink,
    ) {
        let mut out = [0u8; config::MAX_PACKET_LEN];
        let n = self.tmw.build_with(now, service::VERIFICATION, sub, &mut out, |d| {
            let mut w = mib_wire::Writer::new(d);
            w.bytes(&req.to_bytes())?;
            if let Some(n) = step {
                w.uint(8, n.into())?;
            }
            if let Some(f) = fail {
                w.uint(16, f.code().into())?;
                w.bytes(f.data())?;
            }
            Ok(w.len())
        });
        if let Some(n) = n {
            self.send_raw(&out[..n], sink);
        }
    }

    /// TM[1,1] (if asked for): the request is accepted.
    pub fn accept(&mut self, now: u64, t: New, sink: &mut impl TmSink) -> Accepted {
        let rid = t.tok.request_id();
        if t.ack.acceptance() {
            self.report(now, 1, t.req, None, None, sink);
        }
        Token {
            tok: VerificationToken::new_accepted_state(rid),
            ack: t.ack,
            req: t.req,
        }
    }

    /// TM[1,2]: the request is refused (always reported).
    pub fn reject(&mut self, now: u64, t: New, f: &Failure, sink: &mut impl TmSink) {
        self.fail(now, t.req, Stage::Acceptance, f.into(), sink);
    }

    /// TM[1,3] (if asked for): execution started.
    pub fn start(&mut self, now: u64, t: Accepted, sink: &mut impl TmSink) -> Started {
        let rid = t.tok.request_id();
        if t.ack.start() {
            self.report(now, 3, t.req, None, None, sink);
        }
        Token {
            tok: VerificationToken::new_started_state(rid),
            ack: t.ack,
            req: t.req,
        }
    }

    /// TM[1,4]: execution could not start (always reported).
    pub fn fail_start(&mut self, now: u64, t: Accepted, f: &Failure, sink: &mut impl TmSink) {
        self.fail(now, t.req, Stage::Start, f.into(), sink);
    }

    /// TM[1,5] (if asked for): progress step `n` done.
    pub fn step(&mut self, now: u64, t: &Started, n: u8, sink: &mut impl TmSink) {
        if !t.ack.progress() {
            return;
        }
        self.report(now, 5, t.req, Some(n), None, sink);
    }

    /// TM[1,6]: progress step `n` failed; the request ends (always reported).
    pub fn fail_step(&mut self, now: u64, t: Started, n: u8, f: &Failure, sink: &mut impl TmSink) {
        self.report(now, 6, t.req, Some(n), Some(f.into()), sink);
    }

    /// TM[1,7] (if asked for): the request completed.
    pub fn complete(&mut self, now: u64, t: Started, sink: &mut impl TmSink) {
        if t.ack.completion() {
            self.repeat_completion(now, t.req, sink);
        }
    }

    /// TM[1,8]: the request failed (always reported).
    pub fn fail_completion(&mut self, now: u64, t: Started, f: &Failure, sink: &mut impl TmSink) {
        self.fail(now, t.req, Stage::Completion, f.into(), sink);
    }

    /// Repeats TM[1,7] for a duplicate of a request that completed.
    pub fn repeat_completion(&mut self, now: u64, req: RequestId, sink: &mut impl TmSink) {
        self.report(now, 7, req, None, None, sink);
    }

    /// Repeats TM[1,1] for a duplicate of an accepted request.
    pub fn repeat_acceptance(&mut self, now: u64, req: RequestId, sink: &mut impl TmSink) {
        self.report(now, 1, req, None, None, sink);
    }

    /// A failure report at `stage`; used for the first report (through the token
    /// methods above) and to repeat it for a duplicate.
    pub fn fail(&mut self, now: u64, req: RequestId, stage: Stage, f: SentFailure, sink: &mut impl TmSink) {
        let sub = match stage {
            Stage::Acceptance => 2,
            Stage::Start => 4,
            Stage::Completion => 8,
        };
        self.report(now, sub, req, None, Some(f), sink);
    }
}
