//! Model checking of the on-board plans' dependency protocol with `stateright`, driving
//! the real executors (`mmic_plan::Plan`): three robots, a team network that loses,
//! duplicates and reorders progress announcements (any in-flight announcement may be
//! delivered, delivered and kept for a later duplicate, or dropped), and a crash of any
//! robot at any point, restarting from its last durable record (the host stores the record
//! after every action that changed it, before the next step can start).
//!
//! The plan: robot 1 runs A0, A1; robot 2 runs B0 after A0; robot 3 runs C0 after B0 and
//! A1 (a dependency on two robots, one of them on a later step than the other waits for).
//!
//! Properties (always): no step starts before every step it depends on has completed (on
//! the robot that runs it, not as announced); no step of any robot starts twice, across
//! crashes. Sanity (sometimes): every robot completes its plan.
//!
//! Bounds (debug, CI): at most 2 announcements in flight (one announcement to both
//! others), 1 announcement sent per robot (robot 1's after both its steps serves both
//! dependencies), 1 crash. Larger bounds: `PLAN_MODEL_SENDS=2 cargo test --release -p
//! mmic-plan --test model` (memory grows fast: each state holds three whole executors).

use mmic_plan::image::{emit, StepRepr};
use mmic_plan::{Dep, Plan, Poll, State, StepKind};
use stateright::{Checker, Model, Property};
use std::collections::BTreeSet;

