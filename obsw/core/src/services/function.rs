//! PUS 8 function management: the robot's actions (reconfigure, bolt, unbolt, home,
//! single-module moves), STOP and the commanded assembly-system fault. An action runs
//! in the domain controller; its progress and completion come back through `tick`.

use mib::modes::submode;
use mib::robot::Side;
use mib::tc::function;
use mib_wire::ev;

use mmic_domain::controller::{Action, ActionReport, DomainEvent, StartError};

use crate::accept::Tc;
use crate::downlink::{Stage, Started};
use crate::failure::Failure;
use crate::obsw::{Exec, Outcome, Refused};
use crate::robot::{Ports, Robot};
use crate::tm::{TmSink, TmStore};

/// Its contract; its requests are handled by the robot (`Robot::function_request`), which
/// joins them to the controller, the mode tree and FDIR.
pub const CONTRACT: crate::services::Contract =
    crate::services::Contract::new("function", Some(mib::tc::service::FUNCTION), &[]);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// ASSEMBLY_FAULT: the externally commanded "assembly system operation" fault.
    AssemblyFault(ev::AssemblySystemFault),
    /// STOP: abort the running action; actuators hold.
    Stop,
    /// Any other function: an action of the domain controller.
    Start(Action),
}

impl Request {
    /// The typed arguments of the TC's kind (`mib_wire::args`, fields by their MIB name,
    /// values range-checked by `accept`) become the domain's action.
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        use mib_wire::args as arg;
        let a = &tc.args;
        // Side arguments are range-checked (0..=1) by `accept`; argument 0 of every TC
        // that has one.
        let side = |v: u8| Side::from_u8(v).ok_or(Failure::arg_out_of_range(0, i32::from(v)));
        Ok(Request::Start(match tc.def.function {
            function::ASSEMBLY_FAULT => {
                let x = arg::AssemblyFault::of(a);
                return Ok(Request::AssemblyFault(ev::AssemblySystemFault { reason: x.reason }));
            }
            function::STOP => return Ok(Request::Stop),
            function::RECONFIGURE => {
                let x = arg::Reconfigure::of(a);
                Action::Reconfigure { from: x.from, to: x.to }
            }
            function::BOLT_FACE => {
                let x = arg::BoltFace::of(a);
                Action::BoltFace {
                    side: side(x.side)?,
                    pairs: x.pairs,
                }
            }
            function::UNBOLT_FACE => {
                let x = arg::UnboltFace::of(a);
                Action::UnboltFace {
                    side: side(x.side)?,
                    pairs: x.pairs,
                }
            }
            function::HOME => Action::Home,
            function::MOVE_ARM => {
                let x = arg::MoveArm::of(a);
                Action::MoveArm {
                    side: side(x.side)?,
                    pwm: x.pwm,
                }
            }
            function::MOVE_GRIPPER => {
                let x = arg::MoveGripper::of(a);
                Action::MoveGripper {
                    side: side(x.side)?,
                    pwm: x.pwm,
                }
            }
            function::ROTATE_HIP => Action::RotateHip {
                cdeg: arg::RotateHip::of(a).angle,
            },
            function::BOLT_PAIR => {
                let x = arg::BoltPair::of(a);
                Action::BoltPair {
                    side: side(x.side)?,
                    pair: x.pair,
                }
            }
            function::UNBOLT_PAIR => {
                let x = arg::UnboltPair::of(a);
                Action::UnboltPair {
                    side: side(x.side)?,
                    pair: x.pair,
                }
            }
            other => return Err(Failure::unknown_function(other)),
        }))
    }
}

/// The action that runs, with the started token of its request (`None` for actions
/// the OBSW starts itself: homing when entering operational).
#[derive(Debug)]
pub struct Running<T> {
    pub token: T,
    pub function: u16,
    pub reconfigure: bool,
}

impl Running<()> {
    pub(crate) fn with_token(self, token: Option<Started>) -> Running<Option<Started>> {
        Running {
            token,
            function: self.function,
            reconfigure: self.reconfigure,
        }
    }
}

