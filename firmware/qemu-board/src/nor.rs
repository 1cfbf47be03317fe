//! The board's NOR flash, kept in a host file through semihosting: the ESP32-C3 module's
//! whole flash ([`mib::memory::FLASH_BYTES`]), so every partition sits at its offset on
//! board A (the key and counter area at `link_store::AREA_OFFSET`, the PUS 15 store at
//! `mib::memory::store::OFFSET`). It behaves as the part's flash does
//! (`obsw_core::flash_store::Nor`, the rules the host's store file shares): an erase sets
//! a 4 KiB sector to 0xFF, a write programs whole 32-bit words and only clears bits (a
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
use mib::memory::FLASH_BYTES;
use obsw_core::flash_store::{Medium, Nor};
use semihosting::fs::File;
use semihosting::io::{Read, Seek, SeekFrom, Write};

/// The module's flash: the NOR rules of `obsw_core::flash_store::Nor` (the host's store
/// file follows the same) over the flash file.
pub type FileFlash = Nor<FlashFile>;

/// The flash file's bytes.
pub struct FlashFile {
    file: File,
}

/// The host file refused a read or a write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Io;

/// Why the flash file could not be opened.
#[derive(Debug)]
pub enum OpenError {
    /// No such file, or not readable and writable.
    Open,
    /// The file is not the size of the module's flash.
    Size(u64),
}

/// Opens the flash file at `path` (made by the one who provisions the board: the size of
/// the flash, erased, with the key record written).
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
    Ok(Nor::new(FlashFile { file }, FLASH_BYTES))
}

impl Medium for FlashFile {
    type Error = Io;
    fn read_at(&mut self, at: u32, out: &mut [u8]) -> Result<(), Io> {
        self.file.seek(SeekFrom::Start(at.into())).map_err(|_| Io)?;
        self.file.read_exact(out).map_err(|_| Io)
    }
    fn write_at(&mut self, at: u32, bytes: &[u8]) -> Result<(), Io> {
        self.file.seek(SeekFrom::Start(at.into())).map_err(|_| Io)?;
        self.file.write_all(bytes).map_err(|_| Io)
    }
}
