//! One request ID from ground to robot and back: the ground builds a
//! TC, the obsw accepts (or refuses) it and reports in PUS 1, the ground decodes the
//! reports — and every side holds the same `mib_wire::RequestId`, the one type.

use ground_pus::{build_tc, decode_tm, BuiltTc, TmBody};
use mib::config::reset_cause;
use mib_wire::RequestId;
use obsw_core::accept::accept;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};
use proptest::prelude::*;

/// Robot 1's obsw (APID 0x101).
const ROBOT: u8 = 1;

#[derive(Default)]
struct Log(Vec<Vec<u8>>);

impl TmSink for Log {
    fn send_tm(&mut self, p: &[u8]) {
        self.0.push(p.to_vec());
    }
}

/// Hands `raw` to a freshly booted obsw of robot 1 and returns the subservice and the
/// decoded request of every PUS 1 report it sent for it.
fn reports_of(raw: &[u8]) -> Vec<(u8, RequestId)> {
    let mut obsw = Obsw::new(
        Config {
            robot: ROBOT,
            epoch_unix_ms: 1_790_000_000_000,
        },
        RingStore::<8192>::default(),
    );
    let mut log = Log::default();
    obsw.boot(0, reset_cause::POWER_ON, &mut log);
    log.0.clear();
    obsw.handle_tc(1_000, raw, &mut log);
    log.0
        .iter()
        .filter_map(|p| {
            let tm = decode_tm(p).expect("the ground decodes the obsw's TM");
            match tm.body {
                TmBody::Verification(v) => Some((tm.subservice, v.request)),
                _ => None,
            }
        })
        .collect()
}

fn ping(robot: u8, seq: u16) -> BuiltTc {
    build_tc(robot, seq, mib::tc::by_name("PING").unwrap(), &[]).unwrap()
}

/// The request ID of `tc` is the same on every side: the ground's builder, the one read
/// from the bytes, the obsw's acceptance (or refusal), and the decoded reports (`subs`:
/// the PUS 1 subservices expected).
fn same_everywhere(tc: &BuiltTc, raw: &[u8], subs: &[u8]) -> Result<(), TestCaseError> {
    let r = RequestId::of_tc(raw).unwrap();
    prop_assert_eq!(tc.request_id(), r);
    prop_assert_eq!((r.apid(), r.seq()), (tc.apid, tc.seq));
    let on_board = match accept(raw, mib::apid::robot_apid(ROBOT).unwrap()) {
        Ok(t) => Some(t.req),
        Err(rej) => rej.req,
    };
    prop_assert_eq!(on_board, Some(r));
    let reports = reports_of(raw);
    prop_assert_eq!(reports.iter().map(|(s, _)| *s).collect::<Vec<_>>(), subs.to_vec());
    for (_, got) in reports {
        prop_assert_eq!(got, r);
    }
    Ok(())
}

proptest! {
    // verifies: CODEC-RID-01
    #[test]
    fn ground_obsw_and_reports_hold_the_same_request_id(seq in 0u16..=mib::headers::SeqCount::MASK) {
        // Accepted and completed: TM[1,1] and TM[1,7].
        let tc = ping(ROBOT, seq);
        same_everywhere(&tc, &tc.bytes, &[1, 7])?;
        // Refused at acceptance for another robot's APID: TM[1,2].
        let other = ping(ROBOT + 1, seq);
        same_everywhere(&other, &other.bytes, &[2])?;
        // Refused at acceptance for a corrupt CRC: TM[1,2] still names the request.
        let mut bad = tc.bytes.clone();
        *bad.last_mut().unwrap() ^= 0xFF;
        same_everywhere(&tc, &bad, &[2])?;
    }
}
