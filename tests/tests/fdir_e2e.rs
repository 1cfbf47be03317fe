//! End-to-end tests of the FDIR issue: every fault of paper Table 8 injected into the
//! simulator (through its control channel, never the TC path) in the phase where it
//! can happen, checked over real sockets: the PUS 12 transition report, the PUS 5
//! event, the resulting mode in HK and in the mode tree, what happened to the running
//! action, and that commanding back to operational works once the fault is cleared.

use std::time::Duration;

use e2e_tests::{request_of, Client, Obsw, Tm};
use mib::events::eid;
use mib::modes::{node, robot_mode};
use mib::params::pid;
use mib::FailureCode as F;

const T: Duration = Duration::from_secs(10);
const LONG: Duration = Duration::from_secs(60);

fn start() -> (Obsw, Client) {
    let o = Obsw::start(&["--speed", "20"]);
    let c = Client::udp(&o);
    (o, c)
}

fn set_mode(c: &mut Client, mode: u32) -> Tm {
    let raw = c.send("MODE_SET", &[node::ROBOT as i64, mode as i64, 0]);
    c.wait_done(&raw, LONG).expect("mode command finishes")
}

fn operational(c: &mut Client) {
    let t = set_mode(c, robot_mode::OPERATIONAL);
    assert_eq!(
        t.subservice,
        7,
        "operational refused: {:?} data {:02x?}\n{}",
        t.failure_code(),
        &t.data[6..],
        c.summary()
    );
}

/// Paper: in safed only hip and arm commands are accepted; the operator contracts an
/// arm (side 0 = A, 1 = B) before commanding operational again.
fn contract_in_safed(c: &mut Client, side: i64) {
    let m = c.send("MOVE_ARM", &[side, mib::robot::servo::ARM_CONTRACTED_US as i64]);
    let t = c.wait_done(&m, LONG).unwrap();
    assert_eq!(t.subservice, 7, "arm command accepted in safed:\n{}", c.summary());
}

/// Current value of a parameter from a one-shot HK report.
fn hk(c: &mut Client, sid: u16, param: u16) -> i64 {
    c.send("HK_ONE_SHOT", &[sid as i64]);
    c.wait_for(T, |t| t.sid() == Some(sid))
        .expect("HK report")
        .hk(param)
        .expect("parameter in structure")
}

fn robot_mode_reported(c: &mut Client) -> u32 {
    c.send("MODE_READ", &[node::ROBOT as i64]);
    let t = c
        .wait_for(T, |t| {
            t.service == 200 && t.subservice == 6 && t.data[..4] == node::ROBOT.to_be_bytes()
        })
        .expect("TM[200,6]");
    u32::from_be_bytes(t.data[4..8].try_into().unwrap())
}

/// Waits until the robot node reports `mode` in a MODE_CHANGED event.
fn wait_mode(c: &mut Client, mode: u32) -> Tm {
    let hit = |t: &Tm| {
        t.event_id() == Some(eid::MODE_CHANGED)
            && t.data[2..6] == node::ROBOT.to_be_bytes()
            && t.data[10..14] == mode.to_be_bytes()
    };
    if let Some(t) = c.log.iter().find(|t| hit(t)) {
        return t.clone();
    }
    c.wait_for(LONG, hit)
        .unwrap_or_else(|| panic!("robot never entered mode {mode}"))
}

fn wait_event(c: &mut Client, id: u16) -> Tm {
    if let Some(t) = c.log.iter().find(|t| t.event_id() == Some(id)) {
        return t.clone();
    }
    c.wait_for(LONG, |t| t.event_id() == Some(id))
        .unwrap_or_else(|| panic!("no event 0x{id:04X}"))
}

fn wait_monitor(c: &mut Client, monitor: u16, state: u8) -> Tm {
    let hit =
        |t: &Tm| t.service == 12 && t.subservice == 12 && t.data[..2] == monitor.to_be_bytes() && t.data[12] == state;
    if let Some(t) = c.log.iter().find(|t| hit(t)) {
        return t.clone();
    }
    c.wait_for(LONG, hit)
        .unwrap_or_else(|| panic!("no TM[12,12] for monitor {monitor} state {state}"))
}

