//! Independent check of board A's frame link: the TC frame the ground sends and the TM
//! frames `fw_core::spacelink::FrameLink` puts on the serial downlink (COBS-deframed, as
//! the ground reads them) are parsed, CRC-checked and SDLS-verified/decrypted by
//! `obsw/link/tests/py/check_frames.py` — written from the CCSDS standards with Python
//! `cryptography`'s AESGCM, not from our code — under the published test keys.

use std::path::PathBuf;
use std::process::Command;

use fw_core::config;
use fw_core::files::NoFiles;
use fw_core::link::{self, ByteQueue, Counters, TcChannel};
use fw_core::spacelink::{FrameLink, Keys};
use mmic_link::downlink::TmReceiver;
use mmic_link::sdls::{build_tc, MemoryIvStore, RxSa, RxSas, TxSa};
use mmic_link::tc::{FrameType, TcRepr};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};
use mmic_stream::{encode, Deframer};
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::RingStore;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn python() -> PathBuf {
    let p = root().join(".venv/bin/python");
    assert!(
        p.exists(),
        "{} missing: run `bash scripts/python-env.sh` first (needs cryptography)",
        p.display()
    );
    p
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// PUS-C TC[17,1] (ping) for APID 0x101, hand-assembled: primary header, secondary header
/// (version 2, ack flags 0xF, service, subtype, source ID 0), CRC-16/CCITT-FALSE.
fn ping_tc(seq: u16) -> Vec<u8> {
    let mut p = vec![0x19, 0x01, 0xC0 | (seq >> 8) as u8, seq as u8, 0, 0];
    p.extend_from_slice(&[0x2F, 17, 1, 0, 0]);
    let len = (p.len() + 2 - 7) as u16;
    p[4..6].copy_from_slice(&len.to_be_bytes());
    let crc = crc16(&p);
    p.extend_from_slice(&crc.to_be_bytes());
    p
}

fn crc16(data: &[u8]) -> u16 {
    let mut crc = 0xFFFFu16;
    for &b in data {
        crc ^= u16::from(b) << 8;
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

// verifies: FW-LINK-01, FW-LINK-05
#[test]
fn board_frames_verify_with_the_independent_python_decoder() {
    static TCS: TcChannel = TcChannel::new();
    static UP: Counters = Counters::new();
    static TM: ByteQueue<{ 4 * config::GROUND_FRAME_MAX }> = ByteQueue::new();
    static DOWN: Counters = Counters::new();
    let keys = Keys {
        tc_spi: 1,
        tc_key: TEST_KEY_TC_A,
        tm_spi: 17,
        tm_key: TEST_KEY_TM_A,
    };
    let mut fl = FrameLink::new(Some(&keys), Default::default(), MemoryIvStore::default());
    let mut obsw = Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 0,
        },
        RingStore::<8192>::default(),
    );

    // The ground's TC frame: AD, N(S) 0, a ping.
    let mut sa = TxSa::resume(1, &TEST_KEY_TC_A, 0);
    let mut gs = MemoryIvStore::default();
    let header = TcRepr {
        frame_type: FrameType::Ad,
        scid: mib::link::SCID,
        vcid: 0,
        seq: 0,
        data_len: 0,
    };
    let mut buf = [0u8; 1024];
    let n = build_tc(&mut sa, &mut gs, header, &ping_tc(3), &mut buf).unwrap();
    let tc_frame = buf[..n].to_vec();
    let mut cobs = [0u8; config::GROUND_FRAME_MAX];
    let m = encode(&tc_frame, &mut cobs).unwrap();
    let mut deframer: Deframer<{ config::GROUND_RX_BUF }> = Deframer::new();
    link::uplink_bytes(&mut deframer, &cobs[..m], &TCS, &UP);

    // The frame and its replies (their encryption spread over periods 1 ms apart), then
    // (150 ms later) an idle frame.
    for t in 10..26 {
        fl.receive(t, &mut obsw, &mut NoFiles, &TCS, &TM, &DOWN);
        fl.end_period(t, &mut obsw, &TM, &DOWN);
        if !fl.ep.busy() {
            break;
        }
    }
    fl.end_period(160, &mut obsw, &TM, &DOWN);

    // The serial downlink, COBS-deframed: TM frames.
    let mut bytes = vec![0u8; 4 * config::GROUND_FRAME_MAX];
    let k = link::drain(&TM, &mut bytes);
    let mut d: Deframer<{ mib::link::tm_frame::LEN }> = Deframer::new();
    let mut frames: Vec<Vec<u8>> = Vec::new();
    for &b in &bytes[..k] {
        if let Some(r) = d.push(b) {
            frames.push(r.unwrap().to_vec());
        }
    }
    assert_eq!(frames.len(), 2, "one VC0 frame with the replies, one idle frame");

    // Our own ground receiver finds the ping's TM[17,2].
    let mut sas: RxSas<1> = RxSas::default();
    sas.insert(RxSa::new(17, &TEST_KEY_TM_A, 4096)).unwrap();
    let mut rx = TmReceiver::new(mib::link::SCID, sas);
    let mut pong = Vec::new();
    let mut f0 = frames[0].clone();
    rx.receive(&mut MemoryIvStore::default(), &mut f0, |_, p| {
        if p.len() > 8 && p[7] == 17 && p[8] == 2 {
            pong = p.to_vec();
        }
    })
    .unwrap();
    assert!(!pong.is_empty(), "no TM[17,2] in the board's frame");

    // The independent decoder.
    let dir = std::env::temp_dir().join(format!("fw-frames-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("a.tc"), &tc_frame).unwrap();
    for (i, f) in frames.iter().enumerate() {
        std::fs::write(dir.join(format!("b{i}.tm")), f).unwrap();
    }
    let out = Command::new(python())
        .arg(root().join("obsw/link/tests/py/check_frames.py"))
        .arg(&dir)
        .args(["--key", &format!("1={}", hex(&TEST_KEY_TC_A))])
        .args(["--key", &format!("17={}", hex(&TEST_KEY_TM_A))])
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let line = |name: &str| {
        text.lines()
            .find(|l| l.starts_with(name))
            .unwrap_or_else(|| panic!("no line for {name}: {text}"))
            .to_string()
    };
    let tc = line("a.tc");
    assert!(tc.contains(" OK type=AD scid=0x0ab vc=0 seq=0 spi=1 iv=0"), "{tc}");
    assert!(tc.contains(&format!("data={}", hex(&ping_tc(3)))), "{tc}");
    let tm = line("b0.tm");
    assert!(tm.contains(" OK scid=0x0ab vc=0 mc=0 vcc=0"), "{tm}");
    assert!(tm.contains("spi=17 iv=0"), "{tm}");
    assert!(
        tm.contains("cop=1") && tm.contains("nr=1") && tm.contains("lockout=0"),
        "{tm}"
    );
    assert!(
        tm.contains(&hex(&pong)),
        "Python's plaintext lacks the TM[17,2] packet: {tm}"
    );
    let idle = line("b1.tm");
    assert!(
        idle.contains(" OK scid=0x0ab vc=7 mc=1") && idle.contains("idle=1"),
        "{idle}"
    );
    assert!(idle.contains("nr=1"), "{idle}");
}
