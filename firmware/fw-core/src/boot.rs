//! What board A reports at boot: the reset cause as one of the MIB's named codes
//! (event BOOT) and the panic the previous run recorded before its reset (event
//! PREVIOUS_PANIC), read from the RTC-RAM record and marked reported afterwards.

use crate::panic_record::{self, PanicReport, RawRecord};
use mib::config::reset_cause;
use obsw_core::obsw::Obsw;
use obsw_core::tm::{TmSink, TmStore};

/// Raw reset reasons of the ESP32-C3 (RTC_CNTL reset cause, esp-hal's
/// `esp_hal::rtc_cntl::SocResetReason`; ESP32-C3 TRM, "Reset and Clock").
pub mod soc_reset {
    /// Power-on (also brown-out and super watchdog in ESP-IDF's reading).
    pub const CHIP_POWER_ON: u8 = 0x01;
    /// Software reset of the digital core (RTC_CNTL_SW_SYS_RST): `software_reset()`,
    /// which only the panic handler calls.
    pub const CORE_SW: u8 = 0x03;
    /// Deep-sleep wake-up.
    pub const CORE_DEEP_SLEEP: u8 = 0x05;
    /// Main watchdog 0 (TIMG0 MWDT) reset the digital core.
    pub const CORE_MWDT0: u8 = 0x07;
    /// Main watchdog 1 (TIMG1 MWDT, the control-loop watchdog) reset the digital core.
    pub const CORE_MWDT1: u8 = 0x08;
    /// RTC watchdog reset the digital core.
    pub const CORE_RTC_WDT: u8 = 0x09;
    /// Main watchdog 0 reset CPU 0.
    pub const CPU0_MWDT0: u8 = 0x0B;
    /// Software reset of CPU 0 (RTC_CNTL_SW_PROCPU_RST).
    pub const CPU0_SW: u8 = 0x0C;
    /// RTC watchdog reset CPU 0.
    pub const CPU0_RTC_WDT: u8 = 0x0D;
    /// Brown-out.
    pub const SYS_BROWN_OUT: u8 = 0x0F;
    /// RTC watchdog reset the digital core and the RTC module.
    pub const SYS_RTC_WDT: u8 = 0x10;
    /// Main watchdog 1 reset CPU 0.
    pub const CPU0_MWDT1: u8 = 0x11;
    /// Super watchdog reset the digital core and the RTC module.
    pub const SYS_SUPER_WDT: u8 = 0x12;
    /// Every watchdog reset.
    pub const WATCHDOGS: [u8; 8] = [
        CORE_MWDT0,
        CORE_MWDT1,
        CORE_RTC_WDT,
        CPU0_MWDT0,
        CPU0_RTC_WDT,
        SYS_RTC_WDT,
        CPU0_MWDT1,
        SYS_SUPER_WDT,
    ];
}

/// Named reset cause (`mib::config::reset_cause`) of the chip's raw reset reason
/// (`None` when the chip gave none). A software reset is a panic when the panic record
/// holds one (the panic handler is the only caller of the software reset); without a
/// record it is OTHER, as are brown-out, deep sleep, the reset pin and USB resets.
pub fn reset_cause(raw: Option<u8>, panic_recorded: bool) -> u8 {
    match raw {
        Some(soc_reset::CHIP_POWER_ON) => reset_cause::POWER_ON,
        Some(soc_reset::CORE_SW | soc_reset::CPU0_SW) if panic_recorded => reset_cause::PANIC,
        Some(r) if soc_reset::WATCHDOGS.contains(&r) => reset_cause::WATCHDOG,
        _ => reset_cause::OTHER,
    }
}

/// What [`announce`] found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BootReport {
    /// Named reset cause reported in BOOT.
    pub reset_cause: u8,
    /// The previous run's panic, reported in PREVIOUS_PANIC.
    pub panic: Option<PanicReport>,
}

/// Board A's boot announcement: event BOOT with the named reset cause, then, when the
/// panic record holds a valid panic of the previous run, event PREVIOUS_PANIC (reset
/// cause, line, CRC-32 of the file path) — after which the record is marked reported,
/// so the panic is reported once. A corrupted or absent record gives no event.
pub fn announce<S: TmStore>(
    now: u64,
    raw_reset: Option<u8>,
    record: &mut RawRecord,
    obsw: &mut Obsw<S>,
    sink: &mut impl TmSink,
) -> BootReport {
    let panic = panic_record::read(record);
    let cause = reset_cause(raw_reset, panic.is_some());
    obsw.boot(now, cause, sink);
    if let Some(p) = &panic {
        obsw.report_previous_panic(now, cause, p.line, p.file_crc, sink);
    }
    panic_record::mark_reported(record);
    BootReport {
        reset_cause: cause,
        panic,
    }
}

/// Name of a `mib::config::reset_cause` code, for console text.
pub fn reset_cause_name(code: u8) -> &'static str {
    match code {
        reset_cause::POWER_ON => "power-on",
        reset_cause::PANIC => "panic",
        reset_cause::WATCHDOG => "watchdog",
        _ => "other",
    }
}
