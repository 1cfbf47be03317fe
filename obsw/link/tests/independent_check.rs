//! Independent check: TC and TM frames made by mmic-link are parsed, CRC-checked and
//! SDLS-verified/decrypted by `tests/py/check_frames.py`, written from the CCSDS standards
//! with Python `cryptography`'s AESGCM, under the repository's test keys. Altered frames must
//! be reported bad by Python too.

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::Command;

use mmic_link::downlink::{TmFramer, TmVc};
use mmic_link::farm::{Farm, FarmInput};
use mmic_link::fecf;
use mmic_link::sdls::{build_tc, MemoryIvStore, TxSa};
use mmic_link::tc::{ControlCommand, FrameType, TcRepr};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B, TEST_KEY_TM_A};

const SCID: u16 = mib::link::SCID;

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

fn space_packet(apid: u16, seq: u16, len: usize) -> Vec<u8> {
    let mut p = vec![0u8; len];
    p[0..2].copy_from_slice(&(0x1800 | apid).to_be_bytes());
    p[2..4].copy_from_slice(&(0xC000 | seq).to_be_bytes());
    let n = (len - 7) as u16;
    p[4..6].copy_from_slice(&n.to_be_bytes());
    for (i, b) in p[6..].iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(31).wrapping_add(seq as u8);
    }
    p
}

