//! SCOS-2000 MIB ASCII tables: one tab-separated `.dat` file per table, no header
//! line, every column of the SCOS-2000 MIB ICD in its order.
//!
//! SCOS-2000 names are at most 8 characters, so parameters and commands get generated
//! names ([`ScosNames`]); the MIB mnemonic is kept in the description columns.
//!
//! Offsets: `PIC_PI1_OFF` and `PLF_OFFBY` count octets from the first octet of the
//! packet (primary header included); `CDF_BIT` counts bits from the first bit of the
//! TC application data; `PCDF_BIT` from the first bit of the packet.

use super::headers::{self, HeaderField};
use super::{num, trunc};

/// ASCII text cut to a column width.
fn fit(s: &str, n: usize) -> String {
    trunc(&sanitize(s), n)
}
use mib::events::{Severity, EVENTS};
use mib::hk::HK_STRUCTS;
use mib::params::PARAMS;
use mib::tc::{self, TcDef, TCS, TMS};
use mib::types::{Calib, PType};
use mib::{apid, config};

/// Column names of every table written, in file order.
const TABLES: &[(&str, &[&str])] = &[
    (
        "vdf",
        &["VDF_NAME", "VDF_COMMENT", "VDF_DOMAINID", "VDF_RELEASE", "VDF_ISSUE"],
    ),
    (
        "pid",
        &[
            "PID_TYPE",
            "PID_STYPE",
            "PID_APID",
            "PID_PI1_VAL",
            "PID_PI2_VAL",
            "PID_SPID",
            "PID_DESCR",
            "PID_UNIT",
            "PID_TPSD",
            "PID_DFHSIZE",
            "PID_TIME",
            "PID_INTER",
            "PID_VALID",
            "PID_CHECK",
            "PID_EVENT",
            "PID_EVID",
        ],
    ),
    (
        "pic",
        &[
            "PIC_TYPE",
            "PIC_STYPE",
            "PIC_PI1_OFF",
            "PIC_PI1_WID",
            "PIC_PI2_OFF",
            "PIC_PI2_WID",
            "PIC_APID",
        ],
    ),
    ("tpcf", &["TPCF_SPID", "TPCF_NAME", "TPCF_SIZE"]),
    (
        "pcf",
        &[
            "PCF_NAME",
            "PCF_DESCR",
            "PCF_PID",
            "PCF_UNIT",
            "PCF_PTC",
            "PCF_PFC",
            "PCF_WIDTH",
            "PCF_VALID",
            "PCF_RELATED",
            "PCF_CATEG",
            "PCF_NATUR",
            "PCF_CURTX",
            "PCF_INTER",
            "PCF_USCON",
            "PCF_DECIM",
            "PCF_PARVAL",
            "PCF_SUBSYS",
            "PCF_VALPAR",
            "PCF_SPTYPE",
            "PCF_CORR",
            "PCF_OBTID",
            "PCF_DARC",
            "PCF_ENDIAN",
            "PCF_DESCR2",
        ],
    ),
    (
        "plf",
        &[
            "PLF_NAME",
            "PLF_SPID",
            "PLF_OFFBY",
            "PLF_OFFBI",
            "PLF_NBOCC",
            "PLF_LGOCC",
            "PLF_TIME",
            "PLF_TDOCC",
        ],
    ),
    (
        "caf",
        &[
            "CAF_NUMBR",
            "CAF_DESCR",
            "CAF_ENGFMT",
            "CAF_RAWFMT",
            "CAF_RADIX",
            "CAF_UNIT",
            "CAF_NCURVE",
            "CAF_INTER",
        ],
    ),
    ("cap", &["CAP_NUMBR", "CAP_XVALS", "CAP_YVALS"]),
    (
        "ocf",
        &["OCF_NAME", "OCF_NBCHCK", "OCF_NBOOL", "OCF_INTER", "OCF_CODIN"],
    ),
    (
        "ocp",
        &[
            "OCP_NAME",
            "OCP_POS",
            "OCP_TYPE",
            "OCP_LVALU",
            "OCP_HVALU",
            "OCP_RLCHK",
            "OCP_VALPAR",
        ],
    ),
    ("tcp", &["TCP_ID", "TCP_DESC"]),
    ("pcpc", &["PCPC_PNAME", "PCPC_DESC", "PCPC_CODE"]),
    (
        "pcdf",
        &[
            "PCDF_TCNAME",
            "PCDF_DESC",
            "PCDF_TYPE",
            "PCDF_LEN",
            "PCDF_BIT",
            "PCDF_PNAME",
            "PCDF_VALUE",
            "PCDF_RADIX",
        ],
    ),
    (
        "ccf",
        &[
            "CCF_CNAME",
            "CCF_DESCR",
            "CCF_DESCR2",
            "CCF_CTYPE",
            "CCF_CRITICAL",
            "CCF_PKTID",
            "CCF_TYPE",
            "CCF_STYPE",
            "CCF_APID",
            "CCF_NPARS",
            "CCF_PLAN",
            "CCF_EXEC",
            "CCF_ILSCOPE",
            "CCF_ILSTAGE",
            "CCF_SUBSYS",
            "CCF_HIPRI",
            "CCF_MAPID",
            "CCF_DEFSET",
            "CCF_RAPID",
            "CCF_ACK",
            "CCF_SUBSCHEDID",
        ],
    ),
    (
        "cdf",
        &[
            "CDF_CNAME",
            "CDF_ELTYPE",
            "CDF_DESCR",
            "CDF_ELLEN",
            "CDF_BIT",
            "CDF_GRPSIZE",
            "CDF_PNAME",
            "CDF_INTER",
            "CDF_VALUE",
            "CDF_TMID",
        ],
    ),
    (
        "cpc",
        &[
            "CPC_PNAME",
            "CPC_DESCR",
            "CPC_PTC",
            "CPC_PFC",
            "CPC_DISPFMT",
            "CPC_RADIX",
            "CPC_UNIT",
            "CPC_CATEG",
            "CPC_PRFREF",
            "CPC_CCAREF",
            "CPC_PAFREF",
            "CPC_INTER",
            "CPC_DEFVAL",
            "CPC_CORR",
            "CPC_OBTID",
            "CPC_DESCR2",
            "CPC_ENDIAN",
        ],
    ),
    (
        "prf",
        &[
            "PRF_NUMBR",
            "PRF_DESCR",
            "PRF_INTER",
            "PRF_DSPFMT",
            "PRF_RADIX",
            "PRF_NRANGE",
            "PRF_UNIT",
        ],
    ),
    ("prv", &["PRV_NUMBR", "PRV_MINVAL", "PRV_MAXVAL"]),
];

