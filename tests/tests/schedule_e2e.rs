//! PUS 11 over the real link: a TC[11,4] whose activity is itself a TC[11,4] is refused
//! at acceptance (schedules do not nest), naming the activity.

use std::time::Duration;

use e2e_tests::{tc, Client, Obsw};
use mib::FailureCode as F;

// verifies: PUS-11-02
#[test]
fn a_schedule_nested_in_a_schedule_is_refused() {
    let o = Obsw::start(&["--speed", "20"]);
    let mut c = Client::udp(&o);
    // A release time one hour ahead (CDS short with P-field).
    let unix = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as u64
        + 3_600_000;
    let mut at = [0x40u8, 0, 0, 0, 0, 0, 0];
    at[1..3].copy_from_slice(&((unix / 86_400_000 + 4383) as u16).to_be_bytes());
    at[3..].copy_from_slice(&((unix % 86_400_000) as u32).to_be_bytes());
    let mut inner_app = vec![1u8];
    inner_app.extend_from_slice(&at);
    inner_app.extend_from_slice(&tc(o.apid, 900, 17, 1, &[]));
    let inner = tc(o.apid, 901, 11, 4, &inner_app);
    let mut app = vec![1u8];
    app.extend_from_slice(&at);
    app.extend_from_slice(&inner);
    let seq = c.next_seq();
    let raw = tc(o.apid, seq, 11, 4, &app);
    c.send_raw(&raw);
    let t = c.wait_done(&raw, Duration::from_secs(10)).expect("answered");
    assert_eq!((t.subservice, t.failure_code()), (2, Some(F::NESTED_SCHEDULE.code())));
    assert_eq!(t.data[6], 0, "the first activity");
}

/// A release time as Yamcs 5.12.8's `PusCommandPostprocessor` writes it (`mib::tc::sched_cuc`):
/// CUC 4+2 octets, implicit P-field, seconds since 1970 counting leap seconds.
fn yamcs_cuc(unix_ms: u64) -> [u8; 6] {
    let instant = unix_ms + mib::tc::sched_cuc::TAI_MINUS_UTC_S * 1000;
    let mut out = [0u8; 6];
    out[..4].copy_from_slice(&((instant / 1000) as u32).to_be_bytes());
    out[4..].copy_from_slice(&(((instant % 1000) * 65536 / 1000) as u16).to_be_bytes());
    out
}

// verifies: YAMCS-SCHED-01
#[test]
fn a_tc_11_4_in_yamcs_form_runs_at_its_release_time_and_the_cds_form_still_does() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as u64;
    // Yamcs' form: sub-schedule ID 1, N = 1, CUC, the TC.
    let at = now + 1500;
    let inner = tc(o.apid, 900, 17, 1, &[]);
    let mut app = vec![mib::tc::sched_cuc::SUB_SCHEDULE_ID, 1];
    app.extend_from_slice(&yamcs_cuc(at));
    app.extend_from_slice(&inner);
    let seq = c.next_seq();
    let raw = tc(o.apid, seq, 11, 4, &app);
    c.send_raw(&raw);
    assert_eq!(
        c.wait_done(&raw, Duration::from_secs(5)).expect("answered").subservice,
        7
    );
    // The CDS form in the same schedule, 200 ms later.
    let inner2 = tc(o.apid, 901, 17, 1, &[]);
    let unix = at + 200;
    let mut app = vec![1u8, 0x40];
    app.extend_from_slice(&((unix / 86_400_000 + 4383) as u16).to_be_bytes());
    app.extend_from_slice(&((unix % 86_400_000) as u32).to_be_bytes());
    app.extend_from_slice(&inner2);
    let seq = c.next_seq();
    let raw = tc(o.apid, seq, 11, 4, &app);
    c.send_raw(&raw);
    assert_eq!(
        c.wait_done(&raw, Duration::from_secs(5)).expect("answered").subservice,
        7
    );
    for (t, release) in [(&inner, at), (&inner2, at + 200)] {
        let done = c.wait_done(t, Duration::from_secs(5)).expect("released TC verified");
        assert_eq!(done.subservice, 7);
        let days = u16::from_be_bytes([done.raw[14], done.raw[15]]) as u64;
        let ms = u32::from_be_bytes([done.raw[16], done.raw[17], done.raw[18], done.raw[19]]) as u64;
        let onboard = (days - 4383) * 86_400_000 + ms;
        assert!(
            (release..release + 1000).contains(&onboard),
            "released at {onboard}, release time {release}"
        );
    }
}
