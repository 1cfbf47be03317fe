//! The link over a byte stream (a Unix socket pair standing in for the serial line)
//! against an in-process robot that frames as board A does (`mmic_link::stream`), with
//! junk bytes and corrupted bytes injected both ways.

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;

use super::*;
use mmic_link::downlink::{TmFramer, TmVc};
use mmic_link::rx::{RxOutcome, TcReceiver};
use mmic_link::sdls::MemoryIvStore;
use mmic_link::stream::{encode, encoded_len, Deframer};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};

struct StreamRobot {
    s: UnixStream,
    de: Box<Deframer<{ TC_MAX_LEN }>>,
    rx: TcReceiver<2>,
    dl: TmFramer,
    tm_sa: TxSa,
    store: MemoryIvStore,
    executed: Vec<Vec<u8>>,
    rng: u64,
    /// Bytes written so far; junk goes in after every `junk_every` TM frames.
    frames_out: u64,
    junk_every: u64,
    /// Every `flip_every`-th TC byte received is flipped (a noisy line; 0: none).
    flip_every: u64,
    bytes_in: u64,
}

impl StreamRobot {
    fn rand(&mut self) -> u64 {
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        self.rng
    }

    fn write_frame(&mut self, f: &[u8]) {
        let mut enc = vec![0u8; encoded_len(f.len())];
        let n = encode(f, &mut enc).unwrap();
        self.frames_out += 1;
        if self.junk_every > 0 && self.frames_out.is_multiple_of(self.junk_every) {
            // Junk between frames: bytes without a delimiter, ended by the next frame's.
            let junk: Vec<u8> = (0..37).map(|_| (self.rand() as u8) | 1).collect();
            self.s.write_all(&junk).unwrap();
        }
        self.s.write_all(&enc[..n]).unwrap();
    }

    fn step(&mut self) {
        let mut buf = [0u8; 4096];
        let mut frames = Vec::new();
        loop {
            match self.s.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => {
                    for b in &mut buf[..n] {
                        self.bytes_in += 1;
                        if self.flip_every > 0 && self.bytes_in % self.flip_every == self.flip_every / 2 {
                            *b ^= 0x10;
                        }
                    }
                    self.de.feed(&buf[..n], |r| {
                        if let Ok(f) = r {
                            frames.push(f.to_vec());
                        }
                    });
                }
                Err(_) => break,
            }
        }
        let mut out = Vec::new();
        for mut f in frames {
            let mut echoes = Vec::new();
            if let RxOutcome::Accepted { packets, .. } = self.rx.receive(&mut self.store, &mut f, true) {
                for p in packets {
                    self.executed.push(p.to_vec());
                    echoes.push(p.to_vec());
                }
            }
            let clcw = self.rx.farm.clcw();
            for p in echoes {
                self.dl
                    .send(TmVc::Realtime, &p, clcw, &mut self.tm_sa, &mut self.store, |f| {
                        out.push(f.to_vec())
                    })
                    .unwrap();
            }
            self.dl
                .flush(TmVc::Realtime, clcw, &mut self.tm_sa, &mut self.store, |f| {
                    out.push(f.to_vec())
                })
                .unwrap();
        }
        let mut idle = [0u8; 1024];
        self.dl.idle(self.rx.farm.clcw(), &mut idle);
        out.push(idle.to_vec());
        for f in out {
            self.write_frame(&f);
        }
    }
}

fn pair(junk_every: u64, flip_every: u64, seed: u64) -> (GroundFrameLink, StreamRobot) {
    let (a, b) = UnixStream::pair().unwrap();
    b.set_nonblocking(true).unwrap();
    let st = std::env::temp_dir().join(format!("ground-link-stream-{}-{seed}.state", std::process::id()));
    let _ = std::fs::remove_file(&st);
    let cfg = Config {
        robot: "127.0.0.1:9".parse().unwrap(),
        listen: "127.0.0.1:0".parse().unwrap(),
        tc_spi: 1,
        tc_key: TEST_KEY_TC_A,
        tm_key: TEST_KEY_TM_A,
        tm_spare_key: None,
        tm_security: TmSecurity::Encrypt,
        state: st,
        fop: FopConfig {
            t1_ms: 60,
            tx_limit: 20,
            ..FopConfig::mission()
        },
        settle_ms: 30,
    };
    let g = GroundFrameLink::open_port(cfg, Port::from_unix(a).unwrap()).unwrap();
    let mut sas = RxSas::default();
    sas.insert(RxSa::new(TC_SPIS[0], &TEST_KEY_TC_A, ANTI_REPLAY_WINDOW))
        .unwrap();
    let r = StreamRobot {
        s: b,
        de: Box::default(),
        rx: TcReceiver::mission(sas),
        dl: TmFramer::mission(),
        tm_sa: TxSa::resume(TM_SPIS[0], &TEST_KEY_TM_A, 0),
        store: MemoryIvStore::default(),
        executed: Vec::new(),
        rng: seed | 1,
        frames_out: 0,
        junk_every,
        flip_every,
        bytes_in: 0,
    };
    (g, r)
}

fn packet(i: u16) -> Vec<u8> {
    let mut p = vec![0x18, 0x01, 0xC0 | (i >> 8) as u8, i as u8, 0x00, 0x03];
    p.extend_from_slice(&i.to_be_bytes());
    p.extend_from_slice(&[0xAA, 0x55]);
    p
}

