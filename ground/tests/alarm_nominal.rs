//! Nominal plans raise no alarm: the shipped demo and checkout plans
//! run in `ground collect` (started through its API, as the page starts them) against
//! healthy simulated robots (the real `obsw`); the collector's archive must then hold no
//! alarm at all. Each test also checks that the plan did what makes the check
//! meaningful: the hip deviation went far beyond its limits while a primitive turned
//! the hip (the corner turn that raised `HIP_DEVIATION = -55.050 deg` HIGH before the
//! MIB could say "only while no primitive runs").
//!
//! The obsw binary is `$OBSW_BIN`, or the one next to this test's profile directory
//! (`cargo build -p obsw`), or it is built into `<target>/ground-obsw`.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

mod common;
use common::{free_port, ground, http, obsw_bin, text, wait_for, Proc, GROUND};

/// Simulated seconds per wall-clock second: HK persistence counts samples, so a faster
/// simulation checks the same samples in less time.
const SPEED: &str = "4";

/// Robot `robot`'s obsw in configuration state `initial`: (process, TC address).
fn robot(robot: u8, initial: &str) -> (Proc, SocketAddr) {
    let addr: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let ctl: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let mut child = Command::new(obsw_bin())
        .args([
            "--robot",
            &robot.to_string(),
            "--udp",
            &addr.to_string(),
            "--lab-bare-packets",
        ])
        .args(["--tcp", &addr.to_string(), "--sim-ctl", &ctl.to_string()])
        .args(["--initial-state", initial, "--speed", SPEED])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("starting obsw");
    let mut lines = std::io::BufRead::lines(std::io::BufReader::new(child.stdout.take().unwrap()));
    let line = lines.next().and_then(Result::ok).unwrap_or_default();
    assert!(line.starts_with("READY"), "obsw did not start: {line:?}");
    // Keep reading its stdout: a closed pipe would end it at its next line.
    std::thread::spawn(move || lines.for_each(drop));
    (Proc(child), addr)
}

