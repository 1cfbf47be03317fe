//! Runs have an identity; interruption is an operation. Against real
//! `obsw` processes on loopback; what ran on board is judged from the obsw's own
//! `--tm-log` (every TM packet it sent, one hex line each), not from the ground.

use std::collections::BTreeSet;
use std::path::Path;
use std::time::{Duration, Instant};

mod common;
use common::{ground, text, tmpdir, Obsw, Running};

const BOLT_PLAN: &str = r#"
name = "bolt"
[[robot]]
number = 1
initial_state = "Xneg"
[[step]]
id = "operational"
robot = 1
action = "mode"
mode = "operational"
confirm = true
[[step]]
id = "bolt"
robot = 1
action = "bolt"
side = "A"
pairs = "all"
[[step]]
id = "standby"
robot = 1
action = "mode"
mode = "standby"
confirm = true
"#;

/// Distinct TM packets of the obsw's `--tm-log` (a replay writes a packet again).
fn tm_log(path: &Path) -> Vec<ground::pus::Tm> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut seen = BTreeSet::new();
    let mut out = Vec::new();
    for l in text.lines() {
        let bytes: Vec<u8> = (0..l.len() / 2)
            .filter_map(|i| u8::from_str_radix(&l[2 * i..2 * i + 2], 16).ok())
            .collect();
        if !seen.insert(bytes.clone()) {
            continue;
        }
        if let Ok(tm) = ground::pus::decode_tm(&bytes) {
            out.push(tm);
        }
    }
    out
}

fn events_named(tms: &[ground::pus::Tm], name: &str) -> usize {
    tms.iter()
        .filter(|t| matches!(&t.body, ground::pus::TmBody::Event(e) if e.name == name))
        .count()
}

// verifies: OPS-RUN-02, OPS-RUN-03
#[test]
fn ctrl_c_during_a_long_step_then_resume_executes_it_once() {
    let dir = tmpdir("ops", "ctrlc");
    let log = dir.join("tm.log");
    // At speed 2 BOLT_FACE runs for about 8 s.
    let o = Obsw::start(
        1,
        &[
            "--speed",
            "2",
            "--seed",
            "7",
            "--initial-state",
            "Xneg",
            "--tm-log",
            log.to_str().unwrap(),
        ],
    );
    std::fs::write(dir.join("bolt.toml"), BOLT_PLAN).unwrap();
    let r = format!("1={}", o.addr);
    let mut run = Running::start(
        &dir,
        &[
            "run",
            "--lab-udp",
            "bolt.toml",
            "--robot",
            &r,
            "--plain",
            "--grace",
            "1",
        ],
    );
    run.wait_for("send     bolt", Duration::from_secs(20));
    std::thread::sleep(Duration::from_millis(700));
    let t_int = Instant::now();
    run.interrupt();
    let (code, out, err) = run.finish();
    let all = format!("{out}\n{err}");
    assert_eq!(code, Some(6), "{all}");
    assert!(
        t_int.elapsed() < Duration::from_secs(4),
        "bounded wait: {:?}",
        t_int.elapsed()
    );
    assert!(
        out.contains("INTERRUPTED") && out.contains("1 step(s) still running on board"),
        "{all}"
    );
    assert!(
        out.lines().any(|l| l.contains("RUNNING") && l.contains("bolt")),
        "{all}"
    );
    assert!(
        out.lines().any(|l| l.contains("not sent") && l.contains("standby")),
        "{all}"
    );
    let run_id = out
        .lines()
        .find_map(|l| l.strip_prefix("run "))
        .expect("the summary names the run")
        .trim()
        .to_string();

    // The bolting finishes on board while no ground listens; then resume.
    std::thread::sleep(Duration::from_secs(10));
    let res = ground(
        &dir,
        &["run", "--lab-udp", "bolt.toml", "--robot", &r, "--plain", "--resume"],
    );
    let t = text(&res);
    assert_eq!(res.status.code(), Some(0), "{t}");
    assert!(t.contains(&format!("resuming run {run_id}")), "{t}");
    assert!(t.contains("3 of 3 steps done"), "{t}");
    assert!(t.contains("resolving its outcome before anything is sent"), "{t}");

    // Judged from the obsw's own TM: BOLT_FACE bolted the four pairs once, and there is
    // exactly one completion report for one BOLT_FACE request.
    drop(o);
    let tms = tm_log(&log);
    assert_eq!(events_named(&tms, "BOLT_PAIR_DONE"), 4, "{t}");
    let starts: BTreeSet<(u16, u16)> = tms
        .iter()
        .filter_map(|tm| match &tm.body {
            ground::pus::TmBody::Verification(v) if v.stage == ground::pus::Stage::Start => {
                Some((v.request.apid(), v.request.seq()))
            }
            _ => None,
        })
        .collect();
    assert_eq!(
        starts.len(),
        1,
        "one action started on board (BOLT_FACE): {starts:?}\n{t}"
    );
}

