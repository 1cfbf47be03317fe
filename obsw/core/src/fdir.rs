//! FDIR: PUS 12 parameter monitoring, the fault table (paper Table 8) and PUS 19
//! event-action links. Pure logic: the caller supplies parameter values and turns the
//! returned transitions into TM and mode commands.

use mib::fdir::{self, MonitorDef, Phase, Timing, FAULTS, MONITORS};
use mib::params::{pid, NotSupplied, Supplied};

pub const N_MONITORS: usize = MONITORS.len();
pub const N_FAULTS: usize = FAULTS.len();

/// Check state of a monitor (TM[12,12] `state` field).
pub mod check {
    pub const OK: u8 = 0;
    pub const BELOW_LOW: u8 = 1;
    pub const ABOVE_HIGH: u8 = 2;
}

#[derive(Clone, Copy, Debug)]
pub struct Monitor {
    pub def: MonitorDef,
    pub enabled: bool,
    pub state: u8,
    count: u16,
}

/// A monitor changed its check state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transition {
    pub monitor: u16,
    pub param: u16,
    pub value: i64,
    /// The limit that was crossed (or the one now respected again).
    pub limit: i32,
    pub state: u8,
    pub event: u16,
}

pub struct Monitoring {
    pub mons: [Monitor; N_MONITORS],
}

impl Default for Monitoring {
    fn default() -> Self {
        Self::new()
    }
}

impl Monitoring {
    pub fn new() -> Self {
        let mut mons = [Monitor {
            def: MONITORS[0],
            enabled: MONITORS[0].enabled,
            state: check::OK,
            count: 0,
        }; N_MONITORS];
        for (m, d) in mons.iter_mut().zip(MONITORS) {
            *m = Monitor {
                def: *d,
                enabled: d.enabled,
                state: check::OK,
                count: 0,
            };
        }
        Monitoring { mons }
    }

    pub fn get_mut(&mut self, id: u16) -> Option<&mut Monitor> {
        self.mons.iter_mut().find(|m| m.def.id == id)
    }

    /// The parameters the MIB names PUS 12 monitoring the source of.
    pub fn param(&self, id: u16) -> Supplied {
        match id {
            pid::MON_ENABLED => Ok(Some(i64::from(self.enabled_mask()))),
            _ => Err(NotSupplied(id)),
        }
    }

    /// Bit mask of enabled monitors (bit n-1 = monitor n).
    pub fn enabled_mask(&self) -> u32 {
        self.mons
            .iter()
            .filter(|m| m.enabled)
            .fold(0, |acc, m| acc | 1 << (m.def.id - 1))
    }

    /// Evaluates every enabled monitor whose phase `in_phase` accepts, with the values
    /// from `value`. A monitor is skipped, like one out of its phase, while the MIB says
    /// its parameter's limits do not apply in the robot's state
    /// (`mib::params::limits_apply`: root mode, a condition such as "no primitive
    /// running"); `value` must answer those parameters too. A violation must persist
    /// `persistence` consecutive samples before it is reported; a return inside the
    /// limits is reported at once.
    pub fn check(
        &mut self,
        in_phase: impl Fn(Phase) -> bool,
        value: impl Fn(u16) -> Option<i64>,
        out: &mut heapless::Vec<Transition, N_MONITORS>,
    ) {
        for m in self.mons.iter_mut() {
            if !m.enabled || !in_phase(m.def.phase) {
                continue;
            }
            let limited = mib::params::by_id(m.def.param).filter(|p| p.limits.is_some());
            if limited.is_some_and(|p| !mib::params::limits_apply(p, &value)) {
                continue;
            }
            let Some(v) = value(m.def.param) else { continue };
            let (now, limit) = if v < m.def.low as i64 {
                (check::BELOW_LOW, m.def.low)
            } else if v > m.def.high as i64 {
                (check::ABOVE_HIGH, m.def.high)
            } else {
                (
                    check::OK,
                    if m.state == check::BELOW_LOW {
                        m.def.low
                    } else {
                        m.def.high
                    },
                )
            };
            if now == check::OK {
                m.count = 0;
                if m.state != check::OK {
                    m.state = check::OK;
                    // At most one transition per monitor: `out` holds N_MONITORS.
                    let _ = out.push(Transition {
                        monitor: m.def.id,
                        param: m.def.param,
                        value: v,
                        limit,
                        state: now,
                        event: m.def.event,
                    });
                }
                continue;
            }
            m.count = m.count.saturating_add(1);
            if m.count >= m.def.persistence.max(1) && m.state != now {
                m.state = now;
                // At most one transition per monitor: `out` holds N_MONITORS.
                let _ = out.push(Transition {
                    monitor: m.def.id,
                    param: m.def.param,
                    value: v,
                    limit,
                    state: now,
                    event: m.def.event,
                });
            }
        }
    }

