//! Telecommands and telemetry packet types.
//!
//! All TCs are CCSDS version 0 space packets with a PUS-C TC secondary header and a
//! CRC-16/CCITT-FALSE packet error control field; all TM carries a PUS-C TM secondary
//! header with a CDS short time stamp. Multi-byte fields are big-endian.

use crate::failure::FailureCode as F;
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
}

/// Set of root modes in which a TC is accepted (paper Table 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModeSet(pub u8);

impl ModeSet {
    pub const STANDBY: ModeSet = ModeSet(1);
    pub const OPERATIONAL: ModeSet = ModeSet(2);
    pub const SAFED: ModeSet = ModeSet(4);
    pub const ALL: ModeSet = ModeSet(7);
    pub const OPER_SAFED: ModeSet = ModeSet(6);
    pub const fn contains(self, root_mode: u32) -> bool {
        root_mode < 8 && self.0 & (1 << root_mode) != 0
    }
    pub const fn names(self) -> &'static str {
        match self.0 {
            7 => "standby, operational, safed",
            6 => "operational, safed",
            2 => "operational",
            _ => "?",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArgDef {
    pub name: &'static str,
    pub ptype: PType,
    pub unit: &'static str,
    pub min: i64,
    pub max: i64,
    pub desc: &'static str,
}

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
    /// Root modes in which the TC is accepted.
    pub modes: ModeSet,
    /// The TC starts a robot action that reports start, progress and completion later.
    pub long_running: bool,
    /// Failure codes specific to this TC (besides the acceptance checks every TC gets).
    pub failures: &'static [F],
    pub desc: &'static str,
}

/// Failure codes any TC can receive at acceptance.
pub const ACCEPTANCE_FAILURES: &[F] = &[
    F::CRC_MISMATCH,
    F::MALFORMED_PACKET,
    F::WRONG_APID,
    F::NOT_A_PUS_TC,
    F::UNKNOWN_SERVICE,
    F::UNKNOWN_SUBSERVICE,
    F::BAD_ARG_LENGTH,
    F::ARG_OUT_OF_RANGE,
];

const fn a(name: &'static str, ptype: PType, unit: &'static str, min: i64, max: i64, desc: &'static str) -> ArgDef {
    ArgDef {
        name,
        ptype,
        unit,
        min,
        max,
        desc,
    }
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
        modes: ModeSet::ALL,
        long_running: false,
        failures,
        desc,
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
        modes,
        long_running,
        failures,
        desc,
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
const SIDE: ArgDef = a("side", PType::U8, "", 0, 1, "0 = side A, 1 = side B");
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
const MOTION_FAIL: &[F] = &[
    F::NOT_ALLOWED_IN_MODE,
    F::BUSY,
    F::ABORTED_BY_FAULT,
    F::ABORTED_BY_COMMAND,
    F::BOARD_B_NO_ACK,
    F::TIMEOUT,
];
const BOLT_FAIL: &[F] = &[
    F::NOT_ALLOWED_IN_MODE,
    F::BUSY,
    F::ABORTED_BY_FAULT,
    F::ABORTED_BY_COMMAND,
    F::BOARD_B_NO_ACK,
    F::TIMEOUT,
    F::BOLT_FAILED,
];
const UNBOLT_FAIL: &[F] = &[
    F::NOT_ALLOWED_IN_MODE,
    F::BUSY,
    F::ABORTED_BY_FAULT,
    F::ABORTED_BY_COMMAND,
    F::BOARD_B_NO_ACK,
    F::TIMEOUT,
    F::UNBOLT_FAILED,
];
const SID: ArgDef = a("sid", PType::U16, "", 1, 65535, "housekeeping structure ID");
const EVT: ArgDef = a("event_id", PType::U16, "", 1, 65535, "event ID");
const MON: ArgDef = a("monitor_id", PType::U16, "", 1, 65535, "monitoring definition ID");
const NODE: ArgDef = a("node", PType::U32, "", 1, 4_294_967_295, "mode tree node ID");

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
    ),
    tc(
        3,
        27,
        "HK_ONE_SHOT",
        &[SID],
        &[F::UNKNOWN_SID],
        "Generate one report of a housekeeping structure now",
    ),
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
    ),
    tc(
        5,
        7,
        "EVENT_REPORT_DISABLED",
        &[],
        &[],
        "Report the list of disabled events (TM[5,8])",
    ),
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
            ),
            a("to", PType::U8, "", 0, LAST_STATE, "target state"),
        ],
        ModeSet::OPERATIONAL,
        true,
        &[
            F::NOT_ALLOWED_IN_MODE,
            F::BUSY,
            F::INITIAL_STATE_MISMATCH,
            F::UNREACHABLE_STATE,
            F::ABORTED_BY_FAULT,
            F::ABORTED_BY_COMMAND,
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
    ),
    func(
        function::HOME,
        "HOME",
        &[],
        ModeSet::OPERATIONAL,
        true,
        MOTION_FAIL,
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
    ),
    func(
        function::MOVE_GRIPPER,
        "MOVE_GRIPPER",
        &[SIDE, PWM_ARM],
        ModeSet::OPERATIONAL,
        true,
        MOTION_FAIL,
        "Debug: move one gripper to a PWM target",
    ),
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
        MOTION_FAIL,
        "Debug: rotate the hip to an angle",
    ),
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
    ),
    func(
        function::ASSEMBLY_FAULT,
        "ASSEMBLY_FAULT",
        &[a("reason", PType::U16, "", 0, 65535, "ground-defined reason code")],
        ModeSet::ALL,
        false,
        &[],
        "Assembly system operation fault: enter standby after the running motion completes",
    ),
    func(
        function::STOP,
        "STOP",
        &[],
        ModeSet::OPER_SAFED,
        false,
        &[],
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
        "Generate one time report now (TM[9,2])",
    ),
    // --- 11 scheduling ---
    tc(11, 1, "SCHED_ENABLE", &[], &[], "Enable release of scheduled TCs"),
    tc(11, 2, "SCHED_DISABLE", &[], &[], "Disable release of scheduled TCs"),
    tc(11, 3, "SCHED_RESET", &[], &[], "Delete every scheduled TC"),
    TcDef {
        variable: true,
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
            &[F::SCHEDULE_FULL, F::RELEASE_TIME_PASSED, F::SCHEDULED_TC_INVALID],
            "Insert activities: count, then per activity a CDS short release time and a complete TC",
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
    ),
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
    ),
    tc(
        12,
        8,
        "MON_REPORT",
        &[],
        &[],
        "Report all monitoring definitions (TM[12,9])",
    ),
    // --- 15 storage ---
    tc(
        15,
        1,
        "STORE_ENABLE",
        &[],
        &[],
        "Enable storage of TM in the on-board store",
    ),
    tc(15, 2, "STORE_DISABLE", &[], &[], "Disable storage of TM"),
    tc(
        15,
        9,
        "STORE_DOWNLINK",
        &[],
        &[F::STORE_DISABLED],
        "Downlink every stored packet (oldest first), then TM[15,19]",
    ),
    tc(15, 11, "STORE_DELETE", &[], &[], "Delete the store content"),
    // --- 17 test ---
    tc(17, 1, "PING", &[], &[], "Connection test: answered by TM[17,2]"),
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
    ),
    tc(
        19,
        8,
        "EA_REPORT",
        &[],
        &[],
        "Report all event-action definitions (TM[19,9])",
    ),
    // --- 20 parameters ---
    tc(
        20,
        1,
        "PARAM_REPORT",
        &[a("param_id", PType::U16, "", 1, 65535, "on-board parameter ID")],
        &[F::UNKNOWN_PARAMETER],
        "Report an on-board parameter value (TM[20,2])",
    ),
    tc(
        20,
        3,
        "PARAM_SET",
        &[
            a("param_id", PType::U16, "", 1, 65535, "on-board parameter ID"),
            a("value", PType::I32, "", i32::MIN as i64, i32::MAX as i64, "new value"),
        ],
        &[F::UNKNOWN_PARAMETER, F::PARAM_OUT_OF_RANGE],
        "Set an on-board parameter (range-checked)",
    ),
    // --- 200 modes ---
    tc(
        200,
        1,
        "MODE_SET",
        &[
            NODE,
            a("mode", PType::U32, "", 0, 2, "mode"),
            a("submode", PType::U16, "", 0, 0, "submode (0)"),
        ],
        &[
            F::UNKNOWN_MODE_TARGET,
            F::INVALID_MODE,
            F::MODE_CHANGE_FAILED,
            F::FAULT_NOT_CLEARED,
            F::BUSY,
        ],
        "Command the mode of a mode-tree node (only the robot node is commandable; children follow)",
    ),
    tc(
        200,
        3,
        "MODE_READ",
        &[NODE],
        &[F::UNKNOWN_MODE_TARGET],
        "Report the mode of a node (TM[200,6])",
    ),
    tc(
        200,
        5,
        "MODE_ANNOUNCE",
        &[NODE],
        &[F::UNKNOWN_MODE_TARGET],
        "Report the modes of a node and all its descendants",
    ),
];

