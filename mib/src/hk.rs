//! Housekeeping structures (PUS 3). A TM[3,25] report's source data is the structure ID
//! (u16, big-endian) followed by each parameter of the structure, in order, packed with
//! its wire type (see `mib_wire::codec`).

use crate::params::pid;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HkDef {
    pub sid: u16,
    pub name: &'static str,
    pub params: &'static [u16],
    /// Collection interval at boot; changed by TC[3,31].
    pub default_interval_ms: u32,
    /// Periodic generation enabled at boot (no request needed).
    pub default_enabled: bool,
    pub desc: &'static str,
}

/// Structure IDs.
pub mod sid {
    pub const ROBOT_STATUS: u16 = 1;
    pub const B_LINK: u16 = 2;
    pub const FDIR: u16 = 3;
    pub const OBSW: u16 = 4;
    pub const PLATFORM_IO: u16 = 5;
    pub const SPACE_LINK: u16 = 22;
    pub const MODULES: u16 = 23;
    pub const TEAM: u16 = 24;
    pub const PLAN: u16 = 27;
    pub const UPDATE: u16 = 30;
    pub const FILES: u16 = 31;
}

/// Shortest and longest collection interval accepted by TC[3,31].
pub const MIN_INTERVAL_MS: u32 = 10;
pub const MAX_INTERVAL_MS: u32 = 3_600_000;

/// Structures report in different control periods: structure `i` (its index in
/// [`HK_STRUCTS`]) has the phase `i × PHASE_STEP_MS` within each second
/// ([`PHASE_CYCLE_MS`]). Its first report after boot, TC[3,5] or TC[3,31] is one interval
/// after the next instant of its phase, and each later one an interval after the last, so
/// structures whose intervals are whole seconds never report in the same period (their
/// packets, and the store writes they cost, would otherwise all fall in one period at the
/// common multiple of the intervals). A report late by a slow period is rephased the same
/// way. An interval that is not whole seconds keeps no phase: its reports are an interval
/// apart from the TC or the late report that set them. The step is several control
/// periods, so a period that runs late does not bring two phases together.
pub const PHASE_STEP_MS: u32 = 50;
/// The span the phases repeat in; every whole-second interval is a multiple of it.
pub const PHASE_CYCLE_MS: u32 = 1000;

/// The phase of structure `index` of [`HK_STRUCTS`] within [`PHASE_CYCLE_MS`].
pub const fn phase_ms(index: usize) -> u32 {
    (index as u32 * PHASE_STEP_MS) % PHASE_CYCLE_MS
}

// Every structure has a phase of its own, each in a control period of its own.
const _: () = assert!(HK_STRUCTS.len() as u32 * PHASE_STEP_MS <= PHASE_CYCLE_MS);
const _: () = assert!(PHASE_STEP_MS >= 2 * crate::config::CONTROL_PERIOD_MS);

