//! Telecommands and telemetry packet types.
//!
//! All TCs are CCSDS version 0 space packets with a PUS-C TC secondary header and a
//! CRC-16/CCITT-FALSE packet error control field; all TM carries a PUS-C TM secondary
//! header with a CDS short time stamp. Multi-byte fields are big-endian.

use crate::failure::FailureCode as F;
use crate::layout::{f, Field, Item, Names, CDS_TIME, REQUEST_ID, ROOT_MODE_NAMES, SIDE_NAMES};
use crate::robot::{servo, NUM_STATES};
use crate::types::PType;

/// PUS service numbers.
pub mod service {
    pub const VERIFICATION: u8 = 1;
    pub const HOUSEKEEPING: u8 = 3;
    pub const EVENT: u8 = 5;
    pub const FUNCTION: u8 = 8;
    pub const TIME: u8 = 9;
    pub const SCHEDULING: u8 = 11;
    pub const MONITORING: u8 = 12;
    pub const STORAGE: u8 = 15;
    pub const TEST: u8 = 17;
    pub const EVENT_ACTION: u8 = 19;
    pub const PARAMETER: u8 = 20;
    pub const MODE: u8 = 200;
    /// Mission-specific: the module set (docs/modules.md).
    pub const MODULES: u8 = 210;
    /// Team coordination without the ground (`crate::team`).
    pub const TEAM: u8 = crate::team::TEAM_SERVICE;
    /// Mission-specific: space link management (SDLS security associations, docs/space-link.md).
    pub const SPACE_LINK: u8 = 212;
    /// On-board operations procedures: plans the robot runs itself (`crate::plan`).
    pub const PLAN: u8 = 18;
    /// Mission-specific: software update in flight (`crate::update`, docs/update.md).
    pub const UPDATE: u8 = 213;
}

pub use crate::modes::ModeSet;

/// The second form of TC[11,4] (`SCHED_INSERT`): the one Yamcs 5.12's
/// `org.yamcs.pus.PusCommandPostprocessor` writes for a command issued with its option
/// `pus11ScheduleAt` ("Schedule Time"). Application data: sub-schedule ID (u8), N (u8),
/// then per activity a CUC release time with an implicit P-field and a complete TC.
/// PUS-C leaves the presence of the sub-schedule and group IDs to the mission: this robot
/// has one sub-schedule (ID [`SUB_SCHEDULE_ID`](sched_cuc::SUB_SCHEDULE_ID); another ID
/// is refused as `ARG_OUT_OF_RANGE` of argument 0) and no scheduling groups (no group ID).
/// The MIB's first form (N, then CDS with its P-field) stays: the two are told apart by
/// the second octet, the CDS P-field in the first form, N ≤ `SCHEDULE_CAPACITY` < 0x40 in
/// this one.
pub mod sched_cuc {
    /// The one time-based sub-schedule (Yamcs 5.12.8 always writes 1).
    pub const SUB_SCHEDULE_ID: u8 = 1;
    /// CUC P-field of the release time, implicit (not on the wire): agency-defined epoch,
    /// 4 octets of seconds, 2 octets of binary fraction. Yamcs' default; the exporter
    /// writes it into the post-processor's `timeEncoding` all the same.
    pub const PFIELD: u8 = 0x2E;
    /// Octets of whole seconds and of fraction (from [`PFIELD`]).
    pub const COARSE_LEN: usize = 1 + ((PFIELD as usize >> 2) & 3);
    pub const FINE_LEN: usize = PFIELD as usize & 3;
    /// Length of the release time on the wire.
    pub const TIME_LEN: usize = COARSE_LEN + FINE_LEN;
    /// The epoch is Yamcs' time scale (`TimeEncoding`): seconds since 1970 counting leap
    /// seconds, i.e. Unix time plus TAI − UTC. TAI − UTC has been 37 s since
    /// 2017-01-01 (IERS Bulletin C); a new leap second changes this constant.
    pub const TAI_MINUS_UTC_S: u64 = 37;
    /// The octet that tells the forms apart: the first form's CDS P-field.
    pub const CDS_FORM_MARK: u8 = crate::headers::CDS_SHORT_PFIELD as u8;
    const _: () = assert!(crate::config::SCHEDULE_CAPACITY < CDS_FORM_MARK as usize);
    const _: () = assert!(TIME_LEN == 6);
}

/// Bits of the PUS-C acknowledgement flags (TC secondary header).
pub mod ack {
    pub const ACCEPTANCE: u8 = 0b1000;
    pub const START: u8 = 0b0100;
    pub const PROGRESS: u8 = 0b0010;
    pub const COMPLETION: u8 = 0b0001;
    pub const ALL: u8 = ACCEPTANCE | START | PROGRESS | COMPLETION;
}

/// A TC argument is a field of the TC's application data.
pub type ArgDef = Field;

/// Most fixed arguments any TC has (the decoded argument array's length in
/// `mib_wire::codec`; checked for every TC by this module's tests).
pub const MAX_ARGS: usize = 8;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TcDef {
    pub service: u8,
    pub subservice: u8,
    /// PUS 8 function ID (0 for TCs of other services).
    pub function: u16,
    pub name: &'static str,
    pub args: &'static [ArgDef],
    /// Application data continues after the fixed arguments (e.g. embedded TCs).
    pub variable: bool,
    /// Items after the fixed arguments (empty unless `variable`).
    pub rest: &'static [Item],
    /// Root modes in which the TC is accepted.
    pub modes: ModeSet,
    /// The TC starts a robot action that reports start, progress and completion later.
    pub long_running: bool,
    /// Failure codes specific to this TC (besides the acceptance checks every TC gets).
    pub failures: &'static [F],
    /// Why the TC is hazardous (`None` if it is not): it can leave the robot less
    /// attached to the structure, forces a fault or a mode change, destroys on-board data
    /// or weakens on-board protection. Ground tools ask for confirmation before sending
    /// it; the exports mark it critical (SCOS-2000 `CCF_CRITICAL`, XTCE significance).
    pub hazard: Option<crate::types::Text>,
    /// The report the TC asks for besides its PUS 1 verification reports (`None`: none).
    /// Descriptions name no report by hand: [`TcDef::description`] adds this one's
    /// service, subservice and name, so the text cannot name the wrong one.
    pub report: Option<&'static TmDef>,
    pub desc: crate::types::Text,
}

/// Failure codes any TC can receive at acceptance (FRAME_TOO_LONG on a framed link, TCP
/// or serial, when framing merged or garbled frames).
pub const ACCEPTANCE_FAILURES: &[F] = &[
    F::CRC_MISMATCH,
    F::MALFORMED_PACKET,
    F::WRONG_APID,
    F::NOT_A_PUS_TC,
    F::UNKNOWN_SERVICE,
    F::UNKNOWN_SUBSERVICE,
    F::BAD_ARG_LENGTH,
    F::ARG_OUT_OF_RANGE,
    F::FRAME_TOO_LONG,
];

/// Every failure list is a set: no code twice in a TC's list or in [`ACCEPTANCE_FAILURES`]
/// (checked when the MIB compiles).
const fn no_code_twice(list: &[F]) -> bool {
    let mut i = 0;
    while i < list.len() {
        let mut j = i + 1;
        while j < list.len() {
            if list[i].code() == list[j].code() {
                return false;
            }
            j += 1;
        }
        i += 1;
    }
    true
}

const fn lists(list: &[F], code: F) -> bool {
    let mut i = 0;
    while i < list.len() {
        if list[i].code() == code.code() {
            return true;
        }
        i += 1;
    }
    false
}

/// The MIB's failure lists hold together: each a set, and a TC accepted in some modes
/// only lists NOT_ALLOWED_IN_MODE (the OBSW refuses it in the others with that code).
const fn failure_lists_hold() -> bool {
    if !no_code_twice(ACCEPTANCE_FAILURES) {
        return false;
    }
    let mut i = 0;
    while i < TCS.len() {
        let t = &TCS[i];
        if !no_code_twice(t.failures) {
            return false;
        }
        if t.modes.0 != ModeSet::ALL.0 && !lists(t.failures, F::NOT_ALLOWED_IN_MODE) {
            return false;
        }
        i += 1;
    }
    true
}
const _: () = assert!(
    failure_lists_hold(),
    "a TC's failure list names a code twice or misses NOT_ALLOWED_IN_MODE"
);

