//! The whole TC path in-process against the simulator, for the review package's
//! structural coverage (the end-to-end tests exercise the same code in the `obsw`
//! process, whose coverage profile is lost when the harness kills it): every MIB
//! telecommand with its arguments at the minimum, the middle and the maximum, in
//! standby, operational and safed, then every simulator fault while operational.
//! Properties: every TC gets exactly one acceptance verdict, the OBSW keeps answering,
//! and each fault takes the robot out of operational with its Table 8 event.

use arbitrary_int::{u11, u14};
use mib::events::eid;
use mib::modes::{node, robot_mode};
use mmic_sim::{Fault, Sim, SimConfig};
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};
use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId};
use satrs::spacepackets::SpHeader;

#[derive(Default)]
struct Sink(Vec<Vec<u8>>);
impl TmSink for Sink {
    fn send_tm(&mut self, p: &[u8]) {
        self.0.push(p.to_vec());
    }
}

struct Rig {
    o: Box<Obsw<RingStore<16384>>>,
    sim: Sim,
    sink: Sink,
    link: Vec<u8>,
    now: u64,
    seq: u16,
    /// Every event ID reported live, in order.
    events: Vec<u16>,
}

fn tm_seq(p: &[u8]) -> u16 {
    mib::headers::SeqCount::new(u16::from_be_bytes([p[2], p[3]])).get()
}

impl Rig {
    fn new() -> Rig {
        let mut r = Rig {
            o: Box::new(Obsw::new(
                Config {
                    robot: 1,
                    epoch_unix_ms: 1_790_000_000_000,
                },
                RingStore::default(),
            )),
            sim: Sim::new(SimConfig::default()),
            sink: Sink::default(),
            link: Vec::new(),
            now: 0,
            seq: 0,
            events: Vec::new(),
        };
        r.o.boot(0, mib::config::reset_cause::POWER_ON, &mut r.sink);
        r
    }

    fn raw_tc(&mut self, svc: u8, sub: u8, app: &[u8]) -> Vec<u8> {
        self.seq = mib::headers::SeqCount::new(self.seq).next().get();
        let sp = SpHeader::new_for_unseg_tc(u11::new(0x101), u14::new(self.seq), 0);
        let sec = PusTcSecondaryHeader::new(MessageTypeId::new(svc, sub), AckFlags::ALL, 0);
        let mut buf = vec![0u8; 1100];
        let n = PusTcCreator::new(sp, sec, app, CreatorConfig::default())
            .write_to_bytes(&mut buf)
            .expect("TC fits");
        buf.truncate(n);
        buf
    }

    /// Sends a TC; returns the number of distinct live acceptance verdicts it got.
    fn send(&mut self, def: &mib::tc::TcDef, args: &[i64], extra: &[u8]) -> usize {
        let mut app = vec![0u8; 600];
        let n = mib_wire::codec::encode_args(def, args, &mut app).expect("arguments in range");
        app.truncate(n);
        app.extend_from_slice(extra);
        let raw = self.raw_tc(def.service, def.subservice, &app);
        let before = self.sink.0.iter().map(|p| tm_seq(p)).max();
        self.sink.0.clear();
        self.o.handle_tc(self.now, &raw, &mut self.sink);
        let req = &raw[0..4];
        let mut seqs: Vec<u16> = self
            .sink
            .0
            .iter()
            .filter(|p| p.len() > 24 && p[7] == 1 && (p[8] == 1 || p[8] == 2) && &p[20..24] == req)
            .map(|p| tm_seq(p))
            .filter(|s| before.is_none_or(|b| *s > b || self.sink.0.len() > 1000))
            .collect();
        seqs.sort_unstable();
        seqs.dedup();
        seqs.len()
    }

    /// Sends raw TC bytes; returns the subtypes of the PUS 1 reports it got at once.
    fn send_raw(&mut self, raw: &[u8]) -> Vec<u8> {
        self.sink.0.clear();
        self.o.handle_tc(self.now, raw, &mut self.sink);
        self.sink
            .0
            .iter()
            .filter(|p| p.len() > 24 && p[7] == 1 && p[20..24] == raw[0..4])
            .map(|p| p[8])
            .collect()
    }

