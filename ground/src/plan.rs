//! Plan files: parsing (TOML, every value with its span), validation against the MIB
//! (collecting every error, each with file:line:column), and encoding to TC streams.
//!
//! The document is read with `toml`'s span-preserving parser (`toml::de::DeTable`,
//! recoverable, so every syntax error is reported too) and converted by hand into the
//! typed [`Plan`], so that one bad value does not hide the others. See
//! `docs/plan-format.md` for the format.

use std::collections::{HashMap, HashSet, VecDeque};
use std::fmt;
use std::ops::Range;

use mib::modes::robot_mode;
use mib::robot::{self, NUM_STATES};
use mib::tc::{function, TcDef};
use serde::Serialize;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

use crate::pus::{self, BuiltTc, SeqCounters};

/// One problem found in a plan, located by a byte range of the source.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlanError {
    pub span: Range<usize>,
    pub message: String,
}

/// A [`PlanError`] placed in a file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Diagnostic {
    pub file: String,
    pub line: usize,
    pub column: usize,
    pub message: String,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: error: {}",
            self.file, self.line, self.column, self.message
        )
    }
}

/// 1-based line and column (in characters) of a byte offset.
pub fn line_col(src: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(src.len());
    let mut line = 1;
    let mut col = 1;
    for (i, c) in src.char_indices() {
        if i >= offset {
            break;
        }
        if c == '\n' {
            line += 1;
            col = 1;
        } else {
            col += 1;
        }
    }
    (line, col)
}

/// Places errors in `file`, sorted by position. One pass over the source for all errors
/// (linear in the source and the number of errors).
pub fn diagnostics(file: &str, src: &str, errors: &[PlanError]) -> Vec<Diagnostic> {
    let mut errs: Vec<&PlanError> = errors.iter().collect();
    errs.sort_by_key(|e| e.span.start);
    let mut out = Vec::with_capacity(errs.len());
    let (mut line, mut col) = (1usize, 1usize);
    let mut chars = src.char_indices().peekable();
    for e in errs {
        let offset = e.span.start.min(src.len());
        while let Some(&(i, c)) = chars.peek() {
            if i >= offset {
                break;
            }
            if c == '\n' {
                line += 1;
                col = 1;
            } else {
                col += 1;
            }
            chars.next();
        }
        out.push(Diagnostic {
            file: file.to_string(),
            line,
            column: col,
            message: e.message.clone(),
        });
    }
    out
}

/// A robot taking part in the plan.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct RobotDecl {
    pub number: u8,
    pub name: Option<String>,
    /// Ground's belief of the robot's state at the start of the plan.
    pub initial_state: Option<u8>,
    #[serde(skip)]
    pub span: Range<usize>,
}

/// What a step does.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "action", rename_all = "kebab-case")]
pub enum Action {
    /// TC[200,1] on the robot node.
    Mode {
        mode: u32,
    },
    Reconfigure {
        from: u8,
        to: u8,
    },
    Bolt {
        side: u8,
        pairs: u8,
    },
    Unbolt {
        side: u8,
        pairs: u8,
    },
    Home,
    /// A ground-side pause; no TC.
    Wait {
        seconds: f64,
    },
    MoveArm {
        side: u8,
        pwm: u16,
    },
    MoveGripper {
        side: u8,
        pwm: u16,
    },
    RotateHip {
        angle_cdeg: i16,
    },
    BoltPair {
        side: u8,
        pair: u8,
    },
    UnboltPair {
        side: u8,
        pair: u8,
    },
    /// Any TC of the MIB by name, with named arguments.
    Command {
        tc: String,
        args: Vec<i64>,
    },
}

impl Action {
    /// The TC this action sends (`None` for a wait).
    pub fn tc(&self) -> Option<(&'static TcDef, Vec<i64>)> {
        let f = |id| mib::tc::lookup(8, 1, Some(id));
        let r = match self {
            Action::Mode { mode } => (
                mib::tc::by_name("MODE_SET")?,
                vec![mib::modes::node::ROBOT as i64, *mode as i64, 0],
            ),
            Action::Reconfigure { from, to } => (f(function::RECONFIGURE)?, vec![*from as i64, *to as i64]),
            Action::Bolt { side, pairs } => (f(function::BOLT_FACE)?, vec![*side as i64, *pairs as i64]),
            Action::Unbolt { side, pairs } => (f(function::UNBOLT_FACE)?, vec![*side as i64, *pairs as i64]),
            Action::Home => (f(function::HOME)?, vec![]),
            Action::Wait { .. } => return None,
            Action::MoveArm { side, pwm } => (f(function::MOVE_ARM)?, vec![*side as i64, *pwm as i64]),
            Action::MoveGripper { side, pwm } => (f(function::MOVE_GRIPPER)?, vec![*side as i64, *pwm as i64]),
            Action::RotateHip { angle_cdeg } => (f(function::ROTATE_HIP)?, vec![*angle_cdeg as i64]),
            Action::BoltPair { side, pair } => (f(function::BOLT_PAIR)?, vec![*side as i64, *pair as i64]),
            Action::UnboltPair { side, pair } => (f(function::UNBOLT_PAIR)?, vec![*side as i64, *pair as i64]),
            Action::Command { tc, args } => (mib::tc::by_name(tc)?, args.clone()),
        };
        Some(r)
    }

