//! Unit tests of the team state machine on a mock clock (time is a number we advance).

use super::*;
use crate::wire::{Directive, TeamFunction};
use std::collections::VecDeque;

const PLAN: PlanRef = PlanRef {
    id: 7,
    hash: 0xABCD_0123,
};
const LOST: u64 = GROUND_LOSS_TIMEOUT_MS;

fn node(me: RobotId, roster: &[RobotId]) -> Node {
    let mut n = Node::new(me, roster, 0).unwrap();
    n.on_event(
        0,
        0,
        Input::Progress {
            plan: PLAN,
            progress: 0,
            next: Some(TeamFunction::BoltPair),
        },
    );
    n
}

fn sends(e: &Effects) -> std::vec::Vec<(Dest, Message)> {
    e.iter()
        .filter_map(|e| match e {
            Effect::Send { to, msg } => Some((*to, *msg)),
            _ => None,
        })
        .collect()
}

fn events(e: &Effects) -> std::vec::Vec<TeamEvent> {
    e.iter()
        .filter_map(|e| match e {
            Effect::Event(ev) => Some(*ev),
            _ => None,
        })
        .collect()
}

fn actions(e: &Effects) -> std::vec::Vec<Action> {
    e.iter()
        .filter_map(|e| match e {
            Effect::Act(a) => Some(*a),
            _ => None,
        })
        .collect()
}

fn msg(term: u32, sender: RobotId, progress: u16, body: Body) -> Message {
    Message {
        term,
        sender,
        plan: PLAN,
        progress,
        body,
    }
}

/// Instant, lossless delivery between nodes, with a drop filter `(from, to) -> bool`.
struct Cluster {
    nodes: std::vec::Vec<Node>,
    queue: VecDeque<(usize, Message)>,
    now: u64,
    effects: std::vec::Vec<(RobotId, Effect)>,
}

impl Cluster {
    fn new(n: u8) -> Cluster {
        let roster: std::vec::Vec<RobotId> = (1..=n).collect();
        Cluster {
            nodes: roster.iter().map(|r| node(*r, &roster)).collect(),
            queue: VecDeque::new(),
            now: 0,
            effects: std::vec::Vec::new(),
        }
    }
    fn idx(&self, r: RobotId) -> usize {
        self.nodes.iter().position(|n| n.me() == r).unwrap()
    }
    fn feed(&mut self, i: usize, rand: u32, input: Input) {
        let me = self.nodes[i].me();
        let eff = self.nodes[i].on_event(self.now, rand, input);
        for e in eff {
            if let Effect::Send { to, msg } = e {
                for j in 0..self.nodes.len() {
                    let target = self.nodes[j].me();
                    if target != me && (to == Dest::All || to == Dest::To(target)) {
                        self.queue.push_back((j, msg));
                    }
                }
            }
            self.effects.push((me, e));
        }
    }
    /// Advance to `until` in 10 ms steps; robot `i` draws `rand = i * 300` so the first
    /// robot times out first; `up(i)` says whether robot i is connected.
    fn run(&mut self, until: u64, up: &dyn Fn(usize) -> bool) {
        while self.now < until {
            self.now += 10;
            for i in 0..self.nodes.len() {
                if up(i) {
                    self.feed(i, i as u32 * 300, Input::Tick);
                }
            }
            while let Some((j, m)) = self.queue.pop_front() {
                let from = self.idx(m.sender);
                if up(j) && up(from) {
                    self.feed(j, j as u32 * 300, Input::Message(m));
                }
            }
        }
    }
    fn leaders(&self) -> std::vec::Vec<RobotId> {
        self.nodes
            .iter()
            .filter(|n| n.role() == Role::Leader)
            .map(|n| n.me())
            .collect()
    }
}

fn all(_: usize) -> bool {
    true
}

// verifies: TEAM-GROUND-01
#[test]
fn ground_loss_is_detected_after_the_mib_timeout_and_the_robot_holds() {
    let mut n = node(1, &[1, 2, 3]);
    n.on_event(0, 0, Input::Grippers { both_hold: true });
    assert!(n.on_event(LOST - 1, 0, Input::Tick).is_empty());
    assert!(n.ground_seen());
    // A ground TC restarts the count.
    n.on_event(LOST - 1, 0, Input::GroundTc);
    assert!(n.on_event(LOST + 100, 0, Input::Tick).is_empty());
    let e = n.on_event(2 * LOST, 0, Input::Tick);
    assert_eq!(events(&e), vec![TeamEvent::GroundLost]);
    assert_eq!(actions(&e), vec![Action::Hold(HoldTarget::Standby)]);
    assert!(!n.ground_seen());
    // Robot 1 is first in the roster: it stands after the first-election base (+ jitter).
    assert!(n
        .on_event(2 * LOST + ELECTION_FIRST_BASE_MS - 1, 0, Input::Tick)
        .is_empty());
    let e = n.on_event(2 * LOST + ELECTION_FIRST_BASE_MS, 0, Input::Tick);
    assert_eq!(events(&e), vec![TeamEvent::ElectionStarted { term: 1 }]);
}

