//! The file store: a flat set of named files behind a checked interface.
//!
//! Every name that reaches a platform store is a [`FileName`]: at most
//! `mib::cfdp::MAX_NAME_LEN` bytes of ASCII letters, digits, `.`, `_` and `-`, not starting
//! with `.`. There are no directories, so no name can reach outside the store (no `/`, no
//! `..`, no absolute path, no NUL). Every length is checked as well: a write beyond
//! `mib::cfdp::MAX_FILE_LEN`, past the store's free space, or a file more than
//! `mib::cfdp::MAX_FILES` is refused. [`Checked`] puts these checks in front of a platform's
//! [`FlatStore`] (a host directory: `DirStore`; board A's flash: `flash::FlashStore`) and gives
//! cfdp-rs its `VirtualFilestore`; a refusal is counted ([`Checked::counters`]).

use core::cell::Cell;

use ::cfdp::filestore::{FilestoreError, VirtualFilestore};
use mib::cfdp::{MAX_FILES, MAX_FILE_LEN, MAX_NAME_LEN};
use spacepackets::cfdp::ChecksumType;

/// Why a name was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NameError {
    Empty,
    TooLong(usize),
    /// A byte outside `[A-Za-z0-9._-]` (a `/`, a NUL, a space, non-ASCII) at this index.
    BadByte(usize),
    /// Starts with `.` (hidden files, `.` and `..`).
    LeadingDot,
}

impl core::fmt::Display for NameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            NameError::Empty => write!(f, "empty file name"),
            NameError::TooLong(n) => write!(f, "file name of {n} bytes (at most {MAX_NAME_LEN})"),
            NameError::BadByte(i) => write!(
                f,
                "file names are letters, digits, '.', '_' and '-' (no directories); byte {i} is not"
            ),
            NameError::LeadingDot => write!(f, "file names do not start with '.'"),
        }
    }
}

impl core::error::Error for NameError {}

/// A checked file name (see the module documentation).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct FileName(heapless::String<MAX_NAME_LEN>);

impl FileName {
    pub fn new(s: &str) -> Result<FileName, NameError> {
        let b = s.as_bytes();
        if b.is_empty() {
            return Err(NameError::Empty);
        }
        if b.len() > MAX_NAME_LEN {
            return Err(NameError::TooLong(b.len()));
        }
        if let Some(i) = b
            .iter()
            .position(|c| !(c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'-')))
        {
            return Err(NameError::BadByte(i));
        }
        if b[0] == b'.' {
            return Err(NameError::LeadingDot);
        }
        let mut n = heapless::String::new();
        // Checked above: at most MAX_NAME_LEN bytes.
        n.push_str(s).map_err(|_| NameError::TooLong(b.len()))?;
        Ok(FileName(n))
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl core::fmt::Display for FileName {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(&self.0)
    }
}

/// What a platform store can fail with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// No such file.
    NotFound,
    /// The file exists (rename onto an existing name).
    Exists,
    /// No room: the store's free space, `MAX_FILE_LEN` or `MAX_FILES`.
    Full,
    /// The medium failed (I/O error, corrupt file system).
    Io,
}

impl core::fmt::Display for StoreError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            StoreError::NotFound => "no such file",
            StoreError::Exists => "the file exists",
            StoreError::Full => "no room in the file store",
            StoreError::Io => "file store I/O error",
        })
    }
}

