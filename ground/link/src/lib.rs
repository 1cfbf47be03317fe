//! The ground's frame link to one robot (docs/space-link.md): space packets in, TC transfer
//! frames (CCSDS 232.0-B-4) out through FOP-1 (232.1-B-2) and SDLS AES-256-GCM
//! (355.0-B-2, Yamcs 5.12.8's layout), over one UDP socket; TM transfer frames
//! (132.0-B-3) in, space packets and CLCWs out. Everything below the socket is
//! `mmic-link`, the code the robot runs.
//!
//! **Transports.** One frame per UDP datagram ([`GroundFrameLink::open`], what Yamcs uses), or
//! over a byte stream — board A's serial ground link (USB CDC-ACM), a pty, QEMU's
//! `-serial unix:` socket — one COBS frame per transfer frame ([`GroundFrameLink::open_serial`],
//! `mmic_link::stream`, the framing board A runs). The same FOP-1, SDLS and TM receiver
//! run over either; only how a frame is sent and received differs. Framing errors on the
//! stream are counted in [`Counters::stream`].
//!
//! ```text
//! send_packet(pkt) ─▶ queue ─▶ FOP-1 (window K, T1, transmission limit) ─▶ AD frame, SDLS ─▶ UDP
//! poll(now)        ◀─ packets ◀─ TmReceiver (CRC, SDLS, demux) ◀─ TM frames ◀──────────── UDP
//!                                  └─ CLCW ─▶ FOP-1 (acknowledges, retransmits)
//! ```
//!
//! **Bypass.** Class 2 CFDP file data may instead go at once in a BD frame
//! ([`GroundFrameLink::send_bypass`]): SDLS protects it as any frame, FOP-1 does not see
//! it, nothing retransmits it — CFDP's NAKs recover a lost one — and the robot takes no
//! other packet in a BD frame (`mib::cfdp::is_bypass_file_data`).
//!
//! **Exactly once.** A packet is handed to FOP-1 once; COP-1 retransmits its frame (a new
//! SDLS encryption with a fresh IV each time) until a CLCW acknowledges it
//! ([`Event::Acknowledged`]). When FOP-1 gives up (an alert: T1 expired the last time,
//! lockout, an inconsistent CLCW) the frames it purged may or may not have been accepted
//! on board. The link does not guess: it re-initialises with Set V(R) = N(R) from the next
//! CLCW, and since FARM-1 accepts in order, N(R) tells exactly which of the purged frames
//! were accepted (acknowledged now) and which were not (sent again, in order). Only when
//! N(R) lies outside the purged range — the robot restarted and its FARM-1 began again at
//! 0 — is the fate unknown: those packets are reported as [`Event::Unknown`] and not
//! resent (the caller checks their PUS 1 reports).
//!
//! **Timer T1.** With [`FopConfig::mission`] T1 follows the measured round trip
//! (SRTT + 4·RTTVAR, Karn's rule, doubled on expiry) between 300 ms and 2 s: a lone lost
//! frame costs a few hundred milliseconds, not 2 s ([`GroundFrameLink::fop_t1_ms`],
//! `docs/space-link.md` § Timer T1).
//!
//! **Start and restart.** A new `GroundFrameLink` has no COP-1 state: it waits until the CLCW's
//! N(R) has not changed for [`Config::settle_ms`] (idle frames carry the CLCW at least
//! every 100 ms; a dead ground's frames still in flight or queued on board land first —
//! without the wait, a Set V(R) from a stale CLCW would wind V(R) back over frames already
//! accepted, and they would execute twice: the end-to-end test found this) and initiates
//! the AD service with Set V(R) = N(R). A ground restarted mid-sequence resumes with the packet that had N(S) = N(R)
//! (see [`Event::Transmitted`]; keeping that record is the caller's).
//!
//! **Counters and keys.** The SDLS counters (TC transmit high-water mark, TM last IV) live
//! in a state file written before use ([`mmic_link::persist::FileIvStore`]); keys come from
//! raw 32-byte files ([`read_key`], [`create_key_file`]) and are never printed.

