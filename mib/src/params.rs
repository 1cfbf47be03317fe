//! Telemetry parameters (housekeeping), with type, unit, calibration and limits.
//!
//! Parameter IDs are stable: they name the parameter in HK reports, PUS 12 monitors,
//! events and the ground archive.

use crate::layout::{Field, Names, CONFIG_ID_NAMES, CONFIG_STATUS_NAMES, ROOT_MODE_NAMES, SIDE_NAMES};
use crate::modes::ModeSet;
use crate::types::{Calib, Limits, PType};

/// One telemetry parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamDef {
    pub id: u16,
    /// Mnemonic, unique, upper case (also the SCOS-2000 parameter name stem).
    pub name: &'static str,
    pub ptype: PType,
    /// Engineering unit after calibration ("" for none).
    pub unit: &'static str,
    /// By reference (a handful of calibrations shared by every parameter): 12 bytes less
    /// per entry of the table board A keeps in flash.
    pub calib: &'static Calib,
    /// By reference: most parameters have none, and a `Limits` inline (four `f64`) in
    /// every entry cost board A 4.5 KB of flash (docs/firmware.md).
    pub limits: Option<&'static Limits>,
    /// Root modes in which `limits` apply. A value outside them in another mode is no
    /// anomaly: the regulated servo voltage is 0 V in standby, where the regulator is off
    /// (paper Table 7). Use [`limits_apply`].
    pub limits_in: ModeSet,
    pub desc: crate::types::Text,
}

/// A condition on another parameter's raw value: `param == raw`. The condition parameter
/// travels in every HK structure that carries a parameter it conditions (checked by a
/// test), so a sample is judged with the state of the same instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LimitCond {
    pub param: u16,
    pub raw: i64,
    /// What the condition means, for documents and exports.
    pub desc: crate::types::Text,
}

/// ADC (ADS7828, 12 bit) count → volts through the board's voltage divider.
pub const CAL_VOLT: Calib = Calib::new(15.0 / 4095.0, 0.0);
/// ADC count → amperes (1 mA per count after the shunt amplifier).
pub const CAL_AMP: Calib = Calib::new(0.001, 0.0);
/// Hundredths of a degree → degrees.
pub const CAL_CDEG: Calib = Calib::new(0.01, 0.0);
/// Milli-g → g.
pub const CAL_MG: Calib = Calib::new(0.001, 0.0);
const ID: Calib = Calib::IDENTITY;

/// Battery empty (paper: below 10 V the LiPo pack is empty).
pub const V_BAT_EMPTY: f64 = 10.0;
/// Battery full (2S LiPo).
pub const V_BAT_FULL: f64 = 12.6;
/// Regulated servo supply.
pub const V_REG_NOMINAL: f64 = 7.4;
/// Absolute operational current limit of the locomotion modules (arms + hip) per side.
pub const I_LOC_MAX: f64 = 3.0;
/// Absolute operational current limit of a gripper per side.
pub const I_GRIP_MAX: f64 = 1.5;
/// Absolute operational current limit of a bolter per side.
pub const I_BO_MAX: f64 = 2.5;
/// Largest locomotion current drawn while idle (idle overcurrent check).
pub const I_LOC_IDLE_MAX: f64 = 0.4;
/// Hip encoder tolerance around the contracted angle when entering operational.
pub const HIP_CONTRACTED_TOL_DEG: f64 = 5.0;
/// Board B heartbeat age that counts as internal communication loss.
pub const B_HEARTBEAT_TIMEOUT_MS: f64 = 500.0;

/// `Some(&Limits { .. })`: a promoted constant, referenced by the parameters that use it.
macro_rules! lim {
    ($soft_lo:expr, $soft_hi:expr, $hard_lo:expr, $hard_hi:expr) => {
        Some(&Limits {
            soft_lo: $soft_lo,
            soft_hi: $soft_hi,
            hard_lo: $hard_lo,
            hard_hi: $hard_hi,
        })
    };
}
const V_BAT_LIM: Option<&Limits> = lim!(10.5, V_BAT_FULL, V_BAT_EMPTY, 13.0);
const V_REG_LIM: Option<&Limits> = lim!(7.0, 7.8, 6.5, 8.2);
const I_LOC_LIM: Option<&Limits> = lim!(0.0, 2.5, -0.1, I_LOC_MAX);
const I_GRIP_LIM: Option<&Limits> = lim!(0.0, 1.2, -0.1, I_GRIP_MAX);
const I_BO_LIM: Option<&Limits> = lim!(0.0, 2.0, -0.1, I_BO_MAX);
const I_BAT_LIM: Option<&Limits> = lim!(0.0, 5.0, -0.1, 7.0);

/// The on-board component that supplies a telemetry parameter's value: each parameter
/// row names exactly one, and the OBSW asks that component and no other (`Obsw::param`).
/// A component asked for a parameter it does not supply answers [`NotSupplied`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Source {
    /// The mode tree (robot mode).
    Modes,
    /// FDIR: fault flags, counts and the mode it waits to enter.
    Faults,
    /// PUS 12 on-board monitoring.
    Monitoring,
    /// The OBSW's request and event-queue counters.
    Counters,
    /// The downlink: TM writer, on-board store, event throttling.
    Downlink,
    /// PUS 11 time-based schedule.
    Scheduler,
    /// The OBSW's clock (time since boot).
    Clock,
    /// The platform's I/O counters (host binary or firmware).
    Io,
    /// The platform's space-link endpoint (frames, COP-1, SDLS).
    SpaceLink,
    /// Module discovery and the configuration the ground accepted.
    Modules,
    /// Team coordination (service 211, leader selection).
    Team,
    /// The on-board plan (service 18, `crate::plan`).
    Plan,
    /// Software update (service 213, `crate::update`): running version and slot, last outcome.
    Update,
    /// The file service (`crate::files`): what the platform's CFDP entity and file store
    /// counted.
    Files,
    /// Board A's robot logic (the domain controller): its own sensors, actuators, state
    /// estimate, A–B link counters and calibration.
    BoardA,
    /// Board B's heartbeat as board A last received it (no value before the first one).
    BoardB,
}