/// A platform's flat file store; every name is already checked. `&self`: the CFDP
/// handlers share the store (interior mutability is the platform's).
pub trait FlatStore {
    /// Length of the file, `None` when there is none.
    fn len(&self, name: &FileName) -> Result<Option<u64>, StoreError>;
    /// Creates the file empty (truncates an existing one).
    fn create(&self, name: &FileName) -> Result<(), StoreError>;
    /// Reads exactly `buf.len()` bytes at `offset`.
    fn read(&self, name: &FileName, offset: u64, buf: &mut [u8]) -> Result<(), StoreError>;
    /// Writes `data` at `offset` (the file grows as needed).
    fn write(&self, name: &FileName, offset: u64, data: &[u8]) -> Result<(), StoreError>;
    fn remove(&self, name: &FileName) -> Result<(), StoreError>;
    /// Renames `from` to `to`; `Exists` when `to` exists.
    fn rename(&self, from: &FileName, to: &FileName) -> Result<(), StoreError>;
    /// Renames `from` to `to`, replacing `to`'s file if there is one. A platform that can
    /// does it in one step (a reset leaves `to` as it was or as `from` was); this default
    /// removes `to` first, so a reset between the two leaves neither.
    fn replace(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        self.len(from)?.ok_or(StoreError::NotFound)?;
        if from == to {
            return Ok(());
        }
        if self.len(to)?.is_some() {
            self.remove(to)?;
        }
        self.rename(from, to)
    }
    /// Calls `f` with each file's name and length, in name order.
    fn list(&self, f: &mut dyn FnMut(&FileName, u64)) -> Result<(), StoreError>;
    /// Bytes still free.
    fn free(&self) -> Result<u64, StoreError>;
}

/// Counters of the checked store (file store housekeeping).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StoreCounters {
    /// Names refused ([`NameError`]), lengths refused (`Full`), failures of the medium.
    pub bad_names: u32,
    pub full: u32,
    pub io_errors: u32,
    /// File checksums computed whole in one call, not paced by a [`SumJob`] (a path the
    /// entity does not pace: the EOF of a cancellation, a class 1 check-limit retry).
    pub whole_sums: u32,
}

/// Which of the entity's two transfers a checksum job serves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The file being sent: its EOF carries the sum.
    Send,
    /// The file being received: its sum is checked against the sender's.
    Receive,
}

impl Side {
    fn slot(self) -> usize {
        match self {
            Side::Send => 0,
            Side::Receive => 1,
        }
    }
}

/// A file's checksum computed a budget at a time (the entity's `poll`), so no control
/// period reads and sums a whole file; cfdp-rs' single call then takes the result.
struct SumJob {
    name: FileName,
    kind: ChecksumType,
    /// Bytes summed: the first `len`.
    len: u64,
    /// Offset reached, and the partial sum (`None` once done).
    at: u64,
    sum: Option<Checksum>,
    value: Option<u32>,
}

impl SumJob {
    fn is(&self, n: &FileName, kind: ChecksumType, len: u64) -> bool {
        self.name == *n && self.kind == kind && self.len == len
    }
}

/// What the store holds for a checksum cfdp-rs asks for.
enum Cached {
    Value(u32),
    /// Being computed for the file being sent: the source handler's EOF step waits.
    SendPending,
    None,
}

/// Bytes read at a time by a checksum job.
const SUM_CHUNK: usize = 512;

/// The checks in front of a [`FlatStore`], and cfdp-rs' `VirtualFilestore` over them.
pub struct Checked<S> {
    inner: S,
    counters: Cell<StoreCounters>,
    /// A checksum job per [`Side`]. Any change to the part of its file it has summed (a
    /// write of other bytes, create, remove, rename) ends it.
    sums: core::cell::RefCell<[Option<SumJob>; 2]>,
}

fn name(path: &str, c: &Cell<StoreCounters>) -> Result<FileName, FilestoreError> {
    FileName::new(path).map_err(|_| {
        let mut k = c.get();
        k.bad_names = k.bad_names.wrapping_add(1);
        c.set(k);
        FilestoreError::Permission
    })
}

impl<S: FlatStore> Checked<S> {
    pub fn new(inner: S) -> Self {
        Checked {
            inner,
            counters: Cell::new(StoreCounters::default()),
            sums: core::cell::RefCell::new([None, None]),
        }
    }

    /// Starts summing the first `len` bytes of `n` for `side` (kept when that job is
    /// already running or done). A kind without an implementation starts nothing: cfdp-rs'
    /// own call then reports it.
    #[inline(never)]
    pub fn sum_start(&self, side: Side, n: &FileName, kind: ChecksumType, len: u64) {
        let mut sums = self.sums.borrow_mut();
        let slot = &mut sums[side.slot()];
        if slot.as_ref().is_some_and(|j| j.is(n, kind, len)) {
            return;
        }
        *slot = Checksum::new(kind).map(|sum| SumJob {
            name: n.clone(),
            kind,
            len,
            at: 0,
            sum: Some(sum),
            value: None,
        });
    }

