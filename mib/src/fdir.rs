//! FDIR definitions: fault table (paper Table 8), PUS 12 monitoring definitions and
//! PUS 19 event-action links.

use crate::events::eid;
use crate::modes::robot_mode;
use crate::params::{self, pid, CAL_AMP, CAL_CDEG, CAL_VOLT};
use crate::types::Calib;

/// When a fault's recovery mode is entered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timing {
    /// At once: the running action is aborted.
    Immediate,
    /// After the running motion completes (low battery, assembly-system fault).
    AfterMotion,
}

/// One fault of paper Table 8.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FaultDef {
    /// Bit in `FAULT_FLAGS` / `FAULT_LATCHED`.
    pub bit: u8,
    pub event: u16,
    /// Mode entered (through the event-action link).
    pub mode: u32,
    pub timing: Timing,
}

pub const FAULTS: &[FaultDef] = &[
    FaultDef {
        bit: 0,
        event: eid::BOLT_FAILURE,
        mode: robot_mode::STANDBY,
        timing: Timing::Immediate,
    },
    FaultDef {
        bit: 1,
        event: eid::UNBOLT_FAILURE,
        mode: robot_mode::STANDBY,
        timing: Timing::Immediate,
    },
    FaultDef {
        bit: 2,
        event: eid::INITIAL_STATE_MISMATCH,
        mode: robot_mode::STANDBY,
        timing: Timing::Immediate,
    },
    FaultDef {
        bit: 3,
        event: eid::LOW_BATTERY,
        mode: robot_mode::STANDBY,
        timing: Timing::AfterMotion,
    },
    FaultDef {
        bit: 4,
        event: eid::ASSEMBLY_SYSTEM_FAULT,
        mode: robot_mode::STANDBY,
        timing: Timing::AfterMotion,
    },
    FaultDef {
        bit: 5,
        event: eid::ARM_NOT_CONTRACTED,
        mode: robot_mode::SAFED,
        timing: Timing::Immediate,
    },
    FaultDef {
        bit: 6,
        event: eid::IDLE_OVERCURRENT,
        mode: robot_mode::SAFED,
        timing: Timing::Immediate,
    },
    FaultDef {
        bit: 7,
        event: eid::OPERATIONAL_OVERCURRENT,
        mode: robot_mode::SAFED,
        timing: Timing::Immediate,
    },
    FaultDef {
        bit: 8,
        event: eid::HIP_MISMATCH,
        mode: robot_mode::SAFED,
        timing: Timing::Immediate,
    },
    FaultDef {
        bit: 9,
        event: eid::COMM_LOSS_HEARTBEAT,
        mode: robot_mode::SAFED,
        timing: Timing::Immediate,
    },
    FaultDef {
        bit: 10,
        event: eid::COMM_LOSS_NO_ACK,
        mode: robot_mode::SAFED,
        timing: Timing::Immediate,
    },
];

pub fn fault_by_event(event: u16) -> Option<&'static FaultDef> {
    FAULTS.iter().find(|f| f.event == event)
}

/// When a monitor is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Every control cycle while the regulator is on.
    Always,
    /// Every control cycle, whatever the mode (battery).
    AlwaysEvenUnpowered,
    /// At the start and at the end of every reconfiguration (robot idle).
    Idle,
    /// Once, when entering operational after homing.
    EnteringOperational,
    /// Every control cycle while board B is expected to talk (regulator on).
    Link,
}

impl Phase {
    pub const fn name(self) -> &'static str {
        match self {
            Phase::Always => "always (powered)",
            Phase::AlwaysEvenUnpowered => "always",
            Phase::Idle => "start and end of reconfiguration",
            Phase::EnteringOperational => "entering operational",
            Phase::Link => "always (powered)",
        }
    }
}

