//! The file service's housekeeping and events (docs/files.md, "Housekeeping and events").
//!
//! The platform runs the CFDP entity and its file store (`mmic_cfdp`: the host obsw's
//! `files.rs`, and board A's the same way); this component is what the obsw knows of them.
//!
//! - **Takes** no TC (files travel as CFDP PDUs, not as telecommands).
//! - **Is handed** by the platform ([`Obsw::files_report`](crate::obsw::Obsw::files_report)),
//!   as plain numbers: each control period the counters of the entity and the store
//!   ([`FileCounters`]), and each transaction as it begins ([`Began`]) and ends ([`Ended`]).
//! - **Supplies** the parameters of source `Files` (HK structure FILES) and raises
//!   FILE_TRANSFER_STARTED, FILE_TRANSFER_COMPLETED or FILE_TRANSFER_FAILED for each
//!   transaction, FILE_REFUSED for each refusal counter that rose since the last period
//!   (one per counter and period, carrying its total), FILE_STORE_ERROR when the store's
//!   medium failed and FILE_PARTIALS_REMOVED when the platform removed at start the files of
//!   transfers a reset cut short.
//!
//! A platform that runs `mmic_cfdp`'s entity makes these reports with [`cfdp`] (feature
//! `cfdp`): the entity's and the store's counters and its [`Watch`](mmic_cfdp::watch::Watch)
//! (transactions opened, PDUs sent, NAKs) as [`FileCounters`], a transaction opened as
//! [`Began`], a finished one as [`Ended`].
//!
//! Before the platform's first report (a robot without a file service: the host without
//! `--files`, a board without a store) the parameters have no value.

use mib::files::{class, direction};
use mib::params::{pid, NotSupplied, Source, Supplied};
use mib_wire::ev;

use crate::downlink::Downlink;
use crate::services::Contract;
use crate::tm::{TmSink, TmStore};

/// What the platform's CFDP entity and file store counted since start (totals, wrapping).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FileCounters {
    /// PDUs the entity took / sent.
    pub pdus_received: u32,
    pub pdus_sent: u32,
    /// Packets of the CFDP APID refused (not a PDU, malformed, not addressed to us).
    pub pdus_refused: u32,
    /// PDUs of another or an ended transaction, dropped.
    pub pdus_stray: u32,
    /// PDUs and requests the state machine refused.
    pub handler_refused: u32,
    /// File data and EOF before their metadata, dropped.
    pub before_metadata: u32,
    /// Transactions started by the ground's entity / by ours.
    pub tx_received: u32,
    pub tx_sent: u32,
    /// Transactions ended complete / not.
    pub tx_completed: u32,
    pub tx_failed: u32,
    /// CFDP faults declared.
    pub faults: u32,
    /// File data PDUs sent again at the peer's NAKs.
    pub segments_resent: u32,
    /// NAK PDUs sent / taken.
    pub naks_sent: u32,
    pub naks_received: u32,
    /// PDUs lost to a full outbox; segment requests lost to a full resend queue.
    pub outbox_dropped: u32,
    pub resend_dropped: u32,
    /// Incoming transactions ended by the peer's next one.
    pub superseded: u32,
    /// Filestore requests executed / refused; puts the peer asked for refused.
    pub fs_done: u32,
    pub fs_refused: u32,
    pub proxy_refused: u32,
    /// The store's refusals: names, space; failures of its medium.
    pub store_bad_names: u32,
    pub store_full: u32,
    pub store_io_errors: u32,
    /// Files in the store and the bytes it can still take.
    pub store_files: u16,
    pub store_free: u32,
    /// Partly received files of transfers a reset cut short, removed at start.
    pub partials_removed: u16,
}

