//! Files over the space link: the CCSDS File Delivery Protocol (727.0-B-5) between the
//! ground's CFDP entity and each robot's, and the robot's file store. One place for the
//! APID, entity IDs, PDU sizes, timers, limits and the file store's name rules that the
//! on-board entity, the ground's and the documents share (`docs/files.md`).
//!
//! PDUs travel as the data field of space packets on [`APID`] (no PUS secondary header),
//! downlink in TM frames on the files VC, uplink in TC frames through SDLS: directives and
//! class 1 file data in AD frames (COP-1: never lost, in order), class 2 file data in BD
//! frames ([`is_bypass_file_data`]: lost frames are recovered by class 2's NAKs, not by
//! COP-1's go-back-N). The downlink may lose PDUs, and class 2's NAKs recover them.

/// APID of the space packets that carry CFDP PDUs, both directions (one entity per robot
/// behind each space link; the entity IDs tell the robots apart).
pub const APID: u16 = 0x0F0;

/// Whether a TC space packet may travel in a BD (bypass) frame: a PDU packet on [`APID`]
/// (version 0, TC, no secondary header, unsegmented) whose PDU (727.0-B-5 § 5.1) is of
/// version 2 (`001`), file data, toward the file receiver, in acknowledged mode (class 2).
///
/// BD frames pass the same SDLS checks as AD frames (SPI, anti-replay window, MAC) but
/// skip FARM-1's sequence check; the robot refuses a BD frame holding anything but this
/// and time-tagged commands (`crate::link::bypass_admissible`, `LINK_REJ_BD_CONTENT`). File
/// data commands nothing: it lands only in a transaction its metadata (a directive, in an
/// AD frame) opened, under a staging name until the checksum proves the file. Class 1
/// file data stays in AD frames: nothing would recover a lost segment.
pub fn is_bypass_file_data(packet: &[u8]) -> bool {
    const TC_PACKET_ID: u16 = (1 << 12) | APID;
    let Some(([id0, id1, seq0, _, len0, len1], pdu)) = packet.split_first_chunk::<6>() else {
        return false;
    };
    let Some(&first) = pdu.first() else { return false };
    u16::from_be_bytes([*id0, *id1]) == TC_PACKET_ID
        && seq0 & 0xC0 == 0xC0
        && usize::from(u16::from_be_bytes([*len0, *len1])) + 1 == pdu.len()
        // version 001, PDU type 1 (file data), direction 0 (toward the receiver),
        // transmission mode 0 (acknowledged); CRC and large-file flags either way.
        && first & 0xFC == 0b0011_0000
}

/// CFDP entity ID of the ground (the source of puts up, the destination of files down).
pub const GROUND_ENTITY_ID: u16 = 0;

/// CFDP entity ID of robot `n`: the robot number.
pub const fn robot_entity_id(n: u8) -> u16 {
    n as u16
}

/// Bytes of the entity IDs in the PDU header (both ends use the same width).
pub const ENTITY_ID_LEN: usize = 2;
/// Bytes of the transaction sequence number in the PDU header.
pub const SEQ_NUM_LEN: usize = 2;

/// Longest PDU: its space packet (6 header bytes more) fits one TC frame's data field
/// (`link::tc_frame::MAX_PACKET_LEN`) and spans at most one TM frame boundary.
pub const MAX_PDU_LEN: usize = 960;
/// Longest space packet carrying a PDU.
pub const MAX_PACKET_LEN: usize = MAX_PDU_LEN + 6;
const _: () = assert!(MAX_PACKET_LEN <= crate::link::tc_frame::MAX_PACKET_LEN);

/// File data bytes in one file data PDU: the PDU less its header (4 fixed bytes, two entity
/// IDs, a sequence number) and the 4-byte segment offset.
pub const MAX_SEGMENT_LEN: usize = MAX_PDU_LEN - 4 - 2 * ENTITY_ID_LEN - SEQ_NUM_LEN - 4;

