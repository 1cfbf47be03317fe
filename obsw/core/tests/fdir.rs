//! FDIR, in process: every fault of paper Table 8 injected into the simulator (its
//! control commands, never the TC path) in the phase where it can happen, against
//! `Obsw` and `mmic-sim` driven by a mock clock — no sockets, no wall-clock waits, the
//! same simulated seconds on any machine. Checked: the PUS 12 transition report, the
//! PUS 5 event, the resulting mode in HK and in the mode tree, what happened to the
//! running action, and that commanding back to operational works once the fault is
//! cleared. (`tests/tests/fdir_e2e.rs` keeps one real-socket smoke test.)

use arbitrary_int::{u11, u14};
use mib::config::CONTROL_PERIOD_MS;
use mib::events::eid;
use mib::modes::{node, robot_mode};
use mib::params::pid;
use mib::FailureCode as F;
use mib_wire::RequestId;
use mmic_sim::{Sim, SimCommand, SimConfig};
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};
use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId};
use satrs::spacepackets::SpHeader;

/// Simulated milliseconds to wait for a report of a short exchange.
const T: u64 = 30_000;
/// ... and for a motion or a mode transition.
const LONG: u64 = 300_000;

/// A decoded TM packet.
#[derive(Clone, Debug)]
struct Tm {
    service: u8,
    subservice: u8,
    data: Vec<u8>,
}

impl Tm {
    fn parse(raw: &[u8]) -> Tm {
        let tm = PusTmReader::new(raw, mib::config::TIMESTAMP_LEN).expect("the OBSW's TM parses");
        Tm {
            service: tm.service_type_id(),
            subservice: tm.message_subtype_id(),
            data: tm.source_data().to_vec(),
        }
    }
    fn request(&self) -> Option<RequestId> {
        (self.service == 1).then(|| RequestId::of_tc(&self.data).ok()).flatten()
    }
    fn failure_code(&self) -> Option<u16> {
        let off = if self.subservice == 6 { 5 } else { 4 };
        (self.service == 1 && self.subservice.is_multiple_of(2) && self.data.len() >= off + 2)
            .then(|| u16::from_be_bytes([self.data[off], self.data[off + 1]]))
    }
    fn event_id(&self) -> Option<u16> {
        (self.service == 5 && self.subservice <= 4 && self.data.len() >= 2)
            .then(|| u16::from_be_bytes([self.data[0], self.data[1]]))
    }
    fn sid(&self) -> Option<u16> {
        (self.service == 3 && self.subservice == 25).then(|| u16::from_be_bytes([self.data[0], self.data[1]]))
    }
    fn hk(&self, param: u16) -> Option<i64> {
        mib_wire::codec::decode_hk(&self.data).ok()?.get(param)
    }
}

#[derive(Default)]
struct Log(Vec<Tm>);
impl TmSink for Log {
    fn send_tm(&mut self, p: &[u8]) {
        self.0.push(Tm::parse(p));
    }
}

fn request_of(tc: &[u8]) -> RequestId {
    RequestId::of_tc(tc).expect("a TC has a request ID")
}

/// The OBSW of robot 1 and the simulated robot, one control period at a time.
struct Rig {
    obsw: Obsw<RingStore<65536>>,
    sim: Sim,
    now: u64,
    link_rx: Vec<u8>,
    log: Log,
    seq: u16,
    /// Log length when the last TC was sent: its replies come after.
    mark: usize,
}

impl Rig {
    /// As `obsw` starts: robot at rest in state 0, standby, BOOT announced.
    fn start() -> Rig {
        let mut r = Rig {
            obsw: Obsw::new(
                Config {
                    robot: 1,
                    epoch_unix_ms: 1_790_000_000_000,
                },
                RingStore::default(),
            ),
            sim: Sim::new(SimConfig::default()),
            now: 0,
            link_rx: Vec::new(),
            log: Log::default(),
            seq: 0,
            mark: 0,
        };
        r.obsw.boot(0, mib::config::reset_cause::POWER_ON, &mut r.log);
        r
    }

    /// A simulator-control line, as an operator types it.
    fn sim(&mut self, line: &str) {
        let c: SimCommand = line.parse().unwrap_or_else(|e| panic!("{line}: {e:?}"));
        self.sim.apply(c);
    }

