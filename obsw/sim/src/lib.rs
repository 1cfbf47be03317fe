//! MMIC-I simulator.
//!
//! Physics of both sides (arms, grippers and hip at their velocity limits, bolters
//! pushing and rotating fasteners, currents, battery, IMUs, arm switches, hip encoder),
//! the geometry truth of which faces the robot grips, board B running
//! [`mmic_domain::board_b::BoardB`] on its own schedule behind a simulated serial line,
//! and fault injection for every fault of the paper's Table 8. Deterministic for a
//! seed; time advances only through [`Sim::step`] (see [`harness::Harness`] for a mock
//! clock driving the controller and the simulator together).

#![deny(unsafe_code)]

pub mod fastener;
pub mod fault;
pub mod harness;
pub mod modules;
pub mod serial;

pub use fault::{Fault, FaultKind, ParseError, SimCommand};
pub use harness::Harness;

use fastener::{BolterPhys, FastenerPair};
use mib::params::{CAL_VOLT, V_BAT_EMPTY, V_BAT_FULL, V_REG_NOMINAL};
use mib::robot::{servo, state_of, Face, Side, STATES};
use mmic_domain::board_b::{BoardB, BoardBOut};
use mmic_domain::imu::gravity_in_board_frame;
use mmic_domain::{ActuatorsA, BolterDrive, SensorsA, SensorsB, SideActuators};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serial::SerialLine;
use std::collections::HashMap;

/// Simulator configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct SimConfig {
    pub seed: u64,
    /// Configuration state the robot starts in (gripped, at rest).
    pub initial_state: u8,
    /// Per-byte loss probability on the A–B line (both directions).
    pub link_loss: f64,
    /// Per-byte corruption (one bit flipped) probability on the A–B line.
    pub link_corrupt: f64,
    /// Board B's control period and phase (ms): B runs on its own schedule.
    pub b_period_ms: u32,
    pub b_phase_ms: u32,
    /// Random extra delay (0..=jitter ms) of each board B period (its own clock and
    /// scheduling are not A's).
    pub b_jitter_ms: u32,
    /// Battery capacity (mAh): two 1000 mAh packs in parallel.
    pub battery_mah: f64,
    /// Sensor noise on (ADC counts, IMU, encoder).
    pub noise: bool,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            seed: 1,
            initial_state: 0,
            link_loss: 0.0,
            link_corrupt: 0.0,
            b_period_ms: 10,
            b_phase_ms: 3,
            b_jitter_ms: 0,
            battery_mah: 2000.0,
            noise: true,
        }
    }
}

/// Servo physics and sensing constants of the model (documented in docs/domain.md).
pub mod model {
    /// Arm/gripper set point tolerance for the geometry to match a state (µs).
    pub const GEOM_ARM_TOL_US: f64 = 60.0;
    /// Hip tolerance for the geometry to match a state (cdeg).
    pub const GEOM_HIP_TOL_CDEG: f64 = 400.0;
    /// Gripper closes on a face below CLOSED + this, releases above CLOSED + RELEASE.
    pub const GRIP_ATTACH_US: f64 = 60.0;
    pub const GRIP_RELEASE_US: f64 = 200.0;
    /// Arm switch pushed within this of the contracted pulse width (µs).
    pub const ARM_SWITCH_US: f64 = 15.0;
    /// Hip servo: gain, first-order lag (s), load bias (cdeg/s), top speed (cdeg/s).
    pub const HIP_GAIN: f64 = 0.9;
    pub const HIP_TAU_S: f64 = 0.08;
    pub const HIP_BIAS_CDEG_S: f64 = 30.0;
    pub const HIP_VMAX_CDEG_S: f64 = 6000.0;
    /// Currents (mA).
    pub const ARM_MOVE_MA: f64 = 350.0;
    pub const ARM_HOLD_MA: f64 = 60.0;
    pub const ARM_STUCK_MA: f64 = 1400.0;
    pub const ARM_OBSTACLE_MA: f64 = 3400.0;
    pub const ARM_BLOCKED_MA: f64 = 1600.0;
    pub const HIP_IDLE_MA: f64 = 50.0;
    pub const HIP_MA_PER_CDEG_S: f64 = 0.15;
    pub const HIP_STALL_MA_PER_CDEG_S: f64 = 0.4;
    pub const GRIP_MOVE_MA: f64 = 300.0;
    pub const GRIP_HOLD_FACE_MA: f64 = 250.0;
    pub const GRIP_HOLD_EMPTY_MA: f64 = 60.0;
    pub const GRIP_OPEN_MA: f64 = 40.0;
    /// Gripper servo pushing against its end stop (commanded beyond it): above every
    /// revision's operational limit (`I_GRIP_MAX`, the database's `i_op_max_ma`).
    pub const GRIP_STALL_MA: f64 = 1800.0;
    /// Quiescent draw of the two boards, regulator efficiency, battery resistance.
    pub const BOARDS_MA: f64 = 150.0;
    pub const REG_EFFICIENCY: f64 = 0.9;
    /// Regulator dropout: V_reg follows V_bat minus this once V_bat is too low.
    pub const REG_DROPOUT_V: f64 = 0.5;
    pub const BATTERY_OHM: f64 = 0.1;
    /// The dead hip encoder's stuck reading (cdeg).
    pub const DEAD_ENCODER_CDEG: i16 = 16383;
    /// Noise amplitudes (uniform ±): ADC counts, milli-g, cdeg.
    pub const ADC_NOISE: i32 = 6;
    pub const IMU_NOISE_MG: i32 = 15;
    pub const ENC_NOISE_CDEG: i32 = 3;
}
use model::*;

