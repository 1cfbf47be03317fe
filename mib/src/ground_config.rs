//! The ground tool's tuning: TC retries and their back-off, the link-loss rule, TM gap
//! retrieval from the on-board store, the collector's timers. Not flight constants: no
//! on-board code depends on them beyond the compile-time checks that tie them to the
//! flight numbers of [`crate::config`] (the duplicate window must hold every resend).
//! The JSON export and the ICD list them as the ground's.

/// Ground: TC sequence counts skipped after the archived ones when a ground process
/// starts: more than the TCs a ground killed with SIGKILL can have sent without archiving
/// them (its archive writes behind), so a restarted ground never reuses a request ID the
/// robot has seen.
pub const SEQ_SKIP_AFTER_RESTART: u16 = 256;
/// Ground: time to wait for TM[1,1] before resending a TC (paper: 0.7 s).
pub const GROUND_ACK_TIMEOUT_MS: u32 = 700;
/// Ground: connection-test period (paper: 1.2 s polling).
pub const GROUND_PING_PERIOD_MS: u32 = 1200;
/// Ground: link quality is the success rate over this many exchanges (paper: 100).
pub const LINK_QUALITY_WINDOW: usize = 100;
/// Ground: resends of one TC before the step fails.
pub const GROUND_MAX_RESENDS: u32 = 5;
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
const _: () = assert!(crate::config::DUPLICATE_MAX_AGE_MS >= TC_RETRY_SPAN_MS);
/// Ground: a running ground sends a TC[17,1] at least this often (keeps the lease and
/// checks the link).
pub const GROUND_HEARTBEAT_MS: u32 = 1000;
/// Ground: the floor of the link-loss rule ([`link_loss_ms`]): no TM at all for this long
/// means the link or the obsw is lost, however fast the robot's HK. 2.5 s (2.5
/// heartbeats) so that a dead link is reported within 3 s, the ground's promise,
/// including the poll and process exit, at the MIB's default HK interval (1 s).
pub const LINK_LOSS_MS: u32 = 2500;
const _: () = assert!(
    GROUND_HEARTBEAT_MS * 2 < LINK_LOSS_MS
        && (LINK_LOSS_MS as usize) < crate::host_config::SUBSCRIPTION_LEASE_MS as usize
);
/// Ground: over a UDP lab link a robot sends TM only to a ground whose TC it accepted (its
/// subscription, [`SUBSCRIPTION_LEASE_MS`](crate::host_config::SUBSCRIPTION_LEASE_MS));
/// a TC lost or damaged on the way leaves the ground unsubscribed (a damaged one's refusal
/// reaches it, without subscribing it). Until TM only a subscriber gets has come, a
/// watching ground sends a heartbeat this often, so that the ground's own lost TCs never
/// make a live robot silent for [`LINK_LOSS_MS`]: at 25 % of the TCs lost or damaged, the
/// ten sends of the loss time all fail about once in a million.
pub const SUBSCRIBE_RETRY_MS: u32 = 250;
// These heartbeats stand in for the periodic ones (a heartbeat goes only when no TC went
// within its period) and last at most the loss time: with them the heartbeats of one
// retry span and a round of store requests still fit half the duplicate window.
const _: () = assert!(
    LINK_LOSS_MS / SUBSCRIBE_RETRY_MS >= 8
        && GAP_REQUESTS_MAX
            + ((TC_RETRY_SPAN_MS - LINK_LOSS_MS) / GROUND_HEARTBEAT_MS) as usize
            + (LINK_LOSS_MS / SUBSCRIBE_RETRY_MS) as usize
            <= crate::config::DUPLICATE_WINDOW / 2
);
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
/// sixteenth of the on-board store ([`TM_STORE_CAPACITY`](crate::config::TM_STORE_CAPACITY)).
pub const GAP_RANGE_MAX: u16 = 256;
/// Ground: most ranges asked of one robot's store in one round. Each is a TC the robot
/// remembers in its duplicate window ([`DUPLICATE_WINDOW`](crate::config::DUPLICATE_WINDOW)) beside the heartbeats of one
/// retry span (~38): together under half the window, the rest is for plan TCs.
pub const GAP_REQUESTS_MAX: usize = 16;
const _: () = assert!(
    GAP_REQUESTS_MAX + (TC_RETRY_SPAN_MS / GROUND_HEARTBEAT_MS) as usize <= crate::config::DUPLICATE_WINDOW / 2
);
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
/// ([`TM_STORE_CAPACITY`](crate::config::TM_STORE_CAPACITY)) many times over, so the bound only ends a run whose holes keep
/// coming back (each round's own reports lost).
pub const GAP_ROUNDS_MAX: u32 = 40;
const _: () = assert!(
    GAP_ROUNDS_IDLE_MAX < GAP_ROUNDS_MAX
        && GAP_ROUNDS_MAX as usize * GAP_REQUESTS_MAX * GAP_RANGE_MAX as usize >= crate::config::TM_STORE_CAPACITY
);
