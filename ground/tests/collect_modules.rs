//! The collector follows each robot's module configuration (docs/modules.md), end to end: a
//! real obsw built from a module-set file (`obsw --modules plans/modules/…`) under
//! `ground collect --http`, restarted with another set at the same address. The
//! collector asks for the module report (TM[210,3]) at link-up and after the reboot,
//! archives it, shows the set on the page's data (`/api/snapshot`), and raises the
//! CONFIG_CHANGED alarm (archived, `ground alarms list`) when the configuration hash
//! differs from the last one it saw — also when it changed while the collector was down.

use std::io::BufRead;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

mod common;
use common::{free_port, ground, http, obsw_bin, text, wait_for, Obsw, Proc, GROUND};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Robot `robot`'s obsw at `addr` built from `plans/modules/{set}.toml`.
fn obsw(robot: u8, addr: SocketAddr, set: &str) -> Obsw {
    let ctl: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let modules = root().join("plans/modules").join(format!("{set}.toml"));
    let mut child = Command::new(obsw_bin())
        .args([
            "--robot",
            &robot.to_string(),
            "--udp",
            &addr.to_string(),
            "--lab-bare-packets",
        ])
        .args(["--sim-ctl", &ctl.to_string(), "--modules"])
        .arg(&modules)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("starting obsw");
    let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let ready = lines.next().and_then(Result::ok).unwrap_or_default();
    assert!(ready.starts_with("READY"), "obsw --modules {set}: {ready:?}");
    std::thread::spawn(move || for _ in lines {});
    Obsw {
        child,
        addr,
        ctl,
        frame: None,
        tm_to: None,
    }
}

