//! Events (PUS 5). An event report TM[5,s] has subservice `s` = severity (1 info, 2 low,
//! 3 medium, 4 high); its source data is the event ID (u16) followed by the event's
//! parameters, packed with their wire types.

use crate::config::RESET_CAUSE_NAMES;
use crate::files::{CLASS_NAMES, CONDITION_NAMES, DIRECTION_NAMES};
use crate::layout::{Field, Names, MODULE_REASON_NAMES, SIDE_NAMES, SLOT_NAMES};
use crate::team::{
    TEAM_DIRECTIVE_NAMES, TEAM_PLAN_REFUSE_NAMES, TEAM_REFUSE_NAMES, TEAM_REJECT_NAMES, TEAM_STATE_NAMES,
    TEAM_STEP_DOWN_NAMES,
};
use crate::types::PType;

/// PUS 5 severity; the value is the TM[5,x] subservice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Severity {
    Info = 1,
    Low = 2,
    Medium = 3,
    High = 4,
}

impl Severity {
    pub const fn subservice(self) -> u8 {
        self as u8
    }
    pub const fn from_subservice(s: u8) -> Option<Severity> {
        match s {
            1 => Some(Severity::Info),
            2 => Some(Severity::Low),
            3 => Some(Severity::Medium),
            4 => Some(Severity::High),
            _ => None,
        }
    }
    pub const fn name(self) -> &'static str {
        match self {
            Severity::Info => "info",
            Severity::Low => "low",
            Severity::Medium => "medium",
            Severity::High => "high",
        }
    }
}

/// An event parameter is a field of the event report's body.
pub type EventParam = Field;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EventDef {
    pub id: u16,
    pub name: &'static str,
    pub severity: Severity,
    pub params: &'static [EventParam],
    /// True for the faults of paper Table 8 (FDIR detections).
    pub fault: bool,
    pub desc: crate::types::Text,
}

const fn p(name: &'static str, ptype: PType) -> EventParam {
    Field::new(name, ptype, "")
}

