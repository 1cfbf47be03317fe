//! The real `obsw` binary over frames, killed with SIGKILL and restarted on the same state
//! file, with the same ground `GroundFrameLink` throughout: a TC frame captured before the crash
//! is refused and counted as a replay, and the ground's FOP-1 continues (no
//! re-initialisation, no alert) because FARM-1 resumes at the persisted V(R).

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use ground_link::{create_key_file, Config, Event, GroundFrameLink, TmSecurity};
use mib::params::pid;
use mmic_link::fop::{FopConfig, FopState};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B, TEST_KEY_TM_A, TEST_KEY_TM_B};

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

struct Obsw {
    child: Child,
    /// Its frame port (from its READY line).
    frame: SocketAddr,
}

/// How long a restarted obsw waits for the frame port its killed predecessor held.
const REBIND_WAIT: Duration = Duration::from_secs(5);

impl Obsw {
    fn start(frame: Option<SocketAddr>, ground: SocketAddr, dir: &Path) -> Obsw {
        Self::start_with(frame, ground, dir, "tc-spi1.key", "tm-spi17.key")
    }

    fn start_with(frame: Option<SocketAddr>, ground: SocketAddr, dir: &Path, tc_key: &str, tm_key: &str) -> Obsw {
        Self::start_args(frame, ground, dir, tc_key, tm_key, &[])
    }

