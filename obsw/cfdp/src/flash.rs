//! The file store on NOR flash (board A's `files` partition, `mib::memory::FILE_STORE`): a
//! [`FlatStore`] over a region of any `embedded_storage` NOR flash, no heap, fixed RAM.
//!
//! Layout (`docs/files.md`, "The file store"): the region's first [`DIR_SECTORS`] sectors
//! hold the directory, a `sequential-storage` map from a slot (0..`MAX_FILES`) to the
//! file in it — its name, its length and the data sectors that hold its bytes, in order —
//! or "free"; every other sector of the region is a data sector, owned by at most one
//! file or shared by small files: a file of at most [`BLOCK`] bytes takes one 1 KiB block
//! of a shared sector, and moves to sectors of its own when it grows past it. The map
//! writes each new value as a new item with CRCs and keeps the old one until it is
//! superseded, so a directory entry is replaced whole or not at all.
//!
//! Power-fail safety: the directory entry is the commit. Every operation writes new
//! bytes only where the directory as it stands does not look — past a file's length, or
//! into a sector no entry names — and then stores the entry that makes them part of the
//! file. A write that changes bytes a file already has copies the sectors (a small file:
//! the block) it touches to free ones (copy on write) and stores the entry naming the
//! copies; a block is written only while blank. A cut before the
//! entry's store leaves the file as it was; after it, as the operation made it. The
//! sectors an entry no longer names are free again (erased before reuse); at open, a
//! sector no entry names is free, whatever it holds. One exception, a file being received
//! under its staging name (`mib::cfdp::PARTIAL_PREFIX`): its gaps are filled in place, so
//! a cut may leave part of a segment in it (see `Inner::write` for why that is safe).
//!
//! Bounded work: one call touches at most the sectors its bytes fall in, the free sectors
//! it takes (erased on the way when not known to be blank) and one directory store, which
//! `sequential-storage` may precede with the migration of its oldest directory page
//! (`docs/files.md` has the worst case).
//!
//! `sequential-storage` is async; the flashes here are blocking, so every future is ready
//! when first polled and `embassy_futures::block_on` drives it.

use core::cell::RefCell;

use embassy_futures::block_on;
use embedded_storage::nor_flash::{ErrorType, MultiwriteNorFlash, NorFlash, ReadNorFlash};
use mib::cfdp::{MAX_FILES, MAX_NAME_LEN};
use sequential_storage::cache::key_pointers::ArrayKeyPointers;
use sequential_storage::cache::page_pointers::ArrayPagePointers;
use sequential_storage::cache::page_states::ArrayPageStates;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};

use crate::store::{FileName, FlatStore, StoreError};

/// Sectors of the directory map at the start of the region: 64 entries of at most
/// [`ENTRY_ITEM`] bytes fill 1.8 of them; the others keep a directory store from
/// migrating more than two pages (see `docs/files.md`).
pub const DIR_SECTORS: usize = 4;

/// The directory map's key of the kept transaction sequence number (`crate::seq`): past
/// every slot (`MAX_FILES`), so no file's entry and ignored as one.
pub const SEQ_KEY: u8 = u8::MAX;
const _: () = assert!(MAX_FILES <= SEQ_KEY as usize, "the sequence key is no slot");
/// Most data sectors a region may have (the board's partition less the
/// directory): the size of the free-sector bitmaps and of a file's sector list.
pub const MAX_DATA_SECTORS: usize = (mib::cfdp::BOARD_STORE_BYTES / mib::memory::FLASH_SECTOR) as usize - DIR_SECTORS;
/// Free sectors kept back from growth so that a write that changes bytes a file has can
/// always copy the (at most two) sectors a segment of up to one sector falls in.
pub const RESERVE_SECTORS: usize = 2;
const _: () = assert!(MAX_DATA_SECTORS <= 64, "the sector bitmaps are u64");

/// A directory value: kind, generation (u32 LE), name length, name, length (u32 LE),
/// sector count, sectors, and a small file's block.
const ENTRY_MAX: usize = 1 + 4 + 1 + MAX_NAME_LEN + 4 + 1 + MAX_DATA_SECTORS + 1;
/// Map item buffer: the key (one byte) and the largest value, in whole words.
const ITEM_BUF: usize = (1 + ENTRY_MAX).next_multiple_of(4) + 4;
/// Bytes of a full directory entry in flash (item header 8, then key and value in words).
pub const ENTRY_ITEM: usize = 8 + (1 + ENTRY_MAX).next_multiple_of(4);
const KIND_FREE: u8 = 0;
const KIND_FILE: u8 = 1;
const KIND_SMALL: u8 = 2;
/// A small file (at most this many bytes) takes one block of a sector shared with other
/// small files instead of a sector of its own: 64 files of up to 1 KiB take 16 sectors.
pub const BLOCK: usize = 1024;
const BLOCKS: usize = SECTOR / BLOCK;
const _: () = assert!(BLOCKS == 4, "a sector's block states are 4 x 2 bits");
/// The state of a block of a shared sector (2 bits each in `Inner::blocks`).
const B_UNKNOWN: u8 = 0;
const B_BLANK: u8 = 1;
const B_DIRTY: u8 = 2;
const B_USED: u8 = 3;
/// Blocks of unknown state a call reads at most to find a blank one (1 KiB each).
const BLOCK_CHECKS: usize = 2;

/// Bytes copied through RAM at a time (sector copies, comparisons).
const CHUNK: usize = 256;

type DirCache =
    Cache<ArrayPageStates<DIR_SECTORS>, ArrayPagePointers<DIR_SECTORS>, ArrayKeyPointers<u8, MAX_FILES>, u8>;

/// A blocking flash under `sequential-storage`'s async traits (each future is ready at
/// once), counting the erases the directory map makes.
struct Blocking<F> {
    flash: F,
    erases: u32,
}

impl<F: ErrorType> ErrorType for Blocking<F> {
    type Error = F::Error;
}

impl<F: ReadNorFlash> embedded_storage_async::nor_flash::ReadNorFlash for Blocking<F> {
    const READ_SIZE: usize = F::READ_SIZE;
    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.flash.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl<F: NorFlash> embedded_storage_async::nor_flash::NorFlash for Blocking<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.erases = self.erases.wrapping_add(1);
        self.flash.erase(from, to)
    }
    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.flash.write(offset, bytes)
    }
}

impl<F: MultiwriteNorFlash> embedded_storage_async::nor_flash::MultiwriteNorFlash for Blocking<F> {}

