//! The dashboard of a real `ground collect --http` following a real `obsw`, driven
//! through its JSON API (the same calls the page makes; `scripts/web-test.sh` drives the
//! page itself in Chromium): the robot appears with its mode tree and live values, a PING
//! completes with its stages, a hazardous TC needs confirmation, and a battery sag
//! injected through the simulator control port raises an alarm that is acknowledged.
//!
//! Plans (configured with `plans = [...]`): started through the JSON API, every step's
//! progress and the run's end followed over the SSE stream; hazardous plans need
//! confirmation; a second start on a busy robot is refused; a refused step ends the run
//! failed with its failure name.
//!
//! The obsw binary is `$OBSW_BIN`, or the one next to this test's target profile, or
//! built into `<target>/ground-obsw` (as `tests/live.rs` does).

use std::io::{BufRead, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

mod common;
use common::{free_port, http, wait_for, Obsw, Proc};

/// Robot `robot`'s obsw at double speed: `(process, TC address, simulator control)`.
fn start_obsw(robot: u8) -> (Obsw, SocketAddr, SocketAddr) {
    let o = Obsw::start(robot, &["--speed", "2", "--seed", "7"]);
    let (tc, ctl) = (o.addr, o.ctl);
    (o, tc, ctl)
}

/// `ground collect --http` in `dir` with the configuration `config` (robots and plans);
/// returns once the robots are up and in STANDBY.
fn start_collector(dir: &Path, config: &str, robots: usize) -> (Proc, SocketAddr) {
    // The bare-packet lab link (robots on loopback); frames.rs runs the collector over frames.
    std::fs::write(dir.join("collect.toml"), format!("transport = \"lab-udp\"\n{config}")).unwrap();
    let web: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let log = std::fs::File::create(dir.join("collect.log")).unwrap();
    let p = Proc(
        Command::new(env!("CARGO_BIN_EXE_ground"))
            .current_dir(dir)
            .args(["--archive", "a.db", "collect", "--plain", "--config", "collect.toml"])
            .args(["--http", &web.to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("starting ground collect --http"),
    );
    wait_for(60, "robots up under the collector", || {
        let s = std::panic::catch_unwind(|| http(web, "GET", "/api/snapshot", None).1).ok()?;
        let r = s["robots"].as_array()?;
        (r.len() == robots && r.iter().all(|r| r["link"] == "up" && r["mode"] == "STANDBY")).then_some(())
    });
    (p, web)
}

fn tmpdir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dash-live-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

// verifies: GND-16, GND-18, ALM-MSG-01
#[test]
fn live_robot_ping_and_injected_fault_through_the_dashboard_api() {
    let (_obsw, tc, ctl) = start_obsw(1);
    let dir = tmpdir("api");
    let (_collector, a) = start_collector(&dir, &format!("[[robot]]\nnumber = 1\naddr = \"{tc}\"\n"), 1);

    // The robot with its mode and live values.
    let robot = wait_for(30, "robot 1 with mode and HK", || {
        let (_, s) = http(a, "GET", "/api/snapshot", None);
        let r = s["robots"][0].clone();
        (r["mode"] == "STANDBY" && r["hk"]["V_BAT_A"]["unit"] == "V").then_some(r)
    });
    assert_eq!(robot["link"], "up");
    assert!(robot["config"]["face_a"].is_string(), "{}", robot["config"]);

    // PING from the API completes with its stages.
    let (st, r) = http(
        a,
        "POST",
        "/api/tc",
        Some(json!({"robot": 1, "name": "PING", "args": {}})),
    );
    assert_eq!(st, 200, "{r}");
    let id = r["request_id"].as_str().unwrap().to_string();
    let stages = wait_for(30, "PING completion", || {
        let (_, c) = http(a, "GET", &format!("/api/tc/{id}"), None);
        let s = c["stages"].as_array().cloned().unwrap_or_default();
        s.iter().any(|x| x["stage"] == "completion").then_some(s)
    });
    assert_eq!(stages[0]["stage"], "acceptance");
    assert!(stages.iter().all(|s| s["success"] == true), "{stages:?}");

    // Operational (hazardous: refused unconfirmed, then confirmed), then a battery sag
    // from the simulator.
    let mut mode = json!({"robot": 1, "name": "MODE_SET",
        "args": {"node": "ROBOT", "mode": "OPERATIONAL", "submode": 0}});
    assert_eq!(http(a, "POST", "/api/tc", Some(mode.clone())).0, 409);
    mode["confirm"] = json!(true);
    assert_eq!(http(a, "POST", "/api/tc", Some(mode)).0, 200);
    // The mode tree follows the board's MODE_CHANGED events down to the leaves.
    wait_for(30, "OPERATIONAL with its mode tree", || {
        let (_, s) = http(a, "GET", "/api/snapshot", None);
        let r = &s["robots"][0];
        (r["mode"] == "OPERATIONAL" && r["modes"]["GRIPPER_B"] == "ON").then_some(())
    });
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.send_to(b"battery-sag 9.2\n", ctl).unwrap();
    let alarm = wait_for(30, "battery alarm", || {
        let (_, s) = http(a, "GET", "/api/snapshot", None);
        s["alarms"].as_array().and_then(|v| {
            v.iter()
                // The board's LOW_BATTERY fault event, or the ground's hard-limit check
                // of V_BAT_A/B if an HK report caught the sag before the board went to standby.
                .find(|x| {
                    let src = x["source"].as_str().unwrap_or("");
                    matches!(src, "LOW_BATTERY" | "V_BAT_A" | "V_BAT_B") && x["state"] == "active"
                })
                .cloned()
        })
    });
    assert_eq!(alarm["severity"], "high");
    let aid = alarm["id"].as_u64().unwrap();
    assert_eq!(http(a, "POST", &format!("/api/alarms/{aid}/ack"), None).0, 200);
    let (_, s) = http(a, "GET", "/api/snapshot", None);
    let acked = s["alarms"]
        .as_array()
        .unwrap()
        .iter()
        .find(|x| x["id"] == aid)
        .cloned()
        .unwrap();
    assert_eq!(acked["state"], "acknowledged");
    // Acknowledging again is refused, and the refusal names the alarm once
    // ("alarm 3: alarm 3: nothing to acknowledge").
    let (st, r) = http(a, "POST", &format!("/api/alarms/{aid}/ack"), None);
    assert_eq!(st, 400, "{r}");
    let msg = r["error"].as_str().unwrap_or_default();
    assert!(
        msg.starts_with(&format!("alarm {aid}: nothing to acknowledge")),
        "{msg}"
    );
    assert_eq!(msg.matches("alarm ").count(), 1, "{msg}");
    // The board's own fault event is there too, by name.
    wait_for(30, "LOW_BATTERY event", || {
        let (_, s) = http(a, "GET", "/api/snapshot", None);
        s["events"]
            .as_array()
            .and_then(|v| v.iter().find(|e| e["name"] == "LOW_BATTERY").cloned())
    });
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------
// Plans started from the page under a real `ground collect --http`.

/// A short plan for robot 1: a connection test, OPERATIONAL (hazardous: changes module
/// power), a ground pause, STANDBY.
const SHORT_PLAN: &str = r#"
name = "short"
description = "ping, operational, pause, standby"
[[robot]]
number = 1
[[step]]
id = "ping"
robot = 1
action = "command"
tc = "PING"
[[step]]
id = "operational"
robot = 1
action = "mode"
mode = "operational"
[[step]]
id = "pause"
robot = 1
action = "wait"
seconds = 1
[[step]]
id = "standby"
robot = 1
action = "mode"
mode = "standby"
"#;

/// A plan the robot refuses: a reconfiguration from a state it is not in (the
/// simulated robot starts in Xneg).
const REFUSED_PLAN: &str = r#"
name = "refused"
description = "reconfigure from the wrong state"
[[robot]]
number = 1
[[step]]
id = "operational"
robot = 1
action = "mode"
mode = "operational"
[[step]]
id = "walk"
robot = 1
action = "reconfigure"
from = "Xpos"
to = "Xneg"
[[step]]
id = "after"
robot = 1
action = "command"
tc = "PING"
"#;

/// Follows `GET /api/stream` and hands over every `plan` message.
fn plan_messages(addr: SocketAddr) -> std::sync::mpsc::Receiver<Value> {
    let (tx, rx) = std::sync::mpsc::channel();
    let mut s = TcpStream::connect(addr).unwrap();
    s.write_all(b"GET /api/stream HTTP/1.1\r\nHost: localhost\r\nAccept: text/event-stream\r\n\r\n")
        .unwrap();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(s).lines() {
            let Ok(line) = line else { return };
            if let Some(data) = line.strip_prefix("data:") {
                if let Ok(v) = serde_json::from_str::<Value>(data.trim()) {
                    if v["type"] == "plan" && tx.send(v["plan"].clone()).is_err() {
                        return;
                    }
                }
            }
        }
    });
    rx
}

/// `POST /api/plans` for plan `name`, hazards confirmed.
fn start_plan(addr: SocketAddr, name: &str) -> (u16, Value) {
    http(addr, "POST", "/api/plans", Some(json!({"name": name, "confirm": true})))
}

/// Every state each step of run `run_id` went through (in order, repeats folded), and
/// the run's last message, once it is no longer running.
fn follow_run(rx: &std::sync::mpsc::Receiver<Value>, run_id: &str, secs: u64) -> (Vec<Vec<String>>, Value) {
    let end = Instant::now() + Duration::from_secs(secs);
    let mut seen: Vec<Vec<String>> = Vec::new();
    loop {
        let left = end.saturating_duration_since(Instant::now());
        let p = rx
            .recv_timeout(left)
            .unwrap_or_else(|_| panic!("run {run_id} did not end within {secs} s; step states so far {seen:?}"));
        if p["run_id"] != run_id {
            continue;
        }
        let steps = p["steps"].as_array().unwrap();
        seen.resize(steps.len(), Vec::new());
        for (i, s) in steps.iter().enumerate() {
            let st = s["state"].as_str().unwrap().to_string();
            if seen[i].last() != Some(&st) {
                seen[i].push(st);
            }
        }
        if p["state"] != "running" {
            return (seen, p);
        }
    }
}

// verifies: GND-19, GND-18
#[test]
fn plans_start_from_the_page_under_collect_with_live_progress_and_one_per_robot() {
    let (_obsw, tc, _ctl) = start_obsw(1);
    let dir = tmpdir("plans");
    std::fs::write(dir.join("short.toml"), SHORT_PLAN).unwrap();
    std::fs::write(dir.join("refused.toml"), REFUSED_PLAN).unwrap();
    let config = format!("plans = [\"short.toml\", \"refused.toml\"]\n[[robot]]\nnumber = 1\naddr = \"{tc}\"\n");
    let (_collector, web) = start_collector(&dir, &config, 1);

    // The configured plans, with the hazardous TCs named.
    let (st, list) = http(web, "GET", "/api/plans", None);
    assert_eq!(st, 200, "{list}");
    let short = list
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "short")
        .cloned()
        .expect("plan short offered");
    assert_eq!(short["robots"], json!([1]));
    assert_eq!(short["steps"], 4);
    let hazards = short["hazards"].as_array().unwrap();
    assert_eq!(hazards.len(), 2, "{hazards:?}");
    assert!(hazards[0].as_str().unwrap().contains("MODE_SET"), "{hazards:?}");

    let rx = plan_messages(web);
    // Hazardous TCs: not started without the operator's confirmation; unknown plans 404.
    let (st, r) = http(web, "POST", "/api/plans", Some(json!({"name": "short"})));
    assert_eq!(st, 409, "{r}");
    assert!(r["error"].as_str().unwrap().contains("hazardous"), "{r}");
    let (st, r) = start_plan(web, "nope");
    assert_eq!(st, 404, "{r}");

    let (st, r) = start_plan(web, "short");
    assert_eq!(st, 200, "{r}");
    let run = r["run_id"].as_str().unwrap().to_string();
    // One plan per robot: a second start while it runs is refused.
    let (st, r) = start_plan(web, "refused");
    assert_eq!(st, 409, "{r}");
    assert!(r["error"].as_str().unwrap().contains(&run), "{r}");
    // A page TC meanwhile: the same thread, the same counter, never the same request ID.
    let (st, r) = http(
        web,
        "POST",
        "/api/tc",
        Some(json!({"robot": 1, "name": "PING", "args": {}})),
    );
    assert_eq!(st, 200, "{r}");
    let page_id = r["request_id"].as_str().unwrap().to_string();

    let (seen, last) = follow_run(&rx, &run, 120);
    assert_eq!(last["state"], "done", "{last}");
    for (i, s) in seen.iter().enumerate() {
        assert_eq!(s.first().map(String::as_str), Some("waiting"), "step {i} states {s:?}");
        assert!(s.contains(&"running".to_string()), "step {i} states {s:?}");
        assert_eq!(s.last().map(String::as_str), Some("done"), "step {i} states {s:?}");
    }
    let ids: Vec<String> = last["steps"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|s| s["request_id"].as_str().map(str::to_string))
        .collect();
    assert_eq!(ids.len(), 3, "{last}");
    let mut all = ids.clone();
    all.push(page_id);
    all.sort();
    all.dedup();
    assert_eq!(all.len(), 4, "request IDs reused: {ids:?}");
    for id in &ids {
        let (_, c) = http(web, "GET", &format!("/api/tc/{id}"), None);
        assert_eq!(c["origin"], "plan short", "{c}");
        assert!(
            c["stages"]
                .as_array()
                .unwrap()
                .iter()
                .any(|s| s["stage"] == "completion" && s["success"] == true),
            "{c}"
        );
    }

    // The robot is free again; a run the robot refuses ends failed with the failure name,
    // and the step after it is blocked.
    let (st, r) = start_plan(web, "refused");
    assert_eq!(st, 200, "{r}");
    let run = r["run_id"].as_str().unwrap().to_string();
    let (_, last) = follow_run(&rx, &run, 60);
    assert_eq!(last["state"], "failed", "{last}");
    let detail = last["detail"].as_str().unwrap();
    assert!(detail.starts_with("step walk failed: robot 1: "), "{detail}");
    let (_, c) = http(
        web,
        "GET",
        &format!("/api/tc/{}", last["steps"][1]["request_id"].as_str().unwrap()),
        None,
    );
    let name = c["stages"]
        .as_array()
        .unwrap()
        .iter()
        .find_map(|s| s["failure"]["name"].as_str())
        .expect("a failure report")
        .to_string();
    assert!(detail.contains(&name), "{detail} names {name}");
    assert_eq!(last["steps"][2]["state"], "blocked", "{last}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Robot 1 on board: a ping, a long wait, a ping.
const ONBOARD_PLAN: &str = r#"name = "onboard"
description = "robot 1 runs it itself"
[[robot]]
number = 1
[[step]]
id = "ping"
robot = 1
action = "command"
tc = "PING"
[[step]]
id = "hold"
robot = 1
action = "wait"
seconds = 30
[[step]]
id = "ping2"
robot = 1
action = "command"
tc = "PING"
"#;

// verifies: GND-ONBOARD-01, GND-ONBOARD-02
#[test]
fn an_on_board_plan_is_shown_live_and_suspended_and_resumed_through_the_dashboard_api() {
    let (_obsw, tc, _ctl) = start_obsw(1);
    let dir = tmpdir("onboard");
    std::fs::write(dir.join("onboard.toml"), ONBOARD_PLAN).unwrap();
    // Uploaded and started by the CLI, which leaves the robot to it (one commanding ground
    // per robot: the collector follows it afterwards).
    let out = Command::new(env!("CARGO_BIN_EXE_ground"))
        .current_dir(&dir)
        .args(["--archive", "run.db", "run", "--on-board", "--detach", "--lab-udp"])
        .args(["--robot", &format!("1={tc}"), "onboard.toml"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (_collector, a) = start_collector(&dir, &format!("[[robot]]\nnumber = 1\naddr = \"{tc}\"\n"), 1);
    let onboard = |state: &'static str| {
        wait_for(30, state, || {
            let (_, s) = http(a, "GET", "/api/snapshot", None);
            let o = s["robots"][0]["onboard"].clone();
            (o["state"] == state).then_some(o)
        })
    };
    let o = onboard("RUNNING");
    assert_eq!((o["steps"].as_u64(), o["done"].as_u64()), (Some(3), Some(1)), "{o}");
    assert!(
        o["plan_id"]
            .as_str()
            .is_some_and(|p| p.starts_with("0x") && p != "0x00000000"),
        "{o}"
    );
    assert_eq!(o["controls"], json!(["suspend", "abort"]));
    let (st, r) = http(
        a,
        "POST",
        "/api/robots/1/onboard/resume",
        Some(json!({"confirm": true})),
    );
    assert_eq!(st, 409, "{r}");
    let completed = |id: &str| {
        wait_for(30, "the control's completion", || {
            let (_, c) = http(a, "GET", &format!("/api/tc/{id}"), None);
            let stages = c["stages"].as_array()?.clone();
            stages.iter().any(|s| s["stage"] == "completion").then_some(c)
        })
    };
    // Suspend: the robot says SUSPENDED (by command), the TC's stages are all ✓.
    let (st, r) = http(a, "POST", "/api/robots/1/onboard/suspend", None);
    assert_eq!(st, 200, "{r}");
    let c = completed(r["request_id"].as_str().unwrap());
    assert_eq!(
        (c["name"].as_str(), c["origin"].as_str()),
        (Some("PLAN_SUSPEND"), Some("page: on-board plan"))
    );
    assert!(
        c["stages"].as_array().unwrap().iter().all(|s| s["success"] == true),
        "{c}"
    );
    let o = onboard("SUSPENDED");
    assert_eq!(o["cause"], "COMMAND");
    assert_eq!(o["controls"], json!(["resume", "abort", "skip"]));
    // Resume (hazardous: confirmed) skips nothing: every step done in the end.
    let (st, r) = http(a, "POST", "/api/robots/1/onboard/resume", None);
    assert_eq!(st, 409, "{r}");
    let (st, r) = http(
        a,
        "POST",
        "/api/robots/1/onboard/resume",
        Some(json!({"confirm": true})),
    );
    assert_eq!(st, 200, "{r}");
    completed(r["request_id"].as_str().unwrap());
    let o = onboard("COMPLETED");
    assert_eq!(
        (o["done"].as_u64(), o["cause"].as_str()),
        (Some(3), Some("DONE")),
        "{o}"
    );
    assert_eq!(o["controls"], json!([]));
    let (st, r) = http(a, "POST", "/api/robots/1/onboard/abort", None);
    assert_eq!(st, 409, "a completed plan is not aborted from the page: {r}");
}
