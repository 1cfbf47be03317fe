//! The dashboard fed by `dashboard::feed::LinkFeed` (the example binary's feed; `ground
//! collect --http` is tested in `tests/collect.rs`) from a real `obsw`, driven through
//! its JSON API (the same calls the page makes; `scripts/web-test.sh` drives the page
//! itself in Chromium): the robot appears with its mode tree and live values, a PING
//! completes with its stages, and a battery sag injected through the simulator control
//! port raises an alarm that is acknowledged.
//!
//! The obsw binary is `$OBSW_BIN`, or the one next to this test's target profile, or
//! built into `<target>/ground-obsw` (as `tests/live.rs` does).

use std::io::{BufRead, Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ground::dashboard::{self, feed::LinkFeed, Hub, NoArchive};
use serde_json::{json, Value};

fn obsw_bin() -> PathBuf {
    if let Some(p) = std::env::var_os("OBSW_BIN") {
        return PathBuf::from(p);
    }
    let exe = std::env::current_exe().unwrap();
    let profile_dir = exe.parent().and_then(Path::parent).unwrap();
    let next = profile_dir.join("obsw");
    if next.is_file() {
        return next;
    }
    let own = profile_dir.parent().unwrap().join("ground-obsw");
    let st = Command::new(env!("CARGO"))
        .args(["build", "-q", "-p", "obsw", "--bin", "obsw"])
        .env("CARGO_TARGET_DIR", &own)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .status()
        .expect("running cargo to build obsw");
    assert!(st.success(), "building obsw failed");
    own.join("debug").join("obsw")
}

fn free_port() -> u16 {
    loop {
        let t = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let p = t.local_addr().unwrap().port();
        if UdpSocket::bind(("127.0.0.1", p)).is_ok() {
            return p;
        }
    }
}

struct Obsw(Child);
impl Drop for Obsw {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn start_obsw(robot: u8) -> (Obsw, SocketAddr, SocketAddr) {
    let tc: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let ctl: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let mut child = Command::new(obsw_bin())
        .args([
            "--robot",
            &robot.to_string(),
            "--udp",
            &tc.to_string(),
            "--sim-ctl",
            &ctl.to_string(),
        ])
        .args(["--speed", "2", "--seed", "7"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("obsw starts");
    let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    assert!(first.starts_with("READY"), "{first}");
    std::thread::spawn(move || for _ in lines {});
    (Obsw(child), tc, ctl)
}

fn http(addr: SocketAddr, method: &str, path: &str, body: Option<Value>) -> (u16, Value) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let body = body.map(|b| b.to_string()).unwrap_or_default();
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    if !body.is_empty() {
        req.push_str("Content-Type: application/json\r\n");
    }
    req.push_str("\r\n");
    req.push_str(&body);
    s.write_all(req.as_bytes()).unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).unwrap();
    let status = out[9..12].parse().unwrap();
    let text = out.split_once("\r\n\r\n").map(|x| x.1).unwrap_or("");
    (status, serde_json::from_str(text).unwrap_or(Value::Null))
}

/// Polls `f` until it returns `Some`, for at most `secs` seconds (the machine is shared).
fn wait_for<T>(secs: u64, what: &str, mut f: impl FnMut() -> Option<T>) -> T {
    let end = Instant::now() + Duration::from_secs(secs);
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(Instant::now() < end, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

// verifies: GND-16, GND-18
#[test]
fn live_robot_ping_and_injected_fault_through_the_dashboard_api() {
    let (_obsw, tc, ctl) = start_obsw(1);
    let hub = Hub::new();
    let feed = LinkFeed::start(hub.clone(), &[(1, tc)], None).expect("links open");
    let srv = dashboard::spawn(
        "127.0.0.1:0".parse().unwrap(),
        None,
        hub.clone(),
        Arc::new(feed.clone()),
        Arc::new(NoArchive),
    )
    .expect("server starts");
    let a = srv.local_addr();

    // The robot with its mode, mode tree and live values.
    let robot = wait_for(30, "robot 1 with mode tree and HK", || {
        let (_, s) = http(a, "GET", "/api/snapshot", None);
        let r = s["robots"][0].clone();
        (r["mode"] == "STANDBY" && r["modes"]["GRIPPER_B"] == "OFF" && r["hk"]["V_BAT_A"]["unit"] == "V").then_some(r)
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

    // Operational (hazardous: confirmed), then a battery sag from the simulator.
    let mode = json!({"robot": 1, "name": "MODE_SET", "confirm": true,
        "args": {"node": "ROBOT", "mode": "OPERATIONAL", "submode": 0}});
    assert_eq!(http(a, "POST", "/api/tc", Some(mode)).0, 200);
    wait_for(30, "OPERATIONAL", || {
        let (_, s) = http(a, "GET", "/api/snapshot", None);
        (s["robots"][0]["mode"] == "OPERATIONAL").then_some(())
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
    // The board's own fault event is there too, by name.
    wait_for(30, "LOW_BATTERY event", || {
        let (_, s) = http(a, "GET", "/api/snapshot", None);
        s["events"]
            .as_array()
            .and_then(|v| v.iter().find(|e| e["name"] == "LOW_BATTERY").cloned())
    });
    feed.stop();
    srv.stop();
}
