//! The persisted link state: SDLS counters and the on-board FARM-1 state.
//!
//! **Record** (`no_std`, the same layout for the host file and a firmware flash area): a
//! fixed [`SLOT_LEN`]-byte slot, two slots written alternately (slot = sequence mod 2):
//!
//! ```text
//! 0..8     magic "MMICLS02"
//! 8..16    sequence (u64, big-endian): the slot's write number; the newer slot wins
//! 16       number of counter entries n (≤ 16)
//! 17       FARM-1 flags: bit 0 record present, bit 1 lockout; bits 2..7 zero
//! 18       V(R)
//! 19       FARM-B counter
//! 20..324  16 entries × 19 bytes: direction (1 transmit, 2 receive), SPI (u16), value (u128)
//! 324..326 on board: the TM SPI in use (u16; 0 = the first of `mib::link::sdls::TM_SPIS`)
//! 326      on board: retired TC SPIs, bit i = `TC_SPIS[i]` (refused until activated again)
//! 327..508 zero
//! 508..512 CRC-32/ISO-HDLC over bytes 0..508
//! ```
//! The CRC sits at a fixed place and covers the whole slot, so every single-bit error and
//! every truncation is detected. A torn or corrupt slot is refused and the other slot —
//! the previous state, still valid because a write only touches one slot — is used.
//! Slots of the first format ("MMICIV01", no FARM-1 record) are still read.
//!
//! **Host file** ([`FileIvStore`], `std`): the two slots in a file preallocated to
//! [`FILE_LEN`] when it is created (written, `fsync`ed, directory `fsync`ed once). Each
//! update overwrites the older slot in place with one `pwrite` on the file opened
//! `O_DSYNC` (durable when it returns, as `pwrite` + `fdatasync`; other platforms: the
//! explicit `fdatasync`): no rename, no directory sync, no change of size, so the sync
//! carries no metadata. A crash during a
//! write leaves the other slot, one update older than the one being written, whose frame
//! therefore had not been used (the caller uses a frame only after the write returned).
//!
//! **Key files** hold the raw 32 bytes (what Yamcs' `keyFile` reads). They are never printed;
//! errors name the file, never its content.

use core::fmt;

use crate::farm::FarmRecord;

/// Counter entries a record holds (SPIs of both directions).
pub const MAX_ENTRIES: usize = 16;
/// Bytes of one slot.
pub const SLOT_LEN: usize = 512;
/// Bytes of the two slots (the host file's size, a flash area's minimum).
pub const FILE_LEN: usize = 2 * SLOT_LEN;
const MAGIC: &[u8; 8] = b"MMICLS02";
const MAGIC_V1: &[u8; 8] = b"MMICIV01";
const ENTRY: usize = 1 + 2 + 16;
const ENTRIES_AT: usize = 20;
const SELECTION_AT: usize = ENTRIES_AT + MAX_ENTRIES * ENTRY;
const CRC_AT: usize = SLOT_LEN - 4;
const FARM_PRESENT: u8 = 1;
const FARM_LOCKOUT: u8 = 2;
/// Firmware: no table (no flash for it; a slot is written once per TC frame, flash
/// programming dominates).
#[cfg(not(feature = "std"))]
const CRC32: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);
/// Host (`std`): slice-by-16 (16 KiB of tables). The byte-wise table took ≈ 1 µs per slot,
/// on every TC frame (robot) and TM frame (ground): measurable in the ping round trip.
#[cfg(feature = "std")]
const CRC32: crc::Crc<u32, crc::Table<16>> = crc::Crc::<u32, crc::Table<16>>::new(&crc::CRC_32_ISO_HDLC);

/// Which counter an entry is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dir {
    /// Transmit high-water mark.
    Tx,
    /// Last accepted receive IV.
    Rx,
}

impl Dir {
    fn code(self) -> u8 {
        match self {
            Dir::Tx => 1,
            Dir::Rx => 2,
        }
    }

    fn from_code(c: u8) -> Option<Dir> {
        match c {
            1 => Some(Dir::Tx),
            2 => Some(Dir::Rx),
            _ => None,
        }
    }
}

/// One stored counter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Entry {
    pub dir: Dir,
    pub spi: u16,
    pub value: u128,
}

/// Why a slot is not a valid record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// Fewer than [`SLOT_LEN`] bytes (a truncated file).
    Truncated(usize),
    /// CRC mismatch: a torn write or corruption (also an erased or zeroed slot).
    BadCrc,
    /// CRC right, but not a record of a known format.
    BadMagic,
    /// The sequence number does not belong in this slot.
    WrongSlot,
    /// More entries than [`MAX_ENTRIES`].
    TooManyEntries(u8),
    /// Unknown direction code or reserved FARM-1 bits set.
    BadField,
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordError::Truncated(n) => write!(f, "slot of {n} bytes, {SLOT_LEN} expected"),
            RecordError::BadCrc => write!(f, "CRC mismatch (torn write or corruption)"),
            RecordError::BadMagic => write!(f, "not a link state record"),
            RecordError::WrongSlot => write!(f, "sequence number of the other slot"),
            RecordError::TooManyEntries(n) => write!(f, "{n} counter entries, at most {MAX_ENTRIES}"),
            RecordError::BadField => write!(f, "unknown field value"),
        }
    }
}

