//! CCSDS space packets with PUS-C headers through `satrs::spacepackets`, checked against
//! bytes written out by hand and a CRC computed by a reference bit-by-bit routine.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use arbitrary_int::{u11, u14};
use satrs::spacepackets::ecss::tc::{
    AckFlags, GenericPusTcSecondaryHeader, PusTcCreator, PusTcReader, PusTcSecondaryHeader,
};
use satrs::spacepackets::ecss::tm::{GenericPusTmSecondaryHeader, PusTmCreator, PusTmReader, PusTmSecondaryHeader};
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId, PusPacket};
use satrs::spacepackets::{CcsdsPacket, SpHeader};

pub const TESTS: &[Test] = tests![
    crc16_ccitt_false_reference_check_value,
    pus_tc_ping_bytes_match_hand_layout,
    pus_tc_reconfigure_round_trip_and_crc_error,
    pus_tm_pong_bytes_match_hand_layout,
    pus_reader_rejects_truncated_packets,
];

/// CRC-16/CCITT-FALSE, one bit at a time (poly 0x1021, init 0xFFFF, no reflection).
pub(crate) fn crc16_reference(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in data {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

fn crc16_ccitt_false_reference_check_value() -> TestResult {
    // The catalogued check value of CRC-16/CCITT-FALSE.
    check_eq!(crc16_reference(b"123456789"), 0x29B1);
    check_eq!(satrs::spacepackets::crc::CRC_CCITT_FALSE.checksum(b"123456789"), 0x29B1);
    Ok(())
}

const APID: u16 = 0x101;

/// A TC for robot 1 built with the sat-rs encoder, as the ground tool builds it.
pub fn build(seq: u16, svc: u8, sub: u8, app: &[u8], buf: &mut [u8]) -> Option<usize> {
    tc(buf, seq, svc, sub, app)
}

fn tc(buf: &mut [u8], seq: u16, svc: u8, sub: u8, app: &[u8]) -> Option<usize> {
    let sp = SpHeader::new_for_unseg_tc(u11::new(APID), u14::new(seq), 0);
    let sec = PusTcSecondaryHeader::new(MessageTypeId::new(svc, sub), AckFlags::ALL, 0);
    PusTcCreator::new(sp, sec, app, CreatorConfig::default())
        .write_to_bytes(buf)
        .ok()
}

fn pus_tc_ping_bytes_match_hand_layout() -> TestResult {
    check_eq!(mib::apid::robot_apid(1), Some(APID));
    let mut buf = [0u8; 32];
    let n = ok!(tc(&mut buf, 5, 17, 1, &[]));
    let mut expect = [
        0x19, 0x01, // version 0, TC, secondary header, APID 0x101
        0xC0, 0x05, // unsegmented, sequence count 5
        0x00, 0x06, // data length = 13 - 7
        0x2F, // PUS-C, all acknowledgements requested
        17, 1, // PUS 17,1
        0x00, 0x00, // source ID (ground)
        0x00, 0x00, // CRC, filled below
    ];
    let crc = crc16_reference(&expect[..11]);
    expect[11..].copy_from_slice(&crc.to_be_bytes());
    check_eq!(&buf[..n], &expect[..]);
    // The CRC over the whole packet, CRC included, is zero.
    check_eq!(crc16_reference(&buf[..n]), 0);
    Ok(())
}

fn pus_tc_reconfigure_round_trip_and_crc_error() -> TestResult {
    let def = ok!(mib::tc::lookup(8, 1, Some(mib::tc::function::RECONFIGURE)));
    let mut app = [0u8; 8];
    let na = ok!(mib_wire::codec::encode_args(def, &[0, 1], &mut app));
    let mut buf = [0u8; 64];
    let n = ok!(tc(&mut buf, 0x3FFF, 8, 1, &app[..na]));
    check_eq!(n, 6 + 5 + 4 + 2);
    let r = ok!(PusTcReader::new(&buf[..n]));
    check_eq!(r.apid().value(), APID);
    check_eq!(r.seq_count().value(), 0x3FFF);
    check_eq!(PusPacket::message_type_id(&r), MessageTypeId::new(8, 1));
    check_eq!(r.source_id(), 0);
    check_eq!(r.app_data(), &[0x00, 0x01, 0x00, 0x01][..]);
    // One flipped bit anywhere is caught by the CRC.
    for i in 0..n {
        let mut bad = [0u8; 64];
        bad[..n].copy_from_slice(&buf[..n]);
        bad[i] ^= 0x10;
        if let Ok(r) = PusTcReader::new(&bad[..n]) {
            // Only a corrupted length field may still parse (as a shorter packet); then
            // it must not be the same packet.
            check!(r.packet_len() != n, "corruption at byte {} undetected", i);
        }
    }
    Ok(())
}

fn pus_tm_pong_bytes_match_hand_layout() -> TestResult {
    let stamp = [0x00, 0x02, 0x00, 0x00, 0x01, 0x2C, 0x00]; // CDS short: day 2, 76 800 ms
    check_eq!(stamp.len(), mib::config::TIMESTAMP_LEN);
    let sp = SpHeader::new_for_unseg_tm(u11::new(APID), u14::new(7), 0);
    let sec = PusTmSecondaryHeader::new(MessageTypeId::new(17, 2), 3, 0, &stamp);
    let tm = PusTmCreator::new(sp, sec, &[], CreatorConfig::default());
    let mut buf = [0u8; 64];
    let n = ok!(tm.write_to_bytes(&mut buf));
    let mut expect = [0u8; 22];
    expect[..6].copy_from_slice(&[0x09, 0x01, 0xC0, 0x07, 0x00, 0x0F]);
    expect[6..13].copy_from_slice(&[0x20, 17, 2, 0x00, 0x03, 0x00, 0x00]);
    expect[13..20].copy_from_slice(&stamp);
    let crc = crc16_reference(&expect[..20]);
    expect[20..].copy_from_slice(&crc.to_be_bytes());
    check_eq!(&buf[..n], &expect[..]);
    let r = ok!(PusTmReader::new(&buf[..n], mib::config::TIMESTAMP_LEN));
    check_eq!(r.timestamp(), &stamp[..]);
    check_eq!(r.msg_type_counter(), 3);
    check_eq!(r.dest_id(), 0);
    check_eq!(PusPacket::message_type_id(&r), MessageTypeId::new(17, 2));
    Ok(())
}

fn pus_reader_rejects_truncated_packets() -> TestResult {
    let mut buf = [0u8; 32];
    let n = ok!(tc(&mut buf, 1, 17, 1, &[]));
    for len in 0..n {
        check!(PusTcReader::new(&buf[..len]).is_err(), "accepted {} bytes", len);
    }
    Ok(())
}
