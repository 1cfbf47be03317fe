//! FOP-1, the ground's frame operation procedure of COP-1 (CCSDS 232.1-B-2 §5, state table
//! 5-1, Rev. B event numbering as Yamcs 5.12.8's `Cop1TcPacketHandler` uses it). A pure state
//! machine: [`Fop::on_event`]`(now_ms, input) -> effects`; the caller sends what the effects
//! say and feeds back CLCWs and ticks.
//!
//! FDUs are opaque handles `T` (an id the ground maps to its packet): the FOP never builds
//! frames. A `TransmitAd` effect asks the caller to build and send an AD frame with the given
//! N(S) — a retransmission is a new SDLS encryption with a fresh IV, so the on-board
//! anti-replay window never refuses it. The lower layer (one UDP datagram per frame) accepts
//! every frame at once, so AD_Out/BC_Out are always ready (events E41-E46 are implicit).
//!
//! "Sent" means acknowledged: [`FopEffect::Acknowledged`] is emitted only when a CLCW's
//! N(R) passes the frame; [`FopEffect::NotDelivered`] when an alert or termination purges it.
//!
//! **Timer T1.** 232.1-B-2 leaves T1's value to management. With
//! [`FopConfig::t1_min_ms`] below [`FopConfig::t1_ms`] it adapts to the measured round trip
//! ([`T1Estimator`]: TCP's RTO rule, RFC 6298, with Karn's rule), between those two bounds;
//! otherwise it is the fixed `t1_ms`. `docs/space-link.md` (§ "Timer T1") gives the rule.

use crate::clcw::{Clcw, CopInEffect};
use crate::tc::ControlCommand;

/// Largest sliding window this implementation holds (the MIB uses 10).
pub const MAX_WINDOW: usize = 16;
/// Capacity of one effects list: every sent frame retransmitted and acknowledged, plus spare.
pub const MAX_EFFECTS: usize = 2 * MAX_WINDOW + 8;

/// FOP-1 states.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FopState {
    /// S1.
    Active,
    /// S2.
    RetransmitWithoutWait,
    /// S3.
    RetransmitWithWait,
    /// S4.
    InitialisingWithoutBc,
    /// S5.
    InitialisingWithBc,
    /// S6.
    Initial,
}

impl FopState {
    fn num(self) -> u8 {
        match self {
            FopState::Active => 1,
            FopState::RetransmitWithoutWait => 2,
            FopState::RetransmitWithWait => 3,
            FopState::InitialisingWithoutBc => 4,
            FopState::InitialisingWithBc => 5,
            FopState::Initial => 6,
        }
    }
}

/// FOP-1 management parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FopConfig {
    /// K, 1..=MAX_WINDOW.
    pub sliding_window: u8,
    /// T1 in milliseconds; with an adaptive T1 its upper bound and its value before the
    /// first round-trip sample.
    pub t1_ms: u64,
    /// Lower bound of the adaptive T1; `t1_min_ms >= t1_ms` means a fixed T1 of `t1_ms`.
    pub t1_min_ms: u64,
    /// Transmissions per frame, first one included (≥ 1).
    pub tx_limit: u8,
    /// 0: alert when the limit is reached; 1: suspend.
    pub timeout_type: u8,
}

impl FopConfig {
    /// The mission's parameters from `mib::link::cop1`.
    pub fn mission() -> FopConfig {
        use mib::link::cop1::*;
        FopConfig {
            sliding_window: FOP_SLIDING_WINDOW,
            t1_ms: FOP_T1_MS,
            t1_min_ms: FOP_T1_MIN_MS,
            tx_limit: FOP_TX_LIMIT,
            timeout_type: FOP_TIMEOUT_TYPE,
        }
    }
}

/// Adaptive T1 from the measured round trip (RFC 6298's retransmission timer, integer form
/// of Jacobson's estimator): the round trip of an AD frame is the time from its first
/// transmission to the first CLCW whose N(R) passes it; a Set V(R)/Unlock BC frame's, to
/// the CLCW that completes the initialisation. **Karn's rule**: a frame transmitted more
/// than once gives no sample (which transmission did the CLCW answer?). On T1's expiry the
/// value doubles (up to the upper bound) until the next valid sample.
///
/// `srtt8` is 8 × SRTT and `rttvar4` 4 × RTTVAR (milliseconds), so gains of 1/8 and 1/4 keep
/// their fractions: T1 = SRTT + 4 × RTTVAR = `srtt8 / 8 + rttvar4`, clamped to
/// [`min_ms`, `max_ms`]. Before the first sample T1 is `max_ms`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct T1Estimator {
    srtt8: u64,
    rttvar4: u64,
    samples: u32,
    backoff: u8,
    min_ms: u64,
    max_ms: u64,
}

impl T1Estimator {
    /// Most doublings remembered (the result is clamped to the upper bound anyway).
    const MAX_BACKOFF: u8 = 16;

    /// An estimator with no sample yet; `min_ms >= max_ms` gives a fixed T1 of `max_ms`.
    pub const fn new(min_ms: u64, max_ms: u64) -> T1Estimator {
        T1Estimator {
            srtt8: 0,
            rttvar4: 0,
            samples: 0,
            backoff: 0,
            min_ms,
            max_ms,
        }
    }

    /// Whether T1 adapts (the lower bound is below the upper one).
    pub fn adaptive(&self) -> bool {
        self.min_ms < self.max_ms
    }

    /// New bounds (management's Set T1 changes the upper one); the samples are kept.
    pub fn set_bounds(&mut self, min_ms: u64, max_ms: u64) {
        self.min_ms = min_ms;
        self.max_ms = max_ms;
    }

    /// One round-trip sample in milliseconds (of a frame transmitted once only: Karn's
    /// rule is the caller's). Ends a backoff.
    pub fn sample(&mut self, rtt_ms: u64) {
        // Bounded so the scaled sums cannot overflow (an hour is far beyond any T1).
        let r = rtt_ms.min(3_600_000);
        if self.samples == 0 {
            self.srtt8 = r * 8;
            self.rttvar4 = r * 2;
        } else {
            let srtt = self.srtt8 / 8;
            let err = srtt.abs_diff(r);
            self.rttvar4 = self.rttvar4 - self.rttvar4 / 4 + err;
            self.srtt8 = self.srtt8 - self.srtt8 / 8 + r;
        }
        self.samples = self.samples.saturating_add(1);
        self.backoff = 0;
    }

    /// T1 expired: the next T1 is twice the current one (at most the upper bound).
    pub fn expired(&mut self) {
        if self.adaptive() && self.t1_ms() < self.max_ms {
            self.backoff = (self.backoff + 1).min(Self::MAX_BACKOFF);
        }
    }

    /// Round-trip samples taken.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The smoothed round trip (ms), once there is a sample.
    pub fn srtt_ms(&self) -> Option<u64> {
        (self.samples > 0).then_some(self.srtt8 / 8)
    }

    /// T1 now, in milliseconds.
    pub fn t1_ms(&self) -> u64 {
        if !self.adaptive() || self.samples == 0 {
            return self.max_ms;
        }
        let base = (self.srtt8 / 8 + self.rttvar4).clamp(self.min_ms, self.max_ms);
        base.saturating_mul(1u64 << self.backoff).min(self.max_ms)
    }
}

/// Why FOP-1 gave up (it then purges its queues and enters S6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AlertReason {
    /// The FARM reported lockout (E14).
    Lockout,
    /// A CLCW inconsistent with what was sent (E1/E4/E5 in the wrong state).
    Synch,
    /// Wait flag without retransmit flag (E3, E7).
    Clcw,
    /// N(R) outside [NN(R), V(S)] (E13).
    Nnr,
    /// Retransmission limit reached with transmission limit 1 (E101, E102).
    Limit,
    /// Timer T1 expired the last time (E17, E18 in S5) or in S4 (E16).
    T1,
    /// Terminate AD directive (E29).
    Terminated,
}

