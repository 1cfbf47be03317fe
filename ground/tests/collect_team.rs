//! The collector follows the team (docs/team.md), end to end: three real obsw processes
//! with a team (`--team-udp`, `--peer`, `--team-state`) under `ground collect --http`,
//! each behind a UDP relay that can silence the ground (drop every TC while TM still
//! flows). The roster is uploaded from the page's API; the page's data
//! (`/api/snapshot`) shows each robot's TEAM_STATUS: roster, term, role, leader and
//! whether the ground is seen. When the ground goes silent the robots elect a leader,
//! which the page shows; when it returns every robot sees the ground again.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

mod common;
use common::{free_port, http, wait_for, Obsw, Proc};

/// A UDP relay between the collector and one obsw: `front` takes the collector's TCs,
/// forwarded unless `silent`; the obsw's TM goes back to the collector always.
struct GroundRelay {
    front: SocketAddr,
    silent: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
}

impl GroundRelay {
    fn start(obsw: SocketAddr) -> GroundRelay {
        let front = UdpSocket::bind("127.0.0.1:0").unwrap();
        let back = UdpSocket::bind("127.0.0.1:0").unwrap();
        back.connect(obsw).unwrap();
        for s in [&front, &back] {
            s.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
        }
        let (silent, stop) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicBool::new(false)));
        let ground: Arc<Mutex<Option<SocketAddr>>> = Arc::new(Mutex::new(None));
        let r = GroundRelay {
            front: front.local_addr().unwrap(),
            silent: silent.clone(),
            stop: stop.clone(),
        };
        let (f2, b2, g2, st2) = (
            front.try_clone().unwrap(),
            back.try_clone().unwrap(),
            ground.clone(),
            stop.clone(),
        );
        std::thread::spawn(move || {
            let mut buf = [0u8; 65536];
            while !stop.load(Ordering::Relaxed) {
                if let Ok((n, from)) = front.recv_from(&mut buf) {
                    *ground.lock().unwrap() = Some(from);
                    if !silent.load(Ordering::Relaxed) {
                        let _ = back.send(&buf[..n]);
                    }
                }
            }
        });
        std::thread::spawn(move || {
            let mut buf = [0u8; 65536];
            while !st2.load(Ordering::Relaxed) {
                if let Ok(n) = b2.recv(&mut buf) {
                    if let Some(g) = *g2.lock().unwrap() {
                        let _ = f2.send_to(&buf[..n], g);
                    }
                }
            }
        });
        r
    }
}

impl Drop for GroundRelay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

fn teams(web: SocketAddr) -> Vec<Value> {
    let (_, s) = http(web, "GET", "/api/snapshot", None);
    s["robots"]
        .as_array()
        .map(|r| r.iter().map(|r| r["team"].clone()).collect())
        .unwrap_or_default()
}

// verifies: ALM-TEAMVIEW-01
#[test]
fn the_page_shows_the_team_and_the_leader_the_robots_elect_without_the_ground() {
    let dir = common::tmpdir("collect-team", "leader");
    let n = 3u8;
    let team: Vec<SocketAddr> = (0..n).map(|_| ([127, 0, 0, 1], free_port()).into()).collect();
    // Team packets are authenticated (--team-key) where the obsw supports it; this test
    // is about the ground's view, so it runs them bare on loopback.
    let help = std::process::Command::new(common::obsw_bin())
        .arg("--help")
        .output()
        .unwrap();
    let lab_team_bare = String::from_utf8_lossy(&help.stdout).contains("--lab-team-bare");
    let mut robots: Vec<Obsw> = Vec::new();
    for r in 1..=n {
        let mut args: Vec<String> = vec![
            "--team-udp".into(),
            team[r as usize - 1].to_string(),
            "--team-state".into(),
            dir.join(format!("team-{r}.state")).display().to_string(),
        ];
        if lab_team_bare {
            args.push("--lab-team-bare".into());
        }
        for (i, a) in team.iter().enumerate() {
            if i + 1 != r as usize {
                args.extend(["--peer".into(), format!("{}={a}", i + 1)]);
            }
        }
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        robots.push(Obsw::start(r, &refs));
    }
    let relays: Vec<GroundRelay> = robots.iter().map(|o| GroundRelay::start(o.addr)).collect();
    let web: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let log = std::fs::File::create(dir.join("collect.log")).unwrap();
    let mut cmd = std::process::Command::new(common::GROUND);
    cmd.current_dir(&dir).args([
        "--archive",
        "a.db",
        "collect",
        "--lab-udp",
        "--plain",
        "--http",
        &web.to_string(),
    ]);
    for (i, r) in relays.iter().enumerate() {
        cmd.args(["--robot", &format!("{}={}", i + 1, r.front)]);
    }
    let _c = Proc(cmd.stdout(std::process::Stdio::null()).stderr(log).spawn().unwrap());

    // Without a roster each robot reports no team (the collector asked at link-up).
    let t = wait_for(60, "a team status of every robot", || {
        let t = teams(web);
        (t.len() == n as usize && t.iter().all(|t| t.is_object())).then_some(t)
    });
    assert!(t.iter().all(|t| t["roster"] == json!([])), "{t:?}");

    // The roster, uploaded from the page's API.
    for r in 1..=n {
        let mut args = serde_json::Map::new();
        for k in 1..=8u8 {
            args.insert(format!("robot_{k}"), json!(if k <= n { k } else { 0 }));
        }
        let (st, body) = http(
            web,
            "POST",
            "/api/tc",
            Some(json!({"robot": r, "name": "TEAM_ROSTER", "args": args})),
        );
        assert_eq!(st, 200, "{body}");
    }
    wait_for(30, "the roster, ground seen, on the page", || {
        let t = teams(web);
        t.iter()
            .all(|t| t["roster"] == json!([1, 2, 3]) && t["ground_seen"] == true && t["leader"].is_null())
            .then_some(())
    });

    // The ground goes silent: a leader is elected, every robot names it.
    for r in &relays {
        r.silent.store(true, Ordering::Relaxed);
    }
    let t0 = Instant::now();
    let (leader, t) = wait_for(40, "a leader on the page", || {
        let t = teams(web);
        let leaders: Vec<&Value> = t.iter().filter(|t| t["role"] == "LEADER").collect();
        let l = leaders.first()?["leader"].as_u64()?;
        (leaders.len() == 1 && t.iter().all(|t| t["leader"] == l && t["ground_seen"] == false)).then_some((l, t))
    });
    eprintln!(
        "leader robot {leader} shown on the page {:.2} s after the ground went silent",
        t0.elapsed().as_secs_f64()
    );
    let term = t[0]["term"].as_u64().unwrap();
    assert!(term >= 1 && t.iter().all(|x| x["term"] == term), "{t:?}");
    // The team events are in the event list too.
    let (_, s) = http(web, "GET", "/api/snapshot", None);
    let names: Vec<&str> = s["events"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|e| e["name"].as_str())
        .collect();
    assert!(
        names.contains(&"GROUND_LOST") && names.contains(&"LEADER_ELECTED"),
        "{names:?}"
    );

    // The ground is back: the collector's next TCs reach the robots.
    for r in &relays {
        r.silent.store(false, Ordering::Relaxed);
    }
    // The ground is back: every robot sees it and the leader steps down.
    wait_for(30, "the ground seen again by every robot, no robot leading", || {
        teams(web)
            .iter()
            .all(|t| t["ground_seen"] == true && t["role"] != "LEADER")
            .then_some(())
    });
    let _ = std::fs::remove_dir_all(&dir);
}
