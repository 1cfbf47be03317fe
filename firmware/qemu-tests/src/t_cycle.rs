//! The boards' control periods (`fw_core::cycle`), the code the images run every 10 ms,
//! on mock peripherals: board A's OBSW and board B wired through the same byte queues
//! the UART tasks fill, commanded over the ground uplink queue.

use crate::harness::{Test, TestResult};
use crate::mock::{MockI2c, MockPin, MockPwm};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::config::{self, i2c_addr};
use fw_core::cycle::{CycleA, CycleB, LinksA, LinksB, PeripheralsA, PeripheralsB};
use fw_core::files::NoFiles;
use fw_core::link::{self, BarePackets, ByteQueue, Counters, TcChannel};
use fw_core::periph::ads7828::PowerMode;
use fw_core::periph::{
    ActiveLowEnable, ActiveLowSwitch, Ads7828, As5600, BolterMux, BolterServos, HwError, Mpu6000, PwmServo,
    ServoOutput, SideOutputs,
};
use mib::events::eid;
use mib::modes::{node, robot_mode};
use mib::robot::servo;
use mmic_stream::{encode, Deframer};
use obsw_core::obsw::{Config, IoCounters, Obsw};
use obsw_core::tm::RingStore;
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::PusPacket;

pub const TESTS: &[Test] = tests![
    boards_a_and_b_cycles_go_operational_on_a_ground_command,
    cycle_a_reports_platform_io_counters_in_hk_structure_5,
];

pub(crate) type Servo = PwmServo<MockPwm>;
pub(crate) type Side = SideOutputs<Servo, Servo, Servo, Servo, BolterMux<MockPin, MockPin>>;

pub(crate) fn servo() -> Servo {
    PwmServo::new(MockPwm { max: 1 << 14, duty: 0 })
}

pub(crate) fn side() -> Side {
    SideOutputs {
        arm: servo(),
        grip: servo(),
        bolter: BolterServos {
            translate: servo(),
            rotate: servo(),
        },
        mux: BolterMux::new(MockPin::default(), MockPin::default()),
    }
}

/// An ADS7828 answering fixed counts on channels 0..=5.
fn adc(counts: [u16; 6]) -> Ads7828<MockI2c> {
    let mut bus = MockI2c::new(i2c_addr::ADS7828);
    for (ch, v) in counts.iter().enumerate() {
        if let Some(cmd) = fw_core::periph::ads7828::command_byte(ch as u8, PowerMode::RefOnAdcOn) {
            let _ = bus.replies.push((cmd, v.to_be_bytes()));
        }
    }
    Ads7828::new(bus, i2c_addr::ADS7828, PowerMode::RefOnAdcOn)
}

/// An MPU-6000 lying flat with gravity along its −y axis (the floor face).
fn imu() -> Option<Mpu6000<MockI2c>> {
    let mut bus = MockI2c::new(i2c_addr::MPU6000);
    bus.regs[0x75] = 0x68;
    bus.regs[0x3B..0x41].copy_from_slice(&[0x00, 0x00, 0xC0, 0x00, 0x00, 0x00]);
    Mpu6000::init(bus, i2c_addr::MPU6000).ok()
}

type BoardA<H> = PeripheralsA<
    Ads7828<MockI2c>,
    Option<Mpu6000<MockI2c>>,
    As5600<MockI2c>,
    ActiveLowSwitch<MockPin>,
    Servo,
    Servo,
    Servo,
    Servo,
    BolterMux<MockPin, MockPin>,
    H,
    ActiveLowEnable<MockPin>,
>;

