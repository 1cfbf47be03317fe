//! The PUS 15 store in NOR flash, the same code on board A (its flash partition) and on
//! the host (a file of the same size): the store survives a reset, and a reset in the
//! middle of a write loses at most the packet being written.
//!
//! The layout is `sequential-storage`'s queue (item and data CRCs, page states, repair
//! after a cut write, pages used in turn so that erases spread over the area): two
//! queues, one per area of `mib::memory::store`. Periodic housekeeping (TM[3,25]) goes
//! to the HK area, every other packet to the report area. An area that is full gives up
//! its oldest packets, one by one and counted, until its oldest sector is free; the HK
//! area fills first, so periodic HK is overwritten before events and verification.
//!
//! Freeing ahead of need: freeing a sector costs one pop per packet it holds (≈ 40 HK
//! packets), too much for one control period next to its other work. So at the end of a
//! period with few writes ([`TmStore::end_period`], at most
//! `mib::memory::store::FREE_AHEAD_QUIET_WRITES` of them) each area pops up to
//! `FREE_AHEAD_PER_PERIOD` of its oldest packets, counted as overwritten, under one rule:
//! only while the sector after the one being written still holds packets. That sector is
//! the area's oldest, and the next write that does not fit the sector being written has to
//! empty it whole before it can go on: every packet popped ahead is one that write would
//! pop. Popping ahead brings that loss forward by at most one sector's worth of writes, and
//! the area still holds [`FlashStore::min_packets`]' sectors less one; a pop is one item's
//! header cleared, so a reset during it loses nothing else.
//!
//! `sequential-storage` is async; the flashes here are blocking, so every future is
//! ready when first polled and `embassy_futures::block_on` drives it.

use core::cell::RefCell;

use embassy_futures::block_on;
use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use mib::config::MAX_PACKET_LEN;
use mib_wire::header::TmPacket;
use sequential_storage::cache::page_pointers::ArrayPagePointers;
use sequential_storage::cache::page_states::ArrayPageStates;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::queue::{QueueConfig, QueueConfigError, QueueStorage};

use crate::tm::{Skipped, Stretch, TmStore};

/// The store with the MIB's area sizes (board A and the host).
pub type MibFlashStore<'a, F> =
    FlashStore<'a, F, { mib::memory::store::HK_SECTORS }, { mib::memory::store::REPORT_SECTORS }>;

/// One blocking flash shared by the layouts that live on it: the store's two queues (async
/// traits, every future completes when polled) and, on board A, the key and counter area
/// (blocking traits). Each call borrows the flash for its own length only; calls never
/// overlap, so a failed borrow ([`SharedError::Busy`]) is an internal error, refused like a
/// flash error rather than a panic.
pub struct Shared<'a, F>(pub &'a RefCell<F>);

/// A flash error, or the flash already borrowed (cannot happen: calls never overlap).
#[derive(Debug)]
pub enum SharedError<E> {
    Flash(E),
    Busy,
}

impl<E: NorFlashError> NorFlashError for SharedError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            SharedError::Flash(e) => e.kind(),
            SharedError::Busy => NorFlashErrorKind::Other,
        }
    }
}

impl<F: ErrorType> ErrorType for Shared<'_, F> {
    type Error = SharedError<F::Error>;
}

impl<F: ErrorType> Shared<'_, F> {
    fn with<T>(&self, f: impl FnOnce(&mut F) -> Result<T, F::Error>) -> Result<T, SharedError<F::Error>> {
        let mut flash = self.0.try_borrow_mut().map_err(|_| SharedError::Busy)?;
        f(&mut flash).map_err(SharedError::Flash)
    }
}

impl<F: NorFlash> embedded_storage_async::nor_flash::ReadNorFlash for Shared<'_, F> {
    const READ_SIZE: usize = F::READ_SIZE;
    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.with(|f| f.read(offset, bytes))
    }
    fn capacity(&self) -> usize {
        self.0.try_borrow().map_or(0, |f| f.capacity())
    }
}

impl<F: NorFlash> embedded_storage_async::nor_flash::NorFlash for Shared<'_, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.with(|f| f.erase(from, to))
    }
    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.with(|f| f.write(offset, bytes))
    }
}

impl<F: MultiwriteNorFlash> embedded_storage_async::nor_flash::MultiwriteNorFlash for Shared<'_, F> {}

impl<F: ReadNorFlash> ReadNorFlash for Shared<'_, F> {
    const READ_SIZE: usize = F::READ_SIZE;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.with(|f| f.read(offset, bytes))
    }
    fn capacity(&self) -> usize {
        self.0.try_borrow().map_or(0, |f| f.capacity())
    }
}

impl<F: NorFlash> NorFlash for Shared<'_, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.with(|f| f.erase(from, to))
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.with(|f| f.write(offset, bytes))
    }
}

impl<F: MultiwriteNorFlash> MultiwriteNorFlash for Shared<'_, F> {}

/// Bytes at offsets: a file, a memory buffer — what a flash that is not the chip keeps its
/// contents in. [`Nor`] adds the part's rules on top.
pub trait Medium {
    type Error: core::fmt::Debug;
    /// Fills `out` with the bytes from `at`.
    fn read_at(&mut self, at: u32, out: &mut [u8]) -> Result<(), Self::Error>;
    /// Puts `bytes` at `at`, reaching the medium before it returns.
    fn write_at(&mut self, at: u32, bytes: &[u8]) -> Result<(), Self::Error>;
}

/// An access past the end of a medium in RAM.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutOfRange;

/// Bytes in RAM: a test's flash (`Nor::new(&mut bytes[..], len)`).
impl Medium for &mut [u8] {
    type Error = OutOfRange;
    fn read_at(&mut self, at: u32, out: &mut [u8]) -> Result<(), OutOfRange> {
        let a = at as usize;
        let end = a.checked_add(out.len()).ok_or(OutOfRange)?;
        out.copy_from_slice(self.get(a..end).ok_or(OutOfRange)?);
        Ok(())
    }
    fn write_at(&mut self, at: u32, bytes: &[u8]) -> Result<(), OutOfRange> {
        let a = at as usize;
        let end = a.checked_add(bytes.len()).ok_or(OutOfRange)?;
        self.get_mut(a..end).ok_or(OutOfRange)?.copy_from_slice(bytes);
        Ok(())
    }
}

/// The rules of the module's NOR flash (`mib::memory`) over a [`Medium`] of `capacity`
/// bytes — the one definition the host's store file and the QEMU board's flash file
/// share: reads and writes of whole 32-bit words, an erase sets 4 KiB sectors to 0xFF,
/// and a write only clears bits (one that would set a bit is refused, so a layout that
/// relies on more than NOR gives fails here as it would on the chip).
pub struct Nor<M> {
    medium: M,
    capacity: u32,
}

/// Why a [`Nor`] access was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NorError<E> {
    /// The medium refused the read or write.
    Medium(E),
    /// A write that would turn a 0 bit into 1 (NOR flash cannot without an erase).
    SetsBits,
    OutOfBounds,
    NotAligned,
}

impl<E: core::fmt::Debug> NorFlashError for NorError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            NorError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            NorError::NotAligned => NorFlashErrorKind::NotAligned,
            NorError::Medium(_) | NorError::SetsBits => NorFlashErrorKind::Other,
        }
    }
}

