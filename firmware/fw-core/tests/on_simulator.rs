//! Board A's firmware control period (`fw_core::cycle::CycleA`) on the host, against the
//! MMIC-I simulator: the simulator stands behind the same peripheral traits the ESP32-C3
//! drivers implement (ADC channels, IMU, encoder, switch, servo pulses, multiplexer,
//! regulator enable), board B runs inside the simulator behind its serial line, and the
//! ground commands arrive COBS-framed through the uplink queue.
//!
//! Run: `cd firmware && cargo test -p fw-core --target x86_64-unknown-linux-gnu`.

use std::cell::RefCell;
use std::rc::Rc;

use arbitrary_int::{u11, u14};
use fw_core::config::{self, adc_channel as ch};
use fw_core::cycle::{CycleA, LinksA, PeripheralsA};
use fw_core::files::NoFiles;
use fw_core::link::{self, BarePackets, ByteQueue, Counters, TcChannel};
use fw_core::periph::side::bolter_pulses;
use fw_core::periph::{
    AnalogInput, AngleSensor, BolterServos, Enable, GravitySensor, HwError, PairSelect, ServoOutput, SideOutputs,
    Switch,
};
use mib::events::eid;
use mib::modes::{node, robot_mode};
use mib::tc::function;
use mmic_domain::{ActuatorsA, BolterDrive, SensorsA, SideActuators};
use mmic_sim::{Sim, SimConfig};
use mmic_stream::{encode, Deframer};
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::RingStore;
use satrs::spacepackets::ecss::tc::{AckFlags, PusTcCreator, PusTcSecondaryHeader};
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId, PusPacket};
use satrs::spacepackets::SpHeader;

/// What the simulated hardware sees and shows.
#[derive(Default)]
struct Bench {
    sensors: SensorsA,
    /// Pulse widths on the outputs (None = no pulses): arm, gripper, translate, rotate, hip.
    pulses: [Option<u16>; 5],
    mux: u8,
    regulator: bool,
}

type Shared = Rc<RefCell<Bench>>;

struct Adc(Shared);
impl AnalogInput for Adc {
    fn read_raw(&mut self, channel: u8) -> Result<u16, HwError> {
        let s = self.0.borrow().sensors;
        match channel {
            ch::V_BAT => Ok(s.v_bat),
            ch::V_REG => Ok(s.v_reg),
            ch::I_BAT => Ok(s.i_bat),
            ch::I_LOC => Ok(s.i_loc),
            ch::I_GRIP => Ok(s.i_grip),
            ch::I_BO => Ok(s.i_bo),
            _ => Err(HwError::OutOfRange),
        }
    }
}
struct Imu(Shared);
impl GravitySensor for Imu {
    fn gravity_mg(&mut self) -> Result<[i16; 3], HwError> {
        Ok(self.0.borrow().sensors.grav)
    }
}
struct Encoder(Shared);
impl AngleSensor for Encoder {
    fn angle_cdeg(&mut self) -> Result<i16, HwError> {
        Ok(self.0.borrow().sensors.hip_cdeg)
    }
}
struct ArmSwitch(Shared);
impl Switch for ArmSwitch {
    fn is_pushed(&mut self) -> Result<bool, HwError> {
        Ok(self.0.borrow().sensors.arm_switch)
    }
}
struct Servo(Shared, usize);
impl ServoOutput for Servo {
    fn set_pulse_us(&mut self, us: u16) -> Result<(), HwError> {
        self.0.borrow_mut().pulses[self.1] = Some(us);
        Ok(())
    }
    fn release(&mut self) -> Result<(), HwError> {
        self.0.borrow_mut().pulses[self.1] = None;
        Ok(())
    }
}
struct Mux(Shared);
impl PairSelect for Mux {
    fn select(&mut self, bits: u8) -> Result<(), HwError> {
        self.0.borrow_mut().mux = bits;
        Ok(())
    }
}
struct Regulator(Shared);
impl Enable for Regulator {
    fn set_enabled(&mut self, on: bool) -> Result<(), HwError> {
        self.0.borrow_mut().regulator = on;
        Ok(())
    }
}

