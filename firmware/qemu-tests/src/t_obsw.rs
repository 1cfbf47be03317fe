//! obsw-core on the target: the PUS service handlers on a recorded TC stream, through
//! the same uplink deframer and downlink queue board A uses, and the FDIR chain for a
//! low battery (PUS 12 monitor → event → PUS 19 action), checked against the MIB.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::config;
use fw_core::cycle::GroundSink;
use fw_core::link::{self, BarePackets, ByteQueue, Counters, TcChannel};
use mib::events::eid;
use mib::params::pid;
use mib::FailureCode;
use mmic_domain::board_b::{BoardB, BoardBOut};
use mmic_domain::{ActuatorsA, SensorsA, SensorsB};
use mmic_stream::Deframer;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::PusPacket;

pub const TESTS: &[Test] = tests![
    obsw_recorded_tc_stream_gives_the_expected_tm_sequence,
    obsw_low_battery_persists_half_a_second_then_recovers,
    obsw_mode_set_operational_powers_both_sides_and_homes,
    obsw_board_b_silence_is_comm_loss_and_safes_the_robot,
    obsw_standby_with_board_b_never_heard_raises_no_low_battery,
    obsw_tick_and_tc_fit_the_10_ms_control_period,
    obsw_store_returns_every_packet_the_full_downlink_dropped,
    obsw_without_update_refuses_every_update_tc_unavailable_counted_and_evented,
];

/// COBS-framed TCs for robot 1 (APID 0x101) as the ground sends them on the serial
/// link, recorded from an encoder independent of sat-rs (hex of each packet given).
#[rustfmt::skip]
const RECORDED_UPLINK: &[u8] = &[
    // PING (17,1) seq 0: 1901c00000062f11010000ce54
    0x00, 0x04, 0x19, 0x01, 0xC0, 0x01, 0x05, 0x06, 0x2F, 0x11, 0x01, 0x01, 0x03, 0xCE, 0x54, 0x00,
    // HK_ONE_SHOT (3,27) sid 1 seq 1: 1901c00100082f031b000000011d6f
    0x00, 0x05, 0x19, 0x01, 0xC0, 0x01, 0x05, 0x08, 0x2F, 0x03, 0x1B, 0x01, 0x01, 0x04, 0x01, 0x1D, 0x6F, 0x00,
    // HOME (8,1) fn 4 seq 2, refused in standby: 1901c00200082f0801000000047d53
    0x00, 0x05, 0x19, 0x01, 0xC0, 0x02, 0x05, 0x08, 0x2F, 0x08, 0x01, 0x01, 0x01, 0x04, 0x04, 0x7D, 0x53, 0x00,
    // MODE_READ (200,3) node 1 seq 3: 1901c003000a2fc8030000000000016e3f
    0x00, 0x05, 0x19, 0x01, 0xC0, 0x03, 0x05, 0x0A, 0x2F, 0xC8, 0x03, 0x01, 0x01, 0x01, 0x01, 0x04, 0x01, 0x6E, 0x3F, 0x00,
    // PARAM_REPORT (20,1) tunable 1 seq 4: 1901c00400082f1401000000014f2e
    0x00, 0x05, 0x19, 0x01, 0xC0, 0x04, 0x05, 0x08, 0x2F, 0x14, 0x01, 0x01, 0x01, 0x04, 0x01, 0x4F, 0x2E, 0x00,
    // the same PARAM_REPORT again (ground retry): 1901c00400082f1401000000014f2e
    0x00, 0x05, 0x19, 0x01, 0xC0, 0x04, 0x05, 0x08, 0x2F, 0x14, 0x01, 0x01, 0x01, 0x04, 0x01, 0x4F, 0x2E, 0x00,
    // PING seq 5 with a corrupted CRC: 1901c00500062f110100003805
    0x00, 0x05, 0x19, 0x01, 0xC0, 0x05, 0x05, 0x06, 0x2F, 0x11, 0x01, 0x01, 0x03, 0x38, 0x05, 0x00,
    // service 99 seq 6: 1901c00600062f63010000e182
    0x00, 0x05, 0x19, 0x01, 0xC0, 0x06, 0x05, 0x06, 0x2F, 0x63, 0x01, 0x01, 0x03, 0xE1, 0x82, 0x00,
];

/// Received CRC of the corrupted PING and the CRC-16/CCITT-FALSE of its content.
const BAD_CRC_RECEIVED: u16 = 0x3805;
const BAD_CRC_COMPUTED: u16 = 0x86EA;

const ROBOT: u8 = 1;

/// One TM packet as the ground sees it: type, subtype and source data.
struct Tm {
    svc: u8,
    sub: u8,
    data: heapless::Vec<u8, 128>,
}

fn parse_tm(raw: &[u8]) -> Option<Tm> {
    let r = PusTmReader::new(raw, mib::config::TIMESTAMP_LEN).ok()?;
    let mut data = heapless::Vec::new();
    let src = r.user_data();
    data.extend_from_slice(&src[..src.len().min(128)]).ok()?;
    Some(Tm {
        svc: PusPacket::service_type_id(&r),
        sub: PusPacket::message_subtype_id(&r),
        data,
    })
}

