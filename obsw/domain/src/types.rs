//! Sensor readings and actuator commands exchanged with the hardware (or simulator).

/// Raw sensor readings of board A for one control period.
///
/// ADC channels are raw counts (`mib::params::CAL_VOLT` for voltages,
/// `mib::params::CAL_AMP` for currents: 1 mA per count); gravity in milli-g in the
/// board frame (see [`crate::imu`]); hip angle in hundredths of a degree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorsA {
    pub v_bat: u16,
    pub i_bat: u16,
    pub v_reg: u16,
    pub i_loc: u16,
    pub i_grip: u16,
    pub i_bo: u16,
    pub grav: [i16; 3],
    pub hip_cdeg: i16,
    pub arm_switch: bool,
}

/// Raw sensor readings of board B (no hip, no battery current, no regulator channel).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorsB {
    pub v_bat: u16,
    pub i_loc: u16,
    pub i_grip: u16,
    pub i_bo: u16,
    pub grav: [i16; 3],
    pub arm_switch: bool,
}

/// What the selected bolter pair is told to do.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BolterDrive {
    /// Unpowered.
    #[default]
    Off = 0,
    /// Translate toward the fastener and push (commanded beyond the physical stop).
    Descend = 1,
    /// Move back toward home.
    Retract = 2,
    /// Keep pushing and rotate the heads in the locking direction.
    RotateLock = 3,
    /// Keep pushing and rotate the heads in the releasing direction (unbolting).
    RotateUnlock = 4,
    /// Lift off and turn the heads back to disengage them after locking.
    Reverse = 5,
}

impl BolterDrive {
    pub const fn code(self) -> u8 {
        self as u8
    }
    pub const fn from_code(c: u8) -> Option<BolterDrive> {
        match c {
            0 => Some(BolterDrive::Off),
            1 => Some(BolterDrive::Descend),
            2 => Some(BolterDrive::Retract),
            3 => Some(BolterDrive::RotateLock),
            4 => Some(BolterDrive::RotateUnlock),
            5 => Some(BolterDrive::Reverse),
            _ => None,
        }
    }
}

/// Multiplexer select bits A0/A1 for a pair 1..=4 (pair 1 = low-low). 0 for no pair.
pub const fn mux_bits(pair: u8) -> u8 {
    if pair >= 1 && pair <= 4 {
        pair - 1
    } else {
        0
    }
}

/// Commands to one side's modules. `None` = unpowered (servo back-drivable).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SideActuators {
    pub arm_pwm: Option<u16>,
    pub grip_pwm: Option<u16>,
    pub bolter: BolterDrive,
}

/// Everything board A drives in one control period.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ActuatorsA {
    /// 7.4 V servo regulator.
    pub regulator_on: bool,
    pub side: SideActuators,
    /// Hip continuous-servo speed command (cdeg/s); `None` = unpowered.
    pub hip_speed: Option<i16>,
    /// Bolter multiplexer select bits (A0 = bit 0, A1 = bit 1).
    pub mux: u8,
}
