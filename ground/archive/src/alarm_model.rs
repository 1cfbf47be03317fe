//! The alarm model shared by the collector and the archive, ISA-18.2 style. Pure: no I/O
//! and no clock (time is passed in).
//! - [`AlarmState`]: the life cycle of one alarm — active (unacknowledged),
//!   acknowledged, cleared (returned to normal, still unacknowledged), normal (closed),
//!   and shelved on top of any of them — as a state machine with `apply(input) -> effect`;
//! - [`Source`]: what an alarm is about (a parameter, an event, link loss, stale data,
//!   the archive, a change of the robot's module configuration); [`Severity`].
//!
//! It lives in the archive's crate because the archive applies the state machine to
//! the stored alarm in one transaction ([`crate::alarms`]); `ground::alarms` re-exports
//! it beside the collector's limit checker (the archive builds without the
//! collector).

use std::fmt;

use serde::Serialize;

// ---------------------------------------------------------------------------
// Severity and source

/// Alarm severity (a soft limit warns, a hard limit alarms; events keep theirs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Severity {
    Low,
    Medium,
    High,
}

impl Severity {
    pub fn name(self) -> &'static str {
        match self {
            Severity::Low => "low",
            Severity::Medium => "medium",
            Severity::High => "high",
        }
    }
    pub fn parse(s: &str) -> Option<Severity> {
        [Severity::Low, Severity::Medium, Severity::High]
            .into_iter()
            .find(|v| v.name().eq_ignore_ascii_case(s))
    }
    /// The alarm severity of an on-board event severity (info and low raise none).
    pub fn of_event(s: mib::events::Severity) -> Option<Severity> {
        match s {
            mib::events::Severity::Info | mib::events::Severity::Low => None,
            mib::events::Severity::Medium => Some(Severity::Medium),
            mib::events::Severity::High => Some(Severity::High),
        }
    }
}

/// What an alarm is about.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(tag = "kind", content = "name", rename_all = "snake_case")]
pub enum Source {
    /// An HK parameter out of its limits (MIB name).
    Param(String),
    /// An on-board event of medium or high severity (MIB name).
    Event(String),
    /// No TM from the robot for the loss timeout.
    LinkLoss,
    /// The link carries TM but no housekeeping for three HK intervals.
    StaleData,
    /// The archive cannot be written (disk full, I/O error).
    Archive,
    /// The robot's module configuration changed: its configuration hash (HK CONFIG_HASH,
    /// module report TM[210,3]) differs from the last one the collector saw.
    ConfigChange,
}

impl Source {
    pub fn kind(&self) -> &'static str {
        match self {
            Source::Param(_) => "param",
            Source::Event(_) => "event",
            Source::LinkLoss => "link",
            Source::StaleData => "stale",
            Source::Archive => "archive",
            Source::ConfigChange => "config",
        }
    }
    /// The name shown to operators: the parameter or event name, or the condition.
    pub fn name(&self) -> &str {
        match self {
            Source::Param(n) | Source::Event(n) => n,
            Source::LinkLoss => "LINK_LOSS",
            Source::StaleData => "STALE_DATA",
            Source::Archive => "ARCHIVE_WRITE",
            Source::ConfigChange => "CONFIG_CHANGED",
        }
    }
    /// Inverse of (`kind`, `name`), for rows read back from the archive.
    pub fn from_parts(kind: &str, name: &str) -> Option<Source> {
        match kind {
            "param" => Some(Source::Param(name.to_string())),
            "event" => Some(Source::Event(name.to_string())),
            "link" => Some(Source::LinkLoss),
            "stale" => Some(Source::StaleData),
            "archive" => Some(Source::Archive),
            "config" => Some(Source::ConfigChange),
            _ => None,
        }
    }
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

// ---------------------------------------------------------------------------
// The ISA-18.2 state machine

/// The state an operator sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum State {
    /// Condition gone and acknowledged: the alarm is closed.
    Normal,
    /// Condition present, not acknowledged.
    Active,
    /// Condition present, acknowledged.
    Acknowledged,
    /// Condition gone (returned to normal) but never acknowledged.
    Cleared,
    /// Hidden by an operator until a time; the condition is still followed underneath.
    Shelved,
}