impl Robot {
    pub(crate) fn function_request<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        r: Request,
        p: &mut Ports<S, K>,
    ) -> Result<Exec, Refused> {
        let action = match r {
            Request::AssemblyFault(e) => {
                self.raise_fault(now, e, p);
                return Ok(Exec::Done);
            }
            Request::Stop => {
                if let Some(run) = self.running.take() {
                    self.ctrl.abort();
                    let f = Failure::aborted_by_command(run.function);
                    self.finish_running(now, run, Some(f), p);
                }
                return Ok(Exec::Done);
            }
            Request::Start(a) => a,
        };
        if let Some(f) = p.modules.absent_for(&action) {
            return Err(f.into());
        }
        if self.running.is_some() || self.transition.is_some() {
            let busy = self.running.as_ref().map_or(0, |r| r.function);
            return Err(Failure::busy(busy).into());
        }
        let f = action.function_id();
        let reconfigure = f == function::RECONFIGURE;
        if reconfigure {
            // Paper: idle overcurrent is checked at the start of every reconfiguration.
            if let Some(ev) = self.idle_check(now, p) {
                return Err(Failure::aborted_by_fault(ev).into());
            }
        }
        match self.ctrl.start(action, now) {
            Ok(_) => {
                self.modes.submode = submode::BUSY;
                Ok(Exec::Action(Running {
                    token: (),
                    function: f,
                    reconfigure,
                }))
            }
            // Report the refusal first, then let FDIR act on the fault.
            Err(StartError::InitialStateMismatch { believed, computed }) => Err(Refused {
                failure: Failure::initial_state_mismatch(believed, computed),
                fault: Some(ev::InitialStateMismatch { believed, computed }),
            }),
            Err(e) => Err(Failure::from_start(e, f, self.modes.root()).into()),
        }
    }

    /// Ends the running action with a completion report (success if `failure` is None).
    pub(crate) fn finish_running<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        r: Running<Option<Started>>,
        failure: Option<Failure>,
        p: &mut Ports<S, K>,
    ) {
        self.modes.submode = submode::IDLE;
        if let Some(token) = r.token {
            let req = token.req;
            match failure {
                None => {
                    p.dl.complete(now, token, p.sink);
                    p.outcome(req, Outcome::Done);
                }
                Some(f) => {
                    p.dl.fail_completion(now, token, &f, p.sink);
                    p.outcome(req, Outcome::Failed(Stage::Completion, (&f).into()));
                }
            }
        } else if let Some(t) = self
            .transition
            .as_mut()
            .filter(|t| t.entering == crate::services::mode::Entering::Homing)
        {
            // Homing for entry into operational.
            match failure {
                None => t.entering = crate::services::mode::Entering::Ready,
                Some(f) => {
                    // A homing aborted by a fault carries the fault's event ID.
                    let event = f.fault_event().unwrap_or(0);
                    self.transition_failed(now, f.code(), event, p);
                }
            }
        }
        if let Some(m) = self.faults.pending_mode.take() {
            let cause = self.faults.last_event;
            self.set_mode(now, m, cause, p);
        }
    }

    /// Progress and end of the running action, from the controller.
    pub(crate) fn on_report<S: TmStore, K: TmSink>(&mut self, now: u64, r: &ActionReport, p: &mut Ports<S, K>) {
        match *r {
            ActionReport::Step { n } => {
                if let Some(Running { token: Some(t), .. }) = &self.running {
                    p.dl.step(now, t, n, p.sink);
                }
            }
            ActionReport::Completed => {
                let Some(run) = self.running.take() else { return };
                let reconfigure = run.reconfigure;
                self.finish_running(now, run, None, p);
                if reconfigure {
                    // Paper: idle overcurrent is checked at the end of a reconfiguration too.
                    self.idle_check(now, p);
                }
            }
            ActionReport::Failed(f) => {
                let Some(run) = self.running.take() else { return };
                self.finish_running(now, run, Some(Failure::from_action(f)), p);
            }
        }
    }

    /// Domain events become PUS 5 events; fault events go through event-action.
    pub(crate) fn on_domain_event<S: TmStore, K: TmSink>(&mut self, now: u64, e: &DomainEvent, p: &mut Ports<S, K>) {
        let s = |v: Side| v as u8;
        match *e {
            DomainEvent::PrimitiveDone { primitive, state } => {
                p.dl.raise(now, ev::PrimitiveDone { primitive, state }, p.sink)
            }
            DomainEvent::StateReached { state } => p.dl.raise(now, ev::StateReached { state }, p.sink),
            DomainEvent::BoltPairDone { side, pair, attempts } => {
                let side = s(side);
                p.dl.raise(now, ev::BoltPairDone { side, pair, attempts }, p.sink)
            }
            DomainEvent::BoltAttemptFailed { side, pair, attempt } => {
                let side = s(side);
                p.dl.raise(now, ev::BoltAttemptFailed { side, pair, attempt }, p.sink)
            }
            DomainEvent::UnboltPairDone { side, pair, attempts } => {
                let side = s(side);
                p.dl.raise(now, ev::UnboltPairDone { side, pair, attempts }, p.sink)
            }
            DomainEvent::BoltFailure { side, pair, attempts } => {
                let side = s(side);
                self.raise_fault(now, ev::BoltFailure { side, pair, attempts }, p)
            }
            DomainEvent::UnboltFailure { side, pair, attempts } => {
                let side = s(side);
                self.raise_fault(now, ev::UnboltFailure { side, pair, attempts }, p)
            }
            DomainEvent::ArmNotContracted { side } => self.raise_fault(now, ev::ArmNotContracted { side: s(side) }, p),
            DomainEvent::CommLossNoAck { command, retries } => {
                self.raise_fault(now, ev::CommLossNoAck { command, retries }, p)
            }
            // The state computed after a primitive is not the one planned: the robot is
            // not where the ground believes, the same hazard as an initial-state mismatch.
            DomainEvent::StateMismatch { expected, computed } => {
                let e = ev::InitialStateMismatch {
                    believed: expected,
                    computed,
                };
                self.raise_fault(now, e, p)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{failure, obsw, of, send};
    use mib::tc::function;
    use mib::FailureCode;

    // verifies: MMIC-MODE-01, PUS-1-02
    #[test]
    fn an_action_in_standby_is_refused_at_start_with_the_mode() {
        let mut o = obsw();
        let pkts = send(&mut o, 1, 1, 8, 1, &function::HOME.to_be_bytes());
        assert_eq!(
            failure(&of(&pkts, 1, 4)[0]),
            (FailureCode::NOT_ALLOWED_IN_MODE.code(), vec![0])
        );
    }
}
