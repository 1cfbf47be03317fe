//! Module descriptors: fixed 28-byte binary layout with a CRC, and a board's descriptor
//! table (the copy in board A's flash, and board B's half sent over the A–B link).
//!
//! Descriptor (all multi-byte fields big-endian):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 1 | layout version ([`DESCRIPTOR_VERSION`]) |
//! | 1 | 1 | type ([`ModuleType`] code) |
//! | 2 | 1 | variant |
//! | 3 | 1 | revision |
//! | 4 | 4 | serial number |
//! | 8 | 1 | side ([`ModuleSide`] code) |
//! | 9 | 1 | port (PWM channel, I2C address, 0 for boards) |
//! | 10 | 16 | calibration: 8 × i16, meaning per type ([`ModuleType::cal_names`]) |
//! | 26 | 2 | CRC-16/CCITT-FALSE over bytes 0..26 |
//!
//! Table: `'M' 'T'`, table version ([`TABLE_VERSION`]), count (≤ [`MAX_TABLE_ENTRIES`]),
//! then `count` descriptors. A table's header is not covered by a CRC of its own: each
//! entry carries one, and a wrong count shows up as a truncated table or a bad entry CRC.

use super::{ModuleSide, ModuleType, MAX_TABLE_ENTRIES};
use core::fmt;

/// Length of one encoded descriptor.
pub const DESCRIPTOR_LEN: usize = 28;
/// Layout version written in byte 0.
pub const DESCRIPTOR_VERSION: u8 = 1;
/// Table magic.
pub const TABLE_MAGIC: [u8; 2] = *b"MT";
/// Table layout version.
pub const TABLE_VERSION: u8 = 1;
/// Table header length.
pub const TABLE_HEADER_LEN: usize = 4;
/// Largest encoded table.
pub const MAX_TABLE_LEN: usize = TABLE_HEADER_LEN + MAX_TABLE_ENTRIES * DESCRIPTOR_LEN;

/// The descriptor CRC: the project's one CRC-16 (`headers::PEC_CRC`, CRC-16/CCITT-FALSE), as
/// the PUS packets, the A–B link and the transfer frames.
pub const DESCRIPTOR_CRC: crc::Crc<u16> = crate::headers::PEC_CRC;

/// Calibration words of a module (meaning per type, see [`ModuleType::cal_names`]).
/// A word equal to [`CAL_DEFAULT`] means "the database default of this revision"
/// (`super::db::resolve_calibration`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Calibration(pub [i16; 8]);

/// Calibration word meaning "use the module database's default for this word"
/// (`0x8000`, never a valid value of any word).
pub const CAL_DEFAULT: i16 = i16::MIN;

impl Calibration {
    /// Every word "database default".
    pub const DEFAULT: Calibration = Calibration([CAL_DEFAULT; 8]);
}

/// A module descriptor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Descriptor {
    pub ty: ModuleType,
    pub variant: u8,
    pub revision: u8,
    pub serial: u32,
    pub side: ModuleSide,
    pub port: u8,
    pub cal: Calibration,
}

/// Why bytes are not a descriptor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DescError {
    /// Fewer than [`DESCRIPTOR_LEN`] bytes (or, for `emit`, buffer too small).
    Truncated { len: usize },
    /// Layout version other than [`DESCRIPTOR_VERSION`].
    Version(u8),
    /// The CRC over bytes 0..26 does not match the stored one.
    Crc { stored: u16, computed: u16 },
}

impl fmt::Display for DescError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DescError::Truncated { len } => {
                write!(f, "descriptor truncated: {len} bytes, {DESCRIPTOR_LEN} needed")
            }
            DescError::Version(v) => write!(f, "descriptor layout version {v} (expected {DESCRIPTOR_VERSION})"),
            DescError::Crc { stored, computed } => {
                write!(f, "descriptor CRC {stored:#06x} stored, {computed:#06x} computed")
            }
        }
    }
}

impl core::error::Error for DescError {}

/// Why bytes are not a descriptor table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableError {
    /// Shorter than the header.
    Truncated {
        len: usize,
        needed: usize,
    },
    Magic([u8; 2]),
    Version(u8),
    /// More entries than [`MAX_TABLE_ENTRIES`].
    TooMany(u8),
    /// Bytes after the last entry.
    Trailing {
        len: usize,
        expected: usize,
    },
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TableError::Truncated { len, needed } => {
                write!(f, "descriptor table truncated: {len} bytes, {needed} needed")
            }
            TableError::Magic(m) => write!(f, "descriptor table magic {:02x}{:02x} (expected 4d54)", m[0], m[1]),
            TableError::Version(v) => write!(f, "descriptor table version {v} (expected {TABLE_VERSION})"),
            TableError::TooMany(n) => {
                write!(f, "descriptor table lists {n} entries (at most {MAX_TABLE_ENTRIES})")
            }
            TableError::Trailing { len, expected } => {
                write!(f, "descriptor table has {len} bytes, {expected} expected")
            }
        }
    }
}

impl core::error::Error for TableError {}

