//! One `[[step]]` table read into a [`RawStep`]: the keys common to every step, then the
//! keys of its action (a `command` step's arguments read as `ground send` reads them).

use std::ops::Range;

use mib::robot;
use toml::de::DeTable;

use super::values::{
    float_of, get, int_in, int_of, mode_value, pairs_value, req, side_value, state_value, string, unknown_keys, Cx, Tbl,
};
use super::Action;

pub(super) struct RawStep {
    pub(super) id: Option<String>,
    pub(super) robot: Option<u8>,
    pub(super) robot_span: Range<usize>,
    pub(super) action: Option<Action>,
    /// Span of the `from` value, when given explicitly.
    pub(super) from_given: Option<(u8, Range<usize>)>,
    pub(super) after: Vec<(String, Range<usize>)>,
    pub(super) timeout_s: Option<f64>,
    pub(super) confirm: bool,
    pub(super) span: Range<usize>,
    pub(super) action_span: Range<usize>,
}

const COMMON_KEYS: &[&str] = &["id", "robot", "action", "after", "timeout", "confirm", "note"];

fn action_keys(action: &str) -> Option<&'static [&'static str]> {
    Some(match action {
        "mode" => &["mode"],
        "reconfigure" => &["from", "to"],
        "bolt" | "unbolt" => &["side", "pairs"],
        "home" => &[],
        "wait" => &["seconds"],
        "move-arm" | "move-gripper" => &["side", "pwm"],
        "rotate-hip" => &["angle"],
        "bolt-pair" | "unbolt-pair" => &["side", "pair"],
        "command" => &["tc", "args"],
        _ => return None,
    })
}

const ACTIONS: &str =
    "mode, reconfigure, bolt, unbolt, home, wait, move-arm, move-gripper, rotate-hip, bolt-pair, unbolt-pair, command";

pub(super) fn parse_step(cx: &mut Cx, t: &Tbl<'_>, span: Range<usize>) -> RawStep {
    let mut rs = RawStep {
        id: None,
        robot: None,
        robot_span: span.clone(),
        action: None,
        from_given: None,
        after: Vec::new(),
        timeout_s: None,
        confirm: false,
        span: span.clone(),
        action_span: span.clone(),
    };
    if let Some(v) = req(cx, t, "id", span.clone(), "step") {
        if let Some(s) = string(cx, v, "id") {
            if s.is_empty() {
                cx.err(v.span(), "step `id` is empty");
            } else {
                rs.id = Some(s.to_string());
            }
        }
    }
    let what = rs.id.as_ref().map_or("step".to_string(), |i| format!("step \"{i}\""));
    if let Some(v) = req(cx, t, "robot", span.clone(), &what) {
        rs.robot_span = v.span();
        rs.robot = int_in(cx, v, "robot", mib::apid::ROBOT_MIN as i64, mib::apid::ROBOT_MAX as i64).map(|i| i as u8);
    }
    if let Some(v) = get(t, "after") {
        match v.get_ref().as_array() {
            Some(arr) => {
                for e in arr.iter() {
                    if let Some(s) = string(cx, e, "after") {
                        rs.after.push((s.to_string(), e.span()));
                    }
                }
            }
            None => {
                if let Some(s) = string(cx, v, "after") {
                    rs.after.push((s.to_string(), v.span()));
                }
            }
        }
    }
    if let Some(v) = get(t, "timeout") {
        match float_of(v.get_ref()) {
            Some(f) if f > 0.0 && f.is_finite() => rs.timeout_s = Some(f),
            _ => cx.err(v.span(), "`timeout` must be a positive number of seconds"),
        }
    }
    if let Some(v) = get(t, "confirm") {
        match v.get_ref().as_bool() {
            Some(b) => rs.confirm = b,
            None => cx.err(v.span(), "`confirm` must be true or false"),
        }
    }
    let Some(av) = req(cx, t, "action", span.clone(), &what) else {
        return rs;
    };
    rs.action_span = av.span();
    let Some(action) = string(cx, av, "action") else {
        return rs;
    };
    let Some(keys) = action_keys(action) else {
        cx.err(av.span(), format!("unknown action \"{action}\" (actions: {ACTIONS})"));
        return rs;
    };
    let mut allowed: Vec<&str> = COMMON_KEYS.to_vec();
    allowed.extend_from_slice(keys);
    unknown_keys(cx, t, &allowed, &format!("{what} ({action})"));
    let sp = span.clone();
    let need = |cx: &mut Cx, k: &str| req(cx, t, k, sp.clone(), &format!("{what} ({action})"));
    rs.action = match action {
        "mode" => need(cx, "mode")
            .and_then(|v| mode_value(cx, v))
            .map(|mode| Action::Mode { mode }),
        "reconfigure" => {
            if let Some(v) = get(t, "from") {
                if let Some(s) = state_value(cx, v, "from") {
                    rs.from_given = Some((s, v.span()));
                }
            }
            // `from` is filled in by the robot walk below when not given.
            need(cx, "to")
                .and_then(|v| state_value(cx, v, "to"))
                .map(|to| Action::Reconfigure {
                    from: rs.from_given.as_ref().map_or(robot::STATE_UNKNOWN, |f| f.0),
                    to,
                })
        }
        "bolt" | "unbolt" => {
            let side = need(cx, "side").and_then(|v| side_value(cx, v));
            let pairs = need(cx, "pairs").and_then(|v| pairs_value(cx, v));
            match (side, pairs) {
                (Some(side), Some(pairs)) if action == "bolt" => Some(Action::Bolt { side, pairs }),
                (Some(side), Some(pairs)) => Some(Action::Unbolt { side, pairs }),
                _ => None,
            }
        }
        "home" => Some(Action::Home),
        "wait" => need(cx, "seconds").and_then(|v| match float_of(v.get_ref()) {
            Some(s) if (0.0..=86_400.0).contains(&s) => Some(Action::Wait { seconds: s }),
            _ => {
                cx.err(v.span(), "`seconds` must be a number of seconds in 0..=86400");
                None
            }
        }),
        "move-arm" | "move-gripper" => {
            let side = need(cx, "side").and_then(|v| side_value(cx, v));
            let s = robot::servo::PWM_MIN_US as i64;
            let e = robot::servo::PWM_MAX_US as i64;
            let pwm = need(cx, "pwm")
                .and_then(|v| int_in(cx, v, "pwm", s, e))
                .map(|p| p as u16);
            match (side, pwm) {
                (Some(side), Some(pwm)) if action == "move-arm" => Some(Action::MoveArm { side, pwm }),
                (Some(side), Some(pwm)) => Some(Action::MoveGripper { side, pwm }),
                _ => None,
            }
        }
        "rotate-hip" => need(cx, "angle").and_then(|v| {
            let cal = mib::params::CAL_CDEG;
            let lo = cal.eng(robot::servo::HIP_MIN_CDEG as i64);
            let hi = cal.eng(robot::servo::HIP_MAX_CDEG as i64);
            match float_of(v.get_ref()) {
                Some(a) if (lo..=hi).contains(&a) => Some(Action::RotateHip {
                    angle_cdeg: cal.raw(a) as i16,
                }),
                _ => {
                    cx.err(v.span(), format!("`angle` must be degrees in {lo}..={hi}"));
                    None
                }
            }
        }),
        "bolt-pair" | "unbolt-pair" => {
            let side = need(cx, "side").and_then(|v| side_value(cx, v));
            let n = robot::bolter::PAIRS_PER_FACE as i64;
            let pair = need(cx, "pair")
                .and_then(|v| int_in(cx, v, "pair", 1, n))
                .map(|p| p as u8);
            match (side, pair) {
                (Some(side), Some(pair)) if action == "bolt-pair" => Some(Action::BoltPair { side, pair }),
                (Some(side), Some(pair)) => Some(Action::UnboltPair { side, pair }),
                _ => None,
            }
        }
        "command" => parse_command(cx, t, &what, span),
        _ => None,
    };
    rs
}

