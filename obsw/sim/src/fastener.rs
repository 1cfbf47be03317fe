//! Fasteners and the bolter physics: bolter travel, the current drawn while pushing a
//! fastener and while rotating, and the random bolt outcome.
//!
//! The outcome of a locking attempt is drawn when a bolter starts rotating on a
//! fastener pair that is not locked; the probability of success depends on the attempt
//! number so that, over many pairs, the distribution of the paper's ground demo is
//! reproduced (2307 / 103 / 28 / 86 of 2524): p1 = 2307/2524, p2 = 103/217,
//! p3 = 28/114 (later attempts use p3). The controller never sees the outcome: it only
//! sees the current, which rises to the lock level on success and stays low when the
//! heads slip.

use mib::robot::bolter::{DEMO_FAILED, DEMO_FIRST, DEMO_PAIRS, DEMO_SECOND, DEMO_THIRD};
use mmic_domain::BolterDrive;
use rand::Rng;

/// Probability that attempt `k` (1-based) locks a pair, given the earlier ones failed.
pub fn p_success(k: u8) -> f64 {
    let after1 = (DEMO_PAIRS - DEMO_FIRST) as f64; // 217
    let after2 = after1 - DEMO_SECOND as f64; // 114
    debug_assert_eq!(after2 - DEMO_THIRD as f64, DEMO_FAILED as f64);
    match k {
        0 | 1 => DEMO_FIRST as f64 / DEMO_PAIRS as f64,
        2 => DEMO_SECOND as f64 / after1,
        _ => DEMO_THIRD as f64 / after2,
    }
}

/// Stroke position where a bolter touches the fastener (0 = home, 1 = full stroke).
pub const CONTACT_POS: f64 = 0.6;
/// Bolter travel speed (stroke per second).
pub const BOLTER_SPEED: f64 = 1.0;
/// Push current: offset and rise per second of pushing, and the stall limit (mA).
pub const PUSH_I0_MA: f64 = 300.0;
pub const PUSH_RISE_MA_S: f64 = 3000.0;
pub const PUSH_STALL_MA: f64 = 2200.0;
/// Rotation on an engaging fastener: start level, rise per second, torque limit (mA).
pub const LOCK_I0_MA: f64 = 1300.0;
pub const LOCK_RISE_MA_S: f64 = 1000.0;
pub const LOCK_STALL_MA: f64 = 2250.0;
/// Rotation while the heads slip (attempt failing).
pub const SLIP_MA: f64 = 800.0;
/// Fastener counts as locked after this much engaged rotation (s).
pub const LOCK_TIME_S: f64 = 0.5;
/// Unbolting: breakaway current and time, then free running.
pub const BREAKAWAY_MA: f64 = 2100.0;
pub const BREAKAWAY_S: f64 = 0.4;
pub const FREE_MA: f64 = 450.0;
/// Moving bolter, idle bolter (mA).
pub const MOVE_MA: f64 = 250.0;
pub const IDLE_MA: f64 = 30.0;

/// One fastener pair of a face.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FastenerPair {
    pub locked: bool,
    /// Locking attempts made (rotations started while unlocked).
    pub lock_attempts: u8,
    pub unlock_attempts: u8,
    /// Outcome of the attempt in progress.
    pub outcome: Option<bool>,
}

impl FastenerPair {
    /// Starts an attempt if none is in progress.
    pub fn begin_attempt<R: Rng>(&mut self, unlock: bool, jam: bool, rng: &mut R) -> bool {
        if let Some(o) = self.outcome {
            return o;
        }
        let k = if unlock {
            self.unlock_attempts = self.unlock_attempts.saturating_add(1);
            self.unlock_attempts
        } else {
            self.lock_attempts = self.lock_attempts.saturating_add(1);
            self.lock_attempts
        };
        let ok = !jam && rng.gen_bool(p_success(k));
        self.outcome = Some(ok);
        ok
    }
    /// Ends the attempt in progress (both bolters back home).
    pub fn end_attempt(&mut self) {
        self.outcome = None;
    }
}

/// One side's bolter.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BolterPhys {
    /// Stroke position 0..1.
    pub pos: f64,
    /// Time pushing against the fastener (s).
    pub push_s: f64,
    /// Time rotating on the fastener (s).
    pub rotate_s: f64,
    pub current_ma: f64,
    last_drive: BolterDrive,
}

