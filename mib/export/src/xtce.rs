//! XTCE 1.2 (namespace `http://www.omg.org/spec/XTCE/20180204`) description of the
//! robot's TM and TC.
//!
//! Container tree: `CCSDSPacket` (primary header, abstract) → `PUS_TM` (PUS-C TM
//! secondary header with the CDS short time stamp, restricted to TM of the robot's
//! APID) → `HK_REPORT` (TM[3,25], the SID) → `HK_<structure>` (restricted on the SID,
//! the structure's parameters, the PEC); → `EVENT_<severity>` (TM[5,1..4], the event
//! ID) → `EVT_<event>` (restricted on the event ID); parameters whose values the MIB names
//! are enumerated (HK, event parameters, report fields); and one container per other TM
//! type with its fields from the MIB's field list (`mib::layout`): failure reports with
//! one child container per failure code (its failure data integers, not enumerations:
//! they may carry a value the MIB does not define, such as an unknown function), list
//! reports with one per entry count. Limits become default or context alarms (on the
//! parameters that decide when they apply, `mib::params::limits_apply`).
//! Telecommands are MetaCommands deriving from the abstract `PUS_TC`.

use super::headers::{self, HeaderField};
use super::num;
use crate::flavour::Flavour;
use crate::xml::{esc, Xml};
use mib::events::{EventDef, Severity, EVENTS};
use mib::hk::HK_STRUCTS;
use mib::params::{ParamDef, PARAMS};
use mib::tc::{self, TcDef, TCS, TMS};
use mib::types::PType;
use mib::{apid, config};

/// XTCE 1.2 namespace.
pub const XTCE_NS: &str = "http://www.omg.org/spec/XTCE/20180204";

/// Name of the XTCE parameter of event parameter `p` of `e`.
pub fn event_param_name(e: &EventDef, p: &str) -> String {
    format!("{}_{}", e.name, p)
}

fn int_encoding(t: PType) -> String {
    format!(
        "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"{}\"",
        t.bits(),
        if t.signed() { "twosComplement" } else { "unsigned" }
    )
}

fn unit_set(x: &mut Xml, unit: &str) {
    if unit.is_empty() {
        x.line("<xtce:UnitSet/>");
    } else {
        x.open("<xtce:UnitSet>");
        x.line(&format!("<xtce:Unit>{}</xtce:Unit>", esc(unit)));
        x.close("</xtce:UnitSet>");
    }
}

/// Parameter type of a plain integer (or boolean) field.
fn raw_type(x: &mut Xml, name: &str, t: PType, unit: &str, desc: &str) {
    if t == PType::Bool {
        x.open(&format!(
            "<xtce:BooleanParameterType name=\"{}\" shortDescription=\"{}\" zeroStringValue=\"False\" oneStringValue=\"True\">",
            esc(name),
            esc(desc)
        ));
        unit_set(x, unit);
        x.line(&format!("{}/>", int_encoding(t)));
        x.close("</xtce:BooleanParameterType>");
    } else {
        x.open(&format!(
            "<xtce:IntegerParameterType name=\"{}\" shortDescription=\"{}\" signed=\"{}\" sizeInBits=\"{}\">",
            esc(name),
            esc(desc),
            t.signed(),
            32.max(t.bits())
        ));
        unit_set(x, unit);
        x.line(&format!("{}/>", int_encoding(t)));
        x.close("</xtce:IntegerParameterType>");
    }
}

/// Parameter type of a field with `bits` bits (headers).
fn header_type(x: &mut Xml, f: &HeaderField) {
    x.open(&format!(
        "<xtce:IntegerParameterType name=\"{}_Type\" shortDescription=\"{}\" signed=\"false\" sizeInBits=\"32\">",
        f.name,
        esc(f.desc)
    ));
    x.line("<xtce:UnitSet/>");
    x.line(&format!(
        "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"unsigned\"/>",
        f.bits
    ));
    x.close("</xtce:IntegerParameterType>");
}

/// Enumerated parameter type of a field whose values the MIB names.
pub(super) fn enumerated_type(x: &mut Xml, tname: &str, f: &mib::layout::Field) {
    enumerated(x, "EnumeratedParameterType", tname, f, None);
}

