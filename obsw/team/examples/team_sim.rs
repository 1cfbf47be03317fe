//! Seeded simulation of the team protocol and the paper's Floodmax, side by side.
//!
//! `cargo run --release -p mmic-team --example team_sim -- --runs 100000 --robots 2,3,5,8`
//! (optional `--threads N`, default 2). Prints a Markdown table; exit code 1 when the team
//! protocol shows a safety violation or misses a target.

#[path = "../tests/support/sim.rs"]
mod sim;

use sim::{sweep, FloodRobot, Summary, TeamRobot, SCENARIOS};

fn arg<T: std::str::FromStr>(args: &[String], name: &str) -> Option<T> {
    let i = args.iter().position(|a| a == name)?;
    args.get(i + 1)?.parse().ok()
}

fn ms(v: Option<u64>) -> String {
    match v {
        Some(t) => format!("{:.2}", t as f64 / 1000.0),
        None => "never".to_string(),
    }
}

fn row(n: usize, scenario: &str, proto: &str, s: &Summary) -> String {
    format!(
        "| {n} | {scenario} | {proto} | {} | {} | {} | {:.2} % | {} | {} | {} | {} | {:.3} % | {:.3} % | {:.3} % |",
        s.runs,
        s.violations,
        s.runs_with_two_leaders,
        100.0 * s.agreed_at_end as f64 / s.runs as f64,
        ms(s.percentile(50.0)),
        ms(s.percentile(90.0)),
        ms(s.percentile(99.0)),
        ms(s.times.iter().max().copied()),
        100.0 * s.within(3_500),
        100.0 * s.within(6_000),
        100.0 * s.within(10_000),
    )
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let runs: u64 = arg(&args, "--runs").unwrap_or(1_000);
    let threads: u64 = arg(&args, "--threads").unwrap_or(2).max(1);
    let robots: Vec<usize> = arg::<String>(&args, "--robots")
        .unwrap_or_else(|| "2,3,5,8".to_string())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .filter(|n| (mib::team::ROSTER_MIN..=mib::team::ROSTER_MAX).contains(n))
        .collect();
    println!(
        "| robots | scenario | protocol | runs | safety violations | runs with 2 leaders | agreed at end | t50 s | t90 s | t99 s | max s | ≤ 3.5 s | ≤ 6 s | ≤ 10 s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut ok = true;
    for &n in &robots {
        for (si, sc) in SCENARIOS.iter().enumerate() {
            let t = sweep::<TeamRobot>(n, si, runs, threads);
            println!("{}", row(n, sc.name, "team", &t));
            if t.violations > 0 {
                ok = false;
            }
            if sc.kill_leader && n == 2 {
                // A team of two has no leader without both robots: none may emerge.
                if t.agreed_at_end > 0 || !t.times.is_empty() {
                    ok = false;
                }
            } else if let Some((limit, share)) = sc.target {
                if t.within(limit) < share {
                    ok = false;
                }
            }
            let f = sweep::<FloodRobot>(n, si, runs, threads);
            println!("{}", row(n, sc.name, "Floodmax", &f));
        }
    }
    if !ok {
        eprintln!("team protocol: safety violation or target missed");
        std::process::exit(1);
    }
}
