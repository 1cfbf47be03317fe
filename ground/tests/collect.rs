//! `ground collect` and `ground alarms` against the real `obsw` binary over loopback:
//! configuration errors with their place, kill -9 and restart losing and duplicating
//! nothing, alarms raised by a battery sag and acknowledged or shelved from the CLI,
//! SIGTERM ending the collector with exit 0, `--status`.
//!
//! The obsw binary is `$OBSW_BIN`, or the one next to this test's profile directory
//! (`cargo build -p obsw`), or it is built into `<target>/ground-obsw`.

use std::collections::BTreeMap;
use std::io::BufRead;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{free_port, ground, http, pg_db, pg_drop, text, wait_for, Obsw, Proc, GROUND};

/// Robot `robot`'s obsw: `(process, TC address, simulator control address)`.
fn start_obsw(robot: u8) -> (Obsw, SocketAddr, SocketAddr) {
    let o = Obsw::start(robot, &[]);
    let (addr, ctl) = (o.addr, o.ctl);
    (o, addr, ctl)
}

fn tmpdir(name: &str) -> PathBuf {
    common::tmpdir("collect", name)
}

/// Starts `ground --archive ARCH collect` (ARCH: a file in `dir`, or a server URL).
fn collector(dir: &Path, arch: &str, robots: &[String]) -> Proc {
    let mut c = Command::new(GROUND);
    c.current_dir(dir)
        .args(["--archive", arch, "collect", "--lab-udp", "--plain"]);
    for r in robots {
        c.args(["--robot", r]);
    }
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(dir.join("collect.log"))
        .unwrap();
    Proc(
        c.stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("starting ground collect"),
    )
}

