//! The ground over the space link (docs/space-link.md): `ground keys`, and `ping`, `mode`,
//! `send`, `run` and `demo` over TC/TM transfer frames (FOP-1, SDLS) against the real
//! `obsw` with its frame endpoint. What ran on board is judged from the obsw's own
//! `--tm-log` (every TM packet it sent), not from the ground.

use std::collections::{BTreeMap, BTreeSet};
use std::io::BufRead;
use std::net::SocketAddr;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{frame_keys, ground, text, tmpdir, Obsw, Running, GROUND};
use ground::pus::{Stage, TmBody};

fn run(dir: &Path, pre: &[&str], links: &[String], post: &[&str]) -> (Option<i32>, String) {
    let mut a: Vec<&str> = pre.to_vec();
    a.extend(links.iter().map(String::as_str));
    a.extend_from_slice(post);
    let o = ground(dir, &a);
    (o.status.code(), text(&o))
}

/// Distinct TM packets of the obsw's `--tm-log`.
fn tm_log(path: &Path) -> Vec<ground::pus::Tm> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
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

/// Per TC request (APID, sequence count): how many acceptance reports (TM[1,1] or [1,2]).
fn acceptances(tms: &[ground::pus::Tm]) -> BTreeMap<(u16, u16), usize> {
    let mut m = BTreeMap::new();
    for tm in tms {
        if let TmBody::Verification(v) = &tm.body {
            if v.stage == Stage::Acceptance {
                *m.entry((v.request.apid(), v.request.seq())).or_insert(0) += 1;
            }
        }
    }
    m
}

fn events_named(tms: &[ground::pus::Tm], name: &str) -> usize {
    tms.iter()
        .filter(|t| matches!(&t.body, TmBody::Event(e) if e.name == name))
        .count()
}

// verifies: LINK-GND-02
#[test]
fn ping_mode_send_and_run_over_frames_against_the_real_obsw() {
    let dir = tmpdir("frames", "live");
    let keys = frame_keys(&dir, &[1]);
    let log = dir.join("tm.log");
    let o = Obsw::start_frames(
        1,
        &keys,
        &[
            "--speed",
            "50",
            "--seed",
            "7",
            "--initial-state",
            "Xneg",
            "--tm-log",
            log.to_str().unwrap(),
        ],
    );
    let links = o.frame_args(1, &keys);

    let (code, t) = run(&dir, &["ping"], &links, &["-c", "2"]);
    assert_eq!(code, Some(0), "{t}");
    assert!(t.contains("space link") && t.contains("reply in"), "{t}");

    let (code, t) = run(&dir, &["send"], &links, &["RECONFIGURE", "from=Xneg", "to=Xpos"]);
    assert_eq!(code, Some(4), "refused in STANDBY: {t}");
    assert!(t.contains("NOT_ALLOWED_IN_MODE"), "{t}");

    let (code, t) = run(&dir, &["mode"], &links, &["operational", "--confirm"]);
    assert_eq!(code, Some(0), "{t}");

    // `watch` sends nothing: the TM frames arrive anyway (the obsw's fixed --frame-tm-to).
    let (code, t) = run(&dir, &["watch"], &links, &["--duration", "2"]);
    assert_eq!(code, Some(0), "{t}");
    assert!(
        t.lines().filter(|l| l.contains(" robot 1: ")).count() >= 3,
        "TM over frames: {t}"
    );

    let (code, t) = run(&dir, &["send"], &links, &["RECONFIGURE", "from=Xneg", "to=Xpos"]);
    assert_eq!(code, Some(0), "{t}");
    assert!(t.contains("progress ok step 1") && t.contains("completion ok"), "{t}");

    // `--no-wait` exits once the frame is acknowledged: the TC still runs on board.
    let (code, t) = run(
        &dir,
        &["send"],
        &links,
        &["HK_SET_INTERVAL", "sid=1", "interval_ms=500", "--no-wait"],
    );
    assert_eq!(code, Some(0), "{t}");

    let plan = dir.join("p.toml");
    std::fs::write(
        &plan,
        "name = \"frames\"\n[[robot]]\nnumber = 1\ninitial_state = \"Xpos\"\n\
         [[step]]\nid = \"op\"\nrobot = 1\naction = \"mode\"\nmode = \"operational\"\nconfirm = true\n\
         [[step]]\nid = \"turn\"\nrobot = 1\naction = \"reconfigure\"\nfrom = \"Xpos\"\nto = \"Yneg\"\n\
         [[step]]\nid = \"standby\"\nrobot = 1\naction = \"mode\"\nmode = \"standby\"\nconfirm = true\n",
    )
    .unwrap();
    let (code, t) = run(&dir, &["run", plan.to_str().unwrap(), "--plain"], &links, &[]);
    assert_eq!(code, Some(0), "{t}");
    assert!(t.contains("3 of 3 steps done"), "{t}");
    assert!(t.contains("0 resends"), "no packet resends over frames: {t}");
    assert!(t.contains("frames robot 1:"), "{t}");

    // Judged from the obsw's TM: every TC the ground archived was accepted exactly once.
    std::thread::sleep(Duration::from_millis(500));
    drop(o);
    let tms = tm_log(&log);
    let acc = acceptances(&tms);
    let out = ground(&dir, &["archive", "query", "--type", "tc", "--json"]);
    let apid = mib::apid::robot_apid(1).unwrap();
    let sent: Vec<(u16, u16)> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            (apid, v["seq"].as_u64().unwrap() as u16)
        })
        .collect();
    assert!(sent.len() >= 8, "{sent:?}");
    for k in &sent {
        assert_eq!(acc.get(k), Some(&1), "TC {k:?} accepted once on board: {acc:?}");
    }
    assert_eq!(events_named(&tms, "STATE_REACHED"), 2, "two reconfigurations ran");
}

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
id = "walk"
robot = 1
action = "reconfigure"
from = "Xneg"
to = "Xpos"
[[step]]
id = "standby"
robot = 1
action = "mode"
mode = "standby"
confirm = true
"#;

