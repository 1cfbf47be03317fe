//! PUS 1 failure codes. Every refusal or failure of a TC carries one of these as the
//! failure notice code (u16), followed by the failure data listed for it: a field list
//! per code ([`FailureCode::data`]), the one description the wire crate, the exports and
//! the ground decoder use.

use crate::layout::{f, fields_len, Field, Names, MODULE_REASON_NAMES, ROOT_MODE_NAMES, SIDE_NAMES, SLOT_NAMES};
use crate::types::PType;

macro_rules! failure_codes {
    ($( $name:ident = $code:literal, [$($data:expr),* $(,)?], $desc:literal; )*) => {
        /// A PUS 1 failure code. Unknown codes (from a newer OBSW) decode to `Unknown`.
        /// Variants keep the MIB mnemonics (upper case) so code, ICD and SCOS agree.
        #[allow(non_camel_case_types)]
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum FailureCode {
            $( #[doc = $desc] $name, )*
            Unknown(u16),
        }
        impl FailureCode {
            pub const ALL: &'static [FailureCode] = &[ $( FailureCode::$name, )* ];
            pub const fn code(self) -> u16 {
                match self { $( FailureCode::$name => $code, )* FailureCode::Unknown(c) => c }
            }
            pub const fn from_code(c: u16) -> FailureCode {
                match c { $( $code => FailureCode::$name, )* other => FailureCode::Unknown(other) }
            }
            pub const fn name(self) -> &'static str {
                match self { $( FailureCode::$name => stringify!($name), )* FailureCode::Unknown(_) => "UNKNOWN" }
            }
            /// Fields of the failure data that follows the code (empty for an unknown code).
            pub const fn data(self) -> &'static [Field] {
                match self { $( FailureCode::$name => { const D: &[Field] = &[$($data),*]; D } )* FailureCode::Unknown(_) => &[] }
            }
            /// Length of the failure data (0 for an unknown code).
            pub const fn data_len(self) -> usize {
                fields_len(self.data())
            }
            pub const fn description(self) -> &'static str {
                match self { $( FailureCode::$name => $crate::types::text_str($desc), )* FailureCode::Unknown(_) => $crate::types::text_str("code not in this MIB") }
            }
        }
    };
}