fn signal(p: &Proc, sig: &str) {
    let st = Command::new("kill")
        .args([sig, &p.0.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
}

fn wait_exit(p: &mut Proc, limit: Duration) -> Option<i32> {
    let t0 = Instant::now();
    while t0.elapsed() < limit {
        if let Some(s) = p.0.try_wait().unwrap() {
            return s.code();
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    None
}

/// Sequence counts of robot 1's APID in the archive, with how often each is stored.
fn archived_seqs(dir: &Path, arch: &str) -> BTreeMap<i64, u32> {
    let out = ground(dir, &["--archive", arch, "archive", "query", "--type", "tm", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let mut m = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        // A packet kept raw (its body did not decode) has its header only in `raw`.
        let raw = v["raw"].as_str().unwrap_or("");
        let from_raw = |i: usize| u16::from_str_radix(raw.get(i..i + 4).unwrap_or(""), 16).ok();
        let apid = v["apid"].as_i64().or(from_raw(0).map(|a| (a & 0x7FF) as i64));
        let seq = v["seq"]
            .as_i64()
            .or(from_raw(4).map(|s| i64::from(mib::headers::SeqCount::new(s).get())));
        if let (Some(0x101), Some(seq)) = (apid, seq) {
            *m.entry(seq).or_insert(0) += 1;
        }
    }
    m
}

// verifies: GND-11, ALM-CFG-01, ALM-MSG-01
#[test]
fn check_config_names_file_line_and_column() {
    let dir = tmpdir("cfg");
    std::fs::write(
        dir.join("bad.toml"),
        "retain = \"30 days\"\n[link]\nmax_backoff_ms = 9000\n[[robot]]\nnumber = 1\naddres = \"x\"\n",
    )
    .unwrap();
    let out = ground(&dir, &["collect", "--check-config", "bad.toml"]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out));
    let t = text(&out);
    assert!(t.contains("bad.toml:6:1: unknown field `addres`"), "{t}");
    std::fs::write(
        dir.join("bad2.toml"),
        "retain = \"30 days\"\n[link]\nmax_backoff_ms = 9000\n",
    )
    .unwrap();
    let t = text(&ground(&dir, &["collect", "--check-config", "bad2.toml"]));
    assert!(t.contains("bad2.toml:1:10: retain"), "{t}");
    assert!(t.contains("bad2.toml:3:18: max_backoff_ms = 9000"), "{t}");
    std::fs::write(
        dir.join("good.toml"),
        "retain = \"30d\"\ntransport = \"lab-udp\"\n[[robot]]\nnumber = 1\naddr = \"127.0.0.1:7301\"\n",
    )
    .unwrap();
    let out = ground(&dir, &["collect", "--check-config", "good.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    // The retention period is shown in the unit it was given ("3m" was
    // logged as "older than 0 days").
    std::fs::write(dir.join("short.toml"), "retain = \"3m\"\n").unwrap();
    let out = ground(&dir, &["collect", "--check-config", "short.toml"]);
    assert!(
        text(&out).contains("short.toml: ok (0 robots, retain 3m)"),
        "{}",
        text(&out)
    );
    // Every error of a file, not only the first unknown key.
    std::fs::write(
        dir.join("seven.toml"),
        "retian = \"1d\"\nretain = \"x\"\ntransport = \"ip\"\n[link]\nmax_backoff_ms = 0\n\
         [gaps]\nmax_tries = 0\n[[robot]]\nnumber = 0\n[[robot]]\nnumber = 1\nhk_interval_ms = 1\n",
    )
    .unwrap();
    let out = ground(&dir, &["collect", "--check-config", "seven.toml"]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out));
    let t = text(&out);
    assert_eq!(t.matches("seven.toml:").count(), 7, "{t}");
    assert!(t.contains("seven.toml:1:1: unknown field `retian`"), "{t}");
    // The shipped example configuration is valid.
    let example = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/collector.example.toml");
    let out = ground(&dir, &["collect", "--check-config", example]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
}

// verifies: GND-10, GND-02
#[test]
fn kill_9_and_restart_lose_and_duplicate_nothing_alarms_and_sigterm() {
    kill_and_restart(&tmpdir("kill"), "a.db");
}

/// The same on a PostgreSQL archive: the collector's alarms, holes and link health go
/// through the archive's backend-neutral store.
// verifies: GND-10, GND-02, GND-14
#[test]
fn kill_9_and_restart_on_a_postgresql_archive() {
    let url = pg_db("collect_kill");
    kill_and_restart(&tmpdir("kill-pg"), &url);
    pg_drop("collect_kill");
}

fn kill_and_restart(dir: &Path, arch: &str) {
    let (_o, addr, ctl) = start_obsw(1);
    let robots = vec![format!("1={addr}"), "2=127.0.0.1:9".to_string()];
    let mut c = collector(dir, arch, &robots);
    std::thread::sleep(Duration::from_secs(5));
    signal(&c, "-KILL");
    assert!(
        wait_exit(&mut c, Duration::from_secs(2)).is_none(),
        "killed, no exit code"
    );
    // The obsw goes on while nobody collects.
    std::thread::sleep(Duration::from_secs(6));
    let mut c = collector(dir, arch, &robots);
    std::thread::sleep(Duration::from_secs(3));
    let out = ground(dir, &["sim", "--addr", &ctl.to_string(), "battery-sag", "10.3"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    std::thread::sleep(Duration::from_secs(6));
    let t0 = Instant::now();
    signal(&c, "-TERM");
    assert_eq!(
        wait_exit(&mut c, Duration::from_secs(5)),
        Some(0),
        "SIGTERM: exit 0 within 5 s"
    );
    eprintln!("collector stopped in {:?}", t0.elapsed());
    let log = std::fs::read_to_string(dir.join("collect.log")).unwrap();

    // Every count from the first to the last archived, each once: the 6 s while the
    // collector was dead came from the on-board store.
    let seqs = archived_seqs(dir, arch);
    let (first, last) = (*seqs.keys().next().unwrap(), *seqs.keys().last().unwrap());
    let missing: Vec<i64> = (first..=last).filter(|s| !seqs.contains_key(s)).collect();
    let twice: Vec<_> = seqs.iter().filter(|(_, n)| **n > 1).collect();
    assert!(
        missing.is_empty(),
        "missing {:?}\n{log}",
        &missing[..missing.len().min(30)]
    );
    assert!(twice.is_empty(), "stored twice {twice:?}\n{log}");
    assert_eq!(first, 0, "from the obsw's first packet (BOOT)");
    assert!(last - first > 20, "{seqs:?}");

    // The collector's own TCs are archived, and its restart after kill -9 numbers on
    // after them (ops::first_tc_seq, the rule of every front end): no count reused.
    let out = ground(dir, &["--archive", arch, "archive", "query", "--type", "tc", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let mut tcs: Vec<i64> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["apid"] == 0x101 && v["step"].as_str().is_some_and(|s| s.starts_with("collect:")))
        .map(|v| v["seq"].as_i64().unwrap())
        .collect();
    let n = tcs.len();
    assert!(n >= 4, "the collector's subscriptions archived: {tcs:?}");
    tcs.sort_unstable();
    tcs.dedup();
    assert_eq!(tcs.len(), n, "a sequence count used twice: {tcs:?}");

    // Alarms: the sagging battery (soft limit 10.5 V) and the robot that never answered.
    let out = ground(dir, &["--archive", arch, "alarms", "list", "--json"]);
    let rows: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let find = |robot: i64, src: &str| {
        rows.iter()
            .find(|r| r["robot"] == robot && r["source"] == src)
            .unwrap_or_else(|| panic!("no {src} alarm for robot {robot}: {rows:?}\n{log}"))
            .clone()
    };
    let bat = find(1, "V_BAT_A");
    assert_eq!(
        (bat["severity"].as_str(), bat["state"].as_str()),
        (Some("medium"), Some("active"))
    );
    let link = find(2, "LINK_LOSS");
    assert_eq!(link["severity"], "high");
    let id = bat["id"].to_string();
    let out = ground(dir, &["--archive", arch, "alarms", "ack", &id]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(text(&out).contains("acknowledged"));
    let out = ground(dir, &["--archive", arch, "alarms", "ack", &id]);
    assert_eq!(out.status.code(), Some(3), "acknowledging twice is refused");
    let lid = link["id"].to_string();
    let out = ground(dir, &["--archive", arch, "alarms", "shelve", &lid, "--for", "1h"]);
    assert!(text(&out).contains("shelved"), "{}", text(&out));
    let out = ground(dir, &["--archive", arch, "alarms", "list"]);
    assert!(text(&out).contains("shelved<"), "{}", text(&out));

    // Health: when each robot was last heard.
    let out = ground(dir, &["--archive", arch, "collect", "--status"]);
    let t = text(&out);
    assert!(t.contains(&addr.to_string()) && t.contains("never"), "{t}");
}

// verifies: GND-10, GND-13
#[test]
fn full_disk_raises_an_alarm_and_the_collector_goes_on_losing_nothing() {
    let (_o, addr, _ctl) = start_obsw(1);
    let dir = tmpdir("full");
    // Log lines through a pipe: a file would hit the same size limit.
    let mut child = Command::new(GROUND)
        .current_dir(&dir)
        .args([
            "--archive",
            "a.db",
            "collect",
            "--lab-udp",
            "--plain",
            "--robot",
            &format!("1={addr}"),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting ground collect");
    let err = child.stderr.take().unwrap();
    let log = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
    let sink = log.clone();
    std::thread::spawn(move || {
        for l in std::io::BufReader::new(err).lines().map_while(Result::ok) {
            sink.lock().unwrap().push_str(&(l + "\n"));
        }
    });
    let mut c = Proc(child);
    std::thread::sleep(Duration::from_secs(4));
    // The "disk" is full: no file of the collector may grow past 4 KiB.
    let pid = c.0.id().to_string();
    let st = Command::new("prlimit")
        .args(["--pid", &pid, "--fsize=4096:unlimited"])
        .status()
        .expect("prlimit (util-linux)");
    assert!(st.success());
    std::thread::sleep(Duration::from_secs(6));
    assert!(c.0.try_wait().unwrap().is_none(), "still running on a full disk");
    let st = Command::new("prlimit")
        .args(["--pid", &pid, "--fsize=unlimited:unlimited"])
        .status()
        .unwrap();
    assert!(st.success());
    std::thread::sleep(Duration::from_secs(6));
    signal(&c, "-TERM");
    assert_eq!(wait_exit(&mut c, Duration::from_secs(5)), Some(0));
    let log = log.lock().unwrap().clone();
    assert!(log.contains("archive: cannot write"), "{log}");
    assert!(log.contains("writable again"), "{log}");

    let conn = rusqlite::Connection::open(dir.join("a.db")).unwrap();
    let ok: String = conn.query_row("PRAGMA integrity_check", [], |r| r.get(0)).unwrap();
    assert_eq!(ok, "ok");
    let seqs = archived_seqs(&dir, "a.db");
    let (first, last) = (*seqs.keys().next().unwrap(), *seqs.keys().last().unwrap());
    let missing: Vec<i64> = (first..=last).filter(|s| !seqs.contains_key(s)).collect();
    let twice: Vec<_> = seqs.iter().filter(|(_, n)| **n > 1).collect();
    assert!(
        missing.is_empty() && twice.is_empty(),
        "missing {missing:?} twice {twice:?}\n{log}"
    );
    assert!(last - first > 30, "{seqs:?}");
    let out = ground(&dir, &["--archive", "a.db", "alarms", "list", "--all", "--json"]);
    let t = text(&out);
    assert!(t.contains("\"source\":\"ARCHIVE_WRITE\""), "{t}");
    assert!(t.contains("\"state\":\"cleared\""), "{t}");
}

// verifies: GND-07
#[test]
fn dashboard_under_collect_uses_the_collectors_link_alarms_and_archive() {
    let (_o, addr, ctl) = start_obsw(1);
    let dir = tmpdir("dash");
    let port = free_port();
    let web: SocketAddr = ([127, 0, 0, 1], port).into();
    let log = std::fs::File::create(dir.join("collect.log")).unwrap();
    let t_start = Instant::now();
    let mut c = Proc(
        Command::new(GROUND)
            .current_dir(&dir)
            .args([
                "--archive",
                "a.db",
                "collect",
                "--lab-udp",
                "--plain",
                "--http",
                &web.to_string(),
            ])
            .args(["--robot", &format!("1={addr}")])
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("starting ground collect --http"),
    );
    let snapshot = || http(web, "GET", "/api/snapshot", None).1;
    // The robot, fed by the collector's own thread: link, mode, live HK.
    wait_for(30, "robot 1 up with mode and HK", || {
        let r = snapshot()["robots"][0].clone();
        (r["link"] == "up" && r["mode"].is_string() && r["hk"]["V_BAT_A"]["unit"] == "V").then_some(())
    });

    // PING from the page goes over the collector's link; its stages are tracked.
    let (st, r) = http(
        web,
        "POST",
        "/api/tc",
        Some(serde_json::json!({"robot": 1, "name": "PING", "args": {}})),
    );
    assert_eq!(st, 200, "{r}");
    let id = r["request_id"].as_str().unwrap().to_string();
    assert!(id.starts_with("1-101-"), "{id}");
    let stages = wait_for(30, "PING completion", || {
        let (_, c) = http(web, "GET", &format!("/api/tc/{id}"), None);
        let s = c["stages"].as_array().cloned().unwrap_or_default();
        s.iter().any(|x| x["stage"] == "completion").then_some(s)
    });
    assert!(stages.iter().all(|s| s["success"] == true), "{stages:?}");

    // No plans configured: an empty list, and a start names what is offered.
    let (st, r) = http(web, "GET", "/api/plans", None);
    assert_eq!((st, r.clone()), (200, serde_json::json!([])), "{r}");
    let (st, r) = http(web, "POST", "/api/plans", Some(serde_json::json!({"name": "x"})));
    assert_eq!(st, 404, "{r}");
    assert!(r.to_string().contains("no plan named \\\"x\\\""), "{r}");

    // One alarm set: the collector's V_BAT_A alarm shows on the page, is acknowledged
    // there, and `ground alarms list` sees the acknowledgement.
    let out = ground(&dir, &["sim", "--addr", &ctl.to_string(), "battery-sag", "10.3"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let alarm = wait_for(30, "V_BAT_A alarm on the page", || {
        snapshot()["alarms"].as_array().and_then(|v| {
            v.iter()
                .find(|a| a["source"] == "V_BAT_A" && a["state"] == "active")
                .cloned()
        })
    });
    let aid = alarm["id"].as_u64().unwrap();
    let (st, r) = http(web, "POST", &format!("/api/alarms/{aid}/ack"), None);
    assert_eq!(st, 200, "{r}");
    let out = ground(&dir, &["--archive", "a.db", "alarms", "list", "--json"]);
    let row: serde_json::Value = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .find(|r| r["id"].as_u64() == Some(aid))
        .unwrap_or_else(|| panic!("alarm {aid} not in `ground alarms list`: {}", text(&out)));
    assert_eq!(row["state"], "acknowledged", "{row}");

    // Plots come from the archive's decimation.
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as i64;
    wait_for(30, "archived V_BAT_A series", || {
        let (_, s) = http(
            web,
            "GET",
            &format!(
                "/api/series?robot=1&param=V_BAT_A&t0={}&t1={}&columns=50",
                now - 600_000,
                now + 60_000
            ),
            None,
        );
        s["points"].as_array().filter(|p| !p.is_empty()).map(|_| ())
    });

    // The page does not go stale after the 30 s downlink lease: the collector renews it.
    let past_lease = Duration::from_secs(40);
    if let Some(rest) = past_lease.checked_sub(t_start.elapsed()) {
        std::thread::sleep(rest);
    }
    let r = snapshot()["robots"][0].clone();
    let heard = r["last_heard_ms"].as_i64().unwrap();
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as i64;
    assert_eq!(r["link"], "up", "{r}");
    assert!(
        now - heard < 5_000,
        "last heard {} ms ago after the lease time",
        now - heard
    );

    signal(&c, "-TERM");
    assert_eq!(wait_exit(&mut c, Duration::from_secs(5)), Some(0), "SIGTERM: exit 0");
    // What the page's plots read besides the hub's live samples: the archive's
    // min/max decimation of what the collector archived.
    use ground::dashboard::Series;
    let series = ground::collect::dash::ArchiveSeries::new(dir.join("a.db"));
    let cols = series.decimate(1, "V_BAT_A", now - 600_000, now + 60_000, 50);
    assert!(!cols.is_empty(), "no archived V_BAT_A columns");
    assert!(cols.iter().any(|c| c.1 < 10.5), "the sag is in the archive: {cols:?}");
}

// verifies: OPS-TWO-01
#[test]
fn ground_send_beside_ground_collect_on_one_robot_is_refused_naming_the_collector() {
    let dir = tmpdir("two-grounds");
    let (_o, addr, _ctl) = start_obsw(1);
    let r = format!("1={addr}");
    let mut c = collector(&dir, "a.db", std::slice::from_ref(&r));
    // The collector holds the robot once its link is open (a second after its start).
    let o = wait_for(15, "the collector holding robot 1", || {
        let o = ground(&dir, &["--archive", "b.db", "send", "--lab-udp", "--robot", &r, "PING"]);
        (o.status.code() != Some(0)).then_some(o)
    });
    let t = text(&o);
    assert_eq!(o.status.code(), Some(3), "{t}");
    assert!(
        t.contains(&format!("robot 1 at {addr} is already commanded by pid {}", c.0.id())),
        "{t}"
    );
    assert!(t.contains("collect"), "the holder's command line: {t}");
    // Watching is commanding too (it keeps the downlink with PINGs): refused the same way.
    let o = ground(
        &dir,
        &[
            "--archive",
            "b.db",
            "watch",
            "--lab-udp",
            "--robot",
            &r,
            "--duration",
            "1",
        ],
    );
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    // The collector killed with SIGKILL: the operating system frees the robot at once.
    signal(&c, "-KILL");
    let _ = wait_exit(&mut c, Duration::from_secs(5));
    let o = ground(&dir, &["--archive", "b.db", "send", "--lab-udp", "--robot", &r, "PING"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
}