    /// Fault bits whose continuously evaluated monitors are violated right now. Monitors
    /// evaluated only at an instant (start/end of a reconfiguration, entering
    /// operational) raise one-shot faults instead: nothing would re-evaluate them to
    /// clear the fault.
    pub fn violated_fault_bits(&self) -> u32 {
        self.mons
            .iter()
            .filter(|m| m.enabled && m.state != check::OK && is_continuous(m.def.phase))
            .filter_map(|m| fdir::fault_by_event(m.def.event))
            .fold(0, |acc, f| acc | 1 << f.bit)
    }
}

/// True for monitors evaluated every control cycle.
pub const fn is_continuous(p: Phase) -> bool {
    matches!(p, Phase::Always | Phase::AlwaysEvenUnpowered | Phase::Link)
}

/// The state of every fault of Table 8.
#[derive(Default)]
pub struct Faults {
    /// Faults raised by one event (bolt failure, mismatch, ...) that have not yet been
    /// dealt with by their mode change.
    pub oneshot: u32,
    /// Faults whose monitor is violated right now.
    pub monitored: u32,
    pub latched: u32,
    pub count: u32,
    pub last_event: u16,
    /// Mode to enter when the running motion completes.
    pub pending_mode: Option<u32>,
    /// PUS 19 link enabled per fault (index as in `FAULTS`); true by default.
    ea_disabled: u32,
}

/// What FDIR decided for a fault event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Response {
    /// Event-action link disabled (or not a fault): report only.
    None,
    /// Enter `mode` now, aborting what runs.
    Now(u32),
    /// Enter `mode` once the running motion completes.
    AfterMotion(u32),
}

impl Faults {
    pub fn active(&self) -> u32 {
        self.oneshot | self.monitored
    }

    /// The parameters the MIB names FDIR the source of.
    pub fn param(&self, id: u16) -> Supplied {
        Ok(Some(match id {
            pid::FAULT_FLAGS => i64::from(self.active()),
            pid::FAULT_LATCHED => i64::from(self.latched),
            pid::FAULT_COUNT => i64::from(self.count),
            pid::LAST_FAULT_EVENT => i64::from(self.last_event),
            pid::PENDING_MODE => self.pending_mode.map_or(255, i64::from),
            _ => return Err(NotSupplied(id)),
        }))
    }

    /// Records a fault event and returns the recovery the event-action table asks for.
    pub fn raise(&mut self, event: u16, monitored: bool) -> Response {
        let Some(i) = FAULTS.iter().position(|f| f.event == event) else {
            return Response::None;
        };
        let f = FAULTS[i];
        if !monitored {
            self.oneshot |= 1 << f.bit;
        }
        self.latched |= 1 << f.bit;
        self.count = self.count.saturating_add(1);
        self.last_event = event;
        if self.ea_disabled & (1 << i) != 0 {
            return Response::None;
        }
        let Some(a) = fdir::action_for(event) else {
            return Response::None;
        };
        match a.timing {
            Timing::Immediate => Response::Now(a.mode),
            Timing::AfterMotion => Response::AfterMotion(a.mode),
        }
    }

    pub fn set_link_enabled(&mut self, event: u16, enabled: bool) -> bool {
        let Some(i) = FAULTS.iter().position(|f| f.event == event) else {
            return false;
        };
        if enabled {
            self.ea_disabled &= !(1 << i);
        } else {
            self.ea_disabled |= 1 << i;
        }
        true
    }

