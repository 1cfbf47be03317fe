//! End-to-end test of the on-board store across a killed obsw: robot 1 behind the
//! project's relay, the link cut, the obsw killed with SIGKILL in the middle of the
//! outage and started again on the same store file (`--tm-store`), the link back. The
//! collector (`ground collect`) must archive every housekeeping packet the obsw sent
//! during the outage — counted against both runs' TM logs and against the sequence
//! counts, which go on across the restart — and nothing twice.
//!
//! The outage lasts `STORE_OUTAGE_S` seconds (default 20; the 10-minute case is run by
//! hand: `STORE_OUTAGE_S=600 cargo test -p e2e-tests --test store_restart_e2e --
//! --nocapture`).
//!
//! Needs the `ground` and `obsw` binaries next to the test (`cargo build --workspace
//! --bins`, as CI does) or `$GROUND_BIN` / `$OBSW_BIN`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::relay::{Config as RelayConfig, Faults, Relay};
use e2e_tests::{bin, Obsw};

/// (sequence count, on-board time in CCSDS days and ms of day).
type Key = (u16, u16, u32);

/// A TM packet's key and whether it is periodic housekeeping (TM[3,25]).
fn key_of(raw: &[u8]) -> Option<(Key, bool)> {
    let p = mib_wire::header::TmPacket::parse(raw).ok()?;
    Some((
        (p.primary.seq_count, p.time.days, p.time.ms_of_day),
        (p.service, p.subservice) == (3, 25),
    ))
}

fn hex(s: &str) -> Option<Vec<u8>> {
    let s = s.trim();
    (0..s.len())
        .step_by(2)
        .map(|i| s.get(i..i + 2).and_then(|b| u8::from_str_radix(b, 16).ok()))
        .collect()
}

/// Packets of a TM log in the order sent (store replays repeat packets: first sending only).
fn log(path: &Path) -> Vec<(Key, bool)> {
    let mut seen = BTreeSet::new();
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(hex)
        .filter_map(|b| key_of(&b))
        .filter(|(k, _)| seen.insert(*k))
        .collect()
}

struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn collector(dir: &Path) -> Proc {
    let log = std::fs::File::create(dir.join("collect.log")).unwrap();
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

/// Every TM packet in the archive with how many rows it has.
fn archived(dir: &Path) -> BTreeMap<Key, u32> {
    let out = Command::new(bin("ground"))
        .current_dir(dir)
        .args(["--archive", "a.db", "archive", "query", "--type", "tm", "--json"])
        .output()
        .expect("ground archive query");
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let mut n = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let v: serde_json::Value = serde_json::from_str(line).expect("one JSON object a line");
        let raw = v["raw"].as_str().and_then(hex);
        if let Some((k, _)) = raw.as_deref().and_then(key_of) {
            *n.entry(k).or_insert(0) += 1;
        }
    }
    n
}

fn relay(o: &Obsw, listen: Option<std::net::SocketAddr>) -> Relay {
    let mut cfg = RelayConfig::both_ways(o.udp, o.tcp, Faults::new(0.0, 0.0, 0.0), 7);
    if let Some(a) = listen {
        cfg.listen_udp = a;
    }
    cfg.idle = Duration::from_secs(3600);
    Relay::start(cfg).expect("relay")
}

