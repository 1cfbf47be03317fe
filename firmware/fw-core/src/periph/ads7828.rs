//! TI ADS7828: 12-bit, 8-channel I2C ADC (battery voltage, regulated voltage, currents).

use super::{AnalogInput, HwError};
use embedded_hal::i2c::I2c;

/// Power-down selection bits PD1..PD0 (bits 3..2 of the command byte).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PowerMode {
    /// Power down between conversions (external reference).
    PowerDown = 0b00,
    /// Internal reference off, converter on.
    RefOffAdcOn = 0b01,
    /// Internal reference on, converter powered down between conversions.
    RefOnAdcOff = 0b10,
    /// Internal 2.5 V reference on, converter on.
    RefOnAdcOn = 0b11,
}

/// Command byte for a single-ended conversion of `channel` (0..=7):
/// `SD=1 | C2 C1 C0 | PD1 PD0 | x x`. The datasheet's channel-select code for single-ended
/// inputs interleaves even and odd channels: CH0=000, CH1=100, CH2=001, CH3=101, ...
pub const fn command_byte(channel: u8, pd: PowerMode) -> Option<u8> {
    if channel > 7 {
        return None;
    }
    let sel = (channel >> 1) | ((channel & 1) << 2);
    Some(0x80 | (sel << 4) | ((pd as u8) << 2))
}

/// Driver over any `embedded-hal` 1.0 I2C bus.
pub struct Ads7828<I> {
    i2c: I,
    addr: u8,
    pd: PowerMode,
}

impl<I: I2c> Ads7828<I> {
    pub fn new(i2c: I, addr: u8, pd: PowerMode) -> Self {
        Self { i2c, addr, pd }
    }

    pub fn release(self) -> I {
        self.i2c
    }

    /// The bus the converter sits on (bus recovery; test doubles).
    pub fn bus_mut(&mut self) -> &mut I {
        &mut self.i2c
    }
}

impl<I: I2c> AnalogInput for Ads7828<I> {
    fn read_raw(&mut self, channel: u8) -> Result<u16, HwError> {
        let cmd = command_byte(channel, self.pd).ok_or(HwError::OutOfRange)?;
        let mut rx = [0u8; 2];
        self.i2c
            .write_read(self.addr, &[cmd], &mut rx)
            .map_err(|_| HwError::Bus)?;
        // 12-bit result, MSB first, the top four bits are zero.
        Ok(u16::from_be_bytes(rx) & 0x0FFF)
    }
}
