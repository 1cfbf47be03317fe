use super::*;
use arbitrary_int::{u11, u14};
use mib::config::{GROUND_ID, MAX_PACKET_LEN};
use mib::events::eid;
use mib::headers::SeqCount;
use mib::params::pid;
use mib::tc::function;
use mib::FailureCode;
use mib_wire::codec;
use satrs::spacepackets::ecss::tc::ACK_ALL;
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId};
use satrs::spacepackets::SpHeader;

/// A CDS time stamp (2021-01-30T00:00:01.000Z); `out::tests` uses it too.
pub(super) const T0: [u8; 7] = [CDS_PFIELD, 0x5A, 0x00, 0x00, 0x00, 0x03, 0xE8];

/// TM[5,1] source data of MODE_CHANGED: node 10 (BOLTER_B) from 0 (OFF) to 1 (ON).
pub(super) fn mode_changed_source() -> Vec<u8> {
    let mut src = mib::events::eid::MODE_CHANGED.to_be_bytes().to_vec();
    for v in [10u32, 0, 1] {
        src.extend_from_slice(&v.to_be_bytes());
    }
    src.extend_from_slice(&0u16.to_be_bytes());
    src
}

// verifies: MMIC-FW-01
#[test]
fn events_and_failures_read_with_the_mib_names() {
    let src = mode_changed_source();
    let TmBody::Event(e) = decode_tm(&tm(5, 1, &src)).unwrap().body else {
        panic!("not an event")
    };
    let s = e.to_string();
    assert!(s.contains("node=BOLTER_B (10) from=OFF (0) to=ON (1)"), "{s}");
    let f = Failure::from_code(FailureCode::INITIAL_STATE_MISMATCH.code(), &[0, 4]);
    assert!(f.to_string().contains("believed="), "{f}");
    assert!(!f.to_string().contains("believed=0,"), "{f}");
}

// verifies: PUS-PKT-01
#[test]
fn raw_tc_bytes_equal_the_sat_rs_encoder() {
    use satrs::spacepackets::ecss::tc::{PusTcCreator, PusTcSecondaryHeader};
    let data: Vec<u8> = (0..=255u8).collect();
    for (apid, seq, svc, sub, n) in [
        (0x101u16, 0u16, 17u8, 1u8, 0usize),
        (0x7FF, SeqCount::MASK, 8, 1, 6),
        (0x10A, 1234, 200, 1, 10),
        (0x102, 99, 11, 4, 255),
    ] {
        for ack in [ACK_ALL, ack_flags_for(mib::tc::by_name("PING").unwrap())] {
            let ours = build_raw_tc(apid, seq, svc, sub, ack, &data[..n]).unwrap();
            let sp = SpHeader::new_for_unseg_tc(u11::new(apid), u14::new(seq), 0);
            let sec = PusTcSecondaryHeader::new(MessageTypeId::new(svc, sub), ack, GROUND_ID);
            let tc = PusTcCreator::new(sp, sec, &data[..n], CreatorConfig::default());
            let mut theirs = Vec::new();
            tc.append_to_vec(&mut theirs);
            assert_eq!(ours, theirs, "apid {apid:#x} seq {seq} TC[{svc},{sub}] {n} bytes");
        }
    }
    assert!(matches!(
        build_raw_tc(0x101, 0, 17, 1, ACK_ALL, &[0u8; MAX_PACKET_LEN]),
        Err(BuildError::TooLong(_))
    ));
}

// verifies: PUS-PKT-01
#[test]
fn ping_tc_bytes_match_ccsds_and_pus_c_layout() {
    let def = mib::tc::by_name("PING").unwrap();
    let tc = build_tc(1, 5, def, &[]).unwrap();
    // primary header: TC, sec header, APID 0x101; unsegmented, seq 5; length 5+2-1
    assert_eq!(&tc.bytes[..6], &[0x19, 0x01, 0xC0, 0x05, 0x00, 0x06]);
    // PUS-C, ack acceptance+completion; service 17/1; source ID 0
    assert_eq!(&tc.bytes[6..11], &[0x29, 17, 1, 0, 0]);
    let crc = satrs::spacepackets::crc::CRC_CCITT_FALSE.checksum(&tc.bytes[..11]);
    assert_eq!(&tc.bytes[11..], &crc.to_be_bytes());
    assert_eq!(tc.request_id(), RequestId::from_words(0x1901, 0xC005));
}

