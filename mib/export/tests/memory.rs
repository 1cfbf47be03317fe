//! The boards' memory map as the firmware tools read it: `firmware/partitions.csv` and
//! `firmware/memory-map.txt` must be exactly what `mib_export::memory` generates from
//! `mib::memory`, and the partition table must be one ESP-IDF's tools accept (esp-rs's
//! `esp-idf-part`, the parser espflash writes tables with). Regenerate both files with
//! `UPDATE_MEMORY_MAP=1 cargo test -p mib-export --test memory`.

use esp_idf_part::{AppType, DataType, PartitionTable, SubType, Type};
use mib::memory::{self, FlashUse};
use mib_export::memory::{memory_map_txt, partitions_csv};
use std::path::Path;

fn check_generated(file: &str, want: &str) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(file);
    if std::env::var_os("UPDATE_MEMORY_MAP").is_some_and(|v| v == "1") {
        std::fs::write(&path, want).expect("write the generated file");
        return;
    }
    let have = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        have == want,
        "{file} is stale; regenerate it with `UPDATE_MEMORY_MAP=1 cargo test -p mib-export --test memory` and commit it"
    );
}

// verifies: FW-MEM-01
#[test]
fn firmware_partitions_csv_is_generated_from_the_mib() {
    check_generated("firmware/partitions.csv", &partitions_csv());
}

// verifies: FW-MEM-01, FW-MEM-02
#[test]
fn firmware_memory_map_txt_is_generated_from_the_mib() {
    check_generated("firmware/memory-map.txt", &memory_map_txt());
}

// verifies: FW-MEM-01
#[test]
fn partition_table_is_valid_for_esp_idf_and_matches_the_map() {
    let table = PartitionTable::try_from_str(partitions_csv()).expect("esp-idf-part parses the CSV");
    table.validate().expect("esp-idf-part validates the table");
    let listed: Vec<_> = memory::FLASH_MAP
        .iter()
        .filter(|r| r.usage.idf_type().is_some())
        .collect();
    assert_eq!(table.partitions().len(), listed.len());
    for r in listed {
        let p = table.find(r.name).unwrap_or_else(|| panic!("{} in the table", r.name));
        assert_eq!((p.offset(), p.size()), (r.offset, r.size), "{}", r.name);
        // Type and subtype as the binary table stores them (ESP-IDF: ota_N = 0x10 + N,
        // data ota = 0x00; application-defined types 0x40..=0xFE).
        let want = match r.usage {
            FlashUse::AppSlot(n) => (Type::App, 0x10 + n),
            FlashUse::OtaData => (Type::Data, 0x00),
            FlashUse::Own(n) => (Type::Custom(memory::OWN_TYPE), n),
            FlashUse::Bootloader | FlashUse::PartitionTable => unreachable!("not listed"),
        };
        assert_eq!((p.ty(), u8::from(p.subtype())), want, "{}", r.name);
    }
    // The binary form espflash writes at 0x8000 fits the table's region.
    let bin = table.to_bin().expect("binary table");
    assert!(bin.len() as u32 <= memory::PARTITION_TABLE.size);
    // The two slots a software update alternates between, and which one boots.
    assert!(table.find_by_subtype(Type::App, SubType::App(AppType::Ota_0)).is_some());
    assert!(table.find_by_subtype(Type::App, SubType::App(AppType::Ota_1)).is_some());
    assert!(table
        .find_by_subtype(Type::Data, SubType::Data(DataType::Ota))
        .is_some());
}

// verifies: FW-MEM-02
#[test]
fn memory_map_gives_each_store_area_its_room_and_outage() {
    let map = memory_map_txt();
    let secs = memory::TM_STORE_OUTAGE_S;
    for (area, need) in [
        ("hk", memory::store::hk_need(secs)),
        ("reports", memory::store::report_need(secs)),
    ] {
        let line = format!("area tm_store.{area} {:#x} {:#x}", need.room, need.bytes);
        assert!(map.lines().any(|l| l == line), "{line} in the map");
        assert!(need.within_margin(), "{area}: {need:?}");
    }
}