const fn a(name: &'static str, ptype: PType, unit: &'static str, min: i64, max: i64, desc: &'static str) -> ArgDef {
    Field::new(name, ptype, desc).unit(unit).range(min, max)
}

const fn tc(
    service: u8,
    subservice: u8,
    name: &'static str,
    args: &'static [ArgDef],
    failures: &'static [F],
    desc: &'static str,
) -> TcDef {
    TcDef {
        service,
        subservice,
        function: 0,
        name,
        args,
        variable: false,
        rest: &[],
        modes: ModeSet::ALL,
        long_running: false,
        failures,
        hazard: None,
        report: None,
        desc: crate::types::text(desc),
    }
}

const fn func(
    function: u16,
    name: &'static str,
    args: &'static [ArgDef],
    modes: ModeSet,
    long_running: bool,
    failures: &'static [F],
    desc: &'static str,
) -> TcDef {
    TcDef {
        service: service::FUNCTION,
        subservice: 1,
        function,
        name,
        args,
        variable: false,
        rest: &[],
        modes,
        long_running,
        failures,
        hazard: None,
        report: None,
        desc: crate::types::text(desc),
    }
}

/// PUS 8 function IDs.
pub mod function {
    pub const RECONFIGURE: u16 = 1;
    pub const BOLT_FACE: u16 = 2;
    pub const UNBOLT_FACE: u16 = 3;
    pub const HOME: u16 = 4;
    pub const MOVE_ARM: u16 = 5;
    pub const MOVE_GRIPPER: u16 = 6;
    pub const ROTATE_HIP: u16 = 7;
    pub const BOLT_PAIR: u16 = 8;
    pub const UNBOLT_PAIR: u16 = 9;
    pub const ASSEMBLY_FAULT: u16 = 10;
    pub const STOP: u16 = 11;
}

const LAST_STATE: i64 = NUM_STATES as i64 - 1;
const SIDE: ArgDef = a("side", PType::U8, "", 0, 1, "robot side").names(SIDE_NAMES);
const PAIR: ArgDef = a("pair", PType::U8, "", 1, 4, "fastener pair 1..4 (multiplexer A0/A1)");
const PAIRS: ArgDef = a(
    "pairs",
    PType::U8,
    "",
    1,
    15,
    "bit mask of pairs (bit 0 = pair 1); 15 = whole face",
);
const PWM_ARM: ArgDef = a(
    "pwm",
    PType::U16,
    "us",
    servo::PWM_MIN_US as i64,
    servo::PWM_MAX_US as i64,
    "target PWM pulse width",
);
/// Every robot action: refused in a mode without its power, while another runs, without a
/// module it needs (`modules::config::needs`); ended by a fault, STOP or a mode change, a
/// board B that does not answer, or its time limit.
const MOTION_FAIL: &[F] = &[
    F::NOT_ALLOWED_IN_MODE,
    F::BUSY,
    F::MODULE_ABSENT,
    F::ABORTED_BY_FAULT,
    F::ABORTED_BY_COMMAND,
    F::BOARD_B_NO_ACK,
    F::TIMEOUT,
];
/// An action that turns the hip (ROTATE_HIP, HOME): also refused while both grippers hold.
const HIP_FAIL: &[F] = &[
    F::NOT_ALLOWED_IN_MODE,
    F::BUSY,
    F::MODULE_ABSENT,
    F::BOTH_SIDES_GRIPPED,
    F::ABORTED_BY_FAULT,
    F::ABORTED_BY_COMMAND,
    F::BOARD_B_NO_ACK,
    F::TIMEOUT,
];
const BOLT_FAIL: &[F] = &[
    F::NOT_ALLOWED_IN_MODE,
    F::BUSY,
    F::MODULE_ABSENT,
    F::ABORTED_BY_FAULT,
    F::ABORTED_BY_COMMAND,
    F::BOARD_B_NO_ACK,
    F::TIMEOUT,
    F::BOLT_FAILED,
];
const UNBOLT_FAIL: &[F] = &[
    F::NOT_ALLOWED_IN_MODE,
    F::BUSY,
    F::MODULE_ABSENT,
    F::ABORTED_BY_FAULT,
    F::ABORTED_BY_COMMAND,
    F::BOARD_B_NO_ACK,
    F::TIMEOUT,
    F::UNBOLT_FAILED,
];
const SID: ArgDef = a("sid", PType::U16, "", 1, 65535, "housekeeping structure ID").names(Names::Sid);
const EVT: ArgDef = a("event_id", PType::U16, "", 1, 65535, "event ID").names(Names::Event);
const MON: ArgDef = a("monitor_id", PType::U16, "", 1, 65535, "monitoring definition ID").names(Names::Monitor);
const NODE: ArgDef = a("node", PType::U32, "", 1, 4_294_967_295, "mode tree node ID").names(Names::Node);
const TUNABLE: ArgDef = a("param_id", PType::U16, "", 1, 65535, "on-board parameter ID").names(Names::Tunable);

