//! Configuration states, motion primitives and the reconfiguration map.
//!
//! ## Geometry (our design; the paper's Table 5 and Figure 9 were lost)
//! The robot works in the X–Y plane of a reference voxel, gravity along −Y. The four
//! faces of the voxel in that plane, in counter-clockwise order, are `Xpos`, `Ypos`,
//! `Xneg`, `Yneg`. A state is the pair (face gripped by side A, face gripped by side B):
//! - *matched*: both sides on one face, robot contracted — the final states;
//! - *stretch*: sides on opposite faces of one axis, arms extended;
//! - *turn*: sides on faces of different axes, hip at ±90°.
//!
//! All 16 pairs are geometrically possible, but the robot never parks hanging from the
//! voxel's ceiling (`Ypos`): it may grip it transiently, yet a matched state there would
//! leave the whole robot hanging from one contracted face while it bolts. Excluding
//! matched `Ypos` leaves the paper's **15 states**: 3 matched, 4 stretch, 8 turn.
//!
//! ## Primitives
//! Each primitive moves one side (the other stays gripped): "fwd" primitives move side
//! A (the robot advances toward A), "back" primitives move side B.
//! 1–4 are straight (arm extension/contraction), 5–8 rotate the hip by ±90°.
//! [`apply`] is the single definition of what each primitive does; the map is derived.

/// A face of the reference voxel in the working plane, in counter-clockwise order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Face {
    Xpos = 0,
    Ypos = 1,
    Xneg = 2,
    Yneg = 3,
}