/// Enumerated type (`kind`: parameter or argument) of a field whose values the MIB names;
/// only the values within `range` when given (an argument's valid range).
fn enumerated(x: &mut Xml, kind: &str, tname: &str, f: &mib::layout::Field, range: Option<(i64, i64)>) {
    x.open(&format!(
        "<xtce:{kind} name=\"{}\" shortDescription=\"{}\">",
        esc(tname),
        esc(f.desc)
    ));
    unit_set(x, f.unit);
    x.line(&format!(
        "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"{}\"/>",
        f.bits,
        if f.ptype.signed() { "twosComplement" } else { "unsigned" }
    ));
    x.open("<xtce:EnumerationList>");
    let mut seen = std::collections::BTreeMap::new();
    f.names.for_each(|v, n| {
        if range.is_none_or(|(lo, hi)| (lo..=hi).contains(&v)) {
            seen.entry(v).or_insert(n);
        }
    });
    for (v, n) in seen {
        x.line(&format!("<xtce:Enumeration value=\"{v}\" label=\"{}\"/>", esc(n)));
    }
    x.close("</xtce:EnumerationList>");
    x.close(&format!("</xtce:{kind}>"));
}

fn param_type(x: &mut Xml, p: &ParamDef) {
    let tname = format!("{}_Type", p.name);
    if !p.names().is_none() {
        enumerated_type(x, &tname, &p.field());
        return;
    }
    if p.calib.is_identity() && p.limits.is_none() {
        raw_type(x, &tname, p.ptype, p.unit, p.desc);
        return;
    }
    if p.calib.is_identity() {
        // Integer with limits.
        x.open(&format!(
            "<xtce:IntegerParameterType name=\"{}\" shortDescription=\"{}\" signed=\"{}\" sizeInBits=\"32\">",
            esc(&tname),
            esc(p.desc),
            p.ptype.signed()
        ));
    } else {
        x.open(&format!(
            "<xtce:FloatParameterType name=\"{}\" shortDescription=\"{}\" sizeInBits=\"64\">",
            esc(&tname),
            esc(p.desc)
        ));
    }
    unit_set(x, p.unit);
    if p.calib.is_identity() {
        x.line(&format!("{}/>", int_encoding(p.ptype)));
    } else {
        x.open(&format!("{}>", int_encoding(p.ptype)));
        x.open("<xtce:DefaultCalibrator>");
        x.open("<xtce:PolynomialCalibrator>");
        x.line(&format!(
            "<xtce:Term coefficient=\"{}\" exponent=\"0\"/>",
            num(p.calib.offset)
        ));
        x.line(&format!(
            "<xtce:Term coefficient=\"{}\" exponent=\"1\"/>",
            num(p.calib.scale)
        ));
        x.close("</xtce:PolynomialCalibrator>");
        x.close("</xtce:DefaultCalibrator>");
        x.close("</xtce:IntegerDataEncoding>");
    }
    if let Some(l) = p.limits {
        let ranges = |x: &mut Xml| {
            x.open("<xtce:StaticAlarmRanges>");
            x.line(&format!(
                "<xtce:WarningRange minInclusive=\"{}\" maxInclusive=\"{}\"/>",
                num(l.soft_lo),
                num(l.soft_hi)
            ));
            x.line(&format!(
                "<xtce:CriticalRange minInclusive=\"{}\" maxInclusive=\"{}\"/>",
                num(l.hard_lo),
                num(l.hard_hi)
            ));
            x.close("</xtce:StaticAlarmRanges>");
        };
        // Persistence: consecutive violating samples before the alarm (the collector's).
        let min_violations = mib::params::GROUND_LIMIT_PERSISTENCE;
        let contexts = super::limit_contexts(p);
        if contexts.is_empty() {
            x.open(&format!("<xtce:DefaultAlarm minViolations=\"{min_violations}\">"));
            ranges(x);
            x.close("</xtce:DefaultAlarm>");
        } else {
            // No default alarm: the limits hold only in the robot states of `limits_in`
            // and `limits_if`, one context per root mode, each matching the raw values
            // of the parameters that decide (all in the same HK structures).
            x.open("<xtce:ContextAlarmList>");
            for context in contexts {
                x.open(&format!("<xtce:ContextAlarm minViolations=\"{min_violations}\">"));
                ranges(x);
                x.open("<xtce:ContextMatch>");
                let many = context.len() > 1;
                if many {
                    x.open("<xtce:ComparisonList>");
                }
                for (param, raw) in context {
                    let param = mib::params::by_id(param).map_or("?", |q| q.name);
                    x.line(&format!(
                        "<xtce:Comparison parameterRef=\"{}\" useCalibratedValue=\"false\" comparisonOperator=\"==\" value=\"{raw}\"/>",
                        esc(param)
                    ));
                }
                if many {
                    x.close("</xtce:ComparisonList>");
                }
                x.close("</xtce:ContextMatch>");
                x.close("</xtce:ContextAlarm>");
            }
            x.close("</xtce:ContextAlarmList>");
        }
    }
    if p.calib.is_identity() {
        x.close("</xtce:IntegerParameterType>");
    } else {
        x.close("</xtce:FloatParameterType>");
    }
}

