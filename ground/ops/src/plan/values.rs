//! Reading the values of a plan document: every reader records its error (with the
//! value's span) in the [`Cx`] and returns `None`, so that one bad value does not hide
//! the others.

use std::ops::Range;

use mib::robot::{self, NUM_STATES};
use toml::de::{DeTable, DeValue};
use toml::Spanned;

use super::PlanError;

pub(super) type Tbl<'i> = DeTable<'i>;
pub(super) type Val<'i> = Spanned<DeValue<'i>>;

pub(super) struct Cx {
    pub(super) errors: Vec<PlanError>,
}

impl Cx {
    pub(super) fn err(&mut self, span: Range<usize>, message: impl Into<String>) {
        self.errors.push(PlanError {
            span,
            message: message.into(),
        });
    }
}

pub(super) fn int_of(v: &DeValue<'_>) -> Option<i64> {
    let i = v.as_integer()?;
    i64::from_str_radix(i.as_str(), i.radix()).ok()
}

pub(super) fn float_of(v: &DeValue<'_>) -> Option<f64> {
    if let Some(f) = v.as_float() {
        return f.as_str().replace('_', "").parse().ok();
    }
    int_of(v).map(|i| i as f64)
}

pub(super) fn unknown_keys(cx: &mut Cx, t: &Tbl<'_>, allowed: &[&str], what: &str) {
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

pub(super) fn get<'a, 'i>(t: &'a Tbl<'i>, key: &str) -> Option<&'a Val<'i>> {
    t.get(key)
}

pub(super) fn req<'a, 'i>(cx: &mut Cx, t: &'a Tbl<'i>, key: &str, at: Range<usize>, what: &str) -> Option<&'a Val<'i>> {
    let v = get(t, key);
    if v.is_none() {
        cx.err(at, format!("{what}: missing key `{key}`"));
    }
    v
}

pub(super) fn int_in(cx: &mut Cx, v: &Val<'_>, key: &str, min: i64, max: i64) -> Option<i64> {
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

pub(super) fn string<'a>(cx: &mut Cx, v: &'a Val<'_>, key: &str) -> Option<&'a str> {
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

pub(super) fn state_value(cx: &mut Cx, v: &Val<'_>, key: &str) -> Option<u8> {
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

pub(super) fn side_value(cx: &mut Cx, v: &Val<'_>) -> Option<u8> {
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

pub(super) fn pairs_value(cx: &mut Cx, v: &Val<'_>) -> Option<u8> {
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

pub(super) fn mode_value(cx: &mut Cx, v: &Val<'_>) -> Option<u32> {
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

pub(super) fn array_of_tables<'a, 'i>(cx: &mut Cx, v: &'a Val<'i>, key: &str) -> Vec<(&'a Tbl<'i>, Range<usize>)> {
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
