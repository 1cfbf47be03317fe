//! The A–B link: COBS frames with a CRC between board A (`mmic_domain::ablink::
//! LinkManager::receive`) and board B (`mmic_domain::board_b::BoardB::tick`), both fed
//! the bytes of the serial line.
//!
//! Records:
//! - tag % 3 == 0: bytes on the line into board A (acks, heartbeats, module chunks);
//! - 1: bytes on the line into board B (commands); B's answer goes to A;
//! - 2: A queues the command body[0] selects and transmits; the frame goes to B.
//!
//! Invariants: nothing panics; every frame B's decoder completes moves exactly one of B's
//! counters (executed, duplicate, frame error); B acknowledges every command it took
//! (executed or duplicate) or counts the frame its transmit buffer could not take; every
//! message either board's decoder accepts encodes and decodes back to itself.

use heapless::Vec as HVec;
use mmic_domain::ablink::{FrameDecoder, LinkManager, Message, ModuleCmd};
use mmic_domain::board_b::{BoardB, BoardBOut};
use mmic_domain::types::{BolterDrive, SensorsB};

/// Every message a decoder accepted: emit, then parse, gives it back.
fn round_trip(m: &Message) {
    let mut wire: HVec<u8, 512> = HVec::new();
    m.encode(&mut wire).expect("one frame fits");
    let mut d = FrameDecoder::new();
    let back: Vec<_> = wire.iter().filter_map(|b| d.push(*b)).collect();
    assert_eq!(back, [Ok(*m)], "encode then decode");
}

/// Feeds `bytes` to a shadow decoder (the same state as the board's); returns the number
/// of frames it completed (accepted or refused).
fn shadow(d: &mut FrameDecoder, bytes: &[u8]) -> u32 {
    let mut n = 0;
    for &b in bytes {
        if let Some(r) = d.push(b) {
            n += 1;
            if let Ok(m) = r {
                round_trip(&m);
            }
        }
    }
    n
}

fn command(sel: &[u8]) -> ModuleCmd {
    let b = |i: usize| sel.get(i).copied().unwrap_or(0);
    let w = |i: usize| u16::from_be_bytes([b(i), b(i + 1)]);
    match b(0) % 7 {
        0 => ModuleCmd::ArmTarget(w(1)),
        1 => ModuleCmd::GripTarget(w(1)),
        2 => ModuleCmd::Bolter {
            drive: BolterDrive::from_code(b(1) % 6).unwrap_or_default(),
            pair: b(2),
        },
        3 => ModuleCmd::Power {
            arm: b(1),
            grip: b(2),
            bolter: b(3),
        },
        4 => ModuleCmd::Stop,
        5 => ModuleCmd::Assume { arm: w(1), grip: w(3) },
        _ => ModuleCmd::SendModules,
    }
}

pub fn run(data: &[u8]) {
    let mut a = LinkManager::new();
    let mut b = BoardB::new();
    let (mut shadow_a, mut shadow_b) = (FrameDecoder::new(), FrameDecoder::new());
    let sensors = SensorsB {
        v_bat: 2900,
        grav: [0, 0, 1000],
        arm_switch: true,
        ..SensorsB::default()
    };
    let mut out = BoardBOut::default();
    let mut now = 0u64;
    for (tag, body) in crate::records(data, 64) {
        now += 10;
        let to_b: Vec<u8> = match tag % 3 {
            0 => {
                shadow(&mut shadow_a, body);
                a.receive(now, body);
                continue;
            }
            1 => body.to_vec(),
            _ => {
                a.send(command(body));
                let mut tx: HVec<u8, 256> = HVec::new();
                a.transmit(now, 60, 3, &mut tx);
                tx.to_vec()
            }
        };
        let before = *b.counters();
        let frames = shadow(&mut shadow_b, &to_b);
        b.tick(now, &sensors, &to_b, &mut out);
        let after = *b.counters();
        let taken = (after.commands - before.commands) + (after.duplicates - before.duplicates);
        assert_eq!(
            taken + (after.frame_errors - before.frame_errors),
            frames,
            "a frame board B received moved no counter or two"
        );
        // B's answer: one Ack per command taken (or one overflow counted), perhaps a
        // heartbeat or module chunk; all of it well formed.
        let mut d = FrameDecoder::new();
        let mut acks = 0;
        for &x in out.tx.iter() {
            if let Some(r) = d.push(x) {
                let m = r.expect("board B sends well-formed frames");
                acks += u32::from(matches!(m, Message::Ack { .. }));
            }
        }
        // An Ack that did not fit is counted in `tx_overflow`, like a heartbeat or module
        // chunk that did not: every command taken is acknowledged or counted.
        let overflow = after.tx_overflow - before.tx_overflow;
        assert!(
            acks <= taken && taken - acks <= overflow,
            "{taken} commands taken, {acks} acknowledged, {overflow} frames overflowed"
        );
        shadow(&mut shadow_a, &out.tx);
        a.receive(now, &out.tx);
    }
}
