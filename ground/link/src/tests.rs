//! The link against an in-process robot (mmic-link's `TcReceiver` and TM framer on a
//! loopback UDP socket, with seeded loss in both directions).

use super::*;
use mmic_link::downlink::{TmFramer, TmVc};
use mmic_link::rx::{RxOutcome, TcReceiver};
use mmic_link::sdls::MemoryIvStore;
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};

struct Robot {
    sock: UdpSocket,
    ground: SocketAddr,
    rx: TcReceiver<2>,
    dl: TmFramer,
    tm_sa: TxSa,
    store: MemoryIvStore,
    /// Packets executed, in order.
    executed: Vec<Vec<u8>>,
    rng: u64,
    loss: f64,
}

impl Robot {
    fn new(ground: SocketAddr, loss: f64, seed: u64) -> Robot {
        let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        sock.set_nonblocking(true).unwrap();
        let mut sas = RxSas::default();
        sas.insert(RxSa::new(TC_SPIS[0], &TEST_KEY_TC_A, ANTI_REPLAY_WINDOW))
            .unwrap();
        Robot {
            sock,
            ground,
            rx: TcReceiver::mission(sas),
            dl: TmFramer::mission(),
            tm_sa: TxSa::resume(TM_SPIS[0], &TEST_KEY_TM_A, 0),
            store: MemoryIvStore::default(),
            executed: Vec::new(),
            rng: seed | 1,
            loss,
        }
    }

    fn lose(&mut self) -> bool {
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        ((self.rng >> 11) as f64 / (1u64 << 53) as f64) < self.loss
    }

    /// Takes waiting TC frames, answers each with a TM frame (echo of the packet) or an
    /// idle frame carrying the CLCW.
    fn step(&mut self) {
        let mut buf = [0u8; 2048];
        while let Ok((n, _)) = self.sock.recv_from(&mut buf) {
            if self.lose() {
                continue;
            }
            let mut echoes = Vec::new();
            if let RxOutcome::Accepted { packets, .. } = self.rx.receive(&mut self.store, &mut buf[..n], true) {
                for p in packets {
                    self.executed.push(p.to_vec());
                    echoes.push(p.to_vec());
                }
            }
            let clcw = self.rx.farm.clcw();
            let mut frames = Vec::new();
            for p in echoes {
                self.dl
                    .send(TmVc::Realtime, &p, clcw, &mut self.tm_sa, &mut self.store, |f| {
                        frames.push(f.to_vec())
                    })
                    .unwrap();
            }
            self.dl
                .flush(TmVc::Realtime, clcw, &mut self.tm_sa, &mut self.store, |f| {
                    frames.push(f.to_vec())
                })
                .unwrap();
            if frames.is_empty() {
                let mut f = [0u8; 1024];
                self.dl.idle(clcw, &mut f);
                frames.push(f.to_vec());
            }
            for f in frames {
                if !self.lose() {
                    let _ = self.sock.send_to(&f, self.ground);
                }
            }
        }
        let mut f = [0u8; 1024];
        self.dl.idle(self.rx.farm.clcw(), &mut f);
        if !self.lose() {
            let _ = self.sock.send_to(&f, self.ground);
        }
    }
}

fn state(name: &str) -> PathBuf {
    let p = std::env::temp_dir().join(format!("ground-link-{}-{name}.state", std::process::id()));
    let _ = std::fs::remove_file(&p);
    p
}

fn link(robot: SocketAddr, listen: SocketAddr, state: &Path) -> GroundFrameLink {
    GroundFrameLink::open(Config {
        robot,
        listen,
        tc_spi: 1,
        tc_key: TEST_KEY_TC_A,
        tm_key: TEST_KEY_TM_A,
        tm_spare_key: None,
        tm_security: TmSecurity::Encrypt,
        state: state.into(),
        fop: FopConfig {
            t1_ms: 40,
            tx_limit: 20,
            ..FopConfig::mission()
        },
        settle_ms: 30,
    })
    .unwrap()
}