// verifies: TEAM-GROUND-01
#[test]
fn holding_without_both_grippers_means_safed() {
    let mut n = node(1, &[1, 2]);
    let e = n.on_event(LOST, 0, Input::Tick);
    assert_eq!(actions(&e), vec![Action::Hold(HoldTarget::Safed)]);
}

// verifies: TEAM-ELECT-02
#[test]
fn election_timeouts_are_staggered_by_rank_and_randomised() {
    for (me, rank) in [(1u8, 0u64), (3, 2)] {
        let mut seen = std::collections::BTreeSet::new();
        for rand in [0u32, 1, 499, 999, 1_000, u32::MAX, 123_456_789] {
            let mut n = node(me, &[1, 2, 3]);
            n.on_event(LOST, rand, Input::Tick);
            // First election after the ground loss.
            let d = n.next_deadline() - LOST;
            let lo = ELECTION_FIRST_BASE_MS + rank * ELECTION_RANK_STAGGER_MS;
            assert!((lo..lo + ELECTION_JITTER_MS).contains(&d), "{d}");
            seen.insert(d);
            // After a failed candidacy: the full timeout.
            let t = LOST + d;
            n.on_event(t, rand, Input::Tick);
            assert_eq!(n.role(), Role::Candidate);
            let lo = ELECTION_TIMEOUT_MIN_MS + rank * ELECTION_RANK_STAGGER_MS;
            assert_eq!(n.term(), 1);
            let mut k = t;
            while n.term() == 1 {
                k += 1;
                n.on_event(k, rand, Input::Tick);
            }
            assert!((lo..lo + ELECTION_JITTER_MS).contains(&(k - t)), "{}", k - t);
            assert!(k - t < mib::team::ELECTION_TIMEOUT_MAX_MS);
        }
        assert!(seen.len() >= 5, "the random input must spread the timeout: {seen:?}");
    }
}

// verifies: TEAM-PERSIST-01
#[test]
fn term_and_vote_are_persisted_before_any_send() {
    // Candidate: Persist{1, self} first, then the vote request.
    let mut a = node(1, &[1, 2, 3]);
    a.on_event(LOST, 0, Input::Tick);
    let e = a.on_event(LOST + ELECTION_TIMEOUT_MIN_MS, 0, Input::Tick);
    assert_eq!(
        e[0],
        Effect::Persist(Persisted {
            term: 1,
            voted_for: Some(1)
        })
    );
    assert!(e[1..].iter().all(|e| !matches!(e, Effect::Persist(_))));
    assert_eq!(sends(&e).len(), 1);

    // Voter: Persist{1, candidate} first, then the granted vote.
    let mut b = node(2, &[1, 2, 3]);
    b.on_event(LOST, 0, Input::Tick);
    let t = LOST + ELECTION_TIMEOUT_MIN_MS;
    let e = b.on_event(t, 5, Input::Message(msg(1, 1, 0, Body::RequestVote)));
    assert_eq!(
        e[0],
        Effect::Persist(Persisted {
            term: 1,
            voted_for: Some(1)
        })
    );
    let s = sends(&e);
    assert_eq!(s.len(), 1);
    assert_eq!(s[0].0, Dest::To(1));
    assert_eq!(
        s[0].1.body,
        Body::Vote {
            candidate: 1,
            granted: true
        }
    );
    // A repeated request in the same term changes nothing durable: no Persist, same vote.
    let e = b.on_event(t + 1, 5, Input::Message(msg(1, 1, 0, Body::RequestVote)));
    assert!(!matches!(e[0], Effect::Persist(_)));
}

