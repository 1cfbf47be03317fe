//! FOP-1 and FARM-1 connected through a lossy link (in memory, time by hand): every FDU is
//! delivered exactly once and in order, "sent" is reported only for delivered FDUs, and a
//! ground restart mid-stream resynchronises from the CLCW without repeating or skipping.

use std::collections::BTreeMap;

use mmic_link::farm::{Farm, FarmAction, FarmInput};
use mmic_link::fop::{Fop, FopConfig, FopEffect, FopInput, FopState};
use proptest::prelude::*;

/// A lossy link: independent losses with probabilities `up`/`down` (xorshift64 PRNG).
struct LossyChannel {
    state: u64,
    up: f64,
    down: f64,
}

impl LossyChannel {
    fn coin(&mut self, p: f64) -> bool {
        self.state ^= self.state << 13;
        self.state ^= self.state >> 7;
        self.state ^= self.state << 17;
        ((self.state >> 11) as f64 / (1u64 << 53) as f64) < p
    }

    fn lose_up(&mut self) -> bool {
        let p = self.up;
        self.coin(p)
    }

    fn lose_down(&mut self) -> bool {
        let p = self.down;
        self.coin(p)
    }
}

struct World {
    fop: Fop<u32>,
    farm: Farm,
    link: LossyChannel,
    now: u64,
    delivered: Vec<u32>,
    acked: Vec<u32>,
    /// The ground's persisted record: N(S) of every FDU handed to the FOP.
    ns_of: BTreeMap<u8, u32>,
}

impl World {
    fn apply(&mut self, fx: Vec<FopEffect<u32>>) {
        for e in fx {
            match e {
                FopEffect::TransmitAd { ns, fdu, .. } => {
                    self.ns_of.insert(ns, fdu);
                    if !self.link.lose_up() {
                        let r = self.farm.on_event(FarmInput::Ad {
                            ns,
                            buffer_available: true,
                        });
                        if r.action == FarmAction::Accept {
                            self.delivered.push(fdu);
                        }
                    }
                }
                FopEffect::TransmitBc(cmd) if !self.link.lose_up() => {
                    self.farm.on_event(FarmInput::Bc(cmd));
                }
                FopEffect::Acknowledged { fdu, .. } => self.acked.push(fdu),
                FopEffect::Alert(a) => panic!("alert {a:?}"),
                _ => {}
            }
        }
    }

    fn step(&mut self) {
        self.now += 10;
        if !self.link.lose_down() {
            let fx = self.fop.on_event(self.now, FopInput::Clcw(self.farm.clcw()));
            self.apply(fx.into_iter().collect());
        }
        let fx = self.fop.on_event(self.now, FopInput::Tick);
        self.apply(fx.into_iter().collect());
    }

    /// Feeds FDUs `from..to` as the FOP takes them, until all are acknowledged.
    fn run(&mut self, mut next: u32, to: u32, max_steps: usize) -> u32 {
        for _ in 0..max_steps {
            if next < to && self.fop.ready() {
                let fx = self.fop.on_event(self.now, FopInput::TransmitAd(next));
                self.apply(fx.into_iter().collect());
                next += 1;
            }
            self.step();
            if next == to && self.fop.outstanding() == 0 && self.fop.ready() {
                break;
            }
        }
        next
    }
}

fn config() -> FopConfig {
    FopConfig {
        sliding_window: 10,
        t1_ms: 100,
        t1_min_ms: 100,
        tx_limit: 20,
        timeout_type: 0,
    }
}

fn world(seed: u64, up: f64, down: f64) -> World {
    let mut fop = Fop::new(0, config());
    fop.on_event(0, FopInput::InitiateAdWithoutClcw);
    World {
        fop,
        farm: Farm::new(0, 20),
        link: LossyChannel {
            state: seed | 1,
            up,
            down,
        },
        now: 0,
        delivered: vec![],
        acked: vec![],
        ns_of: BTreeMap::new(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    // verifies: LINK-FOP-01, LINK-FARM-01
    #[test]
    fn lossy_link_delivers_every_fdu_exactly_once_in_order(
        seed in any::<u64>(), up in 0.0f64..0.3, down in 0.0f64..0.3,
    ) {
        let mut w = world(seed, up, down);
        let n = 300; // crosses the 8-bit N(S) wrap
        w.run(0, n, 200_000);
        prop_assert_eq!(&w.delivered, &(0..n).collect::<Vec<_>>());
        prop_assert_eq!(&w.acked, &(0..n).collect::<Vec<_>>());
    }

    // verifies: LINK-FOP-02
    #[test]
    fn ground_restart_resynchronises_without_repeat_or_skip(
        seed in any::<u64>(), up in 0.0f64..0.3, down in 0.0f64..0.3,
        kill_after in 5usize..400,
    ) {
        let mut w = world(seed, up, down);
        let mut next = 0u32;
        // Run until the kill: FDUs in flight, some accepted on board but not acknowledged.
        for _ in 0..kill_after {
            if next < 200 && w.fop.ready() {
                let fx = w.fop.on_event(w.now, FopInput::TransmitAd(next));
                w.apply(fx.into_iter().collect());
                next += 1;
            }
            w.step();
        }
        // The ground dies: its FOP state is gone; its persisted record (ns_of) survives.
        // The restarted ground reads N(R) from the next CLCW (idle frames carry it) and
        // initiates AD with Set V(R) = N(R): the FARM keeps its V(R) and clears a retransmit
        // flag left from before (with a CLCW check, E24, that flag would raise an alert).
        let nr = w.farm.clcw().report_value;
        let mut fop: Fop<u32> = Fop::new(0, config());
        let fx = fop.on_event(w.now, FopInput::InitiateAdWithSetVr(nr));
        w.fop = fop;
        w.apply(fx.into_iter().collect());
        while w.fop.state() == FopState::InitialisingWithBc {
            w.step();
        }
        prop_assert_eq!(w.fop.state(), FopState::Active);
        // The FDU sent as N(S) = N(R) is the first not accepted on board; if none was sent
        // with that number, every transmitted FDU was accepted and the ground resumes after
        // the last one transmitted (an FDU still in the FOP's wait queue was never sent).
        let resume = w
            .ns_of
            .get(&nr)
            .copied()
            .unwrap_or_else(|| w.ns_of.values().max().map_or(0, |m| m + 1));
        prop_assert!(resume <= next);
        w.run(resume, 200, 200_000);
        prop_assert_eq!(&w.delivered, &(0..200).collect::<Vec<_>>());
    }
}