const NOR_WORD: u32 = mib::memory::FLASH_WORD;
const NOR_SECTOR: u32 = mib::memory::FLASH_SECTOR;

impl<M: Medium> Nor<M> {
    /// The medium as a flash of `capacity` bytes (whatever it holds is the flash's content).
    pub fn new(medium: M, capacity: u32) -> Self {
        Nor { medium, capacity }
    }

    /// The medium under the rules.
    pub fn medium(&self) -> &M {
        &self.medium
    }

    /// `offset..offset + len` inside the flash and word-aligned.
    fn span(&self, offset: u32, len: usize, unit: u32) -> Result<(), NorError<M::Error>> {
        if !offset.is_multiple_of(unit) || !(len as u32).is_multiple_of(unit) {
            return Err(NorError::NotAligned);
        }
        match u32::try_from(len).ok().and_then(|n| offset.checked_add(n)) {
            Some(end) if end <= self.capacity => Ok(()),
            _ => Err(NorError::OutOfBounds),
        }
    }
}

impl<M: Medium> ErrorType for Nor<M> {
    type Error = NorError<M::Error>;
}

impl<M: Medium> ReadNorFlash for Nor<M> {
    /// The part's reads are word-aligned too (esp-storage without byte-wise reads).
    const READ_SIZE: usize = NOR_WORD as usize;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.span(offset, bytes.len(), NOR_WORD)?;
        self.medium.read_at(offset, bytes).map_err(NorError::Medium)
    }
    fn capacity(&self) -> usize {
        self.capacity as usize
    }
}

impl<M: Medium> NorFlash for Nor<M> {
    const WRITE_SIZE: usize = NOR_WORD as usize;
    const ERASE_SIZE: usize = NOR_SECTOR as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if to < from {
            return Err(NorError::NotAligned);
        }
        self.span(from, (to - from) as usize, NOR_SECTOR)?;
        let erased = [0xFFu8; 256];
        let mut at = from;
        while at < to {
            self.medium.write_at(at, &erased).map_err(NorError::Medium)?;
            at += erased.len() as u32;
        }
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.span(offset, bytes.len(), NOR_WORD)?;
        // Checked a chunk at a time against what the flash holds: only clearing bits.
        let mut now = [0u8; 256];
        for (i, chunk) in bytes.chunks(now.len()).enumerate() {
            let old = &mut now[..chunk.len()];
            self.medium
                .read_at(offset + (i * 256) as u32, old)
                .map_err(NorError::Medium)?;
            if old.iter().zip(chunk).any(|(o, n)| n & !o != 0) {
                return Err(NorError::SetsBits);
            }
        }
        self.medium.write_at(offset, bytes).map_err(NorError::Medium)
    }
}

/// Writing a word again with more bits cleared is what NOR flash does (the part allows
/// it); the check above still refuses any bit set.
impl<M: Medium> MultiwriteNorFlash for Nor<M> {}

type AreaCache<const P: usize> = Cache<ArrayPageStates<P>, ArrayPagePointers<P>, Uncached>;
type Queue<'a, F, const P: usize> = QueueStorage<Shared<'a, F>, AreaCache<P>>;

/// Which area a packet goes to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Area {
    /// Periodic housekeeping, TM[3,25]: overwritten first.
    Hk,
    /// Events, verification and every other report.
    Report,
}

impl Area {
    /// The area of a well-formed TM packet; `None` for anything else (never stored).
    pub fn of(packet: &[u8]) -> Option<Area> {
        use mib_wire::tm::HkReport;
        let p = TmPacket::parse(packet).ok()?;
        Some(
            if (p.service, p.subservice) == (HkReport::SERVICE, HkReport::SUBSERVICE) {
                Area::Hk
            } else {
                Area::Report
            },
        )
    }
}

/// What the store has counted since it was opened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Stored packets overwritten to make room, per area.
    pub hk_overwritten: u32,
    pub report_overwritten: u32,
    /// Packets not stored: not a well-formed TM packet, or the flash refused the write.
    pub not_stored: u32,
    /// Stored items skipped on reading: not a well-formed TM packet, or the flash
    /// refused the read.
    pub unreadable: u32,
}

/// The PUS 15 store over a NOR flash: `H` sectors of HK area from `base`, then `R`
/// sectors of report area, no more than `H`. Both areas are queues of one type, their
/// caches sized for `H`: one copy of the queue's code in an image, not two (12 KB of
/// flash on board A, for the report cache's unused places in RAM).
pub struct FlashStore<'a, F: NorFlash, const H: usize, const R: usize> {
    hk: Queue<'a, F, H>,
    reports: Queue<'a, F, H>,
    hk_len: usize,
    report_len: usize,
    counts: Counts,
    /// Writes since the last end of a period.
    period_writes: u32,
}

/// Why a store could not be opened.
#[derive(Debug, PartialEq, Eq)]
pub enum OpenError {
    /// The areas do not fit the flash's sectors.
    Layout(QueueConfigError),
    /// The flash is smaller than the two areas.
    TooSmall,
}

impl<'a, F: MultiwriteNorFlash, const H: usize, const R: usize> FlashStore<'a, F, H, R> {
    /// Opens the store at `base` of `flash`, keeping what it holds (a cut write is
    /// repaired by the queue on its first use).
    pub fn open(flash: &'a RefCell<F>, base: u32) -> Result<Self, OpenError> {
        const { assert!(R <= H, "the report area's cache is sized for the HK area") };
        let sector = F::ERASE_SIZE as u32;
        let hk_end = base + H as u32 * sector;
        let end = hk_end + R as u32 * sector;
        if flash.try_borrow().map_or(0, |f| f.capacity()) < end as usize {
            return Err(OpenError::TooSmall);
        }
        let hk_cfg = QueueConfig::try_new(base..hk_end).map_err(OpenError::Layout)?;
        let report_cfg = QueueConfig::try_new(hk_end..end).map_err(OpenError::Layout)?;
        let mut s = FlashStore {
            hk: QueueStorage::new(
                Shared(flash),
                hk_cfg,
                Cache::new(ArrayPageStates::new(), ArrayPagePointers::new(), Uncached),
            ),
            reports: QueueStorage::new(
                Shared(flash),
                report_cfg,
                Cache::new(ArrayPageStates::new(), ArrayPagePointers::new(), Uncached),
            ),
            hk_len: 0,
            report_len: 0,
            counts: Counts::default(),
            period_writes: 0,
        };
        s.hk_len = count(&mut s.hk);
        s.report_len = count(&mut s.reports);
        Ok(s)
    }

    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// Packets held per area.
    pub fn lens(&self) -> (usize, usize) {
        (self.hk_len, self.report_len)
    }

    /// Packets of the largest TM one area of `sectors` sectors holds at least (a sector
    /// loses what does not fit at its end; the oldest sector is freed before reuse).
    pub fn min_packets(sectors: usize, packet_len: usize) -> usize {
        let word = F::WRITE_SIZE.max(F::READ_SIZE);
        let item = Queue::<F, 1>::item_overhead_size() as usize + packet_len.next_multiple_of(word);
        let per_sector = (F::ERASE_SIZE - 2 * word) / item;
        per_sector * (sectors - 1)
    }
}