/// The standard's events, for traces and tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FopEvent {
    E1,
    E2,
    E3,
    E4,
    E5,
    E6,
    E7,
    E8,
    E9,
    E10,
    E11,
    E12,
    E13,
    E14,
    E16,
    E17,
    E18,
    E19,
    E20,
    E21,
    E23,
    E24,
    E25,
    E27,
    E29,
    E30,
    E31,
    E32,
    E33,
    E34,
    E35,
    E36,
    E37,
    E38,
    E39,
    E101,
    E102,
    E103,
    E104,
    /// A CLCW for another VC or without COP-1 in effect: ignored.
    ClcwIgnored,
    /// A tick before the timer expired.
    NoTimeout,
    /// A directive not allowed in this state.
    Rejected,
}

/// Inputs: CLCWs, time, requests from the higher layer, management directives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FopInput<T> {
    Clcw(Clcw),
    /// Time passed; fires the timer if it expired.
    Tick,
    /// Request to transfer an FDU on the AD service (E19/E20).
    TransmitAd(T),
    /// Request to transfer an FDU on the BD service (E21).
    TransmitBd(T),
    InitiateAdWithoutClcw,
    InitiateAdWithClcw,
    InitiateAdWithUnlock,
    InitiateAdWithSetVr(u8),
    TerminateAd,
    ResumeAd,
    SetVs(u8),
    SetSlidingWindow(u8),
    SetT1(u64),
    SetTxLimit(u8),
    SetTimeoutType(u8),
}

/// What the caller does.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FopEffect<T> {
    /// Build and send a type-AD frame with this N(S) (fresh SDLS IV every time).
    TransmitAd {
        ns: u8,
        fdu: T,
        retransmission: bool,
    },
    /// Build and send a type-BD frame.
    TransmitBd(T),
    /// Send a type-BC frame (in clear).
    TransmitBc(ControlCommand),
    /// A CLCW acknowledged the frame: it was received on board. "Sent".
    Acknowledged {
        ns: u8,
        fdu: T,
    },
    /// The FDU was accepted into the FOP (moved to the sent queue).
    RequestAccepted,
    /// The request was refused (wait queue busy or AD service not active); FDU handed back.
    RequestRejected(T),
    /// The frame will never be acknowledged (alert, termination): not sent.
    NotDelivered {
        ns: u8,
        fdu: T,
    },
    /// A queued request purged by an alert.
    Purged(T),
    DirectiveAccepted,
    DirectiveRejected,
    /// The initiation of the AD service completed (S4/S5 → S1, or E23).
    Initialised,
    Alert(AlertReason),
    /// Suspended in S6 by timeout type 1; `ResumeAd` returns to this state.
    Suspended(FopState),
    /// The event recognised (first effect of every call).
    Event(FopEvent),
}

/// Effects of one call.
pub type Effects<T> = heapless::Vec<FopEffect<T>, MAX_EFFECTS>;

#[derive(Clone, Debug)]
struct Sent<T> {
    ns: u8,
    fdu: T,
    /// Marked for retransmission.
    retransmit: bool,
    /// First transmission (ms) and whether it was ever retransmitted (Karn's rule).
    first_tx_ms: u64,
    retransmitted: bool,
}

/// FOP-1 for one virtual channel.
#[derive(Clone, Debug)]
pub struct Fop<T: Clone> {
    state: FopState,
    vcid: u8,
    vs: u8,
    nnr: u8,
    sent: heapless::Deque<Sent<T>, MAX_WINDOW>,
    wait_queue: Option<T>,
    timer: Option<u64>,
    tx_count: u8,
    suspend_state: u8,
    pending_bc: Option<ControlCommand>,
    /// When the pending BC frame was sent, while it has been sent once only.
    bc_tx_ms: Option<u64>,
    rtt: T1Estimator,
    config: FopConfig,
}

fn push<T>(fx: &mut Effects<T>, e: FopEffect<T>) {
    // Capacity covers the worst case (MAX_EFFECTS ≥ 2 × window + the fixed effects).
    debug_assert!(!fx.is_full(), "FOP effects capacity exceeded");
    let _ = fx.push(e);
}

impl<T: Clone> Fop<T> {
    pub fn new(vcid: u8, mut config: FopConfig) -> Fop<T> {
        config.sliding_window = config.sliding_window.clamp(1, MAX_WINDOW as u8);
        config.tx_limit = config.tx_limit.max(1);
        Fop {
            state: FopState::Initial,
            vcid,
            vs: 0,
            nnr: 0,
            sent: heapless::Deque::new(),
            wait_queue: None,
            timer: None,
            tx_count: 1,
            suspend_state: 0,
            pending_bc: None,
            bc_tx_ms: None,
            rtt: T1Estimator::new(config.t1_min_ms, config.t1_ms),
            config,
        }
    }

    /// T1 as it is now (the fixed value, or the adaptive one).
    pub fn t1_ms(&self) -> u64 {
        self.rtt.t1_ms()
    }

    /// The round-trip estimator behind an adaptive T1.
    pub fn t1_estimator(&self) -> &T1Estimator {
        &self.rtt
    }

    pub fn state(&self) -> FopState {
        self.state
    }

    /// V(S), the N(S) of the next new frame.
    pub fn vs(&self) -> u8 {
        self.vs
    }

    /// NN(R), the oldest unacknowledged N(S).
    pub fn nnr(&self) -> u8 {
        self.nnr
    }

    pub fn tx_count(&self) -> u8 {
        self.tx_count
    }

    /// Frames sent and not yet acknowledged.
    pub fn outstanding(&self) -> usize {
        self.sent.len()
    }

    /// Whether a `TransmitAd` request would be taken now (wait queue empty, AD active).
    pub fn ready(&self) -> bool {
        self.wait_queue.is_none() && self.state != FopState::Initial
    }

    /// When the caller should send the next `Tick`.
    pub fn next_deadline(&self) -> Option<u64> {
        self.timer
    }

    pub fn config(&self) -> FopConfig {
        self.config
    }