pub(super) fn parameter(x: &mut Xml, name: &str, type_ref: &str, desc: &str, aliases: &[(&str, String)]) {
    if aliases.is_empty() {
        x.line(&format!(
            "<xtce:Parameter name=\"{}\" parameterTypeRef=\"{}\" shortDescription=\"{}\"/>",
            esc(name),
            esc(type_ref),
            esc(desc)
        ));
        return;
    }
    x.open(&format!(
        "<xtce:Parameter name=\"{}\" parameterTypeRef=\"{}\" shortDescription=\"{}\">",
        esc(name),
        esc(type_ref),
        esc(desc)
    ));
    x.open("<xtce:AliasSet>");
    for (ns, a) in aliases {
        x.line(&format!("<xtce:Alias nameSpace=\"{}\" alias=\"{}\"/>", esc(ns), esc(a)));
    }
    x.close("</xtce:AliasSet>");
    x.close("</xtce:Parameter>");
}

fn entries(x: &mut Xml, names: &[String]) {
    x.open("<xtce:EntryList>");
    for n in names {
        x.line(&format!("<xtce:ParameterRefEntry parameterRef=\"{}\"/>", esc(n)));
    }
    x.close("</xtce:EntryList>");
}

pub(super) fn container(
    x: &mut Xml,
    name: &str,
    desc: &str,
    abstract_: bool,
    entries_: &[String],
    base: Option<(&str, &[(&str, String)])>,
) {
    x.open(&format!(
        "<xtce:SequenceContainer name=\"{}\" shortDescription=\"{}\"{}>",
        esc(name),
        esc(desc),
        if abstract_ { " abstract=\"true\"" } else { "" }
    ));
    entries(x, entries_);
    if let Some((b, crit)) = base {
        x.open(&format!("<xtce:BaseContainer containerRef=\"{}\">", esc(b)));
        x.open("<xtce:RestrictionCriteria>");
        x.open("<xtce:ComparisonList>");
        for (p, v) in crit {
            x.line(&format!(
                "<xtce:Comparison parameterRef=\"{}\" value=\"{}\" useCalibratedValue=\"false\"/>",
                esc(p),
                esc(v)
            ));
        }
        x.close("</xtce:ComparisonList>");
        x.close("</xtce:RestrictionCriteria>");
        x.close("</xtce:BaseContainer>");
    }
    x.close("</xtce:SequenceContainer>");
}

fn names(fields: &[HeaderField]) -> Vec<String> {
    fields.iter().map(|f| f.name.to_string()).collect()
}

fn severity_container(s: Severity) -> String {
    format!("EVENT_{}", s.name().to_ascii_uppercase())
}

/// XTCE document for the default robot (APID 0x101).
pub fn xtce_document() -> String {
    xtce_document_for(apid::DEFAULT_ROBOT)
}

/// XTCE document for robot `robot` (1..=254; out-of-range numbers use the default robot).
pub fn xtce_document_for(robot: u8) -> String {
    document(robot, &Flavour::GENERIC)
}

/// XTCE document for robot `robot` in `flavour`.
pub(crate) fn document(robot: u8, flavour: &Flavour) -> String {
    let (robot, apid) = match apid::robot_apid(robot) {
        Some(a) => (robot, a),
        None => (
            apid::DEFAULT_ROBOT,
            apid::robot_apid(apid::DEFAULT_ROBOT).unwrap_or(apid::APID_BASE + 1),
        ),
    };
    let d = Doc { flavour, robot, apid };
    let mut x = Xml {
        s: String::new(),
        depth: 0,
    };
    space_system_header(&mut x, &d);
    x.open("<xtce:TelemetryMetaData>");
    let body = parameter_types(&mut x, &d);
    parameters(&mut x, &d, &body);
    containers(&mut x, &d, &body);
    x.close("</xtce:TelemetryMetaData>");
    x.open("<xtce:CommandMetaData>");
    let tc_header_args = tc_header_args(flavour);
    argument_types(&mut x, &tc_header_args);
    meta_commands(&mut x, &d, &tc_header_args);
    x.close("</xtce:CommandMetaData>");
    (flavour.space_systems)(&mut x);
    x.close("</xtce:SpaceSystem>");
    x.s
}

/// What every section of one robot's XTCE document needs.
struct Doc<'a> {
    flavour: &'a Flavour,
    robot: u8,
    apid: u16,
}

