//! Module discovery on the target (docs/modules.md): both boards' control periods
//! (`fw_core::cycle`) on mock peripherals, booted as the images boot — board A probes
//! its side (`fw_core::modules::probe_a`) and starts discovery with the descriptor table
//! its image carries in flash (`fw_core::modules::TABLE_A`), board B probes its side and
//! sends `TABLE_B` over the A–B byte queues. Judged from the TM board A's downlink queue
//! carries: the module report TM[210,3] and, for an invalid set, CONFIG_INVALID.

use crate::harness::{Test, TestResult};
use crate::mock::{MockI2c, MockPin, MockSwitchLine};
use crate::t_cycle::{servo, side};
use crate::tests;
use crate::{check, check_eq, ok};
use fw_core::config::{self, i2c_addr};
use fw_core::cycle::{CycleA, CycleB, LinksA, LinksB, PeripheralsA, PeripheralsB};
use fw_core::files::NoFiles;
use fw_core::link::{self, BarePackets, ByteQueue, Counters, TcChannel};
use fw_core::modules::{probe_a, probe_b, TABLE_A, TABLE_B};
use fw_core::periph::ads7828::{command_byte, PowerMode};
use fw_core::periph::{ActiveLowEnable, ActiveLowSwitch, Ads7828, As5600, Mpu6000};
use mib::events::eid;
use mib::modules::config::ConfigId;
use mib::modules::descriptor::{MAX_TABLE_LEN, TABLE_HEADER_LEN};
use mib::modules::report::{ModuleReport, NO_SLOT};
use mib::modules::{default_set, slot, NUM_SLOTS};
use mmic_domain::discovery::ArmSwitch;
use mmic_stream::Deframer;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::RingStore;
use satrs::spacepackets::ecss::tm::PusTmReader;
use satrs::spacepackets::ecss::PusPacket;

pub const TESTS: &[Test] = tests![
    discovery_full_set_reports_every_module_within_2_s,
    discovery_imu_not_answering_is_config_invalid_naming_its_slot,
    discovery_corrupted_descriptor_of_board_b_is_config_invalid,
    discovery_arm_switch_probe_tells_pushed_released_absent,
    mib_free_text_is_left_out_of_the_firmware_build,
];

/// What the boards find at boot.
#[derive(Clone, Copy)]
struct Fit {
    /// Board A's MPU-6000 answers.
    imu_a: bool,
    /// Byte of board B's table to invert (index into `TABLE_B`).
    corrupt_b: Option<usize>,
}

/// Outcome seen on board A's downlink.
struct Seen {
    /// Simulated time since boot at which TM[210,3] left board A (ms).
    report_at: u64,
    report: ModuleReport,
    /// CONFIG_INVALID events: (reason, slot).
    invalid: heapless::Vec<(i64, i64), 4>,
    replaced: u32,
    /// Instructions retired by board A's boot-time discovery work: the probes and
    /// `start_discovery`, plus the control period in which discovery ran.
    instructions: u64,
}

fn instret() -> u64 {
    riscv::register::minstret::read64()
}

fn imu_bus(answers: bool) -> MockI2c {
    let mut bus = MockI2c::new(i2c_addr::MPU6000);
    bus.regs[0x75] = 0x68;
    bus.regs[0x3B..0x41].copy_from_slice(&[0x00, 0x00, 0xC0, 0x00, 0x00, 0x00]);
    bus.fail = !answers;
    bus
}

fn adc_bus(counts: [u16; 6]) -> MockI2c {
    let mut bus = MockI2c::new(i2c_addr::ADS7828);
    for (ch, v) in counts.iter().enumerate() {
        if let Some(cmd) = command_byte(ch as u8, PowerMode::RefOnAdcOn) {
            let _ = bus.replies.push((cmd, v.to_be_bytes()));
        }
    }
    bus
}

fn enc_bus() -> MockI2c {
    let mut bus = MockI2c::new(i2c_addr::AS5600);
    bus.regs[0x0B] = 0x20;
    bus.regs[0x0C] = 0x01;
    bus
}