// verifies: PUS-1-03
#[test]
fn robot_action_requests_all_four_acknowledgements_and_round_trips() {
    let def = mib::tc::lookup(8, 1, Some(function::RECONFIGURE)).unwrap();
    let tc = build_tc(2, 77, def, &[0, 4]).unwrap();
    assert_eq!(tc.bytes[6] & 0x0F, 0x0F);
    assert_eq!(tc.apid, 0x102);
    let Packet::Tc(d) = decode_packet(&tc.bytes).unwrap() else {
        panic!("not a TC")
    };
    assert_eq!(d.name, Some("RECONFIGURE"));
    assert_eq!(d.robot, Some(2));
    assert_eq!(d.seq, 77);
    assert_eq!(d.function, Some(function::RECONFIGURE));
    assert_eq!(
        d.args.iter().map(|a| (a.name.as_str(), a.value)).collect::<Vec<_>>(),
        vec![("from", 0), ("to", 4)]
    );
    assert_eq!(d.arg_error, None);
}

// verifies: PUS-8-02
#[test]
fn out_of_range_argument_is_refused_before_sending() {
    let def = mib::tc::by_name("BOLT_FACE").unwrap();
    let e = build_tc(1, 0, def, &[0, 16]).unwrap_err();
    assert!(e.to_string().contains("pairs = 16 outside 1..=15"), "{e}");
    assert!(matches!(build_tc(0, 0, def, &[0, 1]), Err(BuildError::UnknownRobot(0))));
}

// verifies: PUS-PKT-03
#[test]
fn sequence_counts_are_per_apid_and_wrap_at_14_bits() {
    let mut s = SeqCounters::new();
    assert_eq!(s.next(0x101), 0);
    assert_eq!(s.next(0x101), 1);
    assert_eq!(s.next(0x102), 0);
    s.set(0x103, SeqCount::MASK);
    assert_eq!(s.next(0x103), SeqCount::MASK);
    assert_eq!(s.next(0x103), 0);
}

fn tm(service: u8, sub: u8, src: &[u8]) -> Vec<u8> {
    build_tm(0x101, 9, service, sub, 3, &T0, src)
}

// verifies: PUS-1-01
#[test]
fn acceptance_success_from_static_bytes() {
    // TM[1,1] for request 0x1901/0xC005, hand-assembled.
    let mut b = vec![
        0x09, 0x01, 0xC0, 0x09, 0x00, 0x00, // primary header (length patched below)
        0x20, 1, 1, 0x00, 0x03, 0x00, 0x00, // PUS-C TM sec header, msg counter 3, dest 0
    ];
    b.extend_from_slice(&T0);
    b.extend_from_slice(&[0x19, 0x01, 0xC0, 0x05]);
    let len = (b.len() + 2 - 7) as u16;
    b[4..6].copy_from_slice(&len.to_be_bytes());
    let crc = satrs::spacepackets::crc::CRC_CCITT_FALSE.checksum(&b);
    b.extend_from_slice(&crc.to_be_bytes());
    assert_eq!(b, tm(1, 1, &[0x19, 0x01, 0xC0, 0x05]));
    let t = decode_tm(&b).unwrap();
    assert_eq!(t.name, "ACCEPTANCE_SUCCESS");
    assert_eq!(t.robot, Some(1));
    assert_eq!(t.msg_counter, 3);
    assert_eq!(t.time.days, 0x5A00);
    assert_eq!(t.time.ms_of_day, 1000);
    let TmBody::Verification(v) = t.body else { panic!() };
    assert_eq!(v.stage, Stage::Acceptance);
    assert!(v.success);
    assert_eq!(v.request.apid(), 0x101);
    assert_eq!(v.request.seq(), 5);
}