/// Board A's peripherals on mock buses: V_bat 11.7 V, V_reg 7.4 V, small currents, the
/// IMU on the floor face, the hip at its calibrated zero, arm switch pushed.
fn board_a<H: ServoOutput>(hip: H) -> BoardA<H> {
    let mut enc_bus = MockI2c::new(i2c_addr::AS5600);
    enc_bus.regs[0x0B] = 0x20; // magnet detected
    enc_bus.regs[0x0C] = 0x01;
    enc_bus.regs[0x0D] = 0x00; // raw 256 = the calibrated zero below
    PeripheralsA {
        adc: adc([3200, 2020, 300, 50, 20, 0]),
        imu: imu(),
        hip_encoder: As5600::new(enc_bus, i2c_addr::AS5600, 256),
        arm_switch: ActiveLowSwitch(MockPin {
            high: false,
            changes: 0,
        }),
        side: side(),
        hip,
        regulator: ActiveLowEnable(MockPin { high: true, changes: 0 }),
    }
}

fn boards_a_and_b_cycles_go_operational_on_a_ground_command() -> TestResult {
    static TCS: TcChannel = TcChannel::new();
    static TM: ByteQueue<{ config::TM_DOWNLINK_BYTES }> = ByteQueue::new();
    static A_RX: ByteQueue<{ config::AB_RX_BYTES }> = ByteQueue::new();
    static A_TX: ByteQueue<{ config::AB_TX_BYTES }> = ByteQueue::new();
    static B_RX: ByteQueue<{ config::AB_RX_BYTES }> = ByteQueue::new();
    static B_TX: ByteQueue<{ config::AB_TX_BYTES }> = ByteQueue::new();
    // tm, A's ab_tx, B's ab_tx, uplink, A's ab_rx, B's ab_rx
    static STATS: [Counters; 6] = [
        Counters::new(),
        Counters::new(),
        Counters::new(),
        Counters::new(),
        Counters::new(),
        Counters::new(),
    ];

    let mut io_a = board_a(servo());
    let mut io_b = PeripheralsB {
        adc: adc([3200, 0, 0, 50, 20, 0]),
        imu: imu(),
        arm_switch: ActiveLowSwitch(MockPin {
            high: false,
            changes: 0,
        }),
        side: side(),
    };
    check!(io_a.imu.is_some(), "IMU mock not recognised");
    let links_a = LinksA {
        tcs: &TCS,
        tc_stats: &STATS[3],
        tm: &TM,
        tm_stats: &STATS[0],
        ab_rx: &A_RX,
        ab_rx_stats: &STATS[4],
        ab_tx: &A_TX,
        ab_tx_stats: &STATS[1],
    };
    let links_b = LinksB {
        ab_rx: &B_RX,
        ab_tx: &B_TX,
        ab_tx_stats: &STATS[2],
    };
    let mut obsw = Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 0,
        },
        RingStore::<8192>::default(),
    );
    let (mut a, mut b) = (CycleA::new(), CycleB::new());
    io_a.release_all();

    let mut wire = [0u8; config::AB_TX_BYTES];
    let mut tm_bytes = [0u8; config::TM_DOWNLINK_BYTES];
    let mut deframer: Deframer<{ config::MAX_PACKET_LEN }> = Deframer::new();
    let mut uplink: Deframer<{ config::GROUND_RX_BUF }> = Deframer::new();
    let (mut completed, mut root_changed, mut tm_count) = (None, None, 0u32);
    let mut act = mmic_domain::ActuatorsA::default();
    let mut t = 0u64;
    for k in 0..1600u32 {
        t += config::CONTROL_PERIOD_MS as u64;
        if k == 100 {
            // The ground commands operational, COBS-framed as on the USB link.
            let mut app = [0u8; 10];
            app[..4].copy_from_slice(&node::ROBOT.to_be_bytes());
            app[4..8].copy_from_slice(&robot_mode::OPERATIONAL.to_be_bytes());
            let mut tc = [0u8; 32];
            let n = ok!(crate::t_packets::build(1, 200, 1, &app, &mut tc));
            let mut frame = [0u8; 48];
            let m = ok!(encode(&tc[..n], &mut frame));
            link::uplink_bytes(&mut uplink, &frame[..m], &TCS, &STATS[3]);
        }
        act = a.run(t, &mut obsw, &mut BarePackets, &mut NoFiles, &mut io_a, &links_a);
        b.run(t, &mut io_b, &links_b);
        // The UARTs: whatever each side queued arrives at the other.
        let n = link::drain(&A_TX, &mut wire);
        link::push_bytes(&B_RX, &wire[..n], &STATS[5]);
        let n = link::drain(&B_TX, &mut wire);
        link::push_bytes(&A_RX, &wire[..n], &STATS[4]);
        // The downlink.
        let n = link::drain(&TM, &mut tm_bytes);
        for &byte in &tm_bytes[..n] {
            let Some(frame) = deframer.push(byte) else { continue };
            let r = ok!(PusTmReader::new(ok!(frame), mib::config::TIMESTAMP_LEN));
            tm_count += 1;
            match (PusPacket::service_type_id(&r), PusPacket::message_subtype_id(&r)) {
                (1, 7) => completed = completed.or(Some(t)),
                (5, 1) => {
                    if let Ok(ev) = mib_wire::codec::decode_event(r.user_data()) {
                        if ev.def.id == eid::MODE_CHANGED && ev.param("node") == Some(node::ROBOT as i64) {
                            root_changed = Some((t, ev.param("to")));
                        }
                    }
                }
                _ => {}
            }
        }
        if k == 99 {
            // Standby: servo rail off (enable line high), every servo without pulses.
            check!(io_a.regulator.0.high, "regulator on in standby");
            check_eq!(
                (io_a.side.arm.last_us(), io_a.hip.last_us(), io_b.side.arm.last_us()),
                (0, 0, 0)
            );
        }
    }
    check_eq!(STATS[0].get().overflow, 0);
    for (i, c) in STATS.iter().enumerate() {
        check_eq!(c.get().overflow, 0, "queue {}", i);
    }
    check!(tm_count > 20, "only {} TM packets", tm_count);
    let done = ok!(completed);
    let (t_root, to) = ok!(root_changed);
    check_eq!(to, Some(robot_mode::OPERATIONAL as i64));
    check!(
        t_root <= done && done > 1000,
        "root changed at {} ms, completion at {} ms",
        t_root,
        done
    );
    check_eq!(obsw.mode(), robot_mode::OPERATIONAL);
    // Operational: rail on (enable line driven low), both sides homed on the servos.
    check!(act.regulator_on);
    check!(!io_a.regulator.0.high, "regulator enable line not driven low");
    check_eq!(io_a.side.arm.last_us(), servo::ARM_CONTRACTED_US);
    check_eq!(io_a.side.grip.last_us(), servo::GRIP_CLOSED_US);
    check_eq!(io_b.side.arm.last_us(), servo::ARM_CONTRACTED_US);
    check_eq!(io_b.side.grip.last_us(), servo::GRIP_CLOSED_US);
    // The hip holds at home: the continuous servo is at (or next to) standstill.
    let hip = io_a.hip.last_us();
    check!((1450..=1550).contains(&hip), "hip pulse {} us", hip);
    // Sensors arrived through the drivers: A's IMU, B's battery through the heartbeat.
    check_eq!(a.sensors.grav, [0, -1000, 0]);
    check_eq!(a.sensors.hip_cdeg, 0);
    check_eq!(obsw.param::<{ mib::params::pid::V_BAT_B }>(), 3200);
    check_eq!(
        (a.errors.total(), b.errors.total(), a.output_errors, b.output_errors),
        (0, 0, 0, 0)
    );
    // Nothing dropped, nothing failed: the OBSW's platform I/O counters are all zero.
    check_eq!(obsw.io, IoCounters::default());
    Ok(())
}

