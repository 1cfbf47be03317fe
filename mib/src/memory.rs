//! Flash areas the flight software itself reads and writes. Board A's module has 4 MB of
//! NOR flash in 4 KiB sectors; the host obsw keeps the same areas in files of the same
//! size, so that the store's code, layout and capacity are one on both.

/// Flash size of board A's module (ESP32-C3-MINI-1: 4 MB).
pub const FLASH_SIZE: u32 = 4 * 1024 * 1024;
/// Erase unit of the NOR flash.
pub const SECTOR: u32 = 4096;
/// Program unit of the flash (ESP32-C3: a 32-bit word); the store's layout aligns to it.
pub const WORD: u32 = 4;

/// The PUS 15 on-board TM store: a partition of two areas, each a power-fail safe queue
/// of whole TM packets (`sequential-storage`). Periodic housekeeping (TM[3,25]) goes to
/// the HK area, everything else (events, verification, other reports) to the report
/// area. A full area overwrites its own oldest sector; the HK area is the one that fills
/// (see [`store::MIN_DURATION_S`] and [`store::REPORTS_PER_HOUR`]), so periodic HK is
/// overwritten first and events and verification reports are kept longer.
pub mod store {
    use super::{FLASH_SIZE, SECTOR, WORD};

    /// The program unit as a length.
    pub const WORD_USIZE: usize = WORD as usize;

    /// Start of the partition in board A's flash (after the bootloader, the partition
    /// table, the key and counter area and two 1 MiB application slots).
    pub const OFFSET: u32 = 0x22_0000;
    /// Periodic housekeeping area.
    pub const HK_SIZE: u32 = 1_408 * 1024;
    /// Events, verification and every other report.
    pub const REPORT_SIZE: u32 = 512 * 1024;
    /// The whole partition (the host's store file has this size).
    pub const SIZE: u32 = HK_SIZE + REPORT_SIZE;
    pub const HK_SECTORS: usize = (HK_SIZE / SECTOR) as usize;
    pub const REPORT_SECTORS: usize = (REPORT_SIZE / SECTOR) as usize;
    /// The store keeps at least this long of the MIB's default housekeeping (every
    /// structure at its `default_interval_ms`), checked by the store's sizing test.
    pub const MIN_DURATION_S: u32 = 2 * 3600;
    /// Events and verification reports the report area is sized for, per hour, over
    /// [`MIN_DURATION_S`]: an outage sees no ground TC, so this is on-board activity
    /// (events, scheduled and plan steps' verification) at one report every 2 s.
    pub const REPORTS_PER_HOUR: u32 = 1_800;

    const _: () =
        assert!(OFFSET.is_multiple_of(SECTOR) && HK_SIZE.is_multiple_of(SECTOR) && REPORT_SIZE.is_multiple_of(SECTOR));
    const _: () = assert!(OFFSET + SIZE <= FLASH_SIZE);
    // Each area needs two sectors at least: the queue erases its oldest while the
    // youngest is still being written.
    const _: () = assert!(HK_SECTORS >= 2 && REPORT_SECTORS >= 2);
}
