//! The space-link frame endpoint of the host obsw (issue 22, phase 2): one UDP socket
//! taking one TC frame per datagram, and TM frames (fixed length, one per datagram) sent
//! to a fixed ground address.
//!
//! Uplink: `mmic_link::rx::TcReceiver` runs CRC → lengths/header → SDLS (AES-256-GCM,
//! anti-replay window) → packet lengths → FARM-1 → the receive IV and FARM-1's state in
//! one in-place write of the state file, `fdatasync`ed (`mmic_link::persist`); only then
//! do the packets of the frame go to `Obsw::handle_tc`. After a restart FARM-1 resumes at
//! the persisted V(R) (and lockout), so the ground's FOP-1 continues. Every refusal is counted by
//! reason (HK SPACE_LINK) and reported by a throttled event; a refused frame changes
//! nothing (no TC, no COP-1 state, no TM destination: TM frames go to `--frame-tm-to`
//! only, whoever sends frames). BC control frames, which come in clear, are taken at most
//! [`CONTROL_FRAMES_PER_S`] per second; the rest are dropped and counted.
//!
//! Downlink: every TM packet the OBSW sends is multiplexed into VC0 frames (SDLS with the
//! TM key); a partly filled frame is flushed at the end of each batch of inputs and each
//! control period, so a reply never waits for a frame to fill. When no frame has gone out
//! for [`IDLE_INTERVAL`], an idle frame on VC7 carries the CLCW; after an authentic TC
//! frame (accepted, discarded or a control frame) the CLCW goes out at once, so the
//! ground's FOP-1 learns of it without waiting. Store replay (PUS 15) packets go on VC1
//! (`TmSink::send_replay`), each channel with its own partial frame.

