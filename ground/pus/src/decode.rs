//! Decoding packets: headers and CRC checked through `mib_wire`, then the body against
//! the MIB, into the owned values of [`super::Packet`].

use mib::events::Severity;
use mib::tc::service;
use mib_wire::codec;
use mib_wire::header::{TcPacket, TmPacket};

use super::error::{data_err, header_err};
use super::{
    decode_fields, BuildError, CdsShort, DecodeError, EaDefinition, Event, Failure, Field, Hk, HkValue, MonDefinition,
    Packet, Stage, Tc, Tm, TmBody, Verification,
};

/// Length of the packet at the start of `b`, if its header is plausible.
pub fn packet_len(b: &[u8]) -> Result<usize, DecodeError> {
    mib_wire::header::check_primary(b).map(|p| p.len).map_err(header_err)
}

/// Decodes the packet at the start of `b` (trailing bytes are ignored).
pub fn decode_packet(b: &[u8]) -> Result<Packet, DecodeError> {
    let p = mib_wire::header::check_primary(b).map_err(header_err)?;
    if p.is_tc {
        decode_tc(&b[..p.len]).map(Packet::Tc)
    } else {
        decode_tm(&b[..p.len]).map(Packet::Tm)
    }
}

/// `(APID, sequence count, on-board ms)` of a TM packet whose headers and CRC are intact,
/// whether or not its body decodes.
pub fn intact_position(raw: &[u8]) -> Option<(u16, u16, i64)> {
    let p = mib_wire::header::TmPacket::parse(raw).ok()?;
    Some((
        p.primary.apid,
        p.primary.seq_count,
        CdsShort::from_wire(&p.time).unix_ms(),
    ))
}

/// Decodes one TM packet (headers, CRC and body checked against the MIB).
pub fn decode_tm(b: &[u8]) -> Result<Tm, DecodeError> {
    let p = TmPacket::parse(b).map_err(header_err)?;
    let body = decode_tm_source(p.service, p.subservice, p.source)?;
    let apid = p.primary.apid;
    Ok(Tm {
        apid,
        robot: mib::apid::apid_robot(apid),
        seq: p.primary.seq_count,
        service: p.service,
        subservice: p.subservice,
        name: mib::tc::tm_by_type(p.service, p.subservice).map_or("UNKNOWN", |d| d.name),
        msg_counter: p.msg_counter,
        time: CdsShort::from_wire(&p.time),
        len: p.primary.len,
        body,
    })
}

