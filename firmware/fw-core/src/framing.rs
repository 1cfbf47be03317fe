//! COBS framing of packets on a byte stream (ground link and A–B link).
//!
//! A frame on the wire is `0x00, COBS(payload), 0x00`. The leading delimiter lets a
//! receiver that joined mid-stream resynchronise on the next frame; empty frames
//! between two delimiters are ignored. The codec is the `cobs` crate satrs uses.

use cobs::{DecodeResult, DecoderState};

/// Why a frame was dropped by the [`Deframer`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// The decoded payload would not fit the receive buffer.
    TooLong,
    /// A delimiter arrived inside a COBS block: the frame was cut short.
    Corrupt,
}

/// Encodes `payload` as one delimited frame into `out`; returns the frame length, or
/// `None` when `out` is too small (nothing useful is written then).
pub fn encode_frame(payload: &[u8], out: &mut [u8]) -> Option<usize> {
    if out.len() < crate::config::cobs_frame_len(payload.len()) {
        return None;
    }
    cobs::try_encode_including_sentinels(payload, out).ok()
}

/// Streaming decoder: feed it the received bytes one by one; it hands back each
/// complete payload. Holds at most `N` decoded bytes (no heap).
pub struct Deframer<const N: usize> {
    buf: [u8; N],
    len: usize,
    state: DecoderState,
    overflow: bool,
}

impl<const N: usize> Default for Deframer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Deframer<N> {
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            state: DecoderState::Idle,
            overflow: false,
        }
    }

    /// Feeds one byte. Returns `Some(Ok(payload))` when a frame is complete,
    /// `Some(Err(_))` when a frame had to be dropped (the decoder is resynchronised on
    /// the delimiter that ended it), and `None` while a frame is in progress.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], FrameError>> {
        match self.state.feed(byte) {
            Ok(DecodeResult::NoData) => None,
            Ok(DecodeResult::DataStart) => {
                self.len = 0;
                self.overflow = false;
                None
            }
            Ok(DecodeResult::DataContinue(b)) => {
                if self.len < N {
                    self.buf[self.len] = b;
                    self.len += 1;
                } else {
                    self.overflow = true;
                }
                None
            }
            Ok(DecodeResult::DataComplete) => {
                let n = core::mem::take(&mut self.len);
                if core::mem::take(&mut self.overflow) {
                    Some(Err(FrameError::TooLong))
                } else {
                    Some(Ok(&self.buf[..n]))
                }
            }
            Err(_) => {
                self.len = 0;
                self.overflow = false;
                Some(Err(FrameError::Corrupt))
            }
        }
    }

    /// Drops any partial frame.
    pub fn reset(&mut self) {
        self.state = DecoderState::Idle;
        self.len = 0;
        self.overflow = false;
    }
}

/// Counters of a framed link, reported in housekeeping.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounters {
    /// Frames decoded and delivered.
    pub frames_ok: u32,
    /// Frames dropped for bad framing or length.
    pub frame_errors: u32,
    /// Frames decoded but dropped because the consumer's queue was full.
    pub queue_full: u32,
}

impl LinkCounters {
    pub fn record(&mut self, r: &Result<&[u8], FrameError>) {
        match r {
            Ok(_) => self.frames_ok = self.frames_ok.wrapping_add(1),
            Err(_) => self.frame_errors = self.frame_errors.wrapping_add(1),
        }
    }
}
