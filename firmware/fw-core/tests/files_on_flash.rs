//! Board A's file service over the flash file store (`mmic_cfdp::flash::FlashStore` on a
//! model of the module's NOR flash): it erases free sectors ahead of need only in periods
//! without a packet or a transfer, one erase a period at most, and the next file's writes
//! then erase nothing.

use std::cell::RefCell;

use fw_core::files::{FileService, Files};
use mmic_cfdp::flash::FlashStore;
use mmic_cfdp::{FileName, Parts};
use obsw_core::flash_store::Nor;
use obsw_core::tm::TmSink;

/// The downlink: takes every packet.
#[derive(Default)]
struct Down(RefCell<Vec<Vec<u8>>>);

impl TmSink for Down {
    fn send_tm(&mut self, packet: &[u8]) {
        self.0.borrow_mut().push(packet.to_vec());
    }
}

fn erases(parts: &Parts<FlashStore<Nor<&mut [u8]>>>) -> u32 {
    parts.store.inner().counters().erases
}

// verifies: FILE-STORE-08
#[test]
fn free_sectors_are_erased_ahead_only_in_spare_periods_and_the_next_file_erases_none() {
    let region = mib::memory::FILE_STORE.offset..mib::memory::FILE_STORE.end();
    let mut bytes = vec![0xFF; region.end as usize];
    let mut nor = Nor::new(&mut bytes[..], region.end);
    FlashStore::format(&mut nor, region.clone()).unwrap();
    let parts = Parts::new(FlashStore::open(nor, region).unwrap());
    // A file written and removed: its sectors are free and not blank.
    let data: Vec<u8> = (0..40_000u32).map(|i| (i * 7 + 3) as u8).collect();
    let name = FileName::new("old.bin").unwrap();
    parts.store.create(&name).unwrap();
    parts.store.write(&name, 0, &data).unwrap();
    parts.store.remove(&name).unwrap();
    let mut files = Files::new(1, &parts);
    let mut down = Down::default();
    let before = erases(&parts);

    // A period whose packet went to the OBSW: nothing erased.
    files.tc_handled();
    files.poll(10, &mut down);
    assert_eq!(erases(&parts), before, "an erase in a period that handled a TC");
    // A period that took a PDU of the file service (refused here: a malformed one): the same.
    let junk = [0x18, mib::cfdp::APID as u8, 0xC0, 0x00, 0x00, 0x01, 0x24, 0x00];
    assert!(files.take(20, &junk));
    files.poll(20, &mut down);
    assert_eq!(erases(&parts), before, "an erase in a period that took a packet");

    // Spare periods: one erase each at most, until none is left.
    let mut now = 30;
    let mut periods = 0;
    loop {
        let e = erases(&parts);
        files.poll(now, &mut down);
        now += 10;
        periods += 1;
        let d = erases(&parts) - e;
        assert!(d <= 1, "{d} erases in one period");
        if d == 0 && periods > 64 {
            break;
        }
    }
    let ahead = erases(&parts) - before;
    assert!(ahead >= 9, "the removed file's 10 sectors were erased ahead ({ahead})");

    // The next file's writes take blank sectors: they erase nothing.
    let e = erases(&parts);
    let name = FileName::new("new.bin").unwrap();
    parts.store.create(&name).unwrap();
    parts.store.write(&name, 0, &data).unwrap();
    assert_eq!(erases(&parts), e, "the new file's writes erased");
    let mut back = vec![0; data.len()];
    parts.store.read(&name, 0, &mut back).unwrap();
    assert!(back == data);
}
