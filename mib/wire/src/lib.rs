//! MMIC-I packets on the wire, generated from the MIB's field lists (`mib::layout`).
//!
//! For every TC and TM kind of the MIB there is a small owned `Repr` (module [`tc`] and
//! [`tm`]) with a checked `parse` and an `emit` (smoltcp's pattern), and a zero-copy view
//! over the fixed part of the body. Shared pieces: one typed [`Failure`] (failure code and
//! its data), [`Event`] (event ID and its parameters), [`Hk`] (SID and its parameters),
//! [`RequestId`] and [`CdsTime`], and the CCSDS/PUS headers in [`header`]. The build script
//! writes the code from the MIB; nothing here lays a body out by hand.
//!
//! `parse` checks structure (lengths, counts, known codes, booleans 0/1); argument ranges
//! are the acceptance check's job ([`codec::decode_args`], ranges from the MIB). For every body that parses,
//! `emit` writes back exactly the bytes it came from.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]

pub mod codec;
pub mod header;

pub use header::{CRC_LEN, MIN_TC_LEN, MIN_TM_LEN, PRIMARY_HEADER_LEN, TC_SEC_HEADER_LEN, TM_SEC_HEADER_LEN};

/// Why a body could not be parsed or emitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// The body ends before `field`.
    Truncated { field: &'static str },
    /// Bytes left after the last field.
    TrailingBytes { len: usize },
    /// A repeated group longer than its capacity.
    TooMany {
        field: &'static str,
        count: usize,
        max: usize,
    },
    /// An embedded packet longer than its capacity or with an impossible length field.
    BadPacket { field: &'static str, len: usize },
    /// A boolean field other than 0 or 1.
    NotBool { field: &'static str, value: u8 },
    /// A housekeeping structure ID the MIB does not define.
    UnknownSid(u16),
    /// Failure data or event parameters of an unknown code longer than kept.
    UnknownTooLong { code: u16, len: usize },
    /// A service/subservice (or PUS 8 function) the MIB does not define.
    UnknownKind { service: u8, subservice: u8 },
    /// The PUS 8 function ID does not match the kind.
    WrongFunction { expected: u16, got: u16 },
    /// The output buffer is too short.
    BufferTooShort { need: usize, have: usize },
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::Truncated { field } => write!(f, "data ends before field `{field}`"),
            Error::TrailingBytes { len } => write!(f, "{len} bytes after the last field"),
            Error::TooMany { field, count, max } => write!(f, "`{field}`: {count} entries, at most {max}"),
            Error::BadPacket { field, len } => write!(f, "`{field}`: embedded packet of {len} bytes is not valid here"),
            Error::NotBool { field, value } => write!(f, "`{field}` = {value} is not a boolean (0/1)"),
            Error::UnknownSid(s) => write!(f, "housekeeping structure ID {s} not in the MIB"),
            Error::UnknownTooLong { code, len } => {
                write!(
                    f,
                    "code {code} is not in the MIB and its {len} data bytes are too many to keep"
                )
            }
            Error::UnknownKind { service, subservice } => write!(f, "[{service},{subservice}] not in the MIB"),
            Error::WrongFunction { expected, got } => write!(f, "function ID {got}, {expected} expected"),
            Error::BufferTooShort { need, have } => write!(f, "buffer too short: need {need} bytes, have {have}"),
        }
    }
}

impl core::error::Error for Error {}

/// An event's typed parameters (generated per event in [`ev`]): its ID and its values in
/// the MIB's order, for the table codec (`codec::encode_event`).
pub trait EventArgs {
    const ID: u16;
    type Values: AsRef<[i64]>;
    fn values(&self) -> Self::Values;
}

/// Bytes kept of the failure data or event parameters of a code this MIB does not know.
pub const MAX_UNKNOWN_DATA: usize = 32;

/// Bit-exact big-endian reader over a body.
pub struct Reader<'a> {
    buf: &'a [u8],
    bit: usize,
}