/// `ground collect --http` following `robots`, offering plan `name`; returns it and its
/// web address once every robot's link is up.
fn collector(dir: &Path, robots: &[(u8, SocketAddr)], name: &str) -> (Proc, SocketAddr) {
    // The bare-packet lab link (robots on loopback): this test is about alarms.
    let mut config = format!(
        "transport = \"lab-udp\"\nplans = [{:?}]\n",
        plan(name).display().to_string()
    );
    for (n, a) in robots {
        config.push_str(&format!("[[robot]]\nnumber = {n}\naddr = \"{a}\"\n"));
    }
    std::fs::write(dir.join("collect.toml"), config).unwrap();
    let web: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let log = std::fs::File::create(dir.join("collect.log")).unwrap();
    let c = Proc(
        Command::new(GROUND)
            .current_dir(dir)
            .args([
                "--archive",
                "collect.db",
                "collect",
                "--plain",
                "--config",
                "collect.toml",
            ])
            .args(["--http", &web.to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("starting ground collect"),
    );
    // The collector's links are up before the plan starts (it archives from the start).
    wait_for(30, "collector links up", || {
        let s = std::panic::catch_unwind(|| http(web, "GET", "/api/snapshot", None).1).ok()?;
        let r = s["robots"].as_array()?;
        (r.len() == robots.len() && r.iter().all(|r| r["link"] == "up")).then_some(())
    });
    (c, web)
}

/// The `name` a plan file gives itself (what the collector's API starts it by).
fn plan_file_name(file: &str) -> String {
    let text = std::fs::read_to_string(plan(file)).unwrap();
    let v: toml::Value = toml::from_str(&text).unwrap();
    v["name"].as_str().unwrap().to_string()
}

fn plan(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans").join(name)
}

/// Runs `plan` with `ground run` while a collector follows the robots; returns the
/// collector's alarms (`ground alarms list --all --json`, one JSON object per alarm)
/// and its archived HIP_DEVIATION values of robot `hip_robot` with the primitive
/// running at the same instant (from the same FDIR report).
fn run_with_collector(name: &str, robots: &[(u8, &str)], hip_robot: u8) -> (Vec<serde_json::Value>, Vec<(f64, f64)>) {
    let dir = common::tmpdir("alarm-nominal", name);
    let started: Vec<(Proc, SocketAddr)> = robots.iter().map(|(n, s)| robot(*n, s)).collect();
    let links: Vec<(u8, SocketAddr)> = robots.iter().zip(&started).map(|((n, _), (_, a))| (*n, *a)).collect();
    // One ground per robot: the plan runs in the collector that follows the
    // robots, started through its API as the page starts it.
    let (mut c, web) = collector(&dir, &links, name);
    let plan_name = plan_file_name(name);
    let (st, r) = http(
        web,
        "POST",
        "/api/plans",
        Some(serde_json::json!({"name": plan_name, "confirm": true})),
    );
    assert_eq!(st, 200, "starting plan {plan_name}: {r}");
    let run = r["run_id"].as_str().unwrap().to_string();
    let end = wait_for(240, "the plan's end", || {
        let s = http(web, "GET", "/api/snapshot", None).1;
        let p = s["plans"]
            .as_array()?
            .iter()
            .find(|p| p["run_id"] == run.as_str())?
            .clone();
        (p["state"] != "running").then_some(p)
    });
    assert_eq!(end["state"], "done", "plan {name}: {end:#}");
    // Two more FDIR reports (5 s each, simulated) after the end: a late alarm shows too.
    std::thread::sleep(std::time::Duration::from_millis(3_000));
    let _ = c.0.kill();
    let _ = c.0.wait();
    let out = ground(&dir, &["--archive", "collect.db", "alarms", "list", "--all", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let alarms = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // HIP_DEVIATION with ACTIVE_PRIMITIVE of the same FDIR report (same time stamp).
    let series = |param: &str| -> Vec<(String, f64)> {
        let r = hip_robot.to_string();
        let out = ground(
            &dir,
            &[
                "--archive",
                "collect.db",
                "archive",
                "query",
                "--type",
                "hk",
                "--param",
                param,
                "--robot",
                &r,
            ],
        );
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter_map(|l| {
                let f: Vec<&str> = l.split(" | ").collect();
                Some((f.first()?.to_string(), f.get(5)?.trim().parse().ok()?))
            })
            .collect()
    };
    let prim = series("ACTIVE_PRIMITIVE");
    let hip = series("HIP_DEVIATION")
        .into_iter()
        .filter_map(|(t, v)| prim.iter().find(|(tp, _)| *tp == t).map(|(_, p)| (v, *p)))
        .collect();
    (alarms, hip)
}

// verifies: ALM-NOALARM-01, ALM-COND-01
#[test]
fn the_demo_plan_on_healthy_robots_raises_no_alarm() {
    let (alarms, hip) = run_with_collector("demo.toml", &[(1, "Xneg"), (2, "Xpos")], 1);
    assert!(alarms.is_empty(), "alarms during a nominal demo: {alarms:#?}");
    let limit = mib::params::by_id(mib::params::pid::HIP_DEVIATION)
        .unwrap()
        .limits
        .unwrap();
    assert!(
        hip.iter()
            .any(|(v, p)| *p != 0.0 && (*v < limit.hard_lo || *v > limit.hard_hi)),
        "the corner turn was not sampled beyond the hip limits while turning: {hip:?}"
    );
    assert!(
        hip.iter()
            .filter(|(_, p)| *p == 0.0)
            .all(|(v, _)| *v >= limit.soft_lo && *v <= limit.soft_hi),
        "idle hip beyond its limits: {hip:?}"
    );
}

// verifies: ALM-NOALARM-01
#[test]
fn the_checkout_plan_on_a_healthy_robot_raises_no_alarm() {
    let (alarms, hip) = run_with_collector("checkout.toml", &[(1, "Xneg")], 1);
    assert!(alarms.is_empty(), "alarms during a nominal checkout: {alarms:#?}");
    assert!(!hip.is_empty(), "no FDIR report archived");
}
