//! InvenSense MPU-6000 IMU on I2C: the accelerometer gives the gravity vector.

use super::{GravitySensor, HwError};
use embedded_hal::i2c::I2c;

/// Register map (subset).
pub mod reg {
    pub const ACCEL_CONFIG: u8 = 0x1C;
    pub const ACCEL_XOUT_H: u8 = 0x3B;
    pub const PWR_MGMT_1: u8 = 0x6B;
    pub const WHO_AM_I: u8 = 0x75;
}
/// WHO_AM_I value of the MPU-6000/6050.
pub const WHO_AM_I_VALUE: u8 = 0x68;
/// PWR_MGMT_1: wake up, clock from the X gyro PLL.
pub const PWR_CLK_PLL_X: u8 = 0x01;
/// ACCEL_CONFIG full scale ±2 g (AFS_SEL = 0): 16384 LSB/g.
pub const ACCEL_FS_2G: u8 = 0x00;
pub const LSB_PER_G: i32 = 16384;

/// Converts a raw ±2 g accelerometer sample to milli-g (rounded to nearest).
pub const fn raw_to_mg(raw: i16) -> i16 {
    let v = raw as i32 * 1000;
    let r = if v >= 0 {
        (v + LSB_PER_G / 2) / LSB_PER_G
    } else {
        (v - LSB_PER_G / 2) / LSB_PER_G
    };
    r as i16
}

pub struct Mpu6000<I> {
    i2c: I,
    addr: u8,
}

impl<I: I2c> Mpu6000<I> {
    /// Checks the identity, wakes the device and selects ±2 g.
    pub fn init(mut i2c: I, addr: u8) -> Result<Self, (HwError, I)> {
        let mut who = [0u8];
        if i2c.write_read(addr, &[reg::WHO_AM_I], &mut who).is_err() {
            return Err((HwError::Bus, i2c));
        }
        if who[0] != WHO_AM_I_VALUE {
            return Err((
                HwError::WrongDevice {
                    expected: WHO_AM_I_VALUE,
                    got: who[0],
                },
                i2c,
            ));
        }
        let setup = i2c
            .write(addr, &[reg::PWR_MGMT_1, PWR_CLK_PLL_X])
            .and_then(|_| i2c.write(addr, &[reg::ACCEL_CONFIG, ACCEL_FS_2G]));
        if setup.is_err() {
            return Err((HwError::Bus, i2c));
        }
        Ok(Self { i2c, addr })
    }

    pub fn release(self) -> I {
        self.i2c
    }
}

impl<I: I2c> GravitySensor for Mpu6000<I> {
    fn gravity_mg(&mut self) -> Result<[i16; 3], HwError> {
        let mut b = [0u8; 6];
        self.i2c
            .write_read(self.addr, &[reg::ACCEL_XOUT_H], &mut b)
            .map_err(|_| HwError::Bus)?;
        Ok([
            raw_to_mg(i16::from_be_bytes([b[0], b[1]])),
            raw_to_mg(i16::from_be_bytes([b[2], b[3]])),
            raw_to_mg(i16::from_be_bytes([b[4], b[5]])),
        ])
    }
}
