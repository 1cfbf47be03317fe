//! Board A's robot logic: module modes, actions (reconfiguration, bolting, single-module
//! moves), the state estimate, the link to board B, and the MIB parameters the domain
//! owns. The OBSW core drives it every `mib::config::CONTROL_PERIOD_MS` with `tick`.

use crate::ablink::{LinkManager, ModuleCmd};
use crate::bolter::{BoltOp, Bolter, BolterConfig, BolterEvent};
use crate::calib::RobotCal;
use crate::consts::{EST_HIP_TOL_CDEG, LINK_TX_CAP, STATE_SETTLE_TIMEOUT_MS};
use crate::control::{HipController, HipGains, Interpolator};
use crate::estimate::{grippers_closed_cal, state_from_imus, state_from_sensors_cal};
use crate::filter::{to_i16, to_u16, Ma};
use crate::search::{shortest_path, shortest_states, Plan, StatePath};
use crate::tunables::{TunableError, Tunables};
use crate::types::{ActuatorsA, BolterDrive, SensorsA, SideActuators};
use heapless::Vec;
use mib::config::CONTROL_PERIOD_MS;
use mib::events::eid;
use mib::modes::module_mode::{HOLD, OFF, ON};
use mib::params::{pid, NotSupplied, Source, Supplied, B_HEARTBEAT_TIMEOUT_MS};
use mib::robot::{primitive, servo, Motion, Side, StateKind, NUM_STATES, STATES, STATE_UNKNOWN};
use mib::tunables::tid;

/// Modes of the modules (`mib::modes::module_mode`: OFF, ON, HOLD).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ModuleModes {
    pub arm_a: u32,
    pub grip_a: u32,
    pub bolter_a: u32,
    pub arm_b: u32,
    pub grip_b: u32,
    pub bolter_b: u32,
    pub hip: u32,
}

impl ModuleModes {
    /// Every module in the same mode.
    pub const fn all(m: u32) -> Self {
        ModuleModes {
            arm_a: m,
            grip_a: m,
            bolter_a: m,
            arm_b: m,
            grip_b: m,
            bolter_b: m,
            hip: m,
        }
    }
    /// The module modes implied by a root (robot) mode, `mib::modes::child_mode`.
    pub const fn for_root(root_mode: u32) -> Self {
        use mib::modes::{child_mode, NodeKind};
        let arm = child_mode(root_mode, NodeKind::Arm);
        let grip = child_mode(root_mode, NodeKind::Gripper);
        let bolter = child_mode(root_mode, NodeKind::Bolter);
        ModuleModes {
            arm_a: arm,
            grip_a: grip,
            bolter_a: bolter,
            arm_b: arm,
            grip_b: grip,
            bolter_b: bolter,
            hip: child_mode(root_mode, NodeKind::Hip),
        }
    }
    fn any_powered(&self) -> bool {
        [
            self.arm_a,
            self.grip_a,
            self.bolter_a,
            self.arm_b,
            self.grip_b,
            self.bolter_b,
            self.hip,
        ]
        .iter()
        .any(|&m| m != OFF)
    }
    fn arm(&self, s: Side) -> u32 {
        match s {
            Side::A => self.arm_a,
            Side::B => self.arm_b,
        }
    }
    fn grip(&self, s: Side) -> u32 {
        match s {
            Side::A => self.grip_a,
            Side::B => self.grip_b,
        }
    }
}

/// A robot action (PUS 8 functions).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    Reconfigure {
        from: u8,
        to: u8,
    },
    /// Bolt the selected pairs (bit 0 = pair 1) of the face under `side`.
    BoltFace {
        side: Side,
        pairs: u8,
    },
    UnboltFace {
        side: Side,
        pairs: u8,
    },
    /// Grippers closed, hip at 0, arms contracted.
    Home,
    MoveArm {
        side: Side,
        pwm: u16,
    },
    MoveGripper {
        side: Side,
        pwm: u16,
    },
    RotateHip {
        cdeg: i16,
    },
    BoltPair {
        side: Side,
        pair: u8,
    },
    UnboltPair {
        side: Side,
        pair: u8,
    },
}

impl Action {
    /// The PUS 8 function ID (`mib::tc::function`) that starts this action.
    pub const fn function_id(&self) -> u16 {
        use mib::tc::function as f;
        match self {
            Action::Reconfigure { .. } => f::RECONFIGURE,
            Action::BoltFace { .. } => f::BOLT_FACE,
            Action::UnboltFace { .. } => f::UNBOLT_FACE,
            Action::Home => f::HOME,
            Action::MoveArm { .. } => f::MOVE_ARM,
            Action::MoveGripper { .. } => f::MOVE_GRIPPER,
            Action::RotateHip { .. } => f::ROTATE_HIP,
            Action::BoltPair { .. } => f::BOLT_PAIR,
            Action::UnboltPair { .. } => f::UNBOLT_PAIR,
        }
    }
}

/// Why an action was refused. The core turns each variant into the PUS 1 failure
/// code and data the MIB lists for it (`obsw_core::failure`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StartError {
    Busy,
    InitialStateMismatch {
        believed: u8,
        computed: u8,
    },
    Unreachable {
        from: u8,
        to: u8,
    },
    /// A module the action needs is not in a mode that allows it.
    NotPowered,
    /// An argument outside the range the domain can execute (pair 0 or > 4, empty pair
    /// mask): the index of the argument in the TC (after the function ID) and its value.
    InvalidArgument {
        index: u8,
        value: i32,
    },
    /// The action would turn the hip while both grippers hold a face: the two faces are
    /// fixed to the lattice, so the hip cannot move (it would stall against the
    /// structure). Open one gripper first. Data: the gripper PWMs that show both closed.
    BothSidesGripped {
        grip_a_pwm: u16,
        grip_b_pwm: u16,
    },
}

/// Why a running action ended without completing (the data the MIB lists per code).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ActionFailure {
    /// FDIR detected a fault (the fault's event ID).
    AbortedByFault {
        event: u16,
    },
    BoltFailed {
        side: Side,
        pair: u8,
        attempts: u8,
    },
    UnboltFailed {
        side: Side,
        pair: u8,
        attempts: u8,
    },
    BoardBNoAck {
        command: u8,
        retries: u8,
    },
    Timeout {
        elapsed_ms: u32,
    },
    /// The state computed after a primitive is not the planned one.
    StateMismatch {
        expected: u8,
        computed: u8,
    },
}

/// Progress of the running action (PUS 1 progress / completion / failure).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ActionReport {
    /// Progress step `n` (1-based: primitive or fastener pair) done.
    Step {
        n: u8,
    },
    Completed,
    Failed(ActionFailure),
}

/// Domain events for the core to turn into PUS 5 events (and FDIR).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DomainEvent {
    PrimitiveDone {
        primitive: u8,
        state: u8,
    },
    StateReached {
        state: u8,
    },
    BoltPairDone {
        side: Side,
        pair: u8,
        attempts: u8,
    },
    BoltAttemptFailed {
        side: Side,
        pair: u8,
        attempt: u8,
    },
    BoltFailure {
        side: Side,
        pair: u8,
        attempts: u8,
    },
    UnboltPairDone {
        side: Side,
        pair: u8,
        attempts: u8,
    },
    UnboltFailure {
        side: Side,
        pair: u8,
        attempts: u8,
    },
    ArmNotContracted {
        side: Side,
    },
    CommLossNoAck {
        command: u8,
        retries: u8,
    },
    /// After a primitive the computed state is not the expected one (the action fails
    /// with `INITIAL_STATE_MISMATCH`, data expected/computed).
    StateMismatch {
        expected: u8,
        computed: u8,
    },
}

/// Outputs of one control period.
#[derive(Clone, Debug, Default)]
pub struct TickOut {
    pub actuators: ActuatorsA,
    /// Bytes for the serial line to board B.
    pub link_tx: Vec<u8, LINK_TX_CAP>,
    pub events: Vec<DomainEvent, TICK_QUEUE>,
    pub reports: Vec<ActionReport, TICK_QUEUE>,
    /// Events and reports that did not fit this tick's queues (counted, never silent).
    pub dropped: u32,
}

/// Capacity of one tick's event and report queues.
pub const TICK_QUEUE: usize = mib::config::EVENT_QUEUE_DEPTH;