impl State {
    pub fn name(self) -> &'static str {
        match self {
            State::Normal => "normal",
            State::Active => "active",
            State::Acknowledged => "acknowledged",
            State::Cleared => "cleared",
            State::Shelved => "shelved",
        }
    }
    pub fn parse(s: &str) -> Option<State> {
        [
            State::Normal,
            State::Active,
            State::Acknowledged,
            State::Cleared,
            State::Shelved,
        ]
        .into_iter()
        .find(|v| v.name() == s)
    }
}

/// What happens to an alarm.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// The condition is present (again).
    Activate,
    /// The condition is gone.
    Clear,
    /// An operator acknowledges.
    Ack,
    /// An operator shelves it until `until_ms`.
    Shelve { until_ms: i64 },
    /// An operator unshelves it.
    Unshelve,
    /// Time passes (ends an expired shelve).
    Tick,
}

/// Why an operator input was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum Refused {
    /// Nothing to acknowledge: already acknowledged or closed.
    #[error("nothing to acknowledge (already acknowledged or closed)")]
    NothingToAck,
    /// The alarm is closed (normal); there is nothing to shelve.
    #[error("the alarm is closed")]
    Closed,
    /// Unshelve of an alarm that is not shelved.
    #[error("the alarm is not shelved")]
    NotShelved,
    /// Shelve end not after now.
    #[error("the shelve must end in the future")]
    ShelveInPast,
}

/// What a transition did, for logs and for the live display.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Effect {
    pub from: State,
    pub to: State,
}

impl Effect {
    pub fn changed(&self) -> bool {
        self.from != self.to
    }
    /// The alarm has just closed (a later activation opens a new alarm).
    pub fn closed(&self) -> bool {
        self.to == State::Normal && self.from != State::Normal
    }
}

/// The state of one alarm: the condition, whether the current occurrence is
/// acknowledged, and a shelve. Starts in [`State::Normal`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct AlarmState {
    pub condition: bool,
    pub acked: bool,
    /// True from the first activation until the alarm is closed.
    pub open: bool,
    pub shelved_until_ms: Option<i64>,
}

impl AlarmState {
    pub fn state(&self) -> State {
        if !self.open {
            State::Normal
        } else if self.shelved_until_ms.is_some() {
            State::Shelved
        } else if self.condition {
            if self.acked {
                State::Acknowledged
            } else {
                State::Active
            }
        } else {
            State::Cleared
        }
    }

    /// Applies one input at time `now_ms`.
    pub fn apply(&mut self, input: Input, now_ms: i64) -> Result<Effect, Refused> {
        let from = self.state();
        let mut next = *self;
        if let Some(until) = next.shelved_until_ms {
            if now_ms >= until {
                next.unshelve();
            }
        }
        match input {
            Input::Activate => {
                if !next.open {
                    next = AlarmState {
                        open: true,
                        ..AlarmState::default()
                    };
                } else if !next.condition {
                    // Back while still unacknowledged or acknowledged-and-cleared:
                    // a new occurrence needs a new acknowledgement.
                    next.acked = false;
                }
                next.condition = true;
            }
            Input::Clear => {
                next.condition = false;
                if next.acked && next.shelved_until_ms.is_none() {
                    next.open = false;
                }
            }
            Input::Ack => {
                if !next.open || next.acked {
                    return Err(Refused::NothingToAck);
                }
                next.acked = true;
                if !next.condition && next.shelved_until_ms.is_none() {
                    next.open = false;
                }
            }
            Input::Shelve { until_ms } => {
                if !next.open {
                    return Err(Refused::Closed);
                }
                if until_ms <= now_ms {
                    return Err(Refused::ShelveInPast);
                }
                next.shelved_until_ms = Some(until_ms);
            }
            Input::Unshelve => {
                if next.shelved_until_ms.is_none() {
                    return Err(Refused::NotShelved);
                }
                next.unshelve();
            }
            Input::Tick => {}
        }
        if !next.open {
            next = AlarmState::default();
        }
        *self = next;
        Ok(Effect { from, to: self.state() })
    }

