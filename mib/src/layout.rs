//! Packet bodies as lists of fields: the one description of every TC's application data
//! and every TM's source data, service reports included.
//!
//! A body is a list of [`Item`]s: plain [`Field`]s (name, wire type and width, unit,
//! calibration, value names, range), named sub-structures ([`Sub`], e.g. the PUS 1 request
//! ID or a CDS time stamp), repeated groups whose count is an earlier field, embedded
//! packets, and one variable tail selected by an earlier field (failure data by failure
//! code, event parameters by event ID, housekeeping parameters by SID). The wire crate
//! (`mib/wire`) generates parse and emit from these lists; the exporters (XTCE, SCOS-2000,
//! ICD) and the ground decoder read the same lists.

use crate::types::{Calib, PType};

/// A module of codes and the [`Names`] list naming them, each name written once. The
/// module is written as plain Rust (so the JSON export's scan of the sources finds its
/// constants with their docs):
///
/// ```
/// mib::named_codes! {
///     /// Names of the plan states.
///     STATE_NAMES;
///     /// Plan states.
///     pub mod state {
///         /// No plan loaded.
///         pub const EMPTY: u8 = 0;
///         /// A plan is loaded and checked, not started.
///         pub const LOADED: u8 = 1;
///     }
/// }
/// assert_eq!(state::LOADED, 1);
/// assert_eq!(STATE_NAMES, mib::layout::Names::List(&[(0, "EMPTY"), (1, "LOADED")]));
/// ```
#[macro_export]
macro_rules! named_codes {
    ($(#[$nm:meta])* $names:ident; $(#[$m:meta])* pub mod $module:ident { $($(#[$doc:meta])* pub const $name:ident: $ty:ty = $v:expr;)+ }) => {
        $(#[$m])*
        pub mod $module {
            $($(#[$doc])* pub const $name: $ty = $v;)+
        }
        $(#[$nm])*
        pub const $names: $crate::layout::Names =
            $crate::layout::Names::List(&[$(($module::$name as i64, stringify!($name))),+]);
    };
}

/// How raw values of a field are named (enumeration). `None` for plain numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Names {
    None,
    /// A fixed list of `(raw value, name)`.
    List(&'static [(i64, &'static str)]),
    /// PUS 1 failure codes ([`crate::failure::FailureCode`]).
    FailureCode,
    /// Event IDs ([`crate::events::EVENTS`]; 0 = NONE, e.g. a mode change by command).
    Event,
    /// Telemetry parameter IDs ([`crate::params::PARAMS`]).
    Param,
    /// PUS 20 on-board parameter IDs ([`crate::tunables::TUNABLES`]).
    Tunable,
    /// Housekeeping structure IDs ([`crate::hk::HK_STRUCTS`]).
    Sid,
    /// Mode-tree nodes ([`crate::modes::NODES`]).
    Node,
    /// Modes. The name depends on the kind of node: when the body has a `node` field,
    /// decoders name the mode for that node (robot: STANDBY/OPERATIONAL/SAFED, modules:
    /// OFF/ON/HOLD); exports list both names per value.
    Mode,
    /// Configuration states ([`crate::robot::STATES`]; 255 = UNKNOWN).
    State,
    /// Motion primitives ([`crate::robot::PRIMITIVES`]; 0 = NONE).
    Primitive,
    /// PUS 8 function IDs ([`crate::tc::TCS`]).
    Function,
    /// PUS 12 monitoring definitions ([`crate::fdir::MONITORS`]).
    Monitor,
}

/// Robot side (0 = A, 1 = B).
pub const SIDE_NAMES: Names = Names::List(&[(0, "A"), (1, "B")]);
/// Robot root mode with 255 = none (e.g. the pending mode).
pub const ROOT_MODE_NAMES: Names = Names::List(&[(0, "STANDBY"), (1, "OPERATIONAL"), (2, "SAFED"), (255, "NONE")]);
/// PUS 12 check state of a monitor.
pub const CHECK_STATE_NAMES: Names = Names::List(&[(0, "OK"), (1, "BELOW_LOW"), (2, "ABOVE_HIGH")]);
/// Packet type bit of the CCSDS primary header.
pub const PACKET_TYPE_NAMES: Names = Names::List(&[(0, "TM"), (1, "TC")]);
/// Sequence flags of the CCSDS primary header.
pub const SEQ_FLAG_NAMES: Names = Names::List(&[(0, "CONTINUATION"), (1, "FIRST"), (2, "LAST"), (3, "UNSEGMENTED")]);
/// Boolean flag.
pub const BOOL_NAMES: Names = Names::List(&[(0, "FALSE"), (1, "TRUE")]);

/// Module slots (`crate::modules::SLOTS`, by slot number); 255 = none.
pub const SLOT_NAMES: Names = Names::List(&[
    (0, "BOARD_A"),
    (1, "IMU_A"),
    (2, "ADC_A"),
    (3, "ARM_A"),
    (4, "GRIPPER_A"),
    (5, "BOLTER_A"),
    (6, "HIP"),
    (7, "ENCODER"),
    (8, "BOARD_B"),
    (9, "IMU_B"),
    (10, "ADC_B"),
    (11, "ARM_B"),
    (12, "GRIPPER_B"),
    (13, "BOLTER_B"),
    (255, "NONE"),
]);
/// Why a module set is invalid (`mmic_domain::discovery::Invalid::code`); 0 = valid.
pub const MODULE_REASON_NAMES: Names = Names::List(&[
    (0, "NONE"),
    (1, "BOARD_B_SILENT"),
    (2, "TABLE_UNREADABLE"),
    (3, "CORRUPT_DESCRIPTOR"),
    (4, "UNKNOWN_MODULE"),
    (5, "WRONG_BOARD"),
    (6, "WRONG_PORT"),
    (7, "DUPLICATE"),
    (8, "UNKNOWN_REVISION"),
    (9, "INCOMPATIBLE"),
    (10, "PROBE_DISAGREES"),
    (11, "MISSING"),
    (12, "UNSUPPORTED"),
    (13, "CALIBRATION_OUT_OF_RANGE"),
]);
/// Why the host's accepted-configuration state file gave nothing (event CONFIG_STATE_LOST).
pub const CONFIG_STATE_LOST_NAMES: Names =
    Names::List(&[(1, "MISSING"), (2, "UNREADABLE"), (3, "CORRUPT"), (4, "WRITE_FAILED")]);
/// Supported configurations (`crate::modules::config::CONFIGS`); 0 = none (invalid set).
pub const CONFIG_ID_NAMES: Names = Names::List(&[(0, "NONE"), (1, "FULL"), (2, "LOCOMOTION_ONLY")]);
/// State of the module configuration against the one the ground accepted.
pub const CONFIG_STATUS_NAMES: Names = Names::List(&[
    (0, "NOT_DISCOVERED"),
    (1, "ACCEPTED"),
    (2, "NOT_ACCEPTED"),
    (3, "INVALID"),
]);
/// The module set against the configuration the ground accepted (module report).
pub const REPLACEMENT_NAMES: Names = Names::List(&[(0, "NONE_ACCEPTED"), (1, "SAME"), (2, "CHANGED")]);
/// Module types of a descriptor (`crate::modules::ModuleType`).
pub const MODULE_TYPE_NAMES: Names = Names::List(&[
    (1, "HIP"),
    (2, "ARM"),
    (3, "GRIPPER"),
    (4, "BOLTER"),
    (5, "IMU"),
    (6, "ADC"),
    (7, "ENCODER"),
    (8, "BOARD_A"),
    (9, "BOARD_B"),
]);
/// Side of a module descriptor (`crate::modules::ModuleSide`).
pub const MODULE_SIDE_NAMES: Names = Names::List(&[(0, "A"), (1, "B"), (2, "CENTRE")]);

const MODE_BOTH: &[(i64, &str)] = &[(0, "STANDBY/OFF"), (1, "OPERATIONAL/ON"), (2, "SAFED/HOLD")];

impl Names {
    /// Name of a raw value, if it has one.
    pub fn name(self, raw: i64) -> Option<&'static str> {
        match self {
            Names::None => None,
            Names::List(l) => l.iter().find(|(v, _)| *v == raw).map(|(_, n)| *n),
            Names::FailureCode => {
                let c = crate::failure::FailureCode::from_code(u16::try_from(raw).ok()?);
                match c {
                    crate::failure::FailureCode::Unknown(_) => None,
                    known => Some(known.name()),
                }
            }
            Names::Event => match raw {
                0 => Some("NONE"),
                _ => crate::events::by_id(u16::try_from(raw).ok()?).map(|e| e.name),
            },
            Names::Param => crate::params::by_id(u16::try_from(raw).ok()?).map(|p| p.name),
            Names::Tunable => crate::tunables::by_id(u16::try_from(raw).ok()?).map(|t| t.name),
            Names::Sid => crate::hk::by_sid(u16::try_from(raw).ok()?).map(|h| h.name),
            Names::Node => crate::modes::node_by_id(u32::try_from(raw).ok()?).map(|n| n.name),
            Names::Mode => MODE_BOTH.iter().find(|(v, _)| *v == raw).map(|(_, n)| *n),
            Names::State => match raw {
                255 => Some("UNKNOWN"),
                0..=254 => crate::robot::STATES.get(raw as usize).map(|s| s.name),
                _ => None,
            },
            Names::Primitive => match raw {
                0 => Some("NONE"),
                1..=255 => crate::robot::primitive(raw as u8).map(|p| p.name),
                _ => None,
            },
            Names::Function => crate::tc::TCS
                .iter()
                .find(|t| t.service == crate::tc::service::FUNCTION && t.function as i64 == raw)
                .map(|t| t.name),
            Names::Monitor => crate::fdir::monitor_by_id(u16::try_from(raw).ok()?).map(|m| m.name),
        }
    }

    /// The raw value named `name` (case-insensitive, trimmed; configuration states also by
    /// their one-letter label or with `_` for spaces), if any. The inverse of [`Names::name`]
    /// for tools that read names typed by a person.
    pub fn value_of(self, name: &str) -> Option<i64> {
        let name = name.trim();
        match self {
            Names::State => crate::robot::state_by_name(name).map(|s| s.id as i64),
            _ => {
                let mut found = None;
                self.for_each(|v, n| {
                    if found.is_none() && n.eq_ignore_ascii_case(name) {
                        found = Some(v);
                    }
                });
                found
            }
        }
    }

    /// Name of a mode for the node `node` (robot or module names); falls back to
    /// [`Names::name`] when the node is not in the MIB.
    pub fn mode_name_for(node: i64, mode: i64) -> Option<&'static str> {
        let n = crate::modes::node_by_id(u32::try_from(node).ok()?)?;
        crate::modes::mode_name(n.kind, u32::try_from(mode).ok()?)
    }

    /// Calls `f` for every named value (for exports), in raw-value order.
    pub fn for_each(self, mut f: impl FnMut(i64, &'static str)) {
        match self {
            Names::None => {}
            Names::List(l) => l.iter().for_each(|(v, n)| f(*v, n)),
            Names::FailureCode => crate::failure::FailureCode::ALL
                .iter()
                .for_each(|c| f(c.code() as i64, c.name())),
            Names::Event => {
                f(0, "NONE");
                crate::events::EVENTS.iter().for_each(|e| f(e.id as i64, e.name));
            }
            Names::Param => crate::params::PARAMS.iter().for_each(|p| f(p.id as i64, p.name)),
            Names::Tunable => crate::tunables::TUNABLES.iter().for_each(|t| f(t.id as i64, t.name)),
            Names::Sid => crate::hk::HK_STRUCTS.iter().for_each(|h| f(h.sid as i64, h.name)),
            Names::Node => crate::modes::NODES.iter().for_each(|n| f(n.id as i64, n.name)),
            Names::Mode => MODE_BOTH.iter().for_each(|(v, n)| f(*v, n)),
            Names::State => {
                crate::robot::STATES.iter().for_each(|s| f(s.id as i64, s.name));
                f(255, "UNKNOWN");
            }
            Names::Primitive => {
                f(0, "NONE");
                crate::robot::PRIMITIVES.iter().for_each(|p| f(p.id as i64, p.name));
            }
            Names::Function => crate::tc::TCS
                .iter()
                .filter(|t| t.service == crate::tc::service::FUNCTION)
                .for_each(|t| f(t.function as i64, t.name)),
            Names::Monitor => crate::fdir::MONITORS.iter().for_each(|m| f(m.id as i64, m.name)),
        }
    }

    pub const fn is_none(self) -> bool {
        matches!(self, Names::None)
    }
}

/// One field of a packet body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Field {
    /// Mnemonic, lower case, unique within its body.
    pub name: &'static str,
    /// Value type (and byte size when `bits` is the type's full width).
    pub ptype: PType,
    /// Width on the wire in bits: the type's full width, or fewer for a bit field of the
    /// CCSDS headers (consecutive bit fields always fill whole bytes).
    pub bits: u8,
    pub unit: &'static str,
    pub calib: Calib,
    pub names: Names,
    /// Valid raw range (inclusive).
    pub min: i64,
    pub max: i64,
    pub desc: crate::types::Text,
}