macro_rules! events {
    ($( $name:ident = $id:literal, $sev:ident, $fault:literal, [$($pn:literal : $pt:ident $(@ $en:expr)?),*], $desc:literal; )*) => {
        /// Event IDs by mnemonic.
        pub mod eid { $( #[doc = $desc] pub const $name: u16 = $id; )* }
        pub const EVENTS: &[EventDef] = &[ $( EventDef {
            id: $id, name: stringify!($name), severity: Severity::$sev, fault: $fault,
            params: &[$( p($pn, PType::$pt)$(.names($en))? ),*], desc: $crate::types::text($desc),
        }, )* ];
    };
}

events! {
    // --- faults (paper Table 8) ---
    BOLT_FAILURE = 0x0101, High, true, ["side": U8 @SIDE_NAMES, "pair": U8, "attempts": U8], "Bolting failure: a fastener pair did not lock in the allowed attempts";
    UNBOLT_FAILURE = 0x0102, High, true, ["side": U8 @SIDE_NAMES, "pair": U8, "attempts": U8], "Unbolting failure: a fastener pair did not release";
    INITIAL_STATE_MISMATCH = 0x0103, Medium, true, ["believed": U8 @Names::State, "computed": U8 @Names::State], "Reconfiguration refused: ground's initial state differs from the computed state";
    LOW_BATTERY = 0x0104, High, true, ["param_id": U16 @Names::Param, "value": U16, "limit": U16], "V_batA or V_batB below the limit for longer than the persistence";
    ASSEMBLY_SYSTEM_FAULT = 0x0105, High, true, ["reason": U16], "Assembly system operation fault commanded by the ground";
    ARM_NOT_CONTRACTED = 0x0106, High, true, ["side": U8 @SIDE_NAMES], "Arm contracted switch not pushed after a contract command";
    IDLE_OVERCURRENT = 0x0107, High, true, ["param_id": U16 @Names::Param, "value": U16, "limit": U16], "Current above the idle limit at the start or end of a reconfiguration";
    OPERATIONAL_OVERCURRENT = 0x0108, High, true, ["param_id": U16 @Names::Param, "value": U16, "limit": U16], "Current above the module's absolute limit";
    HIP_MISMATCH = 0x0109, High, true, ["angle_cdeg": I16, "expected_cdeg": I16], "Hip encoder far from the contracted angle when entering operational";
    COMM_LOSS_HEARTBEAT = 0x010A, High, true, ["param_id": U16 @Names::Param, "value": U16, "limit": U16], "Board B heartbeat missing for longer than the timeout";
    COMM_LOSS_NO_ACK = 0x010B, High, true, ["command": U8, "retries": U8], "Board B never acknowledged a repeated command";
    // --- information ---
    MODE_CHANGED = 0x0201, Info, false, ["node": U32 @Names::Node, "from": U32 @Names::Mode, "to": U32 @Names::Mode, "cause": U16 @Names::Event], "Mode of a mode-tree node changed (cause: 0 command, else the fault event ID)";
    STATE_REACHED = 0x0202, Info, false, ["state": U8 @Names::State], "Robot reached a configuration state";
    BOLT_PAIR_DONE = 0x0203, Info, false, ["side": U8 @SIDE_NAMES, "pair": U8, "attempts": U8], "Fastener pair locked";
    UNBOLT_PAIR_DONE = 0x0204, Info, false, ["side": U8 @SIDE_NAMES, "pair": U8, "attempts": U8], "Fastener pair released";
    PRIMITIVE_DONE = 0x0205, Info, false, ["primitive": U8 @Names::Primitive, "state": U8 @Names::State], "Motion primitive completed";
    TC_REJECTED = 0x0206, Low, false, ["service": U8, "subservice": U8, "code": U16 @Names::FailureCode], "A telecommand was refused (see the PUS 1 report)";
    BOOT = 0x0207, Info, false, ["reset_cause": U8 @RESET_CAUSE_NAMES], "On-board software started";
    FAULT_CLEARED = 0x0208, Info, false, ["event_id": U16 @Names::Event], "The cause of a fault is no longer present";
    STORE_OVERFLOW = 0x0209, Medium, false, ["dropped": U32], "On-board TM store full: oldest packets overwritten";
    MODE_CHANGE_FAILED = 0x020A, Medium, false, ["node": U32 @Names::Node, "mode": U32 @Names::Mode, "reason": U16 @Names::FailureCode], "A mode transition could not complete";
    BOLT_ATTEMPT_FAILED = 0x020B, Low, false, ["side": U8 @SIDE_NAMES, "pair": U8, "attempt": U8], "One bolting attempt failed; retrying";
    PREVIOUS_PANIC = 0x020C, High, false, ["reset_cause": U8 @RESET_CAUSE_NAMES, "line": U32, "file_crc": U32], "The previous run ended in a panic (location recorded before the reset; file_crc = CRC-32 of the source path)";
    EVENT_QUEUE_OVERFLOW = 0x020D, Low, false, ["dropped": U16], "Event reports dropped because the event queue was full (total in HK EVENTS_DROPPED; raised throttled, dropped = count since the last report)";
    TCP_CONNECTION_REFUSED = 0x020E, Low, false, ["refused": U32], "Ground link: TCP connections refused because TCP_MAX_CONNECTIONS were open (refused = total since boot; at most one report per control period, then throttled)";
    TCP_CLIENT_DROPPED = 0x020F, Medium, false, ["dropped": U32], "Ground link: TCP clients disconnected because their unsent TM passed TCP_TM_BACKLOG bytes (dropped = total since boot; the TM stays in the on-board store)";
    LINK_FRAME_REJECTED = 0x0230, Low, false, ["reason": U8, "total": U32], "Space link: TC frames refused since the last report (reason = the SPACE_LINK HK parameter ID minus 120: 4 bare packet, 5 CRC, 6 length, 7 header, 8 SCID, 9 VC, 10 SDLS too short, 11 unknown SPI, 12 replay, 13 MAC, 14 counter store, 15 unknown control, 16 not packets, 22 control-frame rate, 23 BD frame content; total since boot); at most one per reason and control period, then throttled";
    LINK_CONTROL_FRAME = 0x0231, Low, false, ["command": U8, "vr": U8, "total": U32], "Space link: a BC control frame in clear was executed (command 0 Unlock, 1 Set V(R) with vr; total since boot); at most one per control period, then throttled";
    CONFIG_INVALID = 0x0232, High, false, ["reason": U8 @MODULE_REASON_NAMES, "slot": U8 @SLOT_NAMES, "hash": U32], "Module discovery at boot: the module set is invalid or unsupported (reason, the slot it names or NONE, configuration hash of what was found); the robot stays in STANDBY and OPERATIONAL is refused with CONFIG_INVALID";
    MODULE_REPLACED = 0x0233, Medium, false, ["slot": U8 @SLOT_NAMES, "accepted_hash": U32, "hash": U32], "Module discovery at boot: the module set differs from the configuration the ground last accepted (first slot whose presence, serial or revision differs, or NONE when only calibration changed); OPERATIONAL is refused with CONFIG_NOT_ACCEPTED until ACCEPT_CONFIG with the current hash";
    CONFIG_STATE_LOST = 0x0234, Medium, false, ["reason": U8 @crate::layout::CONFIG_STATE_LOST_NAMES], "The platform's store of the accepted module configuration gave nothing at start (1 missing, 2 unreadable, 3 corrupt: nothing is accepted, OPERATIONAL waits for ACCEPT_CONFIG) or an acceptance could not be written (4: it holds until the next restart only)";
    LINK_SPI_SELECTED = 0x0238, Medium, false, ["tm_spi": U16, "tc_spis": U8], "Space link: LINK_SPI_SELECT executed: TM now under tm_spi, TC accepted under the SPIs of the tc_spis mask (bit 0 = SPI 1, bit 1 = SPI 2), stored on board";
    // --- team coordination without the ground (mib::team) ---
    GROUND_LOST = 0x0301, Medium, false, ["term": U32], "Team: no valid ground TC for GROUND_LOSS_TIMEOUT_MS; the robot finishes its primitive and holds (STANDBY if both grippers hold, SAFED otherwise) and takes part in leader selection";
    ELECTION_STARTED = 0x0302, Info, false, ["term": U32], "Team: the robot stood as candidate in a new term";
    LEADER_ELECTED = 0x0303, Info, false, ["term": U32, "leader": U8], "Team: a leader is known for the term (the robot itself when leader = own number)";
    STEPPED_DOWN = 0x0304, Low, false, ["term": U32, "reason": U8 @TEAM_STEP_DOWN_NAMES], "Team: the robot stopped leading";
    GROUND_REGAINED = 0x0305, Info, false, ["term": U32], "Team: a valid ground TC arrived; obedience to the leader ended";
    DIRECTIVE_EXECUTED = 0x0306, Info, false, ["term": U32, "leader": U8, "directive": U8 @TEAM_DIRECTIVE_NAMES, "step": U16], "Team: a leader's directive was executed (HOLD, or CONTINUE step within the ground authorisation)";
    DIRECTIVE_REFUSED = 0x0307, Low, false, ["term": U32, "sender": U8, "reason": U8 @TEAM_REFUSE_NAMES], "Team: a directive was refused (one event per term and reason)";
    TEAM_PACKET_REJECTED = 0x0308, Low, false, ["reason": U8 @TEAM_REJECT_NAMES, "sender": U8, "total": U32], "Team: inter-robot packets refused (reason; sender as claimed, 0 if unknown; total of that reason since boot, also in HK TEAM); at most one per reason and control period, then throttled";
    TEAM_STATE_LOADED = 0x0309, Info, false, ["status": U8 @TEAM_STATE_NAMES, "term": U32, "roster": U8, "plan": U16], "Team: the team state file read at start (status: 0 restored, 1 none, 2 corrupt: started from term 0 without roster, authorisation or plan; roster = robots restored; plan = authorised plan ID, 0 none)";
    PLAN_UPLOADED = 0x030A, Info, false, ["plan": U16, "first_step": U16, "steps": U8, "hash": U32], "Team: plan steps uploaded by the ground (TC[211,6]) and matching the authorisation's hash";
    PLAN_STEP_EXECUTED = 0x030B, Info, false, ["plan": U16, "step": U16, "function": U16, "leader": U8], "Team: an authorised plan step was started on a leader's CONTINUE (its initial-state check passed)";
    PLAN_STEP_REFUSED = 0x030C, Low, false, ["plan": U16, "step": U16, "reason": U8 @TEAM_PLAN_REFUSE_NAMES], "Team: a CONTINUE was not executed (no plan, step outside the authorisation or expired, initial-state check failed, robot busy); the robot holds";
    PLAN_LOADED = 0x0401, Info, false, ["plan_id": U32, "steps": U8, "crc": U32], "Plan: an image passed PLAN_COMMIT's checks and is the loaded plan";
    PLAN_STATE_CHANGED = 0x0402, Info, false, ["plan_id": U32, "state": U8 @crate::plan::STATE_NAMES, "step": U8, "cause": U8 @crate::plan::CAUSE_NAMES], "Plan: the plan changed state (step = its next step; cause: command, step failed or timed out, fault, done, restart)";
    PLAN_STEP_STARTED = 0x0403, Info, false, ["plan_id": U32, "step": U8, "seq_count": U16], "Plan: a step's TC was handed to the TC path (its PUS 1 reports carry the request ID with this sequence count)";
    PLAN_WAITING = 0x0404, Info, false, ["plan_id": U32, "step": U8, "robot": U8, "robot_step": U8], "Plan: the next step waits for another robot's step to be announced completed over the team link (raised once per wait)";
    UPDATE_INSTALLED = 0x0601, Info, false, ["version": U32, "length": U32, "slot": U8], "Update: an image was copied into the inactive slot and verified there (SHA-256, Ed25519 signature of the ground update key)";
    UPDATE_REFUSED = 0x0602, Low, false, ["reason": U8 @crate::update::REFUSAL_NAMES, "refusals": U32], "Update: an image was refused at install (reason), with the refusals since boot";
    UPDATE_ACTIVATED = 0x0603, Medium, false, ["version": U32, "slot": U8], "Update: otadata now boots the verified image (state NEW); the robot resets into it";
    UPDATE_CONFIRMED = 0x0604, Info, false, ["version": U32, "slot": U8], "Update: the running image passed its self-test and confirmed itself (otadata VALID)";
    UPDATE_SELF_TEST_FAILED = 0x0605, High, false, ["version": U32, "check": U8], "Update: the running image, not yet confirmed, failed its self-test (check that failed); it resets unconfirmed and the previous image boots";
    UPDATE_ROLLED_BACK = 0x0606, High, false, ["aborted_slot": U8, "version": U32], "Update: the image activated last never confirmed; the boot abandoned its slot and runs this version again";
    // --- the file service (docs/files.md, mib::files) ---
    FILE_TRANSFER_STARTED = 0x0701, Info, false, ["source": U16, "seq": U16, "direction": U8 @DIRECTION_NAMES, "class": U8 @CLASS_NAMES, "length": U32], "Files: a CFDP transaction began (its metadata PDU taken from the ground or sent to it); source and seq are its transaction ID (entity 0 the ground, N robot N; the sequence number of that entity), direction RECEIVED from the ground or SENT to it, length the file's bytes (0: a request without a file: get, listing, remove, rename)";
    FILE_TRANSFER_COMPLETED = 0x0702, Info, false, ["source": U16, "seq": U16, "direction": U8 @DIRECTION_NAMES, "condition": U8 @CONDITION_NAMES, "bytes": U32], "Files: a CFDP transaction ended complete (receiver: checksum verified, the file kept under its name; sender: the ground's Finished PDU says so); bytes = the file's bytes moved";
    FILE_TRANSFER_FAILED = 0x0703, Medium, false, ["source": U16, "seq": U16, "direction": U8 @DIRECTION_NAMES, "condition": U8 @CONDITION_NAMES, "bytes": U32], "Files: a CFDP transaction ended incomplete: condition (a checksum failure, an ACK, NAK or check limit, inactivity, a filestore rejection, a cancel; NO_ERROR when the ground reported the file incomplete), bytes = how far the file got; nothing partial is kept under the file's name";
    FILE_REFUSED = 0x0704, Low, false, ["counter": U16 @Names::Param, "total": U32], "Files: the file service refused something since the last report: counter = the FILES HK parameter that rose (FILE_PDU_REFUSED, FILE_FS_REFUSED, FILE_PROXY_REFUSED, FILE_STORE_BAD_NAMES, FILE_STORE_FULL; not FILE_HANDLER_REFUSED, which a lossy link's late and repeated PDUs raise), total = its value; at most one per counter and control period, then throttled";
    FILE_STORE_ERROR = 0x0705, Medium, false, ["errors": U32], "Files: the file store's medium failed (host directory, board flash) since the last report; errors = FILE_STORE_IO_ERRORS; the transfer concerned ends with a filestore rejection";
    FILE_PARTIALS_REMOVED = 0x0706, Medium, false, ["files": U16], "Files: at start, partly received files of transfers a reset cut short were removed (files = how many; never taken for the file they were to be): those transfers ended with the reset, the ground saw them fail and sends them again";
}

/// Events exempt from throttling (`config::EVENT_THROTTLE_MAX`): `MODE_CHANGED` is
/// bounded by the transitions themselves (one per mode-tree node) and every one matters.
pub const UNTHROTTLED: &[u16] = &[eid::MODE_CHANGED];

pub fn by_id(id: u16) -> Option<&'static EventDef> {
    EVENTS.iter().find(|e| e.id == id)
}

pub fn by_name(name: &str) -> Option<&'static EventDef> {
    EVENTS.iter().find(|e| e.name.eq_ignore_ascii_case(name))
}

impl EventDef {
    /// Length of the event's source data (ID included).
    pub fn data_len(&self) -> usize {
        2 + self.params.iter().map(|p| p.ptype.size()).sum::<usize>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: PUS-5-01
    #[test]
    fn event_ids_unique() {
        for (i, e) in EVENTS.iter().enumerate() {
            assert!(EVENTS[i + 1..].iter().all(|o| o.id != e.id && o.name != e.name));
        }
    }
}