impl<'a> Reader<'a> {
    pub fn new(buf: &'a [u8]) -> Self {
        Reader { buf, bit: 0 }
    }
    /// Reads an unsigned value of `bits` bits (at most 32).
    #[inline]
    pub fn uint(&mut self, bits: u8, field: &'static str) -> Result<u32, Error> {
        let bits = bits as usize;
        if self.bit & 7 == 0 && bits & 7 == 0 {
            let o = self.bit / 8;
            let n = bits / 8;
            let b = self.buf.get(o..o + n).ok_or(Error::Truncated { field })?;
            self.bit += bits;
            let mut v = 0u32;
            for x in b {
                v = (v << 8) | *x as u32;
            }
            return Ok(v);
        }
        if self.bit + bits > self.buf.len() * 8 {
            return Err(Error::Truncated { field });
        }
        let mut v = 0u32;
        for _ in 0..bits {
            let byte = self.buf[self.bit / 8];
            let b = (byte >> (7 - self.bit % 8)) & 1;
            v = (v << 1) | b as u32;
            self.bit += 1;
        }
        Ok(v)
    }
    pub fn boolean(&mut self, field: &'static str) -> Result<bool, Error> {
        match self.uint(8, field)? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(Error::NotBool { field, value: v as u8 }),
        }
    }
    /// The unread bytes (the reader must be byte-aligned).
    pub fn rest(&self) -> &'a [u8] {
        self.buf.get(self.bit / 8..).unwrap_or(&[])
    }
    /// Takes `n` bytes.
    pub fn take(&mut self, n: usize, field: &'static str) -> Result<&'a [u8], Error> {
        let o = self.bit / 8;
        let b = self.buf.get(o..o + n).ok_or(Error::Truncated { field })?;
        self.bit += n * 8;
        Ok(b)
    }
    /// Takes an embedded space packet (length from its primary header).
    pub fn packet(&mut self, max: usize, field: &'static str) -> Result<&'a [u8], Error> {
        let r = self.rest();
        if r.len() < PRIMARY_HEADER_LEN {
            return Err(Error::Truncated { field });
        }
        let len = u16::from_be_bytes([r[4], r[5]]) as usize + PRIMARY_HEADER_LEN + 1;
        if len > max {
            return Err(Error::BadPacket { field, len });
        }
        self.take(len, field)
    }
    /// Byte offset of the next field.
    pub fn pos(&self) -> usize {
        self.bit / 8
    }
    /// Ends the parse: every byte must have been read.
    pub fn finish(&self) -> Result<(), Error> {
        let left = self.buf.len().saturating_sub(self.bit.div_ceil(8));
        if left > 0 {
            Err(Error::TrailingBytes { len: left })
        } else {
            Ok(())
        }
    }
}

/// Bit-exact big-endian writer.
pub struct Writer<'a> {
    buf: &'a mut [u8],
    bit: usize,
}

impl<'a> Writer<'a> {
    pub fn new(buf: &'a mut [u8]) -> Self {
        Writer { buf, bit: 0 }
    }
    /// Writes the low `bits` bits of `v`.
    #[inline]
    pub fn uint(&mut self, bits: u8, v: u32) -> Result<(), Error> {
        let bits = bits as usize;
        let need = (self.bit + bits).div_ceil(8);
        if need > self.buf.len() {
            return Err(Error::BufferTooShort {
                need,
                have: self.buf.len(),
            });
        }
        if self.bit & 7 == 0 && bits & 7 == 0 {
            let o = self.bit / 8;
            let n = bits / 8;
            let be = v.to_be_bytes();
            self.buf[o..o + n].copy_from_slice(&be[4 - n..]);
            self.bit += bits;
            return Ok(());
        }
        for i in (0..bits).rev() {
            let b = ((v >> i) & 1) as u8;
            let byte = &mut self.buf[self.bit / 8];
            let sh = 7 - self.bit % 8;
            *byte = (*byte & !(1 << sh)) | (b << sh);
            self.bit += 1;
        }
        Ok(())
    }
    pub fn bytes(&mut self, b: &[u8]) -> Result<(), Error> {
        let o = self.bit / 8;
        let need = o + b.len();
        let have = self.buf.len();
        self.buf
            .get_mut(o..need)
            .ok_or(Error::BufferTooShort { need, have })?
            .copy_from_slice(b);
        self.bit += b.len() * 8;
        Ok(())
    }
    /// Bytes written.
    pub fn len(&self) -> usize {
        self.bit.div_ceil(8)
    }
    pub fn is_empty(&self) -> bool {
        self.bit == 0
    }
}

/// Reads `bits` bits at bit offset `bit` (big-endian); 0 for bits beyond the buffer
/// (views made with `new_unchecked` over short bytes read zeros, never panic).
#[inline]
pub fn get_bits(buf: &[u8], bit: usize, bits: u8) -> u32 {
    let mut v = 0u32;
    for i in bit..bit + bits as usize {
        let b = buf.get(i / 8).map_or(0, |x| (x >> (7 - i % 8)) & 1);
        v = (v << 1) | b as u32;
    }
    v
}

