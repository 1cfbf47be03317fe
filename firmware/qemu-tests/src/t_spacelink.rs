//! The space link core (`mmic-link`) on the target: AES-256-GCM known answers (the GCM
//! specification's test case 16 and NASA CryptoLib v1.3.1's authenticated TC frame), the
//! TC receive pipeline (CRC → lengths → SDLS → FARM-1 → packets) with an authentic frame,
//! a flipped bit and a replay, and an idle TM frame carrying the CLCW.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use aes_gcm::aead::AeadInPlace;
use aes_gcm::{Aes256Gcm, KeyInit, Nonce, Tag};
use mmic_link::clcw::Clcw;
use mmic_link::downlink::TmFramer;
use mmic_link::farm::FarmState;
use mmic_link::rx::{RxError, RxOutcome, TcReceiver};
use mmic_link::sdls::{build_tc, MemoryIvStore, RxSa, RxSas, SdlsError, TxSa};
use mmic_link::tc::{FrameType, TcRepr};
use mmic_link::test_keys::TEST_KEY_TC_A;
use mmic_link::tm::TmFrame;

pub const TESTS: &[Test] = tests![
    link_gcm_spec_test_case_16_aes256,
    link_cryptolib_authenticated_tc_frame_mac,
    link_rx_accepts_authentic_frame_and_refuses_tampered_and_replayed,
    link_idle_tm_frame_carries_the_clcw,
];

/// Hex digits to bytes (test data only; `N` must match the string).
fn hex<const N: usize>(s: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let b = s.as_bytes();
    let nib = |c: u8| match c {
        b'0'..=b'9' => c - b'0',
        b'a'..=b'f' => c - b'a' + 10,
        b'A'..=b'F' => c - b'A' + 10,
        _ => 0,
    };
    for (i, o) in out.iter_mut().enumerate() {
        *o = (nib(b[2 * i]) << 4) | nib(b[2 * i + 1]);
    }
    out
}

fn link_gcm_spec_test_case_16_aes256() -> TestResult {
    // McGrew & Viega, "The Galois/Counter Mode of Operation", test case 16.
    let key: [u8; 32] = hex("feffe9928665731c6d6a8f9467308308feffe9928665731c6d6a8f9467308308");
    let iv: [u8; 12] = hex("cafebabefacedbaddecaf888");
    let aad: [u8; 20] = hex("feedfacedeadbeeffeedfacedeadbeefabaddad2");
    let mut buf: [u8; 60] = hex("d9313225f88406e5a55909c5aff5269a86a7a9531534f7da2e4c303d8a318a72\
         1c3c0c95956809532fcf0e2449a6b525b16aedf5aa0de657ba637b39");
    let expect_ct: [u8; 60] = hex("522dc1f099567d07f47f37a32a84427d643a8cdcbfe5c0c97598a2bd2555d1aa\
         8cb08e48590dbb3da7b08b1056828838c5f61e6393ba7a0abcc9f662");
    let expect_tag: [u8; 16] = hex("76fc6ece0f4e1768cddf8853bb2d551b");
    let c = ok!(Aes256Gcm::new_from_slice(&key).ok());
    let tag = ok!(c.encrypt_in_place_detached(Nonce::from_slice(&iv), &aad, &mut buf).ok());
    check_eq!(&buf[..], &expect_ct[..]);
    check_eq!(tag.as_slice(), &expect_tag[..]);
    // Decrypting with one tag bit flipped fails.
    let mut bad = expect_tag;
    bad[15] ^= 0x80;
    check!(c
        .decrypt_in_place_detached(Nonce::from_slice(&iv), &aad, &mut buf, Tag::from_slice(&bad))
        .is_err());
    Ok(())
}

fn link_cryptolib_authenticated_tc_frame_mac() -> TestResult {
    // NASA CryptoLib v1.3.1 test/unit/et_dt_validation.c, authentication only (GCM with an
    // empty plaintext, the frame up to the MAC as AAD). Its FECF bytes (B401) are wrong;
    // CRC-16/CCITT-FALSE of the frame is 0x78CB.
    let frame: [u8; 56] = hex(
        "2003003700FF0009D79CF22D504CC793C3FB6C8A0000722ee47da4b77424733546c2d400c4e5\
         E7BB31D506998FCBDA078E66D5680194B401",
    );
    let key: [u8; 32] = hex("78dc4e0aaf52d935c3c01eea57428f00ca1fd475f5da86a49c8dd73d68c8e223");
    let c = ok!(Aes256Gcm::new_from_slice(&key).ok());
    let tag = ok!(c
        .encrypt_in_place_detached(Nonce::from_slice(&frame[8..20]), &frame[..38], &mut [])
        .ok());
    check_eq!(tag.as_slice(), &frame[38..54]);
    check_eq!(mmic_link::fecf::crc16(&frame[..54]), 0x78CB);
    Ok(())
}