/// Boots both boards as the images do and runs their control periods until board A's
/// module report went out (at most 3 s).
fn boot(fit: Fit) -> Result<Seen, crate::harness::Failure> {
    static TCS: TcChannel = TcChannel::new();
    static TM: ByteQueue<{ config::TM_DOWNLINK_BYTES }> = ByteQueue::new();
    static A_RX: ByteQueue<{ config::AB_RX_BYTES }> = ByteQueue::new();
    static A_TX: ByteQueue<{ config::AB_TX_BYTES }> = ByteQueue::new();
    static B_RX: ByteQueue<{ config::AB_RX_BYTES }> = ByteQueue::new();
    static B_TX: ByteQueue<{ config::AB_TX_BYTES }> = ByteQueue::new();
    static STATS: [Counters; 6] = [
        Counters::new(),
        Counters::new(),
        Counters::new(),
        Counters::new(),
        Counters::new(),
        Counters::new(),
    ];
    // The statics are shared by the tests of this file: start from empty queues.
    let mut scratch = [0u8; config::TM_DOWNLINK_BYTES];
    for q in [&A_RX, &A_TX, &B_RX, &B_TX] {
        link::drain(q, &mut scratch);
    }
    link::drain(&TM, &mut scratch);

    // Board A at boot: probes on the device buses before the drivers take them.
    let t0 = instret();
    let (mut imu_a, mut adc_a, mut enc_a) = (imu_bus(fit.imu_a), adc_bus([3200, 2020, 300, 50, 20, 0]), enc_bus());
    let mut line_a = MockSwitchLine::arm(true);
    let probes_a = probe_a(&mut imu_a, &mut adc_a, &mut enc_a, &mut line_a);
    let mut obsw = Obsw::new(
        Config {
            robot: 1,
            epoch_unix_ms: 0,
        },
        RingStore::<8192>::default(),
    );
    // The configuration accepted at integration: the set the flash tables describe.
    obsw.set_accepted_config(Some(fw_core::modules::integrated_config()));
    obsw.start_discovery(0, &TABLE_A, probes_a);
    let boot_cost = instret() - t0;

    // Board B at boot: its probes, its table (flash copy, possibly corrupted).
    let (mut imu_b, mut adc_b) = (imu_bus(true), adc_bus([3200, 0, 0, 50, 20, 0]));
    let mut line_b = MockSwitchLine::arm(true);
    let probes_b = probe_b(&mut imu_b, &mut adc_b, &mut line_b);
    let mut table_b = [0u8; MAX_TABLE_LEN];
    table_b[..TABLE_B.len()].copy_from_slice(&TABLE_B);
    if let Some(i) = fit.corrupt_b {
        table_b[i] ^= 0xFF;
    }
    let mut b = CycleB::new();
    b.board.set_modules(&table_b[..TABLE_B.len()], probes_b);

    let mut io_a = PeripheralsA {
        adc: Ads7828::new(adc_a, i2c_addr::ADS7828, PowerMode::RefOnAdcOn),
        imu: Mpu6000::init(imu_a, i2c_addr::MPU6000).ok(),
        hip_encoder: As5600::new(enc_a, i2c_addr::AS5600, 256),
        arm_switch: ActiveLowSwitch(MockPin::default()),
        side: side(),
        hip: servo(),
        regulator: ActiveLowEnable(MockPin { high: true, changes: 0 }),
    };
    let mut io_b = PeripheralsB {
        adc: Ads7828::new(adc_b, i2c_addr::ADS7828, PowerMode::RefOnAdcOn),
        imu: Mpu6000::init(imu_b, i2c_addr::MPU6000).ok(),
        arm_switch: ActiveLowSwitch(MockPin::default()),
        side: side(),
    };
    let links_a = LinksA {
        tcs: &TCS,
        tc_stats: &STATS[3],
        tm: &TM,
        tm_stats: &STATS[0],
        ab_rx: &A_RX,
        ab_rx_stats: &STATS[4],
        ab_tx: &A_TX,
        ab_tx_stats: &STATS[1],
    };
    let links_b = LinksB {
        ab_rx: &B_RX,
        ab_tx: &B_TX,
        ab_tx_stats: &STATS[2],
    };
    let mut a = CycleA::new();
    io_a.release_all();

    let mut wire = [0u8; config::AB_TX_BYTES];
    let mut deframer: Deframer<{ config::MAX_PACKET_LEN }> = Deframer::new();
    let mut invalid = heapless::Vec::new();
    let mut replaced = 0;
    let mut t = 0u64;
    while t < 3000 {
        t += config::CONTROL_PERIOD_MS as u64;
        let c0 = instret();
        a.run(t, &mut obsw, &mut BarePackets, &mut NoFiles, &mut io_a, &links_a);
        let period_cost = instret() - c0;
        b.run(t, &mut io_b, &links_b);
        let n = link::drain(&A_TX, &mut wire);
        link::push_bytes(&B_RX, &wire[..n], &STATS[5]);
        let n = link::drain(&B_TX, &mut wire);
        link::push_bytes(&A_RX, &wire[..n], &STATS[4]);
        let n = link::drain(&TM, &mut scratch);
        for &byte in &scratch[..n] {
            let Some(frame) = deframer.push(byte) else { continue };
            let r = ok!(PusTmReader::new(ok!(frame), mib::config::TIMESTAMP_LEN));
            match (PusPacket::service_type_id(&r), PusPacket::message_subtype_id(&r)) {
                (5, _) => {
                    if let Ok(ev) = mib_wire::codec::decode_event(r.user_data()) {
                        if ev.def.id == eid::CONFIG_INVALID {
                            let _ = invalid.push((ok!(ev.param("reason")), ok!(ev.param("slot"))));
                        } else if ev.def.id == eid::MODULE_REPLACED {
                            replaced += 1;
                        }
                    }
                }
                (210, 3) => {
                    let report = ok!(ModuleReport::parse(r.user_data()).ok());
                    return Ok(Seen {
                        report_at: t,
                        report,
                        invalid,
                        replaced,
                        instructions: boot_cost + period_cost,
                    });
                }
                _ => {}
            }
        }
    }
    Err(crate::harness::Failure::new(
        file!(),
        line!(),
        format_args!("no module report within {} ms", t),
    ))
}