fn obsw_recorded_tc_stream_gives_the_expected_tm_sequence() -> TestResult {
    static TCS: TcChannel = TcChannel::new();
    static TM: ByteQueue<8192> = ByteQueue::new();
    static UP: Counters = Counters::new();
    static DOWN: Counters = Counters::new();
    let mut obsw = Obsw::new(
        Config {
            robot: ROBOT,
            epoch_unix_ms: 0,
        },
        RingStore::<4096>::default(),
    );
    let mut sink = GroundSink {
        link: &mut BarePackets,
        queue: &TM,
        counters: &DOWN,
    };
    obsw.boot(0, 1, &mut sink);

    let mut deframer: Deframer<{ config::GROUND_RX_BUF }> = Deframer::new();
    let mut now = 100;
    let mut recorded: heapless::Vec<heapless::Vec<u8, 32>, 8> = heapless::Vec::new();
    // Arrives in 13-byte pieces, as a UART would deliver it.
    for chunk in RECORDED_UPLINK.chunks(13) {
        link::uplink_bytes(&mut deframer, chunk, &TCS, &UP);
        while let Ok(tc) = TCS.try_receive() {
            let _ = recorded.push(ok!(heapless::Vec::from_slice(&tc[..])));
            obsw.handle_tc(now, &tc, &mut sink);
            now += 10;
        }
    }
    check_eq!(UP.get().delivered, 8);
    check_eq!(UP.get().frame_errors, 0);
    check_eq!(DOWN.get().overflow, 0);

    let mut bytes = [0u8; 8192];
    let n = link::drain(&TM, &mut bytes);
    let mut d: Deframer<{ config::MAX_PACKET_LEN }> = Deframer::new();
    let mut tms: heapless::Vec<Tm, 48> = heapless::Vec::new();
    for &b in &bytes[..n] {
        if let Some(r) = d.push(b) {
            let tm = ok!(parse_tm(ok!(r)));
            check!(tms.push(tm).is_ok(), "more than 48 TM packets");
        }
    }
    let kinds: heapless::Vec<(u8, u8), 48> = tms.iter().map(|t| (t.svc, t.sub)).collect();
    let expect: &[(u8, u8)] = &[
        (5, 1), // BOOT
        (1, 1),
        (17, 2),
        (1, 3),
        (1, 7), // PING
        (1, 1),
        (3, 25),
        (1, 3),
        (1, 7), // HK one shot
        (1, 1),
        (1, 4),
        (5, 2), // HOME refused at start in standby, TC_REJECTED event
        (1, 1),
        (200, 6),
        (1, 3),
        (1, 7), // MODE_READ
        (1, 1),
        (20, 2),
        (1, 3),
        (1, 7), // PARAM_REPORT
        (1, 1),
        (1, 7), // the retry: acknowledged, completion repeated, not executed
        (1, 2),
        (5, 2), // bad CRC
        (1, 2),
        (5, 2), // unknown service
    ];
    check_eq!(&kinds[..], expect);

    // Every verification report names its TC: request ID = the TC's first four bytes.
    let tc_of = |i: usize| -> &[u8] { &recorded[i][..4] };
    let ver: heapless::Vec<&Tm, 24> = tms.iter().filter(|t| t.svc == 1).collect();
    let owners = [0, 0, 0, 1, 1, 1, 2, 2, 3, 3, 3, 4, 4, 4, 5, 5, 6, 7];
    check_eq!(ver.len(), owners.len());
    for (v, &o) in ver.iter().zip(owners.iter()) {
        check_eq!(&v.data[..4], tc_of(o), "report {}.{} of TC {}", v.svc, v.sub, o);
    }
    // BOOT carries the reset cause given at boot.
    let boot = ok!(mib_wire::codec::decode_event(&tms[0].data));
    check_eq!((boot.def.id, boot.param("reset_cause")), (eid::BOOT, Some(1)));
    // HK ROBOT_STATUS: mode standby, no state target.
    let hk = ok!(mib_wire::codec::decode_hk(&tms[6].data));
    check_eq!(hk.get(pid::MODE), Some(0));
    check_eq!(hk.get(pid::TARGET_STATE), Some(mib::robot::STATE_UNKNOWN as i64));
    // HOME refused: NOT_ALLOWED_IN_MODE with the mode (standby) as data.
    let f = &tms[10].data;
    check_eq!(&f[4..], &[0x00, FailureCode::NOT_ALLOWED_IN_MODE.code() as u8, 0][..]);
    let ev = ok!(mib_wire::codec::decode_event(&tms[11].data));
    check_eq!(
        (ev.param("service"), ev.param("subservice"), ev.param("code")),
        (Some(8), Some(1), Some(FailureCode::NOT_ALLOWED_IN_MODE.code() as i64))
    );
    // MODE_REPLY: robot node 1, standby, idle.
    check_eq!(&tms[13].data[..], &[0, 0, 0, 1, 0, 0, 0, 0, 0, 0][..]);
    // PARAM_VALUE: tunable 1 (bolt push threshold) = its MIB default.
    let t = ok!(mib::tunables::by_id(1));
    let mut want = [0u8; 6];
    want[..2].copy_from_slice(&1u16.to_be_bytes());
    want[2..].copy_from_slice(&t.default.to_be_bytes());
    check_eq!(&tms[17].data[..], &want[..]);
    // Bad CRC: code, received CRC, computed CRC.
    let mut crc = [0u8; 6];
    crc[..2].copy_from_slice(&FailureCode::CRC_MISMATCH.code().to_be_bytes());
    crc[2..4].copy_from_slice(&BAD_CRC_RECEIVED.to_be_bytes());
    crc[4..].copy_from_slice(&BAD_CRC_COMPUTED.to_be_bytes());
    check_eq!(&tms[22].data[4..], &crc[..]);
    // Unknown service 99.
    check_eq!(
        &tms[24].data[4..],
        &[0x00, FailureCode::UNKNOWN_SERVICE.code() as u8, 99][..]
    );
    check_eq!(obsw.param::<{ pid::TC_DUPLICATE }>(), 1);
    // Refused at acceptance: bad CRC and unknown service; HOME was accepted and failed
    // at its start.
    check_eq!(obsw.param::<{ pid::TC_REJECTED }>(), 2);
    check_eq!(obsw.param::<{ pid::TC_ACCEPTED }>(), 5);
    Ok(())
}

