//! The one request ID type (`mib_wire::RequestId`): its four bytes, 32-bit key and word
//! forms all round-trip, and agree with the generated body parser.

use mib_wire::RequestId;
use proptest::prelude::*;

proptest! {
    // verifies: CODEC-RID-01
    #[test]
    fn any_four_bytes_round_trip_through_every_form(b in any::<[u8; 4]>(), tail in proptest::collection::vec(any::<u8>(), 0..8)) {
        let r = RequestId::from_bytes(b);
        prop_assert_eq!(r.to_bytes(), b);
        // The generated parser of the MIB layout reads the same fields.
        prop_assert_eq!(RequestId::of_tc(&[&b[..], &tail[..]].concat()), Ok(r));
        prop_assert_eq!(RequestId::parse(&b), Ok(r));
        let mut out = [0u8; 4];
        prop_assert_eq!(r.emit(&mut out), Ok(4));
        prop_assert_eq!(out, b);
        prop_assert_eq!(r.raw(), u32::from_be_bytes(b));
        prop_assert_eq!(RequestId::from_raw(r.raw()), r);
        prop_assert_eq!(RequestId::from_words(r.packet_id(), r.psc()), r);
        prop_assert_eq!((r.apid(), r.seq()), (r.apid, r.seq_count));
        prop_assert_eq!(r.apid(), u16::from_be_bytes([b[0], b[1]]) & 0x7FF);
        prop_assert_eq!(r.seq(), u16::from_be_bytes([b[2], b[3]]) & 0x3FFF);
    }
}

// verifies: CODEC-RID-01
#[test]
fn a_request_prints_as_apid_and_sequence_count() {
    let r = RequestId::from_bytes([0x19, 0x01, 0xC0, 0x05]);
    assert_eq!((r.packet_id(), r.psc()), (0x1901, 0xC005));
    assert_eq!(r.to_string(), "apid 0x101 seq 5");
    assert_eq!(
        RequestId::from_words(0x1FFF, 0xFFFF).to_string(),
        "apid 0x7FF seq 16383"
    );
    // Too short for a request ID: an error, not a panic.
    assert!(RequestId::of_tc(&[0x19, 0x01, 0xC0]).is_err());
}