/// The XML declaration, and the robot's space system opened with its description.
fn space_system_header(x: &mut Xml, d: &Doc) {
    let Doc { robot, apid, .. } = *d;
    x.line("<?xml version=\"1.0\" encoding=\"UTF-8\"?>");
    x.open(&format!(
        "<xtce:SpaceSystem xmlns:xtce=\"{XTCE_NS}\" xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" xsi:schemaLocation=\"{XTCE_NS} https://www.omg.org/spec/XTCE/20180204/SpaceSystem.xsd\" name=\"MMIC_I_ROBOT_{robot}\" shortDescription=\"MMIC-I robot {robot}, APID 0x{apid:03X}\">"
    ));
    x.line(&format!(
        "<xtce:LongDescription>Generated from the MMIC-I MIB (crate mib {}). CCSDS space packets with PUS-C secondary headers; all fields big-endian; every packet ends with a CRC-16/CCITT-FALSE packet error control (PEC).</xtce:LongDescription>",
        env!("CARGO_PKG_VERSION")
    ));
    x.line(&format!(
        "<xtce:Header version=\"{}\" validationStatus=\"Working\"/>",
        env!("CARGO_PKG_VERSION")
    ));
}

/// The TM parameter types; returns the TM kinds' own parameters and containers, written
/// with their types.
fn parameter_types(x: &mut Xml, d: &Doc) -> BodyXtce {
    let Doc { flavour, robot, .. } = *d;
    x.open("<xtce:ParameterTypeSet>");
    for f in headers::PRIMARY_HEADER
        .iter()
        .chain(headers::TM_SEC_HEADER)
        .chain([&headers::PEC])
    {
        if !(flavour.header_type)(x, f) {
            header_type(x, f);
        }
    }
    if let Some(id_types) = flavour.id_types {
        id_types(x);
    } else {
        header_type(
            x,
            &HeaderField {
                name: "HK_SID",
                bits: 16,
                fixed: None,
                desc: "housekeeping structure ID",
            },
        );
        header_type(
            x,
            &HeaderField {
                name: "EVENT_ID",
                bits: 16,
                fixed: None,
                desc: "event ID",
            },
        );
    }
    let mut body = BodyXtce::new();
    for t in TMS
        .iter()
        .filter(|t| !super::scos::is_identified_by_pi1(t.service, t.subservice))
    {
        if (flavour.tm)(t, &mut body.types, &mut body.params, &mut body.containers, robot) {
            continue;
        }
        body.tm(t);
    }
    x.s.push_str(&body.types.s);
    for p in PARAMS {
        param_type(x, p);
    }
    for e in EVENTS {
        for ep in e.params {
            let n = event_param_name(e, ep.name);
            if (flavour.event_param_type)(x, &format!("{n}_Type"), ep) {
                continue;
            }
            if ep.names.is_none() {
                raw_type(
                    x,
                    &format!("{n}_Type"),
                    ep.ptype,
                    "",
                    &format!("{} of event {}", ep.name, e.name),
                );
            } else {
                enumerated_type(x, &format!("{n}_Type"), ep);
            }
        }
    }
    (flavour.extra_types)(x);
    x.close("</xtce:ParameterTypeSet>");
    body
}

/// The TM parameters.
fn parameters(x: &mut Xml, d: &Doc, body: &BodyXtce) {
    x.open("<xtce:ParameterSet>");
    for f in headers::PRIMARY_HEADER
        .iter()
        .chain(headers::TM_SEC_HEADER)
        .chain([&headers::PEC])
    {
        parameter(x, f.name, &format!("{}_Type", f.name), f.desc, &[]);
    }
    parameter(x, "HK_SID", "HK_SID_Type", "housekeeping structure ID", &[]);
    parameter(x, "EVENT_ID", "EVENT_ID_Type", "event ID", &[]);
    x.s.push_str(&body.params.s);
    for p in PARAMS {
        parameter(
            x,
            p.name,
            &format!("{}_Type", p.name),
            p.desc,
            &[
                ("MMIC-I/PID", p.id.to_string()),
                ("SCOS-2000", super::ScosNames::tm_param(p.id)),
            ],
        );
    }
    for e in EVENTS {
        for (i, ep) in e.params.iter().enumerate() {
            let n = event_param_name(e, ep.name);
            parameter(
                x,
                &n,
                &format!("{n}_Type"),
                &format!("parameter {} of event {}", ep.name, e.name),
                &[("SCOS-2000", super::ScosNames::event_param(e.id, i))],
            );
        }
    }
    (d.flavour.extra_params)(x);
    x.close("</xtce:ParameterSet>");
}