/// Physical state of one side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SideTruth {
    pub arm_us: f64,
    pub grip_us: f64,
    /// Face the gripper holds (`None`: open, or closed on nothing).
    pub gripped: Option<Face>,
    /// Orientation of the board: the face its IMU is aligned with.
    pub imu_face: Face,
    pub bolter: BolterPhys,
    pub i_loc_ma: f64,
    pub i_grip_ma: f64,
    /// Commands in force.
    pub arm_cmd: Option<u16>,
    pub grip_cmd: Option<u16>,
    pub bolter_cmd: BolterDrive,
    pub mux: u8,
}

/// What really happened, for tests and the ground's simulator view.
#[derive(Clone, Debug, PartialEq)]
pub struct Truth {
    pub time_ms: u64,
    /// The configuration state the faces form (`None` if a side is free or the pair
    /// is none of the 15 states).
    pub state: Option<u8>,
    pub faces: [Option<Face>; 2],
    /// Both grippers released at once: the robot fell off.
    pub fallen: bool,
    pub v_bat: f64,
    pub i_bat_ma: f64,
    pub hip_cdeg: f64,
    pub arm_us: [f64; 2],
    pub grip_us: [f64; 2],
    pub i_loc_ma: [f64; 2],
    pub i_bo_ma: [f64; 2],
    pub faults: Vec<Fault>,
}

impl std::fmt::Display for Truth {
    /// One line for the simulator control channel's `status` reply.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let face = |x: Option<Face>| x.map_or("-", |f| f.name());
        let state = self
            .state
            .and_then(|s| STATES.get(s as usize))
            .map_or("none".to_string(), |s| format!("{} ({})", s.id, s.name));
        write!(
            f,
            "t={}ms state={} faces=A:{},B:{} fallen={} v_bat={:.2}V i_bat={:.0}mA hip={:.1}deg arms={:.0}/{:.0}us grips={:.0}/{:.0}us i_loc={:.0}/{:.0}mA i_bo={:.0}/{:.0}mA faults=[",
            self.time_ms,
            state,
            face(self.faces[0]),
            face(self.faces[1]),
            self.fallen,
            self.v_bat,
            self.i_bat_ma,
            self.hip_cdeg / 100.0,
            self.arm_us[0],
            self.arm_us[1],
            self.grip_us[0],
            self.grip_us[1],
            self.i_loc_ma[0],
            self.i_loc_ma[1],
            self.i_bo_ma[0],
            self.i_bo_ma[1],
        )?;
        for (i, x) in self.faults.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{x}")?;
        }
        f.write_str("]")
    }
}

