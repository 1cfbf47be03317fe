//! The file checksum spread over control periods: no period of the robot's entity reads
//! more of a file than `CHECKSUM_BYTES_PER_POLL` for a checksum (beside the file data it
//! sends), in both directions and both classes, and a file that does not match its sum
//! still fails its transfer.

mod common;

use common::Rng;
use std::cell::Cell;

use mib::cfdp as m;
use mmic_cfdp::spacepackets::cfdp::pdu::FileDirectiveType;
use mmic_cfdp::spacepackets::cfdp::ConditionCode;
use mmic_cfdp::store::{FlatStore, MemStore, StoreError};
use mmic_cfdp::{Class, Entity, FileName, Parts};

type Mem = MemStore<8, 120_000>;

/// A store that counts the bytes read from it and can flip a byte written at one offset
/// (a fault of the medium: the file is not what was received).
struct Counting {
    mem: Mem,
    read: Cell<u64>,
    flip_at: Cell<Option<u64>>,
}

impl Counting {
    fn new() -> Self {
        Counting {
            mem: Mem::new(2_000_000),
            read: Cell::new(0),
            flip_at: Cell::new(None),
        }
    }
}

impl FlatStore for Counting {
    fn len(&self, n: &FileName) -> Result<Option<u64>, StoreError> {
        self.mem.len(n)
    }
    fn create(&self, n: &FileName) -> Result<(), StoreError> {
        self.mem.create(n)
    }
    fn read(&self, n: &FileName, offset: u64, buf: &mut [u8]) -> Result<(), StoreError> {
        self.read.set(self.read.get() + buf.len() as u64);
        self.mem.read(n, offset, buf)
    }
    fn write(&self, n: &FileName, offset: u64, data: &[u8]) -> Result<(), StoreError> {
        let mut d = data.to_vec();
        if let Some(at) = self.flip_at.get() {
            if (offset..offset + d.len() as u64).contains(&at) && n.as_str().starts_with(m::PARTIAL_PREFIX) {
                d[(at - offset) as usize] ^= 0x40;
            }
        }
        self.mem.write(n, offset, &d)
    }
    fn remove(&self, n: &FileName) -> Result<(), StoreError> {
        self.mem.remove(n)
    }
    fn rename(&self, from: &FileName, to: &FileName) -> Result<(), StoreError> {
        self.mem.rename(from, to)
    }
    fn list(&self, f: &mut dyn FnMut(&FileName, u64)) -> Result<(), StoreError> {
        self.mem.list(f)
    }
    fn free(&self) -> Result<u64, StoreError> {
        self.mem.free()
    }
}

fn big_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new()
        .stack_size(64 << 20)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap();
}

/// The most a robot's control period may read: the checksum's budget, the file data it
/// sends (new and again), and one segment compared before it is written over a summed part.
const PERIOD_READ_BOUND: u64 = (m::CHECKSUM_BYTES_PER_POLL + (m::SEGMENTS_PER_POLL + 1) * m::MAX_SEGMENT_LEN) as u64;

/// Moves PDUs both ways, 10 ms a period, until both entities are idle; the downlink (robot
/// to ground) loses `loss` of its PDUs. `each` runs at the start of every period. Returns
/// the most bytes the robot's store gave in one period (its poll and the PDUs it took).
fn run(g: &mut Entity<Mem>, r: &mut Entity<Counting>, now: &mut u64, loss: f64, mut each: impl FnMut(u64)) -> u64 {
    let mut rng = Rng(7);
    let mut worst = 0;
    let end = *now + 300_000;
    while *now < end {
        *now += 10;
        each(*now);
        let before = r.store().inner().read.get();
        g.poll(*now);
        r.poll(*now);
        for _ in 0..64 {
            let mut moved = false;
            while let Some(p) = g.pop() {
                moved = true;
                r.receive(*now, &p);
            }
            while let Some(p) = r.pop() {
                moved = true;
                if rng.unit() >= loss {
                    g.receive(*now, &p);
                }
            }
            if !moved {
                break;
            }
        }
        worst = worst.max(r.store().inner().read.get() - before);
        if g.idle() && r.idle() {
            return worst;
        }
    }
    panic!("not idle: g {:?} r {:?}", g.counters(), r.counters());
}

