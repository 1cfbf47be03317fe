//! A lossy relay between a ground and an `obsw`, for tests and benchmarks of the link.
//!
//! It listens on one UDP and one TCP address and forwards everything to the obsw's UDP and
//! TCP addresses. Each direction (up: ground → obsw, down: obsw → ground) has its own
//! probabilities of dropping, duplicating and corrupting a packet (a UDP datagram, or a
//! COBS frame on TCP, `mmic_link::stream`'s framing: a corrupted frame is re-encoded, so
//! it still frames but fails the packet CRC). The random numbers are seeded, so a seed replays the same decisions for
//! the same traffic. The relay is bounded (at most [`MAX_PEERS`] UDP grounds and TCP
//! connections), stops by itself after `lifetime` or after `idle` with no traffic, and
//! counts what it did per direction.
//!
//! Each UDP ground gets its own upstream socket, so the obsw sees one address per ground,
//! as it would without the relay.
//!
//! Transfer frames (docs/space-link.md) go up the same UDP path (one TC frame per datagram to the
//! obsw's `--frame-udp` port), but the obsw sends TM frames to a fixed ground address
//! rather than back to the sender: [`Relay::add_downlink_route`] listens where the obsw
//! sends them (`--frame-tm-to`) and forwards each datagram to the ground with the
//! downlink's faults, counted with the other downlink traffic. A corrupted frame keeps its
//! length and fails the frame CRC at the receiver.
//!
//! [`Relay::trace_to`] writes one line per UDP datagram (wall-clock time, direction,
//! length, fate, first header bytes): what each end really sent and what reached the
//! other, to tell a silent sender from a relay or receiver that was not scheduled.

use std::collections::HashMap;
use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use mmic_link::stream::{encode, encoded_len, Deframer};

/// Most UDP grounds and TCP connections relayed at once; more are ignored (counted).
pub const MAX_PEERS: usize = 16;
/// Largest datagram or frame relayed.
const MAX_DATAGRAM: usize = 65_536;
/// How often blocked threads look at the stop flag.
const POLL: Duration = Duration::from_millis(20);

/// Fault probabilities of one direction, each in [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Faults {
    pub drop: f64,
    pub duplicate: f64,
    pub corrupt: f64,
}

impl Faults {
    pub const CLEAN: Faults = Faults {
        drop: 0.0,
        duplicate: 0.0,
        corrupt: 0.0,
    };
    pub fn new(drop: f64, duplicate: f64, corrupt: f64) -> Faults {
        Faults {
            drop,
            duplicate,
            corrupt,
        }
    }
    fn check(&self) -> Result<(), String> {
        for (name, p) in [
            ("drop", self.drop),
            ("duplicate", self.duplicate),
            ("corrupt", self.corrupt),
        ] {
            if !(p.is_finite() && (0.0..=1.0).contains(&p) && p.is_sign_positive()) {
                return Err(format!("{name} probability {p}: must be in [0, 1]"));
            }
        }
        Ok(())
    }
}

/// What the relay is told to do.
#[derive(Clone, Debug)]
pub struct Config {
    /// Where grounds connect (ports may be 0).
    pub listen_udp: SocketAddr,
    pub listen_tcp: SocketAddr,
    /// The obsw's addresses.
    pub target_udp: SocketAddr,
    pub target_tcp: SocketAddr,
    pub up: Faults,
    pub down: Faults,
    pub seed: u64,
    /// The relay stops after this long in any case.
    pub lifetime: Duration,
    /// The relay stops after this long without any packet in either direction.
    pub idle: Duration,
}

impl Config {
    /// A relay on free loopback ports to `udp`/`tcp` with the same faults both ways.
    pub fn both_ways(target_udp: SocketAddr, target_tcp: SocketAddr, faults: Faults, seed: u64) -> Config {
        Config {
            listen_udp: SocketAddr::from(([127, 0, 0, 1], 0)),
            listen_tcp: SocketAddr::from(([127, 0, 0, 1], 0)),
            target_udp,
            target_tcp,
            up: faults,
            down: faults,
            seed,
            lifetime: Duration::from_secs(600),
            idle: Duration::from_secs(60),
        }
    }
}

