//! Shortest primitive sequence between two configuration states.
//!
//! Breadth-first search over `mib::robot::RECONFIG_MAP` with fixed bounds (15 states,
//! depth at most `mib::config::MAX_RECONFIG_PRIMITIVES`), no recursion, no heap. Ties
//! are broken deterministically: states are expanded in BFS order and successors in
//! state-ID order.

use heapless::Vec;
use mib::config::MAX_RECONFIG_PRIMITIVES;
use mib::robot::{NUM_STATES, RECONFIG_MAP};

/// Primitives (1..=8) of a reconfiguration.
pub type Plan = Vec<u8, MAX_RECONFIG_PRIMITIVES>;
/// States visited by a reconfiguration, `from` and `to` included.
pub type StatePath = Vec<u8, { MAX_RECONFIG_PRIMITIVES + 1 }>;

const NONE: u8 = u8::MAX;

/// States along a shortest path from `from` to `to` (both included); `None` if either
/// state is invalid or `to` is not reachable within `MAX_RECONFIG_PRIMITIVES` steps.
pub fn shortest_states(from: u8, to: u8) -> Option<StatePath> {
    let (f, t) = (from as usize, to as usize);
    if f >= NUM_STATES || t >= NUM_STATES {
        return None;
    }
    let mut dist = [NONE; NUM_STATES];
    let mut parent = [NONE; NUM_STATES];
    let mut queue = [0u8; NUM_STATES];
    let (mut head, mut tail) = (0usize, 1usize);
    queue[0] = from;
    dist[f] = 0;
    while head < tail {
        let s = queue[head] as usize;
        head += 1;
        if s == t {
            break;
        }
        if dist[s] as usize >= MAX_RECONFIG_PRIMITIVES {
            continue;
        }
        for (n, &p) in RECONFIG_MAP[s].iter().enumerate() {
            if p != 0 && dist[n] == NONE {
                dist[n] = dist[s] + 1;
                parent[n] = s as u8;
                queue[tail] = n as u8;
                tail += 1;
            }
        }
    }
    if dist[t] == NONE {
        return None;
    }
    // Walk back from `to`; the path has dist[t] + 1 <= 4 states.
    let len = dist[t] as usize + 1;
    let mut rev = [0u8; MAX_RECONFIG_PRIMITIVES + 1];
    let mut cur = to;
    for slot in rev.iter_mut().take(len) {
        *slot = cur;
        cur = parent[cur as usize];
    }
    let mut out = StatePath::new();
    for &s in rev[..len].iter().rev() {
        // Capacity is MAX + 1 >= len: cannot fail.
        let _ = out.push(s);
    }
    Some(out)
}

/// Primitives of a shortest sequence from `from` to `to`; empty when `from == to`;
/// `None` when a state is invalid or `to` is not reachable within 3 primitives.
pub fn shortest_path(from: u8, to: u8) -> Option<Plan> {
    let states = shortest_states(from, to)?;
    let mut plan = Plan::new();
    for w in states.windows(2) {
        let p = RECONFIG_MAP[w[0] as usize][w[1] as usize];
        let _ = plan.push(p);
    }
    Some(plan)
}

/// Number of primitives on a shortest path, if one exists within the bound.
pub fn distance(from: u8, to: u8) -> Option<u8> {
    shortest_states(from, to).map(|s| (s.len() - 1) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::robot::{apply, StateKind, STATES};
    use proptest::prelude::*;

    /// Exhaustive search: length of the shortest primitive sequence (any of the 8
    /// primitives, applied with `mib::robot::apply`) up to 3 steps, independent of the
    /// map and of BFS.
    fn exhaustive_len(from: u8, to: u8) -> Option<usize> {
        if from == to {
            return Some(0);
        }
        for len in 1..=MAX_RECONFIG_PRIMITIVES {
            let combos = 8usize.pow(len as u32);
            for c in 0..combos {
                let mut s = from;
                let mut ok = true;
                let mut x = c;
                for _ in 0..len {
                    let p = (x % 8) as u8 + 1;
                    x /= 8;
                    match apply(s, p) {
                        Some(n) => s = n,
                        None => {
                            ok = false;
                            break;
                        }
                    }
                }
                if ok && s == to {
                    return Some(len);
                }
            }
        }
        None
    }

    fn check(from: u8, to: u8) {
        let plan = shortest_path(from, to);
        match (plan, exhaustive_len(from, to)) {
            (None, None) => {}
            (Some(plan), Some(n)) => {
                assert_eq!(plan.len(), n, "{from}->{to}: not minimal");
                let mut s = from;
                for &p in &plan {
                    assert!((1..=8).contains(&p));
                    let next = RECONFIG_MAP[s as usize]
                        .iter()
                        .position(|&q| q == p)
                        .expect("primitive not in the map row") as u8;
                    assert_eq!(apply(s, p), Some(next));
                    s = next;
                }
                assert_eq!(s, to, "{from}->{to}: does not end at the target");
            }
            (a, b) => panic!("{from}->{to}: search {a:?} vs exhaustive {b:?}"),
        }
    }

    // verifies: MMIC-MOT-04
    #[test]
    fn search_is_valid_and_minimal_for_every_pair_of_states() {
        for f in 0..NUM_STATES as u8 {
            for t in 0..NUM_STATES as u8 {
                check(f, t);
            }
        }
    }

    // verifies: MMIC-MOT-04
    #[test]
    fn every_matched_pair_is_reachable_in_one_to_three_primitives() {
        let matched: std::vec::Vec<u8> = STATES
            .iter()
            .filter(|s| s.kind() == StateKind::Matched)
            .map(|s| s.id)
            .collect();
        for &f in &matched {
            for &t in &matched {
                let n = shortest_path(f, t).expect("matched states connected").len();
                if f == t {
                    assert_eq!(n, 0);
                } else {
                    assert!((1..=3).contains(&n), "{f}->{t}: {n}");
                }
            }
        }
        // Xneg -> Xpos: back extend (B to Xpos), back contract (A onto Xpos); the
        // equally short fwd extend / fwd contract loses the tie on state ID (3 < 4).
        assert_eq!(shortest_path(0, 1).unwrap().as_slice(), &[3, 4]);
        assert_eq!(shortest_states(0, 1).unwrap().as_slice(), &[0, 3, 1]);
    }

    // verifies: MMIC-MOT-05
    #[test]
    fn search_rejects_invalid_states() {
        assert!(shortest_path(15, 0).is_none());
        assert!(shortest_path(0, 200).is_none());
        assert_eq!(shortest_states(3, 3).unwrap().as_slice(), &[3]);
    }

    proptest! {
        // verifies: MMIC-MOT-04
        #[test]
        fn search_result_is_a_valid_minimal_sequence(from in 0u8..15, to in 0u8..15) {
            check(from, to);
        }
        // verifies: MMIC-MOT-05
        #[test]
        fn search_never_panics_on_any_input(from: u8, to: u8) {
            let _ = shortest_path(from, to);
        }
    }
}