/// The cause (fault event) of the robot's last mode change.
fn cause(t: &Tm) -> u16 {
    u16::from_be_bytes([t.data[14], t.data[15]])
}

fn recover(o: &Obsw, c: &mut Client, clear: &str) {
    assert!(o.sim(clear).starts_with("ok"));
    // Give monitors time to see the cause gone (moving average + persistence).
    c.recv_for(Duration::from_millis(400));
    operational(c);
    assert_eq!(robot_mode_reported(c), robot_mode::OPERATIONAL);
}

// verifies: MMIC-FLT-04
#[test]
fn low_battery_mid_motion_lets_the_motion_complete_then_standby() {
    let (o, mut c) = start();
    operational(&mut c);
    let raw = c.send("RECONFIGURE", &[0, 1]);
    c.wait_for(T, |t| t.request() == Some(request_of(&raw)) && t.subservice == 3)
        .expect("started");
    assert!(o.sim("battery-sag 9.5").starts_with("ok"));
    let mon = wait_monitor(&mut c, 1, 1);
    assert!(
        i32::from_be_bytes(mon.data[4..8].try_into().unwrap())
            < i32::from_be_bytes(mon.data[8..12].try_into().unwrap())
    );
    let ev = wait_event(&mut c, eid::LOW_BATTERY);
    assert_eq!(ev.subservice, 4, "high severity");
    let done = c.wait_done(&raw, LONG).expect("reconfiguration finishes");
    assert_eq!(
        done.subservice,
        7,
        "paper: the motion completes first ({:?})",
        done.failure_code()
    );
    let m = wait_mode(&mut c, robot_mode::STANDBY);
    assert_eq!(cause(&m), eid::LOW_BATTERY);
    let mode_change = c
        .log
        .iter()
        .position(|t| t.event_id() == Some(eid::MODE_CHANGED) && t.data[10..14] == robot_mode::STANDBY.to_be_bytes())
        .unwrap();
    let completion = c
        .log
        .iter()
        .position(|t| t.request() == Some(request_of(&raw)) && t.subservice == 7)
        .unwrap();
    assert!(completion < mode_change, "standby only after the motion completed");
    assert_eq!(hk(&mut c, 1, pid::MODE), robot_mode::STANDBY as i64);
    // Still low: operational is refused with the fault named.
    let t = set_mode(&mut c, robot_mode::OPERATIONAL);
    assert_eq!(t.failure_code(), Some(F::FAULT_NOT_CLEARED.code()));
    assert_eq!(u16::from_be_bytes([t.data[6], t.data[7]]), eid::LOW_BATTERY);
    recover(&o, &mut c, "clear battery-sag");
}

// verifies: MMIC-FLT-05
#[test]
fn assembly_system_fault_mid_motion_lets_the_motion_complete_then_standby() {
    let (_o, mut c) = start();
    operational(&mut c);
    let raw = c.send("RECONFIGURE", &[0, 1]);
    c.wait_for(T, |t| t.request() == Some(request_of(&raw)) && t.subservice == 3)
        .expect("started");
    let f = c.send("ASSEMBLY_FAULT", &[7]);
    assert_eq!(c.wait_done(&f, T).unwrap().subservice, 7);
    assert_eq!(wait_event(&mut c, eid::ASSEMBLY_SYSTEM_FAULT).data[2..4], [0, 7]);
    assert_eq!(
        hk(&mut c, 3, pid::PENDING_MODE),
        robot_mode::STANDBY as i64,
        "standby pending while moving"
    );
    assert_eq!(c.wait_done(&raw, LONG).unwrap().subservice, 7);
    assert_eq!(
        cause(&wait_mode(&mut c, robot_mode::STANDBY)),
        eid::ASSEMBLY_SYSTEM_FAULT
    );
    operational(&mut c);
}

