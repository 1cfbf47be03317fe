//! The real `obsw` binary over frames, killed with SIGKILL and restarted on the same state
//! file, with the same ground `FrameLink` throughout: a TC frame captured before the crash
//! is refused and counted as a replay, and the ground's FOP-1 continues (no
//! re-initialisation, no alert) because FARM-1 resumes at the persisted V(R).

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use ground_link::{create_key_file, Config, Event, FrameLink};
use mib::params::pid;
use mmic_link::fop::{FopConfig, FopState};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};

const APID: u16 = 0x101;

/// A PUS-C TC (all acknowledgement flags, source 0) with its CRC.
fn tc(seq: u16, service: u8, subservice: u8, app: &[u8]) -> Vec<u8> {
    let len = (5 + app.len() + 2 - 1) as u16;
    let mut p = vec![
        0x18 | (APID >> 8) as u8,
        APID as u8,
        0xC0 | ((seq >> 8) & 0x3F) as u8,
        seq as u8,
        (len >> 8) as u8,
        len as u8,
        0x2F,
        service,
        subservice,
        0,
        0,
    ];
    p.extend_from_slice(app);
    let crc = mmic_link::fecf::crc16(&p);
    p.extend_from_slice(&crc.to_be_bytes());
    p
}

/// (service, subservice, source data) of a PUS-C TM packet.
fn tm(p: &[u8]) -> Option<(u8, u8, &[u8])> {
    let data = 6 + 7 + mib::config::TIMESTAMP_LEN;
    (p.len() >= data + 2).then(|| (p[7], p[8], &p[data..p.len() - 2]))
}

struct Obsw(Child);

impl Obsw {
    fn start(frame: SocketAddr, ground: SocketAddr, dir: &Path) -> Obsw {
        let s = |n: &str| dir.join(n).display().to_string();
        let mut child = Command::new(env!("CARGO_BIN_EXE_obsw"))
            .args(["--robot", "1", "--sim-ctl", "127.0.0.1:0"])
            .args(["--frame-udp", &frame.to_string(), "--frame-tm-to", &ground.to_string()])
            .args(["--tc-key", &s("tc.key"), "--tm-key", &s("tm.key")])
            .args(["--link-state", &s("obsw.state")])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start obsw");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        assert!(line.starts_with("READY"), "{line:?}");
        Obsw(child)
    }

    fn kill9(&mut self) {
        self.0.kill().unwrap();
        self.0.wait().unwrap();
    }
}

impl Drop for Obsw {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Polls the link until `done` says so (or panics after `limit`), collecting events.
fn until(g: &mut FrameLink, events: &mut Vec<Event>, limit: Duration, mut done: impl FnMut(&[u8]) -> bool) {
    let t0 = Instant::now();
    loop {
        let pkts = g.recv(Duration::from_millis(20)).unwrap();
        events.extend(g.take_events());
        if pkts.iter().any(|p| done(p)) {
            return;
        }
        assert!(t0.elapsed() < limit, "timed out; events {events:?}");
    }
}

/// Sends a ping and waits for its TM[1,7].
fn ping(g: &mut FrameLink, events: &mut Vec<Event>, seq: u16) {
    let p = tc(seq, 17, 1, &[]);
    g.send_packet(&p).unwrap();
    until(
        g,
        events,
        Duration::from_secs(15),
        |t| matches!(tm(t), Some((1, 7, d)) if d.len() >= 4 && d[..4] == p[..4]),
    );
}

fn tmp_dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("obsw-frames-restart-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

// verifies: LINK-PERSIST-02, LINK-PERSIST-03
#[test]
fn after_kill_9_a_captured_frame_is_a_replay_and_the_ground_continues_without_reinitialising() {
    let dir = tmp_dir();
    create_key_file(&dir.join("tc.key"), &TEST_KEY_TC_A).unwrap();
    create_key_file(&dir.join("tm.key"), &TEST_KEY_TM_A).unwrap();
    let frame = UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let mut cfg = Config::from_key_files(
        frame,
        SocketAddr::from(([127, 0, 0, 1], 0)),
        &dir.join("tc.key"),
        &dir.join("tm.key"),
        &dir.join("ground.state"),
    )
    .unwrap();
    cfg.fop = FopConfig {
        t1_ms: 500,
        ..FopConfig::mission()
    };
    let mut g = FrameLink::open(cfg).unwrap();
    let ground = g.local_addr().unwrap();
    let mut obsw = Obsw::start(frame, ground, &dir);
    let mut events = Vec::new();
    let t0 = Instant::now();
    while g.fop_state() != FopState::Active {
        g.recv(Duration::from_millis(20)).unwrap();
        events.extend(g.take_events());
        assert!(t0.elapsed() < Duration::from_secs(15), "COP-1 initialised: {events:?}");
    }
    g.capture(true);
    for seq in 1..=3 {
        ping(&mut g, &mut events, seq);
    }
    let captured = g.take_captured();
    g.capture(false);
    assert_eq!(captured.len(), 3, "one AD frame per ping");
    // Every frame acknowledged (CLCW N(R) = 3) before the crash.
    let t0 = Instant::now();
    while g.pending() > 0 || g.clcw().map(|c| c.report_value) != Some(3) {
        g.recv(Duration::from_millis(20)).unwrap();
        assert!(t0.elapsed() < Duration::from_secs(5));
    }

    obsw.kill9();
    events.clear();
    let _obsw = Obsw::start(frame, ground, &dir);
    // The captured frames, replayed by anyone on the path.
    let attacker = UdpSocket::bind("127.0.0.1:0").unwrap();
    for f in &captured {
        attacker.send_to(f, frame).unwrap();
    }
    // The same ground goes on: three more pings, then the space-link HK.
    for seq in 4..=6 {
        ping(&mut g, &mut events, seq);
    }
    let sid = mib::hk::sid::SPACE_LINK.to_be_bytes();
    let hk_req = tc(7, 3, 27, &[sid[0], sid[1]]);
    g.send_packet(&hk_req).unwrap();
    let mut hk = None;
    until(&mut g, &mut events, Duration::from_secs(15), |t| {
        if let Some((3, 25, d)) = tm(t) {
            if d[..2] == sid {
                hk = mib::codec::decode_hk(d).ok().map(|r| {
                    (
                        r.get(pid::LINK_REJ_REPLAY),
                        r.get(pid::LINK_AD_ACCEPTED),
                        r.get(pid::LINK_FARM_DISCARDED),
                    )
                });
            }
        }
        hk.is_some()
    });
    let (replay, accepted, discarded) = hk.unwrap();
    assert_eq!(replay, Some(3), "each captured frame refused as a replay");
    // The restarted obsw accepted the three new pings and the HK request (its counters
    // start at boot), nothing else; FARM-1 never saw the replays.
    assert_eq!((accepted, discarded), (Some(4), Some(0)));
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, Event::Initialised { .. } | Event::Alert(_) | Event::Unknown { .. })),
        "the ground continued without re-initialising: {events:?}"
    );
    assert_eq!(g.counters.alerts, 0);
    let _ = std::fs::remove_dir_all(&dir);
}
