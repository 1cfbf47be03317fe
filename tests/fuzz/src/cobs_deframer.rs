//! The COBS stream deframer (`mmic_stream::Deframer`, bytes in, frames out): board A's
//! serial ground link, the A–B link, the host's lab TCP link and the ground's stream link
//! all receive through it.
//!
//! The input is the byte stream itself. Invariants:
//! - nothing panics; every delivered frame is non-empty and at most `N` bytes;
//! - the counters match what was delivered and dropped, and every byte is accounted for
//!   exactly once: each non-delimiter byte is in a delivered frame, in `garbage_bytes`,
//!   or in the frame still in progress (the crate's documented promise);
//! - emit then parse: the input's first `N` bytes, encoded with `mmic_stream::encode`,
//!   come back as exactly that one frame, both from a fresh deframer and after the whole
//!   fuzzed stream (the leading delimiter ends any garbage before it: resynchronisation).

use mmic_stream::{encode, encoded_len, Deframer};

/// The deframer's buffer: small, so that oversize frames are common.
const N: usize = 64;

pub fn run(data: &[u8]) {
    let mut de: Deframer<N> = Deframer::new();
    let (mut frames, mut dropped, mut frame_wire) = (0u32, 0u32, 0u64);
    for &b in data {
        let wire_before = de.in_progress();
        match de.push(b) {
            Some(Ok(f)) => {
                assert!(!f.is_empty() && f.len() <= N, "frame of {} bytes", f.len());
                frames += 1;
                frame_wire += u64::from(wire_before);
            }
            Some(Err(_)) => dropped += 1,
            None => {}
        }
    }
    let c = de.counters;
    assert_eq!(c.frames, frames, "frames delivered vs counted");
    assert_eq!(c.dropped(), dropped, "frames dropped vs counted");
    let nonzero = data.iter().filter(|b| **b != 0).count() as u64;
    assert_eq!(
        frame_wire + u64::from(c.garbage_bytes) + u64::from(de.in_progress()),
        nonzero,
        "bytes not accounted for exactly once"
    );

    let frame = &data[..data.len().min(N)];
    if frame.is_empty() {
        return;
    }
    let mut wire = vec![0u8; encoded_len(frame.len())];
    let n = encode(frame, &mut wire).expect("buffer of encoded_len");
    let wire = &wire[..n];
    let mut fresh: Deframer<N> = Deframer::new();
    let mut got: Vec<Vec<u8>> = Vec::new();
    fresh.feed(wire, |r| got.push(r.expect("own encoding decodes").to_vec()));
    assert_eq!(got, [frame.to_vec()], "encode then deframe");
    // After the fuzzed stream: the frame is the last thing delivered.
    let mut last = None;
    de.feed(wire, |r| last = Some(r.map(<[u8]>::to_vec)));
    assert_eq!(last, Some(Ok(frame.to_vec())), "no resynchronisation after garbage");
}
