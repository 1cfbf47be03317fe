//! The flash file store (`mmic_cfdp::flash`) on a model of the board's NOR flash that can
//! lose power at any write or erase: every FlatStore operation, persistence, limits, and
//! the power-cut sweep.

mod common;

use std::collections::BTreeMap;

use common::{Nor, SECTOR};
use mmic_cfdp::flash::{FlashStore, OpenError, BLOCK, DIR_SECTORS, RESERVE_SECTORS};
use mmic_cfdp::store::{Checked, FlatStore, StoreError};
use mmic_cfdp::FileName;

fn n(s: &str) -> FileName {
    FileName::new(s).unwrap()
}

fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(seed | 1).wrapping_add(seed) ^ (i >> 9) as u8)
        .collect()
}

/// Every file's name and bytes.
fn snapshot(s: &impl FlatStore) -> BTreeMap<String, Vec<u8>> {
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

/// The board's layout: the partition at its offset in a flash that ends there (less the
/// 3.75 MiB before it, which the test does not need).
const BASE: u32 = mib::memory::FILE_STORE.offset - 0x3C_0000;
const BOARD: u32 = mib::cfdp::BOARD_STORE_BYTES;

fn board() -> (Nor, std::ops::Range<u32>) {
    (Nor::new((BASE + BOARD) as usize), BASE..BASE + BOARD)
}

// verifies: FILE-STORE-04
#[test]
fn every_store_operation_works_and_the_files_survive_a_reopen() {
    let (nor, region) = board();
    let s = FlashStore::open(nor.clone(), region.clone()).unwrap();
    let data_sectors = BOARD as usize / SECTOR - DIR_SECTORS;
    assert_eq!(
        s.free().unwrap(),
        ((data_sectors - RESERVE_SECTORS) * SECTOR - BLOCK) as u64
    );
    assert_eq!(s.len(&n("a.bin")).unwrap(), None);
    assert_eq!(s.write(&n("a.bin"), 0, b"x"), Err(StoreError::NotFound));
    s.create(&n("a.bin")).unwrap();
    assert_eq!(s.len(&n("a.bin")).unwrap(), Some(0));
    let a = pattern(10_000, 3);
    s.write(&n("a.bin"), 0, &a).unwrap();
    assert_eq!(s.len(&n("a.bin")).unwrap(), Some(10_000));
    let mut buf = vec![0; 300];
    s.read(&n("a.bin"), 4090, &mut buf).unwrap();
    assert_eq!(buf, a[4090..4390], "a read across a sector boundary at an odd offset");
    assert_eq!(
        s.read(&n("a.bin"), 9_800, &mut buf),
        Err(StoreError::NotFound),
        "past the end"
    );
    // Bytes changed in the middle (copy on write) and appended at an odd offset.
    s.write(&n("a.bin"), 4093, b"CHANGED").unwrap();
    s.write(&n("a.bin"), 10_000, b"tail!").unwrap();
    let mut want = a.clone();
    want[4093..4100].copy_from_slice(b"CHANGED");
    want.extend_from_slice(b"tail!");
    s.create(&n("b.txt")).unwrap();
    s.write(&n("b.txt"), 0, b"bravo").unwrap();
    assert_eq!(s.rename(&n("b.txt"), &n("a.bin")), Err(StoreError::Exists));
    assert_eq!(s.rename(&n("zz"), &n("y")), Err(StoreError::NotFound));
    s.rename(&n("b.txt"), &n("0-first.txt")).unwrap();
    s.create(&n("gone")).unwrap();
    s.write(&n("gone"), 0, &pattern(5000, 1)).unwrap();
    s.remove(&n("gone")).unwrap();
    assert_eq!(s.remove(&n("gone")), Err(StoreError::NotFound));
    let snap = snapshot(&s);
    assert_eq!(snap.keys().collect::<Vec<_>>(), ["0-first.txt", "a.bin"], "name order");
    assert_eq!(snap["a.bin"], want);
    assert_eq!(snap["0-first.txt"], b"bravo");
    // Sector granularity: a.bin holds 3 sectors, 0-first.txt one.
    assert_eq!(
        s.free().unwrap(),
        ((data_sectors - RESERVE_SECTORS - 4) * SECTOR - BLOCK) as u64
    );
    let free = s.free().unwrap();
    drop(s);
    let s = FlashStore::open(nor.clone(), region.clone()).unwrap();
    assert_eq!(snapshot(&s), snap, "the same files after a reopen");
    assert_eq!(s.free().unwrap(), free);
    // Truncation keeps the name, frees the sectors.
    s.create(&n("a.bin")).unwrap();
    assert_eq!(s.len(&n("a.bin")).unwrap(), Some(0));
    assert_eq!(s.free().unwrap(), free + 3 * SECTOR as u64);
    drop(s);
    let s = FlashStore::open(nor, region).unwrap();
    assert_eq!(s.len(&n("a.bin")).unwrap(), Some(0));
    assert_eq!(s.counters().bad_entries, 0);
}

// verifies: FILE-STORE-05
#[test]
fn segments_written_out_of_order_and_again_give_the_file_and_cost_nothing_the_second_time() {
    let (nor, region) = board();
    let s = FlashStore::open(nor.clone(), region.clone()).unwrap();
    let f = n("partial-0-1");
    s.create(&f).unwrap();
    let file = pattern(20_000, 7);
    let seg = 946;
    let order: Vec<usize> = (0..file.len().div_ceil(seg))
        .rev()
        .step_by(2)
        .chain((0..file.len().div_ceil(seg)).step_by(2))
        .collect();
    for &k in &order {
        let (a, z) = (k * seg, ((k + 1) * seg).min(file.len()));
        s.write(&f, a as u64, &file[a..z]).unwrap();
    }
    // Every segment again, same bytes: no flash write, no copy.
    let before = (nor.ops(), s.counters());
    for k in 0..file.len().div_ceil(seg) {
        let (a, z) = (k * seg, ((k + 1) * seg).min(file.len()));
        s.write(&f, a as u64, &file[a..z]).unwrap();
    }
    assert_eq!(nor.ops(), before.0, "a repeated segment writes nothing");
    assert_eq!(s.counters().copies, before.1.copies);
    let mut got = vec![0; file.len()];
    s.read(&f, 0, &mut got).unwrap();
    assert!(got == file);
    drop(s);
    let s = FlashStore::open(nor, region).unwrap();
    let mut got = vec![0; file.len()];
    s.read(&f, 0, &mut got).unwrap();
    assert!(got == file, "after a reopen");
}

/// Writes the 946-byte segments `order` of `file` into `f`; returns the copies
/// (`FlashCounters::copies`) each write made.
fn receive(s: &FlashStore<Nor>, f: &FileName, file: &[u8], order: &[usize]) -> Vec<u32> {
    let seg = mib::cfdp::MAX_SEGMENT_LEN;
    order
        .iter()
        .map(|&k| {
            let (a, z) = (k * seg, ((k + 1) * seg).min(file.len()));
            let before = s.counters().copies;
            s.write(f, a as u64, &file[a..z]).unwrap();
            s.counters().copies - before
        })
        .collect()
}

// The one copy a lossy transfer's staging file can make, and when it makes none. The store
// learns a file's length only from its writes: a staging file whose first segment to
// arrive is the file's first (946 bytes: within a block) starts as a small file in a block
// of a shared sector, and the next segment that takes it past the block moves it to a
// sector of its own: one block copy (1 KiB, no erase). Every other write of the transfer
// (gaps filled, segments ahead of a gap, duplicates) is in place. A staging file whose
// first segment to arrive ends past a block never was small: no copy at all. (The order
// begins as `flash_transfer.rs`' seed 11 does: segments 0 to 7 with 5 and 7 twice, 9 (twice)
// ahead of the gap at 8, 14 ahead of 13, 21 (twice) ahead of 18 to 20; then the gaps, the
// rest, and every segment again.)
// verifies: FILE-STORE-05
#[test]
fn a_staging_file_that_begins_in_a_block_is_copied_once_out_of_it_and_one_that_begins_larger_never() {
    let (nor, region) = board();
    let s = FlashStore::open(nor.clone(), region.clone()).unwrap();
    let file = pattern(30_000, 11);
    let segments = file.len().div_ceil(mib::cfdp::MAX_SEGMENT_LEN);
    const { assert!(mib::cfdp::MAX_SEGMENT_LEN <= BLOCK && 2 * mib::cfdp::MAX_SEGMENT_LEN > BLOCK) };
    let ahead = [
        0, 1, 2, 3, 4, 5, 5, 6, 7, 7, 9, 9, 10, 11, 12, 14, 15, 16, 17, 21, 21, 22, 23, 24,
    ];
    let gaps = [13, 8, 20, 18, 19];
    let rest = 25..segments;
    let again = 0..segments;
    let order: Vec<usize> = ahead.into_iter().chain(gaps).chain(rest).chain(again).collect();

    let f = n("partial-0-11");
    s.create(&f).unwrap();
    let copies = receive(&s, &f, &file, &order);
    assert_eq!(
        copies[..2],
        [0, 1],
        "segment 0 in a block, segment 1 moves the file out of it"
    );
    assert!(
        copies[2..].iter().all(|&c| c == 0),
        "every other write in place: {copies:?}"
    );

    // The same segments into a staging file whose first one to arrive is segment 3.
    let g = n("partial-0-3");
    s.create(&g).unwrap();
    let first = order.iter().position(|&k| k == 3).unwrap();
    let order: Vec<usize> = order[first..].iter().chain(&order[..first]).copied().collect();
    let copies = receive(&s, &g, &file, &order);
    assert!(copies.iter().all(|&c| c == 0), "no copy: {copies:?}");

    let c = s.counters();
    assert_eq!((c.copies, c.erases), (1, 0), "{c:?}");
    drop(s);
    let s = FlashStore::open(nor, region).unwrap();
    for name in ["partial-0-11", "partial-0-3"] {
        assert!(snapshot(&s)[name] == file, "{name} byte-exact after a reopen");
    }
}

// verifies: FILE-STORE-06
#[test]
fn free_space_is_what_a_file_can_still_take_and_the_full_store_refuses_more() {
    let (nor, region) = board();
    let s = Checked::new(FlashStore::open(nor, region).unwrap());
    s.create(&n("small")).unwrap();
    s.write(&n("small"), 0, b"123").unwrap();
    let free = s.free().unwrap();
    s.create(&n("big")).unwrap();
    let big = pattern(free as usize, 9);
    s.write(&n("big"), 0, &big).unwrap();
    assert_eq!(s.free().unwrap(), 0);
    assert_eq!(s.write(&n("big"), free, b"x"), Err(StoreError::Full));
    s.create(&n("more")).unwrap();
    assert_eq!(s.write(&n("more"), 0, b"x"), Err(StoreError::Full));
    // A full store still takes changed bytes (the reserve) and keeps its files whole.
    s.write(&n("big"), 5000, b"changed in a full store").unwrap();
    let mut got = vec![0; 23];
    s.read(&n("big"), 5000, &mut got).unwrap();
    assert_eq!(got, b"changed in a full store");
    s.remove(&n("big")).unwrap();
    assert_eq!(s.free().unwrap(), free, "removing gives the space back");
    assert!(s.counters().full >= 2);
}

// verifies: FILE-STORE-06
#[test]
fn sixty_four_files_are_held_and_a_sixty_fifth_is_refused() {
    let (nor, region) = board();
    let s = Checked::new(FlashStore::open(nor.clone(), region.clone()).unwrap());
    let free = s.free().unwrap();
    // Files of up to a block share sectors, four to a sector.
    for k in 0..64 {
        let f = n(&format!("table-{k:02}.bin"));
        s.create(&f).unwrap();
        s.write(&f, 0, &pattern(1000, k as u8)).unwrap();
    }
    assert_eq!(s.create(&n("one-more")), Err(StoreError::Full));
    assert_eq!(s.count_files().unwrap(), 64);
    assert_eq!(
        s.free().unwrap(),
        free - 16 * SECTOR as u64,
        "64 small files in 16 sectors"
    );
    drop(s);
    let s = FlashStore::open(nor, region).unwrap();
    let snap = snapshot(&s);
    assert_eq!(snap.len(), 64);
    for k in 0..64 {
        assert_eq!(
            snap[&format!("table-{k:02}.bin")],
            pattern(1000, k as u8),
            "after a reopen"
        );
    }
    assert_eq!(s.counters().bad_entries, 0);
}

// verifies: FILE-STORE-06
#[test]
fn a_small_file_shares_a_sector_until_it_outgrows_its_block() {
    let (nor, region) = board();
    let s = FlashStore::open(nor.clone(), region.clone()).unwrap();
    let free = s.free().unwrap();
    let (a, b) = (n("a.toml"), n("b.toml"));
    s.create(&a).unwrap();
    s.create(&b).unwrap();
    s.write(&a, 0, b"speed = 3\n").unwrap();
    s.write(&b, 0, &pattern(700, 1)).unwrap();
    assert_eq!(s.free().unwrap(), free - SECTOR as u64, "two small files, one sector");
    // Appended in place, then changed (a copy of the block), then grown past the block.
    s.write(&a, 10, b"turn = 1\n").unwrap();
    let copies = s.counters().copies;
    s.write(&a, 0, b"speed = 4").unwrap();
    assert_eq!(
        s.counters().copies,
        copies + 1,
        "a changed byte copies the block, not a sector"
    );
    let mut want = b"speed = 4\nturn = 1\n".to_vec();
    assert_eq!(snapshot(&s)["a.toml"], want);
    let tail = pattern(5000, 2);
    s.write(&a, want.len() as u64, &tail).unwrap();
    want.extend_from_slice(&tail);
    assert_eq!(
        snapshot(&s)["a.toml"],
        want,
        "grown past its block into sectors of its own"
    );
    assert_eq!(
        s.free().unwrap(),
        free - 3 * SECTOR as u64,
        "b's shared sector and a's two"
    );
    // The last small file gone, its shared sector is free again.
    s.remove(&b).unwrap();
    assert_eq!(s.free().unwrap(), free - 2 * SECTOR as u64);
    s.create(&a).unwrap();
    assert_eq!(s.free().unwrap(), free);
    drop(s);
    let s = FlashStore::open(nor, region).unwrap();
    assert_eq!(s.free().unwrap(), free);
    assert_eq!(snapshot(&s)["a.toml"], b"");
}

// verifies: FILE-STORE-04
#[test]
fn a_region_that_does_not_fit_the_layout_is_refused() {
    let nor = Nor::new(0x40000);
    assert!(matches!(
        FlashStore::open(nor.clone(), 0x1000..0x5000),
        Err(OpenError::Layout)
    ));
    assert!(matches!(
        FlashStore::open(nor.clone(), 0x1001..0x20000),
        Err(OpenError::Layout)
    ));
    assert!(matches!(
        FlashStore::open(nor.clone(), 0x1000..0x50000),
        Err(OpenError::Layout)
    ));
    assert!(FlashStore::open(nor, 0x1000..0x1000 + 12 * SECTOR as u32).is_ok());
}

/// One step of the power-cut sequence.
#[derive(Clone)]
enum Op {
    Create(&'static str),
    Write(&'static str, usize, Vec<u8>),
    Rename(&'static str, &'static str),
    Replace(&'static str, &'static str),
    Remove(&'static str),
}

impl std::fmt::Debug for Op {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Op::Create(a) => write!(f, "create {a}"),
            Op::Write(a, at, d) => write!(f, "write {a} {at}+{}", d.len()),
            Op::Rename(a, b) => write!(f, "rename {a} {b}"),
            Op::Replace(a, b) => write!(f, "replace {a} {b}"),
            Op::Remove(a) => write!(f, "remove {a}"),
        }
    }
}

fn apply(s: &impl FlatStore, op: &Op) -> Result<(), StoreError> {
    match op {
        Op::Create(a) => s.create(&n(a)),
        Op::Write(a, at, d) => s.write(&n(a), *at as u64, d),
        Op::Rename(a, b) => s.rename(&n(a), &n(b)),
        Op::Replace(a, b) => s.replace(&n(a), &n(b)),
        Op::Remove(a) => s.remove(&n(a)),
    }
}

fn sequence() -> Vec<Op> {
    let seg = |k: usize, seed: u8| {
        pattern(946, seed)
            .into_iter()
            .map(move |b| b ^ k as u8)
            .collect::<Vec<_>>()
    };
    let mut ops = vec![
        Op::Create("partial-0-1"),
        Op::Write("partial-0-1", 0, seg(0, 1)),
        Op::Write("partial-0-1", 2 * 946, seg(2, 1)),
        Op::Write("partial-0-1", 4 * 946, seg(4, 1)),
        Op::Write("partial-0-1", 946, seg(1, 1)),
        Op::Write("partial-0-1", 946, seg(1, 1)),
        Op::Write("partial-0-1", 3 * 946, seg(3, 1)),
        Op::Write("partial-0-1", 0, seg(0, 2)),
        Op::Create("plan.toml"),
        Op::Write("plan.toml", 0, pattern(5_000, 5)),
        Op::Rename("partial-0-1", "up.bin"),
        Op::Create("plan.toml"),
        Op::Write("plan.toml", 0, b"short plan".to_vec()),
        Op::Create("log.txt"),
        Op::Write("log.txt", 0, pattern(8_200, 6)),
        Op::Write("log.txt", 4_000, pattern(300, 8)),
        Op::Remove("up.bin"),
    ];
    // Enough directory stores (long names: large entries) to make the map go round its
    // pages, migrating and erasing them.
    const LONG: &str = "a-plan-with-a-name-as-long-as-names-get-48-bytes";
    for _ in 0..360 {
        ops.push(Op::Rename("plan.toml", LONG));
        ops.push(Op::Rename(LONG, "plan.toml"));
    }
    ops.extend([
        // Small files: four to a shared sector, changed (a copy of the block), grown past
        // their block, removed (the shared sector free again).
        Op::Create("s1"),
        Op::Write("s1", 0, pattern(600, 1)),
        Op::Create("s2"),
        Op::Write("s2", 0, pattern(1024, 2)),
        Op::Write("s1", 600, pattern(300, 3)),
        Op::Write("s1", 100, vec![0; 50]),
        Op::Write("s2", 1000, pattern(900, 4)),
        Op::Create("partial-0-9"),
        Op::Write("partial-0-9", 500, pattern(400, 5)),
        Op::Write("partial-0-9", 0, pattern(500, 6)),
        Op::Rename("partial-0-9", "s3"),
        // A received file replacing the file under its name (the entity's last step), big
        // over small and small over big.
        Op::Create("partial-0-10"),
        Op::Write("partial-0-10", 0, pattern(6_000, 7)),
        Op::Replace("partial-0-10", "s2"),
        Op::Create("partial-0-11"),
        Op::Write("partial-0-11", 0, pattern(700, 8)),
        Op::Replace("partial-0-11", "s2"),
        Op::Replace("s1", "s4"),
        Op::Remove("s1"),
        Op::Remove("s3"),
        Op::Remove("s2"),
        Op::Create("a"),
        Op::Write("a", 0, pattern(4_096 * 3, 2)),
        Op::Create("b"),
        Op::Write("b", 0, pattern(4_096 * 2, 3)),
        Op::Write("b", 4_000, pattern(200, 4)),
        // Bytes NOR could program in place (zeros; a gap of erased bytes) in files that are
        // not being received: copied, never written in place.
        Op::Write("b", 1_000, vec![0; 2_000]),
        Op::Create("h"),
        Op::Write("h", 5_000, pattern(100, 5)),
        Op::Write("h", 0, pattern(3_000, 6)),
        Op::Remove("log.txt"),
        Op::Write("a", 100, pattern(4_096, 9)),
    ]);
    ops
}

/// A small region (4 directory sectors, 8 data sectors): the sequence fills it and
/// reuses its sectors.
const SMALL: std::ops::Range<u32> = 0x2000..0x2000 + 12 * SECTOR as u32;

/// The same files with the same bytes (told apart by name and length when not).
fn same_files(got: &BTreeMap<String, Vec<u8>>, want: &BTreeMap<String, Vec<u8>>, what: &str) {
    let lens = |m: &BTreeMap<String, Vec<u8>>| m.iter().map(|(k, v)| (k.clone(), v.len())).collect::<Vec<_>>();
    assert_eq!(lens(got), lens(want), "{what}");
    for (k, v) in want {
        assert!(got[k] == *v, "{what}: the bytes of {k}");
    }
}

/// Every file of `now` is as in `before` or as in `after`; a file being received that
/// `op` writes may hold part of the segment (the entity removes it at start), but its
/// length and every other byte are as before or as after.
fn as_before_or_after(
    now: &BTreeMap<String, Vec<u8>>,
    before: &BTreeMap<String, Vec<u8>>,
    after: &BTreeMap<String, Vec<u8>>,
    op: &Op,
    what: &str,
) {
    let names: std::collections::BTreeSet<_> = before.keys().chain(after.keys()).chain(now.keys()).collect();
    for name in names {
        let got = now.get(name);
        if let (true, Op::Write(w, off, d), Some(g), Some(b), Some(a)) =
            (name.starts_with("partial-"), op, got, before.get(name), after.get(name))
        {
            if w == name {
                assert!(g.len() == b.len() || g.len() == a.len(), "{what}: {name} length");
                let outside = |i: &usize| *i < *off || *i >= off + d.len();
                assert!(
                    (0..g.len()).filter(outside).all(|i| g[i] == a[i]),
                    "{what}: {name} changed outside the segment"
                );
                continue;
            }
        }
        assert!(
            got == before.get(name) || got == after.get(name),
            "{what}: {name} is neither as before nor as after (len {:?})",
            got.map(Vec::len)
        );
    }
}

// The sequence runs once without a cut; before each of its operations the flash is copied,
// and the operation is run again from that copy with the power cut at its first, second, …
// write or erase until it completes. After each cut the store is opened again on what the
// flash holds, checked, and must go on: the operation again and the next one give the files
// of the run without a cut.
// verifies: FILE-STORE-07
#[test]
fn a_power_cut_at_any_write_or_erase_leaves_every_file_as_it_was_or_as_the_operation_made_it() {
    let ops = sequence();
    let nor = Nor::new(SMALL.end as usize);
    let s = FlashStore::open(nor.clone(), SMALL).unwrap();
    let mut states = vec![snapshot(&s)];
    let mut results = Vec::new();
    for op in &ops {
        results.push(apply(&s, op));
        states.push(snapshot(&s));
    }
    assert!(
        results.contains(&Err(StoreError::Full)),
        "the sequence fills the region: {results:?}"
    );
    let dir_end = SMALL.start + (DIR_SECTORS * SECTOR) as u32;
    let erased = nor.0.borrow().erased.clone();
    assert!(
        erased.iter().filter(|&&a| a < dir_end).count() >= DIR_SECTORS,
        "the directory went round its pages: {erased:x?}"
    );
    assert!(
        erased.iter().any(|&a| a >= dir_end),
        "data sectors were reused: {erased:x?}"
    );
    drop(s);

    let nor = Nor::new(SMALL.end as usize);
    let s = FlashStore::open(nor.clone(), SMALL).unwrap();
    let mut cuts = 0;
    for (i, op) in ops.iter().enumerate() {
        let image = nor.0.borrow().mem.clone();
        for cut in 0.. {
            let chip = Nor::new(0);
            chip.0.borrow_mut().mem = image.clone();
            let t = FlashStore::open(chip.clone(), SMALL).unwrap();
            chip.cut_after(cut);
            let r = apply(&t, op);
            if !chip.dead() {
                assert_eq!(r, results[i], "op {i} {op:?} from a reopened store");
                break;
            }
            cuts += 1;
            drop(t);
            chip.power_on();
            let what = format!("cut {cut} in op {i} {op:?}");
            let t = FlashStore::open(chip, SMALL).unwrap_or_else(|e| panic!("{what}: reopen {e:?}"));
            as_before_or_after(&snapshot(&t), &states[i], &states[i + 1], op, &what);
            assert_eq!(t.counters().bad_entries, 0, "{what}");
            let r = apply(&t, op);
            same_files(
                &snapshot(&t),
                &states[i + 1],
                &format!("{what}: the operation again ({r:?})"),
            );
            if let Some(next) = ops.get(i + 1) {
                let r = apply(&t, next);
                same_files(
                    &snapshot(&t),
                    &states[i + 2],
                    &format!("{what}: the next operation ({r:?})"),
                );
            }
        }
        assert_eq!(apply(&s, op), results[i]);
    }
    assert!(cuts > 2_000, "{cuts} cuts");
    eprintln!("power cut at each of {cuts} writes and erases");
}

// verifies: FILE-STORE-04
#[test]
fn the_store_takes_a_fixed_amount_of_ram() {
    let bytes = std::mem::size_of::<FlashStore<Nor>>() - std::mem::size_of::<Nor>();
    eprintln!("FlashStore RAM: {bytes} bytes besides the flash handle");
    assert!(bytes < 10 * 1024, "{bytes}");
}

// verifies: FILE-STORE-08
#[test]
fn sectors_erased_ahead_keep_erases_out_of_the_writes() {
    let (nor, region) = board();
    let s = FlashStore::open(nor.clone(), region.clone()).unwrap();
    let f = n("log.bin");
    let data = pattern(80_000, 4);
    let sectors = data.len().div_ceil(SECTOR) as u32;
    for round in 0..2 {
        // The second round's truncation gives back the sectors of the first one's file.
        s.create(&f).unwrap();
        let before = s.counters().erases;
        let mut ready = 0;
        while s.erase_ahead().unwrap() {
            ready += 1;
        }
        let erased = s.counters().erases - before;
        let all = BOARD as usize / SECTOR - DIR_SECTORS;
        // Round 0 finds every sector blank; round 1 the ones the file gave back, and the
        // shared one its first segment went to before it outgrew a block.
        assert_eq!(
            ready,
            if round == 0 { all } else { sectors as usize + 1 },
            "round {round}"
        );
        assert_eq!(
            erased,
            if round == 0 { 0 } else { sectors + 1 },
            "round {round}: only used ones erased"
        );
        let before = s.counters().erases;
        for (k, seg) in data.chunks(946).enumerate() {
            s.write(&f, (k * 946) as u64, seg).unwrap();
        }
        assert_eq!(s.counters().erases, before, "round {round}: the writes erase nothing");
        let mut got = vec![0; data.len()];
        s.read(&f, 0, &mut got).unwrap();
        assert!(got == data);
    }
    // Without erasing ahead, a write that takes a used sector erases it itself.
    drop(s);
    let s = FlashStore::open(nor, region).unwrap();
    s.create(&f).unwrap();
    for (k, seg) in data.chunks(946).enumerate() {
        s.write(&f, (k * 946) as u64, seg).unwrap();
    }
    assert!(s.counters().erases > 0);
}

// A region that holds something else (another layout, noise): opening it never panics;
// it is refused (`OpenError::Flash`) or opened with every unsound entry left out, and a
// format gives an empty store.
// verifies: FILE-STORE-04
#[test]
fn a_region_of_noise_is_refused_or_opened_clean_and_a_format_empties_it() {
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let mut refused = 0;
    for seed in 0..40u64 {
        let chip = Nor::new(SMALL.end as usize);
        {
            let mut c = chip.0.borrow_mut();
            x ^= seed;
            for (k, b) in c.mem[SMALL.start as usize..].iter_mut().enumerate() {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                // Noise in some pages, erased or zeroed words in others (page markers).
                *b = match (seed + (k / SECTOR) as u64) % 4 {
                    0 => 0xFF,
                    1 if k % SECTOR < 8 || k % SECTOR >= SECTOR - 8 => 0,
                    _ => x as u8,
                };
            }
        }
        match FlashStore::open(chip.clone(), SMALL) {
            Ok(s) => {
                // Whatever it lists, it reads back without error and takes a new file.
                let snap = snapshot(&s);
                let _ = s.create(&n("new.txt"));
                let _ = s.write(&n("new.txt"), 0, b"after noise");
                drop(snap);
            }
            Err(e) => {
                assert_eq!(e, OpenError::Flash, "seed {seed}");
                refused += 1;
            }
        }
        let mut f = chip.clone();
        FlashStore::format(&mut f, SMALL).unwrap();
        let s = FlashStore::open(chip, SMALL).unwrap();
        assert!(snapshot(&s).is_empty(), "seed {seed}");
        s.create(&n("a")).unwrap();
        s.write(&n("a"), 0, b"x").unwrap();
    }
    eprintln!("{refused} of 40 regions of noise refused, the others opened");
}

// The directory's share of one operation's work: however full the directory (63 files with
// the longest names and one being received) and however long it runs, one operation makes at most two page erases
// of the map (the docs' worst case), and a segment write at most two data-sector erases.
// verifies: FILE-STORE-08
#[test]
fn one_operation_erases_at_most_two_directory_pages_and_two_data_sectors() {
    let (nor, region) = board();
    let s = FlashStore::open(nor.clone(), region).unwrap();
    let name = |k: usize, v: usize| n(&format!("{k:02}-{v}-{}", "x".repeat(48 - 5 - v.to_string().len())));
    let (mut max_dir, mut max_data, mut max_read, mut max_written) = (0, 0, 0, 0);
    let mut step = |s: &FlashStore<Nor>, f: &mut dyn FnMut()| {
        let c = s.counters();
        let (r, w) = (nor.0.borrow().read, nor.0.borrow().written);
        f();
        let d = s.counters();
        max_dir = max_dir.max(d.dir_erases - c.dir_erases);
        max_data = max_data.max(d.erases - c.erases);
        max_read = max_read.max(nor.0.borrow().read - r);
        max_written = max_written.max(nor.0.borrow().written - w);
    };
    for k in 0..63 {
        step(&s, &mut || s.create(&name(k, 0)).unwrap());
        step(&s, &mut || s.write(&name(k, 0), 0, &pattern(900, k as u8)).unwrap());
    }
    for v in 1..40 {
        for k in 0..63 {
            step(&s, &mut || s.rename(&name(k, v - 1), &name(k, v)).unwrap());
        }
        // Segments into a file that comes and goes (the data sectors go round).
        let f = n("partial-0-1");
        step(&s, &mut || s.create(&f).unwrap());
        for seg in 0..20 {
            step(&s, &mut || s.write(&f, seg * 946, &pattern(946, v as u8)).unwrap());
        }
        step(&s, &mut || s.remove(&f).unwrap());
    }
    let c = s.counters();
    assert!(c.dir_erases > 40, "the directory went round many times: {c:?}");
    assert!(max_dir <= 2, "{max_dir} directory page erases in one operation");
    assert!(max_data <= 2, "{max_data} data sector erases in one operation");
    eprintln!(
        "most in one operation: directory page erases {max_dir}, data sector erases {max_data}, \
         bytes read {max_read}, bytes written {max_written}; {c:?}"
    );
}

/// The store's files as a model knows them: bytes never written (gaps) are `None`, what
/// the flash holds there is not promised.
type Model = BTreeMap<String, Vec<Option<u8>>>;

fn agrees(s: &FlashStore<Nor>, m: &Model, what: &str) {
    let got = snapshot(s);
    assert_eq!(
        got.iter().map(|(k, v)| (k.clone(), v.len())).collect::<Vec<_>>(),
        m.iter().map(|(k, v)| (k.clone(), v.len())).collect::<Vec<_>>(),
        "{what}: names and lengths"
    );
    for (k, v) in m {
        let g = &got[k];
        assert!(
            v.iter().zip(g).all(|(w, b)| w.is_none_or(|w| w == *b)),
            "{what}: the bytes of {k}"
        );
    }
}

#[derive(Clone, Debug)]
enum RandomOp {
    Create(usize),
    Write(usize, usize, usize, u8),
    Remove(usize),
    Rename(usize, usize),
    Replace(usize, usize),
    Reopen,
}

const NAMES: [&str; 6] = ["a", "b.bin", "partial-0-1", "c.toml", "d", "partial-0-2"];

fn random_op() -> impl proptest::strategy::Strategy<Value = RandomOp> {
    use proptest::prelude::*;
    prop_oneof![
        2 => (0..NAMES.len()).prop_map(RandomOp::Create),
        8 => (0..NAMES.len(), 0..14_000usize, 1..4_098usize, any::<u8>())
            .prop_map(|(f, at, len, seed)| RandomOp::Write(f, at, len, seed)),
        1 => (0..NAMES.len()).prop_map(RandomOp::Remove),
        1 => (0..NAMES.len(), 0..NAMES.len()).prop_map(|(a, b)| RandomOp::Rename(a, b)),
        1 => (0..NAMES.len(), 0..NAMES.len()).prop_map(|(a, b)| RandomOp::Replace(a, b)),
        1 => Just(RandomOp::Reopen),
    ]
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

    // Random operations on a small region (full often) against a model: every result is
    // the model's, a refused operation changes nothing, the files survive reopening, and
    // `free()` is honest: a write of up to one sector whose growth fits it is never refused.
    // verifies: FILE-STORE-06, FILE-STORE-04
    #[test]
    fn random_operations_agree_with_a_model_and_free_space_is_never_overstated(
        ops in proptest::collection::vec(random_op(), 1..80),
    ) {
        let nor = Nor::new(SMALL.end as usize);
        let mut s = FlashStore::open(nor.clone(), SMALL).unwrap();
        let mut m = Model::new();
        for (i, op) in ops.iter().enumerate() {
            let what = format!("op {i} {op:?}");
            match op {
                RandomOp::Create(f) => {
                    let r = s.create(&n(NAMES[*f]));
                    if m.len() < 64 || m.contains_key(NAMES[*f]) {
                        assert_eq!(r, Ok(()), "{what}");
                        m.insert(NAMES[*f].to_string(), Vec::new());
                    }
                }
                RandomOp::Write(f, at, len, seed) => {
                    let data = pattern(*len, *seed);
                    let free = s.free().unwrap();
                    let r = s.write(&n(NAMES[*f]), *at as u64, &data);
                    match m.get_mut(NAMES[*f]) {
                        None => assert_eq!(r, Err(StoreError::NotFound), "{what}"),
                        Some(v) => {
                            let grow = (at + len).saturating_sub(v.len()) as u64;
                            if grow <= free {
                                assert_eq!(r, Ok(()), "{what}: {grow} bytes more with {free} free");
                            }
                            if r.is_ok() {
                                if v.len() < at + len {
                                    v.resize(at + len, None);
                                }
                                for (k, b) in data.iter().enumerate() {
                                    v[at + k] = Some(*b);
                                }
                            } else {
                                assert_eq!(r, Err(StoreError::Full), "{what}");
                            }
                        }
                    }
                }
                RandomOp::Remove(f) => {
                    let r = s.remove(&n(NAMES[*f]));
                    let want = m.remove(NAMES[*f]).map(|_| ()).ok_or(StoreError::NotFound);
                    assert_eq!(r, want, "{what}");
                }
                RandomOp::Rename(a, b) => {
                    let r = s.rename(&n(NAMES[*a]), &n(NAMES[*b]));
                    let want = if !m.contains_key(NAMES[*a]) {
                        Err(StoreError::NotFound)
                    } else if m.contains_key(NAMES[*b]) {
                        Err(StoreError::Exists)
                    } else {
                        let v = m.remove(NAMES[*a]).unwrap();
                        m.insert(NAMES[*b].to_string(), v);
                        Ok(())
                    };
                    assert_eq!(r, want, "{what}");
                }
                RandomOp::Replace(a, b) => {
                    let r = s.replace(&n(NAMES[*a]), &n(NAMES[*b]));
                    let want = match m.remove(NAMES[*a]) {
                        None => Err(StoreError::NotFound),
                        Some(v) => {
                            m.insert(NAMES[*b].to_string(), v);
                            Ok(())
                        }
                    };
                    assert_eq!(r, want, "{what}");
                }
                RandomOp::Reopen => {
                    drop(s);
                    s = FlashStore::open(nor.clone(), SMALL).unwrap();
                    assert_eq!(s.counters().bad_entries, 0);
                }
            }
            agrees(&s, &m, &what);
        }
    }
}

fn to_op(r: &RandomOp) -> Option<Op> {
    Some(match *r {
        RandomOp::Create(f) => Op::Create(NAMES[f]),
        RandomOp::Write(f, at, len, seed) => Op::Write(NAMES[f], at, pattern(len, seed)),
        RandomOp::Remove(f) => Op::Remove(NAMES[f]),
        RandomOp::Rename(a, b) => Op::Rename(NAMES[a], NAMES[b]),
        RandomOp::Replace(a, b) => Op::Replace(NAMES[a], NAMES[b]),
        RandomOp::Reopen => return None,
    })
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

    // Random operations with the power cut at a random write or erase: at the next open
    // every file is as before the operation under way or as after it.
    // verifies: FILE-STORE-07
    #[test]
    fn a_power_cut_in_random_operations_leaves_every_file_as_before_or_after(
        ops in proptest::collection::vec(random_op(), 1..60),
        at_op in proptest::prelude::any::<proptest::sample::Index>(),
    ) {
        let ops: Vec<Op> = ops.iter().filter_map(to_op).collect();
        proptest::prop_assume!(!ops.is_empty());
        let nor = Nor::new(SMALL.end as usize);
        let s = FlashStore::open(nor.clone(), SMALL).unwrap();
        let mut states = vec![snapshot(&s)];
        for op in &ops {
            let _ = apply(&s, op);
            states.push(snapshot(&s));
        }
        proptest::prop_assume!(nor.ops() > 0);
        let cut = at_op.index(nor.ops() as usize) as u64;
        let nor = Nor::new(SMALL.end as usize);
        nor.cut_after(cut);
        let s = FlashStore::open(nor.clone(), SMALL).unwrap();
        let mut at = None;
        for (i, op) in ops.iter().enumerate() {
            let _ = apply(&s, op);
            if nor.dead() {
                at = Some(i);
                break;
            }
        }
        let at = at.expect("the cut falls in an operation");
        drop(s);
        nor.power_on();
        let what = format!("cut {cut} in op {at} {:?}", ops[at]);
        let s = FlashStore::open(nor, SMALL).unwrap_or_else(|e| panic!("{what}: {e:?}"));
        as_before_or_after(&snapshot(&s), &states[at], &states[at + 1], &ops[at], &what);
        assert_eq!(s.counters().bad_entries, 0, "{what}");
    }
}

// Each way an erase of a directory page can be cut, at every directory erase of the
// sequence: after the next open the store keeps taking directory stores for as long as
// the map goes round its pages twice.
// verifies: FILE-STORE-07
#[test]
fn a_cut_directory_erase_of_any_shape_leaves_a_store_that_keeps_working() {
    let ops = sequence();
    let nor = Nor::new(SMALL.end as usize);
    let s = FlashStore::open(nor.clone(), SMALL).unwrap();
    let dir_end = SMALL.start + (DIR_SECTORS * SECTOR) as u32;
    let mut tried = [0; 3];
    for op in &ops {
        let image = nor.0.borrow().mem.clone();
        let erases = nor.0.borrow().erased.len();
        let _ = apply(&s, op);
        // Only the operations that erase a directory page.
        if !nor.0.borrow().erased[erases..].iter().any(|&a| a < dir_end) {
            continue;
        }
        for tear in 0..3u64 {
            for cut in 0.. {
                let chip = Nor::new(0);
                chip.0.borrow_mut().mem = image.clone();
                chip.0.borrow_mut().tear = Some(tear);
                let t = FlashStore::open(chip.clone(), SMALL).unwrap();
                chip.cut_after(cut);
                let _ = apply(&t, op);
                if !chip.dead() {
                    break;
                }
                let torn = chip.0.borrow().torn_erase;
                if torn.is_none_or(|a| a >= dir_end) {
                    continue;
                }
                tried[tear as usize] += 1;
                drop(t);
                chip.power_on();
                let t = FlashStore::open(chip, SMALL).unwrap();
                let before = snapshot(&t);
                let (a, b) = (
                    n("x-renamed-back-and-forth-with-a-long-long-name"),
                    n("y-renamed-back-and-forth-with-a-long-long-name"),
                );
                t.create(&a)
                    .unwrap_or_else(|e| panic!("tear {tear}, cut {cut} in {op:?}: {e:?}"));
                for k in 0..120 {
                    let (from, to) = if k % 2 == 0 { (&a, &b) } else { (&b, &a) };
                    t.rename(from, to)
                        .unwrap_or_else(|e| panic!("tear {tear}, cut {cut} in {op:?}: rename {k}: {e:?}"));
                }
                t.remove(&a).unwrap();
                same_files(&snapshot(&t), &before, &format!("tear {tear}, cut {cut} in {op:?}"));
            }
        }
    }
    assert!(
        tried.iter().all(|&k| k > 0),
        "every shape of cut erase tried: {tried:?}"
    );
    eprintln!("cut directory erases tried (first half, second half, both ends): {tried:?}");
}

// After a reset the store does not know which free blocks of shared sectors are blank:
// a new small file reads at most two of them to find out (then takes a sector), and
// `erase_ahead` tells the others, one a call.
// verifies: FILE-STORE-08
#[test]
fn blocks_of_unknown_state_are_read_a_few_at_a_time() {
    let (nor, region) = board();
    let s = FlashStore::open(nor.clone(), region.clone()).unwrap();
    for k in 0..64 {
        let f = n(&format!("t{k:02}"));
        s.create(&f).unwrap();
        s.write(&f, 0, &pattern(600, k as u8)).unwrap();
    }
    // One file left in each of the 16 shared sectors, three blocks given up in each.
    for k in (0..64).filter(|k| k % 4 != 0) {
        s.remove(&n(&format!("t{k:02}"))).unwrap();
    }
    drop(s);
    let s = FlashStore::open(nor.clone(), region).unwrap();
    let read = nor.0.borrow().read;
    s.create(&n("new")).unwrap();
    s.write(&n("new"), 0, b"a small file").unwrap();
    let took = nor.0.borrow().read - read;
    assert!(took < 12 * 1024, "{took} bytes read to place a small file");
    let mut calls = 0;
    while s.erase_ahead().unwrap() {
        calls += 1;
        assert!(calls < 200);
    }
    // The free sectors, and the 46 blocks of unknown state left.
    assert!(calls >= 46, "{calls}");
    assert_eq!(snapshot(&s)["new"], b"a small file");
}
