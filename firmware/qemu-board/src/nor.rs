//! The board's NOR flash, kept in a host file through semihosting: the ESP32-C3 module's
//! whole flash ([`mib::memory::FLASH_BYTES`]), so every partition sits at its offset on
//! board A (the key and counter area at `link_store::AREA_OFFSET`, the PUS 15 store at
//! `mib::memory::store::OFFSET`). It behaves as the part's flash does: an erase sets a
//! 4 KiB sector to 0xFF, a write programs whole 32-bit words and only clears bits (a
//! write that would set one is refused, so a layout relying on more than NOR gives fails
//! here as it would on the board).
//!
//! Each write and erase reaches the host file before the call returns (QEMU performs the
//! semihosting call with the host's `write`), so a QEMU killed with SIGKILL keeps
//! everything written before the kill; a kill between the calls of one layout operation
//! leaves it cut there, as a reset would on the board.
//!
//! Why a semihosting file rather than the `virt` machine's pflash: QEMU's pflash is a CFI
//! flash with 256 KiB erase blocks (not the part's 4 KiB sectors that the store's layout
//! and `mib::memory` are sized in), and QEMU programs it by overwriting rather than
//! clearing bits; its driver would be code that runs nowhere else.

use core::ffi::CStr;
use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use mib::memory::{FLASH_BYTES, FLASH_SECTOR, FLASH_WORD};
use semihosting::fs::File;
use semihosting::io::{Read, Seek, SeekFrom, Write};

/// The flash file: the module's flash.
pub struct FileFlash {
    file: File,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlashError {
    /// The host file refused the read or write.
    Io,
    /// A write that would turn a 0 bit into 1.
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

/// Why the flash file could not be opened.
#[derive(Debug)]
pub enum OpenError {
    /// No such file, or not readable and writable.
    Open,
    /// The file is not the size of the module's flash.
    Size(u64),
}

impl FileFlash {
    /// Opens the flash file at `path` (made by the one who provisions the board: the
    /// size of the flash, erased, with the key record written).
    pub fn open(path: &CStr) -> Result<FileFlash, OpenError> {
        let file = File::options()
            .read(true)
            .write(true)
            .open(path)
            .map_err(|_| OpenError::Open)?;
        let len = file.metadata().map_err(|_| OpenError::Open)?.len();
        if len != u64::from(FLASH_BYTES) {
            return Err(OpenError::Size(len));
        }
        Ok(FileFlash { file })
    }

    fn check(offset: u32, len: usize) -> Result<(), FlashError> {
        match (offset as usize).checked_add(len) {
            Some(end) if end <= FLASH_BYTES as usize => Ok(()),
            _ => Err(FlashError::OutOfBounds),
        }
    }

    fn read_at(&mut self, offset: u32, out: &mut [u8]) -> Result<(), FlashError> {
        self.file
            .seek(SeekFrom::Start(offset.into()))
            .map_err(|_| FlashError::Io)?;
        self.file.read_exact(out).map_err(|_| FlashError::Io)
    }

    fn write_at(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        self.file
            .seek(SeekFrom::Start(offset.into()))
            .map_err(|_| FlashError::Io)?;
        self.file.write_all(bytes).map_err(|_| FlashError::Io)
    }
}

impl ErrorType for FileFlash {
    type Error = FlashError;
}

impl ReadNorFlash for FileFlash {
    /// The part's reads are word-aligned too (esp-storage without byte-wise reads).
    const READ_SIZE: usize = FLASH_WORD as usize;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        if !offset.is_multiple_of(FLASH_WORD) || !bytes.len().is_multiple_of(FLASH_WORD as usize) {
            return Err(FlashError::NotAligned);
        }
        Self::check(offset, bytes.len())?;
        self.read_at(offset, bytes)
    }
    fn capacity(&self) -> usize {
        FLASH_BYTES as usize
    }
}

impl NorFlash for FileFlash {
    const WRITE_SIZE: usize = FLASH_WORD as usize;
    const ERASE_SIZE: usize = FLASH_SECTOR as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if !from.is_multiple_of(FLASH_SECTOR) || !to.is_multiple_of(FLASH_SECTOR) || to < from {
            return Err(FlashError::NotAligned);
        }
        Self::check(from, (to - from) as usize)?;
        let erased = [0xFFu8; FLASH_SECTOR as usize];
        let mut at = from;
        while at < to {
            self.write_at(at, &erased)?;
            at += FLASH_SECTOR;
        }
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        if !offset.is_multiple_of(FLASH_WORD) || !bytes.len().is_multiple_of(FLASH_WORD as usize) {
            return Err(FlashError::NotAligned);
        }
        Self::check(offset, bytes.len())?;
        // Checked a chunk at a time against what the flash holds: only clearing bits.
        let mut now = [0u8; 256];
        for (i, chunk) in bytes.chunks(now.len()).enumerate() {
            let at = offset + (i * now.len()) as u32;
            let old = &mut now[..chunk.len()];
            self.read_at(at, old)?;
            if old.iter().zip(chunk).any(|(o, n)| n & !o != 0) {
                return Err(FlashError::SetsBits);
            }
        }
        self.write_at(offset, bytes)
    }
}

/// Writing a word again with more bits cleared is what NOR flash does (the part allows
/// it); the check above still refuses any bit set.
impl MultiwriteNorFlash for FileFlash {}