impl Field {
    /// A field covering its type's whole range, no unit, no names.
    pub const fn new(name: &'static str, ptype: PType, desc: &'static str) -> Field {
        Field {
            name,
            ptype,
            bits: ptype.bits() as u8,
            unit: "",
            calib: Calib::IDENTITY,
            names: Names::None,
            min: ptype.min(),
            max: ptype.max(),
            desc: crate::types::text(desc),
        }
    }
    /// A bit field of `bits` bits (unsigned).
    pub const fn bitfield(name: &'static str, bits: u8, desc: &'static str) -> Field {
        let ptype = if bits <= 8 { PType::U8 } else { PType::U16 };
        Field {
            bits,
            max: (1i64 << bits) - 1,
            ..Field::new(name, ptype, desc)
        }
    }
    pub const fn unit(self, unit: &'static str) -> Field {
        Field { unit, ..self }
    }
    pub const fn names(self, names: Names) -> Field {
        Field { names, ..self }
    }
    pub const fn range(self, min: i64, max: i64) -> Field {
        Field { min, max, ..self }
    }
    pub const fn calib(self, calib: Calib) -> Field {
        Field { calib, ..self }
    }
    /// True for a byte-aligned field of its type's full width.
    pub const fn is_whole(&self) -> bool {
        self.bits as usize == self.ptype.bits()
    }
}

