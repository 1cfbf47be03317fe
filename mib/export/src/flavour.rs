//! The choices that make one XTCE reader's flavour of the MIB's XTCE: the generic
//! document ([`Flavour::GENERIC`], any decoder such as space-packet-parser) or a reader's
//! additions (the Yamcs MDB, `yamcs::YAMCS`). [`crate::xtce`] writes the document from
//! these choices, so a flavour depends on the XTCE writer and never the other way round.

use crate::headers::HeaderField;
use crate::xml::Xml;
use mib::events::EventDef;
use mib::layout::Field;
use mib::tc::TmDef;

/// What a reader's XTCE adds to or replaces in the generic document. A replacing choice
/// returns true (or `Some`) when it wrote the element itself.
pub(crate) struct Flavour {
    /// The parameter type of a packet header field.
    pub header_type: fn(&mut Xml, &HeaderField) -> bool,
    /// The parameter types of the housekeeping structure ID and the event ID; `None`: plain
    /// 16-bit integers.
    pub id_types: Option<fn(&mut Xml)>,
    /// The types, parameters and containers of a TM kind, for robot `u8`.
    pub tm: fn(&TmDef, &mut Xml, &mut Xml, &mut Xml, u8) -> bool,
    /// The type of an event parameter (named by the `&str`).
    pub event_param_type: fn(&mut Xml, &str, &Field) -> bool,
    /// The containers of an event below its severity container (the `&str`), for robot `u8`.
    pub event_containers: fn(&mut Xml, &EventDef, &str, u8) -> bool,
    /// Parameter types, parameters and containers appended to their sets.
    pub extra_types: fn(&mut Xml),
    pub extra_params: fn(&mut Xml),
    pub extra_containers: fn(&mut Xml),
    /// The value of a TC header field the flavour fixes (instead of an operator argument).
    pub tc_header_fixed: fn(&HeaderField) -> Option<u32>,
    /// Whether every command assigns its acknowledgement flags from the MIB.
    pub assign_ack_flags: bool,
    /// The verifiers of the abstract PUS telecommand.
    pub verifiers: fn(&mut Xml),
    /// Space systems appended inside the robot's.
    pub space_systems: fn(&mut Xml),
}

impl Flavour {
    /// Plain XTCE 1.2, for any decoder (e.g. space-packet-parser).
    pub const GENERIC: Flavour = Flavour {
        header_type: |_, _| false,
        id_types: None,
        tm: |_, _, _, _, _| false,
        event_param_type: |_, _, _| false,
        event_containers: |_, _, _, _| false,
        extra_types: |_| {},
        extra_params: |_| {},
        extra_containers: |_| {},
        tc_header_fixed: |_| None,
        assign_ack_flags: false,
        verifiers: |_| {},
        space_systems: |_| {},
    };
}
