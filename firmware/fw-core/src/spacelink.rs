//! Board A's ground link over CCSDS transfer frames (issue 22): the same `mmic-link` code
//! the host obsw runs on its UDP frame port, over the serial ground link.
//!
//! - **Uplink**: one TC frame per COBS frame (the COBS delimiters delimit the frame; the
//!   frame's length field must equal the decoded length exactly, as one frame per UDP
//!   datagram on the host). `mmic_link::rx::TcReceiver`: bare-packet check → CRC →
//!   lengths/header/SCID/VC → SDLS (AES-256-GCM, anti-replay window, receive counter
//!   persisted through [`IvStore`] before the frame is used) → packet lengths → FARM-1;
//!   the packets of an accepted frame go to `Obsw::handle_tc`. BC control frames (in
//!   clear) are taken at most [`CONTROL_FRAMES_PER_S`] per second.
//! - **Downlink**: every TM packet is multiplexed into 1024-byte VC0 frames (SDLS with
//!   the TM key, CLCW in the OCF), each frame one COBS frame in the downlink queue. The
//!   partly filled frame is flushed at the end of each control period; when no frame went
//!   out for [`IDLE_INTERVAL_MS`], or after an authentic TC frame, an idle VC7 frame
//!   carries the CLCW.
//! - **Counters**: HK structure SPACE_LINK (`Obsw::space_link`) in the MIB's order, and
//!   `LINK_FRAME_REJECTED` / `LINK_CONTROL_FRAME` events for what changed, once per
//!   period (the OBSW throttles them further).
//!
//! No bare space packet is taken or sent by the firmware.

use crate::link::{downlink_packet, ByteQueue, Counters, TcChannel};
use mib::link::sdls::ANTI_REPLAY_WINDOW;
use mib::link::tm_frame::LEN as TM_LEN;
use mmic_link::clcw::Clcw;
use mmic_link::downlink::{Downlink, TmVc};
use mmic_link::hk::LinkChange;
use mmic_link::rx::{RxCounters, RxOutcome, TcReceiver};
use mmic_link::sdls::{IvStore, Key, RxSa, RxSas, TxSa};
use mmic_link::tc::ControlCommand;
use obsw_core::obsw::{LinkEvent, Obsw, SPACE_LINK_PARAMS};
use obsw_core::services::link::LinkKeys;
use obsw_core::tm::TmStore;

use crate::cycle::GroundSink;

/// Longest time without a TM frame: then an idle frame carries the CLCW (the MIB's report
/// interval, as the host).
pub const IDLE_INTERVAL_MS: u64 = mib::link::cop1::CLCW_REPORT_INTERVAL_MS;
/// BC control frames taken per second (as the host); more are dropped and counted.
pub const CONTROL_FRAMES_PER_S: u32 = 5;
/// TC frames taken from the uplink queue per control period: bounds the period's
/// decryption work (instruction budget, docs/firmware.md). Frames left wait in the
/// queue; when it is full the uplink drops and counts them and COP-1 retransmits.
pub const FRAMES_PER_PERIOD: usize = 1;

/// The provisioned keys (see [`crate::keys`]).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Keys {
    pub tc_spi: u16,
    pub tc_key: Key,
    pub tm_spi: u16,
    pub tm_key: Key,
}

/// Stored counter values of one SPI, as read back from the counter store at boot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Resume {
    /// Last accepted TC IV (None: key never used).
    pub tc_last: Option<u128>,
    /// TM transmit high-water mark (0: key never used).
    pub tm_high_water: u128,
    /// FARM-1's stored state (None: V(R) = 0, Open).
    pub farm: Option<mmic_link::farm::FarmRecord>,
}

/// What the counter store reports in HK SPACE_LINK (LINK_STATE_WRITES,
/// LINK_STATE_BAD_SLOT).
pub trait StoreStats {
    /// Durable writes since boot.
    fn writes(&self) -> u32;
    /// 0, or which part of the store held a torn or corrupted record at boot.
    fn bad_slot(&self) -> u8;
}

impl<F: embedded_storage::nor_flash::NorFlash> StoreStats for crate::link_store::FlashIvStore<F> {
    fn writes(&self) -> u32 {
        self.writes
    }
    fn bad_slot(&self) -> u8 {
        self.bad_sector
    }
}

impl StoreStats for mmic_link::sdls::MemoryIvStore {
    fn writes(&self) -> u32 {
        self.writes
    }
    fn bad_slot(&self) -> u8 {
        0
    }
}

