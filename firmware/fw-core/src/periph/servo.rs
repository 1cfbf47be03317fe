//! Servo outputs on any `embedded-hal` PWM channel (LEDC on the ESP32-C3), 50 Hz frame.

use super::{HwError, ServoOutput};
use crate::config::SERVO_PERIOD_US;
use embedded_hal::pwm::SetDutyCycle;
use mib::robot::servo::{PWM_MAX_US, PWM_MIN_US};

/// Duty-cycle count for a pulse of `us` microseconds in a `SERVO_PERIOD_US` frame with
/// `max_duty` counts per frame (rounded to nearest). `us` is clamped to the MIB range.
pub const fn duty_for_pulse(us: u16, max_duty: u16) -> u16 {
    let us = if us < PWM_MIN_US {
        PWM_MIN_US
    } else if us > PWM_MAX_US {
        PWM_MAX_US
    } else {
        us
    };
    ((us as u32 * max_duty as u32 + SERVO_PERIOD_US / 2) / SERVO_PERIOD_US) as u16
}

pub struct PwmServo<P> {
    pwm: P,
    last_us: u16,
}

impl<P: SetDutyCycle> PwmServo<P> {
    pub fn new(pwm: P) -> Self {
        Self { pwm, last_us: 0 }
    }
    /// Last commanded pulse width (0 = released).
    pub fn last_us(&self) -> u16 {
        self.last_us
    }
}

impl<P: SetDutyCycle> ServoOutput for PwmServo<P> {
    fn set_pulse_us(&mut self, us: u16) -> Result<(), HwError> {
        let duty = duty_for_pulse(us, self.pwm.max_duty_cycle());
        self.pwm.set_duty_cycle(duty).map_err(|_| HwError::Driver)?;
        self.last_us = us.clamp(PWM_MIN_US, PWM_MAX_US);
        Ok(())
    }

    fn release(&mut self) -> Result<(), HwError> {
        self.pwm.set_duty_cycle_fully_off().map_err(|_| HwError::Driver)?;
        self.last_us = 0;
        Ok(())
    }
}
