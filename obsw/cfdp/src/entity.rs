//! One CFDP entity: cfdp-rs' source and destination handlers (one transaction each way at
//! a time) over a checked file store, with the time passed in, PDUs in through
//! [`Entity::receive`] and out through a bounded outbox ([`Entity::pop`]).
//!
//! What this layer adds to cfdp-rs:
//! - **A gate for untrusted PDUs.** Every PDU is parsed whole with spacepackets' readers
//!   (header, lengths, the directive's own fields) and must be addressed to this entity
//!   before a handler sees it; a refusal is counted ([`Counters::refused`]).
//! - **The user's side of the protocol** (727.0-B-5 § 6): a Proxy Put Request (a `get`
//!   from the peer) and a Directory Listing Request carried as reserved messages to user
//!   make this entity put a file back; filestore requests (delete, rename) in a metadata
//!   PDU are executed on the checked store.
//! - **Inactivity**: a transaction that hears no PDU for `mib::cfdp::INACTIVITY_MS` is
//!   abandoned (cfdp-rs 0.3 has no inactivity timer).
//! - **Timers and limits from the MIB** (`mib::cfdp`), one clock for both handlers.
//!
//! Memory: everything is inline (two handlers with 1 KiB buffers each, the outbox of
//! `OUTBOX_DEPTH` PDUs, the lost-segment list); nothing is allocated.

use core::cell::{Cell, RefCell};
use core::time::Duration;

use ::cfdp::dest::DestinationHandler;
use ::cfdp::request::ReadablePutRequest;
use ::cfdp::source::{SourceHandler, TransactionStep as SourceStep};
use ::cfdp::time::Countdown;
use ::cfdp::user::{CfdpUser, FileSegmentRecvdParams, MetadataReceivedParams, TransactionFinishedParams};
use ::cfdp::{
    FaultInfo, GenericSendError, IndicationConfig, LocalEntityConfig, PacketTarget, PduProvider, PduRawWithInfo,
    PduSender, RemoteEntityConfig, State, TimerContext, TimerCreator, TransactionId, UserFaultHook,
};
use mib::cfdp as m;
use spacepackets::cfdp::pdu::ack::AckPdu;
use spacepackets::cfdp::pdu::eof::EofPdu;
use spacepackets::cfdp::pdu::file_data::FileDataPdu;
use spacepackets::cfdp::pdu::finished::FinishedPduReader;
use spacepackets::cfdp::pdu::finished::{DeliveryCode, FileStatus};
use spacepackets::cfdp::pdu::metadata::{MetadataPduCreator, MetadataPduReader};
use spacepackets::cfdp::pdu::nak::{NakPduCreator, NakPduReader};
use spacepackets::cfdp::pdu::CfdpPdu;
use spacepackets::cfdp::pdu::{FileDirectiveType, PduHeader};
use spacepackets::cfdp::tlv::{
    FilestoreActionCode, FilestoreRequestTlv, GenericTlv, ReadableTlv, Tlv, TlvType, WritableTlv,
};
use spacepackets::cfdp::{
    ChecksumType, ConditionCode, PduType, SegmentMetadataFlag, SegmentationControl, TransactionStatus, TransmissionMode,
};
use spacepackets::util::{UnsignedByteField, UnsignedByteFieldU16, UnsignedEnum};

use crate::gaps::Gaps;
use crate::msg::{self, ReservedMsg};
use crate::packet::Direction;
use crate::store::{Checked, FileName, FlatStore, Side};
use ::cfdp::lost_segments::LostSegmentStore;

pub use crate::pdu::Pdu;

/// What a poll may do of the file store's work ([`Entity::poll_paced`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pace {
    /// Nothing read: timers and directives only.
    Quiet,
    /// At most this many file data PDUs, and the checksums.
    Segments(usize),
}

/// The entity's clock (ms, wrapping at 2^32: timers are far shorter) and the outbox the
/// handlers write to; shared by both handlers and their timers.
pub struct PduPort {
    now: Cell<u32>,
    outbox: RefCell<heapless::Deque<Pdu, { m::OUTBOX_DEPTH }>>,
    dropped: Cell<u32>,
    /// When the destination handler last sent a NAK on its NAK timer (the timer's start).
    nak_at: Cell<u32>,
    /// Set for one handler call: a NAK timer started before this time counts as expired
    /// (the retransmissions the last NAK asked for have come and stopped).
    nak_due: Cell<Option<u32>>,
    /// End of the furthest file data segment sent in the running outgoing transaction.
    sent_to: Cell<u64>,
    /// When the last file data PDU of the running incoming transaction arrived.
    data_at: Cell<Option<u32>>,
    /// End of the last segment the destination handler's last NAK asked for (the sender
    /// answers a NAK's requests in order, so its answer ends the NAK's answers).
    nak_end: Cell<Option<u64>>,
    /// That segment arrived after the NAK: what the NAK asked for and is still missing was
    /// lost again, and the next NAK need not wait for `NAK_QUIET_MS`.
    nak_answered: Cell<bool>,
    /// Copies of metadata and Finished PDUs, sent at the next poll (`ROBOT_DIRECTIVE_COPIES`).
    copies_due: RefCell<heapless::Deque<Pdu, { 2 * m::ROBOT_DIRECTIVE_COPIES }>>,
}

impl Default for PduPort {
    fn default() -> Self {
        PduPort {
            now: Cell::new(0),
            outbox: RefCell::new(heapless::Deque::new()),
            dropped: Cell::new(0),
            nak_at: Cell::new(0),
            nak_due: Cell::new(None),
            sent_to: Cell::new(0),
            data_at: Cell::new(None),
            nak_end: Cell::new(None),
            nak_answered: Cell::new(false),
            copies_due: RefCell::new(heapless::Deque::new()),
        }
    }
}

/// A countdown on the entity's clock.
#[derive(Debug)]
pub struct Timer<'a> {
    link: &'a PduPort,
    start: u32,
    period: u32,
    /// The NAK timer (see [`PduPort::nak_due`]).
    nak: bool,
}

impl core::fmt::Debug for PduPort {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("PduPort")
            .field("now", &self.now.get())
            .finish_non_exhaustive()
    }
}

impl Countdown for Timer<'_> {
    fn has_expired(&self) -> bool {
        let now = self.link.now.get();
        let early = self.nak
            && self
                .link
                .nak_due
                .get()
                .is_some_and(|t| t.wrapping_sub(self.start) as i32 > 0 && now.wrapping_sub(t) as i32 >= 0);
        // The answers to the last NAK still coming in: not yet time to ask again.
        let answering = self.nak
            && self
                .link
                .data_at
                .get()
                .is_some_and(|t| (now.wrapping_sub(t) as u64) < m::NAK_QUIET_MS);
        early || (now.wrapping_sub(self.start) >= self.period && !answering)
    }
    fn reset(&mut self) {
        self.start = self.link.now.get();
        if self.nak {
            self.link.nak_at.set(self.start);
        }
    }
}

/// The handlers' timer factory: the check timer from the MIB, the others from the remote
/// entity's configuration (itself from the MIB).
pub struct Timers<'a>(&'a PduPort);

impl<'a> TimerCreator for Timers<'a> {
    type Countdown = Timer<'a>;
    fn create_countdown(&self, ctx: TimerContext) -> Timer<'a> {
        let (ms, nak) = match ctx {
            TimerContext::CheckLimit { .. } => (m::CHECK_TIMER_MS, false),
            TimerContext::NakActivity { expiry_time } => (expiry_time.as_millis() as u64, true),
            TimerContext::PositiveAck { expiry_time } => (expiry_time.as_millis() as u64, false),
        };
        let start = self.0.now.get();
        if nak {
            // Created when the first NAK of the deferred procedure goes out.
            self.0.nak_at.set(start);
        }
        Timer {
            link: self.0,
            start,
            period: ms.min(u32::MAX as u64) as u32,
            nak,
        }
    }
}

/// The handlers' PDU sender: into the outbox. A full outbox refuses the source handler's
/// PDU (its procedure stays where it was and makes the same PDU at its next call: no file
/// data is skipped) and drops the destination handler's, counted, as the link would lose a
/// frame, telling the handler it went out: cfdp-rs 0.3's destination handler stops its
/// procedure half way on a refusal (a gap recorded but the end of the data seen not moved
/// on, an EOF taken but neither acknowledged nor its missing data asked for), while every
/// PDU it sends (NAK, ACK, Finished) is recovered by its own timers or the peer's when lost.
pub struct Sender<'a> {
    port: &'a PduPort,
    when_full: WhenFull,
    /// Copies of each metadata and Finished PDU (see `mib::cfdp::ROBOT_DIRECTIVE_COPIES`).
    copies: usize,
}

/// What a full outbox does to a handler's PDU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum WhenFull {
    /// Refused: the source handler sends it again.
    Refuse,
    /// Dropped as lost on the link: the destination handler.
    Lose,
}

impl<'a> Sender<'a> {
    fn source(port: &'a PduPort) -> Self {
        Sender {
            port,
            when_full: WhenFull::Refuse,
            copies: 1,
        }
    }
    fn dest(port: &'a PduPort) -> Self {
        Sender {
            port,
            when_full: WhenFull::Lose,
            copies: 1,
        }
    }
    /// Entity `id`'s copies of its metadata and Finished PDUs.
    fn copies(mut self, id: u16) -> Self {
        self.copies = if id == m::GROUND_ENTITY_ID {
            m::GROUND_DIRECTIVE_COPIES
        } else {
            m::ROBOT_DIRECTIVE_COPIES
        };
        self
    }
}