    /// Short human description.
    pub fn describe(&self) -> String {
        match self {
            Action::Mode { mode } => format!("mode {}", pus::mode_name(mib::modes::node::ROBOT, *mode)),
            Action::Reconfigure { from, to } => {
                format!("reconfigure {} -> {}", state_name(*from), state_name(*to))
            }
            Action::Bolt { side, pairs } => format!("bolt side {} pairs {}", side_name(*side), pairs_list(*pairs)),
            Action::Unbolt { side, pairs } => {
                format!("unbolt side {} pairs {}", side_name(*side), pairs_list(*pairs))
            }
            Action::Home => "home".into(),
            Action::Wait { seconds } => format!("wait {seconds} s"),
            Action::MoveArm { side, pwm } => format!("move arm {} to {pwm} us", side_name(*side)),
            Action::MoveGripper { side, pwm } => format!("move gripper {} to {pwm} us", side_name(*side)),
            Action::RotateHip { angle_cdeg } => {
                format!("rotate hip to {:.2} deg", mib::params::CAL_CDEG.eng(*angle_cdeg as i64))
            }
            Action::BoltPair { side, pair } => format!("bolt pair {pair} side {}", side_name(*side)),
            Action::UnboltPair { side, pair } => format!("unbolt pair {pair} side {}", side_name(*side)),
            Action::Command { tc, args } => match mib::tc::by_name(tc) {
                Some(def) => {
                    let a: Vec<String> = def
                        .args
                        .iter()
                        .zip(args)
                        .map(|(d, v)| format!("{}={v}", d.name))
                        .collect();
                    format!("{} {}", def.name, a.join(" "))
                }
                None => format!("{tc} {args:?}"),
            },
        }
    }
}

/// Name of a configuration state ("Xneg Xpos"), or `#n`.
pub fn state_name(id: u8) -> String {
    robot::STATES
        .get(id as usize)
        .map_or_else(|| format!("#{id}"), |s| s.name.to_string())
}

fn side_name(s: u8) -> &'static str {
    robot::Side::from_u8(s).map_or("?", |s| s.name())
}

fn pairs_list(mask: u8) -> String {
    let v: Vec<String> = (0..robot::bolter::PAIRS_PER_FACE)
        .filter(|i| mask & (1 << i) != 0)
        .map(|i| (i + 1).to_string())
        .collect();
    v.join(",")
}

/// One step of a plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Step {
    pub id: String,
    pub robot: u8,
    #[serde(flatten)]
    pub action: Action,
    /// Dependencies written in the file.
    pub after: Vec<String>,
    /// Every step this one waits for (indices into `Plan::steps`): the explicit ones
    /// plus the previous step of the same robot.
    pub deps: Vec<usize>,
    /// Longest wait for completion, seconds (`None`: the run's default).
    pub timeout_s: Option<f64>,
    /// `confirm = true`: the operator confirms the step's hazardous TC (the MIB's
    /// `hazard`); `ground run` refuses a hazardous step without it.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub confirm: bool,
    #[serde(skip)]
    pub span: Range<usize>,
}

/// A validated plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Plan {
    pub name: String,
    pub description: String,
    pub robots: Vec<RobotDecl>,
    pub steps: Vec<Step>,
}

impl Plan {
    pub fn step_index(&self, id: &str) -> Option<usize> {
        self.steps.iter().position(|s| s.id == id)
    }

    /// Steps that (transitively) depend on step `i`.
    pub fn dependents(&self, i: usize) -> Vec<usize> {
        let mut out = Vec::new();
        let mut seen = HashSet::new();
        let mut q = VecDeque::from([i]);
        while let Some(c) = q.pop_front() {
            for (j, s) in self.steps.iter().enumerate() {
                if s.deps.contains(&c) && seen.insert(j) {
                    out.push(j);
                    q.push_back(j);
                }
            }
        }
        out.sort_unstable();
        out
    }
}

