//! Cross-check of the XTCE export with an independent decoder.
//!
//! Builds TM packets with the real encoder (`satrs::spacepackets::PusTmCreator`, a CDS
//! short time stamp and `mib_wire::codec`): TM[3,25] for every SID with extreme, negative and
//! pseudo-random values, every event report, and a few other TM. The packets and the
//! XTCE document go to `scripts/xtce_decode.py`, which decodes them with
//! space-packet-parser (installed in `.venv` by `scripts/python-env.sh`); every decoded
//! parameter — raw and calibrated — must equal what our own decoder (`mib_wire::codec`) reads
//! from the same bytes, and every header field must equal what was encoded.
//!
//! A third test decodes a stream of every report kind (successes, failures of several
//! codes with their failure data, events, mode reports, pings, HK of every SID, time,
//! parameter, store and list reports) with space-packet-parser and with
//! `ground decode --json`: every field must be equal in both, names included.
//!
//! Two more checks tie the descriptions to the real encoders: the header layout tables
//! against sat-rs TC and TM packets, and every XTCE MetaCommand (encoded by a small
//! walker over the XML) against `PusTcCreator` + `mib_wire::codec::encode_args`.

use arbitrary_int::{u11, u14};
use mib::events::EVENTS;
use mib::hk::HK_STRUCTS;
use mib::params::{self, ParamDef};
use mib::types::PType;
use mib_export as export;
use mib_wire::codec;
use satrs::spacepackets::ecss::tm::{PusTmCreator, PusTmSecondaryHeader};
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId, WritablePusPacket};
use satrs::spacepackets::time::cds::CdsTime;
use satrs::spacepackets::SpHeader;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const ROBOT: u8 = mib::apid::DEFAULT_ROBOT;

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .nth(2)
        .expect("mib/export/ is two levels below the repository")
        .to_path_buf()
}

/// Deterministic pseudo-random numbers (xorshift64*).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn in_range(&mut self, t: PType) -> i64 {
        let span = (t.max() - t.min()) as u64 + 1;
        t.min() + (self.next() % span) as i64
    }
}

/// Value of parameter `p` in test case `case`: minimum, maximum, zero, minus one (a
/// negative for signed types, saturated to 0 for unsigned ones), then random values.
fn value(p: PType, case: usize, rng: &mut Rng) -> i64 {
    match case {
        0 => p.min(),
        1 => p.max(),
        2 => 0,
        3 => -1,
        4 => p.min() + 1,
        5 => p.max() - 1,
        _ => rng.in_range(p),
    }
}

struct Header {
    service: u8,
    subservice: u8,
    seq: u16,
    counter: u16,
    days: u16,
    ms: u32,
}

fn build(h: &Header, data: &[u8]) -> Vec<u8> {
    let apid = mib::apid::robot_apid(ROBOT).unwrap();
    let time = CdsTime::new_with_u16_days(h.days, h.ms);
    let mut stamp = [0u8; 7];
    let n = time.write_to_bytes(&mut stamp).unwrap();
    assert_eq!(n, mib::config::TIMESTAMP_LEN);
    let sp = SpHeader::new_for_unseg_tm(u11::new(apid), u14::new(h.seq & 0x3FFF), 0);
    let sec = PusTmSecondaryHeader::new(
        MessageTypeId::new(h.service, h.subservice),
        h.counter,
        mib::config::GROUND_ID,
        &stamp,
    );
    let tm = PusTmCreator::new(sp, sec, data, CreatorConfig::default());
    tm.to_vec().unwrap()
}

