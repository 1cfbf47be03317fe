//! Servo outputs on the LEDC low-speed channels: one 50 Hz timer with 14-bit duty
//! resolution (1.22 µs per count) shared by every channel.

use esp_hal::gpio::interconnect::PeripheralOutput;
use esp_hal::gpio::DriveMode;
use esp_hal::ledc::channel::{self, ChannelIFace};
use esp_hal::ledc::timer::{self, TimerIFace};
use esp_hal::ledc::{LSGlobalClkSource, Ledc, LowSpeed};
use esp_hal::time::Rate;
use fw_core::config::SERVO_FREQ_HZ;
use fw_core::periph::PwmServo;
use static_cell::StaticCell;

pub type ServoChannel = channel::Channel<'static, LowSpeed>;
pub type Servo = PwmServo<ServoChannel>;

/// The configured LEDC timer the channels run from.
pub struct ServoBank {
    ledc: Ledc<'static>,
    timer: &'static timer::Timer<'static, LowSpeed>,
}

static TIMER: StaticCell<timer::Timer<'static, LowSpeed>> = StaticCell::new();

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ServoSetupError {
    Timer,
    Channel,
}

impl ServoBank {
    /// Configures LEDC timer 0 for 50 Hz, 14 bit, from the APB clock (call once).
    pub fn new(mut ledc: Ledc<'static>) -> Result<Self, ServoSetupError> {
        ledc.set_global_slow_clock(LSGlobalClkSource::APBClk);
        let mut t = ledc.timer::<LowSpeed>(timer::Number::Timer0);
        t.configure(timer::config::Config {
            duty: timer::config::Duty::Duty14Bit,
            clock_source: timer::LSClockSource::APBClk,
            frequency: Rate::from_hz(SERVO_FREQ_HZ),
        })
        .map_err(|_| ServoSetupError::Timer)?;
        let timer = TIMER.init(t);
        Ok(Self { ledc, timer })
    }

    /// A servo output on `pin`, starting unpowered (duty 0: no pulses).
    pub fn servo(
        &self,
        number: channel::Number,
        pin: impl PeripheralOutput<'static>,
    ) -> Result<Servo, ServoSetupError> {
        let mut ch = self.ledc.channel::<LowSpeed>(number, pin);
        ch.configure(channel::config::Config {
            timer: self.timer,
            duty_pct: 0,
            drive_mode: DriveMode::PushPull,
        })
        .map_err(|_| ServoSetupError::Channel)?;
        Ok(PwmServo::new(ch))
    }
}
