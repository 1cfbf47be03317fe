//! End-to-end test of `ground collect` (issue: unattended housekeeping collection).
//!
//! Three obsw behind the project's lossy relay (10 % drop, 2 % duplicate, 2 % corrupt,
//! both directions); robot 2's link black for 20 s; the collector killed with SIGKILL
//! and restarted 15 s later; a battery sag injected on robot 3 through the simulator
//! control port. Judged from what each obsw really sent (its `--tm-log`): every TM it
//! emitted up to the cut-off is archived exactly once, nothing is archived twice;
//! robot 2 has a link-loss alarm, robot 3 a battery alarm; SIGTERM ends the collector
//! with exit 0 within 5 s.
//!
//! Needs the `ground` and `obsw` binaries next to the test (`cargo build --workspace
//! --bins`, as CI does) or `$GROUND_BIN` / `$OBSW_BIN`.

use std::collections::{BTreeMap, BTreeSet};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::relay::{Config as RelayConfig, Faults, Relay};
use e2e_tests::{bin, Obsw};

/// (APID, sequence count, on-board time in Unix ms).
type Key = (i64, i64, i64);

/// Days from the CCSDS epoch (1958-01-01) to the Unix epoch.
const CCSDS_TO_UNIX_DAYS: i64 = 4383;

fn key_of(raw: &[u8]) -> Option<Key> {
    if raw.len() < 20 {
        return None;
    }
    let apid = u16::from_be_bytes([raw[0], raw[1]]) & 0x7FF;
    let seq = mib::headers::SeqCount::new(u16::from_be_bytes([raw[2], raw[3]])).get();
    let days = u16::from_be_bytes([raw[14], raw[15]]) as i64;
    let ms = u32::from_be_bytes([raw[16], raw[17], raw[18], raw[19]]) as i64;
    Some((apid as i64, seq as i64, (days - CCSDS_TO_UNIX_DAYS) * 86_400_000 + ms))
}

/// The string value of `"field":"..."` in a JSON line (the values read here hold no
/// escapes).
fn json_str<'a>(line: &'a str, field: &str) -> Option<&'a str> {
    let pat = format!("\"{field}\":\"");
    let start = line.find(&pat)? + pat.len();
    line[start..].split('"').next()
}

/// The integer value of `"field":N` in a JSON line.
fn json_int(line: &str, field: &str) -> Option<i64> {
    let pat = format!("\"{field}\":");
    let start = line.find(&pat)? + pat.len();
    let end = line[start..].find(|c: char| !c.is_ascii_digit() && c != '-')?;
    line[start..start + end].parse().ok()
}

fn hex(s: &str) -> Option<Vec<u8>> {
    let s = s.trim();
    (0..s.len())
        .step_by(2)
        .map(|i| s.get(i..i + 2).and_then(|b| u8::from_str_radix(b, 16).ok()))
        .collect()
}

/// Distinct packets in an obsw's TM log (store replays repeat packets).
fn sent(path: &Path) -> BTreeSet<Key> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(hex)
        .filter_map(|b| key_of(&b))
        .collect()
}

struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn kill(p: &Proc, sig: &str) {
    assert!(Command::new("kill")
        .args([sig, &p.0.id().to_string()])
        .status()
        .unwrap()
        .success());
}

fn ground(dir: &Path, args: &[&str]) -> Output {
    Command::new(bin("ground"))
        .current_dir(dir)
        .args(["--archive", "a.db"])
        .args(args)
        .output()
        .expect("running ground")
}

fn collector(dir: &Path) -> Proc {
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(dir.join("collect.log"))
        .unwrap();
    Proc(
        Command::new(bin("ground"))
            .current_dir(dir)
            .args(["--archive", "a.db", "collect", "--config", "c.toml", "--plain"])
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("starting ground collect"),
    )
}

fn relay(o: &Obsw, listen: Option<SocketAddr>, seed: u64) -> Relay {
    let f = Faults::new(0.10, 0.02, 0.02);
    let mut cfg = RelayConfig::both_ways(o.udp, o.tcp, f, seed);
    if let Some(a) = listen {
        cfg.listen_udp = a;
    }
    cfg.idle = Duration::from_secs(120);
    Relay::start(cfg).expect("relay")
}