fn packet(i: u16) -> Vec<u8> {
    // A TC space packet header (APID 0x101, sequence count i) and 4 data bytes.
    let mut p = vec![0x18, 0x01, 0xC0 | (i >> 8) as u8, i as u8, 0x00, 0x03];
    p.extend_from_slice(&i.to_be_bytes());
    p.extend_from_slice(&[0xAA, 0x55]);
    p
}

/// Runs ground and robot (time by the link's own clock) until `done` or 20 s.
fn run(g: &mut GroundFrameLink, r: &mut Robot, mut done: impl FnMut(&GroundFrameLink, &Robot) -> bool) -> Vec<Vec<u8>> {
    let mut got = Vec::new();
    let until = Instant::now() + Duration::from_secs(20);
    while !done(g, r) && Instant::now() < until {
        r.step();
        got.extend(g.poll(g.now_ms()).unwrap());
        std::thread::sleep(Duration::from_millis(2));
    }
    got
}

// verifies: LINK-GND-01
#[test]
fn lossy_link_delivers_each_packet_exactly_once_and_in_order() {
    let st = state("lossy");
    let gsock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let gaddr = gsock.local_addr().unwrap();
    drop(gsock);
    let mut r = Robot::new(gaddr, 0.2, 7);
    let mut g = link(r.sock.local_addr().unwrap(), gaddr, &st);
    let want: Vec<Vec<u8>> = (0..60).map(packet).collect();
    for p in &want {
        g.send_packet(p).unwrap();
    }
    let echoed = run(&mut g, &mut r, |g, _| g.pending() == 0);
    let ev = g.take_events();
    assert_eq!(
        g.pending(),
        0,
        "all acknowledged: {:?} {:?} {:?}",
        g.counters,
        g.fop_state(),
        ev
    );
    assert_eq!(r.executed, want, "each executed once, in order");
    assert!(g.counters.retransmissions > 0, "the loss made COP-1 work");
    assert!(echoed.iter().all(|p| want.contains(p)), "only real packets came back");
    let acked = ev.iter().filter(|e| matches!(e, Event::Acknowledged { .. })).count();
    assert_eq!(acked, 60);
    let _ = std::fs::remove_file(&st);
}

/// A class 2 CFDP file data packet (ground 0 to robot 1, offset `i`) of 8 data bytes.
fn file_data(i: u16) -> Vec<u8> {
    let mut p = vec![0x10, 0xF0, 0xC0 | (i >> 8) as u8, i as u8, 0, 0];
    p.extend([0x30, 0, 20, 0x11, 0, 0, 0, 7, 0, 1, 0, 0]);
    p.extend(i.to_be_bytes());
    p.extend([0xFD; 8]);
    let n = (p.len() - 7) as u16;
    p[4..6].copy_from_slice(&n.to_be_bytes());
    p
}

// verifies: FILE-BD-01, LINK-GND-01
#[test]
fn bypass_frames_go_out_at_once_beside_cop1_and_only_with_file_data() {
    let st = state("bypass");
    let gsock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let gaddr = gsock.local_addr().unwrap();
    drop(gsock);
    let mut r = Robot::new(gaddr, 0.0, 3);
    let mut g = link(r.sock.local_addr().unwrap(), gaddr, &st);
    let cmds: Vec<Vec<u8>> = (0..20).map(packet).collect();
    let data: Vec<Vec<u8>> = (0..20).map(file_data).collect();
    assert!(
        matches!(g.send_bypass(&cmds[0]), Err(LinkError::NotBypass)),
        "a command never goes BD"
    );
    for (c, d) in cmds.iter().zip(&data) {
        g.send_packet(c).unwrap();
        g.send_bypass(d).unwrap();
    }
    assert_eq!(
        g.counters.bd_frames_sent, 20,
        "sent at once, before COP-1 is even initialised"
    );
    run(&mut g, &mut r, |g, _| g.pending() == 0);
    assert_eq!(g.pending(), 0, "{:?}", g.counters);
    let executed_cmds: Vec<_> = r.executed.iter().filter(|p| p[0] == 0x18).cloned().collect();
    let executed_data: Vec<_> = r.executed.iter().filter(|p| p[0] == 0x10).cloned().collect();
    assert_eq!(executed_cmds, cmds, "the AD packets once each, in order");
    assert_eq!(executed_data, data, "the BD frames, SDLS-protected under the same SA");
    assert_eq!((r.rx.counters.bd_accepted, r.rx.counters.rejected()), (20, 0));
    assert_eq!(g.counters.retransmissions, 0, "BD frames leave FOP-1's window alone");
    let _ = std::fs::remove_file(&st);
}