/// Decodes TM source data through the wire crate's `Repr`s (generated from the MIB).
fn decode_tm_source(service: u8, subservice: u8, d: &[u8]) -> Result<TmBody, DecodeError> {
    use mib_wire::Tm as W;
    if mib::tc::tm_by_type(service, subservice).is_none() {
        return Ok(TmBody::Unknown { data: d.to_vec() });
    }
    let w = W::parse(service, subservice, d).map_err(|e| data_err(format!("TM[{service},{subservice}]: {e}")))?;
    let verif = |stage, success, rid: &mib_wire::RequestId, step: Option<u8>, f: Option<&mib_wire::Failure>| {
        Verification {
            stage,
            success,
            request: *rid,
            step,
            // The failure data is the tail of the source data.
            failure: f.map(|f| Failure::from_code(f.code(), &d[d.len() - f.buffer_len()..])),
        }
    };
    Ok(match w {
        W::AcceptanceSuccess(x) => TmBody::Verification(verif(Stage::Acceptance, true, &x.request_id, None, None)),
        W::AcceptanceFailure(x) => {
            TmBody::Verification(verif(Stage::Acceptance, false, &x.request_id, None, Some(&x.failure)))
        }
        W::StartSuccess(x) => TmBody::Verification(verif(Stage::Start, true, &x.request_id, None, None)),
        W::StartFailure(x) => TmBody::Verification(verif(Stage::Start, false, &x.request_id, None, Some(&x.failure))),
        W::ProgressSuccess(x) => TmBody::Verification(verif(Stage::Progress, true, &x.request_id, Some(x.step), None)),
        W::ProgressFailure(x) => TmBody::Verification(verif(
            Stage::Progress,
            false,
            &x.request_id,
            Some(x.step),
            Some(&x.failure),
        )),
        W::CompletionSuccess(x) => TmBody::Verification(verif(Stage::Completion, true, &x.request_id, None, None)),
        W::CompletionFailure(x) => {
            TmBody::Verification(verif(Stage::Completion, false, &x.request_id, None, Some(&x.failure)))
        }
        W::HkReport(x) => TmBody::Hk(hk_of(&x.hk)?),
        W::EventInfo(x) => TmBody::Event(event_of(subservice, &x.event, d)?),
        W::EventLow(x) => TmBody::Event(event_of(subservice, &x.event, d)?),
        W::EventMedium(x) => TmBody::Event(event_of(subservice, &x.event, d)?),
        W::EventHigh(x) => TmBody::Event(event_of(subservice, &x.event, d)?),
        W::DisabledEvents(x) => TmBody::DisabledEvents {
            events: x.events.iter().map(|e| e.event_id).collect(),
        },
        W::TimeReport(x) => TmBody::TimeReport {
            rate_exp: x.rate_exp,
            time: CdsShort::from_wire(&x.time),
        },
        W::MonDefinitions(x) => TmBody::MonDefinitions {
            monitors: x
                .monitors
                .iter()
                .map(|m| MonDefinition {
                    id: m.monitor_id,
                    param: m.param,
                    enabled: m.enabled != 0,
                    low: m.low,
                    high: m.high,
                    persistence: m.persistence,
                    event: m.event,
                })
                .collect(),
        },
        W::MonTransition(x) => TmBody::MonTransition {
            monitor: x.monitor_id,
            param: x.param,
            value: x.value,
            limit: x.limit,
            state: x.state,
        },
        W::StoreDownlinkDone(x) => TmBody::StoreDownlinkDone {
            packets: x.packets,
            oldest_time: CdsShort::from_wire(&x.oldest_time),
            oldest_seq: x.oldest_seq,
            overwritten: x.overwritten,
        },
        W::PingReply(_) => TmBody::PingReply,
        W::EaDefinitions(x) => TmBody::EaDefinitions {
            links: x
                .links
                .iter()
                .map(|l| EaDefinition {
                    event: l.event,
                    enabled: l.enabled != 0,
                    mode: l.mode,
                    deferred: l.deferred != 0,
                })
                .collect(),
        },
        W::ParamValue(x) => TmBody::ParamValue {
            param: x.param_id,
            value: x.value,
        },
        W::ModeReply(x) => TmBody::ModeReply {
            node: x.node,
            mode: x.mode,
            submode: x.submode,
        },
        W::ModeCantReach(x) => TmBody::ModeCantReach {
            node: x.node,
            mode: x.mode,
            submode: x.submode,
            reason: x.reason,
        },
        // TM[210,3] (docs/modules.md): checked, then kept as bytes until the ground has a module
        // view (`mib::modules::report::ModuleReport::parse` rebuilds the set).
        W::ModuleReport(_) => TmBody::Unknown { data: d.to_vec() },
        W::PlanStatus(x) => TmBody::PlanStatus {
            plan_id: x.plan_id,
            state: x.state,
            steps: x.steps,
            next_step: x.next_step,
            done: x.done,
            wait_robot: x.wait_robot,
            wait_step: x.wait_step,
        },
        W::TeamStatus(x) => TmBody::TeamStatus {
            term: x.term,
            role: x.role,
            leader: x.leader,
            ground_seen: x.ground_seen != 0,
            lease: x.lease != 0,
            voted_for: x.voted_for,
            auth_plan: x.auth_plan,
            auth_first_step: x.auth_first_step,
            auth_steps: x.auth_steps,
            auth_left_s: x.auth_left_s,
            refused: x.refused,
            foreign: x.foreign,
            roster: x.roster.iter().map(|r| r.robot).collect(),
        },
    })
}