/// Every telecommand the OBSW accepts.
pub const TCS: &[TcDef] = &[
    // --- 3 housekeeping ---
    tc(
        3,
        5,
        "HK_ENABLE",
        &[SID],
        &[F::UNKNOWN_SID],
        "Enable periodic generation of a housekeeping structure",
    ),
    tc(
        3,
        6,
        "HK_DISABLE",
        &[SID],
        &[F::UNKNOWN_SID],
        "Disable periodic generation of a housekeeping structure",
    )
    .hazardous("stops a housekeeping report"),
    tc(
        3,
        27,
        "HK_ONE_SHOT",
        &[SID],
        &[F::UNKNOWN_SID],
        "Generate one report of a housekeeping structure now",
    )
    .reports("HK_REPORT"),
    tc(
        3,
        31,
        "HK_SET_INTERVAL",
        &[
            SID,
            a(
                "interval_ms",
                PType::U32,
                "ms",
                crate::hk::MIN_INTERVAL_MS as i64,
                crate::hk::MAX_INTERVAL_MS as i64,
                "collection interval",
            ),
        ],
        &[F::UNKNOWN_SID],
        "Modify the collection interval of a housekeeping structure",
    ),
    // --- 5 events ---
    tc(
        5,
        5,
        "EVENT_ENABLE",
        &[EVT],
        &[F::UNKNOWN_EVENT],
        "Enable reporting of an event",
    ),
    tc(
        5,
        6,
        "EVENT_DISABLE",
        &[EVT],
        &[F::UNKNOWN_EVENT],
        "Disable reporting of an event",
    )
    .hazardous("hides an event from the ground"),
    tc(
        5,
        7,
        "EVENT_REPORT_DISABLED",
        &[],
        &[],
        "Report the list of disabled events",
    )
    .reports("DISABLED_EVENTS"),
    // --- 8 functions ---
    func(
        function::RECONFIGURE,
        "RECONFIGURE",
        &[
            a(
                "from",
                PType::U8,
                "",
                0,
                LAST_STATE,
                "ground's belief of the current state",
            )
            .names(Names::State),
            a("to", PType::U8, "", 0, LAST_STATE, "target state").names(Names::State),
        ],
        ModeSet::OPERATIONAL,
        true,
        &[
            F::NOT_ALLOWED_IN_MODE,
            F::BUSY,
            F::MODULE_ABSENT,
            F::INITIAL_STATE_MISMATCH,
            F::UNREACHABLE_STATE,
            F::ABORTED_BY_FAULT,
            F::ABORTED_BY_COMMAND,
            F::BOARD_B_NO_ACK,
            F::TIMEOUT,
        ],
        "Move from one configuration state to another with 1-3 motion primitives (progress per primitive)",
    ),
    func(
        function::BOLT_FACE,
        "BOLT_FACE",
        &[SIDE, PAIRS],
        ModeSet::OPERATIONAL,
        true,
        BOLT_FAIL,
        "Bolt the selected pairs of the face under a side (progress per pair)",
    ),
    func(
        function::UNBOLT_FACE,
        "UNBOLT_FACE",
        &[SIDE, PAIRS],
        ModeSet::OPERATIONAL,
        true,
        UNBOLT_FAIL,
        "Unbolt the selected pairs of the face under a side (progress per pair)",
    )
    .hazardous("removes fasteners: the structure loses a joint"),
    func(
        function::HOME,
        "HOME",
        &[],
        ModeSet::OPERATIONAL,
        true,
        HIP_FAIL,
        "Send all actuators to home: arms contracted, grippers closed, hip at 0",
    ),
    func(
        function::MOVE_ARM,
        "MOVE_ARM",
        &[SIDE, PWM_ARM],
        ModeSet::OPER_SAFED,
        true,
        MOTION_FAIL,
        "Debug: move one arm to a PWM target",
    )
    .hazardous("direct actuator motion outside the reconfiguration planner"),
    func(
        function::MOVE_GRIPPER,
        "MOVE_GRIPPER",
        &[SIDE, PWM_ARM],
        ModeSet::OPERATIONAL,
        true,
        MOTION_FAIL,
        "Debug: move one gripper to a PWM target",
    )
    .hazardous("opening a gripper can detach the robot from the structure"),
    func(
        function::ROTATE_HIP,
        "ROTATE_HIP",
        &[a(
            "angle",
            PType::I16,
            "cdeg",
            servo::HIP_MIN_CDEG as i64,
            servo::HIP_MAX_CDEG as i64,
            "hip target angle",
        )],
        ModeSet::OPER_SAFED,
        true,
        HIP_FAIL,
        "Debug: rotate the hip to an angle",
    )
    .hazardous("direct actuator motion outside the reconfiguration planner"),
    func(
        function::BOLT_PAIR,
        "BOLT_PAIR",
        &[SIDE, PAIR],
        ModeSet::OPERATIONAL,
        true,
        BOLT_FAIL,
        "Debug: bolt one fastener pair",
    ),
    func(
        function::UNBOLT_PAIR,
        "UNBOLT_PAIR",
        &[SIDE, PAIR],
        ModeSet::OPERATIONAL,
        true,
        UNBOLT_FAIL,
        "Debug: unbolt one fastener pair",
    )
    .hazardous("removes fasteners: the structure loses a joint"),
    func(
        function::ASSEMBLY_FAULT,
        "ASSEMBLY_FAULT",
        &[a("reason", PType::U16, "", 0, 65535, "ground-defined reason code")],
        ModeSet::ALL,
        false,
        &[],
        "Assembly system operation fault: enter standby after the running motion completes",
    )
    .hazardous("forces an assembly system fault: the robot goes to standby"),
    func(
        function::STOP,
        "STOP",
        &[],
        ModeSet::OPER_SAFED,
        false,
        &[F::NOT_ALLOWED_IN_MODE],
        "Abort the running action; actuators hold position",
    ),
    // --- 9 time ---
    tc(
        9,
        1,
        "TIME_SET_RATE",
        &[a("rate_exp", PType::U8, "", 0, 8, "report every 2^n seconds")],
        &[],
        "Set the time report generation rate",
    ),
    tc(
        9,
        128,
        "TIME_REPORT_NOW",
        &[],
        &[],
        "Generate one time report now",
    )
    .reports("TIME_REPORT"),
    // --- 11 scheduling ---
    tc(11, 1, "SCHED_ENABLE", &[], &[], "Enable release of scheduled TCs"),
    tc(11, 2, "SCHED_DISABLE", &[], &[], "Disable release of scheduled TCs"),
    tc(11, 3, "SCHED_RESET", &[], &[], "Delete every scheduled TC").hazardous("deletes every scheduled TC"),
    TcDef {
        variable: true,
        rest: &[Item::Group {
            name: "activities",
            count: "count",
            max: crate::config::SCHEDULE_CAPACITY,
            items: &[
                Item::Sub {
                    name: "release_time",
                    sub: &CDS_TIME,
                },
                Item::Packet {
                    name: "tc",
                    max_len: crate::config::MAX_SCHEDULED_TC_LEN,
                },
            ],
        }],
        ..tc(
            11,
            4,
            "SCHED_INSERT",
            &[a(
                "count",
                PType::U8,
                "",
                1,
                crate::config::SCHEDULE_CAPACITY as i64,
                "number of activities",
            )],
            &[
                F::SCHEDULE_FULL,
                F::RELEASE_TIME_PASSED,
                F::SCHEDULED_TC_INVALID,
                F::NESTED_SCHEDULE,
            ],
            "Insert activities: count, then per activity a CDS short release time and a complete TC (or Yamcs' form, sched_cuc: sub-schedule ID, count, CUC release times)",
        )
    },
    // --- 12 monitoring ---
    tc(
        12,
        1,
        "MON_ENABLE",
        &[MON],
        &[F::UNKNOWN_MONITOR],
        "Enable a parameter monitoring definition",
    ),
    tc(
        12,
        2,
        "MON_DISABLE",
        &[MON],
        &[F::UNKNOWN_MONITOR],
        "Disable a parameter monitoring definition",
    )
    .hazardous("weakens on-board limit monitoring (FDIR)"),
    tc(
        12,
        7,
        "MON_MODIFY",
        &[
            MON,
            a(
                "low",
                PType::I32,
                "raw",
                i32::MIN as i64,
                i32::MAX as i64,
                "low limit (raw)",
            ),
            a(
                "high",
                PType::I32,
                "raw",
                i32::MIN as i64,
                i32::MAX as i64,
                "high limit (raw)",
            ),
            a(
                "persistence",
                PType::U16,
                "samples",
                1,
                6000,
                "consecutive violating samples before the event",
            ),
        ],
        &[F::UNKNOWN_MONITOR, F::PARAM_OUT_OF_RANGE],
        "Modify the limits and persistence of a monitoring definition",
    )
    .hazardous("weakens on-board limit monitoring (FDIR)"),
    tc(
        12,
        8,
        "MON_REPORT",
        &[],
        &[],
        "Report all monitoring definitions",
    )
    .reports("MON_DEFINITIONS"),
    // --- 15 storage ---
    tc(
        15,
        1,
        "STORE_ENABLE",
        &[],
        &[],
        "Enable storage of TM in the on-board store",
    ),
    tc(15, 2, "STORE_DISABLE", &[], &[], "Disable storage of TM")
        .hazardous("TM is no longer stored: what the link misses is lost for good"),
    tc(
        15,
        9,
        "STORE_DOWNLINK_TIME",
        &[
            a(
                "start_days",
                PType::U16,
                "day",
                0,
                65535,
                "start of the time span: CDS day (since 1958-01-01)",
            ),
            a(
                "start_ms",
                PType::U32,
                "ms",
                0,
                4_294_967_295,
                "start of the time span: ms of the day",
            ),
            a(
                "end_days",
                PType::U16,
                "day",
                0,
                65535,
                "end of the time span (inclusive): CDS day",
            ),
            a(
                "end_ms",
                PType::U32,
                "ms",
                0,
                4_294_967_295,
                "end of the time span (inclusive): ms of the day",
            ),
        ],
        &[F::STORE_DISABLED],
        "ECSS TC[15,9] by time range (the whole store: 0/0 .. 65535/4294967295): downlink (oldest \
         first) every stored packet whose on-board time stamp (CDS short, as in every TM secondary \
         header) lies in [start, end], then the end report",
    )
    .reports("STORE_DOWNLINK_DONE"),
    tc(
        15,
        128,
        "STORE_DOWNLINK_SEQ",
        &[
            a("apid", PType::U16, "", 0, 2047, "APID of the packets to downlink"),
            a("first_seq", PType::U16, "", 0, 16383, "first packet sequence count"),
            a(
                "last_seq",
                PType::U16,
                "",
                0,
                16383,
                "last packet sequence count (inclusive)",
            ),
        ],
        &[F::STORE_DISABLED],
        "Mission-specific: downlink the stored packets of one APID whose sequence count lies in \
         [first_seq, last_seq], counted modulo 2^14 (first_seq > last_seq wraps through 16383 -> 0), \
         oldest first, then the end report",
    )
    .reports("STORE_DOWNLINK_DONE"),
    tc(15, 11, "STORE_DELETE", &[], &[], "Delete the store content")
        .hazardous("empties the on-board TM store: its packets are lost for good"),
    // --- 17 test ---
    tc(17, 1, "PING", &[], &[], "Connection test").reports("PING_REPLY"),
    // --- 19 event-action ---
    tc(
        19,
        4,
        "EA_ENABLE",
        &[EVT],
        &[F::UNKNOWN_ACTION_LINK],
        "Enable the action linked to an event",
    ),
    tc(
        19,
        5,
        "EA_DISABLE",
        &[EVT],
        &[F::UNKNOWN_ACTION_LINK],
        "Disable the action linked to an event",
    )
    .hazardous("disables an on-board fault reaction (FDIR)"),
    tc(
        19,
        8,
        "EA_REPORT",
        &[],
        &[],
        "Report all event-action definitions",
    )
    .reports("EA_DEFINITIONS"),
    // --- 20 parameters ---
    tc(
        20,
        1,
        "PARAM_REPORT",
        &[TUNABLE],
        &[F::UNKNOWN_PARAMETER],
        "Report an on-board parameter value",
    )
    .reports("PARAM_VALUE"),
    tc(
        20,
        3,
        "PARAM_SET",
        &[
            TUNABLE,
            a("value", PType::I32, "", i32::MIN as i64, i32::MAX as i64, "new value"),
        ],
        &[F::UNKNOWN_PARAMETER, F::PARAM_OUT_OF_RANGE],
        "Set an on-board parameter (range-checked)",
    )
    .hazardous("changes an on-board threshold or gain"),
    // --- 200 modes ---
    tc(
        200,
        1,
        "MODE_SET",
        &[
            NODE,
            a("mode", PType::U32, "", 0, 2, "robot mode").names(ROOT_MODE_NAMES),
            a("submode", PType::U16, "", 0, 0, "submode (0)"),
        ],
        &[
            F::UNKNOWN_MODE_TARGET,
            F::INVALID_MODE,
            F::CONFIG_NOT_ACCEPTED,
            F::CONFIG_INVALID,
            F::MODE_CHANGE_FAILED,
            F::FAULT_NOT_CLEARED,
            F::BUSY,
        ],
        "Command the mode of a mode-tree node (only the robot node is commandable; children follow)",
    )
    .hazardous("changes module power (standby releases the servos)"),
    tc(
        200,
        3,
        "MODE_READ",
        &[NODE],
        &[F::UNKNOWN_MODE_TARGET],
        "Report the mode of a node",
    )
    .reports("MODE_REPLY"),
    tc(
        200,
        5,
        "MODE_ANNOUNCE",
        &[NODE],
        &[F::UNKNOWN_MODE_TARGET],
        "Report the modes of a node and all its descendants, one report each",
    )
    .reports("MODE_REPLY"),
    // --- 210 modules (mission-specific) ---
    tc(
        service::MODULES,
        1,
        "REPORT_MODULES",
        &[],
        &[],
        "Report the module set found at boot",
    )
    .reports("MODULE_REPORT"),
    tc(
        service::MODULES,
        2,
        "ACCEPT_CONFIG",
        &[a(
            "hash",
            PType::U32,
            "",
            0,
            4_294_967_295,
            "configuration hash the ground accepts (HK CONFIG_HASH, MODULE_REPORT)",
        )],
        &[F::CONFIG_INVALID, F::CONFIG_HASH_STALE],
        "Accept the module configuration found at boot by its hash: clears MODULE_REPLACED so that OPERATIONAL may be entered",
    )
    .hazardous("lets the robot operate with modules the ground has not seen before"),
    // --- 18 on-board plans (crate::plan, docs/plan-format.md) ---
    TcDef {
        variable: true,
        rest: &[Item::Group {
            name: "data",
            count: "count",
            max: crate::plan::MAX_CHUNK,
            items: &[Item::Field(f("byte", PType::U8, "image byte"))],
        }],
        ..tc(
            service::PLAN,
            crate::plan::sub::LOAD,
            "PLAN_LOAD",
            &[
                a("offset", PType::U16, "byte", 0, crate::plan::MAX_IMAGE_LEN as i64 - 1, "where the bytes go in the image"),
                a("count", PType::U8, "byte", 1, crate::plan::MAX_CHUNK as i64, "number of image bytes that follow"),
            ],
            &[F::PLAN_BUSY, F::PLAN_TOO_LARGE],
            "Plan: write bytes of a plan image into the staging buffer (a new load starts at offset 0 and clears it); refused while a plan runs or is suspended",
        )
    },
    tc(
        service::PLAN,
        crate::plan::sub::COMMIT,
        "PLAN_COMMIT",
        &[
            a("length", PType::U16, "byte", 1, crate::plan::MAX_IMAGE_LEN as i64, "image length"),
            a("crc", PType::U32, "", 0, 4_294_967_295, "CRC-32 of the image's bytes before its own CRC (the image's trailer)"),
        ],
        &[
            F::PLAN_BUSY,
            F::PLAN_CHECKSUM,
            F::PLAN_INVALID,
            F::PLAN_WRONG_ROBOT,
            F::PLAN_STEP_INVALID,
            F::PLAN_UNREACHABLE,
            F::PLAN_HAZARD_UNCONFIRMED,
        ],
        "Plan: check the staged image (length, CRC-32, format and limits, robot, every step's TC as its acceptance would, reconfigurations against the map, confirmation of every hazardous step) and keep it as the loaded plan; nothing moves",
    ),
    tc(
        service::PLAN,
        crate::plan::sub::START,
        "PLAN_START",
        &[a("plan_id", PType::U32, "", 0, 4_294_967_295, "ID of the loaded plan (a stale command for another plan is refused)")],
        &[F::PLAN_NOT_LOADED, F::PLAN_BAD_STATE],
        "Plan: start the loaded plan: its steps run on board in order, each through the checks of a ground TC, each reported in PUS 1 under its own request ID; it is the ground's approval of those steps, so a running plan continues through a ground loss (a team's hold does not stop it, a leader's step is refused as busy), and only FDIR or a PLAN TC stops it",
    )
    .hazardous("lets the robot move on its own, step after step, without the ground"),
    tc(
        service::PLAN,
        crate::plan::sub::SUSPEND,
        "PLAN_SUSPEND",
        &[],
        &[F::PLAN_BAD_STATE],
        "Plan: suspend the running plan: the running step finishes, no further step starts",
    ),
    tc(
        service::PLAN,
        crate::plan::sub::RESUME,
        "PLAN_RESUME",
        &[],
        &[F::PLAN_BAD_STATE],
        "Plan: resume a suspended plan at the step where it stopped (a failed step runs again)",
    )
    .hazardous("lets the robot move on its own again"),
    tc(
        service::PLAN,
        crate::plan::sub::ABORT,
        "PLAN_ABORT",
        &[],
        &[F::PLAN_NOT_LOADED],
        "Plan: abort the plan: no further step starts (a running action completes or is stopped as a ground STOP would); the plan stays for inspection until the next load",
    ),
    tc(
        service::PLAN,
        crate::plan::sub::SKIP,
        "PLAN_SKIP",
        &[a("step", PType::U8, "", 0, crate::plan::MAX_STEPS as i64 - 1, "the step to skip (0-based): must be the suspended plan's next step")],
        &[F::PLAN_BAD_STATE, F::PLAN_STEP_MISMATCH],
        "Plan: skip the next step of a suspended plan (counted as completed for the team's dependencies); resume with PLAN_RESUME",
    )
    .hazardous("later steps and other robots' dependencies treat the skipped step as done"),
    tc(
        service::PLAN,
        crate::plan::sub::STATUS_REQUEST,
        "PLAN_STATUS_REQUEST",
        &[],
        &[],
        "Plan: report the plan status",
    )
    .reports("PLAN_STATUS"),
    // --- 211 team coordination without the ground (docs/team.md, crate::team) ---
    tc(
        service::TEAM,
        3,
        "TEAM_AUTHORISE",
        &[
            a("plan_id", PType::U16, "", 0, 65535, "plan the leader may continue"),
            a("plan_hash", PType::U32, "", 0, 4_294_967_295, "hash of that plan"),
            a("first_step", PType::U16, "", 1, 65535, "first plan step (1-based) a leader may order"),
            a("max_steps", PType::U8, "", 1, crate::team::MAX_AUTHORISED_STEPS as i64, "most steps from first_step"),
            a("validity_s", PType::U32, "s", 1, crate::team::MAX_AUTHORISATION_MS as i64 / 1000, "validity from the upload"),
        ],
        &[F::ARG_OUT_OF_RANGE],
        "Team: authorise a leader to order CONTINUE for at most max_steps steps of one plan while the ground is away (each step still passes the initial-state check; never UNBOLT)",
    )
    .hazardous("lets robots continue a plan without the ground"),
    tc(
        service::TEAM,
        4,
        "TEAM_ROSTER",
        &[
        a("robot_1", PType::U8, "", 0, 254, "robot number 1 of the roster (0 = unused slot)"),
        a("robot_2", PType::U8, "", 0, 254, "robot number 2 of the roster (0 = unused slot)"),
        a("robot_3", PType::U8, "", 0, 254, "robot number 3 of the roster (0 = unused slot)"),
        a("robot_4", PType::U8, "", 0, 254, "robot number 4 of the roster (0 = unused slot)"),
        a("robot_5", PType::U8, "", 0, 254, "robot number 5 of the roster (0 = unused slot)"),
        a("robot_6", PType::U8, "", 0, 254, "robot number 6 of the roster (0 = unused slot)"),
        a("robot_7", PType::U8, "", 0, 254, "robot number 7 of the roster (0 = unused slot)"),
        a("robot_8", PType::U8, "", 0, 254, "robot number 8 of the roster (0 = unused slot)"),
        ],
        &[F::ARG_OUT_OF_RANGE],
        "Team: upload the roster (robot numbers in order of preference, 2..8 robots, this robot among them; 0 = unused); term and vote kept",
    ),
    tc(
        service::TEAM,
        5,
        "TEAM_STATUS_REQUEST",
        &[],
        &[],
        "Team: report the team status",
    )
    .reports("TEAM_STATUS"),
    tc(
        service::TEAM,
        crate::team::TEAM_SUBSERVICE_PLAN_STEP,
        "TEAM_PLAN_STEP",
        &[
            a("plan_id", PType::U16, "", 0, 65535, "authorised plan the step belongs to"),
            a("step", PType::U16, "", 1, 65535, "plan step number (1-based), inside the authorisation"),
            a("function", PType::U16, "", 0, 65535, "PUS 8 function ID of the step (never UNBOLT_FACE or UNBOLT_PAIR)"),
            a("arg0", PType::I32, "", i32::MIN as i64, i32::MAX as i64, "first argument of the function (0 if none)"),
            a("arg1", PType::I32, "", i32::MIN as i64, i32::MAX as i64, "second argument of the function (0 if none)"),
            a("initial_state", PType::U8, "", 0, LAST_STATE, "configuration state ID the robot must be in when the step starts"),
        ],
        &[F::PLAN_NOT_AUTHORISED, F::PLAN_FORBIDDEN_FUNCTION, F::PLAN_HASH_MISMATCH],
        "Team: upload one step of the authorised plan (the same step for every robot of the roster); once every authorised step is uploaded, their hash (mib::team::plan_hash) must equal the authorisation's plan hash, else all are dropped",
    ),
    // --- 213 software update (crate::update, docs/update.md) ---
    TcDef {
        variable: true,
        rest: &[Item::Group {
            name: "name",
            count: "name_len",
            max: crate::update::MAX_FILE_NAME,
            items: &[Item::Field(f("char", PType::U8, "file name byte (ASCII)"))],
        }],
        ..tc(
            service::UPDATE,
            crate::update::sub::INSTALL,
            "UPDATE_INSTALL",
            &[a("name_len", PType::U8, "byte", 1, crate::update::MAX_FILE_NAME as i64, "length of the file name that follows")],
            &[F::UPDATE_IMAGE_REFUSED, F::UPDATE_UNAVAILABLE],
            "Update: copy the named file of the file store (uploaded with CFDP) into the inactive application slot and verify what the slot holds: header, SHA-256 of the payload, Ed25519 signature of the ground update key; nothing boots it yet",
        )
    },
    tc(
        service::UPDATE,
        crate::update::sub::ACTIVATE,
        "UPDATE_ACTIVATE",
        &[
            a("digest_0", PType::U32, "", 0, 4_294_967_295, "SHA-256 of the image's payload, bytes 0..4 (big-endian)"),
            a("digest_1", PType::U32, "", 0, 4_294_967_295, "SHA-256 of the image's payload, bytes 4..8 (big-endian)"),
            a("digest_2", PType::U32, "", 0, 4_294_967_295, "SHA-256 of the image's payload, bytes 8..12 (big-endian)"),
            a("digest_3", PType::U32, "", 0, 4_294_967_295, "SHA-256 of the image's payload, bytes 12..16 (big-endian)"),
            a("digest_4", PType::U32, "", 0, 4_294_967_295, "SHA-256 of the image's payload, bytes 16..20 (big-endian)"),
            a("digest_5", PType::U32, "", 0, 4_294_967_295, "SHA-256 of the image's payload, bytes 20..24 (big-endian)"),
            a("digest_6", PType::U32, "", 0, 4_294_967_295, "SHA-256 of the image's payload, bytes 24..28 (big-endian)"),
            a("digest_7", PType::U32, "", 0, 4_294_967_295, "SHA-256 of the image's payload, bytes 28..32 (big-endian)"),
        ],
        &[
            F::UPDATE_NOT_INSTALLED,
            F::UPDATE_WRONG_IMAGE,
            F::UPDATE_STALE_ACTIVATION,
            F::UPDATE_SLOT_CHANGED,
            F::UPDATE_UNAVAILABLE,
        ],
        "Update: verify the installed image again and make it the one that boots (otadata NEW), then reset into it; it must confirm after its self-test or the next boot returns to this image. The SHA-256 must be the installed image's; an image already activated or running is refused",
    )
    .hazardous("replaces the running software"),
    tc(
        service::UPDATE,
        crate::update::sub::CONFIRM,
        "UPDATE_CONFIRM",
        &[],
        &[F::UPDATE_NOTHING_TO_CONFIRM, F::UPDATE_UNAVAILABLE],
        "Update: confirm the running image (otadata VALID) — what its self-test does on its own after a good start",
    ),
    tc(
        service::SPACE_LINK,
        1,
        "LINK_SPI_SELECT",
        &[
            a("tm_spi", PType::U16, "", 17, 18, "TM SPI to send under from now on (crate::link::sdls::TM_SPIS)"),
            a("tc_spis", PType::U8, "", 1, 3, "TC SPIs accepted from now on: bit 0 = SPI 1, bit 1 = SPI 2; the other is retired"),
        ],
        &[F::NO_KEY_FOR_SPI],
        "Space link key change without downtime: TM under tm_spi, TC accepted under the SPIs of tc_spis only (stored on board before it takes effect; survives restarts). Refused with NO_KEY_FOR_SPI when the robot has no key for one of them",
    )
    .hazardous("a ground without the keys of the selected SPIs can no longer command the robot or read its TM"),
];

