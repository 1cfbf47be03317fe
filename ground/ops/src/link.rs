//! Links to OBSWs: the space link (TC and TM transfer frames with COP-1 and SDLS, through
//! `ground-link`), or the bare-packet lab links: UDP (one space packet per datagram) or
//! TCP (COBS frames delimited by 0x00, as sat-rs's TCP server frames them). Each link has
//! a thread that pushes every received packet, with its arrival time, into one channel.
//!
//! The space link runs over UDP (one frame per datagram) or, for a robot given in
//! [`FrameOptions::serial`], over a serial device or Unix socket (board A's ground link:
//! one COBS frame per transfer frame, `ground_link::GroundFrameLink::open_serial`); the same
//! FOP-1 and SDLS either way.
//!
//! Over frames, [`Link::send`] hands the packet to FOP-1 (queued, never lost: COP-1
//! retransmits its frame until a CLCW acknowledges it); the ground's own packet resends are
//! not used ([`Link::resends_packets`]). [`Link::frame_stats`] counts what COP-1 did.

use std::collections::{BTreeMap, VecDeque};
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::Sender;
use ground_link::stream;

use crate::pus;

/// Poll interval of the reader threads (how fast they notice a stop).
const READ_POLL: Duration = Duration::from_millis(100);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// Bare space packets, one per UDP datagram (lab mode).
    Udp,
    /// Bare space packets over TCP, COBS-framed (lab mode).
    Tcp,
    /// TC/TM transfer frames, COP-1, SDLS (the space link; needs [`FrameOptions`]).
    Frames,
}

impl Transport {
    pub fn name(self) -> &'static str {
        match self {
            Transport::Udp => "UDP, bare packets",
            Transport::Tcp => "TCP, bare packets",
            Transport::Frames => "space link: TC/TM frames, COP-1, SDLS",
        }
    }
}

/// Where the frame link of each robot finds its keys and receives its TM frames.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameOptions {
    /// The key directory (`ground keys create`): robot N uses `KEYS/robot-N/`
    /// (`tc-spi1.key`, `tm-spi17.key`, and the ground's counter file `ground-link.state`).
    pub keys: PathBuf,
    /// Robot N's TM frames arrive at this local address (the obsw's `--frame-tm-to`);
    /// default [`default_tm_listen`].
    pub tm_listen: BTreeMap<u8, SocketAddr>,
    /// The TC SPI the ground sends under (1, or the spare 2 after a key change,
    /// `mib::link::sdls::TC_SPIS`).
    pub tc_spi: u16,
    /// SDLS on the robot's TM frames (its `--tm-sdls`): both ends must agree.
    pub tm_security: ground_link::TmSecurity,
    /// Robot N's frames over this serial device (raw mode) or Unix socket instead of UDP
    /// (`--serial N=PATH`): TC and TM frames as COBS frames on the byte stream.
    pub serial: BTreeMap<u8, PathBuf>,
    /// Robot N's TM frames on a socket the caller bound before it started the robot (its
    /// address given to the robot as `--frame-tm-to`), instead of one bound at
    /// [`FrameOptions::listen`]: no moment where the port is free for another process.
    pub tm_sockets: BTreeMap<u8, BoundSocket>,
}

/// A UDP socket bound by the caller, shared by the options that name it; two are equal when
/// they are the same socket.
#[derive(Clone, Debug)]
pub struct BoundSocket(Arc<UdpSocket>);

impl BoundSocket {
    /// Binds `addr` (port 0: the kernel chooses, and keeps it taken).
    pub fn bind(addr: SocketAddr) -> io::Result<BoundSocket> {
        Ok(BoundSocket(Arc::new(UdpSocket::bind(addr)?)))
    }

    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.0.local_addr()
    }
}