use std::collections::{BTreeMap, VecDeque};
use std::fmt;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use mib::link::sdls::{ANTI_REPLAY_WINDOW, TC_SPIS, TM_SPIS};
use mib::link::tc_frame::{MAX_LEN as TC_MAX_LEN, MAX_PACKET_LEN};
use mmic_link::clcw::Clcw;
pub use mmic_link::downlink::TmSecurity;
use mmic_link::downlink::{TmReceiver, TmRxCounters};
use mmic_link::fop::{AlertReason, Fop, FopConfig, FopEffect, FopInput, FopState};
use mmic_link::persist::{Dir, FileIvStore};
use mmic_link::sdls::{build_tc, RxSa, RxSas, TxSa};
use mmic_link::stream::port::Port;
use mmic_link::stream::{Deframer, StreamCounters};
use mmic_link::tc::{FrameType, TcRepr};

pub use mmic_link::persist::{create_key_file, read_key};
pub use mmic_link::sdls::Key;
/// The one COBS stream framing (`0x00, COBS(frame), 0x00`) and its counting deframer,
/// re-exported for the ground's lab TCP link.
pub use mmic_link::stream;

mod error;
pub use error::LinkError;

/// Handle of a packet given to [`GroundFrameLink::send_packet`].
pub type PacketId = u64;

/// What the link reports besides packets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Event {
    /// The packet's frame went out with this N(S) (again, when `retransmission`).
    Transmitted { id: PacketId, ns: u8, retransmission: bool },
    /// A CLCW acknowledged the packet's frame: it was accepted on board. Delivered.
    Acknowledged { id: PacketId },
    /// The robot's FARM-1 restarted while the frame was outstanding: it may or may not have
    /// been accepted. Not resent; check its PUS 1 reports.
    Unknown { id: PacketId },
    /// The AD service is (again) initialised, V(S) = N(R) = `vr`.
    Initialised { vr: u8 },
    /// FOP-1 raised an alert; the link re-initialises from the next CLCW.
    Alert(AlertReason),
}

/// Where and with what the link runs.
#[derive(Clone, Debug)]
pub struct Config {
    /// The robot's frame port (`obsw --frame-udp`).
    pub robot: SocketAddr,
    /// The local address TM frames arrive at (`obsw --frame-tm-to`); TC frames leave from it.
    pub listen: SocketAddr,
    /// The TC SPI the link sends under (one of `mib::link::sdls::TC_SPIS`) and its key.
    pub tc_spi: u16,
    pub tc_key: Key,
    /// The key of TM SPI 17 (`TM_SPIS[0]`).
    pub tm_key: Key,
    /// The key of the spare TM SPI 18 (`TM_SPIS[1]`), when there is one: TM frames under
    /// either SPI are accepted, so the robot can switch its TM SPI without a frame lost.
    pub tm_spare_key: Option<Key>,
    /// SDLS on the robot's VC0/VC1 TM frames (its `--tm-sdls`): both ends must agree.
    pub tm_security: TmSecurity,
    /// The ground's SDLS counter state file.
    pub state: PathBuf,
    pub fop: FopConfig,
    /// N(R) must stay the same this long (over several CLCWs) before the link initiates the
    /// AD service with Set V(R) = N(R): frames of a previous ground still in flight or
    /// waiting in the robot's queue land first, so Set V(R) never winds V(R) back over
    /// frames already accepted. [`RESYNC_SETTLE_MS`] by default.
    pub settle_ms: u64,
}

/// Default [`Config::settle_ms`]: three idle-frame intervals of the robot.
pub const RESYNC_SETTLE_MS: u64 = 300;

impl Config {
    /// The mission's link with keys read from files.
    pub fn from_key_files(
        robot: SocketAddr,
        listen: SocketAddr,
        tc_key: &Path,
        tm_key: &Path,
        state: &Path,
    ) -> Result<Config, LinkError> {
        Ok(Config {
            robot,
            listen,
            tc_spi: TC_SPIS[0],
            tc_key: read_key(tc_key)?,
            tm_key: read_key(tm_key)?,
            tm_spare_key: None,
            tm_security: TmSecurity::Encrypt,
            state: state.into(),
            fop: FopConfig::mission(),
            settle_ms: RESYNC_SETTLE_MS,
        })
    }