fn run(g: &mut GroundFrameLink, r: &mut StreamRobot, n: usize) -> Vec<Vec<u8>> {
    let mut echoed = Vec::new();
    let until = Instant::now() + Duration::from_secs(20);
    while (g.pending() > 0 || echoed.len() < n) && Instant::now() < until {
        r.step();
        echoed.extend(g.recv(Duration::from_millis(3)).unwrap());
    }
    echoed
}

// verifies: LINK-STREAM-03
#[test]
fn over_a_byte_stream_each_packet_arrives_once_in_order_and_the_framing_is_shared() {
    let (mut g, mut r) = pair(0, 0, 3);
    let want: Vec<Vec<u8>> = (0..40).map(packet).collect();
    for p in &want {
        g.send_packet(p).unwrap();
    }
    let echoed = run(&mut g, &mut r, want.len());
    assert_eq!(r.executed, want, "each packet executed once, in order");
    assert_eq!(echoed, want, "every TM echo read back through the stream");
    assert_eq!(g.counters.stream.dropped(), 0);
    assert_eq!(g.counters.stream.garbage_bytes, 0);
    assert!(g.counters.stream.frames > 40, "{:?}", g.counters.stream);
    assert!(g.local_addr().is_err(), "no UDP address on a stream link");
}

// verifies: LINK-STREAM-02, LINK-STREAM-03
#[test]
fn junk_and_bit_errors_on_the_stream_are_counted_and_cop1_still_delivers_exactly_once() {
    // Junk before every 5th TM frame; 1 TC byte in 997 flipped on its way up.
    let (mut g, mut r) = pair(5, 997, 11);
    let want: Vec<Vec<u8>> = (0..60).map(packet).collect();
    for p in &want {
        g.send_packet(p).unwrap();
    }
    let echoed = run(&mut g, &mut r, want.len());
    assert_eq!(r.executed, want, "each packet executed once, in order");
    assert_eq!(echoed.len(), want.len());
    let c = g.counters.stream;
    assert!(c.corrupt > 0 && c.garbage_bytes >= 37, "the junk was counted: {c:?}");
    let rc = r.rx.counters;
    let refused = rc.bad_crc + rc.bad_length + rc.bad_header + rc.bad_mac + r.de.counters.dropped();
    assert!(
        refused > 0,
        "the flipped bytes were refused and counted: {rc:?} {:?}",
        r.de.counters
    );
}

/// Reads from `port` until `n` bytes came or 5 s passed.
fn read_n(port: &mut Port, n: usize) -> Vec<u8> {
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let t0 = Instant::now();
    while got.len() < n && t0.elapsed() < Duration::from_secs(5) {
        let k = port.read(&mut buf).unwrap();
        got.extend_from_slice(&buf[..k]);
        if k == 0 {
            port.wait(Duration::from_millis(10)).unwrap();
        }
    }
    got
}

// verifies: LINK-STREAM-03
#[test]
fn a_tty_opened_as_a_port_is_raw_both_ways_and_a_unix_socket_path_is_connected() {
    use std::os::fd::AsRawFd;
    // A fresh pty is cooked (echo, CR/NL translation, ^C, ^S/^Q): every byte value
    // must still cross unchanged in both directions once `port::open` has it.
    let pty = nix::pty::openpty(None, None).unwrap();
    let path = std::fs::read_link(format!("/proc/self/fd/{}", pty.slave.as_raw_fd())).unwrap();
    drop(pty.slave);
    let mut port = mmic_link::stream::port::open(&path).unwrap();
    let mut master = std::fs::File::from(pty.master);
    let all: Vec<u8> = (0..=255u8).cycle().take(1024).collect();
    master.write_all(&all).unwrap();
    assert_eq!(read_n(&mut port, all.len()), all, "robot to ground: raw, no echo");
    assert!(port.send(&all).unwrap());
    let t0 = Instant::now();
    while port.queued() > 0 && t0.elapsed() < Duration::from_secs(5) {
        port.flush().unwrap();
    }
    let mut got = vec![0u8; all.len()];
    master.read_exact(&mut got).unwrap();
    assert_eq!(got, all, "ground to robot: raw");

    // A Unix socket (QEMU's -serial unix:PATH,server) is connected to.
    let sock = std::env::temp_dir().join(format!("ground-link-port-{}.sock", std::process::id()));
    let _ = std::fs::remove_file(&sock);
    let listener = std::os::unix::net::UnixListener::bind(&sock).unwrap();
    let mut port = mmic_link::stream::port::open(&sock).unwrap();
    let (mut peer, _) = listener.accept().unwrap();
    peer.write_all(&all).unwrap();
    assert_eq!(read_n(&mut port, all.len()), all);
    assert!(port.describe.starts_with("unix socket"));
    // The other side closing is an error on a socket (the link stops), not silence.
    drop(peer);
    let mut buf = [0u8; 16];
    let t0 = Instant::now();
    let r = loop {
        match port.read(&mut buf) {
            Ok(0) if t0.elapsed() < Duration::from_secs(5) => std::thread::sleep(Duration::from_millis(5)),
            r => break r,
        }
    };
    assert!(r.is_err(), "{r:?}");
    let _ = std::fs::remove_file(&sock);
    // Neither a tty nor a socket: refused with the system's reason.
    assert!(mmic_link::stream::port::open(Path::new("/dev/null")).is_err());
    assert!(mmic_link::stream::port::open(Path::new("/nonexistent/tty")).is_err());
}
