//! The flash the update works on: a NOR flash (erase by sector to all ones, a write only
//! clears bits), seen through an object-safe trait so that the update service can hold
//! whatever flash its platform has. Every `embedded-storage` [`NorFlash`] is one.
//!
//! [`RamNor`] is a NOR flash in RAM that can lose its power after a given number of byte
//! writes and erases, for the tests that cut a write at every byte.

use core::cell::RefCell;

use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};

/// A flash operation failed (the platform's error is not kept: the update reports it as a
/// flash failure and leaves the decision to the otadata, which a failed write never
/// changes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the flash, or not aligned to its write or erase unit.
    OutOfBounds,
    /// The platform's flash driver failed.
    Device,
    /// [`RamNor`]'s simulated loss of power: the operation stopped part way.
    PowerCut,
}

impl core::fmt::Display for FlashError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FlashError::OutOfBounds => "outside the flash or misaligned",
            FlashError::Device => "flash driver error",
            FlashError::PowerCut => "power cut",
        })
    }
}

impl core::error::Error for FlashError {}

/// A NOR flash region, addressed from 0.
pub trait Flash {
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), FlashError>;
    /// Clears bits: the bytes must have been erased before (`offset` and the length aligned
    /// to [`Self::write_size`]).
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), FlashError>;
    /// Sets every byte of `from..to` to 0xFF (both aligned to [`Self::erase_size`]).
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError>;
    fn capacity(&self) -> u32;
    fn erase_size(&self) -> u32;
    fn write_size(&self) -> u32;
}

impl<F: NorFlash> Flash for F {
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), FlashError> {
        bounds(offset, buf.len(), ReadNorFlash::capacity(self))?;
        ReadNorFlash::read(self, offset, buf).map_err(|_| FlashError::Device)
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), FlashError> {
        bounds(offset, data.len(), ReadNorFlash::capacity(self))?;
        NorFlash::write(self, offset, data).map_err(|_| FlashError::Device)
    }
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if from > to {
            return Err(FlashError::OutOfBounds);
        }
        bounds(from, (to - from) as usize, ReadNorFlash::capacity(self))?;
        NorFlash::erase(self, from, to).map_err(|_| FlashError::Device)
    }
    fn capacity(&self) -> u32 {
        ReadNorFlash::capacity(self) as u32
    }
    fn erase_size(&self) -> u32 {
        F::ERASE_SIZE as u32
    }
    fn write_size(&self) -> u32 {
        F::WRITE_SIZE as u32
    }
}

fn bounds(offset: u32, len: usize, capacity: usize) -> Result<(), FlashError> {
    let end = (offset as usize).checked_add(len).ok_or(FlashError::OutOfBounds)?;
    if end > capacity {
        return Err(FlashError::OutOfBounds);
    }
    Ok(())
}

/// A partition of a larger flash: `size` bytes from `offset`, addressed from 0 (board A's
/// otadata and application slots are partitions of its one SPI flash, at the MIB's
/// `mib::memory` offsets). Nothing outside the window is ever read, written or erased.
/// Several partitions of one flash are held at once (the otadata while a slot is verified
/// for activation); each borrows the flash for one operation only.
pub struct Partition<'a, F: ?Sized> {
    flash: &'a RefCell<F>,
    offset: u32,
    size: u32,
    erase_size: u32,
    write_size: u32,
}

impl<'a, F: Flash + ?Sized> Partition<'a, F> {
    /// The window `offset..offset + size` of `flash`; `None` when it does not lie inside
    /// the flash or is not aligned to its erase unit.
    pub fn new(flash: &'a RefCell<F>, offset: u32, size: u32) -> Option<Self> {
        let (capacity, erase_size, write_size) = {
            let f = flash.try_borrow().ok()?;
            (f.capacity(), f.erase_size().max(1), f.write_size().max(1))
        };
        let end = offset.checked_add(size)?;
        (end <= capacity && offset.is_multiple_of(erase_size) && size.is_multiple_of(erase_size)).then_some(Partition {
            flash,
            offset,
            size,
            erase_size,
            write_size,
        })
    }

