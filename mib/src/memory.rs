//! Memory map of the robot's boards: an ESP32-C3 module with 4 MB of flash (ESP32-C3-MINI-1,
//! -WROOM-02) and the chip's 400 KB of SRAM. The partition table the boards are flashed
//! with (`firmware/partitions.csv`, ESP-IDF format) is generated from [`PARTITIONS`]; the
//! size report (`firmware/tools/size-report.sh`) reads the budgets below through
//! `firmware/memory-map.txt`, generated from this module too, and fails CI when a region
//! leaves the flight margin.
//!
//! Budgets (GSFC-STD-1000 at flight, [`FLIGHT_MARGIN_PCT`]): an image uses at most 70 % of
//! its application slot; static RAM plus the measured stack high-water mark at most 70 %
//! of [`SRAM_USABLE`]; the TM store holds its outage at most 70 % full.

/// Margin every budgeted resource keeps at flight (GSFC-STD-1000): used ≤ 100 − this %.
pub const FLIGHT_MARGIN_PCT: u32 = 30;

/// `true` when `used` leaves at least [`FLIGHT_MARGIN_PCT`] of `available` (in whole
/// units, no rounding: 70.001 % is out).
pub const fn within_margin(used: u64, available: u64) -> bool {
    used * 100 <= available * (100 - FLIGHT_MARGIN_PCT as u64)
}

/// The most of `available` a resource may use and keep the flight margin.
pub const fn budget(available: u32) -> u32 {
    (available as u64 * (100 - FLIGHT_MARGIN_PCT as u64) / 100) as u32
}

/// Size of the module's flash.
pub const FLASH_BYTES: u32 = 4 * 1024 * 1024;
/// Erase unit of the NOR flash (a write only clears bits; a sector erase sets them).
pub const FLASH_SECTOR: u32 = 4096;
/// Application partitions start on a 64 KiB boundary (the flash cache maps 64 KiB pages).
pub const APP_ALIGN: u32 = 0x1_0000;

/// What a flash region holds, with its ESP-IDF partition type and subtype.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashUse {
    /// The ESP-IDF second-stage bootloader the ROM loads (written by `espflash`; not in
    /// the partition table).
    Bootloader,
    /// The partition table itself (not an entry of it).
    PartitionTable,
    /// Application slot `n` (`app`, `ota_n`): the boot loader starts the slot `otadata`
    /// selects, the first one while `otadata` is erased.
    AppSlot(u8),
    /// `data`, `ota`: which slot boots (two sectors, written alternately).
    OtaData,
    /// Partition type [`OWN_TYPE`] with this subtype: a layout of our own.
    Own(u8),
}

/// ESP-IDF partition type of the layouts of our own (application-defined types are
/// 0x40..=0xFE; a numeric subtype is allowed under them, not under `data`).
pub const OWN_TYPE: u8 = 0x40;

impl FlashUse {
    /// ESP-IDF partition type and subtype, as `partitions.csv` writes them; `None` for the
    /// two regions outside the table.
    pub const fn idf_type(self) -> Option<(IdfType, IdfSubtype)> {
        match self {
            FlashUse::Bootloader | FlashUse::PartitionTable => None,
            FlashUse::AppSlot(n) => Some((IdfType::App, IdfSubtype::Ota(n))),
            FlashUse::OtaData => Some((IdfType::Data, IdfSubtype::Named("ota"))),
            FlashUse::Own(s) => Some((IdfType::Number(OWN_TYPE), IdfSubtype::Number(s))),
        }
    }
}

/// The type column of an ESP-IDF partition table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdfType {
    App,
    Data,
    Number(u8),
}

/// The subtype column of an ESP-IDF partition table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdfSubtype {
    Named(&'static str),
    Ota(u8),
    Number(u8),
}

/// One region of the flash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlashRegion {
    /// Partition name (at most 15 characters: the table stores 16 bytes with the NUL).
    pub name: &'static str,
    pub offset: u32,
    pub size: u32,
    pub usage: FlashUse,
    pub text: crate::types::Text,
}

impl FlashRegion {
    /// First byte after the region.
    pub const fn end(&self) -> u32 {
        self.offset + self.size
    }
}

const fn region(name: &'static str, offset: u32, size: u32, usage: FlashUse, text: &'static str) -> FlashRegion {
    FlashRegion {
        name,
        offset,
        size,
        usage,
        text: crate::types::text(text),
    }
}

