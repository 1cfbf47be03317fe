//! Reading a board's sensors into the domain's raw sensor records. A channel whose
//! read fails keeps its previous value and is counted; the control loop never stops
//! for a sensor.

use crate::config::adc_channel as ch;
use crate::periph::{AnalogInput, AngleSensor, GravitySensor, HwError, Switch};
use mmic_domain::{SensorsA, SensorsB};

/// Failed reads since boot, per device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorErrors {
    pub adc: u32,
    pub imu: u32,
    pub encoder: u32,
    pub switch: u32,
    pub last: Option<HwError>,
}

impl SensorErrors {
    fn keep<T>(&mut self, r: Result<T, HwError>, slot: &mut T, counter: fn(&mut Self) -> &mut u32) {
        match r {
            Ok(v) => *slot = v,
            Err(e) => {
                let c = counter(self);
                *c = c.wrapping_add(1);
                self.last = Some(e);
            }
        }
    }
    pub fn total(&self) -> u32 {
        self.adc
            .wrapping_add(self.imu)
            .wrapping_add(self.encoder)
            .wrapping_add(self.switch)
    }
}

/// Board A: ADS7828 channels, IMU gravity, hip encoder, arm switch.
pub fn sample_a(
    adc: &mut impl AnalogInput,
    imu: &mut impl GravitySensor,
    hip: &mut impl AngleSensor,
    arm_switch: &mut impl Switch,
    s: &mut SensorsA,
    err: &mut SensorErrors,
) {
    err.keep(adc.read_raw(ch::V_BAT), &mut s.v_bat, |e| &mut e.adc);
    err.keep(adc.read_raw(ch::V_REG), &mut s.v_reg, |e| &mut e.adc);
    err.keep(adc.read_raw(ch::I_BAT), &mut s.i_bat, |e| &mut e.adc);
    err.keep(adc.read_raw(ch::I_LOC), &mut s.i_loc, |e| &mut e.adc);
    err.keep(adc.read_raw(ch::I_GRIP), &mut s.i_grip, |e| &mut e.adc);
    err.keep(adc.read_raw(ch::I_BO), &mut s.i_bo, |e| &mut e.adc);
    err.keep(imu.gravity_mg(), &mut s.grav, |e| &mut e.imu);
    err.keep(hip.angle_cdeg(), &mut s.hip_cdeg, |e| &mut e.encoder);
    err.keep(arm_switch.is_pushed(), &mut s.arm_switch, |e| &mut e.switch);
}

/// Board B: ADS7828 channels, IMU gravity, arm switch (no hip, no pack current).
pub fn sample_b(
    adc: &mut impl AnalogInput,
    imu: &mut impl GravitySensor,
    arm_switch: &mut impl Switch,
    s: &mut SensorsB,
    err: &mut SensorErrors,
) {
    err.keep(adc.read_raw(ch::V_BAT), &mut s.v_bat, |e| &mut e.adc);
    err.keep(adc.read_raw(ch::I_LOC), &mut s.i_loc, |e| &mut e.adc);
    err.keep(adc.read_raw(ch::I_GRIP), &mut s.i_grip, |e| &mut e.adc);
    err.keep(adc.read_raw(ch::I_BO), &mut s.i_bo, |e| &mut e.adc);
    err.keep(imu.gravity_mg(), &mut s.grav, |e| &mut e.imu);
    err.keep(arm_switch.is_pushed(), &mut s.arm_switch, |e| &mut e.switch);
}