impl PartialEq for BoundSocket {
    fn eq(&self, other: &BoundSocket) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Eq for BoundSocket {}

impl FrameOptions {
    /// Keys in `keys`, TM on the default addresses, TC SPI 1, encrypted TM, UDP.
    pub fn new(keys: PathBuf) -> FrameOptions {
        FrameOptions {
            keys,
            tm_listen: BTreeMap::new(),
            tc_spi: mib::link::sdls::TC_SPIS[0],
            tm_security: ground_link::TmSecurity::Encrypt,
            serial: BTreeMap::new(),
            tm_sockets: BTreeMap::new(),
        }
    }
}

impl FrameOptions {
    /// The local address robot `robot`'s TM frames arrive at.
    pub fn listen(&self, robot: u8, robot_addr: SocketAddr) -> SocketAddr {
        self.tm_sockets
            .get(&robot)
            .and_then(|s| s.local_addr().ok())
            .or_else(|| self.tm_listen.get(&robot).copied())
            .unwrap_or_else(|| default_tm_listen(robot, robot_addr))
    }
}

/// Default address of robot `n` over `transport`: its space-link port
/// (`mib::host_config::frame_port`, obsw --frame-udp's default), or its bare-packet port on a
/// lab link (`mib::host_config::robot_port`, obsw --udp's default); loopback either way.
pub fn default_addr(n: u8, transport: Transport) -> SocketAddr {
    let port = match transport {
        Transport::Frames => mib::host_config::frame_port(n),
        Transport::Udp | Transport::Tcp => mib::host_config::robot_port(n),
    };
    (std::net::Ipv4Addr::LOCALHOST, port).into()
}

/// Robot N's TM frames by default: port `mib::host_config::tm_frame_port(N)` (7600 + N), on
/// loopback when the robot is there.
pub fn default_tm_listen(robot: u8, robot_addr: SocketAddr) -> SocketAddr {
    let port = mib::host_config::tm_frame_port(robot);
    if robot_addr.ip().is_loopback() {
        (std::net::Ipv4Addr::LOCALHOST, port).into()
    } else {
        (std::net::Ipv4Addr::UNSPECIFIED, port).into()
    }
}

/// What COP-1 did on a frame link so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrameStats {
    /// Packets handed to the link.
    pub packets: u64,
    /// AD frames transmitted (first transmissions and retransmissions).
    pub ad_frames: u64,
    /// COP-1 retransmissions of AD frames.
    pub retransmissions: u64,
    /// Packets whose frames a CLCW acknowledged ("sent").
    pub acknowledged: u64,
    /// Packets whose fate the link could not tell (the robot's FARM-1 restarted).
    pub unknown: u64,
    /// FOP-1 alerts (each followed by a re-initialisation).
    pub alerts: u64,
    /// Initialisations of the AD service (Set V(R) or Unlock).
    pub initialisations: u64,
    /// TM frames refused (CRC, SDLS, header; on a serial link also the frames its COBS
    /// framing dropped).
    pub tm_refused: u64,
    /// Packets waiting in the link (queued or not yet acknowledged).
    pub pending: u64,
    /// Last N(R) seen in a CLCW.
    pub nr: Option<u8>,
}

/// A packet (or undecodable chunk) received from a robot's link.
#[derive(Clone, Debug)]
pub struct Incoming {
    pub robot: u8,
    pub t_ms: i64,
    pub bytes: Vec<u8>,
}

enum Io {
    Udp(UdpSocket),
    Tcp(Mutex<TcpStream>),
    Frames {
        to_link: Sender<Vec<u8>>,
        stats: Arc<Mutex<FrameStats>>,
        /// The link could not start or stopped with this error.
        failed: Arc<Mutex<Option<String>>>,
        /// Packets given to `send`.
        submitted: std::sync::atomic::AtomicU64,
        /// Request IDs (APID, sequence count) of the packets whose frames a CLCW
        /// acknowledged, newest last, at most [`DELIVERED_REMEMBERED`].
        delivered: Arc<Mutex<VecDeque<(u16, u16)>>>,
        /// When (archive clock, ms) the last valid TM frame arrived ([`NOT_HEARD`]:
        /// none yet); see [`Link::last_heard_ms`].
        heard: Arc<AtomicI64>,
    },
}