/// The simulator.
#[derive(Clone, Debug)]
pub struct Sim {
    cfg: SimConfig,
    rng: ChaCha8Rng,
    t_ms: u64,
    sides: [SideTruth; 2],
    hip_cdeg: f64,
    hip_vel: f64,
    hip_cmd: Option<i16>,
    regulator_on: bool,
    used_mah: f64,
    i_bat_ma: f64,
    board_b: BoardB,
    b_out: BoardBOut,
    b_next_ms: u64,
    b_rx: Vec<u8>,
    line_ab: SerialLine,
    line_ba: SerialLine,
    faults: Vec<Fault>,
    fasteners: HashMap<(Face, u8), FastenerPair>,
    fallen: bool,
    /// What module discovery reads from this robot (docs/modules.md): tables and probes.
    modules: modules::DiscoveryInput,
    /// What the fitted modules' calibration means physically (docs/modules.md).
    phys: modules::ModulePhysics,
}

fn near(x: f64, target: f64, tol: f64) -> bool {
    (x - target).abs() <= tol
}

/// Deterministic noise in [-amp, amp] from a time and channel (no state needed).
fn noise(seed: u64, t: u64, ch: u64, amp: i32) -> i32 {
    if amp == 0 {
        return 0;
    }
    let mut z = seed ^ t.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ ch.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z % (2 * amp as u64 + 1)) as i32 - amp
}