/// Counters of one direction.
#[derive(Default, Debug)]
pub struct DirCounts {
    /// Packets received by the relay.
    pub seen: AtomicU64,
    /// Packets written onward (duplicates count twice).
    pub forwarded: AtomicU64,
    pub dropped: AtomicU64,
    pub duplicated: AtomicU64,
    pub corrupted: AtomicU64,
    /// When a packet last went onward unaltered (a corrupted copy fails the receiver's
    /// CRC: it is not heard).
    pub last_intact: Mutex<Option<Instant>>,
}

/// A copy of the counters at one moment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DirSnapshot {
    pub seen: u64,
    pub forwarded: u64,
    pub dropped: u64,
    pub duplicated: u64,
    pub corrupted: u64,
}

impl DirCounts {
    pub fn snapshot(&self) -> DirSnapshot {
        DirSnapshot {
            seen: self.seen.load(Ordering::Relaxed),
            forwarded: self.forwarded.load(Ordering::Relaxed),
            dropped: self.dropped.load(Ordering::Relaxed),
            duplicated: self.duplicated.load(Ordering::Relaxed),
            corrupted: self.corrupted.load(Ordering::Relaxed),
        }
    }
}

/// Everything the relay counted.
#[derive(Default, Debug)]
pub struct Counts {
    pub up: DirCounts,
    pub down: DirCounts,
    /// UDP grounds or TCP connections refused because [`MAX_PEERS`] were relayed already.
    pub peers_refused: AtomicU64,
}

impl std::fmt::Display for Counts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (name, d) in [("up", self.up.snapshot()), ("down", self.down.snapshot())] {
            writeln!(
                f,
                "{name}: seen {} forwarded {} dropped {} duplicated {} corrupted {}",
                d.seen, d.forwarded, d.dropped, d.duplicated, d.corrupted
            )?;
        }
        write!(f, "peers refused: {}", self.peers_refused.load(Ordering::Relaxed))
    }
}

/// splitmix64: small, seeded, good enough to draw fault decisions.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && self.unit() < p
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
}

/// What to do with one packet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Fate {
    Drop,
    /// Forward these copies (one, or two for a duplicate; either may be corrupted).
    Send(Vec<Vec<u8>>),
}

/// Decides the fate of one packet: dropped, or forwarded once or twice, possibly with one
/// bit flipped. Counts into `c`.
pub fn decide(rng: &mut Rng, f: &Faults, packet: &[u8], c: &DirCounts) -> Fate {
    c.seen.fetch_add(1, Ordering::Relaxed);
    if rng.chance(f.drop) {
        c.dropped.fetch_add(1, Ordering::Relaxed);
        return Fate::Drop;
    }
    let copies = if rng.chance(f.duplicate) {
        c.duplicated.fetch_add(1, Ordering::Relaxed);
        2
    } else {
        1
    };
    let mut out = Vec::with_capacity(copies);
    for _ in 0..copies {
        let mut p = packet.to_vec();
        if !p.is_empty() && rng.chance(f.corrupt) {
            let i = rng.below(p.len());
            p[i] ^= 1 << rng.below(8);
            c.corrupted.fetch_add(1, Ordering::Relaxed);
        }
        out.push(p);
    }
    c.forwarded.fetch_add(out.len() as u64, Ordering::Relaxed);
    if out.iter().any(|p| p == packet) {
        if let Ok(mut t) = c.last_intact.lock() {
            *t = Some(Instant::now());
        }
    }
    Fate::Send(out)
}

/// A running relay; stopped (and its threads joined) on drop.
pub struct Relay {
    pub udp: SocketAddr,
    pub tcp: SocketAddr,
    pub counts: Arc<Counts>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    shared: Arc<Shared>,
    routes: u64,
}