/// [`Io::Frames`]'s `heard` before the first valid frame.
const NOT_HEARD: i64 = i64::MIN;

/// Acknowledged request IDs a frame link remembers (far more than TCs in flight).
const DELIVERED_REMEMBERED: usize = 4096;

/// What kind of link a TC went out on, for a front end that does not own the link (the
/// collector's plan runner hands its TCs to the robot's thread): the same two facts the
/// commanding rules take from a [`Link`] that `ops::Session` owns. Holds no socket.
#[derive(Clone, Debug)]
pub enum LinkKind {
    /// A bare-packet lab link: the ground resends a packet until it is accepted.
    Packets,
    /// A frame link: COP-1 retransmits; `delivered` are the request IDs whose frames a
    /// CLCW acknowledged (shared with the link's thread).
    Frames {
        delivered: Arc<Mutex<VecDeque<(u16, u16)>>>,
    },
}

impl LinkKind {
    /// As [`Link::resends_packets`].
    pub fn resends_packets(&self) -> bool {
        matches!(self, LinkKind::Packets)
    }
    /// As [`Link::delivered`].
    pub fn delivered(&self, apid: u16, seq: u16) -> bool {
        match self {
            LinkKind::Frames { delivered } => delivered.lock().is_ok_and(|d| d.contains(&(apid, seq))),
            LinkKind::Packets => false,
        }
    }
}

/// An open link to one robot's OBSW.
pub struct Link {
    pub robot: u8,
    pub addr: SocketAddr,
    io: Arc<Io>,
    stop: Arc<AtomicBool>,
    /// Set by the reader when a TCP connection ends (EOF or error).
    closed: Arc<AtomicBool>,
    /// When (archive clock, ms) the reader thread last came back from its socket (a
    /// packet, a frame round or a wait with nothing), with what it read already handed on
    /// ([`NOT_HEARD`]: not yet); see [`Link::listened_ms`].
    listened: Arc<AtomicI64>,
    reader: Option<JoinHandle<()>>,
    /// This process commands the robot (see [`crate::robot_lock`]).
    _lock: crate::robot_lock::RobotLock,
}

/// Splits a buffer of concatenated space packets (a UDP datagram or a COBS frame).
/// Bytes that do not start a plausible packet are passed on as one chunk so that the
/// decoder counts them as corrupt.
pub fn split_packets(mut b: &[u8], mut out: impl FnMut(&[u8])) {
    while !b.is_empty() {
        match pus::packet_len(b) {
            Ok(n) => {
                out(&b[..n]);
                b = &b[n..];
            }
            Err(_) => {
                out(b);
                return;
            }
        }
    }
}

/// COBS-encodes a packet with a 0x00 sentinel before and after (sat-rs framing), with
/// the one encoder, `mmic_link::stream::encode`.
pub fn cobs_frame(packet: &[u8]) -> Vec<u8> {
    let mut buf = vec![0u8; stream::encoded_len(packet.len())];
    // The buffer is `encoded_len` long, so `encode` cannot fail; an empty frame if it did.
    let n = stream::encode(packet, &mut buf).unwrap_or(0);
    buf.truncate(n);
    buf
}

/// Largest decoded lab-TCP frame: a frame may hold several packets (the robot's writer
/// batches them), as the old splitter's bound of two packets.
pub const TCP_FRAME_MAX: usize = 2 * mib::config::MAX_PACKET_LEN;

/// The lab TCP link's deframer: the one COBS deframer, `mmic_link::stream::Deframer`
/// (keeps a partial frame; counts oversize, corrupt and garbage bytes in its `counters`).
pub type TcpDeframer = stream::Deframer<TCP_FRAME_MAX>;

