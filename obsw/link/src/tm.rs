//! TM transfer frames (CCSDS 132.0-B-3 §4.1): fixed length `mib::link::tm_frame::LEN`, no
//! secondary header, OCF (the CLCW) and FECF on every frame.
//!
//! ```text
//!  0               1               2          3          4               5
//! +--+------------+------+-+----------+----------+-+-+-+---+-------------+
//! |TV| SCID (10)  |VC (3)|O| MC count | VC count |S|Y|P|SL | first hdr ptr|
//! +--+------------+------+-+----------+----------+-+-+-+---+-------------+
//! | data field (security header, packets, MAC)          | OCF (4) | FECF |
//! ```
//! O = OCF flag, S = secondary header flag, Y = sync flag, P = packet order, SL = segment
//! length id (`11`), first header pointer 11 bits (0x7FF: no packet starts here, 0x7FE: only
//! idle data).

use core::fmt;

use mib::link::tm_frame::{FECF_LEN, HEADER_LEN, LEN, OCF_LEN};

use crate::fecf;

/// Why TM frame bytes were refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TmError {
    /// Not the fixed frame length.
    BadLength(usize),
    BadVersion(u8),
    /// A secondary header, sync flag, packet order flag or segment length id we do not use.
    UnsupportedDataFieldStatus(u16),
    /// The OCF flag is clear (every frame of this mission carries the CLCW).
    NoOcf,
    BadCrc,
}

impl fmt::Display for TmError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TmError::BadLength(n) => write!(f, "TM frame of {n} bytes, expected {LEN}"),
            TmError::BadVersion(v) => write!(f, "TM frame version {v}"),
            TmError::UnsupportedDataFieldStatus(s) => write!(f, "TM data field status {s:#06x}"),
            TmError::NoOcf => write!(f, "TM frame without OCF"),
            TmError::BadCrc => write!(f, "TM frame CRC mismatch"),
        }
    }
}

impl core::error::Error for TmError {}

/// The first header pointer (11 bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FirstHeaderPointer {
    /// Offset of the first packet header in the packet zone.
    Offset(u16),
    /// 0x7FF: no packet starts in this frame (continuation only).
    NoPacketStart,
    /// 0x7FE: only idle data.
    IdleOnly,
}

impl From<u16> for FirstHeaderPointer {
    fn from(v: u16) -> Self {
        match v & 0x7FF {
            0x7FF => FirstHeaderPointer::NoPacketStart,
            0x7FE => FirstHeaderPointer::IdleOnly,
            n => FirstHeaderPointer::Offset(n),
        }
    }
}

impl From<FirstHeaderPointer> for u16 {
    fn from(f: FirstHeaderPointer) -> u16 {
        match f {
            FirstHeaderPointer::NoPacketStart => 0x7FF,
            FirstHeaderPointer::IdleOnly => 0x7FE,
            FirstHeaderPointer::Offset(n) => n & 0x7FF,
        }
    }
}

/// Segment length id `11` with every other status flag clear.
const DFS_FIXED: u16 = 0b0001_1000_0000_0000;
const DFS_FLAGS: u16 = 0xF800;

/// A zero-copy view over a TM transfer frame.
#[derive(Debug, Clone)]
pub struct TmFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> TmFrame<T> {
    pub const fn new_unchecked(buffer: T) -> Self {
        TmFrame { buffer }
    }

    /// Checks length, version, the data field status flags and the OCF flag. The FECF is not
    /// checked here.
    pub fn new_checked(buffer: T) -> Result<Self, TmError> {
        let len = buffer.as_ref().len();
        if len != LEN {
            return Err(TmError::BadLength(len));
        }
        let f = TmFrame { buffer };
        if f.version() != mib::link::TM_TFVN {
            return Err(TmError::BadVersion(f.version()));
        }
        if f.data_field_status() & DFS_FLAGS != DFS_FIXED {
            return Err(TmError::UnsupportedDataFieldStatus(f.data_field_status()));
        }
        if !f.ocf_flag() {
            return Err(TmError::NoOcf);
        }
        Ok(f)
    }

    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn word0(&self) -> u16 {
        let b = self.buffer.as_ref();
        u16::from_be_bytes([b[0], b[1]])
    }

    pub fn version(&self) -> u8 {
        (self.word0() >> 14) as u8
    }

    pub fn scid(&self) -> u16 {
        (self.word0() >> 4) & 0x3FF
    }

    pub fn vcid(&self) -> u8 {
        ((self.word0() >> 1) & 7) as u8
    }

    pub fn ocf_flag(&self) -> bool {
        self.word0() & 1 != 0
    }

    pub fn mc_count(&self) -> u8 {
        self.buffer.as_ref()[2]
    }

    pub fn vc_count(&self) -> u8 {
        self.buffer.as_ref()[3]
    }

    pub fn data_field_status(&self) -> u16 {
        let b = self.buffer.as_ref();
        u16::from_be_bytes([b[4], b[5]])
    }

