//! The whole MIB as one JSON document (pretty-printed, keys in a stable order).

use super::headers::{self, HeaderField};
use mib::events::EVENTS;
use mib::failure::FailureCode;
use mib::fdir::{self, Timing, FAULTS, MONITORS};
use mib::hk::{self, HK_STRUCTS};
use mib::modes::{self, NODES};
use mib::params::PARAMS;
use mib::robot::{self, PRIMITIVES, RECONFIG_MAP, STATES};
use mib::tc::{TCS, TMS};
use mib::tunables::TUNABLES;
use mib::types::Limits;
use mib::{apid, config};
use serde_json::{json, Value};

fn fields(f: &[HeaderField]) -> Value {
    Value::Array(
        headers::offsets(f)
            .map(
                |(off, f)| json!({"name": f.name, "bit_offset": off, "bits": f.bits, "fixed": f.fixed, "desc": f.desc}),
            )
            .collect(),
    )
}

fn limits(l: &Option<&Limits>) -> Value {
    match l {
        Some(l) => json!({"soft_lo": l.soft_lo, "soft_hi": l.soft_hi, "hard_lo": l.hard_lo, "hard_hi": l.hard_hi}),
        None => Value::Null,
    }
}

/// Named values of a TC argument within its range (`null` for a plain number).
fn arg_names(a: &mib::tc::ArgDef) -> Value {
    if a.names.is_none() {
        return Value::Null;
    }
    let mut v = Vec::new();
    a.names.for_each(|raw, name| {
        if (a.min..=a.max).contains(&raw) {
            v.push(json!({"value": raw, "name": name}));
        }
    });
    Value::Array(v)
}

fn timing(t: Timing) -> &'static str {
    match t {
        Timing::Immediate => "immediate",
        Timing::AfterMotion => "after_motion",
    }
}

/// Part of the document: the MIB version, the APID rule, the configuration numbers and the header layouts.
fn identity() -> Value {
    json!({
        "mib_version": env!("CARGO_PKG_VERSION"),
        "apid": {
            "base": apid::APID_BASE,
            "robot_min": apid::ROBOT_MIN,
            "robot_max": apid::ROBOT_MAX,
            "default_robot": apid::DEFAULT_ROBOT,
            "idle_apid": apid::IDLE_APID,
            "rule": "APID of robot N = base + N",
        },
        // Flight numbers (`mib::config`) apart from the ground's (`mib::ground_config`) and
        // the host binary's (`mib::host_config`): a reader sees which side a number binds.
        "config": {
            "flight": {
                "control_period_ms": config::CONTROL_PERIOD_MS,
                "moving_average_window": config::MOVING_AVERAGE_WINDOW,
                "b_heartbeat_period_ms": config::B_HEARTBEAT_PERIOD_MS,
                "ab_link_baud": config::AB_LINK_BAUD,
                "timestamp_len": config::TIMESTAMP_LEN,
                "max_packet_len": config::MAX_PACKET_LEN,
                "max_tc_app_data": config::MAX_TC_APP_DATA,
                "ground_id": config::GROUND_ID,
                "tm_queue_depth": config::TM_QUEUE_DEPTH,
                "tm_store_capacity": config::TM_STORE_CAPACITY,
                "schedule_capacity": config::SCHEDULE_CAPACITY,
                "duplicate_window": config::DUPLICATE_WINDOW,
                "action_queue_depth": config::ACTION_QUEUE_DEPTH,
                "max_reconfig_primitives": config::MAX_RECONFIG_PRIMITIVES,
            },
            "ground": {
                "ground_ack_timeout_ms": mib::ground_config::GROUND_ACK_TIMEOUT_MS,
                "ground_ping_period_ms": mib::ground_config::GROUND_PING_PERIOD_MS,
                "link_quality_window": mib::ground_config::LINK_QUALITY_WINDOW,
                "ground_max_resends": mib::ground_config::GROUND_MAX_RESENDS,
            },
            "host": {
                "default_port": mib::host_config::DEFAULT_PORT,
            },
        },
        "packet_layout": {
            "primary_header": fields(headers::PRIMARY_HEADER),
            "tm_secondary_header": fields(headers::TM_SEC_HEADER),
            "tc_secondary_header": fields(headers::TC_SEC_HEADER),
            "pec": fields(&[headers::PEC]),
            "tm_source_data_offset": headers::tm_source_data_offset(),
            "tc_app_data_offset": headers::tc_app_data_offset(),
        },
    })
}

