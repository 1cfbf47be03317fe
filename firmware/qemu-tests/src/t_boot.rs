//! Board A's boot report (`fw_core::boot`): the chip's reset reason as the MIB's named
//! reset cause in event BOOT, and the panic the previous run left in the RTC-RAM record
//! as event PREVIOUS_PANIC — once, with the right line and file CRC, never for a
//! corrupted or absent record.

use crate::harness::{Test, TestResult};
use crate::t_support::crc32_bitwise;
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::boot::{self, soc_reset};
use fw_core::panic_record::{self, RawRecord, WORDS};
use mib::config::reset_cause;
use mib::events::eid;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::PusPacket;

pub const TESTS: &[Test] = tests![
    boot_reset_cause_names_every_esp32c3_reset_reason,
    boot_reports_the_previous_panic_once_with_line_and_file_crc,
    boot_with_a_corrupt_or_absent_panic_record_reports_no_panic,
];

/// Event packets: (subtype, source data).
#[derive(Default)]
struct Events(heapless::Vec<(u8, heapless::Vec<u8, 32>), 8>);

impl TmSink for Events {
    fn send_tm(&mut self, packet: &[u8]) {
        let Ok(r) = PusTmReader::new(packet, mib::config::TIMESTAMP_LEN) else {
            return;
        };
        if PusPacket::service_type_id(&r) == 5 {
            let mut d = heapless::Vec::new();
            let _ = d.extend_from_slice(&r.user_data()[..r.user_data().len().min(32)]);
            let _ = self.0.push((PusPacket::message_subtype_id(&r), d));
        }
    }
}

fn obsw() -> Obsw<RingStore<2048>> {
    Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 0,
        },
        RingStore::default(),
    )
}

fn boot_reset_cause_names_every_esp32c3_reset_reason() -> TestResult {
    use reset_cause::{OTHER, PANIC, POWER_ON, WATCHDOG};
    // (raw reason from the ESP32-C3 TRM's reset-cause table, with a panic record?,
    // named cause)
    let table: &[(Option<u8>, bool, u8)] = &[
        (Some(0x01), false, POWER_ON),
        (Some(0x03), true, PANIC),  // software reset by the panic handler
        (Some(0x0C), true, PANIC),  // CPU software reset
        (Some(0x03), false, OTHER), // software reset without a recorded panic
        (Some(0x05), false, OTHER), // deep sleep
        (Some(0x07), false, WATCHDOG),
        (Some(0x08), false, WATCHDOG), // TIMG1: the control-loop watchdog
        (Some(0x08), true, WATCHDOG),  // panic handler stuck, then the watchdog
        (Some(0x09), false, WATCHDOG),
        (Some(0x0B), false, WATCHDOG),
        (Some(0x0D), false, WATCHDOG),
        (Some(0x0F), false, OTHER), // brown-out
        (Some(0x10), false, WATCHDOG),
        (Some(0x11), false, WATCHDOG),
        (Some(0x12), false, WATCHDOG),
        (Some(0x13), false, OTHER), // clock glitch
        (Some(0x15), false, OTHER), // USB UART (espflash)
        (Some(0x16), false, OTHER), // USB JTAG
        (None, false, OTHER),
        (None, true, OTHER),
    ];
    for &(raw, panic, want) in table {
        check_eq!(
            boot::reset_cause(raw, panic),
            want,
            "raw {:?}, panic record {}",
            raw,
            panic
        );
    }
    check_eq!(soc_reset::CORE_MWDT1, 0x08);
    check_eq!((POWER_ON, PANIC, WATCHDOG, OTHER), (0, 1, 2, 3));
    Ok(())
}