use pid::*;
pub const HK_STRUCTS: &[HkDef] = &[
    HkDef {
        sid: sid::ROBOT_STATUS,
        name: "ROBOT_STATUS",
        params: &[
            MODE,
            CONFIG_STATE,
            TARGET_STATE,
            CMD_COMPLETE,
            ACTIVE_PRIMITIVE,
            BOLT_SIDE,
            BOLT_PAIR,
            BOLT_ATTEMPT,
            FAULT_FLAGS,
            ARM_A_TARGET,
            ARM_A_PWM,
            ARM_B_TARGET,
            ARM_B_PWM,
            GRIP_A_TARGET,
            GRIP_A_PWM,
            GRIP_B_TARGET,
            GRIP_B_PWM,
            HIP_TARGET,
            HIP_ANGLE,
            V_BAT_A,
            V_BAT_B,
            I_BAT,
            V_REG,
            I_LOC_A,
            I_LOC_B,
            I_GRIP_A,
            I_GRIP_B,
            I_BO_A,
            I_BO_B,
            ARM_SW_A,
            ARM_SW_B,
            GRAV_A_X,
            GRAV_A_Y,
            GRAV_A_Z,
            GRAV_B_X,
            GRAV_B_Y,
            GRAV_B_Z,
            BOLTER_B_STATE,
        ],
        default_interval_ms: 1000,
        default_enabled: true,
        desc: "Robot status: the paper's heartbeat content, sent without request",
    },
    HkDef {
        sid: sid::B_LINK,
        name: "B_LINK",
        params: &[B_LINK_OK, B_HB_AGE_MS, B_HB_RX, B_FRAME_ERRORS, B_RETRIES, B_ACK_MISSED],
        default_interval_ms: 5000,
        default_enabled: true,
        desc: "Board A-B serial link status",
    },
    HkDef {
        sid: sid::FDIR,
        name: "FDIR",
        params: &[
            FAULT_FLAGS,
            FAULT_LATCHED,
            FAULT_COUNT,
            MON_ENABLED,
            LAST_FAULT_EVENT,
            PENDING_MODE,
            MODE,
            HIP_DEVIATION,
            EVENTS_DROPPED,
            ACTIVE_PRIMITIVE,
        ],
        default_interval_ms: 5000,
        default_enabled: true,
        desc: "Fault detection, isolation and recovery state",
    },
    HkDef {
        sid: sid::OBSW,
        name: "OBSW",
        params: &[
            TC_ACCEPTED,
            TC_REJECTED,
            TC_DUPLICATE,
            TM_SENT,
            TM_STORED,
            TM_STORE_DROPPED,
            SCHED_COUNT,
            SCHED_ENABLED,
            EVENTS_THROTTLED,
            UPTIME_S,
        ],
        default_interval_ms: 10000,
        default_enabled: true,
        desc: "On-board software counters",
    },
    HkDef {
        sid: sid::PLATFORM_IO,
        name: "PLATFORM_IO",
        params: &[
            IO_TC_DROPPED,
            IO_TM_DROPPED,
            IO_SENSOR_ERRORS,
            IO_OUTPUT_ERRORS,
            IO_AB_BYTES_DROPPED,
            IO_STACK_HIGH_WATER,
        ],
        default_interval_ms: 10000,
        default_enabled: true,
        desc: "Counters of the platform's I/O (board A firmware or host binary)",
    },
    HkDef {
        sid: sid::SPACE_LINK,
        name: "SPACE_LINK",
        params: &[
            LINK_AD_ACCEPTED,
            LINK_BD_ACCEPTED,
            LINK_CONTROL_FRAMES,
            LINK_PACKETS,
            LINK_REJ_BARE_PACKET,
            LINK_REJ_BAD_CRC,
            LINK_REJ_BAD_LENGTH,
            LINK_REJ_BAD_HEADER,
            LINK_REJ_WRONG_SCID,
            LINK_REJ_UNKNOWN_VC,
            LINK_REJ_SDLS_SHORT,
            LINK_REJ_UNKNOWN_SPI,
            LINK_REJ_REPLAY,
            LINK_REJ_BAD_MAC,
            LINK_REJ_STORE_FAILED,
            LINK_REJ_UNKNOWN_CONTROL,
            LINK_REJ_NOT_PACKETS,
            LINK_FARM_DISCARDED,
            LINK_CLCW,
            LINK_TM_FRAMES,
            LINK_TM_IDLE_FRAMES,
            LINK_TM_SDLS_FAILED,
            LINK_REJ_CONTROL_STATE,
            LINK_REJ_BD_CONTENT,
            LINK_TM_SPI,
            LINK_TC_SPIS,
            LINK_STATE_WRITES,
            LINK_STATE_BAD_SLOT,
        ],
        default_interval_ms: 10000,
        default_enabled: true,
        desc: "Space link (TC/TM frames, COP-1, SDLS): frames accepted and refused by reason, CLCW, TM frames sent",
    },
    HkDef {
        sid: sid::MODULES,
        name: "MODULES",
        params: &[
            CONFIG_HASH,
            CONFIG_ID,
            CONFIG_STATUS,
            MODULES_PRESENT,
            CAL_GRIP_A_CLOSED,
            CAL_GRIP_A_OPEN,
            CAL_GRIP_B_CLOSED,
            CAL_GRIP_B_OPEN,
            CAL_ENC_ZERO,
            CAL_FROM_DESCRIPTORS,
        ],
        default_interval_ms: 10000,
        default_enabled: true,
        desc: "Module configuration found at boot: hash, supported configuration, state against the ground-accepted configuration, present slots; the calibration in use (gripper pulse widths, encoder zero, slots calibrated from their descriptors)",
    },
    HkDef {
        sid: sid::TEAM,
        name: "TEAM",
        params: &[
            TEAM_TERM,
            TEAM_ROLE,
            TEAM_LEADER,
            TEAM_GROUND_SEEN,
            TEAM_PKT_SENT,
            TEAM_PKT_RECEIVED,
            TEAM_REJ_MALFORMED,
            TEAM_REJ_TRUNCATED,
            TEAM_REJ_UNKNOWN_SENDER,
            TEAM_REJ_BAD_MAC,
            TEAM_REJ_REPLAY,
            TEAM_REJ_STORE_FAILED,
            TEAM_ELECTIONS,
            TEAM_DIR_EXECUTED,
            TEAM_DIR_REFUSED,
            TEAM_PERSIST_FAILED,
            TEAM_STEPS_EXECUTED,
        ],
        default_interval_ms: 5000,
        default_enabled: true,
        desc: "Team coordination without the ground: term, role, leader, ground seen, inter-robot packets sent/accepted/refused by reason, elections, directives executed/refused, failed state writes, plan steps executed",
    },
    HkDef {
        sid: sid::PLAN,
        name: "PLAN",
        params: &[
            PLAN_STATE,
            PLAN_ID,
            PLAN_STEPS,
            PLAN_NEXT_STEP,
            PLAN_DONE,
            PLAN_WAIT_ROBOT,
            PLAN_WAIT_STEP,
            PLAN_PROGRESS_SENT,
            PLAN_PROGRESS_RECEIVED,
            PLAN_PROGRESS_IGNORED,
        ],
        default_interval_ms: 2000,
        default_enabled: true,
        desc: "On-board plan: state, plan ID, steps, next step, steps done, the dependency it waits for, progress announcements sent/accepted/ignored",
    },
    HkDef {
        sid: sid::UPDATE,
        name: "UPDATE",
        params: &[SW_VERSION, SW_SLOT, UPDATE_OUTCOME, UPDATE_INSTALLED_VERSION, UPDATE_REFUSALS],
        default_interval_ms: 5000,
        default_enabled: true,
        desc: "Software update: running version and slot, outcome of the last update, verified image waiting in the other slot, update TCs refused",
    },
    HkDef {
        sid: sid::FILES,
        name: "FILES",
        params: &[
            FILE_PDU_RECEIVED,
            FILE_PDU_SENT,
            FILE_PDU_REFUSED,
            FILE_PDU_STRAY,
            FILE_HANDLER_REFUSED,
            FILE_BEFORE_METADATA,
            FILE_TX_RECEIVED,
            FILE_TX_SENT,
            FILE_TX_COMPLETED,
            FILE_TX_FAILED,
            FILE_FAULTS,
            FILE_SEG_RESENT,
            FILE_NAK_SENT,
            FILE_NAK_RECEIVED,
            FILE_OUTBOX_DROPPED,
            FILE_RESEND_DROPPED,
            FILE_SUPERSEDED,
            FILE_FS_DONE,
            FILE_FS_REFUSED,
            FILE_PROXY_REFUSED,
            FILE_STORE_BAD_NAMES,
            FILE_STORE_FULL,
            FILE_STORE_IO_ERRORS,
            FILE_STORE_FILES,
            FILE_STORE_FREE,
            FILE_PARTIALS_REMOVED,
        ],
        // Counters for trends: the events tell each transfer as it happens. Every 5 s
        // the FILES reports would overflow the TM store's HK area in the outage it must
        // hold (mib::memory, FW-MEM-02).
        default_interval_ms: 30000,
        default_enabled: true,
        desc: "File service (CFDP entity and file store): PDUs taken, sent and refused, transactions started each way, completed and failed, faults, segments sent again, NAKs, drops, filestore and put requests refused, the store's refusals, files and free bytes, partly received files removed at start",
    },
];

/// Looks a structure up by SID.
pub fn by_sid(sid: u16) -> Option<&'static HkDef> {
    HK_STRUCTS.iter().find(|h| h.sid == sid)
}

impl HkDef {
    /// Length of the source data of this structure's TM[3,25] (SID included).
    pub fn data_len(&self) -> usize {
        2 + self
            .params
            .iter()
            .map(|id| crate::params::by_id(*id).map_or(0, |p| p.ptype.size()))
            .sum::<usize>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: PUS-3-01
    #[test]
    fn every_hk_parameter_exists_and_sids_are_unique() {
        for (i, h) in HK_STRUCTS.iter().enumerate() {
            for p in h.params {
                assert!(crate::params::by_id(*p).is_some(), "SID {} param {}", h.sid, p);
            }
            assert!(HK_STRUCTS[i + 1..].iter().all(|o| o.sid != h.sid));
            assert!(h.data_len() <= crate::config::MAX_PACKET_LEN - 32);
            assert!(h.default_interval_ms >= MIN_INTERVAL_MS);
        }
    }
}
