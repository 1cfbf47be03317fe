//! The table-driven codec (flight code) and the generated typed front end (host, ground,
//! tests) write the same bytes for every HK structure and every event of the MIB, with
//! the same saturation of values outside a parameter's type.

use mib::events::EVENTS;
use mib::hk::HK_STRUCTS;
use mib_wire::{codec, Event, Hk, Reader};
use proptest::prelude::*;

/// A raw value for parameter `id` from the random seed, often outside the type's range.
fn raw(seed: &[i64], id: u16) -> i64 {
    seed[id as usize % seed.len()]
}

proptest! {
    // verifies: CODEC-ONE-01
    #[test]
    fn hk_table_codec_and_typed_hk_write_the_same_bytes(
        seed in proptest::collection::vec(proptest::num::i64::ANY, 1..16),
    ) {
        for def in HK_STRUCTS {
            let mut a = [0u8; 1024];
            let n = codec::encode_hk(def, |id| raw(&seed, id), &mut a).unwrap();
            let hk = Hk::from_values(def.sid, |id| raw(&seed, id)).unwrap();
            let mut b = [0u8; 1024];
            b[..2].copy_from_slice(&def.sid.to_be_bytes());
            let mut w = mib_wire::Writer::new(&mut b[2..]);
            hk.write(&mut w).unwrap();
            let m = 2 + w.len();
            prop_assert_eq!(&a[..n], &b[..m], "SID {}", def.sid);
            // and the typed parse reads back what the table codec wrote
            let back = Hk::read(def.sid, &mut Reader::new(&a[2..n])).unwrap();
            prop_assert_eq!(back, hk);
        }
    }

    // verifies: CODEC-ONE-01
    #[test]
    fn event_table_codec_and_typed_event_agree(
        seed in proptest::collection::vec(proptest::num::i64::ANY, 1..8),
    ) {
        for def in EVENTS {
            let args: Vec<i64> = (0..def.params.len()).map(|i| seed[i % seed.len()]).collect();
            let mut a = [0u8; 256];
            let n = codec::encode_event(def, &args, &mut a).unwrap();
            let ev = Event::read(def.id, &mut Reader::new(&a[2..n])).unwrap();
            prop_assert_eq!(ev.id(), def.id);
            prop_assert_eq!(2 + ev.buffer_len(), n, "{}", def.name);
            let mut b = [0u8; 256];
            let mut w = mib_wire::Writer::new(&mut b);
            ev.write(&mut w).unwrap();
            let m = w.len();
            prop_assert_eq!(&a[2..n], &b[..m], "{}", def.name);
        }
    }
}

// verifies: CODEC-ONE-02
#[test]
fn typed_tc_arguments_take_each_value_by_its_mib_name() {
    let mut checked = 0;
    for t in mib::tc::TCS.iter().filter(|t| !t.args.is_empty()) {
        // Distinct values in range, encoded in MIB order by the table codec (the ground's
        // path) and decoded by the one checked parse (the obsw's acceptance).
        let vals: Vec<i64> = t
            .args
            .iter()
            .enumerate()
            .map(|(i, a)| (a.min + 1 + i as i64).min(a.max))
            .collect();
        let mut buf = [0u8; 64];
        let n = codec::encode_args(t, &vals, &mut buf).unwrap();
        let skip = if t.service == mib::tc::service::FUNCTION { 2 } else { 0 };
        let (decoded, _) = codec::decode_args(t, &buf[skip..n]).unwrap();
        for (a, v) in t.args.iter().zip(&vals) {
            assert_eq!(
                mib_wire::args::field_of(t.name, &decoded, a.name),
                Some(*v),
                "{}.{}",
                t.name,
                a.name
            );
        }
        checked += 1;
    }
    assert!(checked > 30, "{checked} TCs with arguments");
}