/// Writes the low `bits` bits of `v` at bit offset `bit`; bits beyond the buffer are
/// dropped.
#[inline]
pub fn set_bits(buf: &mut [u8], bit: usize, bits: u8, v: u32) {
    for (k, i) in (bit..bit + bits as usize).enumerate() {
        let b = ((v >> (bits as usize - 1 - k)) & 1) as u8;
        if let Some(x) = buf.get_mut(i / 8) {
            let sh = 7 - i % 8;
            *x = (*x & !(1 << sh)) | (b << sh);
        }
    }
}

/// Saturating conversions of a raw `i64` parameter value to a field's type, used by the
/// generated `from_values` (out of line: one copy instead of one per parameter).
#[doc(hidden)]
pub mod sat {
    #[inline(never)]
    pub fn u8(v: i64) -> u8 {
        v.clamp(0, u8::MAX as i64) as u8
    }
    #[inline(never)]
    pub fn u16(v: i64) -> u16 {
        v.clamp(0, u16::MAX as i64) as u16
    }
    #[inline(never)]
    pub fn u32(v: i64) -> u32 {
        v.clamp(0, u32::MAX as i64) as u32
    }
    #[inline(never)]
    pub fn i16(v: i64) -> i16 {
        v.clamp(i16::MIN as i64, i16::MAX as i64) as i16
    }
    #[inline(never)]
    pub fn i32(v: i64) -> i32 {
        v.clamp(i32::MIN as i64, i32::MAX as i64) as i32
    }
}

/// The code generated from the MIB (see `build.rs`). Casts are written uniformly for
/// every field type, and the kind enums hold their largest body inline (no heap), hence
/// the allowed lints.
#[allow(clippy::unnecessary_cast, clippy::redundant_field_names, clippy::large_enum_variant)]
mod generated {
    use super::*;
    include!(concat!(env!("OUT_DIR"), "/generated.rs"));
}
pub use generated::*;

/// The one PUS 1 request ID of the project: the obsw's acceptance,
/// verification reports and duplicate window, the ground's TC builder, decoder and JSON
/// output, and the tests all use this type (CODEC-RID-01).
impl RequestId {
    /// The request ID of a TC: the first four bytes of its primary header.
    pub fn of_tc(tc: &[u8]) -> Result<RequestId, Error> {
        let mut r = Reader::new(tc);
        RequestId::read(&mut r)
    }
    /// The request ID of the four bytes of a primary header's packet ID and sequence
    /// control (every value of the four bytes is a request ID).
    pub const fn from_bytes(b: [u8; 4]) -> RequestId {
        RequestId::from_words(u16::from_be_bytes([b[0], b[1]]), u16::from_be_bytes([b[2], b[3]]))
    }
    /// The four bytes on the wire (packet ID, then packet sequence control, big-endian).
    pub const fn to_bytes(&self) -> [u8; 4] {
        self.raw().to_be_bytes()
    }
    /// Packet ID in the upper and sequence control in the lower 16 bits: the 32-bit key
    /// (sat-rs's `verification::RequestId::from(u32)`, the obsw's duplicate window).
    pub const fn raw(&self) -> u32 {
        ((self.packet_id() as u32) << 16) | self.psc() as u32
    }
    /// The request ID of a 32-bit key made by [`RequestId::raw`].
    pub const fn from_raw(raw: u32) -> RequestId {
        RequestId::from_words((raw >> 16) as u16, raw as u16)
    }
    /// APID of the TC (the field, as a method for the callers that read it so).
    pub const fn apid(&self) -> u16 {
        self.apid
    }
    /// Packet sequence count of the TC (the `seq_count` field).
    pub const fn seq(&self) -> u16 {
        self.seq_count
    }
    /// Packet ID (first 16 bits of the primary header).
    pub const fn packet_id(&self) -> u16 {
        ((self.version as u16) << 13) | ((self.packet_type as u16) << 12) | ((self.sec_hdr as u16) << 11) | self.apid
    }
    /// Packet sequence control (second 16 bits).
    pub const fn psc(&self) -> u16 {
        ((self.seq_flags as u16) << 14) | self.seq_count
    }
    /// The request ID of a packet ID word and a packet sequence control word.
    pub const fn from_words(packet_id: u16, psc: u16) -> RequestId {
        RequestId {
            version: (packet_id >> 13) as u8,
            packet_type: ((packet_id >> 12) & 1) as u8,
            sec_hdr: ((packet_id >> 11) & 1) as u8,
            apid: packet_id & 0x7FF,
            seq_flags: (psc >> 14) as u8,
            seq_count: mib::headers::SeqCount::new(psc).get(),
        }
    }
}

/// "apid 0x101 seq 5", as the ground prints a request.
impl core::fmt::Display for RequestId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "apid 0x{:03X} seq {}", self.apid, self.seq_count)
    }
}
