//! The host obsw's transport of the space link: one UDP socket taking one TC frame per
//! datagram and sending TM frames (fixed length, one per datagram) to a fixed ground
//! address, or a serial line. The link itself — receive pipeline, control-frame gate,
//! FARM-1, TM framer, idle frames, SPACE_LINK counters and link events — is
//! `mmic_link::endpoint::Endpoint`, the same code board A runs; this module keeps the I/O,
//! the key files and the state file (`mmic_link::persist`, each write `O_DSYNC`), and the
//! key change (LINK_SPI_SELECT), which only the host can apply (board A holds one key per
//! direction).
//!
//! A refused frame changes nothing (no TC, no COP-1 state, no TM destination: TM frames
//! go to `--frame-tm-to` only, whoever sends frames). The host flushes the partly filled
//! frames at the end of each batch of inputs and each control period, so a reply never
//! waits for a frame to fill; store replay (PUS 15) packets go on VC1
//! (`TmSink::send_replay`), each channel with its own partial frame.
//!
//! Transport: one frame per UDP datagram (`--frame-udp`, TM to `--frame-tm-to`), or a
//! byte stream (`--frame-serial PATH`: a serial device in raw mode, a pty, or a Unix
//! socket), one COBS frame per transfer frame with `mmic_link::stream` — the framing of
//! board A's serial ground link. The stream's framing drops (oversize, corrupt COBS) are
//! counted ([`FrameEndpoint::stream_counters`]) and reported in `IO_TC_DROPPED`; bytes
//! that decode to a frame go through the same receive pipeline and its counters.

use std::net::{SocketAddr, UdpSocket};
use std::os::fd::{AsRawFd, RawFd};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use mib::link::sdls::{ANTI_REPLAY_WINDOW, TC_SPIS, TM_SPIS};
use mib::link::tm_frame::LEN as TM_LEN;
use mmic_link::downlink::{TmFramer as Framer, TmSecurity, TmVc};
use mmic_link::endpoint::{Endpoint, LinkReport};
use mmic_link::farm::Farm;
use mmic_link::persist::{read_key, Dir, FileIvStore};
use mmic_link::rx::TcReceiver;
use mmic_link::sdls::{Key, RxSa, RxSas, TxSa};
use mmic_link::stream::port::Port;
use mmic_link::stream::{Deframer, StreamCounters};
use obsw_core::obsw::{LinkEvent, SPACE_LINK_PARAMS, SPACE_LINK_STATE_PARAMS};
use obsw_core::services::link::{LinkKeys, LinkSelect};

/// Reads a `--tm-sdls` / TOML `tm_sdls` value (`TmSecurity::NAMES`).
pub fn parse_tm_sdls(s: &str) -> Result<TmSecurity, String> {
    TmSecurity::from_name(s).ok_or_else(|| format!("\"{s}\": encrypt or clear"))
}

/// Where the frames travel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameWire {
    /// TC frames on `listen`, one per datagram; TM frames to `tm_to`.
    Udp { listen: SocketAddr, tm_to: SocketAddr },
    /// Both ways on this serial device, pty or Unix socket, one COBS frame each.
    Serial(PathBuf),
}

/// What the command line gives the endpoint.
#[derive(Clone, Debug)]
pub struct FrameConfig {
    pub wire: FrameWire,
    pub tc_key: PathBuf,
    pub tm_key: PathBuf,
    pub state: PathBuf,
    pub tm_sdls: TmSecurity,
}

/// A TC frame's outcome, for the main loop.
#[derive(Debug)]
pub enum FrameInput {
    /// The packets of an accepted frame, in order.
    Packets(Vec<Vec<u8>>),
    /// Anything else (refused, discarded, control): already counted.
    Nothing,
}

/// Why a key change ([`FrameEndpoint::select_spis`]) was refused. Nothing changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpiError {
    /// No key loaded for this SPI (or not an SPI of that direction).
    NoKey(u16),
    /// No TC SPI would be left to accept frames.
    NoTcSpi,
    /// The state file could not be written.
    StoreFailed,
}

