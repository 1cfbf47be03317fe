//! Controller + simulator integration: reconfigurations reach the right true state,
//! bolting outcomes come out of the state machine reading simulated currents, the A–B
//! link survives loss and corruption, and every injected fault of Table 8 produces its
//! domain symptom.

use mib::events::eid;
use mib::params::{pid, CAL_AMP, CAL_VOLT, I_LOC_MAX, V_BAT_EMPTY};
use mib::robot::{Face, Side};
use mmic_domain::controller::{Action, ActionFailure, ActionReport, DomainEvent, StartError};
use mmic_sim::{Fault, Harness, SimConfig};

fn harness(initial: u8, seed: u64) -> Harness {
    let mut h = Harness::new(SimConfig {
        seed,
        initial_state: initial,
        ..SimConfig::default()
    });
    h.power_on();
    h
}

fn param(h: &Harness, p: u16) -> i64 {
    h.ctrl.param(p).expect("domain parameter")
}

// verifies: MMIC-CMD-01
#[test]
fn reconfiguration_xneg_to_xpos_reaches_the_true_state() {
    let mut h = harness(0, 1);
    assert_eq!(h.ctrl.computed_state(), Some(0));
    let r = h.run_action(Action::Reconfigure { from: 0, to: 1 }, 120_000).unwrap();
    assert_eq!(r, Some(ActionReport::Completed), "events {:?}", h.events);
    assert_eq!(h.sim.truth().state, Some(1));
    assert_eq!(h.ctrl.computed_state(), Some(1));
    assert!(!h.sim.truth().fallen);
    let steps: Vec<_> = h
        .reports
        .iter()
        .filter_map(|(_, r)| match r {
            ActionReport::Step { n } => Some(*n),
            _ => None,
        })
        .collect();
    assert_eq!(steps, [1, 2]);
    assert!(h
        .events
        .iter()
        .any(|(_, e)| *e == DomainEvent::StateReached { state: 1 }));
    assert_eq!(param(&h, pid::CONFIG_STATE), 1);
    assert_eq!(param(&h, pid::TARGET_STATE), 1);
    assert_eq!(param(&h, pid::CMD_COMPLETE), 1);
}

// verifies: MMIC-MOT-06
#[test]
fn reconfiguration_xneg_to_yneg_turns_the_hip_and_reaches_the_true_state() {
    let mut h = harness(0, 2);
    let plan = mmic_domain::search::shortest_states(0, 2).unwrap();
    let r = h.run_action(Action::Reconfigure { from: 0, to: 2 }, 180_000).unwrap();
    assert_eq!(r, Some(ActionReport::Completed), "events {:?}", h.events);
    assert_eq!(h.sim.truth().state, Some(2));
    assert_eq!(h.sim.truth().faces, [Some(Face::Yneg), Some(Face::Yneg)]);
    // every intermediate state of the plan was confirmed from the sensors
    let reached: Vec<u8> = h
        .events
        .iter()
        .filter_map(|(_, e)| match e {
            DomainEvent::PrimitiveDone { state, .. } => Some(*state),
            _ => None,
        })
        .collect();
    assert_eq!(reached, plan[1..]);
    // the hip went through a turn and came back home
    assert!(h.sim.truth().hip_cdeg.abs() < 100.0);
    assert_eq!(h.ctrl.computed_state(), Some(2));
}

// verifies: MMIC-CMD-01
#[test]
fn reconfiguration_round_trip_over_every_matched_state() {
    let mut h = harness(0, 3);
    for (from, to) in [(0u8, 2u8), (2, 1), (1, 0)] {
        let r = h.run_action(Action::Reconfigure { from, to }, 180_000).unwrap();
        assert_eq!(r, Some(ActionReport::Completed), "{from}->{to}");
        assert_eq!(h.sim.truth().state, Some(to));
    }
    // batteries discharge with use
    assert!(h.sim.truth().v_bat < 12.6);
}

// verifies: MMIC-AB-07
#[test]
fn reconfiguration_survives_a_lossy_corrupting_link() {
    let mut h = Harness::new(SimConfig {
        seed: 4,
        link_loss: 0.01,
        link_corrupt: 0.01,
        ..SimConfig::default()
    });
    h.power_on();
    let r = h.run_action(Action::Reconfigure { from: 0, to: 1 }, 120_000).unwrap();
    assert_eq!(r, Some(ActionReport::Completed), "events {:?}", h.events);
    assert_eq!(h.sim.truth().state, Some(1));
    assert!(param(&h, pid::B_FRAME_ERRORS) > 0, "corruption was detected");
    assert!(param(&h, pid::B_HB_RX) > 100);
    assert_eq!(param(&h, pid::B_LINK_OK), 1);
}