impl TickOut {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn clear(&mut self) {
        self.link_tx.clear();
        self.events.clear();
        self.reports.clear();
        self.dropped = 0;
    }
    /// Queues a domain event; a full queue counts the loss in `dropped`.
    pub fn event(&mut self, e: DomainEvent) {
        if self.events.push(e).is_err() {
            self.dropped = self.dropped.saturating_add(1);
        }
    }
    /// Queues an action report; a full queue counts the loss in `dropped`.
    pub fn report(&mut self, r: ActionReport) {
        if self.reports.push(r).is_err() {
            self.dropped = self.dropped.saturating_add(1);
        }
    }
}

/// One module move of an action.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Seg {
    /// Gripper(s) to a PWM (`None` = both), per side (index `Side as usize`: each side
    /// has its own calibration).
    Grip {
        side: Option<Side>,
        pwm: [u16; 2],
    },
    /// Arm(s) to a PWM (`None` = both), per side.
    Arm {
        side: Option<Side>,
        pwm: [u16; 2],
    },
    Hip {
        cdeg: i16,
    },
    /// Wait for the arm-contracted switch(es).
    ArmSwitch {
        side: Option<Side>,
    },
    /// Wait for the computed state.
    Settle {
        expect: u8,
    },
    Bolt {
        side: Side,
        pair: u8,
        op: BoltOp,
    },
}

const MAX_SEGS: usize = 8;

#[derive(Clone, Debug)]
struct Run {
    action: Action,
    steps: u8,
    done_steps: u8,
    segs: Vec<Seg, MAX_SEGS>,
    seg: usize,
    seg_started: bool,
    seg_t0: u64,
    step_t0: u64,
    plan: Plan,
    path: StatePath,
}

enum SegResult {
    Running,
    Done,
    Fail(ActionFailure),
}

/// Filtered board A channels.
#[derive(Clone, Debug, Default)]
struct FiltersA {
    v_bat: Ma,
    i_bat: Ma,
    v_reg: Ma,
    i_loc: Ma,
    i_grip: Ma,
    i_bo: Ma,
    grav: [Ma; 3],
    hip: Ma,
}

/// Board A's robot logic.
#[derive(Clone, Debug)]
pub struct Controller {
    modes: ModuleModes,
    b_modes_sent: Option<(u8, u8, u8)>,
    tun: Tunables,
    arm_a: Interpolator,
    grip_a: Interpolator,
    hip: HipController,
    hip_cmd: i16,
    bolter: Bolter,
    b_bolter_sent: (BolterDrive, u8),
    link: LinkManager,
    f: FiltersA,
    raw: SensorsA,
    last_tick: Option<u64>,
    now: u64,
    computed: Option<u8>,
    run: Option<Run>,
    target_state: u8,
    cmd_complete: bool,
    active_primitive: u8,
    bolt_side: u8,
    bolt_pair: u8,
    bolt_attempt: u8,
    /// Since when B's heartbeats report other modes than A wants (link idle).
    b_modes_mismatch_since: Option<u64>,
    /// Arm/gripper positions known (set by `with_positions`, or once a module is
    /// powered); until then they are recovered from the IMU-derived state.
    positions_known: bool,
    b_assume_sent_ms: Option<u64>,
    /// The calibration in use (`RobotCal::COMPILED` until the platform sets the module
    /// set's, docs/modules.md).
    cal: RobotCal,
}

impl Default for Controller {
    fn default() -> Self {
        Self::new()
    }
}

impl Controller {
    /// Board A at boot: modules unpowered; arm and gripper interpolators at the home
    /// position (contracted, closed) until the IMU-derived state tells where the arms
    /// are (see `recover_positions`; stops once an arm or gripper is powered).
    pub fn new() -> Self {
        let tun = Tunables::default();
        Controller {
            modes: ModuleModes::all(OFF),
            b_modes_sent: None,
            arm_a: Interpolator::servo(servo::ARM_CONTRACTED_US),
            grip_a: Interpolator::servo(servo::GRIP_CLOSED_US),
            hip: HipController::new(servo::HIP_HOME_CDEG, HipGains::from_tunables(&tun)),
            hip_cmd: 0,
            bolter: Bolter::new(),
            b_bolter_sent: (BolterDrive::Off, 0),
            link: LinkManager::new(),
            f: FiltersA::default(),
            raw: SensorsA::default(),
            last_tick: None,
            now: 0,
            computed: None,
            run: None,
            target_state: STATE_UNKNOWN,
            cmd_complete: true,
            active_primitive: 0,
            bolt_side: 0,
            bolt_pair: 0,
            bolt_attempt: 0,
            b_modes_mismatch_since: None,
            positions_known: false,
            b_assume_sent_ms: None,
            cal: RobotCal::COMPILED,
            tun,
        }
    }

    /// A controller whose arm A and gripper A are known to be at the given pulse widths
    /// (e.g. the robot booted in a stretch or turn state).
    pub fn with_positions(arm_us: u16, grip_us: u16) -> Self {
        let mut c = Self::new();
        c.arm_a.reset_to(arm_us);
        c.grip_a.reset_to(grip_us);
        c.positions_known = true;
        c
    }

    // ---------------------------------------------------------------- calibration

    /// Applies the module set's calibration (docs/modules.md): servo set points per side, hip
    /// home, encoder zero and direction from now on; the bolter thresholds become the
    /// tunables `BOLT_PUSH_THRESHOLD_MA` / `BOLT_LOCK_THRESHOLD_MA` (clamped to their
    /// ranges, which contain the database's), so the ground can still tune them. Arm and
    /// gripper positions not known yet (boot) start at the home widths and are recovered
    /// with the new set points.
    pub fn set_calibration(&mut self, cal: RobotCal) {
        self.cal = cal;
        for (id, v) in [
            (tid::BOLT_PUSH_THRESHOLD_MA, cal.bolt_push_ma),
            (tid::BOLT_LOCK_THRESHOLD_MA, cal.bolt_lock_ma),
        ] {
            if let Some(d) = mib::tunables::by_id(id) {
                // Cannot fail: clamped to the tunable's own range.
                let _ = self.tun.set(id, (v as i32).clamp(d.min, d.max));
            }
        }
        if !self.positions_known {
            // Not moved since boot: the servos rest at their home widths until the
            // IMU-derived state tells where the arms are (`recover_positions`).
            self.arm_a.reset_to(cal.of(Side::A).arm_home_us);
            self.grip_a.reset_to(cal.of(Side::A).grip_home_us);
            // Board B boots at the compiled widths (`BoardB::new`). Other home widths go
            // to it now, queued ahead of any `Power` (the link keeps the order): a
            // gripper powered before `recover_positions` must not be driven to a width
            // beyond its revision's end stop (REV-ANOM-17).
            let (b, boot) = (cal.of(Side::B), RobotCal::COMPILED.of(Side::B));
            if (b.arm_home_us, b.grip_home_us) != (boot.arm_home_us, boot.grip_home_us) {
                self.link.send(ModuleCmd::Assume {
                    arm: b.arm_home_us,
                    grip: b.grip_home_us,
                });
            }
        }
    }

    /// The calibration in use.
    pub fn calibration(&self) -> &RobotCal {
        &self.cal
    }

    // ---------------------------------------------------------------- modes, tunables

    pub fn modes(&self) -> ModuleModes {
        self.modes
    }

    /// Applies module modes. OFF: unpowered, back-drivable. HOLD: powered, holding the
    /// current position; only single-module moves (`MoveArm`, `RotateHip`) are accepted.
    /// ON: normal. B's modes are forwarded to board B. Any change of modes while an
    /// action runs aborts it without a report, like `abort` (the core, which changed the
    /// mode, reports the TC's failure); setting the same modes again changes nothing.
    pub fn set_module_modes(&mut self, m: ModuleModes) {
        let old = self.modes;
        if [m.arm_a, m.grip_a, m.arm_b, m.grip_b].iter().any(|&x| x != OFF) {
            self.positions_known = true;
        }
        self.modes = m;
        if m.arm_a != ON && old.arm_a == ON {
            self.arm_a.hold();
        }
        if m.grip_a != ON && old.grip_a == ON {
            self.grip_a.hold();
        }
        if m.hip != old.hip {
            if m.hip == OFF {
                self.hip.reset();
            } else if old.hip == OFF || m.hip == HOLD {
                self.hip.reset();
                self.hip.set_target(self.hold_angle());
            }
        }
        if m.bolter_a != ON || m.bolter_b != ON {
            self.bolter.abort();
        }
        if self.run.is_some() && m != old {
            // a mode change ends the running action: HOLD/OFF reset the targets it
            // moves to, and ON after HOLD is a new start
            self.end_run_hold();
        }
        self.sync_b_modes();
    }

