//! Panic handler: records the reason in RTC fast RAM, then resets the chip (which
//! unpowers every servo: LEDC stops, and the regulator enable line returns to its
//! pull-up, i.e. off). The next boot reads the record: board A through
//! [`with_record`] and `fw_core::boot::announce` (event PREVIOUS_PANIC), board B with
//! [`take_report`] (text on its console).

use core::ptr::addr_of_mut;
use fw_core::panic_record::{self, PanicReport, RawRecord, WORDS};

/// Kept across software resets and watchdog resets; zeroed by the start-up code only
/// after a power-on (see esp-hal's `#[ram(unstable(persistent))]`). Any bit pattern is
/// valid: the record carries a magic word and a CRC.
#[esp_hal::ram(unstable(rtc_fast, persistent))]
static mut PANIC_RECORD: RawRecord = [0; WORDS];

/// Runs `f` on the panic record (inside a critical section).
pub fn with_record<R>(f: impl FnOnce(&mut RawRecord) -> R) -> R {
    critical_section::with(|_| {
        // SAFETY: the record is only touched here, inside a critical section, on the
        // single core of the ESP32-C3: no other reference to it can exist.
        let rec = unsafe { &mut *addr_of_mut!(PANIC_RECORD) };
        f(rec)
    })
}

/// The panic recorded before the last reset, if any (reported once).
pub fn take_report() -> Option<PanicReport> {
    with_record(panic_record::take)
}

/// Raw reset reason of this boot (`esp_hal::rtc_cntl::SocResetReason`, e.g. 1 power-on,
/// 3 software reset after a panic, 8 the control-loop watchdog; the values are
/// `fw_core::boot::soc_reset`); `None` when the chip gives none.
pub fn reset_reason() -> Option<u8> {
    esp_hal::system::reset_reason().map(|r| r as u8)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    let location = info.location().map(|l| (l.file(), l.line()));
    with_record(|rec| panic_record::store(rec, location, info.message()));
    esp_hal::system::software_reset()
}
