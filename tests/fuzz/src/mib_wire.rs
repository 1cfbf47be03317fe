//! The generated packet model every other layer parses with (`mib_wire`): TC and TM
//! headers (`TcPacket::parse`, `TmPacket::parse`), TC arguments against the MIB
//! (`codec::decode_args`), housekeeping and event source data (`codec::decode_hk`,
//! `codec::decode_event`).
//!
//! The input is one packet (or source data). Invariants: nothing panics, and every parse
//! has its emit as inverse: a parsed TC or TM written again with `emit_tc`/`emit_tm` is the
//! same bytes (where the header's free fields have the values the emitter writes), decoded
//! arguments encode to the same bytes, decoded HK and event reports encode to the same
//! source data.

use mib_wire::codec::{decode_args, decode_event, decode_hk, encode_args, encode_event, encode_hk};
use mib_wire::header::{emit_tc, emit_tm, TcHeader, TcPacket, TmHeader, TmPacket};

fn source_data(src: &[u8]) {
    // A boolean decodes as its raw byte and encodes as 0 or 1 (`PType::saturate`): the
    // round trip is exact up to that, so the values are compared after saturation.
    if let Ok(r) = decode_hk(src) {
        let values: Vec<(u16, i64)> = r.values().map(|(p, v)| (p.id, p.ptype.saturate(v))).collect();
        let value = |id: u16| values.iter().find(|(p, _)| *p == id).map_or(0, |(_, v)| *v);
        let mut buf = vec![0u8; src.len()];
        let n = encode_hk(r.def, value, &mut buf).expect("a decoded report encodes");
        assert_eq!(n, src.len(), "HK length");
        let back = decode_hk(&buf[..n]).expect("an encoded report decodes");
        let again: Vec<(u16, i64)> = back.values().map(|(p, v)| (p.id, v)).collect();
        assert_eq!(again, values, "HK decode then encode");
    }
    if let Ok(r) = decode_event(src) {
        let types: Vec<mib::types::PType> = r.def.params.iter().map(|p| p.ptype).collect();
        let args: Vec<i64> = r.params().zip(&types).map(|((_, v), t)| t.saturate(v)).collect();
        let mut buf = vec![0u8; src.len()];
        let n = encode_event(r.def, &args, &mut buf).expect("a decoded event encodes");
        assert_eq!(n, src.len(), "event length");
        let back = decode_event(&buf[..n]).expect("an encoded event decodes");
        let again: Vec<i64> = back.params().map(|(_, v)| v).collect();
        assert_eq!(again, args, "event decode then encode");
    }
}

fn tc(data: &[u8]) {
    let Ok(p) = TcPacket::parse(data) else { return };
    let raw = &data[..p.primary.len];
    let h = TcHeader {
        apid: p.primary.apid,
        seq_count: p.primary.seq_count,
        ack: p.ack,
        service: p.service,
        subservice: p.subservice,
        source_id: p.source_id,
    };
    let mut out = vec![0u8; raw.len()];
    let n = emit_tc(&h, &mut out, |b| {
        b[..p.app_data.len()].copy_from_slice(p.app_data);
        Ok(p.app_data.len())
    })
    .expect("a parsed TC fits its own length");
    assert_eq!(n, raw.len());
    let back = TcPacket::parse(&out[..n]).expect("an emitted TC parses");
    assert_eq!(
        (back.ack, back.service, back.subservice, back.source_id),
        (p.ack, p.service, p.subservice, p.source_id)
    );
    assert_eq!(back.app_data, p.app_data);
    if p.primary.seq_flags == 3 {
        assert_eq!(&out[..n], raw, "TC parse then emit");
    }
    // Arguments against the MIB (PUS 8: the function ID first).
    let (function, args) = match (p.service, p.app_data) {
        (mib::tc::service::FUNCTION, [a, b, rest @ ..]) => (Some(u16::from_be_bytes([*a, *b])), rest),
        (mib::tc::service::FUNCTION, _) => return,
        (_, d) => (None, d),
    };
    let Some(def) = mib::tc::lookup(p.service, p.subservice, function) else {
        return;
    };
    if let Ok((values, rest)) = decode_args(def, args) {
        let mut buf = vec![0u8; def.fixed_len()];
        let n = encode_args(def, &values[..def.args.len()], &mut buf).expect("decoded arguments are in range");
        let fixed = &p.app_data[..p.app_data.len() - rest.len()];
        assert_eq!(&buf[..n], fixed, "arguments decode then encode");
    }
}

fn tm(data: &[u8]) {
    let Ok(p) = TmPacket::parse(data) else { return };
    let raw = &data[..p.primary.len];
    let h = TmHeader {
        apid: p.primary.apid,
        seq_count: p.primary.seq_count,
        service: p.service,
        subservice: p.subservice,
        msg_counter: p.msg_counter,
        dest_id: p.dest_id,
        time: p.time,
    };
    let mut out = vec![0u8; raw.len()];
    let n = emit_tm(&h, &mut out, |b| {
        b[..p.source.len()].copy_from_slice(p.source);
        Ok(p.source.len())
    })
    .expect("a parsed TM fits its own length");
    assert_eq!(n, raw.len());
    let back = TmPacket::parse(&out[..n]).expect("an emitted TM parses");
    assert_eq!(
        (back.service, back.subservice, back.msg_counter, back.dest_id),
        (p.service, p.subservice, p.msg_counter, p.dest_id)
    );
    assert_eq!((back.time, back.source), (p.time, p.source));
    // The emitter writes sequence flags 3 and a zero time-reference status.
    if p.primary.seq_flags == 3 && raw[6] & 0x0F == 0 {
        assert_eq!(&out[..n], raw, "TM parse then emit");
    }
    source_data(p.source);
}

pub fn run(data: &[u8]) {
    tc(data);
    tm(data);
    source_data(data);
}