impl FileCounters {
    /// The value of parameter `id` of source `Files`.
    fn param(&self, id: u16) -> Result<u32, NotSupplied> {
        Ok(match id {
            pid::FILE_PDU_RECEIVED => self.pdus_received,
            pid::FILE_PDU_SENT => self.pdus_sent,
            pid::FILE_PDU_REFUSED => self.pdus_refused,
            pid::FILE_PDU_STRAY => self.pdus_stray,
            pid::FILE_HANDLER_REFUSED => self.handler_refused,
            pid::FILE_BEFORE_METADATA => self.before_metadata,
            pid::FILE_TX_RECEIVED => self.tx_received,
            pid::FILE_TX_SENT => self.tx_sent,
            pid::FILE_TX_COMPLETED => self.tx_completed,
            pid::FILE_TX_FAILED => self.tx_failed,
            pid::FILE_FAULTS => self.faults,
            pid::FILE_SEG_RESENT => self.segments_resent,
            pid::FILE_NAK_SENT => self.naks_sent,
            pid::FILE_NAK_RECEIVED => self.naks_received,
            pid::FILE_OUTBOX_DROPPED => self.outbox_dropped,
            pid::FILE_RESEND_DROPPED => self.resend_dropped,
            pid::FILE_SUPERSEDED => self.superseded,
            pid::FILE_FS_DONE => self.fs_done,
            pid::FILE_FS_REFUSED => self.fs_refused,
            pid::FILE_PROXY_REFUSED => self.proxy_refused,
            pid::FILE_STORE_BAD_NAMES => self.store_bad_names,
            pid::FILE_STORE_FULL => self.store_full,
            pid::FILE_STORE_IO_ERRORS => self.store_io_errors,
            pid::FILE_STORE_FILES => u32::from(self.store_files),
            pid::FILE_STORE_FREE => self.store_free,
            pid::FILE_PARTIALS_REMOVED => u32::from(self.partials_removed),
            _ => return Err(NotSupplied(id)),
        })
    }
}

/// The refusal counters FILE_REFUSED reports, by their parameter. Not the state machine's
/// refusals (FILE_HANDLER_REFUSED): a late or repeated PDU of a lossy link, the relay's
/// duplicates, rise it during most transfers; its count is in HK.
const REFUSALS: [u16; 5] = [
    pid::FILE_PDU_REFUSED,
    pid::FILE_FS_REFUSED,
    pid::FILE_PROXY_REFUSED,
    pid::FILE_STORE_BAD_NAMES,
    pid::FILE_STORE_FULL,
];

/// Which way a transaction travels, seen from the robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Started by the ground's entity (a put up, a request).
    Received,
    /// Started by the robot's (a get's file, a listing).
    Sent,
}

impl Direction {
    const fn code(self) -> u8 {
        match self {
            Direction::Received => direction::RECEIVED,
            Direction::Sent => direction::SENT,
        }
    }
}

/// CFDP transfer class.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Class {
    One,
    Two,
}

/// A transaction began: its metadata PDU was taken from the ground or sent to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Began {
    /// Transaction ID: the entity that started it and its sequence number.
    pub source: u16,
    pub seq: u16,
    pub direction: Direction,
    pub class: Class,
    /// The file's bytes (0: a request without a file).
    pub length: u32,
}

/// A transaction ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ended {
    pub source: u16,
    pub seq: u16,
    pub direction: Direction,
    /// CFDP condition code (`mib::files::condition`).
    pub condition: u8,
    /// The file arrived whole (receiver: checksum verified; sender: as the peer says).
    pub complete: bool,
    /// The file's bytes moved (how far it got when incomplete).
    pub bytes: u32,
}

/// What the platform hands in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Report {
    /// The counters, once per control period.
    Counters(FileCounters),
    Began(Began),
    Ended(Ended),
}

/// The file service's component (see the module's documentation).
#[derive(Clone, Copy, Debug, Default)]
pub struct Files {
    /// The counters last handed in (`None`: no file service).
    now: Option<FileCounters>,
}

impl Files {
    pub const CONTRACT: Contract = Contract::new("files", None, &[Source::Files]);

    /// Takes what the platform reports; the events it calls for through the downlink.
    pub fn report<S: TmStore>(&mut self, now: u64, r: Report, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        match r {
            Report::Counters(c) => {
                let was = self.now.unwrap_or_default();
                for id in REFUSALS {
                    let (Ok(before), Ok(total)) = (was.param(id), c.param(id)) else {
                        continue;
                    };
                    if total != before {
                        dl.raise(now, ev::FileRefused { counter: id, total }, sink);
                    }
                }
                if c.store_io_errors != was.store_io_errors {
                    dl.raise(
                        now,
                        ev::FileStoreError {
                            errors: c.store_io_errors,
                        },
                        sink,
                    );
                }
                if c.partials_removed != was.partials_removed {
                    let files = c.partials_removed;
                    dl.raise(now, ev::FilePartialsRemoved { files }, sink);
                }
                self.now = Some(c);
            }
            Report::Began(b) => {
                let e = ev::FileTransferStarted {
                    source: b.source,
                    seq: b.seq,
                    direction: b.direction.code(),
                    class: match b.class {
                        Class::One => class::CLASS_1,
                        Class::Two => class::CLASS_2,
                    },
                    length: b.length,
                };
                dl.raise(now, e, sink);
            }
            Report::Ended(e) => {
                let (source, seq, direction, condition, bytes) =
                    (e.source, e.seq, e.direction.code(), e.condition, e.bytes);
                if e.complete {
                    let ev = ev::FileTransferCompleted {
                        source,
                        seq,
                        direction,
                        condition,
                        bytes,
                    };
                    dl.raise(now, ev, sink);
                } else {
                    let ev = ev::FileTransferFailed {
                        source,
                        seq,
                        direction,
                        condition,
                        bytes,
                    };
                    dl.raise(now, ev, sink);
                }
            }
        }
    }

