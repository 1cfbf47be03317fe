//! FDIR over real sockets: one smoke test through the real `obsw` binary (UDP TC/TM and
//! the simulator-control socket). Every fault of paper Table 8 is tested in process
//! against `Obsw` and the simulator on a mock clock in `obsw/core/tests/fdir.rs`.

use std::time::Duration;

use e2e_tests::{Client, Obsw};
use mib::modes::{node, robot_mode};
use mib::FailureCode as F;

const LONG: Duration = Duration::from_secs(60);

/// A regulator that never comes up (battery sagged to 5 V): the commanded mode change
/// times out, the command fails with the reason, and the robot falls back to standby.
// verifies: PUS-200-01, PUS-1-02
#[test]
fn a_mode_transition_that_cannot_complete_times_out_over_the_real_link() {
    let o = Obsw::start(&["--speed", "20"]);
    let mut c = Client::udp(&o);
    assert!(o.sim("battery-sag 5.0").starts_with("ok"));
    c.recv_for(Duration::from_millis(300));
    let raw = c.send("MODE_SET", &[node::ROBOT as i64, robot_mode::SAFED as i64, 0]);
    let t = c.wait_done(&raw, LONG).expect("mode command finishes");
    assert_eq!(t.failure_code(), Some(F::MODE_CHANGE_FAILED.code()));
    assert_eq!(
        u16::from_be_bytes([t.data[14], t.data[15]]),
        F::TIMEOUT.code(),
        "reason: the transition timed out"
    );
}
