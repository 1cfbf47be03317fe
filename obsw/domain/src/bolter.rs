//! The bolter state machine for one fastener pair (paper §5, Figure 8).
//!
//! Both sides' bolters run the same pair in step: board A drives its own bolter and
//! board B's through the link; every current-regulated transition waits for both
//! `I_boA` and `I_boB` (B's from its heartbeat), as the paper describes.
//!
//! Bolting, per attempt: `Select` (set A0/A1, let the multiplexer settle) → `Descend`
//! (translate toward the fastener and push until I_bo ≥ `BOLT_PUSH_THRESHOLD_MA`) →
//! `Retract` (timed) → `Push` (push again until the threshold) → `Rotate` (push and rotate
//! until I_bo ≥ `BOLT_LOCK_THRESHOLD_MA`: locked) → `Reverse` (timed) → `Return`
//! (timed, home) → success. A current-regulated state lasting longer than
//! `BOLT_STEP_TIMEOUT_MS` fails the attempt: the bolter returns home and the next
//! attempt starts, up to `BOLT_MAX_ATTEMPTS`.
//!
//! Unbolting is the reverse: `Select` → `Descend` (push until the threshold) → `Unlock`
//! (push and rotate backwards; after `BOLT_UNLOCK_MIN_MS`, released when I_bo falls
//! below the push threshold) → `Return` → success.

use crate::consts::{BOLT_RETRACT_MS, BOLT_RETURN_MS, BOLT_REVERSE_MS, BOLT_SELECT_MS, BOLT_UNLOCK_MIN_MS};
use crate::tunables::Tunables;
use crate::types::{mux_bits, BolterDrive};
use mib::tunables::tid;

/// Bolting or unbolting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoltOp {
    Bolt,
    Unbolt,
}

/// States of the machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BolterPhase {
    Idle = 0,
    Select = 1,
    Descend = 2,
    Retract = 3,
    Push = 4,
    Rotate = 5,
    Reverse = 6,
    Return = 7,
    Unlock = 8,
}

impl BolterPhase {
    /// Drive output in this phase.
    pub const fn drive(self, op: BoltOp) -> BolterDrive {
        match self {
            BolterPhase::Idle | BolterPhase::Select => BolterDrive::Off,
            BolterPhase::Descend | BolterPhase::Push => BolterDrive::Descend,
            BolterPhase::Retract | BolterPhase::Return => BolterDrive::Retract,
            BolterPhase::Rotate => BolterDrive::RotateLock,
            BolterPhase::Reverse => BolterDrive::Reverse,
            BolterPhase::Unlock => match op {
                BoltOp::Unbolt => BolterDrive::RotateUnlock,
                BoltOp::Bolt => BolterDrive::Reverse,
            },
        }
    }
    /// Transition of this phase is decided by current (asterisk in Figure 8).
    pub const fn current_regulated(self) -> bool {
        matches!(
            self,
            BolterPhase::Descend | BolterPhase::Push | BolterPhase::Rotate | BolterPhase::Unlock
        )
    }
}

/// Thresholds and limits, from the tunables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BolterConfig {
    pub push_ma: u16,
    pub lock_ma: u16,
    pub max_attempts: u8,
    pub step_timeout_ms: u32,
}

impl BolterConfig {
    pub fn from_tunables(t: &Tunables) -> Self {
        BolterConfig {
            push_ma: t.get(tid::BOLT_PUSH_THRESHOLD_MA).clamp(0, u16::MAX as i32) as u16,
            lock_ma: t.get(tid::BOLT_LOCK_THRESHOLD_MA).clamp(0, u16::MAX as i32) as u16,
            max_attempts: t.get(tid::BOLT_MAX_ATTEMPTS).clamp(1, 255) as u8,
            step_timeout_ms: t.get_u32(tid::BOLT_STEP_TIMEOUT_MS),
        }
    }
}

impl Default for BolterConfig {
    fn default() -> Self {
        Self::from_tunables(&Tunables::default())
    }
}