    /// TM[service, subtype] packets seen since the sink was last cleared.
    fn count(&self, service: u8, subtype: u8) -> usize {
        self.sink
            .0
            .iter()
            .filter(|p| p.len() > 8 && p[7] == service && p[8] == subtype)
            .count()
    }

    fn by_name(&mut self, name: &str, args: &[i64]) -> usize {
        let def = mib::tc::by_name(name).expect("MIB TC");
        self.send(def, args, &[])
    }

    fn run(&mut self, ms: u64) {
        for _ in 0..ms / 10 {
            self.now += 10;
            let s = self.sim.sensors_a();
            let from = self.sink.0.len();
            let out = self.o.tick(self.now, &s, &self.link, &mut self.sink);
            let new: Vec<u16> = self.sink.0[from..]
                .iter()
                .filter(|p| p.len() > 22 && p[7] == 5 && (1..=4).contains(&p[8]))
                .map(|p| u16::from_be_bytes([p[20], p[21]]))
                .collect();
            self.events.extend(new);
            self.link.clear();
            self.sim.step(10, &out.actuators, &out.link_tx, &mut self.link);
            if self.sink.0.len() > 4000 {
                self.sink.0.drain(..3000);
            }
        }
    }

    fn mode(&mut self, mode: u32) {
        assert_eq!(self.by_name("MODE_SET", &[node::ROBOT as i64, mode as i64, 0]), 1);
        self.run(15_000);
    }

    fn events_since(&self, mark: usize) -> Vec<u16> {
        self.events[mark..].to_vec()
    }
}

/// Argument sets for a TC: every argument at its minimum, middle and maximum.
fn arg_sets(def: &mib::tc::TcDef) -> Vec<Vec<i64>> {
    let pick = |f: fn(&mib::tc::ArgDef) -> i64| def.args.iter().map(f).collect::<Vec<i64>>();
    vec![pick(|a| a.min), pick(|a| a.min + (a.max - a.min) / 2), pick(|a| a.max)]
}

fn every_tc(r: &mut Rig, settle_ms: u64) {
    for def in mib::tc::TCS {
        // Mode changes are driven by the test itself; a robot-node MODE_SET is covered there.
        if def.name == "MODE_SET" {
            continue;
        }
        for args in arg_sets(def) {
            let extra: Vec<u8> = if def.variable {
                // an embedded ping for schedule insertions
                r.raw_tc(17, 1, &[])
            } else {
                Vec::new()
            };
            let n = r.send(def, &args, &extra);
            assert_eq!(n, 1, "{} {:?}: {} acceptance verdicts", def.name, args, n);
            r.run(if def.long_running { settle_ms } else { 50 });
        }
    }
    assert_eq!(r.by_name("PING", &[]), 1, "still answers a ping");
}

// verifies: PUS-1-01, DD-ROBUST-01
#[test]
fn every_telecommand_at_its_argument_limits_in_every_mode_gets_one_verdict() {
    let mut r = Rig::new();
    r.run(1_000);
    every_tc(&mut r, 200);
    r.mode(robot_mode::OPERATIONAL);
    assert_eq!(r.o.mode(), robot_mode::OPERATIONAL);
    every_tc(&mut r, 8_000);
    r.mode(robot_mode::SAFED);
    assert_eq!(r.o.mode(), robot_mode::SAFED);
    every_tc(&mut r, 2_000);
    r.mode(robot_mode::STANDBY);
    assert_eq!(r.o.mode(), robot_mode::STANDBY);
    assert_eq!(r.by_name("STORE_DOWNLINK_TIME", &[0, 0, 65535, 4_294_967_295]), 1);
}

/// BOLT_PAIR side A, pair 2 (as the end-to-end bolting-failure test).
const BOLT_ARGS: [i64; 2] = [0, 2];