/// Counts the packets of one queue (at opening).
fn count<F: MultiwriteNorFlash, const P: usize>(q: &mut Queue<'_, F, P>) -> usize {
    let mut n = 0;
    let mut buf = [0u8; MAX_PACKET_LEN];
    if let Ok(mut it) = block_on(q.iter()) {
        while let Ok(Some(_)) = block_on(it.next(&mut buf)) {
            n += 1;
        }
    }
    n
}

/// Stores `packet` in `q`, giving up the oldest packets until it fits; returns how many
/// were given up, or `None` if the packet could not be stored.
fn push<F: MultiwriteNorFlash, const P: usize>(q: &mut Queue<'_, F, P>, len: &mut usize, packet: &[u8]) -> Option<u32> {
    let mut dropped = 0u32;
    // A sector holds at most this many packets; more pops than that means the flash
    // refuses to free one, and the write is given up.
    let bound = F::ERASE_SIZE as u32 / Queue::<F, P>::item_overhead_size() + 1;
    loop {
        match block_on(q.push(packet, false)) {
            Ok(()) => {
                *len += 1;
                return Some(dropped);
            }
            Err(sequential_storage::Error::FullStorage) if dropped <= bound => {
                let mut buf = [0u8; MAX_PACKET_LEN];
                match block_on(q.pop(&mut buf)) {
                    Ok(Some(_)) => {
                        dropped += 1;
                        *len = len.saturating_sub(1);
                    }
                    Ok(None) | Err(_) => return None,
                }
            }
            Err(_) => return None,
        }
    }
}

/// Pops up to `most` of the oldest packets of `q` while the page after the one being
/// written holds live data (the packets the next page change would pop anyway, see the
/// module's description); returns how many.
fn free_ahead<F: MultiwriteNorFlash, const P: usize>(q: &mut Queue<'_, F, P>, len: &mut usize, most: u32) -> u32 {
    // `find_max_fit` says a whole page fits exactly when the next page is free.
    let word = F::WRITE_SIZE.max(F::READ_SIZE);
    let free_page = (F::ERASE_SIZE - 2 * word) as u32;
    let mut popped = 0;
    while popped < most {
        match block_on(q.find_max_fit()) {
            Ok(Some(n)) if n >= free_page => break,
            Ok(_) => {}
            Err(_) => break,
        }
        let mut buf = [0u8; MAX_PACKET_LEN];
        match block_on(q.pop(&mut buf)) {
            Ok(Some(_)) => {
                popped += 1;
                *len = len.saturating_sub(1);
            }
            Ok(None) | Err(_) => break,
        }
    }
    popped
}

/// A stored packet as a visit reads it: its length, time stamp, sequence count and the
/// address of its item.
#[derive(Clone, Copy)]
struct Read {
    len: usize,
    stamp: Stamp,
    apid: u16,
    seq: u16,
    address: u32,
}

impl Read {
    fn mark(&self) -> AreaMark {
        AreaMark {
            address: self.address,
            stamp: self.stamp,
            apid: self.apid,
            seq: self.seq,
        }
    }
}

/// The next well-formed packet of an iteration into `buf`, or `None` at the end (a read
/// error ends the iteration, counted).
fn next_packet<F: MultiwriteNorFlash, const P: usize>(
    it: &mut sequential_storage::queue::QueueIterator<'_, Shared<'_, F>, AreaCache<P>>,
    buf: &mut [u8; MAX_PACKET_LEN],
    unreadable: &mut u32,
) -> Option<Read> {
    loop {
        match block_on(it.next(buf)) {
            Ok(Some(e)) => {
                let address = e.address();
                let len = e.into_buf().len();
                if let Some((stamp, apid, seq)) = stored_id(&buf[..len]) {
                    return Some(Read {
                        len,
                        stamp,
                        apid,
                        seq,
                        address,
                    });
                }
                *unreadable = unreadable.wrapping_add(1);
            }
            Ok(None) => return None,
            Err(_) => {
                *unreadable = unreadable.wrapping_add(1);
                return None;
            }
        }
    }
}

/// An iteration of an area (`$q`) after the packet `$after` marks, with its first packet
/// read into `$buf`: from that item's address when the packet read there is still the
/// marked one, else from the oldest packet (the marked one was popped, and every older one
/// before it). A macro, not a function: a function returning the iterator of one of two
/// borrows of the queue does not pass the borrow checker.
macro_rules! resume {
    ($q:expr, $after:expr, $buf:expr, $unreadable:expr) => {{
        let mut resumed = None;
        if let Some(m) = $after {
            if let Ok(Some(mut it)) = block_on($q.iter_from(m.address)) {
                if next_packet(&mut it, $buf, $unreadable).is_some_and(|r| r.mark() == m) {
                    resumed = Some(it);
                }
            }
        }
        let mut it = match resumed {
            Some(it) => Some(it),
            None => block_on($q.iter()).ok(),
        };
        let first = it.as_mut().and_then(|i| next_packet(i, $buf, $unreadable));
        (it, first)
    }};
}

/// The packet stored at `address` (or the first well-formed one after it), when an item
/// of the queue begins there.
fn read_at<F: MultiwriteNorFlash, const P: usize>(
    q: &mut Queue<'_, F, P>,
    address: u32,
    unreadable: &mut u32,
) -> Option<Read> {
    let mut buf = [0u8; MAX_PACKET_LEN];
    let mut it = block_on(q.iter_from(address)).ok().flatten()?;
    next_packet(&mut it, &mut buf, unreadable)
}

/// The first packet of the page after the one holding `address`, while that page is
/// younger (`QueueStorage::next_page_start`).
fn next_page_first<F: MultiwriteNorFlash, const P: usize>(
    q: &mut Queue<'_, F, P>,
    address: u32,
    unreadable: &mut u32,
) -> Option<Read> {
    let start = block_on(q.next_page_start(address)).ok().flatten()?;
    read_at(q, start, unreadable)
}

/// Most packets one sector of an area holds: items of the smallest TM packet.
fn page_items<F: NorFlash>() -> usize {
    let word = F::WRITE_SIZE.max(F::READ_SIZE);
    let item = Queue::<F, 1>::item_overhead_size() as usize + mib_wire::header::MIN_TM_LEN.next_multiple_of(word);
    (F::ERASE_SIZE - 2 * word) / item
}

/// Where a skip ([`TmStore::skip`]) stands in one area.
#[derive(Clone, Copy)]
struct Walk {
    /// The last packet ruled out, and every one before it; `None`: the walk stands before
    /// the area's oldest packet.
    cur: Option<Read>,
    /// Time stamp of the first packet of `cur`'s page: the area's packets from `cur` on
    /// are in that page or later ones (`cur`'s own stamp when the first is unreadable).
    page_start: Option<Stamp>,
    /// The first packet of the next page (the oldest packet while `cur` is `None`); `None`:
    /// the area ends in `cur`'s page.
    next: Option<Read>,
    /// Page starts of the other area passed by the walk with a time stamp at or after
    /// `cur`'s; `None`: not known (the other area's walk stood ahead of this one).
    others: Option<usize>,
}