impl PduSender for Sender<'_> {
    fn send_pdu(&self, t: PduType, d: Option<FileDirectiveType>, raw: &[u8]) -> Result<(), GenericSendError> {
        if d == Some(FileDirectiveType::NakPdu) {
            if let Ok(nak) = NakPduReader::from_bytes(raw) {
                let end = nak
                    .get_segment_requests_iterator()
                    .into_iter()
                    .flatten()
                    .filter(|&(a, b)| b > a)
                    .map(|(_, b)| b)
                    .max();
                self.port.nak_end.set(end);
                self.port.nak_answered.set(false);
            }
        }
        if t == PduType::FileData {
            if let Ok(fd) = FileDataPdu::from_bytes(raw) {
                let end = fd.offset().saturating_add(fd.file_data().len() as u64);
                self.port.sent_to.set(self.port.sent_to.get().max(end));
            }
        }
        let Ok(pdu) = Pdu::from_slice(raw) else {
            self.port.dropped.set(self.port.dropped.get().wrapping_add(1));
            return Err(GenericSendError::Other);
        };
        let mut outbox = self.port.outbox.borrow_mut();
        if outbox.push_back(pdu).is_err() {
            self.port.dropped.set(self.port.dropped.get().wrapping_add(1));
            return match self.when_full {
                WhenFull::Refuse => Err(GenericSendError::QueueFull(None)),
                WhenFull::Lose => Ok(()),
            };
        }
        if matches!(d, Some(FileDirectiveType::MetadataPdu | FileDirectiveType::FinishedPdu)) {
            // The further copies go at the entity's next poll, in another frame than this
            // one (a frame carries several small PDUs: copies in one frame are lost
            // together). Only where there is room: a lost PDU is recovered as before.
            let mut due = self.port.copies_due.borrow_mut();
            let Some(pdu) = outbox.back() else { return Ok(()) };
            for _ in 1..self.copies {
                if due.push_back(pdu.clone()).is_err() {
                    break;
                }
            }
        }
        Ok(())
    }
}

/// The transaction sequence numbers, kept outside the source handler (which is made anew
/// for each transaction: see [`Entity::put`]).
pub struct Seq<'a>(&'a Cell<u16>);

impl spacepackets::seq_count::SequenceCounter for Seq<'_> {
    type Raw = u16;
    const MAX_BIT_WIDTH: usize = 16;
    fn get(&self) -> u16 {
        self.0.get()
    }
    fn increment(&self) {
        self.0.set(self.0.get().wrapping_add(1));
    }
}

/// Faults the handlers declared (727.0-B-5 § 4.8), counted, the last one's condition kept.
pub struct Faults<'a>(&'a Cell<u32>, &'a Cell<Option<ConditionCode>>);

impl Faults<'_> {
    fn count(&mut self, f: FaultInfo) {
        self.0.set(self.0.get().wrapping_add(1));
        self.1.set(Some(f.condition_code()));
    }
}

impl UserFaultHook for Faults<'_> {
    fn notice_of_suspension_cb(&mut self, f: FaultInfo) {
        self.count(f);
    }
    fn notice_of_cancellation_cb(&mut self, f: FaultInfo) {
        self.count(f);
    }
    fn abandoned_cb(&mut self, f: FaultInfo) {
        self.count(f);
    }
    fn ignore_cb(&mut self, f: FaultInfo) {
        self.count(f);
    }
}

type Source<'a, S> =
    SourceHandler<Sender<'a>, Faults<'a>, &'a Checked<S>, RemoteEntityConfig, Timers<'a>, Timer<'a>, Seq<'a>>;
type Dest<'a, S> =
    DestinationHandler<Sender<'a>, Faults<'a>, &'a Checked<S>, RemoteEntityConfig, Timers<'a>, Timer<'a>, Gaps>;

/// What the caller provides and the entity borrows: the store, the clock and outbox,
/// the fault counter.
pub struct Parts<S> {
    pub store: Checked<S>,
    pub link: PduPort,
    faults: Cell<u32>,
    last_fault: Cell<Option<ConditionCode>>,
    seq: Cell<u16>,
}

impl<S: FlatStore> Parts<S> {
    pub fn new(store: S) -> Self {
        Parts {
            store: Checked::new(store),
            link: PduPort::default(),
            faults: Cell::new(0),
            last_fault: Cell::new(None),
            seq: Cell::new(0),
        }
    }

    /// The next transaction sequence number. Transaction IDs must not repeat: a platform
    /// keeps this across restarts ([`Parts::set_next_seq`] at start-up).
    pub fn next_seq(&self) -> u16 {
        self.seq.get()
    }

    pub fn set_next_seq(&self, seq: u16) {
        self.seq.set(seq);
    }
}

/// Transfer class (727.0-B-5 § 2.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Class {
    /// Unacknowledged: nothing is sent again; the receiver checks the checksum.
    One,
    /// Acknowledged: NAKs for missing data, EOF and Finished acknowledged.
    Two,
}

impl Class {
    fn mode(self) -> TransmissionMode {
        match self {
            Class::One => TransmissionMode::Unacknowledged,
            Class::Two => TransmissionMode::Acknowledged,
        }
    }
}

/// How a transaction ended, as the user sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Finished {
    /// Source entity and sequence number.
    pub source: u16,
    pub seq: u16,
    /// This entity sent the file (`true`) or received it.
    pub sent: bool,
    pub condition: ConditionCode,
    /// The file arrived complete (receiver: checksum verified; sender: as the peer's
    /// Finished PDU says, or `true` in class 1 without closure).
    pub complete: bool,
    /// Receiver: the file was kept in the store.
    pub retained: bool,
}

/// Counters of the entity (file store housekeeping, events).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// PDUs taken (passed the gate).
    pub received: u32,
    /// PDUs refused at the gate (malformed, not for this entity, no transaction).
    pub refused: u32,
    /// PDUs a handler refused (wrong transaction, a second transaction while busy).
    pub handler_errors: u32,
    /// PDUs lost because the outbox was full.
    pub outbox_dropped: u32,
    /// Faults declared (checksum, limits, inactivity, filestore).
    pub faults: u32,
    /// Transactions finished complete / not.
    pub completed: u32,
    pub failed: u32,
    /// Filestore requests executed / refused.
    pub fs_done: u32,
    pub fs_refused: u32,
    /// Puts requested by the peer (get, listing) refused (busy, bad name, no file).
    pub proxy_refused: u32,
    /// File data and EOF PDUs of a transaction whose metadata had not arrived (dropped).
    pub before_metadata: u32,
    /// Segment requests dropped because the resend queue was full (asked for again).
    pub resend_dropped: u32,
    /// Incoming transactions ended by the peer's next one before their Finished was
    /// acknowledged.
    pub superseded: u32,
    /// PDUs of another transaction than the running one, or of one already finished
    /// (late retransmissions, duplicates): dropped.
    pub stray: u32,
    /// Finished PDUs that arrived before the ACK of our EOF (which was lost) and stood
    /// for it.
    pub eof_ack_by_finished: u32,
    /// File data PDUs sent again on the peer's NAKs.
    pub resent: u32,
    /// Finished PDUs of a transaction this entity sent and ended, acknowledged again (the
    /// first ACK was lost).
    pub finished_acked_again: u32,
    /// End indications of a transaction already reported (not reported again).
    pub repeated_ends: u32,
}

/// A put this entity owes its peer (a proxy put or a directory listing), done when the
/// source handler is free.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Owed {
    src: FileName,
    dest: FileName,
    class: Class,
}

/// Why a put request was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PutError {
    /// A transaction is already being sent.
    Busy,
    /// A name failed the store's checks, or the file is missing.
    BadName,
    NoFile,
    /// cfdp-rs refused the request.
    Refused,
}

impl core::fmt::Display for PutError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            PutError::Busy => "a file is already being sent",
            PutError::BadName => "a file name failed the store's checks",
            PutError::NoFile => "no such file in the store",
            PutError::Refused => "the CFDP source handler refused the request",
        })
    }
}

/// The user indications, collected during one handler call.
#[derive(Default)]
struct User {
    finished: heapless::Deque<Finished, 4>,
    owed: heapless::Deque<Owed, 2>,
    proxy_refused: u32,
    /// End of the furthest file data segment received in the running transaction, and the
    /// length of its file.
    progress: u64,
    incoming_len: u64,
    sending: bool,
    /// A listing to write before the put it owes.
    listing: Option<FileName>,
    completed: u32,
    failed: u32,
    /// Finished indications of sent transactions (to see one cfdp-rs did not give).
    sent_reports: u32,
    /// The last transactions reported ended (source, sequence number, sent): cfdp-rs 0.3
    /// indicates an incoming transaction's end again when its EOF comes again while the
    /// Finished waits for its ACK (a serial link's retries, the relay's duplicates): one
    /// report a transaction, or the completed counts and the end events count it twice.
    ended: heapless::Deque<(u16, u16, bool), 8>,
    /// End indications of a transaction already reported.
    repeated_ends: u32,
}

/// Whether a filestore request TLV's value holds its action code and its whole first name
/// (and second name, if any): spacepackets 0.16's `FilestoreRequestTlv::from_bytes` indexes
/// the action code unchecked, and a metadata PDU with an empty filestore request panicked
/// the entity (found by the fuzz target `cfdp_pdu`).
fn filestore_request_whole(v: &[u8]) -> bool {
    let Some((&n1, rest)) = v.get(1..).and_then(<[u8]>::split_first) else {
        return false;
    };
    let Some(rest) = rest.get(usize::from(n1)..) else {
        return false;
    };
    match rest.split_first() {
        None => true,
        Some((&n2, rest)) => rest.len() == usize::from(n2),
    }
}

/// The staging name of the file of incoming transaction `tx` (source entity, sequence).
fn partial_name(tx: (u16, u16)) -> Option<FileName> {
    let mut s: heapless::String<{ m::MAX_NAME_LEN }> = heapless::String::new();
    core::fmt::write(&mut s, format_args!("{}{}-{}", m::PARTIAL_PREFIX, tx.0, tx.1)).ok()?;
    FileName::new(&s).ok()
}

fn id_u16(f: &UnsignedByteField) -> u16 {
    f.value() as u16
}

impl User {
    /// A transaction's end for the user, counted.
    fn report(&mut self, f: Finished) {
        let key = (f.source, f.seq, f.sent);
        if self.ended.iter().any(|k| *k == key) {
            self.repeated_ends = self.repeated_ends.wrapping_add(1);
            return;
        }
        if self.ended.is_full() {
            self.ended.pop_front();
        }
        let _ = self.ended.push_back(key);
        if f.complete {
            self.completed = self.completed.wrapping_add(1);
        } else {
            self.failed = self.failed.wrapping_add(1);
        }
        if self.finished.push_back(f).is_err() {
            // Oldest report out: the counters keep the totals.
            self.finished.pop_front();
            let _ = self.finished.push_back(f);
        }
    }