/// File checksum the entities send (SANA checksum identifier): 0, the modular checksum of
/// 727.0-B-5 Annex F, the one every CFDP implementation has (Yamcs' CFDP service and Python
/// `cfdp` compute no other). Each frame carrying the file is already authenticated by SDLS;
/// the checksum guards the reassembly. Received files are checked with whatever checksum
/// their sender chose (modular, CRC-32, CRC-32C or null).
pub const CHECKSUM_TYPE: u8 = 0;
/// PDUs are sent without the optional PDU CRC: every frame that carries them already has
/// its frame CRC and SDLS MAC, and Python `cfdp` refuses PDUs with a CRC. PDUs that carry
/// one are taken, their CRC checked.
pub const PDU_CRC: bool = false;

// ---------------------------------------------------------------------------------------
// Timers and limits (727.0-B-5 § 4.6.3, 4.6.4, 4.7; ms of the entity's own clock)
// ---------------------------------------------------------------------------------------

/// Positive ACK timer of this project's entities (the robot's and `ground file`'s): an EOF
/// or Finished PDU not acknowledged in this time is sent again. Sized to the link's round
/// trip (a control period on board, the ground's 5 ms poll, an uplink frame that COP-1 sends
/// again after its adaptive T1 of 300 ms and up on a short link), not to its worst case:
/// the answer to a PDU comes down promptly or never (a quarter of the downlink's PDUs are
/// lost through the 20/5/5 relay), and an expiry while the answer is still on its way costs
/// one PDU each way. A 4 s timer cost 4 s for every lost answer: a `get`'s lost ACK of its
/// Finished, a `put`'s lost Finished.
pub const ACK_TIMER_MS: u64 = 1_000;
/// Expiries of the positive ACK timer before the fault "positive ACK limit reached": 32 s of
/// a peer that never answers; a quarter of the answers lost, 32 in a row have a chance of
/// 0.25³² ≈ 5 × 10⁻²⁰.
pub const ACK_LIMIT: u32 = 32;
/// NAK timer of this project's entities: a NAK that brought nothing is sent again after this
/// time, the same round trip as the positive ACK timer. It does not expire while the
/// answers are still coming in (file data within [`NAK_QUIET_MS`]), so a long answer is not
/// asked for twice; a NAK whose answers were all lost costs this timer, once per round.
pub const NAK_TIMER_MS: u64 = ACK_TIMER_MS;
/// A receiver whose last NAK was answered (file data came after it) and that then hears no
/// file data for this long sends its next NAK at once instead of at the NAK timer: the
/// sender sends the segments a NAK asks for back to back (`SEGMENTS_PER_POLL` a control
/// period), so a pause this long means they have all gone out. 30 control periods: a
/// sender held up by its scheduler makes at worst a NAK sent twice, and the segments sent
/// twice.
pub const NAK_QUIET_MS: u64 = 30 * crate::config::CONTROL_PERIOD_MS as u64;
/// Expiries of the NAK timer in one transaction before the fault "NAK limit reached".
/// 727.0-B-5 § 4.6.4.7 restarts the count on every recovered segment; cfdp-rs 0.3 restarts
/// it only while the metadata is missing, so the limit bounds a whole transfer's NAK
/// phase: 600 × 1 s = 10 min, longer than the largest file (`MAX_FILE_LEN`) needs through
/// the relay. A peer that hears the NAKs but says nothing is caught by [`INACTIVITY_MS`]
/// after a minute.
pub const NAK_LIMIT: u32 = 600;
/// Whether the robot's entity sends a NAK for each gap as soon as data after it arrives
/// (727.0-B-5 § 4.6.4.3.1 a, b), besides the NAK of all gaps after the EOF: its NAKs go down
/// in TM packets, nothing queues them, and the sender answers each while the file is still
/// going up.
pub const ROBOT_IMMEDIATE_NAK: bool = true;
/// Whether the ground's entity sends immediate NAKs: no. Each of its PDUs goes up in an AD
/// frame that COP-1 delivers in order, ten frames in the window, go-back-N on a loss: a
/// `get` through the relay made about 30 immediate NAKs, and the NAK of the deferred
/// procedure and the ACKs of the robot's EOF queued behind them for seconds (the robot sent
/// its EOF six times). One NAK after the EOF asks for every gap (up to 120 a PDU).
pub const GROUND_IMMEDIATE_NAK: bool = false;
/// Copies of each metadata and Finished PDU the robot's entity sends. They go down in TM
/// packets, a quarter of which the lossy relay loses: a lost metadata PDU makes the ground
/// drop the file data that comes before its next copy (asked for at once, but a round trip
/// of segments is gone: a traced `get` lost 95 of its 277 so), a lost Finished costs the
/// robot's positive ACK period. The second copy goes at the entity's next poll, in another
/// TM frame than the first (a frame carries several small PDUs: copies in one are lost
/// together); both ends take a repeated one once (cfdp-rs acts on a metadata PDU once, the
/// ground's entity acknowledges a repeated Finished again).
pub const ROBOT_DIRECTIVE_COPIES: usize = 2;
/// The ground's: one. Its directives go up in AD frames that COP-1 delivers.
pub const GROUND_DIRECTIVE_COPIES: usize = 1;
/// How often the file service counts its store's files and free bytes for HK FILES (and
/// when a transaction ended): a listing reads the medium, so not every control period.
pub const STORE_LOOK_MS: u64 = 1000;
/// Yamcs' CFDP service's timers (its `eofAckTimeout`, `finAckTimeout`, `nakTimeout` in the
/// generated instance): twice the ground's COP-1 T1 upper bound (`link::cop1::FOP_T1_MS`),
/// as Yamcs' TCs go up through its own FOP-1 with a fixed T1.
pub const YAMCS_ACK_TIMER_MS: u64 = 2 * crate::link::cop1::FOP_T1_MS;
/// Yamcs' positive ACK limit: 32 s, as [`ACK_LIMIT`] × [`ACK_TIMER_MS`].
pub const YAMCS_ACK_LIMIT: u32 = 8;
/// Yamcs' NAK timer.
pub const YAMCS_NAK_TIMER_MS: u64 = YAMCS_ACK_TIMER_MS;
/// Yamcs' NAK limit: 10 min, as [`NAK_LIMIT`] × [`NAK_TIMER_MS`].
pub const YAMCS_NAK_LIMIT: u32 = 150;
/// Class 1 check timer: after an EOF with data missing, the receiver waits this long for
/// late file data before it counts one check.
pub const CHECK_TIMER_MS: u64 = 1_000;
/// Expiries of the check timer before the class 1 fault "check limit reached".
pub const CHECK_LIMIT: u32 = 2;
/// Inactivity: a transaction that heard no PDU for this long is abandoned (the fault
/// "inactivity detected", reported with that condition), so a vanished peer never holds
/// the entity for ever. Longer than the positive ACK limit (`ACK_LIMIT` × `ACK_TIMER_MS`)
/// so a peer still retrying is never abandoned first.
pub const INACTIVITY_MS: u64 = 60_000;

