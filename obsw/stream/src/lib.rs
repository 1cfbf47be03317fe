//! `mmic-stream`: packets and transfer frames over a byte stream (a serial line, USB
//! CDC-ACM, a pty, a Unix socket, a TCP connection): each frame is one COBS frame between
//! two 0x00 delimiters, `0x00, COBS(frame), 0x00` — the framing of board A's ground link,
//! the A–B link, the host obsw's lab TCP link and the ground (docs/firmware.md,
//! docs/space-link.md). The one codec of the project: `no_std`, no heap, the same on the
//! host, the ground, the tests and the firmware.
//!
//! - [`encode`]: one frame into its delimited COBS form (at most [`encoded_len`] bytes).
//! - [`Deframer`]: the incremental receiver, bytes in, frames out, with a buffer of `N`
//!   bytes in its type (no heap). A COBS error (a delimiter inside a block) or a frame
//!   longer than `N` drops that frame, counts it ([`StreamCounters`]) and resynchronises
//!   on the delimiter that ended it; the leading delimiter of the next frame therefore
//!   ends any garbage before it. Empty frames (two delimiters in a row) are ignored.
//!
//! The COBS frame only delimits; the frame inside is checked by its own layer (transfer
//! frame: length field = decoded length, CRC, SDLS; space packet: its CRC; A–B frame: its
//! CRC), exactly as for one frame per UDP datagram.
//! The codec is the `cobs` crate (0.5, `no_std`), as in sat-rs.
//!
//! The host end of a stream (a serial device in raw mode, a Unix socket) is
//! `mmic_link::stream::port` (`std`), which re-exports this crate's codec.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]

use core::fmt;

use cobs::{DecodeResult, DecoderState};

/// Bytes on the wire of a frame of `len` bytes: COBS overhead plus two delimiters.
pub const fn encoded_len(len: usize) -> usize {
    cobs::max_encoding_length(len) + 2
}

/// Why a frame could not be encoded or was dropped by the [`Deframer`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamError {
    /// The output buffer is shorter than [`encoded_len`] of the frame.
    BufferTooSmall,
    /// The decoded frame would exceed the deframer's buffer (`N` bytes).
    Oversize,
    /// A delimiter arrived inside a COBS block: the frame was cut short or corrupted.
    Corrupt,
}

impl fmt::Display for StreamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StreamError::BufferTooSmall => f.write_str("output buffer too small for the COBS frame"),
            StreamError::Oversize => f.write_str("COBS frame longer than the receive buffer"),
            StreamError::Corrupt => f.write_str("corrupt COBS frame (delimiter inside a block)"),
        }
    }
}

/// Encodes `frame` as `0x00, COBS(frame), 0x00` into `out`; returns the bytes written.
/// Nothing useful is written when `out` is too small.
pub fn encode(frame: &[u8], out: &mut [u8]) -> Result<usize, StreamError> {
    if out.len() < encoded_len(frame.len()) {
        return Err(StreamError::BufferTooSmall);
    }
    cobs::try_encode_including_sentinels(frame, out).map_err(|_| StreamError::BufferTooSmall)
}

/// What a [`Deframer`] saw. Every byte received is in exactly one of: a delivered frame,
/// a dropped frame (`garbage_bytes`), or a delimiter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamCounters {
    /// Frames delivered (decoded, at most `N` bytes, not empty).
    pub frames: u32,
    /// Frames dropped because they exceeded `N` bytes.
    pub oversize: u32,
    /// Frames dropped because their COBS encoding was broken.
    pub corrupt: u32,
    /// Encoded bytes of the dropped frames (oversize or corrupt).
    pub garbage_bytes: u32,
}

impl StreamCounters {
    /// Frames dropped by the framing (oversize + corrupt).
    pub fn dropped(&self) -> u32 {
        self.oversize.saturating_add(self.corrupt)
    }
}

