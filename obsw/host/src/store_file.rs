//! The host's flash for the PUS 15 store: a file the size of the store partition
//! (`mib::memory::store::SIZE`) behaving as NOR flash — erase sets a 4 KiB sector to
//! 0xFF, a write only clears bits (a write that would set one is refused, so a layout
//! that relies on more than NOR gives fails here as it would on board A). The store's
//! code is the flight code (`obsw_core::flash_store`); only this I/O is the host's.
//! Writes go to the file at once, so a killed process loses nothing written; a host
//! power cut may lose what the kernel had not written back yet.

use std::fs::{File, OpenOptions};
use std::os::unix::fs::FileExt;
use std::path::Path;

use anyhow::{bail, Context, Result};
use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use mib::memory::{store, FLASH_SECTOR as SECTOR, FLASH_WORD as WORD};

/// Where the bytes are: a file, or memory when no store file is configured.
enum Medium {
    File(File),
    Memory(Vec<u8>),
}

pub struct HostFlash {
    medium: Medium,
}

#[derive(Debug)]
pub enum FlashError {
    Io,
    /// A write that would turn a 0 bit into 1 (NOR flash cannot without an erase).
    SetsBits,
    OutOfBounds,
    NotAligned,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::Io | FlashError::SetsBits => NorFlashErrorKind::Other,
        }
    }
}

const SIZE: usize = store::SIZE as usize;

impl HostFlash {
    /// Opens the store file at `path`, creating it erased (all 0xFF) if missing. A file
    /// of another size is refused (it is not this store).
    pub fn open(path: &Path) -> Result<HostFlash> {
        let f = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .with_context(|| format!("--tm-store {}", path.display()))?;
        let len = f.metadata()?.len();
        if len == 0 {
            f.write_all_at(&vec![0xFF; SIZE], 0)?;
            f.sync_all()?;
        } else if len != SIZE as u64 {
            bail!("--tm-store {}: {len} bytes, a store file has {SIZE}", path.display());
        }
        Ok(HostFlash {
            medium: Medium::File(f),
        })
    }

    /// A store in memory, erased: lost when the process ends.
    pub fn memory() -> HostFlash {
        HostFlash {
            medium: Medium::Memory(vec![0xFF; SIZE]),
        }
    }

    fn check(offset: u32, len: usize) -> Result<usize, FlashError> {
        let at = offset as usize;
        if at.checked_add(len).is_none_or(|end| end > SIZE) {
            return Err(FlashError::OutOfBounds);
        }
        Ok(at)
    }

    fn read_at(&self, at: usize, out: &mut [u8]) -> Result<(), FlashError> {
        match &self.medium {
            Medium::File(f) => f.read_exact_at(out, at as u64).map_err(|_| FlashError::Io),
            Medium::Memory(m) => {
                out.copy_from_slice(&m[at..at + out.len()]);
                Ok(())
            }
        }
    }

    fn write_at(&mut self, at: usize, bytes: &[u8]) -> Result<(), FlashError> {
        match &mut self.medium {
            Medium::File(f) => f.write_all_at(bytes, at as u64).map_err(|_| FlashError::Io),
            Medium::Memory(m) => {
                m[at..at + bytes.len()].copy_from_slice(bytes);
                Ok(())
            }
        }
    }
}

impl ErrorType for HostFlash {
    type Error = FlashError;
}

impl ReadNorFlash for HostFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let at = Self::check(offset, bytes.len())?;
        self.read_at(at, bytes)
    }
    fn capacity(&self) -> usize {
        SIZE
    }
}

impl NorFlash for HostFlash {
    const WRITE_SIZE: usize = WORD as usize;
    const ERASE_SIZE: usize = SECTOR as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if !from.is_multiple_of(SECTOR) || !to.is_multiple_of(SECTOR) || to < from {
            return Err(FlashError::NotAligned);
        }
        let at = Self::check(from, (to - from) as usize)?;
        self.write_at(at, &vec![0xFF; (to - from) as usize])
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        if !offset.is_multiple_of(WORD) || !bytes.len().is_multiple_of(WORD as usize) {
            return Err(FlashError::NotAligned);
        }
        let at = Self::check(offset, bytes.len())?;
        let mut now = vec![0u8; bytes.len()];
        self.read_at(at, &mut now)?;
        if now.iter().zip(bytes).any(|(old, new)| new & !old != 0) {
            return Err(FlashError::SetsBits);
        }
        self.write_at(at, bytes)
    }
}

/// Writing a word again with more bits cleared is what NOR flash does; the check above
/// still refuses any bit set.
impl MultiwriteNorFlash for HostFlash {}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("obsw-store-{}-{name}", std::process::id()));
        let _ = std::fs::remove_file(&d);
        d
    }

    // verifies: PUS-15-05
    #[test]
    fn the_store_file_behaves_as_nor_flash() {
        let p = temp("nor");
        let mut f = HostFlash::open(&p).unwrap();
        assert_eq!(
            std::fs::metadata(&p).unwrap().len(),
            SIZE as u64,
            "created erased, full size"
        );
        let mut b = [0u8; 8];
        f.read(4096, &mut b).unwrap();
        assert_eq!(b, [0xFF; 8]);
        f.write(4096, &[0xF0, 0x0F, 0xFF, 0x00]).unwrap();
        // Clearing more bits of the same word is allowed; setting one is not.
        f.write(4096, &[0x00, 0x0F, 0xFF, 0x00]).unwrap();
        assert!(matches!(
            f.write(4096, &[0x01, 0x0F, 0xFF, 0x00]),
            Err(FlashError::SetsBits)
        ));
        assert!(matches!(f.write(4097, &[0; 4]), Err(FlashError::NotAligned)));
        assert!(matches!(f.write(SIZE as u32, &[0; 4]), Err(FlashError::OutOfBounds)));
        drop(f);
        let mut f = HostFlash::open(&p).unwrap();
        f.read(4096, &mut b[..4]).unwrap();
        assert_eq!(b[..4], [0x00, 0x0F, 0xFF, 0x00], "kept in the file");
        f.erase(4096, 8192).unwrap();
        f.read(4096, &mut b[..4]).unwrap();
        assert_eq!(b[..4], [0xFF; 4], "an erase sets the sector");
        assert!(matches!(f.erase(100, 4096), Err(FlashError::NotAligned)));
        std::fs::write(&p, b"short").unwrap();
        assert!(HostFlash::open(&p).is_err(), "a file of another size is refused");
        let _ = std::fs::remove_file(&p);
    }
}
