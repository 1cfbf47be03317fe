//! System-wide timing constants and capacities. Every bounded queue, buffer and period
//! of the OBSW, simulator, firmware and ground tool is sized from here.

/// Period of the on-board control loop (sensor sampling, controllers, monitoring).
pub const CONTROL_PERIOD_MS: u32 = 10;
/// Clock of the boards' CPU (ESP32-C3, RV32IMC).
pub const CPU_HZ: u32 = 160_000_000;
/// Cycles per instruction the CPU budget assumes: flash wait states and cache misses make
/// the real figure larger than 1; 2 until a board's cycle counter measures it.
pub const ASSUMED_CYCLES_PER_INSTRUCTION: u32 = 2;
/// Instructions one control period holds at [`ASSUMED_CYCLES_PER_INSTRUCTION`].
pub const PERIOD_INSTRUCTIONS: u32 = CPU_HZ / ASSUMED_CYCLES_PER_INSTRUCTION / 1000 * CONTROL_PERIOD_MS;
/// Share of a control period (in %) everything the period does may take: the worst tick,
/// the worst TC frame, housekeeping, TM framing and store writes together. The other half
/// is margin while the cycles per instruction are assumed.
pub const PERIOD_CPU_BUDGET_PCT: u32 = 50;
/// Instructions a whole control period may take.
pub const PERIOD_INSTRUCTION_BUDGET: u32 = PERIOD_INSTRUCTIONS / 100 * PERIOD_CPU_BUDGET_PCT;
/// Moving-average window applied to every raw sensor channel (paper: 50 samples).
pub const MOVING_AVERAGE_WINDOW: usize = 50;
/// Period of board B's heartbeat to board A.
pub const B_HEARTBEAT_PERIOD_MS: u32 = 50;
/// A–B link: commands waiting behind the one in flight (coalesced per kind, so the
/// queue never overflows: there are fewer command kinds than slots).
pub const AB_LINK_QUEUE_DEPTH: usize = 8;
/// A–B link: largest decoded frame payload (bytes).
pub const AB_LINK_MAX_FRAME: usize = 64;
/// A–B link: bytes one control period may hand to the serial line (115200 Bd carries
/// ~115 bytes per 10 ms).
pub const AB_LINK_TX_CAP: usize = 128;
/// A–B link: shortest interval between re-sends of B's module modes when its heartbeat
/// shows other modes than A wants.
pub const B_MODES_RESEND_MS: u32 = 200;
/// Serial baud rate of the A–B link.
pub const AB_LINK_BAUD: u32 = 115_200;

/// Length of a CDS short time stamp (days u16, ms of day u32) used in all TM.
pub const TIMESTAMP_LEN: usize = 7;
/// Largest space packet the OBSW accepts or emits (primary header included).
pub const MAX_PACKET_LEN: usize = 1024;
/// Largest data field of an event report (TM[5,x]): the TM writer's event buffer.
pub const EVENT_DATA_MAX: usize = 64;
/// Largest application data field of a TC.
pub const MAX_TC_APP_DATA: usize = 512;
/// Destination/source ID the OBSW uses for the ground.
pub const GROUND_ID: u16 = 0;

/// Outgoing TM queue depth of the OBSW (packets). When full, the oldest packet moves to
/// the on-board store instead of being dropped.
pub const TM_QUEUE_DEPTH: usize = 64;
/// On-board TM store (PUS 15) capacity in packets; when full the oldest packet is
/// overwritten and `TM_STORE_DROPPED` counts it.
pub const TM_STORE_CAPACITY: usize = 4096;
/// PUS 11 schedule capacity (activities).
pub const SCHEDULE_CAPACITY: usize = 32;
/// Number of recent TC request IDs remembered for duplicate suppression. A ground's
/// heartbeat pings take about `TC_RETRY_SPAN_MS / GROUND_HEARTBEAT_MS` (~38) entries in
/// one retry span; 128 leaves room for ~90 other TCs in that span, so a plan TC is
/// still remembered at its last resend (the core asserts the relation at compile time).
pub const DUPLICATE_WINDOW: usize = 128;
/// A TC seen longer ago than this is executed again even with the same request ID and
/// CRC (a ground restarted its sequence counts).
pub const DUPLICATE_MAX_AGE_MS: u32 = 60_000;
/// Depth of the pending action queue behind the running action.
pub const ACTION_QUEUE_DEPTH: usize = 1;
/// Longest reconfiguration (primitives).
pub const MAX_RECONFIG_PRIMITIVES: usize = 3;

crate::named_codes! {
    /// Names of the reset causes (BOOT and PREVIOUS_PANIC events).
    RESET_CAUSE_NAMES;
    /// Reset causes reported by the BOOT event (`reset_cause`).
    pub mod reset_cause {
        /// Power-on or a host start.
        pub const POWER_ON: u8 = 0;
        /// Software reset after a panic (a PREVIOUS_PANIC event follows).
        pub const PANIC: u8 = 1;
        /// Watchdog reset.
        pub const WATCHDOG: u8 = 2;
        /// Any other cause (brown-out, external reset pin).
        pub const OTHER: u8 = 3;
    }
}

/// Event throttling: at most `EVENT_THROTTLE_MAX` reports of one event ID per
/// `EVENT_THROTTLE_WINDOW_MS`; the rest are counted (`EVENTS_THROTTLED`) and dropped.
/// `events::UNTHROTTLED` lists the exempt events.
pub const EVENT_THROTTLE_WINDOW_MS: u32 = 1000;
pub const EVENT_THROTTLE_MAX: u8 = 20;
/// Capacity of the queue of event reports raised in one control period. An event that
/// finds it full is dropped and counted in HK `EVENTS_DROPPED`; the core then raises
/// `EVENT_QUEUE_OVERFLOW` (with the count since its last report) at most once per
/// `EVENT_THROTTLE_WINDOW_MS`.
pub const EVENT_QUEUE_DEPTH: usize = 8;
/// Default time report rate exponent (TM[9,2] every 2^n s).
pub const TIME_REPORT_DEFAULT_EXP: u8 = 6;
/// A mode transition not confirmed by every node within this time fails.
pub const MODE_TRANSITION_TIMEOUT_MS: u32 = 3000;
/// Largest embedded TC accepted by TC[11,4].
pub const MAX_SCHEDULED_TC_LEN: usize = 64;

// --- Link robustness (ground retries, downlink subscriptions, TCP bounds) ---

// --- Ground: TM gaps retrieved from the on-board store (PUS 15) ---

// --- Ground: the collector's link and archive timing, `ground run`'s end of run ---

/// OBSW: module discovery (`docs/modules.md`) must be done this long after boot.
pub const MODULE_DISCOVERY_BUDGET_MS: u32 = 2000;
/// OBSW: board A waits this long after it read its own table for board B's half (sent
/// over the A-B link, one entry per B period, three passes); then it runs discovery
/// without it (reason BOARD_B_SILENT). Inside the budget with room for a control period.
pub const MODULE_B_TIMEOUT_MS: u32 = 1000;
const _: () = assert!(MODULE_B_TIMEOUT_MS + 2 * CONTROL_PERIOD_MS < MODULE_DISCOVERY_BUDGET_MS);
/// OBSW: while board B's table is incomplete, board A asks for it again this often.
pub const MODULE_B_REQUEST_MS: u32 = 250;
const _: () = assert!(MODULE_B_REQUEST_MS < MODULE_B_TIMEOUT_MS);