// verifies: TEAM-PERSIST-02
#[test]
fn a_crash_after_persisting_a_vote_never_allows_a_second_vote_in_that_term() {
    let mut b = node(2, &[1, 2, 3]);
    b.on_event(LOST, 0, Input::Tick);
    let t = LOST + ELECTION_TIMEOUT_MIN_MS;
    let e = b.on_event(t, 0, Input::Message(msg(1, 1, 0, Body::RequestVote)));
    let Effect::Persist(p) = e[0] else {
        panic!("no persist first: {e:?}")
    };
    // Crash before the vote is sent: restart from what was persisted.
    let mut b = Node::restore(2, &[1, 2, 3], p, t + 1).unwrap();
    b.on_event(
        t + 1,
        0,
        Input::Progress {
            plan: PLAN,
            progress: 0,
            next: None,
        },
    );
    b.on_event(t + 1 + LOST, 0, Input::Tick); // ground lost again after boot
    let e = b.on_event(t + 2 + LOST, 0, Input::Message(msg(1, 3, 0, Body::RequestVote)));
    let s = sends(&e);
    assert_eq!(
        s[0].1.body,
        Body::Vote {
            candidate: 3,
            granted: false
        }
    );
    // The original candidate still gets its vote again.
    let e = b.on_event(t + 3 + LOST, 0, Input::Message(msg(1, 1, 0, Body::RequestVote)));
    assert_eq!(
        sends(&e)[0].1.body,
        Body::Vote {
            candidate: 1,
            granted: true
        }
    );
}

// verifies: TEAM-PERSIST-02
#[test]
fn a_restarted_robot_does_not_vote_before_an_election_timeout() {
    let mut b = Node::restore(
        2,
        &[1, 2, 3],
        Persisted {
            term: 4,
            voted_for: None,
        },
        0,
    )
    .unwrap();
    assert_eq!(b.term(), 4);
    b.on_event(
        0,
        0,
        Input::Progress {
            plan: PLAN,
            progress: 0,
            next: None,
        },
    );
    // Ground "lost" at boot + LOST; the boot counts as leader contact only for
    // ELECTION_TIMEOUT_MIN, which LOST exceeds: the vote is granted then.
    b.on_event(LOST, 0, Input::Tick);
    let e = b.on_event(LOST, 0, Input::Message(msg(5, 1, 0, Body::RequestVote)));
    assert!(sends(&e).iter().any(|(_, m)| m.body
        == Body::Vote {
            candidate: 1,
            granted: true
        }));
}

// verifies: TEAM-QUORUM-01
#[test]
fn a_majority_of_the_roster_is_needed_to_lead() {
    let mut a = node(1, &[1, 2, 3, 4, 5]);
    a.on_event(LOST, 0, Input::Tick);
    let t = LOST + ELECTION_TIMEOUT_MIN_MS;
    a.on_event(t, 0, Input::Tick);
    assert_eq!(a.role(), Role::Candidate);
    let grant = |from| {
        Input::Message(msg(
            1,
            from,
            0,
            Body::Vote {
                candidate: 1,
                granted: true,
            },
        ))
    };
    a.on_event(t + 1, 0, grant(2));
    // A refusal and a duplicate grant do not count.
    a.on_event(
        t + 2,
        0,
        Input::Message(msg(
            1,
            3,
            0,
            Body::Vote {
                candidate: 1,
                granted: false,
            },
        )),
    );
    a.on_event(t + 3, 0, grant(2));
    // A vote for another candidate does not count either.
    a.on_event(
        t + 4,
        0,
        Input::Message(msg(
            1,
            4,
            0,
            Body::Vote {
                candidate: 5,
                granted: true,
            },
        )),
    );
    assert_eq!(a.role(), Role::Candidate);
    let e = a.on_event(t + 5, 0, grant(4));
    assert_eq!(a.role(), Role::Leader);
    assert!(events(&e).contains(&TeamEvent::LeaderElected { term: 1, leader: 1 }));
    // The new leader's first heartbeat goes out at once, with HOLD (no authorisation).
    assert!(sends(&e).iter().any(|(to, m)| *to == Dest::All
        && matches!(
            m.body,
            Body::LeaderHeartbeat {
                directive: Directive::Hold,
                ..
            }
        )));
}

// verifies: TEAM-QUORUM-02
#[test]
fn a_team_of_two_has_no_leader_without_both_and_each_robot_holds() {
    let mut c = Cluster::new(2);
    // Robot 2 is cut off: robot 1 stands again and again but never leads.
    c.run(LOST + 20_000, &|i| i == 0);
    assert!(c.leaders().is_empty());
    assert!(c.nodes[0].term() >= 5, "it keeps standing");
    assert!(c
        .effects
        .iter()
        .any(|(r, e)| *r == 1 && matches!(e, Effect::Act(Action::Hold(_)))));
    // Both connected: a leader.
    let mut c = Cluster::new(2);
    c.run(LOST + 5_000, &all);
    assert_eq!(c.leaders().len(), 1);
}