/// ROM loads the second-stage bootloader from offset 0 on the ESP32-C3.
pub const BOOTLOADER: FlashRegion = region(
    "bootloader",
    0,
    0x8000,
    FlashUse::Bootloader,
    "ESP-IDF second-stage bootloader (espflash's build): reads the partition table and \
     otadata, boots an application slot",
);
/// ESP-IDF's fixed place for the partition table.
pub const PARTITION_TABLE: FlashRegion = region(
    "partition_table",
    0x8000,
    0x1000,
    FlashUse::PartitionTable,
    "partition table (32-byte entries and an MD5 entry, at most 0xC00 bytes)",
);
/// Board A's space-link keys and SDLS/FARM-1 counter log (`fw_core::link_store`: a key
/// sector and two log sectors); the rest of the partition is headroom.
pub const LINK_STATE: FlashRegion = region(
    "link",
    0x9000,
    0x5000,
    FlashUse::Own(0x00),
    "space-link keys (provisioned, tools/provision-keys.sh) and the SDLS IV / FARM-1 \
     counter log (fw_core::link_store): three 4 KiB sectors used",
);
/// Sectors of [`LINK_STATE`] that `fw_core::link_store` uses: the key record and the two
/// sectors of the counter log.
pub const LINK_STATE_SECTORS_USED: u32 = 3;
const _: () = assert!(LINK_STATE_SECTORS_USED * FLASH_SECTOR <= LINK_STATE.size);
/// Which application slot boots.
pub const OTADATA: FlashRegion = region(
    "otadata",
    0xE000,
    0x2000,
    FlashUse::OtaData,
    "which application slot boots (two sectors, written alternately)",
);
/// Size of each application slot: 576 KiB. An image may take 70 % of it (403 KiB); board A
/// with its file service (the CFDP entity and the flash file store) is ≈ 386 KiB at
/// `opt-level = 2` (67 %). 512 KiB slots (the last map) left it 75 % with the file service;
/// the 64 KiB each slot gained came from the report area of the TM store (576 → 512 KiB:
/// still above the 30 % margin for its 2 h outage) and the file store (192 → 128 KiB). Slots
/// of 896 KiB (the first map) left the TM store 2 MiB, whose HK area then held the 2 h
/// outage with a 3.8 % margin; the HK area is not to shrink below 560 sectors (29.7 % with
/// 544).
pub const APP_SLOT_SIZE: u32 = 0x9_0000;

/// Application slot 0: the image `espflash` writes (the first application partition).
pub const OTA_0: FlashRegion = region(
    "ota_0",
    0x1_0000,
    APP_SLOT_SIZE,
    FlashUse::AppSlot(0),
    "application slot 0 (the image espflash writes)",
);
/// Application slot 1: a software update is written here while slot 0 runs (and the
/// other way round), then `otadata` switches.
pub const OTA_1: FlashRegion = region(
    "ota_1",
    0xA_0000,
    APP_SLOT_SIZE,
    FlashUse::AppSlot(1),
    "application slot 1 (software update written while the other slot runs)",
);
/// Board A's PUS 15 packet store: TM kept across link outages and resets.
pub const TM_STORE: FlashRegion = region(
    "tm_store",
    0x13_0000,
    0x2B_0000,
    FlashUse::Own(0x01),
    "PUS 15 packet store (TM kept across link outages and resets)",
);
/// File store for CFDP transfers (plans, configuration, logs): `mmic_cfdp::flash`, a
/// directory in a `sequential-storage` map and the files' data in sectors of their own.
pub const FILE_STORE: FlashRegion = region(
    "files",
    0x3E_0000,
    0x2_0000,
    FlashUse::Own(0x02),
    "file store for CFDP transfers (plans, configuration, logs): mmic_cfdp::flash, a \
     sequential-storage directory and data sectors",
);

/// The whole flash, in address order, without gaps.
pub const FLASH_MAP: [FlashRegion; 8] = [
    BOOTLOADER,
    PARTITION_TABLE,
    LINK_STATE,
    OTADATA,
    OTA_0,
    OTA_1,
    TM_STORE,
    FILE_STORE,
];

/// Every application slot (an image must fit the smallest).
pub const APP_SLOTS: [FlashRegion; 2] = [OTA_0, OTA_1];

/// Flash an image may take: 70 % of its slot.
pub const IMAGE_BUDGET: u32 = budget(OTA_0.size);

/// Bytes the TM store must hold, from the longest link outage it bridges
/// ([`TM_STORE_OUTAGE_S`]) at the default housekeeping rates: checked by the MIB's tests
/// against the HK table and by the review package.
pub const TM_STORE_OUTAGE_S: u32 = 2 * 3600;