fn parse_command(cx: &mut Cx, t: &Tbl<'_>, what: &str, span: Range<usize>) -> Option<Action> {
    let v = req(cx, t, "tc", span, &format!("{what} (command)"))?;
    let name = string(cx, v, "tc")?;
    let def = match crate::ops::policy::tc_by_name(name) {
        Ok(def) => def,
        Err(e) => {
            cx.err(v.span(), format!("`tc`: {e}"));
            return None;
        }
    };
    if def.variable {
        cx.err(
            v.span(),
            format!("`tc`: {} has variable data and cannot be written in a plan", def.name),
        );
        return None;
    }
    let empty = DeTable::new();
    let (args_t, args_span) = match get(t, "args") {
        Some(a) => match a.get_ref().as_table() {
            Some(tb) => (tb, a.span()),
            None => {
                cx.err(a.span(), "`args` must be a table such as { sid = 1 }");
                return None;
            }
        },
        None => (&empty, v.span()),
    };
    // Names and values are read as `ground send` reads them (one reader, ops::policy):
    // numbers, or the argument's names in the MIB; a near miss gets a suggestion.
    use crate::ops::policy;
    let mut ok = true;
    for (k, _) in args_t.iter() {
        if !def.args.iter().any(|a| a.name == k.get_ref().as_ref()) {
            let e = policy::arg_by_name(def, k.get_ref())
                .err()
                .map_or_else(|| format!("write `{}` in lower case", k.get_ref()), |e| e.to_string());
            cx.err(k.span(), e);
            ok = false;
        }
    }
    let mut vals = Vec::new();
    for a in def.args {
        match get(args_t, a.name) {
            Some(av) => {
                let text = match (int_of(av.get_ref()), av.get_ref().as_str()) {
                    (Some(i), _) => Some(i.to_string()),
                    (None, Some(s)) => Some(s.to_string()),
                    (None, None) => None,
                };
                let parsed = match text {
                    Some(t) => policy::parse_value(def, a, &t).map_err(|e| e.to_string()),
                    None => Err(format!(
                        "`{}` must be an integer or a name, found {}",
                        a.name,
                        av.get_ref().type_str()
                    )),
                };
                match parsed {
                    Ok(i) => vals.push(i),
                    Err(e) => {
                        cx.err(av.span(), e);
                        ok = false;
                    }
                }
            }
            None => {
                cx.err(
                    args_span.clone(),
                    format!("{}: missing argument `{}`", def.name, a.name),
                );
                ok = false;
            }
        }
    }
    ok.then(|| Action::Command {
        tc: def.name.to_string(),
        args: vals,
    })
}
