//! The interface control document (`docs/ICD.md`), generated from the MIB.

use super::headers::{self, HeaderField};
use super::{num, ScosNames};
use mib::events::EVENTS;
use mib::failure::FailureCode;
use mib::fdir::{self, Timing, FAULTS, MONITORS};
use mib::hk::{self, HK_STRUCTS};
use mib::modes::{self, NODES};
use mib::params::{self, ParamDef, PARAMS};
use mib::robot::{self, StateKind, NUM_STATES, PRIMITIVES, RECONFIG_MAP, STATES};
use mib::tc::{self, ACCEPTANCE_FAILURES, TCS, TMS};
use mib::tunables::TUNABLES;
use mib::types::Calib;
use mib::{apid, config, events};
use std::fmt::Write;

/// Escapes table cell text.
fn c(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

fn calib_text(cal: &Calib) -> String {
    if cal.is_identity() {
        "—".to_string()
    } else if cal.offset == 0.0 {
        format!("raw × {}", num(cal.scale))
    } else {
        format!("raw × {} + {}", num(cal.scale), num(cal.offset))
    }
}

fn mode_name_root(m: u32) -> &'static str {
    modes::mode_name(modes::NodeKind::Root, m).unwrap_or("?")
}

fn timing_text(t: Timing) -> &'static str {
    match t {
        Timing::Immediate => "immediately (running action aborted)",
        Timing::AfterMotion => "after the running motion completes",
    }
}

fn header_table(o: &mut String, title: &str, fields: &[HeaderField], note: &str) {
    let _ = writeln!(o, "### {title}\n");
    if !note.is_empty() {
        let _ = writeln!(o, "{note}\n");
    }
    let _ = writeln!(o, "| bit offset | bits | field | value / meaning |");
    let _ = writeln!(o, "|---:|---:|---|---|");
    for (off, f) in headers::offsets(fields) {
        let v = match f.fixed {
            Some(v) => format!("**{v}** — {}", f.desc),
            None => f.desc.to_string(),
        };
        let _ = writeln!(o, "| {off} | {} | `{}` | {} |", f.bits, f.name, c(&v));
    }
    let _ = writeln!(o);
}

fn state_label(id: u8) -> String {
    match STATES.get(id as usize) {
        Some(s) => format!("{} ({})", s.label, s.name),
        None => format!("{id}"),
    }
}

/// Shortest primitive sequence from `from` to `to` (breadth-first on the map).
fn shortest_path(from: u8, to: u8) -> Option<Vec<u8>> {
    let n = NUM_STATES;
    let mut prev: Vec<Option<(u8, u8)>> = vec![None; n];
    let mut seen = vec![false; n];
    let mut queue = std::collections::VecDeque::new();
    seen[from as usize] = true;
    queue.push_back(from);
    while let Some(s) = queue.pop_front() {
        if s == to {
            break;
        }
        for (j, &p) in RECONFIG_MAP[s as usize].iter().enumerate() {
            if p != 0 && !seen[j] {
                seen[j] = true;
                prev[j] = Some((s, p));
                queue.push_back(j as u8);
            }
        }
    }
    if !seen[to as usize] {
        return None;
    }
    let mut path = Vec::new();
    let mut cur = to;
    while cur != from {
        let (p, prim) = prev[cur as usize]?;
        path.push(prim);
        cur = p;
    }
    path.reverse();
    Some(path)
}

/// Description of a TC argument, with its value names when the MIB names its values.
fn arg_desc(a: &tc::ArgDef) -> String {
    let mut names = Vec::new();
    a.names.for_each(|v, n| {
        if (a.min..=a.max).contains(&v) {
            names.push(format!("{v} = {n}"));
        }
    });
    match names.len() {
        0 => a.desc.to_string(),
        1..=6 => format!("{} ({})", a.desc, names.join(", ")),
        n => format!("{} ({n} named values, e.g. {}, …)", a.desc, names[..2].join(", ")),
    }
}

/// When the limits of `p` apply: root modes, then the MIB's condition.
fn applies_text(p: &mib::params::ParamDef) -> String {
    if p.limits.is_none() {
        return "—".into();
    }
    match p.limits_if() {
        Some(c) => format!(
            "{} if `{} = {}` ({})",
            p.limits_in.names(),
            params::by_id(c.param).map_or("?", |q| q.name),
            c.raw,
            c.desc
        ),
        None => p.limits_in.names().into(),
    }
}

fn param_row(o: &mut String, p: &ParamDef) {
    let (s, h) = match p.limits {
        Some(l) => (
            format!("{} … {}", num(l.soft_lo), num(l.soft_hi)),
            format!("{} … {}", num(l.hard_lo), num(l.hard_hi)),
        ),
        None => ("—".into(), "—".into()),
    };
    let _ = writeln!(
        o,
        "| {} | `{}` | {} | {} | {} | {} | {} | {} | `{}` | {} |",
        p.id,
        p.name,
        p.ptype.name(),
        if p.unit.is_empty() { "—" } else { p.unit },
        calib_text(p.calib),
        s,
        h,
        applies_text(p),
        ScosNames::tm_param(p.id),
        c(p.desc)
    );
}

