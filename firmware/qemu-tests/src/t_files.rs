//! Board A's file service (`fw_core::files`) on the target, through the board's real packet
//! path: a ground CFDP entity in this binary (the same `mmic_cfdp::Entity`, as `ground
//! file` runs it) puts its PDUs in TC packets, each in an authenticated AD frame, COBS
//! framed into the uplink queue; board A's frame link (`FrameLink::receive`: SDLS, FARM-1)
//! hands the packets of the CFDP APID to the file service, which polls its entity each
//! period and sends its PDUs as TM packets into the link's TM frames; the ground decrypts
//! those (`TmReceiver`, the TM test key) and feeds their packets to its entity. The board's
//! store is a RAM store (`MemStore`) here: the flash store is judged on its own.
//!
//! Measured: the instructions of the file service's work in a period (the packet taken
//! and the poll: the largest file data packet written, the PDUs of a `get` read and sent
//! into the TM frame, the file's checksum paced at `mib::cfdp::CHECKSUM_BYTES_PER_POLL` a
//! period, the period that handles an EOF), the worst of which the control period's budget
//! (`t_budget`) counts in place of the period's TC packet when it is larger; the entity's
//! RAM. No period sums a whole file: both stores' `whole_sums` stay 0.

use crate::harness::{self, Test, TestResult};
use crate::t_framelink::{test_keys, uplink, MockFlash};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::config;
use fw_core::cycle::GroundSink;
use fw_core::files::{FileService, Files};
use fw_core::link::{self, ByteQueue, Counters, TcChannel};
use fw_core::link_store::FlashIvStore;
use fw_core::spacelink::FrameLink;
use mib::cfdp::{GROUND_ENTITY_ID, MAX_PACKET_LEN, MAX_SEGMENT_LEN};
use mmic_cfdp::entity::Pdu;
use mmic_cfdp::packet::{self, Direction};
use mmic_cfdp::spacepackets::cfdp::ChecksumType;
use mmic_cfdp::store::MemStore;
use mmic_cfdp::{Class, Entity, FileName, Parts};
use mmic_link::downlink::TmReceiver;
use mmic_link::sdls::{build_tc, MemoryIvStore, RxSa, RxSas, TxSa};
use mmic_link::tc::{FrameType, TcRepr};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};
use mmic_stream::Deframer;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};
use portable_atomic::Ordering;

pub const TESTS: &[Test] = tests![files_put_class_2_and_1_get_and_a_malformed_pdu_through_board_a_s_frame_link];

/// Four files of up to 24 KiB on each side.
type Mem = MemStore<4, 24_576>;
type Link = FrameLink<FlashIvStore<MockFlash>>;
type Tm = ByteQueue<{ config::TM_DOWNLINK_BYTES }>;

fn instret() -> u64 {
    riscv::register::minstret::read64()
}

/// The file service with its work per period counted.
struct Timed<'a> {
    files: Files<'a, Mem>,
    /// This period's instructions in `take` and `poll`.
    work: u64,
    /// A packet was taken this period.
    took: bool,
    /// The most a poll took after a packet (nothing read of the store).
    quiet_poll: u64,
    /// The most file data PDUs a poll sent.
    data_sent: usize,
}

/// A sink that counts the file data PDUs sent through it.
struct DataCount<'s, T> {
    inner: &'s mut T,
    data: usize,
}

impl<T: TmSink> TmSink for DataCount<'_, T> {
    fn send_tm(&mut self, packet: &[u8]) {
        self.inner.send_tm(packet);
    }
    fn send_file(&mut self, packet: &[u8]) {
        use mmic_cfdp::spacepackets::cfdp::{pdu::PduHeader, PduType};
        let header = packet::unwrap(Direction::Down, packet).and_then(|pdu| PduHeader::from_bytes(pdu).ok());
        if header.is_some_and(|(h, _)| h.pdu_type() == PduType::FileData) {
            self.data += 1;
        }
        self.inner.send_file(packet);
    }
    fn replay_room(&self) -> usize {
        self.inner.replay_room()
    }
}