/// One file of the directory, as RAM keeps it.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Entry {
    name: FileName,
    len: u32,
    /// Data sector indices (0 = the region's first data sector), in file order; they
    /// cover at least `len` bytes. A small file (`block`) has the one shared sector its
    /// block is in.
    sectors: heapless::Vec<u8, MAX_DATA_SECTORS>,
    /// A small file (at most [`BLOCK`] bytes): its block in `sectors[0]`.
    block: Option<u8>,
}

impl Entry {
    /// The entry as stored, `generation` the store's commit count at its commit.
    fn encode(&self, generation: u32, out: &mut [u8; ENTRY_MAX]) -> usize {
        let n = self.name.as_str().as_bytes();
        out[0] = if self.block.is_some() { KIND_SMALL } else { KIND_FILE };
        out[1..5].copy_from_slice(&generation.to_le_bytes());
        out[5] = n.len() as u8;
        out[6..6 + n.len()].copy_from_slice(n);
        let mut at = 6 + n.len();
        out[at..at + 4].copy_from_slice(&self.len.to_le_bytes());
        at += 4;
        out[at] = self.sectors.len() as u8;
        at += 1;
        out[at..at + self.sectors.len()].copy_from_slice(&self.sectors);
        at += self.sectors.len();
        if let Some(b) = self.block {
            out[at] = b;
            at += 1;
        }
        at
    }

    /// A value read back from the directory, with its generation; `None` when it is not a
    /// whole, sound entry.
    fn decode(v: &[u8], data_sectors: usize) -> Option<Option<(Entry, u32)>> {
        let small = match *v.first()? {
            KIND_FREE if v.len() == 1 => return Some(None),
            KIND_FILE => false,
            KIND_SMALL => true,
            _ => return None,
        };
        let generation = u32::from_le_bytes(v.get(1..5)?.try_into().ok()?);
        let nl = usize::from(*v.get(5)?);
        let name = core::str::from_utf8(v.get(6..6 + nl)?).ok()?;
        let name = FileName::new(name).ok()?;
        let at = 6 + nl;
        let len = u32::from_le_bytes(v.get(at..at + 4)?.try_into().ok()?);
        let ns = usize::from(*v.get(at + 4)?);
        let list = v.get(at + 5..at + 5 + ns)?;
        let block = if small { Some(*v.get(at + 5 + ns)?) } else { None };
        if v.len() != at + 5 + ns + usize::from(small) || list.iter().any(|&s| usize::from(s) >= data_sectors) {
            return None;
        }
        let sectors = heapless::Vec::from_slice(list).ok()?;
        let room = match block {
            Some(b) if ns == 1 && usize::from(b) < BLOCKS => BLOCK,
            Some(_) => return None,
            None => ns * SECTOR,
        };
        let e = Entry {
            name,
            len,
            sectors,
            block,
        };
        (e.len as usize <= room).then_some(Some((e, generation)))
    }
}

/// Sector size the layout is computed with (the flash's erase size must equal it).
const SECTOR: usize = mib::memory::FLASH_SECTOR as usize;

/// What the store counted since it was opened (file store housekeeping).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FlashCounters {
    /// Directory entries found unsound at open (bad name, sector out of range): their
    /// files are left out, their sectors free.
    pub bad_entries: u32,
    /// Entries left out at open because a later one claims their name or bytes (a
    /// `replace` cut between its two stores, or a damaged directory): freed again.
    pub superseded: u32,
    /// Flash operations the store made on its data sectors: reads, writes (calls), sector
    /// erases; and the directory map's page erases (its reads and writes are not counted).
    pub reads: u32,
    pub writes: u32,
    pub erases: u32,
    pub dir_erases: u32,
    /// Sectors (a small file: its block) copied on write (a write that changed bytes a
    /// file had), and small files' blocks moved to a sector of their own (grown past it).
    pub copies: u32,
    /// Writes that changed nothing (a segment received again with the same bytes).
    pub same: u32,
}

/// Why a store could not be opened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OpenError {
    /// The region is not whole sectors of the layout's size, is too small (fewer than
    /// `DIR_SECTORS` + `RESERVE_SECTORS` + 1 sectors) or too large (`MAX_DATA_SECTORS`),
    /// or lies outside the flash.
    Layout,
    /// The flash failed, or the directory cannot be read (not a store: see
    /// [`FlashStore::format`]).
    Flash,
}

/// The file store (see the module documentation).
pub struct FlashStore<F: MultiwriteNorFlash> {
    inner: RefCell<Inner<F>>,
}

struct Inner<F: MultiwriteNorFlash> {
    map: MapStorage<u8, Blocking<F>, DirCache>,
    buf: [u8; ITEM_BUF],
    dir: [Option<Entry>; MAX_FILES],
    /// Address of data sector 0, and how many there are.
    data_base: u32,
    data_sectors: usize,
    /// Data sectors some entry names (shared sectors included).
    used: u64,
    /// Sectors shared by small files, and the state of each of their blocks.
    shared: u64,
    blocks: [u8; MAX_DATA_SECTORS],
    /// Free data sectors known to be erased (blank).
    blank: u64,
    /// Where the search for a free sector starts (round robin: wear spreads).
    cursor: usize,
    /// Entries committed so far (the last one's generation): of two entries that claim
    /// the same name or bytes, the later one is the file (see `replace`).
    generation: u32,
    /// The CFDP transaction sequence number kept under [`SEQ_KEY`] (`crate::seq`).
    seq: Option<u16>,
    counters: FlashCounters,
}

impl<F: MultiwriteNorFlash> FlashStore<F> {
    /// Opens the store in `region` (absolute flash addresses) of `flash`, keeping what it
    /// holds. An erased region is an empty store.
    pub fn open(flash: F, region: core::ops::Range<u32>) -> Result<Self, OpenError> {
        if F::ERASE_SIZE != SECTOR || F::WRITE_SIZE > 4 || F::READ_SIZE > 4 || 4 % F::WRITE_SIZE != 0 {
            return Err(OpenError::Layout);
        }
        let sector = SECTOR as u32;
        if !region.start.is_multiple_of(sector)
            || !region.end.is_multiple_of(sector)
            || region.end as usize > flash.capacity()
            || region.end <= region.start
        {
            return Err(OpenError::Layout);
        }
        let sectors = ((region.end - region.start) / sector) as usize;
        let data_sectors = sectors.checked_sub(DIR_SECTORS).ok_or(OpenError::Layout)?;
        if data_sectors <= RESERVE_SECTORS || data_sectors > MAX_DATA_SECTORS {
            return Err(OpenError::Layout);
        }
        let dir_end = region.start + DIR_SECTORS as u32 * sector;
        let cfg = MapConfig::try_new(region.start..dir_end).map_err(|_| OpenError::Layout)?;
        let cache = Cache::new(
            ArrayPageStates::new(),
            ArrayPagePointers::new(),
            ArrayKeyPointers::new(),
        );
        let mut inner = Inner {
            map: MapStorage::new(Blocking { flash, erases: 0 }, cfg, cache),
            buf: [0; ITEM_BUF],
            dir: core::array::from_fn(|_| None),
            data_base: dir_end,
            data_sectors,
            used: 0,
            shared: 0,
            blocks: [0; MAX_DATA_SECTORS],
            blank: 0,
            cursor: 0,
            generation: 0,
            seq: None,
            counters: FlashCounters::default(),
        };
        inner.load()?;
        Ok(FlashStore {
            inner: RefCell::new(inner),
        })
    }

