//! Property tests over every TC and TM kind of the MIB: random bodies that follow the MIB's
//! field lists parse, and emit gives back the same bytes (emit ∘ parse = identity); parse
//! never panics on arbitrary bytes.
//!
//! The bodies are generated from the MIB's field lists (not from the generated code), so
//! the test also checks that the generator followed the description.

use mib::layout::{Field, Item, Tail};
use mib::types::PType;
use mib_wire::{Tc, Tm};
use proptest::prelude::*;

/// Entropy from proptest, consumed byte by byte.
struct Src<'a> {
    b: &'a [u8],
    i: usize,
}

impl Src<'_> {
    fn byte(&mut self) -> u8 {
        let v = self.b.get(self.i % self.b.len().max(1)).copied().unwrap_or(0);
        self.i += 1;
        v
    }
    fn u32(&mut self) -> u32 {
        u32::from_be_bytes([self.byte(), self.byte(), self.byte(), self.byte()])
    }
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            self.u32() as usize % n
        }
    }
}

struct Body {
    buf: Vec<u8>,
    bit: usize,
}

impl Body {
    /// Appends the low `bits` bits of `v`, most significant first (independent of the
    /// crate's writer).
    fn put(&mut self, bits: u8, v: u32) {
        for i in (0..bits as usize).rev() {
            if self.bit & 7 == 0 {
                self.buf.push(0);
            }
            if (v >> i) & 1 == 1 {
                let last = self.buf.len() - 1;
                self.buf[last] |= 0x80 >> (self.bit % 8);
            }
            self.bit += 1;
        }
    }
    fn bytes(&mut self, b: &[u8]) {
        assert_eq!(self.bit % 8, 0);
        self.buf.extend_from_slice(b);
        self.bit += b.len() * 8;
    }
}

fn field_value(f: &Field, s: &mut Src) -> u32 {
    if f.ptype == PType::Bool {
        return s.byte() as u32 & 1;
    }
    let v = s.u32();
    if f.bits >= 32 {
        v
    } else {
        v & ((1u32 << f.bits) - 1)
    }
}

fn gen_fields(fields: &[Field], s: &mut Src, b: &mut Body) {
    for f in fields {
        let v = field_value(f, s);
        b.put(f.bits, v);
    }
}

fn gen_items(items: &[Item], prefix: &[(Field, Option<u32>)], s: &mut Src, b: &mut Body) {
    let tail = items.iter().find_map(|i| match i {
        Item::Tail(t) => Some(*t),
        _ => None,
    });
    let counts: Vec<(&str, usize)> = items
        .iter()
        .filter_map(|i| match i {
            Item::Group { count, max, .. } => Some((*count, *max)),
            _ => None,
        })
        .collect();
    let mut ctx: Vec<(&str, u32)> = Vec::new();
    let put_field = |f: &Field, fixed: Option<u32>, s: &mut Src, b: &mut Body, ctx: &mut Vec<(&str, u32)>| {
        let v = if let Some(v) = fixed {
            v
        } else if let Some((_, max)) = counts.iter().find(|(c, _)| *c == f.name) {
            s.below((*max).min(4) + 1) as u32
        } else if tail.is_some_and(|t| t.discriminant() == f.name) {
            pick_case(tail.unwrap(), s)
        } else {
            field_value(f, s)
        };
        b.put(f.bits, v);
        ctx.push((f.name, v));
    };
    for (f, fixed) in prefix {
        put_field(f, *fixed, s, b, &mut ctx);
    }
    for it in items {
        match it {
            Item::Field(f) => put_field(f, None, s, b, &mut ctx),
            Item::Sub { sub, .. } => gen_fields(sub.fields, s, b),
            Item::Group { count, items, .. } => {
                let n = ctx.iter().rev().find(|(c, _)| c == count).map_or(0, |(_, v)| *v);
                for _ in 0..n {
                    gen_items(items, &[], s, b);
                }
            }
            Item::Packet { max_len, .. } => {
                let len = 7 + s.below(max_len - 6);
                let mut p: Vec<u8> = (0..len).map(|_| s.byte()).collect();
                p[4..6].copy_from_slice(&((len - 7) as u16).to_be_bytes());
                b.bytes(&p);
            }
            Item::Tail(t) => {
                let d = ctx
                    .iter()
                    .rev()
                    .find(|(c, _)| *c == t.discriminant())
                    .map_or(0, |(_, v)| *v);
                match t {
                    Tail::FailureData => {
                        let c = mib::FailureCode::from_code(d as u16);
                        match c {
                            mib::FailureCode::Unknown(_) => unknown_data(s, b),
                            known => gen_fields(known.data(), s, b),
                        }
                    }
                    Tail::EventParams => match mib::events::by_id(d as u16) {
                        Some(e) => gen_fields(e.params, s, b),
                        None => unknown_data(s, b),
                    },
                    Tail::HkParams => {
                        let h = mib::hk::by_sid(d as u16).expect("generated SIDs exist");
                        for id in h.params {
                            let p = mib::params::by_id(*id).unwrap();
                            gen_fields(&[p.field()], s, b);
                        }
                    }
                }
            }
        }
    }
}

