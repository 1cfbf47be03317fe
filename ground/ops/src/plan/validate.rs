//! Checks across steps: ids unique, robots declared, dependencies (explicit and per
//! robot) without cycles, and each robot's steps walked in order for its mode and
//! configuration state (TC accepted in that mode, arguments in range, reconfigurations
//! from the right state and reachable).

use std::collections::HashMap;

use mib::modes::robot_mode;
use mib::robot;

use super::step::RawStep;
use super::values::Cx;
use super::{reconfig_path, state_name, Action, RobotDecl};
use crate::pus;

/// Every step's dependencies (indices into `raw`): its explicit `after` plus the
/// previous step of the same robot. Reports duplicate ids, undeclared robots, unknown
/// or self dependencies and cycles.
pub(super) fn dependencies(cx: &mut Cx, raw: &[RawStep], robots: &[RobotDecl]) -> Vec<Vec<usize>> {
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

    deps
}

/// Walks each robot's steps in order: modes and states.
pub(super) fn walk_robots(cx: &mut Cx, raw: &mut [RawStep], robots: &[RobotDecl]) {
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
            if !def.modes.contains(*m) {
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
                if let Err(e) = mib_wire::codec::encode_args(def, &args, &mut [0u8; mib::config::MAX_TC_APP_DATA]) {
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
