//! One NOR flash shared by the flash layouts that live on it: board A's key and counter
//! area (`link_store`, which owns its flash) and the PUS 15 store
//! (`obsw_core::flash_store`, which borrows a `RefCell`) sit in partitions of the same
//! chip, driven by one driver. [`SharedFlash`] hands the `RefCell`'s flash to a layout
//! that wants a flash of its own.
//!
//! Every call borrows the flash for its own length only; the layouts run on one task and
//! their calls never overlap, so a borrow that fails ([`SharedError::Busy`]) is an
//! internal error, refused like a flash error rather than a panic.

use core::cell::RefCell;
use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// A flash borrowed from a `RefCell` call by call.
pub struct SharedFlash<'a, F>(pub &'a RefCell<F>);

/// The flash's own error, or the flash already borrowed.
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

impl<F: ErrorType> ErrorType for SharedFlash<'_, F> {
    type Error = SharedError<F::Error>;
}

impl<F: ErrorType> SharedFlash<'_, F> {
    fn with<T>(&self, f: impl FnOnce(&mut F) -> Result<T, F::Error>) -> Result<T, SharedError<F::Error>> {
        let mut flash = self.0.try_borrow_mut().map_err(|_| SharedError::Busy)?;
        f(&mut flash).map_err(SharedError::Flash)
    }
}

impl<F: ReadNorFlash> ReadNorFlash for SharedFlash<'_, F> {
    const READ_SIZE: usize = F::READ_SIZE;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.with(|f| f.read(offset, bytes))
    }
    fn capacity(&self) -> usize {
        self.0.try_borrow().map_or(0, |f| f.capacity())
    }
}

impl<F: NorFlash> NorFlash for SharedFlash<'_, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.with(|f| f.erase(from, to))
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.with(|f| f.write(offset, bytes))
    }
}

impl<F: MultiwriteNorFlash> MultiwriteNorFlash for SharedFlash<'_, F> {}