impl core::error::Error for RecordError {}

/// The record is full (more than [`MAX_ENTRIES`] counters).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecordFull;

impl fmt::Display for RecordFull {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "more than {MAX_ENTRIES} counters for one link state record")
    }
}

/// The persisted link state: counters and (on board) FARM-1.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LinkRecord {
    /// Write number; slot = sequence mod 2.
    pub sequence: u64,
    pub entries: heapless::Vec<Entry, MAX_ENTRIES>,
    pub farm: Option<FarmRecord>,
    /// On board: the TM SPI in use (`None`: the first of `TM_SPIS`).
    pub tm_spi: Option<u16>,
    /// On board: retired TC SPIs, bit i = `TC_SPIS[i]`.
    pub tc_retired: u8,
}

impl LinkRecord {
    /// The stored value of a counter.
    pub fn get(&self, dir: Dir, spi: u16) -> Option<u128> {
        self.entries
            .iter()
            .find(|e| e.dir == dir && e.spi == spi)
            .map(|e| e.value)
    }

    /// Sets a counter (adds it when new).
    pub fn set(&mut self, dir: Dir, spi: u16, value: u128) -> Result<(), RecordFull> {
        match self.entries.iter_mut().find(|e| e.dir == dir && e.spi == spi) {
            Some(e) => {
                e.value = value;
                Ok(())
            }
            None => self.entries.push(Entry { dir, spi, value }).map_err(|_| RecordFull),
        }
    }

    /// The slot this record is written to.
    pub fn slot(&self) -> usize {
        (self.sequence % 2) as usize
    }

    /// The record's slot bytes.
    pub fn encode(&self) -> [u8; SLOT_LEN] {
        let mut b = [0u8; SLOT_LEN];
        b[..8].copy_from_slice(MAGIC);
        b[8..16].copy_from_slice(&self.sequence.to_be_bytes());
        b[16] = self.entries.len() as u8;
        if let Some(f) = self.farm {
            b[17] = FARM_PRESENT | if f.lockout { FARM_LOCKOUT } else { 0 };
            b[18] = f.vr;
            b[19] = f.farm_b;
        }
        b[SELECTION_AT..SELECTION_AT + 2].copy_from_slice(&self.tm_spi.unwrap_or(0).to_be_bytes());
        b[SELECTION_AT + 2] = self.tc_retired;
        for (e, chunk) in self.entries.iter().zip(b[ENTRIES_AT..].chunks_exact_mut(ENTRY)) {
            chunk[0] = e.dir.code();
            chunk[1..3].copy_from_slice(&e.spi.to_be_bytes());
            chunk[3..19].copy_from_slice(&e.value.to_be_bytes());
        }
        let crc = CRC32.checksum(&b[..CRC_AT]);
        b[CRC_AT..].copy_from_slice(&crc.to_be_bytes());
        b
    }

    /// Decodes the slot at index `slot` (0 or 1) from its bytes (at least [`SLOT_LEN`]).
    pub fn decode(bytes: &[u8], slot: usize) -> Result<LinkRecord, RecordError> {
        let b = bytes.get(..SLOT_LEN).ok_or(RecordError::Truncated(bytes.len()))?;
        if &b[..8] == MAGIC_V1 {
            return decode_v1(b, slot);
        }
        let crc = u32::from_be_bytes([b[CRC_AT], b[CRC_AT + 1], b[CRC_AT + 2], b[CRC_AT + 3]]);
        if CRC32.checksum(&b[..CRC_AT]) != crc {
            return Err(RecordError::BadCrc);
        }
        if &b[..8] != MAGIC {
            return Err(RecordError::BadMagic);
        }
        let sequence = be_u64(&b[8..16]);
        if (sequence % 2) as usize != slot {
            return Err(RecordError::WrongSlot);
        }
        let n = b[16];
        if usize::from(n) > MAX_ENTRIES {
            return Err(RecordError::TooManyEntries(n));
        }
        let farm = match b[17] {
            0 => None,
            FARM_PRESENT => Some(false),
            f if f == FARM_PRESENT | FARM_LOCKOUT => Some(true),
            _ => return Err(RecordError::BadField),
        }
        .map(|lockout| FarmRecord {
            vr: b[18],
            lockout,
            farm_b: b[19],
        });
        let entries = decode_entries(&b[ENTRIES_AT..], usize::from(n))?;
        let tm_spi = match u16::from_be_bytes([b[SELECTION_AT], b[SELECTION_AT + 1]]) {
            0 => None,
            s => Some(s),
        };
        let tc_retired = b[SELECTION_AT + 2];
        if u32::from(tc_retired) >> mib::link::sdls::TC_SPIS.len() != 0 {
            return Err(RecordError::BadField);
        }
        Ok(LinkRecord {
            sequence,
            entries,
            farm,
            tm_spi,
            tc_retired,
        })
    }
}

