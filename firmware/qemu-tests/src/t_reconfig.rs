//! The reconfiguration map on the target: every state pair, searched breadth-first by an
//! independent routine here, and the primitives' geometric effect re-derived.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq};
use mib::robot::{self, Face, StateKind, NUM_STATES, RECONFIG_MAP, STATES};

pub const TESTS: &[Test] = tests![
    map_primitives_match_geometry,
    map_matched_states_reach_each_other_in_1_to_3,
];

/// Shortest number of primitives from `a` to `b` over the map (BFS), `None` if unreachable.
pub fn bfs_len(a: usize, b: usize) -> Option<usize> {
    let mut dist = [usize::MAX; NUM_STATES];
    let mut queue = [0usize; NUM_STATES];
    let (mut head, mut tail) = (0, 0);
    dist[a] = 0;
    queue[tail] = a;
    tail += 1;
    while head < tail {
        let s = queue[head];
        head += 1;
        for t in 0..NUM_STATES {
            if RECONFIG_MAP[s][t] != 0 && dist[t] == usize::MAX {
                dist[t] = dist[s] + 1;
                queue[tail] = t;
                tail += 1;
            }
        }
    }
    (dist[b] != usize::MAX).then_some(dist[b])
}

fn map_primitives_match_geometry() -> TestResult {
    // Primitive 1 (fwd extend) from matched Xneg: A jumps to the opposite face Xpos.
    check_eq!(RECONFIG_MAP[0][4], 1);
    let mut edges = 0;
    for (i, s) in STATES.iter().enumerate() {
        for (j, t) in STATES.iter().enumerate() {
            let p = RECONFIG_MAP[i][j];
            if p == 0 {
                continue;
            }
            edges += 1;
            let prim = match robot::primitive(p) {
                Some(p) => p,
                None => {
                    return Err(crate::harness::Failure::new(
                        file!(),
                        line!(),
                        format_args!("bad primitive {}", p),
                    ))
                }
            };
            // Exactly one side moves; the other keeps its face.
            let (moved_from, moved_to, anchor_before, anchor_after) = match prim.moving {
                robot::Side::A => (s.a, t.a, s.b, t.b),
                robot::Side::B => (s.b, t.b, s.a, t.a),
            };
            check_eq!(anchor_before, anchor_after, "{}->{} anchor", i, j);
            let quarter = (moved_to as i8 - moved_from as i8).rem_euclid(4);
            match prim.motion {
                robot::Motion::Extend => {
                    check_eq!(s.kind(), StateKind::Matched);
                    check_eq!(quarter, 2);
                }
                robot::Motion::Contract => {
                    check_eq!(s.kind(), StateKind::Stretch);
                    check_eq!(moved_to, anchor_before);
                }
                robot::Motion::Rotate(q) => check_eq!(quarter, q.rem_euclid(4)),
            }
        }
    }
    check!(edges > 0);
    check_eq!(Face::Xpos.opposite(), Face::Xneg);
    Ok(())
}

fn map_matched_states_reach_each_other_in_1_to_3() -> TestResult {
    let matched: heapless::Vec<usize, 4> = (0..NUM_STATES)
        .filter(|&i| STATES[i].kind() == StateKind::Matched)
        .collect();
    check_eq!(matched.len(), 3);
    for &a in &matched {
        for &b in &matched {
            if a == b {
                continue;
            }
            let d = bfs_len(a, b);
            check!(
                matches!(d, Some(1..=3)),
                "{} -> {}: {:?} primitives",
                STATES[a].name,
                STATES[b].name,
                d
            );
        }
    }
    Ok(())
}