    /// The mission's link with the keys of one robot's folder as `ground keys create`
    /// writes it: TC under `tc_spi` (key `tc-spi<tc_spi>.key`), TM under SPI 17
    /// (`tm-spi17.key`) and, when the file is there, SPI 18 (`tm-spi18.key`). A key change
    /// without downtime: the robot accepts both TC SPIs whose keys it has, so a ground
    /// reopened (or switched with [`GroundFrameLink::switch_tc_spi`]) with `tc_spi` 2 goes on
    /// where the other left off.
    pub fn from_key_dir(
        robot: SocketAddr,
        listen: SocketAddr,
        dir: &Path,
        state: &Path,
        tc_spi: u16,
    ) -> Result<Config, LinkError> {
        if !TC_SPIS.contains(&tc_spi) {
            return Err(LinkError::NotTcSpi(tc_spi));
        }
        let spare = dir.join(format!("tm-spi{}.key", TM_SPIS[1]));
        Ok(Config {
            tc_spi,
            tm_spare_key: if spare.exists() { Some(read_key(&spare)?) } else { None },
            ..Config::from_key_files(
                robot,
                listen,
                &dir.join(format!("tc-spi{tc_spi}.key")),
                &dir.join(format!("tm-spi{}.key", TM_SPIS[0])),
                state,
            )?
        })
    }

    /// Whether two of the keys are the same (refused: GCM nonces would repeat).
    fn shares_a_key(&self) -> bool {
        self.tc_key == self.tm_key || self.tm_spare_key.is_some_and(|k| k == self.tc_key || k == self.tm_key)
    }
}

/// Counters of the ground side.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    pub ad_frames_sent: u64,
    /// BD frames sent ([`GroundFrameLink::send_bypass`]).
    pub bd_frames_sent: u64,
    pub retransmissions: u64,
    pub bc_frames_sent: u64,
    pub acknowledged: u64,
    pub unknown: u64,
    pub alerts: u64,
    /// TM frames refused, by the receiver's reasons.
    pub tm: TmRxCounters,
    /// Datagrams (or stream frames) that are not TM frames of our length.
    pub odd_datagrams: u64,
    /// Serial/stream transport: frames received, frames dropped by the framing (oversize,
    /// corrupt COBS) and their bytes.
    pub stream: StreamCounters,
    /// Serial/stream transport: TC frames not sent because the line's send queue was full
    /// (lost like on a radio link; COP-1 retransmits).
    pub stream_send_dropped: u64,
}

/// How frames travel (see the crate documentation).
enum Wire {
    /// One frame per datagram to and from the robot's frame port.
    /// The socket stays non-blocking: a wait for a frame is one `poll` of its descriptor
    /// (no mode switches around it).
    Udp { sock: UdpSocket, robot: SocketAddr },
    /// One COBS frame per transfer frame on a byte stream.
    Stream {
        port: Port,
        deframer: Box<Deframer<{ mib::link::tm_frame::LEN }>>,
        rbuf: Vec<u8>,
    },
}

/// The frame link (see the crate documentation).
pub struct GroundFrameLink {
    wire: Wire,
    fop: Fop<PacketId>,
    tc_sa: TxSa,
    tm: TmReceiver<2>,
    /// The TM keys (a TC key must differ from each).
    tm_keys: Vec<Key>,
    store: FileIvStore,
    queue: VecDeque<PacketId>,
    packets: BTreeMap<PacketId, Vec<u8>>,
    next_id: PacketId,
    /// Frames purged by FOP-1 (N(S), id), in order, until a CLCW decides their fate.
    limbo: Vec<(u8, PacketId)>,
    /// A packet purged from the wait queue (never transmitted).
    purged_wait: Vec<PacketId>,
    /// CLCWs received so far; the one that re-initialises must come after `init_after`.
    clcws: u64,
    init_after: u64,
    last_clcw: Option<Clcw>,
    /// When (link ms) the last valid TM frame arrived: right length, CRC, SCID, SDLS
    /// authentication — idle frames included. The robot is heard while these come.
    last_frame_ms: Option<u64>,
    /// N(R) of the CLCWs and since when (ms) it has not changed.
    stable_nr: Option<(u8, u64)>,
    settle_ms: u64,
    events: Vec<Event>,
    capture: Option<Vec<Vec<u8>>>,
    pub counters: Counters,
    epoch: Instant,
    buf: Vec<u8>,
}

impl fmt::Debug for GroundFrameLink {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let wire = match &self.wire {
            Wire::Udp { robot, .. } => robot.to_string(),
            Wire::Stream { port, .. } => port.describe.clone(),
        };
        f.debug_struct("GroundFrameLink")
            .field("robot", &wire)
            .field("fop", &self.fop.state())
            .field("queued", &self.queue.len())
            .finish_non_exhaustive()
    }
}

