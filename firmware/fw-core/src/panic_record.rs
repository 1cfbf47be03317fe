//! The panic reason kept across a reset for the next boot's report.
//!
//! The boards place a [`RawRecord`] in RTC fast RAM that the start-up code does not
//! clear (`#[esp_hal::ram(unstable(rtc_fast, persistent))]`); the panic handler writes
//! the location and message into it and resets the chip; the next boot reads it with
//! [`take`], reports it, and clears it. The record is plain words so that any bit
//! pattern is a valid value: a magic word and a CRC tell a real record from garbage
//! left by a power cycle.

use crate::config::PANIC_MSG_LEN;
use core::fmt::Write;

const MAGIC: u32 = 0x4D4D_5043; // "MMPC"
const HEADER_WORDS: usize = 4;
/// Words of the record: magic, panic count, message length, CRC, message bytes.
pub const WORDS: usize = HEADER_WORDS + PANIC_MSG_LEN.div_ceil(4);
/// The persistent record as stored in RAM.
pub type RawRecord = [u32; WORDS];

const CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// A panic found at boot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PanicReport {
    /// Panics recorded since the record was last found invalid (power-on).
    pub count: u32,
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

fn checksum(count: u32, len: u32, msg: &[u8]) -> u32 {
    let mut d = CRC.digest();
    d.update(&count.to_le_bytes());
    d.update(&len.to_le_bytes());
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
    if rec[0] == MAGIC || rec[0] == !MAGIC {
        rec[1]
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
    let len = w.len as u32;
    for (i, chunk) in w.buf.chunks(4).enumerate() {
        let mut word = [0u8; 4];
        word[..chunk.len()].copy_from_slice(chunk);
        rec[HEADER_WORDS + i] = u32::from_le_bytes(word);
    }
    rec[1] = count;
    rec[2] = len;
    rec[3] = checksum(count, len, &w.buf[..w.len]);
    rec[0] = MAGIC;
}

/// Reads and clears a recorded panic. Returns `None` when there is none (or the RAM
/// holds garbage after a power cycle); the panic count survives until then.
pub fn take(rec: &mut RawRecord) -> Option<PanicReport> {
    if rec[0] != MAGIC {
        if rec[0] != !MAGIC {
            // Not ours: power-on garbage. Start counting afresh.
            rec[0] = !MAGIC;
            rec[1] = 0;
        }
        return None;
    }
    let count = rec[1];
    let len = rec[2] as usize;
    if len > PANIC_MSG_LEN {
        rec[0] = !MAGIC;
        rec[1] = 0;
        return None;
    }
    let bytes = message_bytes(rec);
    if checksum(count, len as u32, &bytes[..len]) != rec[3] {
        rec[0] = !MAGIC;
        rec[1] = 0;
        return None;
    }
    // Consumed: keep the count, mark the message as reported.
    rec[0] = !MAGIC;
    let text = match core::str::from_utf8(&bytes[..len]) {
        Ok(s) => s,
        Err(e) => core::str::from_utf8(&bytes[..e.valid_up_to()]).unwrap_or(""),
    };
    let mut message = heapless::String::new();
    // `text` is at most PANIC_MSG_LEN bytes, so this cannot fail.
    let _ = message.push_str(text);
    Some(PanicReport { count, message })
}
