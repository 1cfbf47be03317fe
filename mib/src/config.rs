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
/// Largest application data field of a TC.
pub const MAX_TC_APP_DATA: usize = 512;
/// Destination/source ID the OBSW uses for the ground.
pub const GROUND_ID: u16 = 0;

/// Default UDP/TCP port of robot 1's OBSW; robot N listens on `DEFAULT_PORT + N - 1`
/// when the ground tool starts several OBSWs.
pub const DEFAULT_PORT: u16 = 7301;
/// Host binary: most inputs (TCs, simulator-control lines) handled back to back before
/// a due control period runs.
pub const HOST_INPUT_BATCH: usize = 64;
/// Longest a TM write may wait for the ground link (a TCP client that stops reading is
/// then dropped; a UDP packet that still cannot go is counted in `IO_TM_DROPPED`). The
/// packet stays in the on-board store either way.
pub const TM_WRITE_TIMEOUT_MS: u32 = 100;
/// Simulator control port of robot N is `SIM_CTL_BASE_PORT + N` (host simulator only).
pub const SIM_CTL_BASE_PORT: u16 = 7400;

/// Ground: TC sequence counts skipped after the archived ones when a ground process
/// starts: more than the TCs a ground killed with SIGKILL can have sent without archiving
/// them (its archive writes behind), so a restarted ground never reuses a request ID the
/// robot has seen.
pub const SEQ_SKIP_AFTER_RESTART: u16 = 256;

/// Bare-packet lab port of robot `n` (UDP and TCP; obsw --udp/--tcp).
pub const fn robot_port(n: u8) -> u16 {
    DEFAULT_PORT - 1 + n as u16
}

/// Robot N's space-link port (one TC frame per datagram, obsw --frame-udp) is
/// `FRAME_BASE_PORT + N`.
pub const FRAME_BASE_PORT: u16 = 7_500;
/// Robot N's TM frames go to `TM_FRAME_BASE_PORT + N` on the ground (obsw
/// --frame-tm-to, ground --tm-listen).
pub const TM_FRAME_BASE_PORT: u16 = 7_600;

/// Space-link TC frame port of robot `n`.
pub const fn frame_port(n: u8) -> u16 {
    FRAME_BASE_PORT + n as u16
}

/// Port robot `n`'s TM frames arrive at on the ground.
pub const fn tm_frame_port(n: u8) -> u16 {
    TM_FRAME_BASE_PORT + n as u16
}

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

/// Ground: time to wait for TM[1,1] before resending a TC (paper: 0.7 s).
pub const GROUND_ACK_TIMEOUT_MS: u32 = 700;
/// Ground: connection-test period (paper: 1.2 s polling).
pub const GROUND_PING_PERIOD_MS: u32 = 1200;
/// Ground: link quality is the success rate over this many exchanges (paper: 100).
pub const LINK_QUALITY_WINDOW: usize = 100;
/// Ground: resends of one TC before the step fails.
pub const GROUND_MAX_RESENDS: u32 = 5;

// --- Link robustness (ground retries, downlink subscriptions, TCP bounds) ---

/// Ground: how often a running plan asks the on-board stores for missing TM, over the
/// bare-packet lab link (one range each time: resends still fill the duplicate window).
pub const GAP_CHECK_PERIOD_MS: u32 = 2000;
/// Ground: the same over frames (COP-1 delivers every retrieval once; no window fills).
pub const GAP_CHECK_PERIOD_FRAMES_MS: u32 = 1000;
/// Ground, over frames: how long a run waits for a first TM of each robot before its
/// start markers (the count a marker whose reports are all lost is placed after).
pub const FIRST_TM_WAIT_MS: u32 = 1000;
/// Ground, over frames: how long after a CLCW acknowledged a start or end marker the TM
/// received is taken to cover it when its acceptance report was lost.
pub const MARKER_SETTLE_MS: u32 = 1000;

/// Ground: first wait for a TC's completion (or failure) report before sending the same
/// bytes again.
pub const TC_RETRY_INITIAL_MS: u32 = 700;
/// Ground: each further wait is this many tenths of the previous one (×1.5) ...
pub const TC_RETRY_BACKOFF_TENTHS: u32 = 15;
/// ... up to this wait.
pub const TC_RETRY_CAP_MS: u32 = 4000;
/// Ground: sends of one TC after the first before its outcome is asked of the on-board
/// store; every send carries the same sequence count and bytes.
pub const TC_RETRY_MAX: u32 = 12;

