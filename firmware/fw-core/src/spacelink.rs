//! Board A's ground link over CCSDS transfer frames: `mmic_link::endpoint::Endpoint`, the
//! endpoint the host obsw runs on its UDP frame port, over the serial ground link. What is
//! board A's own is the I/O and the provisioning:
//!
//! - **Uplink**: one TC frame per COBS frame from the uplink queue (the COBS delimiters
//!   delimit the frame; the frame's length field must equal the decoded length exactly, as
//!   one frame per UDP datagram on the host). The SDLS work is spread over control periods
//!   ([`SDLS_WORK_PER_PERIOD`], `Endpoint::schedule`): a frame is taken from the queue
//!   when the one before is done, its MAC check and decryption run over as many periods as
//!   they need, then its packets go to `Obsw::handle_tc`, one per period — those of the
//!   CFDP APID to the file service instead (`crate::files`).
//! - **CPU**: a period does at most [`SDLS_WORK_PER_PERIOD`] GCM work blocks, for the TC
//!   frame or else for the oldest TM frame, and at most one TC packet: the bound
//!   `t_budget` measures under QEMU (docs/firmware.md, The control period's CPU).
//! - **Downlink**: TM frames wait for their encryption (`mmic_link::downlink::SEAL_QUEUE`;
//!   a frame beyond it is counted as downlink overflow, `IO_TM_DROPPED`); every frame the
//!   endpoint emits is one COBS frame in the downlink queue (`downlink_packet`, which
//!   counts what the queue cannot take). TM packets go on VC0 only (replays included: one
//!   packet zone).
//! - **Counters**: at the end of each period the SPACE_LINK values and the link state go
//!   into the OBSW's housekeeping, and the link events for what changed.
//! - **Keys**: one provisioned key per direction ([`Keys`]), the counters and FARM-1's
//!   state resumed from the key and counter area (`link_store`) at boot.
//!
//! No bare space packet is taken or sent by the firmware.

use crate::link::{downlink_packet, ByteQueue, Counters, TcChannel};
use mib::link::sdls::ANTI_REPLAY_WINDOW;
use mmic_link::downlink::{TmFramer, TmVc};
use mmic_link::endpoint::{Endpoint, LinkReport, StoreStats};
use mmic_link::rx::TcReceiver;
use mmic_link::sdls::{IvStore, Key, RxSa, RxSas, TxSa};
use obsw_core::obsw::{LinkEvent, Obsw};
use obsw_core::services::link::LinkKeys;
use obsw_core::tm::TmStore;

use crate::cycle::GroundSink;
use crate::files::FileService;

/// GCM work blocks (a 16-byte block through AES or GHASH, `mmic_link::gcm`) per control
/// period: a 1 024-byte TC frame's MAC check and decryption (124 blocks) take 3 periods,
/// a TM frame's encryption 3 (62 blocks through both), and a period's SDLS work is at most
/// 48 software AES blocks (≈ 140 000 instructions under QEMU). With 64 the busiest period
/// was over the budget (`t_budget`; docs/firmware.md, The control period's CPU). Frames
/// waiting meanwhile stay in the uplink queue; when it is full the uplink drops and counts
/// them and COP-1 retransmits.
pub const SDLS_WORK_PER_PERIOD: usize = 48;
// A period's encryption carries less than one file data segment: the file service's one
// segment a period keeps up with the downlink (`mib::cfdp::BOARD_SEGMENTS_PER_PERIOD`).
const _: () = assert!(
    SDLS_WORK_PER_PERIOD * mmic_link::gcm::BLOCK <= mib::cfdp::BOARD_SEGMENTS_PER_PERIOD * mib::cfdp::MAX_SEGMENT_LEN
);

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

impl<F: embedded_storage::nor_flash::NorFlash> StoreStats for crate::link_store::FlashIvStore<F> {
    fn writes(&self) -> u32 {
        self.writes
    }
    fn bad_slot(&self) -> u32 {
        u32::from(self.bad_sector)
    }
}