fn be_u64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_be_bytes(a)
}

fn decode_entries(b: &[u8], n: usize) -> Result<heapless::Vec<Entry, MAX_ENTRIES>, RecordError> {
    let mut v = heapless::Vec::new();
    for e in b.chunks_exact(ENTRY).take(n) {
        let dir = Dir::from_code(e[0]).ok_or(RecordError::BadField)?;
        let mut val = [0u8; 16];
        val.copy_from_slice(&e[3..19]);
        let entry = Entry {
            dir,
            spi: u16::from_be_bytes([e[1], e[2]]),
            value: u128::from_be_bytes(val),
        };
        v.push(entry).map_err(|_| RecordError::TooManyEntries(n as u8))?;
    }
    Ok(v)
}

/// The first format (`MMICIV01`): magic, generation, n, entries, CRC after the entries.
fn decode_v1(b: &[u8], slot: usize) -> Result<LinkRecord, RecordError> {
    let n = b[16];
    if usize::from(n) > MAX_ENTRIES {
        return Err(RecordError::TooManyEntries(n));
    }
    let end = 17 + usize::from(n) * ENTRY;
    let crc = u32::from_be_bytes([b[end], b[end + 1], b[end + 2], b[end + 3]]);
    if CRC32.checksum(&b[..end]) != crc {
        return Err(RecordError::BadCrc);
    }
    let sequence = be_u64(&b[8..16]);
    if (sequence % 2) as usize != slot {
        return Err(RecordError::WrongSlot);
    }
    Ok(LinkRecord {
        sequence,
        entries: decode_entries(&b[17..end], usize::from(n))?,
        farm: None,
        tm_spi: None,
        tc_retired: 0,
    })
}

/// What loading two slots gave.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Loaded {
    /// The newest valid record.
    pub record: LinkRecord,
    /// A slot that was not valid (index, why): after a crash during a write, the slot
    /// being written; otherwise corruption. The other slot was used.
    pub bad_slot: Option<(usize, RecordError)>,
}

/// Both slots are invalid: the state is lost.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BothSlotsBad(pub RecordError, pub RecordError);

/// Picks the newest valid record of the two slots in `bytes` (at least [`FILE_LEN`]
/// bytes; fewer make the missing slot invalid).
pub fn load(bytes: &[u8]) -> Result<Loaded, BothSlotsBad> {
    let a = LinkRecord::decode(bytes, 0);
    let b = LinkRecord::decode(bytes.get(SLOT_LEN..).unwrap_or(&[]), 1);
    match (a, b) {
        (Ok(a), Ok(b)) => Ok(Loaded {
            record: if a.sequence >= b.sequence { a } else { b },
            bad_slot: None,
        }),
        (Ok(record), Err(e)) => Ok(Loaded {
            record,
            bad_slot: Some((1, e)),
        }),
        (Err(e), Ok(record)) => Ok(Loaded {
            record,
            bad_slot: Some((0, e)),
        }),
        (Err(a), Err(b)) => Err(BothSlotsBad(a, b)),
    }
}

#[cfg(any(test, feature = "std"))]
pub use host::*;

#[cfg(any(test, feature = "std"))]
mod host {
    use std::fs::{File, OpenOptions};
    use std::io::{Read, Write};
    use std::path::{Path, PathBuf};

    use super::{load, BothSlotsBad, Dir, LinkRecord, RecordError, FILE_LEN, SLOT_LEN};
    use crate::farm::FarmRecord;
    use crate::sdls::{IvStore, Key, StoreError};

    /// Why a state or key file could not be used.
    #[derive(Debug)]
    #[non_exhaustive]
    pub enum PersistError {
        Io {
            path: PathBuf,
            error: std::io::Error,
        },
        /// The state file exists but neither slot is valid.
        Corrupt {
            path: PathBuf,
            slots: BothSlotsBad,
        },
        /// A key file that is not exactly 32 bytes (its content is never shown).
        KeyLength {
            path: PathBuf,
            len: usize,
        },
        /// `create_key_file` refuses to overwrite.
        Exists {
            path: PathBuf,
        },
    }