/// Shorthand for [`Field::new`].
pub const fn f(name: &'static str, ptype: PType, desc: &'static str) -> Field {
    Field::new(name, ptype, desc)
}

/// A named structure reused by several bodies (request ID, CDS time stamp).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sub {
    /// Type name in generated code and exports (CamelCase).
    pub name: &'static str,
    pub fields: &'static [Field],
    pub desc: crate::types::Text,
}

impl Sub {
    pub const fn len(&self) -> usize {
        let mut bits = 0;
        let mut i = 0;
        while i < self.fields.len() {
            bits += self.fields[i].bits as usize;
            i += 1;
        }
        bits / 8
    }
    pub const fn is_empty(&self) -> bool {
        self.fields.is_empty()
    }
}

/// The variable tail of a body, selected by the value of an earlier field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tail {
    /// Failure data, by the `failure_code` field: [`crate::failure::FailureCode::data`].
    FailureData,
    /// Event parameters, by the `event_id` field: [`crate::events::EventDef::params`].
    EventParams,
    /// Housekeeping parameters, by the `sid` field: [`crate::hk::HkDef::params`].
    HkParams,
}

impl Tail {
    /// Name of the field that selects the tail.
    pub const fn discriminant(self) -> &'static str {
        match self {
            Tail::FailureData => "failure_code",
            Tail::EventParams => "event_id",
            Tail::HkParams => "sid",
        }
    }
}

