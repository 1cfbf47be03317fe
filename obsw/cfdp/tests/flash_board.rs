//! Board A's flash as the firmware wires it: one 4 MiB NOR flash (`obsw_core`'s model of
//! the module's part, the one the host's store file and the QEMU board's flash share)
//! behind one `RefCell`, the PUS 15 store in its partition and the file store in
//! `mib::memory::FILE_STORE` through the same `Shared` handle, both written in turn and
//! both whole after a reset.

use std::cell::RefCell;

use mmic_cfdp::flash::FlashStore;
use mmic_cfdp::store::FlatStore;
use mmic_cfdp::FileName;
use obsw_core::flash_store::{MibFlashStore, Nor, Shared};
use obsw_core::time::OnboardTime;
use obsw_core::tm::{TmStore, TmWriter};

fn files(s: &impl FlatStore) -> Vec<(String, Vec<u8>)> {
    let mut names = Vec::new();
    s.list(&mut |n, l| names.push((n.clone(), l))).unwrap();
    names
        .into_iter()
        .map(|(n, l)| {
            let mut v = vec![0; l as usize];
            s.read(&n, 0, &mut v).unwrap();
            (n.as_str().to_string(), v)
        })
        .collect()
}

fn tm(s: &mut impl TmStore) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    s.visit(&mut |p| out.push(p.to_vec()));
    out
}

// verifies: FILE-STORE-04
#[test]
fn the_file_store_and_the_tm_store_share_board_as_flash_and_both_survive_a_reset() {
    let bytes = mib::memory::FLASH_BYTES;
    let mut mem = vec![0xFF; bytes as usize];
    let flash = RefCell::new(Nor::new(&mut mem[..], bytes));
    let region = mib::memory::FILE_STORE.offset..mib::memory::FILE_STORE.end();
    let mut w = TmWriter::new(0x101, OnboardTime::new(1_790_000_000_000));
    let mut buf = [0u8; mib::config::MAX_PACKET_LEN];
    let mut packets = Vec::new();
    let mut want = Vec::new();
    {
        let mut tms = MibFlashStore::open(&flash, mib::memory::TM_STORE.offset).unwrap();
        let fs = FlashStore::open(Shared(&flash), region.clone()).unwrap();
        for i in 0..120u32 {
            let len = w.build(1000 * u64::from(i), 3, 25, &[i as u8; 40], &mut buf).unwrap();
            assert_eq!(tms.push(&buf[..len]), 0);
            packets.push(buf[..len].to_vec());
            if i % 10 == 0 {
                let name = format!("log-{i:03}.txt");
                let data: Vec<u8> = (0..(i as usize * 37 + 5)).map(|k| (k as u8) ^ (i as u8)).collect();
                let n = FileName::new(&name).unwrap();
                fs.create(&n).unwrap();
                fs.write(&n, 0, &data).unwrap();
                want.push((name, data));
            }
        }
        assert_eq!(tm(&mut tms), packets);
        assert_eq!(files(&fs), want);
    }
    // A reset: both opened again on what the flash holds.
    let mut tms = MibFlashStore::open(&flash, mib::memory::TM_STORE.offset).unwrap();
    let fs = FlashStore::open(Shared(&flash), region).unwrap();
    assert_eq!(tm(&mut tms), packets, "the TM store after a reset");
    assert_eq!(files(&fs), want, "the files after a reset");
    assert_eq!(fs.counters().bad_entries, 0);
}