impl Source {
    /// Every source, for checks that ask each component in turn.
    pub const ALL: [Source; 16] = [
        Source::Modes,
        Source::Faults,
        Source::Monitoring,
        Source::Counters,
        Source::Downlink,
        Source::Scheduler,
        Source::Clock,
        Source::Io,
        Source::SpaceLink,
        Source::Modules,
        Source::Team,
        Source::Plan,
        Source::Update,
        Source::Files,
        Source::BoardA,
        Source::BoardB,
    ];
}

/// A component was asked for a parameter the MIB does not name it the source of (or a
/// parameter ID the MIB does not define): an error, never a value of 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NotSupplied(pub u16);

impl core::fmt::Display for NotSupplied {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "parameter {} is not supplied here", self.0)
    }
}

impl core::error::Error for NotSupplied {}

/// A component's answer for a parameter it was asked for: `Ok(None)` when the parameter
/// has no valid value now (board B not heard yet, its module absent).
pub type Supplied = Result<Option<i64>, NotSupplied>;

macro_rules! params {
    ($( $name:ident = $id:literal, $src:ident, $t:ident, $unit:literal, $cal:expr, $lim:expr, $desc:literal; )*) => {
        /// Parameter IDs by mnemonic.
        pub mod pid {
            $( #[doc = $desc] pub const $name: u16 = $id; )*
        }
        /// Every telemetry parameter, in ID order.
        pub const PARAMS: &[ParamDef] = &[ $( ParamDef {
            id: $id, name: stringify!($name), ptype: PType::$t, unit: $unit,
            calib: &$cal, limits: $lim, limits_in: limits_in($id), desc: $crate::types::text($desc),
        }, )* ];
        /// The source of each parameter, in the order of `PARAMS` (beside the table rather
        /// than a field of `ParamDef`: one byte per parameter in board A's flash instead of
        /// four with the field's padding).
        const SOURCES: [Source; PARAMS.len()] = [ $( Source::$src, )* ];
    };
}

params! {
    // --- robot status (paper heartbeat, Table 3) ---
    MODE = 1, Modes, U8, "", ID, None, "Robot mode: 0 standby, 1 operational, 2 safed";
    CONFIG_STATE = 2, BoardA, U8, "", ID, None, "Configuration state computed from IMUs, hip encoder and arm PWM (255 = unknown)";
    TARGET_STATE = 3, BoardA, U8, "", ID, None, "Last commanded target state (255 = none)";
    CMD_COMPLETE = 4, BoardA, Bool, "", ID, None, "Last robot command complete";
    ACTIVE_PRIMITIVE = 5, BoardA, U8, "", ID, None, "Motion primitive being executed (0 = none)";
    BOLT_SIDE = 6, BoardA, U8, "", ID, None, "Side whose face is being (un)bolted: 0 A, 1 B";
    BOLT_PAIR = 7, BoardA, U8, "", ID, None, "Active bolter pair 1..4 (0 = none)";
    BOLT_ATTEMPT = 8, BoardA, U8, "", ID, None, "Attempt number on the active pair (1..3)";
    FAULT_FLAGS = 9, Faults, U32, "", ID, None, "Active fault bits (bit n = fault n of the FDIR table)";
    ARM_A_TARGET = 10, BoardA, U16, "us", ID, None, "Arm A target PWM pulse width";
    ARM_A_PWM = 11, BoardA, U16, "us", ID, None, "Arm A last interpolated PWM pulse width";
    ARM_B_TARGET = 12, BoardB, U16, "us", ID, None, "Arm B target PWM pulse width";
    ARM_B_PWM = 13, BoardB, U16, "us", ID, None, "Arm B last interpolated PWM pulse width";
    GRIP_A_TARGET = 14, BoardA, U16, "us", ID, None, "Gripper A target PWM pulse width";
    GRIP_A_PWM = 15, BoardA, U16, "us", ID, None, "Gripper A last interpolated PWM pulse width";
    GRIP_B_TARGET = 16, BoardB, U16, "us", ID, None, "Gripper B target PWM pulse width";
    GRIP_B_PWM = 17, BoardB, U16, "us", ID, None, "Gripper B last interpolated PWM pulse width";
    HIP_TARGET = 18, BoardA, I16, "deg", CAL_CDEG, None, "Hip target angle";
    HIP_ANGLE = 19, BoardA, I16, "deg", CAL_CDEG, None, "Hip angle from the magnetic absolute encoder";
    V_BAT_A = 20, BoardA, U16, "V", CAL_VOLT, V_BAT_LIM, "Battery voltage seen by board A (moving average)";
    V_BAT_B = 21, BoardB, U16, "V", CAL_VOLT, V_BAT_LIM, "Battery voltage seen by board B (moving average)";
    I_BAT = 22, BoardA, U16, "A", CAL_AMP, I_BAT_LIM, "Battery current draw";
    V_REG = 23, BoardA, U16, "V", CAL_VOLT, V_REG_LIM, "Regulated servo voltage (0 when the regulator is off)";
    I_LOC_A = 24, BoardA, U16, "A", CAL_AMP, I_LOC_LIM, "Locomotion current side A (arm A + hip)";
    I_LOC_B = 25, BoardB, U16, "A", CAL_AMP, I_LOC_LIM, "Locomotion current side B (arm B)";
    I_GRIP_A = 26, BoardA, U16, "A", CAL_AMP, I_GRIP_LIM, "Gripper A current";
    I_GRIP_B = 27, BoardB, U16, "A", CAL_AMP, I_GRIP_LIM, "Gripper B current";
    I_BO_A = 28, BoardA, U16, "A", CAL_AMP, I_BO_LIM, "Bolter A current";
    I_BO_B = 29, BoardB, U16, "A", CAL_AMP, I_BO_LIM, "Bolter B current";
    ARM_SW_A = 30, BoardA, Bool, "", ID, None, "Arm A contracted switch pushed";
    ARM_SW_B = 31, BoardB, Bool, "", ID, None, "Arm B contracted switch pushed";
    GRAV_A_X = 32, BoardA, I16, "g", CAL_MG, None, "Gravity vector in board A frame, x";
    GRAV_A_Y = 33, BoardA, I16, "g", CAL_MG, None, "Gravity vector in board A frame, y";
    GRAV_A_Z = 34, BoardA, I16, "g", CAL_MG, None, "Gravity vector in board A frame, z";
    GRAV_B_X = 35, BoardB, I16, "g", CAL_MG, None, "Gravity vector in board B frame, x";
    GRAV_B_Y = 36, BoardB, I16, "g", CAL_MG, None, "Gravity vector in board B frame, y";
    GRAV_B_Z = 37, BoardB, I16, "g", CAL_MG, None, "Gravity vector in board B frame, z";
    BOLTER_B_STATE = 38, BoardB, U8, "", ID, None, "Board B bolter state machine state (sync flags)";
    // --- board B link ---
    B_LINK_OK = 50, BoardA, Bool, "", ID, None, "Board B heartbeat current and commands acknowledged";
    B_HB_AGE_MS = 51, BoardA, U16, "ms", ID, lim!(0.0, 200.0, 0.0, B_HEARTBEAT_TIMEOUT_MS), "Age of the last board B heartbeat";
    B_HB_RX = 52, BoardA, U32, "", ID, None, "Board B heartbeats received";
    B_FRAME_ERRORS = 53, BoardA, U32, "", ID, None, "A-B frames dropped for bad checksum or framing";
    B_RETRIES = 54, BoardA, U32, "", ID, None, "Commands to board B resent for lack of acknowledgement";
    B_ACK_MISSED = 55, BoardA, U32, "", ID, None, "Commands to board B never acknowledged";
    // --- FDIR ---
    FAULT_LATCHED = 60, Faults, U32, "", ID, None, "Latched fault bits (cleared by a successful recovery)";
    FAULT_COUNT = 61, Faults, U32, "", ID, None, "Faults detected since boot";
    MON_ENABLED = 62, Monitoring, U32, "", ID, None, "Enabled PUS 12 monitors (bit n = monitor n)";
    LAST_FAULT_EVENT = 63, Faults, U16, "", ID, None, "Event ID of the last fault (0 = none)";
    HIP_DEVIATION = 65, BoardA, I16, "deg", CAL_CDEG, lim!(-3.0, 3.0, -HIP_CONTRACTED_TOL_DEG, HIP_CONTRACTED_TOL_DEG), "Hip encoder minus the hip angle implied by the IMU-derived state (0 deg when the state is unknown)";
    EVENTS_DROPPED = 66, Counters, U16, "", ID, None, "PUS 5 event reports dropped because the event queue was full (saturates at 65535)";
    PENDING_MODE = 64, Faults, U8, "", ID, None, "Mode to enter when the running motion completes (255 = none)";
    // --- OBSW ---
    TC_ACCEPTED = 70, Counters, U32, "", ID, None, "Telecommands accepted";
    TC_REJECTED = 71, Counters, U32, "", ID, None, "Telecommands rejected";
    TC_DUPLICATE = 72, Counters, U32, "", ID, None, "Duplicate telecommands acknowledged but not executed";
    TM_SENT = 73, Downlink, U32, "", ID, None, "Telemetry packets sent";
    TM_STORED = 74, Downlink, U16, "", ID, None, "Packets held in the on-board store";
    TM_STORE_DROPPED = 75, Downlink, U32, "", ID, None, "Stored packets overwritten because the store was full";
    SCHED_COUNT = 76, Scheduler, U16, "", ID, None, "Activities in the time-based schedule";
    SCHED_ENABLED = 77, Scheduler, Bool, "", ID, None, "Time-based schedule enabled";
    UPTIME_S = 78, Clock, U32, "s", ID, None, "Seconds since boot";
    EVENTS_THROTTLED = 79, Downlink, U32, "", ID, None, "Event reports dropped by throttling";
    // --- platform I/O (board A firmware or host binary) ---
    IO_TC_DROPPED = 80, Io, U32, "", ID, None, "Uplink frames dropped before the OBSW saw them (queue full, framing error)";
    IO_TM_DROPPED = 81, Io, U32, "", ID, None, "Live TM packets the ground link could not send (kept in the store)";
    IO_SENSOR_ERRORS = 82, Io, U32, "", ID, None, "Sensor reads that failed (I2C errors on the ADC, IMU or hip encoder)";
    IO_OUTPUT_ERRORS = 83, Io, U32, "", ID, None, "Actuator writes that failed (PWM, GPIO)";
    IO_AB_BYTES_DROPPED = 84, Io, U32, "", ID, None, "A-B serial bytes dropped by board A's receive or transmit queue";
    IO_STACK_HIGH_WATER = 85, Io, U32, "B", ID, None, "Deepest use of board A's stack since boot, from the paint of start-up (0 on the host and until the first sweep)";
    // --- space link (host frame endpoint; docs/space-link.md) ---
    LINK_AD_ACCEPTED = 120, SpaceLink, U32, "", ID, None, "Space link: AD (sequence-controlled) TC frames accepted by FARM-1";
    LINK_BD_ACCEPTED = 121, SpaceLink, U32, "", ID, None, "Space link: BD (bypass) TC frames accepted";
    LINK_CONTROL_FRAMES = 122, SpaceLink, U32, "", ID, None, "Space link: BC control frames (Unlock, Set V(R), in clear) executed by FARM-1";
    LINK_PACKETS = 123, SpaceLink, U32, "", ID, None, "Space link: TC packets extracted from accepted frames";
    LINK_REJ_BARE_PACKET = 124, SpaceLink, U32, "", ID, None, "Space link: bare space packets refused on the frame port";
    LINK_REJ_BAD_CRC = 125, SpaceLink, U32, "", ID, None, "Space link: TC frames refused for a frame CRC mismatch";
    LINK_REJ_BAD_LENGTH = 126, SpaceLink, U32, "", ID, None, "Space link: TC frames refused for a length (too short, too long, header length not the datagram's)";
    LINK_REJ_BAD_HEADER = 127, SpaceLink, U32, "", ID, None, "Space link: TC frames refused for a header field (version, frame type flags)";
    LINK_REJ_WRONG_SCID = 128, SpaceLink, U32, "", ID, None, "Space link: TC frames for another spacecraft";
    LINK_REJ_UNKNOWN_VC = 129, SpaceLink, U32, "", ID, None, "Space link: TC frames on an unknown virtual channel";
    LINK_REJ_SDLS_SHORT = 130, SpaceLink, U32, "", ID, None, "Space link: TC frames too short for the SDLS header and trailer";
    LINK_REJ_UNKNOWN_SPI = 131, SpaceLink, U32, "", ID, None, "Space link: TC frames with an unknown SPI";
    LINK_REJ_REPLAY = 132, SpaceLink, U32, "", ID, None, "Space link: TC frames whose IV is outside the anti-replay window (replays)";
    LINK_REJ_BAD_MAC = 133, SpaceLink, U32, "", ID, None, "Space link: TC frames failing the SDLS MAC (wrong key, altered, forged)";
    LINK_REJ_STORE_FAILED = 134, SpaceLink, U32, "", ID, None, "Space link: TC frames refused because the counter state file could not be written";
    LINK_REJ_UNKNOWN_CONTROL = 135, SpaceLink, U32, "", ID, None, "Space link: BC frames with an unknown control command";
    LINK_REJ_NOT_PACKETS = 136, SpaceLink, U32, "", ID, None, "Space link: authentic TC frames whose data is not whole space packets";
    LINK_FARM_DISCARDED = 137, SpaceLink, U32, "", ID, None, "Space link: authentic AD frames discarded by FARM-1 (E2-E5: no buffer, gap, duplicate, lockout area)";
    LINK_CLCW = 138, SpaceLink, U32, "", ID, None, "Space link: the current CLCW (raw 32-bit word: FARM state, flags, N(R))";
    LINK_TM_FRAMES = 139, SpaceLink, U32, "", ID, None, "Space link: TM frames sent on VC0/VC1/VC2";
    LINK_TM_IDLE_FRAMES = 140, SpaceLink, U32, "", ID, None, "Space link: idle TM frames sent on VC7";
    LINK_TM_SDLS_FAILED = 141, SpaceLink, U32, "", ID, None, "Space link: TM frames not sent because SDLS failed (counter state file)";
    LINK_REJ_CONTROL_STATE = 142, SpaceLink, U32, "", ID, None, "Space link: BC control frames (in clear, CRC and header valid) refused because FARM-1 does not take them in its state: Unlock outside Lockout and Wait, Set V(R) other than to the present V(R) or in Lockout";
    LINK_REJ_BD_CONTENT = 143, SpaceLink, U32, "", ID, None, "Space link: authentic BD (bypass) TC frames refused because a packet in them is neither a class 2 CFDP file data PDU nor a time-tagged command TC[11,4] (mib::link::bypass_admissible): other commands travel in AD frames only, in COP-1 order";
    CONFIG_HASH = 146, Modules, U32, "", ID, None, "Module configuration hash (CRC-32 over the present slots' descriptors, mib::modules::config::config_hash; 0 before discovery)";
    CONFIG_ID = 147, Modules, U8, "", ID, None, "Supported module configuration found at boot: 0 none (invalid set), 1 FULL, 2 LOCOMOTION_ONLY";
    CONFIG_STATUS = 148, Modules, U8, "", ID, None, "Module configuration state: 0 not discovered, 1 accepted by the ground, 2 not accepted (MODULE_REPLACED: OPERATIONAL refused until ACCEPT_CONFIG), 3 invalid (STANDBY only)";
    MODULES_PRESENT = 149, Modules, U16, "", ID, None, "Present module slots (bit n = slot n of mib::modules::SLOTS)";
    CAL_GRIP_A_CLOSED = 150, BoardA, U16, "us", ID, None, "Calibration in use: gripper A closed pulse width (its descriptor, or the database default of its revision; the MIB constant before discovery)";
    CAL_GRIP_A_OPEN = 151, BoardA, U16, "us", ID, None, "Calibration in use: gripper A open pulse width";
    CAL_GRIP_B_CLOSED = 152, BoardA, U16, "us", ID, None, "Calibration in use: gripper B closed pulse width";
    CAL_GRIP_B_OPEN = 153, BoardA, U16, "us", ID, None, "Calibration in use: gripper B open pulse width";
    CAL_ENC_ZERO = 154, BoardA, U16, "", ID, None, "Calibration in use: hip encoder (AS5600) reading at the hip zero, counts (2048 nominal)";
    CAL_FROM_DESCRIPTORS = 155, BoardA, U16, "", ID, None, "Calibration in use: slots whose calibration came from their descriptor (bit n = slot n; 0 = compiled constants, before discovery)";
    TEAM_TERM = 160, Team, U32, "", ID, None, "Team: current term of the robot's leader-selection node (0 without a roster)";
    TEAM_ROLE = 161, Team, U8, "", ID, None, "Team: role 0 follower, 1 candidate, 2 leader";
    TEAM_LEADER = 162, Team, U8, "", ID, None, "Team: robot number of the known leader of the current term (0 = none)";
    TEAM_GROUND_SEEN = 163, Team, U8, "", ID, None, "Team: 1 while the ground is seen (a valid ground TC within GROUND_LOSS_TIMEOUT_MS), 0 after GROUND_LOST";
    TEAM_PKT_SENT = 164, Team, U32, "", ID, None, "Team: inter-robot packets sent (one per destination robot)";
    TEAM_PKT_RECEIVED = 165, Team, U32, "", ID, None, "Team: inter-robot packets accepted (authentic, in the replay window, valid team message)";
    TEAM_REJ_MALFORMED = 166, Team, U32, "", ID, None, "Team: inter-robot packets refused: authentic but not a TM[211,1] of APID 0x0E0 carrying a valid team message, or no roster set";
    TEAM_REJ_TRUNCATED = 167, Team, U32, "", ID, None, "Team: inter-robot packets refused: too short for the security header and MAC";
    TEAM_REJ_UNKNOWN_SENDER = 168, Team, U32, "", ID, None, "Team: inter-robot packets refused: sender not a peer of this robot, or a team message from a robot outside the roster";
    TEAM_REJ_BAD_MAC = 169, Team, U32, "", ID, None, "Team: inter-robot packets refused: AES-256-GCM tag mismatch (forged, altered, wrong team key)";
    TEAM_REJ_REPLAY = 170, Team, U32, "", ID, None, "Team: inter-robot packets refused: counter not above the sender's last accepted one (replayed)";
    TEAM_REJ_STORE_FAILED = 171, Team, U32, "", ID, None, "Team: inter-robot packets refused or not sent because the team counter state file could not be written";
    TEAM_ELECTIONS = 172, Team, U32, "", ID, None, "Team: elections this robot stood in (ELECTION_STARTED) since boot";
    TEAM_DIR_EXECUTED = 173, Team, U32, "", ID, None, "Team: leader directives executed since boot (DIRECTIVE_EXECUTED)";
    TEAM_DIR_REFUSED = 174, Team, U32, "", ID, None, "Team: leader directives refused since boot (stale term, ground present, outside the authorisation)";
    TEAM_PERSIST_FAILED = 175, Team, U32, "", ID, None, "Team: writes of the team state (term, vote, roster, authorisation) that failed (each treated as a reset of the node)";
    TEAM_STEPS_EXECUTED = 176, Team, U16, "", ID, None, "Team: authorised plan steps executed on CONTINUE since the authorisation was uploaded";
    SW_VERSION = 230, Update, U32, "", ID, None, "Update: version of the running software (0x00MMmmpp; 0 = started without a signed image)";
    SW_SLOT = 231, Update, U8, "", ID, None, "Update: application slot the running software was booted from (0 or 1)";
    UPDATE_OUTCOME = 232, Update, U8, "", ID, None, "Update: outcome of the last update (none, installed, refused, pending confirmation, confirmed, rolled back)";
    UPDATE_INSTALLED_VERSION = 233, Update, U32, "", ID, None, "Update: version of the verified image waiting in the inactive slot (0 = none)";
    UPDATE_REFUSALS = 234, Update, U32, "", ID, None, "Update: update TCs refused since boot (images refused at install, activations for another, a missing or an already activated image)";
    PLAN_STATE = 200, Plan, U8, "", ID, None, "Plan: state 0 empty, 1 loaded, 2 running, 3 suspended, 4 completed, 5 aborted";
    PLAN_ID = 201, Plan, U32, "", ID, None, "Plan: ID of the loaded plan (0 = none)";
    PLAN_STEPS = 202, Plan, U8, "", ID, None, "Plan: steps in this robot's image";
    PLAN_NEXT_STEP = 203, Plan, U8, "", ID, None, "Plan: the step running or to run next (0-based)";
    PLAN_DONE = 204, Plan, U8, "", ID, None, "Plan: steps completed (skipped ones included)";
    PLAN_WAIT_ROBOT = 205, Plan, U8, "", ID, None, "Plan: robot whose announced progress the next step waits for (0 = none)";
    PLAN_WAIT_STEP = 206, Plan, U8, "", ID, None, "Plan: that robot's step (0-based) the next step waits for";
    PLAN_PROGRESS_SENT = 207, Plan, U32, "", ID, None, "Plan: progress announcements sent to the team (one per destination robot)";
    PLAN_PROGRESS_RECEIVED = 208, Plan, U32, "", ID, None, "Plan: progress announcements accepted from other robots (authentic, of the loaded plan)";
    PLAN_PROGRESS_IGNORED = 209, Plan, U32, "", ID, None, "Plan: progress announcements ignored (another plan ID, a robot the plan does not wait for, malformed, or a sender other than the one authenticated)";
    // --- the file service (CFDP entity and file store; docs/files.md, mib::files) ---
    FILE_PDU_RECEIVED = 240, Files, U32, "", ID, None, "Files: CFDP PDUs the robot's entity took (well formed, addressed between the ground's entity and this robot's, of a transaction it runs or opens)";
    FILE_PDU_SENT = 241, Files, U32, "", ID, None, "Files: CFDP PDUs the robot's entity sent to the ground (one TM packet each, files VC)";
    FILE_PDU_REFUSED = 242, Files, U32, "", ID, None, "Files: packets of the CFDP APID refused: no PDU packet, a PDU malformed in a length or a field, not addressed between the ground's entity and this robot's (event FILE_REFUSED)";
    FILE_PDU_STRAY = 243, Files, U32, "", ID, None, "Files: PDUs of a transaction other than the running one or already ended (late retransmissions, duplicates): dropped, a Finished PDU acknowledged again";
    FILE_HANDLER_REFUSED = 244, Files, U32, "", ID, None, "Files: PDUs and requests the CFDP state machine refused (a transaction while one runs the same way, a wrong transaction) (event FILE_REFUSED)";
    FILE_BEFORE_METADATA = 245, Files, U32, "", ID, None, "Files: file data and EOF PDUs of a transaction whose metadata had not arrived: dropped, the metadata asked for again in class 2";
    FILE_TX_RECEIVED = 246, Files, U32, "", ID, None, "Files: transactions the ground's entity started (puts up; get, listing, remove and rename requests), event FILE_TRANSFER_STARTED";
    FILE_TX_SENT = 247, Files, U32, "", ID, None, "Files: transactions the robot's entity started (the file of a get, a listing), event FILE_TRANSFER_STARTED";
    FILE_TX_COMPLETED = 248, Files, U32, "", ID, None, "Files: transactions ended complete (receiver: checksum verified, file kept; sender: the ground's Finished PDU says so), event FILE_TRANSFER_COMPLETED";
    FILE_TX_FAILED = 249, Files, U32, "", ID, None, "Files: transactions ended incomplete (a fault, a cancel, abandoned for inactivity; nothing partial kept), event FILE_TRANSFER_FAILED";
    FILE_FAULTS = 250, Files, U32, "", ID, None, "Files: CFDP faults declared (checksum failure, ACK, NAK or check limit, inactivity, filestore rejection)";
    FILE_SEG_RESENT = 251, Files, U32, "", ID, None, "Files: file data PDUs sent again at the ground's NAKs";
    FILE_NAK_SENT = 252, Files, U32, "", ID, None, "Files: NAK PDUs sent (segments, or the metadata, the robot asks the ground for again)";
    FILE_NAK_RECEIVED = 253, Files, U32, "", ID, None, "Files: NAK PDUs taken from the ground (segments it asks the robot for again)";
    FILE_OUTBOX_DROPPED = 254, Files, U32, "", ID, None, "Files: PDUs lost because the entity's outbox was full (mib::cfdp::OUTBOX_DEPTH; class 2 recovers them)";
    FILE_RESEND_DROPPED = 255, Files, U32, "", ID, None, "Files: segment requests of the ground's NAKs dropped because the resend queue was full (asked for again by the next NAK)";
    FILE_SUPERSEDED = 256, Files, U32, "", ID, None, "Files: incoming transactions ended by the ground's next one before their Finished PDU was acknowledged (that ACK was lost)";
    FILE_FS_DONE = 257, Files, U32, "", ID, None, "Files: filestore requests executed (delete, rename)";
    FILE_FS_REFUSED = 258, Files, U32, "", ID, None, "Files: filestore requests refused (a bad or missing name, an existing target, an action the store does not take) (event FILE_REFUSED)";
    FILE_PROXY_REFUSED = 259, Files, U32, "", ID, None, "Files: puts the ground asked for (a get, a listing) refused: busy, a bad name, no such file (event FILE_REFUSED)";
    FILE_STORE_BAD_NAMES = 260, Files, U32, "", ID, None, "Files: names the store refused (mib::cfdp name rules: 1 to 48 letters, digits, '.', '_', '-', not starting with '.') (event FILE_REFUSED)";
    FILE_STORE_FULL = 261, Files, U32, "", ID, None, "Files: writes the store refused for space (file longer than MAX_FILE_LEN, past the free bytes, more than MAX_FILES files) (event FILE_REFUSED)";
    FILE_STORE_IO_ERRORS = 262, Files, U32, "", ID, None, "Files: failures of the store's medium (host directory, board flash), event FILE_STORE_ERROR";
    FILE_STORE_FILES = 263, Files, U16, "", ID, None, "Files: files in the store (at most mib::cfdp::MAX_FILES; staging files of a transfer under way included)";
    FILE_STORE_FREE = 264, Files, U32, "B", ID, None, "Files: bytes the store can still take";
    FILE_PARTIALS_REMOVED = 265, Files, U16, "", ID, None, "Files: partly received files of transfers a reset cut short, removed at start (never taken for the file they were to be), event FILE_PARTIALS_REMOVED";
    LINK_TM_SPI = 180, SpaceLink, U16, "", ID, None, "Space link: the TM SPI in use (17 or 18; LINK_SPI_SELECT; 0 without a frame link)";
    LINK_TC_SPIS = 181, SpaceLink, U8, "", ID, None, "Space link: TC SPIs accepted (bit 0 SPI 1, bit 1 SPI 2: a key loaded and not retired)";
    LINK_STATE_WRITES = 182, SpaceLink, U32, "", ID, None, "Space link: durable writes of the link state record since boot (receive IV and FARM-1 per authentic TC frame, TM IV blocks, SPI selections)";
    LINK_STATE_BAD_SLOT = 183, SpaceLink, U8, "", ID, None, "Space link: at start, the link state slot found torn or corrupt (0 none, 1 slot 0, 2 slot 1); the other slot, one write older, was used";
}

/// Root modes in which the limits of parameter `id` apply: the regulated servo supply
/// only while the modules are powered (operational, safed); every other limit always.
const fn limits_in(id: u16) -> ModeSet {
    match id {
        pid::V_REG => ModeSet::OPER_SAFED,
        _ => ModeSet::ALL,
    }
}

/// Condition under which the limits of parameter `id` apply (besides `limits_in`): the
/// hip deviation only while no motion primitive runs (a primitive turns the hip away
/// from the angle of the last configuration state; paper: the hip is checked when the
/// robot is idle); every other limit unconditionally.
const fn limits_if(id: u16) -> Option<&'static LimitCond> {
    const NO_PRIMITIVE: LimitCond = LimitCond {
        param: pid::ACTIVE_PRIMITIVE,
        raw: 0,
        desc: crate::types::text("no motion primitive running"),
    };
    match id {
        pid::HIP_DEVIATION => Some(&NO_PRIMITIVE),
        _ => None,
    }
}