/// The TM containers: headers, housekeeping, events, then the other TM kinds.
fn containers(x: &mut Xml, d: &Doc, body: &BodyXtce) {
    let Doc { flavour, robot, apid } = *d;
    x.open("<xtce:ContainerSet>");
    container(
        x,
        "CCSDSPacket",
        "CCSDS space packet primary header",
        true,
        &names(headers::PRIMARY_HEADER),
        None,
    );
    container(
        x,
        "PUS_TM",
        "PUS-C telemetry of this robot: TM secondary header with CDS short time",
        true,
        &names(headers::TM_SEC_HEADER),
        Some((
            "CCSDSPacket",
            &[
                ("PKT_TYPE", "0".to_string()),
                ("SEC_HDR_FLG", "1".to_string()),
                ("PKT_APID", apid.to_string()),
            ],
        )),
    );
    let pec = [headers::PEC.name.to_string()];
    container(
        x,
        "HK_REPORT",
        "TM[3,25] housekeeping parameter report",
        true,
        &["HK_SID".to_string()],
        Some((
            "PUS_TM",
            &[
                (mib::headers::TM_SERVICE, tc::service::HOUSEKEEPING.to_string()),
                ("TM_SUBSERVICE", "25".to_string()),
            ],
        )),
    );
    for h in HK_STRUCTS {
        let mut e: Vec<String> = h
            .params
            .iter()
            .filter_map(|id| mib::params::by_id(*id))
            .map(|p| p.name.to_string())
            .collect();
        e.extend(pec.iter().cloned());
        container(
            x,
            &format!("HK_{}", h.name),
            &format!("SID {}: {}", h.sid, h.desc),
            false,
            &e,
            Some(("HK_REPORT", &[("HK_SID", h.sid.to_string())])),
        );
    }
    let sevs = [Severity::Info, Severity::Low, Severity::Medium, Severity::High];
    for s in sevs {
        container(
            x,
            &severity_container(s),
            &format!("TM[5,{}] {} severity event report", s.subservice(), s.name()),
            true,
            &["EVENT_ID".to_string()],
            Some((
                "PUS_TM",
                &[
                    (mib::headers::TM_SERVICE, tc::service::EVENT.to_string()),
                    ("TM_SUBSERVICE", s.subservice().to_string()),
                ],
            )),
        );
    }
    for e in EVENTS {
        if (flavour.event_containers)(x, e, &severity_container(e.severity), robot) {
            continue;
        }
        let mut en: Vec<String> = e.params.iter().map(|p| event_param_name(e, p.name)).collect();
        en.extend(pec.iter().cloned());
        container(
            x,
            &format!("EVT_{}", e.name),
            &format!("event 0x{:04X}: {}", e.id, e.desc),
            false,
            &en,
            Some((&severity_container(e.severity), &[("EVENT_ID", e.id.to_string())])),
        );
    }
    x.s.push_str(&body.containers.s);
    (flavour.extra_containers)(x);
    x.close("</xtce:ContainerSet>");
}

/// The TC header fields an operator (or the flavour's assignments) supplies.
fn tc_header_args(flavour: &Flavour) -> Vec<&'static HeaderField> {
    headers::PRIMARY_HEADER
        .iter()
        .chain(headers::TC_SEC_HEADER)
        .filter(|f| f.fixed.is_none() && f.name != "PKT_TYPE" && f.name != "TC_SOURCE_ID")
        .filter(|f| (flavour.tc_header_fixed)(f).is_none())
        .collect()
}

/// The TC argument types: the free header fields, then every TC's arguments.
fn argument_types(x: &mut Xml, tc_header_args: &[&HeaderField]) {
    x.open("<xtce:ArgumentTypeSet>");
    for f in tc_header_args {
        x.open(&format!(
            "<xtce:IntegerArgumentType name=\"TC_{}_Type\" shortDescription=\"{}\" signed=\"false\" sizeInBits=\"32\">",
            f.name,
            esc(f.desc)
        ));
        x.line("<xtce:UnitSet/>");
        x.line(&format!(
            "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"unsigned\"/>",
            f.bits
        ));
        x.close("</xtce:IntegerArgumentType>");
    }
    for t in TCS {
        for a in t.args {
            if !a.names.is_none() {
                let tname = format!("{}_{}_Type", t.name, a.name);
                enumerated(x, "EnumeratedArgumentType", &tname, a, Some((a.min, a.max)));
                continue;
            }
            x.open(&format!(
                "<xtce:IntegerArgumentType name=\"{}_{}_Type\" shortDescription=\"{}\" signed=\"{}\" sizeInBits=\"{}\">",
                t.name,
                a.name,
                esc(a.desc),
                a.ptype.signed(),
                32.max(a.ptype.bits())
            ));
            unit_set(x, a.unit);
            x.line(&format!("{}/>", int_encoding(a.ptype)));
            x.open("<xtce:ValidRangeSet>");
            x.line(&format!(
                "<xtce:ValidRange minInclusive=\"{}\" maxInclusive=\"{}\"/>",
                a.min, a.max
            ));
            x.close("</xtce:ValidRangeSet>");
            x.close("</xtce:IntegerArgumentType>");
        }
    }
    x.close("</xtce:ArgumentTypeSet>");
}