    /// The parameters the MIB names this component the source of: no value before the
    /// platform's first report.
    pub fn param(&self, id: u16) -> Supplied {
        let zero = FileCounters::default();
        let v = self.now.as_ref().unwrap_or(&zero).param(id)?;
        Ok(self.now.map(|_| i64::from(v)))
    }
}

/// The reports of a platform that runs `mmic_cfdp`'s entity (the host obsw, and board A the
/// same way).
#[cfg(feature = "cfdp")]
pub mod cfdp {
    use mmic_cfdp::packet::{self, Direction as PacketDirection};
    use mmic_cfdp::watch::{Opened, Watch};
    use mmic_cfdp::{Entity, Finished, FlatStore};

    use super::{Began, Class, Direction, Ended, FileCounters};
    use crate::tm::TmSink;
    use mib::headers::SeqCount;

    /// The entity's PDUs to the downlink as TM packets of `mib::cfdp::APID` (no PUS header),
    /// in order, each wrapped where it lies in the entity's outbox and sent only while the
    /// sink takes it (`TmSink::replay_room`): one that does not fit waits there. The host
    /// obsw and board A send their PDUs through it.
    #[derive(Clone, Copy, Debug, Default)]
    pub struct PduDownlink {
        /// The next packet's sequence count.
        seq: SeqCount,
        /// PDUs no packet could hold (none can: the outbox takes at most `MAX_PDU_LEN`
        /// bytes a PDU), dropped; counted in HK FILES' outbox drops ([`counters`]).
        unsent: u32,
    }

    /// What became of the next PDU.
    enum Next {
        Sent(Option<Opened>),
        NoRoom,
        Unsendable,
    }

    impl PduDownlink {
        /// PDUs no packet could hold, dropped.
        pub fn unsent(&self) -> u32 {
            self.unsent
        }

        /// Sends the entity's next PDU when the sink takes it, wrapped in `buf`: `Some`
        /// with the transaction its metadata opens (`watch`), `None` when there is none or
        /// no room. A caller loops until `None` with one buffer, reporting each opened
        /// transaction in between.
        pub fn send_next<S: FlatStore>(
            &mut self,
            entity: &mut Entity<'_, S>,
            watch: &mut Watch,
            sink: &mut impl TmSink,
            buf: &mut [u8; mib::cfdp::MAX_PACKET_LEN],
        ) -> Option<Option<Opened>> {
            loop {
                let seq = &mut self.seq;
                let next = entity.peek_next(|pdu| {
                    let Some(n) = packet::wrap(PacketDirection::Down, seq.get(), pdu, buf) else {
                        return Next::Unsendable;
                    };
                    if sink.replay_room() < n {
                        return Next::NoRoom;
                    }
                    *seq = seq.next();
                    sink.send_file(&buf[..n]);
                    Next::Sent(watch.sent(pdu))
                })?;
                match next {
                    Next::NoRoom => return None,
                    Next::Unsendable => {
                        self.unsent = self.unsent.wrapping_add(1);
                        entity.drop_next();
                    }
                    Next::Sent(opened) => {
                        entity.drop_next();
                        return Some(opened);
                    }
                }
            }
        }
    }

    /// The store's files and free bytes as HK FILES reports them, counted every
    /// `mib::cfdp::STORE_LOOK_MS` and when a transaction ended.
    #[derive(Clone, Copy, Debug, Default)]
    pub struct StoreLook {
        pub files: u16,
        pub free: u32,
        next_ms: u64,
    }

    impl StoreLook {
        /// Counts again when due; a store that cannot be read keeps its last figures (the
        /// failure is counted by the store).
        pub fn update<S: FlatStore>(&mut self, now_ms: u64, ended: bool, entity: &Entity<'_, S>) {
            if !ended && now_ms < self.next_ms {
                return;
            }
            self.next_ms = now_ms.saturating_add(mib::cfdp::STORE_LOOK_MS);
            let store = entity.store();
            if let (Ok(files), Ok(free)) = (store.count_files(), store.free()) {
                self.files = u16::try_from(files).unwrap_or(u16::MAX);
                self.free = u32::try_from(free).unwrap_or(u32::MAX);
            }
        }
    }