fn event_of(subservice: u8, e: &mib_wire::Event, d: &[u8]) -> Result<Event, DecodeError> {
    let Some(def) = mib::events::by_id(e.id()) else {
        return Err(data_err(format!("event ID 0x{:04X} not in the MIB", e.id())));
    };
    if Some(def.severity) != Severity::from_subservice(subservice) {
        return Err(data_err(format!(
            "event {} has severity {} but came as TM[5,{subservice}]",
            def.name,
            def.severity.name()
        )));
    }
    Ok(Event {
        id: def.id,
        name: def.name,
        severity: def.severity.name(),
        fault: def.fault,
        description: def.desc,
        params: decode_fields(def.params, &d[2..]),
    })
}

/// The decoded values of a housekeeping report, in structure order.
fn hk_of(h: &mib_wire::Hk) -> Result<Hk, DecodeError> {
    let Some(def) = mib::hk::by_sid(h.sid()) else {
        return Err(data_err(format!(
            "housekeeping structure ID {} not in the MIB",
            h.sid()
        )));
    };
    let mut values = Vec::with_capacity(def.params.len());
    for id in def.params {
        let (Some(p), Some(raw)) = (mib::params::by_id(*id), h.get(*id)) else {
            return Err(data_err(format!("HK parameter {id} not in the MIB")));
        };
        values.push(HkValue {
            id: p.id,
            name: p.name,
            raw,
            eng: p.calib.eng(raw),
            unit: p.unit,
        });
    }
    Ok(Hk {
        sid: def.sid,
        name: def.name,
        values,
    })
}

/// Decodes TM[3,25] source data.
pub fn decode_hk(d: &[u8]) -> Result<Hk, DecodeError> {
    let r = mib_wire::tm::HkReport::parse(d).map_err(|e| data_err(format!("TM[3,25]: {e}")))?;
    hk_of(&r.hk)
}

/// Decodes one TC packet (CRC checked) and its arguments against the MIB.
pub fn decode_tc(b: &[u8]) -> Result<Tc, DecodeError> {
    let p = TcPacket::parse(b).map_err(header_err)?;
    let (service, subservice, app) = (p.service, p.subservice, p.app_data);
    let apid = p.primary.apid;
    let (function, data) = if service == service::FUNCTION && app.len() >= 2 {
        (Some(u16::from_be_bytes([app[0], app[1]])), &app[2..])
    } else {
        (None, app)
    };
    let def = mib::tc::lookup(service, subservice, function);
    let mut args = Vec::new();
    let mut arg_error = None;
    match def {
        Some(def) => match codec::decode_args(def, data) {
            Ok((vals, _rest)) => {
                args = def
                    .args
                    .iter()
                    .zip(vals.iter())
                    .map(|(a, v)| Field {
                        name: a.name.to_string(),
                        value: *v,
                    })
                    .collect();
                // The structure (variable part included) must follow the MIB too.
                if let Err(e) = mib_wire::Tc::parse(service, subservice, app) {
                    arg_error = Some(format!("{}: {e}", def.name));
                }
            }
            Err(e) => arg_error = Some(BuildError::Args { tc: def.name, err: e }.to_string()),
        },
        None => {
            arg_error = Some(match function {
                Some(f) => format!("function {f} not in the MIB"),
                None => format!("TC[{service},{subservice}] not in the MIB"),
            })
        }
    }
    Ok(Tc {
        apid,
        robot: mib::apid::apid_robot(apid),
        seq: p.primary.seq_count,
        service,
        subservice,
        ack: p.ack,
        source_id: p.source_id,
        name: def.map(|d| d.name),
        function,
        args,
        arg_error,
        len: p.primary.len,
    })
}