impl std::fmt::Display for SpiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SpiError::NoKey(s) => write!(f, "no key loaded for SPI {s}"),
            SpiError::NoTcSpi => write!(f, "no TC SPI would be left"),
            SpiError::StoreFailed => write!(f, "the link state file could not be written"),
        }
    }
}

/// The key file of spare `spi` beside the first one (`tc-spiN.key` / `tm-spiN.key` in the
/// folder of `--tc-key` / `--tm-key`, the layout of `ground keys create`), if there.
fn spare_key(first: &Path, spi: u16) -> Result<Option<Key>> {
    let dir = if TM_SPIS.contains(&spi) { "tm" } else { "tc" };
    let p = first.with_file_name(format!("{dir}-spi{spi}.key"));
    if p == first || !p.exists() {
        return Ok(None);
    }
    read_key(&p)
        .map(Some)
        .with_context(|| format!("spare key of SPI {spi}"))
}

/// The TM SA of `spi` at its stored high-water mark, if its key is loaded.
fn tx_sa(tm_keys: &[(u16, Key)], spi: u16, store: &FileIvStore) -> Option<TxSa> {
    let (_, key) = tm_keys.iter().find(|(s, _)| *s == spi)?;
    Some(TxSa::resume(spi, key, store.get(Dir::Tx, spi).unwrap_or(0)))
}

fn rx_sa(spi: u16, key: &Key, store: &FileIvStore) -> RxSa {
    match store.get(Dir::Rx, spi) {
        Some(last) => RxSa::resume(spi, key, ANTI_REPLAY_WINDOW, last),
        None => RxSa::new(spi, key, ANTI_REPLAY_WINDOW),
    }
}

/// The receive SAs of the TC keys not retired.
fn rx_sas(tc_keys: &[(u16, Key)], retired: u8, store: &FileIvStore) -> RxSas<2> {
    let mut sas = RxSas::default();
    for (spi, key) in tc_keys {
        let i = TC_SPIS.iter().position(|s| s == spi).unwrap_or(usize::MAX);
        if i < 8 && retired & (1 << i) != 0 {
            continue;
        }
        // Two TC SPIs, two places.
        let _ = sas.insert(rx_sa(*spi, key, store));
    }
    sas
}

/// Applies a LINK_SPI_SELECT the core executed (`Obsw::link_select`), before the next
/// input. The core checked the keys ([`FrameEndpoint::link_keys`]); what can still fail
/// here is the state file write: logged, the selection not applied (HK and the CLCW show
/// the SPIs in use).
pub fn apply_select(sel: &mut Option<LinkSelect>, ep: Option<&mut FrameEndpoint>) {
    let Some(s) = sel.take() else { return };
    let Some(ep) = ep else {
        log::error!("space link: LINK_SPI_SELECT without a frame link (not applied)");
        return;
    };
    if let Err(e) = ep.select_spis(s.tm_spi, &s.tc_spi_list()) {
        log::error!(
            "space link: LINK_SPI_SELECT TM {} TC mask {:#04b} not applied: {e}",
            s.tm_spi,
            s.tc_spis
        );
    }
}

/// The endpoint's transport.
enum Wire {
    Udp {
        sock: UdpSocket,
        tm_to: SocketAddr,
    },
    Stream {
        port: Port,
        de: Box<Deframer<{ mib::link::tc_frame::MAX_LEN }>>,
        /// Bytes read and not yet fed to the deframer: `inbuf[at..len]`.
        inbuf: Vec<u8>,
        at: usize,
        len: usize,
        /// The read error last logged (logged once).
        failed: bool,
    },
}

impl Wire {
    /// Sends one TM frame; false when it could not go (counted by the caller).
    fn send(&mut self, f: &[u8]) -> bool {
        match self {
            Wire::Udp { sock, tm_to } => crate::net::send_udp(sock, f, *tm_to),
            Wire::Stream { port, .. } => {
                let mut enc = [0u8; mmic_link::stream::encoded_len(TM_LEN)];
                match mmic_link::stream::encode(f, &mut enc) {
                    Ok(n) => matches!(port.send(&enc[..n]), Ok(true)),
                    Err(_) => false,
                }
            }
        }
    }
}