/// The incremental receiver (see the module documentation). Holds at most `N` decoded
/// bytes.
#[derive(Debug)]
pub struct Deframer<const N: usize> {
    buf: [u8; N],
    len: usize,
    /// Encoded bytes of the frame in progress (for `garbage_bytes`).
    wire: u32,
    state: DecoderState,
    overflow: bool,
    pub counters: StreamCounters,
}

// By hand: the `cobs` crate's `DecoderState` is not `Clone` (its variants are public).
impl<const N: usize> Clone for Deframer<N> {
    fn clone(&self) -> Self {
        Self {
            buf: self.buf,
            len: self.len,
            wire: self.wire,
            state: match self.state {
                DecoderState::Idle => DecoderState::Idle,
                DecoderState::Grab(n) => DecoderState::Grab(n),
                DecoderState::GrabChain(n) => DecoderState::GrabChain(n),
            },
            overflow: self.overflow,
            counters: self.counters,
        }
    }
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
            wire: 0,
            state: DecoderState::Idle,
            overflow: false,
            counters: StreamCounters {
                frames: 0,
                oversize: 0,
                corrupt: 0,
                garbage_bytes: 0,
            },
        }
    }

    /// Feeds one byte. `Some(Ok(frame))` when a frame is complete, `Some(Err(_))` when one
    /// was dropped (already counted; the deframer is resynchronised on the delimiter that
    /// ended it), `None` otherwise.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], StreamError>> {
        // Delimiters are the only 0x00 bytes on the wire; they belong to no frame.
        if byte != 0 {
            self.wire = self.wire.saturating_add(1);
        }
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
                let wire = core::mem::take(&mut self.wire);
                if core::mem::take(&mut self.overflow) {
                    self.counters.oversize = self.counters.oversize.saturating_add(1);
                    self.counters.garbage_bytes = self.counters.garbage_bytes.saturating_add(wire);
                    Some(Err(StreamError::Oversize))
                } else if n == 0 {
                    // `0x01 0x00`: an empty frame carries nothing; its byte is garbage.
                    self.counters.garbage_bytes = self.counters.garbage_bytes.saturating_add(wire);
                    None
                } else {
                    self.counters.frames = self.counters.frames.saturating_add(1);
                    Some(Ok(&self.buf[..n]))
                }
            }
            Err(_) => {
                // Only a 0x00 ends a block early: the decoder is Idle again, resynchronised.
                self.len = 0;
                self.overflow = false;
                let wire = core::mem::take(&mut self.wire);
                self.counters.corrupt = self.counters.corrupt.saturating_add(1);
                self.counters.garbage_bytes = self.counters.garbage_bytes.saturating_add(wire);
                Some(Err(StreamError::Corrupt))
            }
        }
    }

    /// Feeds `bytes`, calling `out` with every frame completed or dropped, in order.
    pub fn feed(&mut self, bytes: &[u8], mut out: impl FnMut(Result<&[u8], StreamError>)) {
        for &b in bytes {
            if let Some(r) = self.push(b) {
                out(r);
            }
        }
    }

    /// The first `N` decoded bytes of the frame just dropped as [`StreamError::Oversize`]
    /// (its header, e.g. to answer it with its request ID); valid until the next byte is
    /// pushed. Meaningless after any other result.
    pub fn oversize_head(&self) -> &[u8] {
        &self.buf
    }

    /// Bytes of a frame in progress (received since its start, not yet delimited).
    pub fn in_progress(&self) -> u32 {
        self.wire
    }

    /// Drops a frame in progress, counting its bytes as garbage.
    pub fn reset(&mut self) {
        let wire = core::mem::take(&mut self.wire);
        self.counters.garbage_bytes = self.counters.garbage_bytes.saturating_add(wire);
        self.state = DecoderState::Idle;
        self.len = 0;
        self.overflow = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The largest frame of the link (TC and TM frames are at most 1024 bytes).
    const MAX: usize = 1024;

    fn wire(frames: &[Vec<u8>]) -> Vec<u8> {
        let mut w = Vec::new();
        for f in frames {
            let mut b = vec![0u8; encoded_len(f.len())];
            let n = encode(f, &mut b).unwrap();
            w.extend_from_slice(&b[..n]);
        }
        w
    }

    fn deframe(d: &mut Deframer<MAX>, bytes: &[u8]) -> Vec<Result<Vec<u8>, StreamError>> {
        let mut out = Vec::new();
        d.feed(bytes, |r| out.push(r.map(<[u8]>::to_vec)));
        out
    }

    // verifies: LINK-STREAM-01
    #[test]
    fn a_frame_is_one_cobs_frame_between_two_delimiters_and_decodes_back() {
        let frame: Vec<u8> = (0..=255u8).cycle().take(MAX).collect();
        let w = wire(std::slice::from_ref(&frame));
        assert_eq!((w[0], w[w.len() - 1]), (0, 0));
        assert!(!w[1..w.len() - 1].contains(&0), "no 0x00 inside the frame");
        assert!(w.len() <= encoded_len(MAX));
        assert_eq!(
            encoded_len(MAX),
            1031,
            "a 1024-byte TM frame costs 1031 bytes on the wire"
        );
        let mut d = Deframer::<MAX>::new();
        assert_eq!(deframe(&mut d, &w), vec![Ok(frame)]);
        assert_eq!(d.counters.frames, 1);
        let mut small = [0u8; 10];
        assert_eq!(encode(&[1; 9], &mut small), Err(StreamError::BufferTooSmall));
    }

    // verifies: LINK-STREAM-02
    #[test]
    fn an_oversize_frame_is_counted_and_the_next_frame_is_received() {
        let mut d = Deframer::<16>::new();
        let big = vec![7u8; 17];
        let ok = vec![1u8, 2, 3];
        let w = wire(&[big, ok.clone()]);
        let mut out = Vec::new();
        d.feed(&w, |r| out.push(r.map(<[u8]>::to_vec)));
        assert_eq!(out, vec![Err(StreamError::Oversize), Ok(ok)]);
        assert_eq!(d.counters.oversize, 1);
        assert_eq!(d.counters.garbage_bytes, 18, "17 data bytes + 1 COBS code byte");
        assert_eq!(d.counters.frames, 1);
    }

    // verifies: LINK-STREAM-02
    #[test]
    fn an_oversize_frame_keeps_its_head_until_the_next_byte() {
        let mut d = Deframer::<4>::new();
        let big: Vec<u8> = (1..=9).collect();
        let w = wire(&[big]);
        let mut head = None;
        for &b in &w {
            if let Some(Err(StreamError::Oversize)) = d.push(b) {
                head = Some(d.oversize_head().to_vec());
            }
        }
        assert_eq!(head, Some(vec![1, 2, 3, 4]));
    }

    // verifies: LINK-STREAM-02
    #[test]
    fn garbage_before_a_frame_is_counted_and_the_frame_survives() {
        let mut d = Deframer::<MAX>::new();
        let f = vec![0x20, 0x00, 0xAB, 0x00, 0x01];
        // A code byte promising 9 bytes, cut by the next frame's leading delimiter.
        let mut w = vec![0x0A, 0x55, 0x66];
        w.extend(wire(std::slice::from_ref(&f)));
        assert_eq!(deframe(&mut d, &w), vec![Err(StreamError::Corrupt), Ok(f)]);
        assert_eq!(d.counters.corrupt, 1);
        assert_eq!(d.counters.garbage_bytes, 3);
        // Delimiters alone and an empty frame deliver nothing.
        assert_eq!(deframe(&mut d, &[0, 0, 0, 1, 0, 0]), vec![]);
        assert_eq!(d.counters.frames, 1);
    }

    // verifies: LINK-STREAM-02
    #[test]
    fn reset_drops_the_frame_in_progress_and_counts_it() {
        let mut d = Deframer::<MAX>::new();
        let w = wire(&[vec![9u8; 40]]);
        assert!(deframe(&mut d, &w[..20]).is_empty());
        assert_eq!(d.in_progress(), 19);
        d.reset();
        assert_eq!(d.counters.garbage_bytes, 19);
        assert_eq!(deframe(&mut d, &w), vec![Ok(vec![9u8; 40])]);
    }

    // verifies: LINK-STREAM-01
    #[test]
    fn a_clone_taken_mid_frame_finishes_the_same_frame() {
        let f: Vec<u8> = (0..600u32).map(|i| (i % 7) as u8).collect();
        let w = wire(std::slice::from_ref(&f));
        let mut d = Deframer::<MAX>::new();
        assert!(deframe(&mut d, &w[..300]).is_empty());
        let mut c = d.clone();
        assert_eq!(c.in_progress(), d.in_progress());
        assert_eq!(deframe(&mut c, &w[300..]), vec![Ok(f.clone())]);
        assert_eq!(deframe(&mut d, &w[300..]), vec![Ok(f)]);
    }

    proptest! {
        // verifies: LINK-STREAM-02
        #[test]
        fn arbitrary_bytes_never_panic_and_every_byte_is_accounted_for(
            bytes in proptest::collection::vec(any::<u8>(), 0..4000),
        ) {
            let mut d = Deframer::<64>::new();
            let mut delivered = 0u64;
            d.feed(&bytes, |r| {
                if let Ok(f) = r {
                    assert!(!f.is_empty() && f.len() <= 64);
                    delivered += 1;
                }
            });
            let c = d.counters;
            prop_assert_eq!(u64::from(c.frames), delivered);
            // Every byte is a delimiter, part of a frame delivered, dropped, or in progress;
            // a delivered frame of n bytes took at most n + n/254 + 1 bytes.
            prop_assert!(u64::from(c.garbage_bytes) + u64::from(d.in_progress()) <= bytes.len() as u64);
        }

        // verifies: LINK-STREAM-01
        #[test]
        fn frames_split_anywhere_come_out_the_same(
            frames in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 1..MAX), 1..6),
            cuts in proptest::collection::vec(any::<prop::sample::Index>(), 0..12),
        ) {
            let w = wire(&frames);
            let mut at: Vec<usize> = cuts.iter().map(|i| i.index(w.len() + 1)).collect();
            at.sort_unstable();
            let mut d = Deframer::<MAX>::new();
            let mut got = Vec::new();
            let mut from = 0;
            for &c in at.iter().chain(std::iter::once(&w.len())) {
                d.feed(&w[from..c], |r| got.push(r.map(<[u8]>::to_vec)));
                from = c;
            }
            prop_assert_eq!(got, frames.into_iter().map(Ok).collect::<Vec<_>>());
            prop_assert_eq!(d.counters.garbage_bytes, 0);
        }

        // verifies: LINK-STREAM-02
        #[test]
        fn junk_between_frames_costs_at_most_the_frame_it_lands_in(
            frames in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 1..200), 2..8),
            junk in proptest::collection::vec(any::<u8>(), 1..64),
            slot in any::<prop::sample::Index>(),
        ) {
            // Junk inserted between two frames (after one's trailing delimiter): every
            // frame still arrives, and the junk is counted or delivered as a short frame
            // the frame layer refuses (it ends at the next frame's leading delimiter).
            let i = slot.index(frames.len() - 1) + 1;
            let mut w = wire(&frames[..i]);
            w.extend_from_slice(&junk);
            w.extend(wire(&frames[i..]));
            let mut d = Deframer::<MAX>::new();
            let mut got = Vec::new();
            d.feed(&w, |r| if let Ok(f) = r { got.push(f.to_vec()) });
            for f in &frames {
                prop_assert!(got.contains(f));
            }
            prop_assert!(got.len() <= frames.len() + junk.len());
        }
    }
}