fn collector(dir: &Path, robot: SocketAddr, web: SocketAddr) -> Proc {
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(dir.join("collect.log"))
        .unwrap();
    Proc(
        Command::new(GROUND)
            .current_dir(dir)
            .args([
                "--archive",
                "a.db",
                "collect",
                "--lab-udp",
                "--plain",
                "--robot",
                &format!("1={robot}"),
            ])
            .args(["--http", &web.to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("starting ground collect"),
    )
}

/// Robot 1's module view on the page once its report with `config` is in.
fn modules_when(web: SocketAddr, config: &str, secs: u64) -> Value {
    wait_for(secs, &format!("module report {config} on the page"), || {
        let (_, s) = http(web, "GET", "/api/snapshot", None);
        let m = s["robots"].get(0)?["modules"].clone();
        (m["config"] == config && m["report_t_ms"].is_i64()).then_some(m)
    })
}

/// CONFIG_CHANGED alarms of robot 1 in the archive (every state).
fn config_alarms(dir: &Path) -> Vec<Value> {
    let o = ground(dir, &["--archive", "a.db", "alarms", "list", "--all", "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|a| a["source"] == "CONFIG_CHANGED" && a["robot"] == 1)
        .collect()
}

fn stop(mut p: Proc) {
    let _ = Command::new("kill").args(["-TERM", &p.0.id().to_string()]).status();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(6) && matches!(p.0.try_wait(), Ok(None)) {
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn slot<'a>(m: &'a Value, name: &str) -> &'a Value {
    m["slots"]
        .as_array()
        .and_then(|s| s.iter().find(|s| s["name"] == name))
        .unwrap_or_else(|| panic!("no slot {name} in {m}"))
}

// verifies: ALM-MODCFG-01, ALM-MODCFG-02, ALM-MODVIEW-01
#[test]
fn a_robot_rebuilt_with_another_module_set_raises_config_changed() {
    let dir = common::tmpdir("collect-modules", "rebuilt");
    let addr: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let web: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let robot = obsw(1, addr, "full");
    let c = collector(&dir, addr, web);

    // The full robot: every slot present, the report asked for and shown.
    let m = modules_when(web, "FULL", 60);
    let full_hash = m["hash"].as_str().unwrap().to_string();
    assert_ne!(full_hash, "0x00000000");
    assert_eq!(m["status"], "ACCEPTED", "{m}");
    assert!(
        m["slots"]
            .as_array()
            .unwrap()
            .iter()
            .all(|s| s["present"] == true && s["state"] == "ok"),
        "{m}"
    );
    assert_eq!(slot(&m, "GRIPPER_A")["revision"], 1, "{m}");
    let full_arm_b = slot(&m, "ARM_B").clone();
    assert!(config_alarms(&dir).is_empty(), "no change yet");

    // Rebuilt without bolters, same address: the collector sees the reboot, asks for the
    // new report, and raises CONFIG_CHANGED.
    drop(robot);
    let t0 = Instant::now();
    let robot = obsw(1, addr, "locomotion-only");
    let m = modules_when(web, "LOCOMOTION_ONLY", 60);
    let alarm = wait_for(30, "CONFIG_CHANGED in the archive", || {
        config_alarms(&dir).into_iter().next()
    });
    eprintln!(
        "CONFIG_CHANGED archived {:.2} s after the new obsw was READY",
        t0.elapsed().as_secs_f64()
    );
    let loc_hash = m["hash"].as_str().unwrap().to_string();
    assert_ne!(loc_hash, full_hash);
    assert_eq!(m["previous_hash"], full_hash.as_str(), "{m}");
    for b in ["BOLTER_A", "BOLTER_B"] {
        assert_eq!(
            (&slot(&m, b)["present"], &slot(&m, b)["state"]),
            (&Value::Bool(false), &Value::from("changed"))
        );
    }
    // locomotion-only.toml's modules have other serials (serial_base 2000): every
    // present module is another one.
    assert_eq!(slot(&m, "ARM_B")["state"], "changed", "{m}");
    assert_ne!(slot(&m, "ARM_B")["serial"], full_arm_b["serial"], "{m}");
    let msg = alarm["message"].as_str().unwrap();
    assert!(msg.contains(&full_hash) && msg.contains(&loc_hash), "{msg}");
    assert_eq!(alarm["severity"], "medium");
    // Raised and cleared at once, like an event: it waits for an acknowledgement.
    assert_eq!(alarm["state"], "cleared", "{alarm}");
    // Not the configuration the robot accepts at start (the full robot): accepted from the
    // page's API by its hash (hazardous: confirmed); the page shows it accepted at once.
    assert_eq!(m["status"], "NOT_ACCEPTED", "{m}");
    // MODULE_REPLACED named the first slot that differs from the accepted set.
    let replaced = wait_for(10, "the replaced slot on the page", || {
        let (_, s) = http(web, "GET", "/api/snapshot", None);
        let slots = s["robots"].get(0)?["modules"]["slots"].as_array()?.clone();
        let r: Vec<String> = slots
            .iter()
            .filter(|s| s["state"] == "replaced")
            .filter_map(|s| s["name"].as_str().map(str::to_string))
            .collect();
        (r.len() == 1).then_some(r)
    });
    eprintln!("replaced slot: {replaced:?}");
    let hash = i64::from_str_radix(&loc_hash[2..], 16).unwrap();
    let tc = serde_json::json!({"robot": 1, "name": "ACCEPT_CONFIG", "args": {"hash": hash}, "confirm": true});
    let (st, body) = http(web, "POST", "/api/tc", Some(tc));
    assert_eq!(st, 200, "{body}");
    let t_acc = Instant::now();
    wait_for(20, "ACCEPTED on the page", || {
        let (_, s) = http(web, "GET", "/api/snapshot", None);
        (s["robots"].get(0)?["modules"]["status"] == "ACCEPTED").then_some(())
    });
    eprintln!(
        "ACCEPTED shown {:.2} s after ACCEPT_CONFIG",
        t_acc.elapsed().as_secs_f64()
    );
    let (_, s) = http(web, "GET", "/api/snapshot", None);
    let m = &s["robots"][0]["modules"];
    assert!(
        m["slots"].as_array().unwrap().iter().all(|s| s["state"] != "replaced"),
        "{m}"
    );
    // On the page's alarm list too.
    wait_for(10, "CONFIG_CHANGED on the page", || {
        let (_, s) = http(web, "GET", "/api/snapshot", None);
        s["alarms"]
            .as_array()?
            .iter()
            .any(|a| a["source"] == "CONFIG_CHANGED")
            .then_some(())
    });

    // Both module reports are archived (service 210, subservice 3), one per configuration.
    let o = ground(
        &dir,
        &["--archive", "a.db", "archive", "query", "--type", "tm", "--json"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let reports: Vec<Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|t| t["service"] == 210 && t["subservice"] == 3)
        .collect();
    // The report's body starts with the configuration hash (raw: the packet in hex).
    let with = |h: &str| {
        reports
            .iter()
            .filter(|t| t["raw"].as_str().unwrap_or("").to_ascii_lowercase().contains(&h[2..]))
            .count()
    };
    assert!(
        with(&full_hash) >= 1 && with(&loc_hash) >= 1,
        "archived reports: {reports:?}"
    );

    // The collector restarts: the archived hash is the last one seen, so the same robot
    // raises nothing new...
    stop(c);
    let c = collector(&dir, addr, web);
    modules_when(web, "LOCOMOTION_ONLY", 60);
    std::thread::sleep(Duration::from_secs(2));
    let a = config_alarms(&dir);
    assert_eq!(
        (a.len(), &a[0]["count"]),
        (1, &Value::from(1)),
        "same configuration after a collector restart"
    );
    // ... but a robot rebuilt while the collector was down does.
    stop(c);
    drop(robot);
    let _robot = obsw(1, addr, "gripper-rev-b");
    let _c = collector(&dir, addr, web);
    let m = modules_when(web, "FULL", 60);
    // The first alarm was never acknowledged: the same alarm comes back (count 2), its
    // message naming the new change.
    let a = wait_for(30, "a second CONFIG_CHANGED", || {
        let a = config_alarms(&dir);
        (a.iter().map(|x| x["count"].as_i64().unwrap_or(0)).sum::<i64>() == 2).then_some(a)
    });
    let msg = a[0]["message"].as_str().unwrap();
    assert!(msg.contains(&format!("{loc_hash} -> ")), "{msg}");
    assert_eq!(m["previous_hash"], loc_hash.as_str(), "{m}");
    assert_eq!(slot(&m, "GRIPPER_A")["revision"], 2, "{m}");
    let _ = std::fs::remove_dir_all(&dir);
}

// verifies: ALM-MODCFG-01, ALM-MODVIEW-01
#[test]
fn an_invalid_module_set_is_shown_with_its_reason_and_raises_config_invalid() {
    let dir = common::tmpdir("collect-modules", "invalid");
    let addr: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    let web: SocketAddr = ([127, 0, 0, 1], free_port()).into();
    // Arm B not fitted: discovery names the missing slot.
    let robot = obsw(1, addr, "missing-arm-b");
    let c = collector(&dir, addr, web);
    let m = modules_when(web, "NONE", 60);
    assert_eq!(
        (&m["status"], &m["reason"], &m["reason_slot"]),
        (&Value::from("INVALID"), &Value::from("MISSING"), &Value::from("ARM_B")),
        "{m}"
    );
    assert_eq!(
        (&slot(&m, "ARM_B")["present"], &slot(&m, "ARM_B")["state"]),
        (&Value::Bool(false), &Value::from("invalid")),
        "{m}"
    );
    assert_eq!(slot(&m, "ARM_A")["state"], "ok", "{m}");
    // A corrupted descriptor names a board's table entry, no slot: the slot is absent.
    drop(robot);
    let _robot = obsw(1, addr, "corrupted-descriptor");
    let m = wait_for(60, "the corrupted set on the page", || {
        let (_, s) = http(web, "GET", "/api/snapshot", None);
        let m = s["robots"].get(0)?["modules"].clone();
        (m["reason"] == "CORRUPT_DESCRIPTOR").then_some(m)
    });
    assert_eq!(
        (&m["status"], &m["reason_slot"]),
        (&Value::from("INVALID"), &Value::Null),
        "{m}"
    );
    assert_eq!(slot(&m, "GRIPPER_A")["present"], false, "{m}");
    // CONFIG_INVALID (high) is an event alarm of the collector.
    wait_for(30, "CONFIG_INVALID alarm", || {
        let o = ground(&dir, &["--archive", "a.db", "alarms", "list", "--all", "--json"]);
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter_map(|l| serde_json::from_str::<Value>(l).ok())
            .any(|a| a["source"] == "CONFIG_INVALID" && a["severity"] == "high")
            .then_some(())
    });
    drop(c);
    let _ = std::fs::remove_dir_all(&dir);
}
