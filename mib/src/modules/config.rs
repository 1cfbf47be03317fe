//! Supported robot configurations, the configuration hash and which commands need
//! which modules.

use super::descriptor::Descriptor;
use super::{slot, NUM_SLOTS, SLOTS};
use crate::tc::function;

/// A set of slots (bit `n` = slot `n`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct SlotSet(pub u16);

impl SlotSet {
    pub const EMPTY: SlotSet = SlotSet(0);
    pub const ALL: SlotSet = SlotSet((1 << NUM_SLOTS) - 1);
    pub const fn of(slots: &[u8]) -> SlotSet {
        let mut m = 0u16;
        let mut i = 0;
        while i < slots.len() {
            m |= 1 << slots[i];
            i += 1;
        }
        SlotSet(m)
    }
    pub const fn contains(self, slot: u8) -> bool {
        slot < 16 && self.0 & (1 << slot) != 0
    }
    pub const fn with(self, slot: u8) -> SlotSet {
        SlotSet(self.0 | (1 << (slot & 15)))
    }
    pub const fn without(self, other: SlotSet) -> SlotSet {
        SlotSet(self.0 & !other.0)
    }
    pub const fn union(self, other: SlotSet) -> SlotSet {
        SlotSet(self.0 | other.0)
    }
    pub const fn is_subset_of(self, other: SlotSet) -> bool {
        self.0 & !other.0 == 0
    }
    pub const fn len(self) -> u32 {
        self.0.count_ones()
    }
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// The lowest slot in `self`.
    pub const fn first(self) -> Option<u8> {
        if self.0 == 0 {
            None
        } else {
            Some(self.0.trailing_zeros() as u8)
        }
    }
    /// Slots in ascending order.
    pub fn iter(self) -> impl Iterator<Item = u8> {
        (0..16u8).filter(move |s| self.contains(*s))
    }
}

/// Supported configuration (wire code with `Unknown(n)`; HK and the module report).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ConfigId {
    Full,
    LocomotionOnly,
    Unknown(u8),
}

impl ConfigId {
    pub const fn code(self) -> u8 {
        match self {
            ConfigId::Full => 1,
            ConfigId::LocomotionOnly => 2,
            ConfigId::Unknown(n) => n,
        }
    }
    pub const fn from_code(c: u8) -> ConfigId {
        match c {
            1 => ConfigId::Full,
            2 => ConfigId::LocomotionOnly,
            n => ConfigId::Unknown(n),
        }
    }
}

/// A supported configuration: exactly these slots present.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfigDef {
    pub id: ConfigId,
    pub name: &'static str,
    pub slots: SlotSet,
    pub desc: &'static str,
}

/// The bolters (absent in a locomotion-only robot).
pub const BOLTERS: SlotSet = SlotSet::of(&[slot::BOLTER_A, slot::BOLTER_B]);

/// Supported configurations, most complete first.
pub const CONFIGS: &[ConfigDef] = &[
    ConfigDef {
        id: ConfigId::Full,
        name: "FULL",
        slots: SlotSet::ALL,
        desc: "every module: locomotion and bolting",
    },
    ConfigDef {
        id: ConfigId::LocomotionOnly,
        name: "LOCOMOTION_ONLY",
        slots: SlotSet::ALL.without(BOLTERS),
        desc: "no bolters: walks the lattice, refuses bolting commands",
    },
];

pub fn config(id: ConfigId) -> Option<&'static ConfigDef> {
    CONFIGS.iter().find(|c| c.id == id)
}

/// The supported configuration whose slots are exactly `present`.
pub fn config_of(present: SlotSet) -> Option<&'static ConfigDef> {
    CONFIGS.iter().find(|c| c.slots == present)
}

/// The slots every supported configuration has (what no robot may lack).
pub const fn core_slots() -> SlotSet {
    let mut m = SlotSet::ALL.0;
    let mut i = 0;
    while i < CONFIGS.len() {
        m &= CONFIGS[i].slots.0;
        i += 1;
    }
    SlotSet(m)
}