impl TcDef {
    /// The same TC, answered by the report of the MIB named `tm` (in [`TMS`]; a name
    /// that is not there does not compile).
    pub const fn reports(self, tm: &'static str) -> TcDef {
        TcDef {
            report: Some(tm_by_name(tm)),
            ..self
        }
    }
    /// The description as the ICD and the exports show it: the MIB text, then the report
    /// the TC asks for, named from [`TcDef::report`].
    #[cfg(feature = "descriptions")]
    pub fn description(&self) -> TcDescription<'_> {
        TcDescription(self)
    }
    /// True when the MIB says the OBSW may send failure `code` for this TC: a code of
    /// [`ACCEPTANCE_FAILURES`] or of the TC's own list.
    pub fn may_fail_with(&self, code: u16) -> bool {
        ACCEPTANCE_FAILURES
            .iter()
            .chain(self.failures)
            .any(|f| f.code() == code)
    }
    /// The same TC, marked hazardous for the reason `why`.
    pub const fn hazardous(self, why: &'static str) -> TcDef {
        TcDef {
            hazard: Some(crate::types::text(why)),
            ..self
        }
    }
    /// PUS-C acknowledgement flags (TC secondary header, 4 bits: 0b1000 acceptance,
    /// 0b0100 start, 0b0010 progress, 0b0001 completion) a mission control system sets
    /// on this TC without asking the operator: acceptance, start and completion for every
    /// TC, progress as well for a robot action (it reports its steps).
    pub const fn ack_flags(&self) -> u8 {
        if self.long_running {
            ack::ALL
        } else {
            ack::ACCEPTANCE | ack::START | ack::COMPLETION
        }
    }
    /// Length of the fixed application data (PUS 8: function ID included).
    pub fn fixed_len(&self) -> usize {
        let f = if self.service == service::FUNCTION { 2 } else { 0 };
        f + self.args.iter().map(|a| a.ptype.size()).sum::<usize>()
    }
}