    /// A message to user from the peer: a reserved message this entity acts on, or none.
    /// `mode`: the class of a Proxy Transmission Mode sent as a message of its own.
    fn message(&mut self, v: &[u8], mode: Option<Class>) {
        let owed = match msg::parse(v) {
            Some(ReservedMsg::ProxyPut { src, dest, class, .. }) => match (FileName::new(src), FileName::new(dest)) {
                (Ok(src), Ok(dest)) => Some(Owed {
                    src,
                    dest,
                    class: mode.unwrap_or(class),
                }),
                _ => None,
            },
            Some(ReservedMsg::DirectoryListing { dest, .. }) => match FileName::new(dest) {
                Ok(dest) => {
                    self.listing = Some(dest.clone());
                    Some(Owed {
                        src: dest.clone(),
                        dest,
                        class: Class::Two,
                    })
                }
                Err(_) => None,
            },
            None => return,
        };
        match owed.map(|o| self.owed.push_back(o)) {
            Some(Ok(())) => {}
            _ => self.proxy_refused = self.proxy_refused.wrapping_add(1),
        }
    }
}

impl CfdpUser for User {
    fn transaction_indication(&mut self, _id: &TransactionId) {}
    fn eof_sent_indication(&mut self, _id: &TransactionId) {}
    fn transaction_finished_indication(&mut self, p: &TransactionFinishedParams) {
        if self.sending {
            self.sent_reports = self.sent_reports.wrapping_add(1);
        }
        let f = Finished {
            source: id_u16(p.id.source_id()),
            seq: id_u16(p.id.seq_num()),
            sent: self.sending,
            condition: p.condition_code,
            complete: p.condition_code == ConditionCode::NoError && p.delivery_code == DeliveryCode::Complete,
            retained: p.file_status == FileStatus::Retained,
        };
        self.report(f);
    }
    fn metadata_recvd_indication(&mut self, p: &MetadataReceivedParams) {
        self.progress = 0;
        self.incoming_len = p.file_size;
    }
    fn file_segment_recvd_indication(&mut self, p: &FileSegmentRecvdParams) {
        // The end of the furthest segment: duplicates and segments sent again do not count
        // twice (a sum reached 1069 KiB for a 256 KiB file through the relay).
        self.progress = self.progress.max(p.offset.saturating_add(p.length as u64));
    }
    fn report_indication(&mut self, _id: &TransactionId) {}
    fn suspended_indication(&mut self, _id: &TransactionId, _c: ConditionCode) {}
    fn resumed_indication(&mut self, _id: &TransactionId, _p: u64) {}
    fn fault_indication(&mut self, _id: &TransactionId, _c: ConditionCode, _p: u64) {}
    fn abandoned_indication(&mut self, _id: &TransactionId, _c: ConditionCode, _p: u64) {}
    fn eof_recvd_indication(&mut self, _id: &TransactionId) {}
}

/// A put request. cfdp-rs 0.3's own `PutRequest` returns its messages to user as its
/// filestore requests (each message goes out twice, no filestore request at all).
struct Put<'a> {
    dest_id: UnsignedByteField,
    src: Option<&'a str>,
    dest: Option<&'a str>,
    mode: TransmissionMode,
    closure: bool,
    msgs: Option<&'a [Tlv<'a>]>,
    fs: Option<&'a [Tlv<'a>]>,
}

impl ReadablePutRequest for Put<'_> {
    fn destination_id(&self) -> UnsignedByteField {
        self.dest_id
    }
    fn source_file(&self) -> Option<&str> {
        self.src
    }
    fn dest_file(&self) -> Option<&str> {
        self.dest
    }
    fn trans_mode(&self) -> Option<TransmissionMode> {
        Some(self.mode)
    }
    fn closure_requested(&self) -> Option<bool> {
        Some(self.closure)
    }
    fn seg_ctrl(&self) -> Option<spacepackets::cfdp::SegmentationControl> {
        None
    }
    fn msgs_to_user(&self) -> Option<impl Iterator<Item = Tlv<'_>>> {
        self.msgs.map(|m| m.iter().copied())
    }
    fn fault_handler_overrides(&self) -> Option<impl Iterator<Item = Tlv<'_>>> {
        None::<core::iter::Empty<Tlv<'_>>>
    }
    fn flow_label(&self) -> Option<Tlv<'_>> {
        None
    }
    fn fs_requests(&self) -> Option<impl Iterator<Item = Tlv<'_>>> {
        self.fs.map(|m| m.iter().copied())
    }
}

/// The entity (see the module documentation).
pub struct Entity<'a, S: FlatStore> {
    id: u16,
    peer: u16,
    parts: &'a Parts<S>,
    source: Source<'a, S>,
    dest: Dest<'a, S>,
    user: User,
    counters: Counters,
    /// Last time a PDU of the running transactions was heard (inactivity).
    last_heard: u32,
    /// The last transaction whose user requests were acted on (source entity, sequence).
    last_user_tx: Option<(u16, u16)>,
    /// The last metadata NAK: transaction and time.
    metadata_nak: Option<((u16, u16), u32)>,
    /// Class 1 puts ask for closure (a Finished PDU), so the sender learns the outcome.
    class1_closure: bool,
    /// Length of the file being sent (0: metadata only) and its name.
    sending_len: u64,
    sending_name: Option<FileName>,
    /// The last transaction this entity sent that the peer's Finished ended (its Finished
    /// may come again when our ACK was lost).
    finished_tx: Option<(u16, u16)>,
    /// The incoming transaction's file: its name and the staging name it is written under.
    receiving: Option<((u16, u16), FileName, FileName)>,
    /// The last incoming transaction whose file was found complete and put under its name.
    received_whole: Option<(u16, u16)>,
    /// The last incoming transactions that finished: their late PDUs are strays.
    finished_rx: heapless::Deque<(u16, u16), 4>,
    /// Segment requests of the peer's NAKs not yet fed to the source handler, with the
    /// header and scope of the last NAK.
    resend: heapless::Deque<(u32, u32), { m::MAX_LOST_SEGMENTS }>,
    resend_header: Option<PduHeader>,
    resend_scope: (u32, u32),
    /// Segments of the running outgoing transaction already sent again once, one bit per
    /// `MAX_SEGMENT_LEN` of the file: a segment asked for a second time is sent twice (a
    /// loss of one in four through the relay made each further round trip cost a NAK round).
    resent_once: [u32; RESENT_WORDS],
    /// File data PDUs this control period may still send (`SEGMENTS_PER_POLL`).
    budget: usize,
    /// The incoming file's bytes not yet received (from its metadata's length; `None`
    /// when not known: a gap list that overflowed, an EOF of another length).
    rx_missing: Gaps,
    rx_missing_known: bool,
    /// The incoming transaction's checksum type, and whether its EOF went to the handler.
    rx_kind: ChecksumType,
    rx_eof_passed: bool,
    /// End of the furthest segment of the incoming file given to the handler.
    rx_end: u64,
    /// The fault count when the incoming transaction began: after a fault the handler's
    /// own course runs, nothing held (its file may lack a refused write).
    rx_faults: u32,
    /// The PDU that would make the destination handler sum the whole file in one call (the
    /// EOF of a complete file, the segment that completes it after the EOF), held while
    /// [`Entity::poll`] sums the file `CHECKSUM_BYTES_PER_POLL` at a time.
    rx_held: Option<Pdu>,
    /// The end of the held segment; `None`: the held PDU is the EOF.
    rx_held_end: Option<u64>,
}

/// Words of [`Entity::resent_once`]: a bit for each segment of the largest file.
const RESENT_WORDS: usize = (m::MAX_FILE_LEN as usize).div_ceil(m::MAX_SEGMENT_LEN).div_ceil(32);

/// The peer's configuration as entity `id` runs it: sizes, class defaults, timers and
/// limits from the MIB; immediate NAKs from the robot's entity only
/// (`ROBOT_IMMEDIATE_NAK`, `GROUND_IMMEDIATE_NAK`).
pub fn remote_config(id: u16, peer: u16) -> RemoteEntityConfig {
    let mut c = RemoteEntityConfig::new_with_default_values(
        UnsignedByteFieldU16::new(peer).into(),
        m::MAX_PDU_LEN,
        true,
        m::PDU_CRC,
        TransmissionMode::Acknowledged,
        checksum_kind(),
    );
    c.max_file_segment_len = Some(m::MAX_SEGMENT_LEN);
    c.immediate_nak_mode = if id == m::GROUND_ENTITY_ID {
        m::GROUND_IMMEDIATE_NAK
    } else {
        m::ROBOT_IMMEDIATE_NAK
    };
    c.positive_ack_timer_interval = Duration::from_millis(m::ACK_TIMER_MS);
    c.positive_ack_timer_expiration_limit = m::ACK_LIMIT;
    c.nak_timer_interval = Duration::from_millis(m::NAK_TIMER_MS);
    c.nak_timer_expiration_limit = m::NAK_LIMIT;
    c.check_limit = m::CHECK_LIMIT;
    c
}

/// The checksum type of this entity's puts (`mib::cfdp::CHECKSUM_TYPE`).
fn checksum_kind() -> ChecksumType {
    ChecksumType::try_from(m::CHECKSUM_TYPE).unwrap_or(ChecksumType::Modular)
}

fn local_config<S>(id: u16, parts: &Parts<S>) -> LocalEntityConfig<Faults<'_>> {
    LocalEntityConfig::new(
        UnsignedByteFieldU16::new(id).into(),
        IndicationConfig::default(),
        Faults(&parts.faults, &parts.last_fault),
    )
}

/// Whether `raw` is one whole, well-formed PDU: the header's lengths match, and the
/// directive parses with its own reader. cfdp-rs indexes into PDUs it routes; nothing
/// reaches it unparsed.
pub fn well_formed(raw: &[u8]) -> Option<PduHeader> {
    let (h, hl) = PduHeader::from_bytes(raw).ok()?;
    if h.pdu_len() != raw.len() || hl >= raw.len() {
        return None;
    }
    // Files here are far below 4 GiB (`MAX_FILE_LEN`); spacepackets 0.16's readers panic on
    // a short PDU with the large-file flag (8-byte sizes read unchecked).
    if h.common_pdu_conf().file_flag != spacepackets::cfdp::LargeFileFlag::Normal {
        return None;
    }
    let ok = match h.pdu_type() {
        PduType::FileData => file_data_fits(&h, hl, raw) && FileDataPdu::from_bytes(raw).is_ok(),
        PduType::FileDirective => match FileDirectiveType::try_from(raw[hl]).ok()? {
            FileDirectiveType::MetadataPdu => MetadataPduReader::from_bytes(raw).is_ok(),
            // spacepackets 0.16 slices the checksum and file size unchecked: directive,
            // condition, checksum (4) and size (4, normal files) must be there.
            FileDirectiveType::EofPdu => raw.len() >= hl + 10 && EofPdu::from_bytes(raw).is_ok(),
            FileDirectiveType::FinishedPdu => FinishedPduReader::from_bytes(raw).is_ok(),
            FileDirectiveType::AckPdu => AckPdu::from_bytes(raw).is_ok(),
            FileDirectiveType::NakPdu => NakPduReader::from_bytes(raw).is_ok(),
            // Prompt and keep-alive: cfdp-rs 0.3 has no procedure for them.
            FileDirectiveType::PromptPdu | FileDirectiveType::KeepAlivePdu => false,
        },
    };
    ok.then_some(h)
}