/// Shortest primitive sequence from `from` to `to` (at most
/// `mib::config::MAX_RECONFIG_PRIMITIVES`), by the same breadth-first search over the MIB's
/// reconfiguration map. `Some(vec![])` if the states are equal.
pub fn reconfig_path(from: u8, to: u8) -> Option<Vec<u8>> {
    // One search for ground and board: the domain crate's (the OBSW runs the same code).
    mmic_domain::search::shortest_path(from, to).map(|p| p.to_vec())
}

// ---------------------------------------------------------------------------
// Parsing

type Tbl<'i> = DeTable<'i>;
type Val<'i> = Spanned<DeValue<'i>>;

struct Cx {
    errors: Vec<PlanError>,
}

impl Cx {
    fn err(&mut self, span: Range<usize>, message: impl Into<String>) {
        self.errors.push(PlanError {
            span,
            message: message.into(),
        });
    }
}

fn int_of(v: &DeValue<'_>) -> Option<i64> {
    let i = v.as_integer()?;
    i64::from_str_radix(i.as_str(), i.radix()).ok()
}

fn float_of(v: &DeValue<'_>) -> Option<f64> {
    if let Some(f) = v.as_float() {
        return f.as_str().replace('_', "").parse().ok();
    }
    int_of(v).map(|i| i as f64)
}

fn unknown_keys(cx: &mut Cx, t: &Tbl<'_>, allowed: &[&str], what: &str) {
    for (k, _) in t.iter() {
        if !allowed.contains(&k.get_ref().as_ref()) {
            cx.err(
                k.span(),
                format!(
                    "unknown key `{}` in {what} (allowed: {})",
                    k.get_ref(),
                    allowed.join(", ")
                ),
            );
        }
    }
}

fn get<'a, 'i>(t: &'a Tbl<'i>, key: &str) -> Option<&'a Val<'i>> {
    t.get(key)
}

fn req<'a, 'i>(cx: &mut Cx, t: &'a Tbl<'i>, key: &str, at: Range<usize>, what: &str) -> Option<&'a Val<'i>> {
    let v = get(t, key);
    if v.is_none() {
        cx.err(at, format!("{what}: missing key `{key}`"));
    }
    v
}

fn int_in(cx: &mut Cx, v: &Val<'_>, key: &str, min: i64, max: i64) -> Option<i64> {
    match int_of(v.get_ref()) {
        Some(i) if i >= min && i <= max => Some(i),
        Some(i) => {
            cx.err(v.span(), format!("`{key}` = {i} is outside {min}..={max}"));
            None
        }
        None => {
            cx.err(
                v.span(),
                format!("`{key}` must be an integer, found {}", v.get_ref().type_str()),
            );
            None
        }
    }
}

fn string<'a>(cx: &mut Cx, v: &'a Val<'_>, key: &str) -> Option<&'a str> {
    match v.get_ref().as_str() {
        Some(s) => Some(s),
        None => {
            cx.err(
                v.span(),
                format!("`{key}` must be a string, found {}", v.get_ref().type_str()),
            );
            None
        }
    }
}

fn state_value(cx: &mut Cx, v: &Val<'_>, key: &str) -> Option<u8> {
    if let Some(s) = v.get_ref().as_str() {
        match robot::state_by_name(s) {
            Some(d) => Some(d.id),
            None => {
                let names: Vec<&str> = robot::STATES.iter().map(|s| s.name).collect();
                cx.err(
                    v.span(),
                    format!("`{key}`: unknown state \"{s}\" (states: {})", names.join(", ")),
                );
                None
            }
        }
    } else if int_of(v.get_ref()).is_some() {
        int_in(cx, v, key, 0, NUM_STATES as i64 - 1).map(|i| i as u8)
    } else {
        cx.err(v.span(), format!("`{key}` must be a state name or number"));
        None
    }
}

fn side_value(cx: &mut Cx, v: &Val<'_>) -> Option<u8> {
    if let Some(s) = v.get_ref().as_str() {
        match s.to_ascii_uppercase().as_str() {
            "A" => Some(robot::Side::A as u8),
            "B" => Some(robot::Side::B as u8),
            _ => {
                cx.err(v.span(), format!("`side`: \"{s}\" is not A or B"));
                None
            }
        }
    } else {
        int_in(cx, v, "side", 0, 1).map(|i| i as u8)
    }
}