    pub fn first_header_pointer(&self) -> FirstHeaderPointer {
        FirstHeaderPointer::from(self.data_field_status())
    }

    /// The data field: after the primary header, before the OCF.
    pub fn data(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        &b[HEADER_LEN..b.len() - OCF_LEN - FECF_LEN]
    }

    pub fn ocf(&self) -> u32 {
        let b = self.buffer.as_ref();
        let o = b.len() - OCF_LEN - FECF_LEN;
        u32::from_be_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
    }

    pub fn check_fecf(&self) -> bool {
        fecf::check(self.buffer.as_ref())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> TmFrame<T> {
    pub fn data_mut(&mut self) -> &mut [u8] {
        let b = self.buffer.as_mut();
        let end = b.len() - OCF_LEN - FECF_LEN;
        &mut b[HEADER_LEN..end]
    }

    pub fn set_ocf(&mut self, word: u32) {
        let b = self.buffer.as_mut();
        let o = b.len() - OCF_LEN - FECF_LEN;
        b[o..o + 4].copy_from_slice(&word.to_be_bytes());
    }

    pub fn fill_fecf(&mut self) {
        fecf::seal(self.buffer.as_mut());
    }
}

/// The primary header of a TM frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TmRepr {
    pub scid: u16,
    pub vcid: u8,
    pub mc_count: u8,
    pub vc_count: u8,
    pub fhp: FirstHeaderPointer,
}

impl TmRepr {
    pub fn parse<T: AsRef<[u8]>>(f: &TmFrame<T>) -> TmRepr {
        TmRepr {
            scid: f.scid(),
            vcid: f.vcid(),
            mc_count: f.mc_count(),
            vc_count: f.vc_count(),
            fhp: f.first_header_pointer(),
        }
    }

    pub const fn buffer_len(&self) -> usize {
        LEN
    }

    /// Writes the 6 header bytes (OCF flag set). The frame must be `LEN` bytes.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, f: &mut TmFrame<T>) {
        let w0 =
            (u16::from(mib::link::TM_TFVN) << 14) | ((self.scid & 0x3FF) << 4) | (u16::from(self.vcid & 7) << 1) | 1;
        let dfs = DFS_FIXED | u16::from(self.fhp);
        let b = f.buffer.as_mut();
        b[0..2].copy_from_slice(&w0.to_be_bytes());
        b[2] = self.mc_count;
        b[3] = self.vc_count;
        b[4..6].copy_from_slice(&dfs.to_be_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> [u8; LEN] {
        let mut b = [0x55u8; LEN];
        // SCID 0x0AB, VC 1, OCF: 0x0AB<<4 | 1<<1 | 1 = 0x0AB3.
        b[..6].copy_from_slice(&[0x0A, 0xB3, 7, 9, 0x18, 0x10]);
        let o = LEN - 6;
        b[o..o + 4].copy_from_slice(&[0x01, 0x00, 0x00, 0x05]);
        crate::fecf::seal(&mut b);
        b
    }

    // verifies: LINK-TM-01
    #[test]
    fn parse_tm_byte_array() {
        let b = sample();
        let f = TmFrame::new_checked(&b[..]).unwrap();
        assert_eq!(
            TmRepr::parse(&f),
            TmRepr {
                scid: 0x0AB,
                vcid: 1,
                mc_count: 7,
                vc_count: 9,
                fhp: FirstHeaderPointer::Offset(0x10)
            }
        );
        assert!(f.check_fecf());
        assert_eq!(f.ocf(), 0x0100_0005);
        assert_eq!(f.data().len(), LEN - 12);
        let mut e = [0x55u8; LEN];
        let mut ef = TmFrame::new_unchecked(&mut e[..]);
        TmRepr::parse(&f).emit(&mut ef);
        ef.set_ocf(0x0100_0005);
        ef.fill_fecf();
        assert_eq!(e, b);
    }

    // verifies: LINK-TM-01
    #[test]
    fn tm_checked_constructor_refusals() {
        let b = sample();
        assert_eq!(
            TmFrame::new_checked(&b[..LEN - 1]).unwrap_err(),
            TmError::BadLength(LEN - 1)
        );
        let mut v = b;
        v[0] |= 0x40;
        assert_eq!(TmFrame::new_checked(&v[..]).unwrap_err(), TmError::BadVersion(1));
        let mut s = b;
        s[4] |= 0x80;
        assert!(matches!(
            TmFrame::new_checked(&s[..]),
            Err(TmError::UnsupportedDataFieldStatus(_))
        ));
        let mut o = b;
        o[1] &= 0xFE;
        assert_eq!(TmFrame::new_checked(&o[..]).unwrap_err(), TmError::NoOcf);
        let mut c = b;
        c[100] ^= 0x80;
        assert!(!TmFrame::new_checked(&c[..]).unwrap().check_fecf());
        assert_eq!(FirstHeaderPointer::from(0x7FE), FirstHeaderPointer::IdleOnly);
        assert_eq!(u16::from(FirstHeaderPointer::NoPacketStart), 0x7FF);
    }
}