const DRIVES: [BolterDrive; 5] = [
    BolterDrive::Descend,
    BolterDrive::Retract,
    BolterDrive::RotateLock,
    BolterDrive::RotateUnlock,
    BolterDrive::Reverse,
];

impl Bench {
    /// The actuator commands the pulses and lines amount to (what the simulator's
    /// servos, bolter and regulator respond to).
    fn actuators(&self) -> ActuatorsA {
        let [arm, grip, tr, rot, hip] = self.pulses;
        let bolter = match (tr, rot) {
            (Some(t), Some(r)) => DRIVES
                .into_iter()
                .find(|d| bolter_pulses(*d) == Some((t, r)))
                .expect("bolter pulses of no drive"),
            _ => BolterDrive::Off,
        };
        let max = mmic_domain::consts::HIP_MAX_CMD_CDEG_S as i32;
        let span = config::hip_servo::SPAN_US as i32;
        ActuatorsA {
            regulator_on: self.regulator,
            side: SideActuators {
                arm_pwm: arm,
                grip_pwm: grip,
                bolter,
            },
            hip_speed: hip.map(|p| ((p as i32 - config::hip_servo::STOP_US as i32) * max / span) as i16),
            mux: self.mux,
        }
    }
}

type Io = PeripheralsA<Adc, Imu, Encoder, ArmSwitch, Servo, Servo, Servo, Servo, Mux, Servo, Regulator>;

fn io(b: &Shared) -> Io {
    PeripheralsA {
        adc: Adc(b.clone()),
        imu: Imu(b.clone()),
        hip_encoder: Encoder(b.clone()),
        arm_switch: ArmSwitch(b.clone()),
        side: SideOutputs {
            arm: Servo(b.clone(), 0),
            grip: Servo(b.clone(), 1),
            bolter: BolterServos {
                translate: Servo(b.clone(), 2),
                rotate: Servo(b.clone(), 3),
            },
            mux: Mux(b.clone()),
        },
        hip: Servo(b.clone(), 4),
        regulator: Regulator(b.clone()),
    }
}

fn tc_frame(seq: u16, svc: u8, sub: u8, app: &[u8]) -> Vec<u8> {
    let apid = mib::apid::robot_apid(1).unwrap();
    let sp = SpHeader::new_for_unseg_tc(u11::new(apid), u14::new(seq), 0);
    let sec = PusTcSecondaryHeader::new(MessageTypeId::new(svc, sub), AckFlags::ALL, mib::config::GROUND_ID);
    let mut tc = [0u8; 64];
    let n = PusTcCreator::new(sp, sec, app, CreatorConfig::default())
        .write_to_bytes(&mut tc)
        .unwrap();
    let mut frame = vec![0u8; config::cobs_frame_len(n)];
    let m = encode(&tc[..n], &mut frame).unwrap();
    frame.truncate(m);
    frame
}

/// TM seen by the ground: (time, type, subtype, source data).
type Downlinked = Vec<(u64, u8, u8, Vec<u8>)>;

struct Rig {
    sim: Sim,
    bench: Shared,
    io: Io,
    cycle: CycleA,
    obsw: Obsw<RingStore<{ config::TM_STORE_BYTES }>>,
    links: LinksA<'static, { config::TM_DOWNLINK_BYTES }, { config::AB_RX_BYTES }, { config::AB_TX_BYTES }>,
    uplink: Deframer<{ config::GROUND_RX_BUF }>,
    downlink: Deframer<{ config::MAX_PACKET_LEN }>,
    t: u64,
    tm: Downlinked,
    /// Largest hip speed difference between what the OBSW commanded and what the
    /// pulse width carried to the servo (quantisation of the pulse).
    hip_quant: i32,
}

