//! Module discovery at boot (docs/modules.md): which robot is this?
//!
//! Input: board A's descriptor table (flash), board B's half (sent over the A–B link, or
//! `None` when board B never answered) and each board's probe results (MPU-6000
//! `WHO_AM_I`, ADS7828 and AS5600 acknowledge, arm-switch line). Output: the module set
//! by slot, its configuration hash, and the supported configuration — or the one reason
//! it is invalid, by precedence (see [`Invalid::rank`]). Pure functions, no heap, fixed
//! capacities from the MIB (`mib::modules::NUM_SLOTS`, `MAX_TABLE_ENTRIES`).
//!
//! After discovery, [`compare`] checks the set against the configuration the ground last
//! accepted (MODULE_REPLACED), [`operational_allowed`] says whether OPERATIONAL may be
//! entered, and [`missing_for`] which absent module a PUS 8 function would need.

use core::fmt;
use heapless::Vec;
use mib::modules::config::{config_hash, ConfigDef, ConfigId, SlotSet, CONFIGS};
use mib::modules::db::{compatible, lookup, resolve_calibration, CalError};
use mib::modules::descriptor::{DescError, Descriptor, Table, TableError};
use mib::modules::{
    board_slot, slot_of, Board, ModuleSet, ModuleSide, ModuleType, Probe, MPU6000_WHO_AM_I, NUM_SLOTS, SLOTS,
};

/// State of the arm-contracted switch line at boot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ArmSwitch {
    Pushed,
    Released,
    /// Nothing connected: the line follows the pull resistor when it is toggled.
    #[default]
    Absent,
}

/// What one board's probes found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct BoardProbes {
    /// Value read from the MPU-6000 `WHO_AM_I` register; `None` = no answer.
    pub imu_who_am_i: Option<u8>,
    /// The ADS7828 acknowledged its address.
    pub adc_ack: bool,
    /// The AS5600 acknowledged its address (board A only; ignored on board B).
    pub encoder_ack: bool,
    pub arm_switch: ArmSwitch,
}

/// One board's half of the discovery input.
#[derive(Clone, Copy, Debug)]
pub struct BoardInput<'a> {
    /// The board's encoded descriptor table (`mib::modules::descriptor::Table`).
    pub table: &'a [u8],
    pub probes: BoardProbes,
}

/// Why a module set is not a supported configuration. Slots are MIB slot numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Invalid {
    /// Board B did not send its half.
    BoardBSilent,
    /// A board's table header or length is wrong.
    TableUnreadable { board: Board, error: TableError },
    /// An entry's CRC (or length, layout version) is wrong.
    CorruptDescriptor { board: Board, index: u8, error: DescError },
    /// No slot for this (type, side).
    UnknownModule {
        board: Board,
        index: u8,
        ty: ModuleType,
        side: ModuleSide,
    },
    /// The module is listed in the other board's table.
    WrongBoard { slot: u8, board: Board },
    /// The module reports another port than its slot's.
    WrongPort { slot: u8, port: u8 },
    /// Two entries claim the same slot.
    Duplicate { slot: u8 },
    /// (type, variant, revision) is not in the module database.
    UnknownRevision { slot: u8, variant: u8, revision: u8 },
    /// The revision does not work with its board's revision or firmware.
    Incompatible {
        slot: u8,
        revision: u8,
        board_rev: u8,
        fw: u16,
    },
    /// A calibration word (after "default" words took the database's value) is outside
    /// the database's range for this revision.
    CalibrationOutOfRange { slot: u8, error: CalError },
    /// The table lists the module but its probe finds nothing (`listed`), or the probe
    /// finds a module the table does not list.
    ProbeDisagrees { slot: u8, listed: bool },
    /// A module a supported configuration needs is absent (the smallest configuration
    /// containing every present module).
    Missing { slot: u8 },
    /// The present modules are not within any supported configuration.
    Unsupported { present: SlotSet },
}

impl Invalid {
    /// Precedence: the lowest rank found is the outcome.
    pub const fn rank(&self) -> u8 {
        match self {
            Invalid::BoardBSilent | Invalid::TableUnreadable { .. } => 0,
            Invalid::CorruptDescriptor { .. } => 1,
            Invalid::UnknownModule { .. }
            | Invalid::WrongBoard { .. }
            | Invalid::WrongPort { .. }
            | Invalid::Duplicate { .. } => 2,
            Invalid::UnknownRevision { .. } => 3,
            Invalid::Incompatible { .. } | Invalid::CalibrationOutOfRange { .. } => 4,
            Invalid::ProbeDisagrees { .. } => 5,
            Invalid::Missing { .. } => 6,
            Invalid::Unsupported { .. } => 7,
        }
    }
    /// The slot the reason names, if any.
    pub const fn slot(&self) -> Option<u8> {
        match *self {
            Invalid::WrongBoard { slot, .. }
            | Invalid::WrongPort { slot, .. }
            | Invalid::Duplicate { slot }
            | Invalid::UnknownRevision { slot, .. }
            | Invalid::Incompatible { slot, .. }
            | Invalid::CalibrationOutOfRange { slot, .. }
            | Invalid::ProbeDisagrees { slot, .. }
            | Invalid::Missing { slot } => Some(slot),
            Invalid::BoardBSilent
            | Invalid::TableUnreadable { .. }
            | Invalid::CorruptDescriptor { .. }
            | Invalid::UnknownModule { .. }
            | Invalid::Unsupported { .. } => None,
        }
    }
    /// Reason code for the event / module report (`mib::layout::MODULE_REASON_NAMES`, see
    /// docs/modules.md).
    pub const fn code(&self) -> u8 {
        match self {
            Invalid::BoardBSilent => 1,
            Invalid::TableUnreadable { .. } => 2,
            Invalid::CorruptDescriptor { .. } => 3,
            Invalid::UnknownModule { .. } => 4,
            Invalid::WrongBoard { .. } => 5,
            Invalid::WrongPort { .. } => 6,
            Invalid::Duplicate { .. } => 7,
            Invalid::UnknownRevision { .. } => 8,
            Invalid::Incompatible { .. } => 9,
            Invalid::ProbeDisagrees { .. } => 10,
            Invalid::Missing { .. } => 11,
            Invalid::Unsupported { .. } => 12,
            Invalid::CalibrationOutOfRange { .. } => 13,
        }
    }
}