/// True if the limits of `param` apply in the robot state given by `value` (raw value
/// of a parameter by ID, `None` if not known): the root mode (`MODE`) must be one of
/// `limits_in` and the condition `limits_if`, if any, must hold. An unknown mode counts
/// only for limits that hold in every mode; an unknown condition parameter means the
/// limits do not apply (a conditional limit is never judged on a guess). False for a
/// parameter without limits. Ground limit checks (collector alarms, page colours) and
/// the on-board monitors call this before comparing a value with the limits.
pub fn limits_apply(param: &ParamDef, value: impl Fn(u16) -> Option<i64>) -> bool {
    if param.limits.is_none() {
        return false;
    }
    let mode_ok = param.limits_in.0 == ModeSet::ALL.0
        || value(pid::MODE)
            .and_then(|m| u32::try_from(m).ok())
            .is_some_and(|m| param.limits_in.contains(m));
    mode_ok && param.limits_if().is_none_or(|c| value(c.param) == Some(c.raw))
}

/// The parameters whose values decide whether the limits of `param` apply (`MODE` if
/// they hold in some modes only, the parameter of `limits_if`).
pub fn limit_context(param: &ParamDef) -> impl Iterator<Item = u16> {
    let mode = (param.limits.is_some() && param.limits_in.0 != ModeSet::ALL.0).then_some(pid::MODE);
    let cond = param.limits.and(param.limits_if()).map(|c| c.param);
    mode.into_iter().chain(cond)
}

