//! Board A's PUS 15 store on the target: `obsw_core::flash_store` over the project's NOR
//! model (`flash_store::Nor`, the rules the QEMU board's flash file and the host's store
//! file share) in RAM. A reset cut into the store's writes at every byte loses at most the
//! packet being written; and what a store write and a replay's reading cost on RV32IMC, for
//! the control period's budget (`t_budget` adds the store writes of a period).

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use core::cell::RefCell;
use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use mib::config::MAX_PACKET_LEN;
use obsw_core::flash_store::{FlashStore, Medium, Nor};
use obsw_core::obsw::Obsw;
use obsw_core::time::OnboardTime;
use obsw_core::tm::{RingStore, Skipped, Stretch, TmSink, TmStore, TmWriter};
use portable_atomic::Ordering;

pub const TESTS: &[Test] = tests![
    store_reset_cut_into_a_write_at_every_byte_loses_at_most_that_packet,
    store_write_and_replay_read_cost_measured,
    store_paced_replay_from_a_full_store_worst_period_measured,
];

const SECTOR: usize = mib::memory::FLASH_SECTOR as usize;
/// Two HK sectors and two report sectors: the smallest layout with the overwrite path.
const BYTES: usize = 4 * SECTOR;
type Store<'a> = FlashStore<'a, Nor<Ram>, 2, 2>;

/// Packets of the scenario: every third an event (report area), the rest periodic HK.
const PACKETS: usize = 160;
/// A ROBOT_STATUS report's size on the wire, about (`t_budget`'s 91-byte packet).
const HK_DATA: usize = 72;

/// The flash's content in RAM, and a power cut after a budget of written bytes.
#[derive(Clone)]
struct Ram {
    mem: [u8; BYTES],
    /// Units still written before the power goes: a byte of a write, a 256-byte step of an
    /// erase (`Nor` erases in such steps); `None`: no cut.
    budget: Option<usize>,
    cut: bool,
}

#[derive(Debug)]
struct PowerCut;

/// Takes one unit of the budget; false once the power is cut.
fn spend(budget: &mut Option<usize>, cut: &mut bool) -> bool {
    match budget.as_mut() {
        _ if *cut => false,
        Some(0) => {
            *cut = true;
            false
        }
        Some(b) => {
            *b -= 1;
            true
        }
        None => true,
    }
}

impl Medium for Ram {
    type Error = PowerCut;
    fn read_at(&mut self, at: u32, out: &mut [u8]) -> Result<(), PowerCut> {
        if self.cut {
            return Err(PowerCut);
        }
        let at = at as usize;
        out.copy_from_slice(self.mem.get(at..at + out.len()).ok_or(PowerCut)?);
        Ok(())
    }
    fn write_at(&mut self, at: u32, bytes: &[u8]) -> Result<(), PowerCut> {
        let at = at as usize;
        let cells = self.mem.get_mut(at..at + bytes.len()).ok_or(PowerCut)?;
        if self.budget.is_none() && !self.cut {
            // No cut armed: a plain copy, so that the measured costs are the store's.
            cells.copy_from_slice(bytes);
            return Ok(());
        }
        if bytes.len() == 256 && bytes.iter().all(|b| *b == 0xFF) {
            if !spend(&mut self.budget, &mut self.cut) {
                return Err(PowerCut);
            }
            cells.copy_from_slice(bytes);
            return Ok(());
        }
        for (c, b) in cells.iter_mut().zip(bytes) {
            if !spend(&mut self.budget, &mut self.cut) {
                return Err(PowerCut);
            }
            *c = *b;
        }
        Ok(())
    }
}

fn erased() -> Ram {
    Ram {
        mem: [0xFF; BYTES],
        budget: None,
        cut: false,
    }
}

fn flash(ram: &Ram) -> RefCell<Nor<Ram>> {
    RefCell::new(Nor::new(ram.clone(), BYTES as u32))
}

/// The scenario's packets, each as the TM writer makes it (a stamp 1 s apart).
struct Packets {
    bytes: [[u8; 96]; PACKETS],
    len: [usize; PACKETS],
}