    fn tick(&mut self) {
        self.now += CONTROL_PERIOD_MS as u64;
        let sensors = self.sim.sensors_a();
        let out = self.obsw.tick(self.now, &sensors, &self.link_rx, &mut self.log);
        self.link_rx.clear();
        self.sim
            .step(CONTROL_PERIOD_MS, &out.actuators, &out.link_tx, &mut self.link_rx);
    }

    fn send(&mut self, name: &str, args: &[i64]) -> Vec<u8> {
        let def = mib::tc::by_name(name).unwrap_or_else(|| panic!("no TC {name}"));
        let mut app = [0u8; 64];
        let n = mib_wire::codec::encode_args(def, args, &mut app).expect("args");
        self.seq += 1;
        let sp = SpHeader::new_for_unseg_tc(u11::new(self.obsw.apid()), u14::new(self.seq), 0);
        let sec = PusTcSecondaryHeader::new(MessageTypeId::new(def.service, def.subservice), AckFlags::ALL, 0);
        let mut buf = [0u8; 128];
        let len = PusTcCreator::new(sp, sec, &app[..n], CreatorConfig::default())
            .write_to_bytes(&mut buf)
            .unwrap();
        let raw = buf[..len].to_vec();
        self.mark = self.log.0.len();
        self.obsw.handle_tc(self.now, &raw, &mut self.log);
        raw
    }

    /// Runs until a TM after the first `from` matches, at most `max_ms`.
    fn wait_from(&mut self, from: usize, max_ms: u64, hit: impl Fn(&Tm) -> bool) -> Option<Tm> {
        let end = self.now + max_ms;
        let mut checked = from;
        loop {
            if let Some(t) = self.log.0[checked..].iter().find(|t| hit(t)) {
                return Some(t.clone());
            }
            checked = self.log.0.len();
            if self.now >= end {
                return None;
            }
            self.tick();
        }
    }

    /// The first TM since the last TC was sent that matches.
    fn wait_for(&mut self, max_ms: u64, hit: impl Fn(&Tm) -> bool) -> Option<Tm> {
        self.wait_from(self.mark, max_ms, hit)
    }

    /// Any TM so far, or the next, that matches.
    fn wait_any(&mut self, max_ms: u64, hit: impl Fn(&Tm) -> bool) -> Option<Tm> {
        self.wait_from(0, max_ms, hit)
    }

    /// The final verification report of a TC (failure at any stage, or completion).
    fn wait_done(&mut self, tc: &[u8], max_ms: u64) -> Option<Tm> {
        let r = request_of(tc);
        self.wait_any(max_ms, |t| {
            t.request() == Some(r) && matches!(t.subservice, 2 | 4 | 6 | 7 | 8)
        })
    }

    fn run_for(&mut self, ms: u64) {
        let end = self.now + ms;
        while self.now < end {
            self.tick();
        }
    }

    fn position(&self, hit: impl Fn(&Tm) -> bool) -> Option<usize> {
        self.log.0.iter().position(hit)
    }

    fn set_mode(&mut self, mode: u32) -> Tm {
        let raw = self.send("MODE_SET", &[node::ROBOT as i64, mode as i64, 0]);
        self.wait_done(&raw, LONG).expect("mode command finishes")
    }

    fn operational(&mut self) {
        let t = self.set_mode(robot_mode::OPERATIONAL);
        assert_eq!(
            t.subservice,
            7,
            "operational refused: {:?} data {:02x?}",
            t.failure_code(),
            &t.data[6..]
        );
    }

    /// Paper: in safed only hip and arm commands are accepted; the operator contracts
    /// an arm (side 0 = A, 1 = B) before commanding operational again.
    fn contract_in_safed(&mut self, side: i64) {
        let m = self.send("MOVE_ARM", &[side, mib::robot::servo::ARM_CONTRACTED_US as i64]);
        let t = self.wait_done(&m, LONG).unwrap();
        assert_eq!(t.subservice, 7, "arm command accepted in safed");
    }

    /// Current value of a parameter from a one-shot HK report.
    fn hk(&mut self, sid: u16, param: u16) -> i64 {
        self.send("HK_ONE_SHOT", &[sid as i64]);
        self.wait_for(T, |t| t.sid() == Some(sid))
            .expect("HK report")
            .hk(param)
            .expect("parameter in structure")
    }

    fn robot_mode_reported(&mut self) -> u32 {
        self.send("MODE_READ", &[node::ROBOT as i64]);
        let t = self
            .wait_for(T, |t| {
                t.service == 200 && t.subservice == 6 && t.data[..4] == node::ROBOT.to_be_bytes()
            })
            .expect("TM[200,6]");
        u32::from_be_bytes(t.data[4..8].try_into().unwrap())
    }