use std::net::{SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use mib::link::sdls::{ANTI_REPLAY_WINDOW, TC_SPIS, TM_SPIS};
use mib::link::tm_frame::LEN as TM_LEN;
use mmic_link::downlink::{Downlink as Framer, TmVc};
use mmic_link::farm::Farm;
use mmic_link::persist::{read_key, Dir, FileIvStore};
use mmic_link::rx::{RxCounters, RxOutcome, TcReceiver};
use mmic_link::sdls::{RxSa, RxSas, TxSa};
use mmic_link::tc::ControlCommand;
use obsw_core::obsw::SPACE_LINK_PARAMS;

/// Longest time without a TM frame: then an idle frame carries the CLCW.
pub const IDLE_INTERVAL: Duration = Duration::from_millis(100);

/// BC control frames (Unlock, Set V(R): in clear, anyone can send them) taken per second;
/// more are dropped and counted (`LINK_REJ_CONTROL_RATE`). The ground's FOP-1 sends one
/// per T1 (2 s) while it initialises, a few more after a restart.
pub const CONTROL_FRAMES_PER_S: u32 = 5;

/// Whether a datagram's header says BC frame (version 00, bypass 1, control 1).
fn is_control_frame(d: &[u8]) -> bool {
    d.first().is_some_and(|b| b & 0xF0 == 0x30)
}

/// What the command line gives the endpoint.
#[derive(Clone, Debug)]
pub struct FrameConfig {
    pub listen: SocketAddr,
    pub tm_to: SocketAddr,
    pub tc_key: PathBuf,
    pub tm_key: PathBuf,
    pub state: PathBuf,
}

/// A TC frame's outcome, for the main loop.
#[derive(Debug)]
pub enum FrameInput {
    /// The packets of an accepted frame, in order.
    Packets(Vec<Vec<u8>>),
    /// Anything else (refused, discarded, control): already counted.
    Nothing,
}

/// Index of a TM virtual channel in [`FrameEndpoint`]'s pending flags.
const fn vc_index(vc: TmVc) -> usize {
    match vc {
        TmVc::Realtime => 0,
        TmVc::Replay => 1,
    }
}

/// The frame endpoint (see the module documentation).
pub struct FrameEndpoint {
    sock: UdpSocket,
    tm_to: SocketAddr,
    rx: TcReceiver<2>,
    framer: Framer,
    tm_sa: TxSa,
    store: FileIvStore,
    /// Virtual channels holding packet bytes not yet sent in a frame (realtime, replay).
    pending: [bool; 2],
    /// An authentic TC frame changed (or confirmed) the CLCW: send it at once.
    clcw_due: bool,
    last_tx: Instant,
    buf: Vec<u8>,
    /// TM frames the socket refused (counted into the platform's `tm_dropped`).
    pub send_failures: u32,
    /// Counters already reported by events.
    reported: RxCounters,
    last_control: Option<ControlCommand>,
    /// Control frames taken in the current one-second window, and its start.
    control_window: (Instant, u32),
    /// Control frames dropped by the rate limit.
    control_rate_limited: u32,
    reported_rate_limited: u32,
}

impl FrameEndpoint {
    /// Reads the keys, opens the counter state file and binds the socket.
    pub fn open(cfg: &FrameConfig) -> Result<FrameEndpoint> {
        let tc_key = read_key(&cfg.tc_key).context("--tc-key")?;
        let tm_key = read_key(&cfg.tm_key).context("--tm-key")?;
        if tc_key == tm_key {
            anyhow::bail!(
                "--tc-key and --tm-key hold the same key: each direction needs its own (GCM nonces would repeat)"
            );
        }
        let store = FileIvStore::open(&cfg.state).context("--link-state")?;
        let tc_spi = TC_SPIS[0];
        let tm_spi = TM_SPIS[0];
        let rx_sa = match store.get(Dir::Rx, tc_spi) {
            Some(last) => RxSa::resume(tc_spi, &tc_key, ANTI_REPLAY_WINDOW, last),
            None => RxSa::new(tc_spi, &tc_key, ANTI_REPLAY_WINDOW),
        };
        let mut sas = RxSas::default();
        sas.insert(rx_sa)
            .map_err(|_| anyhow::anyhow!("no room for the TC security association"))?;
        if let Some((slot, why)) = store.bad_slot() {
            log::warn!(
                "space link: {} slot {slot} invalid ({why}); the other slot (one write older) was used",
                cfg.state.display()
            );
        }
        // FARM-1 resumes where it was (V(R), lockout, FARM-B): the ground's AD frames in
        // flight continue without a re-initialisation.
        let farm = match store.farm() {
            Some(rec) => {
                log::info!(
                    "space link: FARM-1 resumes at V(R) = {}{}",
                    rec.vr,
                    if rec.lockout { ", in lockout" } else { "" }
                );
                Farm::mission_restored(rec)
            }
            None => Farm::mission(),
        };
        let tm_sa = TxSa::resume(tm_spi, &tm_key, store.get(Dir::Tx, tm_spi).unwrap_or(0));
        let sock = UdpSocket::bind(cfg.listen).with_context(|| format!("cannot bind --frame-udp {}", cfg.listen))?;
        sock.set_nonblocking(true)?;
        Ok(FrameEndpoint {
            sock,
            tm_to: cfg.tm_to,
            rx: TcReceiver::new(mib::link::SCID, mib::link::tc_vc::COMMAND, farm, sas),
            framer: Framer::mission(),
            tm_sa,
            store,
            pending: [false; 2],
            clcw_due: true,
            last_tx: Instant::now(),
            buf: vec![0u8; 65_536],
            send_failures: 0,
            reported: RxCounters::default(),
            last_control: None,
            control_window: (Instant::now(), 0),
            control_rate_limited: 0,
            reported_rate_limited: 0,
        })
    }

    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.sock.local_addr()
    }

    pub fn socket(&self) -> &UdpSocket {
        &self.sock
    }

    /// The next waiting datagram through the receive pipeline, if any (never blocks).
    pub fn next(&mut self) -> Option<FrameInput> {
        let n = loop {
            match self.sock.recv_from(&mut self.buf) {
                Ok((n, _from)) => break n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return None,
                // An ICMP error from an earlier send: not fatal, nothing to read.
                Err(_) => return None,
            }
        };
        let dgram = &mut self.buf[..n];
        if is_control_frame(dgram) {
            let now = Instant::now();
            if now.duration_since(self.control_window.0) >= Duration::from_secs(1) {
                self.control_window = (now, 0);
            }
            if self.control_window.1 >= CONTROL_FRAMES_PER_S {
                self.control_rate_limited = self.control_rate_limited.saturating_add(1);
                return Some(FrameInput::Nothing);
            }
            self.control_window.1 += 1;
        }
        Some(match self.rx.receive(&mut self.store, dgram, true) {
            RxOutcome::Accepted { packets, .. } => {
                self.clcw_due = true;
                FrameInput::Packets(packets.map(<[u8]>::to_vec).collect())
            }
            RxOutcome::Control(c) => {
                self.clcw_due = true;
                self.last_control = Some(c);
                log::warn!("space link: control frame {c:?} executed (in clear)");
                FrameInput::Nothing
            }
            RxOutcome::Discarded(ev) => {
                self.clcw_due = true;
                log::info!("space link: FARM-1 discarded an authentic frame ({ev:?})");
                FrameInput::Nothing
            }
            RxOutcome::Rejected(e) => {
                log::debug!("space link: frame refused: {e}");
                FrameInput::Nothing
            }
        })
    }

    /// Queues one TM packet on `vc` (realtime VC0 or store replay VC1); full frames go out
    /// at once.
    pub fn send_packet(&mut self, packet: &[u8], vc: TmVc) {
        let clcw = self.rx.farm.clcw();
        let (sock, to, fails) = (&self.sock, self.tm_to, &mut self.send_failures);
        let mut sent = false;
        let r = self
            .framer
            .send(vc, packet, clcw, &mut self.tm_sa, &mut self.store, |f| {
                sent = true;
                if !crate::net::send_udp(sock, f, to) {
                    *fails = fails.saturating_add(1);
                }
            });
        if let Err(e) = r {
            log::warn!("space link: TM packet not framed: {e}");
        }
        if sent {
            self.last_tx = Instant::now();
            self.clcw_due = false;
        }
        self.pending[vc_index(vc)] = true;
    }

    /// Sends the partly filled frames of VC0 and VC1, or an idle frame when the CLCW is
    /// due.
    pub fn flush(&mut self, now: Instant) {
        let clcw = self.rx.farm.clcw();
        if self.pending.iter().any(|&p| p) {
            for vc in [TmVc::Realtime, TmVc::Replay] {
                if !std::mem::take(&mut self.pending[vc_index(vc)]) {
                    continue;
                }
                let (sock, to, fails) = (&self.sock, self.tm_to, &mut self.send_failures);
                let r = self.framer.flush(vc, clcw, &mut self.tm_sa, &mut self.store, |f| {
                    if !crate::net::send_udp(sock, f, to) {
                        *fails = fails.saturating_add(1);
                    }
                });
                if let Err(e) = r {
                    log::warn!("space link: TM frame not sent: {e}");
                }
            }
            self.last_tx = now;
            self.clcw_due = false;
            return;
        }
        if self.clcw_due || now.duration_since(self.last_tx) >= IDLE_INTERVAL {
            let mut f = [0u8; TM_LEN];
            self.framer.idle(clcw, &mut f);
            if !crate::net::send_udp(&self.sock, &f, self.tm_to) {
                self.send_failures = self.send_failures.saturating_add(1);
            }
            self.last_tx = now;
            self.clcw_due = false;
        }
    }

    /// The SPACE_LINK HK values, in MIB order (`pid::LINK_AD_ACCEPTED + i`).
    pub fn hk(&self) -> [u32; SPACE_LINK_PARAMS] {
        let c = &self.rx.counters;
        let t = &self.framer.counters;
        let s = |v: &[u32]| v.iter().fold(0u32, |a, b| a.saturating_add(*b));
        [
            c.ad_accepted,
            c.bd_accepted,
            s(&[c.unlock, c.set_vr]),
            c.packets,
            c.bare_packet,
            c.bad_crc,
            c.bad_length,
            c.bad_header,
            c.wrong_scid,
            c.unknown_vc,
            c.sdls_too_short,
            c.unknown_spi,
            c.replay,
            c.bad_mac,
            c.counter_store_failed,
            c.unknown_control,
            c.not_packets,
            s(&[c.farm_e2, c.farm_e3, c.farm_e4, c.farm_e5]),
            self.rx.farm.clcw().emit(),
            t.frames,
            t.idle_frames,
            t.sdls_failed,
            self.control_rate_limited,
        ]
    }

    /// What changed since the last call, as link events: one per refusal reason (code =
    /// HK parameter offset, see `LINK_FRAME_REJECTED`) and one for control frames.
    pub fn events(&mut self) -> Vec<obsw_core::obsw::LinkEvent> {
        use obsw_core::obsw::LinkEvent;
        let now = self.hk();
        let before = {
            let saved = std::mem::replace(&mut self.rx.counters, self.reported);
            let b = self.hk();
            self.rx.counters = saved;
            b
        };
        let mut out = Vec::new();
        // Refusal reasons: the parameter offsets of the LINK_REJ_ counters.
        for reason in (4..=16usize).chain([22]) {
            let before = if reason == 22 {
                self.reported_rate_limited
            } else {
                before[reason]
            };
            if now[reason] != before {
                out.push(LinkEvent::FrameRejected {
                    reason: reason as u8,
                    total: now[reason],
                });
            }
        }
        if now[2] != before[2] {
            let (command, vr) = match self.last_control {
                Some(ControlCommand::SetVr(v)) => (1, v),
                Some(ControlCommand::Unlock) | None => (0, 0),
            };
            out.push(LinkEvent::ControlFrame {
                command,
                vr,
                total: now[2],
            });
        }
        self.reported = self.rx.counters;
        self.reported_rate_limited = self.control_rate_limited;
        out
    }
}
