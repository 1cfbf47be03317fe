//! Module-set files: which modules the simulated robot is built from, with injected
//! faults, turned into what discovery reads (board A's descriptor table, board B's half,
//! each board's probe results). Format and examples: `plans/modules/*.toml`,
//! `docs/modules.md`.
//!
//! ```toml
//! name = "gripper-rev-b"
//! expect = "FULL"                   # documented discovery outcome (checked by tests)
//! base = "full"                     # "full": every slot; "none": only [[module]] entries
//! absent = ["bolter_a"]             # slots left out (not fitted, not listed)
//! serial_base = 1000                # serial of slot n = serial_base + n unless given
//! [boards]
//! a = { revision = 1, firmware = "1.1" }
//! b = { revision = 1, firmware = "1.1" }
//! [[module]]                        # overrides for one slot (and adds it under base = "none")
//! slot = "gripper_b"
//! revision = 2                      # variant, revision, serial, calibration: optional
//! calibration = [1160, "default"]   # words (µs, mA, ...; "default" = the database's
//!                                   # value for this revision, 0x8000 in the descriptor;
//!                                   # words not given: "default"), or "default" for all
//! [[fault]]
//! kind = "corrupt-descriptor"       # corrupt-descriptor | unplugged | unlisted |
//! slot = "gripper_a"                # swap-revision | board-b-silent
//! ```