fn unknown_data(s: &mut Src, b: &mut Body) {
    let n = s.below(mib_wire::MAX_UNKNOWN_DATA + 1);
    let d: Vec<u8> = (0..n).map(|_| s.byte()).collect();
    b.bytes(&d);
}

fn pick_case(t: Tail, s: &mut Src) -> u32 {
    match t {
        Tail::FailureData => {
            let all = mib::FailureCode::ALL;
            match s.below(all.len() + 1) {
                i if i < all.len() => all[i].code() as u32,
                _ => 60_000,
            }
        }
        Tail::EventParams => {
            let all = mib::events::EVENTS;
            match s.below(all.len() + 1) {
                i if i < all.len() => all[i].id as u32,
                _ => 0xFFF0,
            }
        }
        Tail::HkParams => {
            let all = mib::hk::HK_STRUCTS;
            all[s.below(all.len())].sid as u32
        }
    }
}

fn tc_body(def: &mib::tc::TcDef, s: &mut Src) -> Vec<u8> {
    let mut b = Body { buf: vec![], bit: 0 };
    let mut prefix: Vec<(Field, Option<u32>)> = vec![];
    if def.service == mib::tc::service::FUNCTION {
        prefix.push((mib::layout::f("function", PType::U16, ""), Some(def.function as u32)));
    }
    prefix.extend(def.args.iter().map(|a| (*a, None)));
    gen_items(def.rest, &prefix, s, &mut b);
    b.buf
}

fn tm_body(def: &mib::tc::TmDef, s: &mut Src) -> Vec<u8> {
    let mut b = Body { buf: vec![], bit: 0 };
    gen_items(def.body, &[], s, &mut b);
    b.buf
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    // verifies: DD-DEC-01, ICD-06
    #[test]
    fn every_tm_kind_parses_what_the_mib_describes_and_emits_the_same_bytes(seed in proptest::collection::vec(any::<u8>(), 64..512)) {
        let mut s = Src { b: &seed, i: 0 };
        for def in mib::tc::TMS {
            let bytes = tm_body(def, &mut s);
            let repr = Tm::parse(def.service, def.subservice, &bytes)
                .unwrap_or_else(|e| panic!("{}: {e} on {bytes:02x?}", def.name));
            prop_assert_eq!(repr.name(), def.name);
            prop_assert_eq!(repr.buffer_len(), bytes.len());
            let mut out = vec![0u8; bytes.len()];
            let n = repr.emit(&mut out).unwrap();
            prop_assert_eq!(&out[..n], &bytes[..], "{}", def.name);
            prop_assert_eq!(Tm::parse(def.service, def.subservice, &out).unwrap(), repr);
        }
    }

    // verifies: MMIC-CMD-06, ICD-06
    #[test]
    fn every_tc_kind_parses_what_the_mib_describes_and_emits_the_same_bytes(seed in proptest::collection::vec(any::<u8>(), 64..512)) {
        let mut s = Src { b: &seed, i: 0 };
        for def in mib::tc::TCS {
            let bytes = tc_body(def, &mut s);
            let repr = Tc::parse(def.service, def.subservice, &bytes)
                .unwrap_or_else(|e| panic!("{}: {e} on {bytes:02x?}", def.name));
            prop_assert_eq!(repr.name(), def.name);
            prop_assert_eq!(repr.buffer_len(), bytes.len());
            let mut out = vec![0u8; bytes.len()];
            let n = repr.emit(&mut out).unwrap();
            prop_assert_eq!(&out[..n], &bytes[..], "{}", def.name);
            prop_assert_eq!(Tc::parse(def.service, def.subservice, &out).unwrap(), repr);
        }
    }

    // verifies: DD-ROBUST-01
    #[test]
    fn parse_never_panics_on_arbitrary_bytes(data in proptest::collection::vec(any::<u8>(), 0..300)) {
        for def in mib::tc::TMS {
            let _ = Tm::parse(def.service, def.subservice, &data);
        }
        for def in mib::tc::TCS {
            let _ = Tc::parse(def.service, def.subservice, &data);
        }
        let _ = mib_wire::header::TmPacket::parse(&data);
        let _ = mib_wire::header::TcPacket::parse(&data);
    }

    // verifies: DD-ROBUST-01
    #[test]
    fn emit_into_a_short_buffer_is_an_error_not_a_panic(seed in proptest::collection::vec(any::<u8>(), 64..256), cut in 0usize..64) {
        let mut s = Src { b: &seed, i: 0 };
        for def in mib::tc::TMS {
            let bytes = tm_body(def, &mut s);
            let repr = Tm::parse(def.service, def.subservice, &bytes).unwrap();
            let mut out = vec![0u8; bytes.len().saturating_sub(cut + 1)];
            prop_assert!(bytes.is_empty() || repr.emit(&mut out).is_err());
        }
    }
}