impl GroundFrameLink {
    /// Binds the socket and opens the counter state file. COP-1 initialises from the first
    /// CLCW that arrives.
    pub fn open(cfg: Config) -> Result<GroundFrameLink, LinkError> {
        let sock = UdpSocket::bind(cfg.listen)?;
        GroundFrameLink::open_socket(cfg, sock)
    }

    /// [`GroundFrameLink::open`] on a socket bound by the caller (`cfg.listen` is not
    /// used): its address can be given to the robot before the robot's own address — the
    /// link's `cfg.robot` — is known, without a moment where the port is free for another
    /// process to take.
    pub fn open_socket(cfg: Config, sock: UdpSocket) -> Result<GroundFrameLink, LinkError> {
        sock.set_nonblocking(true)?;
        let wire = Wire::Udp { sock, robot: cfg.robot };
        GroundFrameLink::open_on(cfg, wire)
    }

    /// The link over a serial device or a Unix socket at `path`
    /// (`mmic_link::stream::port::open`: a tty in raw mode, its stale input discarded):
    /// one COBS frame per transfer frame, as board A's ground link. `cfg.robot` and
    /// `cfg.listen` are not used.
    pub fn open_serial(cfg: Config, path: &Path) -> Result<GroundFrameLink, LinkError> {
        let port = mmic_link::stream::port::open(path)?;
        GroundFrameLink::open_port(cfg, port)
    }

    /// The link over an open stream port (e.g. one end of a socket pair).
    pub fn open_port(cfg: Config, port: Port) -> Result<GroundFrameLink, LinkError> {
        let wire = Wire::Stream {
            port,
            deframer: Box::default(),
            rbuf: vec![0u8; 4096],
        };
        GroundFrameLink::open_on(cfg, wire)
    }

    fn open_on(cfg: Config, wire: Wire) -> Result<GroundFrameLink, LinkError> {
        if cfg.shares_a_key() {
            return Err(LinkError::SameKey);
        }
        if !TC_SPIS.contains(&cfg.tc_spi) {
            return Err(LinkError::NotTcSpi(cfg.tc_spi));
        }
        let store = FileIvStore::open(&cfg.state)?;
        let tc_sa = TxSa::resume(cfg.tc_spi, &cfg.tc_key, store.get(Dir::Tx, cfg.tc_spi).unwrap_or(0));
        let rx_sa = |spi: u16, key: &Key| match store.get(Dir::Rx, spi) {
            Some(last) => RxSa::resume(spi, key, ANTI_REPLAY_WINDOW, last),
            None => RxSa::new(spi, key, ANTI_REPLAY_WINDOW),
        };
        let mut sas = RxSas::default();
        // Room for two SAs (TM SPIs 17 and 18): both inserts fit.
        let _ = sas.insert(rx_sa(TM_SPIS[0], &cfg.tm_key));
        if let Some(k) = cfg.tm_spare_key {
            let _ = sas.insert(rx_sa(TM_SPIS[1], &k));
        }
        Ok(GroundFrameLink {
            wire,
            fop: Fop::new(mib::link::tc_vc::COMMAND, cfg.fop),
            tc_sa,
            tm: TmReceiver::with_security(mib::link::SCID, cfg.tm_security, sas),
            tm_keys: std::iter::once(cfg.tm_key).chain(cfg.tm_spare_key).collect(),
            store,
            queue: VecDeque::new(),
            packets: BTreeMap::new(),
            next_id: 0,
            limbo: Vec::new(),
            purged_wait: Vec::new(),
            clcws: 0,
            init_after: 0,
            last_clcw: None,
            last_frame_ms: None,
            stable_nr: None,
            settle_ms: cfg.settle_ms,
            events: Vec::new(),
            capture: None,
            counters: Counters::default(),
            epoch: Instant::now(),
            buf: vec![0u8; 65_536],
        })
    }

    /// The local address (TM frames arrive here); an error on a stream link.
    pub fn local_addr(&self) -> Result<SocketAddr, LinkError> {
        match &self.wire {
            Wire::Udp { sock, .. } => Ok(sock.local_addr()?),
            Wire::Stream { port, .. } => Err(LinkError::Io(std::io::Error::other(format!(
                "the frame link runs on {}, not UDP",
                port.describe
            )))),
        }
    }

    /// Milliseconds since the link was opened (the clock `poll` is usually given).
    pub fn now_ms(&self) -> u64 {
        self.epoch.elapsed().as_millis() as u64
    }

