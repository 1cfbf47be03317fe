//! The downlink: TM frames built on board ([`TmFramer`]) and read on the ground
//! ([`TmReceiver`]).
//!
//! Virtual channels (`mib::link::tm_vc`): VC0 realtime and VC1 store replay carry packets,
//! SDLS-protected with the TM SA ([`TmSecurity::Encrypt`], the default) or in clear
//! ([`TmSecurity::Clear`]: no security header or trailer, a 1012-byte packet zone — a
//! configuration for grounds without SDLS on TM); VC7 carries idle frames in clear (only
//! idle data, first header pointer 0x7FE). Every frame carries the CLCW in its OCF —
//! outside the SDLS MAC, as 355.0-B-2 and Yamcs place it — and a FECF. The master channel
//! frame count runs over all VCs, each VC has its own count.

use core::fmt;

use mib::link::tm_frame::{CLEAR_DATA_LEN, HEADER_LEN, LEN, SECURE_DATA_LEN};
use mib::link::tm_vc;

use crate::clcw::{Clcw, ClcwError};
use crate::mux::{DemuxCounters, MuxError, PacketDemux, PacketMux, Zone};
use crate::sdls::{IvStore, RxSas, SdlsError, Sealing, TxSa};
use crate::tm::{FirstHeaderPointer, TmError, TmFrame, TmRepr};

/// How the packet-carrying TM frames (VC0, VC1) are protected. Both ends must agree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TmSecurity {
    /// SDLS authenticated encryption (AES-256-GCM, the TM SA): 982-byte packet zone.
    #[default]
    Encrypt,
    /// No SDLS: the data field is the 1012-byte packet zone. TM is then readable and
    /// forgeable on the path (TC frames stay authenticated).
    Clear,
}

impl TmSecurity {
    /// The configuration names (`--tm-sdls`, TOML `tm_sdls`), one per setting.
    pub const NAMES: [(&'static str, TmSecurity); 2] = [("encrypt", TmSecurity::Encrypt), ("clear", TmSecurity::Clear)];

    /// The setting named `name` ([`TmSecurity::NAMES`]).
    pub fn from_name(name: &str) -> Option<TmSecurity> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
    }

    /// The packet zone of a VC0/VC1 frame.
    pub fn zone_len(self) -> usize {
        match self {
            TmSecurity::Encrypt => SECURE_DATA_LEN,
            TmSecurity::Clear => CLEAR_DATA_LEN,
        }
    }
}

/// The packet-carrying TM virtual channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TmVc {
    Realtime,
    Replay,
    /// CFDP PDU packets (`mib::link::tm_vc::FILES`).
    Files,
}

impl TmVc {
    /// Every packet-carrying VC, in the order of their packet zones.
    pub const ALL: [TmVc; 3] = [TmVc::Realtime, TmVc::Replay, TmVc::Files];

    pub fn id(self) -> u8 {
        match self {
            TmVc::Realtime => tm_vc::REALTIME,
            TmVc::Replay => tm_vc::REPLAY,
            TmVc::Files => tm_vc::FILES,
        }
    }

    /// The VC's index in [`TmVc::ALL`] (its packet zone in a framer with every zone).
    pub const fn index(self) -> usize {
        match self {
            TmVc::Realtime => 0,
            TmVc::Replay => 1,
            TmVc::Files => 2,
        }
    }

    /// The packet-carrying VC with the identifier `id`.
    pub fn from_id(id: u8) -> Option<TmVc> {
        Self::ALL.into_iter().find(|vc| vc.id() == id)
    }
}

/// Why a TM frame could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DownlinkError {
    Packet(MuxError),
    Sdls(SdlsError),
}

impl fmt::Display for DownlinkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DownlinkError::Packet(MuxError::NotAPacket) => write!(f, "not a space packet"),
            DownlinkError::Sdls(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for DownlinkError {}

/// Frame counters of the downlink, for HK.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TxCounters {
    pub frames: u32,
    pub idle_frames: u32,
    /// Frames not sent because SDLS failed (counter store): their packets are lost.
    pub sdls_failed: u32,
    /// Frames not built because [`SEAL_QUEUE`] frames already waited for their
    /// encryption (deferred sealing only): their packets are lost to the live downlink.
    pub seal_queue_full: u32,
}