/// The abstract PUS TC with the headers, then one meta-command per TC.
fn meta_commands(x: &mut Xml, d: &Doc, tc_header_args: &[&HeaderField]) {
    x.open("<xtce:MetaCommandSet>");
    // Abstract PUS-C TC with the headers.
    x.open("<xtce:MetaCommand name=\"PUS_TC\" abstract=\"true\" shortDescription=\"PUS-C telecommand: CCSDS primary header and TC secondary header; a CRC-16/CCITT-FALSE PEC follows the application data\">");
    x.open("<xtce:ArgumentList>");
    for f in tc_header_args {
        x.line(&format!(
            "<xtce:Argument name=\"{}\" argumentTypeRef=\"TC_{}_Type\"{}/>",
            f.name,
            f.name,
            if f.name == "TC_ACK_FLAGS" || f.name == "SRC_SEQ_CTR" || f.name == "PKT_LEN" {
                " initialValue=\"0\""
            } else {
                ""
            }
        ));
    }
    x.close("</xtce:ArgumentList>");
    x.open("<xtce:CommandContainer name=\"PUS_TC\">");
    x.open("<xtce:EntryList>");
    for f in headers::PRIMARY_HEADER.iter().chain(headers::TC_SEC_HEADER) {
        let fixed = match f.name {
            "PKT_TYPE" => Some(1),
            "TC_SOURCE_ID" => Some(config::GROUND_ID as u32),
            _ => (d.flavour.tc_header_fixed)(f).or(f.fixed),
        };
        match fixed {
            Some(v) => x.line(&format!(
                "<xtce:FixedValueEntry name=\"{}\" binaryValue=\"{}\" sizeInBits=\"{}\"/>",
                f.name,
                hex_value(v as u64, f.bits),
                f.bits
            )),
            None => x.line(&format!("<xtce:ArgumentRefEntry argumentRef=\"{}\"/>", f.name)),
        }
    }
    x.close("</xtce:EntryList>");
    x.close("</xtce:CommandContainer>");
    (d.flavour.verifiers)(x);
    x.close("</xtce:MetaCommand>");

    for t in TCS {
        meta_command(x, t, d.apid, d.flavour);
    }
    x.close("</xtce:MetaCommandSet>");
}

/// Hex string of `v` on `bits` bits (whole octets, as `binaryValue` wants).
fn hex_value(v: u64, bits: u32) -> String {
    let octets = bits.div_ceil(8).max(1) as usize;
    format!("{:0width$X}", v, width = octets * 2)
}

fn meta_command(x: &mut Xml, t: &TcDef, apid: u16, flavour: &Flavour) {
    let mut desc = format!(
        "TC[{},{}]{}: {}; accepted in {}",
        t.service,
        t.subservice,
        if t.service == tc::service::FUNCTION {
            format!(" function {}", t.function)
        } else {
            String::new()
        },
        t.description(),
        t.modes.names()
    );
    if t.variable {
        desc.push_str("; variable application data follows the fixed arguments");
    }
    x.open(&format!(
        "<xtce:MetaCommand name=\"{}\" shortDescription=\"{}\">",
        t.name,
        esc(&desc)
    ));
    x.open("<xtce:BaseMetaCommand metaCommandRef=\"PUS_TC\">");
    x.open("<xtce:ArgumentAssignmentList>");
    let mut assigned = vec![
        ("PKT_APID", apid.to_string()),
        ("TC_SERVICE", t.service.to_string()),
        ("TC_SUBSERVICE", t.subservice.to_string()),
    ];
    if flavour.assign_ack_flags {
        assigned.push(("TC_ACK_FLAGS", t.ack_flags().to_string()));
    }
    for (n, v) in assigned {
        x.line(&format!(
            "<xtce:ArgumentAssignment argumentName=\"{n}\" argumentValue=\"{v}\"/>"
        ));
    }
    x.close("</xtce:ArgumentAssignmentList>");
    x.close("</xtce:BaseMetaCommand>");
    if !t.args.is_empty() {
        x.open("<xtce:ArgumentList>");
        for a in t.args {
            x.line(&format!(
                "<xtce:Argument name=\"{}\" argumentTypeRef=\"{}_{}_Type\" shortDescription=\"{}\"/>",
                a.name,
                t.name,
                a.name,
                esc(a.desc)
            ));
        }
        x.close("</xtce:ArgumentList>");
    }
    x.open(&format!("<xtce:CommandContainer name=\"{}_CC\">", t.name));
    x.open("<xtce:EntryList>");
    if t.service == tc::service::FUNCTION {
        x.line(&format!(
            "<xtce:FixedValueEntry name=\"FUNCTION_ID\" binaryValue=\"{}\" sizeInBits=\"16\"/>",
            hex_value(t.function as u64, 16)
        ));
    }
    for a in t.args {
        x.line(&format!("<xtce:ArgumentRefEntry argumentRef=\"{}\"/>", a.name));
    }
    x.close("</xtce:EntryList>");
    x.line("<xtce:BaseContainer containerRef=\"PUS_TC\"/>");
    x.close("</xtce:CommandContainer>");
    if let Some(why) = t.hazard {
        x.line(&format!(
            "<xtce:DefaultSignificance consequenceLevel=\"critical\" reasonForWarning=\"{}\"/>",
            esc(why)
        ));
    }
    x.close("</xtce:MetaCommand>");
}

