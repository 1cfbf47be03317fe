//! The space link end to end (docs/space-link.md): the real `obsw` with its frame endpoint
//! (`--frame-udp`, COP-1, SDLS) and the `ground-link` library as the ground, over loopback
//! UDP (and the lossy relay). Keys are the published TEST keys of `mmic_link::test_keys`,
//! written to files named `TEST-KEY-…` in a temporary directory. What the obsw did is judged
//! from its own TM: its `--tm-log` (every packet it sent) and its SPACE_LINK HK.

use std::collections::BTreeMap;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use e2e_tests::relay::{Config as RelayConfig, Faults, Relay};
use e2e_tests::{free_udp, request_of, tc_named, Obsw, Tm};
use ground_link::{create_key_file, Config, Event, GroundFrameLink, PacketId};
use mib::events::eid;
use mib::link::sdls::{TC_SPIS, TM_SPIS};
use mib::params::pid;
use mmic_link::fop::{FopConfig, FopState};
use mmic_link::sdls::{build_tc, MemoryIvStore, TxSa};
use mmic_link::tc::{FrameType, TcRepr};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B, TEST_KEY_TM_A};

const APID: u16 = 0x101;

/// A temporary directory with the test key files and state files.
struct Dir(PathBuf);

impl Dir {
    fn new(name: &str) -> Dir {
        let d = std::env::temp_dir().join(format!("spacelink-e2e-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        create_key_file(&d.join("TEST-KEY-tc-spi1.key"), &TEST_KEY_TC_A).unwrap();
        create_key_file(&d.join("TEST-KEY-tm-spi17.key"), &TEST_KEY_TM_A).unwrap();
        Dir(d)
    }
    fn p(&self, f: &str) -> PathBuf {
        self.0.join(f)
    }
    fn s(&self, f: &str) -> String {
        self.p(f).display().to_string()
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Starts the obsw with its frame endpoint on `frame` sending TM frames to `tm_to`.
fn obsw(d: &Dir, frame: SocketAddr, tm_to: SocketAddr, tm_log: &str) -> Obsw {
    obsw_with(d, frame, tm_to, tm_log, &[])
}

fn obsw_with(d: &Dir, frame: SocketAddr, tm_to: SocketAddr, tm_log: &str, extra: &[&str]) -> Obsw {
    let (frame, tm_to) = (frame.to_string(), tm_to.to_string());
    let (tck, tmk, st, log) = (
        d.s("TEST-KEY-tc-spi1.key"),
        d.s("TEST-KEY-tm-spi17.key"),
        d.s("obsw-link.state"),
        d.s(tm_log),
    );
    let mut args = vec![
        "--speed",
        "20",
        "--frame-udp",
        &frame,
        "--frame-tm-to",
        &tm_to,
        "--tc-key",
        &tck,
        "--tm-key",
        &tmk,
        "--link-state",
        &st,
        "--tm-log",
        &log,
    ];
    args.extend_from_slice(extra);
    Obsw::start(&args)
}

/// The ground: a frame link and what it received.
struct Ground {
    link: GroundFrameLink,
    log: Vec<Tm>,
    events: Vec<Event>,
}

impl Ground {
    fn open(d: &Dir, robot: SocketAddr, listen: SocketAddr, fop: FopConfig) -> Ground {
        let mut cfg = Config::from_key_files(
            robot,
            listen,
            &d.p("TEST-KEY-tc-spi1.key"),
            &d.p("TEST-KEY-tm-spi17.key"),
            &d.p("ground-link.state"),
        )
        .unwrap();
        cfg.fop = fop;
        // Reopening a fixed address: another process on this shared machine may hold the
        // just-freed port for a moment.
        let mut tries = 0;
        let link = loop {
            match GroundFrameLink::open(cfg.clone()) {
                Ok(l) => break l,
                Err(e) if tries < 100 => {
                    tries += 1;
                    eprintln!("ground link open: {e}; retrying");
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) => panic!("ground link open: {e}"),
            }
        };
        Ground {
            link,
            log: Vec::new(),
            events: Vec::new(),
        }
    }
    fn addr(&self) -> SocketAddr {
        self.link.local_addr().unwrap()
    }
    fn send(&mut self, seq: u16, name: &str, args: &[i64]) -> (Vec<u8>, PacketId) {
        let raw = tc_named(APID, seq, name, args);
        let id = self.link.send_packet(&raw).unwrap();
        (raw, id)
    }
    fn pump(&mut self, d: Duration) {
        for p in self.link.recv(d).unwrap() {
            if let Some(t) = Tm::parse(&p) {
                self.log.push(t);
            }
        }
        self.events.extend(self.link.take_events());
    }
    fn wait_for(&mut self, timeout: Duration, mut pred: impl FnMut(&Ground) -> bool) -> bool {
        let until = Instant::now() + timeout;
        while Instant::now() < until {
            if pred(self) {
                return true;
            }
            self.pump(Duration::from_millis(20));
        }
        pred(self)
    }
    fn done(&self, raw: &[u8]) -> Option<&Tm> {
        let r = request_of(raw);
        self.log
            .iter()
            .find(|t| t.request() == Some(r) && matches!(t.subservice, 2 | 4 | 6 | 7 | 8))
    }
    fn wait_done(&mut self, raw: &[u8], timeout: Duration) -> Option<Tm> {
        self.wait_for(timeout, |g| g.done(raw).is_some());
        self.done(raw).cloned()
    }
    fn active(&mut self) {
        assert!(
            self.wait_for(Duration::from_secs(10), |g| g.link.fop_state() == FopState::Active),
            "COP-1 initialised from the CLCW"
        );
    }
    /// The SPACE_LINK HK report, asked for by a one-shot request.
    fn link_hk(&mut self, seq: u16) -> Tm {
        self.log_hk_one(seq, mib::hk::sid::SPACE_LINK)
    }
    /// An HK report asked for by a one-shot request (the one generated by it: the report
    /// comes before the request's completion).
    fn log_hk_one(&mut self, seq: u16, sid: u16) -> Tm {
        let (raw, _) = self.send(seq, "HK_ONE_SHOT", &[sid as i64]);
        let done = self.wait_done(&raw, Duration::from_secs(10)).expect("HK_ONE_SHOT done");
        let at = self.log.iter().position(|t| t.raw == done.raw).unwrap();
        self.log[..at]
            .iter()
            .rev()
            .find(|t| t.sid() == Some(sid))
            .cloned()
            .expect("the HK report")
    }
}

/// Every TM packet the obsw sent (its `--tm-log`).
fn tm_log(path: &Path) -> Vec<Tm> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| {
            let b: Vec<u8> = (0..l.len() / 2)
                .map(|i| u8::from_str_radix(&l[2 * i..2 * i + 2], 16).unwrap())
                .collect();
            Tm::parse(&b)
        })
        .collect()
}

/// How many TM[1,`sub`] the obsw sent for the TC `raw`.
fn reports(log: &[Tm], raw: &[u8], sub: u8) -> usize {
    let r = request_of(raw);
    log.iter()
        .filter(|t| t.service == 1 && t.subservice == sub && t.request() == Some(r))
        .count()
}

/// Sends `frame` to the obsw from a fresh socket.
fn inject(to: SocketAddr, frame: &[u8]) {
    UdpSocket::bind("127.0.0.1:0").unwrap().send_to(frame, to).unwrap();
}

/// An AD frame with `packet`, N(S) `ns`, protected by SPI `spi` under `key` with IV `iv`.
fn forged(spi: u16, key: &[u8; 32], iv: u128, ns: u8, packet: &[u8]) -> Vec<u8> {
    let mut sa = TxSa::resume(spi, key, iv);
    let mut buf = [0u8; 1024];
    let repr = TcRepr {
        frame_type: FrameType::Ad,
        scid: mib::link::SCID,
        vcid: 0,
        seq: ns,
        data_len: 0,
    };
    let n = build_tc(&mut sa, &mut MemoryIvStore::default(), repr, packet, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn fast_fop() -> FopConfig {
    FopConfig {
        t1_ms: 500,
        ..FopConfig::mission()
    }
}

// verifies: LINK-HOST-01, LINK-GND-01
#[test]
fn ping_and_reconfigure_over_frames_with_the_bare_link_alongside() {
    let d = Dir::new("basic");
    let frame = free_udp();
    let mut g = Ground::open(&d, frame, SocketAddr::from(([127, 0, 0, 1], 0)), fast_fop());
    let o = obsw_with(&d, frame, g.addr(), "tm.log", &["--lab-bare-packets"]);
    g.active();
    let (ping, _) = g.send(1, "PING", &[]);
    let done = g.wait_done(&ping, Duration::from_secs(10)).expect("PING completes");
    assert_eq!(done.subservice, 7);
    let (mode, _) = g.send(
        2,
        "MODE_SET",
        &[
            mib::modes::node::ROBOT as i64,
            mib::modes::robot_mode::OPERATIONAL as i64,
            0,
        ],
    );
    assert_eq!(
        g.wait_done(&mode, Duration::from_secs(30)).map(|t| t.subservice),
        Some(7)
    );
    // Xneg (0) -> Xpos (1).
    let (reconf, _) = g.send(3, "RECONFIGURE", &[0, 1]);
    let done = g
        .wait_done(&reconf, Duration::from_secs(60))
        .expect("RECONFIGURE completes");
    assert_eq!(done.subservice, 7, "failure {:?}", done.failure_code());
    let steps: Vec<u8> = g
        .log
        .iter()
        .filter(|t| t.request() == Some(request_of(&reconf)))
        .map(|t| t.subservice)
        .collect();
    assert_eq!(steps, vec![1, 3, 5, 5, 7], "every stage came down in TM frames");
    assert_eq!(g.link.pending(), 0, "every TC acknowledged by COP-1");
    // The bare-packet UDP link works as before, at the same time.
    let mut c = e2e_tests::Client::udp(&o);
    c.subscribe();
    let hk = g.link_hk(4);
    assert_eq!(hk.hk(pid::LINK_AD_ACCEPTED), Some(4), "{hk:?}");
    assert!(hk.hk(pid::LINK_TM_FRAMES).unwrap() > 0);
    assert!(
        hk.hk(pid::LINK_TM_IDLE_FRAMES).unwrap() > 0,
        "idle frames carry the CLCW"
    );
    assert_eq!(hk.hk(pid::LINK_REJ_BAD_MAC), Some(0));
}

// verifies: LINK-HOST-02, LINK-E2E-02, FILE-BD-01
#[test]
fn attack_frames_are_counted_and_never_executed() {
    let d = Dir::new("attacks");
    let frame = free_udp();
    let mut g = Ground::open(&d, frame, SocketAddr::from(([127, 0, 0, 1], 0)), fast_fop());
    let o = obsw(&d, frame, g.addr(), "tm.log");
    g.active();
    g.link.capture(true);
    let (ping, _) = g.send(1, "PING", &[]);
    assert!(g.wait_done(&ping, Duration::from_secs(10)).is_some());
    let captured = g.link.take_captured();
    g.link.capture(false);
    let nr = g.link.clcw().unwrap().report_value;
    let iv = g.link.tc_next_iv() + 100;
    // Each attack carries its own PING (sequence counts 1000+), so an execution would show.
    let attack = |i: u16| tc_named(APID, 1000 + i, "PING", &[]);
    // 1. Wrong key.
    inject(frame, &forged(TC_SPIS[0], &TEST_KEY_TC_B, iv, nr, &attack(1)));
    // 2. The captured frame replayed.
    inject(frame, &captured[0]);
    // 3. A fresh authentic frame with one bit flipped, the CRC recomputed.
    let mut f = forged(TC_SPIS[0], &TEST_KEY_TC_A, iv + 1, nr, &attack(3));
    f[30] ^= 0x10;
    mmic_link::fecf::seal(&mut f);
    inject(frame, &f);
    // 4. A length field beyond the datagram (CRC recomputed).
    let mut f = forged(TC_SPIS[0], &TEST_KEY_TC_A, iv + 2, nr, &attack(4));
    let claimed = (f.len() + 40 - 1) as u16;
    f[2] = (f[2] & 0xFC) | (claimed >> 8) as u8;
    f[3] = claimed as u8;
    mmic_link::fecf::seal(&mut f);
    inject(frame, &f);
    // 5. An unknown SPI.
    inject(frame, &forged(9, &TEST_KEY_TC_A, iv + 3, nr, &attack(5)));
    // 6. Bare packets on the frame port.
    for i in 0..3 {
        inject(frame, &attack(60 + i));
    }
    // 7. Bare packets on the bare-packet port, which is off without --lab-bare-packets.
    let bare = UdpSocket::bind("127.0.0.1:0").unwrap();
    for i in 0..3 {
        bare.send_to(&attack(70 + i), o.udp).unwrap();
    }
    // 8. A flood of control frames in clear (Unlock: anyone can send it): refused in Open,
    // where it cannot help, each counted.
    let mut unlock = [0u8; 16];
    let k = mmic_link::tc::ControlCommand::Unlock
        .build_frame(mib::link::SCID, 0, &mut unlock)
        .unwrap();
    for _ in 0..50 {
        inject(frame, &unlock[..k]);
    }
    // 10. Authentic frames as BD (bypass) frames with a command: an AD frame whose bypass
    // flag (not covered by the MAC) is flipped on the path, and one the key holder built.
    let mut f = forged(TC_SPIS[0], &TEST_KEY_TC_A, iv + 4, nr, &attack(10));
    f[0] |= 0x20;
    mmic_link::fecf::seal(&mut f);
    inject(frame, &f);
    let mut sa = TxSa::resume(TC_SPIS[0], &TEST_KEY_TC_A, iv + 5);
    let mut buf = [0u8; 1024];
    let repr = TcRepr {
        frame_type: FrameType::Bd,
        scid: mib::link::SCID,
        vcid: 0,
        seq: 0,
        data_len: 0,
    };
    let n = build_tc(&mut sa, &mut MemoryIvStore::default(), repr, &attack(11), &mut buf).unwrap();
    inject(frame, &buf[..n]);
    // 9. A junk flood.
    let mut x: u64 = 0x2545_F491_4F6C_DD1D;
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    for _ in 0..2000 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let len = 1 + (x % 1100) as usize;
        let junk: Vec<u8> = (0..len).map(|i| (x >> (i % 57)) as u8 ^ i as u8).collect();
        let _ = sock.send_to(&junk, frame);
        if x.is_multiple_of(16) {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    g.pump(Duration::from_millis(500));
    // The real ground is unaffected: its next command executes.
    let (ping2, _) = g.send(2, "PING", &[]);
    assert_eq!(
        g.wait_done(&ping2, Duration::from_secs(10)).map(|t| t.subservice),
        Some(7)
    );
    let hk = g.link_hk(3);
    let v = |p| hk.hk(p).unwrap_or(-1);
    assert!(v(pid::LINK_REJ_BAD_MAC) >= 2, "wrong key + flipped bit: {hk:?}");
    assert!(v(pid::LINK_REJ_REPLAY) >= 1, "replay");
    assert!(v(pid::LINK_REJ_BAD_LENGTH) >= 1, "length");
    assert!(v(pid::LINK_REJ_UNKNOWN_SPI) >= 1, "SPI");
    assert!(v(pid::LINK_REJ_BARE_PACKET) >= 3, "bare packets");
    assert_eq!(v(pid::LINK_REJ_BD_CONTENT), 2, "commands in BD frames");
    assert_eq!(v(pid::LINK_BD_ACCEPTED), 0);
    // Junk: CRC failures (junk that looks like a BC frame too: the CRC comes before any
    // control-frame counting), a few with a bad length or header. A loaded machine's kernel
    // may drop some of the flood before the obsw sees it: 90 % must be counted.
    let junk = v(pid::LINK_REJ_BAD_CRC) + v(pid::LINK_REJ_BAD_HEADER) + v(pid::LINK_REJ_BAD_LENGTH);
    assert!(junk >= 1800, "junk: {junk}");
    assert!(v(pid::LINK_REJ_BAD_CRC) >= 1500, "junk: {}", v(pid::LINK_REJ_BAD_CRC));
    assert!(
        bare.set_read_timeout(Some(Duration::from_millis(200))).is_ok() && bare.recv(&mut [0u8; 64]).is_err(),
        "no TM to a bare-packet sender"
    );
    let io = g.log_hk_one(4, mib::hk::sid::PLATFORM_IO);
    assert_eq!(
        io.hk(pid::IO_TC_DROPPED),
        Some(3),
        "the bare packets dropped and counted"
    );
    // The 50 Unlocks refused (FARM-1 is Open), no junk among the control frames; the
    // ground's own Set V(R) executed.
    let (ctl, refused) = (v(pid::LINK_CONTROL_FRAMES), v(pid::LINK_REJ_CONTROL_STATE));
    assert!((1..=3).contains(&ctl), "control frames executed: {ctl}");
    assert!((45..=50).contains(&refused), "refused by FARM-1's state: {refused}");
    // Ping, ping, HK request: nothing else got through.
    assert_eq!(v(pid::LINK_AD_ACCEPTED), 3);
    assert_eq!(v(pid::LINK_PACKETS), 3);
    std::thread::sleep(Duration::from_millis(300));
    let sent = tm_log(&d.p("tm.log"));
    for i in 0..100 {
        let a = attack(i);
        assert_eq!(
            reports(&sent, &a, 1) + reports(&sent, &a, 2),
            0,
            "attack {i} reached the OBSW"
        );
    }
    let rejected_events: Vec<&Tm> = sent
        .iter()
        .filter(|t| t.event_id() == Some(eid::LINK_FRAME_REJECTED))
        .collect();
    let reasons: std::collections::BTreeSet<u8> = rejected_events.iter().map(|t| t.data[2]).collect();
    for r in [5u8, 6, 11, 12, 13, 4, 22, 23] {
        assert!(reasons.contains(&r), "LINK_FRAME_REJECTED reason {r}: {reasons:?}");
    }
    assert!(
        rejected_events.len() < 200,
        "events throttled: {} for 2000+ refusals",
        rejected_events.len()
    );
}

// verifies: LINK-GND-01, LINK-E2E-01
#[test]
fn a_restarted_ground_resynchronises_and_neither_repeats_nor_skips() {
    let d = Dir::new("restart");
    let frame = free_udp();
    let mut g = Ground::open(&d, frame, SocketAddr::from(([127, 0, 0, 1], 0)), fast_fop());
    let listen = g.addr();
    let _o = obsw(&d, frame, listen, "tm.log");
    g.active();
    let tcs: Vec<Vec<u8>> = (1..=16).map(|s| tc_named(APID, s, "PING", &[])).collect();
    for t in &tcs {
        g.link.send_packet(t).unwrap();
    }
    // Until some are acknowledged, then the ground dies (no goodbye), keeping its record
    // of which N(S) each TC was transmitted with.
    let mut ns_of: BTreeMap<u8, usize> = BTreeMap::new();
    let until = Instant::now() + Duration::from_secs(20);
    let mut acked = 0;
    while acked < 6 && Instant::now() < until {
        g.pump(Duration::from_millis(1));
        for e in std::mem::take(&mut g.events) {
            match e {
                Event::Transmitted { id, ns, .. } => {
                    ns_of.insert(ns, id as usize);
                }
                Event::Acknowledged { .. } => acked += 1,
                _ => {}
            }
        }
    }
    assert!(acked >= 6);
    drop(g);
    // The new ground on the same address, with the same keys and counter file.
    let mut g = Ground::open(&d, frame, listen, fast_fop());
    g.active();
    let nr = g.link.clcw().unwrap().report_value;
    let resume = ns_of
        .get(&nr)
        .copied()
        .unwrap_or_else(|| ns_of.values().max().map_or(0, |m| m + 1));
    assert!((6..=16).contains(&resume), "resume at {resume}");
    for t in &tcs[resume..] {
        g.link.send_packet(t).unwrap();
    }
    assert!(g.wait_for(Duration::from_secs(30), |g| g.link.pending() == 0));
    let hk = g.link_hk(100);
    std::thread::sleep(Duration::from_millis(300));
    let sent = tm_log(&d.p("tm.log"));
    for (i, t) in tcs.iter().enumerate() {
        assert_eq!(reports(&sent, t, 1), 1, "TC {i}: accepted once");
        assert_eq!(reports(&sent, t, 7), 1, "TC {i}: completed once");
    }
    assert_eq!(
        hk.hk(pid::LINK_AD_ACCEPTED),
        Some(17),
        "16 TCs and the HK request, no frame twice"
    );
}

// verifies: LINK-E2E-01
#[test]
fn through_the_lossy_relay_every_tc_executes_exactly_once() {
    let d = Dir::new("relay");
    let frame = free_udp();
    let faults = Faults::new(0.2, 0.05, 0.05);
    let mut relay = Relay::start(RelayConfig::both_ways(frame, frame, faults, 22)).unwrap();
    let mut g = Ground::open(&d, relay.udp, SocketAddr::from(([127, 0, 0, 1], 0)), fast_fop());
    let tm_in = relay
        .add_downlink_route(SocketAddr::from(([127, 0, 0, 1], 0)), g.addr())
        .unwrap();
    let _o = obsw(&d, frame, tm_in, "tm.log");
    g.active();
    let tcs: Vec<Vec<u8>> = (1..=30).map(|s| tc_named(APID, s, "PING", &[])).collect();
    let t0 = Instant::now();
    for t in &tcs {
        g.link.send_packet(t).unwrap();
    }
    assert!(
        g.wait_for(Duration::from_secs(90), |g| g.link.pending() == 0),
        "all acknowledged: {:?}",
        g.link.counters
    );
    let took = t0.elapsed();
    std::thread::sleep(Duration::from_millis(300));
    let sent = tm_log(&d.p("tm.log"));
    for (i, t) in tcs.iter().enumerate() {
        assert_eq!(reports(&sent, t, 1), 1, "TC {i}: accepted once");
        assert_eq!(reports(&sent, t, 7), 1, "TC {i}: completed once");
    }
    let up = relay.counts.up.snapshot();
    let down = relay.counts.down.snapshot();
    assert!(up.dropped > 0 && up.corrupted + up.duplicated > 0, "{up:?}");
    assert!(down.dropped > 0, "{down:?}");
    let unknown = g.events.iter().filter(|e| matches!(e, Event::Unknown { .. })).count();
    assert_eq!(unknown, 0);
    eprintln!(
        "30 TCs through 20/5/5 %: {took:?}, {} retransmissions, {} alerts; relay up {up:?} down {down:?}",
        g.link.counters.retransmissions, g.link.counters.alerts
    );
}

// verifies: LINK-HOST-03
#[test]
fn counters_survive_an_obsw_restart_no_tm_iv_repeats_and_no_tc_replays() {
    let d = Dir::new("ivs");
    let frame = free_udp();
    let mut g = Ground::open(&d, frame, SocketAddr::from(([127, 0, 0, 1], 0)), fast_fop());
    let listen = g.addr();
    // Run 1: a ping whose frame is captured, TM collected through the link.
    let mut o = obsw(&d, frame, listen, "tm1.log");
    g.active();
    g.link.capture(true);
    let (ping, _) = g.send(1, "PING", &[]);
    assert!(g.wait_done(&ping, Duration::from_secs(10)).is_some());
    let captured = g.link.take_captured();
    drop(g);
    // The TM IVs of run 1, read off the wire.
    let tm_ivs = |sock: &UdpSocket, d: Duration| -> Vec<u128> {
        let mut ivs = Vec::new();
        let until = Instant::now() + d;
        let mut b = [0u8; 2048];
        sock.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
        while Instant::now() < until {
            if let Ok(n) = sock.recv(&mut b) {
                let vc = (b[1] >> 1) & 7;
                if n == 1024 && vc == 0 {
                    assert_eq!(u16::from_be_bytes([b[6], b[7]]), TM_SPIS[0]);
                    ivs.push(mmic_link::sdls::iv_value(b[8..20].try_into().unwrap()));
                }
            }
        }
        ivs
    };
    let wire = (0..100)
        .find_map(|_| {
            UdpSocket::bind(listen)
                .map_err(|_| std::thread::sleep(Duration::from_millis(20)))
                .ok()
        })
        .expect("rebind the ground's address");
    let run1 = tm_ivs(&wire, Duration::from_millis(1500));
    assert!(!run1.is_empty(), "HK came down on VC0");
    o.kill9();
    let o2 = obsw(&d, frame, listen, "tm2.log");
    let run2 = tm_ivs(&wire, Duration::from_millis(1500));
    drop(wire);
    assert!(!run2.is_empty());
    assert!(
        run2.iter().min() > run1.iter().max(),
        "TM IVs keep increasing across the restart: run 1 up to {:?}, run 2 from {:?}",
        run1.iter().max(),
        run2.iter().min()
    );
    // The frame captured in run 1 is a replay for the restarted obsw (its FARM-1 began
    // again at V(R) = 0, so only SDLS's persisted counter stops it).
    for f in &captured {
        inject(frame, f);
    }
    let mut g = Ground::open(&d, frame, listen, fast_fop());
    g.active();
    let hk = g.link_hk(2);
    assert!(hk.hk(pid::LINK_REJ_REPLAY).unwrap() >= captured.len() as i64, "{hk:?}");
    std::thread::sleep(Duration::from_millis(300));
    let sent = tm_log(&d.p("tm2.log"));
    assert_eq!(reports(&sent, &ping, 1), 0, "the replayed PING never reached the OBSW");
    drop(o2);
}

/// Runs the independent checker (`obsw/link/tests/py/check_frames.py`, written from the
/// standards with Python `cryptography`) over `frames`; returns name -> its line.
fn python_check(d: &Dir, frames: &[(String, Vec<u8>)]) -> BTreeMap<String, String> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let py = root.join(".venv/bin/python");
    assert!(
        py.exists(),
        "{} missing: run `bash scripts/python-env.sh` first (needs cryptography)",
        py.display()
    );
    let dir = d.p("wire");
    std::fs::create_dir_all(&dir).unwrap();
    for (name, bytes) in frames {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    let hex = |k: &[u8; 32]| k.iter().map(|b| format!("{b:02x}")).collect::<String>();
    let out = std::process::Command::new(py)
        .arg(root.join("obsw/link/tests/py/check_frames.py"))
        .arg(&dir)
        .args(["--key", &format!("1={}", hex(&TEST_KEY_TC_A))])
        .args(["--key", &format!("17={}", hex(&TEST_KEY_TM_A))])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter_map(|l| l.split_once(' ').map(|(n, r)| (n.to_string(), r.to_string())))
        .collect()
}

// verifies: LINK-IND-01, LINK-HOST-01, LINK-TM-03
#[test]
fn frames_on_the_wire_verify_with_an_independent_decoder() {
    let d = Dir::new("wire");
    let frame = free_udp();
    let wire = UdpSocket::bind("127.0.0.1:0").unwrap();
    wire.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    let _o = obsw(&d, frame, wire.local_addr().unwrap(), "tm.log");
    // One AD frame by hand (FARM-1 starts at V(R) = 0, the TC key's IVs at 0).
    let ping = tc_named(APID, 7, "PING", &[]);
    let tc_frame = forged(TC_SPIS[0], &TEST_KEY_TC_A, 0, 0, &ping);
    std::thread::sleep(Duration::from_millis(300));
    inject(frame, &tc_frame);
    let mut frames = vec![("a.tc".to_string(), tc_frame)];
    let mut b = [0u8; 2048];
    // Each capture up to 80 frames of its own (HK structures report in periods of their
    // own, so at --speed 20 the first 1.5 s alone can fill 80).
    let mut capture = |frames: &mut Vec<(String, Vec<u8>)>| {
        let until = Instant::now() + Duration::from_millis(1500);
        let first = frames.len();
        while Instant::now() < until && frames.len() - first < 80 {
            if let Ok(n) = wire.recv(&mut b) {
                frames.push((format!("f{:02}.tm", frames.len()), b[..n].to_vec()));
            }
        }
    };
    capture(&mut frames);
    // A second AD frame asks the store for everything of the APID: the replay comes on the
    // replay virtual channel (VC1), the ping's reports among it.
    let replay_tc = tc_named(APID, 8, "STORE_DOWNLINK_SEQ", &[APID as i64, 0, 16383]);
    let replay_frame = forged(TC_SPIS[0], &TEST_KEY_TC_A, 1, 1, &replay_tc);
    inject(frame, &replay_frame);
    frames.push(("b.tc".to_string(), replay_frame));
    capture(&mut frames);
    let r = python_check(&d, &frames);
    assert_eq!(r.len(), frames.len());
    let tc = &r["a.tc"];
    assert!(tc.starts_with("OK ") && tc.contains("spi=1 iv=0"), "{tc}");
    let ping_hex: String = ping.iter().map(|b| format!("{b:02x}")).collect();
    assert!(tc.ends_with(&format!("data={ping_hex}")), "{tc}");
    let tm: Vec<&String> = r.iter().filter(|(n, _)| n.ends_with(".tm")).map(|(_, l)| l).collect();
    let short: Vec<&str> = tm.iter().map(|l| &l[..l.len().min(160)]).collect();
    assert!(tm.len() >= 3, "TM frames on the wire: {short:#?}");
    assert!(
        tm.iter().all(|l| l.starts_with("OK ")),
        "every TM frame verifies: {short:#?}"
    );
    // The ping's completion TM[1,7] (request ID = the TC's first 4 bytes) decrypted by
    // Python, and the CLCW acknowledging the TC frame (N(R) = 1).
    let req: String = ping[..4].iter().map(|b| format!("{b:02x}")).collect();
    assert!(
        tm.iter().any(|l| l.contains("spi=17") && l.contains(&req)),
        "a VC0 frame with the ping's reports: {short:#?}"
    );
    assert!(tm.iter().any(|l| l.contains(" nr=1 ")), "{short:#?}");
    assert!(r["b.tc"].starts_with("OK "), "{}", r["b.tc"]);
    // Realtime TM on VC0 only; the store's replay of the ping's reports on VC1.
    assert!(
        tm.iter().any(|l| l.contains(" vc=1 ") && l.contains(&req)),
        "a VC1 frame replaying the ping's reports: {short:#?}"
    );
    let replay_req: String = replay_tc[..4].iter().map(|b| format!("{b:02x}")).collect();
    assert!(
        tm.iter().any(|l| l.contains(" vc=0 ") && l.contains(&replay_req)),
        "the retrieval's own reports are realtime (VC0): {short:#?}"
    );
}