    /// Sums at most `budget` more bytes of `side`'s job; returns the bytes read. A read
    /// that fails ends the job (cfdp-rs' own call then meets the error).
    #[inline(never)]
    pub fn sum_advance(&self, side: Side, budget: usize) -> usize {
        let mut sums = self.sums.borrow_mut();
        let slot = &mut sums[side.slot()];
        let Some(job) = slot.as_mut() else { return 0 };
        let mut buf = [0u8; SUM_CHUNK];
        let mut read = 0;
        while let Some(sum) = job.sum.as_mut() {
            let k = (job.len - job.at).min((budget - read).min(SUM_CHUNK) as u64) as usize;
            if k == 0 && job.at < job.len {
                break;
            }
            if k > 0 {
                if self.read(&job.name, job.at, &mut buf[..k]).is_err() {
                    *slot = None;
                    return read;
                }
                sum.update(job.at, &buf[..k]);
                job.at += k as u64;
                read += k;
            }
            if job.at == job.len {
                job.value = job.sum.take().map(Checksum::value);
            }
        }
        read
    }

    /// Whether `side` has a job (none: never started, its kind not implemented, a read
    /// failed, its file changed).
    pub fn sum_running(&self, side: Side) -> bool {
        self.sums.borrow()[side.slot()].is_some()
    }

    /// Whether `side`'s job summed the first `len` bytes of `n` and nothing changed them.
    pub fn sum_ready(&self, side: Side, n: &FileName, kind: ChecksumType, len: u64) -> bool {
        self.sum_value(side, n, kind, len).is_some()
    }

    /// The sum of `side`'s job, when it summed the first `len` bytes of `n` and nothing
    /// changed them.
    #[inline(never)]
    pub fn sum_value(&self, side: Side, n: &FileName, kind: ChecksumType, len: u64) -> Option<u32> {
        self.sums.borrow()[side.slot()]
            .as_ref()
            .filter(|j| j.is(n, kind, len))
            .and_then(|j| j.value)
    }

    #[inline(never)]
    fn cached(&self, n: &FileName, kind: ChecksumType, len: u64) -> Cached {
        let sums = self.sums.borrow();
        for (i, j) in sums.iter().enumerate() {
            match j {
                Some(j) if j.is(n, kind, len) => match j.value {
                    Some(v) => return Cached::Value(v),
                    None if i == Side::Send.slot() => return Cached::SendPending,
                    None => {}
                },
                _ => {}
            }
        }
        Cached::None
    }

    /// Ends the jobs over `n` (created, removed, renamed).
    #[inline(never)]
    fn changed(&self, n: &FileName) {
        for j in self.sums.borrow_mut().iter_mut() {
            if j.as_ref().is_some_and(|j| j.name == *n) {
                *j = None;
            }
        }
    }

    /// Whether writing `data` at `offset` of `n` would change bytes a job has summed: a
    /// write past what was summed changes nothing summed, and the same bytes written again
    /// (a duplicate segment, the segment the entity wrote before handing it over) neither.
    #[inline(never)]
    fn changes_summed(&self, n: &FileName, offset: u64, data: &[u8]) -> bool {
        let summed = self
            .sums
            .borrow()
            .iter()
            .flatten()
            .filter(|j| j.name == *n)
            .map(|j| j.at)
            .max();
        let Some(at) = summed else { return false };
        if offset >= at {
            return false;
        }
        let end = (offset + data.len() as u64).min(at);
        let mut buf = [0u8; SUM_CHUNK];
        let mut o = offset;
        while o < end {
            let k = (end - o).min(SUM_CHUNK as u64) as usize;
            let d = (o - offset) as usize;
            if self.inner.read(n, o, &mut buf[..k]).is_err() || buf[..k] != data[d..d + k] {
                return true;
            }
            o += k as u64;
        }
        false
    }

    pub fn inner(&self) -> &S {
        &self.inner
    }

    pub fn counters(&self) -> StoreCounters {
        self.counters.get()
    }