/// The transmit half: TM framer, TM SA, counter store.
struct Tx<St> {
    framer: Downlink<1>,
    sa: Option<TxSa>,
    store: St,
    /// Packet bytes waiting in a partly filled frame.
    pending: bool,
    /// An authentic TC frame changed or confirmed the CLCW: send it at once.
    clcw_due: bool,
    last_tx_ms: u64,
    /// TM packets not framed because no TM key is provisioned.
    unkeyed: u32,
}

impl<St: IvStore> Tx<St> {
    fn send<const N: usize>(&mut self, packet: &[u8], clcw: Clcw, q: &ByteQueue<N>, c: &Counters) {
        let Some(sa) = self.sa.as_mut() else {
            self.unkeyed = self.unkeyed.saturating_add(1);
            return;
        };
        // An SDLS failure is counted by the framer (LINK_TM_SDLS_FAILED); a frame the
        // queue cannot take is counted by `downlink_packet` (IO_TM_DROPPED). The OBSW's
        // store keeps every packet for a PUS 15 downlink.
        let _ = self
            .framer
            .send(TmVc::Realtime, packet, clcw, sa, &mut self.store, |f| {
                downlink_packet(q, f, c);
            });
        self.pending = true;
    }

    fn end_period<const N: usize>(&mut self, now: u64, clcw: Clcw, q: &ByteQueue<N>, c: &Counters) {
        if self.pending {
            self.pending = false;
            if let Some(sa) = self.sa.as_mut() {
                let _ = self.framer.flush(TmVc::Realtime, clcw, sa, &mut self.store, |f| {
                    downlink_packet(q, f, c);
                });
            }
            self.last_tx_ms = now;
            self.clcw_due = false;
        } else if self.clcw_due || now.saturating_sub(self.last_tx_ms) >= IDLE_INTERVAL_MS {
            let mut f = [0u8; TM_LEN];
            self.framer.idle(clcw, &mut f);
            downlink_packet(q, &f, c);
            self.last_tx_ms = now;
            self.clcw_due = false;
        }
    }
}

/// Board A's frame link: TC receive pipeline, TM framer, counters.
pub struct FrameLink<St> {
    pub rx: TcReceiver<1>,
    tx: Tx<St>,
    reported: RxCounters,
    last_control: Option<ControlCommand>,
    /// Start of the current one-second window of control frames, and their number.
    control_window: (u64, u32),
    control_rate_limited: u32,
    reported_rate_limited: u32,
    /// The SPIs with a provisioned key, for the OBSW's LINK_SPI_SELECT check.
    keys: LinkKeys,
}

/// Whether a frame's header says BC frame (version 00, bypass 1, control 1).
fn is_control_frame(d: &[u8]) -> bool {
    d.first().is_some_and(|b| b & 0xF0 == 0x30)
}

impl<St: IvStore + StoreStats> FrameLink<St> {
    /// The link with the provisioned keys (`None`: not provisioned — every AD/BD frame
    /// is refused as an unknown SPI and only idle frames go down) and the counters the
    /// store held at boot.
    pub fn new(keys: Option<&Keys>, resume: Resume, store: St) -> Self {
        let mut sas = RxSas::default();
        let mut sa = None;
        let bit = |spis: &[u16], spi: u16| spis.iter().position(|s| *s == spi).map_or(0, |i| 1u8 << i);
        let link_keys = keys.map_or(LinkKeys::default(), |k| LinkKeys {
            tm: bit(&mib::link::sdls::TM_SPIS, k.tm_spi),
            tc: bit(&mib::link::sdls::TC_SPIS, k.tc_spi),
        });
        if let Some(k) = keys {
            let rx_sa = match resume.tc_last {
                Some(last) => RxSa::resume(k.tc_spi, &k.tc_key, ANTI_REPLAY_WINDOW, last),
                None => RxSa::new(k.tc_spi, &k.tc_key, ANTI_REPLAY_WINDOW),
            };
            // One SA in an empty set: cannot be full.
            let _ = sas.insert(rx_sa);
            sa = Some(TxSa::resume(k.tm_spi, &k.tm_key, resume.tm_high_water));
        }
        FrameLink {
            rx: match resume.farm {
                Some(f) => TcReceiver::new(
                    mib::link::SCID,
                    mib::link::tc_vc::COMMAND,
                    mmic_link::farm::Farm::mission_restored(f),
                    sas,
                ),
                None => TcReceiver::mission(sas),
            },
            tx: Tx {
                framer: Downlink::mission_realtime_only(),
                sa,
                store,
                pending: false,
                clcw_due: false,
                last_tx_ms: 0,
                unkeyed: 0,
            },
            reported: RxCounters::default(),
            last_control: None,
            control_window: (0, 0),
            control_rate_limited: 0,
            reported_rate_limited: 0,
            keys: link_keys,
        }
    }