    /// The obsw sending TM frames to `ground`. `frame`: `None` binds a frame port of its
    /// own (read from READY: no port probed and bound later, which another test could
    /// take in between); `Some` is the port of the obsw it restarts, where the same
    /// ground goes on sending — tried again while the killed process's port is not free.
    fn start_args(
        frame: Option<SocketAddr>,
        ground: SocketAddr,
        dir: &Path,
        tc_key: &str,
        tm_key: &str,
        extra: &[&str],
    ) -> Obsw {
        let s = |n: &str| dir.join(n).display().to_string();
        let listen = frame.map_or_else(|| "127.0.0.1:0".to_string(), |f| f.to_string());
        let t0 = Instant::now();
        loop {
            let mut child = Command::new(env!("CARGO_BIN_EXE_obsw"))
                .args(["--robot", "1", "--sim-ctl", "127.0.0.1:0"])
                // Off (frame link only), but bound: free ports, so tests run side by side.
                .args(["--udp", "127.0.0.1:0", "--tcp", "127.0.0.1:0"])
                .args(["--frame-udp", &listen, "--frame-tm-to", &ground.to_string()])
                .args(["--tc-key", &s(tc_key), "--tm-key", &s(tm_key)])
                .args(["--link-state", &s("obsw.state")])
                .args(extra)
                .stdout(Stdio::piped())
                .stderr(std::fs::File::create(dir.join("obsw.stderr")).unwrap())
                .spawn()
                .expect("start obsw");
            let mut line = String::new();
            BufReader::new(child.stdout.take().unwrap())
                .read_line(&mut line)
                .unwrap();
            if let Some(frame) = line
                .split_whitespace()
                .find_map(|w| w.strip_prefix("frame_udp="))
                .filter(|_| line.starts_with("READY"))
            {
                let frame = frame.parse().expect("frame_udp address");
                return Obsw { child, frame };
            }
            let _ = child.wait();
            let err = std::fs::read_to_string(dir.join("obsw.stderr")).unwrap_or_default();
            assert!(
                frame.is_some() && err.contains("Address already in use") && t0.elapsed() < REBIND_WAIT,
                "{line:?}: {err}"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    fn kill9(&mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }
}

impl Drop for Obsw {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The ground's TM socket, bound (port 0) before the obsw starts: its address goes to the
/// obsw, the socket to [`GroundFrameLink::open_socket`] once the obsw's frame port is known.
fn ground_socket() -> (UdpSocket, SocketAddr) {
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let addr = sock.local_addr().unwrap();
    (sock, addr)
}

/// Polls the link until `done` says so (or panics after `limit`), collecting events.
fn until(g: &mut GroundFrameLink, events: &mut Vec<Event>, limit: Duration, mut done: impl FnMut(&[u8]) -> bool) {
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
fn ping(g: &mut GroundFrameLink, events: &mut Vec<Event>, seq: u16) {
    let p = tc(seq, 17, 1, &[]);
    g.send_packet(&p).unwrap();
    until(
        g,
        events,
        Duration::from_secs(15),
        |t| matches!(tm(t), Some((1, 7, d)) if d.len() >= 4 && d[..4] == p[..4]),
    );
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("obsw-frames-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

// verifies: LINK-PERSIST-02, LINK-PERSIST-03, LINK-HK-01
#[test]
fn after_kill_9_a_captured_frame_is_a_replay_and_the_ground_continues_without_reinitialising() {
    let dir = tmp_dir("restart");
    // Names other than the key folder's: no spare keys are looked for.
    create_key_file(&dir.join("tc.key"), &TEST_KEY_TC_A).unwrap();
    create_key_file(&dir.join("tm.key"), &TEST_KEY_TM_A).unwrap();
    let (sock, ground) = ground_socket();
    let mut obsw = Obsw::start_with(None, ground, &dir, "tc.key", "tm.key");
    let frame = obsw.frame;
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
    let mut g = GroundFrameLink::open_socket(cfg, sock).unwrap();
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
    let _obsw = Obsw::start_with(Some(frame), ground, &dir, "tc.key", "tm.key");
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
                hk = mib_wire::codec::decode_hk(d).ok().map(|r| {
                    (
                        r.get(pid::LINK_REJ_REPLAY),
                        r.get(pid::LINK_AD_ACCEPTED),
                        r.get(pid::LINK_FARM_DISCARDED),
                        r.get(pid::LINK_STATE_WRITES),
                    )
                });
            }
        }
        hk.is_some()
    });
    let (replay, accepted, discarded, writes) = hk.unwrap();
    // One state write per accepted frame (and the TM IV block reserved at boot).
    assert!(writes.is_some_and(|w| w >= 4), "{writes:?}");
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

/// Sends a TC and waits for its completion (`Ok`) or a failure report (`Err(code)`).
fn command(g: &mut GroundFrameLink, events: &mut Vec<Event>, raw: &[u8]) -> Result<(), u16> {
    g.send_packet(raw).unwrap();
    let mut out = None;
    until(g, events, Duration::from_secs(15), |t| {
        if let Some((1, sub, d)) = tm(t) {
            if d.len() >= 4 && d[..4] == raw[..4] {
                match sub {
                    7 => out = Some(Ok(())),
                    2 | 4 | 6 | 8 if d.len() >= 6 => out = Some(Err(u16::from_be_bytes([d[4], d[5]]))),
                    _ => {}
                }
            }
        }
        out.is_some()
    });
    out.unwrap()
}

// verifies: LINK-KEYCHG-01, LINK-KEYCHG-02, LINK-HK-01
#[test]
fn link_spi_select_moves_the_real_obsw_to_tc_spi_2_and_tm_spi_18_without_a_tc_lost() {
    let dir = tmp_dir("spi");
    create_key_file(&dir.join("tc-spi1.key"), &TEST_KEY_TC_A).unwrap();
    create_key_file(&dir.join("tm-spi17.key"), &TEST_KEY_TM_A).unwrap();
    let open = |frame: SocketAddr, tc_spi: u16| {
        let mut cfg = Config::from_key_dir(
            frame,
            SocketAddr::from(([127, 0, 0, 1], 0)),
            &dir,
            &dir.join("ground.state"),
            tc_spi,
        )
        .unwrap();
        cfg.fop.t1_ms = 500;
        cfg
    };
    let (sock, ground) = ground_socket();
    let mut obsw = Obsw::start(None, ground, &dir);
    let mut g = GroundFrameLink::open_socket(open(obsw.frame, 1), sock).unwrap();
    let mut events = Vec::new();
    let active = |g: &mut GroundFrameLink, events: &mut Vec<Event>| {
        let t0 = Instant::now();
        while g.fop_state() != FopState::Active {
            g.recv(Duration::from_millis(20)).unwrap();
            events.extend(g.take_events());
            assert!(t0.elapsed() < Duration::from_secs(15), "COP-1 initialised: {events:?}");
        }
    };
    // Without the spare keys on board: refused with NO_KEY_FOR_SPI (53).
    active(&mut g, &mut events);
    assert_eq!(command(&mut g, &mut events, &tc(1, 212, 1, &[0, 18, 2])), Err(53));
    assert_eq!(
        command(&mut g, &mut events, &tc(2, 17, 1, &[])),
        Ok(()),
        "nothing changed"
    );

    // The spare keys installed on both ends (here: the robot restarted to load them).
    create_key_file(&dir.join("tc-spi2.key"), &TEST_KEY_TC_B).unwrap();
    create_key_file(&dir.join("tm-spi18.key"), &TEST_KEY_TM_B).unwrap();
    obsw.kill9();
    drop(g);
    // Both restarted, each on a port of its own (the ground's link state goes on).
    let (sock, ground) = ground_socket();
    let obsw = Obsw::start(None, ground, &dir);
    let frame = obsw.frame;
    let mut g = GroundFrameLink::open_socket(open(frame, 1), sock).unwrap();
    active(&mut g, &mut events);
    // The ground moves to TC SPI 2 with pings outstanding: both SPIs are accepted.
    for seq in 3..6 {
        g.send_packet(&tc(seq, 17, 1, &[])).unwrap();
    }
    g.poll(g.now_ms()).unwrap();
    g.switch_tc_spi(2, &TEST_KEY_TC_B).unwrap();
    let tm18 = g.tm_last_iv(18);
    // Then TC SPI 1 retired, TM under SPI 18.
    assert_eq!(command(&mut g, &mut events, &tc(6, 212, 1, &[0, 18, 2])), Ok(()));
    assert_eq!(command(&mut g, &mut events, &tc(7, 17, 1, &[])), Ok(()));
    assert_ne!(g.tm_last_iv(18), tm18, "TM under SPI 18 read by the ground");
    // A frame under the retired SPI 1 (authentic, fresh IV) is refused; HK counts it.
    let repr = mmic_link::tc::TcRepr {
        frame_type: mmic_link::tc::FrameType::Ad,
        scid: mib::link::SCID,
        vcid: mib::link::tc_vc::COMMAND,
        seq: 0,
        data_len: 0,
    };
    let mut sa = mmic_link::sdls::TxSa::resume(1, &TEST_KEY_TC_A, 1 << 40);
    let mut buf = [0u8; 128];
    let n = mmic_link::sdls::build_tc(
        &mut sa,
        &mut mmic_link::sdls::MemoryIvStore::default(),
        repr,
        &tc(8, 17, 1, &[]),
        &mut buf,
    )
    .unwrap();
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .send_to(&buf[..n], frame)
        .unwrap();
    let sid = mib::hk::sid::SPACE_LINK.to_be_bytes();
    let hk_req = tc(9, 3, 27, &[sid[0], sid[1]]);
    g.send_packet(&hk_req).unwrap();
    let mut hk = None;
    until(&mut g, &mut events, Duration::from_secs(15), |t| {
        if let Some((3, 25, d)) = tm(t) {
            if d[..2] == sid {
                hk = mib_wire::codec::decode_hk(d).ok().map(|r| {
                    [
                        pid::LINK_REJ_UNKNOWN_SPI,
                        pid::LINK_TM_SPI,
                        pid::LINK_TC_SPIS,
                        pid::LINK_STATE_BAD_SLOT,
                    ]
                    .map(|p| r.get(p))
                });
            }
        }
        hk.is_some()
    });
    let [unknown_spi, tm_spi, tc_spis, bad_slot] = hk.unwrap();
    assert_eq!(unknown_spi, Some(1), "the frame under the retired SPI 1 refused");
    assert_eq!(
        (tm_spi, tc_spis, bad_slot),
        (Some(18), Some(0b10), Some(0)),
        "HK shows the SPIs in use"
    );
    assert_eq!(g.counters.alerts, 0, "{events:?}");
    drop(obsw);
    let _ = std::fs::remove_dir_all(&dir);
}

// verifies: LINK-TM-04
#[test]
fn with_tm_sdls_clear_the_tm_frames_carry_packets_in_clear_and_only_a_clear_ground_reads_them() {
    let dir = tmp_dir("tm-clear");
    create_key_file(&dir.join("tc-spi1.key"), &TEST_KEY_TC_A).unwrap();
    create_key_file(&dir.join("tm-spi17.key"), &TEST_KEY_TM_A).unwrap();
    let (sock, ground) = ground_socket();
    // Kept: the wire is read on the ground's port once the ground is gone.
    let wire = sock.try_clone().unwrap();
    let obsw = Obsw::start_args(
        None,
        ground,
        &dir,
        "tc-spi1.key",
        "tm-spi17.key",
        &["--tm-sdls", "clear"],
    );
    let frame = obsw.frame;
    let mut cfg = Config::from_key_dir(
        frame,
        SocketAddr::from(([127, 0, 0, 1], 0)),
        &dir,
        &dir.join("ground.state"),
        1,
    )
    .unwrap();
    cfg.fop.t1_ms = 500;
    cfg.tm_security = TmSecurity::Clear;
    let mut g = GroundFrameLink::open_socket(cfg, sock).unwrap();
    let mut events = Vec::new();
    let t0 = Instant::now();
    while g.fop_state() != FopState::Active {
        g.recv(Duration::from_millis(20)).unwrap();
        events.extend(g.take_events());
        assert!(t0.elapsed() < Duration::from_secs(15), "COP-1 initialised: {events:?}");
    }
    g.capture(true);
    ping(&mut g, &mut events, 1);
    assert_eq!(g.counters.tm.sdls_rejected, 0);
    assert_eq!(
        g.tm_last_iv(17),
        Some((1u128 << 96) - 1),
        "no TM IV ever accepted: no SDLS on TM"
    );
    drop(g);
    // On the wire: a ping sent as the next AD frame (N(S) = 1, an IV above the ground's),
    // its reports stand in clear right after the frame header of a VC0 frame.
    // The link made the shared socket non-blocking.
    wire.set_nonblocking(false).unwrap();
    wire.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let p = tc(2, 17, 1, &[]);
    let repr = mmic_link::tc::TcRepr {
        frame_type: mmic_link::tc::FrameType::Ad,
        scid: mib::link::SCID,
        vcid: mib::link::tc_vc::COMMAND,
        seq: 1,
        data_len: 0,
    };
    let mut sa = mmic_link::sdls::TxSa::resume(1, &TEST_KEY_TC_A, 1 << 40);
    let mut buf = [0u8; 128];
    let n = mmic_link::sdls::build_tc(
        &mut sa,
        &mut mmic_link::sdls::MemoryIvStore::default(),
        repr,
        &p,
        &mut buf,
    )
    .unwrap();
    wire.send_to(&buf[..n], frame).unwrap();
    let t0 = Instant::now();
    let mut seen_clear_vc0 = false;
    let mut b = [0u8; 2048];
    while !seen_clear_vc0 && t0.elapsed() < Duration::from_secs(10) {
        if let Ok(n) = wire.recv(&mut b) {
            let vc = (b[1] >> 1) & 7;
            if n == 1024 && vc == 0 {
                // A space packet of robot 1 at the start of the data field, never SPI 17.
                assert_eq!(u16::from_be_bytes([b[6], b[7]]) & 0x7FF, APID, "{:02x?}", &b[6..12]);
                seen_clear_vc0 = true;
            }
        }
    }
    assert!(seen_clear_vc0, "a VC0 frame came down");
    drop(obsw);
    let _ = std::fs::remove_dir_all(&dir);
}