// verifies: MMIC-FLT-01
#[test]
fn bolting_failure_goes_to_standby() {
    let o = Obsw::start(&["--speed", "50"]);
    let mut c = Client::udp(&o);
    operational(&mut c);
    assert!(o.sim("fastener-jam").starts_with("ok"));
    let raw = c.send("BOLT_PAIR", &[0, 2]);
    let done = c.wait_done(&raw, LONG).expect("bolt finishes");
    assert_eq!(done.failure_code(), Some(F::BOLT_FAILED.code()));
    let ev = wait_event(&mut c, eid::BOLT_FAILURE);
    assert_eq!(&ev.data[2..5], &[0, 2, 3], "side A, pair 2, 3 attempts");
    assert_eq!(
        c.log
            .iter()
            .filter(|t| t.event_id() == Some(eid::BOLT_ATTEMPT_FAILED))
            .count(),
        3,
        "one event per failed attempt"
    );
    assert_eq!(cause(&wait_mode(&mut c, robot_mode::STANDBY)), eid::BOLT_FAILURE);
    assert_eq!(hk(&mut c, 3, pid::FAULT_LATCHED) & 1, 1, "bolting-failure bit latched");
    recover(&o, &mut c, "clear");
}

// verifies: MMIC-CMD-07, MMIC-FLT-03
#[test]
fn initial_state_mismatch_is_refused_and_goes_to_standby() {
    let (o, mut c) = start();
    operational(&mut c);
    assert!(o.sim("misplaced-voxel").starts_with("ok"));
    c.recv_for(Duration::from_millis(300));
    let raw = c.send("RECONFIGURE", &[0, 1]);
    let t = c.wait_done(&raw, T).unwrap();
    assert_eq!(
        (t.subservice, t.failure_code()),
        (4, Some(F::INITIAL_STATE_MISMATCH.code()))
    );
    assert_eq!(t.data[6], 0, "ground believed state 0");
    wait_event(&mut c, eid::INITIAL_STATE_MISMATCH);
    assert_eq!(
        cause(&wait_mode(&mut c, robot_mode::STANDBY)),
        eid::INITIAL_STATE_MISMATCH
    );
    recover(&o, &mut c, "clear misplaced-voxel");
}

// verifies: MMIC-FLT-06
#[test]
fn arm_not_contracted_goes_to_safed_and_holds_arms_and_hip() {
    let (o, mut c) = start();
    operational(&mut c);
    // Xneg -> Xpos: side A extends to Xpos, then arm B must contract onto it.
    let raw = c.send("RECONFIGURE", &[0, 1]);
    wait_event(&mut c, eid::PRIMITIVE_DONE);
    assert!(o.sim("stuck-arm b").starts_with("ok"));
    let t = c.wait_done(&raw, LONG).unwrap();
    assert_eq!(t.subservice, 8, "the reconfiguration fails: {:?}", t.failure_code());
    assert_eq!(wait_event(&mut c, eid::ARM_NOT_CONTRACTED).data[2], 1, "side B");
    assert_eq!(cause(&wait_mode(&mut c, robot_mode::SAFED)), eid::ARM_NOT_CONTRACTED);
    c.send("MODE_READ", &[node::ARM_B as i64]);
    let arm = c
        .wait_for(T, |t| {
            t.service == 200 && t.subservice == 6 && t.data[..4] == node::ARM_B.to_be_bytes()
        })
        .unwrap();
    assert_eq!(
        u32::from_be_bytes(arm.data[4..8].try_into().unwrap()),
        mib::modes::module_mode::HOLD
    );
    // Paper: in safed the operator may still move arms; contract B, then recover.
    assert!(o.sim("clear stuck-arm").starts_with("ok"));
    contract_in_safed(&mut c, 1);
    operational(&mut c);
}

