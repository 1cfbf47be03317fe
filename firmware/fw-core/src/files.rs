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
//!   frame (`TmSink::replay_room`); the PDU that does not fit waits in the entity's outbox
//!   (`mib::cfdp::OUTBOX_DEPTH`) with the rest, so a slow link slows the transfer down
//!   instead of losing its PDUs. It reads file data only as fast as the downlink takes it,
//!   at most `mib::cfdp::BOARD_SEGMENTS_PER_PERIOD` segments a period, and nothing of the
//!   store (no file data, no checksum) in a period that handled a packet, its own or a TC
//!   ([`FileService::tc_handled`]; `Entity::poll_paced`): one piece of heavy work a
//!   period, the control period's CPU budget (`t_budget`);
//! - **reports** to the OBSW's file service component (`obsw_core::services::files`: HK
//!   FILES and the FILE_* events), as the host obsw does, through its `cfdp` glue
//!   ([`FileService::report`], once per control period after `poll`): the counters of the
//!   entity, its [`Watch`] and the store, each transaction as it began (its metadata PDU
//!   taken or sent) and as it ended;
//! - **keeps** the entity's next transaction sequence number in its store
//!   ([`KeepSeq`]): read at start-up, stored when it changes and before a PDU of the
//!   transaction that took it goes down, so a reset never reuses a transaction ID;
//! - **erases ahead** ([`EraseAhead`]): in a period without a packet or a transfer, one
//!   step of the store's erasing of free sectors (at most one erase), after start-up and
//!   after each transaction that ended, so that a transfer's writes take blank sectors.
//!
//! Memory: the entity is inline (its handlers, outbox and gap list; no heap), borrowing the
//! [`Parts`] the image keeps in a static; [`NoFiles`] is a board without a file store.

use mib::cfdp::{GROUND_ENTITY_ID, MAX_PACKET_LEN};
use mmic_cfdp::entity::{Counters, Pace};
use mmic_cfdp::packet::{self, Direction};
use mmic_cfdp::seq::{EraseAhead, KeepSeq};
use mmic_cfdp::watch::{Opened, Watch};
use mmic_cfdp::{Entity, FlatStore, Parts};
use obsw_core::obsw::Obsw;
use obsw_core::services::files::{cfdp, FileCounters, Report};
use obsw_core::tm::{TmSink, TmStore};

/// Transactions opened since the last report: at most one taken (one packet a period) and
/// one sent each period; the rest is room for a report that comes late.
const OPENED_DEPTH: usize = 4;

/// What the control period asks of a file service.
pub trait FileService {
    /// Whether `packet` (an authenticated TC packet) is the service's; then it was taken.
    fn take(&mut self, now: u64, packet: &[u8]) -> bool;
    /// The period's packet went to the OBSW instead: the service's next poll does no
    /// heavy work of its own (the control period's CPU budget, `t_budget`).
    fn tc_handled(&mut self) {}
    /// Once per control period: timers and file data, then the PDUs the downlink takes.
    fn poll(&mut self, now: u64, sink: &mut impl TmSink);
    /// Once per control period after [`FileService::poll`]: what the service counted and
    /// the transactions that began and ended, to the OBSW (HK FILES, FILE_* events). A
    /// service that reports nothing leaves HK FILES without values.
    fn report<T: TmStore>(&mut self, _now: u64, _obsw: &mut Obsw<T>, _sink: &mut impl TmSink) {}
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
    /// Its PDUs to the downlink (the packets' sequence count, PDUs no packet could hold).
    down: cfdp::PduDownlink,
    parts: &'a Parts<S>,
    watch: Watch,
    /// Transactions opened and not yet reported; those past its depth are counted.
    opened: heapless::Deque<Opened, OPENED_DEPTH>,
    opened_lost: u32,
    /// The sequence number last kept in the store (or tried: a failed store is counted
    /// once, as a store medium error, and tried again when the number changes again).
    kept_seq: u16,
    /// Store medium errors of the service's own calls (keeping the number, erasing ahead).
    medium_errors: u32,
    /// The store may have sectors to erase ahead: at start, and after a transaction ended
    /// (a file written, removed or renamed); cleared when it has none, or on an error.
    erase_left: bool,
    /// Files in the store and its free bytes, and when they are counted next.
    store: cfdp::StoreLook,
    /// Partly received files removed at start.
    removed: u16,
    /// This period handled a packet (its poll reads nothing of the store).
    quiet: bool,
}

