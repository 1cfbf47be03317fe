//! Mission-specific service 210: the module set (docs/modules.md). Discovery runs once at boot
//! on what the platform read (board A's descriptor table and probes, board B's half from
//! the A–B link); the result decides whether OPERATIONAL may be entered, which PUS 8
//! functions can run (MODULE_ABSENT), what HK structure MODULES says and what the module
//! report TM[210,3] carries. TC[210,1] REPORT_MODULES sends the report again; TC[210,2]
//! ACCEPT_CONFIG(hash) records the ground's acceptance of the current configuration.
//!
//! The configuration the ground last accepted is platform state (flash on the boards, a
//! file on the host): the platform hands it in with [`Obsw::set_accepted_config`] before
//! discovery and persists it when [`Obsw::take_accepted_update`] returns one, in the
//! fixed layout of [`AcceptedConfig::to_bytes`] (checked by [`AcceptedConfig::from_bytes`]).
//! A platform whose store gave nothing usable says why with [`Obsw::config_state_lost`].
//!
//! Discovery also sets the calibration the robot runs with
//! (`mmic_domain::calib::RobotCal::from_set`): the controller's servo set points, hip home,
//! encoder zero and bolter thresholds, and the high limits of the current monitors.

use mib::modes::robot_mode;
use mib::modules::descriptor::MAX_TABLE_LEN;
use mib::modules::report::{MAX_REPORT_LEN, NO_SLOT};
use mib::modules::NUM_SLOTS;
use mib::params::{pid, NotSupplied, Source, Supplied};
use mib::tc::service;
use mib_wire::tm;

use mmic_domain::calib::RobotCal;
use mmic_domain::controller::Action;
use mmic_domain::discovery::{
    self, accept, compare, discover, missing_for, operational_allowed, Blocked, BoardInput, BoardProbes, Discovery,
    ModuleIdentity, Replacement,
};

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::obsw::Obsw;
use crate::request::unknown;
use crate::robot::Robot;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};

/// A configuration the ground accepted: its hash and the module identities by slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AcceptedConfig {
    pub hash: u32,
    pub ids: [Option<ModuleIdentity>; NUM_SLOTS],
}

impl AcceptedConfig {
    /// The configuration of a module set (what accepting it records).
    pub fn of(set: &mib::modules::ModuleSet) -> Self {
        AcceptedConfig {
            hash: mib::modules::config::config_hash(set),
            ids: core::array::from_fn(|i| set[i].as_ref().map(ModuleIdentity::from)),
        }
    }

    /// Slots the accepted configuration holds (bit = slot).
    pub fn present(&self) -> u16 {
        self.ids
            .iter()
            .enumerate()
            .filter(|(_, id)| id.is_some())
            .fold(0, |m, (i, _)| m | 1 << i)
    }

    /// The persisted form: [`STATE_MAGIC`], hash u32, present slots u16, per slot
    /// (type u8, variant u8, revision u8, serial u32; zeros when absent), CRC-32/ISO-HDLC
    /// over everything before it. Big-endian, [`STATE_LEN`] bytes.
    pub fn to_bytes(&self) -> [u8; STATE_LEN] {
        let mut b = [0u8; STATE_LEN];
        b[..8].copy_from_slice(&STATE_MAGIC);
        b[8..12].copy_from_slice(&self.hash.to_be_bytes());
        b[12..14].copy_from_slice(&self.present().to_be_bytes());
        for (i, id) in self.ids.iter().enumerate() {
            let at = STATE_HEADER_LEN + i * STATE_ENTRY_LEN;
            if let Some(id) = id {
                b[at] = id.ty.code();
                b[at + 1] = id.variant;
                b[at + 2] = id.revision;
                b[at + 3..at + 7].copy_from_slice(&id.serial.to_be_bytes());
            }
        }
        let crc = mib::modules::config::HASH_CRC.checksum(&b[..STATE_LEN - 4]);
        b[STATE_LEN - 4..].copy_from_slice(&crc.to_be_bytes());
        b
    }

    /// Reads [`AcceptedConfig::to_bytes`]'s layout: length, magic, CRC, then the present
    /// mask against the entries (an absent slot is all zeros, a present one has a type).
    pub fn from_bytes(b: &[u8]) -> Result<AcceptedConfig, StateError> {
        if b.len() != STATE_LEN {
            return Err(StateError::Length(b.len()));
        }
        if b[..8] != STATE_MAGIC {
            return Err(StateError::Magic);
        }
        let stored = u32::from_be_bytes([b[STATE_LEN - 4], b[STATE_LEN - 3], b[STATE_LEN - 2], b[STATE_LEN - 1]]);
        let computed = mib::modules::config::HASH_CRC.checksum(&b[..STATE_LEN - 4]);
        if stored != computed {
            return Err(StateError::Crc { stored, computed });
        }
        let hash = u32::from_be_bytes([b[8], b[9], b[10], b[11]]);
        let present = u16::from_be_bytes([b[12], b[13]]);
        let mut ids = [None; NUM_SLOTS];
        for (i, id) in ids.iter_mut().enumerate() {
            let e = &b[STATE_HEADER_LEN + i * STATE_ENTRY_LEN..STATE_HEADER_LEN + (i + 1) * STATE_ENTRY_LEN];
            let listed = present & (1 << i) != 0;
            match (listed, e[0]) {
                (false, _) if e.iter().all(|&x| x == 0) => {}
                (true, ty) if ty != 0 => {
                    *id = Some(ModuleIdentity {
                        ty: mib::modules::ModuleType::from_code(ty),
                        variant: e[1],
                        revision: e[2],
                        serial: u32::from_be_bytes([e[3], e[4], e[5], e[6]]),
                    })
                }
                _ => return Err(StateError::Entry(i as u8)),
            }
        }
        if present >> NUM_SLOTS != 0 {
            return Err(StateError::Entry(NUM_SLOTS as u8));
        }
        Ok(AcceptedConfig { hash, ids })
    }
}