impl Walk {
    /// The walk of an area from the packet `m` marks: before the oldest packet for `None`
    /// or when that packet is no longer stored (as a visit goes on, [`resume`]). Reads up
    /// to three packets.
    fn start<F: MultiwriteNorFlash, const P: usize>(
        q: &mut Queue<'_, F, P>,
        m: Option<AreaMark>,
        m_next: Option<AreaMark>,
        reads: &mut usize,
        unreadable: &mut u32,
    ) -> Walk {
        // Going on from a skip that stopped on a page's first packet: its next page's first
        // packet, read again, says the area still holds what lies between.
        if let (Some(m), Some(nm)) = (m, m_next) {
            *reads += 1;
            if let Some(n) = read_at(q, nm.address, unreadable).filter(|r| r.mark() == nm) {
                let cur = Read {
                    len: 0,
                    stamp: m.stamp,
                    apid: m.apid,
                    seq: m.seq,
                    address: m.address,
                };
                return Walk {
                    cur: Some(cur),
                    page_start: Some(m.stamp),
                    next: Some(n),
                    others: None,
                };
            }
        }
        let cur = m.and_then(|m| {
            *reads += 1;
            read_at(q, m.address, unreadable).filter(|r| r.mark() == m)
        });
        let Some(c) = cur else {
            *reads += 1;
            let mut buf = [0u8; MAX_PACKET_LEN];
            let next = block_on(q.iter())
                .ok()
                .and_then(|mut it| next_packet(&mut it, &mut buf, unreadable));
            return Walk {
                cur: None,
                page_start: None,
                next,
                others: None,
            };
        };
        let word = F::WRITE_SIZE.max(F::READ_SIZE) as u32;
        let (base, sector) = (q.flash_range().start, F::ERASE_SIZE as u32);
        let first = base + (c.address - base) / sector * sector + word;
        let page_start = if first == c.address {
            Some(c.stamp)
        } else {
            *reads += 1;
            read_at(q, first, unreadable)
                .filter(|r| r.stamp <= c.stamp)
                .map_or(Some(c.stamp), |r| Some(r.stamp))
        };
        *reads += 1;
        Walk {
            cur,
            page_start,
            next: next_page_first(q, c.address, unreadable),
            others: None,
        }
    }

    fn cur_stamp(&self) -> Option<Stamp> {
        self.cur.map(|c| c.stamp)
    }

    /// The next page's first packet, when `cur` is its page's first (what
    /// [`Walk::start`] can go on from).
    fn next_of_page_start(&self) -> Option<AreaMark> {
        let c = self.cur?;
        (self.page_start == Some(c.stamp))
            .then_some(self.next)
            .flatten()
            .map(|n| n.mark())
    }

    /// The stretch from `cur` to `next` (the rest of `cur`'s page and the next page's first
    /// packet); `None` when time went back between them (no order to rely on).
    fn stretch<F: NorFlash>(&self, n: Read) -> Option<Stretch> {
        let Some(c) = self.cur else {
            // The oldest packet alone.
            return Some(Stretch {
                apid: n.apid,
                from: n.stamp,
                to: n.stamp,
                seqs: Some((n.seq, n.seq)),
            });
        };
        if n.stamp < c.stamp {
            return None;
        }
        // The stream's packets between them: this area's (one page and `n`) and the other
        // area's stamped between them, which lie in its page at `cur`'s time, the page
        // starts it passed after that time and one more (a page starting at the same
        // time stamp). Fewer than 2^14 of them: the counts between did not wrap, and the
        // count from `c` to `n` is exact.
        let seqs = self.others.and_then(|k| {
            let most = page_items::<F>() + 1 + (k + 2) * page_items::<F>();
            use mib::headers::SeqCount;
            let d = usize::from(SeqCount::new(n.seq).since(SeqCount::new(c.seq)));
            let modulus = usize::from(SeqCount::MODULUS);
            (c.apid == n.apid && most < modulus && d <= most).then_some((c.seq, n.seq))
        });
        Some(Stretch {
            apid: n.apid,
            from: c.stamp,
            to: n.stamp,
            seqs,
        })
    }
}

/// A CDS time stamp (days, ms of day), ordering the two areas on reading.
type Stamp = (u16, u32);

/// The time stamp and sequence count of a stored TM packet from its headers; `None` for
/// bytes that are not a TM packet of their length. The packet's own CRC is not computed
/// again: the store takes only packets [`Area::of`] checked, and the queue's CRC-32 of each
/// item proves that it reads back as it was written (half of a replay's reading per packet,
/// measured on the target: `t_store` in firmware/qemu-tests).
fn stored_id(p: &[u8]) -> Option<(Stamp, u16, u16)> {
    use mib_wire::header::{check_primary, PRIMARY_HEADER_LEN, TM_SEC_HEADER_LEN};
    let h = check_primary(p).ok()?;
    if h.is_tc || h.len != p.len() {
        return None;
    }
    let at = PRIMARY_HEADER_LEN + TM_SEC_HEADER_LEN;
    let t = p.get(at..at + mib::config::TIMESTAMP_LEN)?;
    Some((
        (
            u16::from_be_bytes([t[1], t[2]]),
            u32::from_be_bytes([t[3], t[4], t[5], t[6]]),
        ),
        h.apid,
        h.seq_count,
    ))
}

/// Where a visit of one area stands: the item of the last packet taken (its address, and
/// its time stamp and sequence count, to know it is still that packet).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AreaMark {
    address: u32,
    stamp: Stamp,
    apid: u16,
    seq: u16,
}

/// Where a visit of the store stands: the last packet taken from each area.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mark {
    hk: Option<AreaMark>,
    report: Option<AreaMark>,
    /// Page starts of the other area a skip saw after each area's marked packet
    /// ([`Walk::others`]), for the next skip to go on with; a visit forgets them.
    hk_others: Option<u16>,
    report_others: Option<u16>,
    /// The first packet of each area's next page, when a skip left the area's mark on the
    /// first packet of a page: the next skip reads it again (to know it is still there)
    /// instead of the marked packet and the page's start.
    hk_next: Option<AreaMark>,
    report_next: Option<AreaMark>,
}