    fn with<R>(&self, op: impl FnOnce(&mut F) -> Result<R, FlashError>) -> Result<R, FlashError> {
        // A partition never calls into another while it holds the flash: a flash already
        // borrowed is a driver fault, not a panic.
        op(&mut *self.flash.try_borrow_mut().map_err(|_| FlashError::Device)?)
    }
}

impl<F: Flash + ?Sized> Flash for Partition<'_, F> {
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), FlashError> {
        bounds(offset, buf.len(), self.size as usize)?;
        self.with(|f| f.read(self.offset + offset, buf))
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), FlashError> {
        bounds(offset, data.len(), self.size as usize)?;
        self.with(|f| f.write(self.offset + offset, data))
    }
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if from > to {
            return Err(FlashError::OutOfBounds);
        }
        bounds(from, (to - from) as usize, self.size as usize)?;
        self.with(|f| f.erase(self.offset + from, self.offset + to))
    }
    fn capacity(&self) -> u32 {
        self.size
    }
    fn erase_size(&self) -> u32 {
        self.erase_size
    }
    fn write_size(&self) -> u32 {
        self.write_size
    }
}

/// A NOR flash of `N` bytes in RAM with 4 KiB sectors and byte writes, that can lose its
/// power: after `budget` byte programs and sector erases every further operation stops
/// with [`FlashError::PowerCut`] (an erase cut part way leaves the first half of its
/// sector erased and the rest as it was, the worst a real erase leaves: neither old nor new).
#[derive(Clone)]
pub struct RamNor<const N: usize> {
    pub bytes: [u8; N],
    budget: Option<usize>,
}

impl<const N: usize> Default for RamNor<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RamNor<N> {
    pub const SECTOR: u32 = 4096;

    /// An erased flash with power that never fails.
    pub const fn new() -> Self {
        RamNor {
            bytes: [0xFF; N],
            budget: None,
        }
    }

    /// Power fails after `steps` more byte programs or sector erases (`None`: never).
    pub fn cut_after(&mut self, steps: Option<usize>) {
        self.budget = steps;
    }

    /// Counts one step; false when the power is gone.
    fn step(&mut self) -> bool {
        match &mut self.budget {
            None => true,
            Some(0) => false,
            Some(n) => {
                *n -= 1;
                true
            }
        }
    }
}

impl<const N: usize> Flash for RamNor<N> {
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), FlashError> {
        bounds(offset, buf.len(), N)?;
        buf.copy_from_slice(&self.bytes[offset as usize..offset as usize + buf.len()]);
        Ok(())
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), FlashError> {
        bounds(offset, data.len(), N)?;
        for (i, b) in data.iter().enumerate() {
            if !self.step() {
                return Err(FlashError::PowerCut);
            }
            self.bytes[offset as usize + i] &= *b;
        }
        Ok(())
    }
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if from > to || !from.is_multiple_of(Self::SECTOR) || !to.is_multiple_of(Self::SECTOR) {
            return Err(FlashError::OutOfBounds);
        }
        bounds(from, (to - from) as usize, N)?;
        let mut s = from;
        while s < to {
            let sector = &mut self.bytes[s as usize..(s + Self::SECTOR) as usize];
            if self.budget == Some(0) {
                sector[..Self::SECTOR as usize / 2].fill(0xFF);
                return Err(FlashError::PowerCut);
            }
            let _ = self.step();
            self.bytes[s as usize..(s + Self::SECTOR) as usize].fill(0xFF);
            s += Self::SECTOR;
        }
        Ok(())
    }
    fn capacity(&self) -> u32 {
        N as u32
    }
    fn erase_size(&self) -> u32 {
        Self::SECTOR
    }
    fn write_size(&self) -> u32 {
        1
    }
}

/// A NOR flash kept in a file (the host's slots and otadata): erased bytes are 0xFF, a
/// write clears bits as the chip does, so a record written over an unerased one reads as
/// the chip would show it.
#[cfg(feature = "std")]
pub struct FileFlash {
    file: std::fs::File,
    size: u32,
}