/// A servo output whose driver refuses every write while `fail` is set.
#[derive(Default)]
struct FlakyServo {
    fail: bool,
}

impl ServoOutput for FlakyServo {
    fn set_pulse_us(&mut self, _us: u16) -> Result<(), HwError> {
        if self.fail {
            Err(HwError::Driver)
        } else {
            Ok(())
        }
    }
    fn release(&mut self) -> Result<(), HwError> {
        self.set_pulse_us(0)
    }
}

/// Board A's control period in standby with faults forced on each path the platform
/// I/O counters cover; a one-shot TC[3,27] for SID 5 then reports them.
fn cycle_a_reports_platform_io_counters_in_hk_structure_5() -> TestResult {
    use mib::params::pid;
    static TCS: TcChannel = TcChannel::new();
    static TM: ByteQueue<{ config::TM_DOWNLINK_BYTES }> = ByteQueue::new();
    static A_RX: ByteQueue<{ config::AB_RX_BYTES }> = ByteQueue::new();
    static A_TX: ByteQueue<{ config::AB_TX_BYTES }> = ByteQueue::new();
    // uplink, tm, ab_rx, ab_tx
    static STATS: [Counters; 4] = [Counters::new(), Counters::new(), Counters::new(), Counters::new()];
    let links = LinksA {
        tcs: &TCS,
        tc_stats: &STATS[0],
        tm: &TM,
        tm_stats: &STATS[1],
        ab_rx: &A_RX,
        ab_rx_stats: &STATS[2],
        ab_tx: &A_TX,
        ab_tx_stats: &STATS[3],
    };
    let mut io = board_a(FlakyServo::default());
    let mut obsw = Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 0,
        },
        RingStore::<16384>::default(),
    );
    let mut cycle = CycleA::new();
    let mut uplink: Deframer<{ config::GROUND_RX_BUF }> = Deframer::new();
    let mut tm_bytes = [0u8; config::TM_DOWNLINK_BYTES];
    let mut t = 0u64;
    let mut step = |cycle: &mut CycleA, obsw: &mut Obsw<RingStore<16384>>, io: &mut BoardA<FlakyServo>| {
        t += config::CONTROL_PERIOD_MS as u64;
        cycle.run(t, obsw, &mut BarePackets, &mut NoFiles, io, &links);
        // Board B is not connected: A's bytes for it go nowhere.
        let mut sink = [0u8; config::AB_TX_BYTES];
        link::drain(&A_TX, &mut sink);
    };
    for _ in 0..10 {
        step(&mut cycle, &mut obsw, &mut io);
    }
    let _ = link::drain(&TM, &mut tm_bytes);
    check_eq!(cycle.io_counters(&links), IoCounters::default());

    // Sensors: the ADC's I2C bus fails for 3 periods, 6 channels each.
    io.adc.bus_mut().fail = true;
    for _ in 0..3 {
        step(&mut cycle, &mut obsw, &mut io);
    }
    io.adc.bus_mut().fail = false;
    // Outputs: the hip servo's driver refuses for 2 periods (one error per period).
    io.hip.fail = true;
    for _ in 0..2 {
        step(&mut cycle, &mut obsw, &mut io);
    }
    io.hip.fail = false;
    // Uplink: six PINGs arrive at once (the TC queue holds 4) and a frame with broken
    // COBS (code 5 announces four bytes, the delimiter comes after one).
    let mut tc = [0u8; 32];
    let mut frame = [0u8; 48];
    for seq in 0..6u16 {
        let n = ok!(crate::t_packets::build(seq, 17, 1, &[], &mut tc));
        let m = ok!(encode(&tc[..n], &mut frame));
        link::uplink_bytes(&mut uplink, &frame[..m], &TCS, &STATS[0]);
    }
    link::uplink_bytes(&mut uplink, &[0x00, 0x05, 0x01, 0x00], &TCS, &STATS[0]);
    check_eq!((STATS[0].get().overflow, STATS[0].get().frame_errors), (2, 1));
    step(&mut cycle, &mut obsw, &mut io);
    // A–B: 600 bytes arrive in one period; the 512-byte receive queue drops 88.
    link::push_bytes(&A_RX, &[0x55; 600], &STATS[2]);
    step(&mut cycle, &mut obsw, &mut io);
    // Downlink jammed: the ground link leaves only 10 bytes free, so every packet of
    // this period (four reports of a PING, and whatever housekeeping is due) is dropped
    // live; the store keeps them all.
    let _ = link::drain(&TM, &mut tm_bytes);
    let junk = [0x11u8; config::TM_DOWNLINK_BYTES - 10];
    link::push_bytes(&TM, &junk, &STATS[1]);
    let stored_before = obsw.param::<{ pid::TM_STORED }>();
    let n = ok!(crate::t_packets::build(6, 17, 1, &[], &mut tc));
    let m = ok!(encode(&tc[..n], &mut frame));
    link::uplink_bytes(&mut uplink, &frame[..m], &TCS, &STATS[0]);
    step(&mut cycle, &mut obsw, &mut io);
    let produced = (obsw.param::<{ pid::TM_STORED }>() - stored_before) as u32;
    check!(produced >= 4, "{} packets in the jammed period", produced);
    let _ = link::drain(&TM, &mut tm_bytes);
    // Two clean periods, then the one-shot report of SID 5.
    for _ in 0..2 {
        step(&mut cycle, &mut obsw, &mut io);
    }
    let _ = link::drain(&TM, &mut tm_bytes);
    let n = ok!(crate::t_packets::build(
        7,
        3,
        27,
        &mib::hk::sid::PLATFORM_IO.to_be_bytes(),
        &mut tc
    ));
    let m = ok!(encode(&tc[..n], &mut frame));
    link::uplink_bytes(&mut uplink, &frame[..m], &TCS, &STATS[0]);
    step(&mut cycle, &mut obsw, &mut io);
    let n = link::drain(&TM, &mut tm_bytes);
    let mut deframer: Deframer<{ config::MAX_PACKET_LEN }> = Deframer::new();
    let mut report = None;
    for &byte in &tm_bytes[..n] {
        let Some(f) = deframer.push(byte) else { continue };
        let r = ok!(PusTmReader::new(ok!(f), mib::config::TIMESTAMP_LEN));
        if (PusPacket::service_type_id(&r), PusPacket::message_subtype_id(&r)) == (3, 25) {
            let mut d: heapless::Vec<u8, 64> = heapless::Vec::new();
            check!(d.extend_from_slice(r.user_data()).is_ok());
            report = Some(d);
        }
    }
    let data = ok!(report);
    let hk = ok!(mib_wire::codec::decode_hk(&data));
    check_eq!(hk.def.sid, mib::hk::sid::PLATFORM_IO);
    // The values as the ground reads them: u32 each after the SID (ICD section 5).
    // The stack's high-water mark is the image's (fw_core::stack): 0 without one.
    let want = [3u32, produced, 18, 2, 88, 0];
    check_eq!(data.len(), 2 + 4 * want.len());
    for (i, w) in want.iter().enumerate() {
        let off = 2 + 4 * i;
        let got = u32::from_be_bytes([data[off], data[off + 1], data[off + 2], data[off + 3]]);
        check_eq!(got, *w, "word {}", i);
    }
    check_eq!(
        (
            hk.get(pid::IO_TC_DROPPED),
            hk.get(pid::IO_TM_DROPPED),
            hk.get(pid::IO_SENSOR_ERRORS),
            hk.get(pid::IO_OUTPUT_ERRORS),
            hk.get(pid::IO_AB_BYTES_DROPPED),
        ),
        (Some(3), Some(produced as i64), Some(18), Some(2), Some(88))
    );
    // The firmware's own counts agree.
    check_eq!(
        (cycle.errors.adc, cycle.errors.total(), cycle.output_errors),
        (18, 18, 2)
    );
    check_eq!(STATS[1].get().overflow, produced);
    Ok(())
}
