//! The space link: TC/TM transfer frames, virtual channels, COP-1 and SDLS parameters
//! (CCSDS 232.0-B-4, 132.0-B-3, 232.1-B-2, 355.0-B-2). One place for every number the
//! on-board FARM, the ground's FOP and the exports share. `docs/space-link.md` explains them.

/// Spacecraft identifier (10 bits, the same in TC and TM frames).
pub const SCID: u16 = 0x0AB;

/// Transfer frame version number of TC frames (`00`, 232.0-B-4 §4.1.2.2).
pub const TC_TFVN: u8 = 0;
/// Transfer frame version number of TM frames (`00`, 132.0-B-3 §4.1.2.2).
pub const TM_TFVN: u8 = 0;

/// Uplink virtual channels.
pub mod tc_vc {
    /// The one TC virtual channel: AD frames (COP-1 sequence controlled, SDLS protected),
    /// BD frames (SDLS protected, bypass) and BC control frames (in clear, as Yamcs sends them).
    pub const COMMAND: u8 = 0;
}

/// Downlink virtual channels (3-bit VCID).
pub mod tm_vc {
    /// Realtime TM (HK, events, verification reports), SDLS protected.
    pub const REALTIME: u8 = 0;
    /// Store replay (PUS 15 dumps), SDLS protected.
    pub const REPLAY: u8 = 1;
    /// File delivery: the CFDP PDU packets (`cfdp::APID`), SDLS protected. A channel of
    /// their own because they are no PUS packets (no secondary header, no packet CRC): a
    /// ground processes each VC's packets one way (Yamcs' PUS preprocessor drops packets
    /// without a secondary header), and a file transfer never fills VC0's frames.
    pub const FILES: u8 = 2;
    /// Idle frames (only idle data, first header pointer 0x7FE), in clear; they carry the
    /// CLCW when nothing else is to send.
    pub const IDLE: u8 = 7;
}

/// TC frame sizes (232.0-B-4; Yamcs `maxFrameLength`).
pub mod tc_frame {
    /// Primary header length.
    pub const HEADER_LEN: usize = 5;
    /// Frame error control field (CRC-16/CCITT-FALSE), always present.
    pub const FECF_LEN: usize = 2;
    /// Largest TC frame (the 10-bit length field allows 1024; Yamcs' `maxFrameLength`).
    pub const MAX_LEN: usize = 1024;
    /// Shortest TC frame we accept: a header, one data byte and the FECF.
    pub const MIN_LEN: usize = HEADER_LEN + 1 + FECF_LEN;
    /// Largest TC space packet in one SDLS-protected frame (no segment header):
    /// 1024 − 5 − 14 − 16 − 2 = 987.
    pub const MAX_PACKET_LEN: usize = MAX_LEN - HEADER_LEN - super::sdls::HEADER_LEN - super::sdls::MAC_LEN - FECF_LEN;
}

/// TM frame sizes (132.0-B-3): fixed length, no secondary header, OCF (CLCW) and FECF on
/// every frame.
pub mod tm_frame {
    /// Fixed TM frame length on every virtual channel (one UDP datagram).
    pub const LEN: usize = 1024;
    /// Primary header length.
    pub const HEADER_LEN: usize = 6;
    /// Operational control field (the CLCW).
    pub const OCF_LEN: usize = 4;
    /// Frame error control field (CRC-16/CCITT-FALSE).
    pub const FECF_LEN: usize = 2;
    /// Data field of an SDLS-protected frame (VC0, VC1): 1024 − 6 − 14 − 16 − 4 − 2 = 982.
    pub const SECURE_DATA_LEN: usize =
        LEN - HEADER_LEN - super::sdls::HEADER_LEN - super::sdls::MAC_LEN - OCF_LEN - FECF_LEN;
    /// Data field of a clear frame (the idle VC; VC0/VC1 with `obsw --tm-sdls clear`): 1024 − 6 − 4 − 2 = 1012.
    pub const CLEAR_DATA_LEN: usize = LEN - HEADER_LEN - OCF_LEN - FECF_LEN;
}

