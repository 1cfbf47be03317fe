//! The calibration the robot runs with (docs/modules.md): servo pulse widths per side, hip home,
//! encoder zero and direction, current thresholds and bolter thresholds, taken from the
//! accepted module set's descriptors (a "default" word = the database default of the
//! module's revision, `mib::modules::db::resolve_calibration`). Before discovery, and for
//! a platform that runs none, [`RobotCal::COMPILED`] holds the MIB's compiled constants
//! (`mib::robot::servo`, `mib::params`), which equal the database defaults of revision 1.
//!
//! Fixed size, `Copy`, no heap.

use mib::modules::db::{lookup, resolve_calibration};
use mib::modules::{slot, Calibration, ModuleSet, ModuleType};
use mib::robot::{servo, Side, StateKind};

/// Pulse widths (µs) of one side's arm and gripper.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SideCal {
    pub arm_contracted_us: u16,
    pub arm_extended_us: u16,
    pub arm_home_us: u16,
    pub grip_closed_us: u16,
    pub grip_open_us: u16,
    pub grip_home_us: u16,
}

impl SideCal {
    /// The arm pulse width of a state of this kind: contracted (matched), extended
    /// (stretch), half way (turn; `servo::ARM_TURN_US` for the default arm).
    pub const fn arm_us(&self, kind: StateKind) -> u16 {
        match kind {
            StateKind::Matched => self.arm_contracted_us,
            StateKind::Stretch => self.arm_extended_us,
            StateKind::Turn => {
                self.arm_contracted_us + (self.arm_extended_us.saturating_sub(self.arm_contracted_us)) / 2
            }
        }
    }
}

/// Current thresholds of a module (mA).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CurrentLimits {
    /// Largest current while the module is idle.
    pub idle_max_ma: u16,
    /// Largest current while it operates.
    pub op_max_ma: u16,
}

/// The robot's calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RobotCal {
    /// Indexed by `Side as usize` (A = 0, B = 1).
    pub side: [SideCal; 2],
    /// Angle `Home` turns the hip to (cdeg).
    pub hip_home_cdeg: i16,
    /// AS5600 reading (counts) at the hip's zero; the platform's nominal zero is
    /// [`ENCODER_NOMINAL_ZERO`].
    pub encoder_zero: u16,
    /// +1 or −1.
    pub encoder_dir: i8,
    pub arm_i: [CurrentLimits; 2],
    pub grip_i: [CurrentLimits; 2],
    pub bolter_i: [CurrentLimits; 2],
    pub hip_i: CurrentLimits,
    /// Bolter push / lock thresholds (mA). Board A runs one bolter state machine for
    /// both sides (they bolt every pair in step), so bolter A's values apply, or bolter
    /// B's when A is absent.
    pub bolt_push_ma: u16,
    pub bolt_lock_ma: u16,
    /// Slots whose calibration came from a descriptor (bit = slot).
    pub from_descriptors: u16,
}

/// The encoder reading the platforms convert to 0 cdeg (half of the AS5600's 12 bits):
/// `SensorsA::hip_cdeg` = (counts − 2048) × 36000 / 4096.
pub const ENCODER_NOMINAL_ZERO: u16 = 2048;
/// AS5600 counts per turn.
pub const ENCODER_COUNTS: i32 = 4096;

const fn ma(amps: f64) -> u16 {
    (amps * 1000.0) as u16
}

const COMPILED_SIDE: SideCal = SideCal {
    arm_contracted_us: servo::ARM_CONTRACTED_US,
    arm_extended_us: servo::ARM_EXTENDED_US,
    arm_home_us: servo::ARM_CONTRACTED_US,
    grip_closed_us: servo::GRIP_CLOSED_US,
    grip_open_us: servo::GRIP_OPEN_US,
    grip_home_us: servo::GRIP_CLOSED_US,
};

impl RobotCal {
    /// The MIB's compiled constants (no discovery).
    pub const COMPILED: RobotCal = RobotCal {
        side: [COMPILED_SIDE; 2],
        hip_home_cdeg: servo::HIP_HOME_CDEG,
        encoder_zero: ENCODER_NOMINAL_ZERO,
        encoder_dir: 1,
        arm_i: [CurrentLimits {
            idle_max_ma: ma(mib::params::I_LOC_IDLE_MAX),
            op_max_ma: ma(mib::params::I_LOC_MAX),
        }; 2],
        grip_i: [CurrentLimits {
            idle_max_ma: ma(mib::params::I_LOC_IDLE_MAX),
            op_max_ma: ma(mib::params::I_GRIP_MAX),
        }; 2],
        bolter_i: [CurrentLimits {
            idle_max_ma: 200,
            op_max_ma: ma(mib::params::I_BO_MAX),
        }; 2],
        hip_i: CurrentLimits {
            idle_max_ma: ma(mib::params::I_LOC_IDLE_MAX),
            op_max_ma: ma(mib::params::I_LOC_MAX),
        },
        bolt_push_ma: 1200,
        bolt_lock_ma: 1800,
        from_descriptors: 0,
    };

