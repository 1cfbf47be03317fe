//! Team coordination without the ground: inter-robot link, leader selection timing and
//! capacities, limited leader authority. One place for every number the on-board team
//! logic, the simulator and the ground share.
//!
//! Rationale for the timing figures is in `docs/team.md` ("Timing"). In short: the
//! inter-robot link is assumed to deliver within [`LINK_MAX_DELAY_MS`] (or lose the packet);
//! on-board clocks drift by at most [`CLOCK_DRIFT_PPM`]; a leader's lease must run out before
//! any robot that acknowledged it can vote for somebody else, so
//! `LEADER_LEASE_MS * (1 + drift) < ELECTION_TIMEOUT_MIN_MS * (1 - drift)`.

use crate::layout::Names;

// ---------------------------------------------------------------------------------------
// Roster
// ---------------------------------------------------------------------------------------

/// Most robots in a team roster (the roster is uploaded by the ground and fixed).
pub const ROSTER_MAX: usize = 8;
/// Fewest robots in a roster: a team of one has nobody to coordinate.
pub const ROSTER_MIN: usize = 2;

/// Votes needed to win an election in a roster of `n` robots: a strict majority of the
/// whole roster (not of the robots currently reachable). A team of two needs both.
pub const fn quorum(n: usize) -> usize {
    n / 2 + 1
}

// ---------------------------------------------------------------------------------------
// Timing (all in ms of the robot's own monotonic clock)
// ---------------------------------------------------------------------------------------

/// The ground is declared lost after this long without a valid ground TC. The ground
/// sends at least a time/housekeeping TC every few seconds during a pass; 5 s is two missed
/// 2 s ground heartbeats plus margin.
pub const GROUND_LOSS_TIMEOUT_MS: u64 = 5_000;
/// Election timeout after hearing a leader (or granting a vote, or a failed candidacy): a
/// robot waits `ELECTION_TIMEOUT_MIN_MS + rank * ELECTION_RANK_STAGGER_MS + jitter` before
/// standing, `rank` being its index in the roster (the ground's order of preference) and
/// `jitter` uniform in `0..ELECTION_JITTER_MS` (randomness from the host). It never votes
/// within `ELECTION_TIMEOUT_MIN_MS` of hearing a leader or granting a vote.
pub const ELECTION_TIMEOUT_MIN_MS: u64 = 1_000;
/// Extra wait per roster rank: the preferred robot stands first, the next one a stagger
/// later, so that with a one-way delay below the stagger their candidacies rarely collide.
pub const ELECTION_RANK_STAGGER_MS: u64 = 800;
/// Random part of every election timeout (exclusive upper bound of the uniform draw).
pub const ELECTION_JITTER_MS: u64 = 200;
/// First election after the ground loss is detected: no leader can exist then, so the
/// base is short: `ELECTION_FIRST_BASE_MS + rank * ELECTION_RANK_STAGGER_MS + jitter`.
pub const ELECTION_FIRST_BASE_MS: u64 = 500;
/// Longest election timeout of any robot (last rank, largest jitter; exclusive bound).
pub const ELECTION_TIMEOUT_MAX_MS: u64 =
    ELECTION_TIMEOUT_MIN_MS + (ROSTER_MAX as u64 - 1) * ELECTION_RANK_STAGGER_MS + ELECTION_JITTER_MS;
/// A leader sends a heartbeat (carrying its directive) this often.
pub const HEARTBEAT_PERIOD_MS: u64 = 200;
/// A candidate repeats its vote request to robots that have not answered this often
/// (the link may lose packets).
pub const VOTE_RETRY_MS: u64 = 300;
/// Leader lease: a leader only directs while a quorum (itself included) has acknowledged a
/// heartbeat it sent less than this long ago; otherwise it steps down.
pub const LEADER_LEASE_MS: u64 = 900;
/// A leader steps down when no quorum acknowledged a heartbeat it sent within this time
/// (check-quorum; longer than the worst round trip plus a heartbeat period).
pub const LEADER_QUORUM_CHECK_MS: u64 = 2_000;
/// Assumed worst one-way delay of the inter-robot link (later packets are treated as lost).
pub const LINK_MAX_DELAY_MS: u64 = 500;
/// Assumed worst relative drift of two robots' clocks, parts per million.
pub const CLOCK_DRIFT_PPM: u64 = 1_000;