fn tmpdir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("store-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

// verifies: PUS-15-03, GND-12
#[test]
fn an_obsw_killed_during_an_outage_keeps_its_store_and_the_collector_archives_all_its_hk() {
    let outage_s: u64 = std::env::var("STORE_OUTAGE_S")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let dir = tmpdir();
    let store = dir.join("tm-store.bin");
    let logs = [dir.join("tm-run1.hex"), dir.join("tm-run2.hex")];
    let args = |log: &Path| -> Vec<String> {
        vec![
            "--tm-store".into(),
            store.to_str().unwrap().into(),
            "--tm-log".into(),
            log.to_str().unwrap().into(),
        ]
    };
    let start = |log: &Path| {
        let a = args(log);
        Obsw::start(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let mut obsw = start(&logs[0]);
    let mut link = relay(&obsw, None);
    std::fs::write(
        dir.join("c.toml"),
        format!(
            "transport = \"lab-udp\"\n[gaps]\nretry_ms = 1500\nmax_tries = 8\n[[robot]]\nnumber = 1\naddr = \"{}\"\n",
            link.udp
        ),
    )
    .unwrap();
    let _c = collector(&dir);
    let t0 = Instant::now();
    let at = |s: u64| {
        if let Some(d) = (t0 + Duration::from_secs(s)).checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    };

    // t = 8 s: the link goes (the collector has followed the robot until now).
    at(8);
    let link_addr = link.udp;
    link.stop();
    let outage_from = log(&logs[0]).len();
    // Half-way through the outage: SIGKILL, and the obsw starts again on its store.
    at(8 + outage_s / 2);
    obsw.kill9();
    let run1 = log(&logs[0]);
    obsw = start(&logs[1]);
    // The end of the outage: the link comes back to the new process.
    at(8 + outage_s);
    let run2_at_link = log(&logs[1]).len();
    link = relay(&obsw, Some(link_addr));

    // What the outage sent: run 1 from the cut to the kill, run 2 until the link came back.
    let run2 = log(&logs[1]);
    let outage: Vec<(Key, bool)> = run1[outage_from..]
        .iter()
        .chain(&run2[..run2_at_link])
        .copied()
        .collect();
    let outage_hk: Vec<Key> = outage.iter().filter(|(_, hk)| *hk).map(|(k, _)| *k).collect();
    assert!(
        outage_hk.len() as u64 >= outage_s,
        "{} HK packets in a {outage_s} s outage",
        outage_hk.len()
    );
    // The sequence count goes on across the restart: one run, no count twice.
    let last1 = run1.last().expect("run 1 sent TM").0 .0;
    let first2 = run2.first().expect("run 2 sent TM").0 .0;
    assert_eq!(
        first2,
        mib::headers::SeqCount::new(last1).next().get(),
        "run 2 goes on after run 1's last count"
    );

    // The collector fills the outage from the store: wait for it (bounded).
    let deadline = Instant::now() + Duration::from_secs(60 + outage_s / 2);
    let (missing, arch) = loop {
        let arch = archived(&dir);
        let missing: Vec<Key> = outage_hk.iter().filter(|k| !arch.contains_key(k)).copied().collect();
        if missing.len() <= 1 || Instant::now() > deadline {
            println!(
                "filled {:.1} s after the link came back",
                t0.elapsed().as_secs_f64() - (8 + outage_s) as f64
            );
            break (missing, arch);
        }
        std::thread::sleep(Duration::from_secs(2));
    };
    let collect_log = std::fs::read_to_string(dir.join("collect.log")).unwrap_or_default();
    // A SIGKILL between sending a packet (and logging it) and storing it loses that one
    // packet: at most the last HK packet run 1 logged.
    let last_hk1 = run1.iter().rev().find(|(_, hk)| *hk).map(|(k, _)| *k);
    assert!(
        missing.is_empty() || (missing.len() == 1 && Some(missing[0]) == last_hk1),
        "{} of {} outage HK packets not archived: {:?}\n{collect_log}",
        missing.len(),
        outage_hk.len(),
        &missing[..missing.len().min(20)]
    );
    let twice: Vec<_> = arch.iter().filter(|(_, n)| **n > 1).collect();
    assert!(twice.is_empty(), "archived twice: {twice:?}");
    println!(
        "outage {outage_s} s: {} HK packets sent ({} by the killed run), {} archived, {} missing, 0 duplicates; {} packets in the archive",
        outage_hk.len(),
        run1[outage_from..].iter().filter(|(_, hk)| *hk).count(),
        outage_hk.len() - missing.len(),
        missing.len(),
        arch.len()
    );
    drop(link);
}