/// The frame endpoint (see the module documentation).
pub struct FrameEndpoint {
    port: Wire,
    ep: Endpoint<FileIvStore, 2, 3>,
    /// Time 0 of the endpoint's clock (ms).
    epoch: Instant,
    /// TM keys loaded (SPI, key), `TM_SPIS` order.
    tm_keys: Vec<(u16, Key)>,
    /// TC keys loaded (SPI, key); which are retired is in the state file.
    tc_keys: Vec<(u16, Key)>,
    buf: Vec<u8>,
    /// TM frames the socket refused (counted into the platform's `tm_dropped`).
    pub send_failures: u32,
    /// UDP with [`FrameEndpoint::track_readiness`]: whether a datagram may be waiting (set
    /// by the main loop's poll, cleared when a read would block), so that a drained socket
    /// costs no system call per wake-up. `None`: every [`FrameEndpoint::next`] reads.
    readable: Option<bool>,
}

impl FrameEndpoint {
    /// Reads the keys, opens the counter state file and binds the socket.
    pub fn open(cfg: &FrameConfig) -> Result<FrameEndpoint> {
        let tc_key = read_key(&cfg.tc_key).context("--tc-key")?;
        let tm_key = read_key(&cfg.tm_key).context("--tm-key")?;
        // The spare SPIs' keys (key change without downtime), when their files are there.
        let mut tc_keys = vec![(TC_SPIS[0], tc_key)];
        let mut tm_keys = vec![(TM_SPIS[0], tm_key)];
        for &spi in &TC_SPIS[1..] {
            if let Some(k) = spare_key(&cfg.tc_key, spi)? {
                tc_keys.push((spi, k));
            }
        }
        for &spi in &TM_SPIS[1..] {
            if let Some(k) = spare_key(&cfg.tm_key, spi)? {
                tm_keys.push((spi, k));
            }
        }
        let all: Vec<&Key> = tc_keys.iter().chain(&tm_keys).map(|(_, k)| k).collect();
        if (1..all.len()).any(|i| all[..i].contains(&all[i])) {
            anyhow::bail!(
                "two of the space link's key files (--tc-key, --tm-key and their spares) hold the same key: \
                 each SPI and direction needs its own (GCM nonces would repeat)"
            );
        }
        let store = FileIvStore::open(&cfg.state).context("--link-state")?;
        if let Some((slot, why)) = store.bad_slot() {
            log::warn!(
                "space link: {} slot {slot} invalid ({why}); the other slot (one write older) was used",
                cfg.state.display()
            );
        }
        let tm_spi = store.record().tm_spi.unwrap_or(TM_SPIS[0]);
        let tm_sa = tx_sa(&tm_keys, tm_spi, &store).with_context(|| {
            format!(
                "{}: TM SPI {tm_spi} was selected, but its key file ({}) is missing",
                cfg.state.display(),
                cfg.tm_key.with_file_name(format!("tm-spi{tm_spi}.key")).display()
            )
        })?;
        let tc_retired = store.record().tc_retired;
        let sas = rx_sas(&tc_keys, tc_retired, &store);
        if sas.is_empty() {
            anyhow::bail!(
                "{}: every TC SPI with a key file is retired (retired mask {tc_retired:#04b}): no TC could be accepted",
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
        log::info!(
            "space link: TC SPIs {:?} accepted, TM SPI {tm_spi}",
            tc_keys
                .iter()
                .map(|(s, _)| *s)
                .filter(|s| sas.get(*s).is_some())
                .collect::<Vec<_>>()
        );
        let port = match &cfg.wire {
            FrameWire::Udp { listen, tm_to } => {
                let sock = UdpSocket::bind(listen).with_context(|| format!("cannot bind --frame-udp {listen}"))?;
                sock.set_nonblocking(true)?;
                Wire::Udp { sock, tm_to: *tm_to }
            }
            FrameWire::Serial(path) => Wire::Stream {
                port: mmic_link::stream::port::open(path)
                    .with_context(|| format!("cannot open --frame-serial {}", path.display()))?,
                de: Box::default(),
                inbuf: vec![0u8; 4096],
                at: 0,
                len: 0,
                failed: false,
            },
        };
        let rx = TcReceiver::new(mib::link::SCID, mib::link::tc_vc::COMMAND, farm, sas);
        Ok(FrameEndpoint {
            port,
            ep: Endpoint::new(
                rx,
                Framer::with_security(mib::link::SCID, cfg.tm_sdls),
                Some(tm_sa),
                store,
            ),
            epoch: Instant::now(),
            tm_keys,
            tc_keys,
            buf: vec![0u8; 65_536],
            send_failures: 0,
            readable: None,
        })
    }

    /// Key change without downtime: TM from now on under `tm_spi`, TC accepted under the
    /// SPIs of `tc_active` only (the others retired: refused as unknown SPI until activated
    /// again). Stored in the state file before it takes effect, so it survives restarts.
    /// Refused, changing nothing, for an SPI without a loaded key or an empty TC set.
    pub fn select_spis(&mut self, tm_spi: u16, tc_active: &[u16]) -> Result<(), SpiError> {
        let tm_sa = tx_sa(&self.tm_keys, tm_spi, self.ep.store()).ok_or(SpiError::NoKey(tm_spi))?;
        if tc_active.is_empty() {
            return Err(SpiError::NoTcSpi);
        }
        if let Some(&s) = tc_active.iter().find(|s| !self.tc_keys.iter().any(|(k, _)| k == *s)) {
            return Err(SpiError::NoKey(s));
        }
        let retired = TC_SPIS
            .iter()
            .enumerate()
            .filter(|(_, s)| !tc_active.contains(s))
            .fold(0u8, |m, (i, _)| m | 1 << i);
        self.ep
            .store_mut()
            .put_selection(tm_spi, retired)
            .map_err(|_| SpiError::StoreFailed)?;
        // The SA in use keeps its counter; another resumes at its stored high-water mark.
        if self.ep.tm_sa().map(TxSa::spi) != Some(tm_spi) {
            self.ep.set_tm_sa(tm_sa);
        }
        // SAs: the retired ones go, the activated ones come back at their stored counter.
        let fresh = rx_sas(&self.tc_keys, retired, self.ep.store());
        for &spi in TC_SPIS.iter() {
            match fresh.get(spi) {
                Some(_) if self.ep.rx.sas.get(spi).is_some() => {}
                Some(_) => {
                    let key = self.tc_keys.iter().find(|(s, _)| *s == spi).map(|(_, k)| *k);
                    if let Some(k) = key {
                        let sa = rx_sa(spi, &k, self.ep.store());
                        let _ = self.ep.rx.sas.insert(sa);
                    }
                }
                None => {
                    self.ep.rx.sas.remove(spi);
                }
            }
        }
        log::warn!("space link: SPIs selected: TM {tm_spi}, TC {tc_active:?}");
        Ok(())
    }

    /// The keys loaded, for the core's LINK_SPI_SELECT check (`Obsw::link_keys`).
    pub fn link_keys(&self) -> LinkKeys {
        let mask = |spis: &[u16], has: &dyn Fn(u16) -> bool| {
            spis.iter()
                .enumerate()
                .filter(|(_, s)| has(**s))
                .fold(0u8, |m, (i, _)| m | 1 << i)
        };
        LinkKeys {
            tm: mask(&TM_SPIS, &|s| self.tm_keys.iter().any(|(k, _)| *k == s)),
            tc: mask(&TC_SPIS, &|s| self.tc_keys.iter().any(|(k, _)| *k == s)),
        }
    }

    /// The TM SPI in use and the TC SPIs accepted.
    #[cfg(test)]
    pub fn spis(&self) -> (u16, Vec<u16>) {
        let tc = TC_SPIS
            .iter()
            .copied()
            .filter(|s| self.ep.rx.sas.get(*s).is_some())
            .collect();
        (self.ep.tm_sa().map_or(0, TxSa::spi), tc)
    }

    /// The UDP address TC frames arrive at (`None` on a serial link).
    pub fn local_addr(&self) -> std::io::Result<Option<SocketAddr>> {
        match &self.port {
            Wire::Udp { sock, .. } => sock.local_addr().map(Some),
            Wire::Stream { .. } => Ok(None),
        }
    }

    /// The descriptor the main loop waits on (readable when a frame may be waiting).
    pub fn raw_fd(&self) -> RawFd {
        match &self.port {
            Wire::Udp { sock, .. } => sock.as_raw_fd(),
            Wire::Stream { port, .. } => port.raw_fd(),
        }
    }

    /// From now on the UDP socket is read only after [`FrameEndpoint::set_readable`] (the
    /// caller's edge-triggered poll watches [`FrameEndpoint::raw_fd`]) until a read would
    /// block. No effect on a stream, which is read at every call.
    pub fn track_readiness(&mut self) {
        if matches!(self.port, Wire::Udp { .. }) {
            self.readable = Some(true);
        }
    }

    /// The poll reported the descriptor readable.
    pub fn set_readable(&mut self) {
        if let Some(r) = self.readable.as_mut() {
            *r = true;
        }
    }

    /// What the stream's framing saw (zero on UDP).
    pub fn stream_counters(&self) -> StreamCounters {
        match &self.port {
            Wire::Udp { .. } => StreamCounters::default(),
            Wire::Stream { de, .. } => de.counters,
        }
    }

    /// The next frame waiting, into `self.buf`: its length (never blocks).
    fn receive(&mut self) -> Option<usize> {
        match &mut self.port {
            Wire::Udp { sock, .. } => loop {
                if self.readable == Some(false) {
                    return None;
                }
                match sock.recv_from(&mut self.buf) {
                    Ok((n, _from)) => return Some(n),
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                        if let Some(r) = self.readable.as_mut() {
                            *r = false;
                        }
                        return None;
                    }
                    // An ICMP error from an earlier send: not fatal, nothing to read.
                    Err(_) => return None,
                }
            },
            Wire::Stream {
                port,
                de,
                inbuf,
                at,
                len,
                failed,
            } => loop {
                while *at < *len {
                    let b = inbuf[*at];
                    *at += 1;
                    // A dropped frame is counted by the deframer (HK IO_TC_DROPPED).
                    if let Some(Ok(f)) = de.push(b) {
                        self.buf[..f.len()].copy_from_slice(f);
                        return Some(f.len());
                    }
                }
                match port.read(inbuf) {
                    Ok(0) => return None,
                    Ok(n) => {
                        (*at, *len) = (0, n);
                    }
                    Err(e) => {
                        if !std::mem::replace(failed, true) {
                            log::error!("space link: reading {}: {e}", port.describe);
                        }
                        return None;
                    }
                }
            },
        }
    }

    /// The endpoint's clock: ms since it was opened.
    fn ms(&self, t: Instant) -> u64 {
        t.saturating_duration_since(self.epoch).as_millis() as u64
    }

    /// The next waiting frame through the receive pipeline, if any (never blocks).
    pub fn next(&mut self) -> Option<FrameInput> {
        let n = self.receive()?;
        Some(match self.ep.receive(&mut self.buf[..n]) {
            Some(packets) => FrameInput::Packets(packets.map(<[u8]>::to_vec).collect()),
            None => FrameInput::Nothing,
        })
    }

    /// Queues one TM packet on `vc` (realtime VC0 or store replay VC1); full frames go out
    /// at once.
    pub fn send_packet(&mut self, packet: &[u8], vc: TmVc) {
        let (port, fails) = (&mut self.port, &mut self.send_failures);
        self.ep.send(vc, packet, |f| {
            if !port.send(f) {
                *fails = fails.saturating_add(1);
            }
        });
    }

    /// Sends the partly filled frames of VC0 and VC1, or an idle frame when the CLCW is
    /// due.
    pub fn flush(&mut self, now: Instant) {
        if let Wire::Stream { port, .. } = &mut self.port {
            // Bytes the line did not take yet (a slow or full line).
            if let Err(e) = port.flush() {
                log::debug!("space link: writing {}: {e}", port.describe);
            }
        }
        let now = self.ms(now);
        let (port, fails) = (&mut self.port, &mut self.send_failures);
        self.ep.flush(now, |f| {
            if !port.send(f) {
                *fails = fails.saturating_add(1);
            }
        });
    }

    /// The SPACE_LINK HK values, in MIB order (`mmic_link::hk`).
    pub fn hk(&self) -> [u32; SPACE_LINK_PARAMS] {
        self.ep.hk()
    }

    /// The link state HK values, in MIB order (`pid::LINK_TM_SPI + i`): TM SPI in use, TC
    /// SPIs accepted (mask), state writes since boot, the slot found bad at start.
    pub fn hk_state(&self) -> [u32; SPACE_LINK_STATE_PARAMS] {
        let tc = TC_SPIS
            .iter()
            .enumerate()
            .filter(|(_, s)| self.ep.rx.sas.get(**s).is_some())
            .fold(0u8, |m, (i, _)| m | 1 << i);
        self.ep.state_values(tc)
    }

    /// What changed since the last call, as link events (`Endpoint::report`).
    pub fn events(&mut self) -> Vec<LinkEvent> {
        let mut out = Vec::new();
        self.ep.report(|r| out.push(link_event(r)));
        out
    }
}

/// The OBSW's event for a link report.
pub fn link_event(r: LinkReport) -> LinkEvent {
    match r {
        LinkReport::Rejected { reason, total } => LinkEvent::FrameRejected { reason, total },
        LinkReport::ControlFrame { command, vr, total } => LinkEvent::ControlFrame { command, vr, total },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ground_link::{create_key_file, Config, GroundFrameLink};
    use mmic_link::fop::FopState;
    use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B, TEST_KEY_TM_A, TEST_KEY_TM_B};
    use std::time::Duration;

    /// A robot that echoes every TC packet it accepts as TM (the host loop's frame part).
    fn serve(ep: &mut FrameEndpoint, got: &mut Vec<Vec<u8>>) {
        while let Some(fi) = ep.next() {
            if let FrameInput::Packets(ps) = fi {
                for p in ps {
                    ep.send_packet(&p, TmVc::Realtime);
                    got.push(p);
                }
            }
        }
        ep.flush(Instant::now());
    }

    fn packet(n: u8) -> Vec<u8> {
        vec![0x18, 0x01, 0xC0, n, 0x00, 0x01, n, 0x5A]
    }

    /// Runs robot and ground until `done` or 10 s.
    fn run(
        ep: &mut FrameEndpoint,
        got: &mut Vec<Vec<u8>>,
        g: &mut GroundFrameLink,
        echoes: &mut Vec<Vec<u8>>,
        mut done: impl FnMut(&GroundFrameLink, &[Vec<u8>], &[Vec<u8>]) -> bool,
    ) {
        let t0 = Instant::now();
        while !done(g, got, echoes) {
            serve(ep, got);
            echoes.extend(g.poll(g.now_ms()).unwrap());
            std::thread::sleep(Duration::from_millis(1));
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "timed out: got {} echoes {}",
                got.len(),
                echoes.len()
            );
        }
    }