    /// The counter store (tests read it back).
    pub fn store(&self) -> &St {
        &self.tx.store
    }

    /// Takes up to [`FRAMES_PER_PERIOD`] TC frames from the uplink queue and executes the
    /// packets of each accepted frame, in order.
    pub fn receive<S: TmStore, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        tcs: &TcChannel,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    ) {
        for _ in 0..FRAMES_PER_PERIOD {
            let Ok(mut frame) = tcs.try_receive() else { break };
            self.frame(now, obsw, &mut frame, tm, tm_stats);
        }
    }

    /// One TC frame through the pipeline.
    pub fn frame<S: TmStore, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        frame: &mut [u8],
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    ) {
        if is_control_frame(frame) {
            let (start, n) = self.control_window;
            if now.saturating_sub(start) >= 1000 {
                self.control_window = (now, 1);
            } else if n >= CONTROL_FRAMES_PER_S {
                self.control_rate_limited = self.control_rate_limited.saturating_add(1);
                return;
            } else {
                self.control_window.1 = n + 1;
            }
        }
        match self.rx.receive(&mut self.tx.store, frame, true) {
            RxOutcome::Accepted { packets, .. } => {
                self.tx.clcw_due = true;
                // One sink type for every OBSW call (tick, TCs, events): the OBSW's
                // generic code is compiled once.
                let mut sink = GroundSink {
                    link: self,
                    queue: tm,
                    counters: tm_stats,
                };
                for p in packets {
                    obsw.handle_tc(now, p, &mut sink);
                }
            }
            RxOutcome::Control(c) => {
                self.last_control = Some(c);
                self.tx.clcw_due = true;
            }
            RxOutcome::Discarded(_) => self.tx.clcw_due = true,
            RxOutcome::Rejected(_) => {}
        }
    }

    /// Sends one TM packet (the control period's tick).
    pub fn send_tm<const N: usize>(&mut self, packet: &[u8], tm: &ByteQueue<N>, tm_stats: &Counters) {
        let clcw = self.rx.farm.clcw();
        self.tx.send(packet, clcw, tm, tm_stats);
    }

    /// The SPACE_LINK HK values, in MIB order (`mmic_link::hk`, as the host).
    pub fn hk(&self) -> [u32; SPACE_LINK_PARAMS] {
        self.hk_of(&self.rx.counters, self.control_rate_limited)
    }

    fn hk_of(&self, rx: &RxCounters, rate_limited: u32) -> [u32; SPACE_LINK_PARAMS] {
        let clcw = self.rx.farm.clcw();
        mmic_link::hk::space_link_values(rx, clcw, &self.tx.framer.counters, self.tx.unkeyed, rate_limited)
    }

    /// End of a control period: SPACE_LINK values into the OBSW, one event per refusal
    /// reason that changed and one for control frames, then the partly filled frame (or
    /// an idle frame with the CLCW).
    pub fn end_period<S: TmStore, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    ) {
        let hk = self.hk();
        let before = self.hk_of(&self.reported, self.reported_rate_limited);
        obsw.space_link = hk;
        // The board holds one key per direction: the only selection LINK_SPI_SELECT can
        // accept is the one in use, so there is nothing to apply.
        obsw.link_keys = self.keys;
        obsw.link_select = None;
        let last_control = self.last_control;
        let mut sink = GroundSink {
            link: &mut *self,
            queue: tm,
            counters: tm_stats,
        };
        for change in mmic_link::hk::changes(&hk, &before) {
            let ev = match change {
                LinkChange::Rejected { reason, total } => LinkEvent::FrameRejected { reason, total },
                LinkChange::ControlFrames { total } => {
                    let (command, vr) = mmic_link::hk::control_event_fields(last_control);
                    LinkEvent::ControlFrame { command, vr, total }
                }
            };
            obsw.link_event(now, ev, &mut sink);
        }
        self.reported = self.rx.counters;
        self.reported_rate_limited = self.control_rate_limited;
        let clcw = self.rx.farm.clcw();
        self.tx.end_period(now, clcw, tm, tm_stats);
        // The link state for HK (after the flush, whose first frame may reserve TM IVs).
        let tm_spi = self.tx.sa.as_ref().map_or(0, |sa| sa.spi());
        obsw.space_link_state = [
            u32::from(tm_spi),
            u32::from(self.keys.tc),
            self.tx.store.writes(),
            u32::from(self.tx.store.bad_slot()),
        ];
    }
}
