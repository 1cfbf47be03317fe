//! Board A's file service: the CFDP entity the host obsw runs (`mmic_cfdp::Entity`,
//! docs/files.md) over a generic file store, beside the OBSW in the control period.
//!
//! Interface:
//! - **takes** the TC packets of `mib::cfdp::APID` that the frame link delivered
//!   ([`FileService::take`], called by `spacelink::FrameLink::receive` before the OBSW
//!   sees a packet): authenticated, in order, once each. The bare-packet test link never
//!   hands it one (nothing unauthenticated reaches the store);
//! - **supplies** TM packets of that APID, no PUS header, on VC0 (board A's framer has one
//!   packet zone), through `TmSink::send_file` ([`FileService::poll`], once per control
//!   period after `Obsw::tick`): only while the downlink takes them without dropping a
//!   frame (`TmSink::replay_room`); the PDU that does not fit waits here, and the entity's
//!   outbox (`mib::cfdp::OUTBOX_DEPTH`) holds the rest, so a slow link slows the transfer
//!   down instead of losing its PDUs;
//! - **counters**: the entity's ([`mmic_cfdp::entity::Counters`]) and the store's.
//!
//! Memory: the entity is inline (its handlers, outbox and gap list; no heap), borrowing the
//! [`Parts`] the image keeps in a static; [`NoFiles`] is a board without a file store.

use mib::cfdp::{GROUND_ENTITY_ID, MAX_PACKET_LEN};
use mmic_cfdp::entity::{Counters, Pdu};
use mmic_cfdp::packet::{self, Direction};
use mmic_cfdp::{Entity, FlatStore, Parts};
use obsw_core::tm::TmSink;

/// What the control period asks of a file service.
pub trait FileService {
    /// Whether `packet` (an authenticated TC packet) is the service's; then it was taken.
    fn take(&mut self, now: u64, packet: &[u8]) -> bool;
    /// Once per control period: timers and file data, then the PDUs the downlink takes.
    fn poll(&mut self, now: u64, sink: &mut impl TmSink);
}

/// A board without a file store: no packet is taken (one of the CFDP APID goes to the
/// OBSW, which refuses and counts it like any packet of an APID it does not serve).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoFiles;

impl FileService for NoFiles {
    fn take(&mut self, _now: u64, _packet: &[u8]) -> bool {
        false
    }
    fn poll(&mut self, _now: u64, _sink: &mut impl TmSink) {}
}

/// The file service over store `S` (see the module documentation).
pub struct Files<'a, S: FlatStore> {
    entity: Entity<'a, S>,
    /// The next TM packet's sequence count on the CFDP APID.
    seq: u16,
    /// A PDU the downlink had no room for: the first to go next period.
    held: Option<Pdu>,
    /// PDUs that did not fit a packet (none can: the outbox holds at most
    /// `MAX_PDU_LEN` bytes a PDU), dropped.
    unsent: u32,
}

impl<'a, S: FlatStore> Files<'a, S> {
    /// Robot `robot`'s entity, talking to the ground's, over `parts`. Files whose transfer
    /// a reset cut short are removed first: never taken for the file they were to be.
    pub fn new(robot: u8, parts: &'a Parts<S>) -> Self {
        let entity = Entity::new(mib::cfdp::robot_entity_id(robot), GROUND_ENTITY_ID, parts);
        entity.discard_partial();
        Files {
            entity,
            seq: 0,
            held: None,
            unsent: 0,
        }
    }

    /// The entity (counters, progress, its store).
    pub fn entity(&self) -> &Entity<'a, S> {
        &self.entity
    }

    /// The entity's counters; PDUs that did not fit a packet count as lost to the outbox.
    pub fn counters(&self) -> Counters {
        let mut c = self.entity.counters();
        c.outbox_dropped = c.outbox_dropped.wrapping_add(self.unsent);
        c
    }
}

impl<S: FlatStore> FileService for Files<'_, S> {
    fn take(&mut self, now: u64, packet: &[u8]) -> bool {
        if packet::apid(packet) != Some(mib::cfdp::APID) {
            return false;
        }
        // A packet of the APID that is not an uplink PDU packet is refused and counted.
        self.entity.receive_packet(now, Direction::Up, packet);
        true
    }

    fn poll(&mut self, now: u64, sink: &mut impl TmSink) {
        self.entity.poll(now);
        let mut buf = [0u8; MAX_PACKET_LEN];
        while let Some(pdu) = self.held.take().or_else(|| self.entity.pop()) {
            // The outbox holds PDUs of at most MAX_PDU_LEN bytes, none empty: each fits.
            let Some(n) = packet::wrap(Direction::Down, self.seq, &pdu, &mut buf) else {
                self.unsent = self.unsent.wrapping_add(1);
                continue;
            };
            if sink.replay_room() < n {
                self.held = Some(pdu);
                break;
            }
            self.seq = self.seq.wrapping_add(1) & 0x3FFF;
            sink.send_file(&buf[..n]);
        }
    }
}
