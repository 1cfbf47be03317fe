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
use crate::rx::{Packets, RxCounters, RxOutcome, Start, TcOpening, TcReceiver};
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
/// zones (3: realtime VC0, replay VC1, files VC2; 1: everything on VC0).
pub struct Endpoint<St, const SAS: usize, const ZONES: usize> {
    pub rx: TcReceiver<SAS>,
    framer: TmFramer<ZONES>,
    /// The TM SA in use (`None`: no TM key, nothing but idle frames goes down).
    tm_sa: Option<TxSa>,
    store: St,
    /// Virtual channels holding packet bytes not yet sent in a frame ([`TmVc::ALL`]'s order).
    pending: [bool; 3],
    /// An authentic TC frame changed (or confirmed) the CLCW: send it at once.
    clcw_due: bool,
    last_tx_ms: u64,
    /// TM packets not framed because there is no TM SA.
    unkeyed: u32,
    /// Counters already reported by events.
    reported: RxCounters,
    last_control: Option<ControlCommand>,
    /// GCM work blocks per control period (`None`: every frame's SDLS work at once).
    work: Option<usize>,
    /// The TC frame in work between periods (scheduled mode).
    tc: Option<TcWork>,
    /// The TC frame used this period's SDLS work.
    tc_worked: bool,
}

/// A TC frame whose SDLS work and packets are spread over control periods.
struct TcWork {
    buf: [u8; mib::link::tc_frame::MAX_LEN],
    len: usize,
    state: TcState,
}

enum TcState {
    /// MAC check, then decryption.
    Open(TcOpening),
    /// Accepted: the packets in `buf[next..end]` wait for their periods.
    Packets { next: usize, end: usize },
}

impl<St: IvStore + StoreStats, const SAS: usize, const ZONES: usize> Endpoint<St, SAS, ZONES> {
    /// An endpoint whose first CLCW goes out at the first [`Endpoint::flush`].
    pub fn new(rx: TcReceiver<SAS>, framer: TmFramer<ZONES>, tm_sa: Option<TxSa>, store: St) -> Self {
        Endpoint {
            rx,
            framer,
            tm_sa,
            store,
            pending: [false; 3],
            clcw_due: true,
            last_tx_ms: 0,
            unkeyed: 0,
            reported: RxCounters::default(),
            last_control: None,
            work: None,
            tc: None,
            tc_worked: false,
        }
    }

    /// Spreads the SDLS work over control periods (board A): each period does at most
    /// `work` GCM work blocks ([`crate::gcm`]), for one direction only — a TC frame's MAC
    /// check and decryption first ([`Endpoint::offer`], [`Endpoint::poll_tc`]), else the
    /// oldest TM frame's encryption ([`Endpoint::poll_tm`]) — and executes at most one TC
    /// packet. Without it (the host) every frame's work is done when the frame comes.
    pub fn schedule(&mut self, work: usize) {
        self.work = Some(work);
        self.framer.defer_sealing();
    }

    /// Work is waiting for later periods: a TC frame, TM packets not yet in a sent
    /// frame.
    pub fn busy(&self) -> bool {
        self.tc.is_some() || self.framer.unsealed() > 0 || self.pending.iter().any(|&p| p)
    }

    /// Bytes of packets `vc` takes now without a frame being dropped, when the caller's
    /// output takes `frames` more frames ([`TmFramer::room`]).
    pub fn tm_room(&self, vc: TmVc, frames: usize) -> usize {
        self.framer.room(vc, frames)
    }

    /// A TC frame is in work: the next waits in the caller's uplink queue.
    pub fn tc_busy(&self) -> bool {
        self.tc.is_some()
    }

    /// Takes a TC frame (scheduled mode): the checks before the MAC now (a refusal is
    /// counted, a control frame executed), the MAC check and decryption in
    /// [`Endpoint::poll_tc`]. Call only when not [`Endpoint::tc_busy`].
    pub fn offer(&mut self, frame: &[u8]) {
        match self.rx.start(&mut self.store, frame) {
            Start::Control(c) => {
                self.clcw_due = true;
                self.last_control = Some(c);
            }
            Start::Rejected(_) => {}
            Start::Open(o) => {
                let mut buf = [0u8; mib::link::tc_frame::MAX_LEN];
                // The frame checks refused anything longer.
                let Some(dst) = buf.get_mut(..frame.len()) else { return };
                dst.copy_from_slice(frame);
                self.tc = Some(TcWork {
                    buf,
                    len: frame.len(),
                    state: TcState::Open(o),
                });
            }
        }
    }