    /// Queues a space packet for the AD service; it is delivered exactly once (see the
    /// crate documentation) as soon as FOP-1's window allows.
    pub fn send_packet(&mut self, packet: &[u8]) -> Result<PacketId, LinkError> {
        if packet.len() < 7 || packet.len() > MAX_PACKET_LEN {
            return Err(LinkError::PacketLength {
                len: packet.len(),
                max: MAX_PACKET_LEN,
            });
        }
        let id = self.next_id;
        self.next_id += 1;
        self.packets.insert(id, packet.to_vec());
        self.queue.push_back(id);
        Ok(id)
    }

    /// Sends a class 2 CFDP file data packet at once in a BD frame (SDLS-protected, no
    /// COP-1: a lost frame is not sent again here; the receiver's NAKs ask for the data).
    /// Any other packet is refused ([`LinkError::NotBypass`]): the robot would refuse it.
    pub fn send_bypass(&mut self, packet: &[u8]) -> Result<(), LinkError> {
        if !mib::cfdp::is_bypass_file_data(packet) {
            return Err(LinkError::NotBypass);
        }
        if packet.len() > MAX_PACKET_LEN {
            return Err(LinkError::PacketLength {
                len: packet.len(),
                max: MAX_PACKET_LEN,
            });
        }
        let mut buf = [0u8; TC_MAX_LEN];
        let repr = TcRepr {
            frame_type: FrameType::Bd,
            scid: mib::link::SCID,
            vcid: mib::link::tc_vc::COMMAND,
            seq: 0,
            data_len: 0,
        };
        let n = build_tc(&mut self.tc_sa, &mut self.store, repr, packet, &mut buf).map_err(LinkError::Sdls)?;
        self.send(&buf[..n])?;
        self.counters.bd_frames_sent += 1;
        Ok(())
    }

    /// Whether the packet `id` gave [`GroundFrameLink::send_packet`] is still queued or
    /// unacknowledged.
    pub fn is_pending(&self, id: PacketId) -> bool {
        self.packets.contains_key(&id)
    }

    /// Packets queued or sent and not yet acknowledged (or declared unknown).
    pub fn pending(&self) -> usize {
        self.packets.len()
    }

    pub fn fop_state(&self) -> FopState {
        self.fop.state()
    }

    /// FOP-1's timer T1 now (ms): with the mission's configuration adapted to the measured
    /// round trip between `mib::link::cop1::FOP_T1_MIN_MS` and `FOP_T1_MS`
    /// (`mmic_link::fop::T1Estimator`).
    pub fn fop_t1_ms(&self) -> u64 {
        self.fop.t1_ms()
    }

    /// The smoothed round trip of AD frames to the CLCW acknowledging them (ms), once
    /// measured (frames sent once only: Karn's rule).
    pub fn srtt_ms(&self) -> Option<u64> {
        self.fop.t1_estimator().srtt_ms()
    }

    /// The IV (anti-replay counter) the next TC frame will carry.
    pub fn tc_next_iv(&self) -> u128 {
        self.tc_sa.next_iv()
    }

    /// The TC SPI frames are sent under.
    pub fn tc_spi(&self) -> u16 {
        self.tc_sa.spi()
    }

    /// Key change without downtime: every TC frame from now on — new ones and COP-1
    /// retransmissions alike (each is a fresh encryption) — goes under `spi` with `key`,
    /// its counter resumed from the state file. Nothing queued or outstanding is lost: the
    /// robot accepts both TC SPIs whose keys it holds (until one is retired on board).
    pub fn switch_tc_spi(&mut self, spi: u16, key: &Key) -> Result<(), LinkError> {
        if !TC_SPIS.contains(&spi) {
            return Err(LinkError::NotTcSpi(spi));
        }
        if self.tm_keys.contains(key) {
            return Err(LinkError::SameKey);
        }
        self.tc_sa = TxSa::resume(spi, key, self.store.get(Dir::Tx, spi).unwrap_or(0));
        Ok(())
    }

    /// The last TM IV accepted under `spi` (`None`: no TM SA for it).
    pub fn tm_last_iv(&self, spi: u16) -> Option<u128> {
        self.tm.sas.get(spi).map(RxSa::last)
    }

    /// The last CLCW received.
    pub fn clcw(&self) -> Option<Clcw> {
        self.last_clcw
    }