// verifies: PUS-1-01
#[test]
fn acceptance_failure_bytes_split_the_request_id_into_its_fields() {
    // TM[1,2] for TC apid 0x101 seq 5, refused with ARG_OUT_OF_RANGE (arg 1, value -3).
    let bytes = [0x19, 0x01, 0xC0, 0x05, 0x00, 0x09, 0x01, 0xFF, 0xFF, 0xFF, 0xFD];
    let Tm::AcceptanceFailure(r) = Tm::parse(1, 2, &bytes).unwrap() else {
        panic!("not TM[1,2]")
    };
    assert_eq!(
        (r.request_id.version, r.request_id.packet_type, r.request_id.sec_hdr),
        (0, 1, 1)
    );
    assert_eq!(
        (r.request_id.apid, r.request_id.seq_flags, r.request_id.seq_count),
        (0x101, 3, 5)
    );
    assert_eq!(r.request_id.packet_id(), 0x1901);
    assert_eq!(r.request_id.psc(), 0xC005);
    assert_eq!(
        r.failure,
        mib_wire::Failure::ArgOutOfRange {
            arg_index: 1,
            value: -3
        }
    );
    assert_eq!(r.failure.code(), mib::FailureCode::ARG_OUT_OF_RANGE.code());
    // Trailing byte, truncated data: errors, not panics.
    assert!(Tm::parse(1, 2, &[&bytes[..], &[0]].concat()).is_err());
    assert!(Tm::parse(1, 2, &bytes[..10]).is_err());
}

// verifies: PUS-5-01
#[test]
fn every_event_knows_the_subservice_of_its_severity() {
    for e in mib::events::EVENTS {
        let data = vec![0u8; e.data_len() - 2];
        let ev = mib_wire::Event::read(e.id, &mut mib_wire::Reader::new(&data)).unwrap();
        assert_eq!(ev.id(), e.id);
        assert_eq!(ev.subservice(), Some(e.severity.subservice()), "{}", e.name);
    }
}

// verifies: PUS-3-01
#[test]
fn hk_report_from_values_is_the_structure_the_mib_lists() {
    let h = mib_wire::Hk::from_values(mib::hk::sid::FDIR, |p| p as i64 * 3).unwrap();
    let rep = mib_wire::tm::HkReport { hk: h };
    let mut buf = [0u8; 256];
    let n = rep.emit(&mut buf).unwrap();
    assert_eq!(n, mib::hk::by_sid(mib::hk::sid::FDIR).unwrap().data_len());
    let back = mib_wire::tm::HkReport::parse(&buf[..n]).unwrap();
    assert_eq!(back.hk.get(mib::params::pid::FAULT_COUNT), Some(61 * 3));
    assert_eq!(back.hk.get(mib::params::pid::EVENTS_DROPPED), Some(66 * 3));
}