/// COP-1 (232.1-B-2) parameters shared by the on-board FARM-1 and the ground's FOP-1.
pub mod cop1 {
    /// FARM-1 sliding window width W (even, 2..=254); positive and negative window are W/2.
    pub const FARM_WINDOW_WIDTH: u8 = 20;
    /// FOP-1 sliding window width K (Yamcs `slidingWindowWidth`). K ≤ W/2 so the ground can
    /// never push the FARM into lockout with frames it has not seen acknowledged.
    pub const FOP_SLIDING_WINDOW: u8 = 10;
    /// FOP-1 timer T1 initial value in milliseconds (Yamcs `cop1T1`, seconds there). The
    /// ground's own FOP-1 adapts T1 to the measured round trip (srtt + 4·rttvar, Karn's rule)
    /// and uses this as its upper bound and its value before the first sample.
    pub const FOP_T1_MS: u64 = 2_000;
    /// Longest time the robot goes without sending a CLCW (an idle frame when nothing else
    /// is to send); after an authentic TC frame the CLCW goes out at once.
    pub const CLCW_REPORT_INTERVAL_MS: u64 = 100;
    /// Lower bound of the ground's adaptive T1: three CLCW report intervals, so a frame
    /// received on board is retransmitted early only when its immediate CLCW and the next
    /// two idle-frame CLCWs are all lost.
    pub const FOP_T1_MIN_MS: u64 = 3 * CLCW_REPORT_INTERVAL_MS;
    /// FOP-1 transmission limit (Yamcs `cop1TxLimit`): first transmission included.
    pub const FOP_TX_LIMIT: u8 = 5;
    /// FOP-1 timeout type (0: alert on the last expiry, 1: suspend).
    pub const FOP_TIMEOUT_TYPE: u8 = 0;
    /// How long a ground's FOP-1 waits, from its link's start, for the first CLCW before
    /// AD service begins (Yamcs `initialClcwWait`, seconds; it takes V(S) from that CLCW's
    /// N(R)). A robot in contact sends a CLCW every [`CLCW_REPORT_INTERVAL_MS`], so the wait
    /// covers the ground's own start: a JVM starting beside five others on two cores
    /// delivered its first TM frame to the FOP more than 10 s after the link started, and
    /// Yamcs' FOP-1 then suspends for good (a CLCW does not resume it), its TCs queued and
    /// never sent until an operator resumes. TCs issued meanwhile wait in the FOP's queue.
    pub const FOP_INITIAL_CLCW_WAIT_S: u64 = 60;
}

/// SDLS (355.0-B-2) parameters: AES-256-GCM authenticated encryption in Yamcs 5.12.8's layout.
pub mod sdls {
    /// Security header: SPI (2 bytes) + IV (12 bytes, the anti-replay counter).
    pub const SPI_LEN: usize = 2;
    /// GCM IV length, which is also the anti-replay sequence number length.
    pub const IV_LEN: usize = 12;
    /// Security header length.
    pub const HEADER_LEN: usize = SPI_LEN + IV_LEN;
    /// Security trailer: the GCM tag.
    pub const MAC_LEN: usize = 16;
    /// AES-256 key length.
    pub const KEY_LEN: usize = 32;
    /// Uplink SPIs (ground → robot, TC frames on `tc_vc::COMMAND`). Two, for key change
    /// without downtime: the ground switches with a command, the robot accepts both while both
    /// are provisioned.
    pub const TC_SPIS: [u16; 2] = [1, 2];
    /// Downlink SPIs (robot → ground, TM frames on VC0 and VC1). Separate keys per direction:
    /// a key shared by both directions with both counters starting at 0 would reuse nonces.
    pub const TM_SPIS: [u16; 2] = [17, 18];
    /// Transmit counters are reserved in blocks of this many IVs: the high-water mark is
    /// persisted before the first IV of a block is used, so a restart skips at most one block
    /// and never reuses a nonce.
    pub const IV_RESERVE_BLOCK: u64 = 1024;
    /// Anti-replay window N: a frame's IV must lie in (last, last + N]. Larger than the
    /// reserve block plus lost frames, so a sender's restart (a jump of up to one block) is
    /// accepted. Replays (IV ≤ last) are refused whatever N is; Yamcs' TM link needs
    /// `seqNumWindow` of at least this too (its default, 10, would refuse TM after a robot
    /// restart).
    pub const ANTI_REPLAY_WINDOW: u64 = 4096;
}

/// What an authentic BD (bypass) TC frame may carry; the robot refuses a BD frame with any
/// other packet in it (`LINK_REJ_BD_CONTENT`), so no command travels past COP-1's order
/// but these two:
/// - class 2 CFDP file data ([`crate::cfdp::is_bypass_file_data`]): it commands nothing,
///   class 2's NAKs recover and order it; `ground file put` sends it so (docs/files.md);
/// - TC[11,4] on a robot's APID (PUS-C), a time-tagged command: Yamcs 5.12.8 can send one
///   only in a BD frame (its COP-1 sizes the AD frame without the wrapping: docs/yamcs.md,
///   "Yamcs defects with time-tagged commands"); the schedule, not the frame order, decides
///   when its command runs, at its release time.
pub fn bypass_admissible(packet: &[u8]) -> bool {
    crate::cfdp::is_bypass_file_data(packet) || is_schedule_insert(packet)
}

