//! ams AS5600 12-bit magnetic absolute encoder on I2C (the hip angle).

use super::{AngleSensor, HwError};
use embedded_hal::i2c::I2c;

/// Register map (subset).
pub mod reg {
    pub const RAW_ANGLE_H: u8 = 0x0C;
    pub const STATUS: u8 = 0x0B;
}
/// STATUS bit: magnet detected.
pub const STATUS_MD: u8 = 0x20;
/// Counts per revolution.
pub const COUNTS: i32 = 4096;

/// Converts a raw count to hundredths of a degree relative to `zero` (the count read
/// with the hip at its contracted angle), wrapped into −18000..18000.
pub const fn counts_to_cdeg(raw: u16, zero: u16) -> i16 {
    let d = (raw as i32 - zero as i32).rem_euclid(COUNTS);
    let d = if d >= COUNTS / 2 { d - COUNTS } else { d };
    // 36000 cdeg per COUNTS, rounded to nearest
    let v = d * 36000;
    let r = if v >= 0 {
        (v + COUNTS / 2) / COUNTS
    } else {
        (v - COUNTS / 2) / COUNTS
    };
    r as i16
}

pub struct As5600<I> {
    i2c: I,
    addr: u8,
    zero: u16,
}

impl<I: I2c> As5600<I> {
    /// `zero` is the raw count at the contracted hip angle (calibrated at integration).
    pub fn new(i2c: I, addr: u8, zero: u16) -> Self {
        Self {
            i2c,
            addr,
            zero: zero & 0x0FFF,
        }
    }

    /// Raw 12-bit angle; fails when no magnet is detected.
    pub fn raw(&mut self) -> Result<u16, HwError> {
        let mut st = [0u8];
        self.i2c
            .write_read(self.addr, &[reg::STATUS], &mut st)
            .map_err(|_| HwError::Bus)?;
        if st[0] & STATUS_MD == 0 {
            return Err(HwError::Driver);
        }
        let mut b = [0u8; 2];
        self.i2c
            .write_read(self.addr, &[reg::RAW_ANGLE_H], &mut b)
            .map_err(|_| HwError::Bus)?;
        Ok(u16::from_be_bytes(b) & 0x0FFF)
    }

    pub fn release(self) -> I {
        self.i2c
    }
}

impl<I: I2c> AngleSensor for As5600<I> {
    fn angle_cdeg(&mut self) -> Result<i16, HwError> {
        let raw = self.raw()?;
        Ok(counts_to_cdeg(raw, self.zero))
    }
}