/// spacepackets 0.16's file data reader slices the segment metadata (its length: the low 6
/// bits of its first byte) and the offset after it (4 bytes, normal files) unchecked: both
/// must be there (found by the `cfdp_pdu` fuzz target: a panic on a PDU whose segment
/// metadata ran to its end).
fn file_data_fits(h: &PduHeader, hl: usize, raw: &[u8]) -> bool {
    let meta = match h.seg_metadata_flag() {
        spacepackets::cfdp::SegmentMetadataFlag::Present => match raw.get(hl) {
            Some(b) => 1 + usize::from(b & 0x3F),
            None => return false,
        },
        spacepackets::cfdp::SegmentMetadataFlag::NotPresent => 0,
    };
    raw.len() >= hl + meta + 4
}

/// Whether `raw` is a metadata PDU (the directive that opens a transaction).
pub fn is_metadata(raw: &[u8]) -> bool {
    match PduHeader::from_bytes(raw) {
        Ok((h, hl)) => {
            h.pdu_type() == PduType::FileDirective && raw.get(hl) == Some(&(FileDirectiveType::MetadataPdu as u8))
        }
        Err(_) => false,
    }
}

// cfdp-rs 0.3 keeps part of a transaction's state (the source's file progress) across
// transactions: each transaction gets a handler made anew (inline, no allocation).
fn new_source<S: FlatStore>(id: u16, peer: u16, parts: &Parts<S>) -> Source<'_, S> {
    SourceHandler::new(
        local_config(id, parts),
        Sender::source(&parts.link).copies(id),
        &parts.store,
        remote_config(id, peer),
        Timers(&parts.link),
        Seq(&parts.seq),
    )
}

fn new_dest<S: FlatStore>(id: u16, peer: u16, parts: &Parts<S>) -> Dest<'_, S> {
    DestinationHandler::new(
        local_config(id, parts),
        Sender::dest(&parts.link).copies(id),
        &parts.store,
        remote_config(id, peer),
        Timers(&parts.link),
        Gaps::new(),
    )
}

impl<'a, S: FlatStore> Entity<'a, S> {
    /// Entity `id` talking to entity `peer`.
    pub fn new(id: u16, peer: u16, parts: &'a Parts<S>) -> Self {
        Entity {
            id,
            peer,
            parts,
            source: new_source(id, peer, parts),
            dest: new_dest(id, peer, parts),
            user: User::default(),
            counters: Counters::default(),
            last_heard: 0,
            last_user_tx: None,
            metadata_nak: None,
            class1_closure: true,
            sending_len: 0,
            sending_name: None,
            finished_tx: None,
            receiving: None,
            received_whole: None,
            finished_rx: heapless::Deque::new(),
            resend: heapless::Deque::new(),
            resend_header: None,
            resend_scope: (0, 0),
            resent_once: [0; RESENT_WORDS],
            budget: m::SEGMENTS_PER_POLL,
            rx_missing: Gaps::new(),
            rx_missing_known: false,
            rx_kind: ChecksumType::NullChecksum,
            rx_eof_passed: false,
            rx_end: 0,
            rx_faults: 0,
            rx_held: None,
            rx_held_end: None,
        }
    }

    /// Whether class 1 puts ask the receiver for a Finished PDU (on by default; a peer that
    /// never answers one, like Python `cfdp` 0.2, makes every class 1 put end on the check
    /// limit).
    pub fn set_class1_closure(&mut self, on: bool) {
        self.class1_closure = on;
    }

    pub fn id(&self) -> u16 {
        self.id
    }