/// Lost segments one receiving transaction tracks: every other segment of the largest file,
/// the most gaps a sender of whole segments can leave. cfdp-rs 0.3 records no gap its list
/// has no room for: the data of that gap is never asked for and the transaction ends with a
/// checksum failure (a 256 KiB `get` through the relay did, with 64 here). Also the
/// sender's queue of segments asked for again.
pub const MAX_LOST_SEGMENTS: usize = (MAX_FILE_LEN as usize).div_ceil(MAX_SEGMENT_LEN) / 2 + 1;
/// File data PDUs a source sends per call of the entity's `poll` (per control period on
/// board), new and sent again together: the rate the file service may take of the
/// downlink (3 × 946 bytes per 10 ms, 284 kB/s), so that a transfer leaves room for
/// housekeeping and events and never sends faster than a ground takes its frames (at 8 a
/// period the ground's socket dropped 113 of 277 frames of a clean 256 KiB `get`).
pub const SEGMENTS_PER_POLL: usize = 3;
/// File data PDUs board A's file service reads and sends a control period, at most
/// (`mmic_cfdp::Entity::poll_paced`), and only while its downlink has room for them: the
/// board encrypts `fw_core::spacelink::SDLS_WORK_PER_PERIOD` GCM blocks a period, less than
/// one segment (a const assertion there), so more would only queue ahead of the link; a
/// segment read and framed is about 30 000 RV32 instructions of the period
/// (`firmware/qemu-tests` `t_files`, enforced in `t_budget`).
pub const BOARD_SEGMENTS_PER_PERIOD: usize = 1;
/// File bytes the robot's entity reads and sums per call of its `poll` (per control period
/// on board; the ground's sums a whole file a poll) while a file's checksum is computed: the sender's during its file data, the
/// receiver's while it holds the EOF (or the segment that completes the file) that would
/// make cfdp-rs sum the whole file in one call. About 5 000 RV32 instructions a KiB (board
/// A, firmware/qemu-tests t_files): a whole file of the board's store in one period broke
/// the period's budget above 17 KiB; 8 KiB a period keeps it well inside and sums the
/// largest file of the board's store in 13 periods.
pub const CHECKSUM_BYTES_PER_POLL: usize = 8 * 1024;
/// Of those, what a sender sums in a poll that may also send file data (up to
/// `SEGMENTS_PER_POLL` segments read and framed, the file service's heaviest period on
/// board A): a little more than the data those segments carry, so the sum, started with
/// the put, is done when the data is and the EOF never waits for it.
pub const CHECKSUM_BYTES_WITH_DATA: usize = checksum_bytes_with(SEGMENTS_PER_POLL);
/// What a sender sums in a poll that may send `segments` file data PDUs (a board paces
/// them to its downlink, `fw_core::files`): one segment more than they carry, none in a
/// poll that sends none (the sum stays ahead of the data it has sent).
pub const fn checksum_bytes_with(segments: usize) -> usize {
    if segments == 0 {
        0
    } else {
        (segments + 1) * MAX_SEGMENT_LEN
    }
}
const _: () = assert!(
    CHECKSUM_BYTES_WITH_DATA <= CHECKSUM_BYTES_PER_POLL
        && CHECKSUM_BYTES_WITH_DATA > SEGMENTS_PER_POLL * MAX_SEGMENT_LEN
);
/// PDUs the entity holds for the link before it drops one (counted; class 2 recovers it).
pub const OUTBOX_DEPTH: usize = 16;