/// Ground: wait after send number `n` (0 = the first send).
pub const fn tc_retry_wait_ms(n: u32) -> u32 {
    let mut w = TC_RETRY_INITIAL_MS;
    let mut i = 0;
    while i < n && w < TC_RETRY_CAP_MS {
        w = w * TC_RETRY_BACKOFF_TENTHS / 10;
        i += 1;
    }
    if w > TC_RETRY_CAP_MS {
        TC_RETRY_CAP_MS
    } else {
        w
    }
}

/// Ground: time from the first send of a TC to the end of its last wait.
pub const TC_RETRY_SPAN_MS: u32 = {
    let mut total = 0;
    let mut n = 0;
    while n <= TC_RETRY_MAX {
        total += tc_retry_wait_ms(n);
        n += 1;
    }
    total
};

// The on-board duplicate window must recognise every resend of a TC as the same TC.
const _: () = assert!(DUPLICATE_MAX_AGE_MS >= TC_RETRY_SPAN_MS);

/// OBSW: most UDP grounds receiving TM at once. A ground subscribes with any accepted TC.
pub const MAX_SUBSCRIBERS: usize = 4;
/// OBSW: a UDP subscription ends this long after the ground's last accepted TC.
pub const SUBSCRIPTION_LEASE_MS: u32 = 30_000;
/// Ground: a running ground sends a TC[17,1] at least this often (keeps the lease and
/// checks the link).
pub const GROUND_HEARTBEAT_MS: u32 = 1000;
/// Ground: the floor of the link-loss rule ([`link_loss_ms`]): no TM at all for this long
/// means the link or the obsw is lost, however fast the robot's HK. 2.5 s (2.5
/// heartbeats) so that a dead link is reported within 3 s, the ground's promise,
/// including the poll and process exit, at the MIB's default HK interval (1 s).
pub const LINK_LOSS_MS: u32 = 2500;
const _: () =
    assert!(GROUND_HEARTBEAT_MS * 2 < LINK_LOSS_MS && (LINK_LOSS_MS as usize) < SUBSCRIPTION_LEASE_MS as usize);
/// Ground: the link is lost after this many tenths of the robot's status-HK interval
/// without TM (2.5 intervals), never sooner than [`LINK_LOSS_MS`]. HK is the TM a robot
/// sends on its own, whatever happens to the uplink (the answers to the ground's TCs need
/// the uplink too): one lost HK report leaves a silence of just under two intervals,
/// which must not count as a loss; the half interval over two is room for scheduling
/// jitter. Every front end (CLI, collector, page) applies [`link_loss_ms`].
pub const LINK_LOSS_HK_TENTHS: u32 = 25;

/// Ground: the one link-loss rule — no TM for this long (ms) with the robot's status HK
/// at `hk_interval_ms` means the link is lost: max([`LINK_LOSS_MS`],
/// [`LINK_LOSS_HK_TENTHS`]/10 × the interval). At the MIB's default interval (1 s) it is
/// [`LINK_LOSS_MS`].
pub const fn link_loss_ms(hk_interval_ms: u32) -> u32 {
    let by_hk = hk_interval_ms as u64 * LINK_LOSS_HK_TENTHS as u64 / 10;
    if by_hk > u32::MAX as u64 {
        u32::MAX
    } else if by_hk > LINK_LOSS_MS as u64 {
        by_hk as u32
    } else {
        LINK_LOSS_MS
    }
}

// --- Ground: TM gaps retrieved from the on-board store (PUS 15) ---