fn tc(sa: &mut TxSa, st: &mut MemoryIvStore, ft: FrameType, seq: u8, payload: &[u8]) -> Vec<u8> {
    let mut buf = [0u8; 1024];
    let h = TcRepr {
        frame_type: ft,
        scid: SCID,
        vcid: 0,
        seq,
        data_len: 0,
    };
    let n = build_tc(sa, st, h, payload, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// Runs the Python checker over `frames`; returns name -> output line (after the name).
fn run_python(frames: &[(String, Vec<u8>)]) -> HashMap<String, String> {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos();
    let dir = std::env::temp_dir().join(format!("mmic-link-check-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, bytes) in frames {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    let script = root().join("obsw/link/tests/py/check_frames.py");
    let out = Command::new(python())
        .arg(&script)
        .arg(&dir)
        .args(["--key", &format!("1={}", hex::encode(TEST_KEY_TC_A))])
        .args(["--key", &format!("2={}", hex::encode(TEST_KEY_TC_B))])
        .args(["--key", &format!("17={}", hex::encode(TEST_KEY_TM_A))])
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert!(
        out.status.success(),
        "checker failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: HashMap<String, String> = text
        .lines()
        .filter_map(|l| l.split_once(' ').map(|(n, r)| (n.to_string(), r.to_string())))
        .collect();
    assert_eq!(lines.len(), frames.len(), "one line per frame:\n{text}");
    lines
}

fn field<'a>(line: &'a str, key: &str) -> &'a str {
    line.split(' ')
        .find_map(|kv| kv.strip_prefix(key).and_then(|r| r.strip_prefix('=')))
        .unwrap_or_else(|| panic!("no {key} in {line}"))
}

// verifies: LINK-IND-01, LINK-SDLS-03, LINK-FRAME-01, LINK-FRAME-03
#[test]
fn python_verifies_tc_frames_and_rejects_altered_ones() {
    let mut st = MemoryIvStore::default();
    let mut sa1 = TxSa::resume(1, &TEST_KEY_TC_A, 0);
    let mut sa2 = TxSa::resume(2, &TEST_KEY_TC_B, 1000);
    let p1 = space_packet(0x64, 1, 40);
    let p2 = space_packet(0x65, 2, 987);
    let ad = tc(&mut sa1, &mut st, FrameType::Ad, 5, &p1);
    let bd = tc(&mut sa2, &mut st, FrameType::Bd, 0, &p2);
    let mut b = [0u8; 16];
    let n = ControlCommand::Unlock.build_frame(SCID, 0, &mut b).unwrap();
    let unlock = b[..n].to_vec();
    let n = ControlCommand::SetVr(42).build_frame(SCID, 0, &mut b).unwrap();
    let setvr = b[..n].to_vec();
    let mut flipped = ad.clone();
    flipped[30] ^= 0x10;
    let flipped_nocrc = flipped.clone();
    fecf::seal(&mut flipped);
    let mut vc_flip = ad.clone();
    vc_flip[2] ^= 0x04;
    fecf::seal(&mut vc_flip);
    let mut wrong = TxSa::resume(1, &TEST_KEY_TC_B, 7);
    let wrong_key = tc(&mut wrong, &mut st, FrameType::Ad, 6, &p1);
    let frames = vec![
        ("a_ad.tc".to_string(), ad.clone()),
        ("b_bd.tc".to_string(), bd.clone()),
        ("c_unlock.tc".to_string(), unlock),
        ("d_setvr.tc".to_string(), setvr),
        ("e_flipped.tc".to_string(), flipped),
        ("f_flipped_nocrc.tc".to_string(), flipped_nocrc),
        ("g_vcid_flip.tc".to_string(), vc_flip),
        ("h_wrong_key.tc".to_string(), wrong_key),
    ];
    let r = run_python(&frames);
    let a = &r["a_ad.tc"];
    assert!(a.starts_with("OK type=AD"), "{a}");
    assert_eq!(field(a, "scid"), "0x0ab");
    assert_eq!(field(a, "vc"), "0");
    assert_eq!(field(a, "seq"), "5");
    assert_eq!(field(a, "spi"), "1");
    assert_eq!(field(a, "iv"), "0");
    assert_eq!(field(a, "data"), hex::encode(&p1));
    let b = &r["b_bd.tc"];
    assert!(b.starts_with("OK type=BD"), "{b}");
    assert_eq!(field(b, "spi"), "2");
    assert_eq!(field(b, "iv"), "1000");
    assert_eq!(field(b, "data"), hex::encode(&p2));
    assert_eq!(bd.len(), 1024, "largest TC packet fills the largest frame");
    assert!(r["c_unlock.tc"].starts_with("OK type=BC"));
    assert_eq!(field(&r["c_unlock.tc"], "cmd"), "unlock");
    assert_eq!(field(&r["d_setvr.tc"], "cmd"), "setvr-42");
    assert_eq!(r["e_flipped.tc"], "BAD mac");
    assert_eq!(r["f_flipped_nocrc.tc"], "BAD crc");
    assert_eq!(r["g_vcid_flip.tc"], "BAD mac", "the VCID is in the authentication mask");
    assert_eq!(r["h_wrong_key.tc"], "BAD mac");
}

// verifies: LINK-IND-01, LINK-TM-01, LINK-CLCW-01, LINK-SDLS-03
#[test]
fn python_verifies_tm_frames_clcw_and_rejects_altered_ones() {
    let mut st = MemoryIvStore::default();
    let mut sa = TxSa::resume(17, &TEST_KEY_TM_A, 5);
    let mut farm = Farm::mission();
    farm.on_event(FarmInput::Bc(ControlCommand::SetVr(42)));
    farm.on_event(FarmInput::Ad {
        ns: 44,
        buffer_available: true,
    }); // a gap: retransmit
    let clcw = farm.clcw();
    let mut dl = TmFramer::mission();
    let mut frames: Vec<Vec<u8>> = vec![];
    let packets: Vec<_> = (0..5).map(|i| space_packet(0x30, i, 500)).collect();
    for p in &packets {
        let mut p = p.clone();
        p[0] &= 0xEF; // TM packets: type bit 0
        dl.send(TmVc::Realtime, &p, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
            .unwrap();
    }
    dl.flush(TmVc::Realtime, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
        .unwrap();
    let mut idle = [0u8; mib::link::tm_frame::LEN];
    dl.idle(clcw, &mut idle);
    assert_eq!(frames.len(), 3);
    let mut named: Vec<(String, Vec<u8>)> = frames
        .iter()
        .enumerate()
        .map(|(i, f)| (format!("rt{i}.tm"), f.clone()))
        .collect();
    named.push(("x_idle.tm".to_string(), idle.to_vec()));
    let mut flipped = frames[1].clone();
    flipped[300] ^= 0x01;
    fecf::seal(&mut flipped);
    named.push(("y_flipped.tm".to_string(), flipped));
    let mut nocrc = frames[1].clone();
    nocrc[300] ^= 0x01;
    named.push(("z_nocrc.tm".to_string(), nocrc));
    let r = run_python(&named);
    let mut stream = String::new();
    for i in 0..3 {
        let l = &r[&format!("rt{i}.tm")];
        assert!(l.starts_with("OK "), "{l}");
        assert_eq!(field(l, "scid"), "0x0ab");
        assert_eq!(field(l, "vc"), "0");
        assert_eq!(field(l, "mc"), i.to_string());
        assert_eq!(field(l, "vcc"), i.to_string());
        assert_eq!(field(l, "len"), "1024");
        assert_eq!(field(l, "spi"), "17");
        assert_eq!(field(l, "iv"), (5 + i).to_string());
        assert_eq!(field(l, "cop"), "1");
        assert_eq!(field(l, "nr"), "42");
        assert_eq!(field(l, "retransmit"), "1");
        assert_eq!(field(l, "lockout"), "0");
        assert_eq!(field(l, "data").len(), 2 * mib::link::tm_frame::SECURE_DATA_LEN);
        stream.push_str(field(l, "data"));
    }
    assert_eq!(field(&r["rt0.tm"], "fhp"), "0x000");
    // 2 × 500 = 1000 bytes: the third packet starts 18 bytes into the second frame.
    assert_eq!(field(&r["rt1.tm"], "fhp"), "0x012");
    assert_eq!(field(&r["rt1.tm"], "first_len"), "500");
    let want: String = packets
        .iter()
        .map(|p| {
            let mut p = p.clone();
            p[0] &= 0xEF;
            hex::encode(p)
        })
        .collect();
    assert!(stream.starts_with(&want), "Python's decrypted packet stream differs");
    let idle = &r["x_idle.tm"];
    assert!(idle.starts_with("OK "), "{idle}");
    assert_eq!(field(idle, "vc"), "7");
    assert_eq!(field(idle, "fhp"), "0x7fe");
    assert_eq!(field(idle, "mc"), "3");
    assert_eq!(field(idle, "nr"), "42");
    assert_eq!(r["y_flipped.tm"], "BAD mac");
    assert_eq!(r["z_nocrc.tm"], "BAD crc");
}

// verifies: LINK-IND-01, LINK-TM-04
#[test]
fn python_reads_clear_tm_frames_packets_in_a_1012_byte_zone() {
    use mmic_link::downlink::TmSecurity;
    let mut st = MemoryIvStore::default();
    let mut sa = TxSa::resume(17, &TEST_KEY_TM_A, 0);
    let clcw = Farm::mission().clcw();
    let mut dl = TmFramer::with_security(mib::link::SCID, TmSecurity::Clear);
    let mut frames: Vec<Vec<u8>> = vec![];
    let packets: Vec<_> = (0..3)
        .map(|i| {
            let mut p = space_packet(0x30, i, 500);
            p[0] &= 0xEF;
            p
        })
        .collect();
    for p in &packets {
        dl.send(TmVc::Realtime, p, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
            .unwrap();
    }
    dl.flush(TmVc::Realtime, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
        .unwrap();
    assert_eq!(frames.len(), 2);
    let mut named: Vec<(String, Vec<u8>)> = frames
        .iter()
        .enumerate()
        .map(|(i, f)| (format!("c{i}.tmclear"), f.clone()))
        .collect();
    // The same bytes read as SDLS frames: refused (no SPI 17 there).
    named.push(("s0.tm".to_string(), frames[0].clone()));
    let r = run_python(&named);
    let mut stream = String::new();
    for i in 0..2 {
        let l = &r[&format!("c{i}.tmclear")];
        assert!(l.starts_with("OK "), "{l}");
        assert_eq!(field(l, "sdls"), "none");
        assert_eq!(field(l, "vc"), "0");
        assert_eq!(field(l, "data").len(), 2 * mib::link::tm_frame::CLEAR_DATA_LEN);
        stream.push_str(field(l, "data"));
    }
    assert_eq!(field(&r["c0.tmclear"], "fhp"), "0x000");
    // The third packet starts at 1000 in the first zone and ends 488 bytes into the second;
    // the idle packet of the flush starts there, and the first header pointer says so.
    assert_eq!(field(&r["c1.tmclear"], "fhp"), format!("{:#05x}", 1500 - 1012));
    let want: String = packets.iter().map(hex::encode).collect();
    assert!(stream.starts_with(&want), "Python's packet stream differs");
    assert!(r["s0.tm"].starts_with("BAD "), "{}", r["s0.tm"]);
}
