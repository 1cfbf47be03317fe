//! CFDP PDUs from the space link into the robot's file service: space packets of the CFDP
//! APID into `mmic_cfdp::Entity::receive_packet` (packet, PDU gate, the cfdp-rs handlers, the
//! entity's user procedures, the file store), as the host obsw feeds them after SDLS and
//! COP-1. A ground entity beside it makes real transactions (puts, gets, listings, deletes),
//! so that fuzzed PDUs also reach a handler in the middle of one.
//!
//! Records: tag % 5 == 0: one raw packet into the robot; 1: the ground's next PDU, its bytes
//! XORed with the body from byte `body[0]` on (a damaged real PDU), wrapped and into the
//! robot; 2: the ground starts a transaction (`body[0]` chooses which); 3: time passes
//! (`body[0..2]` × 10 ms) and both entities poll, the robot as a board paces it when there
//! is a `body[2]` (`Entity::poll_paced`: `Quiet`, or at most 0..=3 segments); 4: the link
//! carries every waiting PDU both ways (`body[0]`'s bits drop some downlink PDUs).
//!
//! Invariants: nothing panics; every packet moves exactly one of the robot's `received`,
//! `refused` and `stray` counters by one; a packet that is not a well-formed PDU packet
//! addressed to the robot is counted `refused` and changes no file of the robot's store;
//! every PDU the robot sends is well formed; a paced poll sends no more file data PDUs than
//! its pace allows (none when quiet).

use mmic_cfdp::entity::{well_formed, Counters, Pace};
use mmic_cfdp::packet::{self, Direction};
use mmic_cfdp::spacepackets::cfdp::{pdu::PduHeader, PduType};
use mmic_cfdp::store::MemStore;
use mmic_cfdp::{Class, Entity, FileName, Parts};

type Mem = MemStore<8, 8_192>;

const ROBOT: u16 = 1;
const GROUND: u16 = 0;

/// The robot's files as (name, length, content), to see that a refused packet changed none.
fn files(p: &Parts<Mem>) -> Vec<(String, Vec<u8>)> {
    let mut names = Vec::new();
    let _ = p.store.list(&mut |n, len| names.push((n.clone(), len)));
    names
        .into_iter()
        .map(|(n, len)| {
            let mut buf = vec![0u8; len as usize];
            let _ = p.store.read(&n, 0, &mut buf);
            (n.as_str().to_string(), buf)
        })
        .collect()
}

fn moved(before: Counters, after: Counters) -> (u32, u32, u32) {
    (
        after.received.wrapping_sub(before.received),
        after.refused.wrapping_sub(before.refused),
        after.stray.wrapping_sub(before.stray),
    )
}

/// One packet into the robot, with the invariants checked.
fn feed(now: u64, robot: &mut Entity<Mem>, rp: &Parts<Mem>, pkt: &[u8]) {
    let malformed = match packet::unwrap(Direction::Up, pkt) {
        None => true,
        Some(pdu) => well_formed(pdu).is_none(),
    };
    let before = robot.counters();
    let store = malformed.then(|| files(rp));
    robot.receive_packet(now, Direction::Up, pkt);
    let m = moved(before, robot.counters());
    assert_eq!(m.0 + m.1 + m.2, 1, "one packet, one count: {m:?}");
    if let Some(store) = store {
        assert_eq!(m, (0, 1, 0), "a malformed packet is counted as refused");
        assert_eq!(files(rp), store, "a malformed packet changed the store");
    }
}

fn wrap(dir: Direction, pdu: &[u8]) -> Option<Vec<u8>> {
    let mut buf = [0u8; mib::cfdp::MAX_PACKET_LEN];
    packet::wrap(dir, 0, pdu, &mut buf).map(|n| buf[..n].to_vec())
}