/// The ICD as Markdown (the content of `docs/ICD.md`).
pub fn icd_markdown() -> String {
    let mut o = String::new();
    let robot1 = apid::robot_apid(apid::DEFAULT_ROBOT).unwrap_or(apid::APID_BASE + 1);
    let _ = writeln!(o, "# MMIC-I interface control document\n");
    let _ = writeln!(
        o,
        "<!-- Generated from the MIB (crate `mib` {}) by `mib_export::icd_markdown()`. Do not edit by hand:\n     regenerate with `UPDATE_ICD=1 cargo test -p mib-export --test icd`. -->\n",
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        o,
        "Every number in this document comes from the mission information base (`mib/`), the single\nsource of truth shared by the on-board software, the simulator, the firmware and the ground tool.\n"
    );
    let _ = writeln!(o, "## Contents\n");
    for (i, s) in [
        "Conventions and APIDs",
        "Packet layouts",
        "Telecommands",
        "Telemetry packets",
        "Housekeeping structures",
        "Parameters",
        "Events",
        "Failure codes",
        "Mode tree",
        "Configuration states",
        "Motion primitives",
        "Reconfiguration map",
        "FDIR",
        "Tunable parameters",
        "Servo and bolter constants",
        "System constants",
        "Ground-system exports",
    ]
    .iter()
    .enumerate()
    {
        let anchor = s.to_ascii_lowercase().replace(' ', "-");
        let _ = writeln!(o, "{}. [{s}](#{}-{anchor})", i + 1, i + 1);
    }
    let _ = writeln!(o);

    section_conventions_and_apids(&mut o, robot1);
    section_packet_layouts(&mut o);
    section_telecommands(&mut o);
    section_telemetry_packets(&mut o);
    section_housekeeping_structures(&mut o);
    section_parameters(&mut o);
    section_events(&mut o);
    section_failure_codes(&mut o);
    section_mode_tree(&mut o);
    section_configuration_states(&mut o);
    section_motion_primitives(&mut o);
    section_reconfiguration_map(&mut o);
    section_fdir(&mut o);
    section_tunable_parameters(&mut o);
    section_servo_and_bolter(&mut o);
    section_system_constants(&mut o);
    section_ground_system_exports(&mut o, robot1);
    o
}

/// ICD §1. Conventions and APIDs
fn section_conventions_and_apids(o: &mut String, robot1: u16) {
    let _ = writeln!(o, "## 1. Conventions and APIDs\n");
    let _ = writeln!(
        o,
        "- Every packet is a CCSDS space packet (version 0) with a PUS-C (ECSS-E-ST-70-41C) secondary header\n  and a packet error control field; all multi-byte fields are **big-endian**.\n- Robot *N* ({}..={}) uses APID **0x{:03X} + N**; robot 1 (the default) is APID **0x{:03X}** ({}). TM and TC\n  of one robot share its APID. APID 0x{:03X} is the CCSDS idle APID.\n- The ground is source/destination ID {}.\n- Time stamps are CDS short: P-field 0x{:02X}, 16-bit days since 1958-01-01, 32-bit milliseconds of day\n  ({} octets).\n",
        apid::ROBOT_MIN,
        apid::ROBOT_MAX,
        apid::APID_BASE,
        robot1,
        robot1,
        apid::IDLE_APID,
        config::GROUND_ID,
        headers::CDS_SHORT_PFIELD,
        config::TIMESTAMP_LEN
    );
    let _ = writeln!(
        o,
        "- Files (docs/files.md): CCSDS File Delivery Protocol (727.0-B-5) PDUs, one per space packet without a
  secondary header, on APID **0x{:03X}** both ways (TC packets up, TM packets down on TM virtual channel {}), on
  the space link only. CFDP entity IDs: the ground {}, robot *N* = *N* ({} octets); transaction sequence numbers {} octets; PDUs of at
  most {} octets, modular checksum (type {}), no PDU CRC.
",
        mib::cfdp::APID,
        mib::link::tm_vc::FILES,
        mib::cfdp::GROUND_ENTITY_ID,
        mib::cfdp::ENTITY_ID_LEN,
        mib::cfdp::SEQ_NUM_LEN,
        mib::cfdp::MAX_PDU_LEN,
        mib::cfdp::CHECKSUM_TYPE
    );
}

/// ICD §2. Packet layouts
fn section_packet_layouts(o: &mut String) {
    let _ = writeln!(o, "## 2. Packet layouts\n");
    let _ = writeln!(
        o,
        "Telemetry: primary header (6) + TM secondary header ({}) + source data + PEC (2): the source data\nstarts at octet **{}** of the packet. Telecommands: primary header (6) + TC secondary header ({}) +\napplication data + PEC (2): the application data starts at octet **{}**. A packet is at most {} octets;\na TC's application data at most {} octets.\n",
        headers::len(headers::TM_SEC_HEADER),
        headers::tm_source_data_offset(),
        headers::len(headers::TC_SEC_HEADER),
        headers::tc_app_data_offset(),
        config::MAX_PACKET_LEN,
        config::MAX_TC_APP_DATA
    );
    header_table(
        o,
        "2.1 CCSDS primary header (6 octets)",
        headers::PRIMARY_HEADER,
        "`PKT_TYPE` is 0 for TM and 1 for TC.",
    );
    header_table(
        o,
        "2.2 PUS-C TM secondary header with CDS short time stamp",
        headers::TM_SEC_HEADER,
        "As `mib_wire::header::emit_tm` writes it for the obsw and the ground (the layout of sat-rs `spacepackets` 0.17's `PusTmCreator` with a `CdsTime` stamp, which reads it back in the tests).",
    );
    header_table(o, "2.3 PUS-C TC secondary header", headers::TC_SEC_HEADER, "");
    header_table(
        o,
        "2.4 Packet error control",
        &[headers::PEC],
        "The last two octets of every TM and TC.",
    );
    let _ = writeln!(
        o,
        "### 2.5 Request ID\n\nPUS 1 reports identify the TC by its request ID: the TC's packet ID (version, type, secondary\nheader flag, APID: u16) followed by its packet sequence control (sequence flags, count: u16).\n"
    );
}

