//! PUS 200 (sat-rs) mode management over the mode tree: the robot node is commanded
//! (standby / operational / safed), its children follow; a transition completes when
//! the hardware confirms every child's mode (and, into operational, after the hip
//! check and homing). Mode reports (TM[200,6]) on request and on every change.

use mib::config;
use mib::fdir::Phase;
use mib::modes::{module_mode, node, robot_mode, NodeKind};
use mib::params::{self, pid, Source};
use mib::tc::{function, service};
use mib::FailureCode;
use mib_wire::tm;

use mmic_domain::controller::{Action, ModuleModes};

use crate::accept::Tc;
use crate::downlink::{Downlink, Stage, Started};
use crate::failure::Failure;
use crate::modes::{Change, ModeTree, N_NODES};
use crate::obsw::{Exec, Outcome, Refused};
use crate::request::unknown;
use crate::robot::{Ports, Robot};
use crate::services::function::Running;
use crate::services::modules::Modules;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};

/// A node of the mode tree; only made from a defined node ID.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Node(u32);

impl Node {
    fn of(id: u32) -> Result<Self, Failure> {
        ModeTree::index(id)
            .map(|_| Node(id))
            .ok_or(Failure::unknown_mode_target(id))
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[200,1] on the robot node with a commandable mode.
    Set { mode: u32 },
    /// TC[200,3]: TM[200,6] of one node.
    Read(Node),
    /// TC[200,5]: TM[200,6] of a node and its descendants.
    Announce(Node),
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        use mib_wire::args::{ModeAnnounce, ModeRead, ModeSet};
        Ok(match tc.subservice {
            1 => {
                let x = ModeSet::of(&tc.args);
                let (n, mode) = (Node::of(x.node)?, x.mode);
                if n.0 != node::ROBOT || !mib::modes::is_commandable_root_mode(mode) {
                    return Err(Failure::invalid_mode(n.0, mode));
                }
                Request::Set { mode }
            }
            3 => Request::Read(Node::of(ModeRead::of(&tc.args).node)?),
            5 => Request::Announce(Node::of(ModeAnnounce::of(&tc.args).node)?),
            _ => return Err(unknown(tc)),
        })
    }
}

/// A mode command waiting for its transition.
#[derive(Debug)]
pub struct ModeCmd<T> {
    pub token: T,
    pub target: u32,
}

