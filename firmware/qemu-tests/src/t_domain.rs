//! mmic-domain on the target: reconfiguration search over every state pair, the bolter
//! state machine, and board B answering the A–B protocol.

use crate::harness::{Failure, Test, TestResult};
use crate::t_reconfig::bfs_len;
use crate::tests;
use crate::{check, check_eq, ok};
use mib::robot::{apply, NUM_STATES};
use mmic_domain::ablink::{FrameDecoder, Message, ModuleCmd};
use mmic_domain::board_b::{BoardB, BoardBOut};
use mmic_domain::bolter::{BoltOp, Bolter, BolterConfig, BolterEvent, BolterPhase};
use mmic_domain::consts::{BOLT_RETRACT_MS, BOLT_RETURN_MS, BOLT_REVERSE_MS, BOLT_SELECT_MS};
use mmic_domain::search;
use mmic_domain::{BolterDrive, SensorsB};

pub const TESTS: &[Test] = tests![
    search_matches_independent_bfs_for_all_225_state_pairs,
    bolter_locks_a_pair_on_the_first_attempt,
    bolter_retries_then_fails_after_max_attempts,
    bolter_waits_for_board_b_current,
    bolter_unbolts_when_current_drops,
    board_b_acks_commands_once_and_heartbeats_every_50_ms,
];

fn search_matches_independent_bfs_for_all_225_state_pairs() -> TestResult {
    let max = mib::config::MAX_RECONFIG_PRIMITIVES;
    let mut reachable = 0;
    for a in 0..NUM_STATES as u8 {
        for b in 0..NUM_STATES as u8 {
            let want = bfs_len(a as usize, b as usize).filter(|&d| d <= max);
            let plan = search::shortest_path(a, b);
            check_eq!(plan.as_ref().map(|p| p.len()), want, "{} -> {}", a, b);
            check_eq!(search::distance(a, b).map(usize::from), want, "{} -> {}", a, b);
            if let Some(plan) = plan {
                // Executing the plan's primitives from `a` ends in `b`.
                let mut s = a;
                for &p in plan.iter() {
                    s = ok!(apply(s, p));
                }
                check_eq!(s, b, "plan {:?} from {}", &plan[..], a);
                reachable += 1;
            }
        }
    }
    // Every pair is connected within three primitives in the MIB's map.
    check_eq!(reachable, NUM_STATES * NUM_STATES);
    check!(search::shortest_path(0, NUM_STATES as u8).is_none());
    Ok(())
}

/// Runs the bolter for up to `limit_ms` in 10 ms steps; `current(phase)` gives
/// (I_boA, I_boB). Returns the phases entered and the events, in order.
fn run(
    b: &mut Bolter,
    t: &mut u64,
    limit_ms: u64,
    current: impl Fn(BolterPhase) -> (u16, Option<u16>),
    phases: &mut heapless::Vec<BolterPhase, 64>,
    events: &mut heapless::Vec<BolterEvent, 8>,
) {
    let end = *t + limit_ms;
    while *t < end {
        *t += 10;
        if phases.last() != Some(&b.phase()) {
            let _ = phases.push(b.phase());
        }
        let (ia, ib) = current(b.phase());
        if let Some(e) = b.tick(*t, ia, ib) {
            let _ = events.push(e);
            if !matches!(e, BolterEvent::AttemptFailed { .. }) {
                break;
            }
        }
    }
}

fn bolter_locks_a_pair_on_the_first_attempt() -> TestResult {
    let cfg = BolterConfig::default();
    check_eq!((cfg.push_ma, cfg.lock_ma, cfg.max_attempts), (1200, 1800, 3));
    let mut b = Bolter::new();
    check!(!b.start(BoltOp::Bolt, 5, 0, cfg), "pair 5 accepted");
    check!(b.start(BoltOp::Bolt, 3, 0, cfg));
    check_eq!(b.mux(), 2);
    let mut t = 0;
    let (mut ph, mut ev) = (heapless::Vec::new(), heapless::Vec::new());
    // Fastener reached at once when pushing, locked at once when rotating.
    run(
        &mut b,
        &mut t,
        20_000,
        |p| match p {
            BolterPhase::Descend | BolterPhase::Push => (1300, Some(1250)),
            BolterPhase::Rotate => (1900, Some(1850)),
            _ => (100, Some(100)),
        },
        &mut ph,
        &mut ev,
    );
    use BolterPhase::*;
    check_eq!(&ph[..], &[Select, Descend, Retract, Push, Rotate, Reverse, Return][..]);
    check_eq!(&ev[..], &[BolterEvent::Succeeded { attempts: 1 }][..]);
    // Timed phases only: select, retract, reverse, return (+ one tick per transition).
    let timed = (BOLT_SELECT_MS + BOLT_RETRACT_MS + BOLT_REVERSE_MS + BOLT_RETURN_MS) as u64;
    check!(t >= timed && t <= timed + 100, "took {} ms, timed part {} ms", t, timed);
    check!(!b.busy());
    check_eq!(b.drive(), BolterDrive::Off);
    Ok(())
}