// verifies: LINK-FOP-T1-01, LINK-GND-01
#[test]
fn mission_t1_adapts_to_the_loopback_round_trip_and_the_lossy_link_still_delivers_once() {
    use mib::link::cop1::{FOP_T1_MIN_MS, FOP_T1_MS};
    let st = state("adaptive-t1");
    let gsock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let gaddr = gsock.local_addr().unwrap();
    drop(gsock);
    let mut r = Robot::new(gaddr, 0.0, 5);
    let mut g = link(r.sock.local_addr().unwrap(), gaddr, &st);
    // The link() helper's fixed 40 ms T1 replaced by the mission's adaptive one.
    g.fop = Fop::new(mib::link::tc_vc::COMMAND, FopConfig::mission());
    assert_eq!(g.fop_t1_ms(), FOP_T1_MS, "no sample yet: the upper bound");
    let want: Vec<Vec<u8>> = (0..40).map(packet).collect();
    for p in &want[..10] {
        g.send_packet(p).unwrap();
    }
    run(&mut g, &mut r, |g, _| g.pending() == 0);
    assert_eq!(g.pending(), 0, "{:?}", g.counters);
    let srtt = g.srtt_ms().expect("round trips measured");
    assert!(srtt < FOP_T1_MIN_MS, "a loopback round trip: {srtt} ms");
    assert_eq!(g.fop_t1_ms(), FOP_T1_MIN_MS, "clamped to the lower bound");
    // 20 % loss both ways: every packet still once and in order, T1 within its bounds.
    r.loss = 0.2;
    for p in &want[10..] {
        g.send_packet(p).unwrap();
    }
    run(&mut g, &mut r, |g, _| g.pending() == 0);
    assert_eq!(g.pending(), 0, "{:?} {:?}", g.counters, g.fop_state());
    assert_eq!(r.executed, want, "each executed once, in order");
    assert!(g.counters.retransmissions > 0, "the loss made COP-1 work");
    assert!((FOP_T1_MIN_MS..=FOP_T1_MS).contains(&g.fop_t1_ms()));
    let _ = std::fs::remove_file(&st);
}