/// Ground: gaps in a robot's TM at most this many sequence counts apart are asked for as
/// one range; the packets between come again and are dropped as duplicates. Merging two
/// gaps `d` apart replays `d` packets the ground already has to save one request and its
/// reports (acceptance, TM[15,19], completion — each of which can be lost and become a
/// gap of its own). 16 bounds that waste per merge while still joining the many short
/// gaps of a lossy link into few ranges; the collector's 64 replayed up to four times as
/// much (both front ends now use this one number).
pub const GAP_MERGE_DISTANCE: u16 = 16;
/// Ground: most sequence counts asked for in one range: the replay of one request stays
/// a short burst however long the outage was (the rest is asked for in the next round):
/// 256 packets of ~100 B are ~25 kB, a fraction of a second on the lab links, and a
/// sixteenth of the on-board store ([`TM_STORE_CAPACITY`]).
pub const GAP_RANGE_MAX: u16 = 256;
/// Ground: most ranges asked of one robot's store in one round. Each is a TC the robot
/// remembers in its duplicate window ([`DUPLICATE_WINDOW`]) beside the heartbeats of one
/// retry span (~38): together under half the window, the rest is for plan TCs.
pub const GAP_REQUESTS_MAX: usize = 16;
const _: () = assert!(GAP_REQUESTS_MAX + (TC_RETRY_SPAN_MS / GROUND_HEARTBEAT_MS) as usize <= DUPLICATE_WINDOW / 2);
/// Ground: ranges asked per round while TM is live (a plan running, a collector
/// following a robot): one, and the next round waits for the pacing rule
/// ([`STORE_REQUEST_TIMEOUT_MS`], [`STORE_REQUEST_MIN_GAP_MS`]), so one replay is in
/// flight per robot and the ground's own requests — whose reports can be lost and make
/// new gaps — cannot snowball. The rest is asked for at the end of a run
/// ([`GAP_REQUESTS_MAX`] per round).
pub const GAP_REQUESTS_LIVE: usize = 1;
/// Ground, every front end (`ground_ops::live::RetrievalPacer`): a store retrieval is in
/// flight until its end report (TM[15,19]) or its TC's completion or failure report, at
/// most this long (its reports were lost; the holes are asked for again): nearly three
/// first waits of a TC ([`TC_RETRY_INITIAL_MS`]).
pub const STORE_REQUEST_TIMEOUT_MS: u32 = 2_000;
/// Ground, every front end (`ground_ops::live::RetrievalPacer`): least time between two
/// store retrievals (rounds of requests) to one robot, however early the last ended: the
/// requests' own reports can be lost and make new gaps, so their rate is bounded (two
/// rounds per second, below the 1 s heartbeat's TM).
pub const STORE_REQUEST_MIN_GAP_MS: u32 = 500;
/// Ground: how long an accepted TC that no step waits for (a marker, a store retrieval,
/// `ground send` without waiting) is tracked for its completion: it is never resent, and
/// a lost completion report is recovered as a TM gap; after this it is forgotten. Seven
/// first waits ([`TC_RETRY_INITIAL_MS`]) for a report that on board follows acceptance
/// within a control period or two (a store replay: [`GAP_RANGE_MAX`] packets at most),
/// short enough not to hold a session's exit for long.
pub const UNTAGGED_COMPLETION_WAIT_MS: u32 = 5_000;
/// Ground (collector): the HK-interval TC is sent this many times per link-up (once per
/// lease renewal, [`GROUND_HEARTBEAT_MS`]: 10 s of trying) until its completion is seen;
/// then the collector waits for the next link-up or reboot, so a robot that refuses it is
/// not sent it forever.
pub const HK_SET_TRIES: u32 = 10;
/// Ground (collector): least time between two requests for the module report or the team
/// status: the answer of the first one (a TC executes within a control period or two) is
/// there by then; a lost one is asked again instead of waiting for the next lease renewal.
pub const GROUND_ASK_AGAIN_MS: u32 = 500;

// --- Ground: the collector's link and archive timing, `ground run`'s end of run ---

/// Ground (collector): first pause before trying a lost robot again (a ping; over TCP a
/// new connection first); each further pause doubles up to the configured cap
/// ([`GROUND_RECONNECT_CAP_MS`]). A quarter of the heartbeat ([`GROUND_HEARTBEAT_MS`]):
/// an obsw restarted at once is found again within half a second, and a try costs one
/// small TC.
pub const GROUND_RECONNECT_FIRST_MS: u32 = 250;
/// Ground (collector): longest pause between two reconnection tries, and the largest the
/// configuration (`[link] max_backoff_ms`) may set: a robot back after an outage is seen
/// within 5 s (two link-loss floors, [`LINK_LOSS_MS`]), while a dead robot costs one TC
/// every 5 s.
pub const GROUND_RECONNECT_CAP_MS: u32 = 5_000;
const _: () =
    assert!(GROUND_RECONNECT_FIRST_MS < GROUND_HEARTBEAT_MS && GROUND_RECONNECT_FIRST_MS < GROUND_RECONNECT_CAP_MS);