/// A TC's description with the report it asks for ([`TcDef::description`]).
#[cfg(feature = "descriptions")]
#[derive(Clone, Copy, Debug)]
pub struct TcDescription<'a>(&'a TcDef);

#[cfg(feature = "descriptions")]
impl core::fmt::Display for TcDescription<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.0.desc)?;
        if let Some(r) = self.0.report {
            write!(f, " (answered by TM[{},{}] {})", r.service, r.subservice, r.name)?;
        }
        Ok(())
    }
}

/// The report of [`TMS`] named `name`, at compile time (a missing name fails the build).
const fn tm_by_name(name: &str) -> &'static TmDef {
    let mut i = 0;
    while i < TMS.len() {
        if const_str_eq(TMS[i].name, name) {
            return &TMS[i];
        }
        i += 1;
    }
    panic!("no TM of that name in TMS")
}

use crate::headers::const_str_eq;

/// Finds the TC definition for a service/subservice (and function ID for PUS 8).
pub fn lookup(service: u8, subservice: u8, function: Option<u16>) -> Option<&'static TcDef> {
    TCS.iter().find(|t| {
        t.service == service
            && t.subservice == subservice
            && (t.service != service::FUNCTION || Some(t.function) == function)
    })
}

pub fn by_name(name: &str) -> Option<&'static TcDef> {
    TCS.iter().find(|t| t.name.eq_ignore_ascii_case(name))
}