/// Frames that can wait for their encryption when sealing is deferred
/// ([`TmFramer::defer_sealing`]); a frame that fills beyond them is not built, and counted.
pub const SEAL_QUEUE: usize = 2;

/// A TM frame built (header, security header, packet zone) whose encryption runs in
/// [`TmFramer::seal`] steps.
#[derive(Debug)]
struct Unsealed {
    frame: [u8; LEN],
    sealing: Sealing,
}

/// The on-board TM framer: master and VC counters and `ZONES` packet multiplexers.
///
/// `ZONES = 3` (the default, the host): one packet zone per packet-carrying VC, realtime
/// on VC0, store replays on VC1, CFDP PDUs on VC2. `ZONES = 1` (board A, whose PUS 15
/// replays go on VC0, `TmSink::send_replay`'s default, and which has no CFDP entity yet):
/// only VC0's zone exists — a packet sent on another VC goes into the VC0 zone and out on
/// VC0 — and the framer is two packet zones (2 × 1012 bytes) smaller. (`ZONES = 2`: VC0 and
/// VC1; file packets go on VC0.)
#[derive(Debug)]
pub struct TmFramer<const ZONES: usize = 3> {
    scid: u16,
    security: TmSecurity,
    mc: u8,
    vc: [u8; 8],
    zones: [PacketMux<CLEAR_DATA_LEN>; ZONES],
    pub counters: TxCounters,
    /// Frames are encrypted in [`TmFramer::seal`] steps instead of when they fill.
    deferred: bool,
    unsealed: heapless::Deque<Unsealed, SEAL_QUEUE>,
}

struct FrameCtx<'a, S: IvStore, O: FnMut(&[u8])> {
    scid: u16,
    mc: &'a mut u8,
    vc: &'a mut [u8; 8],
    counters: &'a mut TxCounters,
    clcw: u32,
    security: TmSecurity,
    sa: &'a mut TxSa,
    store: &'a mut S,
    out: O,
    err: Option<SdlsError>,
    /// `Some`: the frame waits here for [`TmFramer::seal`].
    defer: Option<&'a mut heapless::Deque<Unsealed, SEAL_QUEUE>>,
}

impl<S: IvStore, O: FnMut(&[u8])> FrameCtx<'_, S, O> {
    fn secure(&mut self, vcid: u8, z: Zone<'_>) {
        if self.security == TmSecurity::Encrypt && self.defer.as_ref().is_some_and(|q| q.is_full()) {
            self.counters.seal_queue_full = self.counters.seal_queue_full.saturating_add(1);
            return;
        }
        let mut buf = [0u8; LEN];
        let repr = TmRepr {
            scid: self.scid,
            vcid,
            mc_count: *self.mc,
            vc_count: self.vc[usize::from(vcid & 7)],
            fhp: z.fhp,
        };
        let mut f = TmFrame::new_unchecked(&mut buf[..]);
        repr.emit(&mut f);
        match self.security {
            TmSecurity::Encrypt => {
                let p = HEADER_LEN + mib::link::sdls::HEADER_LEN;
                buf[p..p + SECURE_DATA_LEN].copy_from_slice(z.data);
                if let Some(q) = self.defer.as_mut() {
                    match self.sa.begin_tm(self.store, &mut buf) {
                        Ok(sealing) => {
                            // Room checked above.
                            let _ = q.push_back(Unsealed { frame: buf, sealing });
                            *self.mc = self.mc.wrapping_add(1);
                            let c = &mut self.vc[usize::from(vcid & 7)];
                            *c = c.wrapping_add(1);
                        }
                        Err(e) => {
                            self.counters.sdls_failed = self.counters.sdls_failed.saturating_add(1);
                            self.err = Some(e);
                        }
                    }
                    return;
                }
                if let Err(e) = self.sa.apply_tm(self.store, &mut buf) {
                    self.counters.sdls_failed = self.counters.sdls_failed.saturating_add(1);
                    self.err = Some(e);
                    return;
                }
            }
            TmSecurity::Clear => buf[HEADER_LEN..HEADER_LEN + CLEAR_DATA_LEN].copy_from_slice(z.data),
        }
        let mut f = TmFrame::new_unchecked(&mut buf[..]);
        f.set_ocf(self.clcw);
        f.fill_fecf();
        *self.mc = self.mc.wrapping_add(1);
        let c = &mut self.vc[usize::from(vcid & 7)];
        *c = c.wrapping_add(1);
        self.counters.frames = self.counters.frames.saturating_add(1);
        (self.out)(&buf);
    }
}

