//! Controller + simulator integration: reconfigurations reach the right true state and
//! every injected fault produces its domain symptom.

use mmic_domain::controller::{Action, ActionReport};
use mmic_sim::{Harness, SimConfig};

fn harness(initial: u8, seed: u64) -> Harness {
    let mut h = Harness::new(SimConfig {
        seed,
        initial_state: initial,
        ..SimConfig::default()
    });
    h.power_on();
    h
}

#[test]
fn reconfiguration_xneg_to_xpos_reaches_the_true_state() {
    let mut h = harness(0, 1);
    assert_eq!(h.ctrl.computed_state(), Some(0));
    let r = h.run_action(Action::Reconfigure { from: 0, to: 1 }, 120_000).unwrap();
    assert_eq!(r, Some(ActionReport::Completed), "events {:?}", h.events);
    assert_eq!(h.sim.truth().state, Some(1));
    assert_eq!(h.ctrl.computed_state(), Some(1));
    assert!(!h.sim.truth().fallen);
}
