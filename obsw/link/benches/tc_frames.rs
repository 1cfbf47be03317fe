//! Authenticated TC frames accepted per second on one core through the full receive pipeline
//! (CRC → lengths → SDLS AES-256-GCM → packet lengths → FARM-1 → packet iteration), against
//! two baselines measured in the same run: the CRC + header check alone, and the raw
//! AES-256-GCM verify-and-decrypt of the same frames.
//!
//! `cargo bench -p mmic-link --bench tc_frames`
//! Each iteration processes a batch of 256 frames (N(S) 0..=255, IVs 0..=255); criterion's
//! throughput line is frames per second.

use std::hint::black_box;
use std::time::{Duration, Instant};

use aes_gcm::aead::AeadInPlace;
use aes_gcm::{Aes256Gcm, KeyInit, Nonce, Tag};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use mmic_link::farm::Farm;
use mmic_link::rx::{RxOutcome, TcReceiver};
use mmic_link::sdls::{build_tc, MemoryIvStore, RxSa, RxSas, TxSa, TC_AUTH_MASK};
use mmic_link::tc::{FrameType, TcFrame, TcRepr};
use mmic_link::test_keys::TEST_KEY_TC_A;

const BATCH: usize = 256;

fn frames(packet_len: usize) -> Vec<Vec<u8>> {
    let mut sa = TxSa::resume(1, &TEST_KEY_TC_A, 0);
    let mut st = MemoryIvStore::default();
    let mut p = vec![0u8; packet_len];
    p[0] = 0x18;
    p[1] = 0x64;
    p[2] = 0xC0;
    let n = (packet_len - 7) as u16;
    p[4..6].copy_from_slice(&n.to_be_bytes());
    (0..BATCH)
        .map(|s| {
            let mut buf = [0u8; 1024];
            let h = TcRepr {
                frame_type: FrameType::Ad,
                scid: mib::link::SCID,
                vcid: 0,
                seq: s as u8,
                data_len: 0,
            };
            let n = build_tc(&mut sa, &mut st, h, &p, &mut buf).unwrap();
            buf[..n].to_vec()
        })
        .collect()
}

fn receiver() -> TcReceiver<2> {
    let mut sas = RxSas::default();
    sas.insert(RxSa::new(1, &TEST_KEY_TC_A, BATCH as u64)).unwrap();
    TcReceiver::new(mib::link::SCID, 0, Farm::new(0, 254), sas)
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("tc_frames");
    g.throughput(Throughput::Elements(BATCH as u64));
    g.measurement_time(Duration::from_secs(4));
    for packet_len in [64usize, 987] {
        let fs = frames(packet_len);
        let mut buf = vec![0u8; 1024];

        g.bench_with_input(BenchmarkId::new("pipeline", packet_len), &fs, |b, fs| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let mut rx = receiver();
                    let mut st = MemoryIvStore::default();
                    let t = Instant::now();
                    for f in fs {
                        let d = &mut buf[..f.len()];
                        d.copy_from_slice(f);
                        match rx.receive(&mut st, d, true) {
                            RxOutcome::Accepted { packets, .. } => {
                                for p in packets {
                                    black_box(p);
                                }
                            }
                            other => panic!("not accepted: {other:?}"),
                        }
                    }
                    total += t.elapsed();
                }
                total
            })
        });

        g.bench_with_input(BenchmarkId::new("baseline_crc_header", packet_len), &fs, |b, fs| {
            b.iter(|| {
                for f in fs {
                    let d = &mut buf[..f.len()];
                    d.copy_from_slice(f);
                    let v = TcFrame::new_checked(&*d).unwrap();
                    assert!(v.check_fecf());
                    black_box(v.seq());
                }
            })
        });

        let cipher = Aes256Gcm::new((&TEST_KEY_TC_A).into());
        g.bench_with_input(BenchmarkId::new("baseline_raw_aes_gcm", packet_len), &fs, |b, fs| {
            b.iter(|| {
                for f in fs {
                    let d = &mut buf[..f.len()];
                    d.copy_from_slice(f);
                    let mut aad = [0u8; 19];
                    for (a, (x, m)) in aad.iter_mut().zip(d.iter().zip(TC_AUTH_MASK.iter())) {
                        *a = x & m;
                    }
                    let mac = d.len() - 18;
                    let tag = *Tag::from_slice(&d[mac..mac + 16]);
                    let nonce = *Nonce::from_slice(&d[7..19]);
                    cipher
                        .decrypt_in_place_detached(&nonce, &aad, &mut d[19..mac], &tag)
                        .unwrap();
                    black_box(&d[19..mac]);
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