/// The configuration hash algorithm: CRC-32/ISO-HDLC (the zlib/Ethernet CRC).
pub const HASH_CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// The configuration hash before discovery has finished (CONFIG_HASH's "not discovered";
/// OPERATIONAL is refused with CONFIG_NOT_ACCEPTED and this hash meanwhile).
pub const HASH_NOT_DISCOVERED: u32 = 0;

/// Configuration hash over a descriptor set indexed by slot: CRC-32/ISO-HDLC over, for
/// each present slot in ascending order, the slot number followed by the descriptor's
/// 26 bytes before its CRC (layout version, type, variant, revision, serial, side,
/// port, calibration). Absent slots contribute nothing; the slot numbers make two sets
/// that differ only by which slot holds a module hash differently. Entries beyond
/// [`NUM_SLOTS`] are ignored.
pub fn config_hash(set: &[Option<Descriptor>]) -> u32 {
    let mut d = HASH_CRC.digest();
    for (i, e) in set.iter().enumerate().take(NUM_SLOTS) {
        if let Some(desc) = e {
            d.update(&[i as u8]);
            d.update(&desc.body());
        }
    }
    d.finalize()
}

/// Locomotion modules: both arms, both grippers, the hip and its encoder, both IMUs
/// (state estimation), both boards and ADCs (currents for the overcurrent checks).
pub const LOCOMOTION: SlotSet = SlotSet::ALL.without(BOLTERS);

/// The modules a PUS 8 function needs. `side` is the function's side argument where it
/// has one (MOVE_ARM, MOVE_GRIPPER, BOLT_PAIR, UNBOLT_PAIR: 0 = A, 1 = B); functions
/// without one ignore it. Unknown function IDs need nothing here (the core refuses them
/// on its own grounds).
pub const fn needs(function_id: u16, side: Option<u8>) -> SlotSet {
    match function_id {
        function::RECONFIGURE | function::HOME => LOCOMOTION,
        // Both sides' bolters run every pair in step; I_bo comes from both ADCs.
        function::BOLT_FACE | function::UNBOLT_FACE | function::BOLT_PAIR | function::UNBOLT_PAIR => {
            BOLTERS.union(SlotSet::of(&[slot::ADC_A, slot::ADC_B, slot::BOARD_B]))
        }
        function::MOVE_ARM => own(side, slot::ARM_A, slot::ARM_B),
        function::MOVE_GRIPPER => own(side, slot::GRIPPER_A, slot::GRIPPER_B),
        function::ROTATE_HIP => SlotSet::of(&[slot::HIP, slot::ENCODER]),
        _ => SlotSet::EMPTY,
    }
}

const fn own(side: Option<u8>, a: u8, b: u8) -> SlotSet {
    match side {
        Some(0) => SlotSet::of(&[a]),
        Some(1) => SlotSet::of(&[b]),
        _ => SlotSet::of(&[a, b]),
    }
}