// verifies: PUS-19-01, MMIC-FLT-12
#[test]
fn every_simulated_fault_takes_the_robot_out_of_operational_with_its_event() {
    use mib::robot::Side;
    let cases: [(Fault, &[u16], &str); 5] = [
        (Fault::BatterySag { volts: 9.0 }, &[eid::LOW_BATTERY], "RECONFIGURE"),
        (Fault::Obstacle(Side::A), &[eid::OPERATIONAL_OVERCURRENT], "RECONFIGURE"),
        (
            Fault::CutCable,
            &[eid::COMM_LOSS_HEARTBEAT, eid::COMM_LOSS_NO_ACK],
            "RECONFIGURE",
        ),
        (Fault::MisplacedVoxel, &[eid::INITIAL_STATE_MISMATCH], "RECONFIGURE"),
        (Fault::FastenerJam, &[eid::BOLT_FAILURE], "BOLT_PAIR"),
    ];
    for (fault, events, action) in cases {
        let mut r = Rig::new();
        r.run(1_000);
        r.mode(robot_mode::OPERATIONAL);
        assert_eq!(r.o.mode(), robot_mode::OPERATIONAL, "{fault:?}: operational first");
        r.sim.inject(fault);
        let mark = r.events.len();
        let def = mib::tc::by_name(action).expect("MIB TC");
        // the robot starts matched on Xneg: reconfigure to Xpos, or bolt a pair
        let state = |n: &str| {
            mib::robot::state_by_name(n)
                .map(|s| i64::from(s.id))
                .expect("MIB state")
        };
        let args: Vec<i64> = if action == "RECONFIGURE" {
            vec![state("Xneg"), state("Xpos")]
        } else {
            BOLT_ARGS.to_vec()
        };
        assert_eq!(r.send(def, &args, &[]), 1);
        r.run(60_000);
        let ev = r.events_since(mark);
        assert!(
            events.iter().any(|e| ev.contains(e)),
            "{fault:?}: expected one of {events:?}, got {ev:?}"
        );
        assert_ne!(r.o.mode(), robot_mode::OPERATIONAL, "{fault:?}: left operational");
    }
}

/// CDS short time code of on-board time `ms` (the rig's epoch is `Config::epoch_unix_ms`).
fn cds(unix_ms: u64) -> [u8; 7] {
    let days = (unix_ms / 86_400_000 + 4383) as u16;
    let ms = (unix_ms % 86_400_000) as u32;
    let mut out = [0x40, 0, 0, 0, 0, 0, 0];
    out[1..3].copy_from_slice(&days.to_be_bytes());
    out[3..7].copy_from_slice(&ms.to_be_bytes());
    out
}

const EPOCH: u64 = 1_790_000_000_000;

// verifies: PUS-11-01, PUS-11-02
#[test]
fn a_scheduled_ping_is_released_at_its_time_and_a_past_time_is_refused() {
    let mut r = Rig::new();
    r.run(1_000);
    let inner = r.raw_tc(17, 1, &[]);
    let mut app = vec![1u8];
    app.extend_from_slice(&cds(EPOCH + r.now + 1_500));
    app.extend_from_slice(&inner);
    let ins = r.raw_tc(11, 4, &app);
    assert_eq!(r.send_raw(&ins), vec![1, 3, 7], "accepted, started, completed");
    r.sink.0.clear();
    r.run(1_000);
    assert_eq!(r.count(17, 2), 0, "not before its time");
    r.run(1_000);
    assert_eq!(r.count(17, 2), 1, "released once");
    let mut late = vec![1u8];
    late.extend_from_slice(&cds(EPOCH + r.now - 500));
    late.extend_from_slice(&inner);
    let ins = r.raw_tc(11, 4, &late);
    let v = r.send_raw(&ins);
    assert!(
        v.contains(&2) || v.contains(&8),
        "a past release time is refused: {v:?}"
    );
}