// verifies: TEAM-QUORUM-01, TEAM-ELECT-01
#[test]
fn three_robots_elect_one_leader_and_a_minority_never_leads() {
    let mut c = Cluster::new(3);
    c.run(LOST + 5_000, &all);
    assert_eq!(c.leaders(), vec![1]);
    let term = c.nodes[0].term();
    for n in &c.nodes {
        assert_eq!(n.leader(), Some(1));
        assert_eq!(n.term(), term);
    }
    // Robot 1 is cut off: it steps down (no quorum), robots 2 and 3 elect one of them.
    c.run(LOST + 15_000, &|i| i != 0);
    assert_eq!(c.nodes[0].role(), Role::Leader, "cut off, robot 1 did not tick");
    let l = c.leaders();
    assert!(l.contains(&2) || l.contains(&3));
    assert!(c.nodes[1].term() > term);
}

// verifies: TEAM-VOTE-01
#[test]
fn votes_only_for_the_same_plan_and_at_least_the_voters_progress() {
    let mut b = node(2, &[1, 2, 3]);
    b.on_event(
        0,
        0,
        Input::Progress {
            plan: PLAN,
            progress: 3,
            next: None,
        },
    );
    b.on_event(LOST, 0, Input::Tick);
    let t = LOST + 10;
    let ask = |term, progress, plan: PlanRef| {
        Input::Message(Message {
            plan,
            ..msg(term, 1, progress, Body::RequestVote)
        })
    };
    let granted = |e: &Effects| match sends(e)[0].1.body {
        Body::Vote { granted, .. } => granted,
        other => panic!("{other:?}"),
    };
    // Other hash, same ID: refused.
    let e = b.on_event(t, 0, ask(1, 5, PlanRef { id: 7, hash: 1 }));
    assert!(!granted(&e));
    // Other plan ID: refused.
    let e = b.on_event(t, 0, ask(2, 5, PlanRef { id: 8, ..PLAN }));
    assert!(!granted(&e));
    // Less progress: refused.
    let e = b.on_event(t, 0, ask(3, 2, PLAN));
    assert!(!granted(&e));
    // Same plan, equal progress: granted.
    let e = b.on_event(t, 0, ask(4, 3, PLAN));
    assert!(granted(&e));
    // After a grant the robot ignores requests for an election timeout.
    assert!(sends(&b.on_event(t + 1, 0, ask(5, 9, PLAN))).is_empty());
    // More progress: granted (term 5).
    let t = t + ELECTION_TIMEOUT_MIN_MS;
    let e = b.on_event(t, 0, ask(5, 9, PLAN));
    assert!(granted(&e));
    // A stale term is refused.
    let t = t + ELECTION_TIMEOUT_MIN_MS;
    let e = b.on_event(t, 0, ask(4, 9, PLAN));
    assert!(!granted(&e));
}

// verifies: TEAM-VOTE-02
#[test]
fn a_robot_that_heard_its_leader_recently_ignores_candidates() {
    let mut b = node(2, &[1, 2, 3]);
    b.on_event(LOST, 0, Input::Tick);
    let t = LOST + 3_000;
    let hb = msg(
        1,
        1,
        0,
        Body::LeaderHeartbeat {
            stamp: 0,
            directive: Directive::Hold,
        },
    );
    b.on_event(t, 0, Input::Message(hb));
    assert_eq!(b.leader(), Some(1));
    let e = b.on_event(t + 500, 0, Input::Message(msg(2, 3, 0, Body::RequestVote)));
    assert!(sends(&e).is_empty());
    assert_eq!(b.term(), 1, "the candidate's term is not even adopted");
    // After an election timeout without the leader, the candidate gets the vote.
    let e = b.on_event(
        t + ELECTION_TIMEOUT_MIN_MS,
        0,
        Input::Message(msg(2, 3, 0, Body::RequestVote)),
    );
    assert!(sends(&e).iter().any(|(_, m)| m.body
        == Body::Vote {
            candidate: 3,
            granted: true
        }));
}

// verifies: TEAM-ELECT-01
#[test]
fn a_robot_in_contact_with_the_ground_neither_stands_nor_votes() {
    let mut b = node(2, &[1, 2, 3]);
    for t in (0..30_000).step_by(1_000) {
        b.on_event(t, 0, Input::GroundTc);
        let e = b.on_event(t + 1, 0, Input::Message(msg(1, 1, 0, Body::RequestVote)));
        assert!(sends(&e).is_empty());
        assert!(events(&e).is_empty());
    }
    assert_eq!(b.role(), Role::Follower);
    assert_eq!(b.term(), 0);
}