impl TmFramer {
    /// A framer with SDLS on VC0/VC1 ([`TmSecurity::Encrypt`]).
    pub fn new(scid: u16) -> TmFramer {
        TmFramer::with_security(scid, TmSecurity::Encrypt)
    }

    pub fn with_security(scid: u16, security: TmSecurity) -> TmFramer {
        TmFramer::with_zones(scid, security)
    }

    pub fn mission() -> TmFramer {
        TmFramer::new(mib::link::SCID)
    }
}

impl TmFramer<1> {
    /// The mission's framer with SDLS and only VC0's packet zone (board A: replays go on
    /// VC0 as well).
    pub fn mission_realtime_only() -> TmFramer<1> {
        TmFramer::with_zones(mib::link::SCID, TmSecurity::Encrypt)
    }
}

impl<const ZONES: usize> TmFramer<ZONES> {
    /// A framer with `ZONES` packet zones (1: VC0 only, 2: VC0 and VC1, 3: VC0, VC1, VC2).
    pub fn with_zones(scid: u16, security: TmSecurity) -> TmFramer<ZONES> {
        const {
            assert!(
                ZONES >= 1 && ZONES <= TmVc::ALL.len(),
                "a TM framer has 1 to 3 packet zones"
            )
        };
        TmFramer {
            scid,
            security,
            mc: 0,
            vc: [0; 8],
            zones: core::array::from_fn(|_| PacketMux::with_len(security.zone_len())),
            counters: TxCounters::default(),
            deferred: false,
            unsealed: heapless::Deque::new(),
        }
    }

    /// From now on a filled frame waits (at most [`SEAL_QUEUE`] of them) and is encrypted
    /// in [`TmFramer::seal`] steps, so that the caller bounds the SDLS work per control
    /// period. The frame counts are the frames' build order, which is their send order.
    pub fn defer_sealing(&mut self) {
        self.deferred = true;
    }

    /// Frames waiting for their encryption.
    pub fn unsealed(&self) -> usize {
        self.unsealed.len()
    }

    /// Bytes of packets `vc` takes now without a frame being dropped, when the caller
    /// takes `frames` more frames (those waiting for their encryption included): the
    /// zones that may fill, and the next one short of full.
    pub fn room(&self, vc: TmVc, frames: usize) -> usize {
        // A VC without its zone (ZONES too small) sends on VC0, as `send` does.
        let i = if vc.index() < ZONES { vc.index() } else { 0 };
        let zone = &self.zones[i];
        let frames = frames.saturating_sub(self.unsealed.len());
        let fill = if self.deferred {
            frames.min(SEAL_QUEUE - self.unsealed.len())
        } else {
            frames
        };
        match fill {
            0 => zone.free().saturating_sub(1),
            n => zone.free() + n * zone.zone_len() - 1,
        }
    }

    /// Continues the oldest waiting frame's encryption by at most `work` GCM work blocks
    /// ([`crate::gcm`]); a frame finished gets the CLCW of now and its FECF and goes to
    /// `out`. False when no frame waits.
    pub fn seal(&mut self, work: usize, clcw: Clcw, sa: &TxSa, mut out: impl FnMut(&[u8])) -> bool {
        let Some(u) = self.unsealed.front_mut() else {
            return false;
        };
        if u.sealing.spi() != sa.spi() {
            // Begun under the SA in use before a key change: its IV and key are that
            // SA's, so it cannot be finished; its packets are lost to the live downlink.
            self.unsealed.pop_front();
            self.counters.sdls_failed = self.counters.sdls_failed.saturating_add(1);
            return true;
        }
        if sa.seal(&mut u.sealing, &mut u.frame, work) {
            let mut f = TmFrame::new_unchecked(&mut u.frame[..]);
            f.set_ocf(clcw.emit());
            f.fill_fecf();
            self.counters.frames = self.counters.frames.saturating_add(1);
            out(&u.frame);
            self.unsealed.pop_front();
        }
        true
    }

    pub fn security(&self) -> TmSecurity {
        self.security
    }