    /// When (in [`GroundFrameLink::now_ms`]'s clock, as given to `poll`) the last valid TM
    /// frame arrived — any frame that passed the receiver's checks (length, CRC, SCID,
    /// SDLS authentication), idle frames with only a CLCW included: proof that the robot
    /// is there even when no packet gets through. `None` before the first.
    pub fn last_frame_ms(&self) -> Option<u64> {
        self.last_frame_ms
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// Test aid: keep a copy of every TC frame sent (from now on, until switched off).
    pub fn capture(&mut self, on: bool) {
        self.capture = on.then(Vec::new);
    }

    /// The frames captured since the last call.
    pub fn take_captured(&mut self) -> Vec<Vec<u8>> {
        self.capture.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// One round at time `now_ms`, never blocking: reads every TM frame waiting, feeds the
    /// CLCWs and the timer to FOP-1, (re)initialises when needed, sends what FOP-1 says.
    /// Returns the space packets received.
    pub fn poll(&mut self, now_ms: u64) -> Result<Vec<Vec<u8>>, LinkError> {
        let mut out = Vec::new();
        self.receive_all(now_ms, &mut out)?;
        self.advance(now_ms)?;
        Ok(out)
    }

    /// The part of [`GroundFrameLink::poll`] after the frames are read: FOP-1's timer,
    /// (re)initialisation, the queued packets FOP-1 takes now.
    fn advance(&mut self, now_ms: u64) -> Result<(), LinkError> {
        let fx = self.fop.on_event(now_ms, FopInput::Tick);
        self.apply(now_ms, fx)?;
        self.maybe_initiate(now_ms)?;
        // Only while the AD service runs (S1, S2): an FDU taken into the wait queue during
        // initialisation would wait there until some later CLCW looks for it.
        while self.fop.ready() && matches!(self.fop.state(), FopState::Active | FopState::RetransmitWithoutWait) {
            let Some(id) = self.queue.pop_front() else { break };
            let fx = self.fop.on_event(now_ms, FopInput::TransmitAd(id));
            self.apply(now_ms, fx)?;
        }
        Ok(())
    }

    /// Reads every frame waiting on the wire (never blocks).
    fn receive_all(&mut self, now_ms: u64, out: &mut Vec<Vec<u8>>) -> Result<(), LinkError> {
        if matches!(self.wire, Wire::Udp { .. }) {
            loop {
                let Wire::Udp { sock, .. } = &self.wire else {
                    return Ok(());
                };
                let Some(n) = recv_nonblocking(sock, &mut self.buf)? else {
                    return Ok(());
                };
                self.datagram(n, now_ms, out)?;
            }
        }
        match &mut self.wire {
            Wire::Udp { .. } => Ok(()),
            Wire::Stream { port, deframer, rbuf } => {
                port.flush()?;
                let mut frames = Vec::new();
                loop {
                    let n = port.read(rbuf)?;
                    if n == 0 {
                        break;
                    }
                    deframer.feed(&rbuf[..n], |r| {
                        if let Ok(f) = r {
                            frames.push(f.to_vec());
                        }
                    });
                }
                self.counters.stream = deframer.counters;
                self.counters.stream_send_dropped = port.send_dropped;
                for f in frames {
                    let n = f.len();
                    self.buf[..n].copy_from_slice(&f);
                    self.datagram(n, now_ms, out)?;
                }
                Ok(())
            }
        }
    }

    /// One received datagram (in `self.buf[..n]`): a TM frame's packets to `out`, its CLCW
    /// to FOP-1.
    fn datagram(&mut self, n: usize, now_ms: u64, out: &mut Vec<Vec<u8>>) -> Result<(), LinkError> {
        if n != mib::link::tm_frame::LEN {
            self.counters.odd_datagrams += 1;
            return Ok(());
        }
        let frame = &mut self.buf[..n];
        let r = self.tm.receive(&mut self.store, frame, |_vc, p| out.push(p.to_vec()));
        self.counters.tm = self.tm.counters;
        if let Ok(clcw) = r {
            self.last_frame_ms = Some(now_ms);
            self.clcws += 1;
            self.last_clcw = Some(clcw);
            if self.stable_nr.map(|s| s.0) != Some(clcw.report_value) {
                self.stable_nr = Some((clcw.report_value, now_ms));
            }
            let fx = self.fop.on_event(now_ms, FopInput::Clcw(clcw));
            self.apply(now_ms, fx)?;
        }
        Ok(())
    }

    /// Polls until `timeout` passes or a packet arrives, blocking on the socket in between
    /// (at most 20 ms at a time, so FOP-1's timer is served).
    pub fn recv(&mut self, timeout: Duration) -> Result<Vec<Vec<u8>>, LinkError> {
        let deadline = Instant::now() + timeout;
        loop {
            let got = self.poll(self.now_ms())?;
            let left = deadline.saturating_duration_since(Instant::now());
            if !got.is_empty() || left.is_zero() {
                return Ok(got);
            }
            let wait = left.min(Duration::from_millis(20)).max(Duration::from_millis(1));
            let r = match &self.wire {
                Wire::Udp { sock, .. } => wait_readable(sock, wait).and_then(|ready| {
                    if ready {
                        recv_nonblocking(sock, &mut self.buf)
                    } else {
                        Ok(None)
                    }
                })?,
                Wire::Stream { port, .. } => {
                    // Readable (or writable with bytes queued): the next poll takes it.
                    port.wait(wait)?;
                    continue;
                }
            };
            if let Some(n) = r {
                // The frame the wait was for, at once: its packets go back without another
                // read of the (most likely empty) socket; the next call reads what follows.
                let now = self.now_ms();
                let mut out = Vec::new();
                self.datagram(n, now, &mut out)?;
                self.advance(now)?;
                if !out.is_empty() {
                    return Ok(out);
                }
            }
        }
    }

    /// In S6 with a CLCW newer than the alert: decide the purged frames' fate from N(R),
    /// then initiate AD (Unlock when locked out, else Set V(R) = N(R)).
    fn maybe_initiate(&mut self, now_ms: u64) -> Result<(), LinkError> {
        if self.fop.state() != FopState::Initial || self.clcws <= self.init_after {
            return Ok(());
        }
        let Some(clcw) = self.last_clcw else { return Ok(()) };
        // N(R) must have settled (see `Config::settle_ms`).
        match self.stable_nr {
            Some((_, since)) if now_ms >= since + self.settle_ms => {}
            _ => return Ok(()),
        }
        let nr = clcw.report_value;
        if let Some(&(ns0, _)) = self.limbo.first() {
            let k = usize::from(nr.wrapping_sub(ns0));
            let limbo = std::mem::take(&mut self.limbo);
            let mut resend = Vec::new();
            if k <= limbo.len() {
                for (i, (_, id)) in limbo.into_iter().enumerate() {
                    if i < k {
                        self.delivered(id);
                    } else {
                        resend.push(id);
                    }
                }
            } else {
                for (_, id) in limbo {
                    self.packets.remove(&id);
                    self.counters.unknown += 1;
                    self.events.push(Event::Unknown { id });
                }
            }
            resend.append(&mut self.purged_wait);
            for id in resend.into_iter().rev() {
                self.queue.push_front(id);
            }
        } else {
            for id in std::mem::take(&mut self.purged_wait).into_iter().rev() {
                self.queue.push_front(id);
            }
        }
        self.init_after = self.clcws;
        let input = if clcw.lockout {
            FopInput::InitiateAdWithUnlock
        } else {
            FopInput::InitiateAdWithSetVr(nr)
        };
        let fx = self.fop.on_event(now_ms, input);
        self.apply(now_ms, fx)
    }

    fn delivered(&mut self, id: PacketId) {
        if self.packets.remove(&id).is_some() {
            self.counters.acknowledged += 1;
            self.events.push(Event::Acknowledged { id });
        }
    }

    fn send(&mut self, frame: &[u8]) -> Result<(), LinkError> {
        if let Some(c) = self.capture.as_mut() {
            c.push(frame.to_vec());
        }
        let (sock, robot) = match &mut self.wire {
            Wire::Udp { sock, robot, .. } => (sock, *robot),
            Wire::Stream { port, .. } => {
                let mut enc = [0u8; mmic_link::stream::encoded_len(TC_MAX_LEN)];
                let n = mmic_link::stream::encode(frame, &mut enc)
                    .map_err(|e| LinkError::Io(std::io::Error::other(e.to_string())))?;
                // A full send queue drops the frame whole (counted): COP-1 retransmits.
                port.send(&enc[..n])?;
                self.counters.stream_send_dropped = port.send_dropped;
                return Ok(());
            }
        };
        match sock.send_to(frame, robot) {
            Ok(_) => Ok(()),
            // The robot's port not (yet) open, a full buffer: the frame is lost like on
            // a radio link; COP-1 retransmits.
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::ConnectionRefused | std::io::ErrorKind::WouldBlock
                ) =>
            {
                Ok(())
            }
            Err(e) => Err(e.into()),
        }
    }

    fn apply(&mut self, now_ms: u64, fx: mmic_link::fop::Effects<PacketId>) -> Result<(), LinkError> {
        for e in fx {
            match e {
                FopEffect::TransmitAd {
                    ns,
                    fdu,
                    retransmission,
                } => {
                    let Some(p) = self.packets.get(&fdu) else { continue };
                    let mut buf = [0u8; TC_MAX_LEN];
                    let repr = TcRepr {
                        frame_type: FrameType::Ad,
                        scid: mib::link::SCID,
                        vcid: mib::link::tc_vc::COMMAND,
                        seq: ns,
                        data_len: 0,
                    };
                    let n = build_tc(&mut self.tc_sa, &mut self.store, repr, p, &mut buf).map_err(LinkError::Sdls)?;
                    self.send(&buf[..n])?;
                    self.counters.ad_frames_sent += 1;
                    if retransmission {
                        self.counters.retransmissions += 1;
                    }
                    self.events.push(Event::Transmitted {
                        id: fdu,
                        ns,
                        retransmission,
                    });
                }
                FopEffect::TransmitBc(cmd) => {
                    let mut buf = [0u8; 16];
                    if let Some(n) = cmd.build_frame(mib::link::SCID, mib::link::tc_vc::COMMAND, &mut buf) {
                        self.send(&buf[..n])?;
                        self.counters.bc_frames_sent += 1;
                    }
                }
                FopEffect::TransmitBd(id) => {
                    // The link never requests BD; a packet handed back is queued again.
                    self.queue.push_front(id);
                }
                FopEffect::Acknowledged { fdu, .. } => self.delivered(fdu),
                FopEffect::RequestRejected(id) => self.queue.push_front(id),
                FopEffect::NotDelivered { ns, fdu } => self.limbo.push((ns, fdu)),
                FopEffect::Purged(id) => self.purged_wait.push(id),
                FopEffect::Initialised => self.events.push(Event::Initialised { vr: self.fop.vs() }),
                FopEffect::Alert(a) => {
                    self.counters.alerts += 1;
                    self.init_after = self.clcws;
                    self.events.push(Event::Alert(a));
                }
                FopEffect::Suspended(_) => {
                    // Timeout type 1 is not the mission's; resume at once.
                    let fx = self.fop.on_event(now_ms, FopInput::ResumeAd);
                    for e in fx {
                        if let FopEffect::Alert(a) = e {
                            self.events.push(Event::Alert(a));
                        }
                    }
                }
                FopEffect::RequestAccepted
                | FopEffect::DirectiveAccepted
                | FopEffect::DirectiveRejected
                | FopEffect::Event(_) => {}
            }
        }
        Ok(())
    }
}

/// One datagram from the non-blocking socket into `buf`: its length, or `None` when
/// nothing is waiting. ICMP errors of earlier sends (robot not up yet) are passed over.
fn recv_nonblocking(sock: &UdpSocket, buf: &mut [u8]) -> Result<Option<usize>, LinkError> {
    loop {
        match sock.recv_from(buf) {
            Ok((n, _)) => return Ok(Some(n)),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return Ok(None),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
            Err(e) => return Err(e.into()),
        }
    }
}

/// Waits up to `timeout` (rounded up to whole milliseconds) until `sock` is readable:
/// whether it is (an interrupted wait reports false; the caller polls again).
fn wait_readable(sock: &UdpSocket, timeout: Duration) -> Result<bool, LinkError> {
    use nix::poll::{PollFd, PollFlags, PollTimeout};
    use std::os::fd::AsFd;
    let ms = u16::try_from(timeout.as_micros().div_ceil(1000)).unwrap_or(u16::MAX);
    let mut fds = [PollFd::new(sock.as_fd(), PollFlags::POLLIN)];
    match nix::poll::poll(&mut fds, PollTimeout::from(ms)) {
        Ok(n) => Ok(n > 0),
        Err(nix::errno::Errno::EINTR) => Ok(false),
        Err(e) => Err(LinkError::Io(e.into())),
    }
}

#[cfg(test)]
mod stream_tests;
#[cfg(test)]
mod tests;
