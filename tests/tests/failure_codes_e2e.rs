//! The start and completion failure codes not covered elsewhere, each provoked by a
//! real packet (plus a simulator fault where the hardware must misbehave), and a check
//! that every failure code of the MIB is exercised by some end-to-end test.

use std::time::Duration;

use e2e_tests::{tc, Client, Obsw};
use mib::modes::{node, robot_mode};
use mib::FailureCode as F;

const T: Duration = Duration::from_secs(10);

fn operational(c: &mut Client) {
    let raw = c.send("MODE_SET", &[node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0]);
    assert_eq!(c.wait_done(&raw, Duration::from_secs(60)).unwrap().subservice, 7);
}

// verifies: PUS-15-02
#[test]
fn store_disabled_and_schedule_full_are_reported() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let raw = c.send("STORE_DISABLE", &[]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    let raw = c.send("STORE_DOWNLINK_TIME", &[0, 0, 65535, 4_294_967_295]);
    assert_eq!(
        c.wait_done(&raw, T).unwrap().failure_code(),
        Some(F::STORE_DISABLED.code())
    );
    // Fill the schedule one activity at a time, far in the future.
    let far = {
        let unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_millis() as u64
            + 3_600_000;
        let mut s = [0x40u8, 0, 0, 0, 0, 0, 0];
        s[1..3].copy_from_slice(&((unix / 86_400_000 + 4383) as u16).to_be_bytes());
        s[3..].copy_from_slice(&((unix % 86_400_000) as u32).to_be_bytes());
        s
    };
    let mut last = None;
    for i in 0..=mib::config::SCHEDULE_CAPACITY {
        let mut app = vec![1u8];
        app.extend_from_slice(&far);
        app.extend_from_slice(&tc(o.apid, 1000 + i as u16, 17, 1, &[]));
        let seq = c.next_seq();
        let raw = tc(o.apid, seq, 11, 4, &app);
        c.send_raw(&raw);
        last = c.wait_done(&raw, T);
    }
    assert_eq!(last.unwrap().failure_code(), Some(F::SCHEDULE_FULL.code()));
}

// verifies: MMIC-CTL-03
#[test]
fn a_hip_rotation_with_both_grippers_holding_is_refused_at_start() {
    let o = Obsw::start(&["--speed", "20"]);
    let mut c = Client::udp(&o);
    operational(&mut c);
    // Both grippers hold one face: the hip cannot turn, refused before it stalls.
    let raw = c.send("ROTATE_HIP", &[4500]);
    let t = c.wait_done(&raw, Duration::from_secs(60)).unwrap();
    assert_eq!(
        (t.subservice, t.failure_code()),
        (4, Some(F::BOTH_SIDES_GRIPPED.code()))
    );
}

// verifies: MMIC-FLT-02
#[test]
fn an_unbolting_failure_is_reported() {
    let o = Obsw::start(&["--speed", "50"]);
    let mut c = Client::udp(&o);
    operational(&mut c);
    let raw = c.send("BOLT_PAIR", &[1, 3]);
    assert_eq!(
        c.wait_done(&raw, Duration::from_secs(60)).unwrap().subservice,
        7,
        "bolted first"
    );
    assert!(o.sim("fastener-jam").starts_with("ok"));
    let raw = c.send("UNBOLT_PAIR", &[1, 3]);
    assert_eq!(
        c.wait_done(&raw, Duration::from_secs(60)).unwrap().failure_code(),
        Some(F::UNBOLT_FAILED.code())
    );
}

// verifies: MMIC-FLT-11
#[test]
fn a_command_board_b_never_acknowledges_fails() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    operational(&mut c);
    assert!(o.sim("cut-cable").starts_with("ok"));
    // Board B gives up after B_MAX_RETRIES resends (~4 x 60 ms), well before the
    // heartbeat monitor (500 ms) would notice the cut.
    let raw = c.send("MOVE_ARM", &[1, 1500]);
    let t = c.wait_done(&raw, T).unwrap();
    assert_eq!(t.failure_code(), Some(F::BOARD_B_NO_ACK.code()), "{}", c.summary());
}

// verifies: LINK-KEYCHG-02
#[test]
fn a_key_change_to_an_spi_the_robot_has_no_key_for_is_refused() {
    // The lab link: the robot holds no space-link key at all, so no SPI can be selected.
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let raw = c.send("LINK_SPI_SELECT", &[18, 2]);
    let t = c.wait_done(&raw, T).unwrap();
    assert_eq!(t.failure_code(), Some(F::NO_KEY_FOR_SPI.code()), "{}", c.summary());
}

/// Codes that a packet cannot provoke with this MIB, and why.
const UNREACHABLE: &[(F, &str)] = &[(F::UNREACHABLE_STATE, "every state pair is within 3 primitives")];

// verifies: PUS-1-02
#[test]
fn every_failure_code_is_exercised_by_an_end_to_end_test() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let mut text = String::new();
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "rs") && !p.ends_with("failure_codes_e2e.rs") {
            text.push_str(&std::fs::read_to_string(&p).unwrap());
        }
    }
    // The FDIR faults run in process against the core and the simulator (mock clock).
    text.push_str(include_str!("../../obsw/core/tests/fdir.rs"));
    text.push_str(
        include_str!("failure_codes_e2e.rs")
            .split("/// Codes that a packet cannot")
            .next()
            .unwrap(),
    );
    for code in F::ALL {
        if UNREACHABLE.iter().any(|(c, _)| c == code) {
            continue;
        }
        assert!(
            text.contains(&format!("F::{}", code.name())),
            "no end-to-end test provokes {}",
            code.name()
        );
    }
}

// (After the list above: the codes named here are made by hand, not provoked.)
// verifies: PUS-1-05
#[test]
fn a_failure_code_outside_the_tcs_mib_list_is_caught_by_the_harness() {
    // Every Client checks each failure report it receives for a TC it sent
    // (e2e_tests::unlisted_failure); here the check itself, on reports built by hand.
    let raw = e2e_tests::tc_named(0x101, 7, "BOLT_FACE", &[0, 15]);
    let def = e2e_tests::tc_def(&raw).expect("BOLT_FACE is a MIB TC");
    assert_eq!(def.name, "BOLT_FACE");
    let report = |sub: u8, code: F| {
        let mut data = raw[..4].to_vec();
        data.extend_from_slice(&code.code().to_be_bytes());
        e2e_tests::Tm {
            service: 1,
            subservice: sub,
            seq: 0,
            apid: 0x101,
            data,
            raw: Vec::new(),
            at: std::time::Instant::now(),
        }
    };
    assert_eq!(e2e_tests::unlisted_failure(def, &report(4, F::MODULE_ABSENT)), None);
    assert_eq!(e2e_tests::unlisted_failure(def, &report(2, F::CRC_MISMATCH)), None);
    let why = e2e_tests::unlisted_failure(def, &report(4, F::CONFIG_HASH_STALE)).expect("not listed");
    assert!(why.contains("BOLT_FACE") && why.contains("CONFIG_HASH_STALE"), "{why}");
    // Damaged bytes name no TC: nothing to check them against.
    let mut bad = raw.clone();
    bad[8] ^= 0x40;
    assert!(e2e_tests::tc_def(&bad).is_none());
}