// verifies: FW-MOD-01, FW-MOD-02, FW-MOD-03
fn discovery_full_set_reports_every_module_within_2_s() -> TestResult {
    let seen = boot(Fit {
        imu_a: true,
        corrupt_b: None,
    })?;
    let budget = mib::config::MODULE_DISCOVERY_BUDGET_MS as u64;
    check!(
        seen.report_at <= budget,
        "module report {} ms after boot (budget {} ms)",
        seen.report_at,
        budget
    );
    semihosting::println!(
        "    discovery: module report {} ms after boot, {} instructions (probes + start + discovery period)",
        seen.report_at,
        seen.instructions
    );
    check_eq!(seen.invalid.len(), 0);
    check_eq!(seen.replaced, 0);
    let r = &seen.report;
    check_eq!(r.config, ConfigId::Full.code());
    check_eq!((r.reason, r.reason_slot), (0, NO_SLOT));
    // Every slot present, each with the descriptor the flash tables carry (serials
    // SERIAL_BASE + slot: both halves arrived, B's over the A-B link).
    let expected = default_set(fw_core::modules::SERIAL_BASE);
    for (s, (got, want)) in r.set.iter().zip(expected.iter()).enumerate() {
        check_eq!(got, want, "slot {}", s);
    }
    check_eq!(r.set.len(), NUM_SLOTS);
    check!(r.set[slot::GRIPPER_B as usize].is_some());
    Ok(())
}

// verifies: FW-MOD-01, FW-MOD-04
fn discovery_imu_not_answering_is_config_invalid_naming_its_slot() -> TestResult {
    let seen = boot(Fit {
        imu_a: false,
        corrupt_b: None,
    })?;
    check!(seen.report_at <= mib::config::MODULE_DISCOVERY_BUDGET_MS as u64);
    // The table lists IMU A but its WHO_AM_I gets no answer: PROBE_DISAGREES (10) for
    // slot 1, one high-severity event, and the report names the same reason.
    check_eq!(seen.invalid.as_slice(), &[(10, slot::IMU_A as i64)]);
    check_eq!(seen.report.config, 0);
    check_eq!((seen.report.reason, seen.report.reason_slot), (10, slot::IMU_A));
    Ok(())
}