impl ModeCmd<()> {
    pub(crate) fn with_token(self, token: Started) -> ModeCmd<Started> {
        ModeCmd {
            token,
            target: self.target,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Entering {
    /// Waiting for the modules to confirm power.
    Powering,
    /// Homing after the hip check passed.
    Homing,
    /// Homing done: the robot node may take the mode.
    Ready,
}

/// A transition of the robot node in progress.
#[derive(Clone, Copy, Debug)]
pub struct Transition {
    target: u32,
    started: u64,
    /// The fault event that caused it (0 when commanded).
    cause: u16,
    pub(crate) entering: Entering,
}

/// The mode tree answers the reports itself; a commanded mode comes back as the output,
/// for the robot to start its transition ([`Robot::mode_command`]: the transition joins the
/// mode tree to the controller, the module set, FDIR and the running action).
impl Component for ModeTree {
    const CONTRACT: Contract = Contract::new("mode", Some(service::MODE), &[Source::Modes]);
    type Request<'a> = Request;
    type Output = Option<u32>;
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<Option<u32>, Failure> {
        match r {
            Request::Set { mode } => return Ok(Some(mode)),
            Request::Read(n) => self.reply(now, n.0, dl, sink),
            Request::Announce(n) => {
                for id in ModeTree::subtree(n.0) {
                    self.reply(now, id, dl, sink);
                }
            }
        }
        Ok(None)
    }
}

impl ModeTree {
    /// The power of each module for the controller: the commanded mode of its node, off
    /// for a module the boot discovery found absent.
    pub(crate) fn module_modes(&self, modules: &Modules) -> ModuleModes {
        use mib::modules::slot;
        let m = |slot: u8, node: u32| modules.present_or_off(slot, self.commanded(node));
        ModuleModes {
            arm_a: m(slot::ARM_A, node::ARM_A),
            grip_a: m(slot::GRIPPER_A, node::GRIPPER_A),
            bolter_a: m(slot::BOLTER_A, node::BOLTER_A),
            arm_b: m(slot::ARM_B, node::ARM_B),
            grip_b: m(slot::GRIPPER_B, node::GRIPPER_B),
            bolter_b: m(slot::BOLTER_B, node::BOLTER_B),
            hip: m(slot::HIP, node::HIP),
        }
    }

    /// TM[200,6] of node `n`.
    pub(crate) fn reply<S: TmStore>(&self, now: u64, n: u32, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let Some(ms) = self.mode_and_submode(n) else {
            return;
        };
        let r = tm::ModeReply {
            node: n,
            mode: ms.mode(),
            submode: ms.submode(),
        };
        dl.emit_tm(now, &r, sink);
    }
}

impl Robot {
    pub(crate) fn mode_command<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        target: u32,
        p: &mut Ports<S, K>,
    ) -> Result<Exec, Refused> {
        if target == robot_mode::OPERATIONAL {
            if let Some(f) = p.modules.block_operational() {
                return Err(f.into());
            }
            if let Some(ev) = self.faults.first_active_event() {
                return Err(Failure::fault_not_cleared(ev).into());
            }
        }
        if let Some(prev) = self.mode_cmd.take() {
            self.fail_mode_cmd(now, prev, FailureCode::ABORTED_BY_COMMAND, 0, p);
        }
        if target == self.modes.root() && self.transition.is_none() {
            self.modes.reply(now, node::ROBOT, p.dl, p.sink);
            return Ok(Exec::Done);
        }
        Ok(Exec::Mode(ModeCmd { token: (), target }))
    }

    /// Called once the mode command's start was reported.
    pub(crate) fn mode_command_started<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        cmd: ModeCmd<Started>,
        p: &mut Ports<S, K>,
    ) {
        let target = cmd.target;
        self.mode_cmd = Some(cmd);
        self.set_mode(now, target, 0, p);
    }

    /// Starts a transition of the robot node (by command, cause 0, or by FDIR, cause =
    /// fault event). A running action is aborted unless the target is operational.
    pub(crate) fn set_mode<S: TmStore, K: TmSink>(&mut self, now: u64, target: u32, cause: u16, p: &mut Ports<S, K>) {
        if target != robot_mode::OPERATIONAL {
            if let Some(r) = self.running.take() {
                self.ctrl.abort();
                let f = if cause != 0 {
                    Failure::aborted_by_fault(cause)
                } else {
                    Failure::aborted_by_command(r.function)
                };
                if r.token.is_some() {
                    self.finish_running(now, r, Some(f), p);
                }
                self.modes.submode = mib::modes::submode::IDLE;
            }
        }
        if cause != 0 {
            // FDIR takes over: a pending mode command loses.
            if let Some(c) = self.mode_cmd.take() {
                if c.target != target {
                    self.fail_mode_cmd(now, c, FailureCode::ABORTED_BY_FAULT, cause, p);
                } else {
                    self.mode_cmd = Some(c);
                }
            }
        }
        self.modes.command(target);
        self.transition = Some(Transition {
            target,
            started: now,
            cause,
            entering: Entering::Powering,
        });
        self.apply_module_modes(p.modules);
        self.progress_transition(now, p);
    }

    /// True when the hardware shows that a module is in `mode`.
    fn module_confirms(&self, n: &mib::modes::NodeDef, mode: u32, modules: &Modules) -> bool {
        if mode == module_mode::OFF {
            return true;
        }
        let v_reg_min = params::by_id(pid::V_REG)
            .and_then(|p| p.limits)
            .map_or(0, |l| params::CAL_VOLT.raw(l.hard_lo));
        let powered = self.param_opt(pid::V_REG, modules).is_some_and(|v| v >= v_reg_min);
        if n.parent != Some(node::SIDE_B) {
            return powered;
        }
        // Board B keeps driving its servos at their last set point when A's commands
        // stop, so side B holds position even with the A-B link down (what safed after
        // a communication loss needs); anything else needs B's acknowledgement.
        mode == module_mode::HOLD || self.param_opt(pid::B_LINK_OK, modules) == Some(1)
    }

    pub(crate) fn progress_transition<S: TmStore, K: TmSink>(&mut self, now: u64, p: &mut Ports<S, K>) {
        let Some(t) = self.transition else { return };
        let mut changes: heapless::Vec<Change, N_NODES> = heapless::Vec::new();
        let root_ready = t.target != robot_mode::OPERATIONAL || t.entering == Entering::Ready;
        {
            let this = &*self;
            let confirmed: heapless::Vec<(u32, bool), N_NODES> = mib::modes::NODES
                .iter()
                .map(|n| (n.id, this.module_confirms(n, this.modes.commanded(n.id), p.modules)))
                .collect();
            self.modes.update(
                |n, _| confirmed.iter().any(|(id, ok)| *id == n.id && *ok),
                root_ready,
                &mut changes,
            );
        }
        for c in &changes {
            let e = mib_wire::ev::ModeChanged {
                node: c.node,
                from: c.from,
                to: c.to,
                cause: t.cause,
            };
            p.dl.raise(now, e, p.sink);
        }
        if t.target == robot_mode::OPERATIONAL && t.entering == Entering::Powering {
            let children_done = mib::modes::NODES
                .iter()
                .filter(|n| n.kind != NodeKind::Root)
                .all(|n| self.modes.get(n.id).is_some_and(|m| m.actual == m.commanded));
            if children_done {
                // Paper: hip mismatch is checked when entering operational, then
                // entering operational sends every actuator home.
                if self
                    .run_monitors(now, |ph| ph == Phase::EnteringOperational, p)
                    .is_some()
                {
                    return;
                }
                match self.ctrl.start(Action::Home, now) {
                    Ok(_) => {
                        self.running = Some(Running {
                            token: None,
                            function: function::HOME,
                            reconfigure: false,
                        });
                        if let Some(t) = self.transition.as_mut() {
                            t.entering = Entering::Homing;
                        }
                    }
                    Err(e) => {
                        let f = Failure::from_start(e, function::HOME, self.modes.root());
                        self.transition_failed(now, f.code(), 0, p);
                    }
                }
                return;
            }
        }
        if !self.modes.in_transition() {
            self.transition = None;
            self.modes.reply(now, node::ROBOT, p.dl, p.sink);
            if let Some(c) = self.mode_cmd.take() {
                if c.target == self.modes.root() {
                    let req = c.token.req;
                    p.dl.complete(now, c.token, p.sink);
                    p.outcome(req, Outcome::Done);
                } else {
                    self.mode_cmd = Some(c);
                }
            }
            if t.target == robot_mode::OPERATIONAL {
                // Recovery done: one-shot faults and latches are cleared.
                self.faults.oneshot = 0;
                self.faults.latched = self.faults.monitored;
            } else if t.cause != 0 {
                // The fault has been dealt with by its mode change.
                self.clear_oneshot(now, t.cause, p);
            }
            return;
        }
        let entering_homing = t.entering == Entering::Homing;
        if !entering_homing && now.saturating_sub(t.started) > config::MODE_TRANSITION_TIMEOUT_MS as u64 {
            self.transition_failed(now, FailureCode::TIMEOUT, 0, p);
        }
    }

    /// Completes a mode command with MODE_CHANGE_FAILED: node, target mode, the reason
    /// (a failure code) and the fault event behind it (0 if none).
    fn fail_mode_cmd<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        c: ModeCmd<Started>,
        reason: FailureCode,
        event: u16,
        p: &mut Ports<S, K>,
    ) {
        let f = Failure::mode_change_failed(node::ROBOT, c.target, reason, event);
        let req = c.token.req;
        p.dl.fail_completion(now, c.token, &f, p.sink);
        p.outcome(req, Outcome::Failed(Stage::Completion, (&f).into()));
    }

