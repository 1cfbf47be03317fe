//! The panic reason kept across a reset for the next boot's report.
//!
//! The boards place a [`RawRecord`] in RTC fast RAM that the start-up code does not
//! clear (`#[esp_hal::ram(unstable(rtc_fast, persistent))]`); the panic handler writes
//! the location and message into it and resets the chip; the next boot reads it
//! ([`read`]), reports it (board A: event PREVIOUS_PANIC through [`crate::boot`]; board
//! B: text on its console) and only then marks it reported ([`mark_reported`]; [`take`]
//! does both). The record is plain words so that any bit pattern is a valid value: a
//! magic word and a CRC tell a real record from garbage left by a power cycle.
//!
//! Layout (32-bit words, little-endian bytes): magic, panic count, line, CRC-32 of the
//! file path, message length, CRC-32 of the words before it and the message, message.

use crate::config::PANIC_MSG_LEN;
use core::fmt::Write;

const MAGIC: u32 = 0x4D4D_5043; // "MMPC"
const HEADER_WORDS: usize = 6;
const W_MAGIC: usize = 0;
const W_COUNT: usize = 1;
const W_LINE: usize = 2;
const W_FILE_CRC: usize = 3;
const W_LEN: usize = 4;
const W_CRC: usize = 5;
/// Words of the record: magic, panic count, line, file CRC, message length, CRC,
/// message bytes.
pub const WORDS: usize = HEADER_WORDS + PANIC_MSG_LEN.div_ceil(4);
/// The persistent record as stored in RAM.
pub type RawRecord = [u32; WORDS];

const CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// A panic found at boot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PanicReport {
    /// Panics recorded since the record was last found invalid (power-on).
    pub count: u32,
    /// Source line of the panic (0 when the panic had no location).
    pub line: u32,
    /// CRC-32/ISO-HDLC of the panic location's file path as `core::panic::Location`
    /// gives it ([`file_crc`]; 0 when the panic had no location).
    pub file_crc: u32,
    /// `file:line: message`, truncated to `PANIC_MSG_LEN` bytes at a character boundary.
    pub message: heapless::String<PANIC_MSG_LEN>,
}

struct Truncating {
    buf: [u8; PANIC_MSG_LEN],
    len: usize,
}

impl Write for Truncating {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for c in s.chars() {
            let mut tmp = [0u8; 4];
            let enc = c.encode_utf8(&mut tmp).as_bytes();
            if self.len + enc.len() > PANIC_MSG_LEN {
                // Full: stop quietly, the prefix is what we keep.
                return Ok(());
            }
            self.buf[self.len..self.len + enc.len()].copy_from_slice(enc);
            self.len += enc.len();
        }
        Ok(())
    }
}

/// CRC-32/ISO-HDLC (the `crc` crate's `CRC_32_ISO_HDLC`, zlib's `crc32`) of a source
/// file path: what event PREVIOUS_PANIC reports as `file_crc`.
pub fn file_crc(path: &str) -> u32 {
    CRC.checksum(path.as_bytes())
}

fn checksum(rec: &RawRecord, msg: &[u8]) -> u32 {
    let mut d = CRC.digest();
    for w in &rec[W_COUNT..W_CRC] {
        d.update(&w.to_le_bytes());
    }
    d.update(msg);
    d.finalize()
}

fn message_bytes(rec: &RawRecord) -> [u8; PANIC_MSG_LEN] {
    let mut out = [0u8; PANIC_MSG_LEN];
    for (i, b) in out.iter_mut().enumerate() {
        *b = rec[HEADER_WORDS + i / 4].to_le_bytes()[i % 4];
    }
    out
}

/// Number of panics recorded so far (0 when the record is not valid).
fn previous_count(rec: &RawRecord) -> u32 {
    if rec[W_MAGIC] == MAGIC || rec[W_MAGIC] == !MAGIC {
        rec[W_COUNT]
    } else {
        0
    }
}

/// Records a panic: `location: message`. Never panics itself (the message is cut at
/// `PANIC_MSG_LEN` bytes).
pub fn store(rec: &mut RawRecord, location: Option<(&str, u32)>, message: impl core::fmt::Display) {
    let mut w = Truncating {
        buf: [0; PANIC_MSG_LEN],
        len: 0,
    };
    if let Some((file, line)) = location {
        let _ = write!(w, "{file}:{line}: ");
    }
    let _ = write!(w, "{message}");
    let count = previous_count(rec).wrapping_add(1);
    let (line, crc) = location.map_or((0, 0), |(file, line)| (line, file_crc(file)));
    for (i, chunk) in w.buf.chunks(4).enumerate() {
        let mut word = [0u8; 4];
        word[..chunk.len()].copy_from_slice(chunk);
        rec[HEADER_WORDS + i] = u32::from_le_bytes(word);
    }
    rec[W_COUNT] = count;
    rec[W_LINE] = line;
    rec[W_FILE_CRC] = crc;
    rec[W_LEN] = w.len as u32;
    rec[W_CRC] = checksum(rec, &w.buf[..w.len]);
    rec[W_MAGIC] = MAGIC;
}

/// The panic recorded in `rec`, if it holds a valid, not yet reported one. Changes
/// nothing: the caller reports it, then calls [`mark_reported`].
pub fn read(rec: &RawRecord) -> Option<PanicReport> {
    if rec[W_MAGIC] != MAGIC {
        return None;
    }
    let len = rec[W_LEN] as usize;
    if len > PANIC_MSG_LEN {
        return None;
    }
    let bytes = message_bytes(rec);
    if checksum(rec, &bytes[..len]) != rec[W_CRC] {
        return None;
    }
    let text = match core::str::from_utf8(&bytes[..len]) {
        Ok(s) => s,
        Err(e) => core::str::from_utf8(&bytes[..e.valid_up_to()]).unwrap_or(""),
    };
    let mut message = heapless::String::new();
    // `text` is at most PANIC_MSG_LEN bytes, so this cannot fail.
    let _ = message.push_str(text);
    Some(PanicReport {
        count: rec[W_COUNT],
        line: rec[W_LINE],
        file_crc: rec[W_FILE_CRC],
        message,
    })
}

/// After the report: a valid record is marked as reported (its panic count is kept for
/// the next panic); anything else (power-on garbage, a corrupted record) becomes an
/// empty record with the count started afresh.
pub fn mark_reported(rec: &mut RawRecord) {
    if read(rec).is_none() && rec[W_MAGIC] != !MAGIC {
        rec[W_COUNT] = 0;
    }
    rec[W_MAGIC] = !MAGIC;
}

/// Reads and clears a recorded panic ([`read`] then [`mark_reported`]). Returns `None`
/// when there is none (or the RAM holds garbage after a power cycle).
pub fn take(rec: &mut RawRecord) -> Option<PanicReport> {
    let report = read(rec);
    mark_reported(rec);
    report
}