const N: usize = 3;
const PLAN_ID: u32 = 0x5EED;
const MAX_NET: usize = 2;
/// Announcements per robot (`PLAN_MODEL_SENDS`, default 1).
fn max_sends() -> u8 {
    std::env::var("PLAN_MODEL_SENDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1)
}

/// Each robot's steps: the dependencies of each.
fn deps(robot: usize) -> Vec<Vec<Dep>> {
    let d = |robot, step| Dep { robot, step };
    match robot {
        0 => vec![vec![], vec![]],
        1 => vec![vec![d(1, 0)]],
        _ => vec![vec![d(2, 0), d(1, 1)]],
    }
}

/// The request ID (first four bytes) of robot `r`'s step `s`.
fn tc(r: usize, s: usize) -> [u8; 13] {
    [0x19, 0x01 + r as u8, 0xC0, s as u8, 0, 6, 0x2F, 17, 1, 0, 0, 0xAB, 0xCD]
}

fn image(r: usize) -> Vec<u8> {
    let tcs: Vec<[u8; 13]> = (0..deps(r).len()).map(|s| tc(r, s)).collect();
    let steps: Vec<StepRepr> = deps(r)
        .into_iter()
        .enumerate()
        .map(|(s, d)| StepRepr {
            index: s as u8,
            confirmed: false,
            timeout_s: 0,
            deps: d.into_iter().collect(),
            kind: StepKind::Tc(&tcs[s]),
        })
        .collect();
    let mut out = [0u8; mib::plan::MAX_IMAGE_LEN];
    let n = emit(r as u8 + 1, PLAN_ID, &steps, &mut out).unwrap();
    out[..n].to_vec()
}

fn loaded(r: usize) -> Plan {
    let mut p = Plan::new(r as u8 + 1);
    let img = image(r);
    p.load(0, &img).unwrap();
    let crc = u32::from_be_bytes(img[img.len() - 4..].try_into().unwrap());
    p.commit(img.len() as u16, crc, |_| Ok(())).unwrap();
    p.start(PLAN_ID).unwrap();
    p
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct State0 {
    plans: Vec<Plan>,
    /// The last durable record of each robot (image index implied, progress).
    durable: Vec<Option<mmic_plan::exec::Progress>>,
    /// Ground truth: steps each robot really completed.
    completed: [u8; N],
    /// The step each robot is running (its TC handed out, outcome not yet given).
    running: [Option<u8>; N],
    /// How often each (robot, step) started.
    starts: [[u8; 2]; N],
    clocks: [u64; N],
    sends: [u8; N],
    /// (to, from, announcement).
    net: BTreeSet<(usize, usize, [u8; 6])>,
    crashes: u8,
    /// A step started before a step it depends on had completed.
    early_start: bool,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
enum Action {
    /// The robot's control period: the plan may start its next step.
    Poll(usize),
    /// The running step's action completes.
    Complete(usize),
    /// The robot sends its progress announcement to the others.
    Announce(usize),
    Deliver {
        m: (usize, usize, [u8; 6]),
        keep: bool,
    },
    Drop((usize, usize, [u8; 6])),
    /// Reset: the robot restarts from its durable record.
    Crash(usize),
}

struct PlanModel;

fn persist(s: &mut State0, r: usize) {
    if let Some((_, p)) = s.plans[r].take_record() {
        s.durable[r] = Some(p);
    }
}

impl Model for PlanModel {
    type State = State0;
    type Action = Action;

    fn init_states(&self) -> Vec<State0> {
        let mut s = State0 {
            plans: (0..N).map(loaded).collect(),
            durable: vec![None; N],
            completed: [0; N],
            running: [None; N],
            starts: [[0; 2]; N],
            clocks: [0; N],
            sends: [0; N],
            net: BTreeSet::new(),
            crashes: 0,
            early_start: false,
        };
        for r in 0..N {
            persist(&mut s, r);
        }
        vec![s]
    }

    fn actions(&self, s: &State0, out: &mut Vec<Action>) {
        for r in 0..N {
            if s.plans[r].state() == State::Running && s.running[r].is_none() {
                out.push(Action::Poll(r));
            }
            if s.running[r].is_some() {
                out.push(Action::Complete(r));
            }
            if s.sends[r] < max_sends() && s.net.len() + (N - 1) <= MAX_NET {
                out.push(Action::Announce(r));
            }
            if s.crashes < 1 {
                out.push(Action::Crash(r));
            }
        }
        for m in &s.net {
            out.push(Action::Deliver { m: *m, keep: false });
            out.push(Action::Deliver { m: *m, keep: true });
            out.push(Action::Drop(*m));
        }
    }

    fn next_state(&self, s: &State0, a: Action) -> Option<State0> {
        let mut s = s.clone();
        match a {
            Action::Poll(r) => {
                let now = s.clocks[r];
                match s.plans[r].poll(now) {
                    Poll::RunTc { step, .. } => {
                        for d in &deps(r)[usize::from(step)] {
                            if s.completed[usize::from(d.robot) - 1] <= d.step {
                                s.early_start = true;
                            }
                        }
                        s.starts[r][usize::from(step)] += 1;
                        s.running[r] = Some(step);
                    }
                    Poll::Idle | Poll::Waiting { .. } | Poll::Changed(_) => {}
                }
            }
            Action::Complete(r) => {
                let step = s.running[r].take()?;
                s.completed[r] = s.completed[r].max(step + 1);
                let req = u32::from_be_bytes(tc(r, usize::from(step))[..4].try_into().unwrap());
                s.plans[r].outcome(req, true);
            }
            Action::Announce(r) => {
                // Far enough ahead for the period to have passed.
                s.clocks[r] += mib::plan::PROGRESS_PERIOD_MS;
                let a = s.plans[r].announcement(s.clocks[r])?;
                s.sends[r] += 1;
                for to in (0..N).filter(|&t| t != r) {
                    s.net.insert((to, r, a));
                }
            }
            Action::Deliver { m, keep } => {
                if !keep {
                    s.net.remove(&m);
                }
                let (to, from, a) = m;
                s.plans[to].peer_progress(Some(from as u8 + 1), &a);
            }
            Action::Drop(m) => {
                s.net.remove(&m);
            }
            Action::Crash(r) => {
                s.crashes += 1;
                // The action in flight stops with the reset (its completion is lost).
                s.running[r] = None;
                let mut p = Plan::new(r as u8 + 1);
                if let Some(d) = s.durable[r] {
                    p.restore(&image(r), d);
                }
                s.plans[r] = p;
            }
        }
        for r in 0..N {
            persist(&mut s, r);
            // The HK counters grow with every duplicate delivered: not part of the
            // protocol's state (they would make the state space infinite).
            s.plans[r].counters = Default::default();
        }
        Some(s)
    }

    fn properties(&self) -> Vec<Property<Self>> {
        vec![
            Property::always(
                "no step starts before the steps it depends on completed",
                |_, s: &State0| !s.early_start,
            ),
            Property::always("no step starts twice, across resets", |_, s: &State0| {
                s.starts.iter().flatten().all(|&n| n <= 1)
            }),
            Property::sometimes("every robot completes its plan", |_, s: &State0| {
                s.plans.iter().all(|p| p.state() == State::Completed)
            }),
        ]
    }
}

// verifies: PLAN-MODEL-01
#[test]
fn the_dependency_protocol_holds_under_loss_duplication_reordering_and_a_reset() {
    let checker = PlanModel.checker().spawn_bfs().join();
    let states = checker.unique_state_count();
    eprintln!("plan dependency model: {states} states explored");
    checker.assert_properties();
    assert!(states > 1_000, "{states} states: the model explores little");
}