impl Descriptor {
    /// Bytes 0..26 (everything the CRC covers).
    pub fn body(&self) -> [u8; DESCRIPTOR_LEN - 2] {
        let mut b = [0u8; DESCRIPTOR_LEN - 2];
        b[0] = DESCRIPTOR_VERSION;
        b[1] = self.ty.code();
        b[2] = self.variant;
        b[3] = self.revision;
        b[4..8].copy_from_slice(&self.serial.to_be_bytes());
        b[8] = self.side.code();
        b[9] = self.port;
        for (i, w) in self.cal.0.iter().enumerate() {
            b[10 + 2 * i..12 + 2 * i].copy_from_slice(&w.to_be_bytes());
        }
        b
    }

    /// The encoded descriptor with its CRC.
    pub fn to_bytes(&self) -> [u8; DESCRIPTOR_LEN] {
        let mut out = [0u8; DESCRIPTOR_LEN];
        let body = self.body();
        out[..DESCRIPTOR_LEN - 2].copy_from_slice(&body);
        out[DESCRIPTOR_LEN - 2..].copy_from_slice(&DESCRIPTOR_CRC.checksum(&body).to_be_bytes());
        out
    }

    /// Writes the descriptor into `buf`; returns the length written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, DescError> {
        let len = buf.len();
        let dst = buf.get_mut(..DESCRIPTOR_LEN).ok_or(DescError::Truncated { len })?;
        dst.copy_from_slice(&self.to_bytes());
        Ok(DESCRIPTOR_LEN)
    }

    /// Parses the first [`DESCRIPTOR_LEN`] bytes of `bytes` (checked: length, version, CRC).
    pub fn parse(bytes: &[u8]) -> Result<Descriptor, DescError> {
        let b = bytes
            .get(..DESCRIPTOR_LEN)
            .ok_or(DescError::Truncated { len: bytes.len() })?;
        let stored = u16::from_be_bytes([b[26], b[27]]);
        let computed = DESCRIPTOR_CRC.checksum(&b[..26]);
        if stored != computed {
            return Err(DescError::Crc { stored, computed });
        }
        if b[0] != DESCRIPTOR_VERSION {
            return Err(DescError::Version(b[0]));
        }
        let mut cal = [0i16; 8];
        for (i, w) in cal.iter_mut().enumerate() {
            *w = i16::from_be_bytes([b[10 + 2 * i], b[11 + 2 * i]]);
        }
        Ok(Descriptor {
            ty: ModuleType::from_code(b[1]),
            variant: b[2],
            revision: b[3],
            serial: u32::from_be_bytes([b[4], b[5], b[6], b[7]]),
            side: ModuleSide::from_code(b[8]),
            port: b[9],
            cal: Calibration(cal),
        })
    }
}

/// A parsed table header: the entries follow.
#[derive(Clone, Copy, Debug)]
pub struct Table<'a> {
    entries: &'a [u8],
    count: u8,
}

impl<'a> Table<'a> {
    /// Checks the header and the total length.
    pub fn parse(bytes: &'a [u8]) -> Result<Table<'a>, TableError> {
        if bytes.len() < TABLE_HEADER_LEN {
            return Err(TableError::Truncated {
                len: bytes.len(),
                needed: TABLE_HEADER_LEN,
            });
        }
        if bytes[0..2] != TABLE_MAGIC {
            return Err(TableError::Magic([bytes[0], bytes[1]]));
        }
        if bytes[2] != TABLE_VERSION {
            return Err(TableError::Version(bytes[2]));
        }
        let count = bytes[3];
        if count as usize > MAX_TABLE_ENTRIES {
            return Err(TableError::TooMany(count));
        }
        let expected = TABLE_HEADER_LEN + count as usize * DESCRIPTOR_LEN;
        if bytes.len() < expected {
            return Err(TableError::Truncated {
                len: bytes.len(),
                needed: expected,
            });
        }
        if bytes.len() > expected {
            return Err(TableError::Trailing {
                len: bytes.len(),
                expected,
            });
        }
        Ok(Table {
            entries: &bytes[TABLE_HEADER_LEN..],
            count,
        })
    }
    pub fn len(&self) -> usize {
        self.count as usize
    }
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
    /// Raw bytes of entry `i`.
    pub fn raw(&self, i: usize) -> Option<&'a [u8]> {
        if i >= self.len() {
            return None;
        }
        self.entries.get(i * DESCRIPTOR_LEN..(i + 1) * DESCRIPTOR_LEN)
    }
    /// Entry `i`, parsed and checked.
    pub fn entry(&self, i: usize) -> Option<Result<Descriptor, DescError>> {
        self.raw(i).map(Descriptor::parse)
    }
}