    /// What `entity`, its store, `watch` and `down` counted; the store's files and free
    /// bytes as `look` last counted them (a listing reads the medium), `removed` what
    /// `Entity::discard_partial` removed at start.
    pub fn counters<S: FlatStore>(
        entity: &Entity<'_, S>,
        watch: &Watch,
        down: &PduDownlink,
        look: &StoreLook,
        removed: u16,
    ) -> FileCounters {
        let (c, s, w) = (entity.counters(), entity.store().counters(), watch);
        FileCounters {
            pdus_received: c.received,
            pdus_sent: w.pdus_sent,
            pdus_refused: c.refused,
            pdus_stray: c.stray,
            handler_refused: c.handler_errors,
            before_metadata: c.before_metadata,
            tx_received: w.opened_received,
            tx_sent: w.opened_sent,
            tx_completed: c.completed,
            tx_failed: c.failed,
            faults: c.faults,
            segments_resent: c.resent,
            naks_sent: w.naks_sent,
            naks_received: w.naks_received,
            outbox_dropped: c.outbox_dropped.wrapping_add(down.unsent),
            resend_dropped: c.resend_dropped,
            superseded: c.superseded,
            fs_done: c.fs_done,
            fs_refused: c.fs_refused,
            proxy_refused: c.proxy_refused,
            store_bad_names: s.bad_names,
            store_full: s.full,
            store_io_errors: s.io_errors,
            store_files: look.files,
            store_free: look.free,
            partials_removed: removed,
        }
    }

    fn direction(sent: bool) -> Direction {
        if sent {
            Direction::Sent
        } else {
            Direction::Received
        }
    }

    /// A transaction `watch` saw open.
    pub fn began(o: &Opened) -> Began {
        Began {
            source: o.source,
            seq: o.seq,
            direction: direction(o.sent),
            class: match o.class {
                mmic_cfdp::Class::One => Class::One,
                mmic_cfdp::Class::Two => Class::Two,
            },
            length: u32::try_from(o.length).unwrap_or(u32::MAX),
        }
    }