    /// Boot with unpowered arms: there is no arm position sensor, but with both sides
    /// gripped the geometry fixes the arm length. If the IMUs imply a state, the hip
    /// agrees with it and the arm switches agree with its kind, the arms are at the
    /// state's PWM: start the interpolators (A's, and B's through `Assume`) there.
    fn recover_positions(&mut self, now: u64) {
        if !self.f.grav[0].is_full() {
            return;
        }
        let Some(hb) = self.link.heartbeat().copied() else {
            return;
        };
        let Some(s) = state_from_imus(self.grav_a(), hb.grav) else {
            return;
        };
        let def = &STATES[s as usize];
        if (self.hip_angle() as i32 - def.hip_cdeg() as i32).abs() > crate::consts::EST_HIP_TOL_CDEG as i32 {
            return;
        }
        let contracted = def.kind() == StateKind::Matched;
        if self.raw.arm_switch != contracted || hb.arm_switch() != contracted {
            return;
        }
        let (ca, cb) = (*self.cal.of(Side::A), *self.cal.of(Side::B));
        let pwm = cb.arm_us(def.kind());
        self.arm_a.reset_to(ca.arm_us(def.kind()));
        self.grip_a.reset_to(ca.grip_closed_us);
        let fresh = self.link.hb_age_ms(now) <= 2 * mib::config::B_HEARTBEAT_PERIOD_MS as u64;
        let b_ok = !fresh || (hb.arm_pwm == pwm && hb.grip_pwm == cb.grip_closed_us);
        let due = self
            .b_assume_sent_ms
            .is_none_or(|t| now.saturating_sub(t) >= crate::consts::B_MODES_RESEND_MS as u64);
        if !b_ok && due && self.link.idle() {
            self.link.send(ModuleCmd::Assume {
                arm: pwm,
                grip: cb.grip_closed_us,
            });
            self.b_assume_sent_ms = Some(now);
        }
    }

    fn b_modes_packed(&self) -> u8 {
        (self.modes.arm_b as u8 & 3) | ((self.modes.grip_b as u8 & 3) << 2) | ((self.modes.bolter_b as u8 & 3) << 4)
    }

    /// Board B reports other module modes than A wants (a lost `Power` command, or B
    /// restarted): send them again, at most every `B_MODES_RESEND_MS`, when the link is
    /// idle.
    fn heal_b_modes(&mut self, now: u64) {
        let want = self.b_modes_packed();
        let Some(hb) = self.link.heartbeat() else { return };
        let fresh = self.link.hb_age_ms(now) <= 2 * mib::config::B_HEARTBEAT_PERIOD_MS as u64;
        if hb.modes == want || !self.link.idle() || !fresh {
            // agreement, a command (maybe the Power itself) still on its way, or B
            // silent (a cut cable): nothing to repair over the link now
            self.b_modes_mismatch_since = None;
            return;
        }
        let since = *self.b_modes_mismatch_since.get_or_insert(now);
        if now.saturating_sub(since) >= crate::consts::B_MODES_RESEND_MS as u64 {
            // heartbeats have disagreed for a while with nothing in flight
            self.b_modes_mismatch_since = None;
            self.b_modes_sent = None;
            self.sync_b_modes();
        }
    }

    fn sync_b_modes(&mut self) {
        let b = (
            self.modes.arm_b as u8,
            self.modes.grip_b as u8,
            self.modes.bolter_b as u8,
        );
        if self.b_modes_sent != Some(b) {
            self.link.send(ModuleCmd::Power {
                arm: b.0,
                grip: b.1,
                bolter: b.2,
            });
            self.b_modes_sent = Some(b);
        }
    }

    /// Sets a PUS 20 tunable; hip gains take effect at once, bolter thresholds at the
    /// next pair.
    pub fn set_tunable(&mut self, id: u16, value: i32) -> Result<(), TunableError> {
        self.tun.set(id, value)?;
        self.hip.set_gains(HipGains::from_tunables(&self.tun));
        Ok(())
    }
    pub fn tunable(&self, id: u16) -> Option<i32> {
        self.tun.try_get(id)
    }

    // ---------------------------------------------------------------- actions

    pub fn busy(&self) -> bool {
        self.run.is_some()
    }

    /// The running action, if any.
    pub fn current_action(&self) -> Option<Action> {
        self.run.as_ref().map(|r| r.action)
    }

    /// The configuration state computed from the (moving-averaged) sensors.
    pub fn computed_state(&self) -> Option<u8> {
        self.computed
    }

    fn action_allowed(&self, a: &Action) -> bool {
        let m = &self.modes;
        let on = |x: u32| x == ON;
        let moving = |x: u32| x == ON || x == HOLD;
        match *a {
            Action::Reconfigure { .. } | Action::Home => {
                on(m.arm_a) && on(m.arm_b) && on(m.grip_a) && on(m.grip_b) && on(m.hip)
            }
            Action::BoltFace { .. }
            | Action::UnboltFace { .. }
            | Action::BoltPair { .. }
            | Action::UnboltPair { .. } => on(m.bolter_a) && on(m.bolter_b),
            Action::MoveArm { side, .. } => moving(m.arm(side)),
            Action::MoveGripper { side, .. } => on(m.grip(side)),
            Action::RotateHip { .. } => moving(m.hip),
        }
    }

    /// The hip angle an action turns the hip to before it opens any gripper, if any.
    /// Reconfiguration primitives open a gripper before they turn the hip; `Home` turns
    /// the hip first, `RotateHip` only turns it.
    fn hip_turn_of(&self, a: &Action) -> Option<i16> {
        match *a {
            Action::RotateHip { cdeg } => Some(cdeg),
            Action::Home => Some(self.cal.hip_home_cdeg),
            Action::Reconfigure { .. }
            | Action::BoltFace { .. }
            | Action::UnboltFace { .. }
            | Action::MoveArm { .. }
            | Action::MoveGripper { .. }
            | Action::BoltPair { .. }
            | Action::UnboltPair { .. } => None,
        }
    }

    /// The two gripper PWMs when both grippers are known to hold (A from its own servo,
    /// B from its last heartbeat). Without a heartbeat B's gripper is unknown: not known
    /// to hold.
    fn both_gripped(&self) -> Option<(u16, u16)> {
        let hb = self.link.heartbeat()?;
        let a = self.grip_a.current();
        grippers_closed_cal(a, hb.grip_pwm, &self.cal).then_some((a, hb.grip_pwm))
    }

    /// Starts an action. Returns the number of progress steps it will report.
    pub fn start(&mut self, action: Action, now_ms: u64) -> Result<u8, StartError> {
        if self.run.is_some() {
            return Err(StartError::Busy);
        }
        let ns = NUM_STATES as u8;
        match action {
            Action::Reconfigure { from, to } if from >= ns || to >= ns => {
                return Err(StartError::Unreachable { from, to })
            }
            Action::BoltFace { pairs, .. } | Action::UnboltFace { pairs, .. } if pairs & 0x0F == 0 || pairs > 0x0F => {
                return Err(StartError::InvalidArgument {
                    index: 1,
                    value: pairs as i32,
                })
            }
            Action::BoltPair { pair, .. } | Action::UnboltPair { pair, .. }
                if !(1..=mib::robot::bolter::PAIRS_PER_FACE).contains(&pair) =>
            {
                return Err(StartError::InvalidArgument {
                    index: 1,
                    value: pair as i32,
                })
            }
            _ => {}
        }
        if !self.action_allowed(&action) {
            return Err(StartError::NotPowered);
        }
        if let (Some(target), Some((grip_a_pwm, grip_b_pwm))) = (self.hip_turn_of(&action), self.both_gripped()) {
            if (target as i32 - self.hip_angle() as i32).abs() > EST_HIP_TOL_CDEG as i32 {
                return Err(StartError::BothSidesGripped { grip_a_pwm, grip_b_pwm });
            }
        }
        let mut run = Run {
            action,
            steps: 1,
            done_steps: 0,
            segs: Vec::new(),
            seg: 0,
            seg_started: false,
            seg_t0: now_ms,
            step_t0: now_ms,
            plan: Plan::new(),
            path: StatePath::new(),
        };
        match action {
            Action::Reconfigure { from, to } => {
                let computed = self.computed;
                if computed != Some(from) {
                    return Err(StartError::InitialStateMismatch {
                        believed: from,
                        computed: computed.unwrap_or(STATE_UNKNOWN),
                    });
                }
                let plan = shortest_path(from, to).ok_or(StartError::Unreachable { from, to })?;
                run.path = shortest_states(from, to).ok_or(StartError::Unreachable { from, to })?;
                run.steps = plan.len() as u8;
                run.plan = plan;
                self.target_state = to;
            }
            Action::BoltFace { pairs, .. } | Action::UnboltFace { pairs, .. } => {
                run.steps = pairs.count_ones() as u8;
            }
            _ => {}
        }
        let steps = run.steps;
        self.run = Some(run);
        self.cmd_complete = false;
        self.build_step();
        Ok(steps)
    }

