//! The small traits every board peripheral sits behind, and their drivers.
//!
//! The boards implement these with esp-hal (LEDC, I2C, GPIO); the host simulator or a
//! test double implements them in memory. The control code only sees the traits.

pub mod ads7828;
pub mod as5600;
pub mod mpu6000;
pub mod mux;
pub mod servo;
pub mod side;

pub use ads7828::Ads7828;
pub use as5600::As5600;
pub use mpu6000::Mpu6000;
pub use mux::BolterMux;
pub use servo::PwmServo;
pub use side::{BolterServos, SideOutputs};

/// A peripheral access that failed (bus error, device absent, bad value). The control
/// loop turns it into a stale reading, never a panic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HwError {
    /// The I2C transaction failed (NACK, arbitration, timeout).
    Bus,
    /// The device answered with an unexpected identity.
    WrongDevice { expected: u8, got: u8 },
    /// An argument outside what the device accepts.
    OutOfRange,
    /// A PWM or GPIO driver refused the operation.
    Driver,
}

impl core::fmt::Display for HwError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            HwError::Bus => f.write_str("bus error"),
            HwError::WrongDevice { expected, got } => {
                write!(f, "wrong device: expected id 0x{expected:02X}, got 0x{got:02X}")
            }
            HwError::OutOfRange => f.write_str("argument out of range"),
            HwError::Driver => f.write_str("driver error"),
        }
    }
}

impl core::error::Error for HwError {}

/// One servo output (arm, gripper, hip continuous servo, bolter drive).
pub trait ServoOutput {
    /// Commands a pulse width in microseconds (clamped by the implementation to the
    /// MIB's commandable range).
    fn set_pulse_us(&mut self, us: u16) -> Result<(), HwError>;
    /// Stops the pulse train (servo unpowered / back-drivable).
    fn release(&mut self) -> Result<(), HwError>;
}

/// An analog input multiplexer returning raw counts.
pub trait AnalogInput {
    /// Converts one single-ended channel; returns the raw count.
    fn read_raw(&mut self, channel: u8) -> Result<u16, HwError>;
}

/// Gravity sensor (IMU accelerometer).
pub trait GravitySensor {
    /// Gravity vector in the board frame, milli-g.
    fn gravity_mg(&mut self) -> Result<[i16; 3], HwError>;
}

/// A sensor that may be absent (not found at boot): every read fails, so the last good
/// value (or the default) stays and the failure is counted.
impl<T: GravitySensor> GravitySensor for Option<T> {
    fn gravity_mg(&mut self) -> Result<[i16; 3], HwError> {
        match self {
            Some(s) => s.gravity_mg(),
            None => Err(HwError::Bus),
        }
    }
}

/// Absolute angle sensor of the hip.
pub trait AngleSensor {
    /// Angle in hundredths of a degree, in −18000..18000.
    fn angle_cdeg(&mut self) -> Result<i16, HwError>;
}

/// Fastener pair selection of the bolter (multiplexer A0/A1).
pub trait PairSelect {
    /// Drives the select code (0..=3: pair 1..4; A0 = bit 0, A1 = bit 1).
    fn select(&mut self, bits: u8) -> Result<(), HwError>;
}

/// A digital output (servo regulator enable).
pub trait Enable {
    fn set_enabled(&mut self, on: bool) -> Result<(), HwError>;
}

/// An enable line driven low to switch on (P-MOSFET high-side switch with pull-up).
pub struct ActiveLowEnable<P>(pub P);

impl<P: embedded_hal::digital::OutputPin> Enable for ActiveLowEnable<P> {
    fn set_enabled(&mut self, on: bool) -> Result<(), HwError> {
        self.0.set_state((!on).into()).map_err(|_| HwError::Driver)
    }
}

/// A digital input (arm-contracted switch).
pub trait Switch {
    fn is_pushed(&mut self) -> Result<bool, HwError>;
}

/// The arm switch on a GPIO input with pull-up: pushed pulls the line low.
pub struct ActiveLowSwitch<P>(pub P);

impl<P: embedded_hal::digital::InputPin> Switch for ActiveLowSwitch<P> {
    fn is_pushed(&mut self) -> Result<bool, HwError> {
        self.0.is_low().map_err(|_| HwError::Driver)
    }
}