/// What happened in a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BolterEvent {
    /// Attempt `attempt` failed (a current-regulated state timed out); retrying.
    AttemptFailed { attempt: u8, phase: BolterPhase },
    /// The pair is locked (bolting) or released (unbolting).
    Succeeded { attempts: u8 },
    /// Every allowed attempt failed.
    Failed { attempts: u8 },
}

/// The state machine for one pair.
#[derive(Clone, Debug)]
pub struct Bolter {
    op: BoltOp,
    pair: u8,
    attempt: u8,
    phase: BolterPhase,
    since: u64,
    cfg: BolterConfig,
    /// The current attempt failed; `Return` leads to a retry or the failure.
    attempt_failed: bool,
}

impl Default for Bolter {
    fn default() -> Self {
        Self::new()
    }
}

impl Bolter {
    pub const fn new() -> Self {
        Bolter {
            op: BoltOp::Bolt,
            pair: 0,
            attempt: 0,
            phase: BolterPhase::Idle,
            since: 0,
            cfg: BolterConfig {
                push_ma: 0,
                lock_ma: 0,
                max_attempts: 1,
                step_timeout_ms: 0,
            },
            attempt_failed: false,
        }
    }
    /// Starts (un)bolting `pair` (1..=4). Returns false for an invalid pair.
    pub fn start(&mut self, op: BoltOp, pair: u8, now_ms: u64, cfg: BolterConfig) -> bool {
        if !(1..=mib::robot::bolter::PAIRS_PER_FACE).contains(&pair) {
            return false;
        }
        self.op = op;
        self.pair = pair;
        self.cfg = cfg;
        self.attempt = 1;
        self.attempt_failed = false;
        self.enter(BolterPhase::Select, now_ms);
        true
    }
    /// Stops at once (drive off).
    pub fn abort(&mut self) {
        self.phase = BolterPhase::Idle;
    }
    pub fn busy(&self) -> bool {
        self.phase != BolterPhase::Idle
    }
    pub fn phase(&self) -> BolterPhase {
        self.phase
    }
    pub fn op(&self) -> BoltOp {
        self.op
    }
    pub fn pair(&self) -> u8 {
        self.pair
    }
    pub fn attempt(&self) -> u8 {
        self.attempt
    }
    pub fn drive(&self) -> BolterDrive {
        self.phase.drive(self.op)
    }
    /// Multiplexer bits for the selected pair (0 when idle).
    pub fn mux(&self) -> u8 {
        if self.busy() {
            mux_bits(self.pair)
        } else {
            0
        }
    }

    fn enter(&mut self, p: BolterPhase, now: u64) {
        self.phase = p;
        self.since = now;
    }