    /// Stops the running action: every module holds where it is, bolters stop. No report.
    pub fn abort(&mut self) {
        self.end_run_hold();
    }

    fn end_run_hold(&mut self) {
        self.run = None;
        self.active_primitive = 0;
        self.cmd_complete = true;
        self.arm_a.hold();
        self.grip_a.hold();
        let a = self.hold_angle();
        self.hip.set_target(a);
        self.bolter.abort();
        self.bolt_pair = 0;
        self.link.clear_motion();
        self.link.send(ModuleCmd::Stop);
        self.b_bolter_sent = (BolterDrive::Off, 0);
    }

    /// Segments of the current step of the run.
    fn build_step(&mut self) {
        let cal = self.cal;
        let Some(run) = self.run.as_mut() else { return };
        run.segs.clear();
        run.seg = 0;
        run.seg_started = false;
        let k = run.done_steps as usize;
        let mut push = |s: Seg| {
            let _ = run.segs.push(s);
        };
        match run.action {
            Action::Reconfigure { .. } => {
                if k < run.plan.len() {
                    let (from, to, prim) = (run.path[k], run.path[k + 1], run.plan[k]);
                    for s in primitive_segments(from, to, prim, &cal) {
                        push(s);
                    }
                }
            }
            Action::BoltFace { side, pairs } | Action::UnboltFace { side, pairs } => {
                let op = if matches!(run.action, Action::BoltFace { .. }) {
                    BoltOp::Bolt
                } else {
                    BoltOp::Unbolt
                };
                // k-th set bit
                let mut seen = 0;
                for p in 1..=4u8 {
                    if pairs & (1 << (p - 1)) != 0 {
                        if seen == k {
                            push(Seg::Bolt { side, pair: p, op });
                            break;
                        }
                        seen += 1;
                    }
                }
            }
            Action::BoltPair { side, pair } => push(Seg::Bolt {
                side,
                pair,
                op: BoltOp::Bolt,
            }),
            Action::UnboltPair { side, pair } => push(Seg::Bolt {
                side,
                pair,
                op: BoltOp::Unbolt,
            }),
            Action::Home => {
                // Contract first, grip last: a side left open by an aborted primitive
                // is brought onto the face before its gripper closes (closing first
                // would grip nothing). A gripper is never opened here.
                push(Seg::Hip {
                    cdeg: cal.hip_home_cdeg,
                });
                push(Seg::Arm {
                    side: None,
                    pwm: cal.side.map(|c| c.arm_contracted_us),
                });
                push(Seg::ArmSwitch { side: None });
                push(Seg::Grip {
                    side: None,
                    pwm: cal.side.map(|c| c.grip_closed_us),
                });
            }
            Action::MoveArm { side, pwm } => {
                push(Seg::Arm {
                    side: Some(side),
                    pwm: [pwm; 2],
                });
                if pwm <= cal.of(side).arm_contracted_us {
                    push(Seg::ArmSwitch { side: Some(side) });
                }
            }
            Action::MoveGripper { side, pwm } => push(Seg::Grip {
                side: Some(side),
                pwm: [pwm; 2],
            }),
            Action::RotateHip { cdeg } => push(Seg::Hip { cdeg }),
        }
        if let Action::Reconfigure { .. } = run.action {
            self.active_primitive = run.plan.get(k).copied().unwrap_or(0);
        }
    }

    // ---------------------------------------------------------------- tick

    /// Where to hold the hip: the latest raw encoder reading (the moving average lags
    /// 250 ms, 2.5° at 10 °/s), or the average before the first tick.
    fn hold_angle(&self) -> i16 {
        if self.last_tick.is_some() {
            self.raw.hip_cdeg
        } else {
            self.hip_angle()
        }
    }

    fn hip_angle(&self) -> i16 {
        if self.f.hip.is_empty() {
            self.raw.hip_cdeg
        } else {
            to_i16(self.f.hip.value())
        }
    }

    /// One control period.
    pub fn tick(&mut self, now_ms: u64, sensors: &SensorsA, link_rx: &[u8], out: &mut TickOut) {
        out.clear();
        let dt = match self.last_tick {
            Some(t) => now_ms.saturating_sub(t).min(1000) as u32,
            None => CONTROL_PERIOD_MS,
        };
        self.last_tick = Some(now_ms);
        self.now = now_ms;
        self.raw = *sensors;
        // The encoder's own zero and direction (docs/modules.md).
        self.raw.hip_cdeg = self.cal.hip_from_reading(sensors.hip_cdeg);
        let corrected = self.raw;
        let sensors = &corrected;
        let f = &mut self.f;
        f.v_bat.push(sensors.v_bat as i32);
        f.i_bat.push(sensors.i_bat as i32);
        f.v_reg.push(sensors.v_reg as i32);
        f.i_loc.push(sensors.i_loc as i32);
        f.i_grip.push(sensors.i_grip as i32);
        f.i_bo.push(sensors.i_bo as i32);
        for (m, &g) in f.grav.iter_mut().zip(sensors.grav.iter()) {
            m.push(g as i32);
        }
        f.hip.push(sensors.hip_cdeg as i32);

        // board B
        self.link.receive(now_ms, link_rx);
        if !self.positions_known {
            self.recover_positions(now_ms);
        }
        self.computed = self.estimate();
        self.heal_b_modes(now_ms);

        // action
        let mut gave_up_evt = None;
        self.step_run(now_ms, out);

        // bolter drive to B when it changes
        if self.bolter.busy() {
            let want = (self.bolter.drive(), self.bolter.pair());
            if want != self.b_bolter_sent {
                self.link.send(ModuleCmd::Bolter {
                    drive: want.0,
                    pair: want.1,
                });
                self.b_bolter_sent = want;
            }
        } else if self.b_bolter_sent.0 != BolterDrive::Off {
            self.link.send(ModuleCmd::Bolter {
                drive: BolterDrive::Off,
                pair: 0,
            });
            self.b_bolter_sent = (BolterDrive::Off, 0);
        }

        // link transmit
        let ack_to = self.tun.get_u32(tid::B_ACK_TIMEOUT_MS);
        let retries = self.tun.get(tid::B_MAX_RETRIES).clamp(0, 255) as u8;
        if let Some(g) = self.link.transmit(now_ms, ack_to, retries, &mut out.link_tx) {
            gave_up_evt = Some(g);
        }
        if let Some(g) = gave_up_evt {
            out.event(DomainEvent::CommLossNoAck {
                command: g.command,
                retries: g.retries,
            });
            if self.run.is_some() {
                self.finish_fail(
                    ActionFailure::BoardBNoAck {
                        command: g.command,
                        retries: g.retries,
                    },
                    out,
                );
            }
        }

        // actuators
        let arm = if self.modes.arm_a != OFF {
            Some(self.arm_a.tick(dt))
        } else {
            None
        };
        let grip = if self.modes.grip_a != OFF {
            Some(self.grip_a.tick(dt))
        } else {
            None
        };
        let hip = if self.modes.hip != OFF {
            self.hip_cmd = self.hip.tick(sensors.hip_cdeg, dt);
            Some(self.hip_cmd)
        } else {
            self.hip_cmd = 0;
            None
        };
        let bolter = if self.modes.bolter_a == ON {
            self.bolter.drive()
        } else {
            BolterDrive::Off
        };
        out.actuators = ActuatorsA {
            regulator_on: self.modes.any_powered(),
            side: SideActuators {
                arm_pwm: arm,
                grip_pwm: grip,
                bolter,
            },
            hip_speed: hip,
            mux: self.bolter.mux(),
        };
    }

    fn estimate(&self) -> Option<u8> {
        let hb = self.link.heartbeat()?;
        if !grippers_closed_cal(self.grip_a.current(), hb.grip_pwm, &self.cal) {
            return None;
        }
        let s = state_from_sensors_cal(
            self.grav_a(),
            hb.grav,
            self.hip_angle(),
            self.arm_a.current(),
            hb.arm_pwm,
            &self.cal,
        )?;
        // the arm switches are pushed exactly in the matched (contracted) states
        let contracted = STATES[s as usize].kind() == StateKind::Matched;
        (self.raw.arm_switch == contracted && hb.arm_switch() == contracted).then_some(s)
    }

