//! Host persistence (`std` feature): the SDLS counter state file ([`FileIvStore`]) and key
//! files ([`read_key`], [`create_key_file`]). Used by the host obsw and the ground.
//!
//! **State file.** Two 512-byte slots written alternately; each holds a generation number,
//! up to [`MAX_ENTRIES`] `(direction, SPI, value)` entries and a CRC-32. A call writes the
//! older slot and `fdatasync`s before returning, so the newest valid slot always survives a
//! crash (a torn write damages only the slot being written, whose CRC then fails). Load
//! takes the valid slot with the highest generation.
//!
//! **Key files** hold the raw 32 bytes (what Yamcs' `keyFile` reads). They are never printed;
//! errors name the file, never its content.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::sdls::{IvStore, Key, StoreError};

/// Entries a state file holds (SPIs of both directions).
pub const MAX_ENTRIES: usize = 16;
const SLOT: usize = 512;
const MAGIC: &[u8; 8] = b"MMICIV01";
const ENTRY: usize = 1 + 2 + 16;
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

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
}

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
            PersistError::Corrupt { path } => {
                write!(f, "{}: no valid SDLS counter slot (corrupt state file)", path.display())
            }
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

/// SDLS counters persisted in a file (see the module documentation).
#[derive(Debug)]
pub struct FileIvStore {
    path: PathBuf,
    file: File,
    generation: u64,
    entries: Vec<Entry>,
    /// Successful writes (each one `fdatasync`ed).
    pub writes: u64,
}

/// One stored counter: direction, SPI, value.
type Entry = (Dir, u16, u128);

fn decode_slot(b: &[u8]) -> Option<(u64, Vec<Entry>)> {
    if b.len() < SLOT || &b[..8] != MAGIC {
        return None;
    }
    let n = usize::from(b[16]);
    if n > MAX_ENTRIES {
        return None;
    }
    let end = 17 + n * ENTRY;
    let crc = u32::from_be_bytes([b[end], b[end + 1], b[end + 2], b[end + 3]]);
    if CRC32.checksum(&b[..end]) != crc {
        return None;
    }
    let gen = u64::from_be_bytes(b[8..16].try_into().ok()?);
    let mut v = Vec::with_capacity(n);
    for e in b[17..end].chunks_exact(ENTRY) {
        let dir = match e[0] {
            1 => Dir::Tx,
            2 => Dir::Rx,
            _ => return None,
        };
        let spi = u16::from_be_bytes([e[1], e[2]]);
        let val = u128::from_be_bytes(e[3..19].try_into().ok()?);
        v.push((dir, spi, val));
    }
    Some((gen, v))
}

impl FileIvStore {
    /// Opens (or creates, empty) the state file at `path`.
    pub fn open(path: &Path) -> Result<FileIvStore, PersistError> {
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(io(path))?;
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(io(path))?;
        let (generation, entries) = if bytes.is_empty() {
            (0, Vec::new())
        } else {
            let a = bytes.get(..SLOT).and_then(decode_slot);
            let b = bytes.get(SLOT..2 * SLOT).and_then(decode_slot);
            match (a, b) {
                (Some(a), Some(b)) => {
                    if a.0 >= b.0 {
                        a
                    } else {
                        b
                    }
                }
                (Some(s), None) | (None, Some(s)) => s,
                (None, None) => return Err(PersistError::Corrupt { path: path.into() }),
            }
        };
        Ok(FileIvStore {
            path: path.into(),
            file,
            generation,
            entries,
            writes: 0,
        })
    }

    /// The stored value of a counter.
    pub fn get(&self, dir: Dir, spi: u16) -> Option<u128> {
        self.entries.iter().find(|e| e.0 == dir && e.1 == spi).map(|e| e.2)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Stores `value` for `(dir, spi)`, durably, before returning.
    pub fn put(&mut self, dir: Dir, spi: u16, value: u128) -> Result<(), PersistError> {
        let mut entries = self.entries.clone();
        let full = entries.len() >= MAX_ENTRIES;
        match entries.iter_mut().find(|e| e.0 == dir && e.1 == spi) {
            Some(e) => e.2 = value,
            None if !full => entries.push((dir, spi, value)),
            None => {
                return Err(PersistError::Io {
                    path: self.path.clone(),
                    error: std::io::Error::other("too many SDLS counters for one state file"),
                })
            }
        }
        let gen = self.generation + 1;
        let mut slot = [0u8; SLOT];
        slot[..8].copy_from_slice(MAGIC);
        slot[8..16].copy_from_slice(&gen.to_be_bytes());
        slot[16] = entries.len() as u8;
        let mut p = 17;
        for (d, s, v) in &entries {
            slot[p] = d.code();
            slot[p + 1..p + 3].copy_from_slice(&s.to_be_bytes());
            slot[p + 3..p + 19].copy_from_slice(&v.to_be_bytes());
            p += ENTRY;
        }
        let crc = CRC32.checksum(&slot[..p]);
        slot[p..p + 4].copy_from_slice(&crc.to_be_bytes());
        let off = (gen % 2) * SLOT as u64;
        let path = self.path.clone();
        self.file.seek(SeekFrom::Start(off)).map_err(io(&path))?;
        self.file.write_all(&slot).map_err(io(&path))?;
        self.file.sync_data().map_err(io(&path))?;
        self.generation = gen;
        self.entries = entries;
        self.writes += 1;
        Ok(())
    }
}

impl IvStore for FileIvStore {
    fn reserve_tx(&mut self, spi: u16, high_water: u128) -> Result<(), StoreError> {
        self.put(Dir::Tx, spi, high_water).map_err(|_| StoreError)
    }

    fn record_rx(&mut self, spi: u16, last: u128) -> Result<(), StoreError> {
        self.put(Dir::Rx, spi, last).map_err(|_| StoreError)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sdls::TxSa;
    use crate::test_keys::TEST_KEY_TM_A;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("mmic-link-persist-{}-{name}", std::process::id()));
        let _ = std::fs::remove_file(&d);
        d
    }

    // verifies: LINK-HOST-03
    #[test]
    fn counters_survive_reopen_and_a_torn_slot() {
        let p = tmp("state");
        let mut s = FileIvStore::open(&p).unwrap();
        s.reserve_tx(17, 1024).unwrap();
        s.record_rx(1, 5).unwrap();
        s.record_rx(1, 6).unwrap();
        drop(s);
        let s = FileIvStore::open(&p).unwrap();
        assert_eq!((s.get(Dir::Tx, 17), s.get(Dir::Rx, 1)), (Some(1024), Some(6)));
        // Tear the newest slot (generation 3 is in slot 1): the previous one is used.
        let mut bytes = std::fs::read(&p).unwrap();
        bytes[SLOT + 20] ^= 0xFF;
        std::fs::write(&p, &bytes).unwrap();
        let s = FileIvStore::open(&p).unwrap();
        assert_eq!((s.get(Dir::Tx, 17), s.get(Dir::Rx, 1)), (Some(1024), Some(5)));
        // Both slots bad: refused, never silently reset to zero.
        bytes[20] ^= 0xFF;
        std::fs::write(&p, &bytes).unwrap();
        assert!(matches!(FileIvStore::open(&p), Err(PersistError::Corrupt { .. })));
        let _ = std::fs::remove_file(&p);
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
