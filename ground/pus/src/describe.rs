//! One line of text per packet, for people.

use mib::FailureCode;

use super::{hex, Packet, TmBody};

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
        Packet::Tm(t) => format!(
            "TM  apid=0x{:03X} seq={:5} [{},{}] {} {} {}",
            t.apid,
            t.seq,
            t.service,
            t.subservice,
            t.time,
            t.name,
            describe_body(&t.body)
        ),
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
        TmBody::DisabledEvents { events } => format!("disabled events {events:04X?}"),
        TmBody::TimeReport { rate_exp, time } => format!("on-board time {time} rate 2^{rate_exp} s"),
        TmBody::MonDefinitions { monitors } => format!("{} monitors {monitors:?}", monitors.len()),
        TmBody::MonTransition {
            monitor,
            param,
            value,
            limit,
            state,
        } => format!(
            "monitor {monitor} param {} value {value} limit {limit} state {}",
            mib::params::by_id(*param).map_or("?", |p| p.name),
            match state {
                0 => "ok",
                1 => "below low",
                2 => "above high",
                _ => "?",
            }
        ),
        TmBody::StoreDownlinkDone {
            packets,
            oldest_time,
            oldest_seq,
            overwritten,
        } => format!(
            "store downlink done, {packets} packets; oldest stored: {oldest_time} seq {oldest_seq}; {overwritten} overwritten since boot"
        ),
        TmBody::PingReply => "ping reply".to_string(),
        TmBody::EaDefinitions { links } => format!("{} links {links:?}", links.len()),
        TmBody::ParamValue { param, value } => format!(
            "parameter {} = {value}",
            mib::tunables::by_id(*param).map_or("?", |t| t.name)
        ),
        TmBody::ModeReply { node, mode, submode } => format!(
            "node {} mode {} submode {submode}",
            node_name(*node),
            mode_name(*node, *mode)
        ),
        TmBody::ModeCantReach {
            node,
            mode,
            submode,
            reason,
        } => format!(
            "node {} cannot reach mode {} submode {submode}: reason {reason} ({})",
            node_name(*node),
            mode_name(*node, *mode),
            FailureCode::from_code(*reason).name()
        ),
        TmBody::TeamStatus {
            term,
            role,
            leader,
            ground_seen,
            roster,
            auth_steps,
            ..
        } => format!(
            "team term {term} role {} leader {leader} ground {} roster {roster:?} authorised steps {auth_steps}",
            mib::team::TEAM_ROLE_NAMES.name(i64::from(*role)).unwrap_or("?"),
            if *ground_seen { "seen" } else { "lost" }
        ),
        TmBody::PlanStatus {
            plan_id,
            state,
            steps,
            next_step,
            done,
            wait_robot,
            wait_step,
        } => format!(
            "plan {plan_id:#010x} {} step {next_step}/{steps} done {done}{}",
            mib::plan::STATE_NAMES.name(i64::from(*state)).unwrap_or("?"),
            if *wait_robot != 0 {
                format!(" waiting for robot {wait_robot} step {wait_step}")
            } else {
                String::new()
            }
        ),
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
