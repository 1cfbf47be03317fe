//! The simulator's physical model: geometry truth, determinism, idle currents.

use mib::params::{pid, CAL_AMP, I_LOC_IDLE_MAX};
use mib::robot::{servo, Face};
use mmic_domain::ablink::{Message, ModuleCmd};
use mmic_domain::controller::{Action, ActionReport};
use mmic_domain::{ActuatorsA, BolterDrive, SideActuators};
use mmic_sim::{Harness, Sim, SimConfig};

fn run(sim: &mut Sim, act: &ActuatorsA, ms: u32, to_b: &[u8]) {
    let mut rx = Vec::new();
    sim.step(10, act, to_b, &mut rx);
    for _ in 0..ms / 10 {
        sim.step(10, act, &[], &mut rx);
    }
}

fn frame(seq: u8, cmd: ModuleCmd) -> Vec<u8> {
    let mut v: heapless::Vec<u8, 64> = heapless::Vec::new();
    Message::Command { seq, cmd }.encode(&mut v).unwrap();
    v.to_vec()
}

// verifies: MMIC-MOT-07
#[test]
fn geometry_truth_wrong_motion_gives_no_state_and_releasing_both_sides_falls() {
    let mut sim = Sim::new(SimConfig {
        noise: false,
        ..SimConfig::default()
    });
    let mut act = ActuatorsA {
        regulator_on: true,
        side: SideActuators {
            arm_pwm: Some(servo::ARM_CONTRACTED_US),
            grip_pwm: Some(servo::GRIP_CLOSED_US),
            bolter: BolterDrive::Off,
        },
        hip_speed: Some(0),
        mux: 0,
    };
    run(&mut sim, &act, 100, &[]);
    assert_eq!(sim.truth().state, Some(0));
    // both sides gripped: the arm cannot move
    act.side.arm_pwm = Some(servo::ARM_EXTENDED_US);
    run(&mut sim, &act, 1000, &[]);
    assert_eq!(sim.truth().arm_us[0], servo::ARM_CONTRACTED_US as f64);
    assert!(sim.truth().i_loc_ma[0] > 1000.0, "stalled arm draws current");
    // release A, extend only arm A (B's arm stays contracted): not a configuration
    act.side.grip_pwm = Some(servo::GRIP_OPEN_US);
    run(&mut sim, &act, 2500, &[]);
    assert_eq!(sim.truth().faces[0], None);
    assert_eq!(sim.truth().arm_us[0], servo::ARM_EXTENDED_US as f64);
    act.side.grip_pwm = Some(servo::GRIP_CLOSED_US);
    run(&mut sim, &act, 2000, &[]);
    assert_eq!(sim.truth().faces[0], None, "closed on nothing");
    assert_eq!(sim.truth().state, None);
    assert!(!sim.truth().fallen);
    // the right motion back: open, contract, close -> matched Xneg again
    act.side.grip_pwm = Some(servo::GRIP_OPEN_US);
    run(&mut sim, &act, 2000, &[]);
    act.side.arm_pwm = Some(servo::ARM_CONTRACTED_US);
    run(&mut sim, &act, 2500, &[]);
    act.side.grip_pwm = Some(servo::GRIP_CLOSED_US);
    run(&mut sim, &act, 2000, &[]);
    assert_eq!(sim.truth().faces, [Some(Face::Xneg), Some(Face::Xneg)]);
    assert_eq!(sim.truth().state, Some(0));
    // A open and B open (through board B): the robot falls
    act.side.grip_pwm = Some(servo::GRIP_OPEN_US);
    run(
        &mut sim,
        &act,
        100,
        &frame(
            1,
            ModuleCmd::Power {
                arm: 1,
                grip: 1,
                bolter: 0,
            },
        ),
    );
    run(
        &mut sim,
        &act,
        2500,
        &frame(2, ModuleCmd::GripTarget(servo::GRIP_OPEN_US)),
    );
    assert!(sim.truth().fallen);
    assert_eq!(sim.truth().state, None);
}

// verifies: MMIC-VAL-03
#[test]
fn simulation_is_deterministic_for_a_seed() {
    let go = |seed: u64| {
        let mut h = Harness::new(SimConfig {
            seed,
            link_loss: 0.01,
            ..SimConfig::default()
        });
        h.power_on();
        let r = h.run_action(Action::Reconfigure { from: 0, to: 1 }, 120_000).unwrap();
        (r, h.sim.truth(), h.events.clone(), h.sim.sensors_a())
    };
    let a = go(42);
    let b = go(42);
    assert_eq!(a.0, Some(ActionReport::Completed));
    assert_eq!(a.1, b.1);
    assert_eq!(a.2, b.2);
    assert_eq!(a.3, b.3);
    let c = go(43);
    assert_ne!(a.3, c.3, "another seed gives other sensor noise");
}