fn packets() -> Option<Packets> {
    let mut p = Packets {
        bytes: [[0; 96]; PACKETS],
        len: [0; PACKETS],
    };
    let mut w = TmWriter::new(0x101, OnboardTime::new(1_790_000_000_000));
    let mut buf = [0u8; MAX_PACKET_LEN];
    for i in 0..PACKETS {
        let event = i % 3 == 2;
        let data = [i as u8; HK_DATA];
        let (svc, sub, n) = if event { (5, 1, 12) } else { (3, 25, HK_DATA) };
        let len = w.build(1000 * i as u64, svc, sub, &data[..n], &mut buf)?;
        p.bytes[i][..len].copy_from_slice(&buf[..len]);
        p.len[i] = len;
    }
    Some(p)
}

impl Packets {
    fn get(&self, i: usize) -> &[u8] {
        &self.bytes[i][..self.len[i]]
    }
    /// The packet index of stored bytes (its sequence count), when they are one of ours.
    fn index(&self, stored: &[u8]) -> Option<usize> {
        let i = usize::from(u16::from_be_bytes([*stored.get(2)?, *stored.get(3)?]) & 0x3FFF);
        (i < PACKETS && self.get(i) == stored).then_some(i)
    }
}

/// What the store holds, oldest first, as packet indices; `usize::MAX` for bytes that are
/// none of the packets written (corrupt).
type Content = heapless::Vec<usize, PACKETS>;

fn content(s: &mut Store<'_>, p: &Packets) -> Content {
    let mut out = Content::new();
    s.visit(&mut |b| {
        let _ = out.push(p.index(b).unwrap_or(usize::MAX));
    });
    out
}

// verifies: PUS-15-05
/// A reset at any byte of a store write (and any 256-byte step of the sector erase an
/// overwrite makes): after the restart the store holds everything it held before and
/// everything the finished write keeps, but perhaps the packet being written; nothing
/// corrupt, nothing reordered; and it goes on storing.
fn store_reset_cut_into_a_write_at_every_byte_loses_at_most_that_packet() -> TestResult {
    let p = ok!(packets());
    // How many packets fit before the first overwrite.
    let mut fits = 0;
    {
        let f = flash(&erased());
        let mut s = ok!(Store::open(&f, 0).ok());
        while fits < PACKETS - 10 && s.push(p.get(fits)) == 0 {
            fits += 1;
        }
    }
    check!(
        fits > 20 && fits < PACKETS - 10,
        "{} packets before the first overwrite",
        fits
    );
    // The base: filled to three packets before that; the writes under test overwrite.
    let first = fits - 3;
    let mut base = erased();
    {
        let f = flash(&base);
        let mut s = ok!(Store::open(&f, 0).ok());
        for i in 0..first {
            s.push(p.get(i));
        }
        base = f.borrow().medium().clone();
    }
    const WRITES: usize = 6;
    // The uncut reference: the content before and after each write.
    let mut after: heapless::Vec<Content, { WRITES + 1 }> = heapless::Vec::new();
    let total = {
        let mut armed = base.clone();
        armed.budget = Some(usize::MAX);
        let f = flash(&armed);
        let mut s = ok!(Store::open(&f, 0).ok());
        let _ = after.push(content(&mut s, &p));
        for k in 0..WRITES {
            s.push(p.get(first + k));
            let _ = after.push(content(&mut s, &p));
        }
        let left = ok!(f.borrow().medium().budget);
        usize::MAX - left
    };
    check!(after[0].len() == first, "base holds {} of {}", after[0].len(), first);
    check!(
        after[WRITES].len() < after[0].len() + WRITES,
        "the writes overwrote nothing"
    );
    let (mut cuts, mut lost_the_packet) = (0u32, 0u32);
    for cut in 0..=total {
        let mut armed = base.clone();
        armed.budget = Some(cut);
        let f = flash(&armed);
        let mut in_progress = None;
        {
            let mut s = ok!(Store::open(&f, 0).ok());
            for k in 0..WRITES {
                s.push(p.get(first + k));
                if f.borrow().medium().cut {
                    in_progress = Some(k);
                    break;
                }
            }
        }
        // The restart: the power is back, the store opened again from the flash.
        let mut ram = f.borrow().medium().clone();
        ram.budget = None;
        ram.cut = false;
        let f = flash(&ram);
        let mut s = ok!(Store::open(&f, 0).ok());
        let got = content(&mut s, &p);
        let Some(k) = in_progress else {
            check_eq!(&got[..], &after[WRITES][..]);
            continue;
        };
        cuts += 1;
        let written = first + k;
        let (before, done) = (&after[k], &after[k + 1]);
        // Nothing corrupt, nothing unwritten, nothing out of order.
        let mut at = 0;
        for &i in &got {
            check!(i != usize::MAX, "cut {} in write {}: corrupt bytes read back", cut, k);
            let next = before[at.min(before.len())..].iter().position(|&b| b == i);
            match next {
                Some(n) => at += n + 1,
                None => check!(
                    i == written && at <= before.len(),
                    "cut {} in write {}: packet {} unknown or reordered",
                    cut,
                    k,
                    i
                ),
            }
        }
        // Everything the finished write keeps is there, but for the packet itself.
        for &i in done.iter().filter(|&&i| i != written) {
            check!(got.contains(&i), "cut {} in write {}: lost packet {}", cut, k, i);
        }
        lost_the_packet += u32::from(!got.contains(&written));
        check_eq!(s.len(), got.len());
        // The store goes on working after the restart.
        let next = p.get(first + WRITES);
        s.push(next);
        check_eq!(s.counts().not_stored, 0);
        let now = content(&mut s, &p);
        check_eq!(now.last().copied(), Some(first + WRITES));
    }
    check!(cuts as usize == total, "{} cuts of {} inside a write", cuts, total);
    semihosting::println!(
        "    store writes cut at each of {} bytes and erase steps ({} writes, one overwriting): the packet being written lost {} times, nothing else",
        total,
        WRITES,
        lost_the_packet
    );
    check!(lost_the_packet > 0, "no cut lost the packet: the cuts did not bite");
    Ok(())
}

