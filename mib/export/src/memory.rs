//! The boards' memory map ([`mib::memory`]) as the files the firmware tools read:
//! `firmware/partitions.csv` (ESP-IDF partition table, for `espflash --partition-table`)
//! and `firmware/memory-map.txt` (the regions and budgets the size report checks).

use mib::memory::{self, IdfSubtype, IdfType};
use std::fmt::Write;

/// The ESP-IDF partition table of the boards (CSV: name, type, subtype, offset, size,
/// flags), every partition of [`memory::FLASH_MAP`] that the table lists.
pub fn partitions_csv() -> String {
    let mut s = String::new();
    s.push_str("# ESP-IDF partition table of the MMIC-I boards (ESP32-C3, 4 MB flash).\n");
    s.push_str("# Generated from the MIB (mib::memory): UPDATE_MEMORY_MAP=1 cargo test -p mib-export --test memory\n");
    s.push_str("# Name, Type, SubType, Offset, Size, Flags\n");
    for r in memory::FLASH_MAP {
        let Some((ty, sub)) = r.usage.idf_type() else {
            continue;
        };
        let ty = match ty {
            IdfType::App => "app".to_string(),
            IdfType::Data => "data".to_string(),
            IdfType::Number(n) => format!("{n:#04x}"),
        };
        let sub = match sub {
            IdfSubtype::Named(n) => n.to_string(),
            IdfSubtype::Ota(n) => format!("ota_{n}"),
            IdfSubtype::Number(n) => format!("{n:#04x}"),
        };
        let _ = writeln!(s, "{}, {}, {}, {:#x}, {:#x},", r.name, ty, sub, r.offset, r.size);
    }
    s
}

/// The regions and budgets for `firmware/tools/size-report.sh`, one `key value...` line
/// each (`#` starts a comment):
/// - `margin PCT`: the flight margin;
/// - `flash NAME OFFSET SIZE`: a region of the flash, in address order;
/// - `sram NAME START SIZE usable|reserved`: a region of the SRAM;
/// - `slot NAME SIZE`: an application slot (the image's budget is 70 % of the smallest);
/// - `used NAME BYTES`: what a region other than a slot or the SRAM holds, fixed by design;
/// - `sram_usable BYTES`: SRAM for static data and the stack;
/// - `rtc_fast BYTES`: RTC fast memory (the panic record).
pub fn memory_map_txt() -> String {
    let mut s = String::new();
    s.push_str("# Memory map of the MMIC-I boards, read by firmware/tools/size-report.sh.\n");
    s.push_str("# Generated from the MIB (mib::memory): UPDATE_MEMORY_MAP=1 cargo test -p mib-export --test memory\n");
    let _ = writeln!(s, "margin {}", memory::FLIGHT_MARGIN_PCT);
    for r in memory::FLASH_MAP {
        let _ = writeln!(s, "flash {} {:#x} {:#x}", r.name, r.offset, r.size);
    }
    for r in memory::SRAM_MAP {
        let kind = if r.usable { "usable" } else { "reserved" };
        let _ = writeln!(s, "sram {} {:#x} {:#x} {}", r.name, r.start, r.size, kind);
    }
    for r in memory::APP_SLOTS {
        let _ = writeln!(s, "slot {} {:#x}", r.name, r.size);
    }
    let _ = writeln!(
        s,
        "used {} {:#x}",
        memory::LINK_STATE.name,
        memory::LINK_STATE_SECTORS_USED * memory::FLASH_SECTOR
    );
    let _ = writeln!(
        s,
        "used {} {:#x}",
        memory::PARTITION_TABLE.name,
        partition_table_bytes()
    );
    let _ = writeln!(s, "sram_usable {:#x}", memory::SRAM_USABLE);
    let _ = writeln!(s, "rtc_fast {:#x}", memory::RTC_FAST_BYTES);
    let _ = writeln!(
        s,
        "# the TM store's areas (mib::memory::store): room, and a {} s outage as stored (default HK; reports at REPORTS_PER_HOUR)",
        memory::TM_STORE_OUTAGE_S
    );
    let secs = memory::TM_STORE_OUTAGE_S;
    for (area, need) in [
        ("hk", memory::store::hk_need(secs)),
        ("reports", memory::store::report_need(secs)),
    ] {
        let _ = writeln!(
            s,
            "area {}.{} {:#x} {:#x}",
            memory::TM_STORE.name,
            area,
            need.room,
            need.bytes
        );
    }
    s
}

/// Bytes of the binary partition table: one 32-byte entry per partition, the MD5 entry
/// and the 0xFF end marker entry ESP-IDF's tools write.
pub fn partition_table_bytes() -> u32 {
    let entries = memory::FLASH_MAP
        .iter()
        .filter(|r| r.usage.idf_type().is_some())
        .count() as u32;
    32 * (entries + 2)
}
