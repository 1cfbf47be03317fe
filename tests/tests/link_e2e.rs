//! The ground and the obsw on a bad link, judged from what the obsw really did (its
//! `--tm-log`): the checkout plan through the project's lossy relay, a junk sender, a TCP
//! flood, `kill -9` of the obsw mid-plan, and `run --resume`.
//!
//! Needs the binaries: `cargo build -p obsw -p ground` (found next to the test executable
//! or through `OBSW_BIN` / `GROUND_BIN`).

use std::collections::{HashMap, HashSet};
use std::io::Write;
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::relay::{Config, Faults, Relay};
use e2e_tests::{bin, tc_named, Client, Obsw};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mmic-link-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn plan_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans").join(name)
}

fn ground(args: &[&str]) -> Output {
    Command::new(bin("ground"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run ground")
}

fn text(o: &Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// (APID, sequence count, time bytes) of a TM packet: what makes it one packet.
type Key = (u16, u16, Vec<u8>);

fn key(raw: &[u8]) -> Option<Key> {
    if raw.len() < 6 + 7 + 7 {
        return None;
    }
    let apid = u16::from_be_bytes([raw[0], raw[1]]) & 0x7FF;
    let seq = mib::headers::SeqCount::new(u16::from_be_bytes([raw[2], raw[3]])).get();
    // PUS-C TM secondary header: 7 bytes before the CDS time.
    Some((apid, seq, raw[13..20].to_vec()))
}

/// Every distinct TM packet the obsw sent (live or replayed), from its `--tm-log`.
fn obsw_log(path: &Path) -> Vec<Vec<u8>> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for line in text.lines() {
        let raw: Vec<u8> = (0..line.len() / 2)
            .filter_map(|i| u8::from_str_radix(&line[2 * i..2 * i + 2], 16).ok())
            .collect();
        if let Some(k) = key(&raw) {
            if seen.insert(k) {
                out.push(raw);
            }
        }
    }
    out
}

/// Raw TM rows of the archive.
fn archived_tm(db: &Path) -> Vec<Vec<u8>> {
    let c = rusqlite::Connection::open(db).unwrap();
    let mut q = c.prepare("SELECT raw FROM packet").unwrap();
    let rows = q.query_map([], |r| r.get::<_, Vec<u8>>(0)).unwrap();
    rows.map(Result::unwrap).collect()
}

/// Request IDs (packet ID, PSC) of the plan TCs the ground sent (from the archive).
fn plan_tcs(db: &Path) -> HashSet<(u16, u16)> {
    let c = rusqlite::Connection::open(db).unwrap();
    let mut q = c
        .prepare("SELECT DISTINCT raw FROM tc WHERE step IS NOT NULL AND step NOT IN ('heartbeat', 'end marker', 'gap retrieval')")
        .unwrap();
    let rows = q.query_map([], |r| r.get::<_, Vec<u8>>(0)).unwrap();
    rows.map(Result::unwrap)
        .map(|raw| {
            (
                u16::from_be_bytes([raw[0], raw[1]]),
                u16::from_be_bytes([raw[2], raw[3]]),
            )
        })
        .collect()
}

/// The checkout plan through the relay with one seed: every step done, every plan TC
/// started exactly once by the obsw, every TM the obsw sent up to the end marker archived
/// exactly once. Returns the run's wall time.
fn checkout_through(faults: Faults, seed: u64) -> Duration {
    let dir = tmpdir(&format!("checkout-{seed}-{}", (faults.drop * 100.0) as u32));
    let log = dir.join("tm.log");
    let db = dir.join("archive.db");
    let o = Obsw::start(&["--tm-log", log.to_str().unwrap(), "--seed", &seed.to_string()]);
    let mut cfg = Config::both_ways(o.udp, o.tcp, faults, seed);
    cfg.idle = Duration::from_secs(30);
    let mut relay = Relay::start(cfg).unwrap();
    let t0 = Instant::now();
    let out = ground(&[
        "--archive",
        db.to_str().unwrap(),
        "run",
        "--lab-udp",
        plan_path("checkout.toml").to_str().unwrap(),
        "--robot",
        &format!("1={}", relay.udp),
        "--plain",
        "--json",
    ]);
    let took = t0.elapsed();
    relay.stop();
    let t = text(&out);
    assert_eq!(out.status.code(), Some(0), "seed {seed}: {t}\nrelay: {}", relay.counts);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{e}: {t}"));
    assert_eq!(summary["done"], summary["steps"].as_array().unwrap().len(), "{t}");
    let upto = summary["tm"][0]["upto"]
        .as_u64()
        .unwrap_or_else(|| panic!("no end marker: {t}")) as u16;
    let from = summary["tm"][0]["from"]
        .as_u64()
        .unwrap_or_else(|| panic!("no start marker: {t}")) as u16;
    assert!(
        summary["tm"][0]["overwritten"].as_array().unwrap().is_empty()
            && summary["tm"][0]["not_received"].as_array().unwrap().is_empty(),
        "seed {seed}: TM not complete: {t}"
    );
    // Exactly once, from the obsw's own counters: TC_ACCEPTED counts executions
    // (a resend inside the duplicate window counts in TC_DUPLICATE instead), and every
    // distinct TC that reached the obsw has at least one TM[1,1] in its log. Equal
    // means no TC ran twice. A one-shot OBSW HK report reads the counter.
    let mut c = Client::udp(&o);
    c.subscribe();
    let raw = c.send("HK_ONE_SHOT", &[mib::hk::sid::OBSW as i64]);
    c.wait_done(&raw, Duration::from_secs(5)).expect("one-shot HK");
    let is_obsw_hk = |t: &e2e_tests::Tm| t.sid() == Some(mib::hk::sid::OBSW);
    let hk = match c.log.iter().find(|t| is_obsw_hk(t)) {
        Some(t) => t.clone(),
        None => c.wait_for(Duration::from_secs(5), is_obsw_hk).expect("OBSW HK"),
    };
    let accepted = hk.hk(mib::params::pid::TC_ACCEPTED).unwrap() as usize;
    let duplicates = hk.hk(mib::params::pid::TC_DUPLICATE).unwrap();
    drop(o);
    let sent = obsw_log(&log);
    let mut acknowledged: HashSet<(u16, u16)> = HashSet::new();
    for raw in &sent {
        if raw[7] == 1 && raw[8] == 1 && raw.len() >= 24 {
            acknowledged.insert((
                u16::from_be_bytes([raw[20], raw[21]]),
                u16::from_be_bytes([raw[22], raw[23]]),
            ));
        }
    }
    assert_eq!(
        accepted,
        acknowledged.len(),
        "seed {seed}: {accepted} executions for {} distinct TCs ({duplicates} duplicates answered)",
        acknowledged.len()
    );
    // Every plan TC was among them.
    let tcs = plan_tcs(&db);
    assert!(tcs.len() >= 8, "{tcs:?}");
    for r in &tcs {
        assert!(
            acknowledged.contains(r),
            "seed {seed}: plan TC {r:04x?} never reached the obsw"
        );
    }
    eprintln!("seed {seed}: {accepted} TCs executed once each, {duplicates} resends answered as duplicates");

    // Every TM the obsw sent up to the end marker, archived exactly once.
    let mut archived: HashMap<Key, u32> = HashMap::new();
    for raw in archived_tm(&db) {
        if let Some(k) = key(&raw) {
            *archived.entry(k).or_default() += 1;
        }
    }
    let mut missing = Vec::new();
    for raw in &sent {
        let k = key(raw).unwrap();
        // The run's TM: from the start marker's first report to the end marker's.
        if k.1 < from || k.1 > upto {
            continue;
        }
        match archived.get(&k) {
            Some(1) => {}
            Some(n) => panic!("seed {seed}: TM seq {} archived {n} times", k.1),
            None => missing.push(k.1),
        }
    }
    assert!(missing.is_empty(), "seed {seed}: not archived: {missing:?}\n{t}");
    // Kept only when a check fails (for a look at the archive and the obsw's log).
    let _ = std::fs::remove_dir_all(&dir);
    took
}

const BAD: Faults = Faults {
    drop: 0.20,
    duplicate: 0.05,
    corrupt: 0.05,
};

// verifies: GND-01, GND-02, GND-12
#[test]
fn checkout_completes_exactly_once_and_gap_free_through_a_bad_link() {
    // Several seeds at once (each its own obsw, relay and ground).
    let runs: Vec<_> = [11u64, 12, 13]
        .into_iter()
        .map(|seed| std::thread::spawn(move || checkout_through(BAD, seed)))
        .collect();
    for r in runs {
        let took = r.join().expect("a seed failed (see above)");
        eprintln!("checkout through the bad link: {:.1} s", took.as_secs_f64());
    }
}

/// A junk sender at 50 datagrams/s (empty, garbage and rejected TCs) never takes the
/// downlink: the ground keeps getting every HK report.
// verifies: DD-LINK-02, DD-ROBUST-01
#[test]
fn a_junk_sender_does_not_take_the_downlink() {
    let o = Obsw::start(&[]);
    let mut c = Client::udp(&o);
    c.subscribe();
    let raw = c.send("HK_SET_INTERVAL", &[1, 100]);
    c.wait_done(&raw, Duration::from_secs(5)).expect("interval set");
    let (udp, apid) = (o.udp, o.apid);
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let s2 = stop.clone();
    let junk = std::thread::spawn(move || {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut k = 0u16;
        while !s2.load(std::sync::atomic::Ordering::Relaxed) {
            k = k.wrapping_add(1);
            let mut bad = tc_named(apid, mib::headers::SeqCount::new(k).get(), "PING", &[]);
            *bad.last_mut().unwrap() ^= 0xFF;
            let d: Vec<u8> = match k % 3 {
                0 => Vec::new(),
                1 => vec![0xAB; 40],
                _ => bad,
            };
            let _ = s.send_to(&d, udp);
            std::thread::sleep(Duration::from_millis(20));
        }
    });
    c.recv_for(Duration::from_millis(300));
    let got = c.recv_for(Duration::from_secs(3));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    junk.join().unwrap();
    let hk: Vec<u16> = got.iter().filter(|t| t.sid() == Some(1)).map(|t| t.seq).collect();
    assert!(hk.len() >= 27, "10 Hz for 3 s under junk gave {} HK", hk.len());
    // Every HK in between arrived: no gap in the HK sequence counts seen.
    let all: Vec<u16> = got.iter().map(|t| t.seq).collect();
    for w in all.windows(2) {
        assert_eq!(
            w[1],
            mib::headers::SeqCount::new(w[0]).next().get(),
            "gap in TM: {all:?}"
        );
    }
}

fn proc_status(pid: u32, field: &str) -> u64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    s.lines()
        .find_map(|l| l.strip_prefix(field))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// A flood of valid pings on TCP plus hundreds of idle connections: threads and memory
/// stay flat, connections beyond the cap are refused, a ping is answered right after.
// verifies: DD-LINK-02, DD-ROBUST-01
#[test]
fn a_tcp_flood_keeps_the_obsw_bounded_and_answering() {
    let o = Obsw::start(&[]);
    let pid = o.pid();
    let (threads0, rss0) = (proc_status(pid, "Threads:"), proc_status(pid, "VmRSS:"));
    // A ground subscribed on UDP sees the refusals as events, not only as counters.
    let mut watcher = Client::udp(&o);
    watcher.subscribe();
    let mut idle: Vec<TcpStream> = (0..300).filter_map(|_| TcpStream::connect(o.tcp).ok()).collect();
    let flood_addr: SocketAddr = o.tcp;
    let apid = o.apid;
    let flood = std::thread::spawn(move || {
        let Ok(mut s) = TcpStream::connect(flood_addr) else {
            return 0;
        };
        s.set_write_timeout(Some(Duration::from_millis(200))).unwrap();
        let mut chunk = Vec::new();
        for k in 0..200u16 {
            let raw = tc_named(apid, k, "PING", &[]);
            let mut f = vec![0u8; mmic_link::stream::encoded_len(raw.len())];
            let n = mmic_link::stream::encode(&raw, &mut f).expect("buffer of encoded_len");
            chunk.extend_from_slice(&f[..n]);
        }
        let t0 = Instant::now();
        let mut sent = 0usize;
        while t0.elapsed() < Duration::from_secs(3) {
            match s.write(&chunk) {
                Ok(n) => sent += n,
                Err(_) => break,
            }
        }
        sent
    });
    std::thread::sleep(Duration::from_secs(2));
    let (threads1, rss1) = (proc_status(pid, "Threads:"), proc_status(pid, "VmRSS:"));
    let sent = flood.join().unwrap();
    idle.clear();
    assert!(sent > 0);
    assert!(threads1 <= threads0 + 2, "threads {threads0} -> {threads1}");
    assert!(rss1 < rss0 + 64 * 1024, "RSS {rss0} kB -> {rss1} kB");
    let refused = watcher
        .recv_for(Duration::from_millis(500))
        .iter()
        .filter(|t| t.event_id() == Some(mib::events::eid::TCP_CONNECTION_REFUSED))
        .count();
    assert!(
        refused > 0,
        "no TCP_CONNECTION_REFUSED event reached the subscribed ground"
    );
    // Answered right after (UDP, subscribed with the ping itself).
    std::thread::sleep(Duration::from_millis(200));
    let mut c = Client::udp(&o);
    let t0 = Instant::now();
    let raw = c.send("PING", &[]);
    assert!(
        c.wait_done(&raw, Duration::from_secs(3)).is_some(),
        "no answer after the flood"
    );
    eprintln!(
        "TCP flood: {sent} bytes in 3 s, threads {threads0} -> {threads1}, RSS {rss0} -> {rss1} kB, ping after {:.1} ms",
        t0.elapsed().as_secs_f64() * 1000.0
    );
}

/// `kill -9` of the obsw mid-plan is reported within 3 s with the no-answer exit code;
/// `run --resume` against a new obsw continues without repeating completed steps.
// verifies: GND-09, GND-06
#[test]
fn a_killed_obsw_is_reported_fast_and_the_run_resumes() {
    let dir = tmpdir("kill");
    let db = dir.join("archive.db");
    let mut o = Obsw::start(&[]);
    let addr = o.udp;
    let plan = plan_path("checkout.toml");
    let child = Command::new(bin("ground"))
        .args([
            "--archive",
            db.to_str().unwrap(),
            "run",
            "--lab-udp",
            plan.to_str().unwrap(),
            "--robot",
            &format!("1={addr}"),
            "--plain",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Let a few steps complete, then kill -9.
    std::thread::sleep(Duration::from_secs(6));
    o.kill9();
    let killed = Instant::now();
    let out = child.wait_with_output().unwrap();
    let after = killed.elapsed();
    let t = text(&out);
    assert_eq!(out.status.code(), Some(5), "{t}");
    assert!(t.contains("LINK LOST") && t.contains("nothing heard from"), "{t}");
    assert!(after < Duration::from_millis(3000), "reported after {after:?}");
    // "plan checkout: N of M steps done, ..."
    let done_before: u64 = t
        .lines()
        .find_map(|l| l.strip_prefix("plan checkout: "))
        .and_then(|l| l.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no summary: {t}"));
    assert!(done_before >= 1, "{t}");

    // A new obsw, in the state the robot is in (standby after the restart: the plan's
    // mode step runs again only if it had not completed).
    let o2 = Obsw::start(&[]);
    let out = ground(&[
        "--archive",
        db.to_str().unwrap(),
        "run",
        "--lab-udp",
        plan.to_str().unwrap(),
        "--robot",
        &format!("1={}", o2.udp),
        "--plain",
        "--resume",
        "--json",
    ]);
    let t = text(&out);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{e}: {t}"));
    let resumed = summary["resumed"].as_u64().unwrap();
    assert!(
        resumed >= 1 && resumed <= done_before,
        "resumed {resumed} of {done_before} done: {t}"
    );
    // Completed steps were not sent again: their step IDs appear in the archive's TC
    // table once per send of the first run only.
    let c = rusqlite::Connection::open(&db).unwrap();
    let resent: i64 = c
        .query_row("SELECT COUNT(DISTINCT seq) FROM tc WHERE step = 'hk-fast'", [], |r| {
            r.get(0)
        })
        .unwrap();
    assert_eq!(resent, 1, "hk-fast sent in one run only");
    drop(c);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A TCP frame longer than any packet gets TM[1,2] FRAME_TOO_LONG for the request ID its
/// head carries; the connection stays usable.
// verifies: DD-LINK-02, PUS-1-02
#[test]
fn an_oversize_tcp_frame_is_refused_with_its_own_code() {
    use mib::failure::FailureCode as F;
    let o = Obsw::start(&[]);
    let mut c = Client::tcp(&o);
    let mut big = tc_named(o.apid, 77, "PING", &[]);
    big.resize(3 * mib::config::MAX_PACKET_LEN, 0x11);
    c.send_raw(&big);
    let r = e2e_tests::request_of(&big);
    let t = c
        .wait_for(Duration::from_secs(5), |t| t.request() == Some(r) && t.subservice == 2)
        .expect("TM[1,2] for the oversize frame");
    assert_eq!(t.failure_code(), Some(F::FRAME_TOO_LONG.code()));
    let raw = c.send("PING", &[]);
    assert_eq!(c.wait_done(&raw, Duration::from_secs(5)).map(|t| t.subservice), Some(7));
}

/// Over TCP the end of the connection is the loss: reported at once.
// verifies: GND-09, DD-LINK-01
#[test]
fn a_killed_obsw_over_tcp_is_reported_at_the_connection_end() {
    let mut o = Obsw::start(&[]);
    let plan = plan_path("checkout.toml");
    let child = Command::new(bin("ground"))
        .args(["--no-archive", "run"])
        .arg(&plan)
        .args(["--lab-tcp", "--robot", &format!("1={}", o.tcp), "--plain"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(4));
    o.kill9();
    let killed = Instant::now();
    let out = child.wait_with_output().unwrap();
    let after = killed.elapsed();
    let t = text(&out);
    assert_eq!(out.status.code(), Some(5), "{t}");
    assert!(t.contains("closed the TCP connection"), "{t}");
    assert!(after < Duration::from_millis(1500), "reported after {after:?}");
}