// verifies: MMIC-CMD-02
#[test]
fn bolting_a_face_reports_attempts_that_match_the_simulated_fasteners() {
    let mut h = harness(0, 5);
    let r = h
        .run_action(
            Action::BoltFace {
                side: Side::A,
                pairs: 0x0F,
            },
            300_000,
        )
        .unwrap();
    let done: Vec<(u8, u8)> = h
        .events
        .iter()
        .filter_map(|(_, e)| match e {
            DomainEvent::BoltPairDone { pair, attempts, .. } => Some((*pair, *attempts)),
            _ => None,
        })
        .collect();
    match r {
        Some(ActionReport::Completed) => assert_eq!(done.len(), 4),
        Some(ActionReport::Failed(f)) => assert!(matches!(f, ActionFailure::BoltFailed { .. }), "{f:?}"),
        other => panic!("bolting never finished: {other:?}"),
    }
    for (pair, attempts) in done {
        let f = h.sim.fastener(Face::Xneg, pair).expect("fastener touched");
        assert!(f.locked, "pair {pair} reported locked");
        assert_eq!(f.lock_attempts, attempts, "pair {pair}");
    }
    // and unbolting releases them again
    let r = h
        .run_action(
            Action::UnboltFace {
                side: Side::A,
                pairs: 0x01,
            },
            120_000,
        )
        .unwrap();
    if r == Some(ActionReport::Completed) {
        assert!(!h.sim.fastener(Face::Xneg, 1).unwrap().locked);
    }
}

// verifies: MMIC-FLT-06
#[test]
fn fault_stuck_arm_gives_arm_not_contracted() {
    let mut h = harness(0, 6);
    let r = h.run_action(Action::Reconfigure { from: 0, to: 3 }, 60_000).unwrap();
    assert_eq!(r, Some(ActionReport::Completed));
    h.sim.inject(Fault::StuckArm(Side::A));
    let mark = h.events.len();
    let r = h.run_action(Action::Reconfigure { from: 3, to: 1 }, 60_000).unwrap();
    assert_eq!(
        r,
        Some(ActionReport::Failed(ActionFailure::AbortedByFault {
            event: eid::ARM_NOT_CONTRACTED
        }))
    );
    assert!(h
        .events_since(mark)
        .any(|e| *e == DomainEvent::ArmNotContracted { side: Side::A }));
    assert!(!h.ctrl.busy());
}

// verifies: MMIC-FLT-10
#[test]
fn fault_cut_cable_ages_the_heartbeat_and_gives_comm_loss_no_ack() {
    let mut h = harness(0, 7);
    assert!(param(&h, pid::B_HB_AGE_MS) <= 100);
    h.sim.inject(Fault::CutCable);
    h.advance(1000);
    assert!(param(&h, pid::B_HB_AGE_MS) >= 900);
    assert_eq!(param(&h, pid::B_LINK_OK), 0);
    let mark = h.events.len();
    let r = h
        .run_action(
            Action::MoveGripper {
                side: Side::B,
                pwm: 1500,
            },
            10_000,
        )
        .unwrap();
    let Some(ActionReport::Failed(ActionFailure::BoardBNoAck { command, .. })) = r else {
        panic!("expected a failure, got {r:?}")
    };
    assert_eq!(command, 2, "gripper command");
    assert!(h
        .events_since(mark)
        .any(|e| matches!(e, DomainEvent::CommLossNoAck { command: 2, retries: 3 })));
    assert!(param(&h, pid::B_ACK_MISSED) >= 1);
    assert!(param(&h, pid::B_RETRIES) >= 3);
    // the cable is mended: heartbeats come back
    h.sim.clear_all();
    h.advance(500);
    assert!(param(&h, pid::B_HB_AGE_MS) <= 100);
}

// verifies: MMIC-AV-01
#[test]
fn fault_battery_sag_drops_v_bat_below_ten_volts() {
    let mut h = harness(0, 8);
    let empty = CAL_VOLT.raw(V_BAT_EMPTY);
    assert!(param(&h, pid::V_BAT_A) > empty);
    h.sim.inject(Fault::BatterySag { volts: 9.5 });
    h.advance(1000);
    assert!(param(&h, pid::V_BAT_A) < empty);
    assert!(param(&h, pid::V_BAT_B) < empty);
    let v = CAL_VOLT.eng(param(&h, pid::V_BAT_A));
    assert!((v - 9.5).abs() < 0.1, "{v}");
    // the 7.4 V regulator still regulates at 9.5 V, not at 6 V
    assert!((CAL_VOLT.eng(param(&h, pid::V_REG)) - 7.4).abs() < 0.1);
    h.sim.inject(Fault::BatterySag { volts: 6.0 });
    h.advance(1000);
    assert!((CAL_VOLT.eng(param(&h, pid::V_REG)) - 5.5).abs() < 0.1);
}