/// True if the service is implemented at all.
pub fn service_known(service: u8) -> bool {
    TCS.iter().any(|t| t.service == service)
}

/// True if the service/subservice pair is implemented.
pub fn subservice_known(service: u8, subservice: u8) -> bool {
    TCS.iter().any(|t| t.service == service && t.subservice == subservice)
}

/// A telemetry packet type: its source data as a list of items.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TmDef {
    pub service: u8,
    pub subservice: u8,
    pub name: &'static str,
    /// Source data, field by field.
    pub body: &'static [Item],
    pub desc: crate::types::Text,
}

const fn tm(service: u8, subservice: u8, name: &'static str, body: &'static [Item], desc: &'static str) -> TmDef {
    TmDef {
        service,
        subservice,
        name,
        body,
        desc: crate::types::text(desc),
    }
}

const RID: Item = Item::Sub {
    name: "request_id",
    sub: &REQUEST_ID,
};
const STEP: Item = Item::Field(f(
    "step",
    PType::U8,
    "step number (primitive 1..3 or fastener pair 1..4)",
));
const FAILURE_CODE: Item = Item::Field(f("failure_code", PType::U16, "PUS 1 failure code").names(Names::FailureCode));
const FAILURE_DATA: Item = Item::Tail(crate::layout::Tail::FailureData);
const TM_NODE: Item = Item::Field(f("node", PType::U32, "mode tree node").names(Names::Node));
const TM_MODE: Item = Item::Field(f("mode", PType::U32, "mode").names(Names::Mode));
const TM_SUBMODE: Item = Item::Field(f(
    "submode",
    PType::U16,
    "submode (robot: 0 idle, 1 executing an action)",
));
const EVENT_BODY: &[Item] = &[
    Item::Field(f("event_id", PType::U16, "event ID").names(Names::Event)),
    Item::Tail(crate::layout::Tail::EventParams),
];
/// Most entries of the list reports: every event, monitor, fault (event-action link).
const MAX_EVENTS: usize = crate::events::EVENTS.len();
const MAX_MONITORS: usize = crate::fdir::MONITORS.len();
const MAX_LINKS: usize = crate::fdir::FAULTS.len();