fn slot_name(slot: u8) -> &'static str {
    SLOTS.get(slot as usize).map(|s| s.name).unwrap_or("?")
}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Invalid::BoardBSilent => write!(f, "board B sent no module table"),
            Invalid::TableUnreadable { board, error } => {
                write!(f, "board {} module table unreadable: {error}", board.name())
            }
            Invalid::CorruptDescriptor { board, index, error } => {
                write!(f, "board {} descriptor {index} corrupted: {error}", board.name())
            }
            Invalid::UnknownModule { board, index, ty, side } => write!(
                f,
                "board {} descriptor {index}: no slot for type {} side {}",
                board.name(),
                ty.code(),
                side.code()
            ),
            Invalid::WrongBoard { slot, board } => {
                write!(f, "{} listed by board {}", slot_name(slot), board.name())
            }
            Invalid::WrongPort { slot, port } => write!(f, "{} reports port {port}", slot_name(slot)),
            Invalid::Duplicate { slot } => write!(f, "{} listed twice", slot_name(slot)),
            Invalid::UnknownRevision {
                slot,
                variant,
                revision,
            } => write!(
                f,
                "{}: variant {variant} revision {revision} not in the module database",
                slot_name(slot)
            ),
            Invalid::Incompatible {
                slot,
                revision,
                board_rev,
                fw,
            } => write!(
                f,
                "{} revision {revision} incompatible with board revision {board_rev} firmware {}.{}",
                slot_name(slot),
                fw >> 8,
                fw & 0xff
            ),
            Invalid::CalibrationOutOfRange { slot, error } => write!(f, "{}: {error}", slot_name(slot)),
            Invalid::ProbeDisagrees { slot, listed: true } => {
                write!(f, "{} listed but its probe finds nothing", slot_name(slot))
            }
            Invalid::ProbeDisagrees { slot, listed: false } => {
                write!(f, "{} answers its probe but is not listed", slot_name(slot))
            }
            Invalid::Missing { slot } => write!(f, "{} missing", slot_name(slot)),
            Invalid::Unsupported { present } => {
                write!(f, "module set {:#06x} is not a supported configuration", present.0)
            }
        }
    }
}

impl core::error::Error for Invalid {}

/// Issues kept per discovery (the outcome is one of them); more are counted.
pub const MAX_ISSUES: usize = 2 * NUM_SLOTS;

/// The result of [`discover`].
#[derive(Clone, Debug, PartialEq)]
pub struct Discovery {
    /// Identified modules by slot (valid descriptor in its slot; absent otherwise).
    pub set: ModuleSet,
    /// Slots of `set` that are present.
    pub present: SlotSet,
    /// `mib::modules::config_hash` of `set`.
    pub hash: u32,
    /// The supported configuration, or the highest-precedence reason it is not one.
    pub outcome: Result<ConfigId, Invalid>,
    /// Every issue found, in discovery order (capacity [`MAX_ISSUES`]).
    pub issues: Vec<Invalid, MAX_ISSUES>,
    /// Issues that did not fit.
    pub issues_dropped: u8,
}

impl Discovery {
    fn note(&mut self, i: Invalid) {
        if self.issues.push(i).is_err() {
            self.issues_dropped = self.issues_dropped.saturating_add(1);
        }
    }
}

