//! The document as a whole: `name`, `description`, the `[[robot]]` and `[[step]]`
//! tables, then the checks across steps ([`super::validate`]) and the typed [`Plan`].

use toml::de::DeTable;

use super::step::{parse_step, RawStep};
use super::validate;
use super::values::{array_of_tables, get, int_in, req, state_value, string, unknown_keys, Cx, Tbl};
use super::{Plan, PlanError, RobotDecl, Step};

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
    let robots = robots(&mut cx, doc);

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

    let deps = validate::dependencies(&mut cx, &raw, &robots);
    validate::walk_robots(&mut cx, &mut raw, &robots);

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

/// The `[[robot]]` tables (each number once).
fn robots(cx: &mut Cx, doc: &Tbl<'_>) -> Vec<RobotDecl> {
    let mut robots: Vec<RobotDecl> = Vec::new();
    let Some(v) = get(doc, "robot") else {
        cx.err(0..0, "the plan declares no robot ([[robot]] with `number`)");
        return robots;
    };
    for (t, span) in array_of_tables(cx, v, "robot") {
        unknown_keys(cx, t, &["number", "name", "initial_state"], "robot");
        let Some(nv) = req(cx, t, "number", span.clone(), "robot") else {
            continue;
        };
        let Some(n) = int_in(
            cx,
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
        let initial_state = get(t, "initial_state").and_then(|v| state_value(cx, v, "initial_state"));
        let name = get(t, "name").and_then(|v| string(cx, v, "name")).map(str::to_string);
        robots.push(RobotDecl {
            number: n as u8,
            name,
            initial_state,
            span,
        });
    }
    robots
}