/// Column names of a table, by table name (`"pcf"`) or file name (`"pcf.dat"`).
pub fn scos_columns(table: &str) -> Option<&'static [&'static str]> {
    let t = table.strip_suffix(".dat").unwrap_or(table);
    TABLES.iter().find(|(n, _)| *n == t).map(|(_, c)| *c)
}

/// Generated SCOS-2000 names (8 characters at most).
pub struct ScosNames;

impl ScosNames {
    /// TC packet header definition (`TCP_ID`, `CCF_PKTID`).
    pub const TC_HEADER: &'static str = "MMICTC";
    /// Monitoring parameter holding the housekeeping structure ID (PI1 of TM[3,25]).
    pub const SID: &'static str = "MMSID";
    /// Monitoring parameter holding the event ID (PI1 of TM[5,x]).
    pub const EVENT_ID: &'static str = "MMEVID";
    /// Command parameter of the PUS 8 function ID (a fixed element of every TC[8,1]).
    pub const FUNCTION: &'static str = "MMFUNCID";

    /// Monitoring parameter of an HK parameter: `MMT` + 5-digit parameter ID.
    pub fn tm_param(pid: u16) -> String {
        format!("MMT{pid:05}")
    }
    /// Monitoring parameter of event parameter `index` (0-based): `ME` + event ID in
    /// hex + 2-digit position (1-based).
    pub fn event_param(event_id: u16, index: usize) -> String {
        format!("ME{event_id:04X}{:02}", index + 1)
    }
    /// Command name: `MF` + 6-digit function ID for PUS 8, else `MC` + 3-digit service +
    /// 3-digit subservice.
    pub fn command(t: &TcDef) -> String {
        if t.service == tc::service::FUNCTION {
            format!("MF{:06}", t.function)
        } else {
            format!("MC{:03}{:03}", t.service, t.subservice)
        }
    }
    /// Command parameter `arg` (0-based) of command `t`: `P` + the command name's last
    /// 6 characters + 1 digit.
    pub fn command_param(t: &TcDef, arg: usize) -> String {
        let c = Self::command(t);
        format!("P{}{}", &c[2..], arg)
    }
    /// Range set of a command parameter (`CPC_PRFREF`).
    pub fn range(t: &TcDef, arg: usize) -> String {
        format!("R{}", Self::command_param(t, arg))
    }
    /// SCOS-2000 packet ID of the `index`-th TM packet definition of `robot`.
    pub fn spid(robot: u8, index: usize) -> u32 {
        robot as u32 * 10_000 + index as u32 + 1
    }
}