    fn grav_a(&self) -> [i16; 3] {
        [
            to_i16(self.f.grav[0].value()),
            to_i16(self.f.grav[1].value()),
            to_i16(self.f.grav[2].value()),
        ]
    }

    fn finish_fail(&mut self, f: ActionFailure, out: &mut TickOut) {
        out.report(ActionReport::Failed(f));
        self.end_run_hold();
    }

    fn step_run(&mut self, now: u64, out: &mut TickOut) {
        // bounded: at most one segment completes per tick, plus the step bookkeeping
        let Some(run) = self.run.as_ref() else { return };
        if run.steps == 0 {
            // reconfiguration to the current state
            if let Action::Reconfigure { to, .. } = run.action {
                out.event(DomainEvent::StateReached { state: to });
            }
            out.report(ActionReport::Completed);
            self.run = None;
            self.cmd_complete = true;
            return;
        }
        let seg = run.segs.get(run.seg).copied();
        let Some(seg) = seg else {
            // empty step (cannot happen for valid actions): count it done
            self.step_done(now, out);
            return;
        };
        let motion_step = !matches!(seg, Seg::Bolt { .. });
        let step_elapsed = now.saturating_sub(run.step_t0);
        if motion_step && step_elapsed > self.tun.get_u32(tid::PRIMITIVE_TIMEOUT_MS) as u64 {
            let elapsed_ms = step_elapsed.min(u32::MAX as u64) as u32;
            self.finish_fail(ActionFailure::Timeout { elapsed_ms }, out);
            return;
        }
        if !run.seg_started {
            self.seg_begin(seg, now);
            if let Some(r) = self.run.as_mut() {
                r.seg_started = true;
                r.seg_t0 = now;
            }
        }
        match self.seg_poll(seg, now, out) {
            SegResult::Running => {}
            SegResult::Fail(f) => self.finish_fail(f, out),
            SegResult::Done => {
                let Some(r) = self.run.as_mut() else { return };
                r.seg += 1;
                r.seg_started = false;
                if r.seg >= r.segs.len() {
                    self.step_done(now, out);
                }
            }
        }
    }

    fn step_done(&mut self, now: u64, out: &mut TickOut) {
        let Some(r) = self.run.as_mut() else { return };
        let k = r.done_steps as usize;
        r.done_steps += 1;
        r.step_t0 = now;
        if let Action::Reconfigure { .. } = r.action {
            if let (Some(&p), Some(&s)) = (r.plan.get(k), r.path.get(k + 1)) {
                out.event(DomainEvent::PrimitiveDone { primitive: p, state: s });
            }
        }
        let n = r.done_steps;
        out.report(ActionReport::Step { n });
        if r.done_steps >= r.steps {
            if let Action::Reconfigure { to, .. } = r.action {
                out.event(DomainEvent::StateReached { state: to });
            }
            out.report(ActionReport::Completed);
            self.run = None;
            self.cmd_complete = true;
            self.active_primitive = 0;
        } else {
            self.build_step();
        }
    }

    fn seg_begin(&mut self, seg: Seg, now: u64) {
        match seg {
            Seg::Grip { side, pwm } => {
                if side != Some(Side::B) {
                    self.grip_a.set_target(pwm[0]);
                }
                if side != Some(Side::A) {
                    self.link.send(ModuleCmd::GripTarget(pwm[1]));
                }
            }
            Seg::Arm { side, pwm } => {
                if side != Some(Side::B) {
                    self.arm_a.set_target(pwm[0]);
                }
                if side != Some(Side::A) {
                    self.link.send(ModuleCmd::ArmTarget(pwm[1]));
                }
            }
            Seg::Hip { cdeg } => self.hip.set_target(cdeg),
            Seg::ArmSwitch { .. } | Seg::Settle { .. } => {}
            Seg::Bolt { side, pair, op } => {
                self.bolter.start(op, pair, now, BolterConfig::from_tunables(&self.tun));
                self.bolt_side = side as u8;
                self.bolt_pair = pair;
                self.bolt_attempt = 1;
            }
        }
    }

    fn b_at(&self, f: impl Fn(&crate::ablink::Heartbeat) -> bool) -> bool {
        self.link.heartbeat().is_some_and(f)
    }

    fn seg_poll(&mut self, seg: Seg, now: u64, out: &mut TickOut) -> SegResult {
        let el = now.saturating_sub(self.run.as_ref().map(|r| r.seg_t0).unwrap_or(now));
        match seg {
            Seg::Grip { side, pwm } => {
                let a = side == Some(Side::B) || self.grip_a.done();
                let b = side == Some(Side::A)
                    || (self.link.idle() && self.b_at(|h| h.grip_target == pwm[1] && h.grip_pwm == pwm[1]));
                if a && b {
                    SegResult::Done
                } else {
                    SegResult::Running
                }
            }
            Seg::Arm { side, pwm } => {
                let a = side == Some(Side::B) || self.arm_a.done();
                let b = side == Some(Side::A)
                    || (self.link.idle() && self.b_at(|h| h.arm_target == pwm[1] && h.arm_pwm == pwm[1]));
                if a && b {
                    SegResult::Done
                } else {
                    SegResult::Running
                }
            }
            Seg::Hip { .. } => {
                if self.hip.done() {
                    SegResult::Done
                } else {
                    SegResult::Running
                }
            }
            Seg::ArmSwitch { side } => {
                let a = side == Some(Side::B) || self.raw.arm_switch;
                let b = side == Some(Side::A) || self.b_at(|h| h.arm_switch());
                if a && b {
                    return SegResult::Done;
                }
                if el > self.tun.get_u32(tid::ARM_SWITCH_WAIT_MS) as u64 {
                    let bad = if !a { Side::A } else { Side::B };
                    out.event(DomainEvent::ArmNotContracted { side: bad });
                    return SegResult::Fail(ActionFailure::AbortedByFault {
                        event: eid::ARM_NOT_CONTRACTED,
                    });
                }
                SegResult::Running
            }
            Seg::Settle { expect } => {
                if self.computed == Some(expect) {
                    return SegResult::Done;
                }
                if el > STATE_SETTLE_TIMEOUT_MS as u64 {
                    let computed = self.computed.unwrap_or(STATE_UNKNOWN);
                    out.event(DomainEvent::StateMismatch {
                        expected: expect,
                        computed,
                    });
                    return SegResult::Fail(ActionFailure::StateMismatch {
                        expected: expect,
                        computed,
                    });
                }
                SegResult::Running
            }
            Seg::Bolt { side, pair, op } => {
                let i_a = to_u16(self.f.i_bo.value());
                let i_b = self.link.heartbeat().map(|h| h.i_bo);
                let ev = self.bolter.tick(now, i_a, i_b);
                self.bolt_attempt = self.bolter.attempt();
                match ev {
                    None => SegResult::Running,
                    Some(BolterEvent::AttemptFailed { attempt, .. }) => {
                        out.event(DomainEvent::BoltAttemptFailed { side, pair, attempt });
                        SegResult::Running
                    }
                    Some(BolterEvent::Succeeded { attempts }) => {
                        let e = match op {
                            BoltOp::Bolt => DomainEvent::BoltPairDone { side, pair, attempts },
                            BoltOp::Unbolt => DomainEvent::UnboltPairDone { side, pair, attempts },
                        };
                        out.event(e);
                        self.bolt_pair = 0;
                        SegResult::Done
                    }
                    Some(BolterEvent::Failed { attempts }) => {
                        let (e, f) = match op {
                            BoltOp::Bolt => (
                                DomainEvent::BoltFailure { side, pair, attempts },
                                ActionFailure::BoltFailed { side, pair, attempts },
                            ),
                            BoltOp::Unbolt => (
                                DomainEvent::UnboltFailure { side, pair, attempts },
                                ActionFailure::UnboltFailed { side, pair, attempts },
                            ),
                        };
                        out.event(e);
                        SegResult::Fail(f)
                    }
                }
            }
        }
    }

    // ---------------------------------------------------------------- parameters

    /// Raw value of a MIB parameter the domain supplies ([`Source::BoardA`] or
    /// [`Source::BoardB`]); `None` when it has no valid value, or is not the domain's.
    pub fn param(&self, id: u16) -> Option<i64> {
        match mib::params::source(id) {
            Some(Source::BoardA) => self.board_a_param(id),
            Some(Source::BoardB) => self.board_b_param(id),
            _ => Err(NotSupplied(id)),
        }
        .ok()
        .flatten()
    }