    // verifies: LINK-KEYCHG-01
    #[test]
    fn tc_spi_1_to_2_and_tm_spi_17_to_18_without_a_tc_lost_and_the_choice_survives_a_restart() {
        let dir = std::env::temp_dir().join(format!("obsw-frames-spi-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for (f, k) in [
            ("tc-spi1.key", TEST_KEY_TC_A),
            ("tc-spi2.key", TEST_KEY_TC_B),
            ("tm-spi17.key", TEST_KEY_TM_A),
            ("tm-spi18.key", TEST_KEY_TM_B),
        ] {
            create_key_file(&dir.join(f), &k).unwrap();
        }
        let ground_sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        let ground_addr = ground_sock.local_addr().unwrap();
        drop(ground_sock);
        let fc = FrameConfig {
            wire: FrameWire::Udp {
                listen: "127.0.0.1:0".parse().unwrap(),
                tm_to: ground_addr,
            },
            tc_key: dir.join("tc-spi1.key"),
            tm_key: dir.join("tm-spi17.key"),
            state: dir.join("obsw.state"),
            tm_sdls: TmSecurity::Encrypt,
        };
        let mut ep = FrameEndpoint::open(&fc).unwrap();
        assert_eq!(ep.spis(), (17, vec![1, 2]), "both TC keys loaded");
        let robot = ep.local_addr().unwrap().unwrap();
        let mut cfg = Config::from_key_dir(robot, ground_addr, &dir, &dir.join("ground.state"), 1).unwrap();
        cfg.fop.t1_ms = 300;
        let mut g = GroundFrameLink::open(cfg).unwrap();
        let (mut got, mut echoes) = (Vec::new(), Vec::new());
        run(&mut ep, &mut got, &mut g, &mut echoes, |g, _, _| {
            g.fop_state() == FopState::Active
        });

        // Under SPI 1; then the ground switches to SPI 2 with frames still outstanding.
        g.capture(true);
        for n in 0..4 {
            g.send_packet(&packet(n)).unwrap();
        }
        g.poll(g.now_ms()).unwrap();
        g.switch_tc_spi(2, &TEST_KEY_TC_B).unwrap();
        for n in 4..8 {
            g.send_packet(&packet(n)).unwrap();
        }
        run(&mut ep, &mut got, &mut g, &mut echoes, |g, got, _| {
            got.len() >= 8 && g.pending() == 0
        });
        let spis: Vec<u16> = g
            .take_captured()
            .iter()
            .map(|f| u16::from_be_bytes([f[5], f[6]]))
            .collect();
        assert!(
            spis.contains(&1) && spis.contains(&2),
            "frames under both SPIs: {spis:?}"
        );
        assert_eq!(
            got,
            (0..8).map(packet).collect::<Vec<_>>(),
            "each TC exactly once, in order"
        );

        // The robot retires TC SPI 1 and sends TM under SPI 18.
        assert_eq!(ep.select_spis(19, &[2]), Err(SpiError::NoKey(19)));
        assert_eq!(ep.select_spis(18, &[]), Err(SpiError::NoTcSpi));
        assert_eq!(ep.spis(), (17, vec![1, 2]), "a refused change changes nothing");
        let tm18 = g.tm_last_iv(18);
        ep.select_spis(18, &[2]).unwrap();
        g.send_packet(&packet(8)).unwrap();
        run(&mut ep, &mut got, &mut g, &mut echoes, |_, got, e| {
            got.len() >= 9 && e.contains(&packet(8))
        });
        assert_ne!(g.tm_last_iv(18), tm18, "TM now under SPI 18, and the ground reads it");

        // A ground still on SPI 1 is refused (unknown SPI) and nothing executes; back on
        // SPI 2, COP-1 retransmits and the TC arrives, once.
        g.switch_tc_spi(1, &TEST_KEY_TC_A).unwrap();
        g.send_packet(&packet(9)).unwrap();
        let t0 = Instant::now();
        while ep_unknown_spi(&ep) == 0 {
            serve(&mut ep, &mut got);
            echoes.extend(g.poll(g.now_ms()).unwrap());
            std::thread::sleep(Duration::from_millis(1));
            assert!(t0.elapsed() < Duration::from_secs(10));
        }
        assert_eq!(got.len(), 9);
        g.switch_tc_spi(2, &TEST_KEY_TC_B).unwrap();
        run(&mut ep, &mut got, &mut g, &mut echoes, |g, got, _| {
            got.len() >= 10 && g.pending() == 0
        });
        assert_eq!(got, (0..10).map(packet).collect::<Vec<_>>());

        // The choice survives a restart of the robot.
        drop(ep);
        let mut ep = FrameEndpoint::open(&FrameConfig {
            wire: FrameWire::Udp {
                listen: robot,
                tm_to: ground_addr,
            },
            ..fc
        })
        .unwrap();
        assert_eq!(ep.spis(), (18, vec![2]));
        g.send_packet(&packet(10)).unwrap();
        run(&mut ep, &mut got, &mut g, &mut echoes, |g, got, _| {
            got.len() >= 11 && g.pending() == 0
        });
        assert_eq!(got.last(), Some(&packet(10)));
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn ep_unknown_spi(ep: &FrameEndpoint) -> u32 {
        ep.ep.rx.counters.unknown_spi
    }
}