fn tmpdir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("collect-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

// verifies: GND-10, GND-02, GND-12
#[test]
fn collector_archives_everything_once_through_loss_blackout_kill_and_raises_alarms() {
    let dir = tmpdir();
    let logs: Vec<PathBuf> = (1..=3).map(|r| dir.join(format!("tm-{r}.hex"))).collect();
    let obsws: Vec<Obsw> = (1..=3u8)
        .map(|r| Obsw::start_robot(r, &["--tm-log", logs[r as usize - 1].to_str().unwrap()]))
        .collect();
    let mut relays: Vec<Relay> = obsws
        .iter()
        .enumerate()
        .map(|(i, o)| relay(o, None, 11 + i as u64))
        .collect();
    let mut cfg = String::from("transport = \"lab-udp\"\n[gaps]\nretry_ms = 1500\nmax_tries = 8\n");
    for (i, r) in relays.iter().enumerate() {
        cfg.push_str(&format!("[[robot]]\nnumber = {}\naddr = \"{}\"\n", i + 1, r.udp));
    }
    std::fs::write(dir.join("c.toml"), cfg).unwrap();
    let t0 = Instant::now();
    let at = |s: u64| {
        let t = t0 + Duration::from_secs(s);
        if let Some(d) = t.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    };
    let mut c = collector(&dir);

    // t = 5 s: robot 2's link goes black for 20 s.
    at(5);
    let black_addr = relays[1].udp;
    relays[1].stop();
    // t = 8 s: robot 3's battery sags below the soft and hard limits.
    at(8);
    let reply = obsws[2].sim("battery-sag 9.6");
    assert!(reply.starts_with("ok"), "{reply}");
    at(25);
    relays[1] = relay(&obsws[1], Some(black_addr), 99);
    // t = 32 s: the collector is killed; it comes back 15 s later.
    at(32);
    kill(&c, "-KILL");
    let _ = c.0.wait();
    at(47);
    c = collector(&dir);
    // t = 60 s: the cut-off. Everything sent until now must end up archived.
    at(60);
    let expected: Vec<BTreeSet<Key>> = logs.iter().map(|p| sent(p)).collect();
    // Let the collector retrieve what the lossy links still owe it.
    at(75);
    let stop = Instant::now();
    kill(&c, "-TERM");
    let code = loop {
        if let Some(s) = c.0.try_wait().unwrap() {
            break s.code();
        }
        assert!(stop.elapsed() < Duration::from_secs(5), "SIGTERM: no exit within 5 s");
        std::thread::sleep(Duration::from_millis(20));
    };
    let log = std::fs::read_to_string(dir.join("collect.log")).unwrap_or_default();
    assert_eq!(code, Some(0), "exit code after SIGTERM\n{log}");

    // What the archive holds, with how many rows per packet.
    let out = ground(&dir, &["archive", "query", "--type", "tm", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let mut archived: BTreeMap<Key, u32> = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let key = match (json_int(line, "apid"), json_int(line, "seq"), json_int(line, "obt_ms")) {
            (Some(a), Some(s), Some(t)) => Some((a, s, t)),
            // A packet archived raw (its body did not decode) has its key in `raw`.
            _ => json_str(line, "raw").and_then(hex).and_then(|b| key_of(&b)),
        };
        if let Some(k) = key {
            *archived.entry(k).or_insert(0) += 1;
        }
    }
    let twice: Vec<_> = archived.iter().filter(|(_, n)| **n > 1).collect();
    assert!(twice.is_empty(), "stored twice: {twice:?}\n{log}");
    for (i, exp) in expected.iter().enumerate() {
        assert!(exp.len() > 100, "robot {} sent {} packets", i + 1, exp.len());
        let missing: Vec<&Key> = exp.iter().filter(|k| !archived.contains_key(k)).collect();
        assert!(
            missing.is_empty(),
            "robot {}: {} of {} sent packets not archived: {:?}\n{log}",
            i + 1,
            missing.len(),
            exp.len(),
            &missing[..missing.len().min(20)]
        );
    }

    // Alarms (cleared ones are still open until acknowledged).
    let out = ground(&dir, &["alarms", "list", "--all", "--json"]);
    let alarms: Vec<(i64, String)> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| Some((json_int(l, "robot")?, json_str(l, "source")?.to_string())))
        .collect();
    let has = |robot: i64, f: &dyn Fn(&str) -> bool| alarms.iter().any(|(r, s)| *r == robot && f(s));
    assert!(
        has(2, &|s| s == "LINK_LOSS"),
        "robot 2 link-loss alarm: {alarms:?}\n{log}"
    );
    assert!(
        has(3, &|s| s.starts_with("V_BAT") || s == "LOW_BATTERY"),
        "robot 3 battery alarm: {alarms:?}"
    );
    assert!(
        !has(1, &|s| s.starts_with("V_BAT") || s == "LOW_BATTERY"),
        "robot 1 has no battery alarm: {alarms:?}"
    );
}