/// Ground (collector): a robot's link health (link state, quality, counters) is written to
/// the archive this often: within one link-loss floor ([`LINK_LOSS_MS`]) of a change, at
/// one row per robot per 2 s (43,200 rows a day) however fast the TM.
pub const COLLECTOR_HEALTH_MS: u32 = 2_000;
const _: () = assert!(COLLECTOR_HEALTH_MS < LINK_LOSS_MS);
/// Ground: packets still on their way after a hole was seen, or after a store replay
/// ended, arrive within this (the lab links and the frame link deliver within a few
/// control periods; a count that comes later is a hole): the collector asks the store for
/// a new hole only after it (`[gaps] settle_ms`), and `ground run` waits it after each
/// retrieval round before counting the holes. Below [`STORE_REQUEST_MIN_GAP_MS`], so it
/// never slows the retrieval rate.
pub const GAP_SETTLE_MS: u32 = 300;
const _: () = assert!(GAP_SETTLE_MS < STORE_REQUEST_MIN_GAP_MS);
/// Ground (collector): a hole still there this long after it was last asked for is asked
/// for again (`[gaps] retry_ms`): longer than [`STORE_REQUEST_TIMEOUT_MS`], so the request
/// before it has ended or been given up and one replay is in flight per robot.
pub const GAP_RETRY_MS: u32 = 3_000;
const _: () = assert!(GAP_RETRY_MS > STORE_REQUEST_TIMEOUT_MS);
/// Ground (collector): requests per hole before it is declared not delivered
/// (`[gaps] max_tries`): the hole is lost only when all its replays are lost (at 20 %
/// packet loss 0.2^5 = 0.03 % of the counts), and a hole the store no longer holds is
/// reported within [`GAP_MAX_TRIES`] × [`GAP_RETRY_MS`] = 15 s.
pub const GAP_MAX_TRIES: u32 = 5;
/// Ground (collector): `STALE_DATA` when TM flows but no status HK came for this many HK
/// intervals (`[alarms] stale_hk_intervals`): more than the link-loss rule's 2.5
/// intervals ([`LINK_LOSS_HK_TENTHS`]), so one lost HK report is not an alarm.
pub const STALE_HK_INTERVALS: u32 = 3;
const _: () = assert!(STALE_HK_INTERVALS * 10 > LINK_LOSS_HK_TENTHS);
/// Ground (collector): the stale-HK silence is never shorter than this, whatever the HK
/// interval: one heartbeat ([`GROUND_HEARTBEAT_MS`]), so a fast HK (down to 10 ms) does
/// not raise `STALE_DATA` on a pause of the ground's own scheduling.
pub const STALE_HK_MIN_MS: u32 = 1_000;
/// Ground (`ground run`, over frames): ranges asked at once where an awaited TC's reports
/// are missing: its acceptance and its completion report may fall in two separate holes.
pub const GAP_REQUESTS_AWAITED: usize = 2;
/// Ground (`ground run`, end of a run): one retrieval round waits at most this long for its
/// requests to end: more than [`STORE_REQUEST_TIMEOUT_MS`], after which a request whose
/// end report was lost no longer counts as open (the round ends sooner when none is).
pub const GAP_ROUND_WAIT_MS: u32 = 3_000;
const _: () = assert!(GAP_ROUND_WAIT_MS > STORE_REQUEST_TIMEOUT_MS);
/// Ground (`ground run`, end of a run): retrieval rounds in a row that fill no hole before
/// the rest counts as not recovered. A round fills nothing only when every replay it asked
/// for was lost; eight in a row end a run on a link that delivers nothing, after at most
/// 8 × ([`TC_RETRY_SPAN_MS`] or [`GAP_ROUND_WAIT_MS`] + [`GAP_SETTLE_MS`]).
pub const GAP_ROUNDS_IDLE_MAX: u32 = 8;
/// Ground (`ground run`, end of a run): most retrieval rounds: 40 × [`GAP_REQUESTS_MAX`]
/// ranges of up to [`GAP_RANGE_MAX`] counts cover the whole on-board store
/// ([`TM_STORE_CAPACITY`]) many times over, so the bound only ends a run whose holes keep
/// coming back (each round's own reports lost).
pub const GAP_ROUNDS_MAX: u32 = 40;
const _: () = assert!(
    GAP_ROUNDS_IDLE_MAX < GAP_ROUNDS_MAX
        && GAP_ROUNDS_MAX as usize * GAP_REQUESTS_MAX * GAP_RANGE_MAX as usize >= TM_STORE_CAPACITY
);

/// OBSW: most TCP clients at once; a further connection is closed at once (counted).
pub const TCP_MAX_CONNECTIONS: usize = 8;
/// OBSW: decoded TCs waiting per TCP connection; when full, the obsw stops reading that
/// connection (the kernel's window then holds the sender back).
pub const TCP_INPUT_QUEUE: usize = 16;
/// OBSW: bytes of TM waiting to be written to one TCP client; a client that falls
/// further behind is disconnected (its TM stays in the on-board store).
pub const TCP_TM_BACKLOG: usize = 256 * 1024;
/// OBSW: longest simulator-control line.
pub const SIM_CTL_MAX_LINE: usize = 256;

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