/// A leader (robot 1) of a 3-robot team at time `t`, fully acknowledged.
fn leader_with_acks() -> (Node, u64) {
    let mut a = node(1, &[1, 2, 3]);
    a.on_event(LOST, 0, Input::Tick);
    let t = LOST + ELECTION_TIMEOUT_MIN_MS;
    a.on_event(t, 0, Input::Tick);
    a.on_event(
        t + 10,
        0,
        Input::Message(msg(
            1,
            2,
            0,
            Body::Vote {
                candidate: 1,
                granted: true,
            },
        )),
    );
    assert_eq!(a.role(), Role::Leader);
    (a, t + 10)
}

fn ack(term: u32, from: RobotId, stamp: u64) -> Input {
    Input::Message(msg(
        term,
        from,
        0,
        Body::HeartbeatAck {
            stamp: stamp as u32,
            ok: true,
        },
    ))
}

fn directives(e: &Effects) -> std::vec::Vec<Directive> {
    sends(e)
        .iter()
        .filter_map(|(_, m)| match m.body {
            Body::LeaderHeartbeat { directive, .. } => Some(directive),
            _ => None,
        })
        .collect()
}

fn auth(now: u64) -> Authorisation {
    Authorisation {
        plan: PLAN,
        first_step: 1,
        max_steps: 2,
        expires_at: now + 60_000,
    }
}

// verifies: TEAM-LEASE-01, TEAM-AUTH-02
#[test]
fn continue_needs_the_lease_and_the_lease_expires() {
    let (mut a, t) = leader_with_acks();
    a.authorise(t, auth(t)).unwrap();
    // Fresh acknowledgement from robot 2: CONTINUE step 1 at the next heartbeat.
    let e = a.on_event(t + 5, 0, ack(1, 2, t));
    assert!(directives(&e).is_empty());
    let e = a.on_event(t + HEARTBEAT_PERIOD_MS, 0, Input::Tick);
    assert_eq!(
        directives(&e),
        vec![Directive::Continue {
            step: 1,
            function: TeamFunction::BoltPair
        }]
    );
    assert!(a.status(t + HEARTBEAT_PERIOD_MS).lease);
    // The leader executes it itself too.
    assert!(actions(&e).contains(&Action::Continue {
        plan: PLAN,
        step: 1,
        function: TeamFunction::BoltPair
    }));
    // One more acknowledgement, of a heartbeat stamped t + 250; then none. The lease
    // runs to t + 250 + LEADER_LEASE_MS, the quorum to t + 250 + ELECTION_TIMEOUT_MIN_MS.
    a.on_event(t + 260, 0, ack(1, 2, t + 250));
    let mut now = t + HEARTBEAT_PERIOD_MS;
    while now + HEARTBEAT_PERIOD_MS < t + 250 + LEADER_LEASE_MS {
        now += HEARTBEAT_PERIOD_MS;
        for d in directives(&a.on_event(now, 0, Input::Tick)) {
            assert!(matches!(d, Directive::Continue { .. }), "{now}");
        }
    }
    now += HEARTBEAT_PERIOD_MS;
    assert!(now >= t + 250 + LEADER_LEASE_MS && now < t + 250 + LEADER_QUORUM_CHECK_MS);
    assert_eq!(directives(&a.on_event(now, 0, Input::Tick)), vec![Directive::Hold]);
    assert!(!a.status(now).lease);
    assert_eq!(a.role(), Role::Leader);
    // HOLD goes on until the quorum check fails; then it steps down.
    while now + HEARTBEAT_PERIOD_MS < t + 250 + LEADER_QUORUM_CHECK_MS {
        now += HEARTBEAT_PERIOD_MS;
        assert_eq!(directives(&a.on_event(now, 0, Input::Tick)), vec![Directive::Hold]);
    }
    let e = a.on_event(t + 250 + LEADER_QUORUM_CHECK_MS, 0, Input::Tick);
    assert_eq!(a.role(), Role::Follower);
    assert!(events(&e).contains(&TeamEvent::SteppedDown {
        term: 1,
        reason: StepDownReason::QuorumLost
    }));
}