impl FileService for Timed<'_> {
    fn take(&mut self, now: u64, packet: &[u8]) -> bool {
        let t0 = instret();
        let taken = self.files.take(now, packet);
        self.work += instret() - t0;
        self.took |= taken;
        taken
    }
    fn tc_handled(&mut self) {
        self.files.tc_handled();
    }
    fn poll(&mut self, now: u64, sink: &mut impl TmSink) {
        let mut counted = DataCount { inner: sink, data: 0 };
        let t0 = instret();
        self.files.poll(now, &mut counted);
        let poll = instret() - t0;
        self.data_sent = self.data_sent.max(counted.data);
        self.work += poll;
        if self.took {
            // After a packet the poll reads nothing of the store: what it costs beside a TC.
            self.quiet_poll = self.quiet_poll.max(poll);
        }
    }
}

/// The worst periods of a run.
#[derive(Default)]
struct Worst {
    /// A period that took a file data packet of a whole segment (the largest).
    file_data: u64,
    /// Any period of the file service (a paced checksum, a get's reading, an EOF).
    any: u64,
    /// A period that handled an EOF: the board sent its EOF, or answered the ground's
    /// (its ACK in class 2, its Finished in class 1).
    eof: u64,
    /// Periods run.
    periods: u32,
    /// The board's stack high-water mark in a period (bytes).
    stack: usize,
}

/// Both ends and the link between them.
struct Rig<'a> {
    board: Timed<'a>,
    ground: Entity<'a, Mem>,
    obsw: Obsw<RingStore<8192>>,
    link: Link,
    tc_sa: TxSa,
    ground_ivs: MemoryIvStore,
    /// The next AD frame's N(S) and the next uplink packet's sequence count.
    ns: u8,
    up_seq: u16,
    /// A ground PDU the uplink queue had no room for.
    held: Option<Pdu>,
    tm_rx: TmReceiver<1>,
    tm_ivs: MemoryIvStore,
    now: u64,
    worst: Worst,
}

static TCS: TcChannel = TcChannel::new();
static UP: Counters = Counters::new();
static TM: Tm = ByteQueue::new();
static DOWN: Counters = Counters::new();

impl Rig<'_> {
    /// One packet up in its own AD frame (sequence count and N(S) the ground's).
    fn send_up(&mut self, packet: &[u8]) -> bool {
        let repr = TcRepr {
            frame_type: FrameType::Ad,
            scid: mib::link::SCID,
            vcid: mib::link::tc_vc::COMMAND,
            seq: self.ns,
            data_len: 0,
        };
        let mut frame = [0u8; mib::link::tc_frame::MAX_LEN];
        let Ok(n) = build_tc(&mut self.tc_sa, &mut self.ground_ivs, repr, packet, &mut frame) else {
            return false;
        };
        self.ns = self.ns.wrapping_add(1);
        uplink(&frame[..n], &TCS, &UP);
        true
    }

    /// One control period of both ends: the ground's PDUs up while the uplink queue takes
    /// them, board A's link and file service, the TM frames down to the ground's entity.
    fn period(&mut self) {
        self.now += u64::from(config::CONTROL_PERIOD_MS);
        let now = self.now;
        self.ground.poll(now);
        while !TCS.is_full() {
            let Some(pdu) = self.held.take().or_else(|| self.ground.pop()) else {
                break;
            };
            let mut p = [0u8; MAX_PACKET_LEN];
            let Some(n) = packet::wrap(Direction::Up, self.up_seq, &pdu, &mut p) else {
                break;
            };
            self.up_seq = self.up_seq.wrapping_add(1) & 0x3FFF;
            self.send_up(&p[..n]);
        }
        // Board A's period, as `CycleA::run` orders it (the tick left out: `t_budget` adds it),
        // and its stack.
        let before = self.board.files.entity().progress();
        (self.board.work, self.board.took) = (0, false);
        let ((), stack) = harness::stack_depth(|| {
            self.link
                .receive(now, &mut self.obsw, &mut self.board, &TCS, &TM, &DOWN);
            let mut sink = GroundSink {
                link: &mut self.link,
                queue: &TM,
                counters: &DOWN,
            };
            self.board.poll(now, &mut sink);
            self.link.end_period(now, &mut self.obsw, &TM, &DOWN);
        });
        self.worst.stack = self.worst.stack.max(stack);
        let written = self.board.files.entity().progress().saturating_sub(before);
        if self.board.took && written == MAX_SEGMENT_LEN as u64 {
            self.worst.file_data = self.worst.file_data.max(self.board.work);
        }
        self.worst.any = self.worst.any.max(self.board.work);
        self.worst.periods += 1;
        if self.downlink() {
            self.worst.eof = self.worst.eof.max(self.board.work);
        }
    }

    /// The TM frames in the downlink queue to the ground: the CFDP APID's packets to its
    /// entity. Whether they held an EOF, the ACK of one or a Finished PDU (the board's
    /// period handled an EOF).
    fn downlink(&mut self) -> bool {
        use mmic_cfdp::spacepackets::cfdp::pdu::{FileDirectiveType as D, PduHeader};
        let mut eof = false;
        let mut bytes = [0u8; config::TM_DOWNLINK_BYTES];
        let n = link::drain(&TM, &mut bytes);
        let mut deframer: Deframer<{ mib::link::tm_frame::LEN }> = Deframer::new();
        let mut frame = [0u8; mib::link::tm_frame::LEN];
        let (ground, now) = (&mut self.ground, self.now);
        for &b in &bytes[..n] {
            let Some(Ok(f)) = deframer.push(b) else { continue };
            let len = f.len();
            frame[..len].copy_from_slice(f);
            let _ = self.tm_rx.receive(&mut self.tm_ivs, &mut frame[..len], |_, p| {
                if packet::apid(p) == Some(mib::cfdp::APID) {
                    let directive = packet::unwrap(Direction::Down, p).and_then(|pdu| {
                        let (h, hl) = PduHeader::from_bytes(pdu).ok()?;
                        (h.pdu_type() == mmic_cfdp::spacepackets::cfdp::PduType::FileDirective)
                            .then(|| pdu.get(hl).copied())?
                    });
                    eof |= [D::EofPdu, D::AckPdu, D::FinishedPdu]
                        .iter()
                        .any(|d| directive == Some(*d as u8));
                    ground.receive_packet(now, Direction::Down, p);
                }
            });
        }
        eof
    }

    /// Periods until both entities are idle with nothing in flight (at most `max`).
    fn settle(&mut self, max: u32) -> bool {
        for _ in 0..max {
            self.period();
            let quiet = self.held.is_none() && TCS.is_empty() && !self.link.ep.busy();
            if quiet && self.ground.idle() && self.board.files.entity().idle() {
                return true;
            }
        }
        false
    }
}

