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

/// Pulse width for a hip speed command (cdeg/s, positive = counter-clockwise): linear
/// from standstill to ±`SPAN_US` at ±`HIP_MAX_CMD_CDEG_S`, saturated beyond.
pub const fn hip_pulse(speed_cdeg_s: i16) -> u16 {
    use crate::config::hip_servo::{SPAN_US, STOP_US};
    let max = mmic_domain::consts::HIP_MAX_CMD_CDEG_S as i32;
    let s = speed_cdeg_s as i32;
    let s = if s > max {
        max
    } else if s < -max {
        -max
    } else {
        s
    };
    let num = s * SPAN_US as i32;
    // round to nearest
    let off = if num >= 0 {
        (num + max / 2) / max
    } else {
        (num - max / 2) / max
    };
    (STOP_US as i32 + off) as u16
}