/// Every telemetry packet type the OBSW emits.
pub const TMS: &[TmDef] = &[
    tm(1, 1, "ACCEPTANCE_SUCCESS", &[RID], "TC accepted"),
    tm(
        1,
        2,
        "ACCEPTANCE_FAILURE",
        &[RID, FAILURE_CODE, FAILURE_DATA],
        "TC refused at acceptance",
    ),
    tm(1, 3, "START_SUCCESS", &[RID], "Execution started"),
    tm(
        1,
        4,
        "START_FAILURE",
        &[RID, FAILURE_CODE, FAILURE_DATA],
        "Execution could not start",
    ),
    tm(
        1,
        5,
        "PROGRESS_SUCCESS",
        &[RID, STEP],
        "Step done (primitive or bolter pair)",
    ),
    tm(
        1,
        6,
        "PROGRESS_FAILURE",
        &[RID, STEP, FAILURE_CODE, FAILURE_DATA],
        "Step failed",
    ),
    tm(1, 7, "COMPLETION_SUCCESS", &[RID], "Execution completed"),
    tm(
        1,
        8,
        "COMPLETION_FAILURE",
        &[RID, FAILURE_CODE, FAILURE_DATA],
        "Execution failed",
    ),
    tm(
        3,
        25,
        "HK_REPORT",
        &[
            Item::Field(f("sid", PType::U16, "housekeeping structure ID").names(Names::Sid)),
            Item::Tail(crate::layout::Tail::HkParams),
        ],
        "Housekeeping parameter report",
    ),
    tm(5, 1, "EVENT_INFO", EVENT_BODY, "Informative event"),
    tm(5, 2, "EVENT_LOW", EVENT_BODY, "Low severity anomaly"),
    tm(5, 3, "EVENT_MEDIUM", EVENT_BODY, "Medium severity anomaly"),
    tm(5, 4, "EVENT_HIGH", EVENT_BODY, "High severity anomaly"),
    tm(
        5,
        8,
        "DISABLED_EVENTS",
        &[
            Item::Field(f("count", PType::U16, "number of disabled events").range(0, MAX_EVENTS as i64)),
            Item::Group {
                name: "events",
                count: "count",
                max: MAX_EVENTS,
                items: &[Item::Field(
                    f("event_id", PType::U16, "disabled event").names(Names::Event),
                )],
            },
        ],
        "List of disabled events",
    ),
    tm(
        9,
        2,
        "TIME_REPORT",
        &[
            Item::Field(f("rate_exp", PType::U8, "report every 2^n seconds").range(0, 8)),
            Item::Sub {
                name: "time",
                sub: &CDS_TIME,
            },
        ],
        "On-board time",
    ),
    tm(
        12,
        9,
        "MON_DEFINITIONS",
        &[
            Item::Field(f("count", PType::U16, "number of monitoring definitions").range(0, MAX_MONITORS as i64)),
            Item::Group {
                name: "monitors",
                count: "count",
                max: MAX_MONITORS,
                items: &[
                    Item::Field(f("monitor_id", PType::U16, "monitoring definition").names(Names::Monitor)),
                    Item::Field(f("param", PType::U16, "monitored parameter").names(Names::Param)),
                    Item::Field(f("enabled", PType::U8, "1 = enabled").names(crate::layout::BOOL_NAMES)),
                    Item::Field(f("low", PType::I32, "low limit (raw)")),
                    Item::Field(f("high", PType::I32, "high limit (raw)")),
                    Item::Field(f("persistence", PType::U16, "consecutive violating samples").unit("samples")),
                    Item::Field(f("event", PType::U16, "event raised").names(Names::Event)),
                ],
            },
        ],
        "Monitoring definitions",
    ),
    tm(
        12,
        12,
        "MON_TRANSITION",
        &[
            Item::Field(f("monitor_id", PType::U16, "monitoring definition").names(Names::Monitor)),
            Item::Field(f("param", PType::U16, "monitored parameter").names(Names::Param)),
            Item::Field(f("value", PType::I32, "parameter value (raw)")),
            Item::Field(f("limit", PType::I32, "limit crossed (raw)")),
            Item::Field(f("state", PType::U8, "new check state").names(crate::layout::CHECK_STATE_NAMES)),
        ],
        "Check transition report",
    ),
    tm(
        15,
        19,
        "STORE_DOWNLINK_DONE",
        &[
            Item::Field(f("packets", PType::U32, "packets sent by this downlink")),
            Item::Sub {
                name: "oldest_time",
                sub: &CDS_TIME,
            },
            Item::Field(f("oldest_seq", PType::U16, "sequence count of the oldest stored packet").range(0, 16383)),
            Item::Field(f(
                "overwritten",
                PType::U32,
                "stored packets overwritten since boot (store full)",
            )),
        ],
        "End of a store downlink: packets sent; on-board time and sequence count of the oldest packet \
         still in the store (of the request's APID for TC[15,128], of any APID for TC[15,9]; all 0 when \
         the store is empty); packets overwritten since boot. Anything the ground misses that is older \
         than the oldest stored packet is unrecoverable",
    ),
    tm(17, 2, "PING_REPLY", &[], "Connection test report"),
    tm(
        19,
        9,
        "EA_DEFINITIONS",
        &[
            Item::Field(f("count", PType::U16, "number of event-action links").range(0, MAX_LINKS as i64)),
            Item::Group {
                name: "links",
                count: "count",
                max: MAX_LINKS,
                items: &[
                    Item::Field(f("event", PType::U16, "triggering event").names(Names::Event)),
                    Item::Field(f("enabled", PType::U8, "1 = enabled").names(crate::layout::BOOL_NAMES)),
                    Item::Field(f("mode", PType::U32, "robot mode commanded").names(Names::Mode)),
                    Item::Field(
                        f("deferred", PType::U8, "1 = after the running motion completes")
                            .names(crate::layout::BOOL_NAMES),
                    ),
                ],
            },
        ],
        "Event-action definitions",
    ),
    tm(
        20,
        2,
        "PARAM_VALUE",
        &[
            Item::Field(f("param_id", PType::U16, "on-board parameter").names(Names::Tunable)),
            Item::Field(f("value", PType::I32, "value (unit of the parameter)")),
        ],
        "On-board parameter value",
    ),
    tm(200, 6, "MODE_REPLY", &[TM_NODE, TM_MODE, TM_SUBMODE], "Mode of a node"),
    tm(
        200,
        7,
        "MODE_CANT_REACH",
        &[
            TM_NODE,
            TM_MODE,
            TM_SUBMODE,
            Item::Field(f("reason", PType::U16, "why (failure code)").names(Names::FailureCode)),
        ],
        "Mode could not be reached",
    ),
    tm(
        service::MODULES,
        3,
        "MODULE_REPORT",
        MODULE_REPORT_BODY,
        "Module set found at boot (sent at boot and on REPORT_MODULES): configuration hash, supported \
         configuration, reason it is invalid, state against the ground-accepted configuration, and the \
         descriptor of every present slot (mib::modules::report::ModuleReport; the ground rebuilds the \
         module set and its URDF from it)",
    ),
    tm(
        service::PLAN,
        crate::plan::sub::STATUS,
        "PLAN_STATUS",
        &[
            Item::Field(f("plan_id", PType::U32, "ID of the plan (0 = none)")),
            Item::Field(f("state", PType::U8, "plan state").names(crate::plan::STATE_NAMES)),
            Item::Field(f("steps", PType::U8, "steps in this robot's image")),
            Item::Field(f("next_step", PType::U8, "next step to run or running (0-based)")),
            Item::Field(f("done", PType::U8, "steps completed")),
            Item::Field(f(
                "wait_robot",
                PType::U8,
                "robot whose step the next step waits for (0 = none)",
            )),
            Item::Field(f("wait_step", PType::U8, "that robot's step (0-based)")),
        ],
        "Plan status: what runs, where it is and what it waits for",
    ),
    tm(
        service::TEAM,
        2,
        "TEAM_STATUS",
        &[
            Item::Field(f("term", PType::U32, "current election term")),
            Item::Field(f("role", PType::U8, "team role").names(crate::team::TEAM_ROLE_NAMES)),
            Item::Field(f("leader", PType::U8, "leader of the term (0 = none known)")),
            Item::Field(
                f(
                    "ground_seen",
                    PType::U8,
                    "1 = a valid ground TC within GROUND_LOSS_TIMEOUT_MS",
                )
                .names(crate::layout::BOOL_NAMES),
            ),
            Item::Field(
                f("lease", PType::U8, "1 = this robot leads and holds the lease").names(crate::layout::BOOL_NAMES),
            ),
            Item::Field(f("voted_for", PType::U8, "vote cast in the term (0 = none)")),
            Item::Field(f("auth_plan", PType::U16, "authorised plan ID")),
            Item::Field(f("auth_first_step", PType::U16, "first authorised step")),
            Item::Field(f("auth_steps", PType::U8, "authorised steps (0 = no authorisation)")),
            Item::Field(
                f(
                    "auth_left_s",
                    PType::U32,
                    "seconds until the authorisation expires (0 = expired or none)",
                )
                .unit("s"),
            ),
            Item::Field(f("refused", PType::U32, "directives refused since boot")),
            Item::Field(f(
                "foreign",
                PType::U32,
                "team messages from outside the roster since boot",
            )),
            Item::Field(
                f("roster_len", PType::U8, "robots in the roster (0 = no roster)")
                    .range(0, crate::team::ROSTER_MAX as i64),
            ),
            Item::Group {
                name: "roster",
                count: "roster_len",
                max: crate::team::ROSTER_MAX,
                items: &[Item::Field(f(
                    "robot",
                    PType::U8,
                    "robot number, in order of preference",
                ))],
            },
        ],
        "Team status: term, role, leader, ground seen, authorisation, roster",
    ),
];