/// A PUS TC space packet (version 0, type TC, secondary header flag) of `len` data bytes.
fn packet(seq: u16, len: usize, out: &mut [u8; 64]) -> usize {
    out[..4].copy_from_slice(&[0x18, 0x64, 0xC0 | (seq >> 8) as u8, seq as u8]);
    out[4..6].copy_from_slice(&((len - 1) as u16).to_be_bytes());
    for (i, b) in out[6..6 + len].iter_mut().enumerate() {
        *b = i as u8;
    }
    6 + len
}

fn link_rx_accepts_authentic_frame_and_refuses_tampered_and_replayed() -> TestResult {
    let mut sas: RxSas<2> = RxSas::default();
    check!(sas.insert(RxSa::new(1, &TEST_KEY_TC_A, 64)).is_ok());
    let mut rx = TcReceiver::mission(sas);
    let mut tx = TxSa::resume(1, &TEST_KEY_TC_A, 0);
    let (mut ground_store, mut board_store) = (MemoryIvStore::default(), MemoryIvStore::default());
    let mut pkt = [0u8; 64];
    let n = packet(7, 12, &mut pkt);
    let header = TcRepr {
        frame_type: FrameType::Ad,
        scid: mib::link::SCID,
        vcid: mib::link::tc_vc::COMMAND,
        seq: 0,
        data_len: 0,
    };
    let mut frame = [0u8; 128];
    let len = ok!(build_tc(&mut tx, &mut ground_store, header, &pkt[..n], &mut frame).ok());
    let captured = frame;

    // One flipped bit in the ciphertext, CRC recomputed: refused by the MAC, nothing changes.
    let mut tampered = captured;
    tampered[25] ^= 0x01; // in the ciphertext (after the 5-byte header and 14-byte security header)
    mmic_link::fecf::seal(&mut tampered[..len]);
    match rx.receive(&mut board_store, &mut tampered[..len], true) {
        RxOutcome::Rejected(RxError::Sdls(SdlsError::BadMac)) => {}
        _ => check!(false, "a tampered frame was not refused for its MAC"),
    }
    check_eq!(rx.farm.vr(), 0);

    // The authentic frame: its one packet, V(R) advances.
    let mut f = captured;
    match rx.receive(&mut board_store, &mut f[..len], true) {
        RxOutcome::Accepted { mut packets, seq, .. } => {
            check_eq!(seq, 0);
            let p = ok!(packets.next());
            check_eq!(p, &pkt[..n]);
            check!(packets.next().is_none());
        }
        _ => check!(false, "the authentic frame was not accepted"),
    }
    check_eq!(rx.farm.vr(), 1);
    check_eq!(rx.farm.state(), FarmState::Open);

    // The same frame replayed: refused by the anti-replay window, counted.
    let mut again = captured;
    match rx.receive(&mut board_store, &mut again[..len], true) {
        RxOutcome::Rejected(RxError::Sdls(SdlsError::Replay)) => {}
        _ => check!(false, "a replayed frame was not refused as a replay"),
    }
    check_eq!(rx.farm.vr(), 1);
    check_eq!(rx.counters.ad_accepted, 1);
    check_eq!(rx.counters.rejected(), 2);
    Ok(())
}

fn link_idle_tm_frame_carries_the_clcw() -> TestResult {
    let mut dl = TmFramer::mission();
    let mut rx_sas: RxSas<1> = RxSas::default();
    check!(rx_sas.insert(RxSa::new(1, &TEST_KEY_TC_A, 64)).is_ok());
    let clcw: Clcw = TcReceiver::mission(rx_sas).farm.clcw();
    let mut out = [0u8; mib::link::tm_frame::LEN];
    dl.idle(clcw, &mut out);
    let f = ok!(TmFrame::new_checked(&out[..]).ok());
    check!(f.check_fecf());
    check_eq!(f.vcid(), mib::link::tm_vc::IDLE);
    check_eq!(f.scid(), mib::link::SCID);
    check_eq!(f.ocf(), clcw.emit());
    Ok(())
}