/// A TC[11,4] packet on a robot's APID: version 0, TC, secondary header, PUS-C, service 11
/// subtype 4, its length field the slice's.
fn is_schedule_insert(p: &[u8]) -> bool {
    let Some(([id0, id1, _, _, len0, len1, pus, service, subservice], _)) = p.split_first_chunk::<9>() else {
        return false;
    };
    let apid = u16::from_be_bytes([*id0 & 0x07, *id1]);
    id0 & 0xF8 == 0x18
        && crate::apid::apid_robot(apid).is_some()
        && usize::from(u16::from_be_bytes([*len0, *len1])) + 7 == p.len()
        && u32::from(pus >> 4) == crate::headers::PUS_C_VERSION
        && *service == crate::tc::service::SCHEDULING
        && *subservice == 4
}

// Invariants between the numbers above, checked when the MIB is compiled.
const _: () = {
    assert!(cop1::FARM_WINDOW_WIDTH.is_multiple_of(2));
    // K <= W/2: the ground can never push the FARM into lockout.
    assert!(cop1::FOP_SLIDING_WINDOW <= cop1::FARM_WINDOW_WIDTH / 2);
    // The adaptive T1 has room to adapt, above the CLCW report interval.
    assert!(cop1::CLCW_REPORT_INTERVAL_MS < cop1::FOP_T1_MIN_MS && cop1::FOP_T1_MIN_MS < cop1::FOP_T1_MS);
    assert!(SCID < 1024);
    assert!(tm_vc::IDLE < 8 && tm_vc::REPLAY < 8 && tm_vc::FILES < 8);
    assert!(tm_vc::FILES != tm_vc::REALTIME && tm_vc::FILES != tm_vc::REPLAY && tm_vc::FILES != tm_vc::IDLE);
    // A sender that restarts jumps at most one reserve block ahead.
    assert!(sdls::ANTI_REPLAY_WINDOW > 2 * sdls::IV_RESERVE_BLOCK);
};

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: FILE-BD-01
    #[test]
    fn a_bd_frame_may_carry_class_2_file_data_and_time_tagged_commands_only() {
        let robot = crate::apid::robot_apid(1).unwrap();
        let [hi, lo] = robot.to_be_bytes();
        // TC[11,4] of robot 1 (PUS-C, acks 0b1001, source 0), 4 bytes of application data.
        let mut p = vec![0x18 | hi, lo, 0xC0, 7, 0, 0, 0x29, 11, 4, 0, 0, 1, 1, 0, 0];
        let n = (p.len() - 7) as u16;
        p[4..6].copy_from_slice(&n.to_be_bytes());
        assert!(bypass_admissible(&p));
        let changed = |at: usize, v: u8| {
            let mut q = p.clone();
            q[at] = v;
            bypass_admissible(&q)
        };
        assert!(!changed(8, 1), "TC[11,1]");
        assert!(!changed(7, 17), "TC[17,4]");
        assert!(!changed(6, 0x19), "PUS-A");
        assert!(!changed(1, 0x00), "not a robot's APID");
        assert!(!changed(0, lo & 0x07), "no secondary header");
        assert!(!changed(5, p[5] + 1), "a length that disagrees");
        assert!(!bypass_admissible(&p[..8]));
        // A PING (TC[17,1]) is not.
        let ping = [0x18 | hi, lo, 0xC0, 8, 0, 5, 0x29, 17, 1, 0, 0, 0xAB, 0xCD];
        assert!(!bypass_admissible(&ping));
        // Class 2 file data is.
        let mut fd = vec![
            0x10, 0xF0, 0xC0, 0, 0, 0, 0x30, 0, 5, 0x11, 0, 0, 0, 1, 0, 1, 0, 0, 0, 0, 9,
        ];
        let n = (fd.len() - 7) as u16;
        fd[4..6].copy_from_slice(&n.to_be_bytes());
        assert!(bypass_admissible(&fd));
    }

    // verifies: LINK-MIB-01
    #[test]
    fn link_sizes_are_consistent() {
        assert_eq!(tc_frame::MAX_PACKET_LEN, 987);
        assert_eq!(tm_frame::SECURE_DATA_LEN, 982);
        assert_eq!(tm_frame::CLEAR_DATA_LEN, 1012);
        for s in sdls::TC_SPIS {
            assert!(!sdls::TM_SPIS.contains(&s));
        }
    }
}