    pub fn link_enabled(&self, index: usize) -> bool {
        self.ea_disabled & (1 << index) == 0
    }

    /// Event ID of the lowest active fault.
    pub fn first_active_event(&self) -> Option<u16> {
        let a = self.active();
        FAULTS.iter().find(|f| a & (1 << f.bit) != 0).map(|f| f.event)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::events::eid;
    use mib::params::pid;

    fn run(m: &mut Monitoring, v_bat: i64, cycles: usize) -> usize {
        let mut n = 0;
        for _ in 0..cycles {
            let mut out = heapless::Vec::new();
            m.check(
                |p| p == Phase::AlwaysEvenUnpowered,
                |p| (p == pid::V_BAT_A).then_some(v_bat),
                &mut out,
            );
            n += out.len();
        }
        n
    }

    // verifies: MMIC-FLT-04, PUS-12-01
    #[test]
    fn low_battery_needs_half_a_second_of_persistence() {
        let mut m = Monitoring::new();
        let low = MONITORS[0].low as i64 - 10;
        assert_eq!(run(&mut m, low, 49), 0, "49 cycles (490 ms) are not enough");
        assert_eq!(run(&mut m, low, 1), 1, "the 50th cycle (500 ms) raises it");
        assert_eq!(run(&mut m, low, 100), 0, "reported once");
        assert_ne!(m.violated_fault_bits(), 0);
        assert_eq!(run(&mut m, low + 100, 1), 1, "recovery is reported at once");
        assert_eq!(m.violated_fault_bits(), 0);
    }

    // verifies: MMIC-FLT-04, PUS-12-01
    #[test]
    fn a_short_dip_resets_the_persistence_count() {
        let mut m = Monitoring::new();
        let low = MONITORS[0].low as i64 - 10;
        assert_eq!(run(&mut m, low, 40), 0);
        assert_eq!(run(&mut m, low + 100, 1), 0);
        assert_eq!(run(&mut m, low, 40), 0);
    }

    // verifies: ALM-COND-01, PUS-12-01
    #[test]
    fn the_hip_monitor_is_skipped_while_a_primitive_runs_as_the_mib_says() {
        let mut m = Monitoring::new();
        let high = mib::fdir::monitor_by_id(11).unwrap().high as i64;
        let mut check = |primitive: Option<i64>| {
            let mut out = heapless::Vec::new();
            m.check(
                |p| p == Phase::EnteringOperational,
                |p| match p {
                    pid::HIP_DEVIATION => Some(high + 500),
                    pid::ACTIVE_PRIMITIVE => primitive,
                    _ => None,
                },
                &mut out,
            );
            out.len()
        };
        assert_eq!(check(Some(4)), 0, "a turning hip is no mismatch");
        assert_eq!(check(None), 0, "an unknown state is not judged");
        assert_eq!(check(Some(0)), 1, "idle and 5 deg off: mismatch");
    }

    // verifies: MMIC-FLT-12, PUS-19-01
    #[test]
    fn table8_responses() {
        let mut f = Faults::default();
        assert_eq!(
            f.raise(eid::BOLT_FAILURE, false),
            Response::Now(mib::modes::robot_mode::STANDBY)
        );
        assert_eq!(
            f.raise(eid::LOW_BATTERY, true),
            Response::AfterMotion(mib::modes::robot_mode::STANDBY)
        );
        assert_eq!(
            f.raise(eid::ARM_NOT_CONTRACTED, false),
            Response::Now(mib::modes::robot_mode::SAFED)
        );
        assert_eq!(f.count, 3);
        assert!(f.set_link_enabled(eid::HIP_MISMATCH, false));
        assert_eq!(f.raise(eid::HIP_MISMATCH, false), Response::None);
        assert_eq!(f.raise(eid::STATE_REACHED, false), Response::None);
        assert_eq!(f.first_active_event(), Some(eid::BOLT_FAILURE));
    }
}
