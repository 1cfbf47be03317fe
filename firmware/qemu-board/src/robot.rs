//! The robot's side of the boards' peripherals, for the QEMU board: each device answers
//! on its own mock bus as the part does (the ADS7828 per command byte, the MPU-6000 and
//! AS5600 from their registers), so board A's and board B's drivers (`fw_core::periph`)
//! and module discovery's probes run unchanged over them. The readings are the robot at
//! rest in a healthy state: battery 11.7 V, regulator 7.4 V, small currents, gravity
//! along the IMUs' −y axis, the hip at its calibrated zero, both arms contracted (switch
//! pushed). Servo and GPIO outputs keep what they were last set to.
//!
//! What this model does not do: move. The hip encoder, IMUs and bolter currents do not
//! follow the servos, so a reconfiguration (hip rotation, the IMU's check of the state
//! reached) or a bolting (the current that says "locked") cannot complete here; the
//! plan the end-to-end test flies is the checkout without them.

use embedded_hal::digital::{ErrorType as PinErrorType, InputPin, OutputPin};
use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};
use fw_core::config::i2c_addr;
use fw_core::periph::ads7828::{command_byte, PowerMode};
use fw_core::periph::{as5600, mpu6000};

/// One I2C device on its own bus: a register file with auto-increment, or replies per
/// command byte (ADS7828).
pub struct Device {
    addr: u8,
    regs: [u8; 256],
    replies: heapless::Vec<(u8, [u8; 2]), 8>,
    pointer: u8,
}

impl Device {
    fn new(addr: u8) -> Self {
        Device {
            addr,
            regs: [0; 256],
            replies: heapless::Vec::new(),
            pointer: 0,
        }
    }

    /// An ADS7828 converting `counts` on channels 0..=5.
    pub fn adc(counts: [u16; 6]) -> Self {
        let mut d = Device::new(i2c_addr::ADS7828);
        for (ch, v) in counts.iter().enumerate() {
            if let Some(cmd) = command_byte(ch as u8, PowerMode::RefOnAdcOn) {
                // Six channels in eight places.
                let _ = d.replies.push((cmd, v.to_be_bytes()));
            }
        }
        d
    }

    /// An MPU-6000 lying with gravity along its −y axis (the QEMU tests' resting IMU).
    pub fn imu() -> Self {
        let mut d = Device::new(i2c_addr::MPU6000);
        d.regs[mpu6000::reg::WHO_AM_I as usize] = mpu6000::WHO_AM_I_VALUE;
        let at = mpu6000::reg::ACCEL_XOUT_H as usize;
        d.regs[at..at + 6].copy_from_slice(&[0x00, 0x00, 0xC0, 0x00, 0x00, 0x00]);
        d
    }

    /// An AS5600 with its magnet detected, reading `raw` (the hip's calibrated zero).
    pub fn encoder(raw: u16) -> Self {
        let mut d = Device::new(i2c_addr::AS5600);
        d.regs[as5600::reg::STATUS as usize] = as5600::STATUS_MD;
        let at = as5600::reg::RAW_ANGLE_H as usize;
        d.regs[at..at + 2].copy_from_slice(&raw.to_be_bytes());
        d
    }
}

impl ErrorType for Device {
    type Error = ErrorKind;
}

impl I2c for Device {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), ErrorKind> {
        if address != self.addr {
            return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
        }
        for op in ops {
            match op {
                Operation::Write(data) => {
                    if let Some((&first, rest)) = data.split_first() {
                        self.pointer = first;
                        for (i, b) in rest.iter().enumerate() {
                            self.regs[first.wrapping_add(i as u8) as usize] = *b;
                        }
                    }
                }
                Operation::Read(buf) => {
                    let reply = self.replies.iter().find(|(c, _)| *c == self.pointer).map(|r| r.1);
                    for (i, b) in buf.iter_mut().enumerate() {
                        *b = match reply {
                            Some(r) => r.get(i).copied().unwrap_or(0),
                            None => self.regs[self.pointer.wrapping_add(i as u8) as usize],
                        };
                    }
                }
            }
        }
        Ok(())
    }
}

/// A GPIO line: an output that keeps its level, read back as an input.
pub struct Pin {
    pub high: bool,
}

impl PinErrorType for Pin {
    type Error = core::convert::Infallible;
}

impl OutputPin for Pin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.high = false;
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.high = true;
        Ok(())
    }
}

impl InputPin for Pin {
    fn is_high(&mut self) -> Result<bool, Self::Error> {
        Ok(self.high)
    }
    fn is_low(&mut self) -> Result<bool, Self::Error> {
        Ok(!self.high)
    }
}

/// The arm-contracted switch of a connected arm module, pushed: it pulls the line low
/// whatever the internal pull (module discovery's probe sees "pushed").
pub struct ArmSwitchLine;

impl fw_core::modules::PullProbe for ArmSwitchLine {
    fn level_with_pull(&mut self, _pull_up: bool) -> Result<bool, fw_core::periph::HwError> {
        Ok(false)
    }
}

/// A PWM channel (LEDC on the boards) with a 14-bit duty.
pub struct Pwm {
    pub duty: u16,
}

impl PwmErrorType for Pwm {
    type Error = core::convert::Infallible;
}

impl SetDutyCycle for Pwm {
    fn max_duty_cycle(&self) -> u16 {
        1 << 14
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
        self.duty = duty;
        Ok(())
    }
}
