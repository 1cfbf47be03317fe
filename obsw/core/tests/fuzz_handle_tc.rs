//! Fuzzing of the whole TC path with proptest (the stable toolchain here has no
//! libFuzzer): a seed corpus of one valid TC per MIB telecommand, mutated by random
//! byte flips, truncation, extension and argument values, is fed to `Obsw::handle_tc`
//! interleaved with control ticks against the simulator. Properties: nothing panics,
//! every TC with a request ID is answered by exactly one acceptance report (none if it
//! is accepted and its acknowledgement flags do not ask for one), and the
//! OBSW still answers a ping afterwards.

use arbitrary_int::{u11, u14};
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};
use proptest::prelude::*;
use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId};
use satrs::spacepackets::SpHeader;

#[derive(Default)]
struct Sink(Vec<Vec<u8>>);
impl TmSink for Sink {
    fn send_tm(&mut self, p: &[u8]) {
        self.0.push(p.to_vec());
    }
}

fn tc(seq: u16, svc: u8, sub: u8, app: &[u8]) -> Vec<u8> {
    let sp = SpHeader::new_for_unseg_tc(u11::new(0x101), u14::new(mib::headers::SeqCount::new(seq).get()), 0);
    let sec = PusTcSecondaryHeader::new(MessageTypeId::new(svc, sub), AckFlags::ALL, 0);
    let mut buf = vec![0u8; 1100];
    let n = PusTcCreator::new(sp, sec, app, CreatorConfig::default())
        .write_to_bytes(&mut buf)
        .unwrap();
    buf.truncate(n);
    buf
}

/// One valid TC per MIB definition, arguments at their minimum.
fn corpus() -> Vec<Vec<u8>> {
    mib::tc::TCS
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let args: Vec<i64> = d.args.iter().map(|a| a.min).collect();
            let mut app = vec![0u8; 64];
            let n = mib_wire::codec::encode_args(d, &args, &mut app).unwrap();
            tc(i as u16, d.service, d.subservice, &app[..n])
        })
        .collect()
}

fn seq(p: &[u8]) -> u16 {
    mib::headers::SeqCount::new(u16::from_be_bytes([p[2], p[3]])).get()
}

/// Acceptance reports for a request emitted live by this call: a store downlink (PUS
/// 15) replays older packets, which keep their original (lower) sequence counts and
/// may belong to an earlier mutant whose request ID happens to collide.
/// A downlink in this very call also replays this call's own report: copies (same
/// sequence count) count once.
fn acceptance_reports(sink: &Sink, req: [u8; 4], newer_than: Option<u16>) -> usize {
    let mut seqs: Vec<u16> = sink
        .0
        .iter()
        .filter(|p| p.len() > 24 && p[7] == 1 && (p[8] == 1 || p[8] == 2) && p[20..24] == req)
        .map(|p| seq(p))
        .filter(|s| newer_than.is_none_or(|n| *s > n))
        .collect();
    seqs.sort();
    seqs.dedup();
    seqs.len()
}

#[derive(Debug, Clone)]
enum Mutation {
    Flip(usize, u8),
    Truncate(usize),
    Extend(Vec<u8>),
    Arg(usize, u8),
    FixCrc,
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (0usize..64, 1u8..=255).prop_map(|(i, b)| Mutation::Flip(i, b)),
        (0usize..64).prop_map(Mutation::Truncate),
        proptest::collection::vec(any::<u8>(), 1..40).prop_map(Mutation::Extend),
        (0usize..16, any::<u8>()).prop_map(|(i, b)| Mutation::Arg(i, b)),
        Just(Mutation::FixCrc),
    ]
}

fn apply(raw: &mut Vec<u8>, m: &Mutation) {
    match m {
        Mutation::Flip(i, b) => {
            let n = raw.len();
            if n > 0 {
                raw[*i % n] ^= b;
            }
        }
        Mutation::Truncate(k) => raw.truncate(*k % (raw.len() + 1)),
        Mutation::Extend(v) => raw.extend_from_slice(v),
        // Change an application-data byte and repair the CRC, so the mutation reaches
        // argument checks and execution instead of stopping at the CRC.
        Mutation::Arg(i, b) => {
            if raw.len() > 13 {
                let n = raw.len() - 13;
                raw[11 + i % n] = *b;
            }
            fix_crc(raw);
        }
        Mutation::FixCrc => fix_crc(raw),
    }
}

fn fix_crc(raw: &mut [u8]) {
    if raw.len() >= 13 {
        let l = raw.len();
        let c = satrs::spacepackets::crc::CRC_CCITT_FALSE.checksum(&raw[..l - 2]);
        raw[l - 2..].copy_from_slice(&c.to_be_bytes());
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]
    // verifies: PUS-1-04, DD-ROBUST-01
    #[test]
    fn mutated_tcs_never_panic_and_each_gets_one_acceptance_report(
        picks in proptest::collection::vec((0usize..64, proptest::collection::vec(mutation(), 1..4)), 1..40)
    ) {
        let corpus = corpus();
        let mut o = Box::new(Obsw::new(Config { robot: 1, epoch_unix_ms: 1_790_000_000_000 }, RingStore::<8192>::default()));
        let mut sim = mmic_sim::Sim::new(mmic_sim::SimConfig::default());
        let mut sink = Sink::default();
        let mut link = Vec::new();
        let mut now = 0u64;
        // Highest TM sequence count seen so far (fewer than 16384 packets per case).
        let mut last_seq: Option<u16> = None;
        for (k, (pick, muts)) in picks.iter().enumerate() {
            let mut raw = corpus[pick % corpus.len()].clone();
            // A fresh sequence count per TC, so no mutant is a duplicate of another.
            raw[2] = 0xC0 | ((k >> 8) as u8 & 0x3F);
            raw[3] = k as u8;
            fix_crc(&mut raw);
            for m in muts {
                apply(&mut raw, m);
            }
            // Everything sent so far (TC reports and the ticks' TM) is older than what
            // this TC's handling sends live.
            let before = sink.0.iter().map(|p| seq(p)).max().max(last_seq);
            last_seq = before;
            sink.0.clear();
            o.handle_tc(now, &raw, &mut sink);
            if raw.len() >= 4 {
                let req = [raw[0], raw[1], raw[2], raw[3]];
                let n = acceptance_reports(&sink, req, before);
                // Exactly one, except that an accepted TC whose acknowledgement flags do
                // not ask for acceptance gets none (a refusal is always reported).
                let acceptance_not_requested = raw.len() > 6 && raw[6] & 0x08 == 0;
                prop_assert!(n == 1 || (n == 0 && acceptance_not_requested), "{} acceptance reports for {:02x?}", n, raw);
            }
            for _ in 0..5 {
                now += 10;
                let s = sim.sensors_a();
                let out = o.tick(now, &s, &link, &mut sink);
                link.clear();
                sim.step(10, &out.actuators, &out.link_tx, &mut link);
            }
        }
        sink.0.clear();
        let ping = tc(mib::headers::SeqCount::MASK, 17, 1, &[]);
        o.handle_tc(now + 1, &ping, &mut sink);
        prop_assert!(sink.0.iter().any(|p| p.len() > 8 && p[7] == 17 && p[8] == 2), "still answers a ping");
    }
}
