//! One side's module outputs (arm, gripper, bolter) and the mapping of the domain's
//! actuator commands onto them.

use super::{HwError, PairSelect, ServoOutput};
use crate::config::bolter_servo as bs;
use mmic_domain::{BolterDrive, SideActuators};

/// The bolter's two drives: translation (toward/away from the fastener) and head
/// rotation, both continuous-rotation servos (1500 µs = stop).
pub struct BolterServos<T, R> {
    pub translate: T,
    pub rotate: R,
}

/// Pulse widths (translate, rotate) for a drive command; `None` = unpowered.
pub const fn bolter_pulses(drive: BolterDrive) -> Option<(u16, u16)> {
    match drive {
        BolterDrive::Off => None,
        BolterDrive::Descend => Some((bs::TRANSLATE_PUSH_US, bs::STOP_US)),
        BolterDrive::Retract => Some((bs::TRANSLATE_BACK_US, bs::STOP_US)),
        BolterDrive::RotateLock => Some((bs::TRANSLATE_PUSH_US, bs::ROTATE_LOCK_US)),
        BolterDrive::RotateUnlock => Some((bs::TRANSLATE_PUSH_US, bs::ROTATE_UNLOCK_US)),
        BolterDrive::Reverse => Some((bs::TRANSLATE_BACK_US, bs::ROTATE_UNLOCK_US)),
    }
}

/// Arm, gripper, bolter drives and pair multiplexer of one side.
pub struct SideOutputs<A, G, T, R, M> {
    pub arm: A,
    pub grip: G,
    pub bolter: BolterServos<T, R>,
    pub mux: M,
}

fn servo<S: ServoOutput>(s: &mut S, pulse: Option<u16>) -> Result<(), HwError> {
    match pulse {
        Some(us) => s.set_pulse_us(us),
        None => s.release(),
    }
}

impl<A, G, T, R, M> SideOutputs<A, G, T, R, M>
where
    A: ServoOutput,
    G: ServoOutput,
    T: ServoOutput,
    R: ServoOutput,
    M: PairSelect,
{
    /// Drives every output of the side. All outputs are attempted even if one fails;
    /// the first error is returned.
    pub fn apply(&mut self, cmd: &SideActuators, mux_bits: u8) -> Result<(), HwError> {
        let (t, r) = match bolter_pulses(cmd.bolter) {
            Some((t, r)) => (Some(t), Some(r)),
            None => (None, None),
        };
        // Select the pair before powering the drive.
        let results = [
            self.mux.select(mux_bits),
            servo(&mut self.arm, cmd.arm_pwm),
            servo(&mut self.grip, cmd.grip_pwm),
            servo(&mut self.bolter.translate, t),
            servo(&mut self.bolter.rotate, r),
        ];
        results.into_iter().find(|r| r.is_err()).unwrap_or(Ok(()))
    }

    /// Everything unpowered (boot, panic).
    pub fn release_all(&mut self) {
        let _ = self.arm.release();
        let _ = self.grip.release();
        let _ = self.bolter.translate.release();
        let _ = self.bolter.rotate.release();
    }
}