/// SCOS-2000 (PTC, PFC) of a wire type. Booleans are one octet on the wire, so they are
/// unsigned 8-bit integers for SCOS-2000.
fn ptc_pfc(t: PType) -> (u8, u8) {
    match t {
        PType::Bool | PType::U8 => (3, 4),
        PType::U16 => (3, 12),
        PType::U32 => (3, 14),
        PType::I16 => (4, 12),
        PType::I32 => (4, 14),
    }
}

fn fmt_letter(t: PType) -> &'static str {
    if t.signed() {
        "I"
    } else {
        "U"
    }
}

struct Table {
    name: &'static str,
    rows: Vec<Vec<String>>,
}

impl Table {
    fn new(name: &'static str) -> Self {
        Table { name, rows: Vec::new() }
    }
    fn row<const N: usize>(&mut self, cells: [&str; N]) {
        self.rows.push(cells.iter().map(|c| sanitize(c)).collect());
    }
    fn render(&self) -> String {
        let mut s = String::new();
        for r in &self.rows {
            s.push_str(&r.join("\t"));
            s.push('\n');
        }
        s
    }
}

/// SCOS-2000 tables are ASCII; tabs and line breaks would break the table format.
fn sanitize(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\t' | '\n' | '\r' => o.push(' '),
            '\u{2013}' | '\u{2014}' | '\u{2212}' => o.push('-'),
            '\u{00B0}' => o.push_str("deg"),
            '\u{00B5}' => o.push('u'),
            '\u{00D7}' => o.push('x'),
            '\u{2026}' => o.push_str("..."),
            '\u{2192}' => o.push_str("->"),
            c if c.is_ascii() && !c.is_control() => o.push(c),
            _ => o.push('?'),
        }
    }
    o
}

/// One TM packet definition (one `pid` row).
struct TmPacket {
    service: u8,
    subservice: u8,
    pi1: u16,
    name: String,
    descr: String,
    /// Source data length if fixed.
    data_len: Option<usize>,
    interval_ms: Option<u32>,
    event: &'static str,
    evid: String,
    /// (PCF name, octet offset in the packet, bit offset in the octet) of every parameter.
    params: Vec<(String, usize, usize)>,
    /// Octet offset of PI1 in the packet (16 bits) when packets of this type are told
    /// apart by it.
    pi1_off: Option<usize>,
}

/// Monitoring parameter of field `field` (0-based) of the fixed part of TM kind `tm`
/// (index in `TMS`): `MR` + 2-digit kind + 2-digit field.
fn report_param(tm: usize, field: usize) -> String {
    format!("MR{tm:02}{field:02}")
}

/// Monitoring parameter of failure-data field `field` of failure code `code`:
/// `MD` + 3-digit code + 2-digit field.
fn failure_param(code: u16, field: usize) -> String {
    format!("MD{code:03}{field:02}")
}

/// The fields of a report body at fixed offsets (up to the first variable part), with
/// their bit offsets from the start of the source data.
fn fixed_fields(items: &[mib::layout::Item]) -> Vec<(String, mib::layout::Field, usize)> {
    use mib::layout::Item;
    let mut out = Vec::new();
    let mut bit = 0;
    for it in items {
        match it {
            Item::Field(f) => {
                out.push((f.name.to_string(), *f, bit));
                bit += f.bits as usize;
            }
            Item::Sub { name, sub } => {
                for f in sub.fields {
                    out.push((format!("{name}.{}", f.name), *f, bit));
                    bit += f.bits as usize;
                }
            }
            Item::Group { .. } | Item::Packet { .. } | Item::Tail(_) => break,
        }
    }
    out
}

