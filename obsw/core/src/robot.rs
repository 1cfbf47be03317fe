//! The robot: its actions (PUS 8, `services::function`), its mode tree and transition
//! (PUS 200, `services::mode`) and FDIR (PUS 12 monitoring, `services::monitoring`; PUS 19
//! event-action, `services::event_action`), one component with the domain controller.
//! They act on each other inside one control period — an action's end completes a homing
//! transition and applies a fault's pending mode, a transition aborts the running action
//! and runs the entering-operational monitors, a monitor's violation raises a fault whose
//! link changes the mode — so they share one owner, [`Robot`], and each file adds the
//! methods of its own part to it.
//!
//! Its interface to the rest of the obsw is [`Ports`], given for one call: what it sends
//! (the downlink and the sink), what it tells other components (a fault suspends the
//! on-board plan; a request's outcome goes to the duplicate window and the plan), and what
//! it reads (the module set found at boot). It reads no parameter of another component:
//! every parameter it checks or waits on is one it supplies ([`Robot::param_opt`]; the
//! test `every_parameter_the_robot_reads_is_its_own` holds the MIB to that). It never
//! calls back into the obsw: what the obsw does next with a request comes back as
//! [`Exec`](crate::obsw::Exec) or [`Refused`](crate::obsw::Refused).

use mib::params::{NotSupplied, Source, Supplied};
use mib_wire::RequestId;

use mmic_domain::controller::{Controller, TickOut};

use crate::downlink::{Downlink, Started};
use crate::duplicates::{Duplicates, Outcome};
use crate::fdir::{self, Faults, Monitoring};
use crate::modes::ModeTree;
use crate::obsw::Counters;
use crate::services::function::Running;
use crate::services::mode::{ModeCmd, Transition};
use crate::services::modules::Modules;
use crate::services::plan::OnboardPlan;
use crate::tm::{TmSink, TmStore};

/// The robot's state: the domain controller, the mode tree with its transition and mode
/// command, FDIR's monitors and faults, and the running action.
pub struct Robot {
    pub ctrl: Controller,
    pub monitoring: Monitoring,
    pub faults: Faults,
    pub modes: ModeTree,
    pub(crate) transition: Option<Transition>,
    pub(crate) mode_cmd: Option<ModeCmd<Started>>,
    pub(crate) running: Option<Running<Option<Started>>>,
}

/// What the robot reaches outside itself during one call (see the module's documentation).
pub(crate) struct Ports<'a, S: TmStore, K: TmSink> {
    pub dl: &'a mut Downlink<S>,
    pub sink: &'a mut K,
    /// Suspended by every fault ([`OnboardPlan::fault`]); learns its steps' outcomes.
    pub plan: &'a mut OnboardPlan,
    /// The duplicate window keeps every request's outcome.
    pub seen: &'a mut Duplicates,
    /// An outcome the plan could not take is counted in EVENTS_DROPPED.
    pub counters: &'a mut Counters,
    /// The module set found at boot: an action or OPERATIONAL needing an absent module is
    /// refused, an absent module is unpowered and its parameters have no value.
    pub modules: &'a Modules,
}

impl<S: TmStore, K: TmSink> Ports<'_, S, K> {
    /// Records what became of request `req` ([`record_outcome`]).
    pub(crate) fn outcome(&mut self, req: RequestId, outcome: Outcome) {
        record_outcome(self.plan, self.seen, self.counters, req, outcome);
    }
}

/// Records what became of request `req`: the duplicate window keeps it, and the on-board
/// plan learns the outcome of its step's TC here (one it cannot take is counted in
/// EVENTS_DROPPED).
pub(crate) fn record_outcome(
    plan: &mut OnboardPlan,
    seen: &mut Duplicates,
    counters: &mut Counters,
    req: RequestId,
    outcome: Outcome,
) {
    if plan.outcome(req, &outcome).is_err() {
        counters.events_dropped = counters.events_dropped.saturating_add(1);
    }
    seen.set_outcome(req, outcome);
}

impl Default for Robot {
    fn default() -> Self {
        Self::new()
    }
}