/// Magic and layout version of the persisted accepted configuration.
pub const STATE_MAGIC: [u8; 8] = *b"MMICCFG1";
const STATE_HEADER_LEN: usize = 8 + 4 + 2;
const STATE_ENTRY_LEN: usize = 7;
/// Length of [`AcceptedConfig::to_bytes`].
pub const STATE_LEN: usize = STATE_HEADER_LEN + NUM_SLOTS * STATE_ENTRY_LEN + 4;

/// Why persisted bytes are not an accepted configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateError {
    Length(usize),
    Magic,
    Crc {
        stored: u32,
        computed: u32,
    },
    /// Slot entry inconsistent with the present mask (`NUM_SLOTS`: mask bits beyond).
    Entry(u8),
}

impl core::fmt::Display for StateError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StateError::Length(n) => write!(f, "{n} bytes, {STATE_LEN} expected"),
            StateError::Magic => write!(f, "not an accepted-configuration state (magic)"),
            StateError::Crc { stored, computed } => {
                write!(f, "CRC {stored:#010x} stored, {computed:#010x} computed")
            }
            StateError::Entry(i) => write!(f, "slot entry {i} disagrees with the present mask"),
        }
    }
}

impl core::error::Error for StateError {}

/// Why the platform's store gave no accepted configuration (event CONFIG_STATE_LOST,
/// `mib::layout::CONFIG_STATE_LOST_NAMES`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateLost {
    /// Nothing stored yet.
    Missing,
    /// The store could not be read.
    Unreadable,
    /// The stored bytes failed [`AcceptedConfig::from_bytes`].
    Corrupt,
    /// An acceptance could not be written (it holds until the next restart only).
    WriteFailed,
}

impl StateLost {
    pub const fn code(self) -> u8 {
        match self {
            StateLost::Missing => 1,
            StateLost::Unreadable => 2,
            StateLost::Corrupt => 3,
            StateLost::WriteFailed => 4,
        }
    }
}

/// `CONFIG_STATUS` values (`mib::layout::CONFIG_STATUS_NAMES`).
pub mod status {
    pub const NOT_DISCOVERED: u8 = 0;
    pub const ACCEPTED: u8 = 1;
    pub const NOT_ACCEPTED: u8 = 2;
    pub const INVALID: u8 = 3;
}

/// Module state of the OBSW.
#[derive(Clone, Debug, Default)]
pub struct Modules {
    /// The boot discovery (`None` until the platform ran it).
    pub discovery: Option<Discovery>,
    /// The configuration the ground last accepted.
    pub accepted: Option<AcceptedConfig>,
    /// The discovery against `accepted`.
    pub replacement: Option<Replacement>,
    /// An acceptance the platform has not persisted yet.
    update: Option<AcceptedConfig>,
    /// Board A's table and probes, waiting for board B's half ([`Obsw::start_discovery`]).
    pending: Option<PendingA>,
}

/// Board A's half of discovery, kept until board B's arrives or the wait times out.
#[derive(Clone, Debug)]
struct PendingA {
    table: heapless::Vec<u8, MAX_TABLE_LEN>,
    probes: BoardProbes,
    since: u64,
    /// Requests for board B's table sent so far.
    requests: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// TC[210,1]
    Report,
    /// TC[210,2]
    Accept(u32),
}

impl Request {
    pub fn parse(tc: &Tc) -> Result<Self, Failure> {
        Ok(match tc.subservice {
            1 => Request::Report,
            2 => Request::Accept(mib_wire::args::AcceptConfig::of(&tc.args).hash),
            _ => return Err(unknown(tc)),
        })
    }
}

/// The mode tree's module nodes and the slot of their module.
const MODULE_NODES: [(u32, u8); 7] = {
    use mib::modes::node;
    use mib::modules::slot;
    [
        (node::ARM_A, slot::ARM_A),
        (node::GRIPPER_A, slot::GRIPPER_A),
        (node::BOLTER_A, slot::BOLTER_A),
        (node::HIP, slot::HIP),
        (node::ARM_B, slot::ARM_B),
        (node::GRIPPER_B, slot::GRIPPER_B),
        (node::BOLTER_B, slot::BOLTER_B),
    ]
};

/// The side argument of an action, for [`missing_for`].
fn side_of(a: &Action) -> Option<u8> {
    match *a {
        Action::BoltFace { side, .. }
        | Action::UnboltFace { side, .. }
        | Action::MoveArm { side, .. }
        | Action::MoveGripper { side, .. }
        | Action::BoltPair { side, .. }
        | Action::UnboltPair { side, .. } => Some(side as u8),
        Action::Reconfigure { .. } | Action::Home | Action::RotateHip { .. } => None,
    }
}

/// A PUS 210 request: the module report, or the ground's acceptance of the set found.
impl Component for Modules {
    const CONTRACT: Contract = Contract::new("modules", Some(service::MODULES), &[Source::Modules]);
    type Request<'a> = Request;
    type Output = ();
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<(), Failure> {
        match r {
            Request::Report => {
                self.report(now, dl, sink);
                Ok(())
            }
            Request::Accept(hash) => {
                let Some(d) = self.discovery.as_ref() else {
                    return Err(Failure::config_hash_stale(hash, 0));
                };
                if let Err(why) = d.outcome {
                    return Err(Failure::config_invalid(why.code(), why.slot().unwrap_or(NO_SLOT)));
                }
                accept(d, hash).map_err(|current| Failure::config_hash_stale(hash, current))?;
                let a = AcceptedConfig::of(&d.set);
                self.accepted = Some(a);
                self.update = Some(a);
                self.replacement = Some(Replacement::Same);
                Ok(())
            }
        }
    }
}