fn file(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(29).wrapping_add(seed) ^ (i >> 9) as u8)
        .collect()
}

fn write<S: FlatStore>(p: &Parts<S>, name: &str, data: &[u8]) {
    let n = FileName::new(name).unwrap();
    p.store.create(&n).unwrap();
    p.store.write(&n, 0, data).unwrap();
}

fn read<S: FlatStore>(p: &Parts<S>, name: &str) -> Option<Vec<u8>> {
    let n = FileName::new(name).unwrap();
    let len = p.store.len(&n).unwrap()? as usize;
    let mut v = vec![0; len];
    p.store.read(&n, 0, &mut v).unwrap();
    Some(v)
}

// verifies: FILE-CFDP-08
#[test]
fn no_robot_period_sums_more_than_its_budget_and_large_files_arrive_whole_both_ways() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(4_000_000)), Parts::new(Counting::new()));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let mut now = 0;
        // Far above the one-period sum the board could afford (17 KiB).
        let up = file(110_000, 1);
        write(&gp, "up.bin", &up);
        let down = file(105_001, 2);
        write(&rp, "down.bin", &down);
        for class in [Class::One, Class::Two] {
            let name = format!("up-{class:?}.bin");
            g.put(now, "up.bin", &name, class).unwrap();
            let worst = run(&mut g, &mut r, &mut now, 0.0, |_| {});
            assert!(read(&rp, &name).as_deref() == Some(&up[..]), "{class:?} up");
            assert!(worst <= PERIOD_READ_BOUND, "{class:?} up: {worst} bytes in a period");
            let name = format!("down-{class:?}.bin");
            g.get(now, "down.bin", &name, class).unwrap();
            let worst = run(&mut g, &mut r, &mut now, 0.0, |_| {});
            assert!(read(&gp, &name).as_deref() == Some(&down[..]), "{class:?} down");
            assert!(worst <= PERIOD_READ_BOUND, "{class:?} down: {worst} bytes in a period");
        }
        // Class 2 through a lossy downlink: the robot's sum waits for the segments sent
        // again, and the ground's receiver for the segment that completes the file.
        g.get(now, "down.bin", "lossy.bin", Class::Two).unwrap();
        let worst = run(&mut g, &mut r, &mut now, 0.2, |_| {});
        assert!(read(&gp, "lossy.bin").as_deref() == Some(&down[..]), "lossy down");
        assert!(worst <= PERIOD_READ_BOUND, "lossy down: {worst} bytes in a period");
        // No sum was computed whole in one call, on either side.
        assert_eq!(rp.store.counters().whole_sums, 0);
        assert_eq!(gp.store.counters().whole_sums, 0);
        assert_eq!(g.counters().failed + r.counters().failed, 0);
        assert_eq!(r.counters().handler_errors, 0);
    });
}

// verifies: FILE-CFDP-02, FILE-CFDP-08
#[test]
fn a_received_file_unlike_its_senders_fails_its_checksum_and_is_not_kept_in_either_class() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(4_000_000)), Parts::new(Counting::new()));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let mut now = 0;
        let up = file(60_000, 3);
        write(&gp, "up.bin", &up);
        rp.store.inner().flip_at.set(Some(41_234));
        let mut last = rp.store.counters().whole_sums;
        for class in [Class::One, Class::Two] {
            let name = format!("bad-{class:?}.bin");
            g.put(now, "up.bin", &name, class).unwrap();
            // Class 1 checks again on its check timer before it gives up.
            let _ = run(&mut g, &mut r, &mut now, 0.0, |_| {});
            let got: Vec<_> = std::iter::from_fn(|| r.take_finished()).collect();
            // Class 2 declares the checksum failure; class 1 checks again until its check
            // limit (727.0-B-5 § 4.6.3.2: the data may still be on its way).
            let fault = match class {
                Class::One => ConditionCode::CheckLimitReached,
                Class::Two => ConditionCode::FileChecksumFailure,
            };
            assert!(
                got.iter().any(|f| !f.sent && !f.complete && f.condition == fault),
                "{class:?}: {got:?}"
            );
            assert!(read(&rp, &name).is_none(), "{class:?}: kept under its name");
            let sent: Vec<_> = std::iter::from_fn(|| g.take_finished()).collect();
            assert!(sent.iter().all(|f| !f.complete), "{class:?}: {sent:?}");
            // The check limit's sums again took the paced sum (the file did not change).
            assert_eq!(rp.store.counters().whole_sums, last, "{class:?}");
            last = rp.store.counters().whole_sums;
        }
    });
}