/// Names of the slots in `set`, for messages: calls `f` once per slot name.
pub fn for_each_name(set: SlotSet, mut f: impl FnMut(&'static str)) {
    for s in set.iter() {
        if let Some(d) = SLOTS.get(s as usize) {
            f(d.name);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modules::db::default_def;
    use crate::modules::Calibration;

    fn default_set() -> [Option<Descriptor>; NUM_SLOTS] {
        let mut set = [None; NUM_SLOTS];
        for s in SLOTS {
            let d = default_def(s.ty).unwrap();
            set[s.id as usize] = Some(Descriptor {
                ty: s.ty,
                variant: d.variant,
                revision: d.revision,
                serial: 1000 + s.id as u32,
                side: s.side,
                port: s.port,
                cal: d.cal_default,
            });
        }
        set
    }

    // verifies: MOD-CFG-01
    #[test]
    fn full_and_locomotion_only_are_supported_and_distinct() {
        assert_eq!(config_of(SlotSet::ALL).map(|c| c.id), Some(ConfigId::Full));
        assert_eq!(
            config_of(SlotSet::ALL.without(BOLTERS)).map(|c| c.id),
            Some(ConfigId::LocomotionOnly)
        );
        // One bolter only is not a configuration.
        assert_eq!(config_of(SlotSet::ALL.without(SlotSet::of(&[slot::BOLTER_B]))), None);
        assert_eq!(core_slots(), LOCOMOTION);
        for c in CONFIGS {
            assert_eq!(ConfigId::from_code(c.id.code()), c.id);
            assert_eq!(config(c.id), Some(c));
        }
        assert_eq!(ConfigId::from_code(9), ConfigId::Unknown(9));
    }

    // verifies: MOD-CFG-02
    #[test]
    fn hash_changes_with_serial_revision_calibration_and_slot() {
        let set = default_set();
        let h = config_hash(&set);
        // Independent computation of the documented algorithm.
        let mut bytes = Vec::new();
        for (i, d) in set.iter().enumerate() {
            bytes.push(i as u8);
            bytes.extend_from_slice(&d.unwrap().to_bytes()[..26]);
        }
        assert_eq!(h, HASH_CRC.checksum(&bytes));
        assert_eq!(HASH_CRC.checksum(b"123456789"), 0xCBF4_3926);
        let changed = |f: &dyn Fn(&mut Descriptor)| {
            let mut s = set;
            f(s[slot::GRIPPER_B as usize].as_mut().unwrap());
            config_hash(&s)
        };
        assert_ne!(changed(&|d| d.serial += 1), h);
        assert_ne!(changed(&|d| d.revision = 2), h);
        assert_ne!(changed(&|d| d.cal = Calibration([1; 8])), h);
        assert_eq!(changed(&|_| {}), h);
        let mut no_bolters = set;
        no_bolters[slot::BOLTER_A as usize] = None;
        no_bolters[slot::BOLTER_B as usize] = None;
        assert_ne!(config_hash(&no_bolters), h);
        // Same descriptor in another slot hashes differently.
        let mut moved = [None; NUM_SLOTS];
        moved[0] = set[1];
        let mut moved2 = [None; NUM_SLOTS];
        moved2[2] = set[1];
        assert_ne!(config_hash(&moved), config_hash(&moved2));
    }

    // verifies: MOD-CFG-03
    #[test]
    fn bolting_needs_the_bolters_and_moves_need_their_side() {
        for f in [
            function::BOLT_FACE,
            function::UNBOLT_FACE,
            function::BOLT_PAIR,
            function::UNBOLT_PAIR,
        ] {
            let n = needs(f, Some(0));
            assert!(n.contains(slot::BOLTER_A) && n.contains(slot::BOLTER_B));
            assert!(!n.is_subset_of(LOCOMOTION));
        }
        for f in [
            function::RECONFIGURE,
            function::HOME,
            function::ROTATE_HIP,
            function::STOP,
        ] {
            assert!(needs(f, None).is_subset_of(LOCOMOTION), "function {f}");
        }
        assert_eq!(needs(function::MOVE_ARM, Some(1)), SlotSet::of(&[slot::ARM_B]));
        assert_eq!(needs(function::MOVE_GRIPPER, Some(0)), SlotSet::of(&[slot::GRIPPER_A]));
        assert_eq!(
            needs(function::MOVE_ARM, None),
            SlotSet::of(&[slot::ARM_A, slot::ARM_B])
        );
        assert_eq!(needs(999, None), SlotSet::EMPTY);
        let mut names = Vec::new();
        for_each_name(BOLTERS, |n| names.push(n));
        assert_eq!(names, ["bolter_a", "bolter_b"]);
    }
}