impl Modules {
    /// Why OPERATIONAL is refused by the module set (`None`: allowed, or no discovery
    /// ran on this platform). While discovery waits for board B's half the module set is
    /// not known — nor board B's servo widths, which come with its calibration — so
    /// OPERATIONAL is refused with CONFIG_NOT_ACCEPTED and hash 0 (REV-ANOM-17).
    pub(crate) fn block_operational(&self) -> Option<Failure> {
        if self.pending.is_some() {
            return Some(Failure::config_not_accepted(mib::modules::config::HASH_NOT_DISCOVERED));
        }
        let d = self.discovery.as_ref()?;
        let r = self.replacement.unwrap_or(Replacement::NoneAccepted);
        match operational_allowed(d, r) {
            Ok(_) => None,
            Err(Blocked::Invalid(why)) => Some(Failure::config_invalid(why.code(), why.slot().unwrap_or(NO_SLOT))),
            Err(Blocked::NotAccepted { hash }) => Some(Failure::config_not_accepted(hash)),
        }
    }

    /// True when discovery found the module of `slot` absent.
    pub fn absent(&self, slot: u8) -> bool {
        self.discovery.as_ref().is_some_and(|d| !d.present.contains(slot))
    }

    /// MODULE_ABSENT for an action that needs a module this robot does not have.
    pub(crate) fn absent_for(&self, a: &Action) -> Option<Failure> {
        let d = self.discovery.as_ref()?;
        missing_for(a.function_id(), side_of(a), d.present).map(Failure::module_absent)
    }

    /// Module power for the mode tree's modules: an absent module is never powered.
    pub(crate) fn present_or_off(&self, slot: u8, mode: u32) -> u32 {
        if self.absent(slot) {
            mib::modes::module_mode::OFF
        } else {
            mode
        }
    }

    /// Sends TM[210,3] MODULE_REPORT for the boot discovery (an empty set before it).
    pub(crate) fn report<S: TmStore>(&self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let r = self.replacement.unwrap_or(Replacement::NoneAccepted);
        let body = match self.discovery.as_ref() {
            Some(d) => discovery::report(d, r),
            None => mib::modules::report::ModuleReport {
                hash: mib::modules::config::config_hash(&[None; NUM_SLOTS]),
                config: 0,
                reason: 0,
                reason_slot: NO_SLOT,
                replacement: 0,
                set: [None; NUM_SLOTS],
            },
        };
        let mut buf = [0u8; MAX_REPORT_LEN];
        // The buffer holds the largest report; the MIB's description of TM[210,3] parses
        // what `ModuleReport::emit` writes (unit test below).
        let Ok(n) = body.emit(&mut buf) else { return };
        let Ok(w) = tm::ModuleReport::parse(&buf[..n]) else {
            return;
        };
        dl.emit_tm(now, &w, sink);
    }

    /// Takes in a discovery: compares it with the accepted configuration and raises
    /// CONFIG_INVALID or MODULE_REPLACED.
    fn discovered<S: TmStore>(&mut self, now: u64, d: Discovery, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        let r = compare(
            &d,
            self.accepted.map(|x| x.hash),
            self.accepted.as_ref().map(|x| &x.ids),
        );
        match (d.outcome, r) {
            (Err(why), _) => {
                let e = mib_wire::ev::ConfigInvalid {
                    reason: why.code(),
                    slot: why.slot().unwrap_or(NO_SLOT),
                    hash: d.hash,
                };
                dl.raise(now, e, sink);
            }
            (Ok(_), Replacement::Changed { slot }) => {
                let old = self.accepted.map_or(0, |x| x.hash);
                let e = mib_wire::ev::ModuleReplaced {
                    slot: slot.unwrap_or(NO_SLOT),
                    accepted_hash: old,
                    hash: d.hash,
                };
                dl.raise(now, e, sink);
            }
            (Ok(_), Replacement::Same | Replacement::NoneAccepted) => {}
        }
        self.discovery = Some(d);
        self.replacement = Some(r);
    }

    /// The parameters the MIB names module discovery the source of.
    pub fn param(&self, id: u16) -> Supplied {
        let d = self.discovery.as_ref();
        Ok(Some(match id {
            pid::CONFIG_HASH => d.map_or(mib::modules::config::HASH_NOT_DISCOVERED, |d| d.hash) as i64,
            pid::CONFIG_ID => d.and_then(|d| d.outcome.ok()).map_or(0, |c| c.code()) as i64,
            pid::CONFIG_STATUS => {
                (match (d, self.block_operational()) {
                    (None, _) => status::NOT_DISCOVERED,
                    (Some(d), _) if d.outcome.is_err() => status::INVALID,
                    (Some(_), Some(_)) => status::NOT_ACCEPTED,
                    (Some(_), None) => status::ACCEPTED,
                }) as i64
            }
            pid::MODULES_PRESENT => d.map_or(0, |d| d.present.0) as i64,
            _ => return Err(NotSupplied(id)),
        }))
    }
}

impl<S: TmStore> Obsw<S> {
    /// Hands in the configuration the ground last accepted (from the platform's
    /// non-volatile store), before [`Obsw::discover_modules`].
    pub fn set_accepted_config(&mut self, a: Option<AcceptedConfig>) {
        self.modules.accepted = a;
    }

    /// A configuration the ground accepted since the last call, for the platform to
    /// persist.
    pub fn take_accepted_update(&mut self) -> Option<AcceptedConfig> {
        self.modules.update.take()
    }

    /// Starts discovery with what board A read at boot (its descriptor table from flash
    /// and its probes); board B's half comes over the A–B link. [`Obsw::tick`] runs
    /// discovery once B's whole table arrived, or after `config::MODULE_B_TIMEOUT_MS`
    /// without it (BOARD_B_SILENT). A table longer than any table is kept truncated
    /// (discovery then finds it unreadable).
    pub fn start_discovery(&mut self, now: u64, table: &[u8], probes: BoardProbes) {
        self.last_now = self.last_now.max(now);
        let mut t = heapless::Vec::new();
        // Truncated on purpose when too long: discovery reports the table as unreadable.
        let _ = t.extend_from_slice(&table[..table.len().min(MAX_TABLE_LEN)]);
        self.modules.pending = Some(PendingA {
            table: t,
            probes,
            since: now,
            requests: 0,
        });
    }