    pub fn on_event(&mut self, now: u64, input: FopInput<T>) -> Effects<T> {
        let mut fx = Effects::new();
        match input {
            FopInput::Clcw(c) => self.on_clcw(now, c, &mut fx),
            FopInput::Tick => self.on_tick(now, &mut fx),
            FopInput::TransmitAd(fdu) => {
                if self.wait_queue.is_none() && self.state != FopState::Initial {
                    push(&mut fx, FopEffect::Event(FopEvent::E19));
                    self.wait_queue = Some(fdu);
                    if matches!(self.state, FopState::Active | FopState::RetransmitWithoutWait) {
                        self.look_for_fdu(now, &mut fx);
                    }
                } else {
                    push(&mut fx, FopEffect::Event(FopEvent::E20));
                    push(&mut fx, FopEffect::RequestRejected(fdu));
                }
            }
            FopInput::TransmitBd(fdu) => {
                push(&mut fx, FopEffect::Event(FopEvent::E21));
                push(&mut fx, FopEffect::TransmitBd(fdu));
            }
            FopInput::InitiateAdWithoutClcw => self.initiate(now, FopEvent::E23, None, &mut fx),
            FopInput::InitiateAdWithClcw => self.initiate(now, FopEvent::E24, None, &mut fx),
            FopInput::InitiateAdWithUnlock => self.initiate(now, FopEvent::E25, Some(ControlCommand::Unlock), &mut fx),
            FopInput::InitiateAdWithSetVr(v) => {
                self.initiate(now, FopEvent::E27, Some(ControlCommand::SetVr(v)), &mut fx)
            }
            FopInput::TerminateAd => {
                push(&mut fx, FopEffect::Event(FopEvent::E29));
                push(&mut fx, FopEffect::DirectiveAccepted);
                self.alert(AlertReason::Terminated, &mut fx);
            }
            FopInput::ResumeAd => {
                let target = match (self.state, self.suspend_state) {
                    (FopState::Initial, 1) => Some((FopEvent::E31, FopState::Active)),
                    (FopState::Initial, 2) => Some((FopEvent::E32, FopState::RetransmitWithoutWait)),
                    (FopState::Initial, 3) => Some((FopEvent::E33, FopState::RetransmitWithWait)),
                    (FopState::Initial, 4) => Some((FopEvent::E34, FopState::InitialisingWithoutBc)),
                    _ => None,
                };
                match target {
                    Some((ev, st)) => {
                        push(&mut fx, FopEffect::Event(ev));
                        push(&mut fx, FopEffect::DirectiveAccepted);
                        self.timer = Some(now.saturating_add(self.rtt.t1_ms()));
                        self.suspend_state = 0;
                        self.state = st;
                    }
                    None => {
                        push(&mut fx, FopEffect::Event(FopEvent::E30));
                        push(&mut fx, FopEffect::DirectiveRejected);
                    }
                }
            }
            FopInput::SetVs(v) => {
                if self.state == FopState::Initial && self.suspend_state == 0 {
                    push(&mut fx, FopEffect::Event(FopEvent::E35));
                    push(&mut fx, FopEffect::DirectiveAccepted);
                    self.vs = v;
                    self.nnr = v;
                } else {
                    push(&mut fx, FopEffect::Event(FopEvent::Rejected));
                    push(&mut fx, FopEffect::DirectiveRejected);
                }
            }
            FopInput::SetSlidingWindow(k) => {
                push(&mut fx, FopEffect::Event(FopEvent::E36));
                self.config.sliding_window = k.clamp(1, MAX_WINDOW as u8);
                push(&mut fx, FopEffect::DirectiveAccepted);
            }
            FopInput::SetT1(ms) => {
                push(&mut fx, FopEffect::Event(FopEvent::E37));
                // A fixed T1 stays fixed (at the new value); an adaptive one gets a new
                // upper bound.
                if !self.rtt.adaptive() {
                    self.config.t1_min_ms = ms;
                }
                self.config.t1_ms = ms;
                self.rtt.set_bounds(self.config.t1_min_ms, ms);
                push(&mut fx, FopEffect::DirectiveAccepted);
            }
            FopInput::SetTxLimit(n) => {
                push(&mut fx, FopEffect::Event(FopEvent::E38));
                self.config.tx_limit = n.max(1);
                push(&mut fx, FopEffect::DirectiveAccepted);
            }
            FopInput::SetTimeoutType(t) => {
                push(&mut fx, FopEffect::Event(FopEvent::E39));
                self.config.timeout_type = t & 1;
                push(&mut fx, FopEffect::DirectiveAccepted);
            }
        }
        fx
    }

    fn initialize(&mut self, fx: &mut Effects<T>) {
        self.purge(fx);
        self.tx_count = 1;
        self.suspend_state = 0;
    }

    fn initiate(&mut self, now: u64, ev: FopEvent, bc: Option<ControlCommand>, fx: &mut Effects<T>) {
        if self.state != FopState::Initial {
            push(fx, FopEffect::Event(FopEvent::Rejected));
            push(fx, FopEffect::DirectiveRejected);
            return;
        }
        push(fx, FopEffect::Event(ev));
        push(fx, FopEffect::DirectiveAccepted);
        self.initialize(fx);
        match (ev, bc) {
            (FopEvent::E23, _) => {
                self.timer = None;
                self.state = FopState::Active;
                push(fx, FopEffect::Initialised);
            }
            (_, Some(cmd)) => {
                if let ControlCommand::SetVr(v) = cmd {
                    self.vs = v;
                    self.nnr = v;
                }
                self.pending_bc = Some(cmd);
                self.bc_tx_ms = Some(now);
                push(fx, FopEffect::TransmitBc(cmd));
                self.timer = Some(now.saturating_add(self.rtt.t1_ms()));
                self.state = FopState::InitialisingWithBc;
            }
            (_, None) => {
                self.timer = Some(now.saturating_add(self.rtt.t1_ms()));
                self.state = FopState::InitialisingWithoutBc;
            }
        }
    }

    /// Purges the sent queue and the wait queue (negative confirms), cancels the timer.
    fn purge(&mut self, fx: &mut Effects<T>) {
        while let Some(s) = self.sent.pop_front() {
            push(fx, FopEffect::NotDelivered { ns: s.ns, fdu: s.fdu });
        }
        if let Some(w) = self.wait_queue.take() {
            push(fx, FopEffect::Purged(w));
        }
        self.timer = None;
        self.pending_bc = None;
        self.bc_tx_ms = None;
    }

    fn alert(&mut self, reason: AlertReason, fx: &mut Effects<T>) {
        self.purge(fx);
        self.nnr = self.vs;
        push(fx, FopEffect::Alert(reason));
        self.state = FopState::Initial;
    }

    fn suspend(&mut self, fx: &mut Effects<T>) {
        self.suspend_state = self.state.num();
        self.timer = None;
        push(fx, FopEffect::Suspended(self.state));
        self.state = FopState::Initial;
    }

    /// Removes frames with N(S) < N(R) from the sent queue: they are acknowledged.
    fn remove_acknowledged(&mut self, now: u64, nr: u8, fx: &mut Effects<T>) {
        let mut removed = false;
        // One sample per CLCW: the newest frame it acknowledges that went out once only.
        let mut rtt = None;
        while self.nnr != nr {
            match self.sent.pop_front() {
                Some(s) => {
                    rtt = if s.retransmitted {
                        None
                    } else {
                        Some(now.saturating_sub(s.first_tx_ms))
                    };
                    push(fx, FopEffect::Acknowledged { ns: s.ns, fdu: s.fdu });
                    removed = true;
                }
                None => break,
            }
            self.nnr = self.nnr.wrapping_add(1);
        }
        if let Some(r) = rtt {
            self.rtt.sample(r);
        }
        self.nnr = nr;
        if removed {
            self.tx_count = 1;
            self.timer = if self.sent.is_empty() {
                None
            } else {
                Some(now.saturating_add(self.rtt.t1_ms()))
            };
        }
    }

    fn initiate_retransmission(&mut self, now: u64) {
        self.tx_count = self.tx_count.saturating_add(1);
        for s in self.sent.iter_mut() {
            s.retransmit = true;
            s.retransmitted = true;
        }
        self.timer = Some(now.saturating_add(self.rtt.t1_ms()));
    }

