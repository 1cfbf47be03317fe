//! Peripheral drivers of fw-core against mock buses: the bytes on the wire and the
//! conversions, checked against the datasheets' tables.

use crate::harness::{Test, TestResult};
use crate::mock::{MockI2c, MockPin, MockPwm};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::periph::ads7828::{self, PowerMode};
use fw_core::periph::{
    as5600, mpu6000, ActiveLowSwitch, Ads7828, AnalogInput, AngleSensor, As5600, BolterMux, GravitySensor, HwError,
    Mpu6000, PairSelect, PwmServo, ServoOutput, Switch,
};

pub const TESTS: &[Test] = tests![
    ads7828_command_bytes_follow_datasheet_table,
    ads7828_reads_12_bit_result,
    mpu6000_init_sequence_and_gravity_in_mg,
    mpu6000_wrong_identity_is_an_error,
    as5600_angle_wraps_around_zero,
    as5600_missing_magnet_is_an_error,
    servo_pulse_to_ledc_duty,
    bolter_mux_selects_pairs_1_to_4,
    arm_switch_is_active_low,
];

fn ads7828_command_bytes_follow_datasheet_table() -> TestResult {
    // ADS7828 datasheet, single-ended channel selection (SD=1, C2 C1 C0), PD = 11.
    let table: [(u8, u8); 8] = [
        (0, 0b1000_1100),
        (1, 0b1100_1100),
        (2, 0b1001_1100),
        (3, 0b1101_1100),
        (4, 0b1010_1100),
        (5, 0b1110_1100),
        (6, 0b1011_1100),
        (7, 0b1111_1100),
    ];
    for (ch, byte) in table {
        check_eq!(
            ads7828::command_byte(ch, PowerMode::RefOnAdcOn),
            Some(byte),
            "ch {}",
            ch
        );
    }
    check_eq!(ads7828::command_byte(3, PowerMode::RefOffAdcOn), Some(0b1101_0100));
    check_eq!(ads7828::command_byte(8, PowerMode::RefOnAdcOn), None);
    Ok(())
}

fn ads7828_reads_12_bit_result() -> TestResult {
    let mut bus = MockI2c::new(0x48);
    // V_BAT channel 0 answers 0x0AAA (2730 counts = 10.0 V); garbage in the top nibble
    // must be masked off.
    let _ = bus.replies.push((0x8C, [0xFA, 0xAA]));
    let _ = bus.replies.push((0xCC, [0x01, 0x00]));
    let mut adc = Ads7828::new(bus, 0x48, PowerMode::RefOnAdcOn);
    check_eq!(adc.read_raw(0), Ok(2730));
    check_eq!(adc.read_raw(1), Ok(256));
    check_eq!(adc.read_raw(9), Err(HwError::OutOfRange));
    let mut bus = adc.release();
    check_eq!(&bus.writes[0][..], &[0x8C][..]);
    bus.fail = true;
    let mut adc = Ads7828::new(bus, 0x48, PowerMode::RefOnAdcOn);
    check_eq!(adc.read_raw(0), Err(HwError::Bus));
    Ok(())
}

fn mpu6000_init_sequence_and_gravity_in_mg() -> TestResult {
    check_eq!(mpu6000::raw_to_mg(16384), 1000);
    check_eq!(mpu6000::raw_to_mg(-16384), -1000);
    check_eq!(mpu6000::raw_to_mg(8192), 500);
    check_eq!(mpu6000::raw_to_mg(-8), 0);
    check_eq!(mpu6000::raw_to_mg(i16::MIN), -2000);
    let mut bus = MockI2c::new(0x68);
    bus.regs[0x75] = 0x68;
    // x = 0, y = -1 g, z = +0.5 g
    bus.regs[0x3B..0x41].copy_from_slice(&[0x00, 0x00, 0xC0, 0x00, 0x20, 0x00]);
    let mut imu = match Mpu6000::init(bus, 0x68) {
        Ok(i) => i,
        Err((e, _)) => {
            return Err(crate::harness::Failure::new(
                file!(),
                line!(),
                format_args!("init: {}", e),
            ))
        }
    };
    check_eq!(imu.gravity_mg(), Ok([0, -1000, 500]));
    let bus = imu.release();
    check_eq!(bus.regs[0x6B], 0x01);
    check_eq!(bus.regs[0x1C], 0x00);
    check!(bus.writes.iter().any(|w| w[..] == [0x6B, 0x01]));
    Ok(())
}