fn pairs_value(cx: &mut Cx, v: &Val<'_>) -> Option<u8> {
    let n = robot::bolter::PAIRS_PER_FACE as i64;
    if let Some(s) = v.get_ref().as_str() {
        if s.eq_ignore_ascii_case("all") {
            return Some(((1u16 << n) - 1) as u8);
        }
        cx.err(
            v.span(),
            format!("`pairs`: \"{s}\" is not \"all\" or a list of pairs 1..={n}"),
        );
        return None;
    }
    let Some(arr) = v.get_ref().as_array() else {
        cx.err(v.span(), format!("`pairs` must be \"all\" or a list of pairs 1..={n}"));
        return None;
    };
    if arr.is_empty() {
        cx.err(v.span(), "`pairs` is empty");
        return None;
    }
    let mut mask = 0u8;
    let mut ok = true;
    for e in arr.iter() {
        match int_in(cx, e, "pair", 1, n) {
            Some(p) => {
                let bit = 1u8 << (p - 1);
                if mask & bit != 0 {
                    cx.err(e.span(), format!("pair {p} listed twice"));
                    ok = false;
                }
                mask |= bit;
            }
            None => ok = false,
        }
    }
    ok.then_some(mask)
}

fn mode_value(cx: &mut Cx, v: &Val<'_>) -> Option<u32> {
    if let Some(s) = v.get_ref().as_str() {
        if let Some(m) = mib::modes::root_mode_by_name(s) {
            return Some(m);
        }
        cx.err(
            v.span(),
            format!("`mode`: unknown mode \"{s}\" (standby, operational, safed)"),
        );
        None
    } else {
        let i = int_in(cx, v, "mode", 0, u32::MAX as i64)? as u32;
        if !mib::modes::is_commandable_root_mode(i) {
            cx.err(v.span(), format!("`mode` {i} is not a commandable robot mode"));
            return None;
        }
        Some(i)
    }
}