    /// Sends what is marked for retransmission, then new frames while the window allows.
    ///
    /// **T1 times the oldest unacknowledged frame.** 232.1-B-2's "Transmit Type-AD Frame"
    /// action restarts T1 on every transmission, and E10 (a CLCW asking for retransmission
    /// without new acknowledgement) is ignored in S2. Together they let a steady trickle of
    /// new frames (heartbeats, store requests) hold T1 off forever while the frames the
    /// CLCW asks for are never sent again: FARM-1 discards every frame after the gap, so
    /// the link stops. Here T1 restarts when something is retransmitted (the frames the
    /// CLCW asks for went out again), when the acknowledgement moves on (removing frames
    /// from the sent queue) and when a new frame finds it stopped (the sent queue was
    /// empty); a new frame behind outstanding ones leaves it running. So T1 expires at most
    /// T1 after the last transmission of the oldest outstanding frame, however many new
    /// frames follow (RFC 6298's rule 5.1 for TCP, the same reading).
    fn look_for_fdu(&mut self, now: u64, fx: &mut Effects<T>) {
        let mut retransmitted = false;
        let mut sent_new = false;
        for s in self.sent.iter_mut() {
            if s.retransmit {
                s.retransmit = false;
                push(
                    fx,
                    FopEffect::TransmitAd {
                        ns: s.ns,
                        fdu: s.fdu.clone(),
                        retransmission: true,
                    },
                );
                retransmitted = true;
            }
        }
        if self.sent.len() < usize::from(self.config.sliding_window) {
            if let Some(fdu) = self.wait_queue.take() {
                if self.sent.is_empty() {
                    self.tx_count = 1;
                }
                let ns = self.vs;
                self.vs = self.vs.wrapping_add(1);
                push(fx, FopEffect::RequestAccepted);
                push(
                    fx,
                    FopEffect::TransmitAd {
                        ns,
                        fdu: fdu.clone(),
                        retransmission: false,
                    },
                );
                // Capacity: sent.len() < window ≤ MAX_WINDOW.
                let _ = self.sent.push_back(Sent {
                    ns,
                    fdu,
                    retransmit: false,
                    first_tx_ms: now,
                    retransmitted: false,
                });
                sent_new = true;
            }
        }
        if retransmitted || (sent_new && self.timer.is_none()) {
            self.timer = Some(now.saturating_add(self.rtt.t1_ms()));
        }
    }

    fn on_clcw(&mut self, now: u64, c: Clcw, fx: &mut Effects<T>) {
        use FopEvent::*;
        use FopState::*;
        if c.vcid != self.vcid || c.cop_in_effect != CopInEffect::Cop1 {
            push(fx, FopEffect::Event(ClcwIgnored));
            return;
        }
        let s = self.state;
        let s1_3 = matches!(s, Active | RetransmitWithoutWait | RetransmitWithWait);
        let nr = c.report_value;
        if c.lockout {
            push(fx, FopEffect::Event(E14));
            if s1_3 || s == InitialisingWithoutBc {
                self.alert(AlertReason::Lockout, fx);
            }
            return;
        }
        if s == Initial {
            // Every CLCW event is ignored in S6 (lockout included, reported above).
            push(fx, FopEffect::Event(if nr == self.vs { E1 } else { E13 }));
            return;
        }
        let (r, w) = (c.retransmit, c.wait);
        if nr == self.vs {
            match (r, w) {
                (false, false) => {
                    if s == InitialisingWithoutBc || s == InitialisingWithBc {
                        push(fx, FopEffect::Event(E1));
                        if let Some(t) = self.bc_tx_ms.take() {
                            self.rtt.sample(now.saturating_sub(t));
                        }
                        self.timer = None;
                        self.pending_bc = None;
                        self.state = Active;
                        push(fx, FopEffect::Initialised);
                    } else if nr == self.nnr {
                        push(fx, FopEffect::Event(E1));
                        if s != Active {
                            self.alert(AlertReason::Synch, fx);
                        }
                    } else {
                        push(fx, FopEffect::Event(E2));
                        self.remove_acknowledged(now, nr, fx);
                        self.timer = None;
                        self.state = Active;
                        self.look_for_fdu(now, fx);
                    }
                }
                (false, true) => {
                    push(fx, FopEffect::Event(E3));
                    self.alert(AlertReason::Clcw, fx);
                }
                (true, _) => {
                    push(fx, FopEffect::Event(E4));
                    if s != InitialisingWithBc {
                        self.alert(AlertReason::Synch, fx);
                    }
                }
            }
            return;
        }
        let outstanding = self.vs.wrapping_sub(self.nnr);
        let acked = nr.wrapping_sub(self.nnr);
        if acked >= outstanding {
            push(fx, FopEffect::Event(E13));
            if s != InitialisingWithBc {
                self.alert(AlertReason::Nnr, fx);
            }
            return;
        }
        // NN(R) ≤ N(R) < V(S).
        match (r, w) {
            (false, false) => {
                if nr == self.nnr {
                    push(fx, FopEffect::Event(E5));
                    if matches!(s, RetransmitWithoutWait | RetransmitWithWait) {
                        self.alert(AlertReason::Synch, fx);
                    }
                } else {
                    push(fx, FopEffect::Event(E6));
                    if s1_3 {
                        self.remove_acknowledged(now, nr, fx);
                        self.state = Active;
                        self.look_for_fdu(now, fx);
                    }
                }
            }
            (false, true) => {
                push(fx, FopEffect::Event(E7));
                if s1_3 {
                    self.alert(AlertReason::Clcw, fx);
                }
            }
            (true, _) if self.config.tx_limit == 1 => {
                push(fx, FopEffect::Event(if nr != self.nnr { E101 } else { E102 }));
                if s1_3 {
                    self.remove_acknowledged(now, nr, fx);
                    self.alert(AlertReason::Limit, fx);
                }
            }
            (true, _) if nr != self.nnr => {
                if !w {
                    push(fx, FopEffect::Event(E8));
                    if s1_3 {
                        self.remove_acknowledged(now, nr, fx);
                        self.initiate_retransmission(now);
                        self.state = RetransmitWithoutWait;
                        self.look_for_fdu(now, fx);
                    }
                } else {
                    push(fx, FopEffect::Event(E9));
                    if s1_3 {
                        self.remove_acknowledged(now, nr, fx);
                        self.state = RetransmitWithWait;
                    }
                }
            }
            (true, _) => {
                let below_limit = self.tx_count < self.config.tx_limit;
                match (below_limit, w) {
                    (true, false) => {
                        push(fx, FopEffect::Event(E10));
                        if matches!(s, Active | RetransmitWithWait) {
                            self.initiate_retransmission(now);
                            self.state = RetransmitWithoutWait;
                            self.look_for_fdu(now, fx);
                        }
                    }
                    (true, true) => {
                        push(fx, FopEffect::Event(E11));
                        if matches!(s, Active | RetransmitWithoutWait) {
                            self.state = RetransmitWithWait;
                        }
                    }
                    (false, false) => {
                        push(fx, FopEffect::Event(E12));
                        if matches!(s, Active | RetransmitWithWait) {
                            self.state = RetransmitWithoutWait;
                        }
                    }
                    (false, true) => {
                        push(fx, FopEffect::Event(E103));
                        if matches!(s, Active | RetransmitWithoutWait) {
                            self.state = RetransmitWithWait;
                        }
                    }
                }
            }
        }
    }

