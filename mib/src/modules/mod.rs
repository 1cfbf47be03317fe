//! Plug-and-work: module types, the fixed slots of the MMIC-I topology, module
//! descriptors (binary layout with CRC), the module database ([`db`]), the metric
//! geometry of the robot and the voxel lattice ([`geometry`]) and the supported robot
//! configurations with the configuration hash ([`config`]).
//!
//! The topology of MMIC-I is fixed (one hip, two sides), so plug-and-work means
//! *identify, verify and parameterise*: every module has a slot ([`SLOTS`]), reports a
//! [`Descriptor`] (type, variant, revision, serial, side, port, calibration, CRC) and is
//! looked up in the database by (type, variant, revision). `docs/modules.md` describes
//! the layout and the rules; `mmic_domain::discovery` runs them on board.

pub mod config;
pub mod db;
pub mod descriptor;
pub mod geometry;
pub mod report;

pub use config::{config_hash, ConfigDef, ConfigId, SlotSet, CONFIGS};
pub use db::{lookup, ModuleDef, MODULE_DB};
pub use descriptor::{Calibration, DescError, Descriptor, TableError, CAL_DEFAULT, DESCRIPTOR_LEN};

/// Module type (descriptor byte 1). Wire code with `Unknown(n)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModuleType {
    Hip,
    Arm,
    Gripper,
    Bolter,
    Imu,
    Adc,
    Encoder,
    BoardA,
    BoardB,
    Unknown(u8),
}

impl ModuleType {
    /// Every known type, in code order.
    pub const ALL: [ModuleType; 9] = [
        ModuleType::Hip,
        ModuleType::Arm,
        ModuleType::Gripper,
        ModuleType::Bolter,
        ModuleType::Imu,
        ModuleType::Adc,
        ModuleType::Encoder,
        ModuleType::BoardA,
        ModuleType::BoardB,
    ];
    pub const fn code(self) -> u8 {
        match self {
            ModuleType::Hip => 1,
            ModuleType::Arm => 2,
            ModuleType::Gripper => 3,
            ModuleType::Bolter => 4,
            ModuleType::Imu => 5,
            ModuleType::Adc => 6,
            ModuleType::Encoder => 7,
            ModuleType::BoardA => 8,
            ModuleType::BoardB => 9,
            ModuleType::Unknown(n) => n,
        }
    }
    pub const fn from_code(code: u8) -> ModuleType {
        match code {
            1 => ModuleType::Hip,
            2 => ModuleType::Arm,
            3 => ModuleType::Gripper,
            4 => ModuleType::Bolter,
            5 => ModuleType::Imu,
            6 => ModuleType::Adc,
            7 => ModuleType::Encoder,
            8 => ModuleType::BoardA,
            9 => ModuleType::BoardB,
            n => ModuleType::Unknown(n),
        }
    }
    pub const fn name(self) -> &'static str {
        match self {
            ModuleType::Hip => "hip",
            ModuleType::Arm => "arm",
            ModuleType::Gripper => "gripper",
            ModuleType::Bolter => "bolter",
            ModuleType::Imu => "imu",
            ModuleType::Adc => "adc",
            ModuleType::Encoder => "encoder",
            ModuleType::BoardA => "board_a",
            ModuleType::BoardB => "board_b",
            ModuleType::Unknown(_) => "unknown",
        }
    }
    /// Meaning of the eight calibration words of this type (empty = unused, must be 0).
    pub const fn cal_names(self) -> [&'static str; 8] {
        match self {
            ModuleType::Arm => [
                "pwm_contracted_us",
                "pwm_extended_us",
                "pwm_home_us",
                "i_idle_max_ma",
                "i_op_max_ma",
                "",
                "",
                "",
            ],
            ModuleType::Gripper => [
                "pwm_closed_us",
                "pwm_open_us",
                "pwm_home_us",
                "i_idle_max_ma",
                "i_op_max_ma",
                "",
                "",
                "",
            ],
            ModuleType::Bolter => [
                "push_threshold_ma",
                "lock_threshold_ma",
                "i_idle_max_ma",
                "i_op_max_ma",
                "",
                "",
                "",
                "",
            ],
            ModuleType::Hip => ["home_cdeg", "i_idle_max_ma", "i_op_max_ma", "", "", "", "", ""],
            ModuleType::Encoder => ["zero_counts", "direction", "", "", "", "", "", ""],
            ModuleType::Imu => ["bias_x_mg", "bias_y_mg", "bias_z_mg", "", "", "", "", ""],
            ModuleType::Adc => ["gain_trim_ppm", "offset_counts", "", "", "", "", "", ""],
            ModuleType::BoardA | ModuleType::BoardB => ["firmware_version", "", "", "", "", "", "", ""],
            ModuleType::Unknown(_) => ["", "", "", "", "", "", "", ""],
        }
    }
}