fn mpu6000_wrong_identity_is_an_error() -> TestResult {
    let mut bus = MockI2c::new(0x68);
    bus.regs[0x75] = 0x70;
    match Mpu6000::init(bus, 0x68) {
        Ok(_) => Err(crate::harness::Failure::new(
            file!(),
            line!(),
            format_args!("accepted id 0x70"),
        )),
        Err((e, _)) => {
            check_eq!(
                e,
                HwError::WrongDevice {
                    expected: 0x68,
                    got: 0x70
                }
            );
            Ok(())
        }
    }
}

fn as5600_angle_wraps_around_zero() -> TestResult {
    check_eq!(as5600::counts_to_cdeg(1024, 0), 9000);
    check_eq!(as5600::counts_to_cdeg(3072, 0), -9000);
    check_eq!(as5600::counts_to_cdeg(2048, 0), -18000);
    // 196 counts past a zero at 4000, across the wrap: 196 * 36000 / 4096 = 1722.66
    check_eq!(as5600::counts_to_cdeg(100, 4000), 1723);
    check_eq!(as5600::counts_to_cdeg(4000, 100), -1723);
    let mut bus = MockI2c::new(0x36);
    bus.regs[0x0B] = 0x20;
    bus.regs[0x0C] = 0x04;
    bus.regs[0x0D] = 0x00; // 1024
    let mut e = As5600::new(bus, 0x36, 0);
    check_eq!(e.angle_cdeg(), Ok(9000));
    Ok(())
}

fn as5600_missing_magnet_is_an_error() -> TestResult {
    let mut bus = MockI2c::new(0x36);
    bus.regs[0x0B] = 0x00;
    let mut e = As5600::new(bus, 0x36, 0);
    check!(e.angle_cdeg().is_err());
    Ok(())
}

fn servo_pulse_to_ledc_duty() -> TestResult {
    // 14-bit LEDC duty, 20 ms frame: 1500 us -> 1500 / 20000 * 16383 = 1228.7
    check_eq!(fw_core::periph::servo::duty_for_pulse(1500, 16383), 1229);
    check_eq!(fw_core::periph::servo::duty_for_pulse(1000, 16383), 819);
    // Clamped to the MIB's 900..2100 us.
    check_eq!(fw_core::periph::servo::duty_for_pulse(100, 16383), 737);
    check_eq!(fw_core::periph::servo::duty_for_pulse(3000, 16383), 1720);
    let mut s = PwmServo::new(MockPwm { max: 16383, duty: 0 });
    ok!(s.set_pulse_us(mib::robot::servo::ARM_EXTENDED_US));
    check_eq!(s.last_us(), 2000);
    ok!(s.release());
    check_eq!(s.last_us(), 0);
    Ok(())
}

fn bolter_mux_selects_pairs_1_to_4() -> TestResult {
    let mut m = BolterMux::new(MockPin::default(), MockPin::default());
    // Pair n is select code n-1 on (A0, A1), as the domain computes it.
    let expect = [(1, false, false), (2, true, false), (3, false, true), (4, true, true)];
    for (pair, a0, a1) in expect {
        let bits = mmic_domain::types::mux_bits(pair);
        ok!(m.select(bits));
        check_eq!(m.code(), Some(pair - 1));
        check_eq!(fw_core::periph::mux::mux_levels(bits), Some((a0, a1)));
    }
    check_eq!(m.select(4), Err(HwError::OutOfRange));
    check_eq!(m.code(), Some(3));
    Ok(())
}

fn arm_switch_is_active_low() -> TestResult {
    let mut s = ActiveLowSwitch(MockPin { high: true, changes: 0 });
    check_eq!(s.is_pushed(), Ok(false));
    s.0.high = false;
    check_eq!(s.is_pushed(), Ok(true));
    Ok(())
}