// verifies: OPS-RUN-01
#[test]
fn resume_continues_the_latest_run_and_counts_only_its_steps() {
    let dir = tmpdir("ops", "resume-latest");
    let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans/demo.toml");
    let plan = plan.to_str().unwrap();
    // Run 1 completes on one pair of robots.
    {
        let a = Obsw::start(1, &["--speed", "20", "--seed", "7", "--initial-state", "Xneg"]);
        let b = Obsw::start(2, &["--speed", "20", "--seed", "8", "--initial-state", "Xpos"]);
        let out = ground(
            &dir,
            &[
                "run",
                "--lab-udp",
                plan,
                "--plain",
                "--robot",
                &format!("1={}", a.addr),
                "--robot",
                &format!("2={}", b.addr),
            ],
        );
        assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    }
    // Run 2 on fresh robots, interrupted after robot 1's walk.
    let a = Obsw::start(1, &["--speed", "4", "--seed", "7", "--initial-state", "Xneg"]);
    let b = Obsw::start(2, &["--speed", "4", "--seed", "8", "--initial-state", "Xpos"]);
    let (ra, rb) = (format!("1={}", a.addr), format!("2={}", b.addr));
    let mut run = Running::start(
        &dir,
        &[
            "run",
            "--lab-udp",
            plan,
            "--plain",
            "--robot",
            &ra,
            "--robot",
            &rb,
            "--grace",
            "0.5",
        ],
    );
    run.wait_for("done     r1-walk", Duration::from_secs(60));
    // SIGTERM (a service manager stopping the ground) is the same operation as Ctrl-C.
    run.signal("-TERM");
    let (code, out, err) = run.finish();
    assert_eq!(code, Some(6), "{out}\n{err}");
    let run2 = out
        .lines()
        .find_map(|l| l.strip_prefix("run "))
        .unwrap()
        .trim()
        .to_string();
    let done2 = out.lines().filter(|l| l.trim_start().starts_with("done ")).count();
    assert!((2..10).contains(&done2), "{out}");

    let res = ground(
        &dir,
        &[
            "run",
            "--lab-udp",
            plan,
            "--plain",
            "--robot",
            &ra,
            "--robot",
            &rb,
            "--resume",
        ],
    );
    let t = text(&res);
    assert_eq!(res.status.code(), Some(0), "{t}");
    assert!(
        t.contains(&format!("resuming run {run2}")),
        "the latest run, not run 1: {t}"
    );
    assert!(t.contains("10 of 10 steps done"), "{t}");
    assert!(
        t.contains(&format!("resumed: {done2} steps completed")),
        "only run 2's {done2} steps count: {t}"
    );
    // The robots are where the plan leaves them (their own HK, via ping).
    let p = ground(
        &dir,
        &[
            "ping",
            "--lab-udp",
            "--robot",
            &ra,
            "--robot",
            &rb,
            "-c",
            "3",
            "--interval",
            "1",
        ],
    );
    let pt = text(&p);
    assert!(pt.contains("robot 1: mode STANDBY | state Yneg"), "{pt}");
    assert!(pt.contains("robot 2: mode STANDBY | state Xneg"), "{pt}");
    // A run ID that is not in the archive is refused.
    let bad = ground(
        &dir,
        &[
            "run",
            "--lab-udp",
            plan,
            "--plain",
            "--robot",
            &ra,
            "--robot",
            &rb,
            "--resume",
            "nope",
        ],
    );
    assert_eq!(bad.status.code(), Some(3), "{}", text(&bad));
    assert!(text(&bad).contains("no run nope"), "{}", text(&bad));
}

// verifies: OPS-RUN-02
#[test]
fn a_second_ctrl_c_exits_at_once() {
    let dir = tmpdir("ops", "ctrlc-twice");
    let o = Obsw::start(1, &["--speed", "1", "--seed", "7", "--initial-state", "Xneg"]);
    std::fs::write(dir.join("bolt.toml"), BOLT_PLAN).unwrap();
    let r = format!("1={}", o.addr);
    let mut run = Running::start(
        &dir,
        &[
            "run",
            "--lab-udp",
            "bolt.toml",
            "--robot",
            &r,
            "--plain",
            "--grace",
            "60",
        ],
    );
    run.wait_for("send     bolt", Duration::from_secs(20));
    run.interrupt();
    run.wait_for("waiting up to 60 s for bolt", Duration::from_secs(5));
    let t0 = Instant::now();
    run.interrupt();
    let (code, _out, err) = run.finish();
    assert_eq!(code, Some(130), "{err}");
    assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
    assert!(err.contains("interrupted again: exiting at once"), "{err}");
}