// verifies: TEAM-AUTH-01
#[test]
fn without_an_authorisation_the_leader_only_orders_hold() {
    let (mut a, t) = leader_with_acks();
    let mut now = t;
    for _ in 0..20 {
        now += HEARTBEAT_PERIOD_MS;
        a.on_event(now, 0, ack(1, 2, now - 1));
        for d in directives(&a.on_event(now, 0, Input::Tick)) {
            assert_eq!(d, Directive::Hold);
        }
    }
    assert!(a.status(now).lease);
}

// verifies: TEAM-AUTH-02, TEAM-AUTH-03
#[test]
fn authorisation_limits_steps_expiry_and_unbolt() {
    let (mut a, t) = leader_with_acks();
    // Upload checks.
    let mut bad = auth(t);
    bad.max_steps = mib::team::MAX_AUTHORISED_STEPS + 1;
    assert_eq!(a.authorise(t, bad), Err(AuthError::TooManySteps(bad.max_steps)));
    bad.max_steps = 0;
    assert_eq!(a.authorise(t, bad), Err(AuthError::NoSteps));
    bad = auth(t);
    bad.expires_at = t + MAX_AUTHORISATION_MS + 1;
    assert_eq!(a.authorise(t, bad), Err(AuthError::ExpiryTooFar));
    bad.expires_at = t;
    assert_eq!(a.authorise(t, bad), Err(AuthError::AlreadyExpired));
    a.authorise(t, auth(t)).unwrap();
    let step = |a: &mut Node, now: u64, progress: u16, next: Option<TeamFunction>| {
        a.on_event(now, 0, ack(1, 2, now));
        a.on_event(
            now,
            0,
            Input::Progress {
                plan: PLAN,
                progress,
                next,
            },
        );
        directives(&a.on_event(now + HEARTBEAT_PERIOD_MS, 0, Input::Tick))
    };
    let f = Some(TeamFunction::MoveArm);
    let mut now = t;
    now += 1_000;
    assert_eq!(
        step(&mut a, now, 1, f),
        vec![Directive::Continue {
            step: 2,
            function: TeamFunction::MoveArm
        }]
    );
    // Step 3 is beyond the 2 authorised steps.
    now += 1_000;
    assert_eq!(step(&mut a, now, 2, f), vec![Directive::Hold]);
    // The next step is an unbolt (the host passes `next: None`): HOLD.
    let mut a2 = leader_with_acks().0;
    a2.authorise(t, auth(t)).unwrap();
    assert_eq!(step(&mut a2, t + 1_000, 0, None), vec![Directive::Hold]);
    // Expired authorisation: HOLD.
    let mut a3 = leader_with_acks().0;
    a3.authorise(
        t,
        Authorisation {
            expires_at: t + 500,
            ..auth(t)
        },
    )
    .unwrap();
    assert_eq!(step(&mut a3, t + 1_000, 0, f), vec![Directive::Hold]);
}

fn follower() -> (Node, u64) {
    let mut b = node(2, &[1, 2, 3]);
    b.on_event(
        0,
        0,
        Input::Progress {
            plan: PLAN,
            progress: 0,
            next: Some(TeamFunction::BoltPair),
        },
    );
    b.on_event(LOST, 0, Input::Tick);
    (b, LOST + 10)
}

fn hb(term: u32, directive: Directive) -> Input {
    Input::Message(msg(term, 1, 0, Body::LeaderHeartbeat { stamp: 0, directive }))
}

const STEP1: Directive = Directive::Continue {
    step: 1,
    function: TeamFunction::BoltPair,
};

// verifies: TEAM-AUTH-02
#[test]
fn a_follower_checks_continue_against_its_own_authorisation() {
    let (mut b, t) = follower();
    // No authorisation on the follower: refused even from the legitimate leader.
    let e = b.on_event(t, 0, hb(1, STEP1));
    assert!(actions(&e).is_empty());
    assert!(events(&e).contains(&TeamEvent::DirectiveRefused {
        term: 1,
        from: 1,
        reason: RefuseReason::NotAuthorised
    }));
    // Repeated refusals are counted, the event is raised once.
    let e = b.on_event(t + 200, 0, hb(1, STEP1));
    assert!(events(&e).is_empty());
    assert_eq!(b.counters().refused, 2);
    b.authorise(t, auth(t)).unwrap();
    let e = b.on_event(t + 400, 0, hb(1, STEP1));
    assert_eq!(
        actions(&e),
        vec![Action::Continue {
            plan: PLAN,
            step: 1,
            function: TeamFunction::BoltPair
        }]
    );
    // Executed once per term, not at every heartbeat.
    assert!(actions(&b.on_event(t + 600, 0, hb(1, STEP1))).is_empty());
    // A different function for the step than the robot's own plan: refused.
    let (mut c, t) = follower();
    c.authorise(t, auth(t)).unwrap();
    let e = c.on_event(
        t,
        0,
        hb(
            1,
            Directive::Continue {
                step: 1,
                function: TeamFunction::Home,
            },
        ),
    );
    assert!(actions(&e).is_empty());
    // A step that is not the next one: refused.
    let e = c.on_event(
        t,
        0,
        hb(
            1,
            Directive::Continue {
                step: 2,
                function: TeamFunction::BoltPair,
            },
        ),
    );
    assert!(actions(&e).is_empty());
    assert!(events(&e).contains(&TeamEvent::DirectiveRefused {
        term: 1,
        from: 1,
        reason: RefuseReason::WrongStep
    }));
}