    fn count(&self, e: StoreError) -> StoreError {
        let mut k = self.counters.get();
        match e {
            StoreError::Full => k.full = k.full.wrapping_add(1),
            StoreError::Io => k.io_errors = k.io_errors.wrapping_add(1),
            StoreError::NotFound | StoreError::Exists => {}
        }
        self.counters.set(k);
        e
    }

    /// A name from outside, counted when refused.
    pub fn check(&self, s: &str) -> Result<FileName, NameError> {
        FileName::new(s).inspect_err(|_| {
            let mut k = self.counters.get();
            k.bad_names = k.bad_names.wrapping_add(1);
            self.counters.set(k);
        })
    }

    pub fn len(&self, n: &FileName) -> Result<Option<u64>, StoreError> {
        self.inner.len(n).map_err(|e| self.count(e))
    }

    pub fn remove(&self, n: &FileName) -> Result<(), StoreError> {
        self.changed(n);
        self.inner.remove(n).map_err(|e| self.count(e))
    }

    pub fn rename(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        self.changed(from);
        self.changed(to);
        self.inner.rename(from, to).map_err(|e| self.count(e))
    }

    /// Renames `from` to `to`, replacing `to`'s file ([`FlatStore::replace`]).
    pub fn replace(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        self.changed(from);
        self.changed(to);
        self.inner.replace(from, to).map_err(|e| self.count(e))
    }

    pub fn free(&self) -> Result<u64, StoreError> {
        self.inner.free().map_err(|e| self.count(e))
    }

    pub fn list(&self, f: &mut dyn FnMut(&FileName, u64)) -> Result<(), StoreError> {
        self.inner.list(f).map_err(|e| self.count(e))
    }

    /// Files in the store.
    pub fn count_files(&self) -> Result<usize, StoreError> {
        let mut n = 0;
        self.list(&mut |_, _| n += 1)?;
        Ok(n)
    }

    /// Creates (truncates) `n`, refusing a new file past `MAX_FILES`.
    pub fn create(&self, n: &FileName) -> Result<(), StoreError> {
        if self.len(n)?.is_none() && self.count_files()? >= MAX_FILES {
            return Err(self.count(StoreError::Full));
        }
        self.changed(n);
        self.inner.create(n).map_err(|e| self.count(e))
    }

    /// Writes `data` at `offset`, refusing to grow the file past `MAX_FILE_LEN` or the
    /// free space.
    pub fn write(&self, n: &FileName, offset: u64, data: &[u8]) -> Result<(), StoreError> {
        let end = offset.checked_add(data.len() as u64).ok_or(StoreError::Full)?;
        if end > MAX_FILE_LEN {
            return Err(self.count(StoreError::Full));
        }
        let now = self.len(n)?.ok_or(StoreError::NotFound)?;
        if end > now && end - now > self.free()? {
            return Err(self.count(StoreError::Full));
        }
        if self.changes_summed(n, offset, data) {
            self.changed(n);
        }
        self.inner.write(n, offset, data).map_err(|e| self.count(e))
    }

    pub fn read(&self, n: &FileName, offset: u64, buf: &mut [u8]) -> Result<(), StoreError> {
        let len = self.len(n)?.ok_or(StoreError::NotFound)?;
        if offset.checked_add(buf.len() as u64).is_none_or(|end| end > len) {
            return Err(StoreError::NotFound);
        }
        self.inner.read(n, offset, buf).map_err(|e| self.count(e))
    }

    /// The CFDP checksum of the first `len` bytes (`buf`: the read buffer).
    pub fn checksum(&self, n: &FileName, kind: ChecksumType, len: u64, buf: &mut [u8]) -> Result<u32, FilestoreError> {
        let mut sum = Checksum::new(kind).ok_or(FilestoreError::ChecksumTypeNotImplemented(kind))?;
        let mut at = 0u64;
        while at < len {
            let k = (len - at).min(buf.len() as u64) as usize;
            self.read(n, at, &mut buf[..k]).map_err(fs_err)?;
            sum.update(at, &buf[..k]);
            at += k as u64;
        }
        Ok(sum.value())
    }
}