/// ICD §3. Telecommands
fn section_telecommands(o: &mut String) {
    let _ = writeln!(o, "## 3. Telecommands\n");
    let _ = writeln!(
        o,
        "Every TC may be refused at acceptance (TM[1,2]) with: {}.\nPUS 8 TCs carry the function ID (u16) as the first field of their application data. Offsets below\nare octets from the start of the application data. \"Long-running\" TCs report start (TM[1,3]),\nprogress per step (TM[1,5]) and completion (TM[1,7]) later; the others complete at once.\n",
        ACCEPTANCE_FAILURES
            .iter()
            .map(|f| format!("`{}`", f.name()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        o,
        "| service | subservice | function | name | accepted in | long-running | fixed data octets | hazardous |"
    );
    let _ = writeln!(o, "|---:|---:|---:|---|---|---|---:|---|");
    for t in TCS {
        let _ = writeln!(
            o,
            "| {} | {} | {} | [`{}`](#tc-{}) | {} | {} | {}{} | {} |",
            t.service,
            t.subservice,
            if t.service == tc::service::FUNCTION {
                t.function.to_string()
            } else {
                "—".into()
            },
            t.name,
            t.name.to_ascii_lowercase(),
            t.modes.names(),
            if t.long_running { "yes" } else { "no" },
            t.fixed_len(),
            if t.variable { " + variable" } else { "" },
            t.hazard
                .map_or_else(|| "no".to_string(), |h| format!("**yes**: {}", c(h)))
        );
    }
    let _ = writeln!(o);
    for t in TCS {
        let _ = writeln!(
            o,
            "### TC {}\n\nTC[{},{}]{} — {}. Accepted in: {}. SCOS-2000 name `{}`.\n",
            t.name,
            t.service,
            t.subservice,
            if t.service == tc::service::FUNCTION {
                format!(" function {}", t.function)
            } else {
                String::new()
            },
            c(&t.description().to_string()),
            t.modes.names(),
            ScosNames::command(t)
        );
        if let Some(h) = t.hazard {
            let _ = writeln!(
                o,
                "**Hazardous** (confirmation before sending; SCOS-2000 `CCF_CRITICAL` = Y, XTCE significance critical): {}.\n",
                c(h)
            );
        }
        let mut off = if t.service == tc::service::FUNCTION { 2 } else { 0 };
        if t.args.is_empty() && t.service != tc::service::FUNCTION {
            let _ = writeln!(o, "No application data.\n");
        } else {
            let _ = writeln!(o, "| offset | argument | type | unit | min | max | description |");
            let _ = writeln!(o, "|---:|---|---|---|---:|---:|---|");
            if t.service == tc::service::FUNCTION {
                let _ = writeln!(
                    o,
                    "| 0 | function ID | u16 | — | {} | {} | fixed |",
                    t.function, t.function
                );
            }
            for a in t.args {
                let _ = writeln!(
                    o,
                    "| {off} | `{}` | {} | {} | {} | {} | {} |",
                    a.name,
                    a.ptype.name(),
                    if a.unit.is_empty() { "—" } else { a.unit },
                    a.min,
                    a.max,
                    c(&arg_desc(a))
                );
                off += a.ptype.size();
            }
            if t.variable {
                let _ = writeln!(o, "| {off} | … | variable | | | | see description |");
            }
            let _ = writeln!(o);
        }
        if t.failures.is_empty() {
            let _ = writeln!(o, "Specific failure codes: none.\n");
        } else {
            let _ = writeln!(
                o,
                "Specific failure codes: {}.\n",
                t.failures
                    .iter()
                    .map(|f| format!("`{}` ({})", f.name(), f.code()))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
}

/// ICD §4. Telemetry packets
fn section_telemetry_packets(o: &mut String) {
    let _ = writeln!(o, "## 4. Telemetry packets\n");
    let _ = writeln!(o, "| service | subservice | name | source data | description |");
    let _ = writeln!(o, "|---:|---:|---|---|---|");
    for t in TMS {
        let _ = writeln!(
            o,
            "| {} | {} | `{}` | {} | {} |",
            t.service,
            t.subservice,
            t.name,
            c(&crate::text::summary(t.body)),
            c(t.desc)
        );
    }
    let _ = writeln!(
        o,
        "\nHousekeeping reports are told apart by their SID and event reports by their event ID: the first\nu16 of the source data (octet {} of the packet, the SCOS-2000 PI1).\n",
        headers::tm_source_data_offset()
    );
    let _ = writeln!(
        o,
        "Source data field by field (the MIB's field lists, `mib::layout`; the wire crate `mib-wire`, the\nXTCE export and `ground decode` use the same lists). Offsets in octets from the start of the source\ndata (`.b` = first bit of a bit field); \"—\" after a variable part.\n"
    );
    for t in TMS {
        let _ = writeln!(o, "### TM[{},{}] {}\n", t.service, t.subservice, t.name);
        body_table(o, t.body);
    }
}

/// ICD §5. Housekeeping structures
fn section_housekeeping_structures(o: &mut String) {
    let _ = writeln!(o, "## 5. Housekeeping structures\n");
    let _ = writeln!(
        o,
        "A TM[3,25] report's source data is the SID (u16) followed by the structure's parameters in the\norder below. \"Offset\" counts octets from the start of the source data, \"packet\" from the start of the\npacket. Intervals can be changed with TC[3,31] within {} … {} ms. Each structure reports at its own phase\nwithin the second ({} ms apart, in the order below): its first report after boot, TC[3,5] or TC[3,31] is one\ninterval after the next instant of its phase, so structures with whole-second intervals never report in the\nsame control period. An interval that is not whole seconds keeps no phase: reports come an interval apart.\n",
        hk::MIN_INTERVAL_MS,
        hk::MAX_INTERVAL_MS,
        hk::PHASE_STEP_MS
    );
    let sd = headers::tm_source_data_offset();
    for h in HK_STRUCTS {
        let _ = writeln!(
            o,
            "### SID {} — {}\n\n{}. Default interval {} ms, {} at boot. Source data {} octets; packet {} octets.\n",
            h.sid,
            h.name,
            c(h.desc),
            h.default_interval_ms,
            if h.default_enabled { "enabled" } else { "disabled" },
            h.data_len(),
            headers::tm_packet_len(h.data_len())
        );
        let _ = writeln!(o, "| offset | packet | parameter | ID | type | unit |");
        let _ = writeln!(o, "|---:|---:|---|---:|---|---|");
        let _ = writeln!(o, "| 0 | {sd} | SID = {} | — | u16 | — |", h.sid);
        let mut off = 2;
        for id in h.params {
            if let Some(p) = params::by_id(*id) {
                let _ = writeln!(
                    o,
                    "| {off} | {} | `{}` | {} | {} | {} |",
                    sd + off,
                    p.name,
                    p.id,
                    p.ptype.name(),
                    if p.unit.is_empty() { "—" } else { p.unit }
                );
                off += p.ptype.size();
            }
        }
        let _ = writeln!(o);
    }
}

/// ICD §6. Parameters
fn section_parameters(o: &mut String) {
    let _ = writeln!(o, "## 6. Parameters\n");
    let _ = writeln!(
        o,
        "Engineering value = raw × scale + offset. Limits are in engineering units: outside the soft range\nthe ground warns, outside the hard range it alarms, in the root modes where the limits apply (the\nregulated servo voltage is 0 V in standby, where the regulator is off; SCOS-2000 makes such a check\nrelevant through `OCP_RLCHK`/`OCP_VALPAR` on the mode, XTCE through context alarms on `MODE`), and\nonly while the condition given after \"if\" holds (the hip deviation while no motion primitive runs:\na turning hip is away from the angle of the last state; context on `ACTIVE_PRIMITIVE`). The on-board\nmonitors (section 13) use their own raw limits and are skipped in the same states.\n"
    );
    let _ = writeln!(
        o,
        "Ground-side checking (collector alarms, dashboard colours): a level rises after {} consecutive\nsamples beyond a limit (`GROUND_LIMIT_PERSISTENCE`) and falls once the value is back inside by\n{} ‰ of the soft band (`GROUND_LIMIT_HYSTERESIS_PERMILLE`).\n",
        params::GROUND_LIMIT_PERSISTENCE,
        params::GROUND_LIMIT_HYSTERESIS_PERMILLE
    );
    let _ = writeln!(
        o,
        "| ID | name | type | unit | calibration | soft limits | hard limits | limits apply in | SCOS-2000 | description |"
    );
    let _ = writeln!(o, "|---:|---|---|---|---|---|---|---|---|---|");
    for p in PARAMS {
        param_row(o, p);
    }
    let _ = writeln!(o);
}

/// ICD §7. Events
fn section_events(o: &mut String) {
    let _ = writeln!(o, "## 7. Events\n");
    let _ = writeln!(
        o,
        "An event report TM[5,s] has subservice s = severity (1 info, 2 low, 3 medium, 4 high); its source\ndata is the event ID (u16) followed by the parameters (offsets from the start of the source data).\n\"Fault\" events are the FDIR detections of section 13.\n"
    );
    let _ = writeln!(
        o,
        "| ID | name | severity | fault | parameters (offset: name type) | description |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|");
    for e in EVENTS {
        let mut off = 2;
        let mut ps = Vec::new();
        for p in e.params {
            ps.push(format!("{off}: `{}` {}", p.name, p.ptype.name()));
            off += p.ptype.size();
        }
        let _ = writeln!(
            o,
            "| 0x{:04X} | `{}` | {} (TM[5,{}]) | {} | {} | {} |",
            e.id,
            e.name,
            e.severity.name(),
            e.severity.subservice(),
            if e.fault { "yes" } else { "no" },
            if ps.is_empty() {
                "—".to_string()
            } else {
                ps.join("<br>")
            },
            c(e.desc)
        );
    }
    let _ = writeln!(o);
}

/// ICD §8. Failure codes
fn section_failure_codes(o: &mut String) {
    let _ = writeln!(o, "## 8. Failure codes\n");
    let _ = writeln!(
        o,
        "A failed verification report (TM[1,2], [1,4], [1,6], [1,8]) carries the request ID, (the step for\nprogress), the failure code (u16) and the failure data below. Codes not in this table decode as\n\"unknown\".\n"
    );
    let _ = writeln!(o, "| code | name | failure data | description |");
    let _ = writeln!(o, "|---:|---|---|---|");
    for f in FailureCode::ALL {
        let _ = writeln!(
            o,
            "| {} | `{}` | {} | {} |",
            f.code(),
            f.name(),
            if f.data().is_empty() {
                "—".to_string()
            } else {
                crate::text::fields_summary(f.data())
            },
            c(f.description())
        );
    }
    let _ = writeln!(o);
}

/// ICD §9. Mode tree
fn section_mode_tree(o: &mut String) {
    let _ = writeln!(o, "## 9. Mode tree\n");
    let _ = writeln!(
        o,
        "PUS 200 targets are mode-tree nodes (u32). Only the robot node is commanded (TC[200,1]); every\nother node follows the root. Robot submode: {} idle, {} executing an action.\n",
        modes::submode::IDLE,
        modes::submode::BUSY
    );
    let _ = writeln!(o, "```mermaid\ngraph TD");
    for n in NODES {
        if let Some(p) = n.parent.and_then(modes::node_by_id) {
            let _ = writeln!(o, "  {} --> {}", p.name, n.name);
        }
    }
    let _ = writeln!(o, "```\n");
    let roots = [
        modes::robot_mode::STANDBY,
        modes::robot_mode::OPERATIONAL,
        modes::robot_mode::SAFED,
    ];
    let _ = write!(o, "| node ID | node | parent | kind | modes |");
    for r in roots {
        let _ = write!(o, " robot {} ({r}) |", mode_name_root(r));
    }
    let _ = writeln!(o);
    let _ = writeln!(o, "|---:|---|---|---|---|---|---|---|");
    for n in NODES {
        let modes_list: Vec<String> = (0..8)
            .filter_map(|m| modes::mode_name(n.kind, m).map(|s| format!("{m} {s}")))
            .collect();
        let _ = write!(
            o,
            "| {} | `{}` | {} | {:?} | {} |",
            n.id,
            n.name,
            n.parent.and_then(modes::node_by_id).map(|p| p.name).unwrap_or("—"),
            n.kind,
            modes_list.join(", ")
        );
        for r in roots {
            let m = if n.parent.is_none() {
                r
            } else {
                modes::child_mode(r, n.kind)
            };
            let _ = write!(o, " {} |", modes::mode_name(n.kind, m).unwrap_or("?"));
        }
        let _ = writeln!(o);
    }
    let _ = writeln!(
        o,
        "\nTC acceptance per root mode (paper Table 7): standby accepts mode changes (and the assembly-system\nfault); safed accepts hip and arm actuator commands, stop and mode changes; operational accepts all.\n"
    );
}

/// ICD §10. Configuration states
fn section_configuration_states(o: &mut String) {
    let _ = writeln!(o, "## 10. Configuration states\n");
    let _ = writeln!(
        o,
        "A state is the pair (face gripped by side A, face gripped by side B) of the reference voxel in the\nX–Y plane (gravity along −Y). Matched: both sides on one face (contracted); stretch: opposite faces;\nturn: faces of different axes (hip ±90°). Matched `Ypos` (hanging from the ceiling) is excluded, leaving\n{} states. On the wire, state {} means unknown.\n",
        NUM_STATES,
        robot::STATE_UNKNOWN
    );
    let _ = writeln!(
        o,
        "| ID | letter | name | side A face | side B face | kind | hip angle | arm PWM |"
    );
    let _ = writeln!(o, "|---:|---|---|---|---|---|---:|---:|");
    for s in &STATES {
        let _ = writeln!(
            o,
            "| {} | {} | {} | {} | {} | {} | {}° | {} µs |",
            s.id,
            s.label,
            s.name,
            s.a.name(),
            s.b.name(),
            s.kind().name(),
            num(s.hip_cdeg() as f64 / 100.0),
            s.arm_pwm()
        );
    }
    let _ = writeln!(o);
}

/// ICD §11. Motion primitives
fn section_motion_primitives(o: &mut String) {
    let _ = writeln!(o, "## 11. Motion primitives\n");
    let _ = writeln!(
        o,
        "Each primitive moves one side while the other stays gripped (fwd: side A moves, back: side B).\n"
    );
    let _ = writeln!(o, "| ID | name | moving side | motion |");
    let _ = writeln!(o, "|---:|---|---|---|");
    for p in &PRIMITIVES {
        let m = match p.motion {
            robot::Motion::Extend => "extend to the opposite face (from matched)".to_string(),
            robot::Motion::Contract => "contract onto the other side's face (from stretch)".to_string(),
            robot::Motion::Rotate(q) => format!(
                "swing about the hip by {}90° ({})",
                if q > 0 { "+" } else { "−" },
                if q > 0 { "counter-clockwise" } else { "clockwise" }
            ),
        };
        let _ = writeln!(o, "| {} | {} | {} | {} |", p.id, p.name, p.moving.name(), m);
    }
    let _ = writeln!(o);
}

/// ICD §12. Reconfiguration map
fn section_reconfiguration_map(o: &mut String) {
    let _ = writeln!(o, "## 12. Reconfiguration map\n");
    let _ = writeln!(
        o,
        "Row = from state, column = to state; a cell is the primitive that makes that step, `·` none.\n"
    );
    let _ = write!(o, "| from \\ to |");
    for s in &STATES {
        let _ = write!(o, " {} |", s.label);
    }
    let _ = writeln!(o);
    let _ = write!(o, "|---|");
    for _ in &STATES {
        let _ = write!(o, ":-:|");
    }
    let _ = writeln!(o);
    for (i, row) in RECONFIG_MAP.iter().enumerate() {
        let _ = write!(o, "| **{}** {} |", STATES[i].label, STATES[i].name);
        for &p in row {
            if p == 0 {
                let _ = write!(o, " · |");
            } else {
                let _ = write!(o, " {p} |");
            }
        }
        let _ = writeln!(o);
    }
    let _ = writeln!(
        o,
        "\nShortest reconfigurations between matched states (at most {} primitives are allowed in one\nTC[8,1] RECONFIGURE):\n",
        config::MAX_RECONFIG_PRIMITIVES
    );
    let _ = writeln!(o, "| from | to | primitives |");
    let _ = writeln!(o, "|---|---|---|");
    let matched: Vec<u8> = STATES
        .iter()
        .filter(|s| s.kind() == StateKind::Matched)
        .map(|s| s.id)
        .collect();
    for &a in &matched {
        for &b in &matched {
            if a == b {
                continue;
            }
            let path = match shortest_path(a, b) {
                Some(p) => {
                    let mut cur = a;
                    let mut steps = Vec::new();
                    for prim in p {
                        let next = robot::apply(cur, prim).unwrap_or(robot::STATE_UNKNOWN);
                        steps.push(format!(
                            "{prim} → {}",
                            STATES
                                .get(next as usize)
                                .map(|s| s.label.to_string())
                                .unwrap_or_default()
                        ));
                        cur = next;
                    }
                    steps.join(", ")
                }
                None => "unreachable".to_string(),
            };
            let _ = writeln!(o, "| {} | {} | {} |", state_label(a), state_label(b), path);
        }
    }
    let _ = writeln!(o, "\n```mermaid\ngraph LR");
    for s in &STATES {
        let _ = writeln!(o, "  S{}[\"{}: {}\"]", s.id, s.label, s.name);
    }
    for (i, row) in RECONFIG_MAP.iter().enumerate() {
        for (j, &p) in row.iter().enumerate() {
            if p != 0 {
                let _ = writeln!(o, "  S{} -->|{}| S{}", STATES[i].id, p, STATES[j].id);
            }
        }
    }
    let _ = writeln!(o, "```\n");
}

/// ICD §13. FDIR
fn section_fdir(o: &mut String) {
    let _ = writeln!(o, "## 13. FDIR\n");
    let _ = writeln!(o, "### 13.1 Faults (paper Table 8)\n");
    let _ = writeln!(
        o,
        "Each fault sets bit *n* of `FAULT_FLAGS`/`FAULT_LATCHED`, raises its event, and through its PUS 19\nevent-action link commands the robot node into the recovery mode.\n"
    );
    let _ = writeln!(o, "| bit | event | recovery mode | when |");
    let _ = writeln!(o, "|---:|---|---|---|");
    for f in FAULTS {
        let _ = writeln!(
            o,
            "| {} | `{}` (0x{:04X}) | {} | {} |",
            f.bit,
            events::by_id(f.event).map(|e| e.name).unwrap_or("?"),
            f.event,
            mode_name_root(f.mode),
            timing_text(f.timing)
        );
    }
    let _ = writeln!(o, "\n### 13.2 On-board monitors (PUS 12)\n");
    let _ = writeln!(
        o,
        "Limits are raw values of the parameter (engineering value in brackets); a violation must persist\nfor the given number of {} ms control cycles.\n",
        config::CONTROL_PERIOD_MS
    );
    let _ = writeln!(
        o,
        "| ID | name | parameter | low | high | persistence | event | evaluated | enabled |"
    );
    let _ = writeln!(o, "|---:|---|---|---|---|---|---|---|---|");
    for m in MONITORS {
        let p = params::by_id(m.param);
        let lim = |v: i32, none: i32| -> String {
            if v == none {
                "—".to_string()
            } else {
                match p {
                    Some(p) => format!(
                        "{v} ({} {})",
                        num((p.calib.eng(v as i64) * 1000.0).round() / 1000.0),
                        p.unit
                    )
                    .trim_end()
                    .to_string(),
                    None => v.to_string(),
                }
            }
        };
        let _ = writeln!(
            o,
            "| {} | `{}` | `{}` | {} | {} | {} ({} ms) | `{}` | {} | {} |",
            m.id,
            m.name,
            p.map(|p| p.name).unwrap_or("?"),
            lim(m.low, i32::MIN),
            lim(m.high, i32::MAX),
            m.persistence,
            m.persistence as u32 * config::CONTROL_PERIOD_MS,
            events::by_id(m.event).map(|e| e.name).unwrap_or("?"),
            m.phase.name(),
            if m.enabled { "yes" } else { "no" }
        );
    }
    let _ = writeln!(o, "\n### 13.3 Event-action links (PUS 19)\n");
    let _ = writeln!(o, "| event | action | when | enabled at boot |");
    let _ = writeln!(o, "|---|---|---|---|");
    for f in FAULTS {
        if let Some(a) = fdir::action_for(f.event) {
            let _ = writeln!(
                o,
                "| `{}` (0x{:04X}) | TC[200,1] robot node → {} | {} | {} |",
                events::by_id(a.event).map(|e| e.name).unwrap_or("?"),
                a.event,
                mode_name_root(a.mode),
                timing_text(a.timing),
                if a.enabled { "yes" } else { "no" }
            );
        }
    }
    let _ = writeln!(o);
}

/// ICD §14. Tunable parameters
fn section_tunable_parameters(o: &mut String) {
    let _ = writeln!(o, "## 14. Tunable parameters\n");
    let _ = writeln!(o, "Read with TC[20,1], set with TC[20,3] (value i32, range-checked).\n");
    let _ = writeln!(o, "| ID | name | unit | default | min | max | description |");
    let _ = writeln!(o, "|---:|---|---|---:|---:|---:|---|");
    for t in TUNABLES {
        let _ = writeln!(
            o,
            "| {} | `{}` | {} | {} | {} | {} | {} |",
            t.id,
            t.name,
            if t.unit.is_empty() { "—" } else { t.unit },
            t.default,
            t.min,
            t.max,
            c(t.desc)
        );
    }
    let _ = writeln!(o);
}

/// ICD §15. Servo and bolter constants
fn section_servo_and_bolter(o: &mut String) {
    let _ = writeln!(o, "## 15. Servo and bolter constants\n");
    let _ = writeln!(o, "| constant | value |");
    let _ = writeln!(o, "|---|---:|");
    use robot::{bolter, servo};
    for (n, v) in [
        ("arm contracted", format!("{} µs", servo::ARM_CONTRACTED_US)),
        ("arm at turn length", format!("{} µs", servo::ARM_TURN_US)),
        ("arm extended", format!("{} µs", servo::ARM_EXTENDED_US)),
        ("gripper closed", format!("{} µs", servo::GRIP_CLOSED_US)),
        ("gripper open", format!("{} µs", servo::GRIP_OPEN_US)),
        (
            "commandable PWM",
            format!("{} … {} µs", servo::PWM_MIN_US, servo::PWM_MAX_US),
        ),
        ("servo speed", format!("{} µs/s", servo::SERVO_SPEED_US_PER_S)),
        (
            "hip range",
            format!(
                "{}° … {}°",
                num(servo::HIP_MIN_CDEG as f64 / 100.0),
                num(servo::HIP_MAX_CDEG as f64 / 100.0)
            ),
        ),
        ("hip home", format!("{}°", num(servo::HIP_HOME_CDEG as f64 / 100.0))),
        (
            "hip velocity-mode speed",
            format!("{}°/s", num(servo::HIP_SPEED_CDEG_S as f64 / 100.0)),
        ),
        (
            "hip velocity/position switch",
            format!("{}°", num(servo::HIP_SWITCH_CDEG as f64 / 100.0)),
        ),
        (
            "hip at target within",
            format!("{}°", num(servo::HIP_DONE_CDEG as f64 / 100.0)),
        ),
        ("fastener pairs per face", bolter::PAIRS_PER_FACE.to_string()),
        (
            "ground demo: pairs / 1st / 2nd / 3rd / failed",
            format!(
                "{} / {} / {} / {} / {}",
                bolter::DEMO_PAIRS,
                bolter::DEMO_FIRST,
                bolter::DEMO_SECOND,
                bolter::DEMO_THIRD,
                bolter::DEMO_FAILED
            ),
        ),
        (
            "battery empty / full",
            format!("{} V / {} V", num(params::V_BAT_EMPTY), num(params::V_BAT_FULL)),
        ),
        ("regulated servo supply", format!("{} V", num(params::V_REG_NOMINAL))),
        (
            "current limits: locomotion / gripper / bolter",
            format!(
                "{} A / {} A / {} A",
                num(params::I_LOC_MAX),
                num(params::I_GRIP_MAX),
                num(params::I_BO_MAX)
            ),
        ),
        (
            "idle locomotion current limit",
            format!("{} A", num(params::I_LOC_IDLE_MAX)),
        ),
        (
            "hip contracted tolerance",
            format!("{}°", num(params::HIP_CONTRACTED_TOL_DEG)),
        ),
        (
            "board B heartbeat timeout",
            format!("{} ms", num(params::B_HEARTBEAT_TIMEOUT_MS)),
        ),
    ] {
        let _ = writeln!(o, "| {n} | {v} |");
    }
    let _ = writeln!(o);
}

/// ICD §16. System constants
fn section_system_constants(o: &mut String) {
    let _ = writeln!(o, "## 16. System constants\n");
    let _ = writeln!(o, "| constant | value |");
    let _ = writeln!(o, "|---|---:|");
    for (n, v) in [
        ("control period", format!("{} ms", config::CONTROL_PERIOD_MS)),
        (
            "moving-average window",
            format!("{} samples", config::MOVING_AVERAGE_WINDOW),
        ),
        (
            "board B heartbeat period",
            format!("{} ms", config::B_HEARTBEAT_PERIOD_MS),
        ),
        ("A–B link", format!("{} baud", config::AB_LINK_BAUD)),
        (
            "default OBSW port (robot N: + N − 1)",
            mib::host_config::DEFAULT_PORT.to_string(),
        ),
        ("TM queue depth", format!("{} packets", config::TM_QUEUE_DEPTH)),
        ("TM store capacity", format!("{} packets", config::TM_STORE_CAPACITY)),
        ("schedule capacity", format!("{} activities", config::SCHEDULE_CAPACITY)),
        (
            "duplicate-TC window",
            format!("{} request IDs", config::DUPLICATE_WINDOW),
        ),
        ("pending action queue", config::ACTION_QUEUE_DEPTH.to_string()),
        (
            "ground acknowledgement timeout",
            format!("{} ms", mib::ground_config::GROUND_ACK_TIMEOUT_MS),
        ),
        (
            "ground connection-test period",
            format!("{} ms", mib::ground_config::GROUND_PING_PERIOD_MS),
        ),
        (
            "link-quality window",
            format!("{} exchanges", mib::ground_config::LINK_QUALITY_WINDOW),
        ),
        (
            "ground resends per TC",
            mib::ground_config::GROUND_MAX_RESENDS.to_string(),
        ),
    ] {
        let _ = writeln!(o, "| {n} | {v} |");
    }
    let _ = writeln!(o);
}

/// ICD §17. Ground-system exports
fn section_ground_system_exports(o: &mut String, robot1: u16) {
    let _ = writeln!(o, "## 17. Ground-system exports\n");
    let _ = writeln!(
        o,
        "`ground mib export --format scos|xtce|json --out DIR` writes (through `mib_export::write_all`):\n\n- **scos** — SCOS-2000 MIB ASCII tables (`vdf pid pic tpcf pcf plf caf cap ocf ocp tcp pcpc pcdf ccf cdf\n  cpc prf prv`.dat), tab-separated, no header line, every column of the SCOS-2000 MIB ICD in order.\n  TM packets are identified by APID, type, subtype and PI1 (the SID of TM[3,25], the event ID of\n  TM[5,x]) at octet {} (`pic`); `PLF_OFFBY` counts octets from the start of the packet, `CDF_BIT` bits\n  from the start of the application data. SCOS-2000 names have 8 characters: HK parameter *n* is\n  `MMT` + *n* (5 digits), event parameters `ME` + event ID (hex) + position, commands `MC` + service +\n  subservice (3 digits each) or `MF` + function ID (6 digits), command parameters `P` + the command\n  name's digits + position. The PUS 8 function ID is a fixed element (`MMFUNCID`) of every TC[8,1].\n  The other reports: their fixed fields are parameters `MR` + kind index (2 digits, order of §4) +\n  field index at their octet and bit offsets (`PLF_OFFBI`; bit fields of 1-3 bits PTC 2, 4-16 bits\n  PTC 3); failure reports are one packet per failure code (PI1 = the code), whose failure data\n  fields are `MD` + code (3 digits) + field index. List reports (TM[5,8], [12,9], [19,9]) carry\n  their count; their entries are described in the XTCE export.\n- **xtce** — XTCE 1.2 (`http://www.omg.org/spec/XTCE/20180204`): container tree `CCSDSPacket` →\n  `PUS_TM` → `HK_REPORT` → `HK_<structure>` (restricted on the SID) / `EVENT_<severity>` →\n  `EVT_<event>` (restricted on the event ID) / `TM_<name>` with the report's fields from §4\n  (parameters `<name>_<field path>`, enumerated with the MIB's names; failure reports one child\n  container `<name>_<code>` per failure code with its failure data; list reports one child\n  `<name>_N<count>` per entry count, entries as containers `<name>_<group>_<i>`); polynomial\n  calibrators and alarm ranges; every TC as a MetaCommand derived from the abstract `PUS_TC` with\n  argument valid ranges. `scripts/xtce_decode.py` decodes packets with it (space-packet-parser).\n- **json** — the whole MIB.\n\nThe exports are generated for robot {} (APID 0x{:03X}). Every robot is its own SCOS-2000/XTCE\nspacecraft: for robot *N* call `mib_export::scos_tables_for(N)` / `xtce_document_for(N)`, which change\nonly the APIDs (and the SCOS-2000 SPIDs, `N` × 10000 + index).\n",
        headers::tm_source_data_offset(),
        apid::DEFAULT_ROBOT,
        robot1
    );
}

/// Markdown table of a body's fields (offset, name, type, unit, value names, description).
fn body_table(o: &mut String, items: &[mib::layout::Item]) {
    use crate::text::type_name;
    use mib::layout::{Field, Item, Names, Tail};
    if items.is_empty() {
        let _ = writeln!(o, "No source data.\n");
        return;
    }
    let _ = writeln!(o, "| offset | field | type | unit | values | description |");
    let _ = writeln!(o, "|---|---|---|---|---|---|");
    fn names(n: Names) -> String {
        match n {
            Names::None => String::new(),
            Names::List(l) => l.iter().map(|(v, n)| format!("{v} {n}")).collect::<Vec<_>>().join(", "),
            Names::FailureCode => "failure codes (§8)".into(),
            Names::Event => "events (§7), 0 NONE".into(),
            Names::Param => "parameters (§6)".into(),
            Names::Tunable => "tunable parameters (§14)".into(),
            Names::Sid => "HK structures (§5)".into(),
            Names::Node => "mode-tree nodes (§9)".into(),
            Names::Mode => "modes of the node (§9)".into(),
            Names::State => "configuration states (§10), 255 UNKNOWN".into(),
            Names::Primitive => "motion primitives (§11), 0 NONE".into(),
            Names::Function => "PUS 8 functions (§3)".into(),
            Names::Monitor => "monitors (§13)".into(),
        }
    }
    fn rows(o: &mut String, prefix: &str, items: &[Item], bit: &mut Option<usize>) {
        let row = |o: &mut String, name: String, f: &Field, bit: &mut Option<usize>| {
            let off = match *bit {
                Some(b) if b % 8 == 0 => format!("{}", b / 8),
                Some(b) => format!("{}.{}", b / 8, b % 8),
                None => "—".into(),
            };
            let _ = writeln!(
                o,
                "| {off} | `{name}` | {} | {} | {} | {} |",
                type_name(f),
                f.unit,
                c(&names(f.names)),
                c(f.desc)
            );
            if let Some(b) = bit.as_mut() {
                *b += f.bits as usize;
            }
        };
        for it in items {
            match it {
                Item::Field(f) => row(o, format!("{prefix}{}", f.name), f, bit),
                Item::Sub { name, sub } => {
                    for f in sub.fields {
                        row(o, format!("{prefix}{name}.{}", f.name), f, bit);
                    }
                }
                Item::Group {
                    name,
                    count,
                    max,
                    items,
                } => {
                    let _ = writeln!(
                        o,
                        "| {} | `{prefix}{name}[]` | group | | | `{count}` entries (at most {max}) of (offsets within an entry): |",
                        bit.map_or("—".into(), |b| (b / 8).to_string())
                    );
                    *bit = None;
                    rows(o, &format!("{prefix}{name}[]."), items, &mut Some(0));
                }
                Item::Packet { name, max_len } => {
                    let _ = writeln!(
                        o,
                        "| — | `{prefix}{name}` | packet | | | embedded space packet, at most {max_len} octets |"
                    );
                    *bit = None;
                }
                Item::Tail(t) => {
                    let what = match t {
                        Tail::FailureData => "failure data of the failure code (§8)",
                        Tail::EventParams => "parameters of the event (§7)",
                        Tail::HkParams => "parameters of the structure (§5)",
                    };
                    let _ = writeln!(
                        o,
                        "| {} | `{prefix}{}` | per `{}` | | | {what} |",
                        bit.map_or("—".into(), |b| (b / 8).to_string()),
                        match t {
                            Tail::FailureData => "failure_data",
                            Tail::EventParams | Tail::HkParams => "params",
                        },
                        t.discriminant()
                    );
                    *bit = None;
                }
            }
        }
    }
    rows(o, "", items, &mut Some(0));
    let _ = writeln!(o);
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: MMIC-MOT-04
    #[test]
    fn every_matched_state_reaches_every_other_within_the_limit() {
        for a in STATES.iter().filter(|s| s.kind() == StateKind::Matched) {
            for b in STATES.iter().filter(|s| s.kind() == StateKind::Matched) {
                if a.id != b.id {
                    let p = shortest_path(a.id, b.id).unwrap();
                    assert!(!p.is_empty() && p.len() <= config::MAX_RECONFIG_PRIMITIVES);
                }
            }
        }
        assert_eq!(shortest_path(0, 4), Some(vec![1]));
    }
}