    /// A transaction `entity` reported finished (`Entity::take_finished`), with the bytes it
    /// moved: the entity's progress that way, at most the file's length `watch` saw.
    pub fn ended<S: FlatStore>(entity: &Entity<'_, S>, watch: &Watch, f: &Finished) -> Ended {
        let progress = if f.sent {
            entity.sent_progress().0
        } else {
            entity.progress()
        };
        Ended {
            source: f.source,
            seq: f.seq,
            direction: direction(f.sent),
            condition: f.condition as u8,
            complete: f.complete,
            bytes: u32::try_from(watch.bytes(f, progress)).unwrap_or(u32::MAX),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obsw::tests::{kind, obsw, of, send};
    use mib::events::eid;
    use mib::files::condition;

    /// The events among `pkts`: (severity, event ID, parameter bytes).
    fn events(pkts: &[Vec<u8>]) -> Vec<(u8, u16, Vec<u8>)> {
        pkts.iter()
            .filter(|p| kind(p).0 == 5)
            .map(|p| {
                let (_, sub, d) = kind(p);
                (sub, u16::from_be_bytes([d[0], d[1]]), d[2..].to_vec())
            })
            .collect()
    }

    /// The FILES report of a one-shot request, as (parameter ID, raw value) pairs.
    fn files_hk(o: &mut crate::obsw::tests::TestObsw, now: u64, seq: u16) -> Vec<(u16, u32)> {
        let p = send(o, now, seq, 3, 27, &mib::hk::sid::FILES.to_be_bytes());
        let hk = of(&p, 3, 25);
        assert_eq!(hk.len(), 1, "{p:?}");
        let mut d = &kind(&hk[0]).2[2..];
        let def = mib::hk::by_sid(mib::hk::sid::FILES).unwrap();
        def.params
            .iter()
            .map(|&id| {
                let n = mib::params::by_id(id).unwrap().ptype.size();
                let (v, rest) = d.split_at(n);
                d = rest;
                (id, v.iter().fold(0u32, |a, b| a << 8 | u32::from(*b)))
            })
            .collect()
    }

    // verifies: FILE-HK-01
    #[test]
    fn the_files_report_carries_what_the_platform_counted_and_nothing_before_it() {
        let mut o = obsw();
        assert_eq!(
            o.svc.files.param(pid::FILE_PDU_RECEIVED),
            Ok(None),
            "no file service yet"
        );
        assert_eq!(o.svc.files.param(pid::MODE), Err(NotSupplied(pid::MODE)));
        let c = FileCounters {
            pdus_received: 290,
            pdus_sent: 31,
            tx_received: 2,
            tx_sent: 1,
            tx_completed: 3,
            naks_sent: 4,
            store_files: 7,
            store_free: 4_000_000,
            ..FileCounters::default()
        };
        let mut sink: Vec<Vec<u8>> = Vec::new();
        o.files_report(100, Report::Counters(c), &mut sink);
        assert!(events(&sink).is_empty(), "nothing refused: no event {sink:?}");
        let hk = files_hk(&mut o, 110, 1);
        let v = |id| hk.iter().find(|(p, _)| *p == id).unwrap().1;
        assert_eq!(v(pid::FILE_PDU_RECEIVED), 290);
        assert_eq!(v(pid::FILE_PDU_SENT), 31);
        assert_eq!((v(pid::FILE_TX_RECEIVED), v(pid::FILE_TX_SENT)), (2, 1));
        assert_eq!(v(pid::FILE_TX_COMPLETED), 3);
        assert_eq!(v(pid::FILE_NAK_SENT), 4);
        assert_eq!((v(pid::FILE_STORE_FILES), v(pid::FILE_STORE_FREE)), (7, 4_000_000));
        assert_eq!(v(pid::FILE_TX_FAILED), 0);
        // Every parameter of the set is the component's, with a value now.
        for &id in mib::hk::by_sid(mib::hk::sid::FILES).unwrap().params {
            assert!(matches!(o.svc.files.param(id), Ok(Some(_))), "{id}");
        }
    }

    // verifies: FILE-EV-01
    #[test]
    fn each_transaction_is_evented_as_it_begins_and_ends_with_its_id_and_outcome() {
        let mut o = obsw();
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let began = Began {
            source: 0,
            seq: 513,
            direction: Direction::Received,
            class: Class::Two,
            length: 100_000,
        };
        o.files_report(10, Report::Began(began), &mut sink);
        let end = Ended {
            source: 0,
            seq: 513,
            direction: Direction::Received,
            condition: condition::NO_ERROR,
            complete: true,
            bytes: 100_000,
        };
        o.files_report(20, Report::Ended(end), &mut sink);
        let failed = Ended {
            source: 1,
            seq: 7,
            direction: Direction::Sent,
            condition: condition::INACTIVITY_DETECTED,
            complete: false,
            bytes: 2838,
        };
        o.files_report(30, Report::Ended(failed), &mut sink);
        let e = events(&sink);
        assert_eq!(
            e,
            [
                (1, eid::FILE_TRANSFER_STARTED, vec![0, 0, 2, 1, 0, 2, 0, 1, 0x86, 0xA0]),
                (
                    1,
                    eid::FILE_TRANSFER_COMPLETED,
                    vec![0, 0, 2, 1, 0, 0, 0, 1, 0x86, 0xA0]
                ),
                // A failure stands out: medium severity, the condition code and how far it got.
                (3, eid::FILE_TRANSFER_FAILED, vec![0, 1, 0, 7, 1, 8, 0, 0, 0x0B, 0x16]),
            ]
        );
    }

    // verifies: FILE-EV-02
    #[test]
    fn a_refusal_counter_that_rose_is_evented_once_per_period_with_its_total() {
        let mut o = obsw();
        let mut sink: Vec<Vec<u8>> = Vec::new();
        let mut c = FileCounters {
            pdus_refused: 1,
            store_bad_names: 2,
            ..FileCounters::default()
        };
        o.files_report(10, Report::Counters(c), &mut sink);
        // The same totals next period: nothing new.
        o.files_report(20, Report::Counters(c), &mut sink);
        c.pdus_refused = 5;
        c.store_io_errors = 1;
        c.pdus_received = 40;
        o.files_report(30, Report::Counters(c), &mut sink);
        // What a reset cut short, removed at start: once.
        c.partials_removed = 2;
        o.files_report(40, Report::Counters(c), &mut sink);
        o.files_report(50, Report::Counters(c), &mut sink);
        let e = events(&sink);
        let refused = |id: u16, total: u32| {
            let mut d = id.to_be_bytes().to_vec();
            d.extend(total.to_be_bytes());
            (2, eid::FILE_REFUSED, d)
        };
        assert_eq!(
            e,
            [
                refused(pid::FILE_PDU_REFUSED, 1),
                refused(pid::FILE_STORE_BAD_NAMES, 2),
                refused(pid::FILE_PDU_REFUSED, 5),
                (3, eid::FILE_STORE_ERROR, vec![0, 0, 0, 1]),
                (3, eid::FILE_PARTIALS_REMOVED, vec![0, 2]),
            ]
        );
    }
}