// verifies: FILE-CFDP-08
#[test]
fn a_file_changed_while_it_is_sent_is_summed_again_so_the_eof_matches_what_was_sent() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(4_000_000)), Parts::new(Counting::new()));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let mut now = 0;
        let mut data = file(100_000, 4);
        write(&rp, "tm.bin", &data);
        g.get(now, "tm.bin", "tm.bin", Class::Two).unwrap();
        // A few periods in, the sum is ahead of the file data: a part summed, not yet sent,
        // changes (the robot's own writer appending to a log it rewrites).
        let start = now;
        let patch = [0xA5u8; 500];
        let rs = &rp.store;
        let _ = run(&mut g, &mut r, &mut now, 0.0, |t| {
            if t == start + 60 {
                let n = FileName::new("tm.bin").unwrap();
                rs.write(&n, 30_000, &patch).unwrap();
            }
        });
        data[30_000..30_500].copy_from_slice(&patch);
        assert!(read(&gp, "tm.bin").as_deref() == Some(&data[..]));
        let f = g.take_finished().expect("the ground's finished");
        assert!(f.complete, "{f:?}");
        assert_eq!(r.counters().failed, 0);
    });
}

/// The directive code of a PDU (for the class 1 duplicate-EOF check below).
fn directive(p: &[u8]) -> Option<u8> {
    let (h, hl) = mmic_cfdp::spacepackets::cfdp::pdu::PduHeader::from_bytes(p).ok()?;
    (h.pdu_type() == mmic_cfdp::spacepackets::cfdp::PduType::FileDirective).then(|| p[hl])
}

// verifies: FILE-CFDP-08
#[test]
fn a_class_1_eof_waits_for_its_sum_and_its_repeat_is_dropped() {
    big_stack(|| {
        let (gp, rp) = (Parts::new(Mem::new(4_000_000)), Parts::new(Counting::new()));
        let mut g = Entity::new(0, 1, &gp);
        let mut r = Entity::new(1, 0, &rp);
        let now = 10;
        let up = file(50_000, 5);
        write(&gp, "up.bin", &up);
        g.put(now, "up.bin", "up.bin", Class::One).unwrap();
        let mut eof = None;
        let mut t = now;
        // Up to the EOF: every PDU taken at once.
        while eof.is_none() {
            t += 10;
            g.poll(t);
            while let Some(p) = g.pop() {
                if directive(&p) == Some(FileDirectiveType::EofPdu as u8) {
                    eof = Some(p.clone());
                }
                r.receive(t, &p);
            }
            r.poll(t);
            assert!(t < 60_000);
        }
        let eof = eof.unwrap();
        // Held while summed: nothing finished yet; its copy dropped as a duplicate.
        let stray = r.counters().stray;
        r.receive(t, &eof);
        assert_eq!(r.counters().stray, stray + 1);
        assert!(r.take_finished().is_none());
        let polls = 50_000usize.div_ceil(m::CHECKSUM_BYTES_PER_POLL);
        for k in 1..=polls {
            t += 10;
            r.poll(t);
            if k < polls - 1 {
                assert!(r.take_finished().is_none(), "finished after {k} polls");
            }
        }
        let f = r.take_finished().expect("finished once summed");
        assert!(f.complete && f.retained, "{f:?}");
        assert!(read(&rp, "up.bin").as_deref() == Some(&up[..]));
        assert_eq!(rp.store.counters().whole_sums, 0);
    });
}