/// One region of the SRAM (addresses on the data bus, 0x3FC8_0000..0x3FCE_0000 for the
/// 384 KB of SRAM1; SRAM0 is instruction bus only).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SramRegion {
    pub name: &'static str,
    pub start: u32,
    pub size: u32,
    /// Usable by the image (static data, IRAM code, the stack).
    pub usable: bool,
    pub text: crate::types::Text,
}

const fn sram(name: &'static str, start: u32, size: u32, usable: bool, text: &'static str) -> SramRegion {
    SramRegion {
        name,
        start,
        size,
        usable,
        text: crate::types::text(text),
    }
}

/// SRAM0, 16 KB at 0x4037_C000 (instruction bus): the flash cache.
pub const SRAM_CACHE: SramRegion = sram(
    "icache",
    0x4037_C000,
    0x4000,
    false,
    "SRAM0 16 KB: instruction cache of the flash (code and read-only data run from flash \
     through it)",
);
/// The image's SRAM (esp-hal's linker script: 313 KiB from 0x3FC8_0000): code copied to
/// IRAM (`.rwtext`, `.trap`), `.data`, `.bss` and, in what is left, the one stack.
pub const SRAM_IMAGE: SramRegion = sram(
    "image",
    0x3FC8_0000,
    313 * 1024,
    true,
    "IRAM code, static data (.data, .bss: every queue, the OBSW, the tasks' futures) and \
     the one stack (esp-rtos runs every embassy task and interrupt on it)",
);
/// Used by the second-stage bootloader while it loads the image; free after boot (the
/// images leave it unused: no heap).
pub const SRAM_BOOTLOADER: SramRegion = sram(
    "bootloader",
    0x3FCC_E400,
    0x3FCD_E710 - 0x3FCC_E400,
    false,
    "the second-stage bootloader's memory while it loads the image; unused after boot \
     (no heap in the images): reserve",
);
/// The mask ROM's own data (its functions' `.data`/`.bss`, used at run time).
pub const SRAM_ROM: SramRegion = sram(
    "rom_data",
    0x3FCD_E710,
    0x3FCE_0000 - 0x3FCD_E710,
    false,
    "the mask ROM's data (ROM functions' .data and .bss at run time)",
);
/// The SRAM in address order (SRAM0 first, then SRAM1 on the data bus).
pub const SRAM_MAP: [SramRegion; 4] = [SRAM_CACHE, SRAM_IMAGE, SRAM_BOOTLOADER, SRAM_ROM];
/// SRAM an image may fill with static data and stack.
pub const SRAM_USABLE: u32 = SRAM_IMAGE.size;
/// RTC fast memory (8 KB at 0x5000_0000, kept across a reset): the panic record.
pub const RTC_FAST_BYTES: u32 = 8 * 1024;
/// Static RAM plus the stack's high-water mark may take at most this.
pub const SRAM_BUDGET: u32 = budget(SRAM_USABLE);

/// Program unit of the flash (ESP32-C3: a 32-bit word); the TM store's layout aligns to it.
pub const FLASH_WORD: u32 = 4;

/// The PUS 15 on-board TM store inside [`TM_STORE`]: two areas, each a power-fail safe
/// queue of whole TM packets (`sequential-storage`). Periodic housekeeping (TM[3,25]) goes
/// to the HK area, everything else (events, verification, other reports) to the report
/// area. A full area overwrites its own oldest sector; the HK area is the one that fills
/// (see [`store::MIN_DURATION_S`] and [`store::REPORTS_PER_HOUR`]), so periodic HK is
/// overwritten first and events and verification reports are kept longer. The host obsw
/// keeps the same partition in a file of [`store::SIZE`] bytes.
pub mod store {
    use super::{FLASH_SECTOR, FLASH_WORD, TM_STORE, TM_STORE_OUTAGE_S};

    /// The program unit as a length.
    pub const WORD_USIZE: usize = FLASH_WORD as usize;
    /// Start of the partition in board A's flash.
    pub const OFFSET: u32 = TM_STORE.offset;
    /// Events, verification and every other report.
    pub const REPORT_SIZE: u32 = 512 * 1024;
    /// Periodic housekeeping area: the rest of the partition.
    pub const HK_SIZE: u32 = TM_STORE.size - REPORT_SIZE;
    /// The whole partition (the host's store file has this size).
    pub const SIZE: u32 = TM_STORE.size;
    pub const HK_SECTORS: usize = (HK_SIZE / FLASH_SECTOR) as usize;
    pub const REPORT_SECTORS: usize = (REPORT_SIZE / FLASH_SECTOR) as usize;
    /// The store keeps at least this long of the MIB's default housekeeping (every
    /// structure at its `default_interval_ms`), checked by the store's sizing test.
    pub const MIN_DURATION_S: u32 = TM_STORE_OUTAGE_S;
    /// Events and verification reports the report area is sized for, per hour, over
    /// [`MIN_DURATION_S`]: an outage sees no ground TC, so this is on-board activity
    /// (events, scheduled and plan steps' verification) at one report every 2 s.
    pub const REPORTS_PER_HOUR: u32 = 1_800;