// verifies: TEAM-STALE-01
#[test]
fn a_directive_from_a_stale_term_is_never_executed() {
    let (mut b, t) = follower();
    b.authorise(t, auth(t)).unwrap();
    // The robot is in term 3 (it voted for robot 3).
    b.on_event(t, 0, Input::Message(msg(3, 3, 0, Body::RequestVote)));
    assert_eq!(b.term(), 3);
    // The old leader of term 2 orders HOLD and CONTINUE: both refused, it is told the term.
    for d in [Directive::Hold, STEP1] {
        let e = b.on_event(t + 10, 0, hb(2, d));
        assert!(actions(&e).is_empty(), "{e:?}");
        let s = sends(&e);
        assert_eq!(s.len(), 1);
        assert_eq!(s[0].1.term, 3);
        assert!(matches!(s[0].1.body, Body::HeartbeatAck { ok: false, .. }));
    }
    assert!(
        events(&b.on_event(t + 20, 0, hb(1, STEP1))).contains(&TeamEvent::DirectiveRefused {
            term: 1,
            from: 1,
            reason: RefuseReason::StaleTerm
        })
    );
    // The stale leader steps down when it hears of the newer term.
    let (mut a, t) = leader_with_acks();
    let e = a.on_event(
        t + 10,
        0,
        Input::Message(msg(3, 2, 0, Body::HeartbeatAck { stamp: 0, ok: false })),
    );
    assert_eq!(a.role(), Role::Follower);
    assert_eq!(a.term(), 3);
    assert_eq!(
        e[0],
        Effect::Persist(Persisted {
            term: 3,
            voted_for: None
        })
    );
    assert!(events(&e).contains(&TeamEvent::SteppedDown {
        term: 1,
        reason: StepDownReason::HigherTerm
    }));
}

// verifies: TEAM-GROUND-02
#[test]
fn the_first_ground_tc_ends_obedience_and_the_leader_steps_down() {
    let (mut a, t) = leader_with_acks();
    let e = a.on_event(t + 50, 0, Input::GroundTc);
    assert_eq!(a.role(), Role::Follower);
    assert_eq!(a.leader(), None);
    assert_eq!(
        events(&e),
        vec![
            TeamEvent::GroundRegained { term: 1 },
            TeamEvent::SteppedDown {
                term: 1,
                reason: StepDownReason::GroundRegained
            }
        ]
    );
    // It sends no more heartbeats.
    for k in 1..20 {
        assert!(sends(&a.on_event(t + 50 + k * 100, 0, Input::Tick)).is_empty());
    }
    // A follower: the leader's next directive is refused once the ground is back.
    let (mut b, t) = follower();
    b.authorise(t, auth(t)).unwrap();
    b.on_event(t, 0, hb(1, Directive::Hold));
    assert_eq!(b.leader(), Some(1));
    b.on_event(t + 100, 0, Input::GroundTc);
    assert_eq!(b.leader(), None);
    let e = b.on_event(t + 200, 0, hb(1, STEP1));
    assert!(actions(&e).is_empty());
    assert!(events(&e).contains(&TeamEvent::DirectiveRefused {
        term: 1,
        from: 1,
        reason: RefuseReason::GroundPresent
    }));
}

// verifies: TEAM-STATUS-01
#[test]
fn status_snapshot_and_report_bytes() {
    let (a, t) = leader_with_acks();
    let s = a.status(t);
    assert_eq!(s.term, 1);
    assert_eq!(s.role, Role::Leader);
    assert_eq!(s.leader, Some(1));
    assert!(!s.ground_seen);
    assert_eq!(&s.roster[..], &[1, 2, 3]);
    let b = s.encode();
    assert_eq!(&b[..8], &[0, 0, 0, 1, 2, 1, 0, 3]);
    assert_eq!(&b[8..11], &[1, 2, 3]);
    assert!(b[11..].iter().all(|x| *x == 0));
}

