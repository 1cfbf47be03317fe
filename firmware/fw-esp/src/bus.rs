//! The sensor I2C bus, shared by the ADS7828, the MPU-6000 and (board A) the AS5600.
//! One task (the control loop) uses it, so a `RefCell` device per driver suffices.

use core::cell::RefCell;
use embedded_hal_bus::i2c::RefCellDevice;
use esp_hal::i2c::master::I2c;
use esp_hal::Blocking;
use static_cell::StaticCell;

pub type SensorBus = RefCell<I2c<'static, Blocking>>;
pub type SensorDevice = RefCellDevice<'static, I2c<'static, Blocking>>;

static BUS: StaticCell<SensorBus> = StaticCell::new();

/// Moves the bus into a static and returns it (call once).
pub fn share(i2c: I2c<'static, Blocking>) -> &'static SensorBus {
    BUS.init(RefCell::new(i2c))
}

/// A handle for one driver.
pub fn device(bus: &'static SensorBus) -> SensorDevice {
    RefCellDevice::new(bus)
}
