//! Leader selection (`mmic-team`) on the target: three robots' state machines exchange their
//! messages through a mock inter-robot transport (every message emitted to bytes and parsed
//! back, as the radio will carry them) on a simulated clock. The ground goes silent; one
//! leader is elected, every robot is ordered to hold; the ground returns and the leader
//! steps down.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use heapless::Vec;
use mmic_team::wire::MAX_LEN;
use mmic_team::{Action, Dest, Effect, Input, Message, Node, Role};

pub const TESTS: &[Test] = tests![team_three_robots_elect_one_leader_hold_and_yield_to_the_ground];

const N: usize = 3;
const ROSTER: [u8; N] = [1, 2, 3];
/// Datagrams in flight on the mock link: (destination index, bytes, length).
type Air = Vec<(usize, [u8; MAX_LEN], usize), 64>;

struct Team {
    nodes: [Node; N],
    holds: [u32; N],
    persists: u32,
    air: Air,
    lost: u32,
    rand: u32,
}

impl Team {
    fn rand(&mut self) -> u32 {
        // xorshift32: deterministic randomness for the election timeouts.
        self.rand ^= self.rand << 13;
        self.rand ^= self.rand >> 17;
        self.rand ^= self.rand << 5;
        self.rand
    }

    fn run(&mut self, i: usize, now: u64, input: Input) {
        let r = self.rand();
        let effects = self.nodes[i].on_event(now, r, input);
        for e in effects {
            match e {
                Effect::Persist(_) => self.persists += 1,
                Effect::Send { to, msg } => self.send(i, to, &msg),
                Effect::Act(Action::Hold(_)) => self.holds[i] += 1,
                Effect::Act(Action::Continue { .. }) | Effect::Event(_) => {}
            }
        }
    }

    fn send(&mut self, from: usize, to: Dest, msg: &Message) {
        let mut buf = [0u8; MAX_LEN];
        let Ok(n) = msg.emit(&mut buf) else {
            self.lost += 1;
            return;
        };
        for (j, id) in ROSTER.iter().enumerate() {
            let wanted = match to {
                Dest::All => j != from,
                Dest::To(r) => r == *id,
            };
            if wanted && self.air.push((j, buf, n)).is_err() {
                self.lost += 1;
            }
        }
    }

    /// Delivers what is in the air, then ticks every robot.
    fn step(&mut self, now: u64) {
        let air = core::mem::take(&mut self.air);
        for (j, bytes, n) in air {
            match Message::parse(&bytes[..n]) {
                Ok(m) => self.run(j, now, Input::Message(m)),
                Err(_) => self.lost += 1,
            }
        }
        for i in 0..N {
            self.run(i, now, Input::Tick);
        }
    }

    fn leaders(&self) -> usize {
        self.nodes.iter().filter(|n| n.role() == Role::Leader).count()
    }
}

fn team_three_robots_elect_one_leader_hold_and_yield_to_the_ground() -> TestResult {
    let nodes = [
        ok!(Node::new(1, &ROSTER, 0).ok()),
        ok!(Node::new(2, &ROSTER, 0).ok()),
        ok!(Node::new(3, &ROSTER, 0).ok()),
    ];
    let mut t = Team {
        nodes,
        holds: [0; N],
        persists: 0,
        air: Vec::new(),
        lost: 0,
        rand: 0x2545_F491,
    };
    for i in 0..N {
        t.run(i, 0, Input::GroundTc);
    }
    // The ground goes silent: step 10 ms at a time until every robot follows one leader.
    let mut now = 0u64;
    let mut elected_at = None;
    while now < 30_000 {
        now += 10;
        t.step(now);
        check!(t.leaders() <= 1, "two leaders at {} ms", now);
        let leader = t.nodes[0].leader();
        if t.leaders() == 1 && leader.is_some() && t.nodes.iter().all(|n| n.leader() == leader) {
            elected_at = Some(now);
            break;
        }
    }
    let at = ok!(elected_at);
    let ground_loss = mib::team::GROUND_LOSS_TIMEOUT_MS;
    check!(
        at > ground_loss,
        "a leader at {} ms, before the ground-loss time {}",
        at,
        ground_loss
    );
    check!(
        at - ground_loss <= 3_500,
        "leader {} ms after the ground-loss time",
        at - ground_loss
    );
    // Terms were persisted before votes went out; every robot is ordered to hold.
    check!(t.persists >= 2);
    for _ in 0..50 {
        now += 10;
        t.step(now);
    }
    check!(t.holds.iter().all(|&h| h > 0), "holds per robot: {:?}", t.holds);
    check_eq!(t.lost, 0);
    // The ground returns: each robot's first valid ground TC ends its obedience.
    for i in 0..N {
        t.run(i, now, Input::GroundTc);
    }
    for _ in 0..20 {
        now += 10;
        t.step(now);
    }
    check_eq!(t.leaders(), 0);
    check!(t.nodes.iter().all(|n| n.ground_seen()));
    Ok(())
}