impl<F: MultiwriteNorFlash, const H: usize, const R: usize> TmStore for FlashStore<'_, F, H, R> {
    type Mark = Mark;
    /// A packet read costs its CRC-32 (`mib::memory::store::REPLAY_READS_PER_PERIOD`).
    const READS_PER_PERIOD: usize = mib::memory::store::REPLAY_READS_PER_PERIOD as usize;
    fn push(&mut self, packet: &[u8]) -> u32 {
        self.period_writes = self.period_writes.saturating_add(1);
        let stored = match Area::of(packet) {
            Some(Area::Hk) => push(&mut self.hk, &mut self.hk_len, packet).map(|n| (n, 0)),
            Some(Area::Report) => push(&mut self.reports, &mut self.report_len, packet).map(|n| (0, n)),
            None => None,
        };
        match stored {
            Some((hk, report)) => {
                self.counts.hk_overwritten = self.counts.hk_overwritten.wrapping_add(hk);
                self.counts.report_overwritten = self.counts.report_overwritten.wrapping_add(report);
                hk + report
            }
            None => {
                self.counts.not_stored = self.counts.not_stored.wrapping_add(1);
                1
            }
        }
    }

    /// Frees ahead of need in a period with few writes (the module's description).
    fn end_period(&mut self) -> u32 {
        use mib::memory::store::{FREE_AHEAD_PER_PERIOD, FREE_AHEAD_QUIET_WRITES};
        let quiet = self.period_writes <= FREE_AHEAD_QUIET_WRITES;
        self.period_writes = 0;
        if !quiet {
            return 0;
        }
        let hk = free_ahead(&mut self.hk, &mut self.hk_len, FREE_AHEAD_PER_PERIOD);
        let report = free_ahead(&mut self.reports, &mut self.report_len, FREE_AHEAD_PER_PERIOD);
        self.counts.hk_overwritten = self.counts.hk_overwritten.wrapping_add(hk);
        self.counts.report_overwritten = self.counts.report_overwritten.wrapping_add(report);
        hk + report
    }

    /// Both areas merged by time stamp, oldest first.
    fn visit(&mut self, f: &mut dyn FnMut(&[u8])) {
        self.visit_after(None, usize::MAX, &mut |p, _| {
            f(p);
            true
        });
    }

    /// Each area goes on from the item of the last packet taken from it
    /// ([`QueueStorage::iter_from`](sequential_storage::queue::QueueStorage::iter_from)):
    /// a call reads at most `most` packets and the next one of each area, never the
    /// packets before the mark again.
    fn visit_after(&mut self, after: Option<Mark>, most: usize, f: &mut dyn FnMut(&[u8], Mark) -> bool) -> bool {
        let mut unreadable = 0;
        let mut mark = after.unwrap_or_default();
        (mark.hk_others, mark.report_others) = (None, None);
        (mark.hk_next, mark.report_next) = (None, None);
        let (mut ha, mut ra) = ([0u8; MAX_PACKET_LEN], [0u8; MAX_PACKET_LEN]);
        let (mut hk_it, mut h) = resume!(self.hk, mark.hk, &mut ha, &mut unreadable);
        let (mut report_it, mut r) = resume!(self.reports, mark.report, &mut ra, &mut unreadable);
        let mut called = 0;
        let ended = loop {
            let hk_first = match (h, r) {
                (None, None) => break true,
                (Some(_), None) => true,
                (None, Some(_)) => false,
                (Some(a), Some(b)) => a.stamp <= b.stamp,
            };
            if called == most {
                break false;
            }
            called += 1;
            if hk_first {
                let Some(p) = h else { break true };
                mark.hk = Some(p.mark());
                if !f(&ha[..p.len], mark) {
                    break false;
                }
                h = hk_it.as_mut().and_then(|i| next_packet(i, &mut ha, &mut unreadable));
            } else {
                let Some(p) = r else { break true };
                mark.report = Some(p.mark());
                if !f(&ra[..p.len], mark) {
                    break false;
                }
                r = report_it
                    .as_mut()
                    .and_then(|i| next_packet(i, &mut ra, &mut unreadable));
            }
        };
        self.counts.unreadable = self.counts.unreadable.wrapping_add(unreadable);
        ended
    }

    /// Both areas walk page by page ([`QueueStorage::next_page_start`]: one packet read per
    /// page, the page's first), the one whose next page starts first going on, while
    /// `excludes` rules out the stretch to that page's first packet; the mark moves there.
    /// A stretch's sequence counts are given only when they cannot have wrapped: the other
    /// area's packets in its time span are bounded by the pages of it the walk saw start.
    /// Assumes what the store's time order already does: time stamps that do not go back,
    /// and one TM stream whose every packet is stored while the store is enabled.
    fn skip(&mut self, after: Option<Mark>, most: usize, excludes: &mut dyn FnMut(&Stretch) -> bool) -> Skipped<Mark> {
        /// Reads of [`Walk::start`] for both areas, at most (two when going on from a
        /// skip).
        const START_READS: usize = 6;
        // Page reads cost more than reads on (`mib::memory::store::PAGE_READ_COST`).
        let (cost, per) = mib::memory::store::PAGE_READ_COST;
        let most = most.saturating_mul(per) / cost;
        if most < START_READS {
            return Skipped {
                after,
                reads: 0,
                done: false,
            };
        }
        let (mut reads, mut unreadable) = (0usize, 0u32);
        let mut mark = after.unwrap_or_default();
        let mut hk = Walk::start(&mut self.hk, mark.hk, mark.hk_next, &mut reads, &mut unreadable);
        let mut rp = Walk::start(
            &mut self.reports,
            mark.report,
            mark.report_next,
            &mut reads,
            &mut unreadable,
        );
        // What the last skip saw, else what the walks' places tell.
        hk.others = mark
            .hk_others
            .map(usize::from)
            .or((rp.page_start.or(rp.cur_stamp()) <= hk.cur_stamp()).then_some(0));
        rp.others = mark
            .report_others
            .map(usize::from)
            .or((hk.page_start.or(hk.cur_stamp()) <= rp.cur_stamp()).then_some(0));
        let mut moved = false;
        let done = loop {
            if reads >= most {
                break false;
            }
            let hk_first = match (hk.next, rp.next) {
                (None, None) => break true,
                (Some(_), None) => true,
                (None, Some(_)) => false,
                (Some(a), Some(b)) => a.stamp <= b.stamp,
            };
            let (x, y) = if hk_first {
                (&mut hk, &mut rp)
            } else {
                (&mut rp, &mut hk)
            };
            let Some(n) = x.next else { break true };
            let Some(stretch) = x.stretch::<F>(n) else { break true };
            if !excludes(&stretch) {
                break true;
            }
            x.cur = Some(n);
            x.page_start = Some(n.stamp);
            reads += 1;
            x.next = if hk_first {
                mark.hk = Some(n.mark());
                next_page_first(&mut self.hk, n.address, &mut unreadable)
            } else {
                mark.report = Some(n.mark());
                next_page_first(&mut self.reports, n.address, &mut unreadable)
            };
            x.others = (y.page_start.or(y.cur_stamp()) <= Some(n.stamp)).then_some(0);
            if y.cur_stamp() <= Some(n.stamp) {
                y.others = y.others.map(|k| k + 1);
            }
            moved = true;
        };
        self.counts.unreadable = self.counts.unreadable.wrapping_add(unreadable);
        let known = |w: &Walk| w.others.and_then(|k| u16::try_from(k).ok());
        (mark.hk_others, mark.report_others) = (known(&hk), known(&rp));
        (mark.hk_next, mark.report_next) = (hk.next_of_page_start(), rp.next_of_page_start());
        Skipped {
            after: if moved { Some(mark) } else { after },
            reads: reads.saturating_mul(cost).div_ceil(per),
            done,
        }
    }

    fn len(&self) -> usize {
        self.hk_len + self.report_len
    }

    fn clear(&mut self) {
        let hk = block_on(self.hk.erase_all());
        let reports = block_on(self.reports.erase_all());
        self.hk_len = if hk.is_ok() { 0 } else { count(&mut self.hk) };
        self.report_len = if reports.is_ok() { 0 } else { count(&mut self.reports) };
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::time::OnboardTime;
    use crate::tm::TmWriter;
    use embedded_storage::nor_flash::{ErrorType, ReadNorFlash};
    use mib::memory::store;

    impl Medium for Vec<u8> {
        type Error = ();
        fn read_at(&mut self, at: u32, out: &mut [u8]) -> Result<(), ()> {
            out.copy_from_slice(self.get(at as usize..at as usize + out.len()).ok_or(())?);
            Ok(())
        }
        fn write_at(&mut self, at: u32, bytes: &[u8]) -> Result<(), ()> {
            self.get_mut(at as usize..at as usize + bytes.len())
                .ok_or(())?
                .copy_from_slice(bytes);
            Ok(())
        }
    }

    // verifies: PUS-15-05
    #[test]
    fn the_nor_rules_erase_to_ff_and_writes_only_clear_bits() {
        let mut f = Nor::new(vec![0u8; 8192], 8192);
        // The medium's bytes are the flash's content: 0, so nothing can be set before an erase.
        assert_eq!(f.write(0, &[0xFF; 4]), Err(NorError::SetsBits));
        f.erase(0, 4096).unwrap();
        let mut b = [0u8; 4];
        f.read(0, &mut b).unwrap();
        assert_eq!(b, [0xFF; 4]);
        assert_eq!(f.medium()[4096], 0, "only the sector asked for");
        f.write(0, &[0xF0, 0x0F, 0xFF, 0x00]).unwrap();
        f.write(0, &[0x00, 0x0F, 0xFF, 0x00]).unwrap();
        assert_eq!(f.write(0, &[0x01, 0x0F, 0xFF, 0x00]), Err(NorError::SetsBits));
        assert_eq!(f.write(2, &[0; 4]), Err(NorError::NotAligned));
        assert_eq!(f.read(0, &mut [0; 3]), Err(NorError::NotAligned));
        assert_eq!(f.write(8192, &[0; 4]), Err(NorError::OutOfBounds));
        assert_eq!(f.erase(100, 4096), Err(NorError::NotAligned));
        assert_eq!(f.erase(4096, 12288), Err(NorError::OutOfBounds));
    }

    /// A NOR flash in RAM: erase sets 0xFF, a write only clears bits (a write that
    /// would set one is refused and counted), erases are counted per sector, and a power
    /// cut after a budget of written bytes stops everything there.
    #[derive(Clone)]
    pub struct TestFlash {
        pub mem: Vec<u8>,
        pub erases: Vec<u32>,
        /// Bytes (and erases) still allowed before the power goes; `None`: no cut.
        pub budget: Option<usize>,
        pub cut: bool,
        pub bit_sets: u32,
        /// Bytes read so far.
        pub read_bytes: u64,
    }

    #[derive(Debug)]
    pub enum TestError {
        PowerCut,
        SetsBits,
        Range,
    }

    impl NorFlashError for TestError {
        fn kind(&self) -> NorFlashErrorKind {
            match self {
                TestError::Range => NorFlashErrorKind::OutOfBounds,
                TestError::PowerCut | TestError::SetsBits => NorFlashErrorKind::Other,
            }
        }
    }

    impl TestFlash {
        pub fn new(sectors: usize) -> Self {
            TestFlash {
                mem: vec![0xFF; sectors * 4096],
                erases: vec![0; sectors],
                budget: None,
                cut: false,
                bit_sets: 0,
                read_bytes: 0,
            }
        }
        /// Takes one unit of the budget; false once the power is cut.
        fn spend(&mut self) -> bool {
            match self.budget.as_mut() {
                _ if self.cut => false,
                Some(0) => {
                    self.cut = true;
                    false
                }
                Some(b) => {
                    *b -= 1;
                    true
                }
                None => true,
            }
        }
    }

    impl ErrorType for TestFlash {
        type Error = TestError;
    }

    impl ReadNorFlash for TestFlash {
        const READ_SIZE: usize = 1;
        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), TestError> {
            if self.cut {
                return Err(TestError::PowerCut);
            }
            let at = offset as usize;
            bytes.copy_from_slice(self.mem.get(at..at + bytes.len()).ok_or(TestError::Range)?);
            self.read_bytes += bytes.len() as u64;
            Ok(())
        }
        fn capacity(&self) -> usize {
            self.mem.len()
        }
    }

    impl NorFlash for TestFlash {
        const WRITE_SIZE: usize = store::WORD_USIZE;
        const ERASE_SIZE: usize = 4096;
        fn erase(&mut self, from: u32, to: u32) -> Result<(), TestError> {
            for s in from / 4096..to / 4096 {
                if !self.spend() {
                    return Err(TestError::PowerCut);
                }
                let s = s as usize;
                self.mem
                    .get_mut(s * 4096..(s + 1) * 4096)
                    .ok_or(TestError::Range)?
                    .fill(0xFF);
                self.erases[s] += 1;
            }
            Ok(())
        }
        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), TestError> {
            let at = offset as usize;
            if self.mem.get(at..at + bytes.len()).is_none() {
                return Err(TestError::Range);
            }
            for (i, b) in bytes.iter().enumerate() {
                if !self.spend() {
                    return Err(TestError::PowerCut);
                }
                let cell = &mut self.mem[at + i];
                if *b & !*cell != 0 {
                    self.bit_sets += 1;
                    return Err(TestError::SetsBits);
                }
                *cell &= *b;
            }
            Ok(())
        }
    }

    impl MultiwriteNorFlash for TestFlash {}

    /// 3 HK sectors and 2 report sectors.
    type Small<'a> = FlashStore<'a, TestFlash, 3, 2>;

    fn open(f: &RefCell<TestFlash>) -> Small<'_> {
        Small::open(f, 0).expect("layout fits")
    }

    /// `n` TM packets: every third an event, the rest periodic HK of `hk_len` bytes of data.
    fn packets(n: usize, hk_len: usize) -> Vec<Vec<u8>> {
        packets_every(n, hk_len, 3)
    }

    /// `n` TM packets: every `every`th an event, the rest periodic HK.
    fn packets_every(n: usize, hk_len: usize, every: usize) -> Vec<Vec<u8>> {
        let mut w = TmWriter::new(0x101, OnboardTime::new(1_790_000_000_000));
        let mut buf = [0u8; MAX_PACKET_LEN];
        (0..n)
            .map(|i| {
                let event = i % every == every - 1;
                let data = vec![i as u8; if event { 12 } else { hk_len }];
                let (svc, sub) = if event { (5, 1) } else { (3, 25) };
                let len = w.build(1000 * i as u64, svc, sub, &data, &mut buf).expect("fits");
                buf[..len].to_vec()
            })
            .collect()
    }

    fn content(s: &mut impl TmStore) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        s.visit(&mut |p| out.push(p.to_vec()));
        out
    }

    // verifies: PUS-15-03
    #[test]
    fn the_store_keeps_its_packets_across_a_reopen_in_time_order() {
        let f = RefCell::new(TestFlash::new(5));
        let pkts = packets(60, 40);
        let mut s = open(&f);
        for p in &pkts {
            assert_eq!(s.push(p), 0);
        }
        assert_eq!(content(&mut s), pkts, "HK and events merged back in time order");
        // A reset: a new store over the same flash.
        let mut s = open(&f);
        assert_eq!(s.len(), 60);
        assert_eq!(content(&mut s), pkts, "the same after a reset");
        s.clear();
        assert_eq!((s.len(), content(&mut s).len()), (0, 0));
        assert_eq!(f.borrow().bit_sets, 0, "the layout never sets a bit without an erase");
    }

    // verifies: PUS-15-09
    #[test]
    fn a_paced_visit_goes_on_from_its_mark_reading_a_bounded_slice_across_writes_and_overwrites() {
        // 16 sectors; every 10th packet an event. Each period: some writes, then a visit of
        // at most MOST packets after the mark, beside the reference (the store's whole
        // content, the first MOST packets written after the last one taken).
        const MOST: usize = 5;
        type Mid<'a> = FlashStore<'a, TestFlash, 12, 4>;
        let f = RefCell::new(TestFlash::new(16));
        let mut s = Mid::open(&f, 0).expect("layout fits");
        let pkts = packets_every(4000, 60, 10);
        let index = |p: &[u8]| pkts.iter().position(|q| q == p).expect("a packet written");
        let (mut next, mut mark, mut last) = (0, None, None::<usize>);
        let (mut taken, mut jumps, mut most_read, mut whole_read) = (0, 0, 0, 0);
        // Fast writes first (the marked packet overwritten before the visit goes on), then
        // slow ones (the visit catches up with the newest).
        for period in 0..1000 {
            let writes = if period < 300 { 9 } else { 3 };
            for _ in 0..writes {
                if next < pkts.len() {
                    s.push(&pkts[next]);
                    next += 1;
                }
            }
            let before = f.borrow().read_bytes;
            let all = content(&mut s);
            whole_read = whole_read.max(f.borrow().read_bytes - before);
            let expected: Vec<usize> = all
                .iter()
                .map(|p| index(p))
                .filter(|&i| last.is_none_or(|l| i > l))
                .take(MOST)
                .collect();
            let mut got = Vec::new();
            let before = f.borrow().read_bytes;
            let ended = s.visit_after(mark, MOST, &mut |p, m| {
                got.push(index(p));
                mark = Some(m);
                true
            });
            most_read = most_read.max(f.borrow().read_bytes - before);
            assert_eq!(got, expected, "period {period}");
            assert_eq!(
                ended,
                expected.len() < MOST || all.last().is_some_and(|p| Some(index(p)) == got.last().copied())
            );
            if let (Some(l), Some(&g)) = (last, got.first()) {
                jumps += usize::from(g > l + 1);
            }
            taken += got.len();
            last = got.last().copied().or(last);
        }
        assert_eq!(last, Some(pkts.len() - 1), "the visits reached the newest packet");
        assert!(
            jumps > 10 && taken < pkts.len(),
            "marked packets were overwritten ({jumps} jumps)"
        );
        assert_eq!(s.counts().unreadable, 0);
        // A visit reads its slice, its mark's packets again and the page headers up to them,
        // not the store from its oldest packet.
        println!("bytes read: a paced visit at most {most_read}, the whole store {whole_read}");
        assert!(
            most_read < 2 * 4096 && whole_read > 8 * most_read,
            "{most_read} {whole_read}"
        );
    }

    // verifies: PUS-15-08
    #[test]
    fn freeing_ahead_gives_up_only_packets_the_next_writes_would_and_spares_them_the_pops() {
        // The same packets into two stores: `ahead` with quiet periods (one write each),
        // `plain` never told a period ended.
        let (fa, fp) = (RefCell::new(TestFlash::new(5)), RefCell::new(TestFlash::new(5)));
        let (mut ahead, mut plain) = (open(&fa), open(&fp));
        let pkts = packets_every(900, 60, 10);
        let (mut lost_ahead, mut lost_plain, mut most_in_a_push) = (0, 0, 0);
        let mut gone_from_plain_at = std::collections::HashMap::new();
        let mut popped_ahead_at = Vec::new();
        for (i, p) in pkts.iter().enumerate() {
            let a = ahead.push(p);
            most_in_a_push = most_in_a_push.max(a);
            lost_ahead += a;
            let before = content(&mut plain);
            lost_plain += plain.push(p);
            let after = content(&mut plain);
            for q in before.iter().filter(|q| !after.contains(q)) {
                gone_from_plain_at.insert(q.clone(), i);
            }
            let held = content(&mut ahead);
            let n = ahead.end_period();
            assert!(n <= 2 * mib::memory::store::FREE_AHEAD_PER_PERIOD);
            lost_ahead += n;
            let now = content(&mut ahead);
            for area in [Area::Hk, Area::Report] {
                let of = |c: &[Vec<u8>]| -> Vec<Vec<u8>> {
                    c.iter().filter(|q| Area::of(q) == Some(area)).cloned().collect()
                };
                let (held, now, after) = (of(&held), of(&now), of(&after));
                // Only an area's oldest packets go, never its newest.
                assert!(held.ends_with(&now));
                popped_ahead_at.extend(held[..held.len() - now.len()].iter().map(|q| (q.clone(), i)));
                // What `ahead` holds is what `plain` holds less some of its oldest.
                assert!(after.ends_with(&now), "at packet {i}");
            }
        }
        assert!(
            lost_plain > 100 && most_in_a_push == 0,
            "no write had to free a sector itself"
        );
        assert_eq!(
            ahead.counts().hk_overwritten + ahead.counts().report_overwritten,
            lost_ahead
        );
        // Every packet popped ahead, `plain` gave up too, within a sector's worth of writes
        // into its area.
        let area_writes = |i: usize, q: &[u8]| pkts[..=i].iter().filter(|p| Area::of(p) == Area::of(q)).count();
        let mut checked = 0;
        for (q, at) in popped_ahead_at {
            let per_sector = Small::min_packets(2, q.len());
            let at = area_writes(at, &q);
            let gone = gone_from_plain_at
                .get(&q)
                .map_or(area_writes(pkts.len() - 1, &q) + 1, |&g| area_writes(g, &q));
            assert!(
                gone >= at && gone - at <= per_sector + 1,
                "popped at {at}, gone at {gone}"
            );
            checked += 1;
        }
        assert!(checked > 100, "{checked}");
    }

    // verifies: PUS-15-04
    #[test]
    fn a_full_store_overwrites_periodic_hk_first_and_counts_each_packet() {
        let f = RefCell::new(TestFlash::new(5));
        let mut s = open(&f);
        let pkts = packets_every(600, 60, 10);
        let mut lost = 0;
        for p in &pkts {
            lost += s.push(p);
        }
        let kept = content(&mut s);
        let events: Vec<_> = pkts
            .iter()
            .filter(|p| Area::of(p) == Some(Area::Report))
            .cloned()
            .collect();
        let hk_kept = kept.iter().filter(|p| Area::of(p) == Some(Area::Hk)).count();
        // 60 events of 34 bytes fit the report area; 540 HK of 82 bytes do not fit 3 sectors.
        assert!(
            kept.iter()
                .filter(|p| Area::of(p) == Some(Area::Report))
                .eq(events.iter()),
            "every event kept"
        );
        assert!(hk_kept < 540 && hk_kept > 80, "HK kept: {hk_kept}");
        let c = s.counts();
        assert_eq!(
            c.hk_overwritten as usize,
            540 - hk_kept,
            "each overwritten HK packet counted"
        );
        assert_eq!((c.report_overwritten, c.not_stored), (0, 0));
        assert_eq!(lost, c.hk_overwritten);
        assert_eq!(s.len(), kept.len());
        // What is kept is the newest HK, in order.
        let hk: Vec<_> = pkts.iter().filter(|p| Area::of(p) == Some(Area::Hk)).cloned().collect();
        let hk_kept_pkts: Vec<_> = kept.iter().filter(|p| Area::of(p) == Some(Area::Hk)).cloned().collect();
        assert_eq!(hk_kept_pkts, hk[540 - hk_kept..]);
    }

    // verifies: PUS-15-05
    #[test]
    fn a_power_cut_at_any_byte_of_a_write_loses_at_most_that_packet() {
        // Start from a store whose HK area is one packet from full, so that the writes
        // under test also free and erase a sector (the overwrite path).
        let pkts = packets(220, 60);
        let base = RefCell::new(TestFlash::new(5));
        let (mut pre, mut next) = (Vec::new(), 0);
        {
            let mut s = open(&base);
            while next < pkts.len() - 12 {
                if s.push(&pkts[next]) > 0 {
                    break;
                }
                pre.push(next);
                next += 1;
            }
        }
        // Restart from just before the first overwrite.
        let base = RefCell::new(TestFlash::new(5));
        {
            let mut s = open(&base);
            for &i in pre.iter().take(pre.len().saturating_sub(3)) {
                s.push(&pkts[i]);
            }
        }
        let first = pre.len().saturating_sub(3);
        let writes: Vec<usize> = (first..first + 8).collect();
        // The uncut reference: the content after each write.
        let mut after = Vec::new();
        let reference = RefCell::new(base.borrow().clone());
        {
            let mut s = open(&reference);
            after.push(content(&mut s));
            for &i in &writes {
                s.push(&pkts[i]);
                after.push(content(&mut s));
            }
        }
        let total = {
            let mut f = base.borrow().clone();
            f.budget = Some(usize::MAX);
            let f = RefCell::new(f);
            let mut s = open(&f);
            for &i in &writes {
                s.push(&pkts[i]);
            }
            let left = f.borrow().budget.expect("armed");
            usize::MAX - left
        };
        assert!(total > 8 * 60, "the writes program {total} bytes");
        let mut overwrites_cut = 0;
        for cut in 0..=total {
            let mut f = base.borrow().clone();
            f.budget = Some(cut);
            let f = RefCell::new(f);
            // The write in progress when the power went.
            let mut in_progress = None;
            {
                let mut s = open(&f);
                for (k, &i) in writes.iter().enumerate() {
                    s.push(&pkts[i]);
                    if f.borrow().cut {
                        in_progress = Some(k);
                        break;
                    }
                }
            }
            f.borrow_mut().budget = None;
            f.borrow_mut().cut = false;
            let mut s = open(&f);
            let got = content(&mut s);
            let Some(k) = in_progress else {
                assert_eq!(got, after[writes.len()], "cut {cut}: not reached");
                continue;
            };
            let (before, done) = (&after[k], &after[k + 1]);
            if before.len() + 1 != done.len() {
                overwrites_cut += 1;
            }
            let packet = &pkts[writes[k]];
            // Nothing corrupt, nothing that was not written, nothing out of order.
            let allowed: Vec<&Vec<u8>> = before.iter().chain(std::iter::once(packet)).collect();
            let mut at = 0;
            for p in &got {
                let found = allowed[at..].iter().position(|q| *q == p);
                assert!(found.is_some(), "cut {cut}: unknown or reordered packet");
                at += found.unwrap_or(0) + 1;
            }
            // Everything the finished write keeps is there, but for the packet itself.
            for p in done.iter().filter(|p| *p != packet) {
                assert!(
                    got.contains(p),
                    "cut {cut} in write {k}: lost a packet other than the one written"
                );
            }
            assert_eq!(s.len(), got.len(), "cut {cut}: count after reopening");
            // The store goes on working.
            s.push(&pkts[219]);
            assert_eq!(s.counts().not_stored, 0, "cut {cut}: a write after the reset");
            assert_eq!(content(&mut s).last(), Some(&pkts[219]));
            assert_eq!(f.borrow().bit_sets, 0, "cut {cut}: a bit set without an erase");
        }
        assert!(overwrites_cut > 0, "some cuts hit a write that overwrote");
    }

    // verifies: PUS-15-05
    #[test]
    fn erases_spread_evenly_over_the_area() {
        let f = RefCell::new(TestFlash::new(5));
        let mut s = open(&f);
        // About ten times through each area.
        for p in packets(6000, 60).iter().cycle().take(6000) {
            s.push(p);
        }
        let e = &f.borrow().erases;
        let (hk, rep) = (&e[..3], &e[3..]);
        for area in [hk, rep] {
            let (lo, hi) = (
                area.iter().min().copied().unwrap_or(0),
                area.iter().max().copied().unwrap_or(0),
            );
            assert!(lo >= 5 && hi - lo <= 1, "erase counts {area:?}");
        }
    }

    // verifies: PUS-15-10
    #[test]
    fn a_stretchs_counts_are_given_only_when_they_cannot_have_wrapped() {
        let r = |seq: u16, ms: u32| Read {
            len: 0,
            stamp: (1, ms),
            apid: 0x101,
            seq,
            address: 0,
        };
        let walk = |others| Walk {
            cur: Some(r(100, 10)),
            page_start: Some((1, 10)),
            next: None,
            others,
        };
        let seqs = |w: Walk, n| w.stretch::<TestFlash>(n).map(|s| s.seqs);
        // Few page starts of the other area between: the counts between are exact.
        assert_eq!(seqs(walk(Some(0)), r(150, 20)), Some(Some((100, 150))));
        assert_eq!(
            seqs(walk(Some(3)), r(16_000, 20)),
            Some(None),
            "more counts than the pages hold"
        );
        // The other area started many pages between (its packets there may be 2^14 and
        // more), or it is not known how many: no counts.
        assert_eq!(seqs(walk(Some(200)), r(150, 20)), Some(None));
        assert_eq!(seqs(walk(None), r(150, 20)), Some(None));
        // Another stream: no counts.
        let other_apid = Read {
            apid: 0x102,
            ..r(150, 20)
        };
        assert_eq!(seqs(walk(Some(0)), other_apid), Some(None));
        // Time going back: no stretch at all.
        assert_eq!(seqs(walk(Some(0)), r(150, 5)), None);
        // Before the oldest packet: the oldest alone, whatever is known.
        let first = Walk {
            cur: None,
            ..walk(None)
        };
        assert_eq!(seqs(first, r(7, 3)), Some(Some((7, 7))));
    }

    // verifies: PUS-15-06
    #[test]
    fn the_store_holds_two_hours_of_default_housekeeping_events_and_verification() {
        // The MIB's sizing (mib::memory::store) counts the queue's own item header.
        assert_eq!(Queue::<TestFlash, 1>::item_overhead_size() as usize, store::ITEM_HEADER);
        let secs = store::MIN_DURATION_S;
        let (hk, reports) = (store::hk_need(secs), store::report_need(secs));
        println!(
            "HK {} of {} B ({:.2} h), reports {} of {} B ({:.2} h)",
            hk.bytes,
            hk.room,
            hk.hours(secs),
            reports.bytes,
            reports.room,
            reports.hours(secs)
        );
        // Each area holds the outage with the flight margin.
        assert!(hk.within_margin() && reports.within_margin(), "{hk:?} {reports:?}");
        // The report area outlasts the HK area: HK is overwritten first.
        assert!(reports.hours(secs) > hk.hours(secs));
        assert_eq!(store::SIZE, (store::HK_SECTORS + store::REPORT_SECTORS) as u32 * 4096);
        // The room is what the queue really holds: an area of the HK's largest item, filled
        // until it overwrites, keeps at least the room's worth of items.
        let largest = mib::hk::HK_STRUCTS
            .iter()
            .map(|h| mib_wire::header::MIN_TM_LEN + h.data_len())
            .max()
            .unwrap_or(0);
        let held = FlashStore::<TestFlash, 1, 1>::min_packets(store::HK_SECTORS, largest);
        assert!(held * store::item_bytes(largest) >= store::room(store::HK_SECTORS, store::item_bytes(largest)));
    }
}
