//! Property tests over random action and fault sequences: nothing panics, and the
//! domain never reports success the simulated truth contradicts.

use mib::robot::{Face, Side, NUM_STATES};
use mmic_domain::controller::{Action, ActionReport, DomainEvent};
use mmic_sim::{Fault, Harness, SimConfig};
use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Op {
    Reconfigure { to: u8, lie: bool },
    Bolt { pair: u8 },
    Inject(Fault),
    ClearAll,
    AbortAfter(u32),
    Home,
}

fn op() -> impl Strategy<Value = Op> {
    let side = prop_oneof![Just(Side::A), Just(Side::B)];
    let fault = prop_oneof![
        side.clone().prop_map(Fault::StuckArm),
        side.prop_map(Fault::Obstacle),
        (8.0f32..12.6).prop_map(|volts| Fault::BatterySag { volts }),
        Just(Fault::DeadHipEncoder),
        Just(Fault::CutCable),
        Just(Fault::MisplacedVoxel),
        Just(Fault::FastenerJam),
    ];
    prop_oneof![
        4 => (0u8..NUM_STATES as u8, any::<bool>()).prop_map(|(to, lie)| Op::Reconfigure { to, lie }),
        2 => (1u8..=4).prop_map(|pair| Op::Bolt { pair }),
        2 => fault.prop_map(Op::Inject),
        1 => Just(Op::ClearAll),
        1 => (10u32..5000).prop_map(Op::AbortAfter),
        1 => Just(Op::Home),
    ]
}

proptest! {
    // A fixed seed keeps CI deterministic; explore more with e.g. a different seed here
    // and PROPTEST_CASES=3000 (3000 cases passed during development).
    #![proptest_config(ProptestConfig {
        cases: 24,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x4D4D_4943),
        ..ProptestConfig::default()
    })]

    // verifies: MMIC-MOT-07
    #[test]
    fn no_reported_success_contradicts_the_simulated_truth(
        seed in 0u64..1000,
        initial in prop_oneof![Just(0u8), Just(1u8), Just(2u8)],
        loss in prop_oneof![Just(0.0), Just(0.005)],
        ops in proptest::collection::vec(op(), 1..6),
    ) {
        let mut h = Harness::new(SimConfig { seed, initial_state: initial, link_loss: loss, ..SimConfig::default() });
        h.power_on();
        for op in ops {
            match op {
                Op::Reconfigure { to, lie } => {
                    let from = match (h.ctrl.computed_state(), lie) {
                        (Some(s), false) => s,
                        (Some(s), true) => (s + 1) % NUM_STATES as u8,
                        (None, _) => 0,
                    };
                    if let Ok(Some(r)) = h.run_action(Action::Reconfigure { from, to }, 200_000) {
                        if r == ActionReport::Completed {
                            prop_assert_eq!(h.sim.truth().state, Some(to));
                            prop_assert!(!lie, "a wrong belief must be refused");
                        }
                    }
                }
                Op::Bolt { pair } => {
                    let mark = h.events.len();
                    let _ = h.run_action(Action::BoltPair { side: Side::A, pair }, 120_000);
                    let face = h.sim.fastener_face().unwrap_or(Face::Xneg);
                    for e in h.events_since(mark) {
                        if let DomainEvent::BoltPairDone { pair, .. } = e {
                            prop_assert!(h.sim.fastener(face, *pair).is_some_and(|f| f.locked));
                        }
                    }
                }
                Op::Home => {
                    if let Ok(Some(ActionReport::Completed)) = h.run_action(Action::Home, 120_000) {
                        let t = h.sim.truth();
                        prop_assert!(
                            matches!(t.state, Some(0..=2)),
                            "home completed but the robot is not contracted and gripped: {}", t
                        );
                    }
                }
                Op::Inject(f) => h.sim.inject(f),
                Op::ClearAll => h.sim.clear_all(),
                Op::AbortAfter(ms) => {
                    if let Some(s) = h.ctrl.computed_state() {
                        let _ = h.ctrl.start(Action::Reconfigure { from: s, to: (s + 3) % NUM_STATES as u8 }, h.now_ms());
                        h.advance(ms as u64);
                        h.ctrl.abort();
                        prop_assert!(!h.ctrl.busy());
                        let n = h.reports.len();
                        h.advance(100);
                        prop_assert_eq!(h.reports.len(), n, "no report after abort");
                    }
                }
            }
        }
    }
}