impl Rig {
    fn new(initial_state: u8) -> Rig {
        let links = LinksA {
            tcs: Box::leak(Box::new(TcChannel::new())),
            tc_stats: Box::leak(Box::new(Counters::new())),
            tm: Box::leak(Box::new(ByteQueue::new())),
            tm_stats: Box::leak(Box::new(Counters::new())),
            ab_rx: Box::leak(Box::new(ByteQueue::new())),
            ab_rx_stats: Box::leak(Box::new(Counters::new())),
            ab_tx: Box::leak(Box::new(ByteQueue::new())),
            ab_tx_stats: Box::leak(Box::new(Counters::new())),
        };
        let bench: Shared = Rc::new(RefCell::new(Bench::default()));
        let mut rig = Rig {
            sim: Sim::new(SimConfig {
                initial_state,
                seed: 7,
                ..SimConfig::default()
            }),
            io: io(&bench),
            bench,
            cycle: CycleA::new(),
            obsw: Obsw::new(
                Config {
                    robot: 1,
                    epoch_unix_ms: 0,
                },
                RingStore::default(),
            ),
            links,
            uplink: Deframer::new(),
            downlink: Deframer::new(),
            t: 0,
            tm: Vec::new(),
            hip_quant: 0,
        };
        rig.io.release_all();
        rig
    }

    fn send(&mut self, frame: &[u8]) {
        let before = self.links.tc_stats.get().delivered;
        link::uplink_bytes(&mut self.uplink, frame, self.links.tcs, self.links.tc_stats);
        assert_eq!(self.links.tc_stats.get().delivered, before + 1);
    }

    /// One 10 ms period: firmware cycle, then the simulator with what the outputs show.
    fn step(&mut self) {
        let period = config::CONTROL_PERIOD_MS;
        self.t += period as u64;
        self.bench.borrow_mut().sensors = self.sim.sensors_a();
        let commanded = self.cycle.run(
            self.t,
            &mut self.obsw,
            &mut BarePackets,
            &mut NoFiles,
            &mut self.io,
            &self.links,
        );
        let hw = self.bench.borrow().actuators();
        // Everything but the hip reaches the hardware exactly; the hip speed up to the
        // pulse-width resolution.
        assert_eq!(
            (hw.regulator_on, hw.side, hw.mux),
            (commanded.regulator_on, commanded.side, commanded.mux)
        );
        match (hw.hip_speed, commanded.hip_speed) {
            (Some(a), Some(b)) => self.hip_quant = self.hip_quant.max((a as i32 - b as i32).abs()),
            (a, b) => assert_eq!(a, b),
        }
        let mut a_to_b = [0u8; config::AB_TX_BYTES];
        let n = link::drain(self.links.ab_tx, &mut a_to_b);
        let mut b_to_a = Vec::new();
        self.sim.step(period, &hw, &a_to_b[..n], &mut b_to_a);
        link::push_bytes(self.links.ab_rx, &b_to_a, self.links.ab_tx_stats);
        let mut bytes = vec![0u8; config::TM_DOWNLINK_BYTES];
        let n = link::drain(self.links.tm, &mut bytes);
        for &b in &bytes[..n] {
            if let Some(frame) = self.downlink.push(b) {
                let frame = frame.unwrap();
                let r = match PusTmReader::new(frame, mib::config::TIMESTAMP_LEN) {
                    Ok(r) => r,
                    Err(e) => panic!("bad TM {:?}: {:02x?}", e, frame),
                };
                self.tm.push((
                    self.t,
                    PusPacket::service_type_id(&r),
                    PusPacket::message_subtype_id(&r),
                    r.user_data().to_vec(),
                ));
            }
        }
    }

    /// Runs until a TM[1,7] or TM[1,8] names request `seq` (returns its subtype).
    fn until_done(&mut self, seq: u16, max_ms: u64) -> u8 {
        let psc = (0xC000u16 | seq).to_be_bytes();
        let end = self.t + max_ms;
        while self.t < end {
            self.step();
            if let Some(tm) = self
                .tm
                .iter()
                .find(|(_, s, sub, d)| *s == 1 && (*sub == 7 || *sub == 8) && d[2..4] == psc)
            {
                return tm.2;
            }
        }
        panic!("request {seq} not completed in {max_ms} ms");
    }

    fn faults(&self) -> Vec<u16> {
        self.tm
            .iter()
            .filter(|(_, s, _, _)| *s == 5)
            .filter_map(|(_, _, _, d)| mib_wire::codec::decode_event(d).ok())
            .filter(|e| e.def.fault)
            .map(|e| e.def.id)
            .collect()
    }
}

