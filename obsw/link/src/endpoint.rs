//! The robot's space-link endpoint without I/O: the TC receive pipeline ([`TcReceiver`]:
//! CRC, lengths, SDLS, the control-frame gate, FARM-1), the TM framer ([`TmFramer`], SDLS,
//! CLCW, idle frames), the counter store, the SPACE_LINK housekeeping values and the link
//! events their changes raise. Time is passed in; frames come in as byte slices and go out
//! through a closure.
//!
//! One endpoint, many transports (smoltcp's one `Interface` over many `Device`s): the host
//! obsw drives it from a UDP socket or a serial line (`obsw-host`'s `frames`), board A from
//! its serial uplink queue and downlink queue (`fw-core`'s `spacelink`), the QEMU tests
//! from memory. What a transport keeps is its own: reading, writing and the counters of
//! frames its line lost.

use crate::clcw::Clcw;
use crate::downlink::{TmFramer, TmVc};
use crate::hk::{changes, control_event_fields, space_link_values, LinkChange, SPACE_LINK_PARAMS};
use crate::rx::{Packets, RxCounters, RxOutcome, TcReceiver};
use crate::sdls::{IvStore, TxSa};
use crate::tc::ControlCommand;

/// Longest time without a TM frame: then an idle frame carries the CLCW (the MIB's CLCW
/// report interval).
pub const IDLE_INTERVAL_MS: u64 = mib::link::cop1::CLCW_REPORT_INTERVAL_MS;

/// What a counter store tells housekeeping (LINK_STATE_WRITES, LINK_STATE_BAD_SLOT).
pub trait StoreStats {
    /// Durable writes since boot.
    fn writes(&self) -> u32;
    /// 0, or 1 + the slot (sector) found torn or corrupted at boot.
    fn bad_slot(&self) -> u32;
}

impl StoreStats for crate::sdls::MemoryIvStore {
    fn writes(&self) -> u32 {
        self.writes
    }
    fn bad_slot(&self) -> u32 {
        0
    }
}

/// A link event for the OBSW (`LINK_FRAME_REJECTED`, `LINK_CONTROL_FRAME`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkReport {
    /// Frames refused for `reason` (the HK parameter offset); `total` since boot.
    Rejected { reason: u8, total: u32 },
    /// Control frames executed; the last one's `command` (0 Unlock, 1 Set V(R)) and `vr`.
    ControlFrame { command: u8, vr: u8, total: u32 },
}

/// The endpoint (see the module documentation). `SAS`: receive SAs; `ZONES`: TM packet
/// zones (2: realtime VC0 and replay VC1; 1: replays on VC0).
pub struct Endpoint<St, const SAS: usize, const ZONES: usize> {
    pub rx: TcReceiver<SAS>,
    framer: TmFramer<ZONES>,
    /// The TM SA in use (`None`: no TM key, nothing but idle frames goes down).
    tm_sa: Option<TxSa>,
    store: St,
    /// Virtual channels holding packet bytes not yet sent in a frame (realtime, replay).
    pending: [bool; 2],
    /// An authentic TC frame changed (or confirmed) the CLCW: send it at once.
    clcw_due: bool,
    last_tx_ms: u64,
    /// TM packets not framed because there is no TM SA.
    unkeyed: u32,
    /// Counters already reported by events.
    reported: RxCounters,
    last_control: Option<ControlCommand>,
}

/// Index of a TM virtual channel in the pending flags.
const fn vc_index(vc: TmVc) -> usize {
    match vc {
        TmVc::Realtime => 0,
        TmVc::Replay => 1,
    }
}

impl<St: IvStore + StoreStats, const SAS: usize, const ZONES: usize> Endpoint<St, SAS, ZONES> {
    /// An endpoint whose first CLCW goes out at the first [`Endpoint::flush`].
    pub fn new(rx: TcReceiver<SAS>, framer: TmFramer<ZONES>, tm_sa: Option<TxSa>, store: St) -> Self {
        Endpoint {
            rx,
            framer,
            tm_sa,
            store,
            pending: [false; 2],
            clcw_due: true,
            last_tx_ms: 0,
            unkeyed: 0,
            reported: RxCounters::default(),
            last_control: None,
        }
    }

    pub fn store(&self) -> &St {
        &self.store
    }

    pub fn store_mut(&mut self) -> &mut St {
        &mut self.store
    }

    /// The TM SA in use.
    pub fn tm_sa(&self) -> Option<&TxSa> {
        self.tm_sa.as_ref()
    }

    /// TM from now on under `sa` (key change); the partly filled frames go out under it.
    pub fn set_tm_sa(&mut self, sa: TxSa) {
        self.tm_sa = Some(sa);
    }