impl Face {
    pub const ALL: [Face; 4] = [Face::Xpos, Face::Ypos, Face::Xneg, Face::Yneg];
    pub const fn from_index(i: u8) -> Face {
        match i % 4 {
            0 => Face::Xpos,
            1 => Face::Ypos,
            2 => Face::Xneg,
            _ => Face::Yneg,
        }
    }
    /// The face 90° counter-clockwise (`+1`) or clockwise (`-1`) from this one.
    pub const fn rotate(self, quarter_turns: i8) -> Face {
        Face::from_index(((self as i8 + quarter_turns).rem_euclid(4)) as u8)
    }
    pub const fn opposite(self) -> Face {
        self.rotate(2)
    }
    pub const fn name(self) -> &'static str {
        match self {
            Face::Xpos => "Xpos",
            Face::Ypos => "Ypos",
            Face::Xneg => "Xneg",
            Face::Yneg => "Yneg",
        }
    }
    /// Inward normal of the face (unit vector in the X–Y plane, pointing into the voxel).
    pub const fn inward_normal(self) -> (i8, i8) {
        match self {
            Face::Xpos => (-1, 0),
            Face::Ypos => (0, -1),
            Face::Xneg => (1, 0),
            Face::Yneg => (0, 1),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StateKind {
    Matched,
    Stretch,
    Turn,
}

impl StateKind {
    pub const fn name(self) -> &'static str {
        match self {
            StateKind::Matched => "matched",
            StateKind::Stretch => "stretch",
            StateKind::Turn => "turn",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateDef {
    pub id: u8,
    /// Paper-style letter label (a..o).
    pub label: char,
    /// Paper-style name: "Xneg" for matched, "Xneg Xpos" (A face, B face) otherwise.
    pub name: &'static str,
    pub a: Face,
    pub b: Face,
}

impl StateDef {
    pub const fn kind(&self) -> StateKind {
        let d = (self.b as i8 - self.a as i8).rem_euclid(4);
        match d {
            0 => StateKind::Matched,
            2 => StateKind::Stretch,
            _ => StateKind::Turn,
        }
    }
    /// Hip angle of the state in hundredths of a degree.
    pub const fn hip_cdeg(&self) -> i16 {
        match (self.b as i8 - self.a as i8).rem_euclid(4) {
            1 => 9000,
            3 => -9000,
            _ => 0,
        }
    }
    /// Arm PWM pulse width (µs) of both arms in this state.
    pub const fn arm_pwm(&self) -> u16 {
        match self.kind() {
            StateKind::Matched => servo::ARM_CONTRACTED_US,
            StateKind::Stretch => servo::ARM_EXTENDED_US,
            StateKind::Turn => servo::ARM_TURN_US,
        }
    }
}

use Face::*;
/// Number of configuration states.
pub const NUM_STATES: usize = 15;
/// "No state / unknown" on the wire.
pub const STATE_UNKNOWN: u8 = 255;

pub const STATES: [StateDef; NUM_STATES] = [
    StateDef {
        id: 0,
        label: 'a',
        name: "Xneg",
        a: Xneg,
        b: Xneg,
    },
    StateDef {
        id: 1,
        label: 'b',
        name: "Xpos",
        a: Xpos,
        b: Xpos,
    },
    StateDef {
        id: 2,
        label: 'c',
        name: "Yneg",
        a: Yneg,
        b: Yneg,
    },
    StateDef {
        id: 3,
        label: 'd',
        name: "Xneg Xpos",
        a: Xneg,
        b: Xpos,
    },
    StateDef {
        id: 4,
        label: 'e',
        name: "Xpos Xneg",
        a: Xpos,
        b: Xneg,
    },
    StateDef {
        id: 5,
        label: 'f',
        name: "Yneg Ypos",
        a: Yneg,
        b: Ypos,
    },
    StateDef {
        id: 6,
        label: 'g',
        name: "Ypos Yneg",
        a: Ypos,
        b: Yneg,
    },
    StateDef {
        id: 7,
        label: 'h',
        name: "Xneg Yneg",
        a: Xneg,
        b: Yneg,
    },
    StateDef {
        id: 8,
        label: 'i',
        name: "Xneg Ypos",
        a: Xneg,
        b: Ypos,
    },
    StateDef {
        id: 9,
        label: 'j',
        name: "Xpos Yneg",
        a: Xpos,
        b: Yneg,
    },
    StateDef {
        id: 10,
        label: 'k',
        name: "Xpos Ypos",
        a: Xpos,
        b: Ypos,
    },
    StateDef {
        id: 11,
        label: 'l',
        name: "Yneg Xneg",
        a: Yneg,
        b: Xneg,
    },
    StateDef {
        id: 12,
        label: 'm',
        name: "Yneg Xpos",
        a: Yneg,
        b: Xpos,
    },
    StateDef {
        id: 13,
        label: 'n',
        name: "Ypos Xneg",
        a: Ypos,
        b: Xneg,
    },
    StateDef {
        id: 14,
        label: 'o',
        name: "Ypos Xpos",
        a: Ypos,
        b: Xpos,
    },
];

/// The state with the given faces, if it is one of the 15.
pub const fn state_of(a: Face, b: Face) -> Option<u8> {
    let mut i = 0;
    while i < NUM_STATES {
        if STATES[i].a as u8 == a as u8 && STATES[i].b as u8 == b as u8 {
            return Some(i as u8);
        }
        i += 1;
    }
    None
}

pub fn state_by_name(name: &str) -> Option<&'static StateDef> {
    let n = name.trim();
    STATES.iter().find(|s| {
        s.name.eq_ignore_ascii_case(n)
            || (n.len() == 1 && n.chars().next().map(|c| c.to_ascii_lowercase()) == Some(s.label))
            || (s.name.len() == n.len()
                && s.name
                    .bytes()
                    .zip(n.bytes())
                    .all(|(x, y)| x.eq_ignore_ascii_case(&y) || (x == b' ' && y == b'_')))
    })
}

/// Which side a primitive moves, and how.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// From a matched state, the moving side extends to the opposite face.
    Extend,
    /// From a stretch state, the moving side contracts onto the other side's face.
    Contract,
    /// The moving side swings about the hip by the given quarter turns (±1).
    Rotate(i8),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    A = 0,
    B = 1,
}

impl Side {
    pub const fn from_u8(v: u8) -> Option<Side> {
        match v {
            0 => Some(Side::A),
            1 => Some(Side::B),
            _ => None,
        }
    }
    pub const fn other(self) -> Side {
        match self {
            Side::A => Side::B,
            Side::B => Side::A,
        }
    }
    pub const fn name(self) -> &'static str {
        match self {
            Side::A => "A",
            Side::B => "B",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrimitiveDef {
    pub id: u8,
    pub name: &'static str,
    pub moving: Side,
    pub motion: Motion,
}

pub const NUM_PRIMITIVES: usize = 8;
pub const PRIMITIVES: [PrimitiveDef; NUM_PRIMITIVES] = [
    PrimitiveDef {
        id: 1,
        name: "fwd extend",
        moving: Side::A,
        motion: Motion::Extend,
    },
    PrimitiveDef {
        id: 2,
        name: "fwd contract",
        moving: Side::B,
        motion: Motion::Contract,
    },
    PrimitiveDef {
        id: 3,
        name: "back extend",
        moving: Side::B,
        motion: Motion::Extend,
    },
    PrimitiveDef {
        id: 4,
        name: "back contract",
        moving: Side::A,
        motion: Motion::Contract,
    },
    PrimitiveDef {
        id: 5,
        name: "fwd turn ccw",
        moving: Side::A,
        motion: Motion::Rotate(1),
    },
    PrimitiveDef {
        id: 6,
        name: "fwd turn cw",
        moving: Side::A,
        motion: Motion::Rotate(-1),
    },
    PrimitiveDef {
        id: 7,
        name: "back turn ccw",
        moving: Side::B,
        motion: Motion::Rotate(1),
    },
    PrimitiveDef {
        id: 8,
        name: "back turn cw",
        moving: Side::B,
        motion: Motion::Rotate(-1),
    },
];

pub const fn primitive(id: u8) -> Option<&'static PrimitiveDef> {
    if id >= 1 && id as usize <= NUM_PRIMITIVES {
        Some(&PRIMITIVES[id as usize - 1])
    } else {
        None
    }
}

/// The state reached by executing primitive `prim` (1..=8) from state `from`, if the
/// primitive applies there and leads to one of the 15 states. Single definition of the
/// primitives' effect; the reconfiguration map is derived from it.
pub const fn apply(from: u8, prim: u8) -> Option<u8> {
    if from as usize >= NUM_STATES {
        return None;
    }
    let p = match primitive(prim) {
        Some(p) => p,
        None => return None,
    };
    let s = &STATES[from as usize];
    let (mover, anchor) = match p.moving {
        Side::A => (s.a, s.b),
        Side::B => (s.b, s.a),
    };
    let kind = s.kind();
    let new_mover = match p.motion {
        Motion::Extend => {
            if !matches!(kind, StateKind::Matched) {
                return None;
            }
            mover.opposite()
        }
        Motion::Contract => {
            if !matches!(kind, StateKind::Stretch) {
                return None;
            }
            anchor
        }
        Motion::Rotate(q) => mover.rotate(q),
    };
    match p.moving {
        Side::A => state_of(new_mover, anchor),
        Side::B => state_of(anchor, new_mover),
    }
}

const fn build_map() -> [[u8; NUM_STATES]; NUM_STATES] {
    let mut m = [[0u8; NUM_STATES]; NUM_STATES];
    let mut i = 0;
    while i < NUM_STATES {
        let mut p = 1;
        while p <= NUM_PRIMITIVES as u8 {
            if let Some(j) = apply(i as u8, p) {
                m[i][j as usize] = p;
            }
            p += 1;
        }
        i += 1;
    }
    m
}

/// Reconfiguration map: `RECONFIG_MAP[from][to]` is the primitive that takes `from` to
/// `to` in one step, or 0 when no single primitive does (paper Figure 9).
pub const RECONFIG_MAP: [[u8; NUM_STATES]; NUM_STATES] = build_map();

/// Servo set points shared by OBSW, simulator and firmware.
pub mod servo {
    /// Arm fully contracted (arm switch pushed).
    pub const ARM_CONTRACTED_US: u16 = 1000;
    /// Arm at the length of a turn state.
    pub const ARM_TURN_US: u16 = 1500;
    /// Arm fully extended (spans a voxel with the other arm).
    pub const ARM_EXTENDED_US: u16 = 2000;
    /// Gripper closed on a face.
    pub const GRIP_CLOSED_US: u16 = 1100;
    /// Gripper open.
    pub const GRIP_OPEN_US: u16 = 1900;
    /// Smallest / largest commandable pulse width.
    pub const PWM_MIN_US: u16 = 900;
    pub const PWM_MAX_US: u16 = 2100;
    /// Servo internal velocity limit (µs of pulse width per second).
    pub const SERVO_SPEED_US_PER_S: u16 = 500;
    /// Hip angle range (hundredths of a degree).
    pub const HIP_MIN_CDEG: i16 = -12000;
    pub const HIP_MAX_CDEG: i16 = 12000;
    /// Hip contracted (home) angle.
    pub const HIP_HOME_CDEG: i16 = 0;
    /// Hip velocity-mode speed (paper: 10 °/s) in hundredths of a degree per second.
    pub const HIP_SPEED_CDEG_S: i16 = 1000;
    /// Error beyond which the hip runs the velocity PI (paper: 3°).
    pub const HIP_SWITCH_CDEG: i16 = 300;
    /// Hip is "at target" within this error.
    pub const HIP_DONE_CDEG: i16 = 50;
}

/// State estimator tolerances (configuration state from IMUs, hip encoder, arm and
/// gripper PWM).
pub mod estimator {
    /// Largest hip error (cdeg) still consistent with a state (10°).
    pub const HIP_TOL_CDEG: i16 = 1000;
    /// Largest arm PWM error (µs) still consistent with a state.
    pub const ARM_TOL_US: u16 = 100;
    /// A side counts as gripped only if its gripper PWM is within this of
    /// `servo::GRIP_CLOSED_US` (µs).
    pub const GRIP_TOL_US: u16 = 50;
    /// Smallest dot product (milli-g) between a measured gravity vector and a face's
    /// expected gravity for the face to be recognised (≈ 37°).
    pub const FACE_MIN_DOT_MG: i32 = 800;
    /// Accepted magnitude band (milli-g) of a gravity vector.
    pub const G_MIN_MG: i32 = 700;
    pub const G_MAX_MG: i32 = 1300;
    /// After a primitive, how long the filtered sensors may take to confirm the new state.
    pub const STATE_SETTLE_TIMEOUT_MS: u32 = 2000;
}

/// Hip controller design values.
pub mod hip {
    /// Hip "done": error within `servo::HIP_DONE_CDEG` for this many consecutive ticks.
    pub const DONE_TICKS: u8 = 20;
    /// Largest hip speed command (cdeg/s) the controller outputs.
    pub const MAX_CMD_CDEG_S: i16 = 3000;
    /// Samples spanned by the hip velocity estimate (100 ms at the control period).
    pub const VEL_SPAN: usize = 10;
}

/// Bolter constants.
pub mod bolter {
    /// Multiplexer settling time after selecting a pair.
    pub const SELECT_MS: u32 = 50;
    /// Retract time after the first push.
    pub const RETRACT_MS: u32 = 400;
    /// Reverse rotation time after locking.
    pub const REVERSE_MS: u32 = 500;
    /// Travel time back to the home position.
    pub const RETURN_MS: u32 = 1200;
    /// Unbolting: shortest reverse rotation before release is judged by current.
    pub const UNLOCK_MIN_MS: u32 = 300;
    /// Fastener pairs per face.
    pub const PAIRS_PER_FACE: u8 = 4;
    /// Ground-demo statistics (paper): of 2524 engaged pairs, bolted at the 1st, 2nd and
    /// 3rd attempt, and failed after 3.
    pub const DEMO_PAIRS: u32 = 2524;
    pub const DEMO_FIRST: u32 = 2307;
    pub const DEMO_SECOND: u32 = 103;
    pub const DEMO_THIRD: u32 = 28;
    pub const DEMO_FAILED: u32 = 86;
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: MMIC-MOT-01
    #[test]
    fn fifteen_states_three_matched_four_stretch_eight_turn() {
        let count = |k| STATES.iter().filter(|s| s.kind() == k).count();
        assert_eq!(count(StateKind::Matched), 3);
        assert_eq!(count(StateKind::Stretch), 4);
        assert_eq!(count(StateKind::Turn), 8);
        for (i, s) in STATES.iter().enumerate() {
            assert_eq!(s.id as usize, i);
            assert_eq!(state_of(s.a, s.b), Some(s.id));
        }
        assert_eq!(state_of(Ypos, Ypos), None);
    }
    // verifies: MMIC-MOT-03
    #[test]
    fn map_has_no_self_loops_and_primitives_are_reversible() {
        for (i, row) in RECONFIG_MAP.iter().enumerate() {
            assert_eq!(row[i], 0);
            for (j, p) in row.iter().enumerate() {
                if *p != 0 {
                    assert_ne!(RECONFIG_MAP[j][i], 0, "{i}->{j} has no way back");
                }
            }
        }
        // matched Xneg extends A to Xpos: "Xpos Xneg"
        assert_eq!(RECONFIG_MAP[0][4], 1);
        // "Xpos Xneg" contracts B onto Xpos: matched Xpos
        assert_eq!(RECONFIG_MAP[4][1], 2);
    }
    // verifies: MMIC-MOT-01
    #[test]
    fn state_by_name_accepts_labels_and_names() {
        assert_eq!(state_by_name("Xneg Xpos").unwrap().id, 3);
        assert_eq!(state_by_name("d").unwrap().id, 3);
        assert_eq!(state_by_name("xneg_xpos").unwrap().id, 3);
        assert!(state_by_name("Ypos").is_none());
    }
}
