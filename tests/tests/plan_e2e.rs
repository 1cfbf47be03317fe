//! On-board plans end to end (docs/plan-format.md, "On board"): two real obsw processes
//! whose authenticated team link (`--team-udp`, `--peer`, `--team-key`) carries the plan's
//! progress, and the real `ground` binary uploading `plans/demo.toml` with
//! `run --on-board --detach`, then reattaching with `--on-board --resume`.
//!
//! Judged from what each obsw sent (its `--tm-log`) and the time stamps it put on it:
//! robot 2's walk starts after robot 1's bolt completed, each robot's step TCs start
//! exactly once, and the reattached ground's summary is the one a ground-driven run of
//! the same plan gives.
//!
//! Needs the binaries: `cargo build -p obsw -p ground`.

use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::relay::{Config, Faults, Relay};
use e2e_tests::{bin, Obsw, Tm};
use mib::events::eid;
use mib::plan::state;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mmic-plan-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn free_addr() -> String {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.local_addr().unwrap().to_string()
}

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans/demo.toml")
}

fn ground(dir: &Path, args: &[&str]) -> Output {
    Command::new(bin("ground"))
        .current_dir(dir)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run ground")
}

fn text(o: &Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// On-board time of a TM packet (CDS short after the 7 bytes of the PUS-C TM secondary
/// header before it), in ms since 1958.
fn board_ms(t: &Tm) -> i64 {
    let r = &t.raw;
    let days = i64::from(u16::from_be_bytes([r[14], r[15]]));
    days * 86_400_000 + i64::from(u32::from_be_bytes([r[16], r[17], r[18], r[19]]))
}

/// Every packet of an obsw's `--tm-log`, each once (live or replayed from the store).
fn log(path: &Path) -> Vec<Tm> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let mut seen = std::collections::HashSet::new();
    text.lines()
        .filter_map(|l| {
            let raw: Vec<u8> = (0..l.len() / 2)
                .filter_map(|i| u8::from_str_radix(&l[2 * i..2 * i + 2], 16).ok())
                .collect();
            Tm::parse(&raw)
        })
        .filter(|t| t.raw.len() >= 20 && seen.insert((t.seq, t.raw[13..20].to_vec())))
        .collect()
}

/// Events `id` with their parameters.
fn events(tm: &[Tm], id: u16) -> Vec<&Tm> {
    tm.iter().filter(|t| t.event_id() == Some(id)).collect()
}

/// The plan state of each PLAN_STATE_CHANGED (state, step).
fn states(tm: &[Tm]) -> Vec<(u8, u8)> {
    events(tm, eid::PLAN_STATE_CHANGED)
        .iter()
        .map(|t| (t.data[6], t.data[7]))
        .collect()
}

/// The sequence count robot's plan gave step `step` (PLAN_STEP_STARTED), every time.
fn started(tm: &[Tm], step: u8) -> Vec<u16> {
    events(tm, eid::PLAN_STEP_STARTED)
        .iter()
        .filter(|t| t.data[6] == step)
        .map(|t| u16::from_be_bytes([t.data[7], t.data[8]]))
        .collect()
}

/// The report TM[1,sub] of the TC with sequence count `seq`.
fn report(tm: &[Tm], sub: u8, seq: u16) -> Option<&Tm> {
    tm.iter()
        .find(|t| t.service == 1 && t.subservice == sub && t.request().is_some_and(|r| r.seq() == seq))
}

