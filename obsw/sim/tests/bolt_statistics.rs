//! The bolt outcome distribution over many pairs reproduces the paper's ground demo
//! (2307 / 103 / 28 / 86 of 2524: bolted at the 1st, 2nd, 3rd attempt, failed). The
//! outcome is what the controller's bolter state machine concludes from the simulated
//! currents (through board B and the serial link), never read from the simulator.

use mib::robot::bolter::{DEMO_FAILED, DEMO_FIRST, DEMO_PAIRS, DEMO_SECOND, DEMO_THIRD};
use mib::robot::{Face, Side};
use mmic_domain::controller::{Action, ActionReport, DomainEvent};
use mmic_sim::{Harness, SimConfig};

/// Chi-square critical value, 3 degrees of freedom, p = 0.001.
const CHI2_3DOF_P001: f64 = 16.27;

// verifies: MMIC-VAL-01
#[test]
fn bolt_outcomes_over_many_pairs_match_the_ground_demo_distribution() {
    let mut h = Harness::new(SimConfig {
        seed: 2024,
        noise: true,
        ..SimConfig::default()
    });
    h.power_on();
    let pairs = DEMO_PAIRS as usize;
    // buckets: bolted at attempt 1, 2, 3; failed
    let mut counts = [0u32; 4];
    for i in 0..pairs {
        let pair = (i % 4) as u8 + 1;
        if pair == 1 {
            h.sim.replace_fasteners(); // a new voxel face every four pairs
        }
        let mark = h.events.len();
        let r = h
            .run_action(Action::BoltPair { side: Side::A, pair }, 120_000)
            .expect("bolting accepted");
        let outcome = h.events_since(mark).find_map(|e| match e {
            DomainEvent::BoltPairDone { attempts, .. } => Some(Ok(*attempts)),
            DomainEvent::BoltFailure { attempts, .. } => Some(Err(*attempts)),
            _ => None,
        });
        let truth = h.sim.fastener(Face::Xneg, pair).expect("fastener engaged");
        match (r, outcome) {
            (Some(ActionReport::Completed), Some(Ok(n))) => {
                assert!((1..=3).contains(&n));
                assert!(truth.locked, "pair reported bolted must be locked");
                assert_eq!(truth.lock_attempts, n, "attempts seen by the domain");
                counts[n as usize - 1] += 1;
            }
            (Some(ActionReport::Failed(_)), Some(Err(3))) => {
                assert!(!truth.locked, "pair reported failed must be loose");
                assert_eq!(truth.lock_attempts, 3);
                counts[3] += 1;
            }
            other => panic!("pair {i}: unexpected outcome {other:?}"),
        }
    }
    let demo = [DEMO_FIRST, DEMO_SECOND, DEMO_THIRD, DEMO_FAILED];
    let chi2: f64 = counts
        .iter()
        .zip(demo.iter())
        .map(|(&o, &d)| {
            let e = d as f64 * pairs as f64 / DEMO_PAIRS as f64;
            (o as f64 - e).powi(2) / e
        })
        .sum();
    eprintln!("bolt outcomes {counts:?} vs demo {demo:?}: chi2 = {chi2:.2}");
    assert_eq!(counts.iter().sum::<u32>() as usize, pairs);
    assert!(
        chi2 < CHI2_3DOF_P001,
        "counts {counts:?} differ from the demo {demo:?} (chi2 {chi2:.2})"
    );
}