    /// The MODE_CHANGED event of the robot node into `mode` (so far or next).
    fn wait_mode(&mut self, mode: u32) -> Tm {
        self.wait_any(LONG, |t| {
            t.event_id() == Some(eid::MODE_CHANGED)
                && t.data[2..6] == node::ROBOT.to_be_bytes()
                && t.data[10..14] == mode.to_be_bytes()
        })
        .unwrap_or_else(|| panic!("robot never entered mode {mode}"))
    }

    fn wait_event(&mut self, id: u16) -> Tm {
        self.wait_any(LONG, |t| t.event_id() == Some(id))
            .unwrap_or_else(|| panic!("no event 0x{id:04X}"))
    }

    fn wait_monitor(&mut self, monitor: u16, state: u8) -> Tm {
        self.wait_any(LONG, |t| {
            t.service == 12 && t.subservice == 12 && t.data[..2] == monitor.to_be_bytes() && t.data[12] == state
        })
        .unwrap_or_else(|| panic!("no TM[12,12] for monitor {monitor} state {state}"))
    }

    fn recover(&mut self, clear: &str) {
        self.sim(clear);
        // Give monitors time to see the cause gone (moving average + persistence).
        self.run_for(8000);
        self.operational();
        assert_eq!(self.robot_mode_reported(), robot_mode::OPERATIONAL);
    }
}

/// The cause (fault event) of the robot's last mode change.
fn cause(t: &Tm) -> u16 {
    u16::from_be_bytes([t.data[14], t.data[15]])
}

// verifies: MMIC-FLT-04, PUS-12-01
#[test]
fn low_battery_mid_motion_lets_the_motion_complete_then_standby() {
    let mut c = Rig::start();
    c.operational();
    let raw = c.send("RECONFIGURE", &[0, 1]);
    c.wait_any(T, |t| t.request() == Some(request_of(&raw)) && t.subservice == 3)
        .expect("started");
    c.sim("battery-sag 9.5");
    let mon = c.wait_monitor(1, 1);
    assert!(
        i32::from_be_bytes(mon.data[4..8].try_into().unwrap())
            < i32::from_be_bytes(mon.data[8..12].try_into().unwrap())
    );
    let ev = c.wait_event(eid::LOW_BATTERY);
    assert_eq!(ev.subservice, 4, "high severity");
    let done = c.wait_done(&raw, LONG).expect("reconfiguration finishes");
    assert_eq!(
        done.subservice,
        7,
        "paper: the motion completes first ({:?})",
        done.failure_code()
    );
    let m = c.wait_mode(robot_mode::STANDBY);
    assert_eq!(cause(&m), eid::LOW_BATTERY);
    let mode_change = c
        .position(|t| t.event_id() == Some(eid::MODE_CHANGED) && t.data[10..14] == robot_mode::STANDBY.to_be_bytes())
        .unwrap();
    let completion = c
        .position(|t| t.request() == Some(request_of(&raw)) && t.subservice == 7)
        .unwrap();
    assert!(completion < mode_change, "standby only after the motion completed");
    assert_eq!(c.hk(1, pid::MODE), robot_mode::STANDBY as i64);
    // Still low: operational is refused with the fault named.
    let t = c.set_mode(robot_mode::OPERATIONAL);
    assert_eq!(t.failure_code(), Some(F::FAULT_NOT_CLEARED.code()));
    assert_eq!(u16::from_be_bytes([t.data[6], t.data[7]]), eid::LOW_BATTERY);
    c.recover("clear battery-sag");
}

// verifies: MMIC-FLT-05
#[test]
fn assembly_system_fault_mid_motion_lets_the_motion_complete_then_standby() {
    let mut c = Rig::start();
    c.operational();
    let raw = c.send("RECONFIGURE", &[0, 1]);
    c.wait_any(T, |t| t.request() == Some(request_of(&raw)) && t.subservice == 3)
        .expect("started");
    let f = c.send("ASSEMBLY_FAULT", &[7]);
    assert_eq!(c.wait_done(&f, T).unwrap().subservice, 7);
    assert_eq!(c.wait_event(eid::ASSEMBLY_SYSTEM_FAULT).data[2..4], [0, 7]);
    assert_eq!(
        c.hk(3, pid::PENDING_MODE),
        robot_mode::STANDBY as i64,
        "standby pending while moving"
    );
    assert_eq!(c.wait_done(&raw, LONG).unwrap().subservice, 7);
    assert_eq!(cause(&c.wait_mode(robot_mode::STANDBY)), eid::ASSEMBLY_SYSTEM_FAULT);
    c.operational();
}