/// Monitoring parameters of the report bodies: (PCF name, description, field).
fn report_pcf() -> Vec<(String, String, mib::layout::Field)> {
    let mut out = Vec::new();
    for (ti, t) in TMS.iter().enumerate() {
        if is_identified_by_pi1(t.service, t.subservice) {
            continue;
        }
        for (fi, (path, f, _)) in fixed_fields(t.body).into_iter().enumerate() {
            out.push((report_param(ti, fi), format!("{}.{path}", t.name), f));
        }
    }
    for c in mib::FailureCode::ALL {
        for (fi, f) in c.data().iter().enumerate() {
            out.push((failure_param(c.code(), fi), format!("{}.{}", c.name(), f.name), *f));
        }
    }
    out
}

/// TM[3,25] and TM[5,1..4] are told apart by PI1 (SID / event ID).
pub(crate) fn is_identified_by_pi1(service: u8, subservice: u8) -> bool {
    (service == tc::service::HOUSEKEEPING && subservice == 25)
        || (service == tc::service::EVENT && Severity::from_subservice(subservice).is_some())
}

fn tm_packets() -> Vec<TmPacket> {
    let sd = headers::tm_source_data_offset();
    let mut out = Vec::new();
    for (ti, t) in TMS.iter().enumerate() {
        if is_identified_by_pi1(t.service, t.subservice) {
            continue;
        }
        let fixed = fixed_fields(t.body);
        let params: Vec<(String, usize, usize)> = fixed
            .iter()
            .enumerate()
            .map(|(fi, (_, _, bit))| (report_param(ti, fi), sd + bit / 8, bit % 8))
            .collect();
        let failure = t
            .body
            .contains(&mib::layout::Item::Tail(mib::layout::Tail::FailureData));
        if failure {
            // One packet per failure code (PI1 = the code): the fixed part, then the code's
            // failure data.
            let (_, _, code_bit) = fixed
                .iter()
                .find(|(n, ..)| n == "failure_code")
                .cloned()
                .expect("a failure report has a failure_code field");
            let data_off = sd + code_bit / 8 + 2;
            for c in mib::FailureCode::ALL {
                let mut ps = params.clone();
                let mut bit = 0;
                for (fi, f) in c.data().iter().enumerate() {
                    ps.push((failure_param(c.code(), fi), data_off + bit / 8, bit % 8));
                    bit += f.bits as usize;
                }
                out.push(TmPacket {
                    service: t.service,
                    subservice: t.subservice,
                    pi1: c.code(),
                    name: format!("TM{}_{}_{}", t.service, t.subservice, c.code()),
                    descr: format!("TM[{},{}] {} {}", t.service, t.subservice, t.name, c.name()),
                    data_len: Some(code_bit / 8 + 2 + c.data_len()),
                    interval_ms: None,
                    event: "N",
                    evid: String::new(),
                    params: ps,
                    pi1_off: Some(sd + code_bit / 8),
                });
            }
        } else {
            out.push(TmPacket {
                service: t.service,
                subservice: t.subservice,
                pi1: 0,
                name: t.name.to_string(),
                descr: format!("TM[{},{}] {}: {}", t.service, t.subservice, t.name, t.desc),
                data_len: mib::layout::fixed_len(t.body),
                interval_ms: None,
                event: "N",
                evid: String::new(),
                params,
                pi1_off: None,
            });
        }
    }
    for h in HK_STRUCTS {
        let mut params = vec![(ScosNames::SID.to_string(), sd, 0)];
        let mut off = sd + 2;
        for id in h.params {
            if let Some(p) = mib::params::by_id(*id) {
                params.push((ScosNames::tm_param(p.id), off, 0));
                off += p.ptype.size();
            }
        }
        out.push(TmPacket {
            service: tc::service::HOUSEKEEPING,
            subservice: 25,
            pi1: h.sid,
            name: format!("HK_{}", h.name),
            descr: format!("TM[3,25] SID {} {}: {}", h.sid, h.name, h.desc),
            data_len: Some(h.data_len()),
            interval_ms: Some(h.default_interval_ms),
            event: "N",
            evid: String::new(),
            params,
            pi1_off: Some(sd),
        });
    }
    for e in EVENTS {
        let mut params = vec![(ScosNames::EVENT_ID.to_string(), sd, 0)];
        let mut off = sd + 2;
        for (i, p) in e.params.iter().enumerate() {
            params.push((ScosNames::event_param(e.id, i), off, 0));
            off += p.ptype.size();
        }
        out.push(TmPacket {
            service: tc::service::EVENT,
            subservice: e.severity.subservice(),
            pi1: e.id,
            name: e.name.to_string(),
            descr: format!(
                "TM[5,{}] event 0x{:04X} {}: {}",
                e.severity.subservice(),
                e.id,
                e.name,
                e.desc
            ),
            data_len: Some(e.data_len()),
            interval_ms: None,
            event: match e.severity {
                Severity::Info => "I",
                Severity::Low | Severity::Medium => "W",
                Severity::High => "A",
            },
            evid: fit(e.name, 17),
            params,
            pi1_off: Some(sd),
        });
    }
    out
}