/// `len` bytes of a pseudo-random pattern (xorshift from `seed`).
fn pattern(seed: u32, out: &mut [u8]) {
    let mut x = seed;
    for b in out.iter_mut() {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *b = x as u8;
    }
}

/// The whole file `name` of `store`, into `buf`; its length.
fn read_all(store: &Parts<Mem>, name: &str, buf: &mut [u8]) -> Option<usize> {
    let n = FileName::new(name).ok()?;
    let len = store.store.len(&n).ok()?? as usize;
    store.store.read(&n, 0, buf.get_mut(..len)?).ok()?;
    Some(len)
}

fn write_file(store: &Parts<Mem>, name: &str, data: &[u8]) -> Option<()> {
    let n = FileName::new(name).ok()?;
    store.store.create(&n).ok()?;
    store.store.write(&n, 0, data).ok()
}

/// The store's files (name, length), in name order.
fn listing(store: &Parts<Mem>) -> heapless::Vec<(FileName, u64), 4> {
    let mut v = heapless::Vec::new();
    let _ = store.store.list(&mut |n, len| {
        let _ = v.push((n.clone(), len));
    });
    v
}

// verifies: FW-FILES-01
// verifies: FW-FILES-02
fn files_put_class_2_and_1_get_and_a_malformed_pdu_through_board_a_s_frame_link() -> TestResult {
    let board_parts = Parts::new(Mem::new(u64::from(mib::cfdp::BOARD_STORE_BYTES)));
    let ground_parts = Parts::new(Mem::new(4 * 24_576));
    let keys = test_keys();
    let mut tm_sas: RxSas<1> = RxSas::default();
    check!(tm_sas.insert(RxSa::new(keys.tm_spi, &TEST_KEY_TM_A, 4096)).is_ok());
    let mut rig = Rig {
        board: Timed {
            files: Files::new(1, &board_parts),
            work: 0,
            took: false,
            quiet_poll: 0,
            data_sent: 0,
        },
        ground: Entity::new(GROUND_ENTITY_ID, mib::cfdp::robot_entity_id(1), &ground_parts),
        obsw: Obsw::new(
            Config {
                robot: 1,
                epoch_unix_ms: 0,
            },
            RingStore::default(),
        ),
        link: FrameLink::new(
            Some(&keys),
            Default::default(),
            FlashIvStore::open(MockFlash::erased(), 0),
        ),
        tc_sa: TxSa::resume(keys.tc_spi, &TEST_KEY_TC_A, 0),
        ground_ivs: MemoryIvStore::default(),
        ns: 0,
        up_seq: 0,
        held: None,
        tm_rx: TmReceiver::new(mib::link::SCID, tm_sas),
        tm_ivs: MemoryIvStore::default(),
        now: 0,
        worst: Worst::default(),
    };

    // Class 2 up: 20 000 bytes, 22 segments (the last one short).
    let mut data = [0u8; 20_000];
    pattern(0x1234_5678, &mut data);
    ok!(write_file(&ground_parts, "plan.bin", &data));
    check!(rig.ground.put(rig.now, "plan.bin", "plan.bin", Class::Two).is_ok());
    check!(rig.settle(3000), "class 2 put not done in 3 000 periods");
    let f = ok!(rig.ground.take_finished());
    check!(f.complete && f.sent, "class 2 put ended {:?}", f);
    let mut back = [0u8; 24_576];
    let n = ok!(read_all(&board_parts, "plan.bin", &mut back));
    check_eq!(n, data.len());
    check!(back[..n] == data[..], "the board's copy differs");
    let put2_periods = rig.worst.periods;
    let put2_worst = core::mem::take(&mut rig.worst.any);

    // Class 1 up: 5 000 bytes.
    let mut small = [0u8; 5_000];
    pattern(0x0BAD_CAFE, &mut small);
    ok!(write_file(&ground_parts, "table.bin", &small));
    check!(rig.ground.put(rig.now, "table.bin", "table.bin", Class::One).is_ok());
    check!(rig.settle(3000), "class 1 put not done");
    let f = ok!(rig.ground.take_finished());
    check!(f.complete && f.sent, "class 1 put ended {:?}", f);
    let n = ok!(read_all(&board_parts, "table.bin", &mut back));
    check!(back[..n] == small[..], "the board's class 1 copy differs ({} bytes)", n);

    // A get back down (class 2): the board puts its file to the ground.
    let put1_worst = core::mem::take(&mut rig.worst.any);
    check!(rig.ground.get(rig.now, "plan.bin", "down.bin", Class::Two).is_ok());
    check!(rig.settle(3000), "get not done");
    let mut got_back = false;
    while let Some(f) = rig.ground.take_finished() {
        // The proxy put request (sent), then the board's put (received here).
        if !f.sent {
            check!(f.complete, "the get ended {:?}", f);
            got_back = true;
        }
    }
    check!(got_back, "no file came down");
    let n = ok!(read_all(&ground_parts, "down.bin", &mut back));
    check!(back[..n] == data[..], "the ground's copy differs ({} bytes)", n);
    let get_worst = rig.worst.any;
    // The board read and sent its file at most `BOARD_SEGMENTS_PER_PERIOD` segments a
    // period (`Entity::poll_paced`), and none in the period that took the request.
    check!(
        rig.board.data_sent <= mib::cfdp::BOARD_SEGMENTS_PER_PERIOD,
        "{} file data PDUs sent in one period",
        rig.board.data_sent
    );
    check!(rig.board.data_sent > 0, "file data went down");
    rig.worst.any = rig.worst.any.max(put2_worst).max(put1_worst);
    // No period summed a whole file: the sums were paced, the EOF periods took them.
    check_eq!(board_parts.store.counters().whole_sums, 0);
    check_eq!(ground_parts.store.counters().whole_sums, 0);
    // A file's checksum in one call, read from the RAM store: its cost per KiB (what the
    // paced sum costs a period, `t_budget`).
    let name = ok!(FileName::new("plan.bin"));
    let mut buf = [0u8; 1024];
    let t0 = instret();
    let sum = board_parts
        .store
        .checksum(&name, ChecksumType::Modular, data.len() as u64, &mut buf);
    let checksum_cost = instret() - t0;
    check!(sum.is_ok());

    // Malformed PDUs through the same path: a header whose length runs past the packet,
    // then a well-formed EOF addressed to another entity. Refused, counted, nothing changed.
    let refused = rig.board.files.counters().refused;
    let files_before = listing(&board_parts);
    let mut p = [0u8; 64];
    let bad: [u8; 12] = [0x24, 0x00, 0x40, 0x11, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01, 0x04, 0x00];
    let n = ok!(packet::wrap(Direction::Up, rig.up_seq, &bad, &mut p));
    check!(rig.send_up(&p[..n]));
    rig.up_seq += 1;
    let mut eof = [0u8; 64];
    let n_eof = ok!(other_entitys_eof(&mut eof));
    let n = ok!(packet::wrap(Direction::Up, rig.up_seq, &eof[..n_eof], &mut p));
    check!(rig.send_up(&p[..n]));
    check!(rig.settle(100));
    check_eq!(rig.board.files.counters().refused, refused + 2);
    check!(listing(&board_parts) == files_before, "the store changed");
    check!(rig.board.files.entity().idle(), "a transaction started");
    check_eq!(rig.board.files.counters().handler_errors, 0);

    let w = &rig.worst;
    check!(w.file_data > 0, "a whole segment's period was measured");
    harness::WORST_FILE_DATA.store(w.file_data, Ordering::Relaxed);
    check!(w.eof > 0, "an EOF's period was measured");
    // Every period of the file service, enforced in t_budget: the puts' (the board
    // receiving: file data written, its sum paced while it holds the EOF), the get's (a
    // segment read and framed into the TM frame with the sent file's sum alongside; the
    // request taken and the transaction set up) and every period that handled an EOF.
    let enforced = put2_worst.max(put1_worst).max(w.eof).max(get_worst);
    harness::WORST_FILE_PERIOD.store(enforced, Ordering::Relaxed);
    check!(rig.board.quiet_poll > 0, "a poll after a packet was measured");
    harness::WORST_FILE_QUIET_POLL.store(rig.board.quiet_poll, Ordering::Relaxed);
    harness::CHECKSUM_PER_KIB.store(checksum_cost * 1024 / data.len() as u64, Ordering::Relaxed);
    semihosting::println!(
        "    file service per period (instructions, RAM store): a {}-byte file data packet taken and the poll {}; the worst period of the class 2 put {}, of the class 1 put {}, of the get {}; the class 2 put of {} bytes in {} periods",
        MAX_SEGMENT_LEN,
        w.file_data,
        put2_worst,
        put1_worst,
        get_worst,
        data.len(),
        put2_periods,
    );
    semihosting::println!(
        "    a file's modular checksum (paced, {} bytes a period): {} instructions for {} bytes in one call, {} per KiB; the worst period that handled an EOF {}; the worst period of the puts, the get and EOFs {} (enforced in t_budget), of the get {}",
        mib::cfdp::CHECKSUM_BYTES_PER_POLL,
        checksum_cost,
        data.len(),
        checksum_cost * 1024 / data.len() as u64,
        w.eof,
        enforced,
        get_worst,
    );
    semihosting::println!(
        "    stack high-water of board A's periods (link and file service; put, get, malformed PDUs): {} bytes",
        w.stack
    );
    semihosting::println!(
        "    file service RAM (riscv32imc): Files (the entity, its handlers and gap list) {} bytes, Parts less its store (clock, outbox of {} PDUs) {} bytes",
        core::mem::size_of::<Files<'_, Mem>>(),
        mib::cfdp::OUTBOX_DEPTH,
        core::mem::size_of::<Parts<Mem>>() - core::mem::size_of::<Mem>(),
    );
    Ok(())
}

/// An EOF PDU from the ground to entity 9 (not this robot), transaction 0/77: well formed.
fn other_entitys_eof(out: &mut [u8]) -> Option<usize> {
    use mmic_cfdp::spacepackets::cfdp::pdu::eof::EofPdu;
    use mmic_cfdp::spacepackets::cfdp::pdu::{CommonPduConfig, PduHeader};
    use mmic_cfdp::spacepackets::cfdp::{CrcFlag, LargeFileFlag, TransmissionMode};
    use mmic_cfdp::spacepackets::util::UnsignedByteFieldU16;
    let conf = CommonPduConfig::new_with_byte_fields(
        UnsignedByteFieldU16::new(GROUND_ENTITY_ID),
        UnsignedByteFieldU16::new(9),
        UnsignedByteFieldU16::new(77),
    )
    .ok()?;
    let mut conf = conf;
    conf.trans_mode = TransmissionMode::Acknowledged;
    conf.file_flag = LargeFileFlag::Normal;
    conf.crc_flag = CrcFlag::NoCrc;
    let header = PduHeader::new_for_file_directive(conf, 0);
    EofPdu::new_no_error(header, 0, 0).write_to_bytes(out).ok()
}