// verifies: LINK-GND-01, LINK-FOP-02
#[test]
fn a_restarted_ground_resynchronises_without_repeat_or_skip() {
    let st = state("restart");
    let gsock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let gaddr = gsock.local_addr().unwrap();
    drop(gsock);
    let mut r = Robot::new(gaddr, 0.15, 11);
    let want: Vec<Vec<u8>> = (0..40).map(packet).collect();
    let mut g = link(r.sock.local_addr().unwrap(), gaddr, &st);
    for p in &want {
        g.send_packet(p).unwrap();
    }
    // Run until about half are on board, then "kill" the ground (drop, no goodbye),
    // keeping its record of N(S) per packet.
    let mut ns_of: BTreeMap<u8, PacketId> = BTreeMap::new();
    let until = Instant::now() + Duration::from_secs(20);
    while r.executed.len() < 20 && Instant::now() < until {
        r.step();
        g.poll(g.now_ms()).unwrap();
        for e in g.take_events() {
            if let Event::Transmitted { id, ns, .. } = e {
                ns_of.insert(ns, id);
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    drop(g);
    // The new ground: same keys and state file, no COP-1 memory.
    let mut g = link(r.sock.local_addr().unwrap(), gaddr, &st);
    run(&mut g, &mut r, |g, _| g.fop_state() == FopState::Active);
    assert_eq!(g.fop_state(), FopState::Active);
    let nr = g.clcw().unwrap().report_value;
    let resume = ns_of
        .get(&nr)
        .map(|&id| id as usize)
        .unwrap_or_else(|| ns_of.values().max().map_or(0, |&m| m as usize + 1));
    for p in &want[resume..] {
        g.send_packet(p).unwrap();
    }
    run(&mut g, &mut r, |g, _| g.pending() == 0);
    assert_eq!(r.executed, want, "no repeat, no skip");
    let _ = std::fs::remove_file(&st);
}

// verifies: LINK-GND-01
#[test]
fn bad_packets_and_shared_keys_are_refused() {
    let st = state("bad");
    let a = SocketAddr::from(([127, 0, 0, 1], 0));
    let mut g = link(a, a, &st);
    assert!(matches!(
        g.send_packet(&[1, 2, 3]),
        Err(LinkError::PacketLength { len: 3, .. })
    ));
    assert!(matches!(
        g.send_packet(&vec![0u8; MAX_PACKET_LEN + 1]),
        Err(LinkError::PacketLength { .. })
    ));
    assert_eq!(g.pending(), 0);
    let e = GroundFrameLink::open(Config {
        robot: a,
        listen: a,
        tc_spi: 1,
        tc_key: TEST_KEY_TC_A,
        tm_key: TEST_KEY_TC_A,
        tm_spare_key: None,
        tm_security: TmSecurity::Encrypt,
        state: st.clone(),
        fop: FopConfig::mission(),
        settle_ms: RESYNC_SETTLE_MS,
    })
    .unwrap_err();
    assert!(matches!(e, LinkError::SameKey));
    // The spare TM key counts too, and a TC SPI must be one of the mission's.
    let cfg = Config {
        robot: a,
        listen: a,
        tc_spi: 1,
        tc_key: TEST_KEY_TC_A,
        tm_key: TEST_KEY_TM_A,
        tm_spare_key: Some(TEST_KEY_TC_A),
        tm_security: TmSecurity::Encrypt,
        state: st.clone(),
        fop: FopConfig::mission(),
        settle_ms: RESYNC_SETTLE_MS,
    };
    assert!(matches!(GroundFrameLink::open(cfg.clone()), Err(LinkError::SameKey)));
    let e = GroundFrameLink::open(Config {
        tc_spi: 17,
        tm_spare_key: None,
        ..cfg
    })
    .unwrap_err();
    assert!(matches!(e, LinkError::NotTcSpi(17)));
    assert!(!e.to_string().contains("MMIC"), "never the key");
    let _ = std::fs::remove_file(&st);
}

// verifies: LINK-GND-01, LINK-PERSIST-02
#[test]
fn a_robot_whose_farm_restarts_at_zero_is_followed_after_an_alert() {
    // A robot that does not persist FARM-1 (V(R) back to 0 after its restart; SDLS
    // counters kept): the ground's next frames are out of its window; FOP-1 raises an
    // alert, the link re-initialises from the CLCW and the new packets are delivered once.
    let st = state("robot-restart");
    let gsock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let gaddr = gsock.local_addr().unwrap();
    drop(gsock);
    let mut r = Robot::new(gaddr, 0.0, 3);
    let mut g = link(r.sock.local_addr().unwrap(), gaddr, &st);
    for i in 0..5 {
        g.send_packet(&packet(i)).unwrap();
    }
    run(&mut g, &mut r, |g, _| g.pending() == 0);
    assert_eq!(r.executed.len(), 5);
    r.rx.farm = mmic_link::farm::Farm::mission();
    for i in 5..10 {
        g.send_packet(&packet(i)).unwrap();
    }
    run(&mut g, &mut r, |g, _| g.pending() == 0);
    let ev = g.take_events();
    assert_eq!(g.pending(), 0, "{:?} {:?} {ev:?}", g.counters, g.fop_state());
    assert_eq!(r.executed, (0..10).map(packet).collect::<Vec<_>>());
    assert!(g.counters.alerts >= 1);
    let _ = std::fs::remove_file(&st);
}
