//! Simulated robot-seconds per wall second on one core, with the controller executing
//! reconfigurations and bolting (the whole stack: controller, A–B link, board B,
//! physics).
//!
//! `cargo bench -p mmic-sim --bench sim_speed`. The throughput criterion prints is in
//! simulated milliseconds per wall second ("elem/s"): divide by 1000 for robot-seconds
//! per wall second.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use mib::robot::Side;
use mmic_domain::controller::Action;
use mmic_sim::{Harness, SimConfig};

/// Simulated time per iteration.
const SIM_MS: u64 = 60_000;

fn workload(h: &mut Harness, step: &mut u32) {
    let end = h.now_ms() + SIM_MS;
    while h.now_ms() < end {
        if !h.ctrl.busy() {
            let action = match (*step % 4, h.ctrl.computed_state()) {
                (0, Some(s)) => Some(Action::Reconfigure {
                    from: s,
                    to: if s == 0 { 1 } else { 0 },
                }),
                (1, _) => Some(Action::BoltFace {
                    side: Side::A,
                    pairs: 0x0F,
                }),
                (2, _) => Some(Action::UnboltFace {
                    side: Side::A,
                    pairs: 0x0F,
                }),
                (3, Some(s)) => Some(Action::Reconfigure {
                    from: s,
                    to: if s == 2 { 0 } else { 2 },
                }),
                _ => None,
            };
            if let Some(a) = action {
                let _ = h.ctrl.start(a, h.now_ms());
            }
            *step += 1;
        }
        h.tick();
    }
}

fn bench(c: &mut Criterion) {
    // the workload really runs actions: check once before measuring
    let mut h = Harness::new(SimConfig::default());
    h.power_on();
    let mut step = 0;
    workload(&mut h, &mut step);
    let completed = h
        .reports
        .iter()
        .filter(|(_, r)| *r == mmic_domain::controller::ActionReport::Completed)
        .count();
    assert!(completed >= 3, "only {completed} actions completed in 60 s");
    eprintln!("workload: {completed} actions completed in 60 simulated seconds");

    let mut g = c.benchmark_group("sim");
    g.throughput(Throughput::Elements(SIM_MS));
    g.sample_size(20);
    g.bench_function("robot_60s_reconfigure_and_bolt", |b| {
        b.iter_batched(
            || {
                let mut h = Harness::new(SimConfig::default());
                h.power_on();
                h
            },
            |mut h| {
                let mut step = 0;
                workload(&mut h, &mut step);
                h
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