    /// Freeing ahead of need: in a control period with at most [`FREE_AHEAD_QUIET_WRITES`]
    /// store writes, each area gives up at most this many of its oldest packets, and only
    /// packets of the sector the area's next change of write sector must erase (those the
    /// next writes would overwrite anyway). A write then seldom has to free a whole sector
    /// itself (≈ 40 packets given up in one period).
    pub const FREE_AHEAD_PER_PERIOD: u32 = 4;
    /// The most store writes a period may have had for the store to free ahead in it.
    pub const FREE_AHEAD_QUIET_WRITES: u32 = 2;
    /// A PUS 15 downlink by range reads at most this many stored packets in a control
    /// period (sent or passed over), and goes on from the last one in the next period. A
    /// stored packet read from flash costs about 2 000 instructions on board A (the queue's
    /// CRC-32 over it) and one sent about 1 700 more into the TM frame; the period's budget
    /// with them is enforced (`t_store` and `t_budget` in firmware/qemu-tests). At one period
    /// in 10 ms that is 900 packets a second, beyond what the downlink takes; a range
    /// behind a full store is reached by passing over whole pages, one read each (the
    /// first packet of a page; `TmStore::skip`), not by reading its 24 000 packets. Nine:
    /// with twelve the worst period measured 47.0 % and 49.1 % of the 50 % budget in two
    /// runs of the same QEMU test (`-icount` figures vary with what the run's timing fed
    /// the period), with ten 48.0 %, and 48.3 % once a period's reads could be page reads
    /// (a page read starts its own iteration: about 3 800 instructions against 3 500), too
    /// close to be sure of; each read fewer gives ≈ 0.6 points back.
    pub const REPLAY_READS_PER_PERIOD: u32 = 9;
    /// Packets out of its range a downlink reads in a row before it asks the store to pass
    /// over what it can rule out without reading (`TmStore::skip`): a page holds 40 to 120
    /// packets, so a range's end is followed by a skip within a few periods.
    pub const SKIP_AFTER_MISSES: u32 = 16;
    /// What a page read costs against a packet read on, as (numerator, denominator): a
    /// page read starts an iteration of its own (the queue's ends, the item header checked,
    /// then the item and its CRC), ≈ 4 400 instructions on board A against 3 500 (`t_store`).
    /// A skip reads denominator/numerator as many and counts each by the ratio, so a
    /// period's reads cost the same either way.
    pub const PAGE_READ_COST: (usize, usize) = (5, 4);

    /// `sequential-storage`'s queue item header for a 4-byte flash word (obsw-core's store
    /// tests check it against `QueueStorage::item_overhead_size`).
    pub const ITEM_HEADER: usize = 8;
    /// Largest data field of an event report (the TM writer's event buffer,
    /// `config::EVENT_DATA_MAX`); verification reports are smaller.
    const REPORT_DATA_MAX: usize = crate::config::EVENT_DATA_MAX;

    /// Bytes of a TM packet with `data` bytes of data (headers, time stamp, PEC).
    const fn packet_len(data: usize) -> usize {
        use crate::headers::{CRC_LEN, PRIMARY_HEADER_LEN, TM_SEC_HEADER_LEN};
        PRIMARY_HEADER_LEN + TM_SEC_HEADER_LEN + crate::config::TIMESTAMP_LEN + data + CRC_LEN
    }

    /// Bytes a packet of `len` bytes takes in an area: its item header, the packet padded
    /// to the flash word.
    pub const fn item_bytes(len: usize) -> usize {
        ITEM_HEADER + len.next_multiple_of(WORD_USIZE)
    }

    /// Bytes an area of `sectors` sectors holds for items of at most `largest` bytes: the
    /// queue keeps its oldest sector free for reuse, a sector keeps two state words, and
    /// a sector loses at most one item's bytes less one at its end.
    pub const fn room(sectors: usize, largest: usize) -> usize {
        (sectors - 1) * (FLASH_SECTOR as usize - 2 * WORD_USIZE - (largest - 1))
    }