/// What the independent decoder must report for one packet.
struct Expected {
    header: Vec<(&'static str, i64)>,
    /// (XTCE parameter, raw, calibrated value).
    params: Vec<(String, i64, Eng)>,
    what: String,
}

enum Eng {
    /// An enumerated value: the MIB's name.
    Name(&'static str),
    Int(i64),
    Bool(bool),
    Float(f64),
}

/// A value of an enumerated field: one of its named values (by test case), so that the
/// XTCE enumeration (which has no label for other values) decodes it.
fn named_value(names: mib::layout::Names, case: usize) -> i64 {
    let mut all = Vec::new();
    names.for_each(|v, _| all.push(v));
    all[case % all.len()]
}

fn eng_of(p: &ParamDef, raw: i64) -> Eng {
    if let Some(n) = p.names().name(raw) {
        return Eng::Name(n);
    }
    if p.ptype == PType::Bool {
        Eng::Bool(raw != 0)
    } else if p.calib.is_identity() {
        Eng::Int(raw)
    } else {
        Eng::Float(p.calib.eng(raw))
    }
}

fn header_expect(h: &Header, pkt: &[u8]) -> Vec<(&'static str, i64)> {
    let n = pkt.len();
    vec![
        ("VERSION", 0),
        ("PKT_TYPE", 0),
        ("SEC_HDR_FLG", 1),
        ("PKT_APID", mib::apid::robot_apid(ROBOT).unwrap() as i64),
        ("SEQ_FLGS", 3),
        ("SRC_SEQ_CTR", h.seq as i64),
        ("PKT_LEN", n as i64 - 7),
        ("TM_PUS_VERSION", 2),
        ("TM_TIME_REF", 0),
        ("TM_SERVICE", h.service as i64),
        ("TM_SUBSERVICE", h.subservice as i64),
        ("TM_MSG_COUNTER", h.counter as i64),
        ("TM_DEST_ID", mib::config::GROUND_ID as i64),
        ("TM_TIME_PFIELD", 0x40),
        ("TM_TIME_DAYS", h.days as i64),
        ("TM_TIME_MS", h.ms as i64),
        ("PEC", u16::from_be_bytes([pkt[n - 2], pkt[n - 1]]) as i64),
    ]
}

fn packets() -> Vec<(Vec<u8>, Expected)> {
    let sd = export::headers::tm_source_data_offset();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut out = Vec::new();
    let mut seq = 0u16;
    for h in HK_STRUCTS {
        for case in 0..12 {
            let mut vals = Vec::new();
            let mut buf = [0u8; 512];
            let n = codec::encode_hk(
                h,
                |id| {
                    let p = params::by_id(id).unwrap();
                    let v = if p.names().is_none() {
                        value(p.ptype, case, &mut rng)
                    } else {
                        named_value(p.names(), case)
                    };
                    vals.push((id, v));
                    v
                },
                &mut buf,
            )
            .unwrap();
            let hdr = Header {
                service: 3,
                subservice: 25,
                seq,
                counter: seq.wrapping_mul(7),
                days: (24_000 + seq * 13) % u16::MAX,
                ms: (seq as u32 * 3_600_123) % 86_400_000,
            };
            seq += 1;
            let pkt = build(&hdr, &buf[..n]);
            // Our own decoder, on the bytes of the real packet.
            let rep = codec::decode_hk(&pkt[sd..pkt.len() - 2]).unwrap();
            assert_eq!(rep.def.sid, h.sid);
            let mut exp = Vec::new();
            for ((p, raw), (id, put)) in rep.values().zip(&vals) {
                assert_eq!(p.id, *id);
                assert_eq!(raw, p.ptype.saturate(*put), "{}", p.name);
                exp.push((p.name.to_string(), raw, eng_of(p, raw)));
            }
            assert_eq!(exp.len(), h.params.len());
            exp.push(("HK_SID".to_string(), h.sid as i64, Eng::Int(h.sid as i64)));
            out.push((
                pkt.clone(),
                Expected {
                    header: header_expect(&hdr, &pkt),
                    params: exp,
                    what: format!("HK SID {} case {case}", h.sid),
                },
            ));
        }
    }
    for e in EVENTS {
        for case in [0usize, 1, 3, 7] {
            let args: Vec<i64> = e
                .params
                .iter()
                .map(|p| {
                    if p.names.is_none() {
                        value(p.ptype, case, &mut rng)
                    } else {
                        named_value(p.names, case)
                    }
                })
                .collect();
            let mut buf = [0u8; 64];
            let n = codec::encode_event(e, &args, &mut buf).unwrap();
            let hdr = Header {
                service: 5,
                subservice: e.severity.subservice(),
                seq,
                counter: seq,
                days: 25_000,
                ms: seq as u32,
            };
            seq += 1;
            let pkt = build(&hdr, &buf[..n]);
            let rep = codec::decode_event(&pkt[sd..pkt.len() - 2]).unwrap();
            let mut exp: Vec<(String, i64, Eng)> = rep
                .params()
                .map(|(name, raw)| {
                    let f = e.params.iter().find(|p| p.name == name).unwrap();
                    let t = f.ptype;
                    let eng = if let Some(n) = f.names.name(raw) {
                        Eng::Name(n)
                    } else if t == PType::Bool {
                        Eng::Bool(raw != 0)
                    } else {
                        Eng::Int(raw)
                    };
                    (format!("{}_{}", e.name, name), raw, eng)
                })
                .collect();
            assert_eq!(exp.len(), e.params.len());
            exp.push(("EVENT_ID".to_string(), e.id as i64, Eng::Int(e.id as i64)));
            out.push((
                pkt.clone(),
                Expected {
                    header: header_expect(&hdr, &pkt),
                    params: exp,
                    what: format!("event {} case {case}", e.name),
                },
            ));
        }
    }
    out
}

fn as_i64(v: &Value) -> Option<i64> {
    v.as_i64()
        .or_else(|| v.as_bool().map(|b| b as i64))
        .or_else(|| v.as_u64().map(|u| u as i64))
}

// verifies: ICD-03
#[test]
fn space_packet_parser_decodes_our_packets_like_our_decoder() {
    let root = repo_root();
    let python = root.join(".venv/bin/python");
    assert!(
        python.exists(),
        "{} is missing: run scripts/python-env.sh (creates .venv with space-packet-parser) \
         before `cargo test -p mib-export`; this cross-check must not be skipped",
        python.display()
    );
    let script = root.join("scripts/xtce_decode.py");
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("xtce-crosscheck");
    std::fs::create_dir_all(&dir).unwrap();
    let xtce = dir.join(export::XTCE_FILE);
    std::fs::write(&xtce, export::xtce_document()).unwrap();
    let cases = packets();
    let mut stream = Vec::new();
    for (p, _) in &cases {
        stream.extend_from_slice(p);
    }
    let bin = dir.join("packets.bin");
    std::fs::write(&bin, &stream).unwrap();

    let t0 = Instant::now();
    let out = Command::new(&python)
        .arg(&script)
        .arg(&xtce)
        .arg(&bin)
        .output()
        .expect("run scripts/xtce_decode.py");
    let elapsed = t0.elapsed();
    assert!(
        out.status.success(),
        "xtce_decode.py failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    let report: Value = serde_json::from_slice(&out.stdout).expect("JSON from xtce_decode.py");
    let v = &report["validation"];
    assert_eq!(v["schema_valid"], Value::Bool(true), "{v}");
    assert_eq!(v["structure_errors"].as_array().map(|a| a.len()), Some(0), "{v}");
    let decoded = report["packets"].as_array().expect("packets array");
    assert_eq!(decoded.len(), cases.len());

    let mut compared = 0usize;
    for ((_, exp), got) in cases.iter().zip(decoded) {
        for (name, want) in &exp.header {
            let g = as_i64(&got[*name]["raw"]);
            assert_eq!(g, Some(*want), "{}: header field {name}", exp.what);
            compared += 1;
        }
        for (name, raw, eng) in &exp.params {
            let g = &got[name.as_str()];
            assert!(!g.is_null(), "{}: {name} not decoded by space-packet-parser", exp.what);
            match eng {
                Eng::Name(n) => {
                    assert_eq!(as_i64(&g["raw"]), Some(*raw), "{}: {name} raw", exp.what);
                    assert_eq!(g["value"].as_str(), Some(*n), "{}: {name} name", exp.what);
                }
                Eng::Int(e) => {
                    assert_eq!(as_i64(&g["raw"]), Some(*raw), "{}: {name} raw", exp.what);
                    assert_eq!(as_i64(&g["value"]), Some(*e), "{}: {name} value", exp.what);
                }
                Eng::Bool(b) => {
                    assert_eq!(as_i64(&g["raw"]), Some(*raw), "{}: {name} raw", exp.what);
                    assert_eq!(g["value"].as_bool(), Some(*b), "{}: {name} value", exp.what);
                }
                Eng::Float(e) => {
                    assert_eq!(as_i64(&g["raw"]), Some(*raw), "{}: {name} raw", exp.what);
                    let gv = g["value"].as_f64().expect("calibrated value is a number");
                    let tol = 1e-12 * e.abs().max(1.0);
                    assert!((gv - e).abs() <= tol, "{}: {name} calibrated {gv} != {e}", exp.what);
                }
            }
            compared += 1;
        }
    }
    let hk_params: usize = HK_STRUCTS.iter().map(|h| h.params.len()).sum();
    assert!(compared > hk_params * 12, "only {compared} values compared");
    println!(
        "xtce cross-check: {} packets, {compared} values compared; {} took {:.2} s",
        cases.len(),
        report["decoder"].as_str().unwrap_or("?"),
        elapsed.as_secs_f64()
    );
}

/// Reads the fields of `fields` (MSB first) starting at octet `start` of `pkt`.
fn read_fields(pkt: &[u8], start: usize, fields: &[export::headers::HeaderField]) -> Vec<(&'static str, u64)> {
    export::headers::offsets(fields)
        .map(|(off, f)| {
            let mut v = 0u64;
            for b in 0..f.bits {
                let bit = start * 8 + (off + b) as usize;
                let set = pkt[bit / 8] >> (7 - bit % 8) & 1;
                v = v << 1 | set as u64;
            }
            (f.name, v)
        })
        .collect()
}

// verifies: MMIC-FW-01
#[test]
fn header_layout_tables_match_the_sat_rs_encoders() {
    use export::headers::{self, PRIMARY_HEADER, TC_SEC_HEADER, TM_SEC_HEADER};
    use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
    let apid = mib::apid::robot_apid(ROBOT).unwrap();

    // TC[8,1] RECONFIGURE built by sat-rs with acceptance and completion acknowledged.
    let def = mib::tc::lookup(8, 1, Some(mib::tc::function::RECONFIGURE)).unwrap();
    let mut app = [0u8; 16];
    let n = codec::encode_args(def, &[3, 1], &mut app).unwrap();
    let ack = AckFlags::builder()
        .with_acceptance(true)
        .with_start(false)
        .with_progress(false)
        .with_completion(true)
        .build();
    let sec = PusTcSecondaryHeader::new(MessageTypeId::new(8, 1), ack, mib::config::GROUND_ID);
    let sp = SpHeader::new_for_unseg_tc(u11::new(apid), u14::new(77), 0);
    let tc = PusTcCreator::new(sp, sec, &app[..n], CreatorConfig::default())
        .to_vec()
        .unwrap();
    let off = headers::tc_app_data_offset();
    assert_eq!(tc.len(), off + n + 2);
    assert_eq!(&tc[off..off + n], &app[..n]);
    let mut got = read_fields(&tc, 0, PRIMARY_HEADER);
    got.extend(read_fields(&tc, headers::len(PRIMARY_HEADER), TC_SEC_HEADER));
    let want: Vec<(&str, u64)> = vec![
        ("VERSION", 0),
        ("PKT_TYPE", 1),
        ("SEC_HDR_FLG", 1),
        ("PKT_APID", apid as u64),
        ("SEQ_FLGS", 3),
        ("SRC_SEQ_CTR", 77),
        ("PKT_LEN", (tc.len() - 7) as u64),
        ("TC_PUS_VERSION", 2),
        ("TC_ACK_FLAGS", 0b1001),
        ("TC_SERVICE", 8),
        ("TC_SUBSERVICE", 1),
        ("TC_SOURCE_ID", mib::config::GROUND_ID as u64),
    ];
    assert_eq!(got, want);
    for (name, v) in &got {
        let f = PRIMARY_HEADER
            .iter()
            .chain(TC_SEC_HEADER)
            .find(|f| f.name == *name)
            .unwrap();
        if let Some(fixed) = f.fixed {
            assert_eq!(*v, fixed as u64, "{name}");
        }
    }

    // TM[3,25] built by sat-rs: header fields where the table says, source data after it.
    let h = &HK_STRUCTS[0];
    let mut data = [0u8; 256];
    let n = codec::encode_hk(h, |id| id as i64, &mut data).unwrap();
    let hdr = Header {
        service: 3,
        subservice: 25,
        seq: 9,
        counter: 0xBEEF,
        days: 0x1234,
        ms: 0x0102_0304,
    };
    let tm = build(&hdr, &data[..n]);
    assert_eq!(tm.len(), headers::tm_packet_len(n));
    assert_eq!(&tm[headers::tm_source_data_offset()..tm.len() - 2], &data[..n]);
    let got = read_fields(&tm, headers::len(PRIMARY_HEADER), TM_SEC_HEADER);
    let want: Vec<(&str, u64)> = vec![
        ("TM_PUS_VERSION", 2),
        ("TM_TIME_REF", 0),
        ("TM_SERVICE", 3),
        ("TM_SUBSERVICE", 25),
        ("TM_MSG_COUNTER", 0xBEEF),
        ("TM_DEST_ID", mib::config::GROUND_ID as u64),
        ("TM_TIME_PFIELD", headers::CDS_SHORT_PFIELD as u64),
        ("TM_TIME_DAYS", 0x1234),
        ("TM_TIME_MS", 0x0102_0304),
    ];
    assert_eq!(got, want);
    assert_eq!(headers::tm_time_len(), mib::config::TIMESTAMP_LEN);
}

/// Bit writer for the XTCE command encoder below.
struct Bits {
    out: Vec<u8>,
    n: usize,
}
impl Bits {
    fn push(&mut self, v: u64, bits: u32) {
        for b in (0..bits).rev() {
            if self.n & 7 == 0 {
                self.out.push(0);
            }
            if v >> b & 1 == 1 {
                let last = self.out.len() - 1;
                self.out[last] |= 0x80 >> (self.n % 8);
            }
            self.n += 1;
        }
    }
}

/// Encodes TC `name` the way its XTCE MetaCommand describes it (entries of the base
/// `PUS_TC` container, then the command's own), without the PEC.
fn encode_from_xtce(doc: &roxmltree::Document, name: &str, args: &[i64], seq: u16, ack: u8) -> Vec<u8> {
    let by_name = |tag: &str, n: &str| {
        doc.descendants()
            .find(|x| x.tag_name().name() == tag && x.attribute("name") == Some(n))
            .unwrap_or_else(|| panic!("{tag} {n}"))
    };
    let mc = by_name("MetaCommand", name);
    let base = by_name("MetaCommand", "PUS_TC");
    let mut values: std::collections::BTreeMap<String, i64> = mc
        .descendants()
        .filter(|x| x.tag_name().name() == "ArgumentAssignment")
        .map(|x| {
            (
                x.attribute("argumentName").unwrap().to_string(),
                x.attribute("argumentValue").unwrap().parse().unwrap(),
            )
        })
        .collect();
    values.insert("SRC_SEQ_CTR".into(), seq as i64);
    values.insert("TC_ACK_FLAGS".into(), ack as i64);
    let own: Vec<roxmltree::Node> = mc.descendants().filter(|x| x.tag_name().name() == "Argument").collect();
    assert_eq!(own.len(), args.len());
    for (a, v) in own.iter().zip(args) {
        values.insert(a.attribute("name").unwrap().to_string(), *v);
    }
    let arg_bits = |cmd: roxmltree::Node, arg: &str| -> u32 {
        let a = cmd
            .descendants()
            .find(|x| x.tag_name().name() == "Argument" && x.attribute("name") == Some(arg))
            .unwrap_or_else(|| panic!("argument {arg}"));
        // Integer or enumerated (values the MIB names): both carry an integer encoding.
        let tref = a.attribute("argumentTypeRef").unwrap();
        let ty = doc
            .descendants()
            .find(|x| x.tag_name().name().ends_with("ArgumentType") && x.attribute("name") == Some(tref))
            .unwrap_or_else(|| panic!("argument type {tref}"));
        let enc = ty
            .descendants()
            .find(|x| x.tag_name().name() == "IntegerDataEncoding")
            .unwrap();
        enc.attribute("sizeInBits").unwrap().parse().unwrap()
    };
    let mut entries: Vec<(roxmltree::Node, roxmltree::Node)> = Vec::new();
    for (cmd, container) in [(base, "PUS_TC"), (mc, "")] {
        let c = cmd
            .descendants()
            .find(|x| x.tag_name().name() == "CommandContainer")
            .unwrap();
        if !container.is_empty() {
            assert_eq!(c.attribute("name"), Some(container));
        }
        let list = c.children().find(|x| x.tag_name().name() == "EntryList").unwrap();
        entries.extend(list.children().filter(|x| x.is_element()).map(|e| (cmd, e)));
    }
    // Two passes: the first finds the length for PKT_LEN.
    let mut total_bits = 0;
    for pass in 0..2 {
        let mut w = Bits { out: Vec::new(), n: 0 };
        for (cmd, e) in &entries {
            match e.tag_name().name() {
                "FixedValueEntry" => {
                    let bits: u32 = e.attribute("sizeInBits").unwrap().parse().unwrap();
                    let v = u64::from_str_radix(e.attribute("binaryValue").unwrap(), 16).unwrap();
                    w.push(v, bits);
                }
                "ArgumentRefEntry" => {
                    let arg = e.attribute("argumentRef").unwrap();
                    let bits = arg_bits(*cmd, arg);
                    let v = if arg == "PKT_LEN" {
                        total_bits as i64 / 8 + 2 - 7
                    } else {
                        values[arg]
                    };
                    w.push(v as u64 & ((1u64 << bits) - 1), bits);
                }
                other => panic!("unexpected entry {other}"),
            }
        }
        total_bits = w.n;
        if pass == 1 {
            assert_eq!(w.n % 8, 0);
            return w.out;
        }
    }
    unreachable!()
}

// verifies: MMIC-CMD-06
#[test]
fn xtce_meta_commands_encode_like_the_sat_rs_tc_encoder() {
    use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
    let text = export::xtce_document();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let apid = mib::apid::robot_apid(ROBOT).unwrap();
    let mut rng = Rng(42);
    let mut checked = 0;
    for (i, tc) in mib::tc::TCS.iter().enumerate() {
        for case in 0..3 {
            let args: Vec<i64> = tc
                .args
                .iter()
                .map(|a| match case {
                    0 => a.min,
                    1 => a.max,
                    _ => a.min + (rng.next() % ((a.max - a.min) as u64 + 1)) as i64,
                })
                .collect();
            let mut app = [0u8; 64];
            let n = codec::encode_args(tc, &args, &mut app).unwrap();
            let seq = (i * 3 + case) as u16;
            let sec = PusTcSecondaryHeader::new(
                MessageTypeId::new(tc.service, tc.subservice),
                AckFlags::ALL,
                mib::config::GROUND_ID,
            );
            let sp = SpHeader::new_for_unseg_tc(u11::new(apid), u14::new(seq), 0);
            let want = PusTcCreator::new(sp, sec, &app[..n], CreatorConfig::default())
                .to_vec()
                .unwrap();
            let got = encode_from_xtce(&doc, tc.name, &args, seq, 0b1111);
            assert_eq!(got, want[..want.len() - 2], "{} case {case}", tc.name);
            checked += 1;
        }
    }
    assert_eq!(checked, mib::tc::TCS.len() * 3);
}

// ---------------------------------------------------------------------------------------
// Every report kind: space-packet-parser (our XTCE) against `ground decode --json`.

/// Writes a body along its MIB field list; `pick` chooses each field's raw value by its
/// name (`count` fields and tails follow the values picked for their discriminants).
fn encode_body(items: &[mib::layout::Item], pick: &dyn Fn(&str) -> i64, b: &mut Bits) {
    use mib::layout::{Item, Tail};
    let mut seen: Vec<(&str, i64)> = Vec::new();
    let put = |f: &mib::layout::Field, b: &mut Bits, seen: &mut Vec<(&'static str, i64)>| {
        let v = pick(f.name);
        b.push(v as u64 & ((1u64 << f.bits) - 1), f.bits as u32);
        seen.push((f.name, v));
    };
    for it in items {
        match it {
            Item::Field(f) => put(f, b, &mut seen),
            Item::Sub { sub, .. } => sub.fields.iter().for_each(|f| put(f, b, &mut seen)),
            Item::Group { count, items, .. } => {
                let n = seen.iter().rev().find(|(c, _)| c == count).unwrap().1;
                for _ in 0..n {
                    encode_body(items, pick, b);
                }
            }
            Item::Packet { .. } => panic!("no TM embeds a packet"),
            Item::Tail(t) => {
                let d = seen.iter().rev().find(|(c, _)| *c == t.discriminant()).unwrap().1 as u16;
                let fields: Vec<mib::layout::Field> = match t {
                    Tail::FailureData => mib::FailureCode::from_code(d).data().to_vec(),
                    Tail::EventParams => mib::events::by_id(d).unwrap().params.to_vec(),
                    Tail::HkParams => mib::hk::by_sid(d)
                        .unwrap()
                        .params
                        .iter()
                        .map(|id| params::by_id(*id).unwrap().field())
                        .collect(),
                };
                fields.iter().for_each(|f| put(f, b, &mut seen));
            }
        }
    }
}

/// Flattens `ground decode --json`'s body into the XTCE parameter names: `<TM>_<path>`
/// for the generic reports (the failure data under the code's name), the parameter name
/// for HK, `<EVENT>_<param>` for events. Values: (raw, name or calibrated value).
fn flatten(tm: &str, body: &Value, out: &mut Vec<(String, Value)>) {
    fn walk(prefix: &str, v: &Value, out: &mut Vec<(String, Value)>) {
        match v {
            Value::Object(m) if m.contains_key("raw") => out.push((prefix.to_string(), v.clone())),
            Value::Object(m) => {
                for (k, x) in m {
                    walk(&format!("{prefix}_{k}"), x, out)
                }
            }
            Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    walk(&format!("{prefix}_{i}"), x, out)
                }
            }
            other => out.push((prefix.to_string(), other.clone())),
        }
    }
    let m = body.as_object().unwrap();
    match tm {
        "HK_REPORT" => {
            out.push(("HK_SID".into(), m["sid"].clone()));
            for (k, x) in m["params"].as_object().unwrap() {
                out.push((k.clone(), x.clone()));
            }
        }
        t if t.starts_with("EVENT_") && t != "EVENT_REPORT_DISABLED" && m.contains_key("event_id") => {
            let ev = m["event_id"]["name"].as_str().unwrap().to_string();
            out.push(("EVENT_ID".into(), m["event_id"].clone()));
            for (k, x) in m["params"].as_object().unwrap() {
                out.push((format!("{ev}_{k}"), x.clone()));
            }
        }
        _ => {
            for (k, x) in m {
                if k == "failure_data" {
                    let code = m["failure_code"]["name"].as_str().unwrap();
                    walk(&format!("{tm}_{code}"), x, out);
                } else {
                    walk(&format!("{tm}_{k}"), x, out);
                }
            }
        }
    }
}

/// Chooses a field's raw value by the field's name.
type Pick = Box<dyn Fn(&str) -> i64>;

// verifies: ICD-03, ALM-XTCE-01
#[test]
fn space_packet_parser_decodes_every_report_kind_like_ground_decode_json() {
    let root = repo_root();
    let python = root.join(".venv/bin/python");
    assert!(python.exists(), "run scripts/python-env.sh first (see the test above)");
    // The ground tool of this workspace.
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let st = Command::new(&cargo)
        .args(["build", "-q", "-p", "ground", "--bin", "ground"])
        .current_dir(&root)
        .status()
        .expect("cargo build -p ground");
    assert!(st.success());
    let target = std::env::var("CARGO_TARGET_DIR").map_or_else(|_| root.join("target"), PathBuf::from);
    let ground = target.join("debug/ground");

    // The stream: successes, failures of several codes, events, mode reports, pings, HK,
    // a time report, a parameter value, a store report, a list report.
    let rid = |n: &str| -> Option<i64> {
        Some(match n {
            "version" => 0,
            "packet_type" => 1,
            "sec_hdr" => 1,
            "apid" => mib::apid::robot_apid(ROBOT).unwrap() as i64,
            "seq_flags" => 3,
            "seq_count" => 1234,
            _ => return None,
        })
    };
    let common = move |n: &str| -> i64 {
        rid(n).unwrap_or(match n {
            "step" => 2,
            "pfield" => 0x40,
            "days" => 24_500,
            "ms_of_day" => 43_200_123,
            "node" => mib::modes::node::GRIPPER_B as i64,
            "mode" => 1,
            "submode" => 0,
            "reason" => mib::FailureCode::TIMEOUT.code() as i64,
            "param_id" => mib::tunables::TUNABLES[0].id as i64,
            "value" => -5,
            "rate_exp" => 6,
            "packets" => 4000,
            "oldest_seq" => 16_000,
            "overwritten" => 77,
            "count" => 3,
            "monitor_id" => mib::fdir::MONITORS[0].id as i64,
            "param" => mib::params::pid::V_BAT_A as i64,
            "limit" => 2730,
            "state" => 1,
            _ => 1,
        })
    };
    let mut kinds: Vec<(u8, u8, Pick)> = Vec::new();
    for sub in [1u8, 3, 5, 7] {
        kinds.push((1, sub, Box::new(common)));
    }
    for (sub, code) in [
        (2u8, mib::FailureCode::ARG_OUT_OF_RANGE),
        (2, mib::FailureCode::FRAME_TOO_LONG),
        (4, mib::FailureCode::BOTH_SIDES_GRIPPED),
        (4, mib::FailureCode::NOT_ALLOWED_IN_MODE),
        (6, mib::FailureCode::BOLT_FAILED),
        (8, mib::FailureCode::MODE_CHANGE_FAILED),
        (8, mib::FailureCode::INITIAL_STATE_MISMATCH),
        // Failure data carrying a value the MIB does not define (a ground-sent function
        // or SID that does not exist) must decode too: it reports what the robot received.
        (2, mib::FailureCode::UNKNOWN_FUNCTION),
        (4, mib::FailureCode::UNKNOWN_SID),
        (4, mib::FailureCode::UNKNOWN_EVENT),
        (4, mib::FailureCode::UNKNOWN_MONITOR),
        (4, mib::FailureCode::INVALID_MODE),
    ] {
        kinds.push((
            1,
            sub,
            Box::new(move |n: &str| match n {
                "failure_code" => code.code() as i64,
                "arg_index" => 1,
                "value" => -3,
                "frame_len" => 70_000,
                "max_len" => 1024,
                "grip_a_pwm" => 1000,
                "grip_b_pwm" => 1010,
                "side" => 1,
                "pair" => 3,
                "attempts" => 3,
                "believed" => 0,
                "computed" => 4,
                "event" => mib::events::eid::LOW_BATTERY as i64,
                "function" => 65_535,
                "sid" => 99,
                "event_id" => 4_321,
                "monitor_id" => 250,
                "mode" if code == mib::FailureCode::INVALID_MODE => 77,
                other => common(other),
            }),
        ));
    }
    for e in [
        mib::events::eid::MODE_CHANGED,
        mib::events::eid::BOLT_FAILURE,
        mib::events::eid::TC_REJECTED,
        mib::events::eid::EVENT_QUEUE_OVERFLOW,
        mib::events::eid::STATE_REACHED,
    ] {
        let def = mib::events::by_id(e).unwrap();
        kinds.push((
            5,
            def.severity.subservice(),
            Box::new(move |n: &str| match n {
                "event_id" => e as i64,
                "from" => 0,
                "to" => 1,
                "cause" => 0,
                "code" => mib::FailureCode::BUSY.code() as i64,
                "service" => 8,
                "subservice" => 1,
                "dropped" => 12,
                "state" => 4,
                other => common(other),
            }),
        ));
    }
    for sid in mib::hk::HK_STRUCTS.iter().map(|h| h.sid) {
        kinds.push((
            3,
            25,
            Box::new(move |n: &str| match n {
                "sid" => sid as i64,
                "MODE" | "PENDING_MODE" => 2,
                "CONFIG_STATE" => 3,
                "TARGET_STATE" => 255,
                "ACTIVE_PRIMITIVE" | "BOLT_SIDE" => 1,
                "LAST_FAULT_EVENT" => mib::events::eid::HIP_MISMATCH as i64,
                _ => 1,
            }),
        ));
    }
    for (svc, sub) in [
        (200u8, 6u8),
        (200, 7),
        (17, 2),
        (9, 2),
        (20, 2),
        (15, 19),
        (12, 12),
        (5, 8),
    ] {
        kinds.push((
            svc,
            sub,
            Box::new(move |n: &str| match n {
                "event_id" => mib::events::eid::BOOT as i64,
                other => common(other),
            }),
        ));
    }

    let mut stream = Vec::new();
    for (i, (svc, sub, pick)) in kinds.iter().enumerate() {
        let def = mib::tc::tm_by_type(*svc, *sub).unwrap();
        let mut b = Bits { out: vec![], n: 0 };
        encode_body(def.body, pick.as_ref(), &mut b);
        let hdr = Header {
            service: *svc,
            subservice: *sub,
            seq: i as u16,
            counter: i as u16 * 3,
            days: 24_000,
            ms: i as u32 * 1000,
        };
        stream.extend_from_slice(&build(&hdr, &b.out));
    }
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("xtce-every-report");
    std::fs::create_dir_all(&dir).unwrap();
    let xtce = dir.join(export::XTCE_FILE);
    std::fs::write(&xtce, export::xtce_document()).unwrap();
    let bin = dir.join("reports.bin");
    std::fs::write(&bin, &stream).unwrap();

    let out = Command::new(&python)
        .arg(root.join("scripts/xtce_decode.py"))
        .arg(&xtce)
        .arg(&bin)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let spp: Value = serde_json::from_slice(&out.stdout).unwrap();
    let spp = spp["packets"].as_array().unwrap();
    let out = Command::new(&ground)
        .args(["decode", "--json", "--strict"])
        .arg(&bin)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let ours: Vec<Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(spp.len(), kinds.len());
    assert_eq!(ours.len(), kinds.len());

    let header: Vec<&str> = export::headers::PRIMARY_HEADER
        .iter()
        .chain(export::headers::TM_SEC_HEADER)
        .map(|f| f.name)
        .chain(["PEC"])
        .collect();
    let mut compared = 0;
    for (s, g) in spp.iter().zip(&ours) {
        let name = g["name"].as_str().unwrap();
        assert!(g.get("error").is_none(), "{g}");
        assert_eq!(as_i64(&s["PKT_APID"]["raw"]), g["apid"].as_i64(), "{name}");
        assert_eq!(as_i64(&s["SRC_SEQ_CTR"]["raw"]), g["seq"].as_i64(), "{name}");
        assert_eq!(as_i64(&s["TM_SERVICE"]["raw"]), g["service"].as_i64(), "{name}");
        assert_eq!(as_i64(&s["TM_SUBSERVICE"]["raw"]), g["subservice"].as_i64(), "{name}");
        assert_eq!(as_i64(&s["TM_MSG_COUNTER"]["raw"]), g["msg_counter"].as_i64(), "{name}");
        let mut flat = Vec::new();
        flatten(name, &g["body"], &mut flat);
        // Every field of the XTCE decode (but the headers) is in ours, with equal values.
        let spp_fields: Vec<&String> = s
            .as_object()
            .unwrap()
            .keys()
            .filter(|k| !header.contains(&k.as_str()))
            .collect();
        assert_eq!(
            spp_fields.len(),
            flat.len(),
            "{name}: XTCE fields {spp_fields:?}, ours {:?}",
            flat.iter().map(|(k, _)| k).collect::<Vec<_>>()
        );
        for (k, v) in &flat {
            let sv = &s[k.as_str()];
            assert!(!sv.is_null(), "{name}: {k} not decoded by space-packet-parser");
            let raw = v.get("raw").unwrap_or(v);
            assert_eq!(as_i64(&sv["raw"]), as_i64(raw), "{name}: {k} raw");
            if let (Some(n), Some(label)) = (v.get("name"), sv["value"].as_str()) {
                // Enumerated in the XTCE (every report but HK and event parameters, which
                // stay integers there): the label is the MIB name (modes: both names).
                let ours = n.as_str().unwrap_or("");
                assert!(
                    label == ours || label.split('/').any(|l| l == ours),
                    "{name}: {k} named {ours:?} by ground, {label:?} by XTCE"
                );
            } else if let Some(e) = v.get("eng") {
                let gv = sv["value"].as_f64().unwrap();
                assert!((gv - e.as_f64().unwrap()).abs() < 1e-3, "{name}: {k} eng");
            }
            compared += 1;
        }
    }
    assert!(compared > 100, "only {compared} values compared");
    println!(
        "every report kind: {} packets, {compared} values equal in space-packet-parser and ground decode --json",
        kinds.len()
    );
}