struct RawStep {
    id: Option<String>,
    robot: Option<u8>,
    robot_span: Range<usize>,
    action: Option<Action>,
    /// Span of the `from` value, when given explicitly.
    from_given: Option<(u8, Range<usize>)>,
    after: Vec<(String, Range<usize>)>,
    timeout_s: Option<f64>,
    confirm: bool,
    span: Range<usize>,
    action_span: Range<usize>,
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

fn parse_step(cx: &mut Cx, t: &Tbl<'_>, span: Range<usize>) -> RawStep {
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

fn array_of_tables<'a, 'i>(cx: &mut Cx, v: &'a Val<'i>, key: &str) -> Vec<(&'a Tbl<'i>, Range<usize>)> {
    match v.get_ref().as_array() {
        Some(arr) => arr
            .iter()
            .filter_map(|e| match e.get_ref().as_table() {
                Some(t) => Some((t, e.span())),
                None => {
                    cx.err(e.span(), format!("each `{key}` must be a table ([[{key}]])"));
                    None
                }
            })
            .collect(),
        None => {
            cx.err(v.span(), format!("`{key}` must be an array of tables ([[{key}]])"));
            Vec::new()
        }
    }
}

/// Parses and validates a plan. On failure returns every error found.
pub fn parse(src: &str) -> Result<Plan, Vec<PlanError>> {
    let mut cx = Cx { errors: Vec::new() };
    let (doc, syntax) = DeTable::parse_recoverable(src);
    for e in syntax {
        cx.err(e.span().unwrap_or(0..0), e.message().to_string());
    }
    let doc = doc.get_ref();
    unknown_keys(&mut cx, doc, &["name", "description", "robot", "step"], "the plan");
    let text = |cx: &mut Cx, k: &str| get(doc, k).and_then(|v| string(cx, v, k)).unwrap_or("").to_string();
    let name = text(&mut cx, "name");
    let description = text(&mut cx, "description");

    // Robots.
    let mut robots: Vec<RobotDecl> = Vec::new();
    match get(doc, "robot") {
        Some(v) => {
            for (t, span) in array_of_tables(&mut cx, v, "robot") {
                unknown_keys(&mut cx, t, &["number", "name", "initial_state"], "robot");
                let Some(nv) = req(&mut cx, t, "number", span.clone(), "robot") else {
                    continue;
                };
                let Some(n) = int_in(
                    &mut cx,
                    nv,
                    "number",
                    mib::apid::ROBOT_MIN as i64,
                    mib::apid::ROBOT_MAX as i64,
                ) else {
                    continue;
                };
                if robots.iter().any(|r| r.number as i64 == n) {
                    cx.err(nv.span(), format!("robot {n} declared twice"));
                    continue;
                }
                let initial_state = get(t, "initial_state").and_then(|v| state_value(&mut cx, v, "initial_state"));
                let name = get(t, "name")
                    .and_then(|v| string(&mut cx, v, "name"))
                    .map(str::to_string);
                robots.push(RobotDecl {
                    number: n as u8,
                    name,
                    initial_state,
                    span,
                });
            }
        }
        None => cx.err(0..0, "the plan declares no robot ([[robot]] with `number`)"),
    }

    // Steps.
    let mut raw: Vec<RawStep> = Vec::new();
    match get(doc, "step") {
        Some(v) => {
            for (t, span) in array_of_tables(&mut cx, v, "step") {
                raw.push(parse_step(&mut cx, t, span));
            }
        }
        None => cx.err(0..0, "the plan has no step ([[step]])"),
    }

    // Ids unique; robots declared.
    let mut ids: HashMap<String, usize> = HashMap::new();
    for (i, s) in raw.iter().enumerate() {
        if let Some(id) = &s.id {
            if ids.contains_key(id) {
                cx.err(s.span.clone(), format!("step id \"{id}\" used twice"));
            } else {
                ids.insert(id.clone(), i);
            }
        }
        if let Some(r) = s.robot {
            if !robots.iter().any(|d| d.number == r) {
                cx.err(s.robot_span.clone(), format!("robot {r} is not declared in [[robot]]"));
            }
        }
    }

    // Dependencies: explicit `after` plus the previous step of the same robot.
    let mut deps: Vec<Vec<usize>> = vec![Vec::new(); raw.len()];
    let mut last_of: HashMap<u8, usize> = HashMap::new();
    for (i, s) in raw.iter().enumerate() {
        for (a, span) in &s.after {
            match ids.get(a) {
                Some(&j) if j == i => cx.err(span.clone(), format!("step \"{a}\" depends on itself")),
                Some(&j) => {
                    if !deps[i].contains(&j) {
                        deps[i].push(j)
                    }
                }
                None => cx.err(span.clone(), format!("`after`: no step with id \"{a}\"")),
            }
        }
        if let Some(r) = s.robot {
            if let Some(&p) = last_of.get(&r) {
                if !deps[i].contains(&p) {
                    deps[i].push(p);
                }
            }
            last_of.insert(r, i);
        }
    }
    for cyc in find_cycles(&deps) {
        let names: Vec<String> = cyc
            .iter()
            .map(|&i| raw[i].id.clone().unwrap_or_else(|| format!("#{i}")))
            .collect();
        cx.err(
            raw[cyc[0]].span.clone(),
            format!("dependency cycle: {} -> {}", names.join(" -> "), names[0]),
        );
    }

    // Walk each robot's steps in order: modes and states.
    let mut mode: HashMap<u8, u32> = HashMap::new();
    let mut state: HashMap<u8, Option<u8>> = robots.iter().map(|r| (r.number, r.initial_state)).collect();
    for s in raw.iter_mut() {
        let (Some(r), Some(action)) = (s.robot, s.action.as_mut()) else {
            continue;
        };
        let m = mode.entry(r).or_insert(robot_mode::STANDBY);
        let st = state.entry(r).or_insert(None);
        let what = s.id.as_deref().unwrap_or("?");
        if let Some((def, args)) = action.tc() {
            if !def.modes.contains(*m) && !matches!(action, Action::Reconfigure { .. } if false) {
                cx.err(
                    s.action_span.clone(),
                    format!(
                        "step \"{what}\": {} is not accepted in {} mode (accepted in {}); robot {r} boots in STANDBY, command `mode = \"operational\"` first",
                        def.name,
                        pus::mode_name(mib::modes::node::ROBOT, *m),
                        def.modes.names()
                    ),
                );
            }
            if !matches!(action, Action::Reconfigure { .. }) {
                if let Err(e) = mib::codec::encode_args(def, &args, &mut [0u8; mib::config::MAX_TC_APP_DATA]) {
                    cx.err(
                        s.action_span.clone(),
                        pus::BuildError::Args { tc: def.name, err: e }.to_string(),
                    );
                }
            }
        }
        match action {
            Action::Mode { mode: new } => *m = *new,
            Action::Reconfigure { from, to } => {
                match (s.from_given.clone(), *st) {
                    (Some((f, span)), Some(cur)) if f != cur => cx.err(
                        span,
                        format!(
                            "step \"{what}\": from-state {} differs from robot {r}'s state {} after its previous step",
                            state_name(f),
                            state_name(cur)
                        ),
                    ),
                    (Some(_), _) => {}
                    (None, Some(cur)) => *from = cur,
                    (None, None) => cx.err(
                        s.action_span.clone(),
                        format!(
                            "step \"{what}\": robot {r}'s state is not known here; give `from` or the robot's `initial_state`"
                        ),
                    ),
                }
                if *from != robot::STATE_UNKNOWN {
                    if from == to {
                        cx.err(
                            s.action_span.clone(),
                            format!("step \"{what}\": from and to are the same state"),
                        );
                    } else if reconfig_path(*from, *to).is_none() {
                        cx.err(
                            s.action_span.clone(),
                            format!(
                                "step \"{what}\": {} is not reachable from {} in at most {} primitives",
                                state_name(*to),
                                state_name(*from),
                                mib::config::MAX_RECONFIG_PRIMITIVES
                            ),
                        );
                    }
                }
                *st = Some(*to);
            }
            // Debug moves leave the configuration state unknown to the ground.
            Action::MoveArm { .. } | Action::MoveGripper { .. } | Action::RotateHip { .. } => *st = None,
            _ => {}
        }
    }

    if !cx.errors.is_empty() {
        return Err(cx.errors);
    }
    let steps = raw
        .into_iter()
        .zip(deps)
        .filter_map(|(s, deps)| {
            Some(Step {
                id: s.id?,
                robot: s.robot?,
                action: s.action?,
                after: s.after.into_iter().map(|a| a.0).collect(),
                deps,
                timeout_s: s.timeout_s,
                confirm: s.confirm,
                span: s.span,
            })
        })
        .collect();
    Ok(Plan {
        name,
        description,
        robots,
        steps,
    })
}

/// Every cycle of the dependency graph, each once (as found by depth-first search).
fn find_cycles(deps: &[Vec<usize>]) -> Vec<Vec<usize>> {
    #[derive(Clone, Copy, PartialEq)]
    enum C {
        White,
        Grey,
        Black,
    }
    let n = deps.len();
    let mut color = vec![C::White; n];
    let mut out = Vec::new();
    for root in 0..n {
        if color[root] != C::White {
            continue;
        }
        // Iterative DFS: stack of (node, next dep index).
        let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
        color[root] = C::Grey;
        while let Some(&mut (v, ref mut k)) = stack.last_mut() {
            if *k < deps[v].len() {
                let w = deps[v][*k];
                *k += 1;
                match color[w] {
                    C::White => {
                        color[w] = C::Grey;
                        stack.push((w, 0));
                    }
                    C::Grey => {
                        let pos = stack.iter().position(|&(x, _)| x == w).unwrap_or(0);
                        let mut cyc: Vec<usize> = stack[pos..].iter().map(|&(x, _)| x).collect();
                        cyc.reverse();
                        out.push(cyc);
                    }
                    C::Black => {}
                }
            } else {
                color[v] = C::Black;
                stack.pop();
            }
        }
    }
    out
}

/// Reads and parses a plan file; errors come back as diagnostics.
pub fn load(path: &std::path::Path) -> Result<Plan, LoadError> {
    let bytes = std::fs::read(path).map_err(|e| LoadError::Io(path.display().to_string(), e))?;
    let src = String::from_utf8(bytes).map_err(|e| {
        LoadError::Invalid(vec![Diagnostic {
            file: path.display().to_string(),
            line: 1,
            column: 1,
            message: format!(
                "not a plan: not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        }])
    })?;
    parse(&src).map_err(|errs| LoadError::Invalid(diagnostics(&path.display().to_string(), &src, &errs)))
}

#[derive(Debug)]
pub enum LoadError {
    Io(String, std::io::Error),
    Invalid(Vec<Diagnostic>),
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoadError::Io(p, e) => write!(f, "cannot read {p}: {e}"),
            LoadError::Invalid(d) => {
                for x in d {
                    writeln!(f, "{x}")?;
                }
                write!(f, "{} error(s) in the plan", d.len())
            }
        }
    }
}

impl std::error::Error for LoadError {}

/// One encoded TC of a plan.
#[derive(Clone, Debug)]
pub struct EncodedStep {
    pub step: usize,
    pub tc: Option<BuiltTc>,
}

/// Encodes every step to a TC (per-APID sequence counts from 0, in file order per robot).
pub fn encode(plan: &Plan) -> Result<Vec<EncodedStep>, pus::BuildError> {
    let mut seq = SeqCounters::new();
    plan.steps
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let tc = match s.action.tc() {
                Some((def, args)) => {
                    let apid = mib::apid::robot_apid(s.robot).ok_or(pus::BuildError::UnknownRobot(s.robot))?;
                    Some(pus::build_tc(s.robot, seq.next(apid), def, &args)?)
                }
                None => None,
            };
            Ok(EncodedStep { step: i, tc })
        })
        .collect()
}

/// Writes `apid_0xNNN.bin` per robot (the raw TC stream) and `listing.txt` into `dir`.
/// Returns the paths written.
pub fn write_encoded(
    plan: &Plan,
    enc: &[EncodedStep],
    dir: &std::path::Path,
) -> std::io::Result<Vec<std::path::PathBuf>> {
    use std::fmt::Write as _;
    std::fs::create_dir_all(dir)?;
    let mut streams: std::collections::BTreeMap<u16, Vec<u8>> = std::collections::BTreeMap::new();
    let mut listing = String::new();
    let _ = writeln!(listing, "# plan: {} — {}", plan.name, plan.description);
    let _ = writeln!(listing, "# step | robot | apid | seq | TC | arguments | after | bytes");
    for e in enc {
        let s = &plan.steps[e.step];
        let after: Vec<&str> = s.deps.iter().map(|&d| plan.steps[d].id.as_str()).collect();
        match &e.tc {
            Some(tc) => {
                streams.entry(tc.apid).or_default().extend_from_slice(&tc.bytes);
                let args: Vec<String> = tc
                    .def
                    .args
                    .iter()
                    .zip(&tc.args)
                    .map(|(a, v)| format!("{}={v}", a.name))
                    .collect();
                let _ = writeln!(
                    listing,
                    "{} | {} | 0x{:03X} | {} | TC[{},{}] {} | {} | {} | {}",
                    s.id,
                    s.robot,
                    tc.apid,
                    tc.seq,
                    tc.def.service,
                    tc.def.subservice,
                    tc.def.name,
                    args.join(" "),
                    after.join(","),
                    pus::hex(&tc.bytes)
                );
                let _ = writeln!(listing, "#   {}", s.action.describe());
            }
            None => {
                let _ = writeln!(
                    listing,
                    "{} | {} | - | - | (ground) {} | | {} |",
                    s.id,
                    s.robot,
                    s.action.describe(),
                    after.join(",")
                );
            }
        }
    }
    let mut out = Vec::new();
    for (apid, bytes) in &streams {
        let p = dir.join(format!("apid_0x{apid:03X}.bin"));
        std::fs::write(&p, bytes)?;
        out.push(p);
    }
    let p = dir.join("listing.txt");
    std::fs::write(&p, listing)?;
    out.push(p);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "t"
[[robot]]
number = 1
initial_state = "Xneg"
[[robot]]
number = 2
initial_state = "Xpos"

[[step]]
id = "op1"
robot = 1
action = "mode"
mode = "operational"

[[step]]
id = "op2"
robot = 2
action = "mode"
mode = 1

[[step]]
id = "r1"
robot = 1
action = "reconfigure"
to = "Xpos Xneg"

[[step]]
id = "b2"
robot = 2
action = "bolt"
side = "A"
pairs = "all"
after = ["r1"]

[[step]]
id = "w"
robot = 2
action = "wait"
seconds = 0.5

[[step]]
id = "hk"
robot = 2
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval_ms = 100 }
"#;

    // verifies: GND-04
    #[test]
    fn valid_plan_parses_with_implicit_and_explicit_dependencies() {
        let p = parse(GOOD).unwrap();
        assert_eq!(p.steps.len(), 6);
        let r1 = p.step_index("r1").unwrap();
        assert_eq!(p.steps[r1].action, Action::Reconfigure { from: 0, to: 4 });
        let b2 = p.step_index("b2").unwrap();
        let op2 = p.step_index("op2").unwrap();
        assert_eq!(p.steps[b2].deps, vec![r1, op2]);
        assert_eq!(p.steps[b2].action, Action::Bolt { side: 0, pairs: 15 });
        assert_eq!(p.dependents(r1), vec![b2, b2 + 1, b2 + 2]);
        let enc = encode(&p).unwrap();
        assert_eq!(enc.iter().filter(|e| e.tc.is_some()).count(), 5);
        let hk = enc[5].tc.as_ref().unwrap();
        assert_eq!((hk.apid, hk.seq), (0x102, 2));
    }

    fn errors(src: &str) -> Vec<Diagnostic> {
        diagnostics("p.toml", src, &parse(src).unwrap_err())
    }

    // verifies: GND-03
    #[test]
    fn every_error_is_reported_with_line_and_column() {
        let src = r#"[[robot]]
number = 1
initial_state = "Xneg"
[[step]]
id = "a"
robot = 3
action = "fly"
[[step]]
id = "b"
robot = 1
action = "bolt"
side = "C"
pairs = [1, 5]
after = ["nope"]
[[step]]
id = "b"
robot = 1
action = "reconfigure"
from = "Yneg"
to = "Xpos"
colour = "red"
"#;
        let d = errors(src);
        let text: Vec<String> = d.iter().map(|x| x.to_string()).collect();
        let has = |needle: &str| {
            assert!(
                text.iter().any(|t| t.contains(needle)),
                "missing {needle:?} in {text:#?}"
            )
        };
        has("p.toml:6:9: error: robot 3 is not declared");
        has("p.toml:7:10: error: unknown action \"fly\"");
        has("p.toml:12:8: error: `side`: \"C\" is not A or B");
        has("p.toml:13:13: error: `pair` = 5 is outside 1..=4");
        has("p.toml:14:10: error: `after`: no step with id \"nope\"");
        has("step id \"b\" used twice");
        has("p.toml:21:1: error: unknown key `colour`");
        has("p.toml:18:10: error: step \"b\": RECONFIGURE is not accepted in STANDBY mode");
        has("p.toml:19:8: error: step \"b\": from-state Yneg differs from robot 1's state Xneg");
        assert!(d.len() >= 9, "{text:#?}");
    }

    // verifies: GND-04
    #[test]
    fn from_state_must_match_previous_to_state_and_be_reachable() {
        let src = r#"[[robot]]
number = 1
initial_state = "Xneg"
[[step]]
id = "m"
robot = 1
action = "mode"
mode = "operational"
[[step]]
id = "a"
robot = 1
action = "reconfigure"
to = "Xpos"
[[step]]
id = "b"
robot = 1
action = "reconfigure"
from = "Yneg"
to = "Xneg"
"#;
        let text: Vec<String> = errors(src).iter().map(|x| x.to_string()).collect();
        assert!(
            text.iter()
                .any(|t| t.contains("p.toml:18:8") && t.contains("from-state Yneg differs from robot 1's state Xpos")),
            "{text:#?}"
        );
    }

    // verifies: GND-04
    #[test]
    fn unreachable_reconfiguration_is_an_error() {
        // Find a pair of states more than 3 primitives apart, if the map has one.
        let far = (0..NUM_STATES as u8)
            .flat_map(|a| (0..NUM_STATES as u8).map(move |b| (a, b)))
            .find(|&(a, b)| a != b && reconfig_path(a, b).is_none());
        let Some((a, b)) = far else {
            // Every pair is reachable within 3: check the BFS finds short paths instead.
            assert!(reconfig_path(0, 1).unwrap().len() <= 3);
            return;
        };
        let src = format!(
            "[[robot]]\nnumber = 1\n[[step]]\nid = \"m\"\nrobot = 1\naction = \"mode\"\nmode = \"operational\"\n[[step]]\nid = \"r\"\nrobot = 1\naction = \"reconfigure\"\nfrom = {a}\nto = {b}\n"
        );
        let text: Vec<String> = errors(&src).iter().map(|x| x.to_string()).collect();
        assert!(text.iter().any(|t| t.contains("is not reachable")), "{text:#?}");
    }

    // verifies: GND-04
    #[test]
    fn bfs_follows_the_reconfiguration_map() {
        // Xneg -> Xpos: extend one side, contract the other (two primitives).
        let p = reconfig_path(0, 1).unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(reconfig_path(0, 0), Some(vec![]));
        assert_eq!(reconfig_path(0, 99), None);
        for a in 0..NUM_STATES as u8 {
            for b in 0..NUM_STATES as u8 {
                if let Some(p) = reconfig_path(a, b) {
                    let mut s = a;
                    for prim in &p {
                        s = robot::apply(s, *prim).unwrap();
                    }
                    assert_eq!(s, b);
                    assert!(p.len() <= mib::config::MAX_RECONFIG_PRIMITIVES);
                }
            }
        }
    }

    // verifies: GND-04
    #[test]
    fn dependency_cycle_is_reported() {
        let src = r#"[[robot]]
number = 1
[[robot]]
number = 2
[[step]]
id = "x"
robot = 1
action = "wait"
seconds = 1
after = ["y"]
[[step]]
id = "y"
robot = 2
action = "wait"
seconds = 1
after = ["x"]
"#;
        let text: Vec<String> = errors(src).iter().map(|x| x.to_string()).collect();
        assert!(text.iter().any(|t| t.contains("dependency cycle")), "{text:#?}");
    }

    // verifies: GND-03
    #[test]
    fn syntax_errors_and_bad_command_args_are_located() {
        let d = errors("[[robot]\nnumber = 1\n");
        assert_eq!(d[0].line, 1);
        let src = r#"[[robot]]
number = 1
[[step]]
id = "c"
robot = 1
action = "command"
tc = "HK_SET_INTERVAL"
args = { sid = 1, interval_ms = 1, bogus = 2 }
"#;
        let text: Vec<String> = errors(src).iter().map(|x| x.to_string()).collect();
        // The same reader and words as `ground send` (ops::policy), at the value's place.
        assert!(
            text.iter()
                .any(|t| t.contains("p.toml:8:33") && t.contains("interval_ms = 1 outside 10..=3600000")),
            "{text:#?}"
        );
        assert!(
            text.iter()
                .any(|t| t.contains("p.toml:8:36") && t.contains("has no argument \"bogus\"")),
            "{text:#?}"
        );
    }

    // verifies: GND-03
    #[test]
    fn line_col_counts_characters() {
        assert_eq!(line_col("ab\ncd", 4), (2, 2));
        assert_eq!(line_col("ä\nx", 3), (2, 1));
    }
}