    /// The calibration of a discovered module set: every present module's descriptor
    /// calibration ("default" words resolved); absent modules, modules the database does
    /// not know and out-of-range calibrations (which make the set invalid anyway) keep
    /// [`RobotCal::COMPILED`]'s values.
    pub fn from_set(set: &ModuleSet) -> RobotCal {
        let mut c = RobotCal::COMPILED;
        let cal_of = |s: u8, c: &mut RobotCal| -> Option<Calibration> {
            let d = set.get(s as usize).copied().flatten()?;
            let def = lookup(d.ty, d.variant, d.revision)?;
            let r = resolve_calibration(def, &d.cal).ok()?;
            c.from_descriptors |= 1 << s;
            Some(r)
        };
        let u = |w: i16| w.max(0) as u16;
        for (side, arm, grip, bolter) in [
            (Side::A, slot::ARM_A, slot::GRIPPER_A, slot::BOLTER_A),
            (Side::B, slot::ARM_B, slot::GRIPPER_B, slot::BOLTER_B),
        ] {
            let i = side as usize;
            if let Some(w) = cal_of(arm, &mut c) {
                let w = w.0;
                c.side[i].arm_contracted_us = u(w[0]);
                c.side[i].arm_extended_us = u(w[1]);
                c.side[i].arm_home_us = u(w[2]);
                c.arm_i[i] = CurrentLimits {
                    idle_max_ma: u(w[3]),
                    op_max_ma: u(w[4]),
                };
            }
            if let Some(w) = cal_of(grip, &mut c) {
                let w = w.0;
                c.side[i].grip_closed_us = u(w[0]);
                c.side[i].grip_open_us = u(w[1]);
                c.side[i].grip_home_us = u(w[2]);
                c.grip_i[i] = CurrentLimits {
                    idle_max_ma: u(w[3]),
                    op_max_ma: u(w[4]),
                };
            }
            if let Some(w) = cal_of(bolter, &mut c) {
                let w = w.0;
                c.bolter_i[i] = CurrentLimits {
                    idle_max_ma: u(w[2]),
                    op_max_ma: u(w[3]),
                };
            }
        }
        // Bolter thresholds: A's, else B's.
        let bolter = [slot::BOLTER_A, slot::BOLTER_B].into_iter().find_map(|s| {
            let d = set.get(s as usize).copied().flatten()?;
            resolve_calibration(lookup(ModuleType::Bolter, d.variant, d.revision)?, &d.cal).ok()
        });
        if let Some(w) = bolter {
            c.bolt_push_ma = u(w.0[0]);
            c.bolt_lock_ma = u(w.0[1]);
        }
        if let Some(w) = cal_of(slot::HIP, &mut c) {
            c.hip_home_cdeg = w.0[0];
            c.hip_i = CurrentLimits {
                idle_max_ma: u(w.0[1]),
                op_max_ma: u(w.0[2]),
            };
        }
        if let Some(w) = cal_of(slot::ENCODER, &mut c) {
            c.encoder_zero = u(w.0[0]);
            c.encoder_dir = if w.0[1] < 0 { -1 } else { 1 };
        }
        c
    }

    /// One side's pulse widths.
    pub const fn of(&self, s: Side) -> &SideCal {
        &self.side[s as usize]
    }

    /// The hip angle (cdeg) from the platform's reading, which assumes the nominal
    /// zero and direction: shifted by this encoder's zero and signed by its direction.
    /// Saturates at the `i16` range.
    pub fn hip_from_reading(&self, reading_cdeg: i16) -> i16 {
        if self.encoder_zero == ENCODER_NOMINAL_ZERO && self.encoder_dir == 1 {
            return reading_cdeg;
        }
        let v = (reading_cdeg as i32 - self.encoder_offset_cdeg()) * self.encoder_dir as i32;
        v.clamp(i16::MIN as i32, i16::MAX as i32) as i16
    }

    /// The angle (cdeg) the nominal conversion reads at this encoder's zero, rounded to
    /// the nearest centidegree.
    pub const fn encoder_offset_cdeg(&self) -> i32 {
        let n = (self.encoder_zero as i32 - ENCODER_NOMINAL_ZERO as i32) * 36000;
        let half = ENCODER_COUNTS / 2;
        if n >= 0 {
            (n + half) / ENCODER_COUNTS
        } else {
            (n - half) / ENCODER_COUNTS
        }
    }
}