/// A CFDP file checksum, fed in order (727.0-B-5 § 4.2.2; the SANA checksum registry).
pub enum Checksum {
    /// Modular: the sum of the file's 32-bit big-endian words, aligned on file offsets.
    Modular(u32),
    Crc32(crc::Digest<'static, u32>),
    Crc32c(crc::Digest<'static, u32>),
    Null,
}

impl Checksum {
    pub fn new(kind: ChecksumType) -> Option<Checksum> {
        match kind {
            ChecksumType::Modular => Some(Checksum::Modular(0)),
            ChecksumType::Crc32 => Some(Checksum::Crc32(cfdp::CRC_32.digest())),
            ChecksumType::Crc32C => Some(Checksum::Crc32c(cfdp::CRC_32C.digest())),
            ChecksumType::NullChecksum => Some(Checksum::Null),
            ChecksumType::Crc32Proximity1 => None,
        }
    }

    /// The next bytes, which start at file offset `offset`.
    pub fn update(&mut self, offset: u64, data: &[u8]) {
        match self {
            // Word by word between the bytes before the first word boundary and after the
            // last: `CHECKSUM_BYTES_PER_POLL` of it run in each control period on the board
            // while a file is summed, where byte by byte with a 64-bit offset took 17 000
            // RV32 instructions a KiB (firmware/qemu-tests t_files).
            Checksum::Modular(s) => {
                let head = ((4 - offset % 4) % 4) as usize;
                let (head, rest) = data.split_at(head.min(data.len()));
                let byte = |at: usize, b: u8| (b as u32) << (24 - 8 * (at % 4) as u32);
                for (i, b) in head.iter().enumerate() {
                    *s = s.wrapping_add(byte((offset % 4) as usize + i, *b));
                }
                let mut words = rest.chunks_exact(4);
                for w in &mut words {
                    *s = s.wrapping_add(u32::from_be_bytes([w[0], w[1], w[2], w[3]]));
                }
                for (i, b) in words.remainder().iter().enumerate() {
                    *s = s.wrapping_add(byte(i, *b));
                }
            }
            Checksum::Crc32(d) | Checksum::Crc32c(d) => d.update(data),
            Checksum::Null => {}
        }
    }

    pub fn value(self) -> u32 {
        match self {
            Checksum::Modular(s) => s,
            Checksum::Crc32(d) | Checksum::Crc32c(d) => d.finalize(),
            Checksum::Null => 0,
        }
    }
}

fn fs_err(e: StoreError) -> FilestoreError {
    match e {
        StoreError::NotFound => FilestoreError::FileDoesNotExist,
        StoreError::Exists => FilestoreError::FileAlreadyExists,
        StoreError::Full | StoreError::Io => FilestoreError::Other,
    }
}

/// The empty name is CFDP's "no file" of a metadata-only transaction; cfdp-rs 0.3 still
/// creates, checks and sums it, so it names an empty nothing here, outside the store.
const NO_FILE: &str = "";

impl<S: FlatStore> VirtualFilestore for &Checked<S> {
    fn create_file(&self, path: &str) -> Result<(), FilestoreError> {
        if path == NO_FILE {
            return Ok(());
        }
        let n = name(path, &self.counters)?;
        if self.len(&n).map_err(fs_err)?.is_some() {
            return Err(FilestoreError::FileAlreadyExists);
        }
        self.create(&n).map_err(fs_err)
    }

    fn remove_file(&self, path: &str) -> Result<(), FilestoreError> {
        let n = name(path, &self.counters)?;
        self.remove(&n).map_err(fs_err)
    }

    fn truncate_file(&self, path: &str) -> Result<(), FilestoreError> {
        if path == NO_FILE {
            return Ok(());
        }
        let n = name(path, &self.counters)?;
        if self.len(&n).map_err(fs_err)?.is_none() {
            return Err(FilestoreError::FileDoesNotExist);
        }
        self.create(&n).map_err(fs_err)
    }

    /// The store is flat: no directories to make or remove.
    fn remove_dir(&self, _path: &str, _all: bool) -> Result<(), FilestoreError> {
        Err(FilestoreError::IsNotDirectory)
    }

    fn create_dir(&self, _path: &str) -> Result<(), FilestoreError> {
        Err(FilestoreError::Permission)
    }

    fn read_data(&self, path: &str, offset: u64, read_len: u64, buf: &mut [u8]) -> Result<(), FilestoreError> {
        let n = name(path, &self.counters)?;
        let buf = buf.get_mut(..read_len as usize).ok_or(FilestoreError::Other)?;
        self.read(&n, offset, buf).map_err(fs_err)
    }

    fn write_data(&self, path: &str, offset: u64, buf: &[u8]) -> Result<(), FilestoreError> {
        if path == NO_FILE {
            return Err(FilestoreError::FileDoesNotExist);
        }
        let n = name(path, &self.counters)?;
        self.write(&n, offset, buf).map_err(fs_err)
    }

    fn filename_from_full_path(path: &str) -> Option<&str> {
        Some(path)
    }

    fn is_file(&self, path: &str) -> Result<bool, FilestoreError> {
        self.exists(path)
    }

    fn is_dir(&self, _path: &str) -> Result<bool, FilestoreError> {
        Ok(false)
    }

    fn exists(&self, path: &str) -> Result<bool, FilestoreError> {
        if path == NO_FILE {
            return Ok(false);
        }
        let n = name(path, &self.counters)?;
        Ok(self.len(&n).map_err(fs_err)?.is_some())
    }

    fn file_name<'a>(&self, path: &'a str) -> Result<Option<&'a str>, FilestoreError> {
        Ok(Some(path))
    }

