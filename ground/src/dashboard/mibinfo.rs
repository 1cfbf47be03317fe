//! What the page needs from the MIB: TC forms (arguments, ranges, enumerations,
//! hazard), parameters (units, limits), events, configuration states and the mode tree.
//! Argument checking for `POST /api/tc` lives here too, so the page and the server
//! check against the same table.

use mib::tc::{ArgDef, TcDef};
use serde_json::{json, Map, Value};

/// Why a TC is hazardous, or `None` if it is not.
///
/// The MIB has no hazard flag yet, so this is derived here from the TC definition —
/// the one place to replace when the MIB gains one. A TC is hazardous when it:
/// - can leave the robot less attached to the structure (unbolting, opening a
///   gripper, moving an arm or the hip directly, outside the reconfiguration planner);
/// - forces a fault or a mode change (module power);
/// - destroys on-board data (store, schedule) or weakens on-board protection
///   (disables monitors, event actions, events, housekeeping; changes parameters).
pub fn hazard(def: &TcDef) -> Option<&'static str> {
    use mib::tc::{function as f, service as s};
    if def.service == s::FUNCTION {
        return match def.function {
            f::UNBOLT_FACE | f::UNBOLT_PAIR => Some("removes fasteners: the structure loses a joint"),
            f::MOVE_GRIPPER => Some("opening a gripper can detach the robot from the structure"),
            f::MOVE_ARM | f::ROTATE_HIP => Some("direct actuator motion outside the reconfiguration planner"),
            f::ASSEMBLY_FAULT => Some("forces an assembly system fault: the robot goes to standby"),
            _ => None,
        };
    }
    match (def.service, def.name) {
        (s::MODE, "MODE_SET") => Some("changes module power (standby releases the servos)"),
        (s::STORAGE, "STORE_DELETE" | "STORE_DISABLE") => Some("on-board TM store: packets are lost for good"),
        (s::SCHEDULING, "SCHED_RESET") => Some("deletes every scheduled TC"),
        (s::MONITORING, "MON_DISABLE" | "MON_MODIFY") => Some("weakens on-board limit monitoring (FDIR)"),
        (s::EVENT_ACTION, "EA_DISABLE") => Some("disables an on-board fault reaction (FDIR)"),
        (s::EVENT, "EVENT_DISABLE") => Some("hides an event from the ground"),
        (s::HOUSEKEEPING, "HK_DISABLE") => Some("stops a housekeeping report"),
        (s::PARAMETER, "PARAM_SET") => Some("changes an on-board threshold or gain"),
        _ => None,
    }
}

/// Named values of an argument, when its values have names in the MIB.
pub fn enumeration(def: &TcDef, arg: &ArgDef) -> Option<Vec<(i64, String)>> {
    use mib::robot::{Side, STATES};
    let list: Vec<(i64, String)> = match (def.name, arg.name) {
        (_, "side") => [Side::A, Side::B]
            .iter()
            .map(|s| (*s as i64, format!("side {}", s.name())))
            .collect(),
        ("RECONFIGURE", "from" | "to") => STATES.iter().map(|s| (s.id as i64, s.name.to_string())).collect(),
        ("MODE_SET", "mode") => (arg.min..=arg.max)
            .filter_map(|m| {
                let mode = u32::try_from(m).ok()?;
                mib::modes::mode_name(mib::modes::NodeKind::Root, mode).map(|n| (m, n.to_string()))
            })
            .collect(),
        (_, "node") => mib::modes::NODES
            .iter()
            .map(|n| (n.id as i64, n.name.to_string()))
            .collect(),
        (_, "sid") => mib::hk::HK_STRUCTS
            .iter()
            .map(|h| (h.sid as i64, h.name.to_string()))
            .collect(),
        (_, "event_id") => mib::events::EVENTS
            .iter()
            .map(|e| (e.id as i64, e.name.to_string()))
            .collect(),
        ("PARAM_SET" | "PARAM_REPORT", "param_id") => mib::tunables::TUNABLES
            .iter()
            .map(|t| (t.id as i64, t.name.to_string()))
            .collect(),
        _ => return None,
    };
    Some(list)
}

/// Checks the page's arguments (`{"name": number or enumeration name}`) against the
/// MIB and returns the raw values in MIB order.
pub fn parse_args(def: &TcDef, args: &Map<String, Value>) -> Result<Vec<i64>, String> {
    if def.variable {
        return Err(format!(
            "{} carries variable data (embedded TCs) and cannot be sent from the page",
            def.name
        ));
    }
    for k in args.keys() {
        if !def.args.iter().any(|a| a.name == k) {
            return Err(format!("{} has no argument \"{k}\"", def.name));
        }
    }
    let mut out = Vec::with_capacity(def.args.len());
    for a in def.args {
        let v = args
            .get(a.name)
            .ok_or_else(|| format!("{}: argument \"{}\" missing", def.name, a.name))?;
        let raw = match v {
            Value::Number(n) => n
                .as_i64()
                .ok_or_else(|| format!("{}: argument \"{}\" must be an integer, not {n}", def.name, a.name))?,
            Value::String(s) => match enumeration(def, a).and_then(|e| e.into_iter().find(|(_, n)| n == s)) {
                Some((v, _)) => v,
                None => s
                    .trim()
                    .parse::<i64>()
                    .map_err(|_| format!("{}: argument \"{}\": \"{s}\" is not a value of it", def.name, a.name))?,
            },
            Value::Bool(b) => i64::from(*b),
            Value::Null | Value::Array(_) | Value::Object(_) => {
                return Err(format!("{}: argument \"{}\" must be a number", def.name, a.name))
            }
        };
        if raw < a.min || raw > a.max {
            return Err(format!(
                "{}: argument \"{}\" = {raw} is outside {}..={}",
                def.name, a.name, a.min, a.max
            ));
        }
        if let Some(e) = enumeration(def, a) {
            if !e.iter().any(|(v, _)| *v == raw) {
                return Err(format!("{}: argument \"{}\" = {raw} names no value", def.name, a.name));
            }
        }
        out.push(raw);
    }
    Ok(out)
}

