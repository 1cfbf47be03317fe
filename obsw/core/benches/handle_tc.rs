//! TCs per second the OBSW core accepts and verifies on one core, without sockets:
//! `cargo bench -p obsw-core --bench handle_tc`. Baseline in the same run: acceptance
//! checks alone (parse + CRC + MIB lookup), so the ratio shows what verification,
//! duplicate suppression, TM building and storage cost on top.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use obsw_core::accept::accept;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};

use arbitrary_int::{u11, u14};
use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId};
use satrs::spacepackets::SpHeader;

struct Count(usize);
impl TmSink for Count {
    fn send_tm(&mut self, p: &[u8]) {
        self.0 += p.len();
    }
}

fn pings(n: usize) -> Vec<Vec<u8>> {
    (0..n)
        .map(|i| {
            let sp = SpHeader::new_for_unseg_tc(
                u11::new(0x101),
                u14::new(mib::headers::SeqCount::new(i as u16).get()),
                0,
            );
            let sec = PusTcSecondaryHeader::new(MessageTypeId::new(17, 1), AckFlags::ALL, 0);
            let mut buf = vec![0u8; 64];
            let k = PusTcCreator::new(sp, sec, &[], CreatorConfig::default())
                .write_to_bytes(&mut buf)
                .unwrap();
            buf.truncate(k);
            buf
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    const N: usize = 1000;
    let tcs = pings(N);
    let mut g = c.benchmark_group("tc");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("accept_only", |b| {
        b.iter(|| tcs.iter().filter(|t| accept(t, 0x101).is_ok()).count());
    });
    g.bench_function("handle_tc_ping_verified", |b| {
        b.iter_batched(
            || {
                Box::new(Obsw::new(
                    Config {
                        robot: 1,
                        epoch_unix_ms: 1_790_000_000_000,
                    },
                    RingStore::<65536>::default(),
                ))
            },
            |mut o| {
                let mut sink = Count(0);
                for (i, t) in tcs.iter().enumerate() {
                    // 100 s apart so the duplicate window never matches a wrapped count.
                    o.handle_tc(i as u64, t, &mut sink);
                }
                sink.0
            },
            BatchSize::LargeInput,
        );
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