/// Encodes a table of `descs` into `buf`; returns the length written.
pub fn emit_table(descs: &[Descriptor], buf: &mut [u8]) -> Result<usize, TableError> {
    if descs.len() > MAX_TABLE_ENTRIES {
        return Err(TableError::TooMany(descs.len().min(255) as u8));
    }
    let needed = TABLE_HEADER_LEN + descs.len() * DESCRIPTOR_LEN;
    let len = buf.len();
    let out = buf.get_mut(..needed).ok_or(TableError::Truncated { len, needed })?;
    out[0..2].copy_from_slice(&TABLE_MAGIC);
    out[2] = TABLE_VERSION;
    out[3] = descs.len() as u8;
    for (i, d) in descs.iter().enumerate() {
        let at = TABLE_HEADER_LEN + i * DESCRIPTOR_LEN;
        out[at..at + DESCRIPTOR_LEN].copy_from_slice(&d.to_bytes());
    }
    Ok(needed)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GRIPPER: Descriptor = Descriptor {
        ty: ModuleType::Gripper,
        variant: 0,
        revision: 2,
        serial: 0x0102_0304,
        side: ModuleSide::B,
        port: 2,
        cal: Calibration([1150, 1850, 1150, 350, 950, 0, 0, 0]),
    };

    /// The same descriptor laid out by hand from the table in the module doc.
    const GRIPPER_BYTES_NO_CRC: [u8; 26] = [
        1, 3, 0, 2, 0x01, 0x02, 0x03, 0x04, 1, 2, 0x04, 0x7e, 0x07, 0x3a, 0x04, 0x7e, 0x01, 0x5e, 0x03, 0xb6, 0, 0, 0,
        0, 0, 0,
    ];

    // verifies: MOD-DESC-01
    #[test]
    fn descriptor_layout_matches_the_documented_bytes() {
        let b = GRIPPER.to_bytes();
        assert_eq!(b[..26], GRIPPER_BYTES_NO_CRC);
        // CRC-16/CCITT-FALSE check value of "123456789" is 0x29B1: the right algorithm.
        assert_eq!(DESCRIPTOR_CRC.checksum(b"123456789"), 0x29B1);
        let crc = DESCRIPTOR_CRC.checksum(&GRIPPER_BYTES_NO_CRC);
        assert_eq!(b[26..], crc.to_be_bytes());
        assert_eq!(Descriptor::parse(&b), Ok(GRIPPER));
        let mut buf = [0u8; 40];
        assert_eq!(GRIPPER.emit(&mut buf), Ok(DESCRIPTOR_LEN));
        assert_eq!(buf[..DESCRIPTOR_LEN], b);
        assert_eq!(GRIPPER.emit(&mut buf[..10]), Err(DescError::Truncated { len: 10 }));
    }

    // verifies: MOD-DESC-02
    #[test]
    fn every_single_bit_flip_and_truncation_is_rejected() {
        let good = GRIPPER.to_bytes();
        for bit in 0..DESCRIPTOR_LEN * 8 {
            let mut b = good;
            b[bit / 8] ^= 1 << (bit % 8);
            assert!(
                matches!(Descriptor::parse(&b), Err(DescError::Crc { .. })),
                "bit {bit} flip accepted"
            );
        }
        for len in 0..DESCRIPTOR_LEN {
            assert_eq!(Descriptor::parse(&good[..len]), Err(DescError::Truncated { len }));
        }
        // A wrong layout version with a valid CRC is refused by version.
        let mut body = GRIPPER.body();
        body[0] = 7;
        let mut b = [0u8; DESCRIPTOR_LEN];
        b[..26].copy_from_slice(&body);
        b[26..].copy_from_slice(&DESCRIPTOR_CRC.checksum(&body).to_be_bytes());
        assert_eq!(Descriptor::parse(&b), Err(DescError::Version(7)));
    }

    // verifies: MOD-DESC-03
    #[test]
    fn table_round_trip_and_checked_header() {
        let mut other = GRIPPER;
        other.ty = ModuleType::Arm;
        other.serial = 9;
        let mut buf = [0u8; MAX_TABLE_LEN];
        let n = emit_table(&[GRIPPER, other], &mut buf).unwrap();
        assert_eq!(n, TABLE_HEADER_LEN + 2 * DESCRIPTOR_LEN);
        let t = Table::parse(&buf[..n]).unwrap();
        assert_eq!(t.len(), 2);
        assert_eq!(t.entry(0), Some(Ok(GRIPPER)));
        assert_eq!(t.entry(1), Some(Ok(other)));
        assert_eq!(t.entry(2), None);
        assert!(matches!(Table::parse(&buf[..n - 1]), Err(TableError::Truncated { .. })));
        assert!(matches!(Table::parse(&buf[..n + 1]), Err(TableError::Trailing { .. })));
        assert!(matches!(Table::parse(&buf[..3]), Err(TableError::Truncated { .. })));
        let mut bad = buf;
        bad[0] = b'X';
        assert!(matches!(Table::parse(&bad[..n]), Err(TableError::Magic(_))));
        let mut bad = buf;
        bad[3] = 9;
        assert_eq!(Table::parse(&bad[..n]).err(), Some(TableError::TooMany(9)));
        let mut bad = buf;
        bad[2] = 2;
        assert_eq!(Table::parse(&bad[..n]).err(), Some(TableError::Version(2)));
        let nine = [GRIPPER; 9];
        assert_eq!(emit_table(&nine, &mut buf), Err(TableError::TooMany(9)));
    }
}