fn wait_until(limit: Duration, mut done: impl FnMut() -> bool) -> bool {
    let end = Instant::now() + limit;
    while Instant::now() < end {
        if done() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    done()
}

fn team_key(dir: &Path) {
    let mut k = [0u8; 32];
    std::io::Read::read_exact(&mut std::fs::File::open("/dev/urandom").unwrap(), &mut k).unwrap();
    mmic_link::persist::create_key_file(&dir.join("team.key"), &k).unwrap();
}

/// Robot `robot` (2 starts on Xpos, as the plan says) with its team link on `listen`,
/// sending to its peer at `peer`.
fn robot(dir: &Path, robot: u8, listen: &str, peer: &str, speed: &str) -> Obsw {
    let other = 3 - robot;
    let args: Vec<String> = vec![
        "--tm-log".into(),
        dir.join(format!("tm-{robot}.hex")).display().to_string(),
        "--team-udp".into(),
        listen.into(),
        "--team-state".into(),
        dir.join(format!("team-{robot}.state")).display().to_string(),
        "--team-key".into(),
        dir.join("team.key").display().to_string(),
        "--peer".into(),
        format!("{other}={peer}"),
        "--initial-state".into(),
        if robot == 1 { "Xneg" } else { "Xpos" }.into(),
        "--speed".into(),
        speed.into(),
    ];
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    Obsw::start_robot(robot, &refs)
}

/// What a summary says, without the times: (step, result) in order, bolts, unbolted pairs.
fn outcome(summary: &serde_json::Value) -> (Vec<(String, String)>, serde_json::Value, serde_json::Value) {
    let steps = summary["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            (
                s["id"].as_str().unwrap().to_string(),
                s["result"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    (steps, summary["bolts"].clone(), summary["unbolted_pairs"].clone())
}

fn robots_args(o: &[Obsw]) -> Vec<String> {
    o.iter()
        .enumerate()
        .flat_map(|(i, o)| ["--robot".to_string(), format!("{}={}", i + 1, o.udp)])
        .collect()
}

// verifies: PLAN-E2E-01, PLAN-TEAM-01, PLAN-GROUND-01
#[test]
fn the_demo_plan_runs_on_board_without_the_ground_and_the_reattached_summary_is_the_ground_driven_one() {
    let dir = tmpdir("demo");
    team_key(&dir);
    let (a1, a2) = (free_addr(), free_addr());
    // Speed 1: both robots' clocks are the wall clock, so their time stamps compare.
    let o = [robot(&dir, 1, &a1, &a2, "1"), robot(&dir, 2, &a2, &a1, "1")];
    let plan = demo();
    let robots = robots_args(&o);
    let mut args = vec!["--archive", "archive.db", "run", "--lab-udp", plan.to_str().unwrap()];
    args.extend(robots.iter().map(String::as_str));
    let detach = ground(&dir, &[&args[..], &["--on-board", "--detach", "--plain"]].concat());
    assert_eq!(detach.status.code(), Some(0), "{}", text(&detach));
    assert!(text(&detach).contains("runs on board"), "{}", text(&detach));
    // The ground is gone; both robots carry on.
    let logs = [dir.join("tm-1.hex"), dir.join("tm-2.hex")];
    let done = wait_until(Duration::from_secs(180), || {
        logs.iter()
            .all(|l| states(&log(l)).iter().any(|s| s.0 == state::COMPLETED))
    });
    let tm: Vec<Vec<Tm>> = logs.iter().map(|l| log(l)).collect();
    assert!(done, "robot 1 {:?}, robot 2 {:?}", states(&tm[0]), states(&tm[1]));
    // Every step's TC ran once on each robot and completed.
    for (r, t) in tm.iter().enumerate() {
        for step in 0..5 {
            let seqs = started(t, step);
            assert_eq!(seqs.len(), 1, "robot {} step {step} started {seqs:?}", r + 1);
            assert!(report(t, 7, seqs[0]).is_some(), "robot {} step {step} completed", r + 1);
        }
    }
    // Robot 2's walk (its step 2) waited for robot 1's bolt (robot 1's step 2), and started
    // after it completed, by the two robots' own time stamps.
    let bolt_done = board_ms(report(&tm[0], 7, started(&tm[0], 2)[0]).unwrap());
    let walk_start = board_ms(report(&tm[1], 1, started(&tm[1], 2)[0]).unwrap());
    let waited = events(&tm[1], eid::PLAN_WAITING)
        .iter()
        .any(|t| t.data[6..9] == [2, 1, 2]);
    assert!(waited, "robot 2 reported waiting for robot 1's step 2");
    eprintln!(
        "robot 1 bolt completed at {bolt_done}, robot 2 walk accepted at {walk_start} (+{} ms)",
        walk_start - bolt_done
    );
    assert!(walk_start > bolt_done, "walk at {walk_start}, bolt done at {bolt_done}");
    // The ground reattaches: the steps completed meanwhile are read from the stores.
    let back = ground(
        &dir,
        &[&args[..], &["--on-board", "--resume", "--plain", "--json"]].concat(),
    );
    assert_eq!(back.status.code(), Some(0), "{}", text(&back));
    let on_board: serde_json::Value =
        serde_json::from_slice(&back.stdout).unwrap_or_else(|e| panic!("{e}: {}", text(&back)));
    drop(o);
    // The same plan driven from the ground, on two fresh robots with the same seeds.
    let dir2 = tmpdir("demo-ground");
    team_key(&dir2);
    let (b1, b2) = (free_addr(), free_addr());
    let o2 = [robot(&dir2, 1, &b1, &b2, "4"), robot(&dir2, 2, &b2, &b1, "4")];
    let robots2 = robots_args(&o2);
    let mut args2 = vec![
        "--no-archive",
        "run",
        "--lab-udp",
        plan.to_str().unwrap(),
        "--plain",
        "--json",
    ];
    args2.extend(robots2.iter().map(String::as_str));
    let driven = ground(&dir2, &args2);
    assert_eq!(driven.status.code(), Some(0), "{}", text(&driven));
    let driven: serde_json::Value = serde_json::from_slice(&driven.stdout).unwrap();
    assert_eq!(outcome(&on_board), outcome(&driven));
    assert_eq!(on_board["done"], 10);
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&dir2);
}

// verifies: PLAN-TEAM-02
#[test]
fn through_a_lossy_team_link_the_dependency_holds_and_with_the_link_cut_robot_2_waits_until_it_returns() {
    let dir = tmpdir("cut");
    team_key(&dir);
    let (a1, a2) = (free_addr(), free_addr());
    // Robot 1's team datagrams to robot 2 through the project's relay: 20 % dropped, 5 %
    // duplicated, 5 % corrupted (refused by the MAC). The relay starts cut (not running).
    let relay_at = free_addr();
    let o = [robot(&dir, 1, &a1, &relay_at, "4"), robot(&dir, 2, &a2, &a1, "4")];
    let plan = demo();
    let robots = robots_args(&o);
    let mut args = vec!["--no-archive", "run", "--lab-udp", plan.to_str().unwrap()];
    args.extend(robots.iter().map(String::as_str));
    let detach = ground(&dir, &[&args[..], &["--on-board", "--detach", "--plain"]].concat());
    assert_eq!(detach.status.code(), Some(0), "{}", text(&detach));
    let logs = [dir.join("tm-1.hex"), dir.join("tm-2.hex")];
    // Robot 1 completes alone; robot 2 holds at the walk (its step 2), waiting on robot 1.
    assert!(wait_until(Duration::from_secs(120), || states(&log(&logs[0]))
        .iter()
        .any(|s| s.0 == state::COMPLETED)));
    std::thread::sleep(Duration::from_secs(2));
    let t2 = log(&logs[1]);
    assert!(started(&t2, 2).is_empty(), "robot 2 did not guess: {:?}", states(&t2));
    assert!(events(&t2, eid::PLAN_WAITING).iter().any(|t| t.data[6..9] == [2, 1, 2]));
    // The link returns, lossy: robot 2 continues and completes.
    let team: std::net::SocketAddr = a2.parse().unwrap();
    let mut cfg = Config::both_ways(team, team, Faults::new(0.2, 0.05, 0.05), 7);
    cfg.listen_udp = relay_at.parse().unwrap();
    let mut relay = Relay::start(cfg).unwrap();
    let done = wait_until(Duration::from_secs(120), || {
        states(&log(&logs[1])).iter().any(|s| s.0 == state::COMPLETED)
    });
    relay.stop();
    let t2 = log(&logs[1]);
    assert!(done, "robot 2: {:?}", states(&t2));
    for step in 0..5 {
        assert_eq!(started(&t2, step).len(), 1, "robot 2 step {step}");
    }
    drop(o);
    let _ = std::fs::remove_dir_all(&dir);
}