    /// One TC frame through the pipeline (decrypted in place): the packets of an accepted
    /// frame, in order; `None` for anything else, already counted.
    pub fn receive<'a>(&mut self, frame: &'a mut [u8]) -> Option<Packets<'a>> {
        match self.rx.receive(&mut self.store, frame, true) {
            RxOutcome::Accepted { packets, .. } => {
                self.clcw_due = true;
                Some(packets)
            }
            RxOutcome::Control(c) => {
                self.clcw_due = true;
                self.last_control = Some(c);
                None
            }
            RxOutcome::Discarded(_) => {
                self.clcw_due = true;
                None
            }
            RxOutcome::Rejected(_) => None,
        }
    }

    /// Queues one TM packet on `vc`; every frame that fills goes to `out` at once. The
    /// partly filled frame waits for [`Endpoint::flush`].
    pub fn send(&mut self, vc: TmVc, packet: &[u8], out: impl FnMut(&[u8])) {
        let Some(sa) = self.tm_sa.as_mut() else {
            self.unkeyed = self.unkeyed.saturating_add(1);
            return;
        };
        // An SDLS failure is counted by the framer (LINK_TM_SDLS_FAILED); the OBSW's store
        // keeps every packet for a PUS 15 downlink.
        let _ = self
            .framer
            .send(vc, packet, self.rx.farm.clcw(), sa, &mut self.store, out);
        self.pending[vc_index(vc)] = true;
    }

    /// Sends the partly filled frames, or an idle frame with the CLCW when one is due (an
    /// authentic TC frame since the last frame, or [`IDLE_INTERVAL_MS`] without one).
    pub fn flush(&mut self, now: u64, mut out: impl FnMut(&[u8])) {
        let clcw: Clcw = self.rx.farm.clcw();
        if self.pending.iter().any(|&p| p) {
            for vc in [TmVc::Realtime, TmVc::Replay] {
                if !core::mem::take(&mut self.pending[vc_index(vc)]) {
                    continue;
                }
                if let Some(sa) = self.tm_sa.as_mut() {
                    let _ = self.framer.flush(vc, clcw, sa, &mut self.store, &mut out);
                }
            }
        } else if self.clcw_due || now.saturating_sub(self.last_tx_ms) >= IDLE_INTERVAL_MS {
            let mut f = [0u8; mib::link::tm_frame::LEN];
            self.framer.idle(clcw, &mut f);
            out(&f);
        } else {
            return;
        }
        self.last_tx_ms = now;
        self.clcw_due = false;
    }

    /// The SPACE_LINK HK values, in MIB order ([`crate::hk`]).
    pub fn hk(&self) -> [u32; SPACE_LINK_PARAMS] {
        self.hk_of(&self.rx.counters)
    }

    fn hk_of(&self, rx: &RxCounters) -> [u32; SPACE_LINK_PARAMS] {
        space_link_values(rx, self.rx.farm.clcw(), &self.framer.counters, self.unkeyed)
    }

    /// The link state HK values (`pid::LINK_TM_SPI` ..): TM SPI in use, TC SPIs accepted
    /// (`tc_mask`, bit i = `TC_SPIS[i]`), durable writes since boot, the slot found bad.
    pub fn state_values(&self, tc_mask: u8) -> [u32; 4] {
        [
            u32::from(self.tm_sa.as_ref().map_or(0, TxSa::spi)),
            u32::from(tc_mask),
            self.store.writes(),
            self.store.bad_slot(),
        ]
    }

    /// What changed since the last call, as link events: one per refusal reason that moved
    /// and one for control frames executed.
    pub fn report(&mut self, mut event: impl FnMut(LinkReport)) {
        let (now, before) = (self.hk(), self.hk_of(&self.reported));
        for c in changes(&now, &before) {
            event(match c {
                LinkChange::Rejected { reason, total } => LinkReport::Rejected { reason, total },
                LinkChange::ControlFrames { total } => {
                    let (command, vr) = control_event_fields(self.last_control);
                    LinkReport::ControlFrame { command, vr, total }
                }
            });
        }
        self.reported = self.rx.counters;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rx::TcReceiver;
    use crate::sdls::{MemoryIvStore, RxSa, RxSas};
    use crate::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};
    use mib::params::pid;

    fn endpoint() -> Endpoint<MemoryIvStore, 1, 1> {
        let mut sas = RxSas::default();
        sas.insert(RxSa::new(1, &TEST_KEY_TC_A, 64)).unwrap();
        Endpoint::new(
            TcReceiver::mission(sas),
            TmFramer::mission_realtime_only(),
            Some(TxSa::resume(17, &TEST_KEY_TM_A, 0)),
            MemoryIvStore::default(),
        )
    }

    fn frames(ep: &mut Endpoint<MemoryIvStore, 1, 1>, now: u64) -> usize {
        let mut n = 0;
        ep.flush(now, |_| n += 1);
        n
    }

    // verifies: LINK-EP-01, LINK-HK-01
    #[test]
    fn idle_frame_at_start_after_the_interval_and_after_an_authentic_tc_frame_only() {
        let mut ep = endpoint();
        assert_eq!(frames(&mut ep, 0), 1, "the first CLCW at once");
        assert_eq!(frames(&mut ep, IDLE_INTERVAL_MS - 1), 0);
        assert_eq!(frames(&mut ep, IDLE_INTERVAL_MS), 1);
        // Junk: refused, counted, no CLCW due.
        let mut junk = [0x30u8, 0, 0, 4, 0, 0];
        assert!(ep.receive(&mut junk).is_none());
        assert_eq!(frames(&mut ep, IDLE_INTERVAL_MS + 1), 0);
        // A packet is framed and flushed, then nothing until the interval.
        ep.send(TmVc::Realtime, &[0x08, 1, 0xC0, 0, 0, 0, 0], |_| {});
        assert_eq!(frames(&mut ep, IDLE_INTERVAL_MS + 2), 1);
        assert_eq!(frames(&mut ep, IDLE_INTERVAL_MS + 3), 0);
        let mut events = heapless::Vec::<LinkReport, 4>::new();
        ep.report(|e| events.push(e).unwrap());
        assert_eq!(
            events.as_slice(),
            [LinkReport::Rejected {
                reason: (pid::LINK_REJ_BAD_CRC - pid::LINK_AD_ACCEPTED) as u8,
                total: 1
            }]
        );
        ep.report(|_| panic!("reported once"));
        // One durable write: the TM IV reservation of the first frame.
        assert_eq!(ep.state_values(1), [17, 1, 1, 0]);
    }
}