/// Runs discovery. `b` is `None` when board B sent nothing.
pub fn discover(a: &BoardInput<'_>, b: Option<&BoardInput<'_>>) -> Discovery {
    let mut d = Discovery {
        set: [None; NUM_SLOTS],
        present: SlotSet::EMPTY,
        hash: 0,
        outcome: Err(Invalid::BoardBSilent),
        issues: Vec::new(),
        issues_dropped: 0,
    };
    let mut claimed = SlotSet::EMPTY;
    read_table(&mut d, &mut claimed, Board::A, a.table);
    match b {
        Some(b) => read_table(&mut d, &mut claimed, Board::B, b.table),
        None => d.note(Invalid::BoardBSilent),
    }
    // Database and compatibility, against the board each module is wired to.
    for s in SLOTS {
        let Some(desc) = d.set[s.id as usize] else { continue };
        match lookup(desc.ty, desc.variant, desc.revision) {
            None => {
                d.note(Invalid::UnknownRevision {
                    slot: s.id,
                    variant: desc.variant,
                    revision: desc.revision,
                });
                d.set[s.id as usize] = None;
            }
            Some(def) => {
                if let Some(board) = d.set[board_slot(s.board) as usize] {
                    // The board's firmware version (its own calibration word 0, "default"
                    // resolved; an out-of-range board calibration is reported above).
                    let fw = lookup(board.ty, board.variant, board.revision)
                        .and_then(|bd| resolve_calibration(bd, &board.cal).ok())
                        .map_or(board.cal.0[0], |c| c.0[0]) as u16;
                    if !compatible(def, board.revision, fw) {
                        d.note(Invalid::Incompatible {
                            slot: s.id,
                            revision: desc.revision,
                            board_rev: board.revision,
                            fw,
                        });
                    }
                }
                // Same rank as Incompatible, noted after it: a revision the board cannot
                // drive is named before its calibration.
                if let Err(error) = resolve_calibration(def, &desc.cal) {
                    d.note(Invalid::CalibrationOutOfRange { slot: s.id, error });
                }
            }
        }
    }
    // Probes: on a board that answered, the probe and the table must agree.
    for s in SLOTS {
        let probes = match (s.board, b) {
            (Board::A, _) => a.probes,
            (Board::B, Some(b)) => b.probes,
            (Board::B, None) => continue,
        };
        let found = match s.probe {
            Probe::None => continue,
            Probe::WhoAmI => probes.imu_who_am_i == Some(MPU6000_WHO_AM_I),
            Probe::I2cAck if s.ty == ModuleType::Encoder => probes.encoder_ack,
            Probe::I2cAck => probes.adc_ack,
            Probe::ArmSwitch => probes.arm_switch != ArmSwitch::Absent,
        };
        // A slot claimed by a corrupted (or rejected) entry is neither listed nor
        // unlisted: its probe is not reported on top of the entry's own issue.
        let listed = d.set[s.id as usize].is_some();
        let undecided = claimed.contains(s.id) && !listed;
        if found != listed && !undecided {
            d.note(Invalid::ProbeDisagrees { slot: s.id, listed });
        }
    }
    for s in SLOTS {
        if d.set[s.id as usize].is_some() {
            d.present = d.present.with(s.id);
        }
    }
    d.hash = config_hash(&d.set);
    if let Err(why) = classify(d.present, CONFIGS) {
        d.note(why);
    }
    d.outcome = match d.issues.iter().min_by_key(|i| i.rank()) {
        Some(i) => Err(*i),
        None => classify(d.present, CONFIGS).map(|c| c.id),
    };
    d
}

fn read_table(d: &mut Discovery, claimed: &mut SlotSet, board: Board, bytes: &[u8]) {
    let table = match Table::parse(bytes) {
        Ok(t) => t,
        Err(error) => return d.note(Invalid::TableUnreadable { board, error }),
    };
    for i in 0..table.len() {
        let index = i as u8;
        let desc = match table.entry(i) {
            Some(Ok(desc)) => desc,
            Some(Err(error)) => {
                // Claim the slot the damaged bytes most likely describe (type and side
                // bytes), so that its probe is not reported on top of the corruption.
                if let Some(raw) = table.raw(i) {
                    if let Some(s) = slot_of(ModuleType::from_code(raw[1]), ModuleSide::from_code(raw[8])) {
                        *claimed = claimed.with(s);
                    }
                }
                d.note(Invalid::CorruptDescriptor { board, index, error });
                continue;
            }
            None => continue,
        };
        let Some(s) = slot_of(desc.ty, desc.side) else {
            d.note(Invalid::UnknownModule {
                board,
                index,
                ty: desc.ty,
                side: desc.side,
            });
            continue;
        };
        let def = &SLOTS[s as usize];
        if def.board != board {
            d.note(Invalid::WrongBoard { slot: s, board });
        } else if desc.port != def.port {
            d.note(Invalid::WrongPort {
                slot: s,
                port: desc.port,
            });
        } else if d.set[s as usize].is_some() {
            d.note(Invalid::Duplicate { slot: s });
        } else {
            d.set[s as usize] = Some(desc);
            *claimed = claimed.with(s);
        }
    }
}

/// The supported configuration of `configs` whose slots are exactly `present`, or why
/// there is none: the first slot missing from the smallest configuration that contains
/// every present module, else `Unsupported`.
pub fn classify(present: SlotSet, configs: &'static [ConfigDef]) -> Result<&'static ConfigDef, Invalid> {
    if let Some(c) = configs.iter().find(|c| c.slots == present) {
        return Ok(c);
    }
    let smallest = configs
        .iter()
        .filter(|c| present.is_subset_of(c.slots))
        .min_by_key(|c| c.slots.len());
    match smallest.and_then(|c| c.slots.without(present).first()) {
        Some(slot) => Err(Invalid::Missing { slot }),
        None => Err(Invalid::Unsupported { present }),
    }
}

/// Identity of a module for the replacement check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModuleIdentity {
    pub ty: ModuleType,
    pub variant: u8,
    pub revision: u8,
    pub serial: u32,
}

impl From<&Descriptor> for ModuleIdentity {
    fn from(d: &Descriptor) -> Self {
        ModuleIdentity {
            ty: d.ty,
            variant: d.variant,
            revision: d.revision,
            serial: d.serial,
        }
    }
}

/// The set against the configuration the ground last accepted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Replacement {
    /// The ground has accepted no configuration yet.
    NoneAccepted,
    /// Same configuration hash.
    Same,
    /// Hash differs: a module was replaced, added, removed or recalibrated. `slot` is the
    /// first slot whose presence, serial or revision differs when the accepted identities
    /// are known (`None`: unknown, or only calibration changed).
    Changed { slot: Option<u8> },
}