/// XTCE of the TM kinds that are not told apart by PI1 (all but HK and events), generated
/// from their field lists (`mib::layout`): every field a parameter named
/// `<TM>_<path>`; a failure report an abstract container with one child per failure code
/// (restricted on the code) holding that code's failure data; a list report one child per
/// entry count (restricted on the count) holding that many entry containers.
struct BodyXtce {
    types: Xml,
    params: Xml,
    containers: Xml,
}

const PEC_NAME: &str = "PEC";

fn items_fields(prefix: &str, items: &[mib::layout::Item], out: &mut Vec<(String, mib::layout::Field)>) {
    use mib::layout::Item;
    for it in items {
        match it {
            Item::Field(f) => out.push((format!("{prefix}_{}", f.name), *f)),
            Item::Sub { name, sub } => {
                for f in sub.fields {
                    out.push((format!("{prefix}_{name}_{}", f.name), *f));
                }
            }
            Item::Group { .. } | Item::Packet { .. } | Item::Tail(_) => {}
        }
    }
}

impl BodyXtce {
    fn new() -> Self {
        let x = || Xml {
            s: String::new(),
            depth: 3,
        };
        BodyXtce {
            types: x(),
            params: x(),
            containers: x(),
        }
    }

    /// Type and parameter of one field (enumerated when the MIB names its values, unless
    /// `open`: the field may carry a value the MIB does not define).
    fn field(&mut self, name: &str, f: &mib::layout::Field, desc: &str, open: bool) {
        let x = &mut self.types;
        let tname = format!("{name}_Type");
        let enc = format!(
            "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"{}\"/>",
            f.bits,
            if f.ptype.signed() { "twosComplement" } else { "unsigned" }
        );
        if !f.names.is_none() && !open {
            enumerated_type(x, &tname, f);
        } else {
            x.open(&format!(
                "<xtce:IntegerParameterType name=\"{}\" shortDescription=\"{}\" signed=\"{}\" sizeInBits=\"32\">",
                esc(&tname),
                esc(f.desc),
                f.ptype.signed()
            ));
            unit_set(x, f.unit);
            x.line(&enc);
            x.close("</xtce:IntegerParameterType>");
        }
        parameter(&mut self.params, name, &tname, desc, &[]);
    }

    fn fields(&mut self, list: &[(String, mib::layout::Field)], open: bool) -> Vec<String> {
        for (n, f) in list {
            self.field(n, f, f.desc, open);
        }
        list.iter().map(|(n, _)| n.clone()).collect()
    }