// verifies: MMIC-FLT-08
#[test]
fn operational_overcurrent_mid_motion_aborts_to_safed() {
    let (o, mut c) = start();
    operational(&mut c);
    assert!(o.sim("obstacle a").starts_with("ok"));
    let raw = c.send("RECONFIGURE", &[0, 1]);
    let done = c.wait_done(&raw, LONG).expect("reconfiguration ends");
    assert_eq!(done.failure_code(), Some(F::ABORTED_BY_FAULT.code()));
    assert_eq!(
        u16::from_be_bytes([done.data[6], done.data[7]]),
        eid::OPERATIONAL_OVERCURRENT
    );
    let mon = wait_monitor(&mut c, 3, 2);
    assert_eq!(u16::from_be_bytes([mon.data[2], mon.data[3]]), pid::I_LOC_A);
    let ev = wait_event(&mut c, eid::OPERATIONAL_OVERCURRENT);
    assert_eq!(
        u16::from_be_bytes([ev.data[2], ev.data[3]]),
        pid::I_LOC_A,
        "event names the channel"
    );
    assert_eq!(
        cause(&wait_mode(&mut c, robot_mode::SAFED)),
        eid::OPERATIONAL_OVERCURRENT
    );
    // The motion stopped with side B's gripper open and its arm half extended: the
    // operator contracts both arms in safed (arm commands are allowed there) so the
    // robot is contracted and gripped, as the paper asks before operational.
    assert!(o.sim("clear obstacle").starts_with("ok"));
    contract_in_safed(&mut c, 1);
    contract_in_safed(&mut c, 0);
    operational(&mut c);
}

// verifies: MMIC-FLT-07
#[test]
fn idle_overcurrent_at_reconfiguration_start_goes_to_safed() {
    let (_o, mut c) = start();
    operational(&mut c);
    // Tighten the idle limit below the holding current (PUS 12 modify by TC).
    let m = c.send("MON_MODIFY", &[9, i32::MIN as i64, 20, 1]);
    assert_eq!(c.wait_done(&m, T).unwrap().subservice, 7);
    let raw = c.send("RECONFIGURE", &[0, 1]);
    let t = c.wait_done(&raw, T).unwrap();
    assert_eq!((t.subservice, t.failure_code()), (4, Some(F::ABORTED_BY_FAULT.code())));
    wait_monitor(&mut c, 9, 2);
    wait_event(&mut c, eid::IDLE_OVERCURRENT);
    assert_eq!(cause(&wait_mode(&mut c, robot_mode::SAFED)), eid::IDLE_OVERCURRENT);
    let m = c.send("MON_MODIFY", &[9, i32::MIN as i64, 400, 1]);
    assert_eq!(c.wait_done(&m, T).unwrap().subservice, 7);
    operational(&mut c);
}

// verifies: MMIC-FLT-09
#[test]
fn hip_mismatch_when_entering_operational_goes_to_safed() {
    let (o, mut c) = start();
    assert!(o.sim("dead-hip-encoder").starts_with("ok"));
    c.recv_for(Duration::from_millis(300));
    let t = set_mode(&mut c, robot_mode::OPERATIONAL);
    assert_eq!(t.failure_code(), Some(F::MODE_CHANGE_FAILED.code()));
    wait_monitor(&mut c, 11, 2);
    wait_event(&mut c, eid::HIP_MISMATCH);
    assert_eq!(cause(&wait_mode(&mut c, robot_mode::SAFED)), eid::HIP_MISMATCH);
    recover(&o, &mut c, "clear dead-hip-encoder");
}

// verifies: MMIC-FLT-10
#[test]
fn heartbeat_loss_while_idle_goes_to_safed_and_blocks_recovery_until_the_link_is_back() {
    let (o, mut c) = start();
    operational(&mut c);
    assert!(o.sim("cut-cable").starts_with("ok"));
    wait_monitor(&mut c, 12, 2);
    wait_event(&mut c, eid::COMM_LOSS_HEARTBEAT);
    assert_eq!(cause(&wait_mode(&mut c, robot_mode::SAFED)), eid::COMM_LOSS_HEARTBEAT);
    assert_eq!(hk(&mut c, 2, pid::B_LINK_OK), 0);
    let t = set_mode(&mut c, robot_mode::OPERATIONAL);
    assert_eq!(
        t.failure_code(),
        Some(F::FAULT_NOT_CLEARED.code()),
        "a persisting fault is reported, not retried"
    );
    assert!(o.sim("clear cut-cable").starts_with("ok"));
    wait_monitor(&mut c, 12, 0);
    operational(&mut c);
}