// ---------------------------------------------------------------------------------------
// File store
// ---------------------------------------------------------------------------------------

/// Longest file name: ASCII letters, digits, '.', '_' and '-', not starting with '.',
/// no directories (the store is flat: nothing can name a path outside it).
pub const MAX_NAME_LEN: usize = 48;
/// Largest file the store takes (the board's file store area is 128 KiB, `mib::memory::FILE_STORE`).
pub const MAX_FILE_LEN: u64 = 1 << 20;
/// Files the store holds at most.
pub const MAX_FILES: usize = 64;
/// Bytes of the board's file store area (the memory map's `files` region).
pub const BOARD_STORE_BYTES: u32 = crate::memory::FILE_STORE.size;
/// A file being received is written under `PARTIAL_PREFIX` + "SOURCE-SEQ" (the
/// transaction) and renamed to its name only when it arrived complete, checksum verified:
/// a transfer cut short (a fault, a reset) never leaves a truncated file under the name.
/// The robot removes such files when it starts. Names with this prefix are reserved.
pub const PARTIAL_PREFIX: &str = "partial-";
/// Name of the listing a directory listing request writes (then sent to the requester).
pub const LISTING_NAME: &str = "dir.lst";

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: FILE-CFDP-05, FILE-BD-02
    #[test]
    fn inactivity_outlasts_the_positive_ack_retries_and_timers_cover_a_cop1_retransmission() {
        const { assert!(INACTIVITY_MS > ACK_LIMIT as u64 * ACK_TIMER_MS) };
        const { assert!(INACTIVITY_MS > YAMCS_ACK_LIMIT as u64 * YAMCS_ACK_TIMER_MS) };
        // Yamcs' longer timers keep the same limits in time; ours still outlast an answer
        // whose AD frame COP-1 sends again at the lower bound of the adaptive T1, and a
        // NAK's answers coming in.
        const { assert!(YAMCS_ACK_LIMIT as u64 * YAMCS_ACK_TIMER_MS == ACK_LIMIT as u64 * ACK_TIMER_MS) };
        const { assert!(YAMCS_NAK_LIMIT as u64 * YAMCS_NAK_TIMER_MS == NAK_LIMIT as u64 * NAK_TIMER_MS) };
        const { assert!(ACK_TIMER_MS > 2 * crate::link::cop1::FOP_T1_MIN_MS) };
        const { assert!(NAK_TIMER_MS > NAK_QUIET_MS) };
        const { assert!(YAMCS_ACK_TIMER_MS >= 2 * crate::link::cop1::FOP_T1_MS) };
        const { assert!(YAMCS_NAK_TIMER_MS >= 2 * crate::link::cop1::FOP_T1_MS) };
    }

    // verifies: FILE-BD-01
    #[test]
    fn only_a_class_2_file_data_pdu_packet_may_travel_in_a_bd_frame() {
        // A class 2 file data PDU (version 001, file data, toward the receiver,
        // acknowledged) in an unsegmented TC packet on the CFDP APID.
        let mut p = vec![0x10, 0xF0, 0xC0, 0x00, 0x00, 0x00, 0x30, 0x00, 0x05, 0x11];
        p.extend([0, 0, 0, 1, 0, 1, 0, 0, 0, 0, 0xAB]);
        let n = (p.len() - 7) as u16;
        p[4..6].copy_from_slice(&n.to_be_bytes());
        assert!(is_bypass_file_data(&p));
        let changed = |at: usize, v: u8| {
            let mut q = p.clone();
            q[at] = v;
            is_bypass_file_data(&q)
        };
        assert!(changed(6, 0x32), "a PDU CRC is allowed");
        assert!(!changed(6, 0x20), "a file directive (metadata, EOF, NAK, ...)");
        assert!(!changed(6, 0x34), "class 1 (unacknowledged) file data");
        assert!(!changed(6, 0x38), "toward the sender");
        assert!(!changed(6, 0x50), "another PDU version");
        assert!(!changed(0, 0x18), "a secondary header (a PUS TC)");
        assert!(!changed(0, 0x00), "a TM packet");
        assert!(!changed(1, 0x64), "another APID");
        assert!(!changed(2, 0x40), "segmented");
        assert!(!changed(5, p[5] + 1), "a length that disagrees");
        assert!(!is_bypass_file_data(&p[..6]), "no PDU");
        assert!(!is_bypass_file_data(&[]));
        // A PUS TC of a robot's APID.
        assert!(!is_bypass_file_data(&[0x18, 0x64, 0xC0, 0, 0, 3, 0x2F, 17, 1, 0]));
    }

    // verifies: FILE-CFDP-01
    #[test]
    fn a_pdu_packet_fits_one_tc_frame_and_the_apid_is_no_robots() {
        const { assert!(MAX_PACKET_LEN <= crate::link::tc_frame::MAX_PACKET_LEN) };
        assert!(crate::apid::apid_robot(APID).is_none());
        assert_ne!(APID, crate::apid::IDLE_APID);
        assert_ne!(APID, crate::team::TEAM_APID);
        assert_eq!(robot_entity_id(1), 1);
        assert_ne!(robot_entity_id(crate::apid::ROBOT_MIN), GROUND_ENTITY_ID);
        const { assert!(MAX_SEGMENT_LEN > 900) };
    }
}