fn mode_set(mode: u32) -> Vec<u8> {
    let mut app = [0u8; 10];
    app[..4].copy_from_slice(&node::ROBOT.to_be_bytes());
    app[4..8].copy_from_slice(&mode.to_be_bytes());
    app.to_vec()
}

#[test]
fn firmware_cycle_reconfigures_the_simulated_robot_xneg_to_xpos() {
    let mut rig = Rig::new(0);
    for _ in 0..50 {
        rig.step();
    }
    assert!(!rig.bench.borrow().regulator, "rail on in standby");
    rig.send(&tc_frame(1, 200, 1, &mode_set(robot_mode::OPERATIONAL)));
    assert_eq!(rig.until_done(1, 30_000), 7, "operational refused: {:?}", rig.faults());
    assert!(rig.bench.borrow().regulator);
    assert_eq!(rig.obsw.computed_state(), 0);

    let mut app = [0u8; 4];
    app[..2].copy_from_slice(&function::RECONFIGURE.to_be_bytes());
    app[2] = 0; // believed initial state: matched Xneg
    app[3] = 1; // target: matched Xpos
    rig.send(&tc_frame(2, 8, 1, &app));
    assert_eq!(
        rig.until_done(2, 180_000),
        7,
        "reconfiguration failed: {:?}",
        rig.faults()
    );
    let truth = rig.sim.truth();
    assert_eq!(truth.state, Some(1), "simulated robot ended in {truth}");
    assert!(!truth.fallen);
    assert_eq!(rig.obsw.computed_state(), 1);
    assert!(rig.faults().is_empty(), "faults {:?}", rig.faults());
    // Each primitive reported its completion (PRIMITIVE_DONE) and the state was reached.
    let events: Vec<u16> = rig
        .tm
        .iter()
        .filter(|(_, s, _, _)| *s == 5)
        .filter_map(|(_, _, _, d)| mib_wire::codec::decode_event(d).ok().map(|e| e.def.id))
        .collect();
    assert_eq!(events.iter().filter(|&&e| e == eid::PRIMITIVE_DONE).count(), 2);
    assert!(events.contains(&eid::STATE_REACHED));
    // No queue ever overflowed and no peripheral failed: every platform I/O counter the
    // OBSW reports (housekeeping PLATFORM_IO) is zero.
    assert_eq!(rig.links.tm_stats.get().overflow, 0);
    assert_eq!(rig.links.ab_tx_stats.get().overflow, 0);
    assert_eq!((rig.cycle.errors.total(), rig.cycle.output_errors), (0, 0));
    assert_eq!(rig.obsw.io, obsw_core::obsw::IoCounters::default());
}

#[test]
fn firmware_cycle_turns_the_hip_through_the_servo_pulse_xneg_to_yneg() {
    let mut rig = Rig::new(0);
    rig.send(&tc_frame(1, 200, 1, &mode_set(robot_mode::OPERATIONAL)));
    assert_eq!(rig.until_done(1, 30_000), 7, "operational refused: {:?}", rig.faults());
    let mut app = [0u8; 4];
    app[..2].copy_from_slice(&function::RECONFIGURE.to_be_bytes());
    app[2] = 0;
    app[3] = 2; // matched Yneg: needs a hip rotation
    rig.send(&tc_frame(2, 8, 1, &app));
    assert_eq!(
        rig.until_done(2, 240_000),
        7,
        "reconfiguration failed: {:?}",
        rig.faults()
    );
    assert_eq!(rig.sim.truth().state, Some(2));
    assert!(rig.faults().is_empty(), "faults {:?}", rig.faults());
    // The hip was driven through the continuous servo's pulse width: its speed reached
    // the servo within one microsecond's worth of speed.
    let per_us = mmic_domain::consts::HIP_MAX_CMD_CDEG_S as i32 / config::hip_servo::SPAN_US as i32;
    assert!(
        rig.hip_quant <= per_us,
        "hip speed quantisation {} cdeg/s",
        rig.hip_quant
    );
}