use mib::modules::db::{default_def, lookup};
use mib::modules::descriptor::{emit_table, MAX_TABLE_LEN, TABLE_HEADER_LEN};
use mib::modules::{
    slot_by_name, Board, Calibration, Descriptor, ModuleSet, ModuleType, Probe, CAL_DEFAULT, MPU6000_WHO_AM_I,
    NUM_SLOTS, SLOTS,
};
use mmic_domain::discovery::{discover, ArmSwitch, BoardInput, BoardProbes, Discovery, Invalid};
use serde::Deserialize;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// A module-set file that cannot be used: file, line (1-based, when known), the key
/// concerned and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SetError {
    pub file: PathBuf,
    pub line: Option<usize>,
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for SetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if let Some(k) = &self.key {
            write!(f, ": `{k}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for SetError {}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRepr {
    name: Option<String>,
    description: Option<String>,
    expect: Option<String>,
    base: Option<Spanned<String>>,
    #[serde(default)]
    absent: Vec<Spanned<String>>,
    serial_base: Option<u32>,
    boards: Option<BoardsRepr>,
    #[serde(default)]
    module: Vec<ModuleRepr>,
    #[serde(default)]
    fault: Vec<FaultRepr>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoardsRepr {
    a: Option<BoardRepr>,
    b: Option<BoardRepr>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoardRepr {
    revision: Option<u8>,
    firmware: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModuleRepr {
    slot: Spanned<String>,
    variant: Option<u8>,
    revision: Option<u8>,
    serial: Option<u32>,
    calibration: Option<Spanned<CalRepr>>,
}

/// `calibration = "default"` (every word the database default of the revision) or up to
/// eight words, each a number or `"default"`.
#[derive(Deserialize)]
#[serde(untagged)]
enum CalRepr {
    Words(Vec<CalWord>),
    Keyword(String),
}

#[derive(Deserialize)]
#[serde(untagged)]
enum CalWord {
    Value(i16),
    Keyword(String),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FaultRepr {
    kind: Spanned<String>,
    slot: Option<Spanned<String>>,
    revision: Option<u8>,
    /// corrupt-descriptor: byte (0..28) and bit (0..8) flipped; default byte 5, bit 4.
    byte: Option<Spanned<u8>>,
    bit: Option<Spanned<u8>>,
}

/// A fault injected into the module set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetFault {
    /// The module's stored descriptor has one bit flipped (its CRC no longer matches).
    CorruptDescriptor { slot: u8, byte: u8, bit: u8 },
    /// The module is listed in its board's table but not fitted (its probe finds nothing).
    Unplugged { slot: u8 },
    /// The module is fitted but its descriptor is missing from the table.
    Unlisted { slot: u8 },
    /// The table claims another revision than the fitted module (valid CRC).
    SwapRevision { slot: u8, revision: u8 },
    /// Board B sends no table.
    BoardBSilent,
}

/// Serial base of the factory-built full robot ([`ModuleSetSpec::full`]).
pub const FACTORY_SERIAL_BASE: u32 = 1000;

/// A parsed module-set file.
#[derive(Clone, Debug, PartialEq)]
pub struct ModuleSetSpec {
    pub name: String,
    pub description: String,
    /// Documented discovery outcome ([`outcome_key`] form), if the file states one.
    pub expect: Option<String>,
    /// The fitted modules (before faults that only change the tables).
    pub fitted: ModuleSet,
    pub faults: Vec<SetFault>,
}

/// What discovery reads from the simulated robot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DiscoveryInput {
    pub table_a: Vec<u8>,
    /// `None`: board B sent nothing.
    pub table_b: Option<Vec<u8>>,
    pub probes_a: BoardProbes,
    pub probes_b: BoardProbes,
}

impl DiscoveryInput {
    /// Runs `mmic_domain::discovery::discover` on this input.
    pub fn discover(&self) -> Discovery {
        let a = BoardInput {
            table: &self.table_a,
            probes: self.probes_a,
        };
        let b = self.table_b.as_deref().map(|t| BoardInput {
            table: t,
            probes: self.probes_b,
        });
        discover(&a, b.as_ref())
    }
}

fn line_of(text: &str, span: &Range<usize>) -> usize {
    text.get(..span.start.min(text.len()))
        .map(|s| s.matches('\n').count() + 1)
        .unwrap_or(1)
}

struct Ctx<'a> {
    file: &'a Path,
    text: &'a str,
}

impl Ctx<'_> {
    fn err(&self, span: Option<&Range<usize>>, key: &str, message: impl Into<String>) -> SetError {
        SetError {
            file: self.file.to_path_buf(),
            line: span.map(|s| line_of(self.text, s)),
            key: Some(key.to_string()),
            message: message.into(),
        }
    }
    fn slot(&self, s: &Spanned<String>, key: &str) -> Result<u8, SetError> {
        slot_by_name(s.get_ref()).map(|d| d.id).ok_or_else(|| {
            let names: Vec<&str> = SLOTS.iter().map(|s| s.name).collect();
            self.err(
                Some(&s.span()),
                key,
                format!("unknown slot '{}' (expected one of {})", s.get_ref(), names.join(", ")),
            )
        })
    }
}

/// Parses a firmware version "major.minor" into `major << 8 | minor`.
pub fn parse_firmware(s: &str) -> Option<u16> {
    let (ma, mi) = s.trim().split_once('.')?;
    Some(((ma.parse::<u8>().ok()? as u16) << 8) | mi.parse::<u8>().ok()? as u16)
}

impl ModuleSetSpec {
    /// Reads and checks a module-set file.
    pub fn load(path: &Path) -> Result<ModuleSetSpec, SetError> {
        let text = std::fs::read_to_string(path).map_err(|e| SetError {
            file: path.to_path_buf(),
            line: None,
            key: None,
            message: format!("cannot read: {e}"),
        })?;
        ModuleSetSpec::parse(path, &text)
    }

    /// Parses module-set text; `file` names it in errors.
    pub fn parse(file: &Path, text: &str) -> Result<ModuleSetSpec, SetError> {
        let cx = Ctx { file, text };
        let repr: FileRepr = toml::from_str(text).map_err(|e| SetError {
            file: file.to_path_buf(),
            line: e.span().map(|s| line_of(text, &s)),
            key: None,
            message: e.message().trim().to_string(),
        })?;
        let serial_base = repr.serial_base.unwrap_or(1000);
        let default_desc = |s: u8| -> Option<Descriptor> {
            let sd = &SLOTS[s as usize];
            default_def(sd.ty).map(|d| Descriptor {
                ty: sd.ty,
                variant: d.variant,
                revision: d.revision,
                serial: serial_base.wrapping_add(s as u32),
                side: sd.side,
                port: sd.port,
                cal: d.cal_default,
            })
        };
        let mut fitted: ModuleSet = [None; NUM_SLOTS];
        match repr.base.as_ref().map(|b| (b.get_ref().as_str(), b.span())) {
            None | Some(("full", _)) => {
                for s in 0..NUM_SLOTS as u8 {
                    fitted[s as usize] = default_desc(s);
                }
            }
            Some(("none", _)) => {}
            Some((other, span)) => {
                return Err(cx.err(
                    Some(&span),
                    "base",
                    format!("unknown base '{other}' (expected \"full\" or \"none\")"),
                ))
            }
        }
        for (i, a) in repr.absent.iter().enumerate() {
            let s = cx.slot(a, &format!("absent[{i}]"))?;
            fitted[s as usize] = None;
        }
        let mut seen = [false; NUM_SLOTS];
        for (i, m) in repr.module.iter().enumerate() {
            let key = format!("module[{i}]");
            let s = cx.slot(&m.slot, &format!("{key}.slot"))?;
            if std::mem::replace(&mut seen[s as usize], true) {
                return Err(cx.err(
                    Some(&m.slot.span()),
                    &format!("{key}.slot"),
                    format!("slot '{}' given twice", m.slot.get_ref()),
                ));
            }
            let mut d = match fitted[s as usize].or_else(|| default_desc(s)) {
                Some(d) => d,
                None => return Err(cx.err(Some(&m.slot.span()), &key, "no database entry for this slot")),
            };
            if let Some(v) = m.variant {
                d.variant = v;
            }
            if let Some(r) = m.revision {
                d.revision = r;
                // A known revision brings its own calibration defaults.
                if let Some(def) = lookup(d.ty, d.variant, r) {
                    d.cal = def.cal_default;
                }
            }
            if let Some(n) = m.serial {
                d.serial = n;
            }
            if let Some(c) = &m.calibration {
                let ckey = format!("{key}.calibration");
                let not_default = |k: &str| {
                    cx.err(
                        Some(&c.span()),
                        &ckey,
                        format!("'{k}': a calibration word is a number or \"default\""),
                    )
                };
                d.cal = match c.get_ref() {
                    CalRepr::Keyword(k) if k == "default" => Calibration::DEFAULT,
                    CalRepr::Keyword(k) => return Err(not_default(k)),
                    CalRepr::Words(words) => {
                        if words.len() > 8 {
                            return Err(cx.err(
                                Some(&c.span()),
                                &ckey,
                                format!("{} words given, at most 8", words.len()),
                            ));
                        }
                        // Words not given are "default" too.
                        let mut w = [CAL_DEFAULT; 8];
                        for (o, x) in w.iter_mut().zip(words) {
                            *o = match x {
                                CalWord::Value(v) => *v,
                                CalWord::Keyword(k) if k == "default" => CAL_DEFAULT,
                                CalWord::Keyword(k) => return Err(not_default(k)),
                            };
                        }
                        Calibration(w)
                    }
                };
            }
            fitted[s as usize] = Some(d);
        }
        if let Some(boards) = &repr.boards {
            for (b, key, r) in [(Board::A, "boards.a", &boards.a), (Board::B, "boards.b", &boards.b)] {
                let Some(r) = r else { continue };
                let slot = mib::modules::board_slot(b) as usize;
                let Some(d) = fitted[slot].as_mut() else {
                    return Err(cx.err(None, key, "board is absent but configured"));
                };
                if let Some(rev) = r.revision {
                    d.revision = rev;
                }
                if let Some(fw) = &r.firmware {
                    let v = parse_firmware(fw.get_ref()).ok_or_else(|| {
                        cx.err(
                            Some(&fw.span()),
                            &format!("{key}.firmware"),
                            format!(
                                "bad firmware version '{}' (expected \"major.minor\", e.g. \"1.1\")",
                                fw.get_ref()
                            ),
                        )
                    })?;
                    d.cal.0[0] = v as i16;
                }
            }
        }
        let mut faults = Vec::new();
        for (i, f) in repr.fault.iter().enumerate() {
            let key = format!("fault[{i}]");
            let need_slot = || -> Result<u8, SetError> {
                match &f.slot {
                    Some(s) => cx.slot(s, &format!("{key}.slot")),
                    None => Err(cx.err(
                        Some(&f.kind.span()),
                        &format!("{key}.slot"),
                        format!("fault '{}' needs a slot", f.kind.get_ref()),
                    )),
                }
            };
            let fault = match f.kind.get_ref().as_str() {
                "corrupt-descriptor" => {
                    let slot = need_slot()?;
                    let byte = f.byte.as_ref().map(|b| (*b.get_ref(), b.span())).unwrap_or((5, 0..0));
                    if byte.0 as usize >= mib::modules::DESCRIPTOR_LEN {
                        return Err(cx.err(Some(&byte.1), &format!("{key}.byte"), "byte must be below 28"));
                    }
                    let bit = f.bit.as_ref().map(|b| (*b.get_ref(), b.span())).unwrap_or((4, 0..0));
                    if bit.0 >= 8 {
                        return Err(cx.err(Some(&bit.1), &format!("{key}.bit"), "bit must be below 8"));
                    }
                    SetFault::CorruptDescriptor {
                        slot,
                        byte: byte.0,
                        bit: bit.0,
                    }
                }
                "unplugged" => SetFault::Unplugged { slot: need_slot()? },
                "unlisted" => SetFault::Unlisted { slot: need_slot()? },
                "swap-revision" => {
                    let slot = need_slot()?;
                    let revision = f.revision.ok_or_else(|| {
                        cx.err(
                            Some(&f.kind.span()),
                            &format!("{key}.revision"),
                            "swap-revision needs the revision the table claims",
                        )
                    })?;
                    SetFault::SwapRevision { slot, revision }
                }
                "board-b-silent" => SetFault::BoardBSilent,
                other => {
                    return Err(cx.err(
                        Some(&f.kind.span()),
                        &format!("{key}.kind"),
                        format!(
                            "unknown fault '{other}' (expected corrupt-descriptor, unplugged, unlisted, \
                             swap-revision or board-b-silent)"
                        ),
                    ))
                }
            };
            if let SetFault::CorruptDescriptor { slot, .. }
            | SetFault::Unplugged { slot }
            | SetFault::Unlisted { slot }
            | SetFault::SwapRevision { slot, .. } = fault
            {
                if fitted[slot as usize].is_none() && !matches!(fault, SetFault::Unplugged { .. }) {
                    return Err(cx.err(
                        f.slot.as_ref().map(|s| s.span()).as_ref(),
                        &format!("{key}.slot"),
                        format!("slot '{}' is absent: nothing to inject into", SLOTS[slot as usize].name),
                    ));
                }
            }
            faults.push(fault);
        }
        Ok(ModuleSetSpec {
            name: repr.name.unwrap_or_else(|| {
                file.file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default()
            }),
            description: repr.description.unwrap_or_default(),
            expect: repr.expect,
            fitted,
            faults,
        })
    }

    /// The full robot of the database's default build, serials `FACTORY_SERIAL_BASE + slot`
    /// (the same set as `plans/modules/full.toml`): the simulator's robot when no
    /// module-set file is given, and the configuration the host OBSW treats as accepted
    /// at the factory.
    pub fn full() -> ModuleSetSpec {
        ModuleSetSpec {
            name: "full".into(),
            description: "every module of the database's default build".into(),
            expect: Some("FULL".into()),
            fitted: mib::modules::default_set(FACTORY_SERIAL_BASE),
            faults: Vec::new(),
        }
    }

    /// The descriptor tables and probe results of this robot.
    pub fn discovery_input(&self) -> DiscoveryInput {
        // What the tables list: the fitted modules, plus unplugged ones, minus unlisted.
        let mut listed = self.fitted;
        let mut present = self.fitted;
        for f in &self.faults {
            match *f {
                SetFault::Unplugged { slot } => {
                    present[slot as usize] = None;
                    if listed[slot as usize].is_none() {
                        let sd = &SLOTS[slot as usize];
                        listed[slot as usize] = default_def(sd.ty).map(|d| Descriptor {
                            ty: sd.ty,
                            variant: d.variant,
                            revision: d.revision,
                            serial: 0,
                            side: sd.side,
                            port: sd.port,
                            cal: d.cal_default,
                        });
                    }
                }
                SetFault::Unlisted { slot } => listed[slot as usize] = None,
                SetFault::SwapRevision { slot, revision } => {
                    if let Some(d) = listed[slot as usize].as_mut() {
                        d.revision = revision;
                    }
                }
                SetFault::CorruptDescriptor { .. } | SetFault::BoardBSilent => {}
            }
        }
        let table = |board: Board| -> Vec<u8> {
            let descs: Vec<Descriptor> = SLOTS
                .iter()
                .filter(|s| s.board == board)
                .filter_map(|s| listed[s.id as usize])
                .collect();
            let mut buf = [0u8; MAX_TABLE_LEN];
            let n = emit_table(&descs, &mut buf).unwrap_or(0);
            let mut t = buf[..n].to_vec();
            // Bit flips land in the entry of the slot (entries are in slot order).
            for f in &self.faults {
                if let SetFault::CorruptDescriptor { slot, byte, bit } = *f {
                    if SLOTS[slot as usize].board != board {
                        continue;
                    }
                    let index = SLOTS
                        .iter()
                        .filter(|s| s.board == board && s.id < slot && listed[s.id as usize].is_some())
                        .count();
                    let at = TABLE_HEADER_LEN + index * mib::modules::DESCRIPTOR_LEN + byte as usize;
                    if let Some(b) = t.get_mut(at) {
                        *b ^= 1 << bit;
                    }
                }
            }
            t
        };
        let probes = |board: Board| -> BoardProbes {
            let mut p = BoardProbes::default();
            for s in SLOTS.iter().filter(|s| s.board == board) {
                let fitted = present[s.id as usize].is_some();
                match s.probe {
                    Probe::None => {}
                    Probe::WhoAmI => p.imu_who_am_i = fitted.then_some(MPU6000_WHO_AM_I),
                    Probe::I2cAck if s.ty == ModuleType::Encoder => p.encoder_ack = fitted,
                    Probe::I2cAck => p.adc_ack = fitted,
                    // The robot boots gripped in a matched state: arms contracted.
                    Probe::ArmSwitch => p.arm_switch = if fitted { ArmSwitch::Pushed } else { ArmSwitch::Absent },
                }
            }
            p
        };
        let silent = self.faults.contains(&SetFault::BoardBSilent);
        DiscoveryInput {
            table_a: table(Board::A),
            table_b: (!silent).then(|| table(Board::B)),
            probes_a: probes(Board::A),
            probes_b: probes(Board::B),
        }
    }
}

/// What the fitted modules' calibration means physically for the simulator (the
/// descriptors are bench measurements, so they are the truth): each gripper's closed
/// pulse width and its end stops, and where the hip encoder reads zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModulePhysics {
    /// Per side (A, B): the pulse width at which the gripper closes on a face (µs).
    pub grip_closed_us: [f64; 2],
    /// Per side: the gripper's end stops (µs): the narrowest closed and widest open
    /// pulse widths its revision accepts (`db::cal_range` words 0 and 1). Commanded
    /// beyond them, the servo stalls against the stop.
    pub grip_stops_us: [(f64, f64); 2],
    /// The hip angle the platform's nominal encoder conversion reads at the true zero
    /// (cdeg): (zero − 2048) × 36000 / 4096.
    pub encoder_offset_cdeg: f64,
    /// +1 or −1: the encoder's counting direction.
    pub encoder_dir: f64,
}