/// Distinct calibration curves: (CAF name, calibration, signed raw, unit).
/// A calibration curve: its name, the curve, the raw type and the unit.
type Calibration = (String, Calib, PType, &'static str);

fn calibrations() -> Vec<Calibration> {
    let mut out: Vec<Calibration> = Vec::new();
    for p in PARAMS.iter().filter(|p| !p.calib.is_identity()) {
        let known = out
            .iter()
            .any(|(_, c, t, u)| *c == *p.calib && *t == p.ptype && *u == p.unit);
        if !known {
            let name = format!("MMCAL{:03}", out.len() + 1);
            out.push((name, *p.calib, p.ptype, p.unit));
        }
    }
    out
}

/// SCOS-2000 tables for the default robot (APID 0x101).
pub fn scos_tables() -> Vec<(&'static str, String)> {
    scos_tables_for(apid::DEFAULT_ROBOT)
}

/// SCOS-2000 tables for robot `robot` (1..=254; out-of-range numbers use the default
/// robot). Each robot is its own SCOS-2000 spacecraft database: the APIDs and SPIDs
/// differ, the parameter and command names do not.
pub fn scos_tables_for(robot: u8) -> Vec<(&'static str, String)> {
    let (robot, apid) = match apid::robot_apid(robot) {
        Some(a) => (robot, a),
        None => (
            apid::DEFAULT_ROBOT,
            apid::robot_apid(apid::DEFAULT_ROBOT).unwrap_or(apid::APID_BASE + 1),
        ),
    };
    let apid_s = apid.to_string();
    let cals = calibrations();
    let tables: Vec<Table> = [vdf(robot, apid)]
        .into_iter()
        .chain(packet_tables(robot, &apid_s))
        .chain([pcf(&cals)])
        .chain(calibration_tables(&cals))
        .chain(limit_tables())
        .chain(tc_header_tables(apid))
        .chain(command_tables(&apid_s))
        .collect();

    // Files in the order of TABLES.
    let mut out = Vec::new();
    for (name, _) in TABLES {
        if let Some(t) = tables.iter().find(|t| t.name == *name) {
            out.push((file_name(name), t.render()));
        }
    }
    out
}

/// The robot's spacecraft database: its name and description.
fn vdf(robot: u8, apid: u16) -> Table {
    let mut vdf = Table::new("vdf");
    vdf.row([
        &format!("MMICR{robot:03}"),
        &format!("MMIC-I robot {robot} APID 0x{apid:03X}"),
        "",
        "0",
        "0",
    ]);
    vdf
}

/// The TM packets: identification (`pid`), identification fields (`pic`), characteristics
/// (`tpcf`) and the location of every parameter (`plf`).
fn packet_tables(robot: u8, apid_s: &str) -> [Table; 4] {
    let packets = tm_packets();
    let dfh = headers::tm_data_field_header_len().to_string();
    let mut pid = Table::new("pid");
    let mut tpcf = Table::new("tpcf");
    let mut plf = Table::new("plf");
    let mut pic = Table::new("pic");
    let mut pic_keys: Vec<(u8, u8)> = Vec::new();
    for (i, p) in packets.iter().enumerate() {
        let spid = ScosNames::spid(robot, i).to_string();
        pid.row([
            &p.service.to_string(),
            &p.subservice.to_string(),
            apid_s,
            &p.pi1.to_string(),
            "0",
            &spid,
            &fit(&p.descr, 64),
            "",
            "-1",
            &dfh,
            "N",
            &p.interval_ms.map(|v| v.to_string()).unwrap_or_default(),
            "Y",
            "1",
            p.event,
            &p.evid,
        ]);
        tpcf.row([
            &spid,
            &fit(&p.name, 12),
            &p.data_len
                .map(|n| headers::tm_packet_len(n).to_string())
                .unwrap_or_default(),
        ]);
        for (name, off, bit) in &p.params {
            plf.row([name, &spid, &off.to_string(), &bit.to_string(), "1", "0", "0", "1"]);
        }
        if !pic_keys.contains(&(p.service, p.subservice)) {
            pic_keys.push((p.service, p.subservice));
            if let Some(pi1_off) = p.pi1_off {
                pic.row([
                    &p.service.to_string(),
                    &p.subservice.to_string(),
                    &pi1_off.to_string(),
                    "16",
                    "-1",
                    "0",
                    apid_s,
                ]);
            } else {
                pic.row([
                    &p.service.to_string(),
                    &p.subservice.to_string(),
                    "-1",
                    "0",
                    "-1",
                    "0",
                    apid_s,
                ]);
            }
        }
    }
    [pid, pic, tpcf, plf]
}

/// The monitoring parameters (`pcf`): the identification fields, HK parameters, event
/// parameters, and the fields of the other reports.
fn pcf(cals: &[Calibration]) -> Table {
    let mut pcf = Table::new("pcf");
    let mut pcf_row = |name: &str, descr: &str, obpid: &str, unit: &str, tf: (u8, u8), curtx: &str, descr2: &str| {
        let (ptc, pfc) = tf;
        pcf.row([
            name,
            &fit(descr, 24),
            obpid,
            &fit(unit, 4),
            &ptc.to_string(),
            &pfc.to_string(),
            "",
            "",
            "",
            "N",
            "R",
            curtx,
            if curtx.is_empty() { "F" } else { "P" },
            "N",
            "",
            "",
            "",
            "",
            "",
            "Y",
            "",
            "0",
            "B",
            &fit(descr2, 256),
        ]);
    };
    pcf_row(
        ScosNames::SID,
        "HK_SID",
        "",
        "",
        ptc_pfc(PType::U16),
        "",
        "Housekeeping structure ID (PI1 of TM[3,25])",
    );
    pcf_row(
        ScosNames::EVENT_ID,
        "EVENT_ID",
        "",
        "",
        ptc_pfc(PType::U16),
        "",
        "Event ID (PI1 of TM[5,x])",
    );
    for p in PARAMS {
        let curtx = cals
            .iter()
            .find(|(_, c, t, u)| !p.calib.is_identity() && *c == *p.calib && *t == p.ptype && *u == p.unit)
            .map(|(n, ..)| n.clone())
            .unwrap_or_default();
        pcf_row(
            &ScosNames::tm_param(p.id),
            p.name,
            &p.id.to_string(),
            p.unit,
            ptc_pfc(p.ptype),
            &curtx,
            p.desc,
        );
    }
    for e in EVENTS {
        for (i, ep) in e.params.iter().enumerate() {
            pcf_row(
                &ScosNames::event_param(e.id, i),
                &format!("{}.{}", e.name, ep.name),
                "",
                "",
                ptc_pfc(ep.ptype),
                "",
                &format!("Parameter '{}' of event {} (0x{:04X})", ep.name, e.name, e.id),
            );
        }
    }
    // Fields of the other reports and the failure data of every code.
    for (name, path, f) in report_pcf() {
        let tf = if f.is_whole() {
            ptc_pfc(f.ptype)
        } else if f.bits >= 4 {
            // Unsigned integer of 4..16 bits: PFC = bits - 4.
            (3, f.bits - 4)
        } else {
            // 1..3 bits: an enumerated value of that many bits.
            (2, f.bits)
        };
        pcf_row(&name, &path, "", f.unit, tf, "", f.desc);
    }
    pcf
}

/// The calibration curves (`caf`) and their points (`cap`).
fn calibration_tables(cals: &[Calibration]) -> [Table; 2] {
    let mut caf = Table::new("caf");
    let mut cap = Table::new("cap");
    for (name, c, t, unit) in cals {
        caf.row([
            name,
            &fit(&format!("eng = raw * {} + {}", num(c.scale), num(c.offset)), 32),
            "R",
            fmt_letter(*t),
            "D",
            &fit(unit, 4),
            "2",
            "P",
        ]);
        for raw in [t.min(), t.max()] {
            cap.row([name, &raw.to_string(), &num(c.eng(raw))]);
        }
    }
    [caf, cap]
}

/// The monitoring checks (`ocf`) and their limits (`ocp`).
fn limit_tables() -> [Table; 2] {
    let mut ocf = Table::new("ocf");
    let mut ocp = Table::new("ocp");
    for p in PARAMS {
        if let Some(l) = p.limits {
            let n = ScosNames::tm_param(p.id);
            // Limits that apply only in some robot states: one soft and one hard check
            // per state, relevant when one parameter (OCP_RLCHK: the mode, or the
            // parameter of the MIB's condition) has that raw value. SCOS-2000 has one
            // relevance parameter per check: a MIB test keeps every state to one.
            let contexts: Vec<(String, String)> = match super::limit_contexts(p) {
                c if c.is_empty() => vec![(String::new(), String::new())],
                c => c
                    .iter()
                    .filter_map(|ctx| ctx.first())
                    .map(|&(id, raw)| (ScosNames::tm_param(id), raw.to_string()))
                    .collect(),
            };
            let nbchck = mib::params::GROUND_LIMIT_PERSISTENCE.to_string();
            ocf.row([&n, &nbchck, &(2 * contexts.len()).to_string(), "C", "R"]);
            let mut pos = 0;
            for (rlchk, valpar) in &contexts {
                for (kind, lo, hi) in [("S", l.soft_lo, l.soft_hi), ("H", l.hard_lo, l.hard_hi)] {
                    pos += 1;
                    ocp.row([&n, &pos.to_string(), kind, &num(lo), &num(hi), rlchk, valpar]);
                }
            }
        }
    }
    [ocf, ocp]
}

/// The TC header (`tcp`), its parameters (`pcpc`) and its fields (`pcdf`).
fn tc_header_tables(apid: u16) -> [Table; 3] {
    let mut tcp = Table::new("tcp");
    tcp.row([ScosNames::TC_HEADER, "MMIC-I PUS-C TC header"]);
    let mut pcpc = Table::new("pcpc");
    let mut pcdf = Table::new("pcdf");
    let tc_fields: Vec<HeaderField> = headers::PRIMARY_HEADER
        .iter()
        .chain(headers::TC_SEC_HEADER)
        .copied()
        .collect();
    for (bit, f) in headers::offsets(&tc_fields) {
        let (ty, pname, value): (&str, &str, String) = match f.name {
            "PKT_TYPE" => ("F", "", "1".into()),
            "PKT_APID" => ("A", "MMTCAPID", format!("{apid:X}")),
            "SRC_SEQ_CTR" => ("P", "MMTCSEQ", "0".into()),
            "PKT_LEN" => ("P", "MMTCLEN", "0".into()),
            "TC_ACK_FLAGS" => ("K", "MMTCACK", "0".into()),
            "TC_SERVICE" => ("T", "MMTCTYPE", "0".into()),
            "TC_SUBSERVICE" => ("S", "MMTCSTYP", "0".into()),
            "TC_SOURCE_ID" => ("F", "", format!("{:X}", config::GROUND_ID)),
            _ => ("F", "", format!("{:X}", f.fixed.unwrap_or(0))),
        };
        if !pname.is_empty() {
            pcpc.row([pname, &fit(f.desc, 24), "U"]);
        }
        pcdf.row([
            ScosNames::TC_HEADER,
            &fit(f.name, 24),
            ty,
            &f.bits.to_string(),
            &bit.to_string(),
            pname,
            &value,
            "H",
        ]);
    }
    [tcp, pcpc, pcdf]
}

/// The commands' tables: commands (`ccf`), their elements (`cdf`) and parameters (`cpc`),
/// and the parameters' ranges (`prf`, `prv`).
struct CommandTables {
    ccf: Table,
    cdf: Table,
    cpc: Table,
    prf: Table,
    prv: Table,
}

/// The commands' tables of every TC, and the PUS 8 function ID they share.
fn command_tables(apid_s: &str) -> [Table; 5] {
    let mut c = CommandTables {
        ccf: Table::new("ccf"),
        cdf: Table::new("cdf"),
        cpc: Table::new("cpc"),
        prf: Table::new("prf"),
        prv: Table::new("prv"),
    };
    c.cpc.row([
        ScosNames::FUNCTION,
        "PUS 8 function ID",
        "3",
        "12",
        "U",
        "D",
        "",
        "N",
        "",
        "",
        "",
        "R",
        "",
        "Y",
        "0",
        "Function ID of TC[8,1], first field of its application data",
        "B",
    ]);
    for t in TCS {
        command_rows(&mut c, t, apid_s);
    }
    let CommandTables {
        ccf,
        cdf,
        cpc,
        prf,
        prv,
    } = c;
    [ccf, cdf, cpc, prf, prv]
}

/// The rows of command `t`.
fn command_rows(c: &mut CommandTables, t: &TcDef, apid_s: &str) {
    let cname = ScosNames::command(t);
    let mut bit = 0usize;
    let mut npars = 0usize;
    if t.service == tc::service::FUNCTION {
        c.cdf.row([
            &cname,
            "F",
            "function ID",
            "16",
            "0",
            "0",
            ScosNames::FUNCTION,
            "R",
            &t.function.to_string(),
            "",
        ]);
        bit += 16;
        npars += 1;
    }
    for (i, a) in t.args.iter().enumerate() {
        let pname = ScosNames::command_param(t, i);
        let rname = ScosNames::range(t, i);
        let (ptc, pfc) = ptc_pfc(a.ptype);
        c.cdf.row([
            &cname,
            "E",
            &fit(a.name, 24),
            &a.ptype.bits().to_string(),
            &bit.to_string(),
            "0",
            &pname,
            "R",
            "",
            "",
        ]);
        c.cpc.row([
            &pname,
            &fit(a.name, 24),
            &ptc.to_string(),
            &pfc.to_string(),
            fmt_letter(a.ptype),
            "D",
            &fit(a.unit, 4),
            "N",
            &rname,
            "",
            "",
            "R",
            &a.min.to_string(),
            "Y",
            "0",
            &fit(&format!("{}: {}", t.name, a.desc), 256),
            "B",
        ]);
        c.prf.row([
            &rname,
            &fit(&format!("{} {}", t.name, a.name), 24),
            "R",
            fmt_letter(a.ptype),
            "D",
            "1",
            &fit(a.unit, 4),
        ]);
        c.prv.row([&rname, &a.min.to_string(), &a.max.to_string()]);
        bit += a.ptype.bits();
        npars += 1;
    }
    let mut descr2 = t.description().to_string();
    if t.variable {
        descr2.push_str(" (variable data follows)");
    }
    c.ccf.row([
        &cname,
        &fit(t.name, 24),
        &fit(&descr2, 64),
        "",
        if t.hazard.is_some() { "Y" } else { "N" },
        ScosNames::TC_HEADER,
        &t.service.to_string(),
        &t.subservice.to_string(),
        apid_s,
        &npars.to_string(),
        "N",
        "Y",
        "N",
        "C",
        "",
        "N",
        "",
        "",
        "",
        "",
        "",
    ]);
}

fn file_name(table: &str) -> &'static str {
    match table {
        "vdf" => "vdf.dat",
        "pid" => "pid.dat",
        "pic" => "pic.dat",
        "tpcf" => "tpcf.dat",
        "pcf" => "pcf.dat",
        "plf" => "plf.dat",
        "caf" => "caf.dat",
        "cap" => "cap.dat",
        "ocf" => "ocf.dat",
        "ocp" => "ocp.dat",
        "tcp" => "tcp.dat",
        "pcpc" => "pcpc.dat",
        "pcdf" => "pcdf.dat",
        "ccf" => "ccf.dat",
        "cdf" => "cdf.dat",
        "cpc" => "cpc.dat",
        "prf" => "prf.dat",
        _ => "prv.dat",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: ICD-02
    #[test]
    fn every_table_has_a_file_and_rows_fit_the_columns() {
        let t = scos_tables();
        assert_eq!(t.len(), TABLES.len());
        for (file, content) in &t {
            let cols = scos_columns(file).unwrap();
            for line in content.lines() {
                assert_eq!(line.split('\t').count(), cols.len(), "{file}: {line}");
            }
        }
    }
    // verifies: ICD-02
    #[test]
    fn generated_names_fit_eight_characters_and_are_unique() {
        let mut names: Vec<String> = TCS.iter().map(ScosNames::command).collect();
        for t in TCS {
            for i in 0..t.args.len() {
                names.push(ScosNames::command_param(t, i));
            }
        }
        for n in &names {
            assert!(n.len() <= 8, "{n}");
        }
        let mut sorted = names.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), names.len());
        assert_eq!(ScosNames::event_param(0x0104, 0), "ME010401");
    }
}