/// Keeps the monitoring transitions and events of interest.
#[derive(Default)]
struct FdirLog {
    now: u64,
    /// (time, monitor state) of TM[12,12] for monitor 1.
    mon: heapless::Vec<(u64, u8), 8>,
    /// (time, event ID, decoded args) of fault-related events.
    events: heapless::Vec<(u64, u16, [i64; 3]), 16>,
    other: u32,
    bad: u32,
}

impl TmSink for FdirLog {
    fn send_tm(&mut self, packet: &[u8]) {
        let Some(tm) = parse_tm(packet) else {
            self.bad += 1;
            return;
        };
        match (tm.svc, tm.sub) {
            (12, 12) if tm.data.len() == 13 && tm.data[..2] == 1u16.to_be_bytes() => {
                let _ = self.mon.push((self.now, tm.data[12]));
            }
            (5, _) => {
                if let Ok(ev) = mib_wire::codec::decode_event(&tm.data) {
                    if ev.def.id == eid::LOW_BATTERY || ev.def.id == eid::FAULT_CLEARED {
                        let mut a = [0i64; 3];
                        for (slot, (_, v)) in a.iter_mut().zip(ev.params()) {
                            *slot = v;
                        }
                        let _ = self.events.push((self.now, ev.def.id, a));
                    }
                }
            }
            _ => self.other += 1,
        }
    }
}

/// Board A's OBSW and board B's firmware logic, wired back to back (A's link bytes are
/// B's input and the other way round), stepped every control period.
struct Robot {
    a: Obsw<RingStore<4096>>,
    b: BoardB,
    b_out: BoardBOut,
    b_to_a: heapless::Vec<u8, 256>,
}

impl Robot {
    fn new() -> Self {
        Robot {
            a: Obsw::new(
                Config {
                    robot: ROBOT,
                    epoch_unix_ms: 0,
                },
                RingStore::<4096>::default(),
            ),
            b: BoardB::new(),
            b_out: BoardBOut::default(),
            b_to_a: heapless::Vec::new(),
        }
    }
    /// One control period of both boards; returns board A's actuator commands.
    fn step(&mut self, t: u64, sa: &SensorsA, sb: &SensorsB, sink: &mut impl TmSink) -> ActuatorsA {
        let out = self.a.tick(t, sa, &self.b_to_a, sink);
        self.b.tick(t, sb, &out.link_tx, &mut self.b_out);
        self.b_to_a.clear();
        let _ = self.b_to_a.extend_from_slice(&self.b_out.tx);
        out.actuators
    }
}

fn obsw_low_battery_persists_half_a_second_then_recovers() -> TestResult {
    let limit = ok!(mib::fdir::monitor_by_id(1)).low as i64;
    check_eq!(limit, 2730);
    let mut robot = Robot::new();
    let mut log = FdirLog::default();
    // Board A sees an empty battery (2000 counts = 7.3 V), board B a healthy one.
    let mut s = SensorsA {
        v_bat: 2000,
        v_reg: 0,
        grav: [0, -1000, 0],
        ..Default::default()
    };
    let sb = SensorsB {
        v_bat: 3200,
        grav: [0, -1000, 0],
        arm_switch: true,
        ..Default::default()
    };
    let mut t = 0;
    // 1.5 s of an empty battery.
    while t < 1500 {
        t += mib::config::CONTROL_PERIOD_MS as u64;
        log.now = t;
        robot.step(t, &s, &sb, &mut log);
    }
    check_eq!(log.bad, 0);
    // Raised once, after 50 cycles of 10 ms below 10 V.
    let (t_mon, state) = ok!(log.mon.first().copied());
    check_eq!(state, obsw_core::fdir::check::BELOW_LOW);
    check!((500..=510).contains(&t_mon), "monitor tripped at {} ms", t_mon);
    let lows: heapless::Vec<(u64, u16, [i64; 3]), 16> =
        log.events.iter().filter(|e| e.1 == eid::LOW_BATTERY).copied().collect();
    check_eq!(lows.len(), 1);
    check_eq!((lows[0].0, lows[0].2), (t_mon, [pid::V_BAT_A as i64, 2000, limit]));
    let bit = 1i64 << ok!(mib::fdir::fault_by_event(eid::LOW_BATTERY)).bit;
    check!(robot.a.param::<{ pid::FAULT_FLAGS }>() & bit != 0, "fault bit not set");
    // Board B's battery arrives through its heartbeat.
    check_eq!(robot.a.param::<{ pid::V_BAT_B }>(), 3200);
    // Event-action: low battery leads to standby (the robot is already there).
    check_eq!(robot.a.mode(), mib::modes::robot_mode::STANDBY);

    // Battery back at 11.7 V: the 50-sample average climbs; the monitor clears the cycle
    // the average is no longer below the limit.
    s.v_bat = 3200;
    let mut window = [2000i64; 50];
    let mut expect_clear = None;
    for k in 0..100u64 {
        t += mib::config::CONTROL_PERIOD_MS as u64;
        log.now = t;
        window[(k % 50) as usize] = 3200;
        let sum: i64 = window.iter().sum();
        let avg = (sum + 25) / 50;
        if expect_clear.is_none() && avg >= limit {
            expect_clear = Some(t);
        }
        robot.step(t, &s, &sb, &mut log);
    }
    let expect_clear = ok!(expect_clear);
    check_eq!(log.mon.len(), 2);
    check_eq!(log.mon[1], (expect_clear, obsw_core::fdir::check::OK));
    let cleared: heapless::Vec<(u64, u16, [i64; 3]), 16> = log
        .events
        .iter()
        .filter(|e| e.1 == eid::FAULT_CLEARED)
        .copied()
        .collect();
    check_eq!(cleared.len(), 1);
    check_eq!((cleared[0].0, cleared[0].2[0]), (expect_clear, eid::LOW_BATTERY as i64));
    check!(
        robot.a.param::<{ pid::FAULT_FLAGS }>() & bit == 0,
        "fault bit still set"
    );
    check!(log.other > 0, "no housekeeping at all in 2.5 s");
    Ok(())
}