    /// Queues a packet on `vc`; `out` receives every frame that fills up. `sa` and `store`
    /// are not used in [`TmSecurity::Clear`].
    pub fn send(
        &mut self,
        vc: TmVc,
        packet: &[u8],
        clcw: Clcw,
        sa: &mut TxSa,
        store: &mut impl IvStore,
        out: impl FnMut(&[u8]),
    ) -> Result<(), DownlinkError> {
        self.with_vc(vc, clcw, sa, store, out, |mux, emit| mux.push(packet, emit))?
            .map_err(DownlinkError::Packet)
    }

    /// Sends the partly filled frame of `vc` (padded with an idle packet), if any.
    pub fn flush(
        &mut self,
        vc: TmVc,
        clcw: Clcw,
        sa: &mut TxSa,
        store: &mut impl IvStore,
        out: impl FnMut(&[u8]),
    ) -> Result<(), DownlinkError> {
        self.with_vc(vc, clcw, sa, store, out, |mux, emit| mux.flush(emit))
    }

    /// Runs `op` on `vc`'s multiplexer with a frame emitter that secures, stamps and sends
    /// every frame the multiplexer fills (`send` and `flush` share it). An SDLS failure of
    /// any frame is returned after `op`.
    fn with_vc<R, S: IvStore, O: FnMut(&[u8])>(
        &mut self,
        vc: TmVc,
        clcw: Clcw,
        sa: &mut TxSa,
        store: &mut S,
        out: O,
        op: impl FnOnce(&mut PacketMux<CLEAR_DATA_LEN>, &mut dyn FnMut(Zone<'_>)) -> R,
    ) -> Result<R, DownlinkError> {
        // A VC without its zone (ZONES too small) sends on VC0.
        let vc = if vc.index() < ZONES { vc } else { TmVc::Realtime };
        let i = vc.index();
        let mux = &mut self.zones[i];
        let mut c = FrameCtx {
            scid: self.scid,
            mc: &mut self.mc,
            vc: &mut self.vc,
            counters: &mut self.counters,
            clcw: clcw.emit(),
            security: self.security,
            sa,
            store,
            out,
            err: None,
            defer: self.deferred.then_some(&mut self.unsealed),
        };
        let r = op(mux, &mut |z| c.secure(vc.id(), z));
        c.err.map_or(Ok(r), |e| Err(DownlinkError::Sdls(e)))
    }

    /// An idle frame on VC7 carrying the CLCW (in clear: nothing secret, and the OCF is
    /// outside the MAC on every VC anyway).
    pub fn idle(&mut self, clcw: Clcw, out: &mut [u8; LEN]) {
        let repr = TmRepr {
            scid: self.scid,
            vcid: tm_vc::IDLE,
            mc_count: self.mc,
            vc_count: self.vc[usize::from(tm_vc::IDLE)],
            fhp: FirstHeaderPointer::IdleOnly,
        };
        let mut f = TmFrame::new_unchecked(&mut out[..]);
        repr.emit(&mut f);
        f.data_mut().fill(0x55);
        f.set_ocf(clcw.emit());
        f.fill_fecf();
        self.mc = self.mc.wrapping_add(1);
        let c = &mut self.vc[usize::from(tm_vc::IDLE)];
        *c = c.wrapping_add(1);
        self.counters.idle_frames = self.counters.idle_frames.saturating_add(1);
    }
}

/// Why the ground refused a TM frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TmRxError {
    Frame(TmError),
    WrongScid(u16),
    UnknownVc(u8),
    /// An idle-VC frame that claims packets, or a packet VC frame that claims idle-only.
    BadFirstHeaderPointer,
    Sdls(SdlsError),
    Clcw(ClcwError),
}

impl fmt::Display for TmRxError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TmRxError::Frame(e) => write!(f, "{e}"),
            TmRxError::WrongScid(s) => write!(f, "TM frame for spacecraft {s:#05x}"),
            TmRxError::UnknownVc(v) => write!(f, "TM frame on unknown VC {v}"),
            TmRxError::BadFirstHeaderPointer => write!(f, "first header pointer inconsistent with the VC"),
            TmRxError::Sdls(e) => write!(f, "{e}"),
            TmRxError::Clcw(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for TmRxError {}

/// Counters of the ground's TM receiver.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TmRxCounters {
    pub frames: u32,
    pub idle_frames: u32,
    pub bad_frame: u32,
    pub bad_crc: u32,
    pub wrong_scid: u32,
    pub unknown_vc: u32,
    pub bad_fhp: u32,
    pub sdls_rejected: u32,
    pub bad_clcw: u32,
}

/// The ground's TM frame receiver: CRC, header, SDLS, demultiplexing; returns the CLCW.
#[derive(Debug)]
pub struct TmReceiver<const N: usize> {
    scid: u16,
    security: TmSecurity,
    pub sas: RxSas<N>,
    /// One per packet-carrying VC, in the order of [`TmVc::ALL`].
    pub demux: [PacketDemux; 3],
    pub counters: TmRxCounters,
}

impl<const N: usize> TmReceiver<N> {
    /// A receiver of SDLS-protected TM ([`TmSecurity::Encrypt`]).
    pub fn new(scid: u16, sas: RxSas<N>) -> Self {
        Self::with_security(scid, TmSecurity::Encrypt, sas)
    }