/// A PUS 12 limit check on a telemetry parameter, in raw units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MonitorDef {
    pub id: u16,
    pub name: &'static str,
    pub param: u16,
    pub low: i32,
    pub high: i32,
    /// Consecutive violating samples (control cycles) before the event is raised.
    pub persistence: u16,
    pub event: u16,
    pub phase: Phase,
    pub enabled: bool,
}

const fn raw(c: Calib, eng: f64) -> i32 {
    c.raw(eng) as i32
}
/// Control cycles in `ms` milliseconds.
const fn cycles(ms: u32) -> u16 {
    (ms / crate::config::CONTROL_PERIOD_MS) as u16
}
const NO_LOW: i32 = i32::MIN;
const NO_HIGH: i32 = i32::MAX;

/// Low battery: below 10 V for more than 0.5 s (paper).
pub const LOW_BATTERY_PERSISTENCE_MS: u32 = 500;
/// Operational overcurrent persistence (filters servo inrush).
pub const OVERCURRENT_PERSISTENCE_MS: u32 = 50;

pub const MONITORS: &[MonitorDef] = &[
    MonitorDef {
        id: 1,
        name: "V_BAT_A_LOW",
        param: pid::V_BAT_A,
        low: raw(CAL_VOLT, params::V_BAT_EMPTY),
        high: NO_HIGH,
        persistence: cycles(LOW_BATTERY_PERSISTENCE_MS),
        event: eid::LOW_BATTERY,
        phase: Phase::AlwaysEvenUnpowered,
        enabled: true,
    },
    MonitorDef {
        id: 2,
        name: "V_BAT_B_LOW",
        param: pid::V_BAT_B,
        low: raw(CAL_VOLT, params::V_BAT_EMPTY),
        high: NO_HIGH,
        persistence: cycles(LOW_BATTERY_PERSISTENCE_MS),
        event: eid::LOW_BATTERY,
        phase: Phase::Link,
        enabled: true,
    },
    MonitorDef {
        id: 3,
        name: "I_LOC_A_OPER",
        param: pid::I_LOC_A,
        low: NO_LOW,
        high: raw(CAL_AMP, params::I_LOC_MAX),
        persistence: cycles(OVERCURRENT_PERSISTENCE_MS),
        event: eid::OPERATIONAL_OVERCURRENT,
        phase: Phase::Always,
        enabled: true,
    },
    MonitorDef {
        id: 4,
        name: "I_LOC_B_OPER",
        param: pid::I_LOC_B,
        low: NO_LOW,
        high: raw(CAL_AMP, params::I_LOC_MAX),
        persistence: cycles(OVERCURRENT_PERSISTENCE_MS),
        event: eid::OPERATIONAL_OVERCURRENT,
        phase: Phase::Always,
        enabled: true,
    },
    MonitorDef {
        id: 5,
        name: "I_GRIP_A_OPER",
        param: pid::I_GRIP_A,
        low: NO_LOW,
        high: raw(CAL_AMP, params::I_GRIP_MAX),
        persistence: cycles(OVERCURRENT_PERSISTENCE_MS),
        event: eid::OPERATIONAL_OVERCURRENT,
        phase: Phase::Always,
        enabled: true,
    },
    MonitorDef {
        id: 6,
        name: "I_GRIP_B_OPER",
        param: pid::I_GRIP_B,
        low: NO_LOW,
        high: raw(CAL_AMP, params::I_GRIP_MAX),
        persistence: cycles(OVERCURRENT_PERSISTENCE_MS),
        event: eid::OPERATIONAL_OVERCURRENT,
        phase: Phase::Always,
        enabled: true,
    },
    MonitorDef {
        id: 7,
        name: "I_BO_A_OPER",
        param: pid::I_BO_A,
        low: NO_LOW,
        high: raw(CAL_AMP, params::I_BO_MAX),
        persistence: cycles(OVERCURRENT_PERSISTENCE_MS),
        event: eid::OPERATIONAL_OVERCURRENT,
        phase: Phase::Always,
        enabled: true,
    },
    MonitorDef {
        id: 8,
        name: "I_BO_B_OPER",
        param: pid::I_BO_B,
        low: NO_LOW,
        high: raw(CAL_AMP, params::I_BO_MAX),
        persistence: cycles(OVERCURRENT_PERSISTENCE_MS),
        event: eid::OPERATIONAL_OVERCURRENT,
        phase: Phase::Always,
        enabled: true,
    },
    MonitorDef {
        id: 9,
        name: "I_LOC_A_IDLE",
        param: pid::I_LOC_A,
        low: NO_LOW,
        high: raw(CAL_AMP, params::I_LOC_IDLE_MAX),
        persistence: 1,
        event: eid::IDLE_OVERCURRENT,
        phase: Phase::Idle,
        enabled: true,
    },
    MonitorDef {
        id: 10,
        name: "I_LOC_B_IDLE",
        param: pid::I_LOC_B,
        low: NO_LOW,
        high: raw(CAL_AMP, params::I_LOC_IDLE_MAX),
        persistence: 1,
        event: eid::IDLE_OVERCURRENT,
        phase: Phase::Idle,
        enabled: true,
    },
    MonitorDef {
        id: 11,
        name: "HIP_CONTRACTED",
        param: pid::HIP_DEVIATION,
        low: raw(CAL_CDEG, -params::HIP_CONTRACTED_TOL_DEG),
        high: raw(CAL_CDEG, params::HIP_CONTRACTED_TOL_DEG),
        persistence: 1,
        event: eid::HIP_MISMATCH,
        phase: Phase::EnteringOperational,
        enabled: true,
    },
    MonitorDef {
        id: 12,
        name: "B_HEARTBEAT",
        param: pid::B_HB_AGE_MS,
        low: NO_LOW,
        high: params::B_HEARTBEAT_TIMEOUT_MS as i32,
        persistence: 1,
        event: eid::COMM_LOSS_HEARTBEAT,
        phase: Phase::Link,
        enabled: true,
    },
];