fn bolter_retries_then_fails_after_max_attempts() -> TestResult {
    let cfg = BolterConfig::default();
    let mut b = Bolter::new();
    check!(b.start(BoltOp::Bolt, 1, 0, cfg));
    let mut t = 0;
    let (mut ph, mut ev) = (heapless::Vec::new(), heapless::Vec::new());
    // The fastener is never reached: every Descend times out.
    run(&mut b, &mut t, 60_000, |_| (0, Some(0)), &mut ph, &mut ev);
    let attempt_failed = |a| BolterEvent::AttemptFailed {
        attempt: a,
        phase: BolterPhase::Descend,
    };
    check_eq!(
        &ev[..],
        &[
            attempt_failed(1),
            attempt_failed(2),
            attempt_failed(3),
            BolterEvent::Failed { attempts: 3 }
        ][..]
    );
    // Each attempt: select + step timeout + return.
    let per = (BOLT_SELECT_MS + cfg.step_timeout_ms + BOLT_RETURN_MS) as u64;
    check!(
        t >= 3 * per && t <= 3 * per + 200,
        "took {} ms, expected about {}",
        t,
        3 * per
    );
    Ok(())
}

fn bolter_waits_for_board_b_current() -> TestResult {
    let mut b = Bolter::new();
    check!(b.start(BoltOp::Bolt, 2, 0, BolterConfig::default()));
    let mut t = 0;
    let (mut ph, mut ev) = (heapless::Vec::new(), heapless::Vec::new());
    // A pushes hard, B is silent: the push condition is never met.
    run(&mut b, &mut t, 1000, |_| (2000, None), &mut ph, &mut ev);
    check_eq!(b.phase(), BolterPhase::Descend);
    check_eq!(b.drive(), BolterDrive::Descend);
    check!(ev.is_empty());
    Ok(())
}

fn bolter_unbolts_when_current_drops() -> TestResult {
    let mut b = Bolter::new();
    check!(b.start(BoltOp::Unbolt, 4, 0, BolterConfig::default()));
    let mut t = 0;
    let (mut ph, mut ev) = (heapless::Vec::new(), heapless::Vec::new());
    run(
        &mut b,
        &mut t,
        20_000,
        |p| match p {
            BolterPhase::Descend => (1500, Some(1500)),
            // Released: the current falls below the push threshold.
            BolterPhase::Unlock => (300, Some(300)),
            _ => (0, Some(0)),
        },
        &mut ph,
        &mut ev,
    );
    use BolterPhase::*;
    check_eq!(&ph[..], &[Select, Descend, Unlock, Return][..]);
    check_eq!(&ev[..], &[BolterEvent::Succeeded { attempts: 1 }][..]);
    Ok(())
}

fn frame(seq: u8, cmd: ModuleCmd) -> Result<heapless::Vec<u8, 64>, Failure> {
    let mut v = heapless::Vec::new();
    if (Message::Command { seq, cmd }).encode(&mut v).is_err() {
        return Err(Failure::new(file!(), line!(), format_args!("encode failed")));
    }
    Ok(v)
}

fn board_b_acks_commands_once_and_heartbeats_every_50_ms() -> TestResult {
    let mut b = BoardB::new();
    let mut out = BoardBOut::default();
    let s = SensorsB {
        v_bat: 3000,
        i_loc: 50,
        grav: [0, -1000, 0],
        arm_switch: true,
        ..Default::default()
    };
    let mut dec = FrameDecoder::new();
    let mut acks: heapless::Vec<u8, 8> = heapless::Vec::new();
    let mut heartbeats = 0u32;
    let mut last_hb = None;
    let power = frame(
        1,
        ModuleCmd::Power {
            arm: 1,
            grip: 1,
            bolter: 1,
        },
    )?;
    let arm = frame(2, ModuleCmd::ArmTarget(1500))?;
    for step in 0..=100u64 {
        let now = step * 10;
        let rx: &[u8] = match step {
            1 => &power,
            2 | 3 => &arm, // the second copy is a resend after a lost ack
            _ => &[],
        };
        b.tick(now, &s, rx, &mut out);
        for &byte in out.tx.iter() {
            match dec.push(byte) {
                Some(Ok(Message::Ack { seq })) => {
                    let _ = acks.push(seq);
                }
                Some(Ok(Message::Heartbeat { hb, .. })) => {
                    heartbeats += 1;
                    last_hb = Some(hb);
                }
                Some(Ok(_)) => return Err(Failure::new(file!(), line!(), format_args!("unexpected message"))),
                Some(Err(e)) => return Err(Failure::new(file!(), line!(), format_args!("bad frame {:?}", e))),
                None => {}
            }
        }
    }
    check_eq!(&acks[..], &[1, 2, 2][..]);
    check_eq!(b.counters().commands, 2);
    check_eq!(b.counters().duplicates, 1);
    // 0..=1000 ms at 50 ms: 21 heartbeats.
    check_eq!(heartbeats, 1000 / mib::config::B_HEARTBEAT_PERIOD_MS + 1);
    let hb = ok!(last_hb);
    check_eq!(hb.v_bat, 3000);
    check_eq!(hb.arm_target, 1500);
    check!(hb.arm_switch());
    // The arm moves toward 1500 us at the servo speed limit and is powered.
    let pwm = ok!(out.side.arm_pwm);
    check!(
        pwm > mib::robot::servo::ARM_CONTRACTED_US && pwm <= 1500,
        "arm at {}",
        pwm
    );
    Ok(())
}
