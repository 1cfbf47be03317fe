//! What the file store's tests share: a NOR flash model of the board's part (4 KiB erase
//! sectors, 4-byte words, writes only clear bits) whose power can be cut at any write or
//! erase, with what it did counted; the seeded generator of the lossy links. Each test file
//! uses part of it.
#![allow(dead_code)]

use std::cell::RefCell;
use std::rc::Rc;

use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// A seeded generator for the tests' lossy links (xorshift64): each seed a reproducible run.
pub struct Rng(pub u64);

impl Rng {
    /// A number in [0, 1).
    pub fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The part's erase sector.
pub const SECTOR: usize = 4096;

/// What the flash holds and how many more writes and erases it makes before the power
/// goes (shared with the test, which keeps it across the store's "resets").
pub struct Chip {
    pub mem: Vec<u8>,
    /// Writes and erases left; at 0 the next one is cut half way and the power is gone.
    pub left: Option<u64>,
    pub dead: bool,
    /// Writes and erases made.
    pub ops: u64,
    /// Addresses of the sectors erased.
    pub erased: Vec<u32>,
    /// Bytes read and written.
    pub read: u64,
    pub written: u64,
    /// How a cut erase is left (see `erase`; `None`: by turns), and where the cut erase was.
    pub tear: Option<u64>,
    pub torn_erase: Option<u32>,
}

#[derive(Clone)]
pub struct Nor(pub Rc<RefCell<Chip>>);

#[derive(Debug)]
pub enum NorErr {
    PowerLost,
    Rules,
}

impl NorFlashError for NorErr {
    fn kind(&self) -> NorFlashErrorKind {
        NorFlashErrorKind::Other
    }
}

impl Nor {
    pub fn new(bytes: usize) -> Nor {
        Nor::with(vec![0xFF; bytes])
    }

    /// A flash holding `mem` (an image kept from another).
    pub fn with(mem: Vec<u8>) -> Nor {
        Nor(Rc::new(RefCell::new(Chip {
            mem,
            left: None,
            dead: false,
            ops: 0,
            erased: Vec::new(),
            read: 0,
            written: 0,
            tear: None,
            torn_erase: None,
        })))
    }

    /// Power comes back (after a cut): no limit.
    pub fn power_on(&self) {
        let mut c = self.0.borrow_mut();
        c.dead = false;
        c.left = None;
    }

    pub fn cut_after(&self, n: u64) {
        self.0.borrow_mut().left = Some(n);
    }

    pub fn dead(&self) -> bool {
        self.0.borrow().dead
    }

    pub fn ops(&self) -> u64 {
        self.0.borrow().ops
    }

    /// What it holds now.
    pub fn image(&self) -> Vec<u8> {
        self.0.borrow().mem.clone()
    }

    /// Counts a write or erase; `false` when the power goes during it.
    fn spend(c: &mut Chip) -> Result<bool, NorErr> {
        if c.dead {
            return Err(NorErr::PowerLost);
        }
        c.ops += 1;
        match &mut c.left {
            Some(0) => {
                c.dead = true;
                Ok(false)
            }
            Some(n) => {
                *n -= 1;
                Ok(true)
            }
            None => Ok(true),
        }
    }
}

impl ErrorType for Nor {
    type Error = NorErr;
}

impl ReadNorFlash for Nor {
    const READ_SIZE: usize = 4;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), NorErr> {
        let mut c = self.0.borrow_mut();
        c.read += bytes.len() as u64;
        if c.dead {
            return Err(NorErr::PowerLost);
        }
        let o = offset as usize;
        if !o.is_multiple_of(4) || !bytes.len().is_multiple_of(4) || o + bytes.len() > c.mem.len() {
            return Err(NorErr::Rules);
        }
        bytes.copy_from_slice(&c.mem[o..o + bytes.len()]);
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.0.borrow().mem.len()
    }
}

impl NorFlash for Nor {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = SECTOR;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), NorErr> {
        let c = &mut *self.0.borrow_mut();
        let (f, t) = (from as usize, to as usize);
        if f % SECTOR != 0 || t % SECTOR != 0 || t < f || t > c.mem.len() {
            return Err(NorErr::Rules);
        }
        c.erased.push(from);
        if Nor::spend(c)? {
            c.mem[f..t].fill(0xFF);
            Ok(())
        } else {
            // Cut: part of the sector erased, the rest as it was. Which part is the
            // part's business, so by turns: the first half, the second half, or both ends
            // (the page's first and last words erased, its middle not).
            let (half, quarter) = ((t - f) / 2, (t - f) / 4);
            c.torn_erase = Some(from);
            match c.tear.unwrap_or(c.ops) % 3 {
                0 => c.mem[f..f + half].fill(0xFF),
                1 => c.mem[f + half..t].fill(0xFF),
                _ => {
                    c.mem[f..f + quarter].fill(0xFF);
                    c.mem[t - quarter..t].fill(0xFF);
                }
            }
            Err(NorErr::PowerLost)
        }
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), NorErr> {
        let c = &mut *self.0.borrow_mut();
        let o = offset as usize;
        if !o.is_multiple_of(4) || !bytes.len().is_multiple_of(4) || o + bytes.len() > c.mem.len() {
            return Err(NorErr::Rules);
        }
        // NOR clears bits only: a write that would set one is a bug of the layout.
        if c.mem[o..o + bytes.len()].iter().zip(bytes).any(|(m, b)| b & !m != 0) {
            return Err(NorErr::Rules);
        }
        let whole = Nor::spend(c)?;
        c.written += bytes.len() as u64;
        // Cut: the first half of the words programmed.
        let n = if whole { bytes.len() } else { bytes.len() / 8 * 4 };
        for (m, b) in c.mem[o..o + n].iter_mut().zip(bytes) {
            *m &= b;
        }
        if whole {
            Ok(())
        } else {
            Err(NorErr::PowerLost)
        }
    }
}

impl MultiwriteNorFlash for Nor {}