    /// Erases `region` of `flash`: an empty store (every file is lost).
    pub fn format(flash: &mut F, region: core::ops::Range<u32>) -> Result<(), OpenError> {
        flash.erase(region.start, region.end).map_err(|_| OpenError::Flash)
    }

    pub fn counters(&self) -> FlashCounters {
        self.inner.try_borrow_mut().map_or_else(
            |_| FlashCounters::default(),
            |mut i| FlashCounters {
                dir_erases: i.map.flash().erases,
                ..i.counters
            },
        )
    }

    /// The flash back (the store is closed).
    pub fn into_flash(self) -> F {
        self.inner.into_inner().map.destroy().0.flash
    }

    /// What `free()` says of the store when it is empty: the most one file can hold.
    pub fn capacity(&self) -> u64 {
        self.inner.try_borrow().map_or(0, |i| promise(i.data_sectors))
    }

    /// Makes one free data sector ready (blank) ahead of need: reads it and erases it if
    /// it is not blank; with none left to do, tells whether one block of a shared sector
    /// whose state is not known (after an open) is blank. `Ok(false)` when there is
    /// nothing left to do. At most 4 KiB read and one erase per call: the board calls it
    /// in periods with time to spare, so that writes take blank sectors and blocks and
    /// erase nothing.
    pub fn erase_ahead(&self) -> Result<bool, StoreError> {
        self.with(|i| {
            let free = !i.used & !i.blank & (u64::MAX >> (64 - i.data_sectors));
            if free == 0 {
                return i.tell_a_block();
            }
            let s = free.trailing_zeros() as u8;
            if !i.is_blank(s)? {
                let a = i.addr(s);
                i.counters.erases = i.counters.erases.wrapping_add(1);
                i.flash().erase(a, a + SECTOR as u32).map_err(|_| StoreError::Io)?;
            }
            i.blank |= 1 << s;
            Ok(true)
        })
    }

    /// The transaction sequence number last kept ([`FlashStore::keep_seq`]), if any.
    pub fn kept_seq(&self) -> Option<u16> {
        self.inner.try_borrow().ok().and_then(|i| i.seq)
    }

    /// Keeps `seq` as the next transaction sequence number: one directory store, so a
    /// power cut leaves the number before or this one, like any entry.
    pub fn keep_seq(&self, seq: u16) -> Result<(), StoreError> {
        self.with(|i| {
            let v = seq.to_be_bytes();
            block_on(i.map.store_item(&mut i.buf, &SEQ_KEY, &&v[..])).map_err(|e| match e {
                sequential_storage::Error::FullStorage => StoreError::Full,
                _ => StoreError::Io,
            })?;
            i.seq = Some(seq);
            Ok(())
        })
    }

    fn with<T>(&self, f: impl FnOnce(&mut Inner<F>) -> Result<T, StoreError>) -> Result<T, StoreError> {
        let mut i = self.inner.try_borrow_mut().map_err(|_| StoreError::Io)?;
        f(&mut i)
    }
}

impl<F: MultiwriteNorFlash> Inner<F> {
    /// Reads the directory: the last value of each slot wins.
    fn load(&mut self) -> Result<(), OpenError> {
        let mut raw: [Option<(Entry, u32)>; MAX_FILES] = core::array::from_fn(|_| None);
        let mut bad = [false; MAX_FILES];
        self.repair_torn_erase()?;
        // A cut erase or migration of a directory page is repaired by the map's first
        // operation; `fetch_all_items` cannot repair what it finds (its page search returns
        // the corruption before its repair runs), so a lookup goes first.
        if block_on(self.map.fetch_item::<&[u8]>(&mut self.buf, &0)).is_err() {
            return Err(OpenError::Flash);
        }
        {
            let mut it = block_on(self.map.fetch_all_items(&mut self.buf)).map_err(|_| OpenError::Flash)?;
            loop {
                match block_on(it.next::<&[u8]>(&mut self.buf)) {
                    Ok(Some((slot, v))) => {
                        let i = usize::from(slot);
                        if slot == SEQ_KEY {
                            // The last value stored wins, like a slot's; one of another
                            // length is no number.
                            self.seq = <[u8; 2]>::try_from(v).ok().map(u16::from_be_bytes);
                            continue;
                        }
                        if i >= MAX_FILES {
                            continue;
                        }
                        match Entry::decode(v, self.data_sectors) {
                            Some(e) => {
                                raw[i] = e;
                                bad[i] = false;
                            }
                            None => bad[i] = true,
                        }
                    }
                    Ok(None) => break,
                    Err(_) => return Err(OpenError::Flash),
                }
            }
        }
        // The latest entries first: of two that claim the same name or bytes (a `replace`
        // cut between its two stores), the later one is the file.
        let mut order: heapless::Vec<(u32, usize), MAX_FILES> = heapless::Vec::new();
        for (i, e) in raw.iter().enumerate() {
            match e {
                Some((_, generation)) if !bad[i] => {
                    let _ = order.push((*generation, i));
                    self.generation = self.generation.max(*generation);
                }
                _ => {}
            }
        }
        // Newest first; an insertion sort (at most MAX_FILES entries, once at open): the
        // slice sort's code took 4 to 6 KB of board A's image.
        for k in 1..order.len() {
            let mut j = k;
            while j > 0 && order[j - 1].0 < order[j].0 {
                order.swap(j - 1, j);
                j -= 1;
            }
        }
        self.counters.bad_entries = bad.iter().filter(|&&b| b).count() as u32;
        let mut stale = [false; MAX_FILES];
        for &(_, i) in &order {
            let Some((e, _)) = raw[i].take() else { continue };
            let mut mask = 0u64;
            for &s in &e.sectors {
                mask |= 1 << s;
            }
            let dup_name = self.dir.iter().flatten().any(|o| o.name == e.name);
            let clash = match e.block {
                // A shared sector: not a file's own, and the block not taken.
                Some(b) => {
                    mask & self.used & !self.shared != 0
                        || (mask & self.shared != 0 && self.block(e.sectors[0], b) == B_USED)
                }
                None => mask & self.used != 0,
            };
            if mask.count_ones() as usize != e.sectors.len() || clash || dup_name {
                stale[i] = true;
                continue;
            }
            if let Some(b) = e.block {
                let s = e.sectors[0];
                self.shared |= mask;
                self.set_block(s, b, B_USED);
            }
            self.used |= mask;
            self.dir[i] = Some(e);
        }
        // Entries a later one supersedes are freed now, or a later removal of the file
        // that superseded them would bring them back.
        for (i, _) in stale.iter().enumerate().filter(|(_, s)| **s) {
            self.counters.superseded = self.counters.superseded.wrapping_add(1);
            self.commit(i, None).map_err(|_| OpenError::Flash)?;
        }
        Ok(())
    }