impl Link {
    /// Opens a bare-packet link (UDP or TCP); frames need [`Link::open_with`].
    pub fn open(robot: u8, addr: SocketAddr, transport: Transport, tx: Sender<Incoming>) -> io::Result<Link> {
        Link::open_with(robot, addr, transport, None, tx)
    }

    /// Opens a link; `frames` is required with [`Transport::Frames`].
    pub fn open_with(
        robot: u8,
        addr: SocketAddr,
        transport: Transport,
        frames: Option<&FrameOptions>,
        tx: Sender<Incoming>,
    ) -> io::Result<Link> {
        // One commanding process per robot on this host, held as long as the link.
        let lock = crate::robot_lock::RobotLock::acquire(robot, addr)?;
        let stop = Arc::new(AtomicBool::new(false));
        let closed = Arc::new(AtomicBool::new(false));
        if transport == Transport::Frames {
            let opts = frames.ok_or_else(|| io::Error::other("the frame link needs a key directory (--keys DIR)"))?;
            return open_frames(robot, addr, opts, tx, stop, closed, lock);
        }
        let listened = Arc::new(AtomicI64::new(NOT_HEARD));
        let io = match transport {
            Transport::Frames => unreachable_frames()?,
            Transport::Udp => {
                let bind: SocketAddr = if addr.ip().is_loopback() {
                    (std::net::Ipv4Addr::LOCALHOST, 0).into()
                } else if addr.is_ipv6() {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                } else {
                    (std::net::Ipv4Addr::UNSPECIFIED, 0).into()
                };
                let s = UdpSocket::bind(bind)?;
                s.connect(addr)?;
                s.set_read_timeout(Some(READ_POLL))?;
                Io::Udp(s)
            }
            Transport::Tcp => {
                let s = TcpStream::connect_timeout(&addr, Duration::from_secs(2))?;
                s.set_nodelay(true)?;
                s.set_read_timeout(Some(READ_POLL))?;
                Io::Tcp(Mutex::new(s))
            }
        };
        let io = Arc::new(io);
        let reader = {
            let io = io.clone();
            let stop = stop.clone();
            let closed = closed.clone();
            let listened = listened.clone();
            let reader_stream = match &*io {
                Io::Tcp(m) => Some(m.lock().map_err(|_| io::Error::other("lock"))?.try_clone()?),
                Io::Udp(_) | Io::Frames { .. } => None,
            };
            std::thread::Builder::new()
                .name(format!("link-{robot}"))
                .spawn(move || {
                    reader_loop(robot, &io, reader_stream, &stop, &tx, &listened);
                    if !stop.load(Ordering::Relaxed) {
                        closed.store(true, Ordering::Relaxed);
                    }
                })?
        };
        Ok(Link {
            robot,
            addr,
            io,
            stop,
            closed,
            listened,
            reader: Some(reader),
            _lock: lock,
        })
    }

    /// When (archive clock, [`crate::archive::now_ms`]) the link's reader thread last came
    /// back from its socket, everything it had read by then already in the channel (`None`
    /// before its first read). A silence is only known up to here: on a loaded machine the
    /// reader may not be scheduled for seconds while the robot's packets wait in the
    /// socket, and a front end that judged the silence up to its own clock would call a
    /// live robot lost for the ground's own stall. Read it *before* draining the channel:
    /// what the reader had read by then is then in hand.
    pub fn listened_ms(&self) -> Option<i64> {
        Some(self.listened.load(Ordering::Acquire)).filter(|&t| t != NOT_HEARD)
    }

    /// True on a UDP lab link, where the robot sends TM only to a ground whose TC it
    /// accepted (its subscription lease); TCP clients and the frame link get TM anyway.
    pub fn subscribes(&self) -> bool {
        matches!(&*self.io, Io::Udp(_))
    }

    /// True once a TCP connection ended (the peer closed it or it failed).
    pub fn closed(&self) -> bool {
        self.closed.load(Ordering::Relaxed)
    }

    /// False over frames: COP-1 retransmits, the ground never resends a packet itself.
    pub fn resends_packets(&self) -> bool {
        self.kind().resends_packets()
    }