    /// One control period. `i_a`: A's filtered bolter current (mA); `i_b`: B's from the
    /// last heartbeat (`None` when B is silent: its condition is never met).
    pub fn tick(&mut self, now_ms: u64, i_a: u16, i_b: Option<u16>) -> Option<BolterEvent> {
        let el = now_ms.saturating_sub(self.since);
        let both_at_least = |t: u16| i_a >= t && i_b.is_some_and(|b| b >= t);
        let both_below = |t: u16| i_a < t && i_b.is_some_and(|b| b < t);
        let timed_out = el > self.cfg.step_timeout_ms as u64;
        use BolterPhase::*;
        match self.phase {
            Idle => None,
            Select => {
                if el >= BOLT_SELECT_MS as u64 {
                    self.enter(Descend, now_ms);
                }
                None
            }
            Descend | Push | Rotate | Unlock if timed_out => {
                let phase = self.phase;
                self.attempt_failed = true;
                self.enter(Return, now_ms);
                Some(BolterEvent::AttemptFailed {
                    attempt: self.attempt,
                    phase,
                })
            }
            Descend => {
                if both_at_least(self.cfg.push_ma) {
                    match self.op {
                        BoltOp::Bolt => self.enter(Retract, now_ms),
                        BoltOp::Unbolt => self.enter(Unlock, now_ms),
                    }
                }
                None
            }
            Retract => {
                if el >= BOLT_RETRACT_MS as u64 {
                    self.enter(Push, now_ms);
                }
                None
            }
            Push => {
                if both_at_least(self.cfg.push_ma) {
                    self.enter(Rotate, now_ms);
                }
                None
            }
            Rotate => {
                if both_at_least(self.cfg.lock_ma) {
                    self.enter(Reverse, now_ms);
                }
                None
            }
            Reverse => {
                if el >= BOLT_REVERSE_MS as u64 {
                    self.enter(Return, now_ms);
                }
                None
            }
            Unlock => {
                if el >= BOLT_UNLOCK_MIN_MS as u64 && both_below(self.cfg.push_ma) {
                    self.enter(Return, now_ms);
                }
                None
            }
            Return => {
                if el < BOLT_RETURN_MS as u64 {
                    return None;
                }
                if !self.attempt_failed {
                    self.phase = Idle;
                    return Some(BolterEvent::Succeeded { attempts: self.attempt });
                }
                if self.attempt >= self.cfg.max_attempts {
                    self.phase = Idle;
                    return Some(BolterEvent::Failed { attempts: self.attempt });
                }
                self.attempt += 1;
                self.attempt_failed = false;
                self.enter(Select, now_ms);
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> BolterConfig {
        BolterConfig::default()
    }

    /// Runs the machine with currents given per phase until it reports.
    fn run(
        b: &mut Bolter,
        t: &mut u64,
        mut current: impl FnMut(BolterPhase, u64) -> (u16, Option<u16>),
        trace: &mut std::vec::Vec<BolterPhase>,
    ) -> std::vec::Vec<BolterEvent> {
        let mut evs = std::vec::Vec::new();
        for _ in 0..20_000 {
            *t += 10;
            if trace.last() != Some(&b.phase()) {
                trace.push(b.phase());
            }
            let (a, bb) = current(b.phase(), *t);
            if let Some(e) = b.tick(*t, a, bb) {
                evs.push(e);
                if !matches!(e, BolterEvent::AttemptFailed { .. }) {
                    return evs;
                }
            }
        }
        panic!("bolter never finished: {trace:?}");
    }

    // verifies: MMIC-CTL-04
    #[test]
    fn bolter_transitions_on_push_and_lock_current_thresholds() {
        let c = cfg();
        let mut b = Bolter::new();
        assert!(b.start(BoltOp::Bolt, 3, 0, c));
        assert_eq!(b.mux(), 2, "pair 3 = A1 high, A0 low");
        let mut t = 0;
        let mut trace = std::vec::Vec::new();
        let evs = run(
            &mut b,
            &mut t,
            |p, _| match p {
                BolterPhase::Descend | BolterPhase::Push => (c.push_ma, Some(c.push_ma + 5)),
                BolterPhase::Rotate => (c.lock_ma + 1, Some(c.lock_ma)),
                _ => (100, Some(100)),
            },
            &mut trace,
        );
        use BolterPhase::*;
        assert_eq!(trace, [Select, Descend, Retract, Push, Rotate, Reverse, Return]);
        assert_eq!(evs, [BolterEvent::Succeeded { attempts: 1 }]);
        assert!(!b.busy());
        assert_eq!(b.drive(), BolterDrive::Off);
    }

    // verifies: MMIC-CTL-04
    #[test]
    fn bolter_waits_for_both_sides_and_just_below_threshold_does_not_advance() {
        let c = cfg();
        let mut b = Bolter::new();
        b.start(BoltOp::Bolt, 1, 0, c);
        let mut t = 0;
        for _ in 0..30 {
            t += 10;
            b.tick(t, c.push_ma, Some(c.push_ma - 1));
        }
        assert_eq!(b.phase(), BolterPhase::Descend);
        assert_eq!(b.drive(), BolterDrive::Descend);
        t += 10;
        b.tick(t, c.push_ma, None);
        assert_eq!(
            b.phase(),
            BolterPhase::Descend,
            "silent board B never meets the threshold"
        );
        t += 10;
        b.tick(t, c.push_ma, Some(c.push_ma));
        assert_eq!(b.phase(), BolterPhase::Retract);
    }

    // verifies: MMIC-CTL-05
    #[test]
    fn bolter_retries_after_step_timeout_and_fails_after_max_attempts() {
        let c = cfg();
        let mut b = Bolter::new();
        b.start(BoltOp::Bolt, 2, 0, c);
        let mut t = 0;
        let mut trace = std::vec::Vec::new();
        // reaches push, never locks
        let evs = run(
            &mut b,
            &mut t,
            |p, _| match p {
                BolterPhase::Descend | BolterPhase::Push | BolterPhase::Rotate => {
                    (c.push_ma + 100, Some(c.push_ma + 100))
                }
                _ => (50, Some(50)),
            },
            &mut trace,
        );
        assert_eq!(evs.len(), 4);
        for (i, e) in evs[..3].iter().enumerate() {
            assert_eq!(
                *e,
                BolterEvent::AttemptFailed {
                    attempt: i as u8 + 1,
                    phase: BolterPhase::Rotate
                }
            );
        }
        assert_eq!(evs[3], BolterEvent::Failed { attempts: 3 });
        // each failed attempt spent at least the step timeout in Rotate
        assert!(t >= 3 * c.step_timeout_ms as u64);
    }

    // verifies: MMIC-CTL-05
    #[test]
    fn bolter_succeeds_on_second_attempt() {
        let c = cfg();
        let mut b = Bolter::new();
        b.start(BoltOp::Bolt, 4, 0, c);
        let mut t = 0u64;
        let mut events = std::vec::Vec::new();
        while events.len() < 2 && t < 200_000 {
            t += 10;
            let (a, bb) = match b.phase() {
                BolterPhase::Descend | BolterPhase::Push => (1300, Some(1300)),
                BolterPhase::Rotate if b.attempt() == 2 => (1900, Some(1900)),
                BolterPhase::Rotate => (900, Some(900)),
                _ => (50, Some(50)),
            };
            if let Some(e) = b.tick(t, a, bb) {
                events.push(e);
            }
        }
        assert_eq!(
            events,
            [
                BolterEvent::AttemptFailed {
                    attempt: 1,
                    phase: BolterPhase::Rotate
                },
                BolterEvent::Succeeded { attempts: 2 }
            ]
        );
    }

    // verifies: MMIC-CMD-03
    #[test]
    fn unbolting_is_the_reverse_and_released_by_current_drop() {
        let c = cfg();
        let mut b = Bolter::new();
        b.start(BoltOp::Unbolt, 1, 0, c);
        let mut t = 0;
        let mut trace = std::vec::Vec::new();
        let evs = run(
            &mut b,
            &mut t,
            |p, now| match p {
                BolterPhase::Descend => (1250, Some(1250)),
                // breakaway torque for a while, then the fastener turns free
                BolterPhase::Unlock if now % 100_000 < 900 => (2100, Some(2100)),
                BolterPhase::Unlock => (400, Some(400)),
                _ => (50, Some(50)),
            },
            &mut trace,
        );
        use BolterPhase::*;
        assert_eq!(trace, [Select, Descend, Unlock, Return]);
        assert_eq!(evs, [BolterEvent::Succeeded { attempts: 1 }]);
        // unbolting drives the heads backwards
        assert_eq!(Unlock.drive(BoltOp::Unbolt), BolterDrive::RotateUnlock);
        // a jammed fastener never releases
        let mut b = Bolter::new();
        b.start(BoltOp::Unbolt, 1, 0, c);
        let evs = run(&mut b, &mut t, |_, _| (2200, Some(2200)), &mut trace);
        assert_eq!(evs.last(), Some(&BolterEvent::Failed { attempts: 3 }));
    }

    // verifies: MMIC-AV-03
    #[test]
    fn bolter_rejects_invalid_pairs() {
        let mut b = Bolter::new();
        assert!(!b.start(BoltOp::Bolt, 0, 0, cfg()));
        assert!(!b.start(BoltOp::Bolt, 5, 0, cfg()));
        assert!(!b.busy());
    }
}
