//! Untrusted PDUs: random bytes and real PDUs with random damage never panic the entity
//! (cfdp-rs indexes into PDUs; the gate parses them whole first) and never change the
//! store unless they are whole, addressed and in a transaction.

use mmic_cfdp::store::MemStore;
use mmic_cfdp::{Class, Entity, FileName, Parts};
use proptest::prelude::*;

type Mem = MemStore<4, 8192>;

/// Real PDUs of a class 2 put and a get: metadata, file data, EOF, NAK, ACK, Finished,
/// proxy put and listing requests.
fn real_pdus() -> Vec<Vec<u8>> {
    let (gp, rp) = (Parts::new(Mem::new(30_000)), Parts::new(Mem::new(30_000)));
    let mut g = Entity::new(0, 1, &gp);
    let mut r = Entity::new(1, 0, &rp);
    for (p, n) in [(&gp, "a.bin"), (&rp, "b.bin")] {
        let f = FileName::new(n).unwrap();
        p.store.create(&f).unwrap();
        p.store.write(&f, 0, &[7u8; 3000]).unwrap();
    }
    let mut seen = Vec::new();
    g.put(0, "a.bin", "a.bin", Class::Two).unwrap();
    let mut now = 0;
    for round in 0..300 {
        now += 10;
        if round == 100 {
            g.get(now, "b.bin", "b.bin", Class::Two).unwrap();
        }
        if round == 200 {
            g.list(now, "dir.lst").unwrap();
        }
        g.poll(now);
        r.poll(now);
        while let Some(p) = g.pop() {
            seen.push(p.to_vec());
            r.receive(now, &p);
        }
        while let Some(p) = r.pop() {
            seen.push(p.to_vec());
            g.receive(now, &p);
        }
    }
    seen
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    // verifies: FILE-CFDP-05
    #[test]
    fn random_and_damaged_pdus_never_panic_and_are_counted(
        junk in proptest::collection::vec(any::<u8>(), 0..1100),
        which in any::<usize>(),
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6),
        cut in any::<usize>(),
    ) {
        std::thread::Builder::new().stack_size(16 << 20).spawn(move || {
            let pdus = real_pdus();
            let rp = Parts::new(Mem::new(30_000));
            let mut r = Entity::new(1, 0, &rp);
            let gp = Parts::new(Mem::new(30_000));
            let mut g = Entity::new(0, 1, &gp);
            r.receive(10, &junk);
            g.receive(10, &junk);
            let mut p = pdus[which % pdus.len()].clone();
            for (i, x) in &flips {
                let n = p.len();
                p[i % n] ^= x | 1;
            }
            let keep = cut % (p.len() + 1);
            for e in [&mut r, &mut g] {
                e.receive(20, &p);
                e.receive(30, &p[..keep]);
                e.poll(40);
                e.poll(100_000);
            }
            let c = r.counters();
            assert!(c.received + c.refused >= 1, "{c:?}");
        }).unwrap().join().unwrap();
    }
}