/// Board A's frame link: the endpoint, and the SPIs with a provisioned key.
pub struct FrameLink<St> {
    pub ep: Endpoint<St, 1, 1>,
    /// The SPIs with a provisioned key, for the OBSW's LINK_SPI_SELECT check.
    keys: LinkKeys,
    /// TM frames not built because frames waited for encryption, already counted as
    /// downlink overflow (`IO_TM_DROPPED`).
    seal_queue_full: u32,
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
        let rx = match resume.farm {
            Some(f) => TcReceiver::new(
                mib::link::SCID,
                mib::link::tc_vc::COMMAND,
                mmic_link::farm::Farm::mission_restored(f),
                sas,
            ),
            None => TcReceiver::mission(sas),
        };
        let mut ep = Endpoint::new(rx, TmFramer::mission_realtime_only(), sa, store);
        ep.schedule(SDLS_WORK_PER_PERIOD);
        FrameLink {
            ep,
            keys: link_keys,
            seal_queue_full: 0,
        }
    }

    /// The counter store (tests read it back).
    pub fn store(&self) -> &St {
        self.ep.store()
    }

    /// This period's TC work: takes a TC frame from the uplink queue when none is in work,
    /// continues its MAC check and decryption, and executes at most one of its packets —
    /// in the file service when it takes it (the CFDP APID), else in the OBSW.
    pub fn receive<S: TmStore, F: FileService, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        files: &mut F,
        tcs: &TcChannel,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    ) {
        if !self.ep.tc_busy() {
            if let Ok(frame) = tcs.try_receive() {
                self.ep.offer(&frame);
            }
        }
        let mut packet = [0u8; mib::link::tc_frame::MAX_PACKET_LEN];
        let Some(n) = self.ep.poll_tc(&mut packet) else { return };
        if files.take(now, &packet[..n]) {
            return;
        }
        files.tc_handled();
        // One sink type for every OBSW call (tick, TCs, events): the OBSW's generic code is
        // compiled once.
        let mut sink = GroundSink {
            link: self,
            queue: tm,
            counters: tm_stats,
        };
        obsw.handle_tc(now, &packet[..n], &mut sink);
    }

    /// Sends one TM packet.
    pub fn send_tm<const N: usize>(&mut self, packet: &[u8], tm: &ByteQueue<N>, tm_stats: &Counters) {
        self.ep.send(TmVc::Realtime, packet, |f| {
            downlink_packet(tm, f, tm_stats);
        });
    }

    /// Bytes of replayed TM the downlink takes now without dropping a frame — in the
    /// framer's zone and the frames waiting for their encryption, and in the downlink
    /// queue when they are sealed — less one largest packet for the period's realtime TM.
    pub fn replay_room<const N: usize>(&self, tm: &ByteQueue<N>) -> usize {
        let frames = tm.free_capacity() / crate::config::GROUND_FRAME_MAX;
        self.ep
            .tm_room(TmVc::Realtime, frames)
            .saturating_sub(crate::config::MAX_PACKET_LEN)
    }

    /// End of a control period: SPACE_LINK values into the OBSW, the link events for what
    /// changed, then the partly filled frame (or an idle frame with the CLCW).
    pub fn end_period<S: TmStore, const N: usize>(
        &mut self,
        now: u64,
        obsw: &mut Obsw<S>,
        tm: &ByteQueue<N>,
        tm_stats: &Counters,
    ) {
        obsw.space_link = self.ep.hk();
        // The board holds one key per direction: the only selection LINK_SPI_SELECT can
        // accept is the one in use, so there is nothing to apply.
        obsw.link_keys = self.keys;
        obsw.link_select = None;
        let mut events = heapless::Vec::<LinkReport, 16>::new();
        self.ep.report(|r| {
            // At most one per refusal reason and one for control frames: 16 places.
            let _ = events.push(r);
        });
        let mut sink = GroundSink {
            link: &mut *self,
            queue: tm,
            counters: tm_stats,
        };
        for r in events {
            let ev = match r {
                LinkReport::Rejected { reason, total } => LinkEvent::FrameRejected { reason, total },
                LinkReport::ControlFrame { command, vr, total } => LinkEvent::ControlFrame { command, vr, total },
            };
            obsw.link_event(now, ev, &mut sink);
        }
        self.ep.flush(now, |f| {
            downlink_packet(tm, f, tm_stats);
        });
        self.ep.poll_tm(now, |f| {
            downlink_packet(tm, f, tm_stats);
        });
        let full = self.ep.tx_counters().seal_queue_full;
        let new = full.wrapping_sub(core::mem::replace(&mut self.seal_queue_full, full));
        if new > 0 {
            tm_stats.update(|s| s.overflow = s.overflow.wrapping_add(new));
        }
        // The link state for HK (after the flush, whose first frame may reserve TM IVs).
        obsw.space_link_state = self.ep.state_values(self.keys.tc);
    }
}