    /// A receiver for TM protected as `security` says (the robot's setting).
    pub fn with_security(scid: u16, security: TmSecurity, sas: RxSas<N>) -> Self {
        TmReceiver {
            scid,
            security,
            sas,
            demux: Default::default(),
            counters: TmRxCounters::default(),
        }
    }

    /// Demultiplexer counters of a VC.
    pub fn demux_counters(&self, vc: TmVc) -> DemuxCounters {
        self.demux[vc.index()].counters
    }

    /// Processes one frame (decrypted in place); `out(vcid, packet)` receives its complete
    /// packets. Returns the CLCW of an accepted frame.
    pub fn receive(
        &mut self,
        store: &mut impl IvStore,
        frame: &mut [u8],
        out: impl FnMut(u8, &[u8]),
    ) -> Result<Clcw, TmRxError> {
        let r = self.process(store, frame, out);
        let c = &mut self.counters;
        let slot = match r {
            Ok(_) => None,
            Err(TmRxError::Frame(TmError::BadCrc)) => Some(&mut c.bad_crc),
            Err(TmRxError::Frame(_)) => Some(&mut c.bad_frame),
            Err(TmRxError::WrongScid(_)) => Some(&mut c.wrong_scid),
            Err(TmRxError::UnknownVc(_)) => Some(&mut c.unknown_vc),
            Err(TmRxError::BadFirstHeaderPointer) => Some(&mut c.bad_fhp),
            Err(TmRxError::Sdls(_)) => Some(&mut c.sdls_rejected),
            Err(TmRxError::Clcw(_)) => Some(&mut c.bad_clcw),
        };
        if let Some(s) = slot {
            *s = s.saturating_add(1);
        }
        r
    }