/// Floodmax baseline (paper `002_…`): length of one synchronous round. Floodmax assumes
/// synchronous rounds, so a round lasts the worst link delay.
pub const FLOODMAX_ROUND_MS: u64 = LINK_MAX_DELAY_MS;

// The lease is shorter than the election timeout, with margin for the drift.
const _: () =
    assert!(LEADER_LEASE_MS * (1_000_000 + CLOCK_DRIFT_PPM) < ELECTION_TIMEOUT_MIN_MS * (1_000_000 - CLOCK_DRIFT_PPM));
const _: () = assert!(HEARTBEAT_PERIOD_MS * 3 < LEADER_LEASE_MS);
const _: () = assert!(ELECTION_TIMEOUT_MIN_MS < ELECTION_TIMEOUT_MAX_MS);
const _: () = assert!(LEADER_LEASE_MS < LEADER_QUORUM_CHECK_MS);
const _: () = assert!(2 * LINK_MAX_DELAY_MS + HEARTBEAT_PERIOD_MS < LEADER_QUORUM_CHECK_MS);
const _: () = assert!(ROSTER_MIN <= ROSTER_MAX && ROSTER_MAX <= 32);

// ---------------------------------------------------------------------------------------
// Authority
// ---------------------------------------------------------------------------------------

/// Most plan steps a ground authorisation may let a leader continue without the ground.
pub const MAX_AUTHORISED_STEPS: u8 = 4;
/// Longest validity of a ground authorisation, counted from its upload.
pub const MAX_AUTHORISATION_MS: u64 = 30 * 60 * 1_000;

// ---------------------------------------------------------------------------------------
// Inter-robot link
// ---------------------------------------------------------------------------------------

/// APID of inter-robot team packets (robot APIDs are `0x101..=0x1FE`, idle is `0x7FF`).
/// Intended: a PUS TM-like packet, service [`TEAM_SERVICE`], the team message as the
/// application data, authenticated like the ground link once SDLS has landed.
pub const TEAM_APID: u16 = 0x0E0;
/// Private PUS service type of team messages and of the team TM (events stay in service 5).
pub const TEAM_SERVICE: u8 = 211;
/// Subservice of a team message between robots.
pub const TEAM_SUBSERVICE_MESSAGE: u8 = 1;
/// Subservice of the team status report (TM to the ground).
pub const TEAM_SUBSERVICE_STATUS: u8 = 2;
/// Subservice of the ground's authorisation upload (TC).
pub const TEAM_SUBSERVICE_AUTHORISE: u8 = 3;
/// Version byte of the authenticated team datagram (host inter-robot link):
/// `| version 1 | IV 12 (sender robot, 88-bit counter) | AES-256-GCM ciphertext | MAC 16 |`,
/// the version and IV authenticated as additional data.
pub const TEAM_SEC_VERSION: u8 = 1;
/// Length of the team datagram's security header (version + IV).
pub const TEAM_SEC_HEADER_LEN: usize = 1 + crate::link::sdls::IV_LEN;
/// A sender reserves this many counters per durable write of its high-water mark (as the
/// space link's `IV_RESERVE_BLOCK`): after a restart it resumes above every counter it
/// may have used.
pub const TEAM_IV_RESERVE_BLOCK: u64 = crate::link::sdls::IV_RESERVE_BLOCK;
/// Per-sender replay window: besides any counter above the sender's highest accepted one,
/// a counter up to this many below it that was not seen yet is accepted (reordering).
pub const TEAM_REPLAY_WINDOW: u32 = 64;
/// Version byte of the team message format.
pub const WIRE_VERSION: u8 = 1;
/// Length of the common header of every team message.
pub const WIRE_HEADER_LEN: usize = 15;
/// Longest team message (header + largest body).
pub const WIRE_MAX_LEN: usize = 24;

// ---------------------------------------------------------------------------------------
// Events (PUS 5) the team logic raises (defined in `events.rs`), names of their codes,
// the team TCs and the status report period.
// ---------------------------------------------------------------------------------------

/// Team event IDs (range 0x0300), defined in `crate::events` with their parameters.
pub mod eid {
    pub use crate::events::eid::{
        DIRECTIVE_EXECUTED, DIRECTIVE_REFUSED, ELECTION_STARTED, GROUND_LOST, GROUND_REGAINED, LEADER_ELECTED,
        STEPPED_DOWN,
    };
}