struct Shared {
    stop: Arc<AtomicBool>,
    counts: Arc<Counts>,
    last_traffic: Mutex<Instant>,
    started: Instant,
    cfg: Config,
    trace: Mutex<Option<std::fs::File>>,
}

impl Shared {
    fn running(&self) -> bool {
        if self.stop.load(Ordering::Relaxed) {
            return false;
        }
        let idle = self.last_traffic.lock().map(|t| t.elapsed()).unwrap_or_default();
        if self.started.elapsed() > self.cfg.lifetime || idle > self.cfg.idle {
            self.stop.store(true, Ordering::Relaxed);
            return false;
        }
        true
    }
    fn touch(&self) {
        if let Ok(mut t) = self.last_traffic.lock() {
            *t = Instant::now();
        }
    }
    /// One line of the trace (when tracing): `UNIX_US DIR LEN FATE HEAD`, FATE `drop`,
    /// or one letter per copy sent (`o` intact, `x` corrupted), HEAD the first 6 bytes in
    /// hex (a TM frame's primary header; a TC frame's 5-byte header and one more).
    fn trace(&self, dir: &str, packet: &[u8], fate: &Fate) {
        let Ok(mut t) = self.trace.lock() else { return };
        let Some(f) = t.as_mut() else { return };
        let us = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_micros());
        let fate = match fate {
            Fate::Drop => "drop".to_string(),
            Fate::Send(copies) => copies.iter().map(|c| if c == packet { 'o' } else { 'x' }).collect(),
        };
        let head: String = packet.iter().take(6).map(|b| format!("{b:02x}")).collect();
        // One write per line (the relay may be killed at any moment; nothing buffered).
        let _ = f.write_all(format!("{us} {dir} {} {fate} {head}\n", packet.len()).as_bytes());
    }
    /// A per-stream random generator derived from the seed, the direction and an index.
    fn rng(&self, dir: u64, index: u64) -> Rng {
        Rng::new(self.cfg.seed.wrapping_mul(0x100_0000_01B3) ^ (dir << 32) ^ index)
    }
}

impl Relay {
    /// Binds both listening sockets and starts relaying.
    pub fn start(cfg: Config) -> Result<Relay, String> {
        cfg.up.check().map_err(|e| format!("up: {e}"))?;
        cfg.down.check().map_err(|e| format!("down: {e}"))?;
        let udp = UdpSocket::bind(cfg.listen_udp).map_err(|e| format!("cannot bind UDP {}: {e}", cfg.listen_udp))?;
        let tcp = TcpListener::bind(cfg.listen_tcp).map_err(|e| format!("cannot bind TCP {}: {e}", cfg.listen_tcp))?;
        let udp_addr = udp.local_addr().map_err(|e| e.to_string())?;
        let tcp_addr = tcp.local_addr().map_err(|e| e.to_string())?;
        udp.set_read_timeout(Some(POLL)).map_err(|e| e.to_string())?;
        tcp.set_nonblocking(true).map_err(|e| e.to_string())?;
        let stop = Arc::new(AtomicBool::new(false));
        let counts = Arc::new(Counts::default());
        let shared = Arc::new(Shared {
            stop: stop.clone(),
            counts: counts.clone(),
            last_traffic: Mutex::new(Instant::now()),
            started: Instant::now(),
            cfg,
            trace: Mutex::new(None),
        });
        let mut threads = Vec::new();
        let s = shared.clone();
        threads.push(thread::spawn(move || udp_up(udp, s)));
        let s = shared.clone();
        threads.push(thread::spawn(move || tcp_accept(tcp, s)));
        Ok(Relay {
            udp: udp_addr,
            tcp: tcp_addr,
            counts,
            stop,
            threads,
            shared,
            routes: 0,
        })
    }