    fn process(
        &mut self,
        store: &mut impl IvStore,
        frame: &mut [u8],
        mut out: impl FnMut(u8, &[u8]),
    ) -> Result<Clcw, TmRxError> {
        let (repr, ocf) = {
            let f = TmFrame::new_checked(&*frame).map_err(TmRxError::Frame)?;
            if !f.check_fecf() {
                return Err(TmRxError::Frame(TmError::BadCrc));
            }
            (TmRepr::parse(&f), f.ocf())
        };
        if repr.scid != self.scid {
            return Err(TmRxError::WrongScid(repr.scid));
        }
        let clcw = Clcw::parse(ocf).map_err(TmRxError::Clcw)?;
        if repr.vcid == tm_vc::IDLE {
            if repr.fhp != FirstHeaderPointer::IdleOnly {
                return Err(TmRxError::BadFirstHeaderPointer);
            }
            self.counters.idle_frames = self.counters.idle_frames.saturating_add(1);
            return Ok(clcw);
        }
        let vc = TmVc::from_id(repr.vcid).ok_or(TmRxError::UnknownVc(repr.vcid))?;
        if repr.fhp == FirstHeaderPointer::IdleOnly {
            return Err(TmRxError::BadFirstHeaderPointer);
        }
        let pt = match self.security {
            TmSecurity::Encrypt => self.sas.process_tm(store, frame).map_err(TmRxError::Sdls)?,
            TmSecurity::Clear => HEADER_LEN..HEADER_LEN + CLEAR_DATA_LEN,
        };
        self.demux[vc.index()].feed(repr.vc_count, repr.fhp, &frame[pt], |p| out(repr.vcid, p));
        self.counters.frames = self.counters.frames.saturating_add(1);
        Ok(clcw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::farm::Farm;
    use crate::sdls::{MemoryIvStore, RxSa};
    use crate::test_keys::*;
    use proptest::prelude::*;

    fn packet(apid: u16, seq: u16, len: usize) -> Vec<u8> {
        let mut p = vec![0u8; len.max(7)];
        p[0..2].copy_from_slice(&(0x0800 | apid).to_be_bytes());
        p[2..4].copy_from_slice(&(0xC000 | mib::headers::SeqCount::new(seq).get()).to_be_bytes());
        let n = p.len();
        p[4..6].copy_from_slice(&((n - 7) as u16).to_be_bytes());
        for (i, b) in p[6..].iter_mut().enumerate() {
            *b = (i as u8).wrapping_mul(7) ^ (seq as u8);
        }
        p
    }

    fn ground() -> TmReceiver<2> {
        let mut sas = RxSas::default();
        sas.insert(RxSa::new(17, &TEST_KEY_TM_A, 64)).unwrap();
        TmReceiver::new(mib::link::SCID, sas)
    }

    // verifies: LINK-TM-04
    #[test]
    fn clear_tm_frames_carry_packets_in_a_1012_byte_zone_and_each_end_needs_the_same_setting() {
        let mut dl = TmFramer::with_security(mib::link::SCID, TmSecurity::Clear);
        assert_eq!(dl.security(), TmSecurity::Clear);
        let mut sa = TxSa::resume(17, &TEST_KEY_TM_A, 0);
        let mut st = MemoryIvStore::default();
        let clcw = Farm::mission().clcw();
        let mut frames: Vec<Vec<u8>> = vec![];
        let ps: Vec<_> = (0..4).map(|i| packet(100, i, 400)).collect();
        for p in &ps {
            dl.send(TmVc::Realtime, p, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
                .unwrap();
        }
        dl.flush(TmVc::Realtime, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
            .unwrap();
        // 1600 bytes: one full 1012-byte zone and one flushed; no IV used, nothing stored.
        assert_eq!(frames.len(), 2);
        assert_eq!((st.writes, sa.next_iv()), (0, 0));
        // The first packet starts the data field, in clear, right after the header.
        assert_eq!(&frames[0][6..6 + 400], &ps[0][..]);
        let v = TmFrame::new_checked(&frames[0][..]).unwrap();
        assert!(v.check_fecf());
        assert_eq!(v.ocf(), clcw.emit());
        let mut g = TmReceiver::<2>::with_security(mib::link::SCID, TmSecurity::Clear, RxSas::default());
        let mut got = vec![];
        for f in &frames {
            let c = g
                .receive(&mut MemoryIvStore::default(), &mut f.clone(), |_, p| {
                    got.push(p.to_vec())
                })
                .unwrap();
            assert_eq!(c, clcw);
        }
        assert_eq!(got, ps);
        // A ground expecting SDLS refuses clear frames (and vice versa reads no packets).
        let mut g = ground();
        for f in &frames {
            assert!(g
                .receive(&mut MemoryIvStore::default(), &mut f.clone(), |_, _| panic!())
                .is_err());
        }
        assert_eq!(g.counters.sdls_rejected, 2);
        let mut enc = TmFramer::mission();
        let mut secured = vec![];
        enc.send(TmVc::Realtime, &ps[0], clcw, &mut sa, &mut st, |_| {})
            .unwrap();
        enc.flush(TmVc::Realtime, clcw, &mut sa, &mut st, |f| secured.push(f.to_vec()))
            .unwrap();
        let mut g = TmReceiver::<2>::with_security(mib::link::SCID, TmSecurity::Clear, RxSas::default());
        let mut got = vec![];
        let _ = g.receive(&mut MemoryIvStore::default(), &mut secured[0].clone(), |_, p| {
            got.push(p.to_vec())
        });
        assert!(!got.contains(&ps[0]), "an encrypted packet never comes out in clear");
    }

    // verifies: LINK-TM-05
    #[test]
    fn file_packets_go_down_on_the_files_vc_beside_realtime_tm_and_on_vc0_without_its_zone() {
        let farm = Farm::mission();
        let mut sa = TxSa::resume(17, &TEST_KEY_TM_A, 0);
        let mut st = MemoryIvStore::default();
        let (hk, pdu) = (packet(0x101, 0, 200), packet(mib::cfdp::APID, 0, 300));
        let mut dl = TmFramer::mission();
        let mut frames: Vec<Vec<u8>> = vec![];
        dl.send(TmVc::Realtime, &hk, farm.clcw(), &mut sa, &mut st, |_| {})
            .unwrap();
        dl.send(TmVc::Files, &pdu, farm.clcw(), &mut sa, &mut st, |_| {})
            .unwrap();
        for vc in TmVc::ALL {
            dl.flush(vc, farm.clcw(), &mut sa, &mut st, |f| frames.push(f.to_vec()))
                .unwrap();
        }
        assert_eq!(frames.len(), 2, "one frame per VC with packets");
        let mut g = ground();
        let mut got = vec![];
        for f in &frames {
            g.receive(&mut MemoryIvStore::default(), &mut f.clone(), |vc, p| {
                got.push((vc, p.to_vec()))
            })
            .unwrap();
        }
        assert_eq!(got, [(tm_vc::REALTIME, hk.clone()), (tm_vc::FILES, pdu.clone())]);
        assert_eq!(g.demux_counters(TmVc::Files).frames_lost, 0);
        // Board A's framer has no files zone: the PDU packet goes on VC0.
        let mut board = TmFramer::mission_realtime_only();
        let mut frames: Vec<Vec<u8>> = vec![];
        board
            .send(TmVc::Files, &pdu, farm.clcw(), &mut sa, &mut st, |_| {})
            .unwrap();
        board
            .flush(TmVc::Files, farm.clcw(), &mut sa, &mut st, |f| frames.push(f.to_vec()))
            .unwrap();
        let mut got = vec![];
        g.receive(&mut MemoryIvStore::default(), &mut frames[0].clone(), |vc, p| {
            got.push((vc, p.to_vec()))
        })
        .unwrap();
        assert_eq!(got, [(tm_vc::REALTIME, pdu)]);
    }

    // verifies: LINK-TM-01, LINK-TM-02, LINK-SDLS-03
    #[test]
    fn downlink_frames_carry_clcw_counters_and_packets() {
        let mut dl = TmFramer::mission();
        let mut sa = TxSa::resume(17, &TEST_KEY_TM_A, 0);
        let (mut st, mut gst) = (MemoryIvStore::default(), MemoryIvStore::default());
        let farm = Farm::mission();
        let mut frames: Vec<Vec<u8>> = vec![];
        let ps: Vec<_> = (0..12).map(|i| packet(100, i, 300)).collect();
        for p in &ps {
            dl.send(TmVc::Realtime, p, farm.clcw(), &mut sa, &mut st, |f| {
                frames.push(f.to_vec())
            })
            .unwrap();
        }
        dl.flush(TmVc::Realtime, farm.clcw(), &mut sa, &mut st, |f| {
            frames.push(f.to_vec())
        })
        .unwrap();
        dl.send(TmVc::Replay, &packet(101, 0, 50), farm.clcw(), &mut sa, &mut st, |f| {
            frames.push(f.to_vec())
        })
        .unwrap();
        dl.flush(TmVc::Replay, farm.clcw(), &mut sa, &mut st, |f| frames.push(f.to_vec()))
            .unwrap();
        let mut idle = [0u8; LEN];
        dl.idle(farm.clcw(), &mut idle);
        frames.push(idle.to_vec());
        assert_eq!(frames.len(), 4 + 1 + 1); // 3600 bytes in 982-byte zones, one replay, one idle
        assert_eq!(
            dl.counters,
            TxCounters {
                frames: 5,
                idle_frames: 1,
                sdls_failed: 0,
                seal_queue_full: 0
            }
        );
        let mut g = ground();
        let mut got = vec![];
        for (i, f) in frames.iter().enumerate() {
            let v = TmFrame::new_checked(&f[..]).unwrap();
            assert_eq!(v.mc_count() as usize, i);
            let mut f = f.clone();
            let c = g.receive(&mut gst, &mut f, |vc, p| got.push((vc, p.to_vec()))).unwrap();
            assert_eq!(c, farm.clcw());
        }
        let want: Vec<_> = ps
            .iter()
            .map(|p| (0u8, p.clone()))
            .chain([(1u8, packet(101, 0, 50))])
            .collect();
        assert_eq!(got, want);
        assert_eq!(g.counters.idle_frames, 1);
        // A replayed TM frame and a flipped bit are refused.
        let mut f = frames[0].clone();
        assert_eq!(
            g.receive(&mut gst, &mut f, |_, _| {}),
            Err(TmRxError::Sdls(SdlsError::Replay))
        );
        let mut f = frames[0].clone();
        f[500] ^= 1;
        assert_eq!(
            g.receive(&mut gst, &mut f, |_, _| {}),
            Err(TmRxError::Frame(TmError::BadCrc))
        );
    }

    // verifies: LINK-TM-02
    #[test]
    fn a_framer_with_one_zone_sends_replays_on_vc0_and_is_one_zone_smaller() {
        let mut dl = TmFramer::mission_realtime_only();
        let mut sa = TxSa::resume(17, &TEST_KEY_TM_A, 0);
        let (mut st, mut gst) = (MemoryIvStore::default(), MemoryIvStore::default());
        let clcw = Farm::mission().clcw();
        let mut frames: Vec<Vec<u8>> = vec![];
        let (rt, replay) = (packet(100, 0, 300), packet(101, 0, 50));
        dl.send(TmVc::Realtime, &rt, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
            .unwrap();
        dl.send(TmVc::Replay, &replay, clcw, &mut sa, &mut st, |f| {
            frames.push(f.to_vec())
        })
        .unwrap();
        // Both packets wait in the one zone: flushing "the replay VC" sends them together.
        assert!(frames.is_empty());
        dl.flush(TmVc::Replay, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
            .unwrap();
        dl.flush(TmVc::Realtime, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec()))
            .unwrap();
        assert_eq!(frames.len(), 1);
        let v = TmFrame::new_checked(&frames[0][..]).unwrap();
        assert_eq!((v.vcid(), v.vc_count()), (tm_vc::REALTIME, 0));
        let mut got = vec![];
        ground()
            .receive(&mut gst, &mut frames[0].clone(), |vc, p| got.push((vc, p.to_vec())))
            .unwrap();
        assert_eq!(got, vec![(0u8, rt), (0u8, replay)]);
        assert!(core::mem::size_of::<TmFramer<1>>() + CLEAR_DATA_LEN <= core::mem::size_of::<TmFramer>());
    }

    proptest! {
        // verifies: LINK-RX-02
        #[test]
        fn tm_receiver_random_bytes_never_panic(d in proptest::collection::vec(any::<u8>(), 0..1100), fix_len in any::<bool>()) {
            let mut g = ground();
            let mut st = MemoryIvStore::default();
            let mut d = d;
            if fix_len { d.resize(LEN, 0); crate::fecf::seal(&mut d); }
            let _ = g.receive(&mut st, &mut d, |_, _| {});
        }

        // verifies: LINK-TM-02
        #[test]
        fn downlink_round_trip_with_frame_loss_never_corrupts(
            lens in proptest::collection::vec(7usize..2500, 1..30),
            drop in proptest::collection::vec(any::<bool>(), 64),
        ) {
            let mut dl = TmFramer::mission();
            let mut sa = TxSa::resume(17, &TEST_KEY_TM_A, 0);
            let (mut st, mut gst) = (MemoryIvStore::default(), MemoryIvStore::default());
            let clcw = Farm::mission().clcw();
            let ps: Vec<_> = lens.iter().enumerate().map(|(i, l)| packet(7, i as u16, *l)).collect();
            let mut frames = vec![];
            for p in &ps {
                dl.send(TmVc::Realtime, p, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec())).unwrap();
            }
            dl.flush(TmVc::Realtime, clcw, &mut sa, &mut st, |f| frames.push(f.to_vec())).unwrap();
            let mut g = ground();
            let mut got = vec![];
            let mut dropped = 0;
            for (i, f) in frames.iter().enumerate() {
                if drop[i % drop.len()] { dropped += 1; continue; }
                let mut f = f.clone();
                g.receive(&mut gst, &mut f, |_, p| got.push(p.to_vec())).unwrap();
            }
            let mut it = ps.iter();
            for p in &got {
                prop_assert!(it.any(|q| q == p), "corrupted or reordered packet");
            }
            if dropped == 0 { prop_assert_eq!(got.len(), ps.len()); }
            let lost = g.demux_counters(TmVc::Realtime).frames_lost;
            prop_assert!(lost <= dropped);
        }
    }
}