    /// True while discovery waits for board B's half ([`Obsw::start_discovery`]):
    /// OPERATIONAL is refused until it is done.
    pub fn discovery_pending(&self) -> bool {
        self.modules.pending.is_some()
    }

    /// Runs discovery on what the platform read at boot (`b` = `None`: board B sent
    /// nothing; `Modules::discover`).
    pub fn discover_modules(
        &mut self,
        now: u64,
        a: &BoardInput<'_>,
        b: Option<&BoardInput<'_>>,
        sink: &mut impl TmSink,
    ) {
        self.last_now = self.last_now.max(now);
        self.modules.discover(now, a, b, &mut self.robot, &mut self.dl, sink);
    }

    /// Runs with `cal` from now on (`Robot::apply_calibration`).
    pub fn apply_calibration(&mut self, cal: RobotCal) {
        self.robot.apply_calibration(cal);
    }

    /// Raises CONFIG_STATE_LOST: the platform's store of the accepted configuration gave
    /// nothing (missing, unreadable, corrupt; the robot then has nothing accepted) or an
    /// acceptance could not be written.
    pub fn config_state_lost(&mut self, now: u64, why: StateLost, sink: &mut impl TmSink) {
        self.last_now = self.last_now.max(now);
        self.raise(now, mib_wire::ev::ConfigStateLost { reason: why.code() }, sink);
    }
}

/// Discovery's join with the robot: board B's half of the table from the controller, the
/// calibration to the controller and the current monitors, absent modules to the mode tree.
impl Modules {
    /// Runs a pending discovery when board B's half is in, or the wait is over.
    pub(crate) fn tick<S: TmStore>(
        &mut self,
        now: u64,
        robot: &mut Robot,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) {
        let Some(p) = self.pending.as_ref() else { return };
        let mut b_table = [0u8; MAX_TABLE_LEN];
        let b = match robot.ctrl.board_b_modules() {
            Some((t, probes)) => {
                let n = t.len().min(MAX_TABLE_LEN);
                b_table[..n].copy_from_slice(&t[..n]);
                Some((n, probes))
            }
            None if now.saturating_sub(p.since) >= mib::config::MODULE_B_TIMEOUT_MS as u64 => None,
            None => {
                // Ask again every MODULE_B_REQUEST_MS (frames lost on the line).
                let due = (p.requests as u64 + 1) * mib::config::MODULE_B_REQUEST_MS as u64;
                if now.saturating_sub(p.since) >= due {
                    robot.ctrl.request_board_b_modules();
                    if let Some(p) = self.pending.as_mut() {
                        p.requests += 1;
                    }
                }
                return;
            }
        };
        let Some(p) = self.pending.take() else { return };
        let a = BoardInput {
            table: &p.table,
            probes: p.probes,
        };
        let b = b.map(|(n, probes)| BoardInput {
            table: &b_table[..n],
            probes,
        });
        self.discover(now, &a, b.as_ref(), robot, dl, sink);
    }

    /// Runs discovery on what the platform read at boot (`b` = `None`: board B sent
    /// nothing), compares it with the accepted configuration, raises CONFIG_INVALID or
    /// MODULE_REPLACED, applies the module powers and sends the module report.
    pub(crate) fn discover<S: TmStore>(
        &mut self,
        now: u64,
        a: &BoardInput<'_>,
        b: Option<&BoardInput<'_>>,
        robot: &mut Robot,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) {
        let d = discover(a, b);
        let cal = RobotCal::from_set(&d.set);
        self.discovered(now, d, dl, sink);
        robot.apply_calibration(cal);
        for (n, s) in MODULE_NODES {
            let absent = self.absent(s);
            robot.modes.set_absent(n, absent);
        }
        robot.apply_module_modes(self);
        self.report(now, dl, sink);
    }
}

impl Robot {
    /// Runs with `cal` from now on: the controller's set points and bolter thresholds
    /// (`Controller::set_calibration`) and the high limits of the current monitors (as a
    /// TC[12,7] would set them, so TM[12,9] reports them): locomotion A = the larger of
    /// arm A's and the hip's (they share the sensor), locomotion B = arm B's, grippers and
    /// bolters their own; operational and idle limits.
    pub fn apply_calibration(&mut self, cal: RobotCal) {
        self.ctrl.set_calibration(cal);
        for (name, ma) in monitor_limits(&cal) {
            // The currents are in mA (CAL_AMP: 1 count = 1 mA).
            if let Some(m) = self.monitoring.mons.iter_mut().find(|m| m.def.name == name) {
                m.def.high = ma as i32;
            }
        }
    }
}