/// Part of the document: parameters, housekeeping structures, events and failure codes.
fn parameters_and_events() -> Value {
    json!({
        "parameters": PARAMS.iter().map(|p| json!({
            "id": p.id, "name": p.name, "type": p.ptype.name(), "unit": p.unit,
            "calibration": {"scale": p.calib.scale, "offset": p.calib.offset},
            "limits": limits(&p.limits),
            "limits_in": p.limits.map(|_| p.limits_in.names()), "limits_in_mask": p.limits.map(|_| p.limits_in.0),
            "limits_if": p.limits.and(p.limits_if()).map(|c| json!({
                "param": c.param, "param_name": mib::params::by_id(c.param).map(|q| q.name),
                "raw": c.raw, "desc": c.desc,
            })),
            "limit_persistence": p.limits.map(|_| mib::params::GROUND_LIMIT_PERSISTENCE),
            "desc": p.desc,
        })).collect::<Vec<_>>(),
        "hk_structures": HK_STRUCTS.iter().map(|h| json!({
            "sid": h.sid, "name": h.name, "params": h.params, "data_len": h.data_len(),
            "default_interval_ms": h.default_interval_ms, "default_enabled": h.default_enabled,
            "desc": h.desc,
        })).collect::<Vec<_>>(),
        "hk_interval_ms": {"min": hk::MIN_INTERVAL_MS, "max": hk::MAX_INTERVAL_MS},
        "events": EVENTS.iter().map(|e| json!({
            "id": e.id, "name": e.name, "severity": e.severity.name(),
            "subservice": e.severity.subservice(), "fault": e.fault,
            "params": e.params.iter().map(|p| json!({"name": p.name, "type": p.ptype.name()})).collect::<Vec<_>>(),
            "data_len": e.data_len(), "desc": e.desc,
        })).collect::<Vec<_>>(),
        "failure_codes": FailureCode::ALL.iter().map(|c| json!({
            "code": c.code(), "name": c.name(), "data": crate::text::fields_summary(c.data()), "desc": c.description(),
        })).collect::<Vec<_>>(),
    })
}

/// Part of the document: telecommands and TM reports.
fn commands_and_reports() -> Value {
    json!({
        "telecommands": TCS.iter().map(|t| json!({
            "service": t.service, "subservice": t.subservice, "function": t.function,
            "name": t.name,
            "args": t.args.iter().map(|a| json!({
                "name": a.name, "type": a.ptype.name(), "unit": a.unit, "min": a.min, "max": a.max, "desc": a.desc,
                "names": arg_names(a),
            })).collect::<Vec<_>>(),
            "variable": t.variable, "modes": t.modes.names(), "mode_mask": t.modes.0,
            "long_running": t.long_running, "hazard": t.hazard,
            "failures": t.failures.iter().map(|f| f.name()).collect::<Vec<_>>(),
            "fixed_len": t.fixed_len(), "desc": t.description().to_string(),
            "report": t.report.map(|r| json!({"service": r.service, "subservice": r.subservice, "name": r.name})),
        })).collect::<Vec<_>>(),
        "acceptance_failures": mib::tc::ACCEPTANCE_FAILURES.iter().map(|f| f.name()).collect::<Vec<_>>(),
        "telemetry": TMS.iter().map(|t| json!({
            "service": t.service, "subservice": t.subservice, "name": t.name, "layout": crate::text::summary(t.body), "desc": t.desc,
        })).collect::<Vec<_>>(),
    })
}

