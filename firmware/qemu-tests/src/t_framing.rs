//! COBS framing of the ground and A–B links (`mmic_stream`, the one codec of the project).

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use mmic_stream::{encode, Deframer, StreamError};

pub const TESTS: &[Test] = tests![
    cobs_encodes_reference_vectors,
    cobs_254_byte_block_gets_no_extra_zero,
    deframer_splits_a_stream_and_resyncs,
    deframer_drops_frames_longer_than_its_buffer,
    encode_refuses_short_output_buffer,
];

/// Known COBS encodings (Cheshire & Baker; delimiters added by `encode`).
fn cobs_encodes_reference_vectors() -> TestResult {
    let cases: [(&[u8], &[u8]); 5] = [
        (&[0x00], &[0x01, 0x01]),
        (&[0x00, 0x00], &[0x01, 0x01, 0x01]),
        (&[0x11, 0x22, 0x00, 0x33], &[0x03, 0x11, 0x22, 0x02, 0x33]),
        (&[0x11, 0x22, 0x33, 0x44], &[0x05, 0x11, 0x22, 0x33, 0x44]),
        (&[0x11, 0x00, 0x00, 0x00], &[0x02, 0x11, 0x01, 0x01, 0x01]),
    ];
    for (payload, enc) in cases {
        let mut out = [0u8; 16];
        let n = ok!(encode(payload, &mut out));
        check_eq!(n, enc.len() + 2);
        check_eq!(out[0], 0);
        check_eq!(out[n - 1], 0);
        check_eq!(&out[1..n - 1], enc);
        let mut d: Deframer<16> = Deframer::new();
        let mut got = None;
        for &b in &out[..n] {
            if let Some(r) = d.push(b) {
                let mut v: heapless::Vec<u8, 16> = heapless::Vec::new();
                let _ = v.extend_from_slice(ok!(r));
                got = Some(v);
            }
        }
        let got = ok!(got);
        check_eq!(&got[..], payload);
    }
    Ok(())
}

fn cobs_254_byte_block_gets_no_extra_zero() -> TestResult {
    let mut payload = [0u8; 254];
    for (i, b) in payload.iter_mut().enumerate() {
        *b = i as u8 + 1; // 0x01..=0xFE
    }
    let mut out = [0u8; 300];
    let n = ok!(encode(&payload, &mut out));
    // 0x00, 0xFF, 254 data bytes, 0x00
    check_eq!(n, 257);
    check_eq!(out[1], 0xFF);
    check_eq!(&out[2..256], &payload[..]);
    let mut d: Deframer<300> = Deframer::new();
    let mut len = None;
    for &b in &out[..n] {
        if let Some(r) = d.push(b) {
            let p = ok!(r);
            check_eq!(p, &payload[..]);
            len = Some(p.len());
        }
    }
    check_eq!(len, Some(254));
    Ok(())
}

fn deframer_splits_a_stream_and_resyncs() -> TestResult {
    let frames: [&[u8]; 3] = [&[1, 2, 0, 3], &[0, 0, 0], &[0x7E; 40]];
    let mut wire = [0u8; 256];
    let mut n = 0;
    // Noise before the first delimiter: a receiver joining mid-frame.
    for b in [0x05, 0x33, 0x44] {
        wire[n] = b;
        n += 1;
    }
    for f in frames {
        n += ok!(encode(f, &mut wire[n..]));
    }
    // A frame cut by a delimiter inside a block, then a good one.
    for b in [0x00, 0x05, 0x11, 0x00] {
        wire[n] = b;
        n += 1;
    }
    n += ok!(encode(&[9, 8, 7], &mut wire[n..]));

    let mut d: Deframer<64> = Deframer::new();
    let mut ok_frames = 0;
    let mut errors = 0;
    let expect: [&[u8]; 4] = [&[1, 2, 0, 3], &[0, 0, 0], &[0x7E; 40], &[9, 8, 7]];
    for &b in &wire[..n] {
        match d.push(b) {
            Some(Ok(p)) => {
                check!(ok_frames < expect.len(), "too many frames");
                check_eq!(p, expect[ok_frames], "frame {}", ok_frames);
                ok_frames += 1;
            }
            Some(Err(e)) => {
                check_eq!(e, StreamError::Corrupt);
                errors += 1;
            }
            None => {}
        }
    }
    check_eq!(ok_frames, 4);
    // The leading noise and the cut frame.
    check_eq!(errors, 2);
    Ok(())
}

fn deframer_drops_frames_longer_than_its_buffer() -> TestResult {
    let mut out = [0u8; 64];
    let n = ok!(encode(&[0xAB; 20], &mut out));
    let m = ok!(encode(&[1, 2], &mut out[n..]));
    let mut d: Deframer<8> = Deframer::new();
    let mut results: heapless::Vec<Result<usize, StreamError>, 4> = heapless::Vec::new();
    for &b in &out[..n + m] {
        if let Some(r) = d.push(b) {
            let _ = results.push(r.map(|p| p.len()));
        }
    }
    check_eq!(&results[..], &[Err(StreamError::Oversize), Ok(2)][..]);
    Ok(())
}

fn encode_refuses_short_output_buffer() -> TestResult {
    let mut out = [0u8; 5];
    check_eq!(encode(&[1, 2, 3], &mut out), Err(StreamError::BufferTooSmall));
    check_eq!(fw_core::config::cobs_frame_len(1024), 1031);
    Ok(())
}