/// Builds a TC for this robot with the sat-rs encoder (as the ground tool does).
fn build_tc(seq: u16, svc: u8, sub: u8, app: &[u8], out: &mut [u8]) -> Option<usize> {
    use arbitrary_int::{u11, u14};
    use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
    use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId};
    use satrs::spacepackets::SpHeader;
    let apid = mib::apid::robot_apid(ROBOT)?;
    let sp = SpHeader::new_for_unseg_tc(u11::new(apid), u14::new(seq), 0);
    let sec = PusTcSecondaryHeader::new(MessageTypeId::new(svc, sub), AckFlags::ALL, mib::config::GROUND_ID);
    PusTcCreator::new(sp, sec, app, CreatorConfig::default())
        .write_to_bytes(out)
        .ok()
}

/// Records mode events and verification reports.
#[derive(Default)]
struct ModeLog {
    now: u64,
    /// (time, node, from, to, cause) of MODE_CHANGED: room for every node twice.
    changes: heapless::Vec<(u64, i64, i64, i64, i64), 32>,
    /// (time, subservice) of TM[1,x].
    verif: heapless::Vec<(u64, u8), 16>,
    faults: heapless::Vec<u16, 8>,
    /// TM packets sent.
    packets: u32,
    /// Instructions this log took to parse and record them: the test's own work, taken
    /// out of the OBSW's figures (board A's sink frames the packets instead, counted per
    /// packet by `t_budget`).
    own: u64,
}

impl TmSink for ModeLog {
    fn send_tm(&mut self, packet: &[u8]) {
        let start = instret();
        self.record(packet);
        self.own += instret() - start;
    }
}

impl ModeLog {
    fn record(&mut self, packet: &[u8]) {
        self.packets += 1;
        let Some(tm) = parse_tm(packet) else { return };
        match tm.svc {
            1 => {
                let _ = self.verif.push((self.now, tm.sub));
            }
            5 => {
                if let Ok(ev) = mib_wire::codec::decode_event(&tm.data) {
                    if ev.def.id == eid::MODE_CHANGED {
                        let p = |n| ev.param(n).unwrap_or(-1);
                        let _ = self.changes.push((self.now, p("node"), p("from"), p("to"), p("cause")));
                    } else if ev.def.fault {
                        let _ = self.faults.push(ev.def.id);
                    }
                }
            }
            _ => {}
        }
    }
}

fn obsw_mode_set_operational_powers_both_sides_and_homes() -> TestResult {
    use mib::modes::{node, robot_mode};
    use mib::robot::servo;
    let mut robot = Robot::new();
    let mut log = ModeLog::default();
    // Contracted and gripped on the floor face (matched Yneg): arm switches pushed,
    // hip at its home angle, healthy batteries.
    let sa = SensorsA {
        v_bat: 3200,
        v_reg: 2020,
        grav: [0, -1000, 0],
        hip_cdeg: 0,
        arm_switch: true,
        ..Default::default()
    };
    let sb = SensorsB {
        v_bat: 3200,
        grav: [0, -1000, 0],
        arm_switch: true,
        ..Default::default()
    };
    let mut t = 0;
    for _ in 0..50 {
        t += 10;
        log.now = t;
        robot.step(t, &sa, &sb, &mut log);
    }
    check!(
        !robot.a.tick(t + 1, &sa, &[], &mut log).actuators.regulator_on,
        "regulator on in standby"
    );
    t += 1;
    let mut app = [0u8; 10];
    app[..4].copy_from_slice(&node::ROBOT.to_be_bytes());
    app[4..8].copy_from_slice(&robot_mode::OPERATIONAL.to_be_bytes());
    let mut tc = [0u8; 32];
    let n = ok!(build_tc(7, 200, 1, &app, &mut tc));
    t += 5;
    log.now = t;
    robot.a.handle_tc(t, &tc[..n], &mut log);
    let t_cmd = t;
    let mut t_done = None;
    let mut regulator = false;
    for _ in 0..1500 {
        t += 10;
        log.now = t;
        regulator = robot.step(t, &sa, &sb, &mut log).regulator_on;
        if t_done.is_none() && log.verif.iter().any(|v| v.1 == 7) {
            t_done = Some(t);
        }
    }
    check!(log.faults.is_empty(), "fault events: {:?}", &log.faults[..]);
    let t_done = ok!(t_done);
    // Acceptance and start at the command, completion when the transition ends.
    check_eq!(&log.verif[..2], &[(t_cmd, 1), (t_cmd, 3)][..]);
    check_eq!(log.verif.len(), 3);
    check_eq!(robot.a.mode(), robot_mode::OPERATIONAL);
    // MODE_CHANGED for the robot node: standby -> operational, by command (cause 0).
    let root: heapless::Vec<_, 16> = log
        .changes
        .iter()
        .filter(|c| c.1 == node::ROBOT as i64)
        .copied()
        .collect();
    check_eq!(root.len(), 1);
    check_eq!((root[0].2, root[0].3, root[0].4), (0, 1, 0));
    check!(root[0].0 >= t_cmd && root[0].0 <= t_done);
    // Operational: regulator on, side A homed (arm contracted, gripper closed), side B
    // powered and homed through the link.
    check!(regulator, "regulator off in operational");
    check_eq!(robot.a.param::<{ pid::ARM_A_PWM }>(), servo::ARM_CONTRACTED_US as i64);
    check_eq!(robot.a.param::<{ pid::GRIP_A_PWM }>(), servo::GRIP_CLOSED_US as i64);
    check_eq!(robot.b_out.side.arm_pwm, Some(servo::ARM_CONTRACTED_US));
    check_eq!(robot.b_out.side.grip_pwm, Some(servo::GRIP_CLOSED_US));
    check_eq!(robot.a.param::<{ pid::B_LINK_OK }>(), 1);
    Ok(())
}