    impl std::fmt::Display for PersistError {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            match self {
                PersistError::Io { path, error } => write!(f, "{}: {error}", path.display()),
                PersistError::Corrupt { path, slots } => write!(
                    f,
                    "{}: no valid link state slot (slot 0: {}; slot 1: {}): the SDLS counters are lost. \
                     Never delete it to start again with the same keys (captured frames would be \
                     accepted again and TM nonces reused): change both keys, then remove the file",
                    path.display(),
                    slots.0,
                    slots.1
                ),
                PersistError::KeyLength { path, len } => {
                    write!(
                        f,
                        "{}: a key file holds exactly 32 raw bytes, this one {len}",
                        path.display()
                    )
                }
                PersistError::Exists { path } => write!(f, "{}: exists; not overwritten", path.display()),
            }
        }
    }

    impl std::error::Error for PersistError {}

    fn io(path: &Path) -> impl FnOnce(std::io::Error) -> PersistError + '_ {
        move |error| PersistError::Io {
            path: path.to_path_buf(),
            error,
        }
    }

    #[cfg(unix)]
    fn write_at(file: &File, buf: &[u8], off: u64) -> std::io::Result<()> {
        std::os::unix::fs::FileExt::write_all_at(file, buf, off)
    }

    #[cfg(not(unix))]
    fn write_at(mut file: &File, buf: &[u8], off: u64) -> std::io::Result<()> {
        use std::io::{Seek, SeekFrom};
        file.seek(SeekFrom::Start(off))?;
        file.write_all(buf)
    }

    /// Syncs the directory holding `p` (once, when the file is created).
    fn sync_dir(p: &Path) -> std::io::Result<()> {
        let dir = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        match File::open(dir) {
            Ok(d) => d.sync_all(),
            // Not every platform opens directories; the file's own sync still holds.
            Err(_) => Ok(()),
        }
    }

    /// The link state in a file (see the module documentation): SDLS counters and, on
    /// board, FARM-1.
    #[derive(Debug)]
    pub struct FileIvStore {
        path: PathBuf,
        file: File,
        record: LinkRecord,
        bad_slot: Option<(usize, RecordError)>,
        /// Successful writes (each one durable before it returned).
        pub writes: u64,
    }

    impl FileIvStore {
        /// Opens the state file at `path`, or creates it preallocated with two empty slots.
        /// Refuses a file whose two slots are both invalid (never a silent restart of the
        /// counters at 0).
        pub fn open(path: &Path) -> Result<FileIvStore, PersistError> {
            let mut o = OpenOptions::new();
            o.read(true).write(true).create(true).truncate(false);
            // Every write is durable when it returns (synchronized I/O data integrity, what
            // pwrite + fdatasync give, in one system call).
            #[cfg(all(unix, feature = "std"))]
            {
                use std::os::unix::fs::OpenOptionsExt;
                o.custom_flags(libc::O_DSYNC);
            }
            let mut file = o.open(path).map_err(io(path))?;
            let mut bytes = Vec::with_capacity(FILE_LEN);
            file.read_to_end(&mut bytes).map_err(io(path))?;
            let (record, bad_slot) = if bytes.is_empty() {
                // New: both slots written once, the size and the name made durable; from
                // now on every write is in place.
                let first = LinkRecord::default();
                let second = LinkRecord {
                    sequence: 1,
                    ..LinkRecord::default()
                };
                let mut all = [0u8; FILE_LEN];
                all[..SLOT_LEN].copy_from_slice(&first.encode());
                all[SLOT_LEN..].copy_from_slice(&second.encode());
                file.write_all(&all).map_err(io(path))?;
                file.sync_all().map_err(io(path))?;
                sync_dir(path).map_err(io(path))?;
                (second, None)
            } else {
                let l = load(&bytes).map_err(|slots| PersistError::Corrupt {
                    path: path.into(),
                    slots,
                })?;
                if bytes.len() < FILE_LEN {
                    // A file of the first format: preallocated once.
                    file.set_len(FILE_LEN as u64).map_err(io(path))?;
                    file.sync_all().map_err(io(path))?;
                }
                (l.record, l.bad_slot)
            };
            Ok(FileIvStore {
                path: path.into(),
                file,
                record,
                bad_slot,
                writes: 0,
            })
        }

        /// The stored value of a counter.
        pub fn get(&self, dir: Dir, spi: u16) -> Option<u128> {
            self.record.get(dir, spi)
        }

        /// The stored FARM-1 state (none before the first on-board TC frame).
        pub fn farm(&self) -> Option<FarmRecord> {
            self.record.farm
        }

        /// The slot found invalid at open (the other one was used), and why.
        pub fn bad_slot(&self) -> Option<(usize, RecordError)> {
            self.bad_slot
        }

        /// The record as last written.
        pub fn record(&self) -> &LinkRecord {
            &self.record
        }

        pub fn path(&self) -> &Path {
            &self.path
        }

        /// Writes `next` (sequence already advanced) into its slot, durably.
        fn write(&mut self, next: LinkRecord) -> Result<(), PersistError> {
            let slot = next.encode();
            let off = (next.slot() * SLOT_LEN) as u64;
            write_at(&self.file, &slot, off).map_err(io(&self.path))?;
            #[cfg(not(all(unix, feature = "std")))]
            self.file.sync_data().map_err(io(&self.path))?;
            self.record = next;
            self.writes += 1;
            Ok(())
        }

        fn next(&self) -> LinkRecord {
            let mut r = self.record.clone();
            r.sequence += 1;
            r
        }

        fn full(&self) -> PersistError {
            PersistError::Io {
                path: self.path.clone(),
                error: std::io::Error::other(super::RecordFull.to_string()),
            }
        }

        /// Stores `value` for `(dir, spi)`, durably, before returning.
        pub fn put(&mut self, dir: Dir, spi: u16, value: u128) -> Result<(), PersistError> {
            let mut r = self.next();
            r.set(dir, spi, value).map_err(|_| self.full())?;
            self.write(r)
        }

        /// Stores a receive counter and FARM-1's state in one write.
        pub fn put_rx_farm(&mut self, spi: u16, last: u128, farm: FarmRecord) -> Result<(), PersistError> {
            let mut r = self.next();
            r.set(Dir::Rx, spi, last).map_err(|_| self.full())?;
            r.farm = Some(farm);
            self.write(r)
        }

        /// Stores FARM-1's state.
        pub fn put_farm(&mut self, farm: FarmRecord) -> Result<(), PersistError> {
            let mut r = self.next();
            r.farm = Some(farm);
            self.write(r)
        }

        /// Stores the on-board SA selection: the TM SPI in use and the retired TC SPIs
        /// (bit i = `TC_SPIS[i]`).
        pub fn put_selection(&mut self, tm_spi: u16, tc_retired: u8) -> Result<(), PersistError> {
            let mut r = self.next();
            r.tm_spi = Some(tm_spi);
            r.tc_retired = tc_retired;
            self.write(r)
        }
    }

    impl crate::endpoint::StoreStats for FileIvStore {
        fn writes(&self) -> u32 {
            self.writes.min(u64::from(u32::MAX)) as u32
        }
        fn bad_slot(&self) -> u32 {
            self.bad_slot.as_ref().map_or(0, |(slot, _)| *slot as u32 + 1)
        }
    }

    impl IvStore for FileIvStore {
        fn reserve_tx(&mut self, spi: u16, high_water: u128) -> Result<(), StoreError> {
            self.put(Dir::Tx, spi, high_water).map_err(|_| StoreError)
        }

        fn record_rx(&mut self, spi: u16, last: u128) -> Result<(), StoreError> {
            self.put(Dir::Rx, spi, last).map_err(|_| StoreError)
        }

        fn record_rx_farm(&mut self, spi: u16, last: u128, farm: FarmRecord) -> Result<(), StoreError> {
            self.put_rx_farm(spi, last, farm).map_err(|_| StoreError)
        }

        fn record_farm(&mut self, farm: FarmRecord) -> Result<(), StoreError> {
            self.put_farm(farm).map_err(|_| StoreError)
        }
    }

    /// Reads a key file: exactly 32 raw bytes.
    pub fn read_key(path: &Path) -> Result<Key, PersistError> {
        let bytes = std::fs::read(path).map_err(io(path))?;
        let len = bytes.len();
        bytes
            .try_into()
            .map_err(|_| PersistError::KeyLength { path: path.into(), len })
    }

    /// Writes `key` to a new file readable by its owner only (mode 0600 on Unix); refuses to
    /// overwrite an existing file.
    pub fn create_key_file(path: &Path, key: &Key) -> Result<(), PersistError> {
        let mut o = OpenOptions::new();
        o.write(true).create_new(true);
        #[cfg(unix)]
        {
            use std::os::unix::fs::OpenOptionsExt;
            o.mode(0o600);
        }
        let mut f = o.open(path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::AlreadyExists {
                PersistError::Exists { path: path.into() }
            } else {
                PersistError::Io {
                    path: path.into(),
                    error: e,
                }
            }
        })?;
        f.write_all(key).map_err(io(path))?;
        f.sync_all().map_err(io(path))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::farm::{Farm, FarmState};
    use crate::rx::{RxOutcome, TcReceiver};
    use crate::sdls::{build_tc, IvStore, MemoryIvStore, RxSa, RxSas, TxSa};
    use crate::tc::{ControlCommand, FrameType, TcRepr};
    use crate::test_keys::{TEST_KEY_TC_A, TEST_KEY_TM_A};
    use proptest::prelude::*;
    use std::path::PathBuf;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("mmic-link-persist-{}-{name}", std::process::id()));
        let _ = std::fs::remove_file(&d);
        d
    }

    fn sample(sequence: u64) -> LinkRecord {
        let mut r = LinkRecord {
            sequence,
            ..LinkRecord::default()
        };
        r.set(Dir::Tx, 17, 3 * 1024).unwrap();
        r.set(Dir::Rx, 1, (1u128 << 96) - 2).unwrap();
        r.set(Dir::Rx, 2, 77).unwrap();
        r.farm = Some(FarmRecord {
            vr: 201,
            lockout: true,
            farm_b: 3,
        });
        r.tm_spi = Some(18);
        r.tc_retired = 1;
        r
    }

    // verifies: LINK-PERSIST-01
    #[test]
    fn a_record_round_trips_and_every_single_bit_flip_is_refused() {
        for seq in [6u64, 7] {
            let r = sample(seq);
            let b = r.encode();
            assert_eq!(LinkRecord::decode(&b, r.slot()), Ok(r.clone()));
            // In the other slot it is refused (a slot copied to the wrong place).
            assert_eq!(LinkRecord::decode(&b, 1 - r.slot()), Err(RecordError::WrongSlot));
            for bit in 0..SLOT_LEN * 8 {
                let mut f = b;
                f[bit / 8] ^= 1 << (bit % 8);
                assert!(
                    LinkRecord::decode(&f, r.slot()).is_err(),
                    "bit {bit} flipped and still accepted"
                );
            }
        }
        // Without a FARM record, and the empty record.
        let mut r = sample(2);
        r.farm = None;
        assert_eq!(LinkRecord::decode(&r.encode(), 0), Ok(r));
        let e = LinkRecord::default();
        assert_eq!(LinkRecord::decode(&e.encode(), 0), Ok(e));
    }

    // verifies: LINK-PERSIST-01
    #[test]
    fn every_truncation_and_an_erased_or_zeroed_slot_are_refused() {
        let b = sample(4).encode();
        for n in 0..SLOT_LEN {
            assert_eq!(LinkRecord::decode(&b[..n], 0), Err(RecordError::Truncated(n)));
        }
        assert!(LinkRecord::decode(&[0u8; SLOT_LEN], 0).is_err());
        assert!(LinkRecord::decode(&[0xFFu8; SLOT_LEN], 0).is_err());
        // A file cut inside the second slot: the first slot is used.
        let mut file = [0u8; FILE_LEN];
        file[..SLOT_LEN].copy_from_slice(&sample(4).encode());
        file[SLOT_LEN..].copy_from_slice(&sample(5).encode());
        for n in SLOT_LEN..FILE_LEN {
            let l = load(&file[..n]).unwrap();
            assert_eq!(l.record.sequence, 4);
            assert_eq!(l.bad_slot, Some((1, RecordError::Truncated(n - SLOT_LEN))));
        }
        assert_eq!(load(&file).unwrap().record.sequence, 5);
        assert!(load(&file[..SLOT_LEN - 1]).is_err());
    }

    // verifies: LINK-PERSIST-01
    #[test]
    fn a_slot_of_the_first_format_is_still_read() {
        // Layout of the first format: magic, generation, n, entries, CRC after them.
        let mut b = [0u8; SLOT_LEN];
        b[..8].copy_from_slice(MAGIC_V1);
        b[8..16].copy_from_slice(&3u64.to_be_bytes());
        b[16] = 1;
        b[17] = 2;
        b[18..20].copy_from_slice(&1u16.to_be_bytes());
        b[20..36].copy_from_slice(&41u128.to_be_bytes());
        let crc = CRC32.checksum(&b[..36]);
        b[36..40].copy_from_slice(&crc.to_be_bytes());
        let r = LinkRecord::decode(&b, 1).unwrap();
        assert_eq!((r.sequence, r.get(Dir::Rx, 1), r.farm), (3, Some(41), None));
        b[20] ^= 1;
        assert_eq!(LinkRecord::decode(&b, 1), Err(RecordError::BadCrc));
    }

    proptest! {
        // verifies: LINK-PERSIST-01
        #[test]
        fn a_torn_write_at_any_byte_gives_the_old_or_the_new_state(cut in 0usize..=SLOT_LEN, seq in 2u64..1000) {
            // Slot of `seq` holds the state before; the write of seq + 2 into the same slot
            // stops after `cut` bytes. The other slot holds seq + 1.
            let old = sample(seq);
            let mid = {
                let mut r = sample(seq + 1);
                r.set(Dir::Rx, 1, 5).unwrap();
                r
            };
            let mut new = sample(seq + 2);
            new.set(Dir::Rx, 1, 6).unwrap();
            let mut file = [0u8; FILE_LEN];
            let (o, m) = (old.slot() * SLOT_LEN, mid.slot() * SLOT_LEN);
            file[o..o + SLOT_LEN].copy_from_slice(&old.encode());
            file[m..m + SLOT_LEN].copy_from_slice(&mid.encode());
            let nb = new.encode();
            file[o..o + cut].copy_from_slice(&nb[..cut]);
            let l = load(&file).unwrap();
            prop_assert!(l.record == mid || l.record == new, "{:?}", l.record);
            if cut < SLOT_LEN && l.record == new {
                // Only when the bytes not yet written happened to be the same.
                prop_assert_eq!(&old.encode()[cut..], &nb[cut..]);
            }
        }
    }

    // verifies: LINK-HOST-03, LINK-PERSIST-01
    #[test]
    fn counters_survive_reopen_and_a_torn_slot() {
        let p = tmp("state");
        let mut s = FileIvStore::open(&p).unwrap();
        assert_eq!(std::fs::metadata(&p).unwrap().len(), FILE_LEN as u64, "preallocated");
        s.reserve_tx(17, 1024).unwrap();
        s.record_rx(1, 5).unwrap();
        s.record_rx(1, 6).unwrap();
        assert_eq!(
            std::fs::metadata(&p).unwrap().len(),
            FILE_LEN as u64,
            "written in place"
        );
        drop(s);
        let s = FileIvStore::open(&p).unwrap();
        assert_eq!((s.get(Dir::Tx, 17), s.get(Dir::Rx, 1)), (Some(1024), Some(6)));
        assert_eq!(s.bad_slot(), None);
        // Tear the newest slot (sequence 4 is in slot 0): the previous one is used.
        let mut bytes = std::fs::read(&p).unwrap();
        bytes[20] ^= 0xFF;
        std::fs::write(&p, &bytes).unwrap();
        let s = FileIvStore::open(&p).unwrap();
        assert_eq!((s.get(Dir::Tx, 17), s.get(Dir::Rx, 1)), (Some(1024), Some(5)));
        assert_eq!(s.bad_slot(), Some((0, RecordError::BadCrc)));
        // Both slots bad: refused, never silently reset to zero; the message says why.
        bytes[SLOT_LEN + 20] ^= 0xFF;
        std::fs::write(&p, &bytes).unwrap();
        let e = FileIvStore::open(&p).unwrap_err();
        assert!(matches!(e, PersistError::Corrupt { .. }));
        assert!(e.to_string().contains("change both keys"), "{e}");
        let _ = std::fs::remove_file(&p);
    }

    // verifies: LINK-HOST-03, LINK-PERSIST-02
    #[test]
    fn farm_state_and_receive_iv_survive_a_restart_in_one_write() {
        let p = tmp("farm");
        let build = |tx: &mut TxSa, ns: u8| {
            let mut buf = [0u8; 128];
            let repr = TcRepr {
                frame_type: FrameType::Ad,
                scid: mib::link::SCID,
                vcid: mib::link::tc_vc::COMMAND,
                seq: ns,
                data_len: 0,
            };
            let ping = [0x18, 0x01, 0xC0, 0x00, 0x00, 0x00, 0xAA];
            let n = build_tc(tx, &mut MemoryIvStore::default(), repr, &ping, &mut buf).unwrap();
            buf[..n].to_vec()
        };
        let open = |st: &FileIvStore| {
            let mut sas = RxSas::<2>::default();
            let sa = match st.get(Dir::Rx, 1) {
                Some(l) => RxSa::resume(1, &TEST_KEY_TC_A, 4096, l),
                None => RxSa::new(1, &TEST_KEY_TC_A, 4096),
            };
            sas.insert(sa).unwrap();
            let farm = st.farm().map_or_else(Farm::mission, Farm::mission_restored);
            TcReceiver::new(mib::link::SCID, mib::link::tc_vc::COMMAND, farm, sas)
        };
        let mut tx = TxSa::resume(1, &TEST_KEY_TC_A, 0);
        let mut st = FileIvStore::open(&p).unwrap();
        let mut rx = open(&st);
        let frames: Vec<_> = (0..4).map(|ns| build(&mut tx, ns)).collect();
        for f in &frames[..3] {
            let w = st.writes;
            assert!(matches!(
                rx.receive(&mut st, &mut f.clone(), true),
                RxOutcome::Accepted { .. }
            ));
            assert_eq!(st.writes, w + 1, "one write per accepted frame");
        }
        drop((rx, st));
        // Restart: V(R) = 3, the captured frames are replays, frame 3 continues.
        let mut st = FileIvStore::open(&p).unwrap();
        let mut rx = open(&st);
        assert_eq!((rx.farm.vr(), rx.farm.state()), (3, FarmState::Open));
        for f in &frames[..3] {
            assert!(matches!(
                rx.receive(&mut st, &mut f.clone(), true),
                RxOutcome::Rejected(_)
            ));
        }
        assert_eq!(rx.counters.replay, 3);
        assert!(matches!(
            rx.receive(&mut st, &mut frames[3].clone(), true),
            RxOutcome::Accepted { seq: 3, .. }
        ));
        // Lockout survives a restart (only Unlock leaves it); a control frame is persisted.
        let far = build(&mut tx, 100);
        assert!(matches!(
            rx.receive(&mut st, &mut far.clone(), true),
            RxOutcome::Discarded(_)
        ));
        drop((rx, st));
        let mut st = FileIvStore::open(&p).unwrap();
        let mut rx = open(&st);
        assert_eq!((rx.farm.vr(), rx.farm.state()), (4, FarmState::Lockout));
        let mut unlock = [0u8; 16];
        let n = ControlCommand::Unlock
            .build_frame(mib::link::SCID, mib::link::tc_vc::COMMAND, &mut unlock)
            .unwrap();
        assert!(matches!(
            rx.receive(&mut st, &mut unlock[..n], true),
            RxOutcome::Control(_)
        ));
        drop((rx, st));
        let st = FileIvStore::open(&p).unwrap();
        let f = Farm::mission_restored(st.farm().unwrap());
        assert_eq!((f.vr(), f.state(), f.farm_b_counter()), (4, FarmState::Open, 1));
        let _ = std::fs::remove_file(&p);
    }

    // verifies: LINK-PERSIST-02
    #[test]
    fn a_store_failure_refuses_the_frame_and_changes_neither_sdls_nor_farm() {
        let mut tx = TxSa::resume(1, &TEST_KEY_TC_A, 0);
        let mut sas = RxSas::<2>::default();
        sas.insert(RxSa::new(1, &TEST_KEY_TC_A, 4096)).unwrap();
        let mut rx = TcReceiver::mission(sas);
        let mut st = MemoryIvStore::default();
        let mut buf = [0u8; 128];
        let repr = TcRepr {
            frame_type: FrameType::Ad,
            scid: mib::link::SCID,
            vcid: mib::link::tc_vc::COMMAND,
            seq: 0,
            data_len: 0,
        };
        let ping = [0x18, 0x01, 0xC0, 0x00, 0x00, 0x00, 0xAA];
        let n = build_tc(&mut tx, &mut MemoryIvStore::default(), repr, &ping, &mut buf).unwrap();
        st.fail = true;
        let clcw = rx.farm.clcw();
        assert!(matches!(
            rx.receive(&mut st, &mut buf[..n].to_vec(), true),
            RxOutcome::Rejected(_)
        ));
        assert_eq!((rx.farm.clcw(), rx.counters.counter_store_failed), (clcw, 1));
        let mut unlock = [0u8; 16];
        let k = ControlCommand::SetVr(9)
            .build_frame(mib::link::SCID, mib::link::tc_vc::COMMAND, &mut unlock)
            .unwrap();
        assert!(matches!(
            rx.receive(&mut st, &mut unlock[..k], true),
            RxOutcome::Rejected(_)
        ));
        assert_eq!(rx.farm.clcw(), clcw);
        // The store works again: the same frame is accepted (its IV was never used).
        st.fail = false;
        assert!(matches!(
            rx.receive(&mut st, &mut buf[..n].to_vec(), true),
            RxOutcome::Accepted { .. }
        ));
        assert_eq!((st.rx_last(1), st.farm.map(|f| f.vr)), (Some(0), Some(1)));
    }

    // verifies: LINK-HOST-03
    #[test]
    fn a_transmit_sa_never_reuses_an_iv_across_restarts() {
        let p = tmp("tx");
        let mut seen = std::collections::BTreeSet::new();
        for _run in 0..3 {
            let mut st = FileIvStore::open(&p).unwrap();
            let hw = st.get(Dir::Tx, 17).unwrap_or(0);
            let mut sa = TxSa::resume(17, &TEST_KEY_TM_A, hw);
            for _ in 0..10 {
                let mut f = [0u8; 64];
                sa.apply_tm(&mut st, &mut f).unwrap();
                let iv = crate::sdls::iv_value(f[8..20].try_into().unwrap());
                assert!(seen.insert(iv), "IV {iv} reused");
            }
        }
        assert!(seen.iter().max().unwrap() >= &2048, "one block skipped per restart");
        let _ = std::fs::remove_file(&p);
    }

    // verifies: LINK-HOST-03
    #[test]
    fn key_files_are_exact_and_never_overwritten() {
        let p = tmp("key");
        create_key_file(&p, &TEST_KEY_TM_A).unwrap();
        assert_eq!(read_key(&p).unwrap(), TEST_KEY_TM_A);
        assert!(matches!(
            create_key_file(&p, &TEST_KEY_TM_A),
            Err(PersistError::Exists { .. })
        ));
        std::fs::write(&p, b"short").unwrap();
        let e = read_key(&p).unwrap_err();
        assert!(matches!(e, PersistError::KeyLength { len: 5, .. }));
        assert!(!e.to_string().contains("short"));
        let _ = std::fs::remove_file(&p);
    }
}