// verifies: MMIC-FLT-08
#[test]
fn fault_obstacle_gives_locomotion_overcurrent() {
    let mut h = harness(0, 9);
    let limit = CAL_AMP.raw(I_LOC_MAX);
    h.sim.inject(Fault::Obstacle(Side::A));
    h.ctrl
        .start(Action::Reconfigure { from: 0, to: 1 }, h.now_ms())
        .unwrap();
    let over = h.run_until(10_000, |h| param(h, pid::I_LOC_A) > limit);
    assert!(over, "I_LOC_A never exceeded {limit}");
    // side B's arm is free: no overcurrent there
    assert!(param(&h, pid::I_LOC_B) < limit);
}

// verifies: MMIC-FLT-03
#[test]
fn fault_misplaced_voxel_refuses_reconfiguration_with_initial_state_mismatch() {
    let mut h = harness(0, 10);
    h.sim.inject(Fault::MisplacedVoxel);
    h.advance(1000);
    assert_eq!(h.ctrl.computed_state(), None);
    assert_eq!(
        h.ctrl.start(Action::Reconfigure { from: 0, to: 1 }, h.now_ms()),
        Err(StartError::InitialStateMismatch {
            believed: 0,
            computed: 255
        })
    );
    h.sim.clear_all();
    h.advance(1000);
    assert_eq!(h.ctrl.computed_state(), Some(0));
}

// verifies: MMIC-FLT-09
#[test]
fn fault_dead_hip_encoder_reads_far_from_zero() {
    let mut h = harness(0, 11);
    assert!(param(&h, pid::HIP_ANGLE).abs() < 100);
    assert!(param(&h, pid::HIP_DEVIATION).abs() < 100);
    h.sim.inject(Fault::DeadHipEncoder);
    h.advance(1000);
    assert!(param(&h, pid::HIP_ANGLE).abs() > 5000);
    assert!(param(&h, pid::HIP_DEVIATION).abs() > 500);
    assert_eq!(h.ctrl.computed_state(), None);
}

// verifies: MMIC-FLT-01
#[test]
fn fault_fastener_jam_fails_every_attempt() {
    let mut h = harness(0, 12);
    h.sim.inject(Fault::FastenerJam);
    let mark = h.events.len();
    let r = h
        .run_action(Action::BoltPair { side: Side::A, pair: 2 }, 120_000)
        .unwrap();
    assert_eq!(
        r,
        Some(ActionReport::Failed(ActionFailure::BoltFailed {
            side: Side::A,
            pair: 2,
            attempts: 3
        }))
    );
    let attempts_failed = h
        .events_since(mark)
        .filter(|e| matches!(e, DomainEvent::BoltAttemptFailed { pair: 2, .. }))
        .count();
    assert_eq!(attempts_failed, 3);
    assert!(h.events_since(mark).any(|e| *e
        == DomainEvent::BoltFailure {
            side: Side::A,
            pair: 2,
            attempts: 3
        }));
    assert!(!h.sim.fastener(Face::Xneg, 2).unwrap().locked);
}

// verifies: MMIC-CMD-04
#[test]
fn hip_rotation_reaches_target_in_the_simulator() {
    // turn state "Yneg Xneg": hip at -90 deg; rotate the hip while... the robot is
    // gripped by both sides, so use a released side: reconfigure into a turn
    let mut h = harness(0, 13);
    let r = h.run_action(Action::Reconfigure { from: 0, to: 11 }, 60_000).unwrap();
    assert_eq!(r, Some(ActionReport::Completed), "{:?}", h.events);
    let hip = h.sim.truth().hip_cdeg;
    assert!((hip + 9000.0).abs() <= 60.0, "hip at {hip}");
    assert_eq!(h.sim.truth().state, Some(11));
}

// verifies: MMIC-MOT-06
#[test]
fn reconfiguration_to_every_state_and_back_reaches_the_true_state() {
    let mut h = harness(0, 14);
    let mut visited = 0;
    for to in 1..mib::robot::NUM_STATES as u8 {
        if mmic_domain::search::distance(0, to).is_none() {
            continue;
        }
        for (from, to) in [(0, to), (to, 0)] {
            let r = h.run_action(Action::Reconfigure { from, to }, 180_000).unwrap();
            assert_eq!(r, Some(ActionReport::Completed), "{from}->{to}: {:?}", h.events.last());
            assert_eq!(h.sim.truth().state, Some(to), "{from}->{to}");
            assert_eq!(h.ctrl.computed_state(), Some(to));
        }
        visited += 1;
    }
    assert_eq!(visited, 14, "every state reachable from matched Xneg");
    assert!(!h.sim.truth().fallen);
}

