//! The domain's moving average and the panic record kept across resets.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::panic_record::{self, RawRecord, WORDS};
use mmic_domain::filter::Ma;

pub const TESTS: &[Test] = tests![
    moving_average_window_of_50,
    panic_record_round_trip_and_count,
    panic_record_ignores_garbage_and_corruption,
    panic_record_truncates_at_char_boundary,
    panic_record_file_crc_is_crc32_iso_hdlc,
];

fn moving_average_window_of_50() -> TestResult {
    let mut a = Ma::new();
    check_eq!(a.value(), 0);
    // 25 samples of 100: the average of what arrived so far.
    for _ in 0..25 {
        a.push(100);
    }
    check_eq!(a.value(), 100);
    // 50 more of 400: the window holds only 400s now.
    let mut history = [0u16; 75];
    for h in history.iter_mut().take(25) {
        *h = 100;
    }
    for i in 25..75 {
        history[i] = 400;
        let v = a.push(400);
        // Independent: mean of the last min(50, i+1) samples, rounded.
        let lo = (i + 1).saturating_sub(50);
        let sum: i32 = history[lo..=i].iter().map(|&x| x as i32).sum();
        let n = (i + 1 - lo) as i32;
        check_eq!(v, (sum + n / 2) / n, "sample {}", i);
    }
    check_eq!(a.value(), 400);
    Ok(())
}

fn panic_record_round_trip_and_count() -> TestResult {
    let mut rec: RawRecord = [0; WORDS];
    // Fresh RAM: nothing to report.
    check!(panic_record::take(&mut rec).is_none());
    panic_record::store(
        &mut rec,
        Some(("board-a/src/main.rs", 42)),
        format_args!("index {} out of range", 7),
    );
    let r = ok!(panic_record::take(&mut rec));
    check_eq!(r.count, 1);
    check_eq!(r.message.as_str(), "board-a/src/main.rs:42: index 7 out of range");
    // The location also as numbers: the line, and the CRC-32 of the path (computed
    // here bit by bit, independently of the `crc` crate).
    check_eq!(r.line, 42);
    check_eq!(r.file_crc, crc32_bitwise(b"board-a/src/main.rs"));
    // Taken once: not reported again.
    check!(panic_record::take(&mut rec).is_none());
    panic_record::store(&mut rec, None, "second");
    let r = ok!(panic_record::take(&mut rec));
    check_eq!((r.count, r.message.as_str()), (2, "second"));
    // No location: line and file CRC 0.
    check_eq!((r.line, r.file_crc), (0, 0));
    Ok(())
}

/// CRC-32/ISO-HDLC, one bit at a time (reflected polynomial 0xEDB88320, initial value
/// and final XOR 0xFFFFFFFF).
pub fn crc32_bitwise(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn panic_record_file_crc_is_crc32_iso_hdlc() -> TestResult {
    // The catalogue check value of CRC-32/ISO-HDLC.
    check_eq!(crc32_bitwise(b"123456789"), 0xCBF4_3926);
    check_eq!(panic_record::file_crc("123456789"), 0xCBF4_3926);
    for path in ["fw-core/src/cycle.rs", "/work/main/obsw/core/src/obsw.rs", ""] {
        check_eq!(panic_record::file_crc(path), crc32_bitwise(path.as_bytes()), "{}", path);
    }
    Ok(())
}

fn panic_record_ignores_garbage_and_corruption() -> TestResult {
    let mut rec: RawRecord = [0xA5A5_A5A5; WORDS];
    check!(panic_record::take(&mut rec).is_none());
    panic_record::store(&mut rec, None, "after power-on");
    // Power-on garbage does not count as an earlier panic.
    let r = ok!(panic_record::take(&mut rec));
    check_eq!(r.count, 1);
    panic_record::store(&mut rec, None, "bit flip");
    rec[WORDS - 30] ^= 1 << 9;
    check!(panic_record::take(&mut rec).is_none(), "corrupted record accepted");
    Ok(())
}

fn panic_record_truncates_at_char_boundary() -> TestResult {
    let mut rec: RawRecord = [0; WORDS];
    // 119 ASCII bytes then a 3-byte character: it does not fit and is left out whole.
    let mut long: heapless::String<200> = heapless::String::new();
    for _ in 0..119 {
        let _ = long.push('x');
    }
    let _ = long.push('€');
    let _ = long.push_str("tail");
    panic_record::store(&mut rec, None, long.as_str());
    let r = ok!(panic_record::take(&mut rec));
    check_eq!(r.message.len(), 119);
    check!(r.message.chars().all(|c| c == 'x'));
    Ok(())
}