impl<'a, S: FlatStore + KeepSeq + EraseAhead> Files<'a, S> {
    /// Robot `robot`'s entity, talking to the ground's, over `parts`, going on from the
    /// transaction sequence number its store kept. Files whose transfer a reset cut short
    /// are removed first: never taken for the file they were to be (counted in HK FILES
    /// and evented, FILE_PARTIALS_REMOVED, at the first report).
    pub fn new(robot: u8, parts: &'a Parts<S>) -> Self {
        if let Some(seq) = parts.store.inner().kept_seq() {
            parts.set_next_seq(seq);
        }
        let entity = Entity::new(mib::cfdp::robot_entity_id(robot), GROUND_ENTITY_ID, parts);
        let removed = u16::try_from(entity.discard_partial()).unwrap_or(u16::MAX);
        Files {
            entity,
            down: cfdp::PduDownlink::default(),
            parts,
            watch: Watch::default(),
            opened: heapless::Deque::new(),
            opened_lost: 0,
            kept_seq: parts.next_seq(),
            medium_errors: 0,
            erase_left: true,
            store: cfdp::StoreLook::default(),
            removed,
            quiet: false,
        }
    }

    /// Transactions opened that could not wait for their report (FILE_TRANSFER_STARTED
    /// not raised; they still count in HK FILES).
    pub fn opened_lost(&self) -> u32 {
        self.opened_lost
    }

    fn opened(&mut self, o: Option<Opened>) {
        if let Some(o) = o {
            if self.opened.push_back(o).is_err() {
                self.opened_lost = self.opened_lost.wrapping_add(1);
            }
        }
    }

    /// Stores the next sequence number when the entity took one.
    fn keep_seq(&mut self) {
        let next = self.parts.next_seq();
        if next != self.kept_seq {
            self.kept_seq = next;
            if self.parts.store.inner().keep_seq(next).is_err() {
                self.medium_errors = self.medium_errors.wrapping_add(1);
            }
        }
    }

    /// What the entity, its watch and the store counted (a failed store of the sequence
    /// number or erase ahead is a store medium error).
    fn file_counters(&self) -> FileCounters {
        let mut c = cfdp::counters(&self.entity, &self.watch, &self.down, &self.store, self.removed);
        c.store_io_errors = c.store_io_errors.wrapping_add(self.medium_errors);
        c
    }

    /// The entity (counters, progress, its store).
    pub fn entity(&self) -> &Entity<'a, S> {
        &self.entity
    }

    /// The entity's counters; PDUs that did not fit a packet count as lost to the outbox.
    pub fn counters(&self) -> Counters {
        let mut c = self.entity.counters();
        c.outbox_dropped = c.outbox_dropped.wrapping_add(self.down.unsent());
        c
    }
}

impl<S: FlatStore + KeepSeq + EraseAhead> FileService for Files<'_, S> {
    fn take(&mut self, now: u64, packet: &[u8]) -> bool {
        if packet::apid(packet) != Some(mib::cfdp::APID) {
            return false;
        }
        // A packet of the APID that is not an uplink PDU packet is refused and counted.
        let before = self.entity.counters();
        self.entity.receive_packet(now, Direction::Up, packet);
        let after = self.entity.counters();
        if after.received != before.received && after.handler_errors == before.handler_errors {
            let o = packet::unwrap(Direction::Up, packet).and_then(|pdu| self.watch.taken(pdu));
            self.opened(o);
        }
        self.quiet = true;
        true
    }

    fn tc_handled(&mut self) {
        self.quiet = true;
    }

    fn poll(&mut self, now: u64, sink: &mut impl TmSink) {
        // One piece of heavy work a period: after a packet (a PDU taken, a TC the OBSW
        // handled) nothing read of the store; else file data only as much as the downlink
        // takes now, and the checksums.
        let pace = if core::mem::take(&mut self.quiet) {
            Pace::Quiet
        } else {
            let room = sink.replay_room() / MAX_PACKET_LEN;
            Pace::Segments(room.min(mib::cfdp::BOARD_SEGMENTS_PER_PERIOD))
        };
        self.entity.poll_paced(now, pace);
        // Before any PDU of a transaction that took a new number goes down.
        self.keep_seq();
        // A period with time to spare: no packet, no transfer. One erase at most, so that
        // the next transfer's writes take blank sectors.
        if pace != Pace::Quiet && self.erase_left && self.entity.idle() {
            match self.parts.store.inner().erase_ahead() {
                Ok(more) => self.erase_left = more,
                Err(_) => {
                    self.medium_errors = self.medium_errors.wrapping_add(1);
                    self.erase_left = false;
                }
            }
        }
        let mut buf = [0u8; MAX_PACKET_LEN];
        while let Some(o) = self.down.send_next(&mut self.entity, &mut self.watch, sink, &mut buf) {
            self.opened(o);
        }
    }

    fn report<T: TmStore>(&mut self, now: u64, obsw: &mut Obsw<T>, sink: &mut impl TmSink) {
        while let Some(o) = self.opened.pop_front() {
            obsw.files_report(now, Report::Began(cfdp::began(&o)), sink);
        }
        let mut ended = false;
        while let Some(f) = self.entity.take_finished() {
            let e = cfdp::ended(&self.entity, &self.watch, &f);
            obsw.files_report(now, Report::Ended(e), sink);
            ended = true;
        }
        self.erase_left |= ended;
        self.store.update(now, ended, &self.entity);
        obsw.files_report(now, Report::Counters(self.file_counters()), sink);
    }
}