/// Part of the document: the mode tree, configuration states, primitives and the servo and bolter numbers.
fn modes_and_motion() -> Value {
    let root_modes: Vec<u32> = [
        modes::robot_mode::STANDBY,
        modes::robot_mode::OPERATIONAL,
        modes::robot_mode::SAFED,
    ]
    .to_vec();
    json!({
        "mode_tree": {
            "nodes": NODES.iter().map(|n| json!({
                "id": n.id, "name": n.name, "parent": n.parent, "kind": format!("{:?}", n.kind),
                "modes": (0..3).filter_map(|m| modes::mode_name(n.kind, m).map(|s| json!({"mode": m, "name": s}))).collect::<Vec<_>>(),
                "mode_per_root_mode": root_modes.iter().map(|r| json!({
                    "root_mode": r,
                    "mode": if n.parent.is_none() { *r } else { modes::child_mode(*r, n.kind) },
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "submodes": {"idle": modes::submode::IDLE, "busy": modes::submode::BUSY},
        },
        "states": STATES.iter().map(|s| json!({
            "id": s.id, "label": s.label.to_string(), "name": s.name, "a": s.a.name(), "b": s.b.name(),
            "kind": s.kind().name(), "hip_cdeg": s.hip_cdeg(), "arm_pwm_us": s.arm_pwm(),
        })).collect::<Vec<_>>(),
        "state_unknown": robot::STATE_UNKNOWN,
        "primitives": PRIMITIVES.iter().map(|p| json!({
            "id": p.id, "name": p.name, "moving": p.moving.name(), "motion": format!("{:?}", p.motion),
        })).collect::<Vec<_>>(),
        "reconfig_map": RECONFIG_MAP.iter().map(|r| r.to_vec()).collect::<Vec<_>>(),
        "servo": {
            "arm_contracted_us": robot::servo::ARM_CONTRACTED_US,
            "arm_turn_us": robot::servo::ARM_TURN_US,
            "arm_extended_us": robot::servo::ARM_EXTENDED_US,
            "grip_closed_us": robot::servo::GRIP_CLOSED_US,
            "grip_open_us": robot::servo::GRIP_OPEN_US,
            "pwm_min_us": robot::servo::PWM_MIN_US,
            "pwm_max_us": robot::servo::PWM_MAX_US,
            "servo_speed_us_per_s": robot::servo::SERVO_SPEED_US_PER_S,
            "hip_min_cdeg": robot::servo::HIP_MIN_CDEG,
            "hip_max_cdeg": robot::servo::HIP_MAX_CDEG,
            "hip_home_cdeg": robot::servo::HIP_HOME_CDEG,
            "hip_speed_cdeg_s": robot::servo::HIP_SPEED_CDEG_S,
            "hip_switch_cdeg": robot::servo::HIP_SWITCH_CDEG,
            "hip_done_cdeg": robot::servo::HIP_DONE_CDEG,
        },
        "bolter": {
            "pairs_per_face": robot::bolter::PAIRS_PER_FACE,
            "demo_pairs": robot::bolter::DEMO_PAIRS,
            "demo_first": robot::bolter::DEMO_FIRST,
            "demo_second": robot::bolter::DEMO_SECOND,
            "demo_third": robot::bolter::DEMO_THIRD,
            "demo_failed": robot::bolter::DEMO_FAILED,
        },
    })
}

/// Part of the document: FDIR (faults, monitors, event-action links) and tunable parameters.
fn fdir_and_tunables() -> Value {
    json!({
        "fdir": {
            "faults": FAULTS.iter().map(|f| json!({
                "bit": f.bit, "event": f.event, "mode": f.mode, "timing": timing(f.timing),
            })).collect::<Vec<_>>(),
            "monitors": MONITORS.iter().map(|m| json!({
                "id": m.id, "name": m.name, "param": m.param, "low": m.low, "high": m.high,
                "persistence": m.persistence, "event": m.event, "phase": m.phase.name(), "enabled": m.enabled,
            })).collect::<Vec<_>>(),
            "event_actions": FAULTS.iter().filter_map(|f| fdir::action_for(f.event)).map(|a| json!({
                "event": a.event, "mode": a.mode, "timing": timing(a.timing), "enabled": a.enabled,
            })).collect::<Vec<_>>(),
        },
        "tunables": TUNABLES.iter().map(|t| json!({
            "id": t.id, "name": t.name, "unit": t.unit, "default": t.default, "min": t.min, "max": t.max, "desc": t.desc,
        })).collect::<Vec<_>>(),
    })
}

/// Every public numeric constant of the MIB by module path (`"config"`, `"team"`,
/// `"link::sdls"`): its value and its doc comment. Generated by the build script from the
/// MIB's sources, so a new constant cannot be left out.
fn constants() -> Value {
    let mut by_module = serde_json::Map::new();
    for (module, name, value, desc) in generated::constants() {
        let m = by_module.entry(module).or_insert_with(|| json!({}));
        if let Value::Object(m) = m {
            m.insert(name.to_string(), json!({"value": value, "desc": desc}));
        }
    }
    json!({ "constants": by_module })
}

mod generated {
    include!(concat!(env!("OUT_DIR"), "/constants.rs"));
}

/// The whole MIB as pretty-printed JSON.
pub fn json_document() -> String {
    let mut doc = serde_json::Map::new();
    for part in [
        identity(),
        parameters_and_events(),
        commands_and_reports(),
        modes_and_motion(),
        fdir_and_tunables(),
        constants(),
    ] {
        if let Value::Object(m) = part {
            doc.extend(m);
        }
    }
    let doc = Value::Object(doc);
    let mut s = serde_json::to_string_pretty(&doc).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    s.push('\n');
    s
}
