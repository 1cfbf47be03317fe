//! The command policy, one for every CLI path (`send`, `mode`, plan steps):
//! TC names and `NAME=VALUE` arguments are read by [`tc_by_name`] and [`parse_args`]
//! (a mistyped name gets a "did you mean"), and a hazardous TC (the MIB's `hazard`) is
//! sent only with an explicit confirmation ([`check_confirmed`]).

use mib::tc::{ArgDef, TcDef};

/// Why a command is refused before anything is sent.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PolicyError {
    #[error("\"{name}\" is not a TC of the MIB{}", did_you_mean(.suggestion))]
    UnknownTc { name: String, suggestion: Option<String> },
    #[error("{tc} has no argument \"{name}\"{} (arguments: {all})", did_you_mean(.suggestion))]
    UnknownArg {
        tc: &'static str,
        name: String,
        suggestion: Option<String>,
        all: String,
    },
    #[error("argument \"{0}\" is not NAME=VALUE")]
    NotNameValue(String),
    #[error("{tc}: {arg} = \"{value}\": {why}")]
    BadValue {
        tc: &'static str,
        arg: &'static str,
        value: String,
        why: String,
    },
    #[error("{tc}: {arg} = {value} outside {min}..={max}")]
    OutOfRange {
        tc: &'static str,
        arg: &'static str,
        value: i64,
        min: i64,
        max: i64,
    },
    #[error("{tc}: missing argument {arg}=…")]
    Missing { tc: &'static str, arg: &'static str },
    #[error("{tc}: {arg} given twice")]
    Twice { tc: &'static str, arg: &'static str },
    #[error("{0} has variable data; it cannot be sent from the command line or a plan")]
    Variable(&'static str),
    #[error("{tc} is hazardous ({hazard}): refused without confirmation ({how})")]
    Unconfirmed {
        tc: &'static str,
        hazard: &'static str,
        how: &'static str,
    },
}

fn did_you_mean(s: &Option<String>) -> String {
    s.as_ref().map_or(String::new(), |s| format!(" — did you mean {s}?"))
}

/// The closest of `names` to `given` if it is close enough to be a typo.
pub fn suggest<'a>(given: &str, names: impl IntoIterator<Item = &'a str>) -> Option<String> {
    let g = given.to_ascii_lowercase();
    names
        .into_iter()
        .map(|n| (strsim::jaro_winkler(&g, &n.to_ascii_lowercase()), n))
        .filter(|(score, _)| *score >= 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, n)| n.to_string())
}

/// The MIB TC named `name` (any case); a near miss gets a suggestion.
pub fn tc_by_name(name: &str) -> Result<&'static TcDef, PolicyError> {
    mib::tc::by_name(name).ok_or_else(|| PolicyError::UnknownTc {
        name: name.to_string(),
        suggestion: suggest(name, mib::tc::TCS.iter().map(|t| t.name)),
    })
}

/// Reads one argument value: a number (decimal or `0x…`), or one of the argument's
/// names in the MIB (state, side, mode, event names), checked against its range.
pub fn parse_value(def: &'static TcDef, d: &'static ArgDef, v: &str) -> Result<i64, PolicyError> {
    let v = v.trim();
    let bad = |why: String| PolicyError::BadValue {
        tc: def.name,
        arg: d.name,
        value: v.to_string(),
        why,
    };
    let num = if let Ok(n) = v.parse::<i64>() {
        n
    } else if let Some(h) = v.strip_prefix("0x").or_else(|| v.strip_prefix("0X")) {
        i64::from_str_radix(h, 16).map_err(|_| bad("not a hexadecimal number".into()))?
    } else if let Some(n) = d.names.value_of(v) {
        n
    } else if !d.names.is_none() {
        let mut names = Vec::new();
        d.names.for_each(|n, name| {
            if (d.min..=d.max).contains(&n) {
                names.push((n, name));
            }
        });
        let close = suggest(v, names.iter().map(|(_, n)| *n));
        let listed: Vec<String> = names.iter().map(|(n, name)| format!("{name} ({n})")).collect();
        let why = match (close, listed.split_last()) {
            (Some(c), _) => format!("not a {} — did you mean {c}?", d.name),
            (None, Some((last, rest))) if listed.len() <= 8 && !rest.is_empty() => {
                format!("the {}s are {} and {last}", d.name, rest.join(", "))
            }
            (None, _) => format!(
                "it is none of the {} names of {} (see docs/ICD.md)",
                listed.len(),
                d.name
            ),
        };
        return Err(bad(why));
    } else {
        return Err(bad("not a number".into()));
    };
    if num < d.min || num > d.max {
        return Err(PolicyError::OutOfRange {
            tc: def.name,
            arg: d.name,
            value: num,
            min: d.min,
            max: d.max,
        });
    }
    Ok(num)
}