/// Compares a discovery with the last ground-accepted hash (and, when stored, the
/// accepted identities by slot).
pub fn compare(
    d: &Discovery,
    accepted_hash: Option<u32>,
    accepted_ids: Option<&[Option<ModuleIdentity>; NUM_SLOTS]>,
) -> Replacement {
    let Some(h) = accepted_hash else {
        return Replacement::NoneAccepted;
    };
    if h == d.hash {
        return Replacement::Same;
    }
    let slot = accepted_ids.and_then(|ids| {
        (0..NUM_SLOTS).find_map(|i| {
            let now = d.set[i].as_ref().map(ModuleIdentity::from);
            let differs = match (ids[i], now) {
                (Some(x), Some(y)) => x.serial != y.serial || x.revision != y.revision || x.ty != y.ty,
                (None, None) => false,
                _ => true,
            };
            differs.then_some(i as u8)
        })
    });
    Replacement::Changed { slot }
}

/// Why OPERATIONAL is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blocked {
    /// The set is invalid or unsupported.
    Invalid(Invalid),
    /// The configuration differs from the one the ground accepted (or none is accepted);
    /// the ground must accept `hash` first.
    NotAccepted { hash: u32 },
}

/// Whether OPERATIONAL may be entered: a supported configuration the ground accepted.
pub fn operational_allowed(d: &Discovery, r: Replacement) -> Result<ConfigId, Blocked> {
    let id = d.outcome.map_err(Blocked::Invalid)?;
    match r {
        Replacement::Same => Ok(id),
        Replacement::NoneAccepted | Replacement::Changed { .. } => Err(Blocked::NotAccepted { hash: d.hash }),
    }
}

/// Whether the ground's acceptance of `hash` matches this robot (a stale hash is refused).
pub fn accept(d: &Discovery, hash: u32) -> Result<u32, u32> {
    if d.outcome.is_ok() && hash == d.hash {
        Ok(hash)
    } else {
        Err(d.hash)
    }
}

/// The first module PUS 8 function `function_id` (with side argument `side`) needs that
/// is absent from `present`.
pub fn missing_for(function_id: u16, side: Option<u8>, present: SlotSet) -> Option<u8> {
    mib::modules::config::needs(function_id, side).without(present).first()
}

/// The module report body (`mib::modules::report`) of a discovery: what the robot tells
/// the ground at boot and on request.
pub fn report(d: &Discovery, r: Replacement) -> mib::modules::report::ModuleReport {
    let (reason, reason_slot) = match d.outcome {
        Ok(_) => (0, mib::modules::report::NO_SLOT),
        Err(why) => (why.code(), why.slot().unwrap_or(mib::modules::report::NO_SLOT)),
    };
    mib::modules::report::ModuleReport {
        hash: d.hash,
        config: d.outcome.map(|c| c.code()).unwrap_or(0),
        reason,
        reason_slot,
        replacement: match r {
            Replacement::NoneAccepted => 0,
            Replacement::Same => 1,
            Replacement::Changed { .. } => 2,
        },
        set: d.set,
    }
}

/// Board B's half over the A–B link, one descriptor per message (the link's frames hold
/// at most 64 bytes): chunk = `index u8 | count u8 | descriptor (28 bytes)`, carried
/// in the A–B message kind `Modules` (`crate::ablink::ModulesChunk`).
pub const CHUNK_LEN: usize = 2 + mib::modules::DESCRIPTOR_LEN;

/// Why a chunk was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChunkError {
    /// Not [`CHUNK_LEN`] bytes.
    Length(usize),
    /// `count` above `MAX_TABLE_ENTRIES`, or `index` not below `count`.
    Index { index: u8, count: u8 },
}

impl fmt::Display for ChunkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChunkError::Length(n) => write!(f, "descriptor chunk of {n} bytes (expected {CHUNK_LEN})"),
            ChunkError::Index { index, count } => write!(f, "descriptor chunk {index} of {count}"),
        }
    }
}

impl core::error::Error for ChunkError {}

/// Rebuilds board B's descriptor table from chunks (any order, repeats harmless; a new
/// `count` starts over). Entries are stored as received: their CRCs are checked by
/// [`discover`], so a corrupted entry is reported as such rather than lost.
#[derive(Clone, Debug)]
pub struct TableAssembler {
    buf: [u8; mib::modules::descriptor::MAX_TABLE_LEN],
    count: Option<u8>,
    have: u8,
    /// Chunks refused (length, index); nothing is dropped uncounted.
    pub refused: u16,
}

impl Default for TableAssembler {
    fn default() -> Self {
        Self::new()
    }
}

impl TableAssembler {
    pub const fn new() -> Self {
        TableAssembler {
            buf: [0; mib::modules::descriptor::MAX_TABLE_LEN],
            count: None,
            have: 0,
            refused: 0,
        }
    }

    /// The chunk for entry `index` of a table of `count` entries (board B's side).
    pub fn chunk(index: u8, count: u8, desc: &[u8; mib::modules::DESCRIPTOR_LEN]) -> [u8; CHUNK_LEN] {
        let mut c = [0u8; CHUNK_LEN];
        c[0] = index;
        c[1] = count;
        c[2..].copy_from_slice(desc);
        c
    }

    /// Takes one chunk; `Ok(true)` once every entry has arrived.
    pub fn push(&mut self, chunk: &[u8]) -> Result<bool, ChunkError> {
        let r = self.take(chunk);
        if r.is_err() {
            self.refused = self.refused.saturating_add(1);
        }
        r
    }