// verifies: TEAM-ELECT-01
#[test]
fn foreign_senders_and_bad_rosters_are_refused() {
    assert_eq!(Node::new(1, &[1], 0), Err(RosterError::TooSmall(1)));
    assert_eq!(Node::new(4, &[1, 2], 0), Err(RosterError::NotInRoster(4)));
    assert_eq!(Node::new(1, &[1, 1], 0), Err(RosterError::Duplicate(1)));
    assert_eq!(Node::new(1, &[1, 0], 0), Err(RosterError::BadRobot(0)));
    let (mut b, t) = follower();
    let e = b.on_event(
        t,
        0,
        Input::Message(Message {
            sender: 9,
            ..msg(1, 1, 0, Body::RequestVote)
        }),
    );
    assert!(e.is_empty());
    assert_eq!(b.counters().foreign, 1);
}

mod prop {
    use super::*;
    use proptest::prelude::*;

    fn any_body() -> impl Strategy<Value = Body> {
        prop_oneof![
            Just(Body::RequestVote),
            (1u8..5, any::<bool>()).prop_map(|(candidate, granted)| Body::Vote { candidate, granted }),
            (any::<u32>(), any::<bool>(), 0u16..4).prop_map(|(stamp, hold, step)| {
                Body::LeaderHeartbeat {
                    stamp,
                    directive: if hold {
                        Directive::Hold
                    } else {
                        Directive::Continue {
                            step,
                            function: TeamFunction::BoltPair,
                        }
                    },
                }
            }),
            (any::<u32>(), any::<bool>()).prop_map(|(stamp, ok)| Body::HeartbeatAck { stamp, ok }),
        ]
    }

    fn any_input() -> impl Strategy<Value = Input> {
        prop_oneof![
            3 => Just(Input::Tick),
            1 => Just(Input::GroundTc),
            6 => (0u32..6, 1u8..5, 0u16..3, any_body()).prop_map(|(term, sender, progress, body)| {
                Input::Message(msg(term, sender, progress, body))
            }),
            1 => (0u16..3).prop_map(|progress| Input::Progress {
                plan: PLAN,
                progress,
                next: Some(TeamFunction::BoltPair),
            }),
            1 => any::<bool>().prop_map(|both_hold| Input::Grippers { both_hold }),
        ]
    }

    proptest! {
        // verifies: TEAM-ROBUST-01, TEAM-PERSIST-01, TEAM-VOTE-01
        #[test]
        fn any_input_sequence_keeps_the_invariants(
            steps in proptest::collection::vec((0u64..700, any::<u32>(), any_input()), 1..200)
        ) {
            let mut n = node(2, &[1, 2, 3, 4]);
            n.authorise(0, Authorisation { plan: PLAN, first_step: 1, max_steps: 2, expires_at: 600_000 }).unwrap();
            let mut now = 0;
            let mut durable = n.persisted();
            for (dt, rand, input) in steps {
                now += dt * 20;
                let before = n.persisted();
                let e = n.on_event(now, rand, input);
                let after = n.persisted();
                // The term never goes back; a vote never changes within a term.
                prop_assert!(after.term >= before.term);
                if after.term == before.term && before.voted_for.is_some() {
                    prop_assert_eq!(after.voted_for, before.voted_for);
                }
                // A change is persisted first in the batch, before any send.
                if after != before {
                    prop_assert_eq!(e.first(), Some(&Effect::Persist(after)));
                    durable = after;
                }
                prop_assert_eq!(durable, after);
                for (k, eff) in e.iter().enumerate() {
                    if k > 0 {
                        prop_assert!(!matches!(eff, Effect::Persist(_)));
                    }
                    if let Effect::Send { msg, .. } = eff {
                        // Nothing is sent from a term the durable state has not reached, and
                        // a granted vote is durable (or superseded by a higher term, in which
                        // the robot can never vote in the vote's term again).
                        prop_assert!(msg.term <= after.term);
                        if let Body::Vote { candidate, granted: true } = msg.body {
                            prop_assert!(
                                after.term > msg.term || after.voted_for == Some(candidate)
                            );
                        }
                    }
                }
                prop_assert_eq!(n.counters().effects_dropped, 0);
            }
        }
    }
}