    /// The parameters the MIB names board A's robot logic the source of.
    pub fn board_a_param(&self, id: u16) -> Supplied {
        let b = |v: bool| v as i64;
        let ga = self.grav_a();
        Ok(Some(match id {
            pid::CONFIG_STATE => self.computed.unwrap_or(STATE_UNKNOWN) as i64,
            pid::TARGET_STATE => self.target_state as i64,
            pid::CMD_COMPLETE => b(self.cmd_complete),
            pid::ACTIVE_PRIMITIVE => self.active_primitive as i64,
            pid::BOLT_SIDE => self.bolt_side as i64,
            pid::BOLT_PAIR => {
                if self.bolter.busy() {
                    self.bolt_pair as i64
                } else {
                    0
                }
            }
            pid::BOLT_ATTEMPT => {
                if self.bolter.busy() {
                    self.bolt_attempt as i64
                } else {
                    0
                }
            }
            pid::ARM_A_TARGET => self.arm_a.target() as i64,
            pid::ARM_A_PWM => self.arm_a.current() as i64,
            pid::GRIP_A_TARGET => self.grip_a.target() as i64,
            pid::GRIP_A_PWM => self.grip_a.current() as i64,
            pid::HIP_TARGET => self.hip.target() as i64,
            pid::HIP_ANGLE => self.hip_angle() as i64,
            pid::HIP_DEVIATION => match self.link.heartbeat().and_then(|h| state_from_imus(ga, h.grav)) {
                Some(s) => {
                    let d = self.hip_angle() as i64 - STATES[s as usize].hip_cdeg() as i64;
                    d.clamp(i16::MIN as i64, i16::MAX as i64)
                }
                None => 0,
            },
            pid::V_BAT_A => self.f.v_bat.value() as i64,
            pid::I_BAT => self.f.i_bat.value() as i64,
            pid::V_REG => self.f.v_reg.value() as i64,
            pid::I_LOC_A => self.f.i_loc.value() as i64,
            pid::I_GRIP_A => self.f.i_grip.value() as i64,
            pid::I_BO_A => self.f.i_bo.value() as i64,
            pid::ARM_SW_A => b(self.raw.arm_switch),
            pid::GRAV_A_X => ga[0] as i64,
            pid::GRAV_A_Y => ga[1] as i64,
            pid::GRAV_A_Z => ga[2] as i64,
            pid::B_LINK_OK => b(self.link.link_ok(self.now, B_HEARTBEAT_TIMEOUT_MS as u64)),
            pid::B_HB_AGE_MS => self.link.hb_age_ms(self.now).min(u16::MAX as u64) as i64,
            pid::B_HB_RX => self.link.counters().hb_rx as i64,
            pid::B_FRAME_ERRORS => self.link.counters().frame_errors as i64,
            pid::B_RETRIES => self.link.counters().retries as i64,
            pid::B_ACK_MISSED => self.link.counters().ack_missed as i64,
            pid::CAL_GRIP_A_CLOSED => self.cal.side[0].grip_closed_us as i64,
            pid::CAL_GRIP_A_OPEN => self.cal.side[0].grip_open_us as i64,
            pid::CAL_GRIP_B_CLOSED => self.cal.side[1].grip_closed_us as i64,
            pid::CAL_GRIP_B_OPEN => self.cal.side[1].grip_open_us as i64,
            pid::CAL_ENC_ZERO => self.cal.encoder_zero as i64,
            pid::CAL_FROM_DESCRIPTORS => self.cal.from_descriptors as i64,
            _ => return Err(NotSupplied(id)),
        }))
    }

    /// The parameters the MIB names board B's heartbeat the source of. Side B's readings
    /// only exist once board B has been heard: until then they have no value (rather than
    /// a misleading 0 that would trip a monitor).
    pub fn board_b_param(&self, id: u16) -> Supplied {
        let hb = self.link.heartbeat();
        let v = |f: fn(&crate::ablink::Heartbeat) -> i64| Ok(hb.map(f));
        match id {
            pid::ARM_B_TARGET => v(|h| h.arm_target as i64),
            pid::ARM_B_PWM => v(|h| h.arm_pwm as i64),
            pid::GRIP_B_TARGET => v(|h| h.grip_target as i64),
            pid::GRIP_B_PWM => v(|h| h.grip_pwm as i64),
            pid::V_BAT_B => v(|h| h.v_bat as i64),
            pid::I_LOC_B => v(|h| h.i_loc as i64),
            pid::I_GRIP_B => v(|h| h.i_grip as i64),
            pid::I_BO_B => v(|h| h.i_bo as i64),
            pid::ARM_SW_B => v(|h| h.arm_switch() as i64),
            pid::GRAV_B_X => v(|h| h.grav[0] as i64),
            pid::GRAV_B_Y => v(|h| h.grav[1] as i64),
            pid::GRAV_B_Z => v(|h| h.grav[2] as i64),
            pid::BOLTER_B_STATE => v(|h| h.bolter_state() as i64),
            _ => Err(NotSupplied(id)),
        }
    }

    /// Asks board B to send its descriptor table again (module discovery).
    pub fn request_board_b_modules(&mut self) {
        self.link.send(ModuleCmd::SendModules);
    }
    /// Board B's half of module discovery, once its whole descriptor table arrived over
    /// the link (docs/modules.md).
    pub fn board_b_modules(&self) -> Option<(&[u8], crate::discovery::BoardProbes)> {
        self.link.board_b_modules()
    }
    /// Counters of the A–B link.
    pub fn link_counters(&self) -> crate::ablink::LinkCounters {
        *self.link.counters()
    }
    /// The hip speed command of the last tick (cdeg/s).
    pub fn hip_command(&self) -> i16 {
        self.hip_cmd
    }
}