/// Ground-side limit checking (collector alarms, dashboard colouring): consecutive HK
/// samples a value must be beyond a limit before its level rises, and back inside the
/// limit by [`limit_hysteresis`] before it falls. On board, PUS 12 monitors keep their own
/// persistence (`fdir::MONITORS`).
pub const GROUND_LIMIT_PERSISTENCE: u8 = 2;
/// Hysteresis around each limit for ground-side checking, in per-mille of the soft band
/// (`soft_hi - soft_lo`).
pub const GROUND_LIMIT_HYSTERESIS_PERMILLE: u16 = 20;

/// Hysteresis around each limit of `l` in engineering units
/// (`GROUND_LIMIT_HYSTERESIS_PERMILLE` of the soft band, never 0).
pub fn limit_hysteresis(l: &crate::types::Limits) -> f64 {
    ((l.soft_hi - l.soft_lo).abs() * f64::from(GROUND_LIMIT_HYSTERESIS_PERMILLE) / 1000.0).max(f64::EPSILON)
}

impl ParamDef {
    /// A condition on the robot's state under which `limits` apply, on top of
    /// `limits_in` (`None`: always). The hip deviation, for example, is only an anomaly
    /// while no motion primitive runs: a turning hip is legitimately away from the
    /// angle of the last configuration state. Use [`limits_apply`]. Derived from the ID
    /// rather than stored: a field would cost every row of board A's table 4 bytes.
    pub const fn limits_if(&self) -> Option<&'static LimitCond> {
        limits_if(self.id)
    }
    /// The module slot whose module the parameter measures ([`module_of`]).
    pub const fn module(&self) -> Option<u8> {
        module_of(self.id)
    }
    /// How the parameter's raw values are named (enumerated parameters).
    pub const fn names(&self) -> Names {
        match self.id {
            pid::MODE | pid::PENDING_MODE => ROOT_MODE_NAMES,
            pid::CONFIG_STATE | pid::TARGET_STATE => Names::State,
            pid::ACTIVE_PRIMITIVE => Names::Primitive,
            pid::BOLT_SIDE => SIDE_NAMES,
            pid::LAST_FAULT_EVENT => Names::Event,
            pid::CONFIG_ID => CONFIG_ID_NAMES,
            pid::CONFIG_STATUS => CONFIG_STATUS_NAMES,
            pid::TEAM_ROLE => crate::team::TEAM_ROLE_NAMES,
            pid::PLAN_STATE => crate::plan::STATE_NAMES,
            pid::UPDATE_OUTCOME => crate::update::OUTCOME_NAMES,
            _ => Names::None,
        }
    }
    /// The parameter as a field of a housekeeping report body.
    pub const fn field(&self) -> Field {
        Field {
            desc: self.desc,
            ..Field::new(self.name, self.ptype, "")
        }
        .unit(self.unit)
        .calib(*self.calib)
        .names(self.names())
    }
}