/// Which part of the robot a module belongs to (descriptor byte 8). `Centre` is the
/// hip and its encoder (driven by board A).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModuleSide {
    A,
    B,
    Centre,
    Unknown(u8),
}

impl ModuleSide {
    pub const fn code(self) -> u8 {
        match self {
            ModuleSide::A => 0,
            ModuleSide::B => 1,
            ModuleSide::Centre => 2,
            ModuleSide::Unknown(n) => n,
        }
    }
    pub const fn from_code(code: u8) -> ModuleSide {
        match code {
            0 => ModuleSide::A,
            1 => ModuleSide::B,
            2 => ModuleSide::Centre,
            n => ModuleSide::Unknown(n),
        }
    }
    pub const fn name(self) -> &'static str {
        match self {
            ModuleSide::A => "a",
            ModuleSide::B => "b",
            ModuleSide::Centre => "centre",
            ModuleSide::Unknown(_) => "unknown",
        }
    }
}

/// The board a slot's module is wired to (whose descriptor table lists it).
pub use crate::robot::Side as Board;

/// How discovery confirms a slot on the hardware, independently of the descriptor table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Probe {
    /// Nothing to probe (boards, servos driven open loop).
    None,
    /// MPU-6000 `WHO_AM_I` register (0x75) must read [`MPU6000_WHO_AM_I`].
    WhoAmI,
    /// The I2C device acknowledges its address (ADS7828, AS5600).
    I2cAck,
    /// The arm-contracted switch line is connected (reads a level that does not follow
    /// the pull resistor when it is toggled).
    ArmSwitch,
}

/// Value of the MPU-6000 `WHO_AM_I` register.
pub const MPU6000_WHO_AM_I: u8 = 0x68;

/// One place a module can occupy in the fixed MMIC-I topology.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlotDef {
    pub id: u8,
    pub name: &'static str,
    pub ty: ModuleType,
    pub side: ModuleSide,
    /// The board whose descriptor table lists the module.
    pub board: Board,
    /// Connector on that board: PWM channel (servos), I2C address (sensors), 0 (boards).
    pub port: u8,
    pub probe: Probe,
}

/// Slot numbers (also the bit positions of [`SlotSet`]).
pub mod slot {
    pub const BOARD_A: u8 = 0;
    pub const IMU_A: u8 = 1;
    pub const ADC_A: u8 = 2;
    pub const ARM_A: u8 = 3;
    pub const GRIPPER_A: u8 = 4;
    pub const BOLTER_A: u8 = 5;
    pub const HIP: u8 = 6;
    pub const ENCODER: u8 = 7;
    pub const BOARD_B: u8 = 8;
    pub const IMU_B: u8 = 9;
    pub const ADC_B: u8 = 10;
    pub const ARM_B: u8 = 11;
    pub const GRIPPER_B: u8 = 12;
    pub const BOLTER_B: u8 = 13;
}

/// Number of slots (modules of the full robot).
pub const NUM_SLOTS: usize = 14;
/// Largest number of descriptors in one board's table (board A: 8, board B: 6).
pub const MAX_TABLE_ENTRIES: usize = 8;

const fn s(
    id: u8,
    name: &'static str,
    ty: ModuleType,
    side: ModuleSide,
    board: Board,
    port: u8,
    probe: Probe,
) -> SlotDef {
    SlotDef {
        id,
        name,
        ty,
        side,
        board,
        port,
        probe,
    }
}