impl TcDef {
    /// Length of the fixed application data (PUS 8: function ID included).
    pub fn fixed_len(&self) -> usize {
        let f = if self.service == service::FUNCTION { 2 } else { 0 };
        f + self.args.iter().map(|a| a.ptype.size()).sum::<usize>()
    }
}

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

/// A telemetry packet type (for the ICD and the ground's packet identification).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TmDef {
    pub service: u8,
    pub subservice: u8,
    pub name: &'static str,
    /// Source data layout.
    pub layout: &'static str,
    pub desc: &'static str,
}

pub const TMS: &[TmDef] = &[
    TmDef {
        service: 1,
        subservice: 1,
        name: "ACCEPTANCE_SUCCESS",
        layout: "request_id (packet id u16, psc u16)",
        desc: "TC accepted",
    },
    TmDef {
        service: 1,
        subservice: 2,
        name: "ACCEPTANCE_FAILURE",
        layout: "request_id, code u16, data",
        desc: "TC refused at acceptance",
    },
    TmDef {
        service: 1,
        subservice: 3,
        name: "START_SUCCESS",
        layout: "request_id",
        desc: "Execution started",
    },
    TmDef {
        service: 1,
        subservice: 4,
        name: "START_FAILURE",
        layout: "request_id, code u16, data",
        desc: "Execution could not start",
    },
    TmDef {
        service: 1,
        subservice: 5,
        name: "PROGRESS_SUCCESS",
        layout: "request_id, step u8",
        desc: "Step done (primitive or bolter pair)",
    },
    TmDef {
        service: 1,
        subservice: 6,
        name: "PROGRESS_FAILURE",
        layout: "request_id, step u8, code u16, data",
        desc: "Step failed",
    },
    TmDef {
        service: 1,
        subservice: 7,
        name: "COMPLETION_SUCCESS",
        layout: "request_id",
        desc: "Execution completed",
    },
    TmDef {
        service: 1,
        subservice: 8,
        name: "COMPLETION_FAILURE",
        layout: "request_id, code u16, data",
        desc: "Execution failed",
    },
    TmDef {
        service: 3,
        subservice: 25,
        name: "HK_REPORT",
        layout: "sid u16, parameters of the structure",
        desc: "Housekeeping parameter report",
    },
    TmDef {
        service: 5,
        subservice: 1,
        name: "EVENT_INFO",
        layout: "event_id u16, parameters",
        desc: "Informative event",
    },
    TmDef {
        service: 5,
        subservice: 2,
        name: "EVENT_LOW",
        layout: "event_id u16, parameters",
        desc: "Low severity anomaly",
    },
    TmDef {
        service: 5,
        subservice: 3,
        name: "EVENT_MEDIUM",
        layout: "event_id u16, parameters",
        desc: "Medium severity anomaly",
    },
    TmDef {
        service: 5,
        subservice: 4,
        name: "EVENT_HIGH",
        layout: "event_id u16, parameters",
        desc: "High severity anomaly",
    },
    TmDef {
        service: 5,
        subservice: 8,
        name: "DISABLED_EVENTS",
        layout: "count u16, event_id u16 ...",
        desc: "List of disabled events",
    },
    TmDef {
        service: 9,
        subservice: 2,
        name: "TIME_REPORT",
        layout: "rate_exp u8, CDS short time (7 bytes)",
        desc: "On-board time",
    },
    TmDef {
        service: 12,
        subservice: 9,
        name: "MON_DEFINITIONS",
        layout: "count u16, per monitor: id u16, param u16, enabled u8, low i32, high i32, persistence u16, event u16",
        desc: "Monitoring definitions",
    },
    TmDef {
        service: 12,
        subservice: 12,
        name: "MON_TRANSITION",
        layout: "monitor_id u16, param u16, value i32, limit i32, state u8 (0 ok, 1 below low, 2 above high)",
        desc: "Check transition report",
    },
    TmDef {
        service: 15,
        subservice: 19,
        name: "STORE_DOWNLINK_DONE",
        layout: "packets u32",
        desc: "End of a store downlink",
    },
    TmDef {
        service: 17,
        subservice: 2,
        name: "PING_REPLY",
        layout: "(empty)",
        desc: "Connection test report",
    },
    TmDef {
        service: 19,
        subservice: 9,
        name: "EA_DEFINITIONS",
        layout: "count u16, per link: event u16, enabled u8, mode u32, deferred u8",
        desc: "Event-action definitions",
    },
    TmDef {
        service: 20,
        subservice: 2,
        name: "PARAM_VALUE",
        layout: "param_id u16, value i32",
        desc: "On-board parameter value",
    },
    TmDef {
        service: 200,
        subservice: 6,
        name: "MODE_REPLY",
        layout: "node u32, mode u32, submode u16",
        desc: "Mode of a node",
    },
    TmDef {
        service: 200,
        subservice: 7,
        name: "MODE_CANT_REACH",
        layout: "node u32, mode u32, submode u16, reason u16",
        desc: "Mode could not be reached",
    },
];

pub fn tm_by_type(service: u8, subservice: u8) -> Option<&'static TmDef> {
    TMS.iter().find(|t| t.service == service && t.subservice == subservice)
}

#[cfg(test)]
mod tests {
    use super::*;
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
        }
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