    /// A one-way downlink route for TM frames: datagrams arriving at `listen` (port may be
    /// 0; the bound address is returned — give it to the obsw as `--frame-tm-to`) are
    /// forwarded to `to` with the downlink's faults.
    pub fn add_downlink_route(&mut self, listen: SocketAddr, to: SocketAddr) -> Result<SocketAddr, String> {
        let sock = UdpSocket::bind(listen).map_err(|e| format!("cannot bind UDP {listen}: {e}"))?;
        self.add_downlink_socket(sock, to)
    }

    /// [`Relay::add_downlink_route`] on a socket bound before (to give its address to an
    /// obsw started before the relay, which needs the obsw's frame port).
    pub fn add_downlink_socket(&mut self, sock: UdpSocket, to: SocketAddr) -> Result<SocketAddr, String> {
        let addr = sock.local_addr().map_err(|e| e.to_string())?;
        sock.set_read_timeout(Some(POLL)).map_err(|e| e.to_string())?;
        let out = UdpSocket::bind(SocketAddr::from(([127, 0, 0, 1], 0))).map_err(|e| e.to_string())?;
        self.routes += 1;
        let (s, index) = (self.shared.clone(), self.routes);
        self.threads
            .push(thread::spawn(move || route_down(sock, out, to, s, index)));
        Ok(addr)
    }

    /// From now on, one line per UDP datagram relayed to `file` (`UNIX_US DIR LEN FATE HEAD`, as `relay --trace`).
    pub fn trace_to(&self, file: std::fs::File) {
        if let Ok(mut t) = self.shared.trace.lock() {
            *t = Some(file);
        }
    }

    /// True until the relay stops (asked to, lifetime or idle time over).
    pub fn running(&self) -> bool {
        !self.stop.load(Ordering::Relaxed)
    }

