//! The start and completion failure codes not covered elsewhere, each provoked by a
//! real packet (plus a simulator fault where the hardware must misbehave), and a check
//! that every failure code of the MIB is exercised by some end-to-end test.

use std::time::Duration;

use e2e_tests::{tc, tc_named, Client, Obsw, Tm};
use mib::modes::{node, robot_mode};
use mib::plan::{invalid, state, sub, MAX_CHUNK, MAX_IMAGE_LEN};
use mib::FailureCode as F;
use mmic_plan::image::{crc32, emit};
use mmic_plan::{StepKind, StepRepr};

const T: Duration = Duration::from_secs(10);
/// `Obsw::start` runs robot 1.
const ROBOT: u8 = 1;

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

// verifies: UPD-SVC-02
#[test]
fn an_update_tc_to_an_obsw_without_slots_is_refused_unavailable() {
    // The lab's bare-packet obsw has no boot launcher, hence no application slots.
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let raw = c.send("UPDATE_CONFIRM", &[]);
    assert_eq!(
        c.wait_done(&raw, T).unwrap().failure_code(),
        Some(F::UPDATE_UNAVAILABLE.code())
    );
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

/// The failure code of a refusal report and its data after the code.
fn refusal(t: &Tm) -> (u16, Vec<u8>) {
    let off = if t.subservice == 6 { 7 } else { 6 };
    (t.failure_code().expect("a failure report"), t.data[off..].to_vec())
}

/// A plan image for robot `robot`, emitted as the ground's compiler does.
fn image(robot: u8, plan_id: u32, steps: &[StepKind<'_>], confirmed: bool) -> Vec<u8> {
    let steps: Vec<StepRepr> = steps
        .iter()
        .enumerate()
        .map(|(i, &kind)| StepRepr {
            index: i as u8,
            confirmed,
            timeout_s: 0,
            deps: Default::default(),
            kind,
        })
        .collect();
    let mut buf = [0u8; MAX_IMAGE_LEN];
    let n = emit(robot, plan_id, &steps, &mut buf).expect("emit");
    buf[..n].to_vec()
}

/// Sends a PLAN TC with raw application data; returns its completion or failure.
fn plan_tc(c: &mut Client, apid: u16, subservice: u8, app: &[u8]) -> Tm {
    let seq = c.next_seq();
    let raw = tc(apid, seq, mib::tc::service::PLAN, subservice, app);
    c.send_raw(&raw);
    c.wait_done(&raw, T)
        .unwrap_or_else(|| panic!("no report: {}", c.summary()))
}

fn load(c: &mut Client, apid: u16, offset: u16, bytes: &[u8]) -> Tm {
    let mut app = offset.to_be_bytes().to_vec();
    app.push(bytes.len() as u8);
    app.extend_from_slice(bytes);
    plan_tc(c, apid, sub::LOAD, &app)
}

/// Stages `img` chunk by chunk (each accepted) and commits it with CRC `crc`.
fn upload(c: &mut Client, apid: u16, img: &[u8], crc: u32) -> Tm {
    for (i, chunk) in img.chunks(MAX_CHUNK).enumerate() {
        assert_eq!(load(c, apid, (i * MAX_CHUNK) as u16, chunk).subservice, 7, "staged");
    }
    let mut app = (img.len() as u16).to_be_bytes().to_vec();
    app.extend_from_slice(&crc.to_be_bytes());
    plan_tc(c, apid, sub::COMMIT, &app)
}

fn trailer(img: &[u8]) -> u32 {
    u32::from_be_bytes(img[img.len() - 4..].try_into().unwrap())
}

// verifies: PLAN-LOAD-01, PLAN-LOAD-02, PLAN-IMG-02
#[test]
fn a_plan_too_large_corrupted_malformed_foreign_invalid_or_unconfirmed_is_refused_with_its_code() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let apid = o.apid;
    let max = (MAX_IMAGE_LEN as u16).to_be_bytes();
    // Bytes ending past the largest image, and a chunk leaving a gap after the staged bytes.
    let t = load(&mut c, apid, MAX_IMAGE_LEN as u16 - 10, &[0; 30]);
    let end = (MAX_IMAGE_LEN as u16 + 20).to_be_bytes();
    assert_eq!(refusal(&t), (F::PLAN_TOO_LARGE.code(), [end, max].concat()));
    assert_eq!(load(&mut c, apid, 0, &[0; 10]).subservice, 7);
    let t = load(&mut c, apid, 100, &[0; 10]);
    assert_eq!(
        refusal(&t),
        (F::PLAN_TOO_LARGE.code(), [110u16.to_be_bytes(), max].concat())
    );

    let ping = tc_named(apid, 500, "PING", &[]);
    let good = image(ROBOT, 7, &[StepKind::Tc(&ping)], false);
    let crc = trailer(&good);
    // A chunk lost or corrupted: the TC's CRC is not the staged bytes'.
    let t = upload(&mut c, apid, &good, crc ^ 1);
    let mut data = (crc ^ 1).to_be_bytes().to_vec();
    data.extend_from_slice(&crc.to_be_bytes());
    data.extend_from_slice(&(good.len() as u16).to_be_bytes());
    assert_eq!(refusal(&t), (F::PLAN_CHECKSUM.code(), data));

    // Sealed but of a format version the robot does not know.
    let mut bad = good.clone();
    bad[2] = 9;
    let n = bad.len();
    let resealed = crc32(&bad[..n - 4]);
    bad[n - 4..].copy_from_slice(&resealed.to_be_bytes());
    let t = upload(&mut c, apid, &bad, resealed);
    assert_eq!(refusal(&t), (F::PLAN_INVALID.code(), vec![invalid::FORMAT, 0, 0]));

    let other = image(ROBOT + 1, 7, &[StepKind::Tc(&ping)], false);
    let t = upload(&mut c, apid, &other, trailer(&other));
    assert_eq!(refusal(&t), (F::PLAN_WRONG_ROBOT.code(), vec![ROBOT + 1]));

    // Step 1 is for another APID: its acceptance would refuse it.
    let foreign = tc_named(apid + 1, 501, "PING", &[]);
    let img = image(ROBOT, 7, &[StepKind::Tc(&ping), StepKind::Tc(&foreign)], false);
    let t = upload(&mut c, apid, &img, trailer(&img));
    let mut data = vec![1];
    data.extend_from_slice(&F::WRONG_APID.code().to_be_bytes());
    assert_eq!(refusal(&t), (F::PLAN_STEP_INVALID.code(), data));

    // Step 1 is a hazardous MODE_SET the operator did not confirm.
    let mode = tc_named(
        apid,
        502,
        "MODE_SET",
        &[node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0],
    );
    let img = image(ROBOT, 7, &[StepKind::Tc(&ping), StepKind::Tc(&mode)], false);
    let t = upload(&mut c, apid, &img, trailer(&img));
    assert_eq!(refusal(&t), (F::PLAN_HAZARD_UNCONFIRMED.code(), vec![1]));

    // Nothing was loaded by any of them.
    let t = plan_tc(&mut c, apid, sub::START, &7u32.to_be_bytes());
    assert_eq!(refusal(&t), (F::PLAN_NOT_LOADED.code(), vec![]));
    let t = plan_tc(&mut c, apid, sub::ABORT, &[]);
    assert_eq!(refusal(&t), (F::PLAN_NOT_LOADED.code(), vec![]));
    // Confirmed, the same plan loads.
    let img = image(ROBOT, 7, &[StepKind::Tc(&ping), StepKind::Tc(&mode)], true);
    assert_eq!(upload(&mut c, apid, &img, trailer(&img)).subservice, 7);
}

// verifies: PLAN-EXEC-02
#[test]
fn plan_commands_out_of_state_or_step_are_refused_with_their_code() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let apid = o.apid;
    // Step 0 is refused in standby (the mode check), which suspends the plan at step 0.
    let reconf = tc_named(apid, 600, "RECONFIGURE", &[0, 1]);
    let ping = tc_named(apid, 601, "PING", &[]);
    let img = image(ROBOT, 42, &[StepKind::Tc(&reconf), StepKind::Tc(&ping)], false);
    assert_eq!(upload(&mut c, apid, &img, trailer(&img)).subservice, 7);
    let bad_state = |s: u8| (F::PLAN_BAD_STATE.code(), vec![s]);
    assert_eq!(
        refusal(&plan_tc(&mut c, apid, sub::SUSPEND, &[])),
        bad_state(state::LOADED)
    );
    assert_eq!(
        refusal(&plan_tc(&mut c, apid, sub::RESUME, &[])),
        bad_state(state::LOADED)
    );
    // A stale START for another plan.
    let t = plan_tc(&mut c, apid, sub::START, &41u32.to_be_bytes());
    assert_eq!(refusal(&t), (F::PLAN_NOT_LOADED.code(), vec![]));
    assert_eq!(plan_tc(&mut c, apid, sub::START, &42u32.to_be_bytes()).subservice, 7);
    let t = c
        .wait_done(&reconf, T)
        .expect("step 0 reported under its own request ID");
    assert_eq!(t.failure_code(), Some(F::NOT_ALLOWED_IN_MODE.code()));
    // Suspended: no new image while it holds the robot.
    let t = load(&mut c, apid, 0, &img[..10]);
    assert_eq!(refusal(&t), (F::PLAN_BUSY.code(), vec![state::SUSPENDED]));
    let mut app = (img.len() as u16).to_be_bytes().to_vec();
    app.extend_from_slice(&trailer(&img).to_be_bytes());
    let t = plan_tc(&mut c, apid, sub::COMMIT, &app);
    assert_eq!(refusal(&t), (F::PLAN_BUSY.code(), vec![state::SUSPENDED]));
    assert_eq!(
        refusal(&plan_tc(&mut c, apid, sub::START, &42u32.to_be_bytes())),
        bad_state(state::SUSPENDED)
    );
    // Only the next step may be skipped.
    let t = plan_tc(&mut c, apid, sub::SKIP, &[1]);
    assert_eq!(refusal(&t), (F::PLAN_STEP_MISMATCH.code(), vec![0, 1]));
    assert_eq!(plan_tc(&mut c, apid, sub::SKIP, &[0]).subservice, 7);
    assert_eq!(plan_tc(&mut c, apid, sub::RESUME, &[]).subservice, 7);
    assert_eq!(c.wait_done(&ping, T).map(|t| t.subservice), Some(7), "step 1 ran");
    // Completed: nothing left to skip.
    let t = plan_tc(&mut c, apid, sub::SKIP, &[1]);
    assert_eq!(refusal(&t), bad_state(state::COMPLETED));

    // A plan that runs (a long wait): busy for a new image, and no skip while running.
    let img = image(ROBOT, 43, &[StepKind::Wait { ms: 600_000 }], false);
    assert_eq!(upload(&mut c, apid, &img, trailer(&img)).subservice, 7);
    assert_eq!(plan_tc(&mut c, apid, sub::START, &43u32.to_be_bytes()).subservice, 7);
    let t = load(&mut c, apid, 0, &img[..10]);
    assert_eq!(refusal(&t), (F::PLAN_BUSY.code(), vec![state::RUNNING]));
    assert_eq!(
        refusal(&plan_tc(&mut c, apid, sub::SKIP, &[0])),
        bad_state(state::RUNNING)
    );
    assert_eq!(plan_tc(&mut c, apid, sub::ABORT, &[]).subservice, 7);
    assert_eq!(
        refusal(&plan_tc(&mut c, apid, sub::RESUME, &[])),
        bad_state(state::ABORTED)
    );
}

/// Codes that a packet cannot provoke with this MIB, and why.
const UNREACHABLE: &[(F, &str)] = &[
    (F::UNREACHABLE_STATE, "every state pair is within 3 primitives"),
    (F::PLAN_UNREACHABLE, "every state pair is within 3 primitives"),
];

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