// verifies: MMIC-FLT-11
#[test]
fn communication_loss_mid_motion_aborts_to_safed() {
    let (o, mut c) = start();
    operational(&mut c);
    let raw = c.send("RECONFIGURE", &[0, 1]);
    c.wait_for(T, |t| t.request() == Some(request_of(&raw)) && t.subservice == 3)
        .expect("started");
    assert!(o.sim("cut-cable").starts_with("ok"));
    let done = c.wait_done(&raw, LONG).expect("reconfiguration ends");
    assert_eq!(done.subservice, 8, "aborted");
    let m = wait_mode(&mut c, robot_mode::SAFED);
    assert!([eid::COMM_LOSS_HEARTBEAT, eid::COMM_LOSS_NO_ACK].contains(&cause(&m)));
    assert!(hk(&mut c, 3, pid::FAULT_COUNT) >= 1);
    recover(&o, &mut c, "clear");
}

// verifies: PUS-19-01
#[test]
fn a_disabled_event_action_link_reports_but_does_not_change_mode() {
    let (o, mut c) = start();
    operational(&mut c);
    let d = c.send("EA_DISABLE", &[eid::LOW_BATTERY as i64]);
    assert_eq!(c.wait_done(&d, T).unwrap().subservice, 7);
    c.send("EA_REPORT", &[]);
    let rep = c.wait_for(T, |t| t.service == 19 && t.subservice == 9).unwrap();
    let i = mib::fdir::FAULTS
        .iter()
        .position(|f| f.event == eid::LOW_BATTERY)
        .unwrap();
    assert_eq!(rep.data[2 + 8 * i + 2], 0, "link reported disabled");
    assert!(o.sim("battery-sag 9.0").starts_with("ok"));
    wait_event(&mut c, eid::LOW_BATTERY);
    c.recv_for(Duration::from_millis(300));
    assert_eq!(robot_mode_reported(&mut c), robot_mode::OPERATIONAL);
    assert_ne!(
        hk(&mut c, 3, pid::FAULT_FLAGS),
        0,
        "the fault is still active and visible"
    );
}

// verifies: PUS-12-02
#[test]
fn a_disabled_monitor_does_not_detect_and_definitions_are_reportable() {
    let (o, mut c) = start();
    operational(&mut c);
    c.send("MON_REPORT", &[]);
    let rep = c.wait_for(T, |t| t.service == 12 && t.subservice == 9).unwrap();
    assert_eq!(
        u16::from_be_bytes([rep.data[0], rep.data[1]]) as usize,
        mib::fdir::MONITORS.len()
    );
    for id in [1, 2] {
        let d = c.send("MON_DISABLE", &[id]);
        assert_eq!(c.wait_done(&d, T).unwrap().subservice, 7);
    }
    assert_eq!(hk(&mut c, 3, pid::MON_ENABLED) & 0b11, 0);
    assert!(o.sim("battery-sag 9.0").starts_with("ok"));
    c.recv_for(Duration::from_millis(500));
    assert!(c.log.iter().all(|t| t.event_id() != Some(eid::LOW_BATTERY)));
    assert_eq!(robot_mode_reported(&mut c), robot_mode::OPERATIONAL);
}

// verifies: MMIC-MODE-05
#[test]
fn a_safing_fault_in_standby_is_reported_but_does_not_power_the_servos() {
    let (o, mut c) = start();
    let ping = c.send("PING", &[]); // tells the OBSW where the ground is
    c.wait_done(&ping, T).unwrap();
    assert!(o.sim("cut-cable").starts_with("ok"));
    wait_event(&mut c, eid::COMM_LOSS_HEARTBEAT);
    c.recv_for(Duration::from_millis(300));
    assert_eq!(robot_mode_reported(&mut c), robot_mode::STANDBY);
    assert_ne!(
        hk(&mut c, 3, pid::FAULT_FLAGS),
        0,
        "fault active while the cable is cut"
    );
    let t = set_mode(&mut c, robot_mode::OPERATIONAL);
    assert_eq!(t.failure_code(), Some(F::FAULT_NOT_CLEARED.code()));
    assert!(o.sim("clear cut-cable").starts_with("ok"));
    wait_monitor(&mut c, 12, 0);
    operational(&mut c);
}