impl Robot {
    pub fn new() -> Self {
        Robot {
            ctrl: Controller::new(),
            monitoring: Monitoring::new(),
            faults: Faults::default(),
            modes: ModeTree::new(),
            transition: None,
            mode_cmd: None,
            running: None,
        }
    }

    /// The robot's configuration state as the controller computes it from the sensors
    /// (`mib::robot::STATE_UNKNOWN` when it cannot).
    pub fn computed_state(&self) -> u8 {
        self.ctrl.computed_state().unwrap_or(mib::robot::STATE_UNKNOWN)
    }

    /// The parameter sources the robot is (the rows of `crate::services::COMPONENTS` of its
    /// parts: the mode tree, FDIR's faults and monitors, the controller's two boards).
    pub const SOURCES: [Source; 5] = [
        Source::Modes,
        Source::Faults,
        Source::Monitoring,
        Source::BoardA,
        Source::BoardB,
    ];

    /// Asks the part of the robot that is source `src` for parameter `id`; `Err` for a
    /// source that is not the robot's or a parameter that source does not supply.
    pub fn param_from(&self, src: Source, id: u16) -> Supplied {
        match src {
            Source::Modes => self.modes.param(id),
            Source::Faults => self.faults.param(id),
            Source::Monitoring => self.monitoring.param(id),
            Source::BoardA => self.ctrl.board_a_param(id),
            Source::BoardB => self.ctrl.board_b_param(id),
            Source::Counters
            | Source::Downlink
            | Source::Scheduler
            | Source::Clock
            | Source::Io
            | Source::SpaceLink
            | Source::Modules
            | Source::Team
            | Source::Plan
            | Source::Update
            | Source::Files => Err(NotSupplied(id)),
        }
    }

    /// A parameter the robot supplies, as the obsw reads it (`Obsw::param_value`): `None`
    /// without a valid value now, measured by an absent module, or not the robot's.
    pub(crate) fn param_opt(&self, id: u16, modules: &Modules) -> Option<i64> {
        let src = mib::params::source(id)?;
        let v = self.param_from(src, id).ok().flatten()?;
        let absent = mib::params::module_of(id).is_some_and(|slot| modules.absent(slot));
        (!absent).then_some(v)
    }

    /// The start of a control period, after the controller ran: the progress and end of
    /// the running action, then the domain's events (faults through event-action).
    pub(crate) fn period_start<S: TmStore, K: TmSink>(&mut self, now: u64, out: &TickOut, p: &mut Ports<S, K>) {
        for r in out.reports.iter() {
            self.on_report(now, r, p);
        }
        for e in out.events.iter() {
            self.on_domain_event(now, e, p);
        }
    }

    /// The end of a control period, after module discovery: the continuous monitors, then
    /// the transition's progress.
    pub(crate) fn period_end<S: TmStore, K: TmSink>(&mut self, now: u64, p: &mut Ports<S, K>) {
        self.run_monitors(now, fdir::is_continuous, p);
        self.progress_transition(now, p);
    }

    /// Applies the module powers of the mode tree (off for an absent module) to the
    /// controller. Out of line: called from generic code of every sink type (one copy on
    /// board A).
    #[inline(never)]
    pub(crate) fn apply_module_modes(&mut self, modules: &Modules) {
        self.ctrl.set_module_modes(self.modes.module_modes(modules));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::params::pid;

    // verifies: PUS-12-01
    #[test]
    fn every_parameter_the_robot_reads_is_its_own() {
        // The monitors' parameters and those deciding whether their limits apply, the
        // transition's power and link confirmations and the hip's angle: every one from a
        // source of the robot, so that reading them needs no other component.
        let mut read: Vec<u16> = vec![pid::V_REG, pid::B_LINK_OK, pid::HIP_ANGLE];
        for m in mib::fdir::MONITORS {
            read.push(m.param);
            let def = mib::params::by_id(m.param).expect("a monitored parameter is in the MIB");
            read.extend(mib::params::limit_context(def));
        }
        for id in read {
            let src = mib::params::source(id).expect("a source");
            assert!(Robot::SOURCES.contains(&src), "parameter {id} from {src:?}");
            assert!(Robot::new().param_from(src, id).is_ok(), "parameter {id}");
        }
    }
}
