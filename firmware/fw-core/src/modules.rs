//! Module discovery on the boards (docs/modules.md): each board's descriptor table in flash and
//! the probes that confirm it on the hardware.
//!
//! Board A reads [`TABLE_A`] and probes its side (MPU-6000 `WHO_AM_I`, ADS7828 and
//! AS5600 acknowledge, the arm-switch line), then hands both to
//! `obsw_core::obsw::Obsw::start_discovery`; board B probes its side and hands
//! [`TABLE_B`] and its probes to `mmic_domain::board_b::BoardB::set_modules`, which sends
//! them to A over the A–B link. The discovery itself (which set, which configuration,
//! why it is invalid) is `mmic_domain::discovery`, the same code the host runs.
//!
//! Probe addresses come from the MIB's slot table (`mib::modules::SLOTS[..].port`), so
//! the descriptor a table lists and the address probed cannot disagree.

use crate::periph::mpu6000::reg::WHO_AM_I;
use crate::periph::HwError;
use embedded_hal::i2c::I2c;
use mib::modules::{slot, SLOTS};
use mmic_domain::discovery::{ArmSwitch, BoardProbes};
use obsw_core::services::modules::AcceptedConfig;

include!(concat!(env!("OUT_DIR"), "/module_tables.rs"));

/// The module configuration accepted at integration: the set [`TABLE_A`] and
/// [`TABLE_B`] describe. Board A has no store for the ground's later ACCEPT_CONFIG yet,
/// so this is what discovery compares against at every boot (a set that differs from the
/// tables' raises MODULE_REPLACED and blocks OPERATIONAL until the ground accepts it).
pub fn integrated_config() -> AcceptedConfig {
    AcceptedConfig::of(&mib::modules::default_set(SERIAL_BASE))
}

/// A GPIO input whose internal pull resistor can be switched (the arm-switch line).
///
/// The arm module carries its own pull-up on the switch line (switch to ground): a
/// connected arm reads high when released and low when pushed whatever the internal
/// pull; an unconnected line follows the internal pull. Toggling the pull therefore
/// tells "released" from "absent".
pub trait PullProbe {
    /// Level of the line (`true` = high) with the internal pull-up (`pull_up`) or
    /// pull-down selected, after it settled.
    fn level_with_pull(&mut self, pull_up: bool) -> Result<bool, HwError>;
}

/// The arm-switch line's state, from its level under each internal pull. The pull-up is
/// selected again at the end (the switch's run-time configuration). A read error or a
/// line that follows the pull is [`ArmSwitch::Absent`].
pub fn arm_switch<P: PullProbe>(line: &mut P) -> ArmSwitch {
    let down = line.level_with_pull(false);
    let up = line.level_with_pull(true);
    match (down, up) {
        (Ok(false), Ok(false)) => ArmSwitch::Pushed,
        (Ok(true), Ok(true)) => ArmSwitch::Released,
        // Follows the pull (or reads against it, or fails): nothing the module drives.
        (Ok(_), Ok(_)) | (Err(_), _) | (_, Err(_)) => ArmSwitch::Absent,
    }
}

/// `WHO_AM_I` of the MPU-6000 at `addr`; `None` when it does not answer.
pub fn who_am_i<I: I2c>(i2c: &mut I, addr: u8) -> Option<u8> {
    let mut who = [0u8];
    i2c.write_read(addr, &[WHO_AM_I], &mut who).ok().map(|()| who[0])
}

/// The ADS7828 at `addr` acknowledges: one conversion of channel 0 (command byte, then
/// the two result bytes), the same transaction the sampling does.
pub fn adc_acks<I: I2c>(i2c: &mut I, addr: u8) -> bool {
    let cmd = crate::periph::ads7828::command_byte(0, crate::periph::ads7828::PowerMode::RefOnAdcOn);
    let mut r = [0u8; 2];
    cmd.is_some_and(|c| i2c.write_read(addr, &[c], &mut r).is_ok())
}

/// The AS5600 at `addr` acknowledges: a read of its STATUS register (magnet or not).
pub fn encoder_acks<I: I2c>(i2c: &mut I, addr: u8) -> bool {
    let mut st = [0u8];
    i2c.write_read(addr, &[crate::periph::as5600::reg::STATUS], &mut st)
        .is_ok()
}

/// Board A's probes at boot (IMU, ADC, hip encoder, arm switch), on each device's bus.
pub fn probe_a<Imu: I2c, Adc: I2c, Enc: I2c, Sw: PullProbe>(
    imu: &mut Imu,
    adc: &mut Adc,
    enc: &mut Enc,
    arm_switch: &mut Sw,
) -> BoardProbes {
    BoardProbes {
        imu_who_am_i: who_am_i(imu, SLOTS[slot::IMU_A as usize].port),
        adc_ack: adc_acks(adc, SLOTS[slot::ADC_A as usize].port),
        encoder_ack: encoder_acks(enc, SLOTS[slot::ENCODER as usize].port),
        arm_switch: self::arm_switch(arm_switch),
    }
}

/// Board B's probes at boot (IMU, ADC, arm switch; B has no encoder).
pub fn probe_b<Imu: I2c, Adc: I2c, Sw: PullProbe>(imu: &mut Imu, adc: &mut Adc, arm_switch: &mut Sw) -> BoardProbes {
    BoardProbes {
        imu_who_am_i: who_am_i(imu, SLOTS[slot::IMU_B as usize].port),
        adc_ack: adc_acks(adc, SLOTS[slot::ADC_B as usize].port),
        encoder_ack: false,
        arm_switch: self::arm_switch(arm_switch),
    }
}