fn instret() -> u64 {
    riscv::register::minstret::read64()
}

/// The worst and the least sum over `w` consecutive entries of `costs`.
fn window(costs: &[u32], w: usize) -> (u64, u64) {
    let w = w.clamp(1, costs.len().max(1));
    costs
        .windows(w)
        .map(|c| c.iter().map(|&x| u64::from(x)).sum::<u64>())
        .fold((0, u64::MAX), |(hi, lo), s| (hi.max(s), lo.min(s)))
}

// verifies: FW-CPU-01
/// A store write on board A is a `sequential-storage` push into flash (item CRCs, page
/// states, and a sector erase once the oldest packets are given up), not the RAM ring the
/// OBSW's tick was measured with. The store runs here in control periods as the OBSW drives
/// it: a busy period with the most packets one tick sends, the store's end of period
/// (`TmStore::end_period`, which frees ahead of need in quiet periods) and the most one TC
/// sends, then `QUIET_PERIODS` periods of one write each (far more than the MIB's default
/// housekeeping and events write). The worst period's store work, less what the RAM ring
/// took for the same packets, is what a period adds for its store writes
/// (`harness::STORE_WRITES_EXTRA`); no write may have had to free a sector itself. For
/// comparison, the same packets are pushed in a row into a store never told a period ended
/// (what the store cost before it freed ahead). A replay reads the store from its oldest
/// packet each period: the read cost per packet is printed with what a full store of the
/// MIB's size takes.
fn store_write_and_replay_read_cost_measured() -> TestResult {
    /// Quiet periods after each busy one (one write each).
    const QUIET_PERIODS: usize = 9;
    const CYCLES: usize = 30;
    let p = ok!(packets());
    let tick_packets = crate::harness::MOST_TICK_PACKETS.load(Ordering::Relaxed) as usize;
    let tc_packets = crate::harness::MOST_TC_PACKETS.load(Ordering::Relaxed) as usize;
    let packets_per_period = tick_packets + tc_packets;
    check!(
        packets_per_period > 0,
        "t_obsw ran before and counted the packets of a period"
    );
    let f = flash(&erased());
    let mut s = ok!(Store::open(&f, 0).ok());
    let plain_flash = flash(&erased());
    let mut plain = ok!(Store::open(&plain_flash, 0).ok());
    let mut ring = RingStore::<4096>::default();
    let mut w = TmWriter::new(0x101, OnboardTime::new(1_790_000_000_000));
    let mut buf = [0u8; MAX_PACKET_LEN];
    let mut i = 0usize;
    let (mut freed_by_a_write, mut freed_ahead, mut plain_overwritten) = (0u32, 0u32, 0u32);
    let (mut worst_extra, mut worst_flash, mut worst_end_period) = (0u64, 0u64, 0u64);
    let mut plain_costs: heapless::Vec<u32, 1024> = heapless::Vec::new();
    let mut ring_costs: heapless::Vec<u32, 1024> = heapless::Vec::new();
    let mut median_src: heapless::Vec<u32, 1024> = heapless::Vec::new();
    for period in 0..CYCLES * (1 + QUIET_PERIODS) {
        let busy = period % (1 + QUIET_PERIODS) == 0;
        let (before, after) = if busy { (tick_packets, tc_packets) } else { (1, 0) };
        let (mut flash_cost, mut ring_cost) = (0u64, 0u64);
        for k in 0..before + after {
            // The end of the tick's period falls between its packets and the TC's.
            if k == before {
                let start = instret();
                freed_ahead += s.end_period();
                let c = instret() - start;
                worst_end_period = worst_end_period.max(c);
                flash_cost += c;
            }
            // Fresh stamps and counts, the bytes of the scenario's HK and events.
            let template = p.get(i % PACKETS);
            let (svc, sub) = (template[7], template[8]);
            let data = [i as u8; HK_DATA];
            let n = if svc == 5 { 12 } else { HK_DATA };
            let len = ok!(w.build(1000 * i as u64, svc, sub, &data[..n], &mut buf));
            i += 1;
            let start = instret();
            freed_by_a_write += s.push(&buf[..len]);
            let c = instret() - start;
            flash_cost += c;
            let _ = median_src.push(c as u32);
            let start = instret();
            ring.push(&buf[..len]);
            let c = instret() - start;
            ring_cost += c;
            let _ = ring_costs.push(c as u32);
            let start = instret();
            plain_overwritten += plain.push(&buf[..len]);
            let _ = plain_costs.push((instret() - start) as u32);
        }
        if after == 0 {
            let start = instret();
            freed_ahead += s.end_period();
            let c = instret() - start;
            worst_end_period = worst_end_period.max(c);
            flash_cost += c;
        }
        worst_flash = worst_flash.max(flash_cost);
        worst_extra = worst_extra.max(flash_cost.saturating_sub(ring_cost));
    }
    check!(plain_overwritten > 0, "the store never wrapped");
    check!(freed_ahead > 0, "the store never freed ahead");
    check_eq!(freed_by_a_write, 0);
    check_eq!(s.counts().not_stored, 0);
    crate::harness::STORE_WRITES_EXTRA.store(worst_extra, Ordering::Relaxed);
    // Without freeing ahead: the busy period's packets in a row at the worst place.
    let (plain_worst, _) = window(&plain_costs, packets_per_period);
    let (_, ring_least) = window(&ring_costs, packets_per_period);
    let mut sorted = median_src.clone();
    sorted.sort_unstable();
    let median = sorted[sorted.len() / 2];
    let mut plain_sorted = plain_costs.clone();
    plain_sorted.sort_unstable();
    semihosting::println!(
        "    a store write into flash (sequential-storage over the NOR model): median {} instructions, worst {} freeing ahead, worst {} without (a sector given up in one write); the RAM ring {} median",
        median,
        sorted[sorted.len() - 1],
        plain_sorted[plain_sorted.len() - 1],
        {
            let mut r = ring_costs.clone();
            r.sort_unstable();
            r[r.len() / 2]
        }
    );
    semihosting::println!(
        "    store work of a period ({} + {} packets, the store's end of period between; {} quiet periods of one write after each): worst {} instructions, {} beyond the RAM ring, added to the period; its end of period at most {} ({} packets freed ahead, {} by a write)",
        tick_packets,
        tc_packets,
        QUIET_PERIODS,
        worst_flash,
        worst_extra,
        worst_end_period,
        freed_ahead,
        freed_by_a_write
    );
    semihosting::println!(
        "    without freeing ahead (same run, same packets in a row, worst place): flash {} - RAM ring {} = {} instructions added to the period",
        plain_worst,
        ring_least,
        plain_worst.saturating_sub(ring_least)
    );

    // A replay's reading: every stored packet from the oldest.
    let held = s.len() as u64;
    let mut read = 0u64;
    let start = instret();
    s.visit(&mut |_| read += 1);
    let per_read = (instret() - start) / read.max(1);
    check_eq!(read, held);
    let full = Store::min_packets(mib::memory::store::HK_SECTORS, p.len[0]) as u64;
    semihosting::println!(
        "    a replay's reading: {} instructions per stored packet; from the oldest of a full HK area ({} packets of {} bytes) {} instructions, {:.1} periods' budget",
        per_read,
        full,
        p.len[0],
        per_read * full,
        (per_read * full) as f64 / mib::config::PERIOD_INSTRUCTION_BUDGET as f64
    );
    Ok(())
}

