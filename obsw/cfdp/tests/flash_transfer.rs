//! A CFDP transfer into board A's file store: the ground's entity (a store in RAM) and the
//! robot's (`mmic_cfdp::flash::FlashStore` on a NOR flash model) over a link that loses
//! PDUs both ways, so the robot's store takes segments out of order and twice.

use std::cell::RefCell;
use std::rc::Rc;

use embedded_storage::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use mmic_cfdp::flash::FlashStore;
use mmic_cfdp::store::{FlatStore, MemStore};
use mmic_cfdp::{Class, Entity, FileName, Parts};

const SECTOR: usize = 4096;

/// NOR rules over shared memory (the store is opened again on the same chip).
#[derive(Clone)]
struct Nor(Rc<RefCell<Vec<u8>>>);

#[derive(Debug)]
struct Refused;

impl NorFlashError for Refused {
    fn kind(&self) -> NorFlashErrorKind {
        NorFlashErrorKind::Other
    }
}

impl ErrorType for Nor {
    type Error = Refused;
}

impl ReadNorFlash for Nor {
    const READ_SIZE: usize = 4;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Refused> {
        let m = self.0.borrow();
        let o = offset as usize;
        if !o.is_multiple_of(4) || !bytes.len().is_multiple_of(4) || o + bytes.len() > m.len() {
            return Err(Refused);
        }
        bytes.copy_from_slice(&m[o..o + bytes.len()]);
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.0.borrow().len()
    }
}

impl NorFlash for Nor {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = SECTOR;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Refused> {
        let (f, t) = (from as usize, to as usize);
        let mut m = self.0.borrow_mut();
        if !f.is_multiple_of(SECTOR) || !t.is_multiple_of(SECTOR) || t < f || t > m.len() {
            return Err(Refused);
        }
        m[f..t].fill(0xFF);
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Refused> {
        let mut m = self.0.borrow_mut();
        let o = offset as usize;
        if !o.is_multiple_of(4) || !bytes.len().is_multiple_of(4) || o + bytes.len() > m.len() {
            return Err(Refused);
        }
        if m[o..o + bytes.len()].iter().zip(bytes).any(|(m, b)| b & !m != 0) {
            return Err(Refused);
        }
        m[o..o + bytes.len()].copy_from_slice(bytes);
        Ok(())
    }
}

impl MultiwriteNorFlash for Nor {}

type Ground = MemStore<4, 200_000>;

const REGION: std::ops::Range<u32> = 0x1_0000..0x1_0000 + mib::cfdp::BOARD_STORE_BYTES;

struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Moves PDUs both ways, `loss` of them lost and a quarter of that duplicated on each
/// way, until both entities are idle; returns the clock.
fn run(g: &mut Entity<Ground>, r: &mut Entity<FlashStore<Nor>>, loss: f64, seed: u64, start: u64) -> u64 {
    let mut rng = Rng(seed);
    let mut now = start;
    while now < start + 600_000 {
        now += 10;
        g.poll(now);
        r.poll(now);
        for _ in 0..64 {
            let mut moved = false;
            while let Some(p) = g.pop() {
                moved = true;
                if rng.unit() >= loss {
                    r.receive(now, &p);
                    if rng.unit() < loss / 4.0 {
                        r.receive(now, &p);
                    }
                }
            }
            while let Some(p) = r.pop() {
                moved = true;
                if rng.unit() >= loss {
                    g.receive(now, &p);
                    if rng.unit() < loss / 4.0 {
                        g.receive(now, &p);
                    }
                }
            }
            if !moved {
                break;
            }
        }
        if g.idle() && r.idle() {
            return now;
        }
    }
    panic!("not idle: {:?} {:?}", g.counters(), r.counters());
}

fn file(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(29).wrapping_add(seed) ^ (i >> 10) as u8)
        .collect()
}

fn read_all(s: &impl FlatStore, name: &str) -> Option<Vec<u8>> {
    let n = FileName::new(name).unwrap();
    let len = s.len(&n).unwrap()? as usize;
    let mut v = vec![0; len];
    s.read(&n, 0, &mut v).unwrap();
    Some(v)
}

// verifies: FILE-STORE-05, FILE-STORE-04
#[test]
fn a_class_2_put_through_a_lossy_link_lands_byte_exact_in_the_flash_store_and_stays_after_a_reopen() {
    std::thread::Builder::new()
        .stack_size(32 << 20)
        .spawn(|| {
            let nor = Nor(Rc::new(RefCell::new(vec![0xFF; REGION.end as usize])));
            let up = file(150_000, 5);
            let mut now = 0;
            {
                let gp = Parts::new(Ground::new(1 << 20));
                let rp = Parts::new(FlashStore::open(nor.clone(), REGION).unwrap());
                let mut g = Entity::new(0, 1, &gp);
                let mut r = Entity::new(1, 0, &rp);
                let n = FileName::new("plan.bin").unwrap();
                gp.store.create(&n).unwrap();
                gp.store.write(&n, 0, &up).unwrap();
                g.put(now, "plan.bin", "plan.bin", Class::Two).unwrap();
                now = run(&mut g, &mut r, 0.2, 3, now);
                let f = g.take_finished().expect("the put ended");
                assert!(f.complete, "{f:?} {:?} {:?}", g.counters(), r.counters());
                assert!(read_all(rp.store.inner(), "plan.bin") == Some(up.clone()), "byte-exact");
                let c = rp.store.inner().counters();
                eprintln!("150 000 bytes through 20 % loss: {c:?} {:?}", r.counters());
                // Gaps filled in place in the staging file, duplicates written not at all:
                // no sector copied, nothing erased on a blank region.
                assert_eq!((c.copies, c.erases), (0, 0), "{c:?}");
                assert!(c.same > 0, "duplicated segments: {c:?}");
                assert_eq!(rp.store.counters(), Default::default(), "nothing refused");
            }
            // A reset: the robot opens its store again.
            let rp = Parts::new(FlashStore::open(nor.clone(), REGION).unwrap());
            assert!(
                read_all(rp.store.inner(), "plan.bin") == Some(up.clone()),
                "after a reopen"
            );
            let mut r = Entity::new(1, 0, &rp);
            assert_eq!(r.discard_partial(), 0, "no staging file left");
            // And the file goes down again from the reopened store, byte-exact.
            let gp = Parts::new(Ground::new(1 << 20));
            let mut g = Entity::new(0, 1, &gp);
            g.get(now + 10, "plan.bin", "back.bin", Class::Two).unwrap();
            run(&mut g, &mut r, 0.2, 4, now + 10);
            assert!(read_all(gp.store.inner(), "back.bin") == Some(up), "the get");
        })
        .unwrap()
        .join()
        .unwrap();
}
