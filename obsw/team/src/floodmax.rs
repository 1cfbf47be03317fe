//! The paper's leader selection (source `002_…`, after Lynch's FloodMax), the baseline.
//!
//! Each agent holds `(ID, maxid, leader, round)`, initially `(i, i, unknown, 0)`. In every
//! round with `round < diam` it sends `maxid` to its neighbours; at the end of a round
//! `maxid := max(maxid, received)` and `round := round + 1`; when `round = diam` it decides:
//! leader iff `maxid = ID`. (The paper prints every condition as `s_com < diam`; per Lynch
//! the decision happens at `round = diam`.) Rounds are synchronous: here a round lasts
//! [`mib::team::FLOODMAX_ROUND_MS`] of the robot's clock from the moment the robot detects
//! the ground loss, and a message is counted in the round in which it arrives. There is
//! no failure handling, exactly as in the paper: no terms, no quorum, no retry.

use crate::wire::RobotId;
use mib::team::{FLOODMAX_ROUND_MS, GROUND_LOSS_TIMEOUT_MS};

/// The leader flag of the paper.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Leader {
    Unknown,
    True,
    False,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FloodInput {
    Tick,
    GroundTc,
    /// `maxid` received from a neighbour.
    Message {
        from: RobotId,
        maxid: RobotId,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FloodEffect {
    /// Send `maxid` to every neighbour.
    Broadcast { maxid: RobotId },
    /// Decided at `round = diam`.
    Decided { leader: Leader, maxid: RobotId },
}

/// One agent of the paper's Floodmax.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Floodmax {
    id: RobotId,
    diam: u8,
    maxid: RobotId,
    leader: Leader,
    round: u8,
    /// Largest identifier received in the current round.
    received: RobotId,
    /// `None` until the ground loss is detected (the algorithm starts then).
    round_end: Option<u64>,
    ground_last: u64,
    done: bool,
}

impl Floodmax {
    /// Agent `id` in a network of diameter `diam` (1 for a fully connected team).
    pub fn new(id: RobotId, diam: u8, now: u64) -> Floodmax {
        Floodmax {
            id,
            diam: diam.max(1),
            maxid: id,
            leader: Leader::Unknown,
            round: 0,
            received: 0,
            round_end: None,
            ground_last: now,
            done: false,
        }
    }

    pub fn leader(&self) -> Leader {
        self.leader
    }
    pub fn maxid(&self) -> RobotId {
        self.maxid
    }
    pub fn decided(&self) -> bool {
        self.done
    }

    /// When the next `Tick` may change something.
    pub fn next_deadline(&self) -> u64 {
        match self.round_end {
            None => self.ground_last.saturating_add(GROUND_LOSS_TIMEOUT_MS),
            Some(_) if self.done => u64::MAX,
            Some(end) => end,
        }
    }

    /// Handle one input; at most one effect per call.
    pub fn on_event(&mut self, now: u64, input: FloodInput) -> Option<FloodEffect> {
        match input {
            FloodInput::GroundTc => self.ground_last = now,
            FloodInput::Message { maxid, .. } => {
                if !self.done {
                    self.received = self.received.max(maxid);
                }
            }
            FloodInput::Tick => {}
        }
        match self.round_end {
            None => {
                if now.saturating_sub(self.ground_last) >= GROUND_LOSS_TIMEOUT_MS {
                    // Round 0 starts: msg(w, i) = maxid while round < diam.
                    self.round_end = Some(now + FLOODMAX_ROUND_MS);
                    return Some(FloodEffect::Broadcast { maxid: self.maxid });
                }
                None
            }
            Some(end) if !self.done && now >= end => {
                // define_leader(w, y): new maxid, round + 1, decide at round = diam.
                self.maxid = self.maxid.max(self.received);
                self.round = self.round.saturating_add(1);
                if self.round >= self.diam {
                    self.done = true;
                    self.leader = if self.maxid == self.id {
                        Leader::True
                    } else {
                        Leader::False
                    };
                    Some(FloodEffect::Decided {
                        leader: self.leader,
                        maxid: self.maxid,
                    })
                } else {
                    self.round_end = Some(end + FLOODMAX_ROUND_MS);
                    Some(FloodEffect::Broadcast { maxid: self.maxid })
                }
            }
            Some(_) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use heapless::Vec;

    fn run(ids: &[RobotId], diam: u8, deliver: impl Fn(RobotId, RobotId) -> bool) -> Vec<Floodmax, 8> {
        let mut nodes: Vec<Floodmax, 8> = ids.iter().map(|i| Floodmax::new(*i, diam, 0)).collect();
        let mut t = 0;
        while t < GROUND_LOSS_TIMEOUT_MS + FLOODMAX_ROUND_MS * (u64::from(diam) + 2) {
            let mut sends: Vec<(RobotId, RobotId), 8> = Vec::new();
            for n in nodes.iter_mut() {
                if let Some(FloodEffect::Broadcast { maxid }) = n.on_event(t, FloodInput::Tick) {
                    sends.push((n.id, maxid)).unwrap();
                }
            }
            for (from, maxid) in sends {
                for n in nodes.iter_mut() {
                    if n.id != from && deliver(from, n.id) {
                        n.on_event(t + 10, FloodInput::Message { from, maxid });
                    }
                }
            }
            t += 50;
        }
        nodes
    }

    // verifies: TEAM-FLOOD-01
    #[test]
    fn synchronous_lossless_floodmax_elects_the_maximum() {
        // A line 1-2-3-4 (diameter 3): only neighbours hear each other.
        let nodes = run(&[3, 1, 4, 2], 3, |a, b| a.abs_diff(b) == 1);
        for n in &nodes {
            assert!(n.decided());
            assert_eq!(n.maxid(), 4);
            let expect = if n.id == 4 { Leader::True } else { Leader::False };
            assert_eq!(n.leader(), expect);
        }
        // With diam = 1 on a line, robot 1 never hears of 4 before deciding: it decides
        // for 2 (the paper's algorithm needs the true diameter).
        let nodes = run(&[1, 2, 3, 4], 1, |a, b| a.abs_diff(b) == 1);
        assert_eq!(nodes[0].maxid(), 2);
    }

    // verifies: TEAM-FLOOD-01
    #[test]
    fn partition_gives_two_leaders() {
        // {1, 2} and {3, 4} cannot hear each other: each side elects its maximum.
        let nodes = run(&[1, 2, 3, 4], 1, |a, b| (a <= 2) == (b <= 2));
        let leaders: Vec<RobotId, 8> = nodes
            .iter()
            .filter(|n| n.leader() == Leader::True)
            .map(|n| n.id)
            .collect();
        assert_eq!(&leaders[..], &[2, 4]);
    }
}