    /// What a front end that commands through this link from another thread needs of it
    /// (the collector's plan runner): see [`LinkKind`].
    pub fn kind(&self) -> LinkKind {
        match &*self.io {
            Io::Frames { delivered, .. } => LinkKind::Frames {
                delivered: Arc::clone(delivered),
            },
            Io::Udp(_) | Io::Tcp(_) => LinkKind::Packets,
        }
    }

    /// What COP-1 did (frame links only).
    pub fn frame_stats(&self) -> Option<FrameStats> {
        match &*self.io {
            Io::Frames { stats, .. } => stats.lock().ok().map(|s| *s),
            Io::Udp(_) | Io::Tcp(_) => None,
        }
    }

    /// True if a CLCW acknowledged the frame of the packet with this request ID: COP-1
    /// delivered it to the robot's FARM-1, so it reached the on-board software (frame
    /// links only; a bare-packet link never knows).
    pub fn delivered(&self, apid: u16, seq: u16) -> bool {
        self.kind().delivered(apid, seq)
    }

    /// When (archive clock, [`crate::archive::now_ms`]) the link last proved the robot is
    /// there without a packet: over frames, the last valid TM frame (CRC, SCID and SDLS
    /// checked; idle frames with only a CLCW included), which the robot sends at least every
    /// `mib::link::cop1::CLCW_REPORT_INTERVAL_MS`. `None` on a bare-packet link (there
    /// only packets prove it) or before the first frame. Every front end feeds it to its
    /// [`crate::live::LinkWatch`] so that a robot is heard while its frames come, whatever
    /// happens to its packets.
    pub fn last_heard_ms(&self) -> Option<i64> {
        match &*self.io {
            Io::Frames { heard, .. } => Some(heard.load(Ordering::Relaxed)).filter(|&t| t != NOT_HEARD),
            Io::Udp(_) | Io::Tcp(_) => None,
        }
    }

    /// Why the frame link stopped, if it did.
    pub fn failure(&self) -> Option<String> {
        match &*self.io {
            Io::Frames { failed, .. } => failed.lock().ok().and_then(|f| f.clone()),
            Io::Udp(_) | Io::Tcp(_) => None,
        }
    }

    /// Sends one packet (over frames: queues it for FOP-1; "sent" is its acknowledgement,
    /// counted in [`Link::frame_stats`]).
    pub fn send(&self, packet: &[u8]) -> io::Result<()> {
        match &*self.io {
            Io::Frames { to_link, .. } => {
                if self.closed() {
                    return Err(io::Error::other(
                        self.failure().unwrap_or_else(|| "frame link stopped".into()),
                    ));
                }
                to_link
                    .send(packet.to_vec())
                    .map_err(|_| io::Error::other("frame link stopped"))
            }
            Io::Udp(s) => s.send(packet).map(|_| ()),
            Io::Tcp(m) => {
                let frame = cobs_frame(packet);
                m.lock()
                    .map_err(|_| io::Error::other("link lock poisoned"))?
                    .write_all(&frame)
            }
        }
    }
}

/// Longest wait, when a frame link closes, for COP-1 to deliver what is still queued.
const FRAME_FLUSH: Duration = Duration::from_secs(5);