// verifies: DD-ROBUST-02, GND-01
#[test]
fn a_duplicate_ping_is_acknowledged_again_but_answered_once() {
    let mut r = Rig::new();
    r.run(500);
    let ping = r.raw_tc(17, 1, &[]);
    let first = r.send_raw(&ping);
    let pongs = r.count(17, 2);
    let again = r.send_raw(&ping);
    let pongs_again = r.count(17, 2);
    assert_eq!(first.iter().filter(|s| **s == 1).count(), 1);
    assert_eq!(again.iter().filter(|s| **s == 1).count(), 1, "acknowledged again");
    assert_eq!((pongs, pongs_again), (1, 0), "executed once");
}

// verifies: MMIC-CMD-02, MMIC-CMD-03, MMIC-FLT-02
#[test]
fn a_pair_bolts_unbolts_and_a_jammed_pair_fails_to_unbolt_with_its_events() {
    let mut r = Rig::new();
    r.run(1_000);
    r.mode(robot_mode::OPERATIONAL);
    let mark = r.events.len();
    assert_eq!(r.by_name("BOLT_PAIR", &[0, 1]), 1);
    r.run(60_000);
    assert_eq!(r.by_name("UNBOLT_PAIR", &[0, 1]), 1);
    r.run(60_000);
    let ev = r.events_since(mark);
    assert!(ev.contains(&eid::BOLT_PAIR_DONE), "{ev:?}");
    assert!(ev.contains(&eid::UNBOLT_PAIR_DONE), "{ev:?}");
    assert_eq!(r.by_name("BOLT_PAIR", &[0, 3]), 1);
    r.run(60_000);
    r.sim.inject(Fault::FastenerJam);
    let mark = r.events.len();
    assert_eq!(r.by_name("UNBOLT_PAIR", &[0, 3]), 1);
    r.run(90_000);
    let ev = r.events_since(mark);
    assert!(ev.contains(&eid::UNBOLT_FAILURE), "{ev:?}");
    assert_eq!(r.o.mode(), robot_mode::STANDBY);
}

// verifies: MMIC-FLT-09
#[test]
fn entering_operational_with_a_dead_hip_encoder_fails_the_mode_command() {
    let mut r = Rig::new();
    r.run(1_000);
    r.sim.inject(Fault::DeadHipEncoder);
    let mark = r.events.len();
    assert_eq!(
        r.by_name("MODE_SET", &[node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0]),
        1
    );
    r.run(15_000);
    let ev = r.events_since(mark);
    assert!(ev.contains(&eid::HIP_MISMATCH), "{ev:?}");
    assert_ne!(r.o.mode(), robot_mode::OPERATIONAL);
}

// verifies: DD-BOOT-01
#[test]
fn boot_reports_the_cause_and_a_previous_panic_and_the_state_is_computed() {
    let mut r = Rig::new();
    assert_eq!(r.o.apid(), 0x101);
    let before = r.events.len();
    r.sink.0.clear();
    r.o.report_previous_panic(0, mib::config::reset_cause::PANIC, 42, 0x231D_C4FE, &mut r.sink);
    let panics = r
        .sink
        .0
        .iter()
        .filter(|p| p.len() > 22 && p[7] == 5 && u16::from_be_bytes([p[20], p[21]]) == eid::PREVIOUS_PANIC)
        .count();
    assert_eq!(panics, 1);
    assert_eq!(r.events.len(), before);
    r.run(2_000);
    assert!(r.o.next_deadline() >= r.now, "the next deadline is not in the past");
    let xneg = mib::robot::state_by_name("Xneg").map(|s| s.id).expect("MIB state");
    assert_eq!(r.o.computed_state(), xneg, "the simulator starts matched on Xneg");
}

/// Sends a TC by MIB name; returns its PUS 1 report subtypes.
fn verdicts(r: &mut Rig, name: &str, args: &[i64]) -> Vec<u8> {
    let def = mib::tc::by_name(name).expect("MIB TC");
    let mut app = vec![0u8; 64];
    let n = mib_wire::codec::encode_args(def, args, &mut app).expect("arguments in range");
    let raw = r.raw_tc(def.service, def.subservice, &app[..n]);
    r.send_raw(&raw)
}