    fn file_size(&self, path: &str) -> Result<u64, FilestoreError> {
        if path == NO_FILE {
            return Ok(0);
        }
        let n = name(path, &self.counters)?;
        self.len(&n).map_err(fs_err)?.ok_or(FilestoreError::FileDoesNotExist)
    }

    fn calculate_checksum(
        &self,
        path: &str,
        kind: ChecksumType,
        size_to_verify: u64,
        buf: &mut [u8],
    ) -> Result<u32, FilestoreError> {
        if path == NO_FILE {
            return Checksum::new(kind)
                .map(Checksum::value)
                .ok_or(FilestoreError::ChecksumTypeNotImplemented(kind));
        }
        let n = name(path, &self.counters)?;
        match self.cached(&n, kind, size_to_verify) {
            Cached::Value(v) => Ok(v),
            // Not an error of the file: the source handler stays at its EOF step and asks
            // again at its next call (the entity calls it when the sum is done).
            Cached::SendPending => Err(FilestoreError::Other),
            Cached::None => {
                let mut k = self.counters.get();
                k.whole_sums = k.whole_sums.wrapping_add(1);
                self.counters.set(k);
                self.checksum(&n, kind, size_to_verify, buf)
            }
        }
    }
}

/// A store in RAM for tests and the simulator: at most `N` files of at most `CAP` bytes each.
pub struct MemStore<const N: usize, const CAP: usize> {
    files: core::cell::RefCell<heapless::Vec<(FileName, heapless::Vec<u8, CAP>), N>>,
    capacity: u64,
}

impl<const N: usize, const CAP: usize> MemStore<N, CAP> {
    /// An empty store holding `capacity` bytes in all.
    pub fn new(capacity: u64) -> Self {
        MemStore {
            files: core::cell::RefCell::new(heapless::Vec::new()),
            capacity,
        }
    }
}

