//! Ground-side alarms of the collector (`ground collect`), ISA-18.2 style.
//!
//! Pure parts, no I/O and no clock (time is passed in):
//! - the alarm model — [`AlarmState`] (the life cycle of one alarm as a state machine),
//!   [`Source`] (what an alarm is about) and [`Severity`] — lives in
//!   `ground_archive::alarm_model` (the archive applies it to stored alarms) and is
//!   re-exported here;
//! - [`LimitChecker`]: every HK parameter with MIB limits, checked against its soft and
//!   hard limits with persistence and hysteresis.
//!
//! Limits, the robot state in which they apply (root modes, a condition such as "no
//! primitive running"), persistence and hysteresis all come from the MIB
//! (`mib::params`: `limits_apply`, `GROUND_LIMIT_PERSISTENCE`, `limit_hysteresis`).

use mib::types::Limits;
use serde::Serialize;

pub use ground_archive::alarm_model::{AlarmState, Effect, Input, Refused, Severity, Source, State};

// ---------------------------------------------------------------------------
// Limit checking

/// How far out of its limits a value is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Level {
    Ok,
    Soft,
    Hard,
}

impl Level {
    pub fn severity(self) -> Option<Severity> {
        match self {
            Level::Ok => None,
            Level::Soft => Some(Severity::Medium),
            Level::Hard => Some(Severity::High),
        }
    }
}

/// Raw level of a value against limits, with hysteresis relative to the current level:
/// to fall back from a level the value must be inside that level's limit by `hyst`.
pub fn level_of(v: f64, l: &Limits, current: Level, hyst: f64) -> Level {
    let beyond = |lo: f64, hi: f64| v < lo || v > hi;
    let within_margin = |lo: f64, hi: f64| v < lo + hyst || v > hi - hyst;
    if beyond(l.hard_lo, l.hard_hi) || (current >= Level::Hard && within_margin(l.hard_lo, l.hard_hi)) {
        Level::Hard
    } else if beyond(l.soft_lo, l.soft_hi) || (current >= Level::Soft && within_margin(l.soft_lo, l.soft_hi)) {
        Level::Soft
    } else {
        Level::Ok
    }
}

/// A change of one parameter's limit level.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LimitChange {
    pub param: &'static str,
    pub from: Level,
    pub to: Level,
    pub value: f64,
    pub unit: &'static str,
    /// The limit crossed (the one of the new level, or of the old when returning).
    pub limit: f64,
}

#[derive(Clone, Copy, Debug)]
struct ParamTrack {
    level: Level,
    candidate: Level,
    count: u8,
}

/// Limit checks of every HK parameter with MIB limits, for one robot.
#[derive(Clone, Debug)]
pub struct LimitChecker {
    tracks: Vec<(u16, ParamTrack)>,
}

impl Default for LimitChecker {
    fn default() -> Self {
        Self::new()
    }
}

impl LimitChecker {
    pub fn new() -> LimitChecker {
        LimitChecker {
            tracks: mib::params::PARAMS
                .iter()
                .filter(|p| p.limits.is_some())
                .map(|p| {
                    (
                        p.id,
                        ParamTrack {
                            level: Level::Ok,
                            candidate: Level::Ok,
                            count: 0,
                        },
                    )
                })
                .collect(),
        }
    }

    /// Checks one HK sample (parameter ID, engineering value); `ctx` gives the raw
    /// values of the same packet, which decide whether the MIB's limits apply
    /// (`mib::params::limits_apply`: the root mode, a condition such as "no primitive
    /// running"). Returns the level change, if any.
    pub fn check(&mut self, id: u16, eng: f64, ctx: impl Fn(u16) -> Option<i64>) -> Option<LimitChange> {
        let p = mib::params::by_id(id)?;
        let l = p.limits?;
        let (_, t) = self.tracks.iter_mut().find(|(i, _)| *i == id)?;
        let applies = mib::params::limits_apply(p, ctx);
        let raw_level = if applies && eng.is_finite() {
            level_of(eng, l, t.level, mib::params::limit_hysteresis(l))
        } else if applies {
            Level::Hard
        } else {
            Level::Ok
        };
        if raw_level == t.level {
            t.candidate = t.level;
            t.count = 0;
            return None;
        }
        if raw_level != t.candidate {
            t.candidate = raw_level;
            t.count = 0;
        }
        t.count = t.count.saturating_add(1);
        if t.count < mib::params::GROUND_LIMIT_PERSISTENCE {
            return None;
        }
        let from = t.level;
        t.level = raw_level;
        t.count = 0;
        let shown = raw_level.max(from);
        let limit = match (shown, eng < (l.soft_lo + l.soft_hi) / 2.0) {
            (Level::Hard, true) => l.hard_lo,
            (Level::Hard, false) => l.hard_hi,
            (_, true) => l.soft_lo,
            (_, false) => l.soft_hi,
        };
        Some(LimitChange {
            param: p.name,
            from,
            to: raw_level,
            value: eng,
            unit: p.unit,
            limit,
        })
    }

