//! PUS 1 failure codes. Every refusal or failure of a TC carries one of these as the
//! failure notice code (u16), followed by the failure data listed for it.

macro_rules! failure_codes {
    ($( $name:ident = $code:literal, $data:literal, $desc:literal; )*) => {
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
            /// Layout of the failure data that follows the code.
            pub const fn data_layout(self) -> &'static str {
                match self { $( FailureCode::$name => $data, )* FailureCode::Unknown(_) => "" }
            }
            pub const fn description(self) -> &'static str {
                match self { $( FailureCode::$name => $desc, )* FailureCode::Unknown(_) => "code not in this MIB" }
            }
        }
    };
}

failure_codes! {
    CRC_MISMATCH = 1, "crc_received u16, crc_computed u16", "Packet error control (CRC-16/CCITT-FALSE) does not match";
    MALFORMED_PACKET = 2, "received_len u16, expected_len u16", "Truncated packet, length field mismatch or secondary header too short";
    WRONG_APID = 3, "apid u16", "APID is not this robot's";
    NOT_A_PUS_TC = 4, "version u8, type u8, sec_hdr u8", "Not a CCSDS version 0 telecommand with a PUS-C secondary header";
    UNKNOWN_SERVICE = 5, "service u8", "Service not implemented";
    UNKNOWN_SUBSERVICE = 6, "service u8, subservice u8", "Subservice not implemented for this service";
    UNKNOWN_FUNCTION = 7, "function u16", "PUS 8 function ID not defined";
    BAD_ARG_LENGTH = 8, "received_len u16, expected_len u16", "Application data length does not match the command's arguments";
    ARG_OUT_OF_RANGE = 9, "arg_index u8, value i32", "An argument is outside its MIB range";
    NOT_ALLOWED_IN_MODE = 10, "mode u8", "Command not accepted in the current mode (paper Table 7)";
    BUSY = 11, "running_function u16", "Another robot action is running";
    INITIAL_STATE_MISMATCH = 12, "believed u8, computed u8", "Ground's initial state differs from the state computed from sensors";
    UNREACHABLE_STATE = 13, "from u8, to u8", "No primitive sequence of at most 3 steps connects the states (cannot happen with the current map, where every pair is within 3; kept for map changes)";
    BOLT_FAILED = 14, "side u8, pair u8, attempts u8", "A fastener pair did not lock within the allowed attempts";
    UNBOLT_FAILED = 15, "side u8, pair u8, attempts u8", "A fastener pair did not release within the allowed attempts";
    ABORTED_BY_FAULT = 16, "event_id u16", "Action aborted because FDIR detected a fault";
    MODE_CHANGE_FAILED = 17, "node u32, mode u32, reason u16 (failure code), event u16 (fault event or 0)", "A mode transition could not complete";
    FAULT_NOT_CLEARED = 18, "event_id u16", "Recovery to operational refused while the fault is still present";
    UNKNOWN_SID = 19, "sid u16", "Housekeeping structure ID not defined";
    UNKNOWN_EVENT = 20, "event_id u16", "Event ID not defined";
    UNKNOWN_PARAMETER = 21, "param_id u16", "On-board parameter ID not defined";
    PARAM_OUT_OF_RANGE = 22, "param_id u16, value i32", "Value outside the parameter's range";
    UNKNOWN_MONITOR = 23, "monitor_id u16", "Monitoring definition not defined";
    SCHEDULE_FULL = 24, "capacity u16", "Time-based schedule is full";
    RELEASE_TIME_PASSED = 25, "release_ms u32", "Release time of a scheduled TC lies in the past";
    SCHEDULED_TC_INVALID = 26, "inner_code u16", "An embedded TC of TC[11,4] is not a valid TC for this robot";
    BOARD_B_NO_ACK = 27, "command u8, retries u8", "Board B did not acknowledge a module command";
    UNKNOWN_MODE_TARGET = 28, "node u32", "Mode tree node not defined";
    INVALID_MODE = 29, "node u32, mode u32", "Mode or submode not defined for the node, or not commandable there";
    UNKNOWN_ACTION_LINK = 30, "event_id u16", "No event-action definition for this event";
    STORE_DISABLED = 31, "", "On-board storage is disabled";
    TIMEOUT = 32, "elapsed_ms u32", "Action did not complete in its time limit";
    ABORTED_BY_COMMAND = 33, "function u16", "Action aborted by a STOP command or a commanded mode change";
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
