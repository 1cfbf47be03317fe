//! Plan completion time on a bad link against a clean one, measured in the same run
//! (`cargo build --release -p obsw -p ground && cargo bench -p e2e-tests --bench plan_link`).
//!
//! Runs `ground run plans/checkout.toml` through the project's relay (`e2e_tests::relay`)
//! against a fresh `obsw` each time: clean (no faults) and bad (20 % drop, 5 % duplicate,
//! 5 % corrupt, both directions), `BENCH_RUNS` seeds each (default 3), one after the
//! other. Prints every run and the medians, and the ratio bad/clean.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::relay::{Config, Faults, Relay};
use e2e_tests::{bin, Obsw};

fn run(faults: Faults, seed: u64) -> (f64, bool) {
    let o = Obsw::start(&["--seed", &seed.to_string()]);
    let mut cfg = Config::both_ways(o.udp, o.tcp, faults, seed);
    cfg.idle = Duration::from_secs(30);
    let relay = Relay::start(cfg).expect("relay");
    let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans/checkout.toml");
    let t0 = Instant::now();
    let status = Command::new(bin("ground"))
        .args(["--no-archive", "run"])
        .arg(&plan)
        .args(["--lab-udp", "--robot", &format!("1={}", relay.udp), "--plain"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .expect("ground");
    (t0.elapsed().as_secs_f64(), status.success())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let runs: u64 = std::env::var("BENCH_RUNS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let bad = Faults::new(0.20, 0.05, 0.05);
    let (mut clean_t, mut bad_t) = (Vec::new(), Vec::new());
    for seed in 1..=runs {
        let (t, ok) = run(Faults::CLEAN, seed);
        println!("clean seed {seed}: {t:.1} s{}", if ok { "" } else { " (FAILED)" });
        clean_t.push(t);
        let (t, ok) = run(bad, seed);
        println!("bad   seed {seed}: {t:.1} s{}", if ok { "" } else { " (FAILED)" });
        bad_t.push(t);
    }
    let (c, b) = (median(clean_t), median(bad_t));
    println!("checkout clean link: median {c:.1} s");
    println!("checkout bad link (20% drop, 5% dup, 5% corrupt both ways): median {b:.1} s");
    println!("bad/clean: {:.2}x", b / c);
}
