//! The transaction sequence number the flash file store keeps (`mmic_cfdp::seq`): kept
//! across a reopen and across the directory's page migrations, and a power cut at any
//! write or erase while it is stored leaves the number before or the new one, with every
//! file as it was.

mod common;

use std::collections::BTreeMap;

use common::{Nor, SECTOR};
use mmic_cfdp::flash::FlashStore;
use mmic_cfdp::seq::KeepSeq;
use mmic_cfdp::store::{FlatStore, MemStore};
use mmic_cfdp::FileName;

/// A small region: 4 directory sectors and 8 data sectors.
const REGION: std::ops::Range<u32> = 0x2000..0x2000 + 12 * SECTOR as u32;

fn files(s: &impl FlatStore) -> BTreeMap<String, Vec<u8>> {
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

/// A store holding two files (one small, one of its own sectors).
fn with_files() -> (Nor, FlashStore<Nor>) {
    let nor = Nor::with(vec![0xFF; REGION.end as usize]);
    let s = FlashStore::open(nor.clone(), REGION).unwrap();
    for (name, len) in [("plan.txt", 300usize), ("table.bin", 6000)] {
        let n = FileName::new(name).unwrap();
        s.create(&n).unwrap();
        let data: Vec<u8> = (0..len).map(|i| (i * 7 + len) as u8).collect();
        s.write(&n, 0, &data).unwrap();
    }
    (nor, s)
}

// verifies: FILE-STORE-10
#[test]
fn the_sequence_number_is_kept_across_reopens_and_directory_migrations_beside_the_files() {
    let (nor, s) = with_files();
    let want = files(&s);
    assert_eq!(KeepSeq::kept_seq(&s), None, "a new store keeps no number");
    s.keep_seq(7).unwrap();
    drop(s);
    let s = FlashStore::open(nor.clone(), REGION).unwrap();
    assert_eq!(KeepSeq::kept_seq(&s), Some(7));
    assert_eq!(files(&s), want);
    // Enough numbers to take the directory round all its pages several times.
    for seq in 8..3000u16 {
        s.keep_seq(seq).unwrap();
    }
    let erases = s.counters().dir_erases;
    assert!(erases >= 4, "the directory pages were migrated: {erases} erases");
    drop(s);
    let s = FlashStore::open(nor, REGION).unwrap();
    assert_eq!(KeepSeq::kept_seq(&s), Some(2999));
    assert_eq!(files(&s), want, "the files outlive the numbers");
    assert_eq!(s.counters().bad_entries, 0);
    // The number wraps like the entity's.
    s.keep_seq(u16::MAX).unwrap();
    s.keep_seq(0).unwrap();
    assert_eq!(KeepSeq::kept_seq(&s), Some(0));

    // A RAM store keeps nothing across a reset (its files neither).
    let m: MemStore<2, 64> = MemStore::new(128);
    m.keep_seq(5).unwrap();
    assert_eq!(m.kept_seq(), None);
}

// verifies: FILE-STORE-10
#[test]
fn a_power_cut_while_the_number_is_stored_leaves_the_old_or_the_new_and_every_file() {
    let (nor, s) = with_files();
    let want = files(&s);
    // Close to the directory's first migration.
    for seq in 1..=1200u16 {
        s.keep_seq(seq).unwrap();
    }
    drop(s);
    let mut image = nor.image();
    let (mut cuts, mut migrations) = (0, 0);
    // Each store of the next number from the last image, cut at its first, second, ...
    // write or erase until it completes; past a directory migration or two.
    for seq in 1201..2400u16 {
        for cut in 0.. {
            let chip = Nor::with(image.clone());
            let t = FlashStore::open(chip.clone(), REGION).unwrap();
            chip.cut_after(cut);
            let r = t.keep_seq(seq);
            let erases = t.counters().dir_erases;
            drop(t);
            if !chip.dead() {
                r.unwrap();
                migrations += erases;
                image = chip.image();
                break;
            }
            cuts += 1;
            let what = format!("cut {cut} storing {seq}");
            chip.power_on();
            let t = FlashStore::open(chip, REGION).unwrap_or_else(|e| panic!("{what}: reopen {e:?}"));
            let kept = KeepSeq::kept_seq(&t);
            assert!(kept == Some(seq - 1) || kept == Some(seq), "{what}: kept {kept:?}");
            assert_eq!(files(&t), want, "{what}");
            assert_eq!(t.counters().bad_entries, 0, "{what}");
            // The store goes on: the number again.
            t.keep_seq(seq).unwrap_or_else(|e| panic!("{what}: again {e:?}"));
            assert_eq!(KeepSeq::kept_seq(&t), Some(seq), "{what}");
        }
    }
    let s = FlashStore::open(Nor::with(image), REGION).unwrap();
    assert_eq!(KeepSeq::kept_seq(&s), Some(2399));
    assert_eq!(files(&s), want);
    assert!(
        migrations >= 2,
        "the sweep crossed directory migrations: {migrations} erases"
    );
    eprintln!("power cut at each of {cuts} writes and erases of a number's store ({migrations} page erases)");
}
