use super::*;
use crate::build_tm;
use crate::tests::{mode_changed_source, T0};

fn json_of(raw: &[u8]) -> serde_json::Value {
    let mut w = Writer::new(Format::Json);
    let Some(RawItem::Tm { offset, packet }) = RawStream::new(raw).next() else {
        panic!("not a TM")
    };
    let _ = w.tm(offset, &packet);
    serde_json::from_slice(&w.out).unwrap()
}

// verifies: DD-DEC-01, PUS-1-02
#[test]
fn failure_report_json_splits_request_id_and_names_code_and_data() {
    // TM[1,4] START_FAILURE for TC 0x1901/0xC007: NOT_ALLOWED_IN_MODE, mode 0.
    let src = [0x19, 0x01, 0xC0, 0x07, 0x00, 10, 0];
    let v = json_of(&build_tm(0x101, 3, 1, 4, 0, &T0, &src));
    assert_eq!(v["name"], "START_FAILURE");
    assert_eq!(v["body"]["request_id"]["apid"], 0x101);
    assert_eq!(v["body"]["request_id"]["seq_count"], 7);
    assert_eq!(v["body"]["request_id"]["seq_flags"]["name"], "UNSEGMENTED");
    assert_eq!(v["body"]["failure_code"]["name"], "NOT_ALLOWED_IN_MODE");
    assert_eq!(v["body"]["failure_code"]["raw"], 10);
    assert_eq!(v["body"]["failure_data"]["mode"]["name"], "STANDBY");
    assert_eq!(v["time"], "2021-01-30T00:00:01.000Z");
}

// verifies: DD-DEC-01, PUS-200-01
#[test]
fn mode_changed_event_names_node_and_modes_of_that_node() {
    let src = mode_changed_source();
    let v = json_of(&build_tm(0x101, 3, 5, 1, 0, &T0, &src));
    assert_eq!(v["body"]["event_id"]["name"], "MODE_CHANGED");
    assert_eq!(v["body"]["params"]["node"]["name"], "BOLTER_B");
    assert_eq!(v["body"]["params"]["from"]["name"], "OFF");
    assert_eq!(v["body"]["params"]["to"]["name"], "ON");
}

// verifies: DD-DEC-01, GND-08
#[test]
fn a_body_that_does_not_match_is_an_error_line_with_its_bytes() {
    let v = json_of(&build_tm(0x101, 3, 17, 2, 0, &T0, &[1, 2]));
    assert_eq!(v["name"], "PING_REPLY");
    assert!(v["error"].as_str().unwrap().contains("2 bytes after"));
    assert_eq!(v["data"], "0102");
}

// verifies: DD-DEC-01
#[test]
fn engineering_values_show_one_raw_count() {
    assert_eq!(decimals(0.001), 3);
    assert_eq!(decimals(0.01), 2);
    assert_eq!(decimals(15.0 / 4095.0), 4);
    assert_eq!(decimals(1.0), 0);
    let mut w = Writer::new(Format::Json);
    w.float(-0.0405, 3);
    w.out.push(b' ');
    w.float(9.597069597, 4);
    w.out.push(b' ');
    w.float(23.58, 2);
    assert_eq!(String::from_utf8(w.out).unwrap(), "-0.041 9.5971 23.58");
}

// verifies: DD-DEC-01
#[test]
fn every_mib_name_and_unit_is_plain_json() {
    let plain = |s: &str| s.bytes().all(|c| c >= 0x20 && c != b'"' && c != b'\\');
    for p in mib::params::PARAMS {
        assert!(plain(p.name) && plain(p.unit));
    }
    for t in mib::tc::TMS {
        assert!(plain(t.name));
    }
}