// verifies: FW-MOD-01, FW-MOD-04
fn discovery_corrupted_descriptor_of_board_b_is_config_invalid() -> TestResult {
    // A serial-number byte of B's third descriptor, flipped in B's flash copy: the
    // descriptor's CRC no longer matches when A reassembles B's half.
    let at = TABLE_HEADER_LEN + 2 * mib::modules::DESCRIPTOR_LEN + 5;
    check!(at < TABLE_B.len());
    let seen = boot(Fit {
        imu_a: true,
        corrupt_b: Some(at),
    })?;
    check!(seen.report_at <= mib::config::MODULE_DISCOVERY_BUDGET_MS as u64);
    // CORRUPT_DESCRIPTOR (3), no slot named (the entry cannot be trusted).
    check_eq!(seen.invalid.as_slice(), &[(3, NO_SLOT as i64)]);
    check_eq!(seen.report.config, 0);
    check_eq!((seen.report.reason, seen.report.reason_slot), (3, NO_SLOT));
    Ok(())
}

// verifies: FW-MOD-02
fn discovery_arm_switch_probe_tells_pushed_released_absent() -> TestResult {
    use fw_core::modules::arm_switch;
    let mut pushed = MockSwitchLine {
        connected: true,
        pushed: true,
        pull_up: false,
        reads: 0,
    };
    let mut released = MockSwitchLine {
        connected: true,
        pushed: false,
        pull_up: false,
        reads: 0,
    };
    let mut absent = MockSwitchLine {
        connected: false,
        pushed: false,
        pull_up: false,
        reads: 0,
    };
    check_eq!(arm_switch(&mut pushed), ArmSwitch::Pushed);
    check_eq!(arm_switch(&mut released), ArmSwitch::Released);
    check_eq!(arm_switch(&mut absent), ArmSwitch::Absent);
    // Both pulls were tried, and the run-time pull-up is selected again at the end.
    check_eq!((absent.reads, absent.pull_up), (2, true));
    // The probe on the I2C side: no device on the bus means no WHO_AM_I, no ack.
    let mut nobody = MockI2c::new(0x00);
    check_eq!(fw_core::modules::who_am_i(&mut nobody, i2c_addr::MPU6000), None);
    check!(!fw_core::modules::adc_acks(&mut nobody, i2c_addr::ADS7828));
    check!(!fw_core::modules::encoder_acks(&mut nobody, i2c_addr::AS5600));
    let mut imu = imu_bus(true);
    check_eq!(fw_core::modules::who_am_i(&mut imu, i2c_addr::MPU6000), Some(0x68));
    Ok(())
}

// verifies: FW-MOD-05
fn mib_free_text_is_left_out_of_the_firmware_build() -> TestResult {
    // The firmware builds the MIB without feature `descriptions`: table entries carry a
    // zero-sized `Text` and the failure-code text is empty; names and numbers stay.
    check_eq!(core::mem::size_of::<mib::types::Text>(), 0);
    check_eq!(mib::FailureCode::CRC_MISMATCH.description(), "");
    check_eq!(mib::types::text_str("any description"), "");
    let p = ok!(mib::params::by_id(mib::params::pid::V_BAT_A));
    check_eq!(p.name, "V_BAT_A");
    check_eq!(p.unit, "V");
    check!(p.limits.is_some());
    // The module database the firmware searches: every entry of MODULE_DB with its
    // identity, calibration and compatibility, without the URDF geometry.
    use mib::modules::db::{MODULE_DB, MODULE_INFO};
    check_eq!(MODULE_INFO.len(), MODULE_DB.len());
    for (i, d) in MODULE_DB.iter().enumerate() {
        let m = &MODULE_INFO[i];
        check_eq!(
            (m.ty, m.variant, m.revision),
            (d.ty, d.variant, d.revision),
            "entry {}",
            i
        );
        check_eq!(
            (m.cal_default, m.cal_range, m.compat),
            (d.cal_default, d.cal_range, d.compat),
            "entry {}",
            i
        );
    }
    check!(core::mem::size_of_val(&MODULE_INFO[0]) < core::mem::size_of_val(&MODULE_DB[0]));
    Ok(())
}
