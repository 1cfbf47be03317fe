//! A PDU held for the link: its bytes in a fixed buffer of `mib::cfdp::MAX_PDU_LEN`.
//!
//! Its own type, not `heapless::Vec<u8, N>`: heapless 0.8 fills a `Vec` from a slice and
//! clones it one byte at a time (≈ 14 600 instructions for a 960-byte file data PDU on
//! RV32IMC, measured in `firmware/qemu-tests` `t_files`), where a slice copy is `memcpy`.
//! A board's get made that copy twice a segment, three segments a period.

use core::fmt;
use core::ops::Deref;
use mib::cfdp as m;

/// At most `MAX_PDU_LEN` bytes; never more (the constructors refuse them). Word-aligned:
/// RV32 copies it a word at a time (aligned to its `u16` it was copied a half-word at a
/// time, ≈ 2 000 instructions a move).
#[derive(Clone)]
#[repr(C, align(4))]
pub struct Pdu {
    bytes: [u8; m::MAX_PDU_LEN],
    len: u16,
}

/// A PDU longer than `MAX_PDU_LEN`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TooLong;

// The length is kept in a u16.
const _: () = assert!(m::MAX_PDU_LEN <= u16::MAX as usize);

impl Pdu {
    /// No bytes.
    pub const fn new() -> Self {
        Pdu {
            bytes: [0; m::MAX_PDU_LEN],
            len: 0,
        }
    }

    /// A copy of `raw`.
    pub fn from_slice(raw: &[u8]) -> Result<Self, TooLong> {
        let mut p = Pdu::new();
        p.set(raw)?;
        Ok(p)
    }

    /// Holds a copy of `raw` instead of what it held (in place: a board's stack need not
    /// hold a second buffer); on `TooLong` it is left empty.
    pub fn set(&mut self, raw: &[u8]) -> Result<(), TooLong> {
        let Some(dst) = self.bytes.get_mut(..raw.len()) else {
            self.len = 0;
            return Err(TooLong);
        };
        dst.copy_from_slice(raw);
        self.len = raw.len() as u16;
        Ok(())
    }

    pub fn as_slice(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }
}

impl Default for Pdu {
    fn default() -> Self {
        Pdu::new()
    }
}

impl Deref for Pdu {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        self.as_slice()
    }
}

impl AsRef<[u8]> for Pdu {
    fn as_ref(&self) -> &[u8] {
        self.as_slice()
    }
}

impl PartialEq for Pdu {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl Eq for Pdu {}

impl fmt::Debug for Pdu {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("Pdu").field(&self.as_slice()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: FILE-CFDP-01
    #[test]
    fn holds_a_copy_and_refuses_one_byte_too_many() {
        let raw = [7u8; m::MAX_PDU_LEN];
        let p = Pdu::from_slice(&raw).unwrap();
        assert_eq!(&*p, &raw[..]);
        assert_eq!(p.clone(), p);
        let long = [7u8; m::MAX_PDU_LEN + 1];
        assert_eq!(Pdu::from_slice(&long), Err(TooLong));
        let mut q = Pdu::from_slice(&[1, 2, 3]).unwrap();
        assert_eq!(q.set(&long), Err(TooLong));
        assert!(q.is_empty(), "left empty, not holding the old bytes");
        assert_eq!(Pdu::new().len(), 0);
    }
}