pub fn run(data: &[u8]) {
    let rp = Parts::new(Mem::new(200_000));
    let gp = Parts::new(Mem::new(200_000));
    let name = |s: &str| FileName::new(s).expect("a valid name");
    let seed: Vec<u8> = (0..5_000u32).map(|i| (i * 7 + i / 256) as u8).collect();
    for (p, n) in [(&rp, "r.bin"), (&gp, "g.bin")] {
        p.store.create(&name(n)).expect("room for a file");
        p.store.write(&name(n), 0, &seed).expect("room for its bytes");
    }
    let mut robot = Entity::new(ROBOT, GROUND, &rp);
    let mut ground = Entity::new(GROUND, ROBOT, &gp);
    let mut now = 1_000u64;
    // Downlink PDUs on their way to the ground, uplink ones to the robot.
    let mut up: Vec<Vec<u8>> = Vec::new();
    let mut down: Vec<Vec<u8>> = Vec::new();
    for (tag, body) in crate::records(data, 128) {
        let b0 = body.first().copied().unwrap_or(0);
        match tag % 5 {
            0 => feed(now, &mut robot, &rp, body),
            1 => {
                if up.is_empty() {
                    up.extend(std::iter::from_fn(|| ground.pop()).map(|p| p.to_vec()));
                }
                if up.is_empty() {
                    continue;
                }
                let mut pdu = up.remove(0);
                let at = usize::from(b0);
                for (i, x) in body.iter().skip(1).enumerate() {
                    if let Some(b) = pdu.get_mut(at + i) {
                        *b ^= x;
                    }
                }
                if let Some(pkt) = wrap(Direction::Up, &pdu) {
                    feed(now, &mut robot, &rp, &pkt);
                }
            }
            2 => {
                let _ = match b0 % 6 {
                    0 => ground.put(now, "g.bin", "up.bin", Class::Two),
                    1 => ground.put(now, "g.bin", "up1.bin", Class::One),
                    2 => ground.get(now, "r.bin", "down.bin", Class::Two),
                    3 => ground.list(now, mib::cfdp::LISTING_NAME),
                    4 => ground.filestore(now, "r.bin", Some("s.bin")),
                    _ => ground.filestore(now, "up.bin", None),
                };
            }
            3 => {
                let ms = u64::from(u16::from_be_bytes([b0, body.get(1).copied().unwrap_or(1)]));
                now += ms * 10;
                match body.get(2).map(|x| x % 5) {
                    None => robot.poll(now),
                    Some(x) => {
                        // The robot's PDUs so far go on their way first: what the poll adds
                        // is counted alone.
                        down.extend(std::iter::from_fn(|| robot.pop()).map(|p| p.to_vec()));
                        let (pace, most) = match x {
                            0 => (Pace::Quiet, 0),
                            n => (Pace::Segments(usize::from(n - 1)), usize::from(n - 1)),
                        };
                        robot.poll_paced(now, pace);
                        let added: Vec<Vec<u8>> = std::iter::from_fn(|| robot.pop()).map(|p| p.to_vec()).collect();
                        let data = added
                            .iter()
                            .filter(|p| PduHeader::from_bytes(p).is_ok_and(|(h, _)| h.pdu_type() == PduType::FileData))
                            .count();
                        assert!(data <= most, "{data} file data PDUs in a poll paced {pace:?}");
                        down.extend(added);
                    }
                }
                ground.poll(now);
            }
            _ => {
                up.extend(std::iter::from_fn(|| ground.pop()).map(|p| p.to_vec()));
                for pdu in std::mem::take(&mut up) {
                    if let Some(pkt) = wrap(Direction::Up, &pdu) {
                        feed(now, &mut robot, &rp, &pkt);
                    }
                }
                let mut k = 0;
                down.extend(std::iter::from_fn(|| robot.pop()).map(|p| p.to_vec()));
                for pdu in std::mem::take(&mut down) {
                    assert!(well_formed(&pdu).is_some(), "the robot sent a malformed PDU");
                    k += 1;
                    if b0 & (1 << (k % 8)) == 0 {
                        ground.receive(now, &pdu);
                    }
                }
            }
        }
    }
}
