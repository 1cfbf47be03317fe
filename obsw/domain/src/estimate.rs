//! The configuration state computed from sensor data, as the paper does: the faces from
//! the two IMU gravity vectors, cross-checked with the hip encoder (`StateDef::hip_cdeg`)
//! and the arm PWM values (`StateDef::arm_pwm`). A belief that disagrees with this is an
//! initial-state mismatch.

use crate::calib::RobotCal;
use crate::consts::{EST_ARM_TOL_US, EST_HIP_TOL_CDEG};
use crate::imu::face_from_gravity;
use mib::robot::{state_of, Side, STATES};

/// Why no state could be computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EstimateError {
    /// A side's gravity vector matches no face.
    NoFace(Side),
    /// The two faces form none of the 15 states (e.g. both on `Ypos`).
    NotAState,
    /// The hip angle disagrees with the state the IMUs imply.
    Hip { state: u8, hip_cdeg: i16 },
    /// A side's arm PWM disagrees with the state the IMUs imply.
    Arm { state: u8, side: Side, pwm: u16 },
}

/// Both grippers closed (PWM within `EST_GRIP_TOL_US` of `servo::GRIP_CLOSED_US`): a
/// configuration state needs both sides gripped.
pub fn grippers_closed(grip_a_pwm: u16, grip_b_pwm: u16) -> bool {
    grippers_closed_cal(grip_a_pwm, grip_b_pwm, &RobotCal::COMPILED)
}

/// [`grippers_closed`] against each side's calibrated closed pulse width.
pub fn grippers_closed_cal(grip_a_pwm: u16, grip_b_pwm: u16, cal: &RobotCal) -> bool {
    grip_a_pwm.abs_diff(cal.of(Side::A).grip_closed_us) <= crate::consts::EST_GRIP_TOL_US
        && grip_b_pwm.abs_diff(cal.of(Side::B).grip_closed_us) <= crate::consts::EST_GRIP_TOL_US
}

/// The state implied by the IMUs alone (no cross-check), if any.
pub fn state_from_imus(grav_a: [i16; 3], grav_b: [i16; 3]) -> Option<u8> {
    state_of(face_from_gravity(grav_a)?, face_from_gravity(grav_b)?)
}

/// The state computed from the sensors, or why it cannot be computed.
pub fn estimate(
    grav_a: [i16; 3],
    grav_b: [i16; 3],
    hip_cdeg: i16,
    arm_a_pwm: u16,
    arm_b_pwm: u16,
) -> Result<u8, EstimateError> {
    estimate_cal(grav_a, grav_b, hip_cdeg, arm_a_pwm, arm_b_pwm, &RobotCal::COMPILED)
}

/// [`estimate`] with each side's calibrated arm pulse widths.
pub fn estimate_cal(
    grav_a: [i16; 3],
    grav_b: [i16; 3],
    hip_cdeg: i16,
    arm_a_pwm: u16,
    arm_b_pwm: u16,
    cal: &RobotCal,
) -> Result<u8, EstimateError> {
    let fa = face_from_gravity(grav_a).ok_or(EstimateError::NoFace(Side::A))?;
    let fb = face_from_gravity(grav_b).ok_or(EstimateError::NoFace(Side::B))?;
    let state = state_of(fa, fb).ok_or(EstimateError::NotAState)?;
    let def = &STATES[state as usize];
    if (hip_cdeg as i32 - def.hip_cdeg() as i32).abs() > EST_HIP_TOL_CDEG as i32 {
        return Err(EstimateError::Hip { state, hip_cdeg });
    }
    for (side, pwm) in [(Side::A, arm_a_pwm), (Side::B, arm_b_pwm)] {
        if pwm.abs_diff(cal.of(side).arm_us(def.kind())) > EST_ARM_TOL_US {
            return Err(EstimateError::Arm { state, side, pwm });
        }
    }
    Ok(state)
}

/// The state computed from the sensors, `None` if they are inconsistent.
pub fn state_from_sensors(
    grav_a: [i16; 3],
    grav_b: [i16; 3],
    hip_cdeg: i16,
    arm_a_pwm: u16,
    arm_b_pwm: u16,
) -> Option<u8> {
    estimate(grav_a, grav_b, hip_cdeg, arm_a_pwm, arm_b_pwm).ok()
}