// verifies: CODEC-RID-01
#[test]
fn a_verification_report_serialises_its_request_as_packet_id_and_psc() {
    // The JSON of the ground's outputs (`ground live`, the collector) keeps the request as
    // the two words, whichever type carries it.
    let t = decode_tm(&tm(1, 1, &[0x19, 0x01, 0xC0, 0x05])).unwrap();
    let TmBody::Verification(v) = t.body else { panic!() };
    assert_eq!(
        serde_json::to_string(&v).unwrap(),
        r#"{"stage":"acceptance","success":true,"request":{"packet_id":6401,"psc":49157},"step":null,"failure":null}"#
    );
    assert_eq!(v.request.to_string(), "apid 0x101 seq 5");
}

// verifies: PUS-1-03
#[test]
fn progress_and_failure_reports_carry_step_code_and_named_data() {
    let t = decode_tm(&tm(1, 5, &[0x19, 0x01, 0xC0, 0x05, 2])).unwrap();
    let TmBody::Verification(v) = t.body else { panic!() };
    assert_eq!((v.stage, v.step, v.success), (Stage::Progress, Some(2), true));

    let code = FailureCode::BOLT_FAILED.code().to_be_bytes();
    let src = [0x19, 0x01, 0xC0, 0x05, 3, code[0], code[1], 1, 3, 3];
    let TmBody::Verification(v) = decode_tm(&tm(1, 6, &src)).unwrap().body else {
        panic!()
    };
    let f = v.failure.unwrap();
    assert_eq!(v.step, Some(3));
    assert_eq!(f.name, "BOLT_FAILED");
    assert_eq!(
        (f.field("side"), f.field("pair"), f.field("attempts")),
        (Some(1), Some(3), Some(3))
    );
    assert!(f.to_string().contains("did not lock"));

    let code = FailureCode::NOT_ALLOWED_IN_MODE.code().to_be_bytes();
    let src = [0x19, 0x01, 0xC0, 0x05, code[0], code[1], 0];
    let TmBody::Verification(v) = decode_tm(&tm(1, 2, &src)).unwrap().body else {
        panic!()
    };
    assert_eq!(v.stage, Stage::Acceptance);
    assert_eq!(v.failure.unwrap().field("mode"), Some(0));
    // success report with trailing bytes is refused
    assert!(decode_tm(&tm(1, 7, &[0x19, 0x01, 0xC0, 0x05, 9])).is_err());
}

// verifies: PUS-3-01
#[test]
fn hk_report_decodes_with_calibration() {
    let def = mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).unwrap();
    let mut src = [0u8; 256];
    let n = codec::encode_hk(def, |id| if id == pid::V_BAT_A { 3276 } else { 1 }, &mut src).unwrap();
    let t = decode_tm(&tm(3, 25, &src[..n])).unwrap();
    let TmBody::Hk(h) = t.body else { panic!() };
    assert_eq!(h.name, "ROBOT_STATUS");
    assert_eq!(h.values.len(), def.params.len());
    assert_eq!(h.raw(pid::V_BAT_A), Some(3276));
    assert!((h.eng(pid::V_BAT_A).unwrap() - 12.0).abs() < 0.01);
    // truncated HK is an error value
    assert!(decode_tm(&tm(3, 25, &src[..n - 1])).is_err());
}

// verifies: PUS-5-01
#[test]
fn event_report_must_match_its_severity() {
    let def = mib::events::by_id(eid::BOLT_FAILURE).unwrap();
    let mut src = [0u8; 16];
    let n = codec::encode_event(def, &[0, 2, 3], &mut src).unwrap();
    let TmBody::Event(e) = decode_tm(&tm(5, 4, &src[..n])).unwrap().body else {
        panic!()
    };
    assert!(e.fault);
    assert_eq!(e.param("pair"), Some(2));
    assert!(decode_tm(&tm(5, 1, &src[..n])).is_err());
}