// verifies: MMIC-FLT-02
#[test]
fn fault_fastener_jam_gives_unbolting_failure() {
    let mut h = harness(0, 15);
    let r = h
        .run_action(Action::BoltPair { side: Side::B, pair: 3 }, 120_000)
        .unwrap();
    assert_eq!(r, Some(ActionReport::Completed), "precondition: pair 3 bolted");
    assert!(h.sim.fastener(Face::Xneg, 3).unwrap().locked);
    h.sim.inject(Fault::FastenerJam);
    let mark = h.events.len();
    let r = h
        .run_action(
            Action::UnboltFace {
                side: Side::B,
                pairs: 0b0100,
            },
            120_000,
        )
        .unwrap();
    assert_eq!(
        r,
        Some(ActionReport::Failed(ActionFailure::UnboltFailed {
            side: Side::B,
            pair: 3,
            attempts: 3
        }))
    );
    assert!(h.events_since(mark).any(|e| *e
        == DomainEvent::UnboltFailure {
            side: Side::B,
            pair: 3,
            attempts: 3
        }));
    assert!(h.sim.fastener(Face::Xneg, 3).unwrap().locked, "still locked");
    // cleared: the pair comes loose
    h.sim.clear_all();
    let r = h
        .run_action(Action::UnboltPair { side: Side::B, pair: 3 }, 120_000)
        .unwrap();
    if r == Some(ActionReport::Completed) {
        assert!(!h.sim.fastener(Face::Xneg, 3).unwrap().locked);
    }
}

// verifies: MMIC-AB-07
#[test]
fn board_b_on_a_jittery_schedule_still_runs_reconfigurations() {
    let mut h = Harness::new(SimConfig {
        seed: 16,
        b_period_ms: 7,
        b_phase_ms: 1,
        b_jitter_ms: 6,
        ..SimConfig::default()
    });
    h.power_on();
    let r = h.run_action(Action::Reconfigure { from: 0, to: 2 }, 180_000).unwrap();
    assert_eq!(r, Some(ActionReport::Completed), "{:?}", h.events);
    assert_eq!(h.sim.truth().state, Some(2));
    assert!(param(&h, pid::B_HB_AGE_MS) <= 100);
}

// verifies: MMIC-CMD-05
#[test]
fn home_after_an_aborted_primitive_contracts_then_grips() {
    let mut h = harness(0, 17);
    h.ctrl
        .start(Action::Reconfigure { from: 0, to: 1 }, h.now_ms())
        .unwrap();
    // first primitive: side B released, arms extending
    assert!(h.run_until(30_000, |h| h.sim.truth().faces[1].is_none()
        && h.sim.truth().arm_us[1] > 1300.0));
    h.ctrl.abort();
    h.advance(500);
    assert_eq!(h.sim.truth().state, None);
    assert_eq!(h.ctrl.computed_state(), None, "a released side is no state");
    let r = h.run_action(Action::Home, 60_000).unwrap();
    assert_eq!(r, Some(ActionReport::Completed), "{:?}", h.events);
    assert_eq!(h.sim.truth().state, Some(0), "{}", h.sim.truth());
    h.advance(1000);
    assert_eq!(h.ctrl.computed_state(), Some(0));
}

// verifies: MMIC-AB-07
#[test]
fn cut_cable_does_not_flood_board_b_with_retries() {
    let mut h = harness(0, 18);
    h.sim.inject(Fault::CutCable);
    h.advance(200);
    // the core would now enter safed: B's modes change while B cannot hear
    h.ctrl.set_module_modes(mmic_domain::controller::ModuleModes::for_root(
        mib::modes::robot_mode::SAFED,
    ));
    h.advance(20_000);
    let missed = param(&h, pid::B_ACK_MISSED);
    assert!(missed <= 2, "{missed} commands given up in 20 s with B silent");
    // cable mended: B's modes are repaired from its heartbeat
    h.sim.clear_all();
    h.advance(2_000);
    assert_eq!(param(&h, pid::B_LINK_OK), 1);
    assert_eq!(h.sim.side(Side::B).arm_cmd, Some(1000), "arm B powered (HOLD)");
    assert_eq!(h.sim.side(Side::B).bolter_cmd, mmic_domain::BolterDrive::Off);
}
