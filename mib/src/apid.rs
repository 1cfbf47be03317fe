//! Application process identifiers: one APID per robot.

/// APID of robot 1 is `APID_BASE + 1`.
pub const APID_BASE: u16 = 0x100;
/// Lowest robot number.
pub const ROBOT_MIN: u8 = 1;
/// Highest robot number.
pub const ROBOT_MAX: u8 = 254;
/// Robot used when none is given.
pub const DEFAULT_ROBOT: u8 = 1;
/// APID of time-correlation / idle packets (CCSDS idle APID).
pub const IDLE_APID: u16 = 0x7FF;

/// APID of robot `n` (1..=254); `None` outside that range.
pub const fn robot_apid(n: u8) -> Option<u16> {
    if n >= ROBOT_MIN && n <= ROBOT_MAX {
        Some(APID_BASE + n as u16)
    } else {
        None
    }
}

/// Robot number of an APID, if the APID belongs to a robot.
pub const fn apid_robot(apid: u16) -> Option<u8> {
    if apid > APID_BASE && apid <= APID_BASE + ROBOT_MAX as u16 {
        Some((apid - APID_BASE) as u8)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: PUS-PKT-02
    #[test]
    fn robot_one_is_0x101_and_round_trips() {
        assert_eq!(robot_apid(1), Some(0x101));
        assert_eq!(robot_apid(0), None);
        assert_eq!(robot_apid(255), None);
        for n in ROBOT_MIN..=ROBOT_MAX {
            assert_eq!(apid_robot(robot_apid(n).unwrap()), Some(n));
        }
        assert_eq!(apid_robot(0x100), None);
        assert_eq!(apid_robot(0x1FF), None);
    }
}
