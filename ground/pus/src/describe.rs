//! One line of text per packet, for people.

use mib::FailureCode;

use super::out::{self, Format};
use super::packet::report_bytes;
use super::{hex, CdsShort, Packet, TmBody};

/// One line of human-readable text for a packet.
pub fn describe(p: &Packet) -> String {
    match p {
        Packet::Tc(t) => {
            let mut s = format!(
                "TC  apid=0x{:03X} seq={:5} [{},{}] {}",
                t.apid,
                t.seq,
                t.service,
                t.subservice,
                t.name.unwrap_or("UNKNOWN")
            );
            for a in &t.args {
                s.push_str(&format!(" {}={}", a.name, a.value));
            }
            if let Some(e) = &t.arg_error {
                s.push_str(&format!(" (bad arguments: {e})"));
            }
            s
        }
        Packet::Tm(t) => {
            let mut s = format!(
                "TM  apid=0x{:03X} seq={:5} [{},{}] {} {}",
                t.apid, t.seq, t.service, t.subservice, t.time, t.name,
            );
            let body = describe_body(&t.body);
            if !body.is_empty() {
                s.push(' ');
                s.push_str(&body);
            }
            s
        }
    }
}

/// The phrase of a report kind people read often; every other kind as its fields.
fn describe_report(r: &mib_wire::Tm) -> String {
    use mib_wire::Tm as W;
    match r {
        W::DisabledEvents(x) => {
            let events: Vec<u16> = x.events.iter().map(|e| e.event_id).collect();
            format!("disabled events {events:04X?}")
        }
        W::TimeReport(x) => format!("on-board time {} rate 2^{} s", CdsShort::from_wire(&x.time), x.rate_exp),
        W::MonTransition(x) => format!(
            "monitor {} param {} value {} limit {} state {}",
            x.monitor_id,
            mib::params::by_id(x.param).map_or("?", |p| p.name),
            x.value,
            x.limit,
            match x.state {
                0 => "ok",
                1 => "below low",
                2 => "above high",
                _ => "?",
            }
        ),
        W::StoreDownlinkDone(x) => format!(
            "store downlink done, {} packets; oldest stored: {} seq {}; {} overwritten since boot",
            x.packets,
            CdsShort::from_wire(&x.oldest_time),
            x.oldest_seq,
            x.overwritten
        ),
        W::PingReply(_) => "ping reply".to_string(),
        W::ParamValue(x) => format!(
            "parameter {} = {}",
            mib::tunables::by_id(x.param_id).map_or("?", |t| t.name),
            x.value
        ),
        W::ModeReply(x) => format!(
            "node {} mode {} submode {}",
            node_name(x.node),
            mode_name(x.node, x.mode),
            x.submode
        ),
        W::ModeCantReach(x) => format!(
            "node {} cannot reach mode {} submode {}: reason {} ({})",
            node_name(x.node),
            mode_name(x.node, x.mode),
            x.submode,
            x.reason,
            FailureCode::from_code(x.reason).name()
        ),
        W::TeamStatus(x) => {
            let roster: Vec<u8> = x.roster.iter().map(|r| r.robot).collect();
            format!(
                "team term {} role {} leader {} ground {} roster {roster:?} authorised steps {}",
                x.term,
                mib::team::TEAM_ROLE_NAMES.name(i64::from(x.role)).unwrap_or("?"),
                x.leader,
                if x.ground_seen != 0 { "seen" } else { "lost" },
                x.auth_steps
            )
        }
        // A kind without a phrase of its own (a new TM kind of the MIB among them) is
        // written in full from its field list: nothing of it is left out.
        _ => report_text(r),
    }
}

/// A report's fields as `name=value` pairs, as the decode output writes them (names from
/// the MIB beside the values); empty for a report without fields.
fn report_text(r: &mib_wire::Tm) -> String {
    match report_bytes(r)
        .map_err(|e| e.to_string())
        .and_then(|b| out::report(Format::Text, r, &b).map_err(|e| e.0))
    {
        Ok(t) => String::from_utf8_lossy(&t).trim_start().to_string(),
        Err(e) => format!("(not written: {e})"),
    }
}

/// Human-readable text for a TM body.
pub fn describe_body(b: &TmBody) -> String {
    match b {
        TmBody::Verification(v) => {
            let mut s = format!(
                "{} {} for {}",
                v.stage.name(),
                if v.success { "ok" } else { "FAILED" },
                v.request
            );
            if let Some(st) = v.step {
                s.push_str(&format!(" step {st}"));
            }
            if let Some(f) = &v.failure {
                s.push_str(&format!(": {f}"));
            }
            s
        }
        TmBody::Hk(h) => {
            let mut s = format!("{} (sid {})", h.name, h.sid);
            for v in &h.values {
                if v.unit.is_empty() {
                    s.push_str(&format!(" {}={}", v.name, v.raw));
                } else {
                    s.push_str(&format!(" {}={:.3}{}", v.name, v.eng, v.unit));
                }
            }
            s
        }
        TmBody::Event(e) => e.to_string(),
        TmBody::Report(r) => describe_report(r.as_ref()),
        TmBody::Unknown { data } => format!("undefined TM type, data {}", hex(data)),
    }
}

/// Name of a mode-tree node.
pub fn node_name(node: u32) -> String {
    mib::modes::node_by_id(node).map_or_else(|| format!("#{node}"), |n| n.name.to_string())
}

/// Name of a mode of a node.
pub fn mode_name(node: u32, mode: u32) -> String {
    mib::modes::node_by_id(node)
        .and_then(|n| mib::modes::mode_name(n.kind, mode))
        .map_or_else(|| format!("#{mode}"), |s| s.to_string())
}