/// The flash store of the MIB's size: its partition's bytes in RAM (written once by this
/// test, its only user).
static mut PARTITION: [u8; mib::memory::store::SIZE as usize] = [0; mib::memory::store::SIZE as usize];

/// The partition as the NOR model's medium.
struct Partition(&'static mut [u8]);

impl Medium for Partition {
    type Error = ();
    fn read_at(&mut self, at: u32, out: &mut [u8]) -> Result<(), ()> {
        let at = at as usize;
        out.copy_from_slice(self.0.get(at..at + out.len()).ok_or(())?);
        Ok(())
    }
    fn write_at(&mut self, at: u32, bytes: &[u8]) -> Result<(), ()> {
        let at = at as usize;
        self.0.get_mut(at..at + bytes.len()).ok_or(())?.copy_from_slice(bytes);
        Ok(())
    }
}

type FullStore = obsw_core::flash_store::MibFlashStore<'static, Nor<Partition>>;

/// Board A's store with the instructions its replay reading takes counted
/// ([`TmStore::visit_after`], with the replay's own filter called from inside it).
struct Metered {
    store: FullStore,
    /// Instructions of `visit_after` and `skip` since the last take.
    reading: u64,
    /// Calls of `skip`.
    skips: u32,
}

impl TmStore for Metered {
    type Mark = <FullStore as TmStore>::Mark;
    const READS_PER_PERIOD: usize = FullStore::READS_PER_PERIOD;
    fn push(&mut self, packet: &[u8]) -> u32 {
        self.store.push(packet)
    }
    fn visit(&mut self, f: &mut dyn FnMut(&[u8])) {
        self.store.visit(f)
    }
    fn visit_after(
        &mut self,
        after: Option<Self::Mark>,
        most: usize,
        f: &mut dyn FnMut(&[u8], Self::Mark) -> bool,
    ) -> bool {
        let start = instret();
        let ended = self.store.visit_after(after, most, f);
        self.reading += instret() - start;
        ended
    }
    fn skip(
        &mut self,
        after: Option<Self::Mark>,
        most: usize,
        excludes: &mut dyn FnMut(&Stretch) -> bool,
    ) -> Skipped<Self::Mark> {
        let start = instret();
        let skipped = self.store.skip(after, most, excludes);
        self.reading += instret() - start;
        self.skips += 1;
        skipped
    }
    fn end_period(&mut self) -> u32 {
        self.store.end_period()
    }
    fn len(&self) -> usize {
        self.store.len()
    }
    fn clear(&mut self) {
        self.store.clear()
    }
}

static mut FLASH: MaybeUninit<RefCell<Nor<Partition>>> = MaybeUninit::uninit();
static mut REPLAY_OBSW: MaybeUninit<Obsw<Metered>> = MaybeUninit::uninit();

/// A TM sink that takes, each period, what board A's empty downlink queue holds.
struct EmptyQueueSink {
    room: usize,
    replayed: heapless::Vec<u16, 512>,
    sent_now: u64,
}

impl TmSink for EmptyQueueSink {
    fn send_tm(&mut self, _packet: &[u8]) {}
    fn send_replay(&mut self, packet: &[u8]) {
        self.room = self.room.saturating_sub(packet.len());
        self.sent_now += 1;
        let _ = self.replayed.push(u16::from_be_bytes([packet[2], packet[3]]) & 0x3FFF);
    }
    fn replay_room(&self) -> usize {
        self.room
    }
}

// verifies: FW-CPU-01, PUS-15-09, PUS-15-10
/// A paced PUS 15 downlink from board A's flash store of the MIB's size, its HK area full
/// (written until it overwrote): the ground asks for the newest packets by time, behind the
/// whole area. The replay reads `mib::memory::store::REPLAY_READS_PER_PERIOD` packets a
/// period and goes on from its mark; every period's reading (the store's and the replay's
/// filter) is counted, and the worst, with the most packets sent in a period, goes into the
/// control period's enforced budget (`t_budget`). For comparison, in the same run: one
/// reading of the store from its oldest packet, what every period of a paced replay cost
/// before it went on from a mark.
fn store_paced_replay_from_a_full_store_worst_period_measured() -> TestResult {
    use mib::memory::store;
    use obsw_core::obsw::Config;
    const EPOCH: u64 = 1_790_000_000_000;
    /// Newest packets the ground asks for.
    const ASKED: usize = 300;
    let apid = ok!(mib::apid::robot_apid(1));
    // SAFETY: this test is the statics' only user and runs once on the one hart.
    let (flash, obsw_slot) = unsafe {
        let part = &mut *addr_of_mut!(PARTITION);
        part.fill(0xFF);
        let flash = (*addr_of_mut!(FLASH)).write(RefCell::new(Nor::new(Partition(part), store::SIZE)));
        (&*flash, &mut *addr_of_mut!(REPLAY_OBSW))
    };
    let mut s = ok!(FullStore::open(flash, 0).ok());
    // Fill: HK of the scenario's size, every tenth packet an event, 1 s apart, until the
    // HK area has overwritten.
    let mut w = TmWriter::new(apid, OnboardTime::new(EPOCH));
    let mut buf = [0u8; MAX_PACKET_LEN];
    let (mut written, mut overwritten) = (0u64, 0u32);
    // The store's end of period at this size (one write a period: quiet), the worst when it
    // freed nothing and the worst when it freed ahead.
    let (mut end_nothing, mut end_freeing) = (0u64, 0u64);
    while overwritten == 0 || written % 10 != 0 {
        let event = written % 10 == 9;
        let data = [written as u8; HK_DATA];
        let (svc, sub, n) = if event { (5, 1, 12) } else { (3, 25, HK_DATA) };
        let len = ok!(w.build(1000 * written, svc, sub, &data[..n], &mut buf));
        overwritten += s.push(&buf[..len]);
        let start = instret();
        let freed = s.end_period();
        let c = instret() - start;
        if freed == 0 {
            end_nothing = end_nothing.max(c);
        } else {
            end_freeing = end_freeing.max(c);
        }
        overwritten += freed;
        written += 1;
    }
    let held = s.len();
    // Full: freeing ahead keeps a sector's packets fewer at most.
    let full = FullStore::min_packets(store::HK_SECTORS - 1, p_len(HK_DATA));
    check!(s.lens().0 >= full, "HK area holds {} of at least {}", s.lens().0, full);
    // Before: one reading from the oldest packet, as each period of a paced replay did.
    let start = instret();
    let mut read = 0usize;
    s.visit(&mut |_| read += 1);
    let from_oldest = instret() - start;
    check_eq!(read, held);

    let obsw = obsw_slot.write(Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: EPOCH,
        },
        Metered {
            store: s,
            reading: 0,
            skips: 0,
        },
    ));
    // TC[15,9]: the newest ASKED packets' time span.
    let first = written - ASKED as u64;
    let cds = |ms: u64| OnboardTime::new(EPOCH).cds(ms);
    let (a, b) = (cds(1000 * first), cds(1000 * (written - 1)));
    let mut app = [0u8; 12];
    app[..6].copy_from_slice(&a[1..7]);
    app[6..].copy_from_slice(&b[1..7]);
    let mut tc = [0u8; 64];
    let n = ok!(crate::t_packets::build(77, 15, 9, &app, &mut tc));
    let room = fw_core::config::TM_DOWNLINK_BYTES;
    let mut down = EmptyQueueSink {
        room,
        replayed: heapless::Vec::new(),
        sent_now: 0,
    };
    let sensors = mmic_domain::SensorsA::default();
    let now0 = 1000 * written;
    obsw.handle_tc(now0, &tc[..n], &mut down);
    let (mut worst, mut most_sent, mut periods) = (0u64, 0u64, 0u32);
    let mut reads_seen = 0u64;
    loop {
        obsw.tick(now0 + 10 * u64::from(periods), &sensors, &[], &mut down);
        let d = obsw.store_mut().reading;
        worst = worst.max(d);
        reads_seen += d;
        obsw.store_mut().reading = 0;
        most_sent = most_sent.max(down.sent_now);
        down.sent_now = 0;
        down.room = room;
        periods += 1;
        if obsw.replays_pending() == 0 || periods > 5000 {
            break;
        }
    }
    check!(obsw.replays_pending() == 0, "the replay ended in {} periods", periods);
    // Read packet by packet, the range behind the whole HK area took one period per
    // REPLAY_READS_PER_PERIOD packets (2 429 periods for 24 202 packets); passing over the
    // pages it rules out by their first packets, it takes a period per ten pages.
    let pages = (store::HK_SECTORS + store::REPORT_SECTORS) as u32;
    check!(
        periods <= pages / store::REPLAY_READS_PER_PERIOD + 150 && obsw.store_mut().skips > 0,
        "{} periods for a range behind {} pages",
        periods,
        pages
    );
    // Exactly the asked packets, each once, in order (HK and events merged by time).
    let expect = (first..written).map(|i| (i % 16384) as u16);
    check!(
        down.replayed.iter().copied().eq(expect),
        "replayed {} packets, not the {} asked in order",
        down.replayed.len(),
        ASKED
    );
    crate::harness::REPLAY_READ_WORST.store(worst, Ordering::Relaxed);
    crate::harness::REPLAY_MOST_SENT.store(most_sent, Ordering::Relaxed);
    semihosting::println!(
        "    paced replay from a full flash store ({} packets, HK area {} sectors; the newest {} asked by time): {} periods ({} skips over pages), at most {} reads each, worst period's reading {} instructions, at most {} packets sent in a period (framed on the board: t_budget); {} instructions in all",
        held,
        store::HK_SECTORS,
        ASKED,
        periods,
        obsw.store_mut().skips,
        store::REPLAY_READS_PER_PERIOD,
        worst,
        most_sent,
        reads_seen
    );
    semihosting::println!(
        "    before (same run): reading this store from its oldest packet, what each period of a paced replay did: {} instructions, {:.1} periods' budget",
        from_oldest,
        from_oldest as f64 / mib::config::PERIOD_INSTRUCTION_BUDGET as f64
    );
    semihosting::println!(
        "    the store's end of a quiet period at the MIB's size (its find_max_fit per area, the pops ahead): at most {} instructions when it freed nothing, {} when it freed ahead",
        end_nothing,
        end_freeing
    );
    check!(worst > 0 && most_sent > 0, "the replay read and sent");
    Ok(())
}

/// A TM packet's length with `data` bytes of source data.
fn p_len(data: usize) -> usize {
    mib_wire::header::MIN_TM_LEN + data
}
