//! A short tour of the simulator: boot, power on, reconfigure Xneg → Yneg, bolt the
//! face, then inject a stuck arm and watch the controller report it.
//!
//! `cargo run -p mmic-sim --example demo [seed]`

use mib::params::pid;
use mib::robot::{Side, STATES};
use mmic_domain::controller::{Action, ActionReport};
use mmic_sim::{Fault, Harness, SimConfig};

fn show(h: &Harness, what: &str, r: Option<ActionReport>, from: usize) {
    println!("{:>8.2} s  {what}: {r:?}", h.now_ms() as f64 / 1000.0);
    for (t, e) in &h.events[from..] {
        println!("{:>8.2} s    event {e:?}", *t as f64 / 1000.0);
    }
    println!("           truth: {}", h.sim.truth());
    let state = h.ctrl.computed_state();
    println!(
        "           computed state {:?} ({}), V_BAT_A raw {}, B heartbeats {}",
        state,
        state.and_then(|s| STATES.get(s as usize)).map_or("unknown", |s| s.name),
        h.ctrl.param(pid::V_BAT_A).unwrap_or(0),
        h.ctrl.param(pid::B_HB_RX).unwrap_or(0),
    );
}

fn main() {
    let seed = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(7);
    let mut h = Harness::new(SimConfig {
        seed,
        ..SimConfig::default()
    });
    h.power_on();
    println!("booted and powered: {}", h.sim.truth());

    let steps: [(&str, Action); 3] = [
        ("reconfigure Xneg -> Yneg", Action::Reconfigure { from: 0, to: 2 }),
        (
            "bolt the face under side A",
            Action::BoltFace {
                side: Side::A,
                pairs: 0x0F,
            },
        ),
        ("reconfigure Yneg -> Xneg", Action::Reconfigure { from: 2, to: 0 }),
    ];
    for (what, action) in steps {
        let mark = h.events.len();
        let r = h.run_action(action, 300_000);
        show(&h, what, r.ok().flatten(), mark);
    }

    println!("inject: stuck-arm b, then Xneg -> Xpos");
    h.sim.inject(Fault::StuckArm(Side::B));
    let mark = h.events.len();
    let r = h.run_action(Action::Reconfigure { from: 0, to: 1 }, 300_000);
    show(&h, "reconfigure Xneg -> Xpos with a stuck arm", r.ok().flatten(), mark);
}