/// Highest parameter ID of the MIB.
const MAX_PID: usize = {
    let (mut m, mut i) = (0, 0);
    while i < PARAMS.len() {
        if PARAMS[i].id as usize > m {
            m = PARAMS[i].id as usize;
        }
        i += 1;
    }
    m
};

/// `PARAMS` index of every parameter ID (`u8::MAX`: no such parameter), built at compile
/// time: [`by_id`] is one table read instead of a scan of `PARAMS`. Every HK report
/// looks up each of its parameters (its length and each value's type), so a scan made
/// the on-board tick grow with (HK size × number of parameters); this table is
/// `MAX_PID + 1` bytes of flash.
const INDEX: [u8; MAX_PID + 1] = {
    assert!(PARAMS.len() < u8::MAX as usize, "PARAMS index must fit a u8");
    let mut t = [u8::MAX; MAX_PID + 1];
    let mut i = 0;
    while i < PARAMS.len() {
        assert!(t[PARAMS[i].id as usize] == u8::MAX, "parameter ID defined twice");
        t[PARAMS[i].id as usize] = i as u8;
        i += 1;
    }
    t
};

/// Looks a parameter up by ID.
pub fn by_id(id: u16) -> Option<&'static ParamDef> {
    INDEX.get(usize::from(id)).and_then(|&i| PARAMS.get(usize::from(i)))
}