impl Sim {
    pub fn new(cfg: SimConfig) -> Self {
        let s = STATES.get(cfg.initial_state as usize).copied().unwrap_or(STATES[0]);
        let side = |face: Face| SideTruth {
            arm_us: s.arm_pwm() as f64,
            grip_us: servo::GRIP_CLOSED_US as f64,
            gripped: Some(face),
            imu_face: face,
            bolter: BolterPhys::default(),
            i_loc_ma: 0.0,
            i_grip_ma: 0.0,
            arm_cmd: None,
            grip_cmd: None,
            bolter_cmd: BolterDrive::Off,
            mux: 0,
        };
        let mut sim = Sim {
            rng: ChaCha8Rng::seed_from_u64(cfg.seed),
            t_ms: 0,
            sides: [side(s.a), side(s.b)],
            hip_cdeg: s.hip_cdeg() as f64,
            hip_vel: 0.0,
            hip_cmd: None,
            regulator_on: false,
            used_mah: 0.0,
            i_bat_ma: BOARDS_MA,
            board_b: BoardB::with_positions(s.arm_pwm(), servo::GRIP_CLOSED_US),
            b_out: BoardBOut::default(),
            b_next_ms: cfg.b_phase_ms as u64,
            b_rx: Vec::new(),
            line_ab: SerialLine::default(),
            line_ba: SerialLine::default(),
            faults: Vec::new(),
            fasteners: HashMap::new(),
            fallen: false,
            modules: modules::ModuleSetSpec::full().discovery_input(),
            phys: modules::ModuleSetSpec::full().physics(),
            cfg,
        };
        sim.set_modules(&modules::ModuleSetSpec::full());
        sim
    }

    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }

    /// Builds the simulated robot from a module set (default: the full robot,
    /// [`modules::ModuleSetSpec::full`]): what its descriptor tables and probes answer.
    /// Board B gets its half (table and probes) and sends it to A over the simulated
    /// A–B link at boot; board A's half is for the platform to read ([`Sim::modules`]).
    /// A set whose board B is silent sends nothing.
    pub fn set_modules(&mut self, spec: &modules::ModuleSetSpec) {
        self.modules = spec.discovery_input();
        self.phys = spec.physics();
        if self.t_ms == 0 {
            // At rest since boot: each gripper closed at its own width.
            for (s, closed) in self.sides.iter_mut().zip(self.phys.grip_closed_us) {
                s.grip_us = closed;
            }
        }
        match &self.modules.table_b {
            Some(t) => self.board_b.set_modules(t, self.modules.probes_b),
            None => self.board_b.set_modules(&[], self.modules.probes_b),
        }
    }
    /// What discovery reads: board A's table and probes, board B's table (`None` when
    /// board B stays silent) and probes.
    pub fn modules(&self) -> &modules::DiscoveryInput {
        &self.modules
    }
    pub fn time_ms(&self) -> u64 {
        self.t_ms
    }

    // ------------------------------------------------------------ faults

    pub fn inject(&mut self, f: Fault) {
        // one fault per kind and side: a new one replaces the old
        self.faults.retain(|o| {
            o.kind() != f.kind()
                || match (o, &f) {
                    (Fault::StuckArm(a), Fault::StuckArm(b)) | (Fault::Obstacle(a), Fault::Obstacle(b)) => a != b,
                    _ => false,
                }
        });
        if f == Fault::CutCable {
            self.line_ab.drop_in_transit();
            self.line_ba.drop_in_transit();
        }
        self.faults.push(f);
    }
    pub fn clear(&mut self, kind: FaultKind) {
        self.faults.retain(|f| f.kind() != kind);
    }
    pub fn clear_all(&mut self) {
        self.faults.clear();
    }
    pub fn faults(&self) -> &[Fault] {
        &self.faults
    }
    /// Applies a control-protocol command.
    pub fn apply(&mut self, c: SimCommand) {
        match c {
            SimCommand::Inject(f) => self.inject(f),
            SimCommand::Clear(k) => self.clear(k),
            SimCommand::ClearAll => self.clear_all(),
            SimCommand::SetLinkLoss(p) => self.cfg.link_loss = p.clamp(0.0, 1.0),
            SimCommand::SetLinkCorrupt(p) => self.cfg.link_corrupt = p.clamp(0.0, 1.0),
        }
    }
    fn has(&self, f: Fault) -> bool {
        self.faults.contains(&f)
    }
    fn has_kind(&self, k: FaultKind) -> bool {
        self.faults.iter().any(|f| f.kind() == k)
    }

    /// A new voxel face: every fastener unlocked with no attempts (for long bolting
    /// campaigns on one spot).
    pub fn replace_fasteners(&mut self) {
        self.fasteners.clear();
    }
    /// The face whose fasteners the bolters work on: side A's gripped face, else B's.
    pub fn fastener_face(&self) -> Option<Face> {
        self.sides[0].gripped.or(self.sides[1].gripped)
    }
    /// A fastener pair's truth (on [`Sim::fastener_face`]).
    pub fn fastener(&self, face: Face, pair: u8) -> Option<FastenerPair> {
        self.fasteners.get(&(face, pair)).copied()
    }

    // ------------------------------------------------------------ sensing

    fn battery_v(&self) -> f64 {
        if let Some(Fault::BatterySag { volts }) = self.faults.iter().find(|f| f.kind() == FaultKind::BatterySag) {
            return *volts as f64;
        }
        let soc = (1.0 - self.used_mah / self.cfg.battery_mah).clamp(0.0, 1.0);
        let v_oc = V_BAT_EMPTY - 0.3 + (V_BAT_FULL - V_BAT_EMPTY + 0.3) * soc;
        (v_oc - BATTERY_OHM * self.i_bat_ma / 1000.0).max(0.0)
    }

    fn n(&self, ch: u64, amp: i32) -> i32 {
        if self.cfg.noise {
            noise(self.cfg.seed, self.t_ms, ch, amp)
        } else {
            0
        }
    }

    fn adc(&self, ch: u64, v: f64) -> u16 {
        (v.round() as i32 + self.n(ch, ADC_NOISE)).clamp(0, 4095) as u16
    }

    fn volts_raw(&self, ch: u64, v: f64) -> u16 {
        self.adc(ch, CAL_VOLT.raw(v) as f64)
    }

    fn imu(&self, side: usize, ch: u64) -> [i16; 3] {
        let mut face = self.sides[side].imu_face;
        if side == 1 && self.has(Fault::MisplacedVoxel) {
            face = face.rotate(1);
        }
        let g = gravity_in_board_frame(face);
        let mut out = [0i16; 3];
        for (i, o) in out.iter_mut().enumerate() {
            *o = (g[i] as i32 + self.n(ch + i as u64, IMU_NOISE_MG)) as i16;
        }
        out
    }

    fn arm_switch(&self, side: usize) -> bool {
        self.sides[side].arm_us <= servo::ARM_CONTRACTED_US as f64 + ARM_SWITCH_US
    }

    /// Board A's raw sensors now.
    pub fn sensors_a(&self) -> SensorsA {
        let s = &self.sides[0];
        let hip = if self.has(Fault::DeadHipEncoder) {
            DEAD_ENCODER_CDEG
        } else {
            // The platform converts counts with the nominal zero: this encoder's own zero
            // and direction show as an offset and a sign (docs/modules.md).
            let read = self.phys.encoder_offset_cdeg + self.phys.encoder_dir * self.hip_cdeg;
            (read.round() as i32 + self.n(20, ENC_NOISE_CDEG)).clamp(i16::MIN as i32, i16::MAX as i32) as i16
        };
        SensorsA {
            v_bat: self.volts_raw(1, self.battery_v()),
            i_bat: self.adc(2, self.i_bat_ma),
            v_reg: if self.regulator_on {
                // the linear regulator drops out below its input headroom
                self.volts_raw(3, V_REG_NOMINAL.min(self.battery_v() - REG_DROPOUT_V).max(0.0))
            } else {
                self.adc(3, 0.0)
            },
            i_loc: self.adc(4, s.i_loc_ma),
            i_grip: self.adc(5, s.i_grip_ma),
            i_bo: self.adc(6, s.bolter.current_ma),
            grav: self.imu(0, 7),
            hip_cdeg: hip,
            arm_switch: self.arm_switch(0),
        }
    }

    /// Board B's raw sensors now.
    pub fn sensors_b(&self) -> SensorsB {
        let s = &self.sides[1];
        SensorsB {
            v_bat: self.volts_raw(11, self.battery_v() - 0.02),
            i_loc: self.adc(12, s.i_loc_ma),
            i_grip: self.adc(13, s.i_grip_ma),
            i_bo: self.adc(14, s.bolter.current_ma),
            grav: self.imu(1, 15),
            arm_switch: self.arm_switch(1),
        }
    }

    // ------------------------------------------------------------ geometry

    /// Quarter turns from A's face to B's face that the current arm lengths and hip
    /// angle realise, if they match one of the four configurations.
    fn geometry(&self) -> Option<i8> {
        let (a, b, h) = (self.sides[0].arm_us, self.sides[1].arm_us, self.hip_cdeg);
        let arms = |us: u16| near(a, us as f64, GEOM_ARM_TOL_US) && near(b, us as f64, GEOM_ARM_TOL_US);
        let hip = |c: f64| near(h, c, GEOM_HIP_TOL_CDEG);
        if hip(0.0) && arms(servo::ARM_CONTRACTED_US) {
            Some(0)
        } else if hip(0.0) && arms(servo::ARM_EXTENDED_US) {
            Some(2)
        } else if hip(9000.0) && arms(servo::ARM_TURN_US) {
            Some(1)
        } else if hip(-9000.0) && arms(servo::ARM_TURN_US) {
            Some(-1)
        } else {
            None
        }
    }

    /// The face side `i` would reach given the other side's grip and the geometry.
    fn predicted_face(&self, i: usize) -> Option<Face> {
        let d = self.geometry()?;
        let other = self.sides[1 - i].gripped?;
        Some(if i == 1 { other.rotate(d) } else { other.rotate(-d) })
    }

    fn both_gripped(&self) -> bool {
        self.sides[0].gripped.is_some() && self.sides[1].gripped.is_some()
    }

    // ------------------------------------------------------------ physics

    fn integrate(&mut self, dt_ms: u64) {
        if dt_ms == 0 {
            return;
        }
        let dt = dt_ms as f64 / 1000.0;
        let locked = self.both_gripped() || self.fallen;
        let v_servo = servo::SERVO_SPEED_US_PER_S as f64;
        let mut servo_ma = 0.0;
        let jam = self.has(Fault::FastenerJam);
        let fastener_face = self.sides[0].gripped.or(self.sides[1].gripped);

        for i in 0..2 {
            let side = if i == 0 { Side::A } else { Side::B };
            let stuck = self.has(Fault::StuckArm(side));
            let obstacle = self.has(Fault::Obstacle(side));
            let s = &mut self.sides[i];
            // arm
            s.i_loc_ma = 0.0;
            if let Some(cmd) = s.arm_cmd {
                let target = cmd as f64;
                let err = target - s.arm_us;
                if err.abs() < 0.5 {
                    s.i_loc_ma = ARM_HOLD_MA;
                } else if stuck {
                    s.i_loc_ma = ARM_STUCK_MA;
                } else if obstacle {
                    s.i_loc_ma = ARM_OBSTACLE_MA;
                } else if locked {
                    s.i_loc_ma = ARM_BLOCKED_MA;
                } else {
                    let step = (v_servo * dt).min(err.abs());
                    s.arm_us += step * err.signum();
                    s.i_loc_ma = ARM_MOVE_MA;
                }
            }
            // gripper
            s.i_grip_ma = 0.0;
            if let Some(cmd) = s.grip_cmd {
                // The gripper's end stops (its revision): beyond them the servo stalls.
                let (stop_lo, stop_hi) = self.phys.grip_stops_us[i];
                let target = (cmd as f64).clamp(stop_lo, stop_hi);
                let err = target - s.grip_us;
                if err.abs() >= 0.5 {
                    let step = (v_servo * dt).min(err.abs());
                    s.grip_us += step * err.signum();
                    s.i_grip_ma = GRIP_MOVE_MA;
                } else if (cmd as f64 - target).abs() >= 0.5 {
                    s.i_grip_ma = GRIP_STALL_MA;
                } else if s.gripped.is_some() {
                    s.i_grip_ma = GRIP_HOLD_FACE_MA;
                } else if s.grip_us <= self.phys.grip_closed_us[i] + GRIP_ATTACH_US {
                    s.i_grip_ma = GRIP_HOLD_EMPTY_MA;
                } else {
                    s.i_grip_ma = GRIP_OPEN_MA;
                }
            }
            // bolter: the fastener pair under the selected mux channel
            let drive = s.bolter_cmd;
            let pair_no = s.mux + 1;
            let pair = match (fastener_face, drive) {
                (Some(face), BolterDrive::RotateLock | BolterDrive::RotateUnlock) if s.gripped.is_some() => {
                    Some(self.fasteners.entry((face, pair_no)).or_default())
                }
                _ => None,
            };
            let on_face = s.gripped.is_some();
            s.bolter.step(dt, drive, on_face, pair, jam, &mut self.rng);
            servo_ma += s.i_loc_ma + s.i_grip_ma + s.bolter.current_ma;
        }
        // attempts end when both bolters are home
        if self.sides.iter().all(|s| s.bolter.pos <= 0.0) {
            for p in self.fasteners.values_mut() {
                p.end_attempt();
            }
        }

        // hip
        let mut hip_ma = 0.0;
        match self.hip_cmd {
            Some(cmd) if locked => {
                self.hip_vel = 0.0;
                hip_ma = HIP_IDLE_MA + HIP_STALL_MA_PER_CDEG_S * (cmd as f64).abs();
            }
            Some(cmd) => {
                let bias = HIP_BIAS_CDEG_S * (1.0 + (self.hip_cdeg / 9000.0 * std::f64::consts::FRAC_PI_2).sin());
                let goal = (HIP_GAIN * cmd as f64 - bias).clamp(-HIP_VMAX_CDEG_S, HIP_VMAX_CDEG_S);
                self.hip_vel += (goal - self.hip_vel) * (dt / HIP_TAU_S).min(1.0);
                self.hip_cdeg += self.hip_vel * dt;
                let lim = servo::HIP_MAX_CDEG as f64;
                if self.hip_cdeg.abs() > lim {
                    self.hip_cdeg = self.hip_cdeg.clamp(-lim, lim);
                    self.hip_vel = 0.0;
                    hip_ma = HIP_IDLE_MA + HIP_STALL_MA_PER_CDEG_S * (cmd as f64).abs();
                } else {
                    hip_ma = HIP_IDLE_MA + HIP_MA_PER_CDEG_S * self.hip_vel.abs();
                }
            }
            None => self.hip_vel = 0.0,
        }
        self.sides[0].i_loc_ma += hip_ma;
        servo_ma += hip_ma;

        // grippers attach / release (around each gripper's own closed width)
        for i in 0..2 {
            let g = self.sides[i].grip_us;
            let closed = self.phys.grip_closed_us[i];
            if g >= closed + GRIP_RELEASE_US {
                self.sides[i].gripped = None;
            } else if g <= closed + GRIP_ATTACH_US
                && self.sides[i].gripped.is_none()
                && self.sides[i].grip_cmd.is_some()
            {
                if let Some(f) = self.predicted_face(i) {
                    self.sides[i].gripped = Some(f);
                }
            }
        }
        if self.sides.iter().all(|s| s.gripped.is_none()) {
            self.fallen = true;
        }
        // board orientation
        for i in 0..2 {
            let f = self.sides[i].gripped.or_else(|| self.predicted_face(i));
            if let Some(f) = f {
                self.sides[i].imu_face = f;
            }
        }

        // battery
        let v = self.battery_v().max(1.0);
        let servo_bat = if self.regulator_on || servo_ma > 0.0 {
            servo_ma * V_REG_NOMINAL / v / REG_EFFICIENCY
        } else {
            0.0
        };
        self.i_bat_ma = BOARDS_MA + servo_bat;
        self.used_mah += self.i_bat_ma * dt / 3600.0;
    }

    fn run_board_b(&mut self, t: u64) {
        self.b_rx.clear();
        self.line_ab.recv(t * 1000, &mut self.b_rx);
        let sensors = self.sensors_b();
        let rx = std::mem::take(&mut self.b_rx);
        self.board_b.tick(t, &sensors, &rx, &mut self.b_out);
        self.b_rx = rx;
        let out: SideActuators = self.b_out.side;
        let b = &mut self.sides[1];
        b.arm_cmd = out.arm_pwm;
        b.grip_cmd = out.grip_pwm;
        b.bolter_cmd = out.bolter;
        b.mux = self.b_out.mux;
        let cut = self.has_kind(FaultKind::CutCable);
        let (loss, corrupt) = (self.cfg.link_loss, self.cfg.link_corrupt);
        self.line_ba
            .send(t * 1000, &self.b_out.tx, loss, corrupt, cut, &mut self.rng);
    }

    /// Advances the simulation by `dt_ms` with board A's actuator commands `act` and
    /// the bytes board A wrote to the serial line (`a_to_b`); bytes board B sent that
    /// arrive by the end of the step are appended to `b_to_a`.
    pub fn step(&mut self, dt_ms: u32, act: &ActuatorsA, a_to_b: &[u8], b_to_a: &mut Vec<u8>) {
        let t0 = self.t_ms;
        let t1 = t0 + dt_ms as u64;
        let a = &mut self.sides[0];
        a.arm_cmd = if act.regulator_on { act.side.arm_pwm } else { None };
        a.grip_cmd = if act.regulator_on { act.side.grip_pwm } else { None };
        a.bolter_cmd = if act.regulator_on {
            act.side.bolter
        } else {
            BolterDrive::Off
        };
        a.mux = act.mux & 3;
        self.hip_cmd = if act.regulator_on { act.hip_speed } else { None };
        self.regulator_on = act.regulator_on;
        let cut = self.has_kind(FaultKind::CutCable);
        let (loss, corrupt) = (self.cfg.link_loss, self.cfg.link_corrupt);
        self.line_ab.send(t0 * 1000, a_to_b, loss, corrupt, cut, &mut self.rng);

        let mut t = t0;
        let period = self.cfg.b_period_ms.max(1) as u64;
        while self.b_next_ms < t1 {
            let tb = self.b_next_ms.max(t);
            self.integrate(tb - t);
            t = tb;
            self.t_ms = t;
            self.run_board_b(t);
            let jitter = if self.cfg.b_jitter_ms > 0 {
                self.rng.gen_range(0..=self.cfg.b_jitter_ms as u64)
            } else {
                0
            };
            self.b_next_ms += period + jitter;
        }
        self.integrate(t1 - t);
        self.t_ms = t1;
        self.line_ba.recv(t1 * 1000, b_to_a);
    }

    // ------------------------------------------------------------ truth

    pub fn truth(&self) -> Truth {
        let faces = [self.sides[0].gripped, self.sides[1].gripped];
        let state = match faces {
            [Some(a), Some(b)] if !self.fallen => state_of(a, b),
            _ => None,
        };
        Truth {
            time_ms: self.t_ms,
            state,
            faces,
            fallen: self.fallen,
            v_bat: self.battery_v(),
            i_bat_ma: self.i_bat_ma,
            hip_cdeg: self.hip_cdeg,
            arm_us: [self.sides[0].arm_us, self.sides[1].arm_us],
            grip_us: [self.sides[0].grip_us, self.sides[1].grip_us],
            i_loc_ma: [self.sides[0].i_loc_ma, self.sides[1].i_loc_ma],
            i_bo_ma: [self.sides[0].bolter.current_ma, self.sides[1].bolter.current_ma],
            faults: self.faults.clone(),
        }
    }
    /// Side physics (tests, diagnostics).
    pub fn side(&self, s: Side) -> &SideTruth {
        &self.sides[s as usize]
    }
    /// Serial line statistics (A→B, B→A).
    pub fn line_stats(&self) -> (serial::LineStats, serial::LineStats) {
        (self.line_ab.stats, self.line_ba.stats)
    }
    /// Board B's counters.
    pub fn board_b_counters(&self) -> mmic_domain::board_b::BoardBCounters {
        *self.board_b.counters()
    }
}