impl BolterPhys {
    pub fn at_contact(&self) -> bool {
        self.pos >= CONTACT_POS - 1e-9
    }
    /// Integrates `dt` seconds. `on_face`: the side is gripped to a face, so its bolter
    /// reaches a fastener (otherwise it strokes into free space up to its travel limit,
    /// where the servo stops without load). `pair`: the selected fastener pair under it.
    pub fn step<R: Rng>(
        &mut self,
        dt: f64,
        drive: BolterDrive,
        on_face: bool,
        pair: Option<&mut FastenerPair>,
        jam: bool,
        rng: &mut R,
    ) {
        if drive != self.last_drive {
            if !matches!(drive, BolterDrive::RotateLock | BolterDrive::RotateUnlock) {
                self.rotate_s = 0.0;
            }
            self.last_drive = drive;
        }
        match drive {
            BolterDrive::Off => {
                self.current_ma = 0.0;
                self.push_s = 0.0;
            }
            BolterDrive::Retract | BolterDrive::Reverse => {
                self.push_s = 0.0;
                if self.pos > 0.0 {
                    self.pos = (self.pos - BOLTER_SPEED * dt).max(0.0);
                    self.current_ma = MOVE_MA;
                } else {
                    self.current_ma = IDLE_MA;
                }
            }
            BolterDrive::Descend | BolterDrive::RotateLock | BolterDrive::RotateUnlock if !on_face => {
                self.push_s = 0.0;
                if self.pos < 1.0 {
                    self.pos = (self.pos + BOLTER_SPEED * dt).min(1.0);
                    self.current_ma = MOVE_MA;
                } else {
                    self.current_ma = IDLE_MA;
                }
            }
            BolterDrive::Descend | BolterDrive::RotateLock | BolterDrive::RotateUnlock => {
                if self.pos > CONTACT_POS {
                    // was stroking in free space: back onto the fastener level
                    self.pos = CONTACT_POS;
                }
                if !self.at_contact() {
                    self.pos = (self.pos + BOLTER_SPEED * dt).min(CONTACT_POS);
                    self.push_s = 0.0;
                    self.current_ma = MOVE_MA;
                    return;
                }
                self.push_s += dt;
                let push = (PUSH_I0_MA + PUSH_RISE_MA_S * self.push_s).min(PUSH_STALL_MA);
                match (drive, pair) {
                    (BolterDrive::RotateLock, Some(p)) if !p.locked || p.outcome.is_some() => {
                        let ok = p.begin_attempt(false, jam, rng);
                        self.rotate_s += dt;
                        if ok {
                            self.current_ma = (LOCK_I0_MA + LOCK_RISE_MA_S * self.rotate_s).min(LOCK_STALL_MA);
                            if self.rotate_s >= LOCK_TIME_S {
                                p.locked = true;
                            }
                        } else {
                            self.current_ma = SLIP_MA;
                        }
                    }
                    (BolterDrive::RotateLock, _) => {
                        // already locked: the heads stall at once
                        self.rotate_s += dt;
                        self.current_ma = LOCK_STALL_MA;
                    }
                    (BolterDrive::RotateUnlock, Some(p)) if p.locked || p.outcome.is_some() => {
                        let ok = p.begin_attempt(true, jam, rng);
                        self.rotate_s += dt;
                        if ok && self.rotate_s >= BREAKAWAY_S {
                            p.locked = false;
                            self.current_ma = FREE_MA;
                        } else if ok {
                            self.current_ma = BREAKAWAY_MA;
                        } else {
                            self.current_ma = LOCK_STALL_MA;
                        }
                    }
                    (BolterDrive::RotateUnlock, _) => {
                        self.rotate_s += dt;
                        self.current_ma = FREE_MA;
                    }
                    _ => self.current_ma = push,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: MMIC-VAL-01
    #[test]
    fn conditional_probabilities_reproduce_the_demo_counts() {
        let n = DEMO_PAIRS as f64;
        let first = n * p_success(1);
        let second = (n - first) * p_success(2);
        let third = (n - first - second) * p_success(3);
        let failed = n - first - second - third;
        assert!((first - 2307.0).abs() < 1e-6);
        assert!((second - 103.0).abs() < 1e-6);
        assert!((third - 28.0).abs() < 1e-6);
        assert!((failed - 86.0).abs() < 1e-6);
    }
}
