//! fw-core's link queues, sensor sampling and output mapping: the glue between the
//! drivers and the OBSW, exercised with in-memory queues and mock peripherals.

use crate::harness::{Test, TestResult};
use crate::mock::{MockI2c, MockPin, MockPwm};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::config;
use fw_core::link::{self, ByteQueue, Counters, TcChannel};
use fw_core::periph::ads7828::PowerMode;
use fw_core::periph::servo::hip_pulse;
use fw_core::periph::side::bolter_pulses;
use fw_core::periph::{
    ActiveLowSwitch, Ads7828, AngleSensor, BolterMux, BolterServos, GravitySensor, HwError, PwmServo, SideOutputs,
};
use fw_core::sampling::{sample_a, SensorErrors};
use mmic_domain::{BolterDrive, SensorsA, SideActuators};
use mmic_stream::{encode, Deframer};

pub const TESTS: &[Test] = tests![
    uplink_delivers_each_tc_and_counts_drops,
    downlink_queues_whole_frames_or_nothing,
    downlink_frame_wrapping_around_the_ring_stays_whole,
    byte_queue_overflow_is_counted,
    sampling_keeps_last_value_of_a_failed_channel,
    side_outputs_follow_domain_commands,
    hip_speed_to_pulse_is_linear_and_saturates,
];

fn uplink_delivers_each_tc_and_counts_drops() -> TestResult {
    let tcs = TcChannel::new();
    let stats = Counters::new();
    let mut d: Deframer<{ config::GROUND_RX_BUF }> = Deframer::new();
    let mut wire = [0u8; 512];
    let mut n = 0;
    for i in 0..(config::TC_QUEUE_DEPTH as u8 + 2) {
        n += ok!(encode(&[0x18, 0x01, i, 0x00, 0x00], &mut wire[n..]));
    }
    wire[n..n + 3].copy_from_slice(&[0x04, 0x11, 0x00]); // cut frame
    n += 3;
    // Arrives in arbitrary chunks.
    for chunk in wire[..n].chunks(7) {
        link::uplink_bytes(&mut d, chunk, &tcs, &stats);
    }
    let s = stats.get();
    check_eq!(s.delivered, config::TC_QUEUE_DEPTH as u32);
    check_eq!(s.overflow, 2);
    check_eq!(s.frame_errors, 1);
    for i in 0..config::TC_QUEUE_DEPTH as u8 {
        let tc = ok!(tcs.try_receive());
        check_eq!(&tc[..], &[0x18, 0x01, i, 0x00, 0x00][..]);
    }
    check!(tcs.try_receive().is_err());
    Ok(())
}

fn downlink_queues_whole_frames_or_nothing() -> TestResult {
    let q: ByteQueue<64> = ByteQueue::new();
    let stats = Counters::new();
    let packet = [0x08u8, 0x01, 0xC0, 0x00, 0x00, 0x10, 0x20, 0x00, 0x11];
    check!(link::downlink_packet(&q, &packet, &stats));
    check!(link::downlink_packet(&q, &packet, &stats));
    let used = q.len();
    // COBS adds one overhead byte to a short packet, plus the two delimiters.
    check_eq!(used, 2 * (packet.len() + 3));
    let big = [0x55u8; 60];
    check!(
        !link::downlink_packet(&q, &big, &stats),
        "a frame larger than the room went in"
    );
    check_eq!(q.len(), used);
    check_eq!(stats.get().overflow, 1);
    let mut out = [0u8; 64];
    let n = link::drain(&q, &mut out);
    check_eq!(n, used);
    let mut d: Deframer<64> = Deframer::new();
    let mut frames = 0;
    for &b in &out[..n] {
        if let Some(r) = d.push(b) {
            check_eq!(ok!(r), &packet[..]);
            frames += 1;
        }
    }
    check_eq!(frames, 2);
    Ok(())
}

/// Regression: a ring buffer hands out contiguous space only; a frame that wraps around
/// its end must still go in whole (found by the firmware-on-simulator test).
fn downlink_frame_wrapping_around_the_ring_stays_whole() -> TestResult {
    let q: ByteQueue<64> = ByteQueue::new();
    let stats = Counters::new();
    let small = [0x11u8; 9]; // 12-byte frames
    for _ in 0..4 {
        check!(link::downlink_packet(&q, &small, &stats));
    }
    // The transmitter takes 40 bytes: 8 left at offsets 40..48, 16 free up to the end.
    let mut out = [0u8; 96];
    let mut taken = 0;
    while taken < 40 {
        taken += ok!(q.try_read(&mut out[taken..40]));
    }
    let big = [0x22u8; 21]; // 24-byte frame: wraps around the end of the ring
    check!(link::downlink_packet(&q, &big, &stats));
    check_eq!(q.len(), 8 + 24);
    let n = link::drain(&q, &mut out[40..]);
    check_eq!(n, 32);
    let mut d: Deframer<64> = Deframer::new();
    let mut frames: heapless::Vec<heapless::Vec<u8, 32>, 8> = heapless::Vec::new();
    for &b in &out[..40 + n] {
        if let Some(r) = d.push(b) {
            let _ = frames.push(ok!(heapless::Vec::from_slice(ok!(r))));
        }
    }
    check_eq!(frames.len(), 5);
    check_eq!(&frames[4][..], &big[..]);
    check_eq!(stats.get().overflow, 0);
    Ok(())
}