    /// This period's TC work (scheduled mode): the frame's MAC check and decryption go on
    /// by the period's work blocks; once accepted, one packet per period is copied into
    /// `packet` (its length returned) for the OBSW to execute.
    pub fn poll_tc(&mut self, packet: &mut [u8; mib::link::tc_frame::MAX_PACKET_LEN]) -> Option<usize> {
        let work = self.work?;
        let w = self.tc.as_mut()?;
        if let TcState::Open(o) = &mut w.state {
            self.tc_worked = true;
            let buf = &mut w.buf[..w.len];
            let base = buf.as_ptr() as usize;
            match self.rx.resume(&mut self.store, buf, o, work, true)? {
                RxOutcome::Accepted { packets, .. } => {
                    self.clcw_due = true;
                    let rest = packets.rest();
                    let next = rest.as_ptr() as usize - base;
                    w.state = TcState::Packets {
                        next,
                        end: next + rest.len(),
                    };
                }
                RxOutcome::Discarded(_) | RxOutcome::Control(_) => {
                    self.clcw_due = true;
                    self.tc = None;
                    return None;
                }
                RxOutcome::Rejected(_) => {
                    self.tc = None;
                    return None;
                }
            }
        }
        let TcState::Packets { next, end } = &mut w.state else {
            return None;
        };
        let p = Packets::over(&w.buf[*next..*end]).next();
        let n = p.map_or(0, <[u8]>::len);
        *next += n;
        let done = *next >= *end;
        // A packet lies inside the frame's data field, which is at most MAX_PACKET_LEN.
        let r = match (p, packet.get_mut(..n)) {
            (Some(p), Some(dst)) => {
                dst.copy_from_slice(p);
                Some(n)
            }
            _ => None,
        };
        if done || r.is_none() {
            self.tc = None;
        }
        r
    }