/// One item of a body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Item {
    Field(Field),
    /// A named structure, stored under `name`.
    Sub {
        name: &'static str,
        sub: &'static Sub,
    },
    /// `count` repetitions (the value of the earlier field named `count`, at most `max`)
    /// of `items`.
    Group {
        name: &'static str,
        count: &'static str,
        max: usize,
        items: &'static [Item],
    },
    /// An embedded CCSDS space packet (length from its own primary header), at most
    /// `max_len` bytes.
    Packet {
        name: &'static str,
        max_len: usize,
    },
    /// The rest of the body, selected by an earlier field.
    Tail(Tail),
}

/// The PUS 1 request ID: the packet ID and sequence control of the TC, in its fields.
pub const REQUEST_ID: Sub = Sub {
    name: "RequestId",
    fields: &[
        Field::bitfield("version", 3, "CCSDS version number of the TC (0)"),
        Field::bitfield("packet_type", 1, "packet type of the TC (1 = TC)").names(PACKET_TYPE_NAMES),
        Field::bitfield("sec_hdr", 1, "secondary header flag of the TC").names(BOOL_NAMES),
        Field::bitfield("apid", 11, "APID of the TC"),
        Field::bitfield("seq_flags", 2, "sequence flags of the TC (3 = unsegmented)").names(SEQ_FLAG_NAMES),
        Field::bitfield("seq_count", 14, "packet sequence count of the TC"),
    ],
    desc: crate::types::text("PUS 1 request ID: packet ID and packet sequence control of the TC"),
};