    /// Stops the relay and waits for its threads.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Ground → obsw on UDP; starts one downstream thread per ground.
fn udp_up(listen: UdpSocket, s: Arc<Shared>) {
    let listen = Arc::new(listen);
    let mut peers: HashMap<SocketAddr, UdpSocket> = HashMap::new();
    let mut downs = Vec::new();
    let mut rng = s.rng(1, 0);
    let mut buf = vec![0u8; MAX_DATAGRAM];
    while s.running() {
        let (n, from) = match listen.recv_from(&mut buf) {
            Ok(x) => x,
            Err(_) => continue,
        };
        s.touch();
        if !peers.contains_key(&from) {
            if peers.len() >= MAX_PEERS {
                s.counts.peers_refused.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            let Ok(up) = UdpSocket::bind(SocketAddr::from(([127, 0, 0, 1], 0))) else {
                continue;
            };
            let _ = up.set_read_timeout(Some(POLL));
            let Ok(reader) = up.try_clone() else { continue };
            let (l, sh, idx) = (listen.clone(), s.clone(), peers.len() as u64);
            downs.push(thread::spawn(move || udp_down(reader, l, from, sh, idx)));
            peers.insert(from, up);
        }
        let Some(up) = peers.get(&from) else { continue };
        let fate = decide(&mut rng, &s.cfg.up, &buf[..n], &s.counts.up);
        s.trace("up", &buf[..n], &fate);
        if let Fate::Send(copies) = fate {
            for c in copies {
                let _ = up.send_to(&c, s.cfg.target_udp);
            }
        }
    }
    for d in downs {
        let _ = d.join();
    }
}

/// Obsw → one ground on UDP.
fn udp_down(up: UdpSocket, listen: Arc<UdpSocket>, ground: SocketAddr, s: Arc<Shared>, index: u64) {
    let mut rng = s.rng(2, index);
    let mut buf = vec![0u8; MAX_DATAGRAM];
    while s.running() {
        let n = match up.recv(&mut buf) {
            Ok(n) => n,
            Err(_) => continue,
        };
        s.touch();
        let fate = decide(&mut rng, &s.cfg.down, &buf[..n], &s.counts.down);
        s.trace("down", &buf[..n], &fate);
        if let Fate::Send(copies) = fate {
            for c in copies {
                let _ = listen.send_to(&c, ground);
            }
        }
    }
}

/// Obsw → a fixed ground address (TM frames), downlink faults.
fn route_down(listen: UdpSocket, out: UdpSocket, to: SocketAddr, s: Arc<Shared>, index: u64) {
    let mut rng = s.rng(5, index);
    let mut buf = vec![0u8; MAX_DATAGRAM];
    while s.running() {
        let n = match listen.recv(&mut buf) {
            Ok(n) => n,
            Err(_) => continue,
        };
        s.touch();
        let fate = decide(&mut rng, &s.cfg.down, &buf[..n], &s.counts.down);
        s.trace("down", &buf[..n], &fate);
        if let Fate::Send(copies) = fate {
            for c in copies {
                let _ = out.send_to(&c, to);
            }
        }
    }
}

fn tcp_accept(listen: TcpListener, s: Arc<Shared>) {
    let mut pumps: Vec<JoinHandle<()>> = Vec::new();
    let mut index = 0u64;
    while s.running() {
        pumps.retain(|p| !p.is_finished());
        let ground = match listen.accept() {
            Ok((g, _)) => g,
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                thread::sleep(POLL);
                continue;
            }
            Err(_) => continue,
        };
        if pumps.len() / 2 >= MAX_PEERS {
            s.counts.peers_refused.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        let Ok(obsw) = TcpStream::connect(s.cfg.target_tcp) else {
            continue;
        };
        let _ = ground.set_nonblocking(false);
        for sock in [&ground, &obsw] {
            let _ = sock.set_nodelay(true);
            let _ = sock.set_read_timeout(Some(POLL));
        }
        let (Ok(g2), Ok(o2)) = (ground.try_clone(), obsw.try_clone()) else {
            continue;
        };
        index += 1;
        let (s1, s2) = (s.clone(), s.clone());
        pumps.push(thread::spawn(move || tcp_pump(ground, obsw, true, s1, index)));
        pumps.push(thread::spawn(move || tcp_pump(o2, g2, false, s2, index)));
    }
    for p in pumps {
        let _ = p.join();
    }
}

/// Copies COBS frames from `from` to `to`, deciding the fate of each frame.
fn tcp_pump(mut from: TcpStream, mut to: TcpStream, up: bool, s: Arc<Shared>, index: u64) {
    let (faults, counts) = if up {
        (s.cfg.up, &s.counts.up)
    } else {
        (s.cfg.down, &s.counts.down)
    };
    let mut rng = s.rng(if up { 3 } else { 4 }, index);
    let mut chunk = [0u8; 4096];
    // The one deframer (mmic_link::stream), and the encoded bytes of the frame in
    // progress, to pass on a frame it drops.
    let mut de = Box::new(Deframer::<MAX_DATAGRAM>::new());
    let mut raw: Vec<u8> = Vec::new();
    let mut encoded = Vec::new();
    'outer: while s.running() {
        let n = match from.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) =>
            {
                continue
            }
            Err(_) => break,
        };
        s.touch();
        for &b in &chunk[..n] {
            if b != 0 && raw.len() < MAX_DATAGRAM {
                raw.push(b);
            }
            let packet: &[u8] = match de.push(b) {
                None => {
                    if b == 0 {
                        // Delimiters, or an empty frame: nothing to relay.
                        raw.clear();
                    }
                    continue;
                }
                Some(Ok(p)) => p,
                // A frame that does not decode (or is longer than MAX_DATAGRAM) is passed
                // on as it is, its COBS bytes as the packet (the obsw judges it).
                Some(Err(_)) => &raw,
            };
            if let Fate::Send(copies) = decide(&mut rng, &faults, packet, counts) {
                for c in copies {
                    encoded.resize(encoded_len(c.len()), 0);
                    let k = encode(&c, &mut encoded).expect("buffer sized by encoded_len");
                    if to.write_all(&encoded[..k]).is_err() {
                        break 'outer;
                    }
                }
            }
            raw.clear();
        }
    }
    let _ = to.shutdown(Shutdown::Write);
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: DD-TEST-01
    #[test]
    fn fates_follow_the_probabilities_and_the_seed() {
        let f = Faults::new(0.2, 0.05, 0.05);
        let run = |seed| {
            let c = DirCounts::default();
            let mut rng = Rng::new(seed);
            let fates: Vec<Fate> = (0..10_000u32)
                .map(|i| decide(&mut rng, &f, &i.to_be_bytes(), &c))
                .collect();
            (fates, c.snapshot())
        };
        let (a, ca) = run(7);
        let (b, _) = run(7);
        let (c, _) = run(8);
        assert_eq!(a, b, "same seed, same decisions");
        assert_ne!(a, c, "another seed, other decisions");
        assert_eq!(ca.seen, 10_000);
        assert!((1800..2200).contains(&ca.dropped), "{ca:?}");
        assert!((300..500).contains(&ca.duplicated), "{ca:?}");
        assert!((300..550).contains(&ca.corrupted), "{ca:?}");
        assert_eq!(ca.forwarded, ca.seen - ca.dropped + ca.duplicated);
    }

    // verifies: DD-TEST-01
    #[test]
    fn bad_probabilities_are_refused() {
        let t = SocketAddr::from(([127, 0, 0, 1], 9));
        for bad in [-0.0, -0.1, 1.5, f64::NAN] {
            let cfg = Config::both_ways(t, t, Faults::new(bad, 0.0, 0.0), 1);
            assert!(Relay::start(cfg).is_err(), "{bad}");
        }
    }

    // verifies: DD-TEST-01
    #[test]
    fn udp_and_tcp_are_relayed_and_counted() {
        // An echo "obsw" on UDP and TCP.
        let echo_udp = UdpSocket::bind("127.0.0.1:0").unwrap();
        let echo_tcp = TcpListener::bind("127.0.0.1:0").unwrap();
        let (eu, et) = (echo_udp.local_addr().unwrap(), echo_tcp.local_addr().unwrap());
        thread::spawn(move || {
            let mut b = [0u8; 2048];
            while let Ok((n, from)) = echo_udp.recv_from(&mut b) {
                let _ = echo_udp.send_to(&b[..n], from);
            }
        });
        thread::spawn(move || {
            if let Ok((mut s, _)) = echo_tcp.accept() {
                let mut b = [0u8; 2048];
                while let Ok(n) = s.read(&mut b) {
                    if n == 0 || s.write_all(&b[..n]).is_err() {
                        break;
                    }
                }
            }
        });
        let mut cfg = Config::both_ways(eu, et, Faults::CLEAN, 3);
        cfg.up = Faults::new(0.0, 1.0, 0.0);
        let mut relay = Relay::start(cfg).unwrap();
        let g = UdpSocket::bind("127.0.0.1:0").unwrap();
        g.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        g.send_to(b"hello", relay.udp).unwrap();
        let mut b = [0u8; 64];
        for _ in 0..2 {
            let n = g.recv(&mut b).unwrap();
            assert_eq!(&b[..n], b"hello");
        }
        let mut t = TcpStream::connect(relay.tcp).unwrap();
        t.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut f = [0u8; 16];
        let k = encode(b"abc", &mut f).unwrap();
        t.write_all(&f[..k]).unwrap();
        let mut got = Vec::new();
        while got.iter().filter(|b| **b == 0).count() < 4 {
            let n = t.read(&mut b).unwrap();
            assert!(n > 0);
            got.extend_from_slice(&b[..n]);
        }
        let two: Vec<u8> = [&f[..k], &f[..k]].concat();
        assert_eq!(got, two, "frame duplicated on the way up, echoed twice");
        relay.stop();
        let up = relay.counts.up.snapshot();
        assert_eq!((up.seen, up.duplicated, up.forwarded), (2, 2, 4));
        assert_eq!(relay.counts.down.snapshot().seen, 4);
    }

    // verifies: DD-TEST-01, LINK-E2E-01
    #[test]
    fn downlink_routes_forward_frames_to_a_fixed_ground_with_faults() {
        let t = SocketAddr::from(([127, 0, 0, 1], 9));
        let mut cfg = Config::both_ways(t, t, Faults::CLEAN, 5);
        cfg.down = Faults::new(0.0, 1.0, 0.0);
        let mut relay = Relay::start(cfg).unwrap();
        let ground = UdpSocket::bind("127.0.0.1:0").unwrap();
        ground.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let tm_in = relay
            .add_downlink_route(SocketAddr::from(([127, 0, 0, 1], 0)), ground.local_addr().unwrap())
            .unwrap();
        let obsw = UdpSocket::bind("127.0.0.1:0").unwrap();
        let frame = [0x5Au8; 1024];
        obsw.send_to(&frame, tm_in).unwrap();
        let mut b = [0u8; 2048];
        for _ in 0..2 {
            let n = ground.recv(&mut b).unwrap();
            assert_eq!(&b[..n], &frame[..], "duplicated on the way down, unchanged");
        }
        relay.stop();
        let down = relay.counts.down.snapshot();
        assert_eq!((down.seen, down.duplicated, down.forwarded), (1, 1, 2));
    }

    // verifies: DD-TEST-01
    #[test]
    fn the_trace_has_one_line_per_datagram_with_its_fate() {
        let t = SocketAddr::from(([127, 0, 0, 1], 9));
        let mut cfg = Config::both_ways(t, t, Faults::CLEAN, 5);
        cfg.down = Faults::new(0.5, 0.0, 0.0);
        let mut relay = Relay::start(cfg).unwrap();
        let ground = UdpSocket::bind("127.0.0.1:0").unwrap();
        let tm_in = relay
            .add_downlink_route(SocketAddr::from(([127, 0, 0, 1], 0)), ground.local_addr().unwrap())
            .unwrap();
        let dir = std::env::temp_dir().join(format!("relay-trace-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("trace");
        relay.trace_to(std::fs::File::create(&path).unwrap());
        let obsw = UdpSocket::bind("127.0.0.1:0").unwrap();
        for i in 0..20u8 {
            obsw.send_to(&[i, 1, 2, 3, 4, 5, 6, 7], tm_in).unwrap();
        }
        let t0 = Instant::now();
        while relay.counts.down.snapshot().seen < 20 && t0.elapsed() < Duration::from_secs(5) {
            thread::sleep(Duration::from_millis(5));
        }
        relay.stop();
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        let lines: Vec<Vec<&str>> = text.lines().map(|l| l.split(' ').collect()).collect();
        assert_eq!(lines.len(), 20, "{text}");
        let down = relay.counts.down.snapshot();
        let dropped = lines.iter().filter(|l| l[3] == "drop").count() as u64;
        assert_eq!(dropped, down.dropped);
        assert!(dropped > 0 && dropped < 20, "{text}");
        for (i, l) in lines.iter().enumerate() {
            assert_eq!(&l[1..3], ["down", "8"]);
            assert!(l[3] == "drop" || l[3] == "o", "{text}");
            assert_eq!(l[4], format!("{i:02x}0102030405"));
        }
    }

    // verifies: DD-TEST-01
    #[test]
    fn stops_by_itself_when_idle() {
        let t = SocketAddr::from(([127, 0, 0, 1], 9));
        let mut cfg = Config::both_ways(t, t, Faults::CLEAN, 1);
        cfg.idle = Duration::from_millis(100);
        let relay = Relay::start(cfg).unwrap();
        let until = Instant::now() + Duration::from_secs(5);
        while relay.running() && Instant::now() < until {
            thread::sleep(Duration::from_millis(20));
        }
        assert!(!relay.running());
    }
}