/// The argument of `def` named `name` (any case); a near miss gets a suggestion.
pub fn arg_by_name(def: &'static TcDef, name: &str) -> Result<(usize, &'static ArgDef), PolicyError> {
    def.args
        .iter()
        .enumerate()
        .find(|(_, d)| d.name.eq_ignore_ascii_case(name))
        .ok_or_else(|| PolicyError::UnknownArg {
            tc: def.name,
            name: name.to_string(),
            suggestion: suggest(name, def.args.iter().map(|d| d.name)),
            all: if def.args.is_empty() {
                "none".into()
            } else {
                def.args.iter().map(|d| d.name).collect::<Vec<_>>().join(", ")
            },
        })
}

/// Reads the arguments of `def` from `(name, value)` pairs: every argument exactly once,
/// each within its MIB range. The one argument reader of `send` and plan `command` steps.
pub fn parse_args<'a>(
    def: &'static TcDef,
    pairs: impl IntoIterator<Item = (&'a str, &'a str)>,
) -> Result<Vec<i64>, PolicyError> {
    if def.variable {
        return Err(PolicyError::Variable(def.name));
    }
    let mut vals: Vec<Option<i64>> = vec![None; def.args.len()];
    for (k, v) in pairs {
        let (idx, d) = arg_by_name(def, k.trim())?;
        if vals[idx].is_some() {
            return Err(PolicyError::Twice {
                tc: def.name,
                arg: d.name,
            });
        }
        vals[idx] = Some(parse_value(def, d, v)?);
    }
    vals.iter()
        .zip(def.args)
        .map(|(v, d)| {
            v.ok_or(PolicyError::Missing {
                tc: def.name,
                arg: d.name,
            })
        })
        .collect()
}

/// [`parse_args`] over `NAME=VALUE` words (the command line).
pub fn parse_arg_words(def: &'static TcDef, words: &[String]) -> Result<Vec<i64>, PolicyError> {
    let mut pairs = Vec::with_capacity(words.len());
    for w in words {
        pairs.push(w.split_once('=').ok_or_else(|| PolicyError::NotNameValue(w.clone()))?);
    }
    parse_args(def, pairs)
}

/// Refuses a hazardous TC without confirmation; `how` says how to confirm on this path
/// (e.g. "add --confirm").
pub fn check_confirmed(def: &'static TcDef, confirmed: bool, how: &'static str) -> Result<(), PolicyError> {
    match def.hazard {
        Some(hazard) if !confirmed => Err(PolicyError::Unconfirmed {
            tc: def.name,
            hazard,
            how,
        }),
        Some(_) | None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: OPS-POLICY-02
    #[test]
    fn a_mistyped_tc_or_argument_gets_a_suggestion() {
        let e = tc_by_name("BOLT_FCE").unwrap_err().to_string();
        assert!(e.contains("did you mean BOLT_FACE?"), "{e}");
        assert!(!tc_by_name("XYZZY").unwrap_err().to_string().contains("did you mean"));
        let def = tc_by_name("reconfigure").unwrap();
        let e = parse_arg_words(def, &["form=Xneg".into(), "to=Xpos".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("did you mean from?"), "{e}");
        let e = parse_arg_words(def, &["from=Xnge".into(), "to=Xpos".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("did you mean Xneg?"), "{e}");
        let ok = parse_arg_words(def, &["from=Xneg".into(), "TO=Xpos".into()]).unwrap();
        assert_eq!(ok.len(), 2);
        let e = parse_arg_words(def, &["from=Xneg".into()]).unwrap_err();
        assert!(matches!(e, PolicyError::Missing { arg: "to", .. }));
    }

    // verifies: OPS-POLICY-01
    #[test]
    fn hazardous_tcs_need_confirmation() {
        let unbolt = tc_by_name("UNBOLT_FACE").unwrap();
        let e = check_confirmed(unbolt, false, "add --confirm").unwrap_err().to_string();
        assert!(e.contains("hazardous") && e.contains("--confirm"), "{e}");
        assert!(check_confirmed(unbolt, true, "").is_ok());
        assert!(check_confirmed(tc_by_name("PING").unwrap(), false, "").is_ok());
    }
}