    /// Ends a shelve: a condition still present comes back unacknowledged; one that
    /// went away while shelved closes the alarm.
    fn unshelve(&mut self) {
        self.shelved_until_ms = None;
        if self.condition {
            self.acked = false;
        } else {
            self.open = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: GND-13
    #[test]
    fn lifecycle_active_ack_clear_closes() {
        let mut a = AlarmState::default();
        assert_eq!(a.state(), State::Normal);
        assert_eq!(a.apply(Input::Activate, 0).unwrap().to, State::Active);
        assert_eq!(a.apply(Input::Ack, 1).unwrap().to, State::Acknowledged);
        let e = a.apply(Input::Clear, 2).unwrap();
        assert_eq!(e.to, State::Normal);
        assert!(e.closed());
    }

    // verifies: GND-13
    #[test]
    fn cleared_alarm_waits_for_ack_and_comes_back_unacked() {
        let mut a = AlarmState::default();
        a.apply(Input::Activate, 0).unwrap();
        assert_eq!(a.apply(Input::Clear, 1).unwrap().to, State::Cleared);
        assert_eq!(a.apply(Input::Activate, 2).unwrap().to, State::Active);
        a.apply(Input::Ack, 3).unwrap();
        a.apply(Input::Clear, 4).unwrap();
        assert_eq!(a.state(), State::Normal);
        // Cleared then acknowledged closes.
        a.apply(Input::Activate, 5).unwrap();
        a.apply(Input::Clear, 6).unwrap();
        assert!(a.apply(Input::Ack, 7).unwrap().closed());
    }

    // verifies: GND-13
    #[test]
    fn acknowledging_twice_or_a_closed_alarm_is_refused() {
        let mut a = AlarmState::default();
        assert_eq!(a.apply(Input::Ack, 0), Err(Refused::NothingToAck));
        a.apply(Input::Activate, 0).unwrap();
        a.apply(Input::Ack, 1).unwrap();
        assert_eq!(a.apply(Input::Ack, 2), Err(Refused::NothingToAck));
        assert_eq!(a.state(), State::Acknowledged);
    }

    // verifies: GND-13
    #[test]
    fn acknowledged_alarm_reactivating_after_clear_needs_new_ack() {
        let mut a = AlarmState::default();
        a.apply(Input::Activate, 0).unwrap();
        a.apply(Input::Ack, 1).unwrap();
        // Activate again while acknowledged and still active: stays acknowledged.
        assert_eq!(a.apply(Input::Activate, 2).unwrap().to, State::Acknowledged);
    }

    // verifies: GND-13
    #[test]
    fn shelve_hides_until_expiry_then_returns_unacked_if_still_present() {
        let mut a = AlarmState::default();
        a.apply(Input::Activate, 0).unwrap();
        a.apply(Input::Ack, 1).unwrap();
        assert_eq!(a.apply(Input::Shelve { until_ms: 100 }, 2).unwrap().to, State::Shelved);
        assert_eq!(a.apply(Input::Activate, 50).unwrap().to, State::Shelved);
        let e = a.apply(Input::Tick, 100).unwrap();
        assert_eq!((e.from, e.to), (State::Shelved, State::Active));
    }

    // verifies: GND-13
    #[test]
    fn shelved_alarm_whose_condition_went_away_closes_on_unshelve() {
        let mut a = AlarmState::default();
        a.apply(Input::Activate, 0).unwrap();
        a.apply(Input::Shelve { until_ms: 100 }, 1).unwrap();
        assert_eq!(a.apply(Input::Clear, 10).unwrap().to, State::Shelved);
        assert!(a.apply(Input::Unshelve, 20).unwrap().closed());
        assert_eq!(a.apply(Input::Unshelve, 21), Err(Refused::NotShelved));
    }

    // verifies: GND-13
    #[test]
    fn shelving_closed_alarms_or_into_the_past_is_refused() {
        let mut a = AlarmState::default();
        assert_eq!(a.apply(Input::Shelve { until_ms: 10 }, 0), Err(Refused::Closed));
        a.apply(Input::Activate, 0).unwrap();
        assert_eq!(a.apply(Input::Shelve { until_ms: 5 }, 5), Err(Refused::ShelveInPast));
        assert_eq!(a.state(), State::Active);
    }

    // verifies: GND-13, PUS-5-01
    #[test]
    fn event_severities_map_to_alarm_severities() {
        assert_eq!(Severity::of_event(mib::events::Severity::Info), None);
        assert_eq!(Severity::of_event(mib::events::Severity::Low), None);
        assert_eq!(Severity::of_event(mib::events::Severity::High), Some(Severity::High));
        assert_eq!(
            Source::from_parts("event", "LOW_BATTERY"),
            Some(Source::Event("LOW_BATTERY".into()))
        );
        assert_eq!(Source::from_parts(Source::LinkLoss.kind(), "x"), Some(Source::LinkLoss));
    }
}