/// The healthy robot of the mode test: contracted on the floor face, batteries full.
fn healthy() -> (SensorsA, SensorsB) {
    (
        SensorsA {
            v_bat: 3200,
            v_reg: 2020,
            grav: [0, -1000, 0],
            hip_cdeg: 0,
            arm_switch: true,
            ..Default::default()
        },
        SensorsB {
            v_bat: 3200,
            grav: [0, -1000, 0],
            arm_switch: true,
            ..Default::default()
        },
    )
}

fn obsw_board_b_silence_is_comm_loss_and_safes_the_robot() -> TestResult {
    use mib::modes::{node, robot_mode};
    let mut robot = Robot::new();
    let mut log = ModeLog::default();
    let (sa, sb) = healthy();
    let mut t = 0;
    for _ in 0..20 {
        t += 10;
        robot.step(t, &sa, &sb, &mut log);
    }
    let mut app = [0u8; 10];
    app[..4].copy_from_slice(&node::ROBOT.to_be_bytes());
    app[4..8].copy_from_slice(&robot_mode::OPERATIONAL.to_be_bytes());
    let mut tc = [0u8; 32];
    let n = ok!(build_tc(9, 200, 1, &app, &mut tc));
    robot.a.handle_tc(t, &tc[..n], &mut log);
    for _ in 0..1500 {
        t += 10;
        log.now = t;
        robot.step(t, &sa, &sb, &mut log);
    }
    check_eq!(robot.a.mode(), robot_mode::OPERATIONAL);
    check!(
        log.faults.is_empty(),
        "fault events before the cut: {:?}",
        &log.faults[..]
    );
    // Board B goes silent: A keeps running, B's bytes no longer arrive.
    let t_cut = t;
    let mut act = ActuatorsA::default();
    for _ in 0..200 {
        t += 10;
        log.now = t;
        act = robot.a.tick(t, &sa, &[], &mut log).actuators;
    }
    // The missing heartbeat is detected first; the module commands A then sends to the
    // silent B go unacknowledged as well (COMM_LOSS_NO_ACK), nothing else.
    check_eq!(log.faults.first().copied(), Some(eid::COMM_LOSS_HEARTBEAT));
    check!(
        log.faults
            .iter()
            .all(|&f| f == eid::COMM_LOSS_HEARTBEAT || f == eid::COMM_LOSS_NO_ACK),
        "faults: {:?}",
        &log.faults[..]
    );
    check_eq!(log.faults.iter().filter(|&&f| f == eid::COMM_LOSS_HEARTBEAT).count(), 1);
    // The heartbeat is 500 ms old at the latest 50 ms (one heartbeat period) plus one
    // control period after the last one arrived.
    let timeout = ok!(mib::params::by_id(pid::B_HB_AGE_MS))
        .limits
        .map(|l| l.hard_hi as u64);
    let timeout = ok!(timeout);
    // The transition by FDIR: MODE_CHANGED events caused by the fault (cause = its event
    // ID), all at one time.
    check!(log.changes.len() < 32, "MODE_CHANGED log full");
    let by_fault: heapless::Vec<(u64, i64, i64, i64, i64), 16> = log
        .changes
        .iter()
        .filter(|c| c.4 == eid::COMM_LOSS_HEARTBEAT as i64)
        .copied()
        .collect();
    check!(!by_fault.is_empty(), "no MODE_CHANGED caused by the comm loss");
    let t_safe = by_fault[0].0;
    check!(by_fault.iter().all(|c| c.0 == t_safe));
    // The robot node itself: exactly one MODE_CHANGED, operational -> safed, caused by
    // the heartbeat loss (no longer lost to event throttling among the module nodes'
    // reports), and one report per node at most.
    let root: heapless::Vec<(u64, i64, i64, i64, i64), 4> =
        by_fault.iter().filter(|c| c.1 == node::ROBOT as i64).copied().collect();
    check_eq!(root.len(), 1);
    check_eq!(
        (root[0].2, root[0].3),
        (robot_mode::OPERATIONAL as i64, robot_mode::SAFED as i64)
    );
    for (i, c) in by_fault.iter().enumerate() {
        check!(by_fault[..i].iter().all(|d| d.1 != c.1), "node {} reported twice", c.1);
    }
    check!(by_fault.len() > 1, "no module node followed the robot node");
    check!(
        t_safe > t_cut + timeout - 60 && t_safe <= t_cut + timeout + 20,
        "safed at +{} ms after the cut, timeout {} ms",
        t_safe - t_cut,
        timeout
    );
    // Safed (Table 7): the arms hold, the bolters are off.
    for c in by_fault.iter() {
        let kind = ok!(mib::modes::node_by_id(c.1 as u32)).kind;
        check_eq!(
            c.3 as u32,
            mib::modes::child_mode(robot_mode::SAFED, kind),
            "node {}",
            c.1
        );
    }
    check_eq!(robot.a.mode(), robot_mode::SAFED);
    // Safed (Table 7): modules powered and holding, bolter off.
    check!(act.regulator_on, "regulator off in safed");
    check_eq!(act.side.bolter, mmic_domain::BolterDrive::Off);
    check!(act.side.arm_pwm.is_some(), "arm A unpowered in safed");
    check_eq!(robot.a.param::<{ pid::B_LINK_OK }>(), 0);
    Ok(())
}