const CAL: &str = "calibration word (meaning per module type, docs/modules.md)";
/// Body of TM[210,3]: `mib::modules::report::ModuleReport`.
const MODULE_REPORT_BODY: &[Item] = &[
    Item::Field(f(
        "hash",
        PType::U32,
        "configuration hash of the present slots' descriptors",
    )),
    Item::Field(
        f(
            "config_id",
            PType::U8,
            "supported configuration (0 = none: invalid set)",
        )
        .names(crate::layout::CONFIG_ID_NAMES),
    ),
    Item::Field(f("reason", PType::U8, "why the set is invalid (0 = valid)").names(crate::layout::MODULE_REASON_NAMES)),
    Item::Field(f("reason_slot", PType::U8, "slot the reason names (255 = none)").names(crate::layout::SLOT_NAMES)),
    Item::Field(
        f("replacement", PType::U8, "against the ground-accepted configuration")
            .names(crate::layout::REPLACEMENT_NAMES),
    ),
    Item::Field(
        f("present", PType::U16, "present slots (bit n = slot n)").range(0, (1 << crate::modules::NUM_SLOTS) - 1),
    ),
    Item::Field(
        f("count", PType::U8, "number of descriptors (present slots)").range(0, crate::modules::NUM_SLOTS as i64),
    ),
    Item::Group {
        name: "descriptors",
        count: "count",
        max: crate::modules::NUM_SLOTS,
        items: &[
            Item::Field(f("layout", PType::U8, "descriptor layout version").range(1, 1)),
            Item::Field(f("module_type", PType::U8, "module type").names(crate::layout::MODULE_TYPE_NAMES)),
            Item::Field(f("variant", PType::U8, "variant")),
            Item::Field(f("revision", PType::U8, "revision")),
            Item::Field(f("serial", PType::U32, "serial number")),
            Item::Field(f("side", PType::U8, "side").names(crate::layout::MODULE_SIDE_NAMES)),
            Item::Field(f("port", PType::U8, "PWM channel, I2C address, or 0 for a board")),
            Item::Field(f("cal0", PType::I16, CAL)),
            Item::Field(f("cal1", PType::I16, CAL)),
            Item::Field(f("cal2", PType::I16, CAL)),
            Item::Field(f("cal3", PType::I16, CAL)),
            Item::Field(f("cal4", PType::I16, CAL)),
            Item::Field(f("cal5", PType::I16, CAL)),
            Item::Field(f("cal6", PType::I16, CAL)),
            Item::Field(f("cal7", PType::I16, CAL)),
            Item::Field(f(
                "crc",
                PType::U16,
                "CRC-16/CCITT-FALSE over the descriptor's first 26 bytes",
            )),
        ],
    },
];

pub fn tm_by_type(service: u8, subservice: u8) -> Option<&'static TmDef> {
    TMS.iter().find(|t| t.service == service && t.subservice == subservice)
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: PUS-1-05
    #[test]
    fn failure_lists_are_sets_and_name_the_mode_refusal() {
        // The compile-time check rests on these: a repeat and a missing mode refusal are seen.
        assert!(!no_code_twice(&[F::BUSY, F::TIMEOUT, F::BUSY]));
        assert!(no_code_twice(&[F::BUSY, F::TIMEOUT]));
        assert!(lists(MOTION_FAIL, F::NOT_ALLOWED_IN_MODE) && !lists(&[F::BUSY], F::NOT_ALLOWED_IN_MODE));
        assert!(failure_lists_hold());
        // The codes the review of the lists found missing are there now.
        let of = |n: &str| by_name(n).unwrap().failures;
        assert!(lists(of("BOLT_FACE"), F::MODULE_ABSENT));
        assert!(lists(of("MODE_SET"), F::CONFIG_NOT_ACCEPTED) && lists(of("MODE_SET"), F::CONFIG_INVALID));
    }
    // verifies: ICD-01
    #[test]
    fn a_tc_names_its_report_from_the_mib_not_by_hand() {
        // No description types a TM kind: TcDef::report names it.
        for t in TCS {
            assert!(
                !t.desc.contains("TM["),
                "{}: name the report with .reports(), not in the text",
                t.name
            );
            if let Some(r) = t.report {
                assert!(TMS.iter().any(|m| core::ptr::eq(m, r)), "{}", t.name);
                let d = t.description().to_string();
                assert!(
                    d.ends_with(&format!("(answered by TM[{},{}] {})", r.service, r.subservice, r.name)),
                    "{d}"
                );
            }
        }
        let status = by_name("TEAM_STATUS_REQUEST").unwrap();
        assert_eq!(
            status.report.map(|r| (r.service, r.subservice, r.name)),
            Some((service::TEAM, 2, "TEAM_STATUS"))
        );
        assert!(status.description().to_string().contains("TM[211,2] TEAM_STATUS"));
        assert_eq!(
            by_name("PING").unwrap().report.map(|r| (r.service, r.subservice)),
            Some((17, 2))
        );
    }
    // verifies: MMIC-CMD-06
    #[test]
    fn tc_names_and_keys_unique() {
        for (i, t) in TCS.iter().enumerate() {
            for o in &TCS[i + 1..] {
                assert_ne!(t.name, o.name);
                assert!(!(t.service == o.service && t.subservice == o.subservice && t.function == o.function));
            }
            for a in t.args {
                assert!(
                    a.min >= a.ptype.min() && a.max <= a.ptype.max() && a.min <= a.max,
                    "{} {}",
                    t.name,
                    a.name
                );
            }
            assert!(t.fixed_len() <= crate::config::MAX_TC_APP_DATA);
            assert!(t.args.len() <= MAX_ARGS, "{}", t.name);
        }
    }
    // verifies: MMIC-CMD-06
    #[test]
    fn hazardous_tcs_are_those_that_detach_force_or_destroy() {
        let hazardous: Vec<&str> = TCS.iter().filter(|t| t.hazard.is_some()).map(|t| t.name).collect();
        assert_eq!(
            hazardous,
            [
                "HK_DISABLE",
                "EVENT_DISABLE",
                "UNBOLT_FACE",
                "MOVE_ARM",
                "MOVE_GRIPPER",
                "ROTATE_HIP",
                "UNBOLT_PAIR",
                "ASSEMBLY_FAULT",
                "SCHED_RESET",
                "MON_DISABLE",
                "MON_MODIFY",
                "STORE_DISABLE",
                "STORE_DELETE",
                "EA_DISABLE",
                "PARAM_SET",
                "MODE_SET",
                "ACCEPT_CONFIG",
                "PLAN_START",
                "PLAN_RESUME",
                "PLAN_SKIP",
                "TEAM_AUTHORISE",
                "UPDATE_ACTIVATE",
                "LINK_SPI_SELECT",
            ]
        );
        for t in TCS {
            assert!(t.hazard.is_none_or(|h| !h.is_empty()), "{}", t.name);
        }
    }
    // verifies: MMIC-CMD-06
    #[test]
    fn every_enumerated_argument_names_values_in_its_range() {
        // Arguments that select one of a set of MIB items carry their names.
        for t in TCS {
            for a in t.args {
                let enumerated = matches!(
                    a.name,
                    "side" | "from" | "to" | "node" | "mode" | "sid" | "event_id" | "monitor_id" | "param_id"
                );
                assert_eq!(!a.names.is_none(), enumerated, "{} {}", t.name, a.name);
                let mut n = 0;
                a.names.for_each(|v, _| n += usize::from((a.min..=a.max).contains(&v)));
                assert!(
                    !enumerated || n > 0,
                    "{} {} names no value in its range",
                    t.name,
                    a.name
                );
            }
        }
        let mode = by_name("MODE_SET").unwrap().args[1];
        assert_eq!(mode.names.name(1), Some("OPERATIONAL"));
    }
    // verifies: MMIC-MODE-01
    #[test]
    fn table7_standby_accepts_no_robot_function_and_safed_only_hip_and_arm() {
        for t in TCS
            .iter()
            .filter(|t| t.service == service::FUNCTION && t.function != function::ASSEMBLY_FAULT)
        {
            assert!(!t.modes.contains(crate::modes::robot_mode::STANDBY), "{}", t.name);
        }
        let safed: Vec<_> = TCS
            .iter()
            .filter(|t| t.service == service::FUNCTION && t.modes.contains(crate::modes::robot_mode::SAFED))
            .map(|t| t.function)
            .collect();
        assert_eq!(
            safed,
            vec![
                function::MOVE_ARM,
                function::ROTATE_HIP,
                function::ASSEMBLY_FAULT,
                function::STOP
            ]
        );
    }
}
