//! The boards' control periods (`fw_core::cycle`), the code the images run every 10 ms,
//! on mock peripherals: board A's OBSW and board B wired through the same byte queues
//! the UART tasks fill, commanded over the ground uplink queue.

use crate::harness::{Test, TestResult};
use crate::mock::{MockI2c, MockPin, MockPwm};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::config::{self, i2c_addr};
use fw_core::cycle::{CycleA, CycleB, LinksA, LinksB, PeripheralsA, PeripheralsB};
use fw_core::framing::{encode_frame, Deframer};
use fw_core::link::{self, ByteQueue, Counters, TcChannel};
use fw_core::periph::ads7828::PowerMode;
use fw_core::periph::{
    ActiveLowEnable, ActiveLowSwitch, Ads7828, As5600, BolterMux, BolterServos, Mpu6000, PwmServo, SideOutputs,
};
use mib::events::eid;
use mib::modes::{node, robot_mode};
use mib::robot::servo;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::RingStore;
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::PusPacket;

pub const TESTS: &[Test] = tests![boards_a_and_b_cycles_go_operational_on_a_ground_command];

type Servo = PwmServo<MockPwm>;
type Side = SideOutputs<Servo, Servo, Servo, Servo, BolterMux<MockPin, MockPin>>;

fn servo() -> Servo {
    PwmServo::new(MockPwm { max: 1 << 14, duty: 0 })
}

fn side() -> Side {
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

fn boards_a_and_b_cycles_go_operational_on_a_ground_command() -> TestResult {
    static TCS: TcChannel = TcChannel::new();
    static TM: ByteQueue<{ config::TM_DOWNLINK_BYTES }> = ByteQueue::new();
    static A_RX: ByteQueue<{ config::AB_RX_BYTES }> = ByteQueue::new();
    static A_TX: ByteQueue<{ config::AB_TX_BYTES }> = ByteQueue::new();
    static B_RX: ByteQueue<{ config::AB_RX_BYTES }> = ByteQueue::new();
    static B_TX: ByteQueue<{ config::AB_TX_BYTES }> = ByteQueue::new();
    static STATS: [Counters; 4] = [Counters::new(), Counters::new(), Counters::new(), Counters::new()];

    // V_bat 11.7 V, V_reg 7.4 V, small currents.
    let mut enc_bus = MockI2c::new(i2c_addr::AS5600);
    enc_bus.regs[0x0B] = 0x20; // magnet detected
    enc_bus.regs[0x0C] = 0x01;
    enc_bus.regs[0x0D] = 0x00; // raw 256 = the calibrated zero below
    let mut io_a = PeripheralsA {
        adc: adc([3200, 2020, 300, 50, 20, 0]),
        imu: imu(),
        hip_encoder: As5600::new(enc_bus, i2c_addr::AS5600, 256),
        arm_switch: ActiveLowSwitch(MockPin {
            high: false,
            changes: 0,
        }),
        side: side(),
        hip: servo(),
        regulator: ActiveLowEnable(MockPin { high: true, changes: 0 }),
    };
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
        tm: &TM,
        tm_stats: &STATS[0],
        ab_rx: &A_RX,
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
            let m = ok!(encode_frame(&tc[..n], &mut frame));
            link::uplink_bytes(&mut uplink, &frame[..m], &TCS, &STATS[3]);
        }
        act = a.run(t, &mut obsw, &mut io_a, &links_a);
        b.run(t, &mut io_b, &links_b);
        // The UARTs: whatever each side queued arrives at the other.
        let n = link::drain(&A_TX, &mut wire);
        link::push_bytes(&B_RX, &wire[..n], &STATS[2]);
        let n = link::drain(&B_TX, &mut wire);
        link::push_bytes(&A_RX, &wire[..n], &STATS[1]);
        // The downlink.
        let n = link::drain(&TM, &mut tm_bytes);
        for &byte in &tm_bytes[..n] {
            let Some(frame) = deframer.push(byte) else { continue };
            let r = ok!(PusTmReader::new(ok!(frame), mib::config::TIMESTAMP_LEN));
            tm_count += 1;
            match (PusPacket::service_type_id(&r), PusPacket::message_subtype_id(&r)) {
                (1, 7) => completed = completed.or(Some(t)),
                (5, 1) => {
                    if let Ok(ev) = mib::codec::decode_event(r.user_data()) {
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
    check_eq!((STATS[1].get().overflow, STATS[2].get().overflow), (0, 0));
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
    check_eq!(obsw.param(mib::params::pid::V_BAT_B), 3200);
    check_eq!(
        (a.errors.total(), b.errors.total(), a.output_errors, b.output_errors),
        (0, 0, 0, 0)
    );
    Ok(())
}
