//! End-to-end tests of the PUS services that do not move the robot: 3, 5, 9, 11, 15,
//! 17, 20 — each over real sockets against the real `obsw`.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use e2e_tests::{tc, Client, Obsw};
use mib::events::eid;
use mib::params::pid;
use mib::tunables::tid;

const T: Duration = Duration::from_secs(5);

/// CDS short time stamp (P-field 0x40, 16-bit days, ms of day) of a Unix time in ms.
fn cds(unix_ms: u64) -> [u8; 7] {
    let days = (unix_ms / 86_400_000 + 4383) as u16;
    let ms = (unix_ms % 86_400_000) as u32;
    let mut out = [0x40, 0, 0, 0, 0, 0, 0];
    out[1..3].copy_from_slice(&days.to_be_bytes());
    out[3..7].copy_from_slice(&ms.to_be_bytes());
    out
}

fn unix_ms() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_millis() as u64
}

// verifies: PUS-3-02
#[test]
fn hk_can_be_disabled_enabled_and_requested_once() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let raw = c.send("HK_SET_INTERVAL", &[1, 50]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    let raw = c.send("HK_DISABLE", &[1]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    c.recv_for(Duration::from_millis(100));
    let quiet = c.recv_for(Duration::from_millis(500));
    assert!(
        quiet.iter().all(|t| t.sid() != Some(1)),
        "disabled structure stays quiet"
    );
    c.send("HK_ONE_SHOT", &[1]);
    assert!(c.wait_for(T, |t| t.sid() == Some(1)).is_some(), "one-shot report");
    let raw = c.send("HK_ENABLE", &[1]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    let back = c.recv_for(Duration::from_millis(500));
    assert!(
        back.iter().filter(|t| t.sid() == Some(1)).count() >= 5,
        "periodic again at 20 Hz"
    );
}

// verifies: PUS-5-02
#[test]
fn events_can_be_disabled_and_the_disabled_list_reported() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let raw = c.send("EVENT_DISABLE", &[eid::TC_REJECTED as i64]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    c.send_raw(&tc(o.apid, 500, 99, 1, &[]));
    c.recv_for(Duration::from_millis(300));
    assert!(
        c.log.iter().all(|t| t.event_id() != Some(eid::TC_REJECTED)),
        "disabled event not reported"
    );
    c.send("EVENT_REPORT_DISABLED", &[]);
    let t = c.wait_for(T, |t| t.service == 5 && t.subservice == 8).expect("TM[5,8]");
    assert_eq!(
        &t.data[..4],
        &[0, 1, (eid::TC_REJECTED >> 8) as u8, eid::TC_REJECTED as u8]
    );
    let raw = c.send("EVENT_ENABLE", &[eid::TC_REJECTED as i64]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    c.send_raw(&tc(o.apid, 501, 99, 1, &[]));
    assert!(c.wait_for(T, |t| t.event_id() == Some(eid::TC_REJECTED)).is_some());
}

// verifies: PUS-9-01
#[test]
fn time_reports_follow_the_commanded_rate_and_carry_on_board_time() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let before = unix_ms();
    let raw = c.send("TIME_SET_RATE", &[0]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    let reports: Vec<_> = c
        .recv_for(Duration::from_millis(2600))
        .into_iter()
        .filter(|t| t.service == 9 && t.subservice == 2)
        .collect();
    assert!(
        (2..=4).contains(&reports.len()),
        "one report per second (plus the immediate one): {}",
        reports.len()
    );
    let t = &reports[0];
    assert_eq!(t.data[0], 0, "rate exponent");
    let days = u16::from_be_bytes([t.data[2], t.data[3]]) as u64;
    let ms = u32::from_be_bytes([t.data[4], t.data[5], t.data[6], t.data[7]]) as u64;
    let unix = (days - 4383) * 86_400_000 + ms;
    assert!(
        unix + 2000 >= before && unix <= unix_ms() + 2000,
        "on-board time close to the host clock at speed 1"
    );
}

// verifies: MMIC-FW-03, PUS-11-01
#[test]
fn a_scheduled_tc_is_released_at_its_time() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    c.send("PING", &[]);
    c.recv_for(Duration::from_millis(200));
    let inner = tc(o.apid, 900, 17, 1, &[]);
    let mut app = vec![1u8];
    app.extend_from_slice(&cds(unix_ms() + 1500));
    app.extend_from_slice(&inner);
    let seq = c.next_seq();
    let ins = tc(o.apid, seq, 11, 4, &app);
    c.send_raw(&ins);
    assert_eq!(c.wait_done(&ins, T).unwrap().subservice, 7);
    c.send("HK_ONE_SHOT", &[4]);
    let hk = c.wait_for(T, |t| t.sid() == Some(4)).unwrap();
    assert_eq!(hk.hk(pid::SCHED_COUNT), Some(1));
    let early = c.recv_for(Duration::from_millis(900));
    assert!(
        early.iter().all(|t| !(t.service == 17 && t.subservice == 2)),
        "not before its time"
    );
    let done = c
        .wait_done(&inner, Duration::from_secs(3))
        .expect("released TC verified");
    assert_eq!(done.subservice, 7);
    // Reset empties the schedule.
    let mut app = vec![1u8];
    app.extend_from_slice(&cds(unix_ms() + 60_000));
    app.extend_from_slice(&tc(o.apid, 901, 17, 1, &[]));
    let seq = c.next_seq();
    c.send_raw(&tc(o.apid, seq, 11, 4, &app));
    let raw = c.send("SCHED_RESET", &[]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    c.send("HK_ONE_SHOT", &[4]);
    let hk = c.wait_for(T, |t| t.sid() == Some(4) && t.hk(pid::SCHED_COUNT) == Some(0));
    assert!(hk.is_some(), "schedule empty after reset");
}

// verifies: PUS-15-01, GND-02
#[test]
fn stored_tm_is_downlinked_on_request_with_nothing_lost() {
    let o = Obsw::start(&[]);
    // HK at 20 Hz while no ground is listening (nobody has sent a TC yet).
    let mut first = Client::udp(&o);
    let raw = first.send("HK_SET_INTERVAL", &[1, 50]);
    first.wait_done(&raw, T).unwrap();
    let live_seq: Vec<u16> = first
        .recv_for(Duration::from_millis(300))
        .iter()
        .map(|t| t.seq)
        .collect();
    drop(first);
    // A new ground station (another port) asks for the store: it gets everything that
    // was sent while it was not listening, oldest first, then TM[15,19].
    std::thread::sleep(Duration::from_millis(500));
    let mut c = Client::udp(&o);
    let raw = c.send("STORE_DOWNLINK_TIME", &[0, 0, 65535, 4_294_967_295]);
    let end = c
        .wait_for(T, |t| t.service == 15 && t.subservice == 19)
        .expect("end of downlink");
    let count = u32::from_be_bytes(end.data[..4].try_into().unwrap()) as usize;
    let replay: Vec<u16> = c
        .log
        .iter()
        .filter(|t| t.raw != end.raw && t.request() != Some(e2e_tests::request_of(&raw)))
        .map(|t| t.seq)
        .collect();
    assert!(
        count >= replay.len().saturating_sub(2) && count >= 10,
        "downlinked {count}"
    );
    for s in live_seq.iter().chain([live_seq.last().unwrap() + 5].iter()) {
        assert!(replay.contains(s), "sequence count {s} kept in the store");
    }
    let mut sorted = replay.clone();
    sorted.sort();
    sorted.dedup();
    assert!(
        sorted.windows(2).filter(|w| w[1] != w[0] + 1).count() <= 2,
        "no gaps in the stored sequence counts"
    );
}

// verifies: PUS-20-01
#[test]
fn tunables_are_reported_set_and_range_checked() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    c.send("PARAM_REPORT", &[tid::BOLT_MAX_ATTEMPTS as i64]);
    let t = c.wait_for(T, |t| t.service == 20 && t.subservice == 2).unwrap();
    assert_eq!(i32::from_be_bytes(t.data[2..6].try_into().unwrap()), 3);
    let raw = c.send("PARAM_SET", &[tid::BOLT_MAX_ATTEMPTS as i64, 2]);
    assert_eq!(c.wait_done(&raw, T).unwrap().subservice, 7);
    let t = c
        .log
        .iter()
        .rev()
        .find(|t| t.service == 20 && t.subservice == 2)
        .unwrap();
    assert_eq!(i32::from_be_bytes(t.data[2..6].try_into().unwrap()), 2);
    let raw = c.send("PARAM_SET", &[tid::BOLT_MAX_ATTEMPTS as i64, 9]);
    assert_eq!(
        c.wait_done(&raw, T).unwrap().failure_code(),
        Some(mib::FailureCode::PARAM_OUT_OF_RANGE.code())
    );
}
