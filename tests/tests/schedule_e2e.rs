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