    /// The cut erases of a directory page that `sequential-storage`'s repair does not
    /// recognise (it knows the one whose first word reads erased and last word
    /// programmed):
    /// - first word programmed, last erased: the page looks "partly open" next to the
    ///   page its items went to (which is), and the map refuses every store from then on.
    ///   Two adjacent partly open pages happen no other way (a page is closed before the
    ///   next is opened), and the second one's items are all in the first (its erase is a
    ///   migration's last step): it is erased again;
    /// - both words erased, bytes between them not: the page looks open, and the map
    ///   would write items over what is left (on the part, a write only clears bits: a
    ///   corrupt item, an entry lost after it was reported stored). An open page is all
    ///   erased in the map's own rules (items go to partly open pages only): one that is
    ///   not is erased again.
    fn repair_torn_erase(&mut self) -> Result<(), OpenError> {
        let start = self.data_base - (DIR_SECTORS * SECTOR) as u32;
        let mut partly_open = [false; DIR_SECTORS];
        for (p, open) in partly_open.iter_mut().enumerate() {
            let a = start + (p * SECTOR) as u32;
            let (mut first, mut last) = ([0u8; 4], [0u8; 4]);
            let f = self.flash();
            f.read(a, &mut first).map_err(|_| OpenError::Flash)?;
            f.read(a + SECTOR as u32 - 4, &mut last).map_err(|_| OpenError::Flash)?;
            // The map's rule: a marker is written when at least half a byte's bits are 0.
            let marked = |w: [u8; 4]| w.iter().map(|b| b.count_zeros()).sum::<u32>() >= 4;
            *open = marked(first) && !marked(last);
            if !marked(first) && !marked(last) && !self.blank_at(a, SECTOR).map_err(|_| OpenError::Flash)? {
                self.map.flash().erases = self.map.flash().erases.wrapping_add(1);
                self.flash().erase(a, a + SECTOR as u32).map_err(|_| OpenError::Flash)?;
            }
        }
        for p in 0..DIR_SECTORS {
            let q = (p + 1) % DIR_SECTORS;
            if partly_open[p] && partly_open[q] {
                let a = start + (q * SECTOR) as u32;
                self.map.flash().erases = self.map.flash().erases.wrapping_add(1);
                self.flash().erase(a, a + SECTOR as u32).map_err(|_| OpenError::Flash)?;
                return Ok(());
            }
        }
        Ok(())
    }

    fn find(&self, name: &FileName) -> Option<usize> {
        self.dir
            .iter()
            .position(|e| e.as_ref().is_some_and(|e| &e.name == name))
    }

    fn block(&self, s: u8, b: u8) -> u8 {
        (self.blocks[usize::from(s)] >> (2 * b)) & 3
    }

    fn set_block(&mut self, s: u8, b: u8, state: u8) {
        let v = &mut self.blocks[usize::from(s)];
        *v = (*v & !(3 << (2 * b))) | (state << (2 * b));
    }

    /// A blank block of a shared sector, or a blank sector to share (`taken`: the sectors
    /// this call has taken). The block is marked dirty at once (it is about to be
    /// written); a new shared sector joins the shared ones only when the call commits.
    fn take_block(&mut self, taken: &mut u64, growth: bool) -> Result<(u8, u8), StoreError> {
        // Blocks not known either way (after an open) are read to tell: at most
        // `BLOCK_CHECKS` of them a call (`erase_ahead` tells the others).
        let mut checks = BLOCK_CHECKS;
        for pass in [B_BLANK, B_UNKNOWN] {
            for s in 0..self.data_sectors as u8 {
                if self.shared & (1 << s) == 0 {
                    continue;
                }
                for b in 0..BLOCKS as u8 {
                    if self.block(s, b) != pass {
                        continue;
                    }
                    if pass == B_UNKNOWN {
                        if checks == 0 {
                            continue;
                        }
                        checks -= 1;
                        if !self.blank_at(self.addr(s) + (usize::from(b) * BLOCK) as u32, BLOCK)? {
                            self.set_block(s, b, B_DIRTY);
                            continue;
                        }
                    }
                    self.set_block(s, b, B_DIRTY);
                    return Ok((s, b));
                }
            }
        }
        // A new shared sector for a new file comes out of what `free()` promised, not out
        // of the reserve.
        if growth && self.free_sectors() <= RESERVE_SECTORS + taken.count_ones() as usize {
            return Err(StoreError::Full);
        }
        let s = self.take(*taken | self.used)?;
        *taken |= 1 << s;
        Ok((s, 0))
    }

    /// Reads one block of a shared sector whose state is not known and records whether it
    /// is blank; `false` when there is none.
    fn tell_a_block(&mut self) -> Result<bool, StoreError> {
        for s in 0..self.data_sectors as u8 {
            if self.shared & (1 << s) == 0 {
                continue;
            }
            for b in 0..BLOCKS as u8 {
                if self.block(s, b) == B_UNKNOWN {
                    let blank = self.blank_at(self.addr(s) + (usize::from(b) * BLOCK) as u32, BLOCK)?;
                    self.set_block(s, b, if blank { B_BLANK } else { B_DIRTY });
                    return Ok(true);
                }
            }
        }
        Ok(false)
    }

    /// Gives up block `b` of shared sector `s`; the sector is free again when it holds
    /// no other file.
    fn release_block(&mut self, s: u8, b: u8) {
        self.set_block(s, b, B_DIRTY);
        if (0..BLOCKS as u8).all(|k| self.block(s, k) != B_USED) {
            self.shared &= !(1 << s);
            self.used &= !(1 << s);
            self.blank &= !(1 << s);
        }
    }

    /// Gives up what entry `e` held.
    fn release(&mut self, e: &Entry) {
        match e.block {
            Some(b) => self.release_block(e.sectors[0], b),
            None => {
                for &s in &e.sectors {
                    self.used &= !(1u64 << s);
                }
            }
        }
    }