#[cfg(feature = "std")]
impl FileFlash {
    /// Opens `path` as a flash of `size` bytes, creating it erased (or extending it with
    /// erased bytes) when it is shorter.
    pub fn open(path: &std::path::Path, size: u32) -> std::io::Result<Self> {
        use std::io::{Seek, SeekFrom, Write};
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)?;
        let len = file.metadata()?.len();
        if len < u64::from(size) {
            file.seek(SeekFrom::Start(len))?;
            let pad = vec![0xFF; (u64::from(size) - len) as usize];
            file.write_all(&pad)?;
            file.sync_all()?;
        }
        Ok(FileFlash { file, size })
    }
}

#[cfg(feature = "std")]
impl Flash for FileFlash {
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), FlashError> {
        use std::os::unix::fs::FileExt;
        bounds(offset, buf.len(), self.size as usize)?;
        self.file
            .read_exact_at(buf, u64::from(offset))
            .map_err(|_| FlashError::Device)
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), FlashError> {
        use std::os::unix::fs::FileExt;
        bounds(offset, data.len(), self.size as usize)?;
        let mut old = vec![0u8; data.len()];
        self.file
            .read_exact_at(&mut old, u64::from(offset))
            .map_err(|_| FlashError::Device)?;
        for (o, d) in old.iter_mut().zip(data) {
            *o &= *d;
        }
        self.file
            .write_all_at(&old, u64::from(offset))
            .map_err(|_| FlashError::Device)?;
        self.file.sync_data().map_err(|_| FlashError::Device)
    }
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        use std::os::unix::fs::FileExt;
        if from > to || !from.is_multiple_of(4096) || !to.is_multiple_of(4096) {
            return Err(FlashError::OutOfBounds);
        }
        bounds(from, (to - from) as usize, self.size as usize)?;
        let ones = vec![0xFF; (to - from) as usize];
        self.file
            .write_all_at(&ones, u64::from(from))
            .map_err(|_| FlashError::Device)?;
        self.file.sync_data().map_err(|_| FlashError::Device)
    }
    fn capacity(&self) -> u32 {
        self.size
    }
    fn erase_size(&self) -> u32 {
        4096
    }
    fn write_size(&self) -> u32 {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: UPD-OTA-03
    #[test]
    fn a_partition_never_reaches_outside_its_window() {
        let nor = RefCell::new(RamNor::<{ 4 * 4096 }>::new());
        assert!(Partition::new(&nor, 4096, 3 * 4096 + 1).is_none(), "past the end");
        assert!(Partition::new(&nor, 100, 4096).is_none(), "misaligned");
        let mut p = Partition::new(&nor, 4096, 2 * 4096).unwrap();
        let mut q = Partition::new(&nor, 3 * 4096, 4096).unwrap();
        assert_eq!(p.capacity(), 8192);
        p.write(0, &[0x12, 0x34]).unwrap();
        assert_eq!(p.write(8191, &[0, 0]), Err(FlashError::OutOfBounds));
        assert_eq!(p.erase(0, 3 * 4096), Err(FlashError::OutOfBounds));
        let mut b = [0; 2];
        p.read(0, &mut b).unwrap();
        assert_eq!(b, [0x12, 0x34]);
        p.erase(0, 4096).unwrap();
        assert!(
            nor.borrow().bytes.iter().all(|&x| x == 0xFF),
            "erased at the window, nothing else"
        );
        p.write(8191, &[0]).unwrap();
        q.read(4095, &mut b[..1]).unwrap();
        assert_eq!(b[0], 0xFF, "the two windows do not overlap");
        q.write(0, &[0]).unwrap();
        assert_eq!(nor.borrow().bytes[3 * 4096 - 1], 0);
        assert_eq!(nor.borrow().bytes[3 * 4096], 0);
        assert_eq!(nor.borrow().bytes.iter().filter(|&&x| x != 0xFF).count(), 2);
        let held = nor.borrow_mut();
        assert_eq!(
            q.write(1, &[0]),
            Err(FlashError::Device),
            "a flash in use is an error, not a panic"
        );
        drop(held);
    }
}