use ModuleSide as MS;
use ModuleType as MT;
/// The slots of the MMIC-I topology, indexed by slot number.
pub const SLOTS: [SlotDef; NUM_SLOTS] = [
    s(0, "board_a", MT::BoardA, MS::A, Board::A, 0, Probe::None),
    s(1, "imu_a", MT::Imu, MS::A, Board::A, 0x68, Probe::WhoAmI),
    s(2, "adc_a", MT::Adc, MS::A, Board::A, 0x48, Probe::I2cAck),
    s(3, "arm_a", MT::Arm, MS::A, Board::A, 1, Probe::ArmSwitch),
    s(4, "gripper_a", MT::Gripper, MS::A, Board::A, 2, Probe::None),
    s(5, "bolter_a", MT::Bolter, MS::A, Board::A, 3, Probe::None),
    s(6, "hip", MT::Hip, MS::Centre, Board::A, 4, Probe::None),
    s(7, "encoder", MT::Encoder, MS::Centre, Board::A, 0x36, Probe::I2cAck),
    s(8, "board_b", MT::BoardB, MS::B, Board::B, 0, Probe::None),
    s(9, "imu_b", MT::Imu, MS::B, Board::B, 0x68, Probe::WhoAmI),
    s(10, "adc_b", MT::Adc, MS::B, Board::B, 0x48, Probe::I2cAck),
    s(11, "arm_b", MT::Arm, MS::B, Board::B, 1, Probe::ArmSwitch),
    s(12, "gripper_b", MT::Gripper, MS::B, Board::B, 2, Probe::None),
    s(13, "bolter_b", MT::Bolter, MS::B, Board::B, 3, Probe::None),
];

/// The slot a module of type `ty` on side `side` occupies, if any.
pub const fn slot_of(ty: ModuleType, side: ModuleSide) -> Option<u8> {
    let mut i = 0;
    while i < NUM_SLOTS {
        if SLOTS[i].ty.code() == ty.code() && SLOTS[i].side.code() == side.code() {
            return Some(i as u8);
        }
        i += 1;
    }
    None
}

/// A robot's modules, indexed by slot (`None` = absent).
pub type ModuleSet = [Option<Descriptor>; NUM_SLOTS];

/// The default build: every slot with variant 0 at its lowest revision, the database's
/// calibration defaults, serial `serial_base + slot`.
pub fn default_set(serial_base: u32) -> ModuleSet {
    let mut set = [None; NUM_SLOTS];
    for s in SLOTS {
        if let Some(d) = db::default_def(s.ty) {
            set[s.id as usize] = Some(Descriptor {
                ty: s.ty,
                variant: d.variant,
                revision: d.revision,
                serial: serial_base.wrapping_add(s.id as u32),
                side: s.side,
                port: s.port,
                cal: d.cal_default,
            });
        }
    }
    set
}

/// The slot with the given name (`"gripper_a"`, ...).
pub fn slot_by_name(name: &str) -> Option<&'static SlotDef> {
    SLOTS.iter().find(|s| s.name.eq_ignore_ascii_case(name.trim()))
}

/// The slot of the board that lists `board`'s descriptors.
pub const fn board_slot(board: Board) -> u8 {
    match board {
        Board::A => slot::BOARD_A,
        Board::B => slot::BOARD_B,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: MOD-DESC-01
    #[test]
    fn type_and_side_codes_round_trip_and_unknown_is_kept() {
        for t in ModuleType::ALL {
            assert_eq!(ModuleType::from_code(t.code()), t);
        }
        assert_eq!(ModuleType::from_code(0), ModuleType::Unknown(0));
        assert_eq!(ModuleType::from_code(200).code(), 200);
        for c in 0..=255u8 {
            assert_eq!(ModuleSide::from_code(c).code(), c);
        }
    }

    // verifies: MOD-DB-01
    #[test]
    fn slots_are_indexed_by_id_and_unique_per_type_and_side() {
        for (i, s) in SLOTS.iter().enumerate() {
            assert_eq!(s.id as usize, i);
            assert_eq!(slot_of(s.ty, s.side), Some(s.id));
            assert_eq!(slot_by_name(s.name).map(|d| d.id), Some(s.id));
        }
        let on = |b| SLOTS.iter().filter(|s| s.board == b).count();
        assert!(on(Board::A) <= MAX_TABLE_ENTRIES && on(Board::B) <= MAX_TABLE_ENTRIES);
        assert_eq!(on(Board::A) + on(Board::B), NUM_SLOTS);
    }
}