    /// This period's TM work (scheduled mode), after [`Endpoint::flush`]: the oldest TM
    /// frame's encryption goes on by the period's work blocks unless a TC frame used them;
    /// a finished frame (with the CLCW of now) goes to `out`.
    pub fn poll_tm(&mut self, now: u64, mut out: impl FnMut(&[u8])) {
        let Some(work) = self.work else { return };
        if core::mem::take(&mut self.tc_worked) {
            return;
        }
        let Some(sa) = self.tm_sa.as_ref() else { return };
        let mut sent = false;
        self.framer.seal(work, self.rx.farm.clcw(), sa, |f| {
            sent = true;
            out(f)
        });
        if sent {
            self.last_tx_ms = now;
            self.clcw_due = false;
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
        self.pending[vc.index()] = true;
    }

    /// Sends the partly filled frames, or an idle frame with the CLCW when one is due (an
    /// authentic TC frame since the last frame, or [`IDLE_INTERVAL_MS`] without one).
    /// Scheduled ([`Endpoint::schedule`]): nothing while frames wait for their encryption.
    pub fn flush(&mut self, now: u64, mut out: impl FnMut(&[u8])) {
        let clcw: Clcw = self.rx.farm.clcw();
        if self.work.is_some() && self.framer.unsealed() > 0 {
            // Scheduled: while frames wait for their encryption, new packets gather in
            // the open frame (one frame, not one per period); that frame follows them.
            return;
        }
        if self.pending.iter().any(|&p| p) {
            for vc in TmVc::ALL {
                if !core::mem::take(&mut self.pending[vc.index()]) {
                    continue;
                }
                if let Some(sa) = self.tm_sa.as_mut() {
                    let _ = self.framer.flush(vc, clcw, sa, &mut self.store, &mut out);
                }
            }
        } else if self.framer.unsealed() == 0
            && (self.clcw_due || now.saturating_sub(self.last_tx_ms) >= IDLE_INTERVAL_MS)
        {
            // (A frame waiting for its encryption carries the CLCW when it goes.)
            let mut f = [0u8; mib::link::tm_frame::LEN];
            self.framer.idle(clcw, &mut f);
            out(&f);
        } else {
            return;
        }
        self.last_tx_ms = now;
        self.clcw_due = false;
    }

    /// The TM framer's counters.
    pub fn tx_counters(&self) -> crate::downlink::TxCounters {
        self.framer.counters
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
    use crate::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B, TEST_KEY_TM_A};
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

    fn tc_packet(seq: u16, len: usize) -> Vec<u8> {
        let mut p = vec![0x18, 0x64, 0xC0 | (seq >> 8) as u8, seq as u8, 0, 0];
        p.extend((0..len).map(|i| i as u8));
        let n = (p.len() - 7) as u16;
        p[4..6].copy_from_slice(&n.to_be_bytes());
        p
    }

    fn tc_frame(seq: u8, payload: &[u8], key: &crate::sdls::Key) -> Vec<u8> {
        let mut tx = TxSa::resume(1, key, u128::from(seq));
        let mut buf = [0u8; 1024];
        let h = crate::tc::TcRepr {
            frame_type: crate::tc::FrameType::Ad,
            scid: mib::link::SCID,
            vcid: 0,
            seq,
            data_len: 0,
        };
        let n = crate::sdls::build_tc(&mut tx, &mut MemoryIvStore::default(), h, payload, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    /// One scheduled period: TC work, the OBSW's `replies` to a packet, the flush and the
    /// TM work. The packet executed, and the frames sent.
    fn period(
        ep: &mut Endpoint<MemoryIvStore, 1, 1>,
        now: u64,
        replies: &[Vec<u8>],
    ) -> (Option<Vec<u8>>, Vec<Vec<u8>>) {
        let mut out = Vec::new();
        let mut p = [0u8; mib::link::tc_frame::MAX_PACKET_LEN];
        let packet = ep.poll_tc(&mut p).map(|n| p[..n].to_vec());
        if packet.is_some() {
            for r in replies {
                ep.send(TmVc::Realtime, r, |f| out.push(f.to_vec()));
            }
        }
        ep.flush(now, |f| out.push(f.to_vec()));
        ep.poll_tm(now, |f| out.push(f.to_vec()));
        (packet, out)
    }

    // verifies: LINK-EP-02
    #[test]
    fn scheduled_endpoint_spreads_a_frames_sdls_work_over_periods_one_direction_each() {
        use crate::downlink::TmReceiver;
        const WORK: usize = 48;
        let mut ep = endpoint();
        ep.schedule(WORK);
        assert_eq!(frames(&mut ep, 0), 1, "the first CLCW (idle frame) at once");
        // A 1024-byte frame of three packets, as the synchronous endpoint sees it.
        let packets = [tc_packet(1, 400), tc_packet(2, 400), tc_packet(3, 169)];
        let payload: Vec<u8> = packets.concat();
        let frame = tc_frame(0, &payload, &TEST_KEY_TC_A);
        assert_eq!(frame.len(), 1024);
        let mut sync = endpoint();
        let mut f = frame.clone();
        let want: Vec<Vec<u8>> = sync.receive(&mut f).unwrap().map(<[u8]>::to_vec).collect();
        assert_eq!(want, packets);
        // TM waiting when the frame comes: one full frame's worth of replies.
        let reply = tc_packet(9, 90);
        let mut sent = Vec::new();
        for _ in 0..10 {
            ep.send(TmVc::Realtime, &reply, |f| sent.push(f.to_vec()));
        }
        assert!(sent.is_empty(), "no frame is encrypted when it fills");
        ep.offer(&frame);
        assert!(ep.tc_busy());
        // 62 data blocks: the MAC check and the decryption (124 work blocks) take 3
        // periods of 48; TM waits meanwhile, then its frames take 3 periods each.
        let mut got = Vec::new();
        let mut tm = Vec::new();
        let mut log = Vec::new();
        for t in 1..=20u64 {
            let (p, out) = period(&mut ep, 10 * t, core::slice::from_ref(&reply));
            log.push((p.is_some(), out.len()));
            got.extend(p);
            tm.extend(out);
            if !ep.busy() {
                break;
            }
        }
        assert_eq!(got, want, "the packets, one per period, as the synchronous endpoint");
        let first = log.iter().position(|(p, _)| *p).unwrap();
        assert_eq!(first, 2, "accepted in the third period: {log:?}");
        assert!(
            log[..first].iter().all(|(_, n)| *n == 0),
            "no TM encrypted while the TC frame used the periods"
        );
        assert_eq!(ep.rx.counters.ad_accepted, 1);
        // The ground reads every TM packet: 10 waiting replies and one per TC packet.
        let mut sas = RxSas::<1>::default();
        sas.insert(RxSa::new(17, &TEST_KEY_TM_A, 64)).unwrap();
        let mut ground = TmReceiver::new(mib::link::SCID, sas);
        let mut n = 0;
        for f in &tm {
            let mut f = f.clone();
            if ground
                .receive(&mut MemoryIvStore::default(), &mut f, |_, p| {
                    assert_eq!(p, &reply[..]);
                    n += 1;
                })
                .is_err()
            {
                panic!("a TM frame the ground refused");
            }
        }
        assert_eq!(n, 13);
        // A forged frame: refused after the MAC check, counted, nothing executed.
        let forged = tc_frame(1, &payload, &TEST_KEY_TC_B);
        ep.offer(&forged);
        for t in 30..40u64 {
            assert!(period(&mut ep, 10 * t, &[]).0.is_none());
        }
        assert!(!ep.busy());
        assert_eq!(ep.rx.counters.bad_mac, 1);
        // More TM than the frames waiting for encryption can hold: 40 replies of 96 bytes
        // fill three 982-byte packet zones; two frames wait, the third is not built and
        // is counted.
        for _ in 0..40 {
            ep.send(TmVc::Realtime, &reply, |_| panic!("no frame at once"));
        }
        assert_eq!(ep.tx_counters().seal_queue_full, 1);
    }

    // verifies: LINK-EP-02
    #[test]
    fn a_tm_frame_waiting_for_encryption_across_a_key_change_is_dropped_and_counted() {
        let mut ep = endpoint();
        ep.schedule(8);
        let reply = tc_packet(9, 90);
        for _ in 0..11 {
            ep.send(TmVc::Realtime, &reply, |_| panic!("no frame at once"));
        }
        ep.poll_tm(10, |_| panic!("8 work blocks do not finish a frame"));
        assert_eq!(ep.framer.unsealed(), 1);
        ep.set_tm_sa(TxSa::resume(18, &TEST_KEY_TC_B, 0));
        ep.poll_tm(20, |_| panic!("no frame under a mixed key"));
        assert_eq!((ep.framer.unsealed(), ep.tx_counters().sdls_failed), (0, 1));
    }
}