// verifies: PUS-5-02, PUS-19-01, PUS-20-01, PUS-12-02
#[test]
fn service_requests_with_real_identifiers_complete() {
    let mut r = Rig::new();
    r.run(500);
    let t = &mib::tunables::TUNABLES[0];
    let mon = i64::from(mib::fdir::MONITORS[0].id);
    let ev = i64::from(eid::BOLT_ATTEMPT_FAILED);
    let fault = i64::from(eid::BOLT_FAILURE);
    let requests: [(&str, Vec<i64>); 10] = [
        ("EVENT_DISABLE", vec![ev]),
        ("EVENT_REPORT_DISABLED", vec![]),
        ("EVENT_ENABLE", vec![ev]),
        ("EA_DISABLE", vec![fault]),
        ("EA_ENABLE", vec![fault]),
        ("EA_REPORT", vec![]),
        ("PARAM_REPORT", vec![i64::from(t.id)]),
        ("PARAM_SET", vec![i64::from(t.id), i64::from(t.default)]),
        ("MON_DISABLE", vec![mon]),
        ("MON_ENABLE", vec![mon]),
    ];
    for (name, args) in requests {
        let v = verdicts(&mut r, name, &args);
        assert!(v.contains(&1) && v.contains(&7), "{name} {args:?}: {v:?}");
        r.run(50);
    }
}

// verifies: MMIC-CMD-02, MMIC-CMD-04
#[test]
fn bolt_face_and_gripper_moves_run_to_completion_when_idle() {
    let mut r = Rig::new();
    r.run(1_000);
    r.mode(robot_mode::OPERATIONAL);
    let bolt = verdicts(&mut r, "BOLT_FACE", &[0, 1]);
    assert!(bolt.contains(&1), "{bolt:?}");
    r.run(90_000);
    let g = mib::tc::by_name("MOVE_GRIPPER").expect("MIB TC");
    let args: Vec<i64> = g.args.iter().map(|a| a.min + (a.max - a.min) / 2).collect();
    let grip = verdicts(&mut r, "MOVE_GRIPPER", &args);
    assert!(grip.contains(&1), "{grip:?}");
    r.run(20_000);
    assert_eq!(r.o.mode(), robot_mode::OPERATIONAL, "no fault on the way");
}

// verifies: MMIC-FLT-10, MMIC-FLT-06
#[test]
fn entering_operational_without_board_b_or_with_a_stuck_arm_fails_safe() {
    let mut r = Rig::new();
    r.run(1_000);
    r.sim.inject(Fault::CutCable);
    r.run(1_000);
    let v = verdicts(
        &mut r,
        "MODE_SET",
        &[node::ROBOT as i64, robot_mode::OPERATIONAL as i64, 0],
    );
    r.run(20_000);
    assert!(v.contains(&1) || v.contains(&2), "{v:?}");
    assert_ne!(r.o.mode(), robot_mode::OPERATIONAL, "never operational without board B");

    let mut r = Rig::new();
    r.run(1_000);
    r.mode(robot_mode::OPERATIONAL);
    // Xneg -> Xpos: side A extends to Xpos, then arm B must contract onto it; it sticks
    // after the first primitive.
    let mark = r.events.len();
    assert_eq!(r.by_name("RECONFIGURE", &[0, 1]), 1);
    for _ in 0..600 {
        if r.events_since(mark).contains(&eid::PRIMITIVE_DONE) {
            break;
        }
        r.run(100);
    }
    assert!(r.events_since(mark).contains(&eid::PRIMITIVE_DONE));
    r.sim.inject(Fault::StuckArm(mib::robot::Side::B));
    r.run(60_000);
    let ev = r.events_since(mark);
    assert!(
        ev.contains(&eid::ARM_NOT_CONTRACTED) || ev.contains(&eid::OPERATIONAL_OVERCURRENT),
        "{ev:?}"
    );
    assert_ne!(r.o.mode(), robot_mode::OPERATIONAL);
}