fn byte_queue_overflow_is_counted() -> TestResult {
    let q: ByteQueue<16> = ByteQueue::new();
    let stats = Counters::new();
    link::push_bytes(&q, &[1; 10], &stats);
    link::push_bytes(&q, &[2; 10], &stats);
    check_eq!(q.len(), 16);
    check_eq!(stats.get().overflow, 4);
    check_eq!(stats.get().delivered, 1);
    let mut out = [0u8; 32];
    check_eq!(link::drain(&q, &mut out), 16);
    check_eq!(&out[..10], &[1; 10][..]);
    check_eq!(&out[10..16], &[2; 6][..]);
    Ok(())
}

struct FlakyImu(u32);
impl GravitySensor for FlakyImu {
    fn gravity_mg(&mut self) -> Result<[i16; 3], HwError> {
        self.0 += 1;
        if self.0.is_multiple_of(2) {
            Err(HwError::Bus)
        } else {
            Ok([self.0 as i16, -1000, 0])
        }
    }
}
struct FixedHip(i16);
impl AngleSensor for FixedHip {
    fn angle_cdeg(&mut self) -> Result<i16, HwError> {
        Ok(self.0)
    }
}

fn sampling_keeps_last_value_of_a_failed_channel() -> TestResult {
    let mut bus = MockI2c::new(0x48);
    // V_BAT ch0 = 3000, V_REG ch1 = 2020, I_BAT ch2 = 700, I_LOC ch3 = 120,
    // I_GRIP ch4 = 80, I_BO ch5 = 40 (command bytes from the ADS7828 table).
    for (cmd, v) in [
        (0x8Cu8, 3000u16),
        (0xCC, 2020),
        (0x9C, 700),
        (0xDC, 120),
        (0xAC, 80),
        (0xEC, 40),
    ] {
        let _ = bus.replies.push((cmd, v.to_be_bytes()));
    }
    let mut adc = Ads7828::new(bus, 0x48, PowerMode::RefOnAdcOn);
    let mut imu = FlakyImu(0);
    let mut hip = FixedHip(-250);
    let mut sw = ActiveLowSwitch(MockPin {
        high: false,
        changes: 0,
    });
    let mut s = SensorsA::default();
    let mut e = SensorErrors::default();
    sample_a(&mut adc, &mut imu, &mut hip, &mut sw, &mut s, &mut e);
    check_eq!(
        (s.v_bat, s.v_reg, s.i_bat, s.i_loc, s.i_grip, s.i_bo),
        (3000, 2020, 700, 120, 80, 40)
    );
    check_eq!(s.grav, [1, -1000, 0]);
    check_eq!(s.hip_cdeg, -250);
    check!(s.arm_switch);
    // Second cycle: the IMU fails, its last value stays; the ADC bus fails too.
    let mut bus = adc.release();
    bus.fail = true;
    let mut adc = Ads7828::new(bus, 0x48, PowerMode::RefOnAdcOn);
    sample_a(&mut adc, &mut imu, &mut hip, &mut sw, &mut s, &mut e);
    check_eq!(s.grav, [1, -1000, 0]);
    check_eq!(s.v_bat, 3000);
    check_eq!((e.imu, e.adc, e.encoder, e.switch), (1, 6, 0, 0));
    check_eq!(e.last, Some(HwError::Bus));
    Ok(())
}

fn side_outputs_follow_domain_commands() -> TestResult {
    let pwm = || PwmServo::new(MockPwm { max: 16384, duty: 0 });
    let mut side = SideOutputs {
        arm: pwm(),
        grip: pwm(),
        bolter: BolterServos {
            translate: pwm(),
            rotate: pwm(),
        },
        mux: BolterMux::new(MockPin::default(), MockPin::default()),
    };
    let cmd = SideActuators {
        arm_pwm: Some(2000),
        grip_pwm: None,
        bolter: BolterDrive::RotateLock,
    };
    ok!(side.apply(&cmd, 3));
    check_eq!(side.arm.last_us(), 2000);
    check_eq!(side.grip.last_us(), 0);
    let (t, r) = ok!(bolter_pulses(BolterDrive::RotateLock));
    check_eq!((side.bolter.translate.last_us(), side.bolter.rotate.last_us()), (t, r));
    // Locking pushes and turns: both drives away from standstill.
    check!(t != config::bolter_servo::STOP_US && r != config::bolter_servo::STOP_US);
    check_eq!(side.mux.code(), Some(3));
    check!(bolter_pulses(BolterDrive::Off).is_none());
    ok!(side.apply(&SideActuators::default(), 0));
    check_eq!((side.arm.last_us(), side.bolter.translate.last_us()), (0, 0));
    Ok(())
}

fn hip_speed_to_pulse_is_linear_and_saturates() -> TestResult {
    let max = mmic_domain::consts::HIP_MAX_CMD_CDEG_S;
    check_eq!(hip_pulse(0), 1500);
    check_eq!(hip_pulse(max), 2000);
    check_eq!(hip_pulse(-max), 1000);
    check_eq!(hip_pulse(max / 2), 1750);
    check_eq!(hip_pulse(i16::MAX), 2000);
    check_eq!(hip_pulse(i16::MIN), 1000);
    // Paper: 10 deg/s in velocity mode.
    let v = mib::robot::servo::HIP_SPEED_CDEG_S;
    check_eq!(
        hip_pulse(v) as i32,
        1500 + (v as i32 * 500 + max as i32 / 2) / max as i32
    );
    Ok(())
}
