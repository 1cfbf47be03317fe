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

// spacepackets 0.16 reads a filestore request's action code unchecked: a metadata PDU with an
// empty filestore request TLV panicked the entity (found by the fuzz target `cfdp_pdu`). It
// is refused as a filestore request (counted), the transaction goes on, nothing changes.
// verifies: FILE-CFDP-05
#[test]
fn a_metadata_pdu_with_an_empty_or_cut_filestore_request_is_counted_and_changes_nothing() {
    use spacepackets::cfdp::pdu::metadata::{MetadataGenericParams, MetadataPduCreator};
    use spacepackets::cfdp::pdu::{CommonPduConfig, PduHeader};
    use spacepackets::cfdp::{ChecksumType, TransmissionMode};
    use spacepackets::util::UnsignedByteFieldU16;
    std::thread::Builder::new()
        .stack_size(16 << 20)
        .spawn(|| {
            // Empty; action code only; a first name longer than the TLV; a second name cut.
            for (seq, opts) in [
                vec![0x00, 0x00],
                vec![0x00, 0x01, 0x00],
                vec![0x00, 0x03, 0x00, 0x05, b'a'],
                vec![0x00, 0x05, 0x10, 0x01, b'a', 0x04, b'b'],
            ]
            .into_iter()
            .enumerate()
            {
                let rp = Parts::new(Mem::new(30_000));
                let f = FileName::new("a.bin").unwrap();
                rp.store.create(&f).unwrap();
                rp.store.write(&f, 0, &[1, 2, 3]).unwrap();
                let mut r = Entity::new(1, 0, &rp);
                let mut conf = CommonPduConfig::new_with_byte_fields(
                    UnsignedByteFieldU16::new(0),
                    UnsignedByteFieldU16::new(1),
                    UnsignedByteFieldU16::new(seq as u16),
                )
                .unwrap();
                conf.trans_mode = TransmissionMode::Acknowledged;
                let params = MetadataGenericParams::new(true, ChecksumType::Modular, 0);
                let empty = spacepackets::cfdp::lv::Lv::new_empty();
                let md =
                    MetadataPduCreator::new(PduHeader::new_for_file_directive(conf, 0), params, empty, empty, &opts);
                let mut raw = [0u8; 256];
                let n = md.write_to_bytes(&mut raw).unwrap();
                r.receive(10, &raw[..n]);
                r.poll(20);
                let c = r.counters();
                assert_eq!(c.fs_refused, 1, "{opts:02x?}: {c:?}");
                assert_eq!(c.fs_done, 0);
                let mut b = [0u8; 3];
                rp.store.read(&f, 0, &mut b).unwrap();
                assert_eq!(b, [1, 2, 3]);
            }
        })
        .unwrap()
        .join()
        .unwrap();
}

// A file data PDU whose segment metadata runs to the PDU's end (or past it) panicked the
// entity's gate: spacepackets 0.16 slices the metadata and the offset after it unchecked
// (found by the fuzz target `cfdp_pdu`, input
// `tests/fuzz/corpus/cfdp_pdu/crash-e4827cf200188d414ddfb5516f593c6597823927`). Refused and
// counted; a well-formed one with segment metadata still passes the gate.
// verifies: FILE-CFDP-05
#[test]
fn a_file_data_pdu_whose_segment_metadata_runs_to_its_end_is_refused_and_counted() {
    use spacepackets::cfdp::pdu::{CommonPduConfig, PduHeader};
    use spacepackets::cfdp::{SegmentMetadataFlag, SegmentationControl};
    use spacepackets::util::UnsignedByteFieldU16;
    let conf = CommonPduConfig::new_with_byte_fields(
        UnsignedByteFieldU16::new(0),
        UnsignedByteFieldU16::new(1),
        UnsignedByteFieldU16::new(3),
    )
    .unwrap();
    // Data field: the metadata's first byte (length in its low 6 bits), then what follows.
    for (field, whole) in [
        (vec![0x00u8], false),                   // no offset after an empty metadata
        (vec![0x03, 1, 2, 3], false),            // metadata to the end, no offset
        (vec![0x3F, 1, 2], false),               // metadata longer than the PDU
        (vec![0x02, 1, 2, 0, 0, 0, 0, 9], true), // metadata, offset 0, one data byte
    ] {
        let h = PduHeader::new_for_file_data(
            conf,
            field.len() as u16,
            SegmentMetadataFlag::Present,
            SegmentationControl::NoRecordBoundaryPreservation,
        );
        let mut raw = [0u8; 64];
        let hl = h.write_to_bytes(&mut raw).unwrap();
        raw[hl..hl + field.len()].copy_from_slice(&field);
        let raw = &raw[..hl + field.len()];
        assert_eq!(mmic_cfdp::entity::well_formed(raw).is_some(), whole, "{field:02x?}");
        let rp = Parts::new(Mem::new(30_000));
        let mut r = Entity::new(1, 0, &rp);
        let before = r.counters();
        r.receive(10, raw);
        if !whole {
            assert_eq!(r.counters().refused, before.refused + 1, "{field:02x?}");
        }
    }
}
