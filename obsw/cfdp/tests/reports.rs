//! Each transaction's end is reported once (`Entity::take_finished`), however often its
//! closing PDUs come again: the housekeeping's completed and failed counts and the
//! FILE_TRANSFER_* events are made from these reports.

use mmic_cfdp::spacepackets::cfdp::pdu::FileDirectiveType;
use mmic_cfdp::store::MemStore;
use mmic_cfdp::{Class, Entity, FileName, Parts};

const EOF: u8 = FileDirectiveType::EofPdu as u8;
const FINISHED: u8 = FileDirectiveType::FinishedPdu as u8;

type Mem = MemStore<4, 40_000>;

fn directive(p: &[u8]) -> Option<u8> {
    let (h, hl) = mmic_cfdp::spacepackets::cfdp::pdu::PduHeader::from_bytes(p).ok()?;
    (h.pdu_type() == mmic_cfdp::spacepackets::cfdp::PduType::FileDirective).then(|| p[hl])
}

// A link that repeats the sender's EOF and the receiver's Finished after the transaction
// ended (a serial link's retries, the relay's duplicates): one report each side.
// verifies: FILE-EV-01
#[test]
fn a_transaction_whose_closing_pdus_come_again_is_reported_finished_once() {
    std::thread::Builder::new()
        .stack_size(16 << 20)
        .spawn(|| {
            let (gp, rp) = (Parts::new(Mem::new(100_000)), Parts::new(Mem::new(100_000)));
            let mut g = Entity::new(0, 1, &gp);
            let mut r = Entity::new(1, 0, &rp);
            let n = FileName::new("up.bin").unwrap();
            let data: Vec<u8> = (0..20_000u32).map(|i| (i * 7) as u8).collect();
            gp.store.create(&n).unwrap();
            gp.store.write(&n, 0, &data).unwrap();
            g.put(0, "up.bin", "up.bin", Class::Two).unwrap();
            let (mut eof, mut fin, mut again) = (None, None, false);
            let mut t = 0;
            let (mut g_reports, mut r_reports) = (Vec::new(), Vec::new());
            while t < 20_000 {
                t += 10;
                g.poll(t);
                r.poll(t);
                while let Some(p) = g.pop() {
                    if directive(&p) == Some(EOF) {
                        eof = Some(p.to_vec());
                    }
                    r.receive(t, &p);
                }
                while let Some(p) = r.pop() {
                    if directive(&p) == Some(FINISHED) {
                        fin = Some(p.to_vec());
                        // The EOF again while the robot waits for its Finished's ACK (once:
                        // the robot answers it with its Finished again).
                        if let Some(e) = eof.as_ref().filter(|_| !again) {
                            again = true;
                            r.receive(t, e);
                        }
                    }
                    g.receive(t, &p);
                }
                // After the end, every 100 ms: the EOF and the Finished again.
                if g.idle() && r.idle() && t % 100 == 0 && t < 2_000 {
                    if let (Some(e), Some(f)) = (&eof, &fin) {
                        r.receive(t, e);
                        g.receive(t, f);
                    }
                }
                g_reports.extend(std::iter::from_fn(|| g.take_finished()));
                r_reports.extend(std::iter::from_fn(|| r.take_finished()));
            }
            assert_eq!(g_reports.len(), 1, "the ground's: {g_reports:?}");
            assert_eq!(r_reports.len(), 1, "the robot's: {r_reports:?}");
            assert!(g_reports[0].complete && r_reports[0].complete);
            assert_eq!((r.counters().completed, g.counters().completed), (1, 1));
            assert!(
                r.counters().repeated_ends >= 1,
                "the repeat was there: {:?}",
                r.counters()
            );
        })
        .unwrap()
        .join()
        .unwrap();
}
