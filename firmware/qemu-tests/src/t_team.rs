//! Leader selection (`mmic-team`) on the target: three robots' state machines exchange their
//! messages through the firmware's team transport (`fw_core::team::TeamIo` over
//! `TeamTransport`), here a mock radio per robot (every message emitted to bytes and
//! parsed back, as the radio will carry them) on a simulated clock. The ground goes
//! silent; one leader is elected, every robot is ordered to hold; the ground returns and
//! the leader steps down.

use crate::harness::{Test, TestResult};
use crate::mock::{MockRadio, RADIO_QUEUE};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::team::{TeamIo, TeamTransport, TransportError};
use heapless::Vec;
use mmic_team::wire::MAX_LEN;
use mmic_team::{Action, Dest, Effect, Input, Message, Node, Role};

pub const TESTS: &[Test] = tests![
    team_three_robots_elect_one_leader_hold_and_yield_to_the_ground,
    team_transport_refuses_and_counts_what_it_cannot_carry,
];

const N: usize = 3;
const ROSTER: [u8; N] = [1, 2, 3];
struct Team {
    nodes: [Node; N],
    holds: [u32; N],
    persists: u32,
    /// Each robot's team transport: a mock radio behind the firmware's counters.
    radios: [TeamIo<MockRadio>; N],
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
        if self.radios[from].send(to, &buf[..n]).is_err() {
            self.lost += 1;
        }
    }

    /// The medium: every sent datagram reaches the radios it is addressed to.
    fn carry(&mut self) {
        for from in 0..N {
            while let Some((to, (bytes, n))) = self.radios[from].transport.take_sent() {
                for (j, id) in ROSTER.iter().enumerate() {
                    let wanted = match to {
                        Dest::All => j != from,
                        Dest::To(r) => r == *id,
                    };
                    if wanted && self.radios[j].transport.deliver(&bytes[..n]).is_err() {
                        self.lost += 1;
                    }
                }
            }
        }
    }

    /// Carries what was sent, hands each robot what its transport received, then ticks
    /// every robot.
    fn step(&mut self, now: u64) {
        self.carry();
        for j in 0..N {
            let mut got: Vec<([u8; MAX_LEN], usize), RADIO_QUEUE> = Vec::new();
            let mut buf = [0u8; MAX_LEN];
            self.radios[j].poll(&mut buf, RADIO_QUEUE, |p| {
                let mut d = [0u8; MAX_LEN];
                d[..p.len()].copy_from_slice(p);
                let _ = got.push((d, p.len()));
            });
            for (bytes, n) in got {
                match Message::parse(&bytes[..n]) {
                    Ok(m) => self.run(j, now, Input::Message(m)),
                    Err(_) => self.lost += 1,
                }
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

// verifies: FW-TEAM-01, FW-TEAM-02
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
        radios: [
            TeamIo::new(MockRadio::new()),
            TeamIo::new(MockRadio::new()),
            TeamIo::new(MockRadio::new()),
        ],
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
    // Everything went through the transports, nothing refused or lost on the way.
    let sum = |f: fn(&fw_core::team::TeamCounters) -> u32| t.radios.iter().map(|r| f(&r.counters)).sum::<u32>();
    check!(sum(|c| c.sent) > 0);
    check!(
        sum(|c| c.received) >= sum(|c| c.sent),
        "every packet goes to at least one robot"
    );
    check_eq!((sum(|c| c.send_errors), sum(|c| c.receive_errors)), (0, 0));
    Ok(())
}

// verifies: FW-TEAM-01
fn team_transport_refuses_and_counts_what_it_cannot_carry() -> TestResult {
    let mut io = TeamIo::new(MockRadio::new());
    // Longer than a datagram: refused with the sizes, counted, nothing queued.
    let big = [0u8; MAX_LEN + 1];
    check_eq!(
        io.send(Dest::All, &big),
        Err(TransportError::TooLong {
            len: MAX_LEN + 1,
            max: <MockRadio as TeamTransport>::MAX_PACKET
        })
    );
    check!(io.transport.take_sent().is_none());
    // A full transmit queue refuses the next packet.
    for k in 0..RADIO_QUEUE {
        check!(io.send(Dest::To(2), &[k as u8; 4]).is_ok());
    }
    check_eq!(io.send(Dest::To(2), &[0xEE; 4]), Err(TransportError::Full));
    check_eq!((io.counters.sent, io.counters.send_errors), (RADIO_QUEUE as u32, 2));
    // Packets come out in order; one longer than the receive buffer is consumed,
    // refused and counted, and the next one still arrives.
    check!(io.transport.deliver(&[1, 2, 3]).is_ok());
    check!(MAX_LEN > 8, "team datagram of {} bytes", MAX_LEN);
    check!(io.transport.deliver(&[9; 9]).is_ok());
    check!(io.transport.deliver(&[4, 5]).is_ok());
    let mut small = [0u8; 8];
    let mut got: Vec<(u8, usize), 4> = Vec::new();
    let n = io.poll(&mut small, 8, |p| {
        let _ = got.push((p[0], p.len()));
    });
    check_eq!(n, 2);
    check_eq!(got.as_slice(), &[(1, 3), (4, 2)]);
    check_eq!((io.counters.received, io.counters.receive_errors), (2, 1));
    // At most `limit` packets per poll: a flooding peer cannot hold the control period.
    for _ in 0..5 {
        check!(io.transport.deliver(&[7]).is_ok());
    }
    check_eq!(io.poll(&mut small, 3, |_| {}), 3);
    check_eq!(io.poll(&mut small, 3, |_| {}), 2);
    Ok(())
}