/// [`state_from_sensors`] with each side's calibrated arm pulse widths.
pub fn state_from_sensors_cal(
    grav_a: [i16; 3],
    grav_b: [i16; 3],
    hip_cdeg: i16,
    arm_a_pwm: u16,
    arm_b_pwm: u16,
    cal: &RobotCal,
) -> Option<u8> {
    estimate_cal(grav_a, grav_b, hip_cdeg, arm_a_pwm, arm_b_pwm, cal).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imu::gravity_in_board_frame as g;
    use mib::robot::{Face, NUM_STATES};

    // verifies: MMIC-MOT-02
    #[test]
    fn estimator_recovers_each_of_the_fifteen_states() {
        for s in STATES.iter() {
            let got = state_from_sensors(g(s.a), g(s.b), s.hip_cdeg(), s.arm_pwm(), s.arm_pwm());
            assert_eq!(got, Some(s.id), "{}", s.name);
            // small sensor errors are tolerated
            let mut ga = g(s.a);
            ga[1] += 60;
            let got = state_from_sensors(ga, g(s.b), s.hip_cdeg() + 250, s.arm_pwm() + 40, s.arm_pwm() - 30);
            assert_eq!(got, Some(s.id), "{} with noise", s.name);
        }
        assert_eq!(STATES.len(), NUM_STATES);
    }

    // verifies: MMIC-MOT-02
    #[test]
    fn estimator_detects_mismatch_between_imus_hip_and_arms() {
        let s = &STATES[0]; // matched Xneg
                            // A's IMU sees another face (misplaced voxel): IMUs say a turn state, hip says 0
        let r = estimate(g(Face::Yneg), g(s.b), 0, 1000, 1000);
        assert!(matches!(r, Err(EstimateError::Hip { state: 11, .. })), "{r:?}");
        // hip far from the state's angle
        assert!(matches!(
            estimate(g(s.a), g(s.b), 4500, 1000, 1000),
            Err(EstimateError::Hip { .. })
        ));
        // arm B extended in a matched state
        assert_eq!(
            estimate(g(s.a), g(s.b), 0, 1000, 2000),
            Err(EstimateError::Arm {
                state: 0,
                side: Side::B,
                pwm: 2000
            })
        );
        // both on the ceiling is not a state
        assert_eq!(
            estimate(g(Face::Ypos), g(Face::Ypos), 0, 1000, 1000),
            Err(EstimateError::NotAState)
        );
        // no gravity at all
        assert_eq!(
            estimate([0; 3], g(s.b), 0, 1000, 1000),
            Err(EstimateError::NoFace(Side::A))
        );
    }

    // verifies: MOD-CAL-03
    #[test]
    fn the_estimator_follows_each_sides_calibration() {
        let mut cal = RobotCal::COMPILED;
        cal.side[1].grip_closed_us = 1150;
        cal.side[1].arm_extended_us = 1900;
        // Gripper B closed at rev 2's 1150 µs; at rev 1's 1100 it would still be within
        // the tolerance, at 1210 not.
        assert!(grippers_closed_cal(1100, 1150, &cal));
        assert!(!grippers_closed_cal(1100, 1210, &cal));
        assert!(grippers_closed(1100, 1140) && !grippers_closed(1100, 1160));
        // A stretch with arm B at its own extended width: recognised with B's calibration
        // only (1900 is 100 µs from the compiled 2000, 1850 is more).
        let s = &STATES[4];
        assert_eq!(s.kind(), mib::robot::StateKind::Stretch);
        assert_eq!(
            state_from_sensors_cal(g(s.a), g(s.b), s.hip_cdeg(), 2000, 1850, &cal),
            Some(s.id)
        );
        assert_eq!(state_from_sensors(g(s.a), g(s.b), s.hip_cdeg(), 2000, 1850), None);
    }

    // verifies: MMIC-MOT-02
    #[test]
    fn a_state_needs_both_grippers_closed() {
        assert!(grippers_closed(1100, 1140));
        assert!(!grippers_closed(1100, 1300));
        assert!(!grippers_closed(1900, 1100));
    }
}