// verifies: MMIC-FLT-07
#[test]
fn idle_locomotion_current_stays_below_the_idle_limit_at_rest() {
    let mut h = Harness::new(SimConfig {
        seed: 9,
        ..SimConfig::default()
    });
    h.power_on();
    let limit = CAL_AMP.raw(I_LOC_IDLE_MAX);
    for (from, to) in [(0u8, 11u8), (11, 2)] {
        let r = h.run_action(Action::Reconfigure { from, to }, 120_000).unwrap();
        assert_eq!(r, Some(ActionReport::Completed));
        // rest two minutes gripped: no servo may wind up to a stall current
        h.advance(120_000);
        for p in [pid::I_LOC_A, pid::I_LOC_B] {
            let v = h.ctrl.param(p).unwrap();
            assert!(v < limit, "state {to}: param {p} = {v} >= {limit}");
        }
    }
}

// verifies: MMIC-MOT-02
#[test]
fn boot_in_a_stretch_or_turn_state_recovers_arm_positions_from_the_imus() {
    for initial in [3u8, 11, 6] {
        let mut h = Harness::new(SimConfig {
            seed: 20 + initial as u64,
            initial_state: initial,
            ..SimConfig::default()
        });
        let pwm = mib::robot::STATES[initial as usize].arm_pwm() as i64;
        h.advance(1000);
        assert_eq!(h.ctrl.computed_state(), Some(initial), "state {initial}");
        assert_eq!(h.ctrl.param(pid::ARM_A_PWM), Some(pwm));
        assert_eq!(h.ctrl.param(pid::ARM_B_PWM), Some(pwm));
        h.ctrl
            .set_module_modes(mmic_domain::controller::ModuleModes::all(mib::modes::module_mode::ON));
        h.advance(1000);
        // powering on does not move the arms: the robot stays where it is
        assert_eq!(h.sim.truth().state, Some(initial));
        let r = h
            .run_action(Action::Reconfigure { from: initial, to: 0 }, 120_000)
            .unwrap();
        assert_eq!(r, Some(ActionReport::Completed), "{initial}->0");
        assert_eq!(h.sim.truth().state, Some(0));
    }
}

// verifies: MMIC-CTL-06
#[test]
fn abort_during_a_hip_rotation_holds_the_hip_where_it_is() {
    let mut h = Harness::new(SimConfig {
        seed: 30,
        ..SimConfig::default()
    });
    h.power_on();
    h.ctrl
        .start(Action::Reconfigure { from: 0, to: 11 }, h.now_ms())
        .unwrap();
    assert!(h.run_until(60_000, |h| h.sim.truth().hip_cdeg < -4500.0));
    let at_abort = h.sim.truth().hip_cdeg;
    h.ctrl.abort();
    h.advance(3000);
    let held = h.sim.truth().hip_cdeg;
    assert!(
        (held - at_abort).abs() < 200.0,
        "aborted at {at_abort:.0}, held at {held:.0} cdeg"
    );
    assert!(!h.ctrl.busy());
    assert!(!h.sim.truth().fallen, "the anchored side still grips");
}

// verifies: MMIC-VAL-03
#[test]
fn truth_status_line_names_state_faces_and_faults() {
    let mut sim = Sim::new(SimConfig::default());
    sim.inject(mmic_sim::Fault::StuckArm(mib::robot::Side::B));
    let line = sim.truth().to_string();
    assert!(line.contains("state=0 (Xneg)"), "{line}");
    assert!(line.contains("faces=A:Xneg,B:Xneg"), "{line}");
    assert!(line.contains("faults=[stuck-arm b]"), "{line}");
    assert!(!line.contains('\n'));
}

// verifies: MMIC-AV-05
#[test]
fn controller_and_board_b_fit_a_microcontroller() {
    let c = std::mem::size_of::<mmic_domain::controller::Controller>();
    let b = std::mem::size_of::<mmic_domain::board_b::BoardB>();
    eprintln!("Controller {c} bytes, BoardB {b} bytes");
    assert!(c < 8 * 1024 && b < 4 * 1024, "Controller {c} B, BoardB {b} B");
}