// verifies: MMIC-FLT-01
#[test]
fn bolting_failure_goes_to_standby() {
    let mut c = Rig::start();
    c.operational();
    c.sim("fastener-jam");
    let raw = c.send("BOLT_PAIR", &[0, 2]);
    let done = c.wait_done(&raw, LONG).expect("bolt finishes");
    assert_eq!(done.failure_code(), Some(F::BOLT_FAILED.code()));
    assert_eq!(&done.data[6..9], &[0, 2, 3], "failure data: side A, pair 2, 3 attempts");
    let ev = c.wait_event(eid::BOLT_FAILURE);
    assert_eq!(&ev.data[2..5], &[0, 2, 3], "side A, pair 2, 3 attempts");
    let attempts = c
        .log
        .0
        .iter()
        .filter(|t| t.event_id() == Some(eid::BOLT_ATTEMPT_FAILED))
        .count();
    assert_eq!(attempts, 3, "one event per failed attempt");
    assert_eq!(cause(&c.wait_mode(robot_mode::STANDBY)), eid::BOLT_FAILURE);
    assert_eq!(c.hk(3, pid::FAULT_LATCHED) & 1, 1, "bolting-failure bit latched");
    c.recover("clear");
}

// verifies: MMIC-FLT-03, MMIC-CMD-07, PUS-8-01
#[test]
fn initial_state_mismatch_is_refused_and_goes_to_standby() {
    let mut c = Rig::start();
    c.operational();
    c.sim("misplaced-voxel");
    c.run_for(6000);
    let raw = c.send("RECONFIGURE", &[0, 1]);
    let t = c.wait_done(&raw, T).unwrap();
    assert_eq!(
        (t.subservice, t.failure_code()),
        (4, Some(F::INITIAL_STATE_MISMATCH.code()))
    );
    assert_eq!(t.data[6], 0, "ground believed state 0");
    c.wait_event(eid::INITIAL_STATE_MISMATCH);
    // The refusal is reported before FDIR acts on the fault.
    let refusal = c.position(|x| x.request() == Some(request_of(&raw)) && x.subservice == 4);
    let fault = c.position(|x| x.event_id() == Some(eid::INITIAL_STATE_MISMATCH));
    assert!(refusal < fault);
    assert_eq!(cause(&c.wait_mode(robot_mode::STANDBY)), eid::INITIAL_STATE_MISMATCH);
    c.recover("clear misplaced-voxel");
}

// verifies: MMIC-FLT-06
#[test]
fn arm_not_contracted_goes_to_safed_and_holds_arms_and_hip() {
    let mut c = Rig::start();
    c.operational();
    // Xneg -> Xpos: side A extends to Xpos, then arm B must contract onto it.
    let raw = c.send("RECONFIGURE", &[0, 1]);
    c.wait_event(eid::PRIMITIVE_DONE);
    c.sim("stuck-arm b");
    let t = c.wait_done(&raw, LONG).unwrap();
    assert_eq!(t.subservice, 8, "the reconfiguration fails: {:?}", t.failure_code());
    assert_eq!(c.wait_event(eid::ARM_NOT_CONTRACTED).data[2], 1, "side B");
    assert_eq!(cause(&c.wait_mode(robot_mode::SAFED)), eid::ARM_NOT_CONTRACTED);
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
    c.sim("clear stuck-arm");
    c.contract_in_safed(1);
    c.operational();
}