    fn on_tick(&mut self, now: u64, fx: &mut Effects<T>) {
        use FopEvent::*;
        use FopState::*;
        let Some(deadline) = self.timer else {
            push(fx, FopEffect::Event(NoTimeout));
            return;
        };
        if now < deadline {
            push(fx, FopEffect::Event(NoTimeout));
            return;
        }
        self.timer = None;
        self.rtt.expired();
        let s = self.state;
        if self.tx_count < self.config.tx_limit {
            push(
                fx,
                FopEffect::Event(if self.config.timeout_type == 0 { E16 } else { E104 }),
            );
            match s {
                Active | RetransmitWithoutWait => {
                    self.initiate_retransmission(now);
                    self.look_for_fdu(now, fx);
                }
                RetransmitWithWait | Initial => {}
                InitialisingWithoutBc => {
                    if self.config.timeout_type == 0 {
                        self.alert(AlertReason::T1, fx);
                    } else {
                        self.suspend(fx);
                    }
                }
                InitialisingWithBc => {
                    self.tx_count = self.tx_count.saturating_add(1);
                    self.bc_tx_ms = None;
                    if let Some(cmd) = self.pending_bc {
                        push(fx, FopEffect::TransmitBc(cmd));
                    }
                    self.timer = Some(now.saturating_add(self.rtt.t1_ms()));
                }
            }
        } else if self.config.timeout_type == 0 {
            push(fx, FopEffect::Event(E17));
            if s != Initial {
                self.alert(AlertReason::T1, fx);
            }
        } else {
            push(fx, FopEffect::Event(E18));
            match s {
                Active | RetransmitWithoutWait | RetransmitWithWait | InitialisingWithoutBc => self.suspend(fx),
                InitialisingWithBc => self.alert(AlertReason::T1, fx),
                Initial => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use FopEffect as F;
    use FopEvent::*;
    use FopState::*;

    const T1: u64 = 1000;

    fn cfg() -> FopConfig {
        FopConfig {
            sliding_window: 4,
            t1_ms: T1,
            t1_min_ms: T1,
            tx_limit: 3,
            timeout_type: 0,
        }
    }

    fn clcw(nr: u8, r: bool, w: bool, lockout: bool) -> FopInput<u32> {
        FopInput::Clcw(Clcw {
            status: 0,
            cop_in_effect: CopInEffect::Cop1,
            vcid: 0,
            no_rf_available: false,
            no_bit_lock: false,
            lockout,
            wait: w,
            retransmit: r,
            farm_b_counter: 0,
            report_value: nr,
        })
    }

    fn ok(nr: u8) -> FopInput<u32> {
        clcw(nr, false, false, false)
    }

    fn ev(fx: &Effects<u32>) -> FopEvent {
        match fx.first() {
            Some(F::Event(e)) => *e,
            other => panic!("no event first: {other:?}"),
        }
    }

    fn sent(fx: &Effects<u32>) -> Vec<(u8, u32, bool)> {
        fx.iter()
            .filter_map(|e| match e {
                F::TransmitAd {
                    ns,
                    fdu,
                    retransmission,
                } => Some((*ns, *fdu, *retransmission)),
                _ => None,
            })
            .collect()
    }

    fn acked(fx: &Effects<u32>) -> Vec<u8> {
        fx.iter()
            .filter_map(|e| {
                if let F::Acknowledged { ns, .. } = e {
                    Some(*ns)
                } else {
                    None
                }
            })
            .collect()
    }

    /// An active FOP (E23) at V(S) = `vs` with `n` frames sent (FDUs 100, 101, ...).
    fn active(vs: u8, n: u32) -> Fop<u32> {
        let mut f = Fop::new(0, cfg());
        f.on_event(0, FopInput::SetVs(vs));
        f.on_event(0, FopInput::InitiateAdWithoutClcw);
        for i in 0..n {
            f.on_event(0, FopInput::TransmitAd(100 + i));
        }
        f
    }

    // verifies: LINK-FOP-02
    #[test]
    fn fop_e23_initiate_ad_without_clcw_check_goes_active() {
        let mut f: Fop<u32> = Fop::new(0, cfg());
        assert_eq!(f.state(), Initial);
        let fx = f.on_event(0, FopInput::InitiateAdWithoutClcw);
        assert_eq!(ev(&fx), E23);
        assert!(fx.contains(&F::Initialised));
        assert_eq!(f.state(), Active);
        // Not allowed outside S6.
        let fx = f.on_event(0, FopInput::InitiateAdWithoutClcw);
        assert!(fx.contains(&F::DirectiveRejected));
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e19_transmit_request_sends_within_window_e20_rejects_when_queue_busy() {
        let mut f = active(0, 0);
        for i in 0..4 {
            let fx = f.on_event(0, FopInput::TransmitAd(i));
            assert_eq!(ev(&fx), E19);
            assert_eq!(sent(&fx), vec![(i as u8, i, false)]);
        }
        assert_eq!(f.vs(), 4);
        assert_eq!(f.next_deadline(), Some(T1));
        // Window K = 4 full: the fifth waits in the wait queue, the sixth is rejected.
        let fx = f.on_event(0, FopInput::TransmitAd(4));
        assert!(sent(&fx).is_empty());
        assert!(!f.ready());
        let fx = f.on_event(0, FopInput::TransmitAd(5));
        assert_eq!(ev(&fx), E20);
        assert!(fx.contains(&F::RequestRejected(5)));
        // E2-type ack of two frames frees the window: the waiting FDU goes out as N(S) 4.
        let fx = f.on_event(10, ok(2));
        assert_eq!(ev(&fx), E6);
        assert_eq!(acked(&fx), vec![0, 1]);
        assert_eq!(sent(&fx), vec![(4, 4, false)]);
        assert!(f.ready());
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e1_clcw_all_acknowledged_no_change_in_s1() {
        let mut f = active(9, 0);
        let fx = f.on_event(0, ok(9));
        assert_eq!(ev(&fx), E1);
        assert_eq!(f.state(), Active);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e2_clcw_acknowledges_everything_only_then_sent() {
        let mut f = active(254, 3); // N(S) 254, 255, 0: across the wrap
        assert_eq!(f.outstanding(), 3);
        // N(R) = 255 acknowledges only 254 (N(R) is the next expected).
        let fx = f.on_event(5, ok(255));
        assert_eq!(ev(&fx), E6);
        assert_eq!(acked(&fx), vec![254]);
        let fx = f.on_event(6, ok(1));
        assert_eq!(ev(&fx), E2);
        assert_eq!(acked(&fx), vec![255, 0]);
        assert_eq!(f.outstanding(), 0);
        assert_eq!(f.next_deadline(), None);
        assert_eq!(f.nnr(), 1);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e3_wait_without_retransmit_alerts() {
        let mut f = active(0, 1);
        let fx = f.on_event(0, clcw(1, false, true, false));
        assert_eq!(ev(&fx), E3);
        assert!(fx.contains(&F::Alert(AlertReason::Clcw)));
        assert_eq!(f.state(), Initial);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e4_retransmit_with_all_acknowledged_alerts_synch() {
        let mut f = active(0, 1);
        let fx = f.on_event(0, clcw(1, true, false, false));
        assert_eq!(ev(&fx), E4);
        assert!(fx.contains(&F::Alert(AlertReason::Synch)));
        assert!(!fx.iter().any(|e| matches!(e, F::Acknowledged { .. })));
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e5_no_new_acknowledgement_no_change_in_s1() {
        let mut f = active(0, 2);
        let fx = f.on_event(0, ok(0));
        assert_eq!(ev(&fx), E5);
        assert_eq!(f.state(), Active);
        assert_eq!(f.outstanding(), 2);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e7_partial_ack_with_wait_only_alerts() {
        let mut f = active(0, 2);
        let fx = f.on_event(0, clcw(1, false, true, false));
        assert_eq!(ev(&fx), E7);
        assert!(fx.contains(&F::Alert(AlertReason::Clcw)));
        // Purged frames are reported as not delivered, never as sent.
        assert!(fx.iter().any(|e| matches!(e, F::NotDelivered { ns: 0, .. })));
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e8_retransmit_flag_with_partial_ack_retransmits_rest() {
        let mut f = active(0, 3);
        let fx = f.on_event(100, clcw(1, true, false, false));
        assert_eq!(ev(&fx), E8);
        assert_eq!(acked(&fx), vec![0]);
        assert_eq!(sent(&fx), vec![(1, 101, true), (2, 102, true)]);
        assert_eq!(f.state(), RetransmitWithoutWait);
        assert_eq!(f.tx_count(), 2);
        assert_eq!(f.next_deadline(), Some(100 + T1));
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e9_retransmit_and_wait_with_partial_ack_enters_s3() {
        let mut f = active(0, 3);
        let fx = f.on_event(0, clcw(1, true, true, false));
        assert_eq!(ev(&fx), E9);
        assert!(sent(&fx).is_empty());
        assert_eq!(f.state(), RetransmitWithWait);
        // The FARM's buffer frees (wait clears, retransmit still set): E10 retransmits.
        let fx = f.on_event(0, clcw(1, true, false, false));
        assert_eq!(ev(&fx), E10);
        assert_eq!(sent(&fx), vec![(1, 101, true), (2, 102, true)]);
        assert_eq!(f.state(), RetransmitWithoutWait);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e10_gap_reported_retransmits_in_s1_and_is_ignored_in_s2() {
        let mut f = active(0, 2);
        let fx = f.on_event(0, clcw(0, true, false, false));
        assert_eq!(ev(&fx), E10);
        assert_eq!(sent(&fx).len(), 2);
        assert_eq!(f.state(), RetransmitWithoutWait);
        // The same CLCW again while retransmitting: no second burst.
        let fx = f.on_event(1, clcw(0, true, false, false));
        assert_eq!(ev(&fx), E10);
        assert!(sent(&fx).is_empty());
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e11_retransmit_and_wait_no_ack_enters_s3() {
        let mut f = active(0, 2);
        let fx = f.on_event(0, clcw(0, true, true, false));
        assert_eq!(ev(&fx), E11);
        assert_eq!(f.state(), RetransmitWithWait);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e12_and_e103_at_transmission_limit() {
        let mut f = active(0, 1);
        f.on_event(0, clcw(0, true, false, false)); // E10, count 2
        f.on_event(T1, FopInput::Tick); // E16, count 3 = limit
        assert_eq!(f.tx_count(), 3);
        let fx = f.on_event(T1 + 1, clcw(0, true, true, false));
        assert_eq!(ev(&fx), E103);
        assert_eq!(f.state(), RetransmitWithWait);
        let fx = f.on_event(T1 + 2, clcw(0, true, false, false));
        assert_eq!(ev(&fx), E12);
        assert!(sent(&fx).is_empty());
        assert_eq!(f.state(), RetransmitWithoutWait);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e13_nr_outside_sent_range_alerts() {
        let mut f = active(10, 2); // 10, 11 outstanding, V(S) 12
        let fx = f.on_event(0, ok(13));
        assert_eq!(ev(&fx), E13);
        assert!(fx.contains(&F::Alert(AlertReason::Nnr)));
        let mut g = active(10, 2);
        assert_eq!(ev(&g.on_event(0, ok(9))), E13);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e14_lockout_alerts_and_purges() {
        let mut f = active(0, 2);
        let fx = f.on_event(0, clcw(0, false, false, true));
        assert_eq!(ev(&fx), E14);
        assert!(fx.contains(&F::Alert(AlertReason::Lockout)));
        assert_eq!(f.outstanding(), 0);
        assert_eq!(f.state(), Initial);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e16_timer_expiry_retransmits_and_e17_alerts_at_limit() {
        let mut f = active(0, 2);
        assert_eq!(ev(&f.on_event(T1 - 1, FopInput::Tick)), NoTimeout);
        let fx = f.on_event(T1, FopInput::Tick);
        assert_eq!(ev(&fx), E16);
        assert_eq!(sent(&fx), vec![(0, 100, true), (1, 101, true)]);
        assert_eq!(f.tx_count(), 2);
        let fx = f.on_event(2 * T1, FopInput::Tick);
        assert_eq!(ev(&fx), E16);
        assert_eq!(f.tx_count(), 3);
        let fx = f.on_event(3 * T1, FopInput::Tick);
        assert_eq!(ev(&fx), E17);
        assert!(fx.contains(&F::Alert(AlertReason::T1)));
        assert_eq!(fx.iter().filter(|e| matches!(e, F::NotDelivered { .. })).count(), 2);
        assert_eq!(f.state(), Initial);
    }

    // verifies: LINK-FOP-03
    #[test]
    fn fop_resends_what_the_clcw_asks_for_however_many_new_frames_follow() {
        // The failing sequence seen through a lossy relay: the CLCW's N(R) stuck at 52 with
        // the retransmit flag set while new frames 54, 55, ... keep going out.
        let mut f = Fop::new(
            0,
            FopConfig {
                sliding_window: 10,
                ..cfg()
            },
        );
        f.on_event(0, FopInput::SetVs(50));
        f.on_event(0, FopInput::InitiateAdWithoutClcw);
        for fdu in 50..54 {
            f.on_event(0, FopInput::TransmitAd(fdu));
        }
        // 50 and 51 arrive, 52 is lost: E8 acknowledges two and resends 52 and 53 (both
        // lost again).
        let fx = f.on_event(100, clcw(52, true, false, false));
        assert_eq!(ev(&fx), E8);
        assert_eq!(sent(&fx), vec![(52, 52, true), (53, 53, true)]);
        let resent_at = 100;
        // A CLCW every 100 ms, all alike (E10, ignored in S2), and a new frame every 250 ms
        // (a heartbeat's, a store request's) until the window is full: FARM-1 discards
        // them all (they follow the gap).
        let mut next_fdu = 54;
        let mut resends = Vec::new();
        for t in (200..=3000u64).step_by(50) {
            if t % 250 == 0 && f.ready() {
                let fx = f.on_event(t, FopInput::TransmitAd(next_fdu));
                assert_eq!(sent(&fx), vec![(next_fdu as u8, next_fdu, false)]);
                next_fdu += 1;
            }
            if t % 100 == 0 {
                let fx = f.on_event(t, clcw(52, true, false, false));
                // E10 (E12 at the transmission limit) in S2: ignored.
                assert!(sent(&fx).is_empty(), "{t}: {:?}", ev(&fx));
            }
            let fx = f.on_event(t, FopInput::Tick);
            resends.extend(sent(&fx).into_iter().map(|(ns, _, r)| (t, ns, r)));
        }
        assert!(next_fdu >= 58, "new frames 54-57 went out: {next_fdu}");
        // T1 after their last transmission, 52 and 53 go out again (with everything
        // after them), whatever the new frames did meanwhile.
        let first: Vec<u8> = resends
            .iter()
            .filter(|&&(t, _, _)| t == resent_at + T1)
            .map(|&(_, ns, _)| ns)
            .collect();
        assert_eq!(first[..2], [52, 53], "{resends:?}");
        assert!(resends.iter().all(|&(_, _, r)| r), "{resends:?}");
        assert!(resends.iter().all(|&(t, _, _)| t >= resent_at + T1), "{resends:?}");
        // Lost once more, T1 later the transmission limit (3) is reached: the alert, after
        // which the ground's link re-initialises from N(R) (never a silent stop).
        assert_eq!(resends.iter().filter(|&&(_, ns, _)| ns == 52).count(), 1);
        assert_eq!(f.state(), Initial);
    }

    // verifies: LINK-FOP-03
    #[test]
    fn fop_new_frame_starts_t1_only_when_it_is_stopped() {
        let mut f = active(0, 1);
        assert_eq!(f.next_deadline(), Some(T1));
        // A second frame 400 ms later leaves T1 where the first set it.
        f.on_event(400, FopInput::TransmitAd(1));
        assert_eq!(f.next_deadline(), Some(T1));
        // Acknowledgement of the first restarts it for the second.
        f.on_event(500, ok(1));
        assert_eq!(f.next_deadline(), Some(500 + T1));
        // All acknowledged: stopped; the next new frame starts it.
        f.on_event(600, ok(2));
        assert_eq!(f.next_deadline(), None);
        f.on_event(700, FopInput::TransmitAd(2));
        assert_eq!(f.next_deadline(), Some(700 + T1));
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e18_timeout_type_1_suspends_and_e31_resumes() {
        let mut f = active(0, 1);
        f.on_event(0, FopInput::SetTimeoutType(1));
        f.on_event(0, FopInput::SetTxLimit(1));
        let fx = f.on_event(T1, FopInput::Tick);
        assert_eq!(ev(&fx), E18);
        assert!(fx.contains(&F::Suspended(Active)));
        assert_eq!(f.state(), Initial);
        assert_eq!(f.outstanding(), 1); // suspended, not purged
        let fx = f.on_event(T1 + 5, FopInput::ResumeAd);
        assert_eq!(ev(&fx), E31);
        assert_eq!(f.state(), Active);
        assert_eq!(f.next_deadline(), Some(2 * T1 + 5));
        let fx = f.on_event(0, FopInput::ResumeAd);
        assert_eq!(ev(&fx), E30);
        assert!(fx.contains(&F::DirectiveRejected));
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e101_transmission_limit_1_alerts_on_retransmit_flag() {
        let mut f = active(0, 2);
        f.on_event(0, FopInput::SetTxLimit(1));
        let fx = f.on_event(0, clcw(1, true, false, false));
        assert_eq!(ev(&fx), E101);
        assert_eq!(acked(&fx), vec![0]);
        assert!(fx.contains(&F::Alert(AlertReason::Limit)));
    }

    // verifies: LINK-FOP-02
    #[test]
    fn fop_e24_initiate_with_clcw_check_completes_on_matching_clcw() {
        let mut f: Fop<u32> = Fop::new(0, cfg());
        f.on_event(0, FopInput::SetVs(42));
        let fx = f.on_event(0, FopInput::InitiateAdWithClcw);
        assert_eq!(ev(&fx), E24);
        assert_eq!(f.state(), InitialisingWithoutBc);
        let fx = f.on_event(10, ok(42));
        assert_eq!(ev(&fx), E1);
        assert!(fx.contains(&F::Initialised));
        assert_eq!(f.state(), Active);
        // Without a CLCW, T1 ends the attempt (E16 in S4: alert).
        let mut g: Fop<u32> = Fop::new(0, cfg());
        g.on_event(0, FopInput::InitiateAdWithClcw);
        let fx = g.on_event(T1, FopInput::Tick);
        assert!(fx.contains(&F::Alert(AlertReason::T1)));
    }

    // verifies: LINK-FOP-02
    #[test]
    fn fop_e25_initiate_with_unlock_sends_bc_and_retransmits_it_on_t1() {
        let mut f: Fop<u32> = Fop::new(0, cfg());
        let fx = f.on_event(0, FopInput::InitiateAdWithUnlock);
        assert_eq!(ev(&fx), E25);
        assert!(fx.contains(&F::TransmitBc(ControlCommand::Unlock)));
        assert_eq!(f.state(), InitialisingWithBc);
        // A lockout CLCW (the FARM has not seen the Unlock yet) is ignored in S5.
        let fx = f.on_event(1, clcw(0, false, false, true));
        assert_eq!(f.state(), InitialisingWithBc);
        assert!(!fx.iter().any(|e| matches!(e, F::Alert(_))));
        let fx = f.on_event(T1, FopInput::Tick);
        assert!(fx.contains(&F::TransmitBc(ControlCommand::Unlock)));
        let fx = f.on_event(T1 + 1, ok(0));
        assert!(fx.contains(&F::Initialised));
        assert_eq!(f.state(), Active);
    }

    // verifies: LINK-FOP-02
    #[test]
    fn fop_e27_initiate_with_set_vr_sends_set_vr_and_uses_it_as_vs() {
        let mut f: Fop<u32> = Fop::new(0, cfg());
        let fx = f.on_event(0, FopInput::InitiateAdWithSetVr(200));
        assert_eq!(ev(&fx), E27);
        assert!(fx.contains(&F::TransmitBc(ControlCommand::SetVr(200))));
        assert_eq!((f.vs(), f.nnr()), (200, 200));
        // The FARM still reports the old V(R): E13 ignored in S5.
        f.on_event(1, ok(17));
        assert_eq!(f.state(), InitialisingWithBc);
        f.on_event(2, ok(200));
        assert_eq!(f.state(), Active);
        // Alert at the transmission limit in S5 (timeout type 0: E17).
        let mut g: Fop<u32> = Fop::new(0, cfg());
        g.on_event(0, FopInput::InitiateAdWithSetVr(1));
        g.on_event(T1, FopInput::Tick);
        g.on_event(2 * T1, FopInput::Tick);
        let fx = g.on_event(3 * T1, FopInput::Tick);
        assert_eq!(ev(&fx), E17);
        assert_eq!(g.state(), Initial);
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e29_terminate_purges_as_not_delivered() {
        let mut f = active(0, 2);
        let fx = f.on_event(0, FopInput::TerminateAd);
        assert_eq!(ev(&fx), E29);
        assert!(fx.contains(&F::Alert(AlertReason::Terminated)));
        assert_eq!(fx.iter().filter(|e| matches!(e, F::NotDelivered { .. })).count(), 2);
        assert!(acked(&fx).is_empty());
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e21_bd_request_passes_through_in_any_state() {
        let mut f: Fop<u32> = Fop::new(0, cfg());
        let fx = f.on_event(0, FopInput::TransmitBd(7));
        assert_eq!(ev(&fx), E21);
        assert!(fx.contains(&F::TransmitBd(7)));
        // AD requests are refused in S6.
        assert!(f.on_event(0, FopInput::TransmitAd(8)).contains(&F::RequestRejected(8)));
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_e36_to_e39_set_parameters() {
        let mut f: Fop<u32> = Fop::new(0, cfg());
        assert_eq!(ev(&f.on_event(0, FopInput::SetSlidingWindow(99))), E36);
        assert_eq!(f.config().sliding_window, MAX_WINDOW as u8);
        assert_eq!(ev(&f.on_event(0, FopInput::SetT1(5))), E37);
        assert_eq!(ev(&f.on_event(0, FopInput::SetTxLimit(0))), E38);
        assert_eq!(f.config().tx_limit, 1);
        assert_eq!(ev(&f.on_event(0, FopInput::SetTimeoutType(1))), E39);
        assert_eq!(
            f.config(),
            FopConfig {
                sliding_window: 16,
                t1_ms: 5,
                t1_min_ms: 5,
                tx_limit: 1,
                timeout_type: 1
            }
        );
        // E35 Set V(S) only in S6.
        f.on_event(0, FopInput::InitiateAdWithoutClcw);
        assert!(f.on_event(0, FopInput::SetVs(3)).contains(&F::DirectiveRejected));
    }

    // verifies: LINK-FOP-01
    #[test]
    fn fop_ignores_clcw_of_other_vc() {
        let mut f = active(0, 1);
        let mut c = Clcw::parse(0).unwrap();
        c.vcid = 3;
        c.cop_in_effect = CopInEffect::Cop1;
        c.report_value = 1;
        assert_eq!(ev(&f.on_event(0, FopInput::Clcw(c))), ClcwIgnored);
        assert_eq!(f.outstanding(), 1);
    }

    fn adaptive(min: u64, max: u64) -> FopConfig {
        FopConfig {
            t1_ms: max,
            t1_min_ms: min,
            ..cfg()
        }
    }

    // verifies: LINK-FOP-T1-01
    #[test]
    fn t1_estimator_uses_the_upper_bound_before_the_first_sample() {
        let e = T1Estimator::new(300, 2000);
        assert!(e.adaptive());
        assert_eq!(e.t1_ms(), 2000);
        assert_eq!(e.srtt_ms(), None);
    }

    // verifies: LINK-FOP-T1-01
    #[test]
    fn t1_estimator_is_srtt_plus_four_rttvar_as_rfc_6298() {
        let mut e = T1Estimator::new(10, 5000);
        // First sample R: SRTT = R, RTTVAR = R/2, T1 = R + 4·R/2 = 3R.
        e.sample(400);
        assert_eq!(e.srtt_ms(), Some(400));
        assert_eq!(e.t1_ms(), 1200);
        // Same again: RTTVAR = 3/4 · 200 + 1/4 · 0 = 150; SRTT stays 400; T1 = 1000.
        e.sample(400);
        assert_eq!(e.t1_ms(), 1000);
        // 800: RTTVAR = 3/4 · 150 + 1/4 · 400 = 212.5; SRTT = 7/8 · 400 + 1/8 · 800 = 450.
        e.sample(800);
        assert_eq!(e.srtt_ms(), Some(450));
        assert_eq!(e.t1_ms(), 450 + 850);
        assert_eq!(e.samples(), 3);
    }

    // verifies: LINK-FOP-T1-01
    #[test]
    fn t1_estimator_is_clamped_to_the_mib_bounds() {
        use mib::link::cop1::{FOP_T1_MIN_MS, FOP_T1_MS};
        let mut e = T1Estimator::new(FOP_T1_MIN_MS, FOP_T1_MS);
        for _ in 0..20 {
            e.sample(3);
        }
        assert_eq!(e.t1_ms(), FOP_T1_MIN_MS, "a loopback round trip of 3 ms");
        let mut e = T1Estimator::new(FOP_T1_MIN_MS, FOP_T1_MS);
        e.sample(10_000);
        assert_eq!(e.t1_ms(), FOP_T1_MS, "a round trip longer than the upper bound");
        // Huge samples neither overflow nor escape the bound.
        e.sample(u64::MAX);
        assert_eq!(e.t1_ms(), FOP_T1_MS);
    }

    // verifies: LINK-FOP-T1-01
    #[test]
    fn t1_estimator_doubles_on_expiry_up_to_the_upper_bound_until_the_next_sample() {
        let mut e = T1Estimator::new(300, 2000);
        for _ in 0..20 {
            e.sample(5);
        }
        assert_eq!(e.t1_ms(), 300);
        e.expired();
        assert_eq!(e.t1_ms(), 600);
        e.expired();
        assert_eq!(e.t1_ms(), 1200);
        e.expired();
        assert_eq!(e.t1_ms(), 2000);
        for _ in 0..40 {
            e.expired();
        }
        assert_eq!(e.t1_ms(), 2000);
        e.sample(5);
        assert_eq!(e.t1_ms(), 300, "a valid sample ends the backoff");
    }

    // verifies: LINK-FOP-T1-01
    #[test]
    fn t1_estimator_is_fixed_when_the_lower_bound_is_not_below_the_upper() {
        let mut e = T1Estimator::new(T1, T1);
        assert!(!e.adaptive());
        e.sample(3);
        e.expired();
        assert_eq!(e.t1_ms(), T1);
    }

    // verifies: LINK-FOP-T1-01
    #[test]
    fn fop_adaptive_t1_samples_a_frame_sent_once_and_times_the_next_frame_by_it() {
        let mut f = Fop::new(0, adaptive(100, 1000));
        f.on_event(0, FopInput::InitiateAdWithoutClcw);
        f.on_event(0, FopInput::TransmitAd(1));
        assert_eq!(f.next_deadline(), Some(1000), "no sample yet: the upper bound");
        // Acknowledged 20 ms later: SRTT 20, RTTVAR 10, T1 = 60, clamped to 100.
        assert_eq!(acked(&f.on_event(20, ok(1))), vec![0]);
        assert_eq!(f.t1_estimator().srtt_ms(), Some(20));
        assert_eq!(f.t1_ms(), 100);
        f.on_event(50, FopInput::TransmitAd(2));
        assert_eq!(f.next_deadline(), Some(150));
        assert_eq!(ev(&f.on_event(149, FopInput::Tick)), NoTimeout);
        let fx = f.on_event(150, FopInput::Tick);
        assert_eq!(ev(&fx), E16);
        assert_eq!(sent(&fx), vec![(1, 2, true)]);
        // Backed off: the retransmission waits 200 ms.
        assert_eq!(f.next_deadline(), Some(350));
    }

    // verifies: LINK-FOP-T1-01
    #[test]
    fn fop_karn_rule_takes_no_sample_from_a_retransmitted_frame() {
        let mut f = Fop::new(0, adaptive(100, 1000));
        f.on_event(0, FopInput::InitiateAdWithoutClcw);
        f.on_event(0, FopInput::TransmitAd(1));
        // T1 expires, the frame goes again and is acknowledged 5 ms after the
        // retransmission: which transmission the CLCW answers is unknown, no sample.
        assert_eq!(ev(&f.on_event(1000, FopInput::Tick)), E16);
        assert_eq!(acked(&f.on_event(1005, ok(1))), vec![0]);
        assert_eq!(f.t1_estimator().samples(), 0);
        assert_eq!(f.t1_ms(), 1000);
        // A gap reported by the FARM (retransmit flag) marks the window retransmitted too.
        f.on_event(2000, FopInput::TransmitAd(2));
        f.on_event(2000, FopInput::TransmitAd(3));
        let fx = f.on_event(2010, clcw(1, true, false, false));
        assert_eq!(ev(&fx), E10);
        assert_eq!(acked(&f.on_event(2015, ok(3))), vec![1, 2]);
        assert_eq!(f.t1_estimator().samples(), 0);
        // A frame sent once gives its sample.
        f.on_event(3000, FopInput::TransmitAd(4));
        f.on_event(3030, ok(4));
        assert_eq!(f.t1_estimator().srtt_ms(), Some(30));
    }

    // verifies: LINK-FOP-T1-01, LINK-FOP-02
    #[test]
    fn fop_adaptive_t1_samples_the_set_vr_round_trip_unless_the_bc_frame_was_repeated() {
        let mut f = Fop::<u32>::new(0, adaptive(100, 1000));
        f.on_event(0, FopInput::InitiateAdWithSetVr(5));
        assert_eq!(ev(&f.on_event(40, ok(5))), E1);
        assert_eq!(f.state(), Active);
        assert_eq!(f.t1_estimator().srtt_ms(), Some(40));
        let mut f = Fop::<u32>::new(0, adaptive(100, 1000));
        f.on_event(0, FopInput::InitiateAdWithSetVr(5));
        let fx = f.on_event(1000, FopInput::Tick);
        assert!(fx.contains(&F::TransmitBc(ControlCommand::SetVr(5))));
        f.on_event(1010, ok(5));
        assert_eq!(f.state(), Active);
        assert_eq!(f.t1_estimator().samples(), 0);
    }

    // verifies: LINK-FOP-T1-01, LINK-FOP-01
    #[test]
    fn fop_e37_set_t1_keeps_a_fixed_t1_fixed_and_bounds_an_adaptive_one() {
        let mut f = active(0, 0);
        f.on_event(0, FopInput::SetT1(5000));
        assert!(!f.t1_estimator().adaptive());
        assert_eq!(f.t1_ms(), 5000);
        let mut f = Fop::<u32>::new(0, adaptive(100, 1000));
        f.on_event(0, FopInput::SetT1(500));
        assert!(f.t1_estimator().adaptive());
        assert_eq!(f.t1_ms(), 500);
    }

    // verifies: LINK-FOP-T1-01
    #[test]
    fn fop_mission_config_has_an_adaptive_t1_within_the_mib_bounds() {
        use mib::link::cop1::{FOP_T1_MIN_MS, FOP_T1_MS};
        let c = FopConfig::mission();
        assert_eq!((c.t1_min_ms, c.t1_ms), (FOP_T1_MIN_MS, FOP_T1_MS));
        assert!(Fop::<u32>::new(0, c).t1_estimator().adaptive());
    }
}