failure_codes! {
    CRC_MISMATCH = 1, [f("crc_received", PType::U16, "crc received"), f("crc_computed", PType::U16, "crc computed")], "Packet error control (CRC-16/CCITT-FALSE) does not match";
    MALFORMED_PACKET = 2, [f("received_len", PType::U16, "received len").unit("byte"), f("expected_len", PType::U16, "expected len").unit("byte")], "Truncated packet, length field mismatch or secondary header too short";
    WRONG_APID = 3, [f("apid", PType::U16, "apid")], "APID is not this robot's";
    NOT_A_PUS_TC = 4, [f("version", PType::U8, "version"), f("type", PType::U8, "type"), f("sec_hdr", PType::U8, "sec hdr")], "Not a CCSDS version 0 telecommand with a PUS-C secondary header";
    UNKNOWN_SERVICE = 5, [f("service", PType::U8, "service")], "Service not implemented";
    UNKNOWN_SUBSERVICE = 6, [f("service", PType::U8, "service"), f("subservice", PType::U8, "subservice")], "Subservice not implemented for this service";
    UNKNOWN_FUNCTION = 7, [f("function", PType::U16, "function").names(Names::Function)], "PUS 8 function ID not defined";
    BAD_ARG_LENGTH = 8, [f("received_len", PType::U16, "received len").unit("byte"), f("expected_len", PType::U16, "expected len").unit("byte")], "Application data length does not match the command's arguments";
    ARG_OUT_OF_RANGE = 9, [f("arg_index", PType::U8, "arg index"), f("value", PType::I32, "value")], "An argument is outside its MIB range";
    NOT_ALLOWED_IN_MODE = 10, [f("mode", PType::U8, "mode").names(ROOT_MODE_NAMES)], "Command not accepted in the current mode (paper Table 7)";
    BUSY = 11, [f("running_function", PType::U16, "running function").names(Names::Function)], "Another robot action is running";
    INITIAL_STATE_MISMATCH = 12, [f("believed", PType::U8, "believed").names(Names::State), f("computed", PType::U8, "computed").names(Names::State)], "Ground's initial state differs from the state computed from sensors";
    UNREACHABLE_STATE = 13, [f("from", PType::U8, "from").names(Names::State), f("to", PType::U8, "to").names(Names::State)], "No primitive sequence of at most 3 steps connects the states (cannot happen with the current map, where every pair is within 3; kept for map changes)";
    BOLT_FAILED = 14, [f("side", PType::U8, "side").names(SIDE_NAMES), f("pair", PType::U8, "pair"), f("attempts", PType::U8, "attempts")], "A fastener pair did not lock within the allowed attempts";
    UNBOLT_FAILED = 15, [f("side", PType::U8, "side").names(SIDE_NAMES), f("pair", PType::U8, "pair"), f("attempts", PType::U8, "attempts")], "A fastener pair did not release within the allowed attempts";
    ABORTED_BY_FAULT = 16, [f("event_id", PType::U16, "event id").names(Names::Event)], "Action aborted because FDIR detected a fault";
    MODE_CHANGE_FAILED = 17, [f("node", PType::U32, "node").names(Names::Node), f("mode", PType::U32, "mode").names(Names::Mode), f("reason", PType::U16, "failure code").names(Names::FailureCode), f("event", PType::U16, "fault event or 0").names(Names::Event)], "A mode transition could not complete";
    FAULT_NOT_CLEARED = 18, [f("event_id", PType::U16, "event id").names(Names::Event)], "Recovery to operational refused while the fault is still present";
    UNKNOWN_SID = 19, [f("sid", PType::U16, "sid").names(Names::Sid)], "Housekeeping structure ID not defined";
    UNKNOWN_EVENT = 20, [f("event_id", PType::U16, "event id").names(Names::Event)], "Event ID not defined";
    UNKNOWN_PARAMETER = 21, [f("param_id", PType::U16, "param id").names(Names::Tunable)], "On-board parameter ID not defined";
    PARAM_OUT_OF_RANGE = 22, [f("param_id", PType::U16, "param id").names(Names::Tunable), f("value", PType::I32, "value")], "Value outside the parameter's range";
    UNKNOWN_MONITOR = 23, [f("monitor_id", PType::U16, "monitor id").names(Names::Monitor)], "Monitoring definition not defined";
    SCHEDULE_FULL = 24, [f("capacity", PType::U16, "capacity")], "Time-based schedule is full";
    RELEASE_TIME_PASSED = 25, [f("release_ms", PType::U32, "release ms").unit("ms")], "Release time of a scheduled TC lies in the past";
    SCHEDULED_TC_INVALID = 26, [f("inner_code", PType::U16, "inner code").names(Names::FailureCode)], "An embedded TC of TC[11,4] is not a valid TC for this robot";
    BOARD_B_NO_ACK = 27, [f("command", PType::U8, "command"), f("retries", PType::U8, "retries")], "Board B did not acknowledge a module command";
    UNKNOWN_MODE_TARGET = 28, [f("node", PType::U32, "node").names(Names::Node)], "Mode tree node not defined";
    INVALID_MODE = 29, [f("node", PType::U32, "node").names(Names::Node), f("mode", PType::U32, "mode").names(Names::Mode)], "Mode or submode not defined for the node, or not commandable there";
    UNKNOWN_ACTION_LINK = 30, [f("event_id", PType::U16, "event id").names(Names::Event)], "No event-action definition for this event";
    STORE_DISABLED = 31, [], "On-board storage is disabled";
    TIMEOUT = 32, [f("elapsed_ms", PType::U32, "elapsed ms").unit("ms")], "Action did not complete in its time limit";
    ABORTED_BY_COMMAND = 33, [f("function", PType::U16, "function").names(Names::Function)], "Action aborted by a STOP command or a commanded mode change";
    BOTH_SIDES_GRIPPED = 34, [f("grip_a_pwm", PType::U16, "grip a pwm").unit("us"), f("grip_b_pwm", PType::U16, "grip b pwm").unit("us")], "Start refused: the primitive needs a hip rotation but both grippers hold (the robot is clamped to the lattice on both sides, the hip cannot turn); data: the two gripper PWM pulse widths (us) that show both closed";
    FRAME_TOO_LONG = 35, [f("frame_len", PType::U32, "frame len").unit("byte"), f("max_len", PType::U32, "max len").unit("byte")], "Acceptance refused: a TCP or serial frame is longer than the largest packet (config::MAX_PACKET_LEN); data: the frame length and the limit";
    NESTED_SCHEDULE = 36, [f("activity", PType::U8, "activity")], "Acceptance refused: an activity of TC[11,4] embeds another TC[11,4] (schedules do not nest); data: the activity's index (0-based)";
    CONFIG_INVALID = 37, [f("reason", PType::U8, "why the module set is invalid").names(MODULE_REASON_NAMES), f("slot", PType::U8, "slot the reason names").names(SLOT_NAMES)], "Refused: the module set found at boot is invalid or unsupported (robot stays in STANDBY); data: the reason and its slot (NONE if it names none)";
    CONFIG_NOT_ACCEPTED = 38, [f("hash", PType::U32, "current configuration hash")], "OPERATIONAL refused: the module configuration differs from the one the ground accepted (MODULE_REPLACED), or is not known yet (hash 0: discovery still waits for board B, at most 1 s after boot); data: the current hash, to accept with ACCEPT_CONFIG";
    CONFIG_HASH_STALE = 39, [f("received", PType::U32, "hash in the TC"), f("current", PType::U32, "current configuration hash")], "ACCEPT_CONFIG refused: the hash is not the current configuration's";
    MODULE_ABSENT = 40, [f("slot", PType::U8, "first absent module the command needs").names(SLOT_NAMES)], "Refused: the command needs a module this robot does not have; data: its slot";
    PLAN_NOT_AUTHORISED = 45, [f("plan", PType::U16, "plan ID of the step"), f("step", PType::U16, "step number")], "TEAM_PLAN_STEP refused: no authorisation for this plan, or the step lies outside it";
    PLAN_FORBIDDEN_FUNCTION = 46, [f("function", PType::U16, "function of the step").names(Names::Function)], "TEAM_PLAN_STEP refused: the function cannot be a team step (UNBOLT_FACE, UNBOLT_PAIR, or not an action)";
    PLAN_HASH_MISMATCH = 47, [f("authorised", PType::U32, "plan hash of the authorisation"), f("uploaded", PType::U32, "hash of the uploaded steps")], "TEAM_PLAN_STEP refused: the uploaded steps do not hash to the authorised plan hash; every uploaded step of the plan is dropped";
    NO_KEY_FOR_SPI = 53, [f("spi", PType::U16, "SPI without a key on board")], "LINK_SPI_SELECT refused: the robot has no key loaded for this SPI (or has no space link); nothing changed";
    PLAN_BUSY = 70, [f("state", PType::U8, "plan state").names(crate::plan::STATE_NAMES)], "Plan: refused while a plan runs or is suspended (abort it first); data: the plan state";
    PLAN_TOO_LARGE = 71, [f("end", PType::U16, "end of the bytes in the image").unit("byte"), f("max", PType::U16, "largest image").unit("byte")], "PLAN_LOAD refused: the bytes end beyond the largest image the robot holds, or leave a gap after the staged bytes";
    PLAN_CHECKSUM = 72, [f("expected", PType::U32, "CRC-32 in the TC"), f("computed", PType::U32, "CRC-32 of the staged bytes (0 when the length is wrong)"), f("staged", PType::U16, "bytes staged").unit("byte")], "PLAN_COMMIT refused: the staged image's length or CRC-32 differs from the TC's (a chunk lost or corrupted); nothing loaded";
    PLAN_INVALID = 73, [f("reason", PType::U8, "why").names(crate::plan::INVALID_NAMES), f("offset", PType::U16, "offset in the image").unit("byte")], "PLAN_COMMIT refused: the image breaks the format or the MIB's plan limits (crate::plan)";
    PLAN_WRONG_ROBOT = 74, [f("robot", PType::U8, "robot the image is for")], "PLAN_COMMIT refused: the image is another robot's";
    PLAN_STEP_INVALID = 75, [f("step", PType::U8, "step (0-based)"), f("inner_code", PType::U16, "the code its TC would be refused with").names(Names::FailureCode)], "PLAN_COMMIT refused: a step's TC would be refused at acceptance (CRC, APID, service, arguments), or is no TC a plan may hold (PUS 18, PUS 11 insert)";
    PLAN_UNREACHABLE = 76, [f("step", PType::U8, "step (0-based)"), f("from", PType::U8, "from").names(Names::State), f("to", PType::U8, "to").names(Names::State)], "PLAN_COMMIT refused: a reconfiguration of the plan is not possible in MAX_RECONFIG_PRIMITIVES primitives of the reconfiguration map";
    PLAN_HAZARD_UNCONFIRMED = 77, [f("step", PType::U8, "step (0-based)")], "PLAN_COMMIT refused: a step's TC is hazardous and the operator's confirmation flag is not set in the image";
    PLAN_NOT_LOADED = 78, [], "Plan: no plan is loaded, or the TC names another plan ID";
    PLAN_BAD_STATE = 79, [f("state", PType::U8, "plan state").names(crate::plan::STATE_NAMES)], "Plan: the TC does not apply in the plan's state (resume of a plan not suspended, skip while running, ...)";
    UPDATE_IMAGE_REFUSED = 90, [f("reason", PType::U8, "why the image was refused").names(crate::update::REFUSAL_NAMES)], "UPDATE_INSTALL refused: the file is missing, truncated, not an image, for another target, too large, or its digest or Ed25519 signature does not verify (nothing of it may be activated)";
    UPDATE_NOT_INSTALLED = 91, [], "UPDATE_ACTIVATE refused: no verified image waits in the inactive slot (install one first)";
    UPDATE_WRONG_IMAGE = 92, [f("installed_version", PType::U32, "version of the image installed (0 = none)")], "UPDATE_ACTIVATE refused: the SHA-256 in the TC is not the installed image's (an activation written for another image)";
    UPDATE_STALE_ACTIVATION = 93, [f("version", PType::U32, "version of the image the TC names")], "UPDATE_ACTIVATE refused: the image it names is already activated or already running (a replayed or repeated activation)";
    UPDATE_NOTHING_TO_CONFIRM = 94, [], "UPDATE_CONFIRM refused: the running image is not waiting for its confirmation";
    UPDATE_SLOT_CHANGED = 95, [f("reason", PType::U8, "why the slot no longer verifies").names(crate::update::REFUSAL_NAMES)], "UPDATE_ACTIVATE refused: the inactive slot no longer verifies (checked again before otadata is written)";
    UPDATE_UNAVAILABLE = 96, [], "Update refused: this platform has no application slots (started without a boot launcher, or a board without the update store)";
    PLAN_STEP_MISMATCH = 80, [f("next", PType::U8, "the plan's next step"), f("given", PType::U8, "step in the TC")], "PLAN_SKIP refused: the step is not the suspended plan's next step";
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: PUS-1-02
    #[test]
    fn codes_round_trip_and_unknown_is_a_value() {
        for (i, c) in FailureCode::ALL.iter().enumerate() {
            assert_eq!(FailureCode::from_code(c.code()), *c);
            assert!(FailureCode::ALL[i + 1..].iter().all(|o| o.code() != c.code()));
        }
        assert_eq!(FailureCode::from_code(999), FailureCode::Unknown(999));
        assert_eq!(FailureCode::Unknown(999).code(), 999);
    }
}