// verifies: MMIC-FLT-08
#[test]
fn operational_overcurrent_mid_motion_aborts_to_safed() {
    let mut c = Rig::start();
    c.operational();
    c.sim("obstacle a");
    let raw = c.send("RECONFIGURE", &[0, 1]);
    let done = c.wait_done(&raw, LONG).expect("reconfiguration ends");
    assert_eq!(done.failure_code(), Some(F::ABORTED_BY_FAULT.code()));
    assert_eq!(
        u16::from_be_bytes([done.data[6], done.data[7]]),
        eid::OPERATIONAL_OVERCURRENT
    );
    let mon = c.wait_monitor(3, 2);
    assert_eq!(u16::from_be_bytes([mon.data[2], mon.data[3]]), pid::I_LOC_A);
    let ev = c.wait_event(eid::OPERATIONAL_OVERCURRENT);
    assert_eq!(
        u16::from_be_bytes([ev.data[2], ev.data[3]]),
        pid::I_LOC_A,
        "event names the channel"
    );
    assert_eq!(cause(&c.wait_mode(robot_mode::SAFED)), eid::OPERATIONAL_OVERCURRENT);
    // The motion stopped with side B's gripper open and its arm half extended: the
    // operator contracts both arms in safed (arm commands are allowed there) so the
    // robot is contracted and gripped, as the paper asks before operational.
    c.sim("clear obstacle");
    c.contract_in_safed(1);
    c.contract_in_safed(0);
    c.operational();
}

// verifies: MMIC-FLT-07
#[test]
fn idle_overcurrent_at_reconfiguration_start_goes_to_safed() {
    let mut c = Rig::start();
    c.operational();
    // Tighten the idle limit below the holding current (PUS 12 modify by TC).
    let m = c.send("MON_MODIFY", &[9, i32::MIN as i64, 20, 1]);
    assert_eq!(c.wait_done(&m, T).unwrap().subservice, 7);
    let raw = c.send("RECONFIGURE", &[0, 1]);
    let t = c.wait_done(&raw, T).unwrap();
    assert_eq!((t.subservice, t.failure_code()), (4, Some(F::ABORTED_BY_FAULT.code())));
    c.wait_monitor(9, 2);
    c.wait_event(eid::IDLE_OVERCURRENT);
    assert_eq!(cause(&c.wait_mode(robot_mode::SAFED)), eid::IDLE_OVERCURRENT);
    let m = c.send("MON_MODIFY", &[9, i32::MIN as i64, 400, 1]);
    assert_eq!(c.wait_done(&m, T).unwrap().subservice, 7);
    c.operational();
}

// verifies: MMIC-FLT-09
#[test]
fn hip_mismatch_when_entering_operational_goes_to_safed() {
    let mut c = Rig::start();
    c.sim("dead-hip-encoder");
    c.run_for(6000);
    let t = c.set_mode(robot_mode::OPERATIONAL);
    assert_eq!(t.failure_code(), Some(F::MODE_CHANGE_FAILED.code()));
    c.wait_monitor(11, 2);
    c.wait_event(eid::HIP_MISMATCH);
    assert_eq!(cause(&c.wait_mode(robot_mode::SAFED)), eid::HIP_MISMATCH);
    c.recover("clear dead-hip-encoder");
}

// verifies: MMIC-FLT-10
#[test]
fn heartbeat_loss_while_idle_goes_to_safed_and_blocks_recovery_until_the_link_is_back() {
    let mut c = Rig::start();
    c.operational();
    c.sim("cut-cable");
    c.wait_monitor(12, 2);
    c.wait_event(eid::COMM_LOSS_HEARTBEAT);
    assert_eq!(cause(&c.wait_mode(robot_mode::SAFED)), eid::COMM_LOSS_HEARTBEAT);
    assert_eq!(c.hk(2, pid::B_LINK_OK), 0);
    let t = c.set_mode(robot_mode::OPERATIONAL);
    assert_eq!(
        t.failure_code(),
        Some(F::FAULT_NOT_CLEARED.code()),
        "a persisting fault is reported, not retried"
    );
    c.sim("clear cut-cable");
    c.wait_monitor(12, 0);
    c.operational();
}

// verifies: MMIC-FLT-10, MMIC-FLT-11
#[test]
fn communication_loss_mid_motion_aborts_to_safed() {
    let mut c = Rig::start();
    c.operational();
    let raw = c.send("RECONFIGURE", &[0, 1]);
    c.wait_any(T, |t| t.request() == Some(request_of(&raw)) && t.subservice == 3)
        .expect("started");
    c.sim("cut-cable");
    let done = c.wait_done(&raw, LONG).expect("reconfiguration ends");
    assert_eq!(done.subservice, 8, "aborted");
    let m = c.wait_mode(robot_mode::SAFED);
    assert!([eid::COMM_LOSS_HEARTBEAT, eid::COMM_LOSS_NO_ACK].contains(&cause(&m)));
    assert!(c.hk(3, pid::FAULT_COUNT) >= 1);
    c.recover("clear");
}

