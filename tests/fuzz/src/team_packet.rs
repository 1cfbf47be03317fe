//! Team messages on the inter-robot link (`mmic_team::wire::Message::parse`) and the
//! election state machine they drive (`mmic_team::Node::on_event`), as the host feeds
//! them after the team link's authentication.
//!
//! Records: tag % 3 == 0: one team datagram's plaintext into robot 1 (roster 1, 2, 3);
//! 1: time passes (body's first two bytes, ms) and the node ticks; 2: a ground TC arrived.
//!
//! Invariants: nothing panics; parse then emit gives back exactly the bytes received (the
//! format has one encoding per message); every message the node sends emits and parses
//! back to itself.

use mmic_team::{Effect, Input, Message, Node};

fn emit(m: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; m.buffer_len()];
    let n = m.emit(&mut buf).expect("buffer of buffer_len");
    buf.truncate(n);
    buf
}

pub fn run(data: &[u8]) {
    let Ok(mut node) = Node::new(1, &[1, 2, 3], 0) else {
        unreachable!("a valid roster")
    };
    let mut now = 0u64;
    for (k, (tag, body)) in crate::records(data, 64).enumerate() {
        let input = match tag % 3 {
            0 => match Message::parse(body) {
                Ok(m) => {
                    assert_eq!(emit(&m), body, "parse then emit");
                    Input::Message(m)
                }
                Err(_) => continue,
            },
            1 => {
                now += u64::from(u16::from_be_bytes([
                    body.first().copied().unwrap_or(0),
                    body.get(1).copied().unwrap_or(100),
                ]));
                Input::Tick
            }
            _ => Input::GroundTc,
        };
        for e in node.on_event(now, (k as u32).wrapping_mul(2_654_435_761), input) {
            if let Effect::Send { msg, .. } = e {
                assert_eq!(Message::parse(&emit(&msg)), Ok(msg), "a sent message round trip");
            }
        }
    }
}