    /// Current level of a parameter.
    pub fn level(&self, id: u16) -> Level {
        self.tracks
            .iter()
            .find(|(i, _)| *i == id)
            .map_or(Level::Ok, |(_, t)| t.level)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::params::pid;

    fn vbat_raw(volts: f64) -> f64 {
        volts
    }

    /// The raw values of an HK packet in root mode `mode` with no primitive running.
    fn m(mode: i64) -> impl Fn(u16) -> Option<i64> {
        move |id| match id {
            pid::MODE => Some(mode),
            pid::ACTIVE_PRIMITIVE => Some(0),
            _ => None,
        }
    }

    // verifies: GND-13, ALM-PERSIST-01
    #[test]
    fn battery_sag_raises_soft_then_hard_after_persistence() {
        let mut c = LimitChecker::new();
        let id = pid::V_BAT_A;
        assert_eq!(c.check(id, vbat_raw(12.0), m(0)), None);
        assert_eq!(c.check(id, 10.3, m(0)), None, "one sample is not persistent");
        let ch = c.check(id, 10.3, m(0)).unwrap();
        assert_eq!((ch.from, ch.to, ch.limit), (Level::Ok, Level::Soft, 10.5));
        assert_eq!(c.check(id, 9.8, m(0)), None);
        let ch = c.check(id, 9.8, m(0)).unwrap();
        assert_eq!((ch.to, ch.limit), (Level::Hard, 10.0));
        assert_eq!(ch.to.severity(), Some(Severity::High));
    }

    // verifies: GND-13
    #[test]
    fn hysteresis_keeps_a_value_hovering_at_the_limit_from_chattering() {
        let mut c = LimitChecker::new();
        let id = pid::V_BAT_A;
        for _ in 0..2 {
            c.check(id, 10.45, m(0));
        }
        assert_eq!(c.level(id), Level::Soft);
        // Just inside the soft limit, within the hysteresis (2 % of 2.1 V = 42 mV).
        for _ in 0..5 {
            assert_eq!(c.check(id, 10.52, m(0)), None);
        }
        assert_eq!(c.level(id), Level::Soft);
        c.check(id, 10.6, m(0));
        let ch = c.check(id, 10.6, m(0)).unwrap();
        assert_eq!((ch.from, ch.to), (Level::Soft, Level::Ok));
    }

    // verifies: GND-13
    #[test]
    fn interrupted_excursion_does_not_count_as_persistent() {
        let mut c = LimitChecker::new();
        let id = pid::I_BO_A;
        assert_eq!(c.check(id, 2.2, m(1)), None);
        assert_eq!(c.check(id, 1.0, m(1)), None);
        assert_eq!(c.check(id, 2.2, m(1)), None);
        assert!(c.check(id, 2.2, m(1)).is_some());
    }

    // verifies: GND-13
    #[test]
    fn regulator_voltage_is_not_checked_in_standby() {
        let mut c = LimitChecker::new();
        for _ in 0..5 {
            assert_eq!(c.check(pid::V_REG, 0.0, m(0)), None);
        }
        c.check(pid::V_REG, 0.0, m(1));
        assert_eq!(c.check(pid::V_REG, 0.0, m(1)).unwrap().to, Level::Hard);
    }

    // verifies: ALM-COND-01
    #[test]
    fn hip_deviation_is_checked_only_while_no_primitive_runs() {
        let mut c = LimitChecker::new();
        let turning = |id| match id {
            pid::MODE => Some(1),
            pid::ACTIVE_PRIMITIVE => Some(4),
            _ => None,
        };
        // The corner turn: -55 deg while a primitive turns the hip.
        for _ in 0..5 {
            assert_eq!(c.check(pid::HIP_DEVIATION, -55.05, turning), None);
        }
        assert_eq!(c.check(pid::HIP_DEVIATION, -55.05, m(1)), None);
        let ch = c.check(pid::HIP_DEVIATION, -55.05, m(1)).unwrap();
        assert_eq!((ch.to, ch.limit), (Level::Hard, -5.0));
    }

    // verifies: GND-13
    #[test]
    fn parameters_without_limits_are_not_checked() {
        let mut c = LimitChecker::new();
        for _ in 0..5 {
            assert_eq!(c.check(pid::MODE, 99.0, m(0)), None);
        }
    }
}