// verifies: PUS-19-01, MMIC-FLT-12
#[test]
fn a_disabled_event_action_link_reports_but_does_not_change_mode() {
    let mut c = Rig::start();
    c.operational();
    let d = c.send("EA_DISABLE", &[eid::LOW_BATTERY as i64]);
    assert_eq!(c.wait_done(&d, T).unwrap().subservice, 7);
    c.send("EA_REPORT", &[]);
    let rep = c.wait_for(T, |t| t.service == 19 && t.subservice == 9).unwrap();
    let i = mib::fdir::FAULTS
        .iter()
        .position(|f| f.event == eid::LOW_BATTERY)
        .unwrap();
    assert_eq!(rep.data[2 + 8 * i + 2], 0, "link reported disabled");
    c.sim("battery-sag 9.0");
    c.wait_event(eid::LOW_BATTERY);
    c.run_for(6000);
    assert_eq!(c.robot_mode_reported(), robot_mode::OPERATIONAL);
    assert_ne!(c.hk(3, pid::FAULT_FLAGS), 0, "the fault is still active and visible");
}

// verifies: PUS-12-01
#[test]
fn a_disabled_monitor_does_not_detect_and_definitions_are_reportable() {
    let mut c = Rig::start();
    c.operational();
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
    assert_eq!(c.hk(3, pid::MON_ENABLED) & 0b11, 0);
    c.sim("battery-sag 9.0");
    c.run_for(10_000);
    assert!(c.log.0.iter().all(|t| t.event_id() != Some(eid::LOW_BATTERY)));
    assert_eq!(c.robot_mode_reported(), robot_mode::OPERATIONAL);
}

// verifies: MMIC-FLT-10, MMIC-MODE-05
#[test]
fn a_safing_fault_in_standby_is_reported_but_does_not_power_the_servos() {
    let mut c = Rig::start();
    c.sim("cut-cable");
    c.wait_event(eid::COMM_LOSS_HEARTBEAT);
    c.run_for(6000);
    assert_eq!(c.robot_mode_reported(), robot_mode::STANDBY);
    assert_ne!(c.hk(3, pid::FAULT_FLAGS), 0, "fault active while the cable is cut");
    let t = c.set_mode(robot_mode::OPERATIONAL);
    assert_eq!(t.failure_code(), Some(F::FAULT_NOT_CLEARED.code()));
    c.sim("clear cut-cable");
    c.wait_monitor(12, 0);
    c.operational();
}

// verifies: MMIC-MOT-07
#[test]
fn turning_the_hip_with_both_grippers_holding_is_refused_before_it_stalls() {
    let mut c = Rig::start();
    c.operational();
    let raw = c.send("ROTATE_HIP", &[4500]);
    let t = c.wait_done(&raw, T).unwrap();
    assert_eq!(
        (t.subservice, t.failure_code()),
        (4, Some(F::BOTH_SIDES_GRIPPED.code()))
    );
    let closed = mib::robot::servo::GRIP_CLOSED_US as i64;
    let pwm = |i: usize| u16::from_be_bytes([t.data[i], t.data[i + 1]]) as i64;
    assert!(
        (pwm(6) - closed).abs() <= 60 && (pwm(8) - closed).abs() <= 60,
        "{:?}",
        &t.data
    );
    // With gripper A open the hip turns.
    let g = c.send("MOVE_GRIPPER", &[0, mib::robot::servo::GRIP_OPEN_US as i64]);
    assert_eq!(c.wait_done(&g, LONG).unwrap().subservice, 7);
    let raw = c.send("ROTATE_HIP", &[4500]);
    assert_eq!(c.wait_done(&raw, LONG).unwrap().subservice, 7);
}

// verifies: MMIC-MODE-02, PUS-200-01
#[test]
fn a_regulator_that_never_comes_up_times_the_mode_transition_out() {
    let mut c = Rig::start();
    c.sim("battery-sag 5.0");
    c.run_for(6000);
    let t = c.set_mode(robot_mode::SAFED);
    assert_eq!(t.failure_code(), Some(F::MODE_CHANGE_FAILED.code()), "{:?}", t.data);
    let reason = u16::from_be_bytes([t.data[14], t.data[15]]);
    assert_eq!(reason, F::TIMEOUT.code(), "reason: the transition timed out");
    assert_eq!(c.robot_mode_reported(), robot_mode::STANDBY, "back to standby");
}