impl Default for RobotCal {
    fn default() -> Self {
        RobotCal::COMPILED
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::modules::db::default_def;
    use mib::modules::{default_set, CAL_DEFAULT};

    // verifies: MOD-CAL-03
    #[test]
    fn the_default_build_runs_with_the_compiled_constants() {
        let c = RobotCal::from_set(&default_set(1000));
        assert_eq!(
            RobotCal {
                from_descriptors: 0,
                ..c
            },
            RobotCal::COMPILED
        );
        let calibrated = [
            slot::ARM_A,
            slot::GRIPPER_A,
            slot::BOLTER_A,
            slot::HIP,
            slot::ENCODER,
            slot::ARM_B,
            slot::GRIPPER_B,
            slot::BOLTER_B,
        ];
        assert_eq!(c.from_descriptors, calibrated.iter().fold(0, |m, s| m | 1 << s));
        // The default arm's turn length is the MIB's ARM_TURN_US.
        assert_eq!(c.side[0].arm_us(StateKind::Turn), servo::ARM_TURN_US);
        // The compiled bolter thresholds are the tunables' defaults.
        assert_eq!(
            c.bolt_push_ma as i32,
            mib::tunables::by_id(mib::tunables::tid::BOLT_PUSH_THRESHOLD_MA)
                .unwrap()
                .default
        );
        assert_eq!(
            c.bolt_lock_ma as i32,
            mib::tunables::by_id(mib::tunables::tid::BOLT_LOCK_THRESHOLD_MA)
                .unwrap()
                .default
        );
        // Fixed size, on the stack (docs/modules.md quotes it).
        let size = core::mem::size_of::<RobotCal>();
        println!("size_of::<RobotCal>() = {size} bytes");
        assert!(size <= 96, "{size}");
        let b = default_def(ModuleType::Bolter).unwrap().cal_default.0;
        assert_eq!((b[0], b[1]), (1200, 1800));
    }

    // verifies: MOD-CAL-03
    #[test]
    fn descriptors_and_default_words_give_each_side_its_own_calibration() {
        let mut set = default_set(1000);
        // Gripper B: revision 2, every word "default" (the database's rev-2 values).
        let gb = set[slot::GRIPPER_B as usize].as_mut().unwrap();
        gb.revision = 2;
        gb.cal = Calibration::DEFAULT;
        // Arm A: bench-measured end points, the rest default.
        let aa = set[slot::ARM_A as usize].as_mut().unwrap();
        aa.cal = Calibration([1010, 1990, CAL_DEFAULT, CAL_DEFAULT, 2800, 0, 0, 0]);
        // Encoder mounted 100 counts off, counting backwards.
        set[slot::ENCODER as usize].as_mut().unwrap().cal = Calibration([2148, -1, 0, 0, 0, 0, 0, 0]);
        // Bolter A absent: B's thresholds apply.
        set[slot::BOLTER_A as usize] = None;
        set[slot::BOLTER_B as usize].as_mut().unwrap().cal = Calibration([1000, 1700, 200, 2500, 0, 0, 0, 0]);
        let c = RobotCal::from_set(&set);
        assert_eq!((c.side[1].grip_closed_us, c.side[1].grip_open_us), (1150, 1850));
        assert_eq!(c.grip_i[1].op_max_ma, 1600);
        assert_eq!((c.side[0].grip_closed_us, c.side[0].grip_open_us), (1100, 1900));
        assert_eq!(c.of(Side::A).arm_us(StateKind::Matched), 1010);
        assert_eq!(c.of(Side::A).arm_us(StateKind::Stretch), 1990);
        assert_eq!(c.of(Side::A).arm_us(StateKind::Turn), 1500);
        assert_eq!(
            c.arm_i[0],
            CurrentLimits {
                idle_max_ma: 400,
                op_max_ma: 2800
            }
        );
        assert_eq!((c.bolt_push_ma, c.bolt_lock_ma), (1000, 1700));
        assert_eq!(c.from_descriptors & (1 << slot::BOLTER_A), 0);
        // 100 counts = 878.9 cdeg (rounded); reversed.
        assert_eq!(c.encoder_offset_cdeg(), 879);
        assert_eq!(c.hip_from_reading(879), 0);
        assert_eq!(c.hip_from_reading(879 + 9000), -9000);
        let mut low = c;
        low.encoder_zero = 1948;
        assert_eq!(low.encoder_offset_cdeg(), -879);
        assert_eq!(c.hip_from_reading(i16::MIN), i16::MAX, "saturates, never wraps");
        // An out-of-range word is not used (discovery reports the set invalid).
        set[slot::GRIPPER_A as usize].as_mut().unwrap().cal.0[0] = 500;
        let c = RobotCal::from_set(&set);
        assert_eq!(c.side[0].grip_closed_us, servo::GRIP_CLOSED_US);
        assert_eq!(c.from_descriptors & (1 << slot::GRIPPER_A), 0);
    }
}
