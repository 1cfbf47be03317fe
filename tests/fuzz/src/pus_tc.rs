//! Space packets into the OBSW's TC path (`obsw_core::obsw::Obsw::handle_tc`: acceptance
//! checks — header, CRC, APID, MIB lookup, arguments — then verification and execution),
//! interleaved with control ticks against the simulator, the way the host feeds packets
//! that came off the link. The harness follows `obsw/core/tests/fuzz_handle_tc.rs`.
//!
//! Records: body = one TC packet; tag bit 0 repairs its CRC (so mutations reach argument
//! checks and execution), bit 1 runs five 10 ms control ticks after it, bit 2 keeps the
//! packet's sequence count (otherwise it gets a fresh one, so that it is no duplicate).
//!
//! Invariants: nothing panics; each TC with a request ID gets exactly one acceptance
//! report (success or failure), none only when it was accepted and its acknowledgement
//! flags do not ask for one; the OBSW still answers a ping at the end.

use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};

#[derive(Default)]
struct Sink(Vec<Vec<u8>>);
impl TmSink for Sink {
    fn send_tm(&mut self, p: &[u8]) {
        self.0.push(p.to_vec());
    }
}

/// The APID of robot 1, the OBSW under test.
pub const APID: u16 = 0x101;

fn seq(p: &[u8]) -> u16 {
    mib::headers::SeqCount::new(u16::from_be_bytes([p[2], p[3]])).get()
}

fn fix_crc(raw: &mut [u8]) {
    if raw.len() >= 13 {
        let l = raw.len();
        let c = mib_wire::header::crc16(&raw[..l - 2]);
        raw[l - 2..].copy_from_slice(&c.to_be_bytes());
    }
}

/// A PUS TC for robot 1 built with the MIB's emitter.
pub fn tc(seq_count: u16, service: u8, subservice: u8, app: &[u8]) -> Vec<u8> {
    let h = mib_wire::header::TcHeader {
        apid: APID,
        seq_count,
        ack: 0xF,
        service,
        subservice,
        source_id: 0,
    };
    let mut buf = vec![0u8; 1100];
    let n = mib_wire::header::emit_tc(&h, &mut buf, |b| {
        b[..app.len()].copy_from_slice(app);
        Ok(app.len())
    })
    .expect("TC fits");
    buf.truncate(n);
    buf
}

/// Acceptance reports (TM[1,1], TM[1,2]) for `req` sent live by the last call: store
/// replays keep their older sequence counts; copies of one report count once.
fn acceptance_reports(sink: &Sink, req: [u8; 4], newer_than: Option<u16>) -> usize {
    let mut seqs: Vec<u16> = sink
        .0
        .iter()
        .filter(|p| p.len() > 24 && p[7] == 1 && (p[8] == 1 || p[8] == 2) && p[20..24] == req)
        .map(|p| seq(p))
        .filter(|s| newer_than.is_none_or(|n| *s > n))
        .collect();
    seqs.sort_unstable();
    seqs.dedup();
    seqs.len()
}

pub fn run(data: &[u8]) {
    let mut o = Box::new(Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 1_790_000_000_000,
        },
        RingStore::<8192>::default(),
    ));
    let mut sim = mmic_sim::Sim::new(mmic_sim::SimConfig::default());
    let mut sink = Sink::default();
    let mut link = Vec::new();
    let mut now = 0u64;
    let mut last_seq: Option<u16> = None;
    for (k, (tag, body)) in crate::records(data, 32).enumerate() {
        let mut raw = body.to_vec();
        if tag & 4 == 0 && raw.len() >= 4 {
            raw[2] = 0xC0 | ((k >> 8) as u8 & 0x3F);
            raw[3] = k as u8;
        }
        if tag & 1 != 0 {
            fix_crc(&mut raw);
        }
        let before = sink.0.iter().map(|p| seq(p)).max().max(last_seq);
        last_seq = before;
        sink.0.clear();
        o.handle_tc(now, &raw, &mut sink);
        if raw.len() >= 4 {
            let req = [raw[0], raw[1], raw[2], raw[3]];
            let n = acceptance_reports(&sink, req, before);
            let acceptance_not_requested = raw.len() > 6 && raw[6] & 0x08 == 0;
            assert!(
                n == 1 || (n == 0 && acceptance_not_requested),
                "{n} acceptance reports for {raw:02x?}"
            );
        }
        if tag & 2 != 0 {
            for _ in 0..5 {
                now += 10;
                let s = sim.sensors_a();
                let out = o.tick(now, &s, &link, &mut sink);
                link.clear();
                sim.step(10, &out.actuators, &out.link_tx, &mut link);
            }
        }
    }
    sink.0.clear();
    let ping = tc(mib::headers::SeqCount::MASK, 17, 1, &[]);
    // As a packet the link delivered once: a fuzzed copy of this very ping earlier must not
    // make it a duplicate (answered, not executed).
    o.handle_tc_delivered_once(now + 1, &ping, &mut sink);
    assert!(
        sink.0.iter().any(|p| p.len() > 8 && p[7] == 17 && p[8] == 2),
        "the OBSW no longer answers a ping"
    );
}