    pub fn store(&self) -> &'a Checked<S> {
        &self.parts.store
    }

    pub fn counters(&self) -> Counters {
        let mut c = self.counters;
        c.outbox_dropped = self.parts.link.dropped.get();
        c.faults = self.parts.faults.get();
        c.completed = self.user.completed;
        c.repeated_ends = self.user.repeated_ends;
        c.failed = self.user.failed.wrapping_add(self.counters.failed);
        c
    }

    /// Neither handler has a transaction.
    pub fn idle(&self) -> bool {
        self.source.state() == State::Idle && self.dest.state() == State::Idle && self.user.owed.is_empty()
    }

    /// The running (or last) outgoing transaction's progress: end of the furthest file data
    /// segment sent, and the file's length.
    pub fn sent_progress(&self) -> (u64, u64) {
        (self.parts.link.sent_to.get(), self.sending_len)
    }

    /// The running (or last) incoming transaction's file length, as its metadata says.
    pub fn incoming_len(&self) -> u64 {
        self.user.incoming_len
    }

    /// End of the furthest file data segment received in the running (or last) incoming
    /// transaction (progress: not counting duplicates or segments sent again).
    pub fn progress(&self) -> u64 {
        self.user.progress
    }

    /// The next PDU for the link.
    pub fn pop(&mut self) -> Option<Pdu> {
        self.parts.link.outbox.borrow_mut().pop_front()
    }

    /// What `f` makes of the next PDU for the link, in place (a board's period does not
    /// copy it out); [`Entity::drop_next`] then removes it when it went.
    pub fn peek_next<R>(&self, f: impl FnOnce(&[u8]) -> R) -> Option<R> {
        self.parts.link.outbox.borrow().front().map(|p| f(p))
    }

    /// Removes the next PDU for the link.
    pub fn drop_next(&mut self) {
        let _ = self.parts.link.outbox.borrow_mut().pop_front();
    }

    /// The next finished transaction.
    pub fn take_finished(&mut self) -> Option<Finished> {
        self.user.finished.pop_front()
    }

    fn tick(&mut self, now_ms: u64) {
        self.parts.link.now.set(now_ms as u32);
    }

    /// Starts sending `src` (a file of this entity's store) to the peer as `dest`.
    pub fn put(&mut self, now_ms: u64, src: &str, dest: &str, class: Class) -> Result<(), PutError> {
        self.tick(now_ms);
        let s = self.parts.store.check(src).map_err(|_| PutError::BadName)?;
        self.parts.store.check(dest).map_err(|_| PutError::BadName)?;
        let Some(len) = self.parts.store.len(&s).ok().flatten() else {
            return Err(PutError::NoFile);
        };
        // Summed during the file data, `CHECKSUM_BYTES_PER_POLL` a poll; the source
        // handler's EOF step waits for it.
        self.parts.store.sum_start(Side::Send, &s, checksum_kind(), len);
        self.start_put(now_ms, Some(src), Some(dest), class, None, None)?;
        self.sending_len = len;
        self.sending_name = Some(s);
        Ok(())
    }

    /// Asks the peer to send its file `src` here as `dest` (a Proxy Put Request in a
    /// metadata-only transaction of `class`).
    pub fn get(&mut self, now_ms: u64, src: &str, dest: &str, class: Class) -> Result<(), PutError> {
        self.tick(now_ms);
        self.parts.store.check(src).map_err(|_| PutError::BadName)?;
        self.parts.store.check(dest).map_err(|_| PutError::BadName)?;
        let mut buf = [0u8; 2 * m::MAX_NAME_LEN + 16];
        let n = msg::proxy_put(&mut buf, self.id, src, dest, class).ok_or(PutError::BadName)?;
        let tlv = Tlv::new(TlvType::MsgToUser, &buf[..n]).map_err(|_| PutError::BadName)?;
        self.start_put(now_ms, None, None, class, Some(&[tlv]), None)
    }

    /// Asks the peer for its directory listing, sent here as `dest`.
    pub fn list(&mut self, now_ms: u64, dest: &str) -> Result<(), PutError> {
        self.tick(now_ms);
        self.parts.store.check(dest).map_err(|_| PutError::BadName)?;
        let mut buf = [0u8; m::MAX_NAME_LEN + 16];
        let n = msg::directory_listing(&mut buf, "/", dest).ok_or(PutError::BadName)?;
        let tlv = Tlv::new(TlvType::MsgToUser, &buf[..n]).map_err(|_| PutError::BadName)?;
        self.start_put(now_ms, None, None, Class::Two, Some(&[tlv]), None)
    }

    /// Asks the peer to delete `name` (`to`: None) or rename it to `to` (a filestore
    /// request in a metadata-only class 2 transaction).
    pub fn filestore(&mut self, now_ms: u64, name: &str, to: Option<&str>) -> Result<(), PutError> {
        self.tick(now_ms);
        self.parts.store.check(name).map_err(|_| PutError::BadName)?;
        let first = spacepackets::cfdp::lv::Lv::new_from_str(name).map_err(|_| PutError::BadName)?;
        let req = match to {
            None => FilestoreRequestTlv::new_delete_file(first),
            Some(t) => {
                self.parts.store.check(t).map_err(|_| PutError::BadName)?;
                let second = spacepackets::cfdp::lv::Lv::new_from_str(t).map_err(|_| PutError::BadName)?;
                FilestoreRequestTlv::new_rename_file(first, second)
            }
        }
        .map_err(|_| PutError::BadName)?;
        let mut buf = [0u8; 2 * m::MAX_NAME_LEN + 8];
        let n = req.write_to_bytes(&mut buf).map_err(|_| PutError::BadName)?;
        let tlv = Tlv::from_bytes(&buf[..n]).map_err(|_| PutError::BadName)?;
        self.start_put(now_ms, None, None, Class::Two, None, Some(&[tlv]))
    }

    fn start_put(
        &mut self,
        now_ms: u64,
        src: Option<&str>,
        dest: Option<&str>,
        class: Class,
        msgs: Option<&[Tlv]>,
        fs: Option<&[Tlv]>,
    ) -> Result<(), PutError> {
        if self.source.state() != State::Idle {
            return Err(PutError::Busy);
        }
        self.source = new_source(self.id, self.peer, self.parts);
        self.parts.link.sent_to.set(0);
        self.resent_once = [0; RESENT_WORDS];
        self.sending_len = 0;
        self.sending_name = None;
        let req = Put {
            dest_id: UnsignedByteFieldU16::new(self.peer).into(),
            src,
            dest,
            mode: class.mode(),
            closure: class == Class::Two || self.class1_closure,
            msgs,
            fs,
        };
        self.source.put_request(&req).map_err(|_| PutError::Refused)?;
        self.last_heard = now_ms as u32;
        // Its metadata and first file data go at the next poll, within its budget: a put
        // the peer asked for (a get) starts in the period that took the request.
        Ok(())
    }

    fn run_source(&mut self, pdu: Option<&PduRawWithInfo>) {
        self.user.sending = true;
        let busy = self.source.state() != State::Idle;
        let reported = self.user.sent_reports;
        if self.source.state_machine(&mut self.user, pdu).is_err() && !self.source_waits_for_sum() {
            self.counters.handler_errors = self.counters.handler_errors.wrapping_add(1);
        }
        // A transaction cfdp-rs ended on a fault (a class 1 check limit, a cancellation)
        // without a finished indication: the user learns it ended, not complete.
        if busy && self.source.state() == State::Idle && self.user.sent_reports == reported {
            let id = self.source.transaction_id();
            let f = Finished {
                source: self.id,
                seq: id.map_or(0, |t| id_u16(t.seq_num())),
                sent: true,
                condition: self
                    .parts
                    .last_fault
                    .get()
                    .unwrap_or(ConditionCode::CancelRequestReceived),
                complete: false,
                retained: false,
            };
            self.user.report(f);
        }
        self.user.sending = false;
    }

    /// Sums the sent file at most `budget` bytes further.
    #[inline(never)]
    fn sum_sent(&mut self, budget: usize) {
        let Some(name) = self
            .sending_name
            .as_ref()
            .filter(|_| self.source.state() != State::Idle)
        else {
            return;
        };
        let store = &self.parts.store;
        store.sum_start(Side::Send, name, checksum_kind(), self.sending_len);
        store.sum_advance(Side::Send, budget);
    }

    /// The source handler has a transaction and has not sent its EOF yet: its metadata or
    /// file data may still come (what a poll without file data must not run it for), and a
    /// Finished PDU now is the receiver ending the transaction early.
    fn source_before_eof(&self) -> bool {
        self.source.state() != State::Idle
            && matches!(
                self.source.step(),
                SourceStep::Idle
                    | SourceStep::TransactionStart
                    | SourceStep::SendingMetadata
                    | SourceStep::SendingFileData
            )
    }

    /// The source handler has sent its file data and its EOF step waits for the file's
    /// checksum (the store's job, advanced by [`Entity::poll`]).
    #[inline(never)]
    fn source_waits_for_sum(&self) -> bool {
        let Some(name) = self.sending_name.as_ref() else {
            return false;
        };
        let eof_next = match self.source.step() {
            SourceStep::SendingEof => true,
            SourceStep::SendingFileData => self.parts.link.sent_to.get() >= self.sending_len,
            _ => false,
        };
        self.source.state() != State::Idle
            && eof_next
            && !self
                .parts
                .store
                .sum_ready(Side::Send, name, checksum_kind(), self.sending_len)
    }

    /// A PDU counted as taken when it passed the gate that the hold then drops (a copy of
    /// one held): a stray instead, so that each packet is counted once.
    fn taken_as_stray(&mut self) {
        self.counters.received = self.counters.received.wrapping_sub(1);
        self.counters.stray = self.counters.stray.wrapping_add(1);
    }

    /// A PDU of the running incoming transaction that would make the destination handler
    /// sum the whole file in one call, held (`rx_held`) until [`Entity::poll`] has summed
    /// it: an EOF of a complete file (in class 1 every EOF: the handler sums what it has),
    /// or the segment that completes the file after the EOF. Whether `raw` was held.
    #[inline(never)]
    fn hold_for_sum(&mut self, raw: &[u8], h: &PduHeader, pdu: &PduRawWithInfo) -> bool {
        let Some((_, _, staging)) = self.receiving.clone() else {
            return false;
        };
        // The null checksum is not summed; a kind not implemented is the handler's to
        // declare.
        if self.rx_kind == ChecksumType::NullChecksum
            || crate::store::Checksum::new(self.rx_kind).is_none()
            || self.parts.faults.get() != self.rx_faults
        {
            return false;
        }
        let class1 = h.common_pdu_conf().trans_mode == TransmissionMode::Unacknowledged;
        let held_end;
        if pdu.pdu_type() == PduType::FileData {
            let Ok(fd) = FileDataPdu::from_bytes(raw) else {
                return false;
            };
            if !class1 && self.rx_eof_passed && self.rx_held.is_some() {
                // The segment that completes the file is held: every byte is here, and this
                // copy (a duplicate, a segment sent again) would complete the file in the
                // handler before its sum is done.
                self.taken_as_stray();
                return true;
            }
            let seg = (fd.offset(), fd.offset().saturating_add(fd.file_data().len() as u64));
            self.rx_end = self.rx_end.max(seg.1);
            let was_missing = self.rx_missing_known && !self.rx_missing.is_empty();
            if self.rx_missing_known && seg.0 < seg.1 && self.rx_missing.remove_lost_segment(seg).is_err() {
                self.rx_missing_known = false;
            }
            let complete = self.rx_missing_known && self.rx_missing.is_empty();
            // The handler sums the file when this segment closes its last gap after the
            // EOF: written first (the handler's own write of the same bytes then changes
            // nothing summed), handed over when summed.
            if class1 || !self.rx_eof_passed || !was_missing || !complete || self.rx_held.is_some() {
                return false;
            }
            if self.parts.store.write(&staging, fd.offset(), fd.file_data()).is_err() {
                return false;
            }
            held_end = Some(seg.1);
        } else if pdu.file_directive_type() == Some(FileDirectiveType::EofPdu) {
            let Ok(eof) = EofPdu::from_bytes(raw) else { return false };
            if self.rx_held.is_some() && self.rx_held_end.is_none() {
                // The sender's EOF again while the first waits: the first is answered.
                self.taken_as_stray();
                return true;
            }
            if eof.condition_code() != ConditionCode::NoError || self.rx_eof_passed {
                return false;
            }
            if self.user.incoming_len != eof.file_size() {
                self.rx_missing_known = false;
            }
            let complete = self.rx_missing_known && self.rx_missing.is_empty();
            if !(class1 || complete) {
                self.rx_eof_passed = true;
                return false;
            }
            held_end = None;
        } else {
            return false;
        }
        // In place: a PDU buffer is 1 KiB of the board's stack.
        let held = self.rx_held.insert(Pdu::new());
        if held.set(raw).is_err() {
            self.rx_held = None;
            return false;
        }
        self.rx_held_end = held_end;
        self.sum_received(0);
        true
    }

    /// Sums the incoming file at most `budget` bytes further; when its sum is done, hands
    /// the held PDU to the destination handler (which takes the sum from the store).
    /// Returns the bytes read.
    fn sum_received(&mut self, budget: usize) -> usize {
        if self.rx_held.is_none() {
            return 0;
        }
        let Some((_, _, staging)) = self.receiving.clone().filter(|_| self.dest.state() != State::Idle) else {
            self.rx_held = None;
            return 0;
        };
        // What the handler will sum: up to the end of the furthest segment it took (and
        // the held one).
        let len = self.rx_end.max(self.rx_held_end.unwrap_or(0));
        let store = &self.parts.store;
        let faulted = self.parts.faults.get() != self.rx_faults;
        let (read, sum) = if faulted {
            // The handler's own course: the held PDU goes to it as it is.
            (0, None)
        } else {
            store.sum_start(Side::Receive, &staging, self.rx_kind, len);
            let read = store.sum_advance(Side::Receive, budget);
            match store.sum_value(Side::Receive, &staging, self.rx_kind, len) {
                Some(sum) => (read, Some(sum)),
                // A read of the file failed: the handler's own sum meets the error and
                // declares it (a filestore rejection), rather than the PDU held until
                // inactivity.
                None if !store.sum_running(Side::Receive) => (read, None),
                None => return read,
            }
        };
        let Some(mut held) = self.rx_held.take() else {
            return read;
        };
        if self.rx_held_end.is_none() {
            self.rx_eof_passed = true;
            if let Some(failed) = sum.and_then(|sum| Self::eof_of_a_checksum_failure(&held, sum, len)) {
                held = failed;
            }
        }
        if let Ok(p) = PduRawWithInfo::new(&held) {
            self.run_dest(Some(&p));
        }
        read
    }

    /// cfdp-rs 0.3's destination handler checks the file's checksum in class 2 only when
    /// the EOF found gaps: a file complete at its EOF was taken whole unchecked. Here the
    /// sum is done: an EOF whose checksum differs goes to the handler with the condition
    /// "file checksum failure" (its cancel response checks the sum, declares that fault and
    /// ends the transaction not complete, the file not kept).
    /// (`len`: the bytes summed; data past the EOF's size is the handler's file size error.)
    #[inline(never)]
    fn eof_of_a_checksum_failure(raw: &[u8], sum: u32, len: u64) -> Option<Pdu> {
        let eof = EofPdu::from_bytes(raw).ok()?;
        if eof.file_size() != len {
            return None;
        }
        if eof.pdu_header().common_pdu_conf().trans_mode != TransmissionMode::Acknowledged || eof.file_checksum() == sum
        {
            return None;
        }
        let failed = EofPdu::new(
            *eof.pdu_header(),
            ConditionCode::FileChecksumFailure,
            eof.file_checksum(),
            eof.file_size(),
            None,
        );
        let mut buf = [0u8; 64];
        let n = failed.write_to_bytes(&mut buf).ok()?;
        Pdu::from_slice(&buf[..n]).ok()
    }

    fn run_dest(&mut self, pdu: Option<&PduRawWithInfo>) {
        self.user.sending = false;
        let tx = self
            .dest
            .transaction_id()
            .map(|t| (id_u16(t.source_id()), id_u16(t.seq_num())));
        if self.dest.state_machine(&mut self.user, pdu).is_err() {
            self.counters.handler_errors = self.counters.handler_errors.wrapping_add(1);
        }
        self.settle_received();
        let after = self
            .dest
            .transaction_id()
            .map(|t| (id_u16(t.source_id()), id_u16(t.seq_num())));
        if let Some(t) = tx.or(after) {
            if self.dest.state() == State::Idle && !self.finished_rx.iter().any(|x| *x == t) {
                if self.finished_rx.is_full() {
                    self.finished_rx.pop_front();
                }
                let _ = self.finished_rx.push_back(t);
            }
        }
    }

    /// A received file whose transaction ended: renamed from its staging name to its name
    /// when complete and retained, else removed.
    fn settle_received(&mut self) {
        let Some((tx, fin, stg)) = self.receiving.clone() else {
            return;
        };
        let Some(f) = self
            .user
            .finished
            .iter_mut()
            .find(|f| !f.sent && (f.source, f.seq) == tx)
        else {
            return;
        };
        self.receiving = None;
        let store = &self.parts.store;
        if f.complete && f.retained {
            // One step: a reset never leaves neither the old file nor the new one.
            let replaced = store.replace(&stg, &fin);
            if replaced.is_ok() {
                self.received_whole = Some(tx);
            }
            if replaced.is_err() {
                // The report must not say complete for a file that is not under its name.
                f.complete = false;
                f.retained = false;
                self.counters.fs_refused = self.counters.fs_refused.wrapping_add(1);
                let _ = store.remove(&stg);
            }
        } else if store.len(&stg).ok().flatten().is_some() {
            let _ = store.remove(&stg);
        }
    }

    /// Removes the staging files of transfers a reset cut short (call at start-up, on the
    /// robot's own store only). Returns how many.
    pub fn discard_partial(&self) -> usize {
        let mut names: heapless::Vec<FileName, { m::MAX_FILES }> = heapless::Vec::new();
        let _ = self.parts.store.list(&mut |n, _| {
            if n.as_str().starts_with(m::PARTIAL_PREFIX) {
                let _ = names.push(n.clone());
            }
        });
        names.iter().filter(|n| self.parts.store.remove(n).is_ok()).count()
    }

    /// One space packet of the CFDP APID from the link (untrusted): its PDU to
    /// [`Entity::receive`]. A packet that is not a PDU packet of direction `dir` (another
    /// APID or type, a secondary header, segmented, lengths that disagree) is refused and
    /// counted ([`Counters::refused`]).
    pub fn receive_packet(&mut self, now_ms: u64, dir: Direction, packet: &[u8]) {
        match crate::packet::unwrap(dir, packet) {
            Some(pdu) => self.receive(now_ms, pdu),
            None => {
                self.tick(now_ms);
                self.counters.refused = self.counters.refused.wrapping_add(1);
            }
        }
    }

    /// One PDU from the link (untrusted).
    pub fn receive(&mut self, now_ms: u64, raw: &[u8]) {
        self.tick(now_ms);
        let Some(h) = well_formed(raw) else {
            self.counters.refused = self.counters.refused.wrapping_add(1);
            return;
        };
        let (src, dst) = (h.common_pdu_conf().source_id(), h.common_pdu_conf().dest_id());
        let Ok(pdu) = PduRawWithInfo::new(raw) else {
            self.counters.refused = self.counters.refused.wrapping_add(1);
            return;
        };
        let Ok(target) = pdu.packet_target() else {
            self.counters.refused = self.counters.refused.wrapping_add(1);
            return;
        };
        // Towards our destination handler the peer is the source; towards our source
        // handler we are.
        let addressed = match target {
            PacketTarget::DestEntity => id_u16(&dst) == self.id && id_u16(&src) == self.peer,
            PacketTarget::SourceEntity => id_u16(&src) == self.id && id_u16(&dst) == self.peer,
        };
        if !addressed {
            self.counters.refused = self.counters.refused.wrapping_add(1);
            return;
        }
        // A PDU of another transaction than the handler's (a late retransmission, a
        // duplicate of one already finished) is not the handler's business: cfdp-rs 0.3 does
        // not compare transaction IDs on every path.
        let tx = (id_u16(&src), id_u16(&h.common_pdu_conf().transaction_seq_num));
        let is_metadata = pdu.file_directive_type() == Some(FileDirectiveType::MetadataPdu);
        let current = match target {
            PacketTarget::SourceEntity => self.source.transaction_id(),
            PacketTarget::DestEntity => self.dest.transaction_id(),
        }
        .map(|t| (id_u16(t.source_id()), id_u16(t.seq_num())));
        let busy = match target {
            PacketTarget::SourceEntity => self.source.state() != State::Idle,
            PacketTarget::DestEntity => self.dest.state() != State::Idle,
        };
        // File data after the file was found complete and put under its name (a copy sent
        // twice, a duplicate the link made): cfdp-rs 0.3 writes it to the staging name, gone
        // by then, and declares a filestore rejection on the finished transaction. Only
        // then: a transaction a fault ended keeps its handler's own course (dropping its
        // file data there made cfdp-rs 0.3 answer the EOF with a Finished "no error").
        let complete = pdu.pdu_type() == PduType::FileData && self.received_whole == Some(tx);
        let stray = match target {
            PacketTarget::SourceEntity => !busy || current != Some(tx),
            PacketTarget::DestEntity => (!is_metadata && busy && current != Some(tx)) || complete,
        };
        if stray || (target == PacketTarget::DestEntity && self.finished_rx.iter().any(|t| *t == tx)) {
            self.counters.stray = self.counters.stray.wrapping_add(1);
            if target == PacketTarget::SourceEntity
                && pdu.file_directive_type() == Some(FileDirectiveType::FinishedPdu)
                && self.finished_tx == Some(tx)
            {
                self.ack_finished_again(raw, &h);
            }
            return;
        }
        self.counters.received = self.counters.received.wrapping_add(1);
        self.last_heard = now_ms as u32;
        match target {
            PacketTarget::SourceEntity if pdu.file_directive_type() == Some(FileDirectiveType::NakPdu) => {
                self.nak_split(raw)
            }
            PacketTarget::SourceEntity
                if pdu.file_directive_type() == Some(FileDirectiveType::FinishedPdu)
                    && (self.source_before_eof() || self.source.step() == SourceStep::SendingEof) =>
            {
                self.finished_before_eof(raw, &h, tx)
            }
            PacketTarget::SourceEntity => {
                let finished = pdu.file_directive_type() == Some(FileDirectiveType::FinishedPdu);
                if finished {
                    self.eof_acked_by_finished(&h);
                }
                self.run_source(Some(&pdu));
                if finished && self.source.state() == State::Idle {
                    self.finished_tx = Some(tx);
                }
            }
            PacketTarget::DestEntity if pdu.file_directive_type() == Some(FileDirectiveType::MetadataPdu) => {
                self.metadata(raw, (id_u16(&src), id_u16(&h.common_pdu_conf().transaction_seq_num)))
            }
            PacketTarget::DestEntity if self.dest.state() == State::Idle => {
                let eof = pdu.file_directive_type() == Some(FileDirectiveType::EofPdu);
                self.before_metadata(now_ms, &h, eof)
            }
            PacketTarget::DestEntity => {
                if pdu.pdu_type() == PduType::FileData {
                    let link = &self.parts.link;
                    link.data_at.set(Some(now_ms as u32));
                    if let (Ok(fd), Some(end)) = (FileDataPdu::from_bytes(raw), link.nak_end.get()) {
                        let seg = (fd.offset(), fd.offset().saturating_add(fd.file_data().len() as u64));
                        if seg.0 < end && seg.1 >= end {
                            link.nak_answered.set(true);
                        }
                    }
                }
                if !self.hold_for_sum(raw, &h, &pdu) {
                    self.run_dest(Some(&pdu))
                }
            }
        }
        self.settle();
    }

    /// A Finished PDU while the source still waits for the ACK of its EOF: the receiver
    /// sends its Finished only after it took the EOF, so the EOF's ACK was lost on the way.
    /// cfdp-rs 0.3 refuses a Finished PDU in that step; the peer then needs our next EOF
    /// and its own next Finished, one positive ACK period each, to end the transaction: a
    /// `get` saw its file arrive before its request was done. The ACK the Finished implies
    /// is given to the handler first.
    fn eof_acked_by_finished(&mut self, h: &PduHeader) {
        if self.source.step() != SourceStep::WaitingForEofAck {
            return;
        }
        let ack = AckPdu::new_for_eof_pdu(
            PduHeader::new_for_file_directive(*h.common_pdu_conf(), 0),
            ConditionCode::NoError,
            TransactionStatus::Active,
        );
        let mut buf = [0u8; 64];
        let Ok(n) = ack.write_to_bytes(&mut buf) else { return };
        if let Ok(p) = PduRawWithInfo::new(&buf[..n]) {
            self.counters.eof_ack_by_finished = self.counters.eof_ack_by_finished.wrapping_add(1);
            self.run_source(Some(&p));
        }
    }

    /// The peer's Finished PDU again, for a transaction this entity sent and has ended: our
    /// ACK of it was lost. cfdp-rs 0.3 forgets the transaction at its first Finished; without
    /// an answer the peer would send its Finished until its positive ACK limit and declare
    /// that fault for a file that arrived whole.
    fn ack_finished_again(&mut self, raw: &[u8], h: &PduHeader) {
        if self.ack_finished(raw, h).is_some() {
            self.counters.finished_acked_again = self.counters.finished_acked_again.wrapping_add(1);
        }
    }

    /// The receiver's Finished PDU while this sender has not sent its EOF (727.0-B-5: the
    /// receiver may end a transaction at any time, its store refused a write; cfdp-rs 0.3
    /// refuses a Finished before its step that waits for the EOF's ACK, and went on sending
    /// the whole file): acknowledged, and the put ends here, not complete, with the
    /// receiver's condition; the rest of the file is not sent.
    fn finished_before_eof(&mut self, raw: &[u8], h: &PduHeader, tx: (u16, u16)) {
        let Some(condition) = self.ack_finished(raw, h) else {
            return;
        };
        self.source.abandon_transaction();
        self.finished_tx = Some(tx);
        self.user.report(Finished {
            source: self.id,
            seq: tx.1,
            sent: true,
            condition,
            complete: false,
            retained: false,
        });
    }

    /// The ACK of the Finished PDU `raw` of the transaction in `h`; its condition code.
    fn ack_finished(&mut self, raw: &[u8], h: &PduHeader) -> Option<ConditionCode> {
        let Ok(fin) = FinishedPduReader::from_bytes(raw) else {
            return None;
        };
        let mut conf = *h.common_pdu_conf();
        conf.direction = spacepackets::cfdp::Direction::TowardsReceiver;
        conf.crc_flag = m::PDU_CRC.into();
        let Ok(ack) = AckPdu::new(
            PduHeader::new_for_file_directive(conf, 0),
            FileDirectiveType::FinishedPdu,
            fin.condition_code(),
            TransactionStatus::Terminated,
        ) else {
            return None;
        };
        let mut buf = [0u8; 64];
        let n = ack.write_to_bytes(&mut buf).ok()?;
        let _ =
            Sender::dest(&self.parts.link).send_pdu(PduType::FileDirective, Some(FileDirectiveType::AckPdu), &buf[..n]);
        Some(fin.condition_code())
    }

    /// File data or an EOF of a transaction whose metadata was lost: cfdp-rs 0.3 would
    /// write the data to a file without a name and fail the transaction. Dropped (counted);
    /// in class 2 a NAK asks for the metadata (segment request 0-0), at most once per NAK
    /// timer interval (and on each EOF), and the data missing then is asked for after the
    /// EOF.
    fn before_metadata(&mut self, now_ms: u64, h: &PduHeader, eof: bool) {
        self.counters.before_metadata = self.counters.before_metadata.wrapping_add(1);
        let mut conf = *h.common_pdu_conf();
        if conf.trans_mode != TransmissionMode::Acknowledged {
            return;
        }
        let tx = (id_u16(&conf.source_id()), id_u16(&conf.transaction_seq_num));
        let now = now_ms as u32;
        // An EOF comes at most once per positive ACK period and is not acknowledged until
        // the metadata is here: each one asks for it, or the sender's ACK limit runs out.
        if let Some((t, at)) = self.metadata_nak.filter(|_| !eof) {
            if t == tx && (now.wrapping_sub(at) as u64) < m::NAK_TIMER_MS {
                return;
            }
        }
        self.metadata_nak = Some((tx, now));
        conf.direction = spacepackets::cfdp::Direction::TowardsSender;
        let Ok(nak) = NakPduCreator::new_normal_file_size(PduHeader::new_for_file_directive(conf, 0), 0, 0, &[(0, 0)])
        else {
            return;
        };
        let mut buf = [0u8; 64];
        if let Ok(n) = nak.write_to_bytes(&mut buf) {
            let _ = Sender::dest(&self.parts.link).send_pdu(
                PduType::FileDirective,
                Some(FileDirectiveType::NakPdu),
                &buf[..n],
            );
        }
    }

    /// A NAK to the source handler, its segment requests cut to at most one file segment
    /// each (cfdp-rs 0.3 resends only the first segment of a longer request) and queued,
    /// then fed to the handler as the outbox has room ([`Entity::resend`]).
    fn nak_split(&mut self, raw: &[u8]) {
        let Ok(nak) = NakPduReader::from_bytes(raw) else { return };
        let (start, end) = (nak.start_of_scope(), nak.end_of_scope());
        if end > u32::MAX as u64 {
            // A large file (beyond this entity's files): as it is.
            if let Ok(p) = PduRawWithInfo::new(raw) {
                self.run_source(Some(&p));
            }
            return;
        }
        let seg = m::MAX_SEGMENT_LEN as u64;
        self.resend_header = Some(*nak.pdu_header());
        self.resend_scope = (start as u32, end as u32);
        for (a, b) in nak.get_segment_requests_iterator().into_iter().flatten() {
            // Never past the end of the file being sent (cfdp-rs would read beyond it).
            let b = if a == 0 && b == 0 { 0 } else { b.min(self.sending_len) };
            if b < a || (a == b && a != 0) {
                continue;
            }
            let mut at = a;
            loop {
                // Metadata is asked for as 0-0.
                let to = if a == b { b } else { (at + seg).min(b) };
                if to > u32::MAX as u64 {
                    break;
                }
                // A segment already queued (by an earlier NAK, or by an overlapping request
                // of this one) is queued once; the rest of the request still is.
                let queued = self.resend.iter().any(|r| *r == (at as u32, to as u32));
                if !queued && self.resend.push_back((at as u32, to as u32)).is_err() {
                    // Full: the rest is asked for again by the next NAK.
                    self.counters.resend_dropped = self.counters.resend_dropped.wrapping_add(1);
                    break;
                }
                at = to;
                if at >= b {
                    break;
                }
            }
        }
        self.resend();
    }

    /// Sends the queued segment requests while the outbox has room: file data read from the
    /// store here, the metadata (0-0) by the source handler. cfdp-rs 0.3 counts each
    /// segment it sends again as new progress: the next new segment then skips ahead, and
    /// its EOF (sent again on each positive ACK timer expiry) carries that count as the file
    /// size; the receiver then asks for data past the end of the file, which this entity
    /// cannot send, and the transaction falls silent until inactivity ends it.
    fn resend(&mut self) {
        let Some(header) = self.resend_header else { return };
        let (start, end) = self.resend_scope;
        let mut buf = [0u8; m::MAX_PDU_LEN];
        while self.source.state() != State::Idle {
            if self.parts.link.outbox.borrow().len() + 2 >= m::OUTBOX_DEPTH {
                return;
            }
            if self.budget == 0 && self.resend.front().is_some_and(|r| *r != (0, 0)) {
                return;
            }
            let Some((a, b)) = self.resend.pop_front() else { break };
            if a == 0 && b == 0 {
                let Ok(c) = NakPduCreator::new_normal_file_size(header, start, end, &[(0, 0)]) else {
                    continue;
                };
                let Ok(n) = c.write_to_bytes(&mut buf) else { continue };
                if let Ok(p) = PduRawWithInfo::new(&buf[..n]) {
                    self.run_source(Some(&p));
                }
                continue;
            }
            // Asked for before: its earlier answer was lost too; two copies this time, when
            // the poll's budget has room for both.
            let k = a as usize / m::MAX_SEGMENT_LEN;
            let bit = self.resent_once.get_mut(k / 32).map(|w| {
                let again = *w & (1 << (k % 32)) != 0;
                *w |= 1 << (k % 32);
                again
            });
            self.resend_segment(&header, a, b);
            if bit == Some(true) && self.budget > 0 {
                self.resend_segment(&header, a, b);
            }
        }
        if self.source.state() == State::Idle {
            self.resend.clear();
        }
    }

    /// File data `a..b` of the file being sent (at most one segment), again.
    fn resend_segment(&mut self, nak: &PduHeader, a: u32, b: u32) {
        let Some(name) = self.sending_name.clone() else { return };
        let len = (b - a) as usize;
        let mut data = [0u8; m::MAX_SEGMENT_LEN];
        if len > data.len() || self.parts.store.read(&name, a as u64, &mut data[..len]).is_err() {
            self.counters.resend_dropped = self.counters.resend_dropped.wrapping_add(1);
            return;
        }
        let mut conf = *nak.common_pdu_conf();
        conf.direction = spacepackets::cfdp::Direction::TowardsReceiver;
        conf.crc_flag = m::PDU_CRC.into();
        let h = PduHeader::new_for_file_data(
            conf,
            0,
            SegmentMetadataFlag::NotPresent,
            SegmentationControl::NoRecordBoundaryPreservation,
        );
        let pdu = FileDataPdu::new_no_seg_metadata(h, a as u64, &data[..len]);
        let mut buf = [0u8; m::MAX_PDU_LEN];
        match pdu.write_to_bytes(&mut buf) {
            Ok(n) => {
                self.budget = self.budget.saturating_sub(1);
                self.counters.resent = self.counters.resent.wrapping_add(1);
                let _ = Sender::source(&self.parts.link).send_pdu(PduType::FileData, None, &buf[..n]);
            }
            Err(_) => self.counters.resend_dropped = self.counters.resend_dropped.wrapping_add(1),
        }
    }

    /// A metadata PDU: to the destination handler without its messages to user (cfdp-rs 0.3
    /// panics on them: it copies each into a fixed buffer of another length), which this
    /// entity acts on itself, with the filestore requests, once per transaction.
    fn metadata(&mut self, raw: &[u8], tx: (u16, u16)) {
        let Ok(md) = MetadataPduReader::from_bytes(raw) else {
            return;
        };
        let mut opts = [0u8; m::MAX_PDU_LEN];
        let mut n = 0;
        if let Some(it) = md.options_iter() {
            for tlv in it {
                if tlv.tlv_type() == Some(TlvType::MsgToUser) {
                    continue;
                }
                match tlv.write_to_bytes(&mut opts[n..]) {
                    Ok(k) => n += k,
                    Err(_) => return,
                }
            }
        }
        // Received under a staging name until complete (`mib::cfdp::PARTIAL_PREFIX`).
        let final_name = md
            .dest_file_name()
            .value_as_str()
            .and_then(|r| r.ok())
            .and_then(|d| FileName::new(d).ok());
        let staging = final_name.as_ref().and_then(|_| partial_name(tx));
        let staging_lv = staging
            .as_ref()
            .and_then(|s| spacepackets::cfdp::lv::Lv::new_from_str(s.as_str()).ok());
        let stripped = MetadataPduCreator::new(
            *md.pdu_header(),
            *md.metadata_params(),
            md.src_file_name(),
            staging_lv.unwrap_or(md.dest_file_name()),
            &opts[..n],
        );
        let mut buf = [0u8; m::MAX_PDU_LEN];
        let Ok(len) = stripped.write_to_bytes(&mut buf) else {
            return;
        };
        let Ok(pdu) = PduRawWithInfo::new(&buf[..len]) else {
            return;
        };
        // A new transaction while the last one waits for the ACK of its Finished PDU: the
        // peer runs one transaction at a time, so it has ended the last one (that ACK was
        // lost); the new one starts on a fresh handler.
        let stale = self.dest.state() != State::Idle
            && self
                .dest
                .transaction_id()
                .is_some_and(|t| (id_u16(t.source_id()), id_u16(t.seq_num())) != tx);
        if stale {
            self.counters.superseded = self.counters.superseded.wrapping_add(1);
        }
        let was_idle = self.dest.state() == State::Idle || stale;
        if was_idle {
            self.parts.link.data_at.set(None);
            self.dest = new_dest(self.id, self.peer, self.parts);
            self.receiving = final_name.zip(staging).map(|(f, s)| (tx, f, s));
            let params = md.metadata_params();
            self.rx_kind = params.checksum_type;
            self.rx_eof_passed = false;
            self.rx_end = 0;
            self.rx_faults = self.parts.faults.get();
            self.rx_held = None;
            // Reset in place: the list is 4 KiB and more of the board's stack.
            LostSegmentStore::reset(&mut self.rx_missing);
            self.rx_missing_known =
                params.file_size == 0 || self.rx_missing.add_lost_segment((0, params.file_size)).is_ok();
        }
        let errors = self.counters.handler_errors;
        self.run_dest(Some(&pdu));
        // A repeated metadata PDU (class 2 resends it; a link may duplicate it) acts once.
        if was_idle && errors == self.counters.handler_errors && self.last_user_tx != Some(tx) {
            self.last_user_tx = Some(tx);
            self.user_requests(&md);
        }
    }

    /// The messages to user and filestore requests of a metadata PDU the destination
    /// handler took: delete and rename on the checked store (anything else is refused,
    /// counted); proxy puts and directory listings owed to the peer.
    fn user_requests(&mut self, md: &MetadataPduReader) {
        let Some(opts) = md.options_iter() else { return };
        // The standard's Proxy Transmission Mode is a message of its own (Yamcs sends it so).
        let mode = md.options_iter().and_then(|mut o| {
            o.find_map(|t| {
                (t.tlv_type() == Some(TlvType::MsgToUser)).then(|| msg::proxy_transmission_mode(t.value()))?
            })
        });
        for tlv in opts {
            if tlv.tlv_type() == Some(TlvType::MsgToUser) {
                self.user.message(tlv.value(), mode);
                continue;
            }
            if tlv.tlv_type() != Some(TlvType::FilestoreRequest) {
                continue;
            }
            if !filestore_request_whole(tlv.value()) {
                // spacepackets 0.16 reads the action code of an empty request unchecked.
                self.counters.fs_refused = self.counters.fs_refused.wrapping_add(1);
                continue;
            }
            let mut buf = [0u8; 260];
            let ok = tlv
                .write_to_bytes(&mut buf)
                .ok()
                .and_then(|n| FilestoreRequestTlv::from_bytes(&buf[..n]).ok())
                .and_then(|r| self.filestore_request(&r));
            match ok {
                Some(()) => self.counters.fs_done = self.counters.fs_done.wrapping_add(1),
                None => self.counters.fs_refused = self.counters.fs_refused.wrapping_add(1),
            }
        }
    }

    fn filestore_request(&self, r: &FilestoreRequestTlv) -> Option<()> {
        let store = &self.parts.store;
        let first = store.check(r.first_name().value_as_str()?.ok()?).ok()?;
        match r.action_code() {
            FilestoreActionCode::DeleteFile => store.remove(&first).ok(),
            FilestoreActionCode::RenameFile => {
                let second = store.check(r.second_name()?.value_as_str()?.ok()?).ok()?;
                store.rename(&first, &second).ok()
            }
            FilestoreActionCode::CreateFile
            | FilestoreActionCode::AppendFile
            | FilestoreActionCode::ReplaceFile
            | FilestoreActionCode::CreateDirectory
            | FilestoreActionCode::RemoveDirectory
            | FilestoreActionCode::DenyFile
            | FilestoreActionCode::DenyDirectory => None,
        }
    }

    /// Time passes: timers, the next file data, owed puts, inactivity. Call every control
    /// period and after the outbox was emptied.
    pub fn poll(&mut self, now_ms: u64) {
        self.poll_paced(now_ms, Pace::Segments(m::SEGMENTS_PER_POLL));
    }

    /// [`Entity::poll`] within a board's period (`fw_core::files`): with [`Pace::Quiet`]
    /// it reads nothing of the store (no file data, no checksum: the period did other
    /// work), with [`Pace::Segments`] at most that many file data PDUs (new and asked for
    /// again; never more than `SEGMENTS_PER_POLL`) and the sent file's sum paced to match.
    /// The handlers' timers run and their directives go either way.
    pub fn poll_paced(&mut self, now_ms: u64, pace: Pace) {
        let segments = match pace {
            Pace::Quiet => 0,
            Pace::Segments(n) => n.min(m::SEGMENTS_PER_POLL),
        };
        self.tick(now_ms);
        {
            let (mut outbox, mut due) = (
                self.parts.link.outbox.borrow_mut(),
                self.parts.link.copies_due.borrow_mut(),
            );
            while outbox.len() + 2 < m::OUTBOX_DEPTH {
                let Some(pdu) = due.pop_front() else { break };
                let _ = outbox.push_back(pdu);
            }
            due.clear();
        }
        // The checksums, `CHECKSUM_BYTES_PER_POLL` in all: the received file's first (its
        // held PDU waits), then the sent file's, alongside its file data
        // (`CHECKSUM_BYTES_WITH_DATA`, faster than the data goes: the sum is done when the
        // data is, and the EOF does not wait), all of the budget once the data is out.
        let (all, with_data) = match pace {
            Pace::Quiet => (0, 0),
            // The ground has no control period to keep: a file a poll.
            Pace::Segments(_) if self.id == m::GROUND_ENTITY_ID => (m::MAX_FILE_LEN as usize, m::MAX_FILE_LEN as usize),
            Pace::Segments(_) => (m::CHECKSUM_BYTES_PER_POLL, m::checksum_bytes_with(segments)),
        };
        let left = all - self.sum_received(all);
        self.sum_sent(if self.source_waits_for_sum() {
            left
        } else {
            left.min(with_data)
        });
        // Segments asked for again go first: the receiver waits for them.
        self.budget = segments;
        self.resend();
        self.nak_early(now_ms as u32);
        if self.budget == 0 {
            // No file data: the source only past it (its EOF, its ACK timer), the
            // destination's timers (its PDUs are directives).
            if self.source.state() != State::Idle && !self.source_waits_for_sum() && !self.source_before_eof() {
                self.run_source(None);
            }
            if self.dest.state() != State::Idle {
                self.run_dest(None);
            }
        }
        while self.budget > 0 {
            if self.parts.link.outbox.borrow().len() + 2 >= m::OUTBOX_DEPTH {
                break;
            }
            let before = self.parts.link.outbox.borrow().len();
            if self.source.state() != State::Idle && !self.source_waits_for_sum() {
                self.run_source(None);
            }
            if self.dest.state() != State::Idle {
                self.run_dest(None);
            }
            if self.parts.link.outbox.borrow().len() == before {
                break;
            }
            self.budget -= 1;
        }
        self.parts.link.nak_due.set(None);
        self.settle();
        // A sender still sending its file data waits for nothing from its peer (a class 2
        // receiver on a lossless uplink says nothing until the EOF): its silence is not
        // inactivity. A put through the relay's COP-1 took more than INACTIVITY_MS to get its
        // data up on a loaded machine and was abandoned.
        if self.source.state() != State::Idle
            && (self.source.step() == SourceStep::SendingFileData || self.source_waits_for_sum())
        {
            self.last_heard = now_ms as u32;
        }
        if (self.source.state() != State::Idle || self.dest.state() != State::Idle)
            && (now_ms as u32).wrapping_sub(self.last_heard) as u64 >= m::INACTIVITY_MS
        {
            self.abandon();
        }
    }

    /// The receiver's next NAK without waiting for the NAK timer: the segment at the end of
    /// the last NAK's requests arrived (the sender answers a NAK's requests in order), or file
    /// data came after the last NAK and then none for `NAK_QUIET_MS` (that segment was lost)
    /// — the sender has sent what that NAK asked for, and what is still missing was lost
    /// again. The NAK timer
    /// (which cfdp-rs 0.3 restarts only when it expires) stays for a NAK or an answer lost
    /// on the way; waiting for it cost a NAK period (4 s) per round through the relay.
    fn nak_early(&mut self, now: u32) {
        if self.rx_held.is_some() {
            // The file is complete, the segment that completed it held while it is summed:
            // nothing to ask for.
            return;
        }
        let link = &self.parts.link;
        let quiet = link.data_at.get().is_some_and(|t| {
            t.wrapping_sub(link.nak_at.get()) as i32 > 0 && (now.wrapping_sub(t) as u64) >= m::NAK_QUIET_MS
        });
        let answered = quiet || link.nak_answered.take();
        if answered && self.dest.state() != State::Idle {
            link.nak_due.set(Some(now));
        }
    }

    /// Counts finished transactions and starts an owed put when the source is free.
    fn settle(&mut self) {
        self.counters.proxy_refused = self
            .counters
            .proxy_refused
            .wrapping_add(core::mem::take(&mut self.user.proxy_refused));
        if self.source.state() != State::Idle {
            return;
        }
        let Some(o) = self.user.owed.pop_front() else { return };

        if self.user.listing.as_ref() == Some(&o.src) {
            self.user.listing = None;
            if self.write_listing(&o.src).is_none() {
                self.counters.proxy_refused = self.counters.proxy_refused.wrapping_add(1);
                return;
            }
        }
        let now = self.parts.link.now.get() as u64;
        let (src, dest) = (o.src.clone(), o.dest.clone());
        if self.put(now, src.as_str(), dest.as_str(), o.class).is_err() {
            self.counters.proxy_refused = self.counters.proxy_refused.wrapping_add(1);
        }
    }

    /// Writes the store's listing into `name`: one `NAME LENGTH` line per file, then
    /// `free BYTES`.
    fn write_listing(&self, name: &FileName) -> Option<()> {
        let store = &self.parts.store;
        let mut text: heapless::String<{ m::MAX_FILES * (m::MAX_NAME_LEN + 12) + 32 }> = heapless::String::new();
        let mut ok = true;
        store
            .list(&mut |n, len| {
                if n != name {
                    ok &= core::fmt::write(&mut text, format_args!("{n} {len}\n")).is_ok();
                }
            })
            .ok()?;
        let free = store.free().ok()?;
        ok &= core::fmt::write(&mut text, format_args!("free {free}\n")).is_ok();
        if !ok {
            return None;
        }
        store.create(name).ok()?;
        store.write(name, 0, text.as_bytes()).ok()
    }

    /// Ends the running transactions without a word to the peer (inactivity).
    fn abandon(&mut self) {
        self.parts.faults.set(self.parts.faults.get().wrapping_add(1));
        if self.source.state() != State::Idle {
            let seq = self.source.transaction_id().map_or(0, |t| id_u16(t.seq_num()));
            self.source.abandon_transaction();
            // cfdp-rs reports nothing for an abandoned transaction: the user must still
            // learn that its put ended (the report counts it as failed).
            self.user.report(Finished {
                source: self.id,
                seq,
                sent: true,
                condition: ConditionCode::InactivityDetected,
                complete: false,
                retained: false,
            });
        }
        if self.dest.state() != State::Idle {
            let reported = self.user.failed;
            if let Some(id) = self.dest.transaction_id() {
                // cfdp-rs 0.3 cancels only as on a user's request; the report says why.
                let before = self.user.finished.len();
                self.dest.cancel_request(&id);
                self.run_dest(None);
                for f in self.user.finished.iter_mut().skip(before) {
                    f.condition = ConditionCode::InactivityDetected;
                }
            }
            self.dest.reset();
            // Counted once: by its report, or here when the handler made none.
            if self.user.failed == reported {
                self.counters.failed = self.counters.failed.wrapping_add(1);
            }
        }
    }
}
