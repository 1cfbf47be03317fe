//! What the page needs from the MIB: TC forms (arguments, ranges, enumerations and
//! hazard, all as the MIB defines them), parameters (units, limits), events, configuration states and the mode tree.
//! Argument checking for `POST /api/tc` lives here too, so the page and the server
//! check against the same table.

use mib::tc::{ArgDef, TcDef};
use serde_json::{json, Map, Value};

/// Why a TC is hazardous (the MIB's `TcDef::hazard`), or `None` if it is not.
pub fn hazard(def: &TcDef) -> Option<&'static str> {
    def.hazard
}

/// Named values of an argument within its range, when the MIB names its values.
pub fn enumeration(arg: &ArgDef) -> Option<Vec<(i64, String)>> {
    if arg.names.is_none() {
        return None;
    }
    let mut list = Vec::new();
    arg.names.for_each(|v, n| {
        if (arg.min..=arg.max).contains(&v) {
            list.push((v, n.to_string()));
        }
    });
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
            Value::String(s) => match a.names.value_of(s) {
                Some(v) => v,
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
        if let Some(e) = enumeration(a) {
            if !e.iter().any(|(v, _)| *v == raw) {
                return Err(format!("{}: argument \"{}\" = {raw} names no value", def.name, a.name));
            }
        }
        out.push(raw);
    }
    Ok(out)
}

/// The MIB as the page uses it.
/// When the limits of `p` apply, in words ("" when always): the MIB's root modes and
/// condition (`limits_in`, `limits_if`), as the page shows beside the limits.
fn applies(p: &mib::params::ParamDef) -> String {
    let mut w = Vec::new();
    if p.limits_in != mib::modes::ModeSet::ALL {
        w.push(format!("in {}", p.limits_in.names()));
    }
    if let Some(c) = p.limits_if() {
        w.push(format!("if {}", c.desc));
    }
    w.join(", ")
}

pub fn page_mib() -> Value {
    let tcs: Vec<Value> = mib::tc::TCS
        .iter()
        .map(|t| {
            let args: Vec<Value> = t
                .args
                .iter()
                .map(|a| {
                    json!({"name": a.name, "type": a.ptype.name(), "unit": a.unit, "min": a.min, "max": a.max,
                        "desc": a.desc, "enum": enumeration(a)})
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
            // Value names the MIB lists (module configuration, states of small sets);
            // modes, states and events are named by the page from their own tables.
            let names: Option<Vec<(i64, &str)>> = match p.names() {
                mib::layout::Names::List(l) => Some(l.to_vec()),
                _ => None,
            };
            json!({"id": p.id, "name": p.name, "unit": p.unit, "desc": p.desc, "hk": hk,
                "scale": p.calib.scale, "offset": p.calib.offset, "names": names,
                "limits": p.limits.map(|l| json!({"soft_lo": l.soft_lo, "soft_hi": l.soft_hi,
                    "hard_lo": l.hard_lo, "hard_hi": l.hard_hi, "applies": applies(p)}))})
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
    // The on-board plan panel's buttons: each control, its TC and the plan states it is
    // accepted in (`crate::onboard::PlanControl`).
    let plan_controls: Vec<Value> = crate::onboard::PlanControl::ALL
        .iter()
        .map(|c| json!({"control": c.word(), "tc": c.tc_name(), "states": c.states()}))
        .collect();
    json!({"tcs": tcs, "params": params, "events": events, "states": states, "nodes": nodes, "faces": faces,
        "failures": failures, "plan_controls": plan_controls})
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

    // verifies: GND-07
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

    // verifies: MMIC-CMD-06
    #[test]
    fn hazard_and_enumerations_come_from_the_mib() {
        let h = |n| hazard(mib::tc::by_name(n).unwrap());
        assert!(h("PING").is_none());
        assert!(h("RECONFIGURE").is_none());
        assert!(h("UNBOLT_FACE").is_some());
        assert!(h("MOVE_GRIPPER").is_some());
        assert!(h("MODE_SET").is_some());
        assert!(h("STORE_DELETE").is_some());
        let m = page_mib();
        for (t, pt) in mib::tc::TCS.iter().zip(m["tcs"].as_array().into_iter().flatten()) {
            assert_eq!(pt["hazard"].as_str(), t.hazard, "{}", t.name);
        }
        let mode = mib::tc::by_name("MODE_SET").unwrap();
        let names = enumeration(&mode.args[1]).unwrap();
        assert_eq!(
            names,
            [
                (0, "STANDBY".to_string()),
                (1, "OPERATIONAL".to_string()),
                (2, "SAFED".to_string())
            ]
        );
        let side = enumeration(&mib::tc::by_name("BOLT_PAIR").unwrap().args[0]).unwrap();
        assert_eq!(side, [(0, "A".to_string()), (1, "B".to_string())]);
        let mon = mib::tc::by_name("MON_DISABLE").unwrap();
        assert_eq!(
            enumeration(&mon.args[0]).map(|e| e.len()),
            Some(mib::fdir::MONITORS.len())
        );
        assert_eq!(
            parse_args(mon, &obj(json!({"monitor_id": mib::fdir::MONITORS[0].name}))),
            Ok(vec![i64::from(mib::fdir::MONITORS[0].id)])
        );
        let events = enumeration(&mib::tc::by_name("EVENT_DISABLE").unwrap().args[0]).unwrap();
        assert!(
            events.iter().all(|(v, _)| *v != 0),
            "NONE (0) is outside the argument's range"
        );
        assert!(enumeration(&mib::tc::by_name("BOLT_PAIR").unwrap().args[1]).is_none());
    }

    // verifies: GND-07
    #[test]
    fn every_tc_of_the_mib_appears_in_the_page_mib() {
        let m = page_mib();
        assert_eq!(m["tcs"].as_array().map(Vec::len), Some(mib::tc::TCS.len()));
        assert_eq!(m["params"].as_array().map(Vec::len), Some(mib::params::PARAMS.len()));
    }

    // verifies: ALM-COND-01
    #[test]
    fn the_page_mib_says_when_limits_apply() {
        let m = page_mib();
        let lim = |name: &str| {
            m["params"]
                .as_array()
                .unwrap()
                .iter()
                .find(|p| p["name"] == name)
                .unwrap()["limits"]["applies"]
                .clone()
        };
        assert_eq!(lim("HIP_DEVIATION"), "if no motion primitive running");
        assert_eq!(lim("V_REG"), "in operational, safed");
        assert_eq!(lim("V_BAT_A"), "");
    }
}