    fn take(&mut self, chunk: &[u8]) -> Result<bool, ChunkError> {
        use mib::modules::descriptor::{TABLE_HEADER_LEN, TABLE_MAGIC, TABLE_VERSION};
        use mib::modules::{DESCRIPTOR_LEN, MAX_TABLE_ENTRIES};
        if chunk.len() != CHUNK_LEN {
            return Err(ChunkError::Length(chunk.len()));
        }
        let (index, count) = (chunk[0], chunk[1]);
        if count as usize > MAX_TABLE_ENTRIES || index >= count {
            return Err(ChunkError::Index { index, count });
        }
        if self.count != Some(count) {
            self.count = Some(count);
            self.have = 0;
        }
        let at = TABLE_HEADER_LEN + index as usize * DESCRIPTOR_LEN;
        self.buf[at..at + DESCRIPTOR_LEN].copy_from_slice(&chunk[2..]);
        self.buf[0..2].copy_from_slice(&TABLE_MAGIC);
        self.buf[2] = TABLE_VERSION;
        self.buf[3] = count;
        self.have |= 1 << index;
        Ok(self.complete())
    }

    fn complete(&self) -> bool {
        match self.count {
            Some(0) => true,
            Some(n) => self.have.count_ones() == n as u32,
            None => false,
        }
    }