// verifies: DD-DEC-01
#[test]
fn other_tm_types_decode_per_mib_layouts() {
    use mib_wire::{tm as wtm, Tm as W};
    let report = |b: TmBody| b.report().cloned().expect("a report");
    assert_eq!(
        report(decode_tm(&tm(17, 2, &[])).unwrap().body),
        W::PingReply(wtm::PingReply {})
    );
    let b = decode_tm(&tm(200, 6, &[0, 0, 0, 1, 0, 0, 0, 1, 0, 0])).unwrap().body;
    assert_eq!(
        report(b.clone()),
        W::ModeReply(wtm::ModeReply {
            node: 1,
            mode: 1,
            submode: 0
        })
    );
    assert_eq!(describe_body(&b), "node ROBOT mode OPERATIONAL submode 0");
    let W::DisabledEvents(d) = report(decode_tm(&tm(5, 8, &[0, 2, 1, 1, 2, 6])).unwrap().body) else {
        panic!()
    };
    assert_eq!(
        d.events.iter().map(|e| e.event_id).collect::<Vec<_>>(),
        vec![0x0101, 0x0206]
    );
    let mut src = vec![3u8];
    src.extend_from_slice(&T0);
    assert!(matches!(
        report(decode_tm(&tm(9, 2, &src)).unwrap().body),
        W::TimeReport(wtm::TimeReport { rate_exp: 3, .. })
    ));
    assert_eq!(
        report(decode_tm(&tm(20, 2, &[0, 3, 0, 0, 0, 4])).unwrap().body),
        W::ParamValue(wtm::ParamValue { param_id: 3, value: 4 })
    );
    let W::StoreDownlinkDone(s) = report(
        decode_tm(&tm(
            15,
            19,
            &[0, 0, 1, 0, CDS_PFIELD, 0x5A, 0, 0, 0, 0, 1, 0, 7, 0, 0, 0, 2],
        ))
        .unwrap()
        .body,
    ) else {
        panic!()
    };
    assert_eq!(
        (
            s.packets,
            CdsShort::from_wire(&s.oldest_time),
            s.oldest_seq,
            s.overwritten
        ),
        (
            256,
            CdsShort {
                days: 0x5A00,
                ms_of_day: 1
            },
            7,
            2
        )
    );
    let mon = [
        0, 1, 0, 1, 0, 20, 1, 0, 0, 0x0A, 0xAA, 0x7F, 0xFF, 0xFF, 0xFF, 0, 50, 1, 4,
    ];
    let W::MonDefinitions(m) = report(decode_tm(&tm(12, 9, &mon)).unwrap().body) else {
        panic!()
    };
    assert_eq!(m.monitors[0].param, pid::V_BAT_A);
    assert_eq!(m.monitors[0].event, eid::LOW_BATTERY);
    assert!(decode_tm(&tm(12, 9, &mon[..mon.len() - 1])).is_err());
    let ea = [0, 1, 1, 1, 1, 0, 0, 0, 0, 0];
    let W::EaDefinitions(e) = report(decode_tm(&tm(19, 9, &ea)).unwrap().body) else {
        panic!()
    };
    assert_eq!(e.links[0].event, eid::BOLT_FAILURE);
    let tr = [0, 1, 0, 20, 0, 0, 10, 0, 0, 0, 11, 0, 1];
    assert!(matches!(
        report(decode_tm(&tm(12, 12, &tr)).unwrap().body),
        W::MonTransition(wtm::MonTransition { state: 1, .. })
    ));
    assert!(matches!(
        decode_tm(&tm(99, 1, &[1, 2])).unwrap().body,
        TmBody::Unknown { .. }
    ));
}

// verifies: PUS-PKT-01
#[test]
fn crc_error_and_bad_versions_are_values() {
    let mut b = tm(17, 2, &[]);
    let last = b.len() - 1;
    b[last] ^= 1;
    assert!(matches!(decode_tm(&b), Err(DecodeError::Crc { .. })));
    let mut b = tm(17, 2, &[]);
    b[6] = 0x10; // PUS-A
    assert!(matches!(decode_packet(&b), Err(DecodeError::NotPus { .. })));
    assert!(matches!(
        decode_packet(&[0x08, 1, 0xC0, 0, 0, 0]),
        Err(DecodeError::Truncated { .. })
    ));
    assert!(matches!(
        decode_packet(&[0x08, 1, 0xC0, 0, 0xFF, 0xFF]),
        Err(DecodeError::TooLong { .. })
    ));
}

