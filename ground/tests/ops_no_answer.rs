//! One answer for "the robot does not answer": the same message and
//! exit code from `run`, `send`, `ping` and `watch`, fast; a `--robot` not in the plan
//! and a verb without a robot are refused up front.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{free_port, ground, text, tmpdir, Obsw, GROUND};

const ONE_ROBOT_PLAN: &str = r#"
name = "one"
[[robot]]
number = 1
[[step]]
id = "ping"
robot = 1
action = "command"
tc = "PING"
"#;

/// Each verb with `robot` (`N=HOST:PORT`) as its robot, in `dir` (which holds `one.toml`).
fn verbs(robot: &str) -> Vec<Vec<String>> {
    let v = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    vec![
        v(&["--no-archive", "send", "--lab-udp", "--robot", robot, "PING"]),
        v(&["--no-archive", "ping", "--lab-udp", "--robot", robot, "-c", "2"]),
        v(&[
            "--no-archive",
            "watch",
            "--lab-udp",
            "--robot",
            robot,
            "--duration",
            "8",
        ]),
        v(&[
            "--no-archive",
            "run",
            "--lab-udp",
            "one.toml",
            "--plain",
            "--robot",
            robot,
        ]),
    ]
}

fn check_all(dir: &Path, robot: &str, code: i32, says: &str, within: Duration) {
    for args in verbs(robot) {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let t0 = Instant::now();
        let out = ground(dir, &a);
        let took = t0.elapsed();
        let t = text(&out);
        assert_eq!(out.status.code(), Some(code), "{a:?}: {t}");
        assert!(t.contains(says), "{a:?} does not say {says:?}: {t}");
        assert!(took < within, "{a:?} took {took:?}: {t}");
    }
}

// verifies: OPS-ANSWER-01
#[test]
fn nothing_heard_is_exit_8_from_every_verb_within_the_link_loss_time() {
    let dir = tmpdir("ops", "nothing");
    std::fs::write(dir.join("one.toml"), ONE_ROBOT_PLAN).unwrap();
    let robot = format!("1=127.0.0.1:{}", free_port());
    let limit = Duration::from_millis(mib::ground_config::LINK_LOSS_MS as u64) + Duration::from_secs(2);
    check_all(&dir, &robot, 8, "robot 1: nothing heard from 127.0.0.1:", limit);
}

// verifies: OPS-ANSWER-01
#[test]
fn replies_from_another_apid_are_exit_7_from_every_verb_at_once() {
    let dir = tmpdir("ops", "other-apid");
    std::fs::write(dir.join("one.toml"), ONE_ROBOT_PLAN).unwrap();
    let b = Obsw::start(2, &["--speed", "20"]);
    let robot = format!("1={}", b.addr);
    check_all(
        &dir,
        &robot,
        7,
        "carry APID 0x102 (robot 2), not robot 1's 0x101: another robot answers at this address",
        Duration::from_millis(2000),
    );
}

// verifies: OPS-ANSWER-01
#[test]
fn heard_then_lost_is_exit_5_from_watch_run_and_send() {
    let dir = tmpdir("ops", "lost");
    std::fs::write(
        dir.join("walk.toml"),
        r#"
name = "walk"
[[robot]]
number = 1
initial_state = "Xneg"
[[step]]
id = "op"
robot = 1
action = "mode"
mode = "operational"
confirm = true
[[step]]
id = "walk"
robot = 1
action = "reconfigure"
to = "Xpos"
"#,
    )
    .unwrap();
    for args in [
        vec!["--no-archive", "watch", "--lab-udp", "--duration", "30"],
        vec!["--no-archive", "run", "--lab-udp", "walk.toml", "--plain"],
        vec![
            "--no-archive",
            "send",
            "--lab-udp",
            "RECONFIGURE",
            "from=Xneg",
            "to=Xpos",
        ],
    ] {
        let o = Obsw::start(1, &["--speed", "1", "--initial-state", "Xneg"]);
        let r = format!("1={}", o.addr);
        if args[1] == "send" {
            let out = ground(
                &dir,
                &[
                    "--no-archive",
                    "mode",
                    "--lab-udp",
                    "--robot",
                    &r,
                    "operational",
                    "--confirm",
                ],
            );
            assert_eq!(out.status.code(), Some(0), "{}", text(&out));
        }
        let mut a = args.clone();
        a.extend(["--robot", &r]);
        let child = Command::new(GROUND)
            .current_dir(&dir)
            .args(&a)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_secs(3));
        let t0 = Instant::now();
        drop(o); // SIGTERM: the obsw stops
        let out = child.wait_with_output().unwrap();
        let t = text(&out);
        assert_eq!(out.status.code(), Some(5), "{a:?}: {t}");
        assert!(
            t.contains("robot 1: heard, then lost: nothing heard from"),
            "{a:?}: {t}"
        );
        assert!(t0.elapsed() < Duration::from_secs(6), "{a:?}: {:?}", t0.elapsed());
    }
}

// verifies: OPS-ANSWER-01, OPS-DEFAULT-01
#[test]
fn a_robot_not_in_the_plan_and_a_verb_without_a_robot_are_refused_up_front() {
    let dir = tmpdir("ops", "refused");
    let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans/demo.toml");
    let t0 = Instant::now();
    let out = ground(
        &dir,
        &[
            "--no-archive",
            "run",
            "--lab-udp",
            plan.to_str().unwrap(),
            "--robot",
            "3",
            "--plain",
        ],
    );
    let t = text(&out);
    assert_eq!(out.status.code(), Some(2), "{t}");
    assert!(t.contains("robot 3 is not in plan \"demo\" (its robots: 1, 2)"), "{t}");
    assert!(t0.elapsed() < Duration::from_secs(2));
    for args in [
        vec!["send", "--lab-udp", "PING"],
        vec!["ping"],
        vec!["watch", "--lab-udp", "--duration", "1"],
        vec!["mode", "--lab-udp", "standby", "--confirm"],
    ] {
        let mut a = vec!["--no-archive"];
        a.extend(args);
        let out = ground(&dir, &a);
        assert_eq!(out.status.code(), Some(2), "{a:?}: {}", text(&out));
        assert!(text(&out).contains("give --robot N"), "{a:?}: {}", text(&out));
    }
    let out = ground(&dir, &["sim", "status"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    // Every verb that talks to robots says to which.
    let o = Obsw::start(1, &["--speed", "20"]);
    let out = ground(
        &dir,
        &[
            "--no-archive",
            "ping",
            "--lab-udp",
            "--robot",
            &format!("1={}", o.addr),
            "-c",
            "1",
        ],
    );
    assert!(
        text(&out).contains(&format!("talking to robot 1 at {} (UDP, bare packets)", o.addr)),
        "{}",
        text(&out)
    );
}