/// Every event and monitoring transition, with the time it was reported.
#[derive(Default)]
struct AllEvents {
    now: u64,
    /// (time, event ID, first parameter)
    events: heapless::Vec<(u64, u16, i64), 32>,
    /// (time, monitor ID, new state) of TM[12,12].
    mon: heapless::Vec<(u64, u16, u8), 16>,
}

impl TmSink for AllEvents {
    fn send_tm(&mut self, packet: &[u8]) {
        let Some(tm) = parse_tm(packet) else { return };
        match (tm.svc, tm.sub) {
            (12, 12) if tm.data.len() == 13 => {
                let id = u16::from_be_bytes([tm.data[0], tm.data[1]]);
                let _ = self.mon.push((self.now, id, tm.data[12]));
            }
            (5, _) => {
                if let Ok(ev) = mib_wire::codec::decode_event(&tm.data) {
                    let first = ev.params().next().map_or(0, |(_, v)| v);
                    let _ = self.events.push((self.now, ev.def.id, first));
                }
            }
            _ => {}
        }
    }
}

/// Board B not connected (never heard): its readings have no value, so its battery
/// monitor neither trips nor reports, however long the robot waits; what B's absence
/// does raise is a comm loss (its boot module command unacknowledged, no heartbeat).
/// Once B is heard with an empty battery, the same monitor trips after its 0.5 s
/// persistence.
fn obsw_standby_with_board_b_never_heard_raises_no_low_battery() -> TestResult {
    let mon_b = ok!(mib::fdir::MONITORS.iter().find(|m| m.param == pid::V_BAT_B)).id;
    let mut robot = Robot::new();
    let mut log = AllEvents::default();
    let (sa, mut sb) = healthy();
    let mut t = 0;
    // 3 s from boot in standby, board A alone (six times the low-battery persistence).
    for _ in 0..300 {
        t += 10;
        log.now = t;
        let _ = robot.a.tick(t, &sa, &[], &mut log);
    }
    check_eq!(robot.a.param_opt(pid::V_BAT_B), None);
    check!(
        log.events.iter().all(|e| e.1 != eid::LOW_BATTERY),
        "LOW_BATTERY without board B: {:?}",
        &log.events[..]
    );
    check!(
        log.mon.iter().all(|m| m.1 != mon_b),
        "V_BAT_B monitor reported: {:?}",
        &log.mon[..]
    );
    let bit = 1i64 << ok!(mib::fdir::fault_by_event(eid::LOW_BATTERY)).bit;
    check_eq!(robot.a.param::<{ pid::FAULT_FLAGS }>() & bit, 0);
    // The faults B's absence raises: comm loss, and nothing else.
    let faults: heapless::Vec<u16, 32> = log
        .events
        .iter()
        .map(|e| e.1)
        .filter(|&id| mib::events::by_id(id).is_some_and(|d| d.fault))
        .collect();
    check!(
        faults.contains(&eid::COMM_LOSS_HEARTBEAT),
        "no COMM_LOSS_HEARTBEAT: {:?}",
        &faults[..]
    );
    check!(
        faults
            .iter()
            .all(|&f| f == eid::COMM_LOSS_HEARTBEAT || f == eid::COMM_LOSS_NO_ACK),
        "faults: {:?}",
        &faults[..]
    );

    // Board B connects with an empty battery (7.3 V): now its reading counts.
    sb.v_bat = 2000;
    let t_link = t;
    let mon_before = log.mon.len();
    for _ in 0..150 {
        t += 10;
        log.now = t;
        robot.step(t, &sa, &sb, &mut log);
    }
    check_eq!(robot.a.param_opt(pid::V_BAT_B), Some(2000));
    let low: heapless::Vec<(u64, u16, i64), 4> =
        log.events.iter().filter(|e| e.1 == eid::LOW_BATTERY).copied().collect();
    check_eq!(low.len(), 1);
    // Parameter V_BAT_B, after 50 samples below the limit.
    check_eq!(low[0].2, pid::V_BAT_B as i64);
    check!(
        low[0].0 >= t_link + 500,
        "tripped {} ms after B was heard",
        low[0].0 - t_link
    );
    let b_mon: heapless::Vec<(u64, u16, u8), 8> =
        log.mon[mon_before..].iter().filter(|m| m.1 == mon_b).copied().collect();
    check_eq!(b_mon.len(), 1);
    check_eq!((b_mon[0].0, b_mon[0].2), (low[0].0, obsw_core::fdir::check::BELOW_LOW));
    check!(log.events.len() < 32 && log.mon.len() < 16, "event log full");
    Ok(())
}

/// Instructions retired (minstret; exact under QEMU with `-icount`).
fn instret() -> u64 {
    riscv::register::minstret::read64()
}