/// The high limits (mA) the calibration gives the current monitors, by monitor name
/// (`mib::fdir::MONITORS`).
fn monitor_limits(cal: &RobotCal) -> [(&'static str, u16); 8] {
    let (arm_a, arm_b, hip) = (cal.arm_i[0], cal.arm_i[1], cal.hip_i);
    [
        ("I_LOC_A_OPER", arm_a.op_max_ma.max(hip.op_max_ma)),
        ("I_LOC_B_OPER", arm_b.op_max_ma),
        ("I_GRIP_A_OPER", cal.grip_i[0].op_max_ma),
        ("I_GRIP_B_OPER", cal.grip_i[1].op_max_ma),
        ("I_BO_A_OPER", cal.bolter_i[0].op_max_ma),
        ("I_BO_B_OPER", cal.bolter_i[1].op_max_ma),
        ("I_LOC_A_IDLE", arm_a.idle_max_ma.max(hip.idle_max_ma)),
        ("I_LOC_B_IDLE", arm_b.idle_max_ma),
    ]
}

/// The root mode a refusal of OPERATIONAL leaves the robot in (for documentation and
/// tests: it stays where it is, STANDBY after boot).
pub const STAYS_IN: u32 = robot_mode::STANDBY;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obsw::tests::{failure, kind, obsw, of, send, TestObsw};
    use mib::events::eid;
    use mib::modules::descriptor::{emit_table, MAX_TABLE_LEN};
    use mib::modules::report::ModuleReport;
    use mib::modules::{default_set, slot, Board, ModuleSet, NUM_SLOTS, SLOTS};
    use mib::FailureCode;
    use mmic_domain::discovery::{ArmSwitch, BoardProbes};

    fn probes(set: &ModuleSet, board: Board) -> BoardProbes {
        let (imu, adc, arm) = match board {
            Board::A => (slot::IMU_A, slot::ADC_A, slot::ARM_A),
            Board::B => (slot::IMU_B, slot::ADC_B, slot::ARM_B),
        };
        BoardProbes {
            imu_who_am_i: set[imu as usize].map(|_| mib::modules::MPU6000_WHO_AM_I),
            adc_ack: set[adc as usize].is_some(),
            encoder_ack: board == Board::A && set[slot::ENCODER as usize].is_some(),
            arm_switch: if set[arm as usize].is_some() {
                ArmSwitch::Pushed
            } else {
                ArmSwitch::Absent
            },
        }
    }

    /// Runs discovery on `set` (tables built from it) and returns the packets.
    fn boot(o: &mut TestObsw, set: &ModuleSet, corrupt: Option<(usize, u8)>) -> Vec<Vec<u8>> {
        let mut ta = [0u8; MAX_TABLE_LEN];
        let mut tb = [0u8; MAX_TABLE_LEN];
        let half = |board: Board| -> ModuleSet { core::array::from_fn(|i| set[i].filter(|_| SLOTS[i].board == board)) };
        let na = emit_table(&half(Board::A).iter().flatten().copied().collect::<Vec<_>>(), &mut ta).unwrap();
        let nb = emit_table(&half(Board::B).iter().flatten().copied().collect::<Vec<_>>(), &mut tb).unwrap();
        if let Some((byte, bit)) = corrupt {
            ta[byte] ^= 1 << bit;
        }
        let a = BoardInput {
            table: &ta[..na],
            probes: probes(set, Board::A),
        };
        let b = BoardInput {
            table: &tb[..nb],
            probes: probes(set, Board::B),
        };
        let mut sink = Vec::new();
        o.discover_modules(5, &a, Some(&b), &mut sink);
        sink
    }

    fn events(pkts: &[Vec<u8>], id: u16) -> Vec<Vec<u8>> {
        pkts.iter()
            .filter(|p| p[7] == 5 && p[20..22] == id.to_be_bytes())
            .map(|p| kind(p).2[2..].to_vec())
            .collect()
    }

    fn operational(o: &mut TestObsw, seq: u16) -> Vec<Vec<u8>> {
        let mut app = mib::modes::node::ROBOT.to_be_bytes().to_vec();
        app.extend_from_slice(&robot_mode::OPERATIONAL.to_be_bytes());
        app.extend_from_slice(&0u16.to_be_bytes());
        send(o, 10, seq, 200, 1, &app)
    }

    fn accepted_full() -> Option<AcceptedConfig> {
        Some(AcceptedConfig::of(&default_set(1000)))
    }

    // verifies: MOD-OBSW-01, MOD-OBSW-06
    #[test]
    fn a_full_robot_reports_its_modules_and_raises_nothing() {
        let mut o = obsw();
        o.set_accepted_config(accepted_full());
        let pkts = boot(&mut o, &default_set(1000), None);
        let rep = of(&pkts, 210, 3);
        assert_eq!(rep.len(), 1);
        let r = ModuleReport::parse(kind(&rep[0]).2).unwrap();
        assert_eq!((r.config, r.reason, r.replacement), (1, 0, 1));
        assert_eq!(r.set, default_set(1000));
        assert!(events(&pkts, eid::CONFIG_INVALID).is_empty() && events(&pkts, eid::MODULE_REPLACED).is_empty());
        assert_eq!(
            o.param::<{ pid::CONFIG_HASH }>(),
            mib::modules::config::config_hash(&default_set(1000)) as i64
        );
        assert_eq!(o.param::<{ pid::CONFIG_ID }>(), 1);
        assert_eq!(o.param::<{ pid::CONFIG_STATUS }>(), status::ACCEPTED as i64);
        assert!(o.modules.block_operational().is_none());
        // On request, the same report again.
        let again = of(&send(&mut o, 20, 1, 210, 1, &[]), 210, 3);
        assert_eq!(kind(&again[0]).2, kind(&rep[0]).2);
    }

    // verifies: MOD-OBSW-02
    #[test]
    fn a_missing_arm_keeps_standby_with_one_high_event_and_config_invalid() {
        let mut o = obsw();
        o.set_accepted_config(accepted_full());
        let mut set = default_set(1000);
        set[slot::ARM_B as usize] = None;
        let pkts = boot(&mut o, &set, None);
        let ev = events(&pkts, eid::CONFIG_INVALID);
        assert_eq!(ev.len(), 1);
        assert_eq!(&ev[0][..2], &[11, slot::ARM_B], "reason MISSING, slot arm_b");
        assert!(pkts.iter().any(|p| p[7] == 5 && p[8] == 4), "high severity");
        let f = of(&operational(&mut o, 1), 1, 4);
        assert_eq!(
            failure(&f[0]),
            (FailureCode::CONFIG_INVALID.code(), vec![11, slot::ARM_B])
        );
        assert_eq!(o.mode(), STAYS_IN);
        assert_eq!(o.param::<{ pid::CONFIG_STATUS }>(), status::INVALID as i64);
        assert_eq!(o.param::<{ pid::CONFIG_ID }>(), 0);
        // Nothing to accept.
        let h = (o.param::<{ pid::CONFIG_HASH }>() as u32).to_be_bytes();
        let f = of(&send(&mut o, 20, 2, 210, 2, &h), 1, 4);
        assert_eq!(failure(&f[0]).0, FailureCode::CONFIG_INVALID.code());
    }

    // verifies: MOD-OBSW-02
    #[test]
    fn a_corrupted_descriptor_is_named_as_the_reason() {
        let mut o = obsw();
        o.set_accepted_config(accepted_full());
        // Table header 4 bytes, gripper A is entry 4: flip a bit of its serial.
        let pkts = boot(&mut o, &default_set(1000), Some((4 + 4 * 28 + 5, 4)));
        let ev = events(&pkts, eid::CONFIG_INVALID);
        assert_eq!(ev.len(), 1);
        assert_eq!(ev[0][0], 3, "CORRUPT_DESCRIPTOR");
        let f = of(&operational(&mut o, 1), 1, 4);
        assert_eq!(failure(&f[0]).0, FailureCode::CONFIG_INVALID.code());
        assert_eq!(failure(&f[0]).1[0], 3);
    }

    // verifies: MOD-OBSW-03
    #[test]
    fn a_replaced_gripper_blocks_operational_until_the_current_hash_is_accepted() {
        let mut o = obsw();
        o.set_accepted_config(accepted_full());
        let mut set = default_set(1000);
        let g = set[slot::GRIPPER_B as usize].as_mut().unwrap();
        g.serial = 4242;
        let hash = mib::modules::config::config_hash(&set);
        let pkts = boot(&mut o, &set, None);
        let ev = events(&pkts, eid::MODULE_REPLACED);
        assert_eq!(ev.len(), 1);
        assert_eq!(ev[0][0], slot::GRIPPER_B);
        assert_eq!(&ev[0][5..9], &hash.to_be_bytes());
        assert_eq!(o.param::<{ pid::CONFIG_STATUS }>(), status::NOT_ACCEPTED as i64);
        let f = of(&operational(&mut o, 1), 1, 4);
        assert_eq!(
            failure(&f[0]),
            (FailureCode::CONFIG_NOT_ACCEPTED.code(), hash.to_be_bytes().to_vec())
        );
        // A stale hash (the old configuration's) is refused with the current one.
        let old = accepted_full().unwrap().hash;
        let f = of(&send(&mut o, 20, 2, 210, 2, &old.to_be_bytes()), 1, 4);
        let mut data = old.to_be_bytes().to_vec();
        data.extend_from_slice(&hash.to_be_bytes());
        assert_eq!(failure(&f[0]), (FailureCode::CONFIG_HASH_STALE.code(), data));
        assert!(o.take_accepted_update().is_none());
        // The current hash is accepted and handed to the platform to persist.
        let ok = send(&mut o, 30, 3, 210, 2, &hash.to_be_bytes());
        assert_eq!(of(&ok, 1, 7).len(), 1);
        assert_eq!(o.take_accepted_update().map(|a| a.hash), Some(hash));
        assert!(o.modules.block_operational().is_none());
        assert_eq!(o.param::<{ pid::CONFIG_STATUS }>(), status::ACCEPTED as i64);
    }

    // verifies: MOD-CAL-03, MOD-CAL-04
    #[test]
    fn discovery_applies_the_module_sets_calibration_to_the_controller_and_the_monitors() {
        let limit = |o: &TestObsw, name: &str| {
            o.robot
                .monitoring
                .mons
                .iter()
                .find(|m| m.def.name == name)
                .map(|m| m.def.high)
                .unwrap()
        };
        // Every monitor the calibration sets exists, measures a current in mA, and gets
        // exactly its MIB limit from the compiled constants.
        for (name, ma) in monitor_limits(&RobotCal::COMPILED) {
            let m = mib::fdir::MONITORS.iter().find(|m| m.name == name);
            let m = m.unwrap_or_else(|| panic!("no monitor {name}"));
            assert_eq!(m.high, ma as i32, "{name}");
            let p = mib::params::by_id(m.param).unwrap();
            assert_eq!(p.unit, "A", "{name}");
        }
        // Before discovery: the compiled constants.
        let mut o = obsw();
        assert_eq!(*o.robot.ctrl.calibration(), RobotCal::COMPILED);
        assert_eq!(limit(&o, "I_GRIP_B_OPER"), 1500);
        // Gripper B revision 2 (boards on firmware 1.1), its descriptor "default": the
        // database's rev-2 values; arm A bench-calibrated; a stronger hip.
        let mut set = default_set(1000);
        for b in [slot::BOARD_A, slot::BOARD_B] {
            set[b as usize].as_mut().unwrap().cal.0[0] = 0x0101;
        }
        let g = set[slot::GRIPPER_B as usize].as_mut().unwrap();
        g.revision = 2;
        g.cal = mib::modules::Calibration::DEFAULT;
        set[slot::ARM_A as usize].as_mut().unwrap().cal.0[4] = 2600;
        set[slot::HIP as usize].as_mut().unwrap().cal.0[2] = 3500;
        let pkts = boot(&mut o, &set, None);
        assert!(events(&pkts, eid::CONFIG_INVALID).is_empty());
        let c = *o.robot.ctrl.calibration();
        assert_eq!((c.side[1].grip_closed_us, c.side[1].grip_open_us), (1150, 1850));
        assert_eq!((c.side[0].grip_closed_us, c.side[0].grip_open_us), (1100, 1900));
        assert_eq!(limit(&o, "I_GRIP_B_OPER"), 1600);
        assert_eq!(limit(&o, "I_GRIP_A_OPER"), 1500);
        assert_eq!(limit(&o, "I_LOC_A_OPER"), 3500, "the larger of arm A and hip");
        assert_eq!(limit(&o, "I_LOC_B_OPER"), 3000);
        assert_eq!(limit(&o, "I_LOC_A_IDLE"), 400);
        // HK structure MODULES reports the calibration in use.
        assert_eq!(o.param::<{ pid::CAL_GRIP_B_CLOSED }>(), 1150);
        assert_eq!(o.param::<{ pid::CAL_GRIP_B_OPEN }>(), 1850);
        assert_eq!(o.param::<{ pid::CAL_GRIP_A_CLOSED }>(), 1100);
        assert_eq!(o.param::<{ pid::CAL_ENC_ZERO }>(), 2048);
        assert_eq!(
            o.param::<{ pid::CAL_FROM_DESCRIPTORS }>() & (1 << slot::GRIPPER_B),
            1 << slot::GRIPPER_B
        );
        assert!(mib::hk::HK_STRUCTS
            .iter()
            .any(|h| h.sid == mib::hk::sid::MODULES && h.params.contains(&pid::CAL_GRIP_B_CLOSED)));
    }

    // verifies: MOD-PERSIST-01, MOD-PERSIST-03
    #[test]
    fn the_accepted_configuration_round_trips_and_damage_is_refused() {
        let a = accepted_full().unwrap();
        let b = a.to_bytes();
        assert_eq!(b.len(), STATE_LEN);
        assert_eq!(AcceptedConfig::from_bytes(&b), Ok(a));
        // A locomotion-only configuration (absent slots) too.
        let mut set = default_set(7);
        set[slot::BOLTER_A as usize] = None;
        set[slot::BOLTER_B as usize] = None;
        let l = AcceptedConfig::of(&set);
        assert_eq!(l.present(), 0x3FFF & !(1 << slot::BOLTER_A) & !(1 << slot::BOLTER_B));
        assert_eq!(AcceptedConfig::from_bytes(&l.to_bytes()), Ok(l));
        // Every single bit flip and every truncation is refused.
        for i in 0..STATE_LEN * 8 {
            let mut x = b;
            x[i / 8] ^= 1 << (i % 8);
            assert!(AcceptedConfig::from_bytes(&x).is_err(), "bit {i}");
        }
        for n in 0..STATE_LEN {
            assert_eq!(AcceptedConfig::from_bytes(&b[..n]), Err(StateError::Length(n)));
        }
        assert_eq!(AcceptedConfig::from_bytes(&[0u8; STATE_LEN]), Err(StateError::Magic));
        // A mask that disagrees with its entries, with a valid CRC.
        let mut x = l.to_bytes();
        x[13] |= 1 << slot::BOLTER_A;
        let crc = mib::modules::config::HASH_CRC.checksum(&x[..STATE_LEN - 4]);
        x[STATE_LEN - 4..].copy_from_slice(&crc.to_be_bytes());
        assert_eq!(AcceptedConfig::from_bytes(&x), Err(StateError::Entry(slot::BOLTER_A)));
        // What the platform raises when its store gave nothing.
        let mut o = obsw();
        let mut sink = Vec::new();
        o.config_state_lost(3, StateLost::Corrupt, &mut sink);
        assert_eq!(events(&sink, eid::CONFIG_STATE_LOST), vec![vec![3u8]]);
    }

    // verifies: MOD-OBSW-04, MOD-OBSW-05
    #[test]
    fn a_locomotion_only_robot_refuses_bolting_with_module_absent_and_does_not_monitor_bolters() {
        let mut o = obsw();
        let mut set = default_set(1000);
        set[slot::BOLTER_A as usize] = None;
        set[slot::BOLTER_B as usize] = None;
        o.set_accepted_config(Some(AcceptedConfig::of(&set)));
        let pkts = boot(&mut o, &set, None);
        assert!(events(&pkts, eid::CONFIG_INVALID).is_empty());
        assert_eq!(o.param::<{ pid::CONFIG_ID }>(), 2);
        let bolt = Action::BoltFace {
            side: mib::robot::Side::A,
            pairs: 15,
        };
        assert_eq!(
            o.modules.absent_for(&bolt),
            Some(Failure::module_absent(slot::BOLTER_A))
        );
        let walk = Action::Reconfigure { from: 0, to: 1 };
        assert_eq!(o.modules.absent_for(&walk), None);
        // Bolter currents have no valid value: PUS 12 skips them.
        assert_eq!(o.param_opt(pid::I_BO_A), None);
        assert_eq!(o.param_opt(pid::I_BO_B), None);
        assert_eq!(
            o.modules.present_or_off(slot::BOLTER_A, mib::modes::module_mode::ON),
            mib::modes::module_mode::OFF
        );
        assert_eq!(
            o.modules.present_or_off(slot::ARM_A, mib::modes::module_mode::ON),
            mib::modes::module_mode::ON
        );
        // The mode tree keeps the absent bolters OFF in every robot mode.
        use mib::modes::{module_mode, node};
        for m in [robot_mode::OPERATIONAL, robot_mode::SAFED, robot_mode::STANDBY] {
            o.robot.modes.command(m);
            assert_eq!(o.robot.modes.commanded(node::BOLTER_A), module_mode::OFF);
            assert_eq!(o.robot.modes.commanded(node::BOLTER_B), module_mode::OFF);
        }
        o.robot.modes.command(robot_mode::OPERATIONAL);
        assert_eq!(o.robot.modes.commanded(node::ARM_A), module_mode::ON);
    }

    // verifies: MOD-OBSW-06
    #[test]
    fn the_module_report_is_what_the_mib_describes() {
        // Every shape of report: the MIB's TM[210,3] (wire crate) parses what
        // `ModuleReport::emit` writes and writes the same bytes back.
        for drop in [None, Some(slot::BOLTER_A), Some(slot::ARM_B)] {
            let mut set = default_set(7);
            if let Some(s) = drop {
                set[s as usize] = None;
            }
            let r = ModuleReport {
                hash: mib::modules::config::config_hash(&set),
                config: 1,
                reason: 0,
                reason_slot: NO_SLOT,
                replacement: 2,
                set,
            };
            let mut buf = [0u8; MAX_REPORT_LEN];
            let n = r.emit(&mut buf).unwrap();
            let w = tm::ModuleReport::parse(&buf[..n]).unwrap();
            let mut back = [0u8; MAX_REPORT_LEN];
            let m = w.emit(&mut back).unwrap();
            assert_eq!(&back[..m], &buf[..n]);
        }
    }

    fn half(set: &ModuleSet, board: Board) -> Vec<u8> {
        let descs: Vec<_> = (0..NUM_SLOTS)
            .filter(|i| SLOTS[*i].board == board)
            .filter_map(|i| set[i])
            .collect();
        let mut t = [0u8; MAX_TABLE_LEN];
        let n = emit_table(&descs, &mut t).unwrap();
        t[..n].to_vec()
    }

    // verifies: MOD-OBSW-01, MOD-OBSW-07, MOD-OBSW-08
    #[test]
    fn board_b_half_over_the_link_completes_discovery_within_a_few_periods() {
        use mmic_domain::board_b::{BoardB, BoardBOut};
        let set = default_set(1000);
        let mut o = obsw();
        o.set_accepted_config(accepted_full());
        o.start_discovery(0, &half(&set, Board::A), probes(&set, Board::A));
        let mut b = BoardB::new();
        b.set_modules(&half(&set, Board::B), probes(&set, Board::B));
        let mut out = BoardBOut::default();
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let mut rx: Vec<u8> = Vec::new();
        let mut done_at = None;
        // Until discovery is done the module set is unknown: OPERATIONAL is refused
        // with CONFIG_NOT_ACCEPTED, hash 0 (not known yet), and nothing is powered.
        let f = of(&operational(&mut o, 1), 1, 4);
        assert_eq!(
            failure(&f[0]),
            (FailureCode::CONFIG_NOT_ACCEPTED.code(), 0u32.to_be_bytes().to_vec())
        );
        for t in (10..2000u64).step_by(10) {
            o.tick(t, &mmic_domain::SensorsA::default(), &rx, &mut sink);
            b.tick(t, &mmic_domain::SensorsB::default(), &[], &mut out);
            rx = out.tx.to_vec();
            if done_at.is_none() && !of(&sink, 210, 3).is_empty() {
                done_at = Some(t);
            }
        }
        let done_at = done_at.expect("module report sent");
        assert!(
            done_at <= 100,
            "B's 6 entries arrive one per period: done at {done_at} ms"
        );
        assert!(o.modules.block_operational().is_none(), "the accepted set, found");
        let r = ModuleReport::parse(kind(&of(&sink, 210, 3)[0]).2).unwrap();
        assert_eq!((r.config, r.replacement), (1, 1));
        assert_eq!(of(&sink, 210, 3).len(), 1, "discovery runs once");
    }

    // verifies: MOD-OBSW-01, MOD-OBSW-02
    #[test]
    fn a_silent_board_b_is_reported_after_the_wait() {
        let set = default_set(1000);
        let mut o = obsw();
        o.start_discovery(0, &half(&set, Board::A), probes(&set, Board::A));
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let wait = mib::config::MODULE_B_TIMEOUT_MS as u64;
        for t in (10..wait).step_by(10) {
            o.tick(t, &mmic_domain::SensorsA::default(), &[], &mut sink);
        }
        assert!(of(&sink, 210, 3).is_empty(), "still waiting for board B");
        o.tick(wait, &mmic_domain::SensorsA::default(), &[], &mut sink);
        let ev = events(&sink, eid::CONFIG_INVALID);
        assert_eq!(ev.len(), 1);
        assert_eq!(ev[0][..2], [1, NO_SLOT], "BOARD_B_SILENT");
        assert_eq!(of(&sink, 210, 3).len(), 1);
    }

    // verifies: MOD-OBSW-01, MOD-OBSW-07
    #[test]
    fn a_asks_board_b_again_when_its_table_was_lost_on_the_line() {
        use mmic_domain::board_b::{BoardB, BoardBOut};
        let set = default_set(1000);
        let mut o = obsw();
        o.set_accepted_config(accepted_full());
        o.start_discovery(0, &half(&set, Board::A), probes(&set, Board::A));
        let mut b = BoardB::new();
        b.set_modules(&half(&set, Board::B), probes(&set, Board::B));
        let mut out = BoardBOut::default();
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let (mut to_a, mut to_b): (Vec<u8>, Vec<u8>) = (Vec::new(), Vec::new());
        let mut done_at = None;
        for t in (10..2000u64).step_by(10) {
            let tx = o
                .tick(t, &mmic_domain::SensorsA::default(), &to_a, &mut sink)
                .link_tx
                .to_vec();
            b.tick(t, &mmic_domain::SensorsB::default(), &to_b, &mut out);
            to_b = tx;
            // The line loses everything B sends in its first 200 ms: all three passes.
            to_a = if t < 200 { Vec::new() } else { out.tx.to_vec() };
            if done_at.is_none() && !of(&sink, 210, 3).is_empty() {
                done_at = Some(t);
            }
        }
        let done_at = done_at.expect("module report sent");
        let ask = mib::config::MODULE_B_REQUEST_MS as u64;
        assert!(
            done_at > ask && done_at < mib::config::MODULE_B_TIMEOUT_MS as u64,
            "complete after A asked again, before the wait ends: {done_at} ms"
        );
        let r = ModuleReport::parse(kind(&of(&sink, 210, 3)[0]).2).unwrap();
        assert_eq!((r.config, r.reason), (1, 0), "FULL, not BOARD_B_SILENT");
    }
}