    fn tm(&mut self, t: &mib::tc::TmDef) {
        use mib::layout::{Item, Tail};
        let base_crit = [
            (mib::headers::TM_SERVICE, t.service.to_string()),
            ("TM_SUBSERVICE", t.subservice.to_string()),
        ];
        let cname = format!("TM_{}", t.name);
        let desc = format!("TM[{},{}] {}", t.service, t.subservice, t.desc);
        let mut fixed = Vec::new();
        items_fields(t.name, t.body, &mut fixed);
        let entries = self.fields(&fixed, false);
        let tail = t.body.iter().find_map(|i| match i {
            Item::Tail(x) => Some(*x),
            _ => None,
        });
        let group = t.body.iter().find_map(|i| match i {
            Item::Group {
                name,
                count,
                max,
                items,
                ..
            } => Some((*name, *count, *max, *items)),
            _ => None,
        });
        match (tail, group) {
            (Some(Tail::FailureData), None) => {
                container(
                    &mut self.containers,
                    &cname,
                    &desc,
                    true,
                    &entries,
                    Some(("PUS_TM", &base_crit)),
                );
                let code_param = format!("{}_failure_code", t.name);
                for c in mib::FailureCode::ALL {
                    let list: Vec<(String, mib::layout::Field)> = c
                        .data()
                        .iter()
                        .map(|f| (format!("{}_{}_{}", t.name, c.name(), f.name), *f))
                        .collect();
                    // Failure data report what the robot received or found (an unknown
                    // function, SID, event, monitor or mode among them): integers, so an
                    // independent decoder reads any value; the ICD and
                    // `ground decode` name the values the MIB defines.
                    let mut e = self.fields(&list, true);
                    e.push(PEC_NAME.to_string());
                    container(
                        &mut self.containers,
                        &format!("{}_{}", t.name, c.name()),
                        &format!(
                            "{} with failure {} ({}): {}",
                            t.name,
                            c.name(),
                            c.code(),
                            c.description()
                        ),
                        false,
                        &e,
                        Some((&cname, &[(code_param.as_str(), c.code().to_string())])),
                    );
                }
            }
            (None, Some((gname, count, max, items))) => {
                container(
                    &mut self.containers,
                    &cname,
                    &desc,
                    true,
                    &entries,
                    Some(("PUS_TM", &base_crit)),
                );
                for i in 0..max {
                    let mut list = Vec::new();
                    items_fields(&format!("{}_{gname}_{i}", t.name), items, &mut list);
                    let e = self.fields(&list, false);
                    container(
                        &mut self.containers,
                        &format!("{}_{gname}_{i}", t.name),
                        &format!("entry {i} of {}", t.name),
                        false,
                        &e,
                        None,
                    );
                }
                let count_param = format!("{}_{count}", t.name);
                for n in 0..=max {
                    // Entries are containers: written here rather than through `container`.
                    let x = &mut self.containers;
                    x.open(&format!(
                        "<xtce:SequenceContainer name=\"{}_N{n}\" shortDescription=\"{} with {n} entries\">",
                        t.name, t.name
                    ));
                    x.open("<xtce:EntryList>");
                    for i in 0..n {
                        x.line(&format!(
                            "<xtce:ContainerRefEntry containerRef=\"{}_{gname}_{i}\"/>",
                            t.name
                        ));
                    }
                    x.line(&format!("<xtce:ParameterRefEntry parameterRef=\"{PEC_NAME}\"/>"));
                    x.close("</xtce:EntryList>");
                    x.open(&format!("<xtce:BaseContainer containerRef=\"{cname}\">"));
                    x.open("<xtce:RestrictionCriteria>");
                    x.open("<xtce:ComparisonList>");
                    x.line(&format!(
                        "<xtce:Comparison parameterRef=\"{count_param}\" value=\"{n}\" useCalibratedValue=\"false\"/>"
                    ));
                    x.close("</xtce:ComparisonList>");
                    x.close("</xtce:RestrictionCriteria>");
                    x.close("</xtce:BaseContainer>");
                    x.close("</xtce:SequenceContainer>");
                }
            }
            (None, None) => {
                let mut e = entries;
                e.push(PEC_NAME.to_string());
                container(
                    &mut self.containers,
                    &cname,
                    &desc,
                    false,
                    &e,
                    Some(("PUS_TM", &base_crit)),
                );
            }
            (Some(_), _) => {
                // A body with another tail (events, HK) or a group and a tail: HK and events
                // have their own containers above; no other TM has both.
                unreachable!("TM {} has a body the XTCE export does not describe", t.name)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: ICD-03
    #[test]
    fn document_mentions_every_hk_parameter_and_tc() {
        let d = xtce_document();
        for p in PARAMS {
            assert!(d.contains(&format!("name=\"{}\"", p.name)), "{}", p.name);
        }
        for t in TCS {
            assert!(d.contains(&format!("<xtce:MetaCommand name=\"{}\"", t.name)));
        }
        assert!(d.contains("value=\"257\""));
        assert!(xtce_document_for(2).contains("value=\"258\""));
        assert_eq!(hex_value(8, 16), "0008");
        assert_eq!(hex_value(1, 1), "01");
        assert_eq!(esc("a<b&\"c\""), "a&lt;b&amp;&quot;c&quot;");
    }
}