    /// What an outage of `secs` seconds puts into one area, and what the area holds.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct Need {
        /// The outage's packets as the area stores them (items).
        pub bytes: usize,
        /// The area's room for them ([`room`] with the largest of those items).
        pub room: usize,
    }

    impl Need {
        /// Hours of such traffic the area holds.
        pub fn hours(&self, secs: u32) -> f64 {
            self.room as f64 / self.bytes as f64 * secs as f64 / 3600.0
        }
        /// True when the area keeps the flight margin ([`super::FLIGHT_MARGIN_PCT`]).
        pub fn within_margin(&self) -> bool {
            super::within_margin(self.bytes as u64, self.room as u64)
        }
    }

    /// The HK area over an outage of `secs` s: every housekeeping structure the MIB enables
    /// by default at its `default_interval_ms`.
    pub fn hk_need(secs: u32) -> Need {
        let (mut bytes, mut largest) = (0, 0);
        for h in crate::hk::HK_STRUCTS.iter().filter(|h| h.default_enabled) {
            let item = item_bytes(packet_len(h.data_len()));
            largest = largest.max(item);
            bytes += secs as usize * 1000 / h.default_interval_ms as usize * item;
        }
        Need {
            bytes,
            room: room(HK_SECTORS, largest),
        }
    }

    /// The report area over an outage of `secs` s: [`REPORTS_PER_HOUR`] reports of the
    /// largest size.
    pub fn report_need(secs: u32) -> Need {
        let item = item_bytes(packet_len(REPORT_DATA_MAX));
        Need {
            bytes: REPORTS_PER_HOUR as usize * secs as usize / 3600 * item,
            room: room(REPORT_SECTORS, item),
        }
    }

    const _: () = assert!(HK_SIZE.is_multiple_of(FLASH_SECTOR) && REPORT_SIZE.is_multiple_of(FLASH_SECTOR));
    // Each area needs two sectors at least: the queue erases its oldest while the
    // youngest is still being written.
    const _: () = assert!(HK_SECTORS >= 2 && REPORT_SECTORS >= 2);
}

/// Byte the images paint their stack with at start-up: the lowest address that no longer
/// holds it is the stack's high-water mark.
pub const STACK_PAINT: u8 = 0xA5;

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: FW-MEM-01
    #[test]
    fn flash_map_covers_the_flash_in_order_without_overlap() {
        let mut at = 0;
        for r in FLASH_MAP {
            assert_eq!(r.offset, at, "{} starts where the previous region ends", r.name);
            assert!(r.size > 0 && r.size % FLASH_SECTOR == 0, "{}: whole sectors", r.name);
            assert!(r.name.len() <= 15, "{}: name fits the table's 16 bytes", r.name);
            at = r.end();
        }
        assert_eq!(at, FLASH_BYTES);
        for s in APP_SLOTS {
            assert_eq!(s.offset % APP_ALIGN, 0, "{} on a 64 KiB boundary", s.name);
        }
    }

    // verifies: FW-MEM-01
    #[test]
    fn sram_map_covers_sram1_in_order() {
        let mut at = SRAM_IMAGE.start;
        for r in &SRAM_MAP[1..] {
            assert_eq!(r.start, at, "{}", r.name);
            at = r.start + r.size;
        }
        // SRAM1: 384 KB on the data bus; with SRAM0 the chip's 400 KB.
        assert_eq!(at, 0x3FCE_0000);
        assert_eq!(SRAM_MAP.iter().map(|r| r.size).sum::<u32>(), 400 * 1024);
    }

    // verifies: FW-MEM-02
    #[test]
    fn each_store_area_holds_the_outage_with_the_flight_margin() {
        let (hk, reports) = (store::hk_need(TM_STORE_OUTAGE_S), store::report_need(TM_STORE_OUTAGE_S));
        assert!(hk.within_margin(), "HK area: {hk:?}");
        assert!(reports.within_margin(), "report area: {reports:?}");
        // Twice the outage no longer fits: the figures are not vacuous.
        assert!(store::hk_need(2 * TM_STORE_OUTAGE_S).bytes > hk.room);
    }

    // verifies: FW-MEM-02
    #[test]
    fn margin_is_checked_in_bytes() {
        assert!(within_margin(70, 100));
        assert!(!within_margin(71, 100));
        assert!(within_margin(IMAGE_BUDGET as u64, OTA_0.size as u64));
        assert!(!within_margin(IMAGE_BUDGET as u64 + 1, OTA_0.size as u64));
        assert!(within_margin(SRAM_BUDGET as u64, SRAM_USABLE as u64));
        assert!(!within_margin(SRAM_BUDGET as u64 + 1, SRAM_USABLE as u64));
    }
}