// verifies: DD-LINK-01
#[test]
fn stream_decoder_resynchronises_after_garbage() {
    let mut s = tm(17, 2, &[]);
    s.extend_from_slice(&[0xFF, 0x00, 0x13]);
    let ping = build_tc(1, 1, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
    s.extend_from_slice(&ping.bytes);
    s.extend_from_slice(&tm(17, 2, &[])[..10]);
    let items: Vec<_> = StreamDecoder::new(&s).collect();
    let mut st = StreamStats::default();
    items.iter().for_each(|i| st.add(i));
    assert_eq!((st.tm, st.tc, st.corrupt_stretches, st.corrupt_bytes), (1, 1, 2, 13));
    assert!(matches!(items[1], StreamItem::Corrupt { len: 3, .. }));
}

// verifies: PUS-PKT-04
#[test]
fn time_stamp_round_trips_through_unix_ms() {
    let t = CdsShort::from_unix_ms(1_700_000_000_123);
    assert_eq!(t.unix_ms(), 1_700_000_000_123);
    assert_eq!(CdsShort::parse(&t.to_bytes()), Some(t));
    assert_eq!(t.to_string(), "2023-11-14T22:13:20.123Z");
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;
    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        // verifies: DD-ROBUST-01
        #[test]
        fn random_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..400)) {
            let mut st = StreamStats::default();
            let mut covered = 0usize;
            for item in StreamDecoder::new(&data) {
                st.add(&item);
                covered += match &item {
                    StreamItem::Packet { packet: Packet::Tc(t), .. } => t.len,
                    StreamItem::Packet { packet: Packet::Tm(t), .. } => t.len,
                    StreamItem::Corrupt { len, .. } => *len,
                };
            }
            prop_assert_eq!(covered, data.len());
        }

        // verifies: GND-08
        #[test]
        fn valid_header_random_body_never_panics(
            tc in any::<bool>(), svc in any::<u8>(), sub in any::<u8>(),
            body in proptest::collection::vec(any::<u8>(), 0..64)) {
            let b = if tc {
                build_raw_tc(0x101, 1, svc, sub, ACK_ALL, &body).unwrap()
            } else {
                build_tm(0x101, 1, svc, sub, 0, &T0, &body)
            };
            // Valid CRC, arbitrary content: decodes or reports, never panics.
            let _ = decode_packet(&b);
            let mut flipped = b.clone();
            let i = body.len() % flipped.len();
            flipped[i] ^= 0x5A;
            let _ = decode_packet(&flipped);
        }
    }
}

// verifies: DD-DEC-01
#[test]
fn a_report_is_written_as_its_kind_and_its_mib_fields() {
    // One model: a report of the MIB that the ground has no view of is the wire value, and
    // its JSON and text are written from the MIB's field list (names beside raw values).
    let t = decode_tm(&tm(200, 6, &[0, 0, 0, 1, 0, 0, 0, 1, 0, 0])).unwrap();
    assert_eq!(
        serde_json::to_value(&t.body).unwrap(),
        serde_json::json!({
            "kind": "mode_reply",
            "node": {"raw": 1, "name": "ROBOT"},
            "mode": {"raw": 1, "name": "OPERATIONAL"},
            "submode": 0
        })
    );
    let e = decode_tm(&tm(19, 9, &[0, 1, 1, 1, 1, 0, 0, 0, 0, 0])).unwrap();
    assert_eq!(serde_json::to_value(&e.body).unwrap()["kind"], "ea_definitions");
    let text = describe_body(&e.body);
    assert!(
        text.starts_with("count=1 links=") && text.contains("BOLT_FAILURE"),
        "{text}"
    );
    assert_eq!(
        serde_json::to_value(&TmBody::Unknown { data: vec![1, 0xAB] }).unwrap()["data"],
        "01ab"
    );
}
