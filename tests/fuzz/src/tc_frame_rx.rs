//! TC transfer frames through the robot's receive pipeline (`mmic_link::rx::TcReceiver`:
//! CRC, lengths, SDLS, FARM-1, packet split), the API the host and the firmware call
//! with each datagram of the frame port.
//!
//! Records (see [`crate::records`]):
//! - tag % 4 == 0: a raw datagram (an attacker's bytes, or a captured frame replayed);
//! - 1: an AD frame sealed here with the TC test key: body = flags, N(S), payload;
//! - 2: a BD frame sealed here: body = flags, payload;
//! - 3: the host releases FARM-1's buffer (E10).
//!
//! Flags: bit 0 wraps the payload in one TC space-packet header (so the frame carries whole
//! packets and reaches FARM-1), bit 1 seals under SPI 2's key, bit 2 claims the buffer is
//! full.
//!
//! Invariants: nothing panics; every datagram moves exactly one outcome counter by one
//! (accepted AD/BD, control, FARM-1 discard by event, or one rejection reason); every
//! accepted frame's packets are whole and are exactly a payload this input sealed with a
//! key (a raw datagram never smuggles in packets of its own: nothing unauthenticated
//! commands the robot).

use mib::link::sdls::ANTI_REPLAY_WINDOW;
use mmic_link::rx::{RxCounters, RxOutcome, TcReceiver};
use mmic_link::sdls::{build_tc, MemoryIvStore, RxSa, RxSas, TxSa};
use mmic_link::tc::{FrameType, TcRepr};
use mmic_link::test_keys::{TEST_KEY_TC_A, TEST_KEY_TC_B};

/// Every counter of an outcome (not `packets`, which counts packets of accepted frames).
fn outcomes(c: &RxCounters) -> u64 {
    [
        c.ad_accepted,
        c.bd_accepted,
        c.unlock,
        c.set_vr,
        c.farm_e2,
        c.farm_e3,
        c.farm_e4,
        c.farm_e5,
    ]
    .iter()
    .map(|v| u64::from(*v))
    .sum::<u64>()
        + u64::from(c.rejected())
}

/// Wraps `body` in a TC space-packet primary header whose length field fits it.
pub fn tc_packet(apid_lo: u8, body: &[u8]) -> Vec<u8> {
    let body: &[u8] = if body.is_empty() { &[0] } else { body };
    let n = (body.len() - 1) as u16;
    let mut p = vec![0x18, apid_lo, 0xC0, 0x00];
    p.extend_from_slice(&n.to_be_bytes());
    p.extend_from_slice(body);
    p
}

pub fn run(data: &[u8]) {
    let mut sas = RxSas::default();
    let _ = sas.insert(RxSa::new(1, &TEST_KEY_TC_A, ANTI_REPLAY_WINDOW));
    let _ = sas.insert(RxSa::new(2, &TEST_KEY_TC_B, ANTI_REPLAY_WINDOW));
    let mut rx: TcReceiver<2> = TcReceiver::mission(sas);
    let mut store = MemoryIvStore::default();
    let mut tx = [TxSa::resume(1, &TEST_KEY_TC_A, 0), TxSa::resume(2, &TEST_KEY_TC_B, 0)];
    let mut tx_store = MemoryIvStore::default();
    // Payloads sealed with a key in this input.
    let mut sealed: Vec<Vec<u8>> = Vec::new();

    for (tag, body) in crate::records(data, 64) {
        let flags = body.first().copied().unwrap_or(0);
        let mut buffer_full = false;
        let mut datagram = match tag % 4 {
            0 => body.to_vec(),
            t @ (1 | 2) => {
                let (seq, rest) = match (t, body) {
                    (1, [_, ns, rest @ ..]) => (*ns, rest),
                    (2, [_, rest @ ..]) => (0, rest),
                    _ => continue,
                };
                let payload = if flags & 1 != 0 {
                    tc_packet(0x65, rest)
                } else {
                    rest.to_vec()
                };
                buffer_full = flags & 4 != 0;
                let header = TcRepr {
                    frame_type: if t == 1 { FrameType::Ad } else { FrameType::Bd },
                    scid: mib::link::SCID,
                    vcid: mib::link::tc_vc::COMMAND,
                    seq,
                    data_len: 0,
                };
                let sa = &mut tx[usize::from(flags >> 1 & 1)];
                let mut buf = [0u8; mib::link::tc_frame::MAX_LEN];
                let Ok(n) = build_tc(sa, &mut tx_store, header, &payload, &mut buf) else {
                    continue;
                };
                sealed.push(payload);
                buf[..n].to_vec()
            }
            _ => {
                rx.buffer_released();
                continue;
            }
        };
        let before = outcomes(&rx.counters);
        let raw = tag % 4 == 0;
        match rx.receive(&mut store, &mut datagram, !buffer_full) {
            RxOutcome::Accepted { packets, .. } => {
                let mut joined = Vec::new();
                for p in packets {
                    assert!(p.len() >= 7, "accepted packet shorter than a header: {p:02x?}");
                    assert_eq!(
                        usize::from(u16::from_be_bytes([p[4], p[5]])) + 7,
                        p.len(),
                        "packet length field"
                    );
                    joined.extend_from_slice(p);
                }
                assert!(
                    sealed.contains(&joined),
                    "accepted packets that no key sealed (raw datagram: {raw}): {joined:02x?}"
                );
            }
            RxOutcome::Control(_) | RxOutcome::Discarded(_) | RxOutcome::Rejected(_) => {}
        }
        assert_eq!(
            outcomes(&rx.counters),
            before + 1,
            "a datagram not counted exactly once"
        );
    }
}