/// The MIB as the page uses it.
pub fn page_mib() -> Value {
    let tcs: Vec<Value> = mib::tc::TCS
        .iter()
        .map(|t| {
            let args: Vec<Value> = t
                .args
                .iter()
                .map(|a| {
                    json!({"name": a.name, "type": a.ptype.name(), "unit": a.unit, "min": a.min, "max": a.max,
                        "desc": a.desc, "enum": enumeration(t, a)})
                })
                .collect();
            json!({"name": t.name, "service": t.service, "subservice": t.subservice, "function": t.function,
                "args": args, "variable": t.variable, "modes": t.modes.names(), "long_running": t.long_running,
                "hazard": hazard(t), "desc": t.desc})
        })
        .collect();
    let params: Vec<Value> = mib::params::PARAMS
        .iter()
        .map(|p| {
            let hk = mib::hk::HK_STRUCTS
                .iter()
                .find(|h| h.params.contains(&p.id))
                .map(|h| h.name);
            json!({"id": p.id, "name": p.name, "unit": p.unit, "desc": p.desc, "hk": hk,
                "scale": p.calib.scale, "offset": p.calib.offset,
                "limits": p.limits.map(|l| json!({"soft_lo": l.soft_lo, "soft_hi": l.soft_hi,
                    "hard_lo": l.hard_lo, "hard_hi": l.hard_hi}))})
        })
        .collect();
    let events: Vec<Value> = mib::events::EVENTS
        .iter()
        .map(|e| json!({"id": e.id, "name": e.name, "severity": e.severity.name(), "fault": e.fault, "desc": e.desc}))
        .collect();
    let states: Vec<Value> = mib::robot::STATES
        .iter()
        .map(|s| json!({"id": s.id, "name": s.name, "kind": s.kind().name(), "a": s.a.name(), "b": s.b.name()}))
        .collect();
    let nodes: Vec<Value> = mib::modes::NODES
        .iter()
        .map(|n| json!({"id": n.id, "name": n.name, "parent": n.parent.and_then(mib::modes::node_by_id).map(|p| p.name)}))
        .collect();
    let faces: Vec<Value> = mib::robot::Face::ALL
        .iter()
        .map(|f| json!({"name": f.name(), "normal": [f.inward_normal().0, f.inward_normal().1]}))
        .collect();
    let failures: Vec<Value> = mib::FailureCode::ALL
        .iter()
        .map(|f| json!({"code": f.code(), "name": f.name(), "desc": f.description()}))
        .collect();
    json!({"tcs": tcs, "params": params, "events": events, "states": states, "nodes": nodes, "faces": faces,
        "failures": failures})
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(v: Value) -> Map<String, Value> {
        match v {
            Value::Object(m) => m,
            _ => Map::new(),
        }
    }

    #[test]
    fn args_are_checked_against_mib_ranges_and_enumerations() {
        let rec = mib::tc::by_name("RECONFIGURE").unwrap();
        let from = mib::robot::STATES[0].name;
        let to = mib::robot::STATES[3].name;
        assert_eq!(parse_args(rec, &obj(json!({"from": from, "to": to}))), Ok(vec![0, 3]));
        assert!(parse_args(rec, &obj(json!({"from": 0, "to": 99})))
            .unwrap_err()
            .contains("outside"));
        assert!(parse_args(rec, &obj(json!({"from": 0})))
            .unwrap_err()
            .contains("missing"));
        assert!(parse_args(rec, &obj(json!({"from": 0, "to": 1, "x": 1})))
            .unwrap_err()
            .contains("no argument"));
        let ping = mib::tc::by_name("PING").unwrap();
        assert_eq!(parse_args(ping, &Map::new()), Ok(vec![]));
        let mode = mib::tc::by_name("MODE_SET").unwrap();
        assert_eq!(
            parse_args(
                mode,
                &obj(json!({"node": "ROBOT", "mode": "OPERATIONAL", "submode": 0}))
            ),
            Ok(vec![1, 1, 0])
        );
    }

    #[test]
    fn hazard_marks_motion_that_detaches_and_leaves_ping_alone() {
        let h = |n| hazard(mib::tc::by_name(n).unwrap());
        assert!(h("PING").is_none());
        assert!(h("RECONFIGURE").is_none());
        assert!(h("UNBOLT_FACE").is_some());
        assert!(h("MOVE_GRIPPER").is_some());
        assert!(h("MODE_SET").is_some());
        assert!(h("STORE_DELETE").is_some());
    }

    #[test]
    fn every_tc_of_the_mib_appears_in_the_page_mib() {
        let m = page_mib();
        assert_eq!(m["tcs"].as_array().map(Vec::len), Some(mib::tc::TCS.len()));
        assert_eq!(m["params"].as_array().map(Vec::len), Some(mib::params::PARAMS.len()));
    }
}