fn boot_reports_the_previous_panic_once_with_line_and_file_crc() -> TestResult {
    let mut rec: RawRecord = [0; WORDS];
    // The previous run: a panic at a real source location (this line), recorded the way
    // the panic handler does, then the software reset.
    let loc = core::panic::Location::caller();
    let here = (loc.file(), loc.line());
    check_eq!((here.0, here.1), (file!(), line!() - 2));
    panic_record::store(&mut rec, Some(here), "attempt to divide by zero");

    let mut a = obsw();
    let mut ev = Events::default();
    let r = boot::announce(1234, Some(soc_reset::CORE_SW), &mut rec, &mut a, &mut ev);
    check_eq!(r.reset_cause, reset_cause::PANIC);
    check_eq!(ok!(r.panic.as_ref()).line, here.1);
    check_eq!(ev.0.len(), 2);
    // BOOT (TM[5,1]) with the named cause.
    let (sub, data) = &ev.0[0];
    check_eq!(*sub, 1);
    check_eq!(&data[..], &[0x02, 0x07, reset_cause::PANIC][..]);
    // PREVIOUS_PANIC (high severity, TM[5,4]): event ID, reset cause, line, CRC-32 of
    // the path, big-endian (ICD section 7), assembled here by hand.
    let (sub, data) = &ev.0[1];
    check_eq!(*sub, 4);
    let mut want = [0u8; 11];
    want[..2].copy_from_slice(&0x020Cu16.to_be_bytes());
    want[2] = reset_cause::PANIC;
    want[3..7].copy_from_slice(&here.1.to_be_bytes());
    want[7..].copy_from_slice(&crc32_bitwise(here.0.as_bytes()).to_be_bytes());
    check_eq!(&data[..], &want[..]);
    let d = ok!(mib_wire::codec::decode_event(data));
    check_eq!(d.def.id, eid::PREVIOUS_PANIC);
    check_eq!(d.param("line"), Some(here.1 as i64));

    // Reported: the record is cleared, the next boot (a watchdog reset, say) reports
    // only BOOT.
    check!(
        panic_record::read(&rec).is_none(),
        "record still valid after the report"
    );
    let mut a = obsw();
    let mut ev = Events::default();
    let r = boot::announce(0, Some(soc_reset::CORE_MWDT1), &mut rec, &mut a, &mut ev);
    check_eq!((r.reset_cause, r.panic.is_none()), (reset_cause::WATCHDOG, true));
    check_eq!(ev.0.len(), 1);
    check_eq!(&ev.0[0].1[..], &[0x02, 0x07, reset_cause::WATCHDOG][..]);
    // The panic count survives the report: the next panic is number 2.
    panic_record::store(&mut rec, Some(("fw-core/src/cycle.rs", 7)), "again");
    check_eq!(ok!(panic_record::read(&rec)).count, 2);
    Ok(())
}

fn boot_with_a_corrupt_or_absent_panic_record_reports_no_panic() -> TestResult {
    // Power-on: RTC RAM holds garbage.
    let mut rec: RawRecord = [0x5A5A_5A5A; WORDS];
    let mut ev = Events::default();
    let r = boot::announce(0, Some(soc_reset::CHIP_POWER_ON), &mut rec, &mut obsw(), &mut ev);
    check_eq!((r.reset_cause, r.panic.is_none()), (reset_cause::POWER_ON, true));
    check_eq!(ev.0.len(), 1);
    check_eq!(&ev.0[0].1[..], &[0x02, 0x07, reset_cause::POWER_ON][..]);

    // A record with one bit flipped in its line (word 2), file CRC (3), message length
    // (4), CRC (5) or message (6): no PREVIOUS_PANIC with a wrong location, and the
    // software reset is then not known to be a panic.
    for word in [2usize, 3, 4, 5, 6] {
        let mut rec: RawRecord = [0; WORDS];
        panic_record::store(&mut rec, Some(("fw-core/src/boot.rs", 99)), "flip");
        rec[word] ^= 1 << 17;
        let mut ev = Events::default();
        let r = boot::announce(0, Some(soc_reset::CORE_SW), &mut rec, &mut obsw(), &mut ev);
        check_eq!(
            (r.reset_cause, r.panic.is_none()),
            (reset_cause::OTHER, true),
            "word {}",
            word
        );
        check_eq!(ev.0.len(), 1, "word {}", word);
        check_eq!(ev.0[0].0, 1);
        // Cleared: a panic recorded afterwards counts from 1 again.
        panic_record::store(&mut rec, None, "next");
        check_eq!(ok!(panic_record::read(&rec)).count, 1, "word {}", word);
    }
    Ok(())
}