// verifies: DD-DEC-01, ICD-06
#[test]
fn views_read_and_write_the_fixed_fields_in_place() {
    let bytes = [0x19, 0x01, 0xC0, 0x05, 0x00, 0x09, 0x01, 0xFF, 0xFF, 0xFF, 0xFD];
    let v = mib_wire::tm::AcceptanceFailureView::new_checked(&bytes[..]).unwrap();
    assert_eq!(v.request_id().unwrap().seq_count, 5);
    assert_eq!(v.failure_code(), mib::FailureCode::ARG_OUT_OF_RANGE.code());
    assert_eq!(v.rest(), &bytes[6..]);
    assert!(mib_wire::tm::AcceptanceFailureView::new_checked(&bytes[..7]).is_err());

    let mut buf = [0u8; 10];
    let mut m = mib_wire::tm::ModeReplyView::new_unchecked(&mut buf[..]);
    m.set_node(mib::modes::node::HIP);
    m.set_mode(1);
    m.set_submode(0);
    let r = mib_wire::tm::ModeReply::parse(&buf).unwrap();
    assert_eq!((r.node, r.mode, r.submode), (mib::modes::node::HIP, 1, 0));
    // A view over too few bytes reads zeros, never panics.
    let short = mib_wire::tm::ModeReplyView::new_unchecked(&buf[..3]);
    assert_eq!(short.mode(), 0);
}

proptest! {
    // verifies: MMIC-CMD-06, ICD-06
    #[test]
    fn view_getters_agree_with_the_repr_of_a_tc(seed in proptest::collection::vec(any::<u8>(), 64..256)) {
        let mut s = Src { b: &seed, i: 0 };
        let def = mib::tc::by_name("MON_MODIFY").unwrap();
        let bytes = tc_body(def, &mut s);
        let r = mib_wire::tc::MonModify::parse(&bytes).unwrap();
        let v = mib_wire::tc::MonModifyView::new_checked(&bytes[..]).unwrap();
        prop_assert_eq!((v.monitor_id(), v.low(), v.high(), v.persistence()), (r.monitor_id, r.low, r.high, r.persistence));
    }
}

// verifies: PUS-PKT-01, ICD-06
#[test]
fn header_lengths_agree_with_the_exporters_header_tables() {
    use mib_export::headers as x;
    use mib_wire::header::*;
    assert_eq!(x::len(x::PRIMARY_HEADER), PRIMARY_HEADER_LEN);
    assert_eq!(x::len(x::TC_SEC_HEADER), TC_SEC_HEADER_LEN);
    assert_eq!(
        x::tm_source_data_offset(),
        PRIMARY_HEADER_LEN + TM_SEC_HEADER_LEN + mib::config::TIMESTAMP_LEN
    );
    assert_eq!(x::tc_app_data_offset(), PRIMARY_HEADER_LEN + TC_SEC_HEADER_LEN);
    assert_eq!(x::tm_packet_len(0), MIN_TM_LEN);
    assert_eq!(x::CDS_SHORT_PFIELD, CDS_PFIELD as u32);
    assert_eq!(x::PUS_C_VERSION, PUS_C as u32);
}

// verifies: PUS-3-01
#[test]
fn hk_from_values_saturates_each_parameter_to_its_type() {
    use mib::params::pid;
    let h = mib_wire::Hk::from_values(mib::hk::sid::ROBOT_STATUS, |p| match p {
        pid::MODE => 300,            // u8
        pid::CONFIG_STATE => -5,     // u8
        pid::HIP_ANGLE => -100_000,  // i16
        pid::HIP_TARGET => 40_000,   // i16
        pid::FAULT_FLAGS => 1 << 40, // u32
        pid::V_BAT_A => 70_000,      // u16
        pid::ARM_SW_A => 7,          // bool
        _ => 1,
    })
    .unwrap();
    assert_eq!(h.get(pid::MODE), Some(255));
    assert_eq!(h.get(pid::CONFIG_STATE), Some(0));
    assert_eq!(h.get(pid::HIP_ANGLE), Some(i16::MIN as i64));
    assert_eq!(h.get(pid::HIP_TARGET), Some(i16::MAX as i64));
    assert_eq!(h.get(pid::FAULT_FLAGS), Some(u32::MAX as i64));
    assert_eq!(h.get(pid::V_BAT_A), Some(u16::MAX as i64));
    assert_eq!(h.get(pid::ARM_SW_A), Some(1));
    assert_eq!(mib_wire::sat::i32(i64::MIN), i32::MIN);
    assert_eq!(mib_wire::sat::i32(i64::MAX), i32::MAX);
}