/// The module slot (`crate::modules::slot`) whose module parameter `id` measures, for
/// parameters that have no valid value when discovery found that module absent (so
/// housekeeping carries no reading and PUS 12 does not judge one).
pub const fn module_of(id: u16) -> Option<u8> {
    use crate::modules::slot;
    match id {
        pid::I_BO_A => Some(slot::BOLTER_A),
        pid::I_BO_B | pid::BOLTER_B_STATE => Some(slot::BOLTER_B),
        pid::I_GRIP_A => Some(slot::GRIPPER_A),
        pid::I_GRIP_B => Some(slot::GRIPPER_B),
        _ => None,
    }
}

/// The component that supplies parameter `id` (`None`: no such parameter).
pub fn source(id: u16) -> Option<Source> {
    INDEX
        .get(usize::from(id))
        .and_then(|&i| SOURCES.get(usize::from(i)))
        .copied()
}

/// Looks a parameter up by mnemonic (case-insensitive).
pub fn by_name(name: &str) -> Option<&'static ParamDef> {
    PARAMS.iter().find(|p| p.name.eq_ignore_ascii_case(name))
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: ICD-05
    #[test]
    fn ids_and_names_are_unique() {
        for (i, a) in PARAMS.iter().enumerate() {
            for b in &PARAMS[i + 1..] {
                assert_ne!(a.id, b.id, "{} / {}", a.name, b.name);
                assert_ne!(a.name, b.name);
            }
        }
    }
    // verifies: ICD-05
    #[test]
    fn by_id_finds_every_parameter_and_nothing_else() {
        for p in PARAMS {
            assert_eq!(by_id(p.id).map(|q| q.name), Some(p.name));
        }
        for id in 0..=u16::MAX {
            assert_eq!(
                by_id(id).map(|p| p.id),
                PARAMS.iter().find(|p| p.id == id).map(|p| p.id)
            );
        }
    }

    fn state(mode: Option<i64>, primitive: Option<i64>) -> impl Fn(u16) -> Option<i64> {
        move |id| match id {
            pid::MODE => mode,
            pid::ACTIVE_PRIMITIVE => primitive,
            _ => None,
        }
    }

    // verifies: MMIC-MODE-01
    #[test]
    fn regulator_voltage_limits_apply_only_while_the_modules_are_powered() {
        use crate::modes::robot_mode;
        let v_reg = by_id(pid::V_REG).unwrap();
        let m = |m: u32| state(Some(m as i64), Some(0));
        assert!(!limits_apply(v_reg, m(robot_mode::STANDBY)));
        assert!(limits_apply(v_reg, m(robot_mode::OPERATIONAL)));
        assert!(limits_apply(v_reg, m(robot_mode::SAFED)));
        let v_bat = by_id(pid::V_BAT_A).unwrap();
        for mode in crate::modes::ROOT_MODES {
            assert!(limits_apply(v_bat, m(mode)));
            assert!(!limits_apply(by_id(pid::MODE).unwrap(), m(mode)), "MODE has no limits");
        }
        assert!(!limits_apply(v_reg, m(7)), "no limits in a mode the MIB does not know");
        assert!(
            limits_apply(v_bat, state(None, None)),
            "V_BAT's limits hold in every mode"
        );
        assert!(!limits_apply(v_reg, state(None, None)), "V_REG's need the mode");
        assert_eq!(limit_context(v_reg).collect::<Vec<_>>(), [pid::MODE]);
        assert_eq!(limit_context(v_bat).count(), 0);
    }

    // verifies: ALM-COND-01
    #[test]
    fn hip_deviation_limits_apply_only_while_no_primitive_runs() {
        let hip = by_id(pid::HIP_DEVIATION).unwrap();
        assert!(limits_apply(hip, state(Some(1), Some(0))));
        assert!(!limits_apply(hip, state(Some(1), Some(3))), "turning: not an anomaly");
        assert!(!limits_apply(hip, state(Some(1), None)), "unknown state: not judged");
        assert_eq!(limit_context(hip).collect::<Vec<_>>(), [pid::ACTIVE_PRIMITIVE]);
    }

    // verifies: ALM-COND-01
    #[test]
    fn every_hk_structure_carrying_a_limited_parameter_carries_its_context() {
        for h in crate::hk::HK_STRUCTS {
            for p in h.params.iter().filter_map(|id| by_id(*id)) {
                for c in limit_context(p) {
                    assert!(h.params.contains(&c), "SID {} has {} without {}", h.sid, p.name, c);
                }
                if let Some(c) = p.limits_if() {
                    let cp = by_id(c.param).unwrap();
                    assert!(c.raw >= cp.ptype.min() && c.raw <= cp.ptype.max(), "{}", p.name);
                }
            }
        }
    }

    // verifies: MMIC-AV-01
    #[test]
    fn battery_calibration_maps_empty_to_about_ten_volts() {
        let p = by_id(pid::V_BAT_A).unwrap();
        let raw = p.calib.raw(V_BAT_EMPTY);
        assert!((p.calib.eng(raw) - V_BAT_EMPTY).abs() < 0.005);
        assert!(raw > 0 && raw < 4096);
    }
}