pub fn monitor_by_id(id: u16) -> Option<&'static MonitorDef> {
    MONITORS.iter().find(|m| m.id == id)
}

/// A PUS 19 event-action link: the fault event triggers a TC[200,1] to the robot node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ActionDef {
    pub event: u16,
    pub mode: u32,
    pub timing: Timing,
    pub enabled: bool,
}

/// One link per fault, derived from [`FAULTS`].
pub const fn action_for(event: u16) -> Option<ActionDef> {
    let mut i = 0;
    while i < FAULTS.len() {
        let f = &FAULTS[i];
        if f.event == event {
            return Some(ActionDef {
                event,
                mode: f.mode,
                timing: f.timing,
                enabled: true,
            });
        }
        i += 1;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events;
    // verifies: MMIC-FLT-12
    #[test]
    fn every_fault_event_has_a_fault_entry_and_unique_bit() {
        for e in events::EVENTS.iter().filter(|e| e.fault) {
            assert!(fault_by_event(e.id).is_some(), "{}", e.name);
        }
        for (i, f) in FAULTS.iter().enumerate() {
            assert!(FAULTS[i + 1..].iter().all(|o| o.bit != f.bit && o.event != f.event));
            assert!(f.bit < 32);
        }
    }
    // verifies: MMIC-FLT-04
    #[test]
    fn low_battery_is_ten_volts_for_half_a_second() {
        let m = monitor_by_id(1).unwrap();
        assert_eq!(m.persistence as u32 * crate::config::CONTROL_PERIOD_MS, 500);
        assert!((CAL_VOLT.eng(m.low as i64) - 10.0).abs() < 0.01);
        for (i, m) in MONITORS.iter().enumerate() {
            assert!(MONITORS[i + 1..].iter().all(|o| o.id != m.id));
            assert!(crate::params::by_id(m.param).is_some());
            assert!(events::by_id(m.event).is_some());
            assert!(m.id >= 1 && m.id <= 32, "monitor bit must fit MON_ENABLED");
        }
    }
}