    fn free_sectors(&self) -> usize {
        self.data_sectors - self.used.count_ones() as usize
    }

    fn addr(&self, sector: u8) -> u32 {
        self.data_base + u32::from(sector) * SECTOR as u32
    }

    fn flash(&mut self) -> &mut F {
        &mut self.map.flash().flash
    }

    fn read_raw(&mut self, at: u32, out: &mut [u8]) -> Result<(), StoreError> {
        self.counters.reads = self.counters.reads.wrapping_add(1);
        self.flash().read(at, out).map_err(|_| StoreError::Io)
    }

    fn write_raw(&mut self, at: u32, bytes: &[u8]) -> Result<(), StoreError> {
        self.counters.writes = self.counters.writes.wrapping_add(1);
        self.flash().write(at, bytes).map_err(|_| StoreError::Io)
    }

    /// Stores slot `i`'s entry (or "free"): the commit of every operation.
    fn commit(&mut self, i: usize, e: Option<&Entry>) -> Result<(), StoreError> {
        let mut v = [0u8; ENTRY_MAX];
        let n = match e {
            Some(e) => {
                self.generation = self.generation.wrapping_add(1);
                e.encode(self.generation, &mut v)
            }
            None => {
                v[0] = KIND_FREE;
                1
            }
        };
        block_on(self.map.store_item(&mut self.buf, &(i as u8), &&v[..n])).map_err(|e| match e {
            sequential_storage::Error::FullStorage => StoreError::Full,
            _ => StoreError::Io,
        })
    }

    /// A free data sector, erased; not yet marked used.
    fn take(&mut self, taken: u64) -> Result<u8, StoreError> {
        let free = !self.used & !taken & (u64::MAX >> (64 - self.data_sectors));
        if free == 0 {
            return Err(StoreError::Full);
        }
        // Blank ones first, round robin from the cursor among either kind.
        let pick = |set: u64, from: usize| -> Option<usize> {
            (0..self.data_sectors)
                .map(|k| (from + k) % self.data_sectors)
                .find(|&s| set & (1 << s) != 0)
        };
        let s = pick(free & self.blank, self.cursor)
            .or_else(|| pick(free, self.cursor))
            .ok_or(StoreError::Full)?;
        self.cursor = (s + 1) % self.data_sectors;
        let s8 = s as u8;
        if self.blank & (1 << s) == 0 && !self.is_blank(s8)? {
            let a = self.addr(s8);
            self.counters.erases = self.counters.erases.wrapping_add(1);
            self.flash().erase(a, a + SECTOR as u32).map_err(|_| StoreError::Io)?;
        }
        self.blank &= !(1 << s);
        Ok(s8)
    }

    fn is_blank(&mut self, s: u8) -> Result<bool, StoreError> {
        self.blank_at(self.addr(s), SECTOR)
    }