impl<const N: usize, const CAP: usize> FlatStore for MemStore<N, CAP> {
    fn len(&self, name: &FileName) -> Result<Option<u64>, StoreError> {
        Ok(self
            .files
            .borrow()
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, d)| d.len() as u64))
    }

    fn create(&self, name: &FileName) -> Result<(), StoreError> {
        let mut files = self.files.borrow_mut();
        match files.iter_mut().find(|(n, _)| n == name) {
            Some((_, d)) => d.clear(),
            None => files
                .push((name.clone(), heapless::Vec::new()))
                .map_err(|_| StoreError::Full)?,
        }
        Ok(())
    }

    fn read(&self, name: &FileName, offset: u64, buf: &mut [u8]) -> Result<(), StoreError> {
        let files = self.files.borrow();
        let (_, d) = files.iter().find(|(n, _)| n == name).ok_or(StoreError::NotFound)?;
        let src = d
            .get(offset as usize..offset as usize + buf.len())
            .ok_or(StoreError::NotFound)?;
        buf.copy_from_slice(src);
        Ok(())
    }

    fn write(&self, name: &FileName, offset: u64, data: &[u8]) -> Result<(), StoreError> {
        let mut files = self.files.borrow_mut();
        let (_, d) = files.iter_mut().find(|(n, _)| n == name).ok_or(StoreError::NotFound)?;
        let end = offset as usize + data.len();
        if end > d.len() {
            d.resize(end, 0).map_err(|_| StoreError::Full)?;
        }
        d[offset as usize..end].copy_from_slice(data);
        Ok(())
    }

    fn remove(&self, name: &FileName) -> Result<(), StoreError> {
        let mut files = self.files.borrow_mut();
        let i = files.iter().position(|(n, _)| n == name).ok_or(StoreError::NotFound)?;
        files.swap_remove(i);
        Ok(())
    }

    fn rename(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        let mut files = self.files.borrow_mut();
        if files.iter().any(|(n, _)| n == to) {
            return Err(StoreError::Exists);
        }
        let f = files.iter_mut().find(|(n, _)| n == from).ok_or(StoreError::NotFound)?;
        f.0 = to.clone();
        Ok(())
    }

    fn list(&self, f: &mut dyn FnMut(&FileName, u64)) -> Result<(), StoreError> {
        let mut files = self.files.borrow_mut();
        files.sort_unstable_by(|a, b| a.0.cmp(&b.0));
        for (n, d) in files.iter() {
            f(n, d.len() as u64);
        }
        Ok(())
    }

    fn free(&self) -> Result<u64, StoreError> {
        let used: u64 = self.files.borrow().iter().map(|(_, d)| d.len() as u64).sum();
        Ok(self.capacity.saturating_sub(used))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: FILE-STORE-01
    #[test]
    fn names_that_could_leave_the_store_are_refused_and_counted() {
        for bad in [
            "",
            "..",
            ".",
            "../etc/passwd",
            "/etc/passwd",
            "a/b",
            "a\\b",
            "a\0b",
            ".hidden",
            "a b",
            "é",
        ] {
            assert!(FileName::new(bad).is_err(), "{bad:?}");
        }
        assert_eq!(
            FileName::new(&"x".repeat(MAX_NAME_LEN + 1)),
            Err(NameError::TooLong(MAX_NAME_LEN + 1))
        );
        assert!(FileName::new(&"x".repeat(MAX_NAME_LEN)).is_ok());
        assert!(FileName::new("plan-3_v2.toml").is_ok());
        let s = Checked::new(MemStore::<4, 64>::new(1000));
        assert!(matches!((&s).create_file("../x"), Err(FilestoreError::Permission)));
        assert!(matches!(
            (&s).write_data("/etc/passwd", 0, b"x"),
            Err(FilestoreError::Permission)
        ));
        assert_eq!(s.counters().bad_names, 2);
        assert!(s.inner().len(&FileName::new("x").unwrap()).unwrap().is_none());
    }

    // verifies: FILE-STORE-02
    #[test]
    fn lengths_are_checked_against_the_file_limit_and_the_free_space() {
        let s = Checked::new(MemStore::<2, 64>::new(10));
        let a = FileName::new("a").unwrap();
        s.create(&a).unwrap();
        s.write(&a, 0, b"0123456789").unwrap();
        assert_eq!(s.write(&a, 10, b"x"), Err(StoreError::Full), "past the free space");
        assert_eq!(s.write(&a, u64::MAX, b"x"), Err(StoreError::Full), "offset overflow");
        let mut buf = [0u8; 4];
        assert_eq!(s.read(&a, 8, &mut buf), Err(StoreError::NotFound), "read past the end");
        s.read(&a, 6, &mut buf).unwrap();
        assert_eq!(&buf, b"6789");
        let b = FileName::new("b").unwrap();
        s.create(&b).unwrap();
        assert_eq!(s.rename(&a, &b), Err(StoreError::Exists));
        s.remove(&b).unwrap();
        s.rename(&a, &b).unwrap();
        let mut names = std::vec::Vec::new();
        s.list(&mut |n, l| names.push((n.as_str().to_string(), l))).unwrap();
        assert_eq!(names, [("b".to_string(), 10)]);
        assert_eq!(s.free().unwrap(), 0);
    }

    // verifies: FILE-CFDP-08
    #[test]
    fn a_checksum_job_reads_its_budget_a_step_and_only_a_change_of_summed_bytes_ends_it() {
        let s = Checked::new(MemStore::<2, 4096>::new(10_000));
        let n = FileName::new("f").unwrap();
        let data: std::vec::Vec<u8> = (0..3000u32).map(|i| (i * 7 + 3) as u8).collect();
        s.create(&n).unwrap();
        s.write(&n, 0, &data).unwrap();
        let kind = ChecksumType::Crc32;
        let whole = s.checksum(&n, kind, 3000, &mut [0u8; 256]).unwrap();
        s.sum_start(Side::Send, &n, kind, 3000);
        // Not done: the source handler's call is told "not yet", nothing read whole.
        assert!(matches!(
            (&s).calculate_checksum("f", kind, 3000, &mut [0u8; 64]),
            Err(FilestoreError::Other)
        ));
        assert_eq!(s.sum_advance(Side::Send, 1000), 1000);
        // A write past what was summed, and the same bytes again, change nothing summed.
        s.write(&n, 2000, &data[2000..2100]).unwrap();
        s.write(&n, 10, &data[10..700]).unwrap();
        assert!(s.sum_running(Side::Send));
        assert_eq!(s.sum_advance(Side::Send, 1000), 1000);
        assert_eq!(s.sum_advance(Side::Send, 5000), 1000);
        assert_eq!(s.sum_value(Side::Send, &n, kind, 3000), Some(whole));
        assert_eq!((&s).calculate_checksum("f", kind, 3000, &mut [0u8; 64]).unwrap(), whole);
        assert_eq!(s.counters().whole_sums, 0);
        // Another length or kind is not this job's: summed whole, counted.
        assert!((&s).calculate_checksum("f", kind, 2999, &mut [0u8; 64]).is_ok());
        assert_eq!(s.counters().whole_sums, 1);
        // Other bytes where the job summed end it, as do a create, a rename, a remove.
        s.write(&n, 5, b"x").unwrap();
        assert!(!s.sum_running(Side::Send));
        s.sum_start(Side::Receive, &n, kind, 3000);
        s.create(&n).unwrap();
        assert!(!s.sum_running(Side::Receive));
        // A read that fails (a job longer than its file) ends the job.
        s.sum_start(Side::Receive, &n, kind, 3000);
        assert_eq!(s.sum_advance(Side::Receive, 8192), 0);
        assert!(!s.sum_running(Side::Receive));
    }

    // verifies: FILE-CFDP-02
    #[test]
    fn the_modular_checksum_adds_big_endian_words_at_file_offsets() {
        let mut c = Checksum::new(ChecksumType::Modular).unwrap();
        c.update(0, &[1, 2]);
        c.update(2, &[3, 4, 5]);
        assert_eq!(c.value(), 0x0102_0304 + 0x0500_0000);
        // Word by word and byte by byte agree for every start and split.
        let data: std::vec::Vec<u8> = (0..64u32).map(|i| (i * 37 + 11) as u8).collect();
        let bytewise = |offset: u64, d: &[u8]| {
            d.iter().enumerate().fold(0u32, |s, (i, b)| {
                s.wrapping_add((*b as u32) << (24 - 8 * ((offset + i as u64) % 4) as u32))
            })
        };
        for start in 0..8 {
            for split in start..data.len() {
                let mut c = Checksum::new(ChecksumType::Modular).unwrap();
                c.update(start as u64, &data[start..split]);
                c.update(split as u64, &data[split..]);
                assert_eq!(
                    c.value(),
                    bytewise(start as u64, &data[start..]),
                    "start {start} split {split}"
                );
            }
        }
        let mut c = Checksum::new(ChecksumType::Crc32).unwrap();
        c.update(0, b"123456789");
        assert_eq!(c.value(), 0xCBF4_3926);
    }
}