    /// A transition that cannot complete: report it and fall back to standby.
    pub(crate) fn transition_failed<S: TmStore, K: TmSink>(
        &mut self,
        now: u64,
        reason: FailureCode,
        event: u16,
        p: &mut Ports<S, K>,
    ) {
        let Some(t) = self.transition.take() else { return };
        let r = tm::ModeCantReach {
            node: node::ROBOT,
            mode: t.target,
            submode: 0,
            reason: reason.code(),
        };
        p.dl.emit_tm(now, &r, p.sink);
        let e = mib_wire::ev::ModeChangeFailed {
            node: node::ROBOT,
            mode: t.target,
            reason: reason.code(),
        };
        p.dl.raise(now, e, p.sink);
        if let Some(c) = self.mode_cmd.take() {
            self.fail_mode_cmd(now, c, reason, event, p);
        }
        if t.target != robot_mode::STANDBY {
            self.set_mode(now, robot_mode::STANDBY, t.cause, p);
        } else {
            let mut ch = heapless::Vec::new();
            self.modes.settle(&mut ch);
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::obsw::tests::{failure, kind, obsw, of, send};
    use mib::modes::{node, robot_mode};
    use mib::FailureCode;

    fn set(node: u32, mode: u32) -> Vec<u8> {
        let mut app = node.to_be_bytes().to_vec();
        app.extend_from_slice(&mode.to_be_bytes());
        app.extend_from_slice(&0u16.to_be_bytes());
        app
    }

    // verifies: PUS-200-01
    #[test]
    fn a_child_node_is_not_commandable_and_an_unknown_node_is_refused() {
        let mut o = obsw();
        let pkts = send(&mut o, 1, 1, 200, 1, &set(node::ARM_A, robot_mode::SAFED));
        let mut data = node::ARM_A.to_be_bytes().to_vec();
        data.extend_from_slice(&robot_mode::SAFED.to_be_bytes());
        assert_eq!(failure(&of(&pkts, 1, 2)[0]), (FailureCode::INVALID_MODE.code(), data));
        let pkts = send(&mut o, 2, 2, 200, 3, &0xDEADu32.to_be_bytes());
        assert_eq!(
            failure(&of(&pkts, 1, 2)[0]),
            (
                FailureCode::UNKNOWN_MODE_TARGET.code(),
                0xDEADu32.to_be_bytes().to_vec()
            )
        );
    }

    // verifies: PUS-200-01
    #[test]
    fn commanding_the_current_mode_completes_at_once_with_a_mode_report() {
        let mut o = obsw();
        let pkts = send(&mut o, 1, 1, 200, 1, &set(node::ROBOT, robot_mode::STANDBY));
        let reply = of(&pkts, 200, 6);
        assert_eq!(&kind(&reply[0]).2[4..8], &robot_mode::STANDBY.to_be_bytes());
        assert_eq!(of(&pkts, 1, 7).len(), 1);
    }

    // verifies: PUS-200-01, PUS-1-02
    #[test]
    fn safed_without_power_times_out_and_the_command_fails_with_the_reason() {
        let mut o = obsw();
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let pkts = send(&mut o, 1, 1, 200, 1, &set(node::ROBOT, robot_mode::SAFED));
        assert_eq!(of(&pkts, 1, 3).len(), 1, "started");
        // No sensors: the regulator never confirms power.
        let t = 2 + mib::config::MODE_TRANSITION_TIMEOUT_MS as u64;
        let (robot, mut p) = o.robot(&mut sink);
        robot.progress_transition(t, &mut p);
        let f = of(&sink, 1, 8);
        assert_eq!(f.len(), 1);
        let (code, data) = failure(&f[0]);
        assert_eq!(code, FailureCode::MODE_CHANGE_FAILED.code());
        assert_eq!(&data[8..10], &FailureCode::TIMEOUT.code().to_be_bytes());
    }
}