/// Execution cost of the OBSW's entry points on RV32IMC, in instructions, over a
/// standby → operational transition with homing, HK every second and a burst of TCs.
/// At the ESP32-C3's 160 MHz, even at 2 cycles per instruction (flash cache misses),
/// one control period of 10 ms holds 800 000 instructions; the worst tick must fit in
/// half of that, leaving the other half to the drivers and the link tasks.
fn obsw_tick_and_tc_fit_the_10_ms_control_period() -> TestResult {
    use mib::modes::{node, robot_mode};
    const BUDGET: u64 = 160_000_000 / 2 / 1000 * mib::config::CONTROL_PERIOD_MS as u64 / 2;
    let mut robot = Robot::new();
    let mut log = ModeLog::default();
    let (sa, sb) = healthy();
    let (mut t, mut worst_tick, mut worst_tc) = (0u64, 0u64, 0u64);
    let mut ticks = 0u32;
    let mut most_packets = 0u32;
    let mut step = |robot: &mut Robot, t: u64, log: &mut ModeLog| {
        let (start, before, own) = (instret(), log.packets, log.own);
        let out = robot.a.tick(t, &sa, &robot.b_to_a, log);
        let cost = instret() - start - (log.own - own);
        most_packets = most_packets.max(log.packets - before);
        robot.b.tick(t, &sb, &out.link_tx, &mut robot.b_out);
        robot.b_to_a.clear();
        let _ = robot.b_to_a.extend_from_slice(&robot.b_out.tx);
        cost
    };
    for _ in 0..50 {
        t += 10;
        worst_tick = worst_tick.max(step(&mut robot, t, &mut log));
        ticks += 1;
    }
    let mut app = [0u8; 10];
    app[..4].copy_from_slice(&node::ROBOT.to_be_bytes());
    app[4..8].copy_from_slice(&robot_mode::OPERATIONAL.to_be_bytes());
    let mut tc = [0u8; 32];
    let n = ok!(build_tc(11, 200, 1, &app, &mut tc));
    let (start, own, before) = (instret(), log.own, log.packets);
    robot.a.handle_tc(t, &tc[..n], &mut log);
    worst_tc = worst_tc.max(instret() - start - (log.own - own));
    let mut most_tc_packets = log.packets - before;
    for i in 0..1000u16 {
        t += 10;
        worst_tick = worst_tick.max(step(&mut robot, t, &mut log));
        ticks += 1;
        if i % 100 == 50 {
            // HK one-shot of the largest structure, a ping and a mode read.
            for (k, (svc, sub, app)) in [
                (3u8, 27u8, &[0u8, 1][..]),
                (17, 1, &[][..]),
                (200, 3, &[0, 0, 0, 1][..]),
            ]
            .into_iter()
            .enumerate()
            {
                let n = ok!(build_tc(100 + i + k as u16, svc, sub, app, &mut tc));
                let (start, own, before) = (instret(), log.own, log.packets);
                robot.a.handle_tc(t, &tc[..n], &mut log);
                worst_tc = worst_tc.max(instret() - start - (log.own - own));
                most_tc_packets = most_tc_packets.max(log.packets - before);
            }
        }
    }
    check_eq!(robot.a.mode(), robot_mode::OPERATIONAL);
    semihosting::println!(
        "    worst Obsw::tick {} instructions, worst Obsw::handle_tc {} ({} ticks, budget {}; the test sink's own {} instructions over the run not counted)",
        worst_tick,
        worst_tc,
        ticks,
        BUDGET,
        log.own
    );
    crate::harness::WORST_TICK.store(worst_tick, portable_atomic::Ordering::Relaxed);
    crate::harness::WORST_TC.store(worst_tc, portable_atomic::Ordering::Relaxed);
    crate::harness::MOST_TICK_PACKETS.store(u64::from(most_packets), portable_atomic::Ordering::Relaxed);
    crate::harness::MOST_TC_PACKETS.store(u64::from(most_tc_packets), portable_atomic::Ordering::Relaxed);
    check!(worst_tick > 1000, "instruction counter not running ({})", worst_tick);
    check!(worst_tick < BUDGET, "tick takes {} instructions", worst_tick);
    check!(worst_tc < BUDGET, "handle_tc takes {} instructions", worst_tc);
    Ok(())
}

/// Sequence count (14 bits) of a TM packet.
fn seq_of(packet: &[u8]) -> u16 {
    u16::from_be_bytes([packet[2], packet[3]]) & 0x3FFF
}