    fn blank_at(&mut self, a: u32, len: usize) -> Result<bool, StoreError> {
        let mut b = [0u8; CHUNK];
        for k in (0..len).step_by(CHUNK) {
            self.read_raw(a + k as u32, &mut b)?;
            if b.iter().any(|&x| x != 0xFF) {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// Reads `out.len()` bytes at `off` of sector `s` (any alignment).
    fn read_at(&mut self, s: u8, off: usize, out: &mut [u8]) -> Result<(), StoreError> {
        let base = self.addr(s);
        let mut done = 0;
        while done < out.len() {
            let at = off + done;
            let start = at - at % 4;
            let mut b = [0u8; CHUNK];
            let n = (CHUNK - (at - start)).min(out.len() - done);
            let span = (at - start + n).next_multiple_of(4);
            self.read_raw(base + start as u32, &mut b[..span])?;
            out[done..done + n].copy_from_slice(&b[at - start..at - start + n]);
            done += n;
        }
        Ok(())
    }

    fn len(&self, name: &FileName) -> Option<u64> {
        self.find(name)
            .and_then(|i| self.dir[i].as_ref())
            .map(|e| u64::from(e.len))
    }

    fn create(&mut self, name: &FileName) -> Result<(), StoreError> {
        let (i, old) = match self.find(name) {
            Some(i) => (i, self.dir[i].take()),
            None => (self.dir.iter().position(Option::is_none).ok_or(StoreError::Full)?, None),
        };
        let e = Entry {
            name: name.clone(),
            len: 0,
            sectors: heapless::Vec::new(),
            block: None,
        };
        if let Err(err) = self.commit(i, Some(&e)) {
            self.dir[i] = old;
            return Err(err);
        }
        if let Some(old) = old {
            self.release(&old);
        }
        self.dir[i] = Some(e);
        Ok(())
    }

    fn remove(&mut self, name: &FileName) -> Result<(), StoreError> {
        let i = self.find(name).ok_or(StoreError::NotFound)?;
        self.commit(i, None)?;
        if let Some(old) = self.dir[i].take() {
            self.release(&old);
        }
        Ok(())
    }

    fn rename(&mut self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        let i = self.find(from).ok_or(StoreError::NotFound)?;
        if self.find(to).is_some() {
            return Err(StoreError::Exists);
        }
        let mut e = self.dir[i].clone().ok_or(StoreError::NotFound)?;
        e.name = to.clone();
        self.commit(i, Some(&e))?;
        self.dir[i] = Some(e);
        Ok(())
    }

    /// `from` under the name `to`, `to`'s old file gone, in one step: `from`'s slot takes
    /// the name first (a later entry than `to`'s, which an open after a cut here frees),
    /// then `to`'s slot is freed.
    fn replace(&mut self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        let i = self.find(from).ok_or(StoreError::NotFound)?;
        if from == to {
            return Ok(());
        }
        let Some(t) = self.find(to) else {
            return self.rename(from, to);
        };
        let mut e = self.dir[i].clone().ok_or(StoreError::NotFound)?;
        e.name = to.clone();
        self.commit(i, Some(&e))?;
        self.dir[i] = Some(e);
        if let Some(old) = self.dir[t].take() {
            self.release(&old);
        }
        self.commit(t, None)
    }

    fn read(&mut self, name: &FileName, offset: u64, buf: &mut [u8]) -> Result<(), StoreError> {
        let i = self.find(name).ok_or(StoreError::NotFound)?;
        let e = self.dir[i].as_ref().ok_or(StoreError::NotFound)?;
        let end = offset.checked_add(buf.len() as u64).ok_or(StoreError::NotFound)?;
        if end > u64::from(e.len) {
            return Err(StoreError::NotFound);
        }
        let sectors = e.sectors.clone();
        let base = e.block.map_or(0, |b| usize::from(b) * BLOCK);
        let mut done = 0usize;
        while done < buf.len() {
            let at = base + offset as usize + done;
            let (k, o) = (at / SECTOR, at % SECTOR);
            let n = (SECTOR - o).min(buf.len() - done);
            self.read_at(sectors[k], o, &mut buf[done..done + n])?;
            done += n;
        }
        Ok(())
    }

    /// Writes `data` at `offset` of file `name`: new bytes past the file's length go in
    /// place, changed bytes below it to copies of their sectors; then the entry commits.
    ///
    /// A file being received (`mib::cfdp::PARTIAL_PREFIX`) takes its segments in place
    /// wherever NOR allows it, gaps below its length included: a cut may leave such a
    /// file with some of a segment's bytes, which is safe because the entity removes
    /// staging files at start (`Entity::discard_partial`) and renames one to its name
    /// only after the file's checksum, read back from flash, is verified. This keeps the
    /// sector copies (and their erases) out of a lossy transfer's gap filling.
    fn write(&mut self, name: &FileName, offset: u64, data: &[u8]) -> Result<(), StoreError> {
        let i = self.find(name).ok_or(StoreError::NotFound)?;
        let old = self.dir[i].clone().ok_or(StoreError::NotFound)?;
        let end = offset.checked_add(data.len() as u64).ok_or(StoreError::Full)?;
        if end > (self.data_sectors * SECTOR) as u64 {
            return Err(StoreError::Full);
        }
        if data.is_empty() {
            return Ok(());
        }
        let (offset, end) = (offset as usize, end as usize);
        // A file that is empty or small stays (becomes) small while it fits a block.
        let small = end <= BLOCK && (old.sectors.is_empty() || old.block.is_some());
        let have = if old.block.is_some() { 0 } else { old.sectors.len() };
        let grow = if small {
            0
        } else {
            end.div_ceil(SECTOR).saturating_sub(have)
        };
        if grow + RESERVE_SECTORS > self.free_sectors() {
            return Err(StoreError::Full);
        }
        let mut new = old.clone();
        // Sectors taken by this call (new ones and copies), sectors it gives up, and the
        // block it takes for a small file.
        let mut taken = 0u64;
        let mut given = 0u64;
        let mut block = None;
        let r = if small {
            self.write_small(&mut new, &old, offset, data, &mut taken, &mut block)
        } else {
            new.sectors.clear();
            new.sectors
                .extend_from_slice(&old.sectors[..have])
                .map_err(|_| StoreError::Io)?;
            new.block = None;
            self.write_into(&mut new, &old, offset, data, &mut taken, &mut given)
        };
        let r = r.and_then(|()| {
            new.len = new.len.max(end as u32);
            if new == old {
                self.counters.same = self.counters.same.wrapping_add(1);
                Ok(())
            } else {
                self.commit(i, Some(&new))
            }
        });
        match r {
            Ok(()) => {
                self.used = (self.used | taken) & !given;
                if let Some((s, b)) = block {
                    if taken & (1 << s) != 0 {
                        // A sector newly shared: its other blocks are blank.
                        self.shared |= 1 << s;
                        self.blocks[usize::from(s)] = 0b0101_0101;
                    }
                    self.set_block(s, b, B_USED);
                }
                if let Some(b) = old.block {
                    if new.block != old.block || new.sectors.first() != old.sectors.first() {
                        self.release_block(old.sectors[0], b);
                    }
                }
                self.dir[i] = Some(new);
                Ok(())
            }
            Err(e) => {
                // What the call wrote is in sectors no entry names (free, not blank) or in
                // a block marked dirty.
                self.used &= !taken;
                Err(e)
            }
        }
    }

    /// A write that leaves the file small (at most `BLOCK` bytes): into a new block for
    /// an empty file, in place past the committed length (or anywhere in a file being
    /// received), otherwise into a copy of the block.
    fn write_small(
        &mut self,
        new: &mut Entry,
        old: &Entry,
        offset: usize,
        data: &[u8],
        taken: &mut u64,
        block: &mut Option<(u8, u8)>,
    ) -> Result<(), StoreError> {
        let committed = old.len as usize;
        let staging = new.name.as_str().starts_with(mib::cfdp::PARTIAL_PREFIX);
        let done = match old.block {
            None => false,
            Some(b) => {
                let (s, lo) = (old.sectors[0], usize::from(b) * BLOCK + offset);
                if offset < committed && !staging {
                    self.equal(s, lo, data)?
                } else {
                    !matches!(self.program(s, lo, data)?, Program::NeedsErase)
                }
            }
        };
        if done {
            return Ok(());
        }
        let (s, b) = self.take_block(taken, old.block.is_none())?;
        *block = Some((s, b));
        let to = self.addr(s) + (usize::from(b) * BLOCK) as u32;
        match old.block {
            Some(ob) => {
                let from = self.addr(old.sectors[0]) + (usize::from(ob) * BLOCK) as u32;
                self.counters.copies = self.counters.copies.wrapping_add(1);
                self.copy_unit(from, to, BLOCK, committed, offset, data)?;
            }
            // A blank block: the bytes go in as they are.
            None => {
                if matches!(
                    self.program(s, usize::from(b) * BLOCK + offset, data)?,
                    Program::NeedsErase
                ) {
                    return Err(StoreError::Io);
                }
            }
        }
        new.sectors.clear();
        new.sectors.push(s).map_err(|_| StoreError::Io)?;
        new.block = Some(b);
        Ok(())
    }

    fn write_into(
        &mut self,
        new: &mut Entry,
        old: &Entry,
        offset: usize,
        data: &[u8],
        taken: &mut u64,
        given: &mut u64,
    ) -> Result<(), StoreError> {
        let end = offset + data.len();
        let staging = new.name.as_str().starts_with(mib::cfdp::PARTIAL_PREFIX);
        while new.sectors.len() < end.div_ceil(SECTOR) {
            let s = self.take(*taken | self.used)?;
            *taken |= 1 << s;
            new.sectors.push(s).map_err(|_| StoreError::Full)?;
        }
        let committed = old.len as usize;
        if let Some(b) = old.block {
            // A small file grown past its block: its bytes go first to its first sector.
            let from = self.addr(old.sectors[0]) + (usize::from(b) * BLOCK) as u32;
            let to = self.addr(new.sectors[0]);
            let n = data.len().min(BLOCK.saturating_sub(offset));
            self.counters.copies = self.counters.copies.wrapping_add(1);
            self.copy_unit(from, to, BLOCK, committed, offset, &data[..n])?;
        }
        let mut at = offset;
        while at < end {
            let k = at / SECTOR;
            let (lo, hi) = (at % SECTOR, (end - k * SECTOR).min(SECTOR));
            let piece = &data[at - offset..at - offset + (hi - lo)];
            let s = new.sectors[k];
            let fresh = *taken & (1 << s) != 0;
            // Below the committed length the bytes are the file's: never written in place,
            // but in a file being received (see `write`).
            let visible = k * SECTOR + lo < committed && !staging;
            if fresh || !visible {
                match self.program(s, lo, piece)? {
                    Program::Done | Program::Same => {}
                    Program::NeedsErase => self.copy_on_write(new, committed, k, lo, piece, taken, given)?,
                }
            } else if !self.equal(s, lo, piece)? {
                self.copy_on_write(new, committed, k, lo, piece, taken, given)?;
            }
            at = (k + 1) * SECTOR;
        }
        Ok(())
    }

    /// Compares `piece` with the bytes at `lo` of sector `s`.
    fn equal(&mut self, s: u8, lo: usize, piece: &[u8]) -> Result<bool, StoreError> {
        let mut b = [0u8; CHUNK];
        for (n, c) in piece.chunks(CHUNK).enumerate() {
            self.read_at(s, lo + n * CHUNK, &mut b[..c.len()])?;
            if b[..c.len()] != *c {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// Programs `piece` at `lo` of sector `s` in place when NOR allows it (only clearing
    /// bits), the words' other bytes written as they are.
    fn program(&mut self, s: u8, lo: usize, piece: &[u8]) -> Result<Program, StoreError> {
        // First check every word, then write: a refused piece leaves the sector untouched.
        let mut b = [0u8; CHUNK + 8];
        let mut same = true;
        for pass in 0..2 {
            let mut at = lo;
            let hi = lo + piece.len();
            while at < hi {
                let start = at - at % 4;
                let stop = (start + CHUNK).min(hi.next_multiple_of(4));
                let w = &mut b[..stop - start];
                self.read_at(s, start, w)?;
                let from = at.max(start);
                let to = hi.min(stop);
                let mut differs = false;
                for (j, &n) in piece[from - lo..to - lo].iter().enumerate() {
                    let o = w[from - start + j];
                    if n & !o != 0 {
                        return Ok(Program::NeedsErase);
                    }
                    differs |= n != o;
                    w[from - start + j] = n;
                }
                if pass == 1 && differs {
                    let a = self.addr(s) + start as u32;
                    self.write_raw(a, &b[..stop - start])?;
                }
                same &= !differs;
                at = stop;
            }
            if same {
                return Ok(Program::Same);
            }
        }
        Ok(Program::Done)
    }

    /// Copies sector `k` of the file to a free sector with `piece` at `lo`, and names the
    /// copy in `new` (the old sector is given up when `new` commits).
    #[allow(clippy::too_many_arguments)]
    fn copy_on_write(
        &mut self,
        new: &mut Entry,
        committed: usize,
        k: usize,
        lo: usize,
        piece: &[u8],
        taken: &mut u64,
        given: &mut u64,
    ) -> Result<(), StoreError> {
        let from = new.sectors[k];
        let to = self.take(*taken | self.used)?;
        *taken |= 1 << to;
        self.counters.copies = self.counters.copies.wrapping_add(1);
        let valid = committed.saturating_sub(k * SECTOR);
        let (a, z) = (self.addr(from), self.addr(to));
        self.copy_unit(a, z, SECTOR, valid, lo, piece)?;
        if *taken & (1 << from) != 0 {
            // A sector this call took and now replaces: free again at once.
            *taken &= !(1 << from);
        } else {
            *given |= 1 << from;
        }
        new.sectors[k] = to;
        Ok(())
    }

    /// Copies the `unit` bytes at `from` to the blank `to`, the first `valid` of them (the
    /// rest as erased) with `piece` at `lo` over them.
    fn copy_unit(
        &mut self,
        from: u32,
        to: u32,
        unit: usize,
        valid: usize,
        lo: usize,
        piece: &[u8],
    ) -> Result<(), StoreError> {
        let hi = lo + piece.len();
        let mut b = [0u8; CHUNK];
        for start in (0..unit).step_by(CHUNK) {
            self.read_raw(from + start as u32, &mut b)?;
            for (j, x) in b.iter_mut().enumerate() {
                if start + j >= valid {
                    *x = 0xFF;
                }
            }
            let (a, z) = (lo.max(start), hi.min(start + CHUNK));
            if a < z {
                b[a - start..z - start].copy_from_slice(&piece[a - lo..z - lo]);
            }
            if b.iter().any(|&x| x != 0xFF) {
                self.write_raw(to + start as u32, &b)?;
            }
        }
        Ok(())
    }

    fn list(&self, f: &mut dyn FnMut(&FileName, u64)) {
        // Name order without a buffer: each round the least name above the last.
        let mut last: Option<&FileName> = None;
        loop {
            let next = self
                .dir
                .iter()
                .flatten()
                .filter(|e| last.is_none_or(|l| &e.name > l))
                .min_by(|a, b| a.name.cmp(&b.name));
            match next {
                Some(e) => {
                    f(&e.name, u64::from(e.len));
                    last = Some(&e.name);
                }
                None => return,
            }
        }
    }

    fn free(&self) -> u64 {
        promise(self.free_sectors())
    }
}

/// The bytes one file can still grow by with `free` free sectors, kept honest for every
/// kind of growth: the reserve stays (so changed bytes always find sectors to be copied
/// to), and a small file growing past its block needs sectors for the bytes its block
/// held too — at most one block more than its growth.
fn promise(free: usize) -> u64 {
    ((free.saturating_sub(RESERVE_SECTORS) * SECTOR).saturating_sub(BLOCK)) as u64
}

enum Program {
    Done,
    Same,
    NeedsErase,
}

impl<F: MultiwriteNorFlash> FlatStore for FlashStore<F> {
    fn len(&self, name: &FileName) -> Result<Option<u64>, StoreError> {
        self.with(|i| Ok(i.len(name)))
    }

    fn create(&self, name: &FileName) -> Result<(), StoreError> {
        self.with(|i| i.create(name))
    }

    fn read(&self, name: &FileName, offset: u64, buf: &mut [u8]) -> Result<(), StoreError> {
        self.with(|i| i.read(name, offset, buf))
    }

    fn write(&self, name: &FileName, offset: u64, data: &[u8]) -> Result<(), StoreError> {
        self.with(|i| i.write(name, offset, data))
    }

    fn remove(&self, name: &FileName) -> Result<(), StoreError> {
        self.with(|i| i.remove(name))
    }

    fn rename(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        self.with(|i| i.rename(from, to))
    }

    fn replace(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        self.with(|i| i.replace(from, to))
    }

    fn list(&self, f: &mut dyn FnMut(&FileName, u64)) -> Result<(), StoreError> {
        self.with(|i| {
            i.list(f);
            Ok(())
        })
    }

    fn free(&self) -> Result<u64, StoreError> {
        self.with(|i| Ok(i.free()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_storage::nor_flash::{NorFlashError, NorFlashErrorKind};
    use proptest::prelude::*;

    /// A RAM NOR flash: reads and writes of words, writes only clear bits.
    struct Ram(std::vec::Vec<u8>);

    #[derive(Debug)]
    struct Refused;

    impl NorFlashError for Refused {
        fn kind(&self) -> NorFlashErrorKind {
            NorFlashErrorKind::Other
        }
    }

    impl ErrorType for Ram {
        type Error = Refused;
    }

    impl ReadNorFlash for Ram {
        const READ_SIZE: usize = 4;
        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Refused> {
            let o = offset as usize;
            bytes.copy_from_slice(self.0.get(o..o + bytes.len()).ok_or(Refused)?);
            Ok(())
        }
        fn capacity(&self) -> usize {
            self.0.len()
        }
    }

    impl NorFlash for Ram {
        const WRITE_SIZE: usize = 4;
        const ERASE_SIZE: usize = SECTOR;
        fn erase(&mut self, from: u32, to: u32) -> Result<(), Refused> {
            self.0.get_mut(from as usize..to as usize).ok_or(Refused)?.fill(0xFF);
            Ok(())
        }
        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Refused> {
            let o = offset as usize;
            let m = self.0.get_mut(o..o + bytes.len()).ok_or(Refused)?;
            if m.iter().zip(bytes).any(|(m, b)| b & !m != 0) {
                return Err(Refused);
            }
            m.copy_from_slice(bytes);
            Ok(())
        }
    }

    impl MultiwriteNorFlash for Ram {}

    const REGION: core::ops::Range<u32> = 0..16 * SECTOR as u32;

    fn entry(name: &str, len: u32, sectors: &[u8], block: Option<u8>) -> Entry {
        Entry {
            name: FileName::new(name).unwrap(),
            len,
            sectors: heapless::Vec::from_slice(sectors).unwrap(),
            block,
        }
    }

    // verifies: FILE-STORE-04
    #[test]
    fn a_full_entry_takes_the_bytes_the_layout_counts_with() {
        let overhead = MapStorage::<u8, Blocking<Ram>, DirCache>::item_overhead_size() as usize;
        assert_eq!(ENTRY_ITEM, overhead + (1 + ENTRY_MAX).next_multiple_of(4));
        // 64 of them fill less than two of the directory's pages (less their markers).
        const { assert!(MAX_FILES * ENTRY_ITEM < 2 * (SECTOR - 8)) };
    }

    // verifies: FILE-STORE-04
    #[test]
    fn entries_decode_as_encoded_and_unsound_ones_are_refused() {
        let data_sectors = 12;
        for e in [
            entry("a", 0, &[], None),
            entry("b.bin", 9000, &[3, 0, 11], None),
            entry(&"n".repeat(MAX_NAME_LEN), 1024, &[5], Some(3)),
        ] {
            let mut v = [0u8; ENTRY_MAX];
            let k = e.encode(7, &mut v);
            assert_eq!(Entry::decode(&v[..k], data_sectors), Some(Some((e.clone(), 7))));
            assert_eq!(Entry::decode(&v[..k - 1], data_sectors), None, "cut short");
            let mut longer = v[..k].to_vec();
            longer.push(0);
            assert_eq!(Entry::decode(&longer, data_sectors), None, "a byte too many");
        }
        assert_eq!(Entry::decode(&[KIND_FREE], data_sectors), Some(None));
        for bad in [
            entry("a", 9000, &[3, 0], None),  // longer than its sectors
            entry("a", 10, &[12], None),      // a sector past the region
            entry("a", 1025, &[1], Some(0)),  // longer than a block
            entry("a", 10, &[1], Some(4)),    // no such block
            entry("a", 10, &[1, 2], Some(0)), // a small file in two sectors
        ] {
            let mut v = [0u8; ENTRY_MAX];
            let k = bad.encode(1, &mut v);
            assert_eq!(Entry::decode(&v[..k], data_sectors), None, "{bad:?}");
        }
        let mut v = [0u8; ENTRY_MAX];
        let k = entry("a", 1, &[1], None).encode(1, &mut v);
        v[6] = b'/';
        assert_eq!(
            Entry::decode(&v[..k], data_sectors),
            None,
            "a name that is not a file name"
        );
    }

    // Of two entries that claim the same sector, the same block of a shared sector or the
    // same name, the later one is the file; the other is left out at open, counted, and
    // freed (the next open does not see it): no two files share bytes.
    // verifies: FILE-STORE-04
    #[test]
    fn entries_that_clash_are_left_out_at_open_and_counted() {
        let s = FlashStore::open(Ram(std::vec![0xFF; REGION.end as usize]), REGION).unwrap();
        {
            let mut i = s.inner.borrow_mut();
            i.commit(0, Some(&entry("a", 5000, &[0, 1], None))).unwrap();
            i.commit(1, Some(&entry("b", 10, &[1], None))).unwrap();
            i.commit(2, Some(&entry("c", 10, &[2], Some(1)))).unwrap();
            i.commit(3, Some(&entry("d", 10, &[2], Some(1)))).unwrap();
            i.commit(4, Some(&entry("e", 10, &[0], Some(0)))).unwrap();
            i.commit(5, Some(&entry("a", 10, &[3], None))).unwrap();
            i.commit(6, Some(&entry("f", 10, &[2], Some(2)))).unwrap();
        }
        let s = FlashStore::open(s.into_flash(), REGION).unwrap();
        let listing = |s: &FlashStore<Ram>| {
            let mut names = std::vec::Vec::new();
            s.list(&mut |n, l| names.push((n.as_str().to_string(), l))).unwrap();
            names
        };
        let want = [("a", 10), ("b", 10), ("d", 10), ("e", 10), ("f", 10)].map(|(n, l)| (n.to_string(), l));
        // c: d's block, stored before d; the first a: the later a's name, and b's sector.
        assert_eq!(listing(&s), want);
        assert_eq!((s.counters().superseded, s.counters().bad_entries), (2, 0));
        let s = FlashStore::open(s.into_flash(), REGION).unwrap();
        assert_eq!(listing(&s), want);
        assert_eq!(s.counters().superseded, 0, "freed at the last open");
    }

    proptest! {
        // verifies: FILE-STORE-04
        #[test]
        fn any_bytes_decode_without_a_panic(v in proptest::collection::vec(any::<u8>(), 0..120)) {
            let _ = Entry::decode(&v, MAX_DATA_SECTORS);
        }
    }
}
