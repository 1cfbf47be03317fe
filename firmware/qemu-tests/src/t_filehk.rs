//! Board A's file service reporting to the OBSW (`FileService::report`, once per control
//! period after `poll`): HK FILES gets its values and each transaction raises
//! FILE_TRANSFER_STARTED and FILE_TRANSFER_COMPLETED, as on the host obsw. A ground CFDP
//! entity in this binary (the same `mmic_cfdp::Entity`) exchanges PDU packets with the
//! board's file service directly (the frame link is `t_files`' business): a class 2 put,
//! then a get back.
//!
//! Measured: the instructions of the report in its costliest period (a transaction ended:
//! its event, the store counted, the counters compared for refusal events), which the
//! control period adds to the file service's poll.

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::files::{FileService, Files};
use mib::cfdp::{GROUND_ENTITY_ID, MAX_PACKET_LEN};
use mib::events::eid;
use mib::params::pid;
use mmic_cfdp::packet::{self, Direction};
use mmic_cfdp::store::MemStore;
use mmic_cfdp::{Class, Entity, FileName, Parts};
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::{RingStore, TmSink};
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::PusPacket;

pub const TESTS: &[Test] = tests![board_a_s_file_service_reports_hk_files_and_each_transfer_s_events_each_period];

type Mem = MemStore<2, 8192>;

/// What the OBSW sent: the file service's events.
#[derive(Default)]
struct Events {
    started: u32,
    completed: u32,
    failed: u32,
    refused: u32,
}

impl TmSink for Events {
    fn send_tm(&mut self, packet: &[u8]) {
        let Ok(r) = PusTmReader::new(packet, mib::config::TIMESTAMP_LEN) else {
            return;
        };
        if PusPacket::service_type_id(&r) != 5 {
            return;
        }
        let Ok(ev) = mib_wire::codec::decode_event(r.user_data()) else {
            return;
        };
        match ev.def.id {
            eid::FILE_TRANSFER_STARTED => self.started += 1,
            eid::FILE_TRANSFER_COMPLETED => self.completed += 1,
            eid::FILE_TRANSFER_FAILED => self.failed += 1,
            eid::FILE_REFUSED => self.refused += 1,
            _ => {}
        }
    }
}

/// The board's file packets, straight to the ground's entity.
struct ToGround<'e, 'a> {
    ground: &'e mut Entity<'a, Mem>,
    now: u64,
}

impl TmSink for ToGround<'_, '_> {
    fn send_tm(&mut self, packet: &[u8]) {
        self.ground.receive_packet(self.now, Direction::Down, packet);
    }
}

fn instret() -> u64 {
    riscv::register::minstret::read64()
}

// verifies: FILE-HK-01, FILE-EV-01
fn board_a_s_file_service_reports_hk_files_and_each_transfer_s_events_each_period() -> TestResult {
    let board_parts = Parts::new(Mem::new(16_384));
    let ground_parts = Parts::new(Mem::new(16_384));
    let mut files = Files::new(1, &board_parts);
    let mut ground = Entity::new(GROUND_ENTITY_ID, mib::cfdp::robot_entity_id(1), &ground_parts);
    let mut obsw: Obsw<RingStore<4096>> = Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 0,
        },
        RingStore::default(),
    );
    let mut events = Events::default();
    check!(
        obsw.param_opt(pid::FILE_TX_COMPLETED).is_none(),
        "HK FILES has a value before the file service reported"
    );

    let data: [u8; 3000] = core::array::from_fn(|i| (i * 31 + 7) as u8);
    let name = ok!(FileName::new("up.bin"));
    ok!(ground_parts.store.create(&name).ok());
    ok!(ground_parts.store.write(&name, 0, &data).ok());

    let (mut now, mut up_seq, mut worst) = (0u64, 0u16, 0u64);
    let mut run = |ground: &mut Entity<'_, Mem>, events: &mut Events, now: &mut u64| -> bool {
        for _ in 0..2000 {
            *now += u64::from(fw_core::config::CONTROL_PERIOD_MS);
            ground.poll(*now);
            // At most one packet a period reaches the file service, as on the board.
            if let Some(pdu) = ground.pop() {
                let mut p = [0u8; MAX_PACKET_LEN];
                if let Some(n) = packet::wrap(Direction::Up, up_seq, &pdu, &mut p) {
                    up_seq = up_seq.wrapping_add(1) & 0x3FFF;
                    files.take(*now, &p[..n]);
                }
            }
            files.poll(*now, &mut ToGround { ground, now: *now });
            let t0 = instret();
            files.report(*now, &mut obsw, events);
            worst = worst.max(instret() - t0);
            if ground.idle() && files.entity().idle() {
                return true;
            }
        }
        false
    };

    check!(ground.put(now, "up.bin", "up.bin", Class::Two).is_ok());
    check!(run(&mut ground, &mut events, &mut now), "put not done in 2 000 periods");
    let f = ok!(ground.take_finished());
    check!(f.complete, "put ended {:?}", f);
    check!(ground.get(now, "up.bin", "down.bin", Class::Two).is_ok());
    check!(run(&mut ground, &mut events, &mut now), "get not done in 2 000 periods");
    // A period more: the last report after both ends are idle.
    now += u64::from(fw_core::config::CONTROL_PERIOD_MS);
    files.poll(
        now,
        &mut ToGround {
            ground: &mut ground,
            now,
        },
    );
    files.report(now, &mut obsw, &mut events);

    // The put (received), the get's request (received) and the board's put (sent).
    check_eq!(events.started, 3);
    check_eq!(events.completed, 3);
    check_eq!((events.failed, events.refused), (0, 0));
    let hk = |id| obsw.param_opt(id);
    check_eq!(hk(pid::FILE_TX_COMPLETED), Some(3));
    check_eq!(hk(pid::FILE_TX_RECEIVED), Some(2));
    check_eq!(hk(pid::FILE_TX_SENT), Some(1));
    check_eq!(hk(pid::FILE_TX_FAILED), Some(0));
    check_eq!(hk(pid::FILE_STORE_FILES), Some(1));
    check!(
        hk(pid::FILE_PDU_SENT).is_some_and(|n| n > 3),
        "PDUs sent {:?}",
        hk(pid::FILE_PDU_SENT)
    );
    // The robot's own transaction took its sequence number 0; the next is 1.
    check_eq!(board_parts.next_seq(), 1);
    // The control period's budget (t_budget: 45.3 % with the store work) leaves 4.7 % of
    // the 800 000 instructions a period holds, 37 600: the report takes a small part.
    check!(worst < 15_000, "the report took {} instructions", worst);
    semihosting::println!(
        "    file service report: worst period {worst} instructions (an ended transaction's event, the store counted, HK FILES)"
    );
    Ok(())
}