impl ModuleSetSpec {
    /// The physics of this robot's fitted modules (absent or unknown modules: the MIB's
    /// compiled constants, the servo's whole range).
    pub fn physics(&self) -> ModulePhysics {
        let cal = mmic_domain::calib::RobotCal::from_set(&self.fitted);
        let stops = |slot: u8| -> (f64, f64) {
            let full = (
                mib::robot::servo::PWM_MIN_US as f64,
                mib::robot::servo::PWM_MAX_US as f64,
            );
            self.fitted[slot as usize]
                .and_then(|d| lookup(d.ty, d.variant, d.revision))
                .map_or(full, |def| (def.cal_range[0].0 as f64, def.cal_range[1].1 as f64))
        };
        ModulePhysics {
            grip_closed_us: [cal.side[0].grip_closed_us as f64, cal.side[1].grip_closed_us as f64],
            grip_stops_us: [
                stops(mib::modules::slot::GRIPPER_A),
                stops(mib::modules::slot::GRIPPER_B),
            ],
            encoder_offset_cdeg: cal.encoder_offset_cdeg() as f64,
            encoder_dir: cal.encoder_dir as f64,
        }
    }
}

/// Short, stable form of a discovery outcome, as module-set files state it in `expect`:
/// the configuration name (`FULL`, `LOCOMOTION_ONLY`) or `invalid: <reason> <where>`.
pub fn outcome_key(d: &Discovery) -> String {
    let name = |s: u8| SLOTS.get(s as usize).map(|d| d.name).unwrap_or("?");
    match d.outcome {
        Ok(id) => mib::modules::config::config(id)
            .map(|c| c.name.to_string())
            .unwrap_or_else(|| format!("config {}", id.code())),
        Err(why) => {
            let r = match why {
                Invalid::BoardBSilent => "board-b-silent".to_string(),
                Invalid::TableUnreadable { board, .. } => format!("table-unreadable {}", board.name().to_lowercase()),
                Invalid::CorruptDescriptor { board, index, .. } => {
                    format!("corrupt-descriptor {}/{index}", board.name().to_lowercase())
                }
                Invalid::UnknownModule { board, index, .. } => {
                    format!("unknown-module {}/{index}", board.name().to_lowercase())
                }
                Invalid::WrongBoard { slot, .. } => format!("wrong-board {}", name(slot)),
                Invalid::WrongPort { slot, .. } => format!("wrong-port {}", name(slot)),
                Invalid::Duplicate { slot } => format!("duplicate {}", name(slot)),
                Invalid::UnknownRevision { slot, .. } => format!("unknown-revision {}", name(slot)),
                Invalid::Incompatible { slot, .. } => format!("incompatible {}", name(slot)),
                Invalid::ProbeDisagrees { slot, .. } => format!("probe-disagrees {}", name(slot)),
                Invalid::Missing { slot } => format!("missing {}", name(slot)),
                Invalid::Unsupported { present } => format!("unsupported {:#06x}", present.0),
                Invalid::CalibrationOutOfRange { slot, error } => {
                    format!("calibration-out-of-range {} word {}", name(slot), error.word)
                }
            };
            format!("invalid: {r}")
        }
    }
}