/// Names of the STEPPED_DOWN reason codes (`mmic_team::node::StepDownReason`).
pub const TEAM_STEP_DOWN_NAMES: Names = Names::List(&[(0, "GROUND_REGAINED"), (1, "HIGHER_TERM"), (2, "QUORUM_LOST")]);
/// Names of the directive codes (wire: 1 HOLD, 2 CONTINUE).
pub const TEAM_DIRECTIVE_NAMES: Names = Names::List(&[(1, "HOLD"), (2, "CONTINUE")]);
/// Names of the DIRECTIVE_REFUSED reason codes (`mmic_team::node::RefuseReason`).
pub const TEAM_REFUSE_NAMES: Names = Names::List(&[
    (0, "STALE_TERM"),
    (1, "GROUND_PRESENT"),
    (2, "NOT_AUTHORISED"),
    (3, "EXPIRED"),
    (4, "PLAN_MISMATCH"),
    (5, "WRONG_STEP"),
]);
/// Names of the team roles in the status report.
pub const TEAM_ROLE_NAMES: Names = Names::List(&[(0, "FOLLOWER"), (1, "CANDIDATE"), (2, "LEADER")]);
/// Names of the TEAM_PACKET_REJECTED reasons (HK TEAM parameter `TEAM_REJ_MALFORMED + code`).
pub const TEAM_REJECT_NAMES: Names = Names::List(&[
    (0, "MALFORMED"),
    (1, "TRUNCATED"),
    (2, "UNKNOWN_SENDER"),
    (3, "BAD_MAC"),
    (4, "REPLAY"),
    (5, "STORE_FAILED"),
]);
/// Names of the TEAM_STATE_LOADED status codes.
pub const TEAM_STATE_NAMES: Names = Names::List(&[(0, "RESTORED"), (1, "NONE"), (2, "CORRUPT")]);
/// Names of the PLAN_STEP_REFUSED reason codes.
pub const TEAM_PLAN_REFUSE_NAMES: Names = Names::List(&[
    (0, "NO_PLAN"),
    (1, "NOT_AUTHORISED"),
    (2, "INITIAL_STATE"),
    (3, "BUSY"),
    (4, "FORBIDDEN"),
    (5, "REFUSED"),
]);

/// Subservice of the TC that uploads the team roster.
pub const TEAM_SUBSERVICE_ROSTER: u8 = 4;
/// Subservice of the TC that uploads one step of the authorised plan.
pub const TEAM_SUBSERVICE_PLAN_STEP: u8 = 6;

/// One step of an authorised plan as uploaded (TC TEAM_PLAN_STEP): the same for every
/// robot of the roster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlanStep {
    pub step: u16,
    pub function: u16,
    pub args: [i32; 2],
    pub initial_state: u8,
}

const PLAN_CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// The plan hash the ground puts in TEAM_AUTHORISE: CRC-32 (ISO-HDLC) over plan ID (u16),
/// then per step in order step (u16), function (u16), arg0 (i32), arg1 (i32), initial
/// state (u8), all big-endian. A check that robots and ground mean the same steps (the
/// uploads come over the authenticated ground link), not a cryptographic digest.
pub fn plan_hash(plan_id: u16, steps: &[PlanStep]) -> u32 {
    let mut d = PLAN_CRC.digest();
    d.update(&plan_id.to_be_bytes());
    for s in steps {
        d.update(&s.step.to_be_bytes());
        d.update(&s.function.to_be_bytes());
        d.update(&s.args[0].to_be_bytes());
        d.update(&s.args[1].to_be_bytes());
        d.update(&[s.initial_state]);
    }
    d.finalize()
}

/// Subservice of the TC that asks for a team status report.
pub const TEAM_SUBSERVICE_STATUS_REQUEST: u8 = 5;
/// The obsw sends a team status report this often (and on request).
pub const STATUS_PERIOD_MS: u64 = 2_000;

/// Length of the team status report's application data: term (4), role (1), leader (1),
/// ground seen (1), roster length (1), roster (ROSTER_MAX).
pub const STATUS_REPORT_LEN: usize = 8 + ROSTER_MAX;

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: TEAM-QUORUM-01
    #[test]
    fn quorum_is_a_strict_majority_of_the_roster() {
        for n in ROSTER_MIN..=ROSTER_MAX {
            let q = quorum(n);
            assert!(2 * q > n, "n={n}");
            assert!(2 * (q - 1) <= n, "n={n}");
        }
        assert_eq!(quorum(2), 2);
        assert_eq!(quorum(3), 2);
        assert_eq!(quorum(8), 5);
    }
}