    /// The rebuilt table once complete.
    pub fn table(&self) -> Option<&[u8]> {
        let n = self.count? as usize;
        if !self.complete() {
            return None;
        }
        self.buf
            .get(..mib::modules::descriptor::TABLE_HEADER_LEN + n * mib::modules::DESCRIPTOR_LEN)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::modules::descriptor::{emit_table, MAX_TABLE_LEN};
    use mib::modules::{default_set, slot};
    use mib::tc::function;

    // verifies: MOD-OBSW-06
    #[test]
    fn reason_codes_are_the_mib_reason_names() {
        use mib::layout::MODULE_REASON_NAMES as N;
        let b = Board::A;
        let all = [
            (Invalid::BoardBSilent, "BOARD_B_SILENT"),
            (
                Invalid::TableUnreadable {
                    board: b,
                    error: TableError::Version(2),
                },
                "TABLE_UNREADABLE",
            ),
            (
                Invalid::CorruptDescriptor {
                    board: b,
                    index: 0,
                    error: DescError::Version(2),
                },
                "CORRUPT_DESCRIPTOR",
            ),
            (
                Invalid::UnknownModule {
                    board: b,
                    index: 0,
                    ty: ModuleType::Unknown(99),
                    side: ModuleSide::A,
                },
                "UNKNOWN_MODULE",
            ),
            (Invalid::WrongBoard { slot: 1, board: b }, "WRONG_BOARD"),
            (Invalid::WrongPort { slot: 1, port: 9 }, "WRONG_PORT"),
            (Invalid::Duplicate { slot: 1 }, "DUPLICATE"),
            (
                Invalid::UnknownRevision {
                    slot: 1,
                    variant: 0,
                    revision: 9,
                },
                "UNKNOWN_REVISION",
            ),
            (
                Invalid::Incompatible {
                    slot: 1,
                    revision: 2,
                    board_rev: 1,
                    fw: 0x100,
                },
                "INCOMPATIBLE",
            ),
            (Invalid::ProbeDisagrees { slot: 1, listed: true }, "PROBE_DISAGREES"),
            (Invalid::Missing { slot: 1 }, "MISSING"),
            (
                Invalid::CalibrationOutOfRange {
                    slot: 4,
                    error: CalError {
                        word: 0,
                        value: 1100,
                        min: 1120,
                        max: 1300,
                    },
                },
                "CALIBRATION_OUT_OF_RANGE",
            ),
            (
                Invalid::Unsupported {
                    present: SlotSet::EMPTY,
                },
                "UNSUPPORTED",
            ),
        ];
        for (why, name) in all {
            assert_eq!(N.name(why.code() as i64), Some(name), "{why}");
        }
    }

    struct Robot {
        set: ModuleSet,
        probes: [BoardProbes; 2],
    }

    fn good_probes(board: Board) -> BoardProbes {
        BoardProbes {
            imu_who_am_i: Some(MPU6000_WHO_AM_I),
            adc_ack: true,
            encoder_ack: board == Board::A,
            arm_switch: ArmSwitch::Pushed,
        }
    }

    fn full() -> Robot {
        Robot {
            set: default_set(100),
            probes: [good_probes(Board::A), good_probes(Board::B)],
        }
    }

    fn tables(set: &ModuleSet) -> ([u8; MAX_TABLE_LEN], usize, [u8; MAX_TABLE_LEN], usize) {
        let mut out = [([0u8; MAX_TABLE_LEN], 0usize), ([0u8; MAX_TABLE_LEN], 0usize)];
        for (k, board) in [Board::A, Board::B].into_iter().enumerate() {
            let descs: std::vec::Vec<Descriptor> = SLOTS
                .iter()
                .filter(|s| s.board == board)
                .filter_map(|s| set[s.id as usize])
                .collect();
            out[k].1 = emit_table(&descs, &mut out[k].0).unwrap();
        }
        (out[0].0, out[0].1, out[1].0, out[1].1)
    }

    fn run(r: &Robot) -> Discovery {
        let (ta, na, tb, nb) = tables(&r.set);
        discover(
            &BoardInput {
                table: &ta[..na],
                probes: r.probes[0],
            },
            Some(&BoardInput {
                table: &tb[..nb],
                probes: r.probes[1],
            }),
        )
    }

    // verifies: MOD-DISC-01, MOD-DISC-04
    #[test]
    fn full_and_locomotion_only_robots_are_recognised_with_their_hash() {
        let r = full();
        let d = run(&r);
        assert_eq!(d.outcome, Ok(ConfigId::Full));
        assert!(d.issues.is_empty());
        assert_eq!(d.hash, config_hash(&r.set));
        assert_eq!(d.set, r.set);
        // The whole result lives on the stack (docs/modules.md quotes the size).
        let size = core::mem::size_of::<Discovery>();
        println!("size_of::<Discovery>() = {size} bytes");
        assert!(size <= 2048, "{size}");
        let mut loco = full();
        loco.set[slot::BOLTER_A as usize] = None;
        loco.set[slot::BOLTER_B as usize] = None;
        let d2 = run(&loco);
        assert_eq!(d2.outcome, Ok(ConfigId::LocomotionOnly));
        assert_ne!(d2.hash, d.hash);
        // The locomotion-only robot refuses bolting and nothing else.
        assert_eq!(missing_for(function::BOLT_FACE, None, d2.present), Some(slot::BOLTER_A));
        assert_eq!(
            missing_for(function::UNBOLT_PAIR, Some(1), d2.present),
            Some(slot::BOLTER_A)
        );
        assert_eq!(missing_for(function::RECONFIGURE, None, d2.present), None);
        assert_eq!(missing_for(function::BOLT_FACE, None, d.present), None);
    }

    // verifies: MOD-DISC-02
    #[test]
    fn missing_arm_is_missing_and_probe_finds_the_absent_switch() {
        let mut r = full();
        r.set[slot::ARM_B as usize] = None;
        r.probes[1].arm_switch = ArmSwitch::Absent;
        let d = run(&r);
        assert_eq!(d.outcome, Err(Invalid::Missing { slot: slot::ARM_B }));
        // Without bolters and without arm B: the smallest configuration is still named.
        r.set[slot::BOLTER_A as usize] = None;
        r.set[slot::BOLTER_B as usize] = None;
        assert_eq!(run(&r).outcome, Err(Invalid::Missing { slot: slot::ARM_B }));
        // The table lists arm B but no switch answers: the probe disagrees.
        let mut r = full();
        r.probes[1].arm_switch = ArmSwitch::Absent;
        assert_eq!(
            run(&r).outcome,
            Err(Invalid::ProbeDisagrees {
                slot: slot::ARM_B,
                listed: true
            })
        );
        // An IMU answering with another WHO_AM_I, an ADC answering while unlisted.
        let mut r = full();
        r.probes[0].imu_who_am_i = Some(0x70);
        assert_eq!(
            run(&r).outcome,
            Err(Invalid::ProbeDisagrees {
                slot: slot::IMU_A,
                listed: true
            })
        );
        let mut r = full();
        r.set[slot::ADC_B as usize] = None;
        let d = run(&r);
        assert_eq!(
            d.outcome,
            Err(Invalid::ProbeDisagrees {
                slot: slot::ADC_B,
                listed: false
            })
        );
        assert!(d.issues.contains(&Invalid::Missing { slot: slot::ADC_B }));
    }

    // verifies: MOD-DISC-02
    #[test]
    fn corrupted_descriptor_outranks_everything_after_it() {
        let r = full();
        let (ta, na, tb, nb) = tables(&r.set);
        let mut ta = ta;
        // Gripper A is entry 4 of board A's table: flip a bit in its serial.
        ta[4 + 4 * 28 + 5] ^= 0x10;
        let d = discover(
            &BoardInput {
                table: &ta[..na],
                probes: r.probes[0],
            },
            Some(&BoardInput {
                table: &tb[..nb],
                probes: r.probes[1],
            }),
        );
        assert!(matches!(
            d.outcome,
            Err(Invalid::CorruptDescriptor {
                board: Board::A,
                index: 4,
                error: DescError::Crc { .. }
            })
        ));
        assert!(d.issues.contains(&Invalid::Missing { slot: slot::GRIPPER_A }));
        assert_eq!(d.set[slot::GRIPPER_A as usize], None);
        // A truncated table, board B silent.
        let d = discover(
            &BoardInput {
                table: &ta[..na - 1],
                probes: r.probes[0],
            },
            None,
        );
        assert!(matches!(
            d.outcome,
            Err(Invalid::TableUnreadable { board: Board::A, .. })
        ));
        assert!(d.issues.contains(&Invalid::BoardBSilent));
        let d = discover(
            &BoardInput {
                table: &ta[..na],
                probes: r.probes[0],
            },
            None,
        );
        assert!(matches!(
            d.issues.first(),
            Some(Invalid::CorruptDescriptor { index: 4, .. })
        ));
        assert_eq!(d.outcome.err().map(|e| e.rank()), Some(0));
    }

    // verifies: MOD-DISC-02
    #[test]
    fn unknown_and_incompatible_revisions_and_misplaced_modules() {
        // Gripper rev 2 needs firmware 1.1: with boards at 1.0 it is incompatible.
        let mut r = full();
        r.set[slot::GRIPPER_B as usize].as_mut().unwrap().revision = 2;
        r.set[slot::GRIPPER_B as usize].as_mut().unwrap().cal = mib::modules::Calibration::DEFAULT;
        assert_eq!(
            run(&r).outcome,
            Err(Invalid::Incompatible {
                slot: slot::GRIPPER_B,
                revision: 2,
                board_rev: 1,
                fw: 0x0100
            })
        );
        // Board B at firmware 1.1: supported.
        r.set[slot::BOARD_B as usize].as_mut().unwrap().cal.0[0] = 0x0101;
        assert_eq!(run(&r).outcome, Ok(ConfigId::Full));
        // A revision the database does not know.
        let mut r = full();
        r.set[slot::HIP as usize].as_mut().unwrap().revision = 7;
        let d = run(&r);
        assert_eq!(
            d.outcome,
            Err(Invalid::UnknownRevision {
                slot: slot::HIP,
                variant: 0,
                revision: 7
            })
        );
        assert_eq!(d.set[slot::HIP as usize], None);
        // Wrong port, and a module of side B in board A's table.
        let mut r = full();
        r.set[slot::ARM_A as usize].as_mut().unwrap().port = 5;
        assert_eq!(
            run(&r).outcome,
            Err(Invalid::WrongPort {
                slot: slot::ARM_A,
                port: 5
            })
        );
        let r = full();
        let mut descs: std::vec::Vec<Descriptor> = SLOTS
            .iter()
            .filter(|s| s.board == Board::A)
            .filter_map(|s| r.set[s.id as usize])
            .collect();
        descs[7] = r.set[slot::GRIPPER_B as usize].unwrap();
        let mut ta = [0u8; MAX_TABLE_LEN];
        let na = emit_table(&descs, &mut ta).unwrap();
        let (_, _, tb, nb) = tables(&r.set);
        let mut dup = descs.clone();
        dup[7] = dup[4];
        let d = discover(
            &BoardInput {
                table: &ta[..na],
                probes: r.probes[0],
            },
            Some(&BoardInput {
                table: &tb[..nb],
                probes: r.probes[1],
            }),
        );
        assert!(d.issues.contains(&Invalid::WrongBoard {
            slot: slot::GRIPPER_B,
            board: Board::A
        }));
        let na = emit_table(&dup, &mut ta).unwrap();
        let d = discover(
            &BoardInput {
                table: &ta[..na],
                probes: r.probes[0],
            },
            Some(&BoardInput {
                table: &tb[..nb],
                probes: r.probes[1],
            }),
        );
        assert!(d.issues.contains(&Invalid::Duplicate { slot: slot::GRIPPER_A }));
        // An unknown type.
        let mut odd = descs.clone();
        odd[7].ty = ModuleType::Unknown(42);
        let na = emit_table(&odd, &mut ta).unwrap();
        let d = discover(
            &BoardInput {
                table: &ta[..na],
                probes: r.probes[0],
            },
            Some(&BoardInput {
                table: &tb[..nb],
                probes: r.probes[1],
            }),
        );
        assert!(matches!(d.outcome, Err(Invalid::UnknownModule { index: 7, .. })));
    }

    // verifies: MOD-CAL-02
    #[test]
    fn calibration_outside_the_database_range_is_its_own_reason() {
        // Gripper B rev 2 (boards at firmware 1.1) still carrying rev 1's closed width:
        // below rev 2's end stop.
        let mut r = full();
        r.set[slot::BOARD_A as usize].as_mut().unwrap().cal.0[0] = 0x0101;
        r.set[slot::BOARD_B as usize].as_mut().unwrap().cal.0[0] = 0x0101;
        let gb = r.set[slot::GRIPPER_B as usize].as_mut().unwrap();
        gb.revision = 2;
        let d = run(&r);
        let why = Invalid::CalibrationOutOfRange {
            slot: slot::GRIPPER_B,
            error: CalError {
                word: 0,
                value: 1100,
                min: 1120,
                max: 1300,
            },
        };
        assert_eq!(d.outcome, Err(why));
        assert_eq!((why.code(), why.slot()), (13, Some(slot::GRIPPER_B)));
        assert_eq!(
            std::format!("{why}"),
            "gripper_b: calibration word 0 = 1100 outside 1120..=1300"
        );
        // The module stays in the set (it is identified; its calibration is wrong), and
        // OPERATIONAL is blocked by the reason.
        assert!(d.present.contains(slot::GRIPPER_B));
        assert_eq!(operational_allowed(&d, Replacement::Same), Err(Blocked::Invalid(why)));
        // "Default" words take rev 2's values: valid.
        r.set[slot::GRIPPER_B as usize].as_mut().unwrap().cal = mib::modules::Calibration::DEFAULT;
        assert_eq!(run(&r).outcome, Ok(ConfigId::Full));
        // A board's firmware word may be "default" too (1.0): then rev 2 is incompatible.
        r.set[slot::BOARD_B as usize].as_mut().unwrap().cal = mib::modules::Calibration::DEFAULT;
        assert!(matches!(run(&r).outcome, Err(Invalid::Incompatible { fw: 0x0100, .. })));
        // An encoder whose zero is beyond 12 bits.
        let mut r = full();
        r.set[slot::ENCODER as usize].as_mut().unwrap().cal.0[0] = 5000;
        assert!(matches!(
            run(&r).outcome,
            Err(Invalid::CalibrationOutOfRange { slot: slot::ENCODER, error }) if error.word == 0 && error.value == 5000
        ));
    }

    // verifies: MOD-DISC-03
    #[test]
    fn replaced_gripper_blocks_operational_until_the_new_hash_is_accepted() {
        let r = full();
        let before = run(&r);
        let mut ids = [None; NUM_SLOTS];
        for (i, d) in before.set.iter().enumerate() {
            ids[i] = d.as_ref().map(ModuleIdentity::from);
        }
        assert_eq!(compare(&before, Some(before.hash), Some(&ids)), Replacement::Same);
        assert_eq!(operational_allowed(&before, Replacement::Same), Ok(ConfigId::Full));
        let mut swapped = full();
        swapped.set[slot::GRIPPER_B as usize].as_mut().unwrap().serial = 4242;
        let after = run(&swapped);
        assert_eq!(after.outcome, Ok(ConfigId::Full));
        let rep = compare(&after, Some(before.hash), Some(&ids));
        assert_eq!(
            rep,
            Replacement::Changed {
                slot: Some(slot::GRIPPER_B)
            }
        );
        assert_eq!(
            compare(&after, Some(before.hash), None),
            Replacement::Changed { slot: None }
        );
        assert_eq!(compare(&after, None, None), Replacement::NoneAccepted);
        assert_eq!(
            operational_allowed(&after, rep),
            Err(Blocked::NotAccepted { hash: after.hash })
        );
        // A stale hash is refused, the current one accepted.
        assert_eq!(accept(&after, before.hash), Err(after.hash));
        assert_eq!(accept(&after, after.hash), Ok(after.hash));
        // Recalibration only: changed, no slot named.
        let mut recal = full();
        recal.set[slot::ARM_A as usize].as_mut().unwrap().cal.0[3] += 1;
        let d = run(&recal);
        assert_eq!(
            compare(&d, Some(before.hash), Some(&ids)),
            Replacement::Changed { slot: None }
        );
        // An invalid set is blocked for its reason even if its hash was accepted.
        let mut bad = full();
        bad.set[slot::ARM_B as usize] = None;
        bad.probes[1].arm_switch = ArmSwitch::Absent;
        let d = run(&bad);
        assert_eq!(
            operational_allowed(&d, Replacement::Same),
            Err(Blocked::Invalid(Invalid::Missing { slot: slot::ARM_B }))
        );
        assert_eq!(accept(&d, d.hash), Err(d.hash));
    }

    // verifies: MOD-DISC-02
    #[test]
    fn unsupported_when_no_configuration_contains_the_set() {
        static ONLY_LOCO: [ConfigDef; 1] = [ConfigDef {
            id: ConfigId::LocomotionOnly,
            name: "LOCOMOTION_ONLY",
            slots: mib::modules::config::LOCOMOTION,
            desc: "",
        }];
        assert_eq!(
            classify(SlotSet::ALL, &ONLY_LOCO),
            Err(Invalid::Unsupported { present: SlotSet::ALL })
        );
        assert_eq!(
            classify(mib::modules::config::LOCOMOTION, &ONLY_LOCO).map(|c| c.id),
            Ok(ConfigId::LocomotionOnly)
        );
        // Every reason has a distinct code and a message.
        let all = [
            Invalid::BoardBSilent,
            Invalid::Missing { slot: 3 },
            Invalid::Unsupported { present: SlotSet::ALL },
        ];
        for i in all {
            let mut s = heapless::String::<128>::new();
            core::fmt::write(&mut s, format_args!("{i}")).unwrap();
            assert!(!s.is_empty());
        }
    }

    // verifies: MOD-DISC-05
    #[test]
    fn arbitrary_table_bytes_never_panic() {
        use proptest::prelude::*;
        let r = full();
        let (ta, na, _, _) = tables(&r.set);
        proptest!(ProptestConfig::with_cases(512), |(bytes in proptest::collection::vec(any::<u8>(), 0..300),
                                                      flips in proptest::collection::vec((0usize..MAX_TABLE_LEN, 0u8..8), 0..6))| {
            let d = discover(&BoardInput { table: &bytes, probes: good_probes(Board::A) }, None);
            prop_assert!(d.outcome.is_err());
            let mut t = ta;
            for (at, bit) in flips {
                t[at % na] ^= 1 << bit;
            }
            let d = discover(&BoardInput { table: &t[..na], probes: good_probes(Board::A) }, None);
            prop_assert!(d.outcome.is_err());
        });
    }

    // verifies: MOD-DISC-06
    #[test]
    fn board_b_half_rebuilt_from_chunks_in_any_order() {
        let r = full();
        let (ta, na, tb, nb) = tables(&r.set);
        let table = Table::parse(&tb[..nb]).unwrap();
        let n = table.len() as u8;
        let mut asm = TableAssembler::new();
        assert_eq!(asm.table(), None);
        // Reverse order, one repeat, garbage in between.
        for i in (0..n).rev() {
            let raw: [u8; 28] = table.raw(i as usize).unwrap().try_into().unwrap();
            let c = TableAssembler::chunk(i, n, &raw);
            assert_eq!(asm.push(&c), Ok(i == 0));
            if i == 3 {
                assert_eq!(asm.push(&c), Ok(false));
                assert_eq!(asm.push(&c[..10]), Err(ChunkError::Length(10)));
                assert_eq!(
                    asm.push(&TableAssembler::chunk(9, 9, &raw)),
                    Err(ChunkError::Index { index: 9, count: 9 })
                );
                assert_eq!(
                    asm.push(&TableAssembler::chunk(6, 6, &raw)),
                    Err(ChunkError::Index { index: 6, count: 6 })
                );
            }
        }
        assert_eq!(asm.refused, 3);
        assert_eq!(asm.table(), Some(&tb[..nb]));
        let d = discover(
            &BoardInput {
                table: &ta[..na],
                probes: r.probes[0],
            },
            Some(&BoardInput {
                table: asm.table().unwrap(),
                probes: r.probes[1],
            }),
        );
        assert_eq!(d.outcome, Ok(ConfigId::Full));
        // A new count starts over.
        let raw: [u8; 28] = table.raw(0).unwrap().try_into().unwrap();
        assert_eq!(asm.push(&TableAssembler::chunk(0, 2, &raw)), Ok(false));
        assert_eq!(asm.table(), None);
    }
}