/// Module moves of primitive `prim` from state `from` to `to`: release the moving
/// side's gripper; move the arms to the target state's length and the hip to its angle
/// (arms first when entering a turn, hip first when leaving one); wait for the arm
/// switches after contracting; grip; wait until the sensors confirm the new state.
fn primitive_segments(from: u8, to: u8, prim: u8, cal: &RobotCal) -> Vec<Seg, MAX_SEGS> {
    let mut v = Vec::new();
    let (Some(p), Some(f), Some(t)) = (primitive(prim), STATES.get(from as usize), STATES.get(to as usize)) else {
        return v;
    };
    let mover = Some(p.moving);
    let mut push = |s: Seg| {
        let _ = v.push(s);
    };
    push(Seg::Grip {
        side: mover,
        pwm: cal.side.map(|c| c.grip_open_us),
    });
    let arms = Seg::Arm {
        side: None,
        pwm: cal.side.map(|c| c.arm_us(t.kind())),
    };
    let hip = Seg::Hip { cdeg: t.hip_cdeg() };
    let rotates = matches!(p.motion, Motion::Rotate(_));
    if rotates && t.kind() == StateKind::Turn {
        push(arms);
        push(hip);
    } else if rotates {
        push(hip);
        push(arms);
    } else {
        push(arms);
    }
    if f.kind() != StateKind::Matched && t.kind() == StateKind::Matched {
        push(Seg::ArmSwitch { side: None });
    }
    push(Seg::Grip {
        side: mover,
        pwm: cal.side.map(|c| c.grip_closed_us),
    });
    push(Seg::Settle { expect: to });
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: MMIC-MOT-03
    #[test]
    fn primitives_are_release_move_grip_and_confirm() {
        // matched Xneg -> "Xpos Xneg": A releases, arms extend, A grips
        let s = primitive_segments(0, 4, 1, &RobotCal::COMPILED);
        assert_eq!(
            s.as_slice(),
            &[
                Seg::Grip {
                    side: Some(Side::A),
                    pwm: [servo::GRIP_OPEN_US; 2]
                },
                Seg::Arm {
                    side: None,
                    pwm: [servo::ARM_EXTENDED_US; 2]
                },
                Seg::Grip {
                    side: Some(Side::A),
                    pwm: [servo::GRIP_CLOSED_US; 2]
                },
                Seg::Settle { expect: 4 },
            ]
        );
        // stretch -> matched contracts and checks the switches
        let s = primitive_segments(4, 1, 2, &RobotCal::COMPILED);
        assert!(s.contains(&Seg::ArmSwitch { side: None }));
        assert_eq!(
            s[0],
            Seg::Grip {
                side: Some(Side::B),
                pwm: [servo::GRIP_OPEN_US; 2]
            }
        );
        // into a turn: arms first, then hip; out of a turn: hip first
        let into = primitive_segments(0, 11, 5, &RobotCal::COMPILED);
        let pos_arm = into.iter().position(|s| matches!(s, Seg::Arm { .. })).unwrap();
        let pos_hip = into.iter().position(|s| matches!(s, Seg::Hip { .. })).unwrap();
        assert!(pos_arm < pos_hip);
        let out = primitive_segments(11, 0, 6, &RobotCal::COMPILED);
        let pos_arm = out.iter().position(|s| matches!(s, Seg::Arm { .. })).unwrap();
        let pos_hip = out.iter().position(|s| matches!(s, Seg::Hip { .. })).unwrap();
        assert!(pos_hip < pos_arm);
        // every primitive of the map fits
        for f in 0..NUM_STATES as u8 {
            for t in 0..NUM_STATES as u8 {
                let p = mib::robot::RECONFIG_MAP[f as usize][t as usize];
                if p != 0 {
                    let s = primitive_segments(f, t, p, &RobotCal::COMPILED);
                    assert!(s.len() >= 4 && s.len() <= MAX_SEGS);
                    assert_eq!(*s.last().unwrap(), Seg::Settle { expect: t });
                }
            }
        }
    }

    // verifies: MOD-CAL-03
    #[test]
    fn primitives_and_home_use_each_sides_calibration() {
        let mut cal = RobotCal::COMPILED;
        cal.side[1].grip_closed_us = 1150;
        cal.side[1].grip_open_us = 1850;
        cal.side[0].arm_extended_us = 1980;
        cal.hip_home_cdeg = 120;
        let s = primitive_segments(0, 4, 1, &cal);
        assert_eq!(
            &s[..3],
            &[
                Seg::Grip {
                    side: Some(Side::A),
                    pwm: [1900, 1850]
                },
                Seg::Arm {
                    side: None,
                    pwm: [1980, 2000]
                },
                Seg::Grip {
                    side: Some(Side::A),
                    pwm: [1100, 1150]
                },
            ]
        );
        // B's gripper target over the link is B's own closed width.
        let mut c = Controller::new();
        c.set_calibration(cal);
        c.set_module_modes(ModuleModes::all(ON));
        c.start(Action::Home, 0).unwrap();
        let segs = c.run.as_ref().unwrap().segs.clone();
        assert_eq!(segs[0], Seg::Hip { cdeg: 120 });
        assert!(segs.contains(&Seg::Grip {
            side: None,
            pwm: [1100, 1150]
        }));
        // Before any move, arm A and gripper A are assumed at their home widths.
        let mut home = RobotCal::COMPILED;
        home.side[0].arm_home_us = 1010;
        home.side[0].grip_home_us = 1120;
        let mut fresh = Controller::new();
        fresh.set_calibration(home);
        assert_eq!(fresh.param(pid::ARM_A_PWM), Some(1010));
        assert_eq!(fresh.param(pid::GRIP_A_PWM), Some(1120));
        // The bolter thresholds became the tunables (the ground can still change them).
        cal.bolt_push_ma = 1000;
        cal.bolt_lock_ma = 9999;
        c.set_calibration(cal);
        assert_eq!(c.tunable(tid::BOLT_PUSH_THRESHOLD_MA), Some(1000));
        assert_eq!(
            c.tunable(tid::BOLT_LOCK_THRESHOLD_MA),
            Some(2450),
            "clamped to the tunable's range"
        );
    }

    // verifies: MMIC-CMD-08, MMIC-CMD-07
    #[test]
    fn controller_refuses_when_busy_unpowered_mismatched_or_unreachable() {
        let mut c = Controller::new();
        assert_eq!(c.start(Action::Home, 0), Err(StartError::NotPowered));
        c.set_module_modes(ModuleModes::all(ON));
        // no heartbeat yet: the state is unknown
        assert_eq!(
            c.start(Action::Reconfigure { from: 0, to: 1 }, 0),
            Err(StartError::InitialStateMismatch {
                believed: 0,
                computed: 255
            })
        );
        assert_eq!(
            c.start(Action::Reconfigure { from: 0, to: 99 }, 0),
            Err(StartError::Unreachable { from: 0, to: 99 })
        );
        assert_eq!(
            c.start(
                Action::BoltFace {
                    side: Side::A,
                    pairs: 0
                },
                0
            ),
            Err(StartError::InvalidArgument { index: 1, value: 0 })
        );
        assert_eq!(
            c.start(Action::BoltPair { side: Side::A, pair: 5 }, 0),
            Err(StartError::InvalidArgument { index: 1, value: 5 })
        );
        assert_eq!(c.start(Action::Home, 0), Ok(1));
        assert!(c.busy());
        assert_eq!(c.start(Action::Home, 0), Err(StartError::Busy));
        c.abort();
        assert!(!c.busy());
        // safed-like HOLD: arm and hip moves allowed, gripper and reconfiguration not
        c.set_module_modes(ModuleModes::all(HOLD));
        assert_eq!(
            c.start(
                Action::MoveGripper {
                    side: Side::A,
                    pwm: 1500
                },
                0
            ),
            Err(StartError::NotPowered)
        );
        assert_eq!(
            c.start(
                Action::MoveArm {
                    side: Side::A,
                    pwm: 1500
                },
                0
            ),
            Ok(1)
        );
    }

    // verifies: PUS-20-01
    #[test]
    fn controller_answers_every_domain_parameter() {
        let c = Controller::new();
        for p in mib::params::PARAMS {
            let (a, b) = (c.board_a_param(p.id), c.board_b_param(p.id));
            match mib::params::source(p.id) {
                Some(Source::BoardA) => {
                    assert!(matches!(a, Ok(Some(_))), "{}", p.name);
                    assert_eq!(b, Err(NotSupplied(p.id)), "{}", p.name);
                }
                Some(Source::BoardB) => {
                    // Before board B's first heartbeat its readings have no value.
                    assert_eq!(b, Ok(None), "{}", p.name);
                    assert_eq!(a, Err(NotSupplied(p.id)), "{}", p.name);
                }
                _ => {
                    assert_eq!((a, b), (Err(NotSupplied(p.id)), Err(NotSupplied(p.id))), "{}", p.name);
                    assert_eq!(c.param(p.id), None, "{}", p.name);
                }
            }
        }
        assert_eq!(c.param(pid::MODE), None);
        assert_eq!(c.param(pid::CONFIG_STATE), Some(255));
    }

    // verifies: MMIC-MODE-04
    #[test]
    fn module_modes_follow_the_root_mode_and_actions_name_their_function() {
        use mib::modes::robot_mode;
        let safed = ModuleModes::for_root(robot_mode::SAFED);
        assert_eq!((safed.arm_a, safed.hip, safed.bolter_b), (HOLD, HOLD, OFF));
        assert_eq!(ModuleModes::for_root(robot_mode::OPERATIONAL), ModuleModes::all(ON));
        assert_eq!(ModuleModes::for_root(robot_mode::STANDBY), ModuleModes::all(OFF));
        assert_eq!(Action::Home.function_id(), mib::tc::function::HOME);
        assert_eq!(
            Action::UnboltPair { side: Side::B, pair: 1 }.function_id(),
            mib::tc::function::UNBOLT_PAIR
        );
    }

    /// Controller and a real board B on a perfect serial line, with fixed sensors of a
    /// robot at rest in matched Xneg.
    struct Loop {
        c: Controller,
        b: crate::board_b::BoardB,
        t: u64,
        out: TickOut,
        bout: crate::board_b::BoardBOut,
        b_to_a: std::vec::Vec<u8>,
        sa: SensorsA,
        sb: crate::types::SensorsB,
    }

    impl Loop {
        fn new() -> Self {
            let g = crate::imu::gravity_in_board_frame(mib::robot::Face::Xneg);
            Loop {
                c: Controller::new(),
                b: crate::board_b::BoardB::new(),
                t: 0,
                out: TickOut::new(),
                bout: Default::default(),
                b_to_a: std::vec::Vec::new(),
                sa: SensorsA {
                    v_bat: 3400,
                    grav: g,
                    arm_switch: true,
                    ..Default::default()
                },
                sb: crate::types::SensorsB {
                    v_bat: 3400,
                    grav: g,
                    arm_switch: true,
                    ..Default::default()
                },
            }
        }
        fn step(&mut self) {
            self.c.tick(self.t, &self.sa, &self.b_to_a, &mut self.out);
            self.b.tick(self.t + 3, &self.sb, &self.out.link_tx, &mut self.bout);
            self.b_to_a = self.bout.tx.to_vec();
            self.t += 10;
        }
        fn run(&mut self, ms: u64) {
            for _ in 0..ms / 10 {
                self.step();
            }
        }
    }

    // verifies: MMIC-MODE-01, MMIC-MODE-03
    #[test]
    fn module_modes_off_unpowers_everything_and_on_powers() {
        let mut l = Loop::new();
        l.run(100);
        assert!(!l.out.actuators.regulator_on);
        assert_eq!(l.out.actuators.side.arm_pwm, None);
        assert_eq!(l.out.actuators.hip_speed, None);
        l.c.set_module_modes(ModuleModes::all(ON));
        l.run(600);
        let a = l.out.actuators;
        assert!(a.regulator_on);
        assert_eq!(a.side.arm_pwm, Some(servo::ARM_CONTRACTED_US));
        assert_eq!(a.side.grip_pwm, Some(servo::GRIP_CLOSED_US));
        assert!(a.hip_speed.is_some());
        // B got its modes over the link and reports them
        assert_eq!(l.c.link.heartbeat().unwrap().modes, 0b01_01_01);
        assert_eq!(l.bout.side.arm_pwm, Some(servo::ARM_CONTRACTED_US));
        assert_eq!(l.c.computed_state(), Some(0));
        l.c.set_module_modes(ModuleModes::all(OFF));
        l.run(200);
        assert!(!l.out.actuators.regulator_on);
        assert_eq!(l.bout.side.arm_pwm, None);
    }

    // verifies: MMIC-CTL-06, MMIC-AB-06
    #[test]
    fn hold_mode_aborts_running_motion_and_keeps_position() {
        let mut l = Loop::new();
        l.c.set_module_modes(ModuleModes::all(ON));
        l.run(600);
        l.c.start(
            Action::MoveGripper {
                side: Side::A,
                pwm: servo::GRIP_OPEN_US,
            },
            l.t,
        )
        .unwrap();
        l.run(500);
        let mid = l.out.actuators.side.grip_pwm.unwrap();
        assert!(mid > servo::GRIP_CLOSED_US && mid < servo::GRIP_OPEN_US);
        l.c.set_module_modes(ModuleModes::all(HOLD));
        assert!(!l.c.busy(), "gripper action needs ON");
        l.run(500);
        assert_eq!(l.out.actuators.side.grip_pwm, Some(mid), "held where it was");
        assert_eq!(l.c.link.heartbeat().unwrap().modes, 0b10_10_10);
    }

    /// Opens gripper A and waits until the move completed.
    fn open_gripper_a(l: &mut Loop) {
        l.c.start(
            Action::MoveGripper {
                side: Side::A,
                pwm: servo::GRIP_OPEN_US,
            },
            l.t,
        )
        .unwrap();
        for _ in 0..500 {
            l.run(10);
            if !l.c.busy() {
                return;
            }
        }
        panic!("gripper A did not open");
    }

    // verifies: MMIC-MOT-07
    #[test]
    fn turning_the_hip_while_both_grippers_hold_is_refused_at_start() {
        let mut l = Loop::new();
        l.c.set_module_modes(ModuleModes::all(ON));
        l.run(600);
        let r = l.c.start(Action::RotateHip { cdeg: 4000 }, l.t);
        assert!(matches!(r, Err(StartError::BothSidesGripped { .. })), "{r:?}");
        assert!(!l.c.busy(), "nothing started");
        // Turning to where the hip already is moves nothing: allowed.
        let here = l.c.hip_angle();
        assert!(l.c.start(Action::RotateHip { cdeg: here }, l.t).is_ok());
        l.c.abort();
        // With one side open the hip turns.
        open_gripper_a(&mut l);
        assert!(l.c.start(Action::RotateHip { cdeg: 4000 }, l.t).is_ok());
    }

    // verifies: MMIC-CTL-06, PUS-200-01
    #[test]
    fn entering_hold_during_a_hip_rotation_ends_it_and_same_modes_do_not() {
        let mut l = Loop::new();
        l.c.set_module_modes(ModuleModes::all(ON));
        l.run(600);
        open_gripper_a(&mut l);
        l.c.start(Action::RotateHip { cdeg: 4000 }, l.t).unwrap();
        l.run(100);
        l.c.set_module_modes(ModuleModes::all(ON));
        assert!(l.c.busy(), "same modes again: still running");
        l.c.set_module_modes(ModuleModes::all(HOLD));
        assert!(!l.c.busy());
        l.run(100);
        assert!(l.out.reports.is_empty());
    }

    // verifies: MMIC-CTL-06
    #[test]
    fn abort_holds_arm_a_and_board_b_where_they_are() {
        let mut l = Loop::new();
        l.c.set_module_modes(ModuleModes::all(ON));
        l.run(600);
        l.c.start(
            Action::MoveArm {
                side: Side::B,
                pwm: 2000,
            },
            l.t,
        )
        .unwrap();
        l.run(400);
        l.c.abort();
        assert!(!l.c.busy());
        l.run(200);
        let held = l.bout.side.arm_pwm.unwrap();
        assert!(held > 1000 && held < 2000, "{held}");
        l.run(500);
        assert_eq!(l.bout.side.arm_pwm, Some(held));
        assert!(l.out.reports.is_empty());
    }

    // verifies: MMIC-CMD-04
    #[test]
    fn move_arm_completes_when_board_b_reports_the_target() {
        let mut l = Loop::new();
        l.c.set_module_modes(ModuleModes::all(ON));
        l.run(600);
        assert_eq!(
            l.c.start(
                Action::MoveArm {
                    side: Side::B,
                    pwm: 1500
                },
                l.t
            ),
            Ok(1)
        );
        let mut reports = std::vec::Vec::new();
        for _ in 0..300 {
            l.step();
            reports.extend(l.out.reports.iter().copied());
        }
        assert_eq!(reports, [ActionReport::Step { n: 1 }, ActionReport::Completed]);
        assert_eq!(l.c.param(pid::ARM_B_PWM), Some(1500));
        assert_eq!(l.c.param(pid::ARM_B_TARGET), Some(1500));
    }

    // verifies: MMIC-AB-07
    #[test]
    fn board_b_modes_are_resent_after_b_restarts() {
        let mut l = Loop::new();
        l.c.set_module_modes(ModuleModes::all(ON));
        l.run(600);
        l.b = crate::board_b::BoardB::new(); // B reboots: modules OFF
        l.run(1000);
        assert_eq!(l.c.link.heartbeat().unwrap().modes, 0b01_01_01);
        assert_eq!(l.bout.side.arm_pwm, Some(servo::ARM_CONTRACTED_US));
    }

    // verifies: PUS-20-01
    #[test]
    fn tunables_reach_the_controller_and_bad_values_are_refused() {
        let mut c = Controller::new();
        assert_eq!(c.tunable(tid::BOLT_PUSH_THRESHOLD_MA), Some(1200));
        c.set_tunable(tid::BOLT_PUSH_THRESHOLD_MA, 1000).unwrap();
        assert_eq!(c.tunable(tid::BOLT_PUSH_THRESHOLD_MA), Some(1000));
        assert!(c.set_tunable(tid::BOLT_PUSH_THRESHOLD_MA, 99_999).is_err());
        assert!(c.set_tunable(0xFFFF, 1).is_err());
        c.set_tunable(tid::HIP_KP_POS, 0).unwrap();
        assert_eq!(c.hip.clone().tick(-200, 10), 0, "no gain, no position output");
    }

    proptest::proptest! {
        // verifies: MMIC-AB-04, DD-ROBUST-01
        #[test]
        fn controller_never_panics_on_garbage_link_bytes(
            chunks in proptest::collection::vec(proptest::collection::vec(proptest::prelude::any::<u8>(), 0..80), 1..20)
        ) {
            let mut c = Controller::new();
            c.set_module_modes(ModuleModes::all(ON));
            let mut out = TickOut::new();
            let mut t = 0;
            for ch in &chunks {
                c.tick(t, &SensorsA::default(), ch, &mut out);
                t += 10;
            }
            let mut b = crate::board_b::BoardB::new();
            let mut bout = crate::board_b::BoardBOut::default();
            for ch in &chunks {
                b.tick(t, &crate::types::SensorsB::default(), ch, &mut bout);
                t += 10;
            }
        }
    }
}