/// Link down: the downlink queue is full and live TM is not sent, but every packet is
/// in the on-board store, and TC[15,9] brings them all back in order.
fn obsw_store_returns_every_packet_the_full_downlink_dropped() -> TestResult {
    static SMALL: ByteQueue<128> = ByteQueue::new();
    static BIG: ByteQueue<16384> = ByteQueue::new();
    static S1: Counters = Counters::new();
    static S2: Counters = Counters::new();
    let mut obsw = Obsw::new(
        Config {
            robot: ROBOT,
            epoch_unix_ms: 0,
        },
        RingStore::<{ config::TM_STORE_BYTES }>::default(),
    );
    let mut live = GroundSink {
        link: &mut BarePackets,
        queue: &SMALL,
        counters: &S1,
    };
    obsw.boot(0, 1, &mut live);
    let mut tc = [0u8; 32];
    for i in 0..10u16 {
        let n = ok!(crate::t_packets::build(i, 17, 1, &[], &mut tc));
        obsw.handle_tc(10 + i as u64, &tc[..n], &mut live);
    }
    // BOOT + 10 x (1,1 17,2 1,3 1,7) = 41 packets; the link took only the first few.
    let (sent, dropped) = (S1.get().delivered, S1.get().overflow);
    check_eq!(sent + dropped, 41);
    check!(dropped > 30, "only {} dropped", dropped);
    check_eq!(obsw.param::<{ pid::TM_STORED }>(), 41);

    // Link back: downlink the store.
    let mut sink = GroundSink {
        link: &mut BarePackets,
        queue: &BIG,
        counters: &S2,
    };
    // TC[15,9] by time span: the whole span (CDS day 0 ms 0 .. day 65535 ms 2^32-1).
    let mut span = [0u8; 12];
    span[6..8].copy_from_slice(&u16::MAX.to_be_bytes());
    span[8..].copy_from_slice(&u32::MAX.to_be_bytes());
    let n = ok!(crate::t_packets::build(10, 15, 9, &span, &mut tc));
    obsw.handle_tc(100, &tc[..n], &mut sink);
    let mut bytes = [0u8; 16384];
    let n = link::drain(&BIG, &mut bytes);
    let mut d: Deframer<{ config::MAX_PACKET_LEN }> = Deframer::new();
    let mut seqs: heapless::Vec<u16, 64> = heapless::Vec::new();
    let mut kinds: heapless::Vec<(u8, u8), 64> = heapless::Vec::new();
    let mut done = None;
    for &b in &bytes[..n] {
        if let Some(r) = d.push(b) {
            let p = ok!(r);
            let tm = ok!(parse_tm(p));
            if (tm.svc, tm.sub) == (15, 19) {
                done = Some(u32::from_be_bytes([tm.data[0], tm.data[1], tm.data[2], tm.data[3]]));
            } else if done.is_none() {
                let _ = seqs.push(seq_of(p));
            }
            let _ = kinds.push((tm.svc, tm.sub));
        }
    }
    // First the TC[15,9]'s acceptance and start, sent live (a downlink by range is paced:
    // it runs after its start, and completes after its end report); then the store,
    // oldest first: the 41 packets, that acceptance and that start again (the store keeps
    // a copy of everything), with consecutive sequence counts; then the end report
    // counting the 43, and the completion.
    check_eq!(done, Some(43));
    check_eq!(seqs.len(), 45);
    check_eq!(&kinds[..2], &[(1, 1), (1, 3)][..]);
    let stored = &seqs[2..];
    for (i, s) in stored.iter().enumerate() {
        check_eq!(*s, stored[0] + i as u16, "stored packet {}", i);
    }
    check_eq!(&stored[41..], &seqs[..2]);
    check_eq!(kinds[2], (5, 1));
    check_eq!(&kinds[45..], &[(15, 19), (1, 7)][..]);
    check_eq!(S2.get().overflow, 0);

    // TC[15,128] by APID and sequence range: exactly packets 5..=7 again, unchanged
    // (the store is read, not emptied), then TM[15,19]: 3 sent, oldest stored seq 0,
    // nothing overwritten.
    let apid = obsw.apid();
    let mut range = [0u8; 6];
    range[..2].copy_from_slice(&apid.to_be_bytes());
    range[2..4].copy_from_slice(&5u16.to_be_bytes());
    range[4..].copy_from_slice(&7u16.to_be_bytes());
    let n = ok!(crate::t_packets::build(11, 15, 128, &range, &mut tc));
    obsw.handle_tc(200, &tc[..n], &mut sink);
    let n = link::drain(&BIG, &mut bytes);
    let mut replayed: heapless::Vec<u16, 8> = heapless::Vec::new();
    let mut end = None;
    for &b in &bytes[..n] {
        if let Some(r) = d.push(b) {
            let p = ok!(r);
            let tm = ok!(parse_tm(p));
            if (tm.svc, tm.sub) == (15, 19) {
                end = Some(tm.data);
            } else if end.is_none() {
                let _ = replayed.push(seq_of(p));
            }
        }
    }
    // First the TC's own acceptance and start (live), then the three stored packets.
    check_eq!(&replayed[2..], &[5u16, 6, 7][..]);
    let end = ok!(end);
    check_eq!(&end[..4], &3u32.to_be_bytes()[..]);
    // packets u32, oldest_time CDS (7 bytes), oldest_seq u16, overwritten u32
    check_eq!(&end[11..13], &0u16.to_be_bytes()[..]);
    check_eq!(&end[13..17], &0u32.to_be_bytes()[..]);
    Ok(())
}

/// Failure codes of TM[1,x] failure reports and TC_REJECTED events.
#[derive(Default)]
struct Refusals {
    failures: heapless::Vec<u16, 8>,
    rejected: u32,
}

impl TmSink for Refusals {
    fn send_tm(&mut self, packet: &[u8]) {
        let Some(tm) = parse_tm(packet) else { return };
        match tm.svc {
            1 if tm.sub % 2 == 0 && tm.data.len() >= 6 => {
                let _ = self.failures.push(u16::from_be_bytes([tm.data[4], tm.data[5]]));
            }
            5 => {
                if let Ok(ev) = mib_wire::codec::decode_event(&tm.data) {
                    self.rejected += u32::from(ev.def.id == eid::TC_REJECTED);
                }
            }
            _ => {}
        }
    }
}

// verifies: UPD-SVC-04
/// Board A's obsw is built without the `update` feature (no file store to install from, no
/// verifier in its image): install, activate and confirm each get UPDATE_UNAVAILABLE, are
/// counted in UPDATE_REFUSALS and evented.
fn obsw_without_update_refuses_every_update_tc_unavailable_counted_and_evented() -> TestResult {
    use mib::tc::service::UPDATE;
    use mib::update::sub;
    let mut robot = Robot::new();
    let mut log = Refusals::default();
    let requests: [(u8, &[u8]); 3] = [
        (sub::INSTALL, &[5, b'a', b'.', b'i', b'm', b'g']),
        (sub::ACTIVATE, &[0x5A; 32]),
        (sub::CONFIRM, &[]),
    ];
    let mut tc = [0u8; 64];
    for (n, (sub, app)) in requests.into_iter().enumerate() {
        let len = ok!(build_tc(20 + n as u16, UPDATE, sub, app, &mut tc));
        robot.a.handle_tc(100 + 10 * n as u64, &tc[..len], &mut log);
    }
    let unavailable = FailureCode::UPDATE_UNAVAILABLE.code();
    check_eq!(&log.failures[..], &[unavailable; 3][..]);
    check_eq!(log.rejected, 3);
    check_eq!(robot.a.param::<{ pid::UPDATE_REFUSALS }>(), 3);
    Ok(())
}