/// A CDS short time stamp (p-field, days since 1958-01-01, ms of day).
pub const CDS_TIME: Sub = Sub {
    name: "CdsTime",
    fields: &[
        f("pfield", PType::U8, "CDS p-field (0x40: 16-bit days, no sub-ms)").range(
            crate::headers::CDS_SHORT_PFIELD as i64,
            crate::headers::CDS_SHORT_PFIELD as i64,
        ),
        f("days", PType::U16, "days since 1958-01-01 (CCSDS epoch)").unit("day"),
        f("ms_of_day", PType::U32, "milliseconds of the day")
            .unit("ms")
            .range(0, crate::headers::MS_PER_DAY),
    ],
    desc: crate::types::text("CDS short time stamp"),
};

/// Length on the wire of a list of fields (bit fields summed; whole bytes).
pub const fn fields_len(fields: &[Field]) -> usize {
    let mut bits = 0;
    let mut i = 0;
    while i < fields.len() {
        bits += fields[i].bits as usize;
        i += 1;
    }
    bits / 8
}

/// Fixed length of a list of items, or `None` if it holds a variable part.
pub const fn fixed_len(items: &[Item]) -> Option<usize> {
    let mut bits = 0;
    let mut i = 0;
    while i < items.len() {
        match &items[i] {
            Item::Field(f) => bits += f.bits as usize,
            Item::Sub { sub, .. } => bits += sub.len() * 8,
            Item::Group { .. } | Item::Packet { .. } | Item::Tail(_) => return None,
        }
        i += 1;
    }
    Some(bits / 8)
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: MOD-OBSW-06
    #[test]
    fn module_value_names_follow_the_module_tables() {
        for s in crate::modules::SLOTS {
            assert_eq!(SLOT_NAMES.name(s.id as i64), Some(s.name.to_ascii_uppercase().as_str()));
        }
        for c in crate::modules::config::CONFIGS {
            assert_eq!(CONFIG_ID_NAMES.name(c.id.code() as i64), Some(c.name));
        }
        for code in 1..=9u8 {
            let t = crate::modules::ModuleType::from_code(code);
            assert_eq!(
                MODULE_TYPE_NAMES.name(code as i64),
                Some(t.name().to_ascii_uppercase().as_str())
            );
        }
    }
    // verifies: PUS-PKT-04
    #[test]
    fn request_id_and_cds_time_have_their_ccsds_lengths() {
        assert_eq!(REQUEST_ID.len(), 4);
        assert_eq!(CDS_TIME.len(), crate::config::TIMESTAMP_LEN);
    }
    // verifies: MMIC-CMD-06
    #[test]
    fn every_named_value_names_back() {
        for n in [
            Names::FailureCode,
            Names::Event,
            Names::Param,
            Names::Tunable,
            Names::Sid,
            Names::Node,
            Names::State,
            Names::Primitive,
            Names::Function,
            Names::Monitor,
            SIDE_NAMES,
        ] {
            let mut count = 0;
            n.for_each(|v, name| {
                assert_eq!(n.name(v), Some(name));
                if n != Names::State || v != 255 {
                    assert_eq!(n.value_of(&name.to_ascii_lowercase()), Some(v), "{name}");
                }
                count += 1;
            });
            assert!(count > 0);
        }
    }
}
