//! CFDP PDUs in space packets (133.0-B-2): version 0, no secondary header, APID
//! `mib::cfdp::APID`, one PDU per packet (sequence flags "unsegmented"). Uplink packets are
//! TC packets, downlink ones TM packets; the sequence count is the sender's, per direction.

use mib::cfdp::{APID, MAX_PACKET_LEN};

const HEADER_LEN: usize = 6;

/// Which way a packet goes (the packet type bit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Ground to robot (TC).
    Up,
    /// Robot to ground (TM).
    Down,
}

/// Wraps `pdu` into `out`; the packet's length, or `None` when it does not fit.
pub fn wrap(dir: Direction, seq: u16, pdu: &[u8], out: &mut [u8]) -> Option<usize> {
    let n = HEADER_LEN + pdu.len();
    if pdu.is_empty() || n > MAX_PACKET_LEN || n > out.len() {
        return None;
    }
    let kind: u16 = match dir {
        Direction::Up => 1 << 12,
        Direction::Down => 0,
    };
    out[..2].copy_from_slice(&(kind | APID).to_be_bytes());
    out[2..4].copy_from_slice(&(0xC000 | mib::headers::SeqCount::new(seq).get()).to_be_bytes());
    out[4..6].copy_from_slice(&((pdu.len() - 1) as u16).to_be_bytes());
    out[HEADER_LEN..n].copy_from_slice(pdu);
    Some(n)
}

/// The PDU of a packet of direction `dir` on the CFDP APID; `None` for anything else (other
/// APID, a secondary header, segmented, lengths that disagree).
pub fn unwrap(dir: Direction, packet: &[u8]) -> Option<&[u8]> {
    if packet.len() <= HEADER_LEN || packet.len() > MAX_PACKET_LEN {
        return None;
    }
    let id = u16::from_be_bytes([packet[0], packet[1]]);
    let kind = match dir {
        Direction::Up => 1 << 12,
        Direction::Down => 0,
    };
    // Version 0, the type, no secondary header, our APID.
    if id != kind | APID {
        return None;
    }
    if packet[2] & 0xC0 != 0xC0 {
        return None;
    }
    let len = u16::from_be_bytes([packet[4], packet[5]]) as usize + 1;
    (packet.len() == HEADER_LEN + len).then(|| &packet[HEADER_LEN..])
}

/// The APID of a space packet (to route it), if it has a header.
pub fn apid(packet: &[u8]) -> Option<u16> {
    (packet.len() >= HEADER_LEN).then(|| u16::from_be_bytes([packet[0], packet[1]]) & 0x7FF)
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: FILE-CFDP-01
    #[test]
    fn a_pdu_round_trips_through_its_packet_and_other_packets_are_refused() {
        let mut out = [0u8; MAX_PACKET_LEN];
        let n = wrap(Direction::Up, 5, b"abc", &mut out).unwrap();
        assert_eq!(
            &out[..n],
            &[0x10 | (APID >> 8) as u8, APID as u8, 0xC0, 5, 0, 2, b'a', b'b', b'c']
        );
        assert_eq!(unwrap(Direction::Up, &out[..n]), Some(&b"abc"[..]));
        assert_eq!(unwrap(Direction::Down, &out[..n]), None, "wrong type");
        assert_eq!(unwrap(Direction::Up, &out[..n - 1]), None, "short");
        assert_eq!(apid(&out[..n]), Some(APID));
        out[1] ^= 1;
        assert_eq!(unwrap(Direction::Up, &out[..n]), None, "other APID");
        assert!(wrap(Direction::Down, 0, &[0; MAX_PACKET_LEN], &mut [0; 2 * MAX_PACKET_LEN]).is_none());
    }
}