impl Drop for Link {
    fn drop(&mut self) {
        if let Io::Frames { stats, submitted, .. } = &*self.io {
            // A packet given to `send` is delivered (acknowledged by a CLCW) before the
            // link closes, e.g. `ground send --no-wait` exiting at once; bounded wait.
            let t0 = std::time::Instant::now();
            let given = submitted.load(Ordering::Relaxed);
            while !self.closed() && t0.elapsed() < FRAME_FLUSH {
                let settled = stats.lock().map_or(given, |s| s.acknowledged + s.unknown);
                if settled >= given {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        }
        self.stop.store(true, Ordering::Relaxed);
        if let Io::Tcp(m) = &*self.io {
            if let Ok(s) = m.lock() {
                let _ = s.shutdown(std::net::Shutdown::Both);
            }
        }
        if let Some(h) = self.reader.take() {
            let _ = h.join();
        }
    }
}

fn reader_loop(
    robot: u8,
    io: &Io,
    tcp: Option<TcpStream>,
    stop: &AtomicBool,
    tx: &Sender<Incoming>,
    listened: &AtomicI64,
) {
    let mut buf = vec![0u8; 65536];
    // After what a read brought is in the channel (see `Link::listened_ms`).
    let back = || listened.store(crate::archive::now_ms(), Ordering::Release);
    let emit = |bytes: &[u8]| {
        let _ = tx.send(Incoming {
            robot,
            t_ms: crate::archive::now_ms(),
            bytes: bytes.to_vec(),
        });
    };
    match (io, tcp) {
        (Io::Udp(s), _) => {
            while !stop.load(Ordering::Relaxed) {
                match s.recv(&mut buf) {
                    Ok(n) => split_packets(&buf[..n], emit),
                    Err(e)
                        if matches!(
                            e.kind(),
                            io::ErrorKind::WouldBlock
                                | io::ErrorKind::TimedOut
                                | io::ErrorKind::ConnectionRefused
                                | io::ErrorKind::Interrupted
                        ) => {}
                    Err(_) => std::thread::sleep(READ_POLL),
                }
                back();
            }
        }
        (Io::Tcp(_), Some(mut s)) => {
            let mut split = Box::new(TcpDeframer::new());
            while !stop.load(Ordering::Relaxed) {
                match s.read(&mut buf) {
                    Ok(0) => return,
                    Ok(n) => split.feed(&buf[..n], |f| match f {
                        Ok(frame) => split_packets(frame, emit),
                        // A dropped frame (counted by the deframer) reaches the reader as
                        // an empty, undecodable packet: counted there as well.
                        Err(_) => emit(&[]),
                    }),
                    Err(e)
                        if matches!(
                            e.kind(),
                            io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                        ) => {}
                    Err(_) => return,
                }
                back();
            }
        }
        (Io::Tcp(_), None) | (Io::Frames { .. }, _) => {}
    }
}

fn unreachable_frames() -> io::Result<Io> {
    Err(io::Error::other("frame link opened as a bare-packet link"))
}

/// Opens robot `robot`'s frame link: its thread owns the `ground_link::GroundFrameLink`.
fn open_frames(
    robot: u8,
    addr: SocketAddr,
    opts: &FrameOptions,
    tx: Sender<Incoming>,
    stop: Arc<AtomicBool>,
    closed: Arc<AtomicBool>,
    lock: crate::robot_lock::RobotLock,
) -> io::Result<Link> {
    let dir = crate::keys::robot_dir(&opts.keys, robot);
    let listen = opts.listen(robot, addr);
    // The key folder's layout (`ground keys create`): the TC key of the chosen SPI, the TM
    // key of SPI 17 and, when there, the spare TM key of SPI 18 (accepted as well).
    let mut cfg =
        ground_link::Config::from_key_dir(addr, listen, &dir, &crate::keys::ground_state_path(&dir), opts.tc_spi)
            .map_err(|e| io::Error::other(format!("robot {robot}'s keys in {}: {e}", dir.display())))?;
    cfg.tm_security = opts.tm_security;
    let mut fl = match opts.serial.get(&robot) {
        Some(path) => ground_link::GroundFrameLink::open_serial(cfg, path).map_err(|e| {
            io::Error::other(format!(
                "frame link of robot {robot} over serial {}: {e}",
                path.display()
            ))
        })?,
        None => match opts.tm_sockets.get(&robot) {
            Some(s) => ground_link::GroundFrameLink::open_socket(cfg, s.0.try_clone()?),
            None => ground_link::GroundFrameLink::open(cfg),
        }
        .map_err(|e| io::Error::other(format!("frame link of robot {robot} (TM frames on {listen}): {e}")))?,
    };
    let (to_link, from_ground) = crossbeam_channel::unbounded::<Vec<u8>>();
    let stats = Arc::new(Mutex::new(FrameStats::default()));
    let failed = Arc::new(Mutex::new(None));
    let delivered = Arc::new(Mutex::new(VecDeque::new()));
    let heard = Arc::new(AtomicI64::new(NOT_HEARD));
    let listened = Arc::new(AtomicI64::new(NOT_HEARD));
    let reader = {
        let (stop, closed, stats, failed) = (stop.clone(), closed.clone(), stats.clone(), failed.clone());
        let delivered = delivered.clone();
        let (heard, listened) = (heard.clone(), listened.clone());
        std::thread::Builder::new()
            .name(format!("frames-{robot}"))
            .spawn(move || {
                let shared = FrameShared {
                    stats: &stats,
                    delivered: &delivered,
                    heard: &heard,
                    listened: &listened,
                };
                if let Err(e) = frame_loop(robot, &mut fl, &from_ground, &stop, &tx, shared) {
                    if let Ok(mut f) = failed.lock() {
                        *f = Some(e.to_string());
                    }
                    closed.store(true, Ordering::Relaxed);
                }
            })?
    };
    Ok(Link {
        robot,
        addr,
        io: Arc::new(Io::Frames {
            to_link,
            stats,
            failed,
            submitted: Default::default(),
            delivered,
            heard,
        }),
        stop,
        closed,
        listened,
        reader: Some(reader),
        _lock: lock,
    })
}

/// How long the frame thread sleeps on its socket between rounds (the latency of a
/// queued packet when no TM arrives).
const FRAME_ROUND: Duration = Duration::from_millis(5);

/// What the frame thread shares with its [`Link`].
struct FrameShared<'a> {
    stats: &'a Mutex<FrameStats>,
    delivered: &'a Mutex<VecDeque<(u16, u16)>>,
    heard: &'a AtomicI64,
    listened: &'a AtomicI64,
}

/// A space packet's request ID: APID and sequence count from its primary header.
fn request_id(packet: &[u8]) -> Option<(u16, u16)> {
    use satrs::spacepackets::CcsdsPacket;
    let (h, _) = satrs::spacepackets::SpHeader::from_be_bytes(packet).ok()?;
    Some((h.apid().value(), h.seq_count().value()))
}

fn frame_loop(
    robot: u8,
    fl: &mut ground_link::GroundFrameLink,
    from_ground: &crossbeam_channel::Receiver<Vec<u8>>,
    stop: &AtomicBool,
    tx: &Sender<Incoming>,
    shared: FrameShared,
) -> Result<(), ground_link::LinkError> {
    let mut st = FrameStats::default();
    // Packets handed to FOP-1 and not yet acknowledged (or given up as unknown).
    let mut in_flight: std::collections::HashMap<ground_link::PacketId, (u16, u16)> = Default::default();
    let mut last_frame = None;
    while !stop.load(Ordering::Relaxed) {
        while let Ok(p) = from_ground.try_recv() {
            let id = fl.send_packet(&p)?;
            if let Some(rid) = request_id(&p) {
                in_flight.insert(id, rid);
            }
            st.packets += 1;
        }
        let packets = fl.recv(FRAME_ROUND)?;
        let t_ms = crate::archive::now_ms();
        // A valid frame came in this round (at most FRAME_ROUND ago): the robot is heard.
        if fl.last_frame_ms() != last_frame {
            last_frame = fl.last_frame_ms();
            shared.heard.store(t_ms, Ordering::Relaxed);
        }
        for p in packets {
            let _ = tx.send(Incoming { robot, t_ms, bytes: p });
        }
        shared.listened.store(t_ms, Ordering::Release);
        let events = fl.take_events();
        for e in &events {
            match e {
                ground_link::Event::Acknowledged { id } => {
                    if let (Some(rid), Ok(mut d)) = (in_flight.remove(id), shared.delivered.lock()) {
                        if d.len() >= DELIVERED_REMEMBERED {
                            d.pop_front();
                        }
                        d.push_back(rid);
                    }
                }
                ground_link::Event::Unknown { id } => {
                    in_flight.remove(id);
                }
                ground_link::Event::Transmitted { .. }
                | ground_link::Event::Initialised { .. }
                | ground_link::Event::Alert(_) => {}
                _ => {}
            }
        }
        st.initialisations += events
            .iter()
            .filter(|e| matches!(e, ground_link::Event::Initialised { .. }))
            .count() as u64;
        let c = fl.counters;
        st.ad_frames = c.ad_frames_sent;
        st.retransmissions = c.retransmissions;
        st.acknowledged = c.acknowledged;
        st.unknown = c.unknown;
        st.alerts = c.alerts;
        let t = &c.tm;
        st.tm_refused = [
            t.bad_frame,
            t.bad_crc,
            t.wrong_scid,
            t.unknown_vc,
            t.bad_fhp,
            t.sdls_rejected,
            t.bad_clcw,
        ]
        .iter()
        .map(|&n| u64::from(n))
        .sum::<u64>()
            + c.odd_datagrams
            + u64::from(c.stream.dropped());
        st.pending = fl.pending() as u64;
        st.nr = fl.clcw().map(|c| c.report_value);
        if let Ok(mut s) = shared.stats.lock() {
            *s = st;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: DD-LINK-01
    #[test]
    fn cobs_frames_round_trip_across_partial_reads() {
        let p1 = vec![0x19, 0x01, 0x00, 0x05, 0x00, 0x00, 0x07];
        let p2 = vec![1, 2, 3];
        let mut stream = cobs_frame(&p1);
        stream.extend(cobs_frame(&p2));
        let f1 = cobs_frame(&p1);
        assert_eq!((f1[0], f1[f1.len() - 1]), (0, 0));
        assert!(!f1[1..f1.len() - 1].contains(&0));
        let mut sp = Box::new(TcpDeframer::new());
        let mut got = Vec::new();
        for chunk in stream.chunks(3) {
            sp.feed(chunk, |f| got.push(f.unwrap().to_vec()));
        }
        assert_eq!(got, vec![p1, p2]);
        assert_eq!(sp.counters.frames, 2);
    }

    // verifies: DD-LINK-01
    #[test]
    fn a_corrupt_or_oversize_tcp_frame_is_counted_not_lost() {
        let mut sp = Box::new(TcpDeframer::new());
        let mut errs = 0;
        let mut ok = Vec::new();
        // A block announcing 5 bytes cut by a delimiter, then an oversize frame, then a good one.
        let mut stream = vec![0, 5, 1, 2, 0];
        stream.extend(cobs_frame(&vec![7u8; TCP_FRAME_MAX + 1]));
        stream.extend(cobs_frame(&[1, 2, 3]));
        sp.feed(&stream, |f| match f {
            Ok(p) => ok.push(p.to_vec()),
            Err(_) => errs += 1,
        });
        assert_eq!(ok, vec![vec![1, 2, 3]]);
        assert_eq!(errs, 2);
        let c = sp.counters;
        assert_eq!((c.corrupt, c.oversize, c.frames), (1, 1, 1));
    }

    // verifies: DD-LINK-01
    #[test]
    fn datagram_with_two_packets_splits() {
        let t = [0x40, 0, 1, 0, 0, 0, 0];
        let a = pus::build_tm(0x101, 1, 17, 2, 0, &t, &[]);
        let mut d = a.clone();
        d.extend_from_slice(&a);
        d.extend_from_slice(&[9, 9]);
        let mut parts = Vec::new();
        split_packets(&d, |p| parts.push(p.to_vec()));
        assert_eq!(parts, vec![a.clone(), a, vec![9, 9]]);
    }
}