// verifies: LINK-GND-03
#[test]
fn a_ground_killed_mid_plan_over_frames_resynchronises_and_neither_repeats_nor_skips() {
    let dir = tmpdir("frames", "kill");
    let keys = frame_keys(&dir, &[1]);
    let log = dir.join("tm.log");
    // At speed 2 BOLT_FACE runs for about 8 s.
    let o = Obsw::start_frames(
        1,
        &keys,
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
    let links = o.frame_args(1, &keys);
    let mut args: Vec<String> = vec!["run".into(), "bolt.toml".into(), "--plain".into()];
    args.extend(links.iter().cloned());
    let mut g = Running::start(&dir, &args);
    g.wait_for("send     bolt", Duration::from_secs(30));
    // Long enough for the archive to hold the BOLT_FACE TC, well before it completes.
    std::thread::sleep(Duration::from_millis(2000));
    // SIGKILL: no summary, no goodbye; the FOP-1 state dies with the process.
    g.kill();

    let mut args: Vec<String> = vec!["run".into(), "bolt.toml".into(), "--plain".into(), "--resume".into()];
    args.extend(links.iter().cloned());
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let res = ground(&dir, &a);
    let t = text(&res);
    assert_eq!(res.status.code(), Some(0), "{t}");
    assert!(t.contains("4 of 4 steps done"), "{t}");
    assert!(t.contains("initialisations"), "{t}");

    std::thread::sleep(Duration::from_millis(500));
    drop(o);
    let tms = tm_log(&log);
    // Nothing repeated: BOLT_FACE bolted the four pairs once, one action started per
    // action TC (bolt, walk), every TC accepted exactly once.
    assert_eq!(events_named(&tms, "BOLT_PAIR_DONE"), 4, "{t}");
    let starts: BTreeSet<(u16, u16)> = tms
        .iter()
        .filter_map(|tm| match &tm.body {
            TmBody::Verification(v) if v.stage == Stage::Start => Some((v.request.apid(), v.request.seq())),
            _ => None,
        })
        .collect();
    assert_eq!(
        starts.len(),
        2,
        "BOLT_FACE and RECONFIGURE started once each: {starts:?}\n{t}"
    );
    let acc = acceptances(&tms);
    assert!(acc.values().all(|&n| n == 1), "a TC accepted twice: {acc:?}");
    // Nothing skipped: the walk ran and the robot ended in STANDBY at Xpos.
    assert_eq!(events_named(&tms, "STATE_REACHED"), 1, "{t}");
    let modes: Vec<i64> = tms
        .iter()
        .filter_map(|tm| match &tm.body {
            TmBody::Event(e) if e.name == "MODE_CHANGED" && e.param("node") == Some(mib::modes::node::ROBOT as i64) => {
                e.param("to")
            }
            _ => None,
        })
        .collect();
    assert_eq!(modes.len(), 2, "operational, then standby, once each: {modes:?}");
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

// verifies: LINK-KEYS-01
#[test]
fn ground_keys_creates_private_keys_and_never_prints_them() {
    let dir = tmpdir("frames", "keys");
    let keys = dir.join("k");
    let o = ground(
        &dir,
        &["keys", "create", keys.to_str().unwrap(), "--robot", "1", "--robot", "2"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let created = text(&o);
    let show = ground(&dir, &["keys", "show", keys.to_str().unwrap()]);
    assert!(show.status.success(), "{}", text(&show));
    let shown = text(&show);
    let files: Vec<_> = ["robot-1", "robot-2"]
        .iter()
        .flat_map(|r| ["tc-spi1.key", "tc-spi2.key", "tm-spi17.key", "tm-spi18.key"].map(|f| keys.join(r).join(f)))
        .collect();
    for f in &files {
        let key = std::fs::read(f).unwrap();
        assert_eq!(key.len(), 32, "{}", f.display());
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(std::fs::metadata(f).unwrap().permissions().mode() & 0o777, 0o600);
        }
        assert!(shown.contains(&f.display().to_string()), "{shown}");
        for out in [&created, &shown] {
            let lower = out.to_lowercase();
            // Not the key, nor any 8 bytes of it, in hex; not its raw bytes.
            for w in key.windows(8) {
                assert!(!lower.contains(&hex(w)), "key bytes printed:\n{out}");
            }
            assert!(!out.as_bytes().windows(8).any(|w| key.windows(8).any(|k| k == w)));
        }
    }
    assert_eq!(shown.matches("SPI ").count(), 8, "{shown}");
    assert_eq!(shown.matches("sha256 ").count(), 8, "{shown}");
    assert!(
        shown.contains("SPI 17") && shown.contains("TM (robot to ground)"),
        "{shown}"
    );
    // Keys differ between robots (no nonce reuse under one key).
    assert_ne!(std::fs::read(&files[0]).unwrap(), std::fs::read(&files[4]).unwrap());
    // Never overwritten.
    let again = ground(&dir, &["keys", "create", keys.to_str().unwrap()]);
    assert!(!again.status.success(), "{}", text(&again));
}

// verifies: LINK-GND-04, OPS-DEMO-TM-01, OPS-DEMO-PORTS-01
#[test]
fn demo_runs_over_frames_with_test_keys_and_no_resends() {
    let dir = tmpdir("frames", "demo");
    let obsw = common::obsw_bin();
    let o = ground(
        &dir,
        &["--no-archive", "demo", "--plain", "--obsw", obsw.to_str().unwrap()],
    );
    let t = text(&o);
    assert_eq!(o.status.code(), Some(0), "{t}");
    assert!(t.contains("TEST KEYS made for this demo only"), "{t}");
    assert!(t.contains("10 of 10 steps done"), "{t}");
    for r in [1, 2] {
        let link = t
            .lines()
            .find(|l| l.starts_with(&format!("link robot {r}:")))
            .unwrap_or_else(|| panic!("{t}"));
        assert!(link.contains("quality 100%") && link.ends_with(" 0 resends"), "{link}");
        let fr = t
            .lines()
            .find(|l| l.starts_with(&format!("frames robot {r}:")))
            .unwrap_or_else(|| panic!("{t}"));
        // Every TC packet was acknowledged by a CLCW; no alert.
        let packets = count_before(fr, " TC packets");
        assert!(packets > 0, "{fr}");
        assert_eq!(count_before(fr, " acknowledged by CLCW"), packets, "{fr}");
        assert_eq!(count_before(fr, " alerts"), 0, "{fr}");
        // The robots were booted by the demo: their TM is complete from their first
        // packet, what went out before the ground listened fetched from the store.
        let tm = format!(
            "TM robot {r}: complete from seq {} up to",
            ground_ops::live::BOOT_FIRST_SEQ
        );
        assert!(t.contains(&tm), "{tm:?} in {t}");
    }
}

/// The number just before `label` in `line`.
fn count_before(line: &str, label: &str) -> u64 {
    let head = &line[..line.find(label).unwrap_or_else(|| panic!("{label:?} in {line}"))];
    head.rsplit(|c: char| !c.is_ascii_digit())
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

// verifies: LINK-GND-02, OPS-LINK-DEFAULT-01, OPS-ENGINE-01
#[test]
fn the_collector_follows_a_robot_over_frames_and_archives_each_tm_once() {
    let dir = tmpdir("frames", "collect");
    let keys = frame_keys(&dir, &[1]);
    let o = Obsw::start_frames(1, &keys, &["--speed", "5", "--seed", "3"]);
    // The configuration file names the frame link too (checked, not run).
    std::fs::write(
        dir.join("c.toml"),
        "transport = \"frames\"\nkeys = \"TEST-KEYS\"\n[[robot]]\nnumber = 1\ntm_listen = \"127.0.0.1:7401\"\n",
    )
    .unwrap();
    let out = ground(&dir, &["collect", "--check-config", "c.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    std::fs::write(dir.join("bad.toml"), "transport = \"frames\"\n[[robot]]\nnumber = 1\n").unwrap();
    let out = ground(&dir, &["collect", "--check-config", "bad.toml"]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out));
    assert!(text(&out).contains("keys = \"DIR\""), "{}", text(&out));

    // The collector with its page, over frames (the default link): the page's TCs go
    // through the collector's link, FOP-1 and SDLS.
    let web: SocketAddr = ([127, 0, 0, 1], common::free_port()).into();
    let mut args: Vec<String> = vec!["collect".into(), "--plain".into(), "--http".into(), web.to_string()];
    args.extend(o.frame_args(1, &keys));
    let mut c = Command::new(GROUND)
        .current_dir(&dir)
        .args(&args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    common::wait_for(30, "the robot up on the page", || {
        let s = std::panic::catch_unwind(|| common::http(web, "GET", "/api/snapshot", None).1).ok()?;
        (s["robots"][0]["link"] == "up").then_some(())
    });
    let stages_of = |id: &str| {
        common::wait_for(30, "the page's TC completed", || {
            let (_, c) = common::http(web, "GET", &format!("/api/tc/{id}"), None);
            let s = c["stages"].as_array().cloned().unwrap_or_default();
            s.iter().any(|x| x["stage"] == "completion").then_some(s)
        })
    };
    let (st, r) = common::http(
        web,
        "POST",
        "/api/tc",
        Some(serde_json::json!({"robot": 1, "name": "PING", "args": {}})),
    );
    assert_eq!(st, 200, "{r}");
    let stages = stages_of(r["request_id"].as_str().unwrap());
    assert!(stages.iter().all(|s| s["success"] == true), "{stages:?}");
    let mode = serde_json::json!({"robot": 1, "name": "MODE_SET", "confirm": true,
        "args": {"node": "ROBOT", "mode": "OPERATIONAL", "submode": 0}});
    let (st, r) = common::http(web, "POST", "/api/tc", Some(mode));
    assert_eq!(st, 200, "{r}");
    let stages = stages_of(r["request_id"].as_str().unwrap());
    assert!(
        stages.iter().all(|s| s["success"] == true),
        "MODE_SET from the page over frames: {stages:?}"
    );
    std::thread::sleep(Duration::from_secs(2));
    Command::new("kill")
        .args(["-TERM", &c.id().to_string()])
        .status()
        .unwrap();
    let t0 = Instant::now();
    while c.try_wait().unwrap().is_none() && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = c.kill();
    assert_eq!(c.wait().unwrap().code(), Some(0));
    drop(o);
    let out = ground(&dir, &["archive", "query", "--type", "tm", "--json"]);
    let apid = i64::from(mib::apid::robot_apid(1).unwrap());
    let mut seqs: BTreeMap<i64, u32> = BTreeMap::new();
    for l in String::from_utf8_lossy(&out.stdout).lines() {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        if v["apid"].as_i64() == Some(apid) {
            *seqs.entry(v["seq"].as_i64().unwrap()).or_insert(0) += 1;
        }
    }
    assert!(seqs.len() >= 10, "TM over frames archived: {seqs:?}");
    // The page's TCs are archived by the collector, once each.
    let out = ground(&dir, &["archive", "query", "--type", "tc", "--json"]);
    let page: Vec<String> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["step"] == "collect:page")
        .map(|v| v["name"].as_str().unwrap_or("").to_string())
        .collect();
    assert_eq!(page, ["PING", "MODE_SET"], "the page's TCs archived");
    assert!(seqs.values().all(|&n| n == 1), "each TM once: {seqs:?}");
    let (lo, hi) = (*seqs.keys().next().unwrap(), *seqs.keys().last().unwrap());
    assert_eq!(seqs.len() as i64, hi - lo + 1, "no gap: {seqs:?}");
}

const WALK_PLAN: &str = r#"
name = "walk"
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
id = "walk"
robot = 1
action = "reconfigure"
from = "Xneg"
to = "Xpos"
[[step]]
id = "turn"
robot = 1
action = "reconfigure"
from = "Xpos"
to = "Yneg"
[[step]]
id = "standby"
robot = 1
action = "mode"
mode = "standby"
confirm = true
"#;

/// Runs WALK_PLAN over frames, through the lossy relay when `faults` is given; returns
/// the summary, the run's seconds and the obsw's TM.
fn walk_over_frames(name: &str, faults: Option<(&str, u64)>) -> (String, f64, Vec<ground::pus::Tm>) {
    let dir = tmpdir("frames", name);
    let keys = frame_keys(&dir, &[1]);
    let log = dir.join("tm.log");
    std::fs::write(dir.join("walk.toml"), WALK_PLAN).unwrap();
    let frame: std::net::SocketAddr = ([127, 0, 0, 1], common::free_port()).into();
    let ground_tm: std::net::SocketAddr = ([127, 0, 0, 1], common::free_port()).into();
    let extra = [
        "--speed",
        "10",
        "--seed",
        "7",
        "--initial-state",
        "Xneg",
        "--tm-log",
        log.to_str().unwrap(),
    ];
    let (_relay, tc_to, tm_to) = match faults {
        None => (None, frame, ground_tm),
        Some((p, seed)) => {
            let mut child = Command::new(common::relay_bin())
                .args(["--to-udp", &frame.to_string(), "--tm-frames-to", &ground_tm.to_string()])
                .args(["--drop", p.split(',').next().unwrap()])
                .args(["--duplicate", p.split(',').nth(1).unwrap()])
                .args(["--corrupt", p.split(',').nth(2).unwrap()])
                .args(["--seed", &seed.to_string()])
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(Stdio::null())
                .spawn()
                .expect("starting the relay");
            let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
            let ready = lines.next().and_then(Result::ok).unwrap_or_default();
            let field = |k: &str| -> std::net::SocketAddr {
                ready
                    .split_whitespace()
                    .find_map(|w| w.strip_prefix(k))
                    .unwrap_or_else(|| panic!("relay: {ready:?}"))
                    .parse()
                    .unwrap()
            };
            let (udp, tmf) = (field("udp="), field("tm_frames="));
            std::thread::spawn(move || for _ in lines {});
            (Some(common::Proc(child)), udp, tmf)
        }
    };
    let o = Obsw::start_frames_at(1, &keys, frame, tm_to, &extra);
    let links = [
        "--keys".to_string(),
        keys.to_str().unwrap().into(),
        "--robot".into(),
        format!("1={tc_to}"),
        "--tm-listen".into(),
        format!("1={ground_tm}"),
    ];
    let t0 = Instant::now();
    let (code, t) = run(&dir, &["run", "walk.toml", "--plain"], &links, &[]);
    let secs = t0.elapsed().as_secs_f64();
    assert_eq!(code, Some(0), "{t}");
    std::thread::sleep(Duration::from_millis(500));
    drop(o);
    (t, secs, tm_log(&log))
}

// verifies: LINK-GND-02
#[test]
// Over frames a TM[1,x] lost on the downlink is a TM gap: the ground asks the store at once
// for the gaps after the awaited TC went out, and a TC a CLCW acknowledged is never failed
// for want of reports. The time against the clean link is printed (REV-ANOM-13 gives the
// measured spread; the issue's aim is 2x).
fn a_plan_over_frames_through_the_lossy_relay_executes_every_tc_exactly_once() {
    let (clean, clean_s, _) = walk_over_frames("relay-clean", None);
    assert!(clean.contains("4 of 4 steps done"), "{clean}");
    let (t, lossy_s, tms) = walk_over_frames("relay-lossy", Some(("0.2,0.05,0.05", 11)));
    assert!(t.contains("4 of 4 steps done"), "{t}");
    assert!(
        t.contains(" 0 resends"),
        "the ground never resends a packet over frames: {t}"
    );
    // Judged from the obsw's own TM: every TC it accepted, accepted once; both
    // reconfigurations ran once; the robot reached STANDBY once more after OPERATIONAL.
    let acc = acceptances(&tms);
    assert!(acc.values().all(|&n| n == 1), "a TC accepted twice: {acc:?}\n{t}");
    assert_eq!(events_named(&tms, "STATE_REACHED"), 2, "{t}");
    let starts = tms
        .iter()
        .filter(|tm| matches!(&tm.body, TmBody::Verification(v) if v.stage == Stage::Start))
        .count();
    assert_eq!(starts, 2, "two action TCs started once each\n{t}");
    eprintln!(
        "walk plan over frames: clean {clean_s:.1} s, 20/5/5 relay {lossy_s:.1} s ({:.2}x)",
        lossy_s / clean_s
    );
}

// verifies: LINK-KEYS-01, TEAM-AUTH-01
#[test]
fn ground_keys_create_team_makes_the_key_the_obsw_team_link_takes() {
    let dir = tmpdir("frames", "team-key");
    let keys = dir.join("k");
    let o = ground(&dir, &["keys", "create", keys.to_str().unwrap(), "--team"]);
    assert!(o.status.success(), "{}", text(&o));
    let team = keys.join("team.key");
    let key = std::fs::read(&team).unwrap();
    assert_eq!(key.len(), 32);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        assert_eq!(std::fs::metadata(&team).unwrap().permissions().mode() & 0o777, 0o600);
    }
    // --team alone makes no link keys; a second creation never overwrites.
    assert!(!keys.join("robot-1").exists());
    let again = ground(&dir, &["keys", "create", keys.to_str().unwrap(), "--team"]);
    assert!(!again.status.success(), "{}", text(&again));
    assert_eq!(std::fs::read(&team).unwrap(), key);
    let show = text(&ground(&dir, &["keys", "show", keys.to_str().unwrap()]));
    assert!(show.contains("team.key  team (robot to robot)  sha256 "), "{show}");
    for out in [text(&o), show] {
        for w in key.windows(8) {
            assert!(!out.to_lowercase().contains(&hex(w)), "key bytes printed:\n{out}");
        }
    }
    // The obsw's team link starts with it (READY), authenticated, no lab flag.
    let port = common::free_port();
    let peer = common::free_port();
    let o = Obsw::start(
        1,
        &[
            "--team-udp",
            &format!("127.0.0.1:{port}"),
            "--peer",
            &format!("2=127.0.0.1:{peer}"),
            "--team-state",
            dir.join("team.state").to_str().unwrap(),
            "--team-key",
            team.to_str().unwrap(),
        ],
    );
    drop(o);
}

/// Key change without downtime from the command line (docs/space-link.md): LINK_SPI_SELECT
/// sent over SPI 1 (hazardous: confirmed), then the same key folder's spare keys with
/// `--spi 2`; the robot's TM comes under SPI 18 from then on and the ground reads it
/// with the spare TM key. Judged from the obsw's own TM: the selection event, and the
/// PING under SPI 2 answered.
// verifies: LINK-KEYCHG-01, OPS-LINK-DEFAULT-01
#[test]
fn a_key_change_from_the_command_line_moves_the_robot_to_spi_2_and_18() {
    let dir = tmpdir("frames", "spi-change");
    let keys = frame_keys(&dir, &[1]);
    let tm = dir.join("tm.log");
    let o = Obsw::start_frames(1, &keys, &["--tm-log", tm.to_str().unwrap()]);
    let links = o.frame_args(1, &keys);
    // Hazardous: refused without confirmation, before anything is sent.
    let (code, t) = run(
        &dir,
        &["--no-archive", "send"],
        &links,
        &["LINK_SPI_SELECT", "tm_spi=18", "tc_spis=2"],
    );
    assert_eq!(code, Some(3), "{t}");
    let (code, t) = run(
        &dir,
        &["--no-archive", "send"],
        &links,
        &["LINK_SPI_SELECT", "tm_spi=18", "tc_spis=2", "--confirm"],
    );
    assert_eq!(code, Some(0), "{t}");
    assert!(t.contains("completion ok") && t.contains("LINK_SPI_SELECTED"), "{t}");
    let (code, t) = run(&dir, &["--no-archive", "send", "--spi", "2"], &links, &["PING"]);
    assert_eq!(code, Some(0), "PING under SPI 2, its reports under SPI 18: {t}");
    assert!(t.contains("completion ok"), "{t}");
    drop(o);
    let log = tm_log(&tm);
    let selected: Vec<(Option<i64>, Option<i64>)> = log
        .iter()
        .filter_map(|p| match &p.body {
            TmBody::Event(e) if e.name == "LINK_SPI_SELECTED" => Some((e.param("tm_spi"), e.param("tc_spis"))),
            _ => None,
        })
        .collect();
    assert_eq!(selected, [(Some(18), Some(2))], "the robot's selection event");
    let pings = log.iter().filter(|p| (p.service, p.subservice) == (17, 2)).count();
    assert_eq!(pings, 1, "the PING under SPI 2 answered once");
}

/// SDLS on TM as a configuration: a robot started with `--tm-sdls clear` and a ground
/// with the same setting (TC frames stay authenticated).
// verifies: LINK-TM-04, OPS-LINK-DEFAULT-01
#[test]
fn clear_tm_frames_are_a_configuration_both_ends_name() {
    let dir = tmpdir("frames", "tm-clear");
    let keys = frame_keys(&dir, &[1]);
    let o = Obsw::start_frames(1, &keys, &["--tm-sdls", "clear"]);
    let links = o.frame_args(1, &keys);
    let (code, t) = run(
        &dir,
        &["--no-archive", "ping", "--tm-sdls", "clear"],
        &links,
        &["-c", "2"],
    );
    assert_eq!(code, Some(0), "{t}");
    assert!(t.contains("reply in"), "{t}");
}
