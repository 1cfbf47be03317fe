//! Coverage-guided fuzz targets of MMIC-I: one module per parser that takes bytes from
//! outside, each a `run(&[u8])` that libFuzzer calls (`fuzz_targets/<name>.rs`) and that
//! asserts what must hold besides "no panic" (round trips where the crate emits, every
//! datagram counted once, nothing unauthenticated accepted). Each target calls the public
//! API at the level of bytes in. `docs/fuzzing.md` lists them and the campaign.
//!
//! Targets that take a sequence of inputs (frames, TCs, datagrams) read the fuzz input as
//! [`records`]: `tag, length (u16, big-endian), body` repeated, so that a seed is a
//! recorded session and libFuzzer mutates one record at a time.

pub mod ab_link;
pub mod cfdp_pdu;
pub mod cobs_deframer;
pub mod ground_tm_frames;
pub mod mib_wire;
pub mod module_set_file;
pub mod plan_file;
pub mod pus_tc;
pub mod tc_frame_rx;
pub mod team_packet;

/// Splits `data` into `(tag, body)` records: one tag byte, a big-endian u16 length, that
/// many body bytes (fewer at the end of the input). At most `max` records.
pub fn records(data: &[u8], max: usize) -> impl Iterator<Item = (u8, &[u8])> {
    let mut rest = data;
    core::iter::from_fn(move || {
        if rest.len() < 3 {
            return None;
        }
        let tag = rest[0];
        let n = usize::from(u16::from_be_bytes([rest[1], rest[2]])).min(rest.len() - 3);
        let body = &rest[3..3 + n];
        rest = &rest[3 + n..];
        Some((tag, body))
    })
    .take(max)
}

/// Appends one record (the inverse of [`records`]), for the seed generator.
pub fn push_record(out: &mut Vec<u8>, tag: u8, body: &[u8]) {
    let n = u16::try_from(body.len()).expect("record body fits a u16 length");
    out.push(tag);
    out.extend_from_slice(&n.to_be_bytes());
    out.extend_from_slice(body);
}
