//! The QEMU board: board A's control task — `fw_core::cycle::CycleA::run` every 10 ms,
//! with the OBSW, the frame link and the PUS 15 store as board A composes them — on
//! QEMU's `virt` machine (RV32IMC), and board B's control period beside it over the
//! same A–B byte queues its UART fills. Only the I/O is this board's:
//!
//! | board A                          | here                                              |
//! |----------------------------------|---------------------------------------------------|
//! | USB serial, COBS frames          | the `virt` 16550 UART (`uart`), the same bytes     |
//! | flash (esp-storage)              | a NOR flash in a host file (`nor`, semihosting)   |
//! | I2C sensors, LEDC servos, GPIO   | mock devices of a robot at rest (`robot`)          |
//! | board B on UART1                 | `CycleB` in the same loop, queues crossed          |
//! | file service over the flash file store | the file service over the same flash store |
//! | embassy tasks, 10 ms ticker      | one loop: UART in, period when due, UART out       |
//!
//! Run by the end-to-end test (tests/tests/qemu_board_e2e.rs): `qemu-system-riscv32
//! -machine virt -bios none -semihosting-config enable=on,target=native -serial
//! unix:SOCKET -kernel qemu-board`, in a folder holding the flash file
//! [`FLASH_FILE`] (the module's 4 MB, erased, the key record provisioned at 0x9000 as
//! `firmware/tools/provision-keys.sh --out` writes it). Prints `READY` with what the
//! store held at boot on its semihosting stdout, and each board's stack high-water mark
//! when it grows (`stack`; board A's also in PLATFORM_IO HK, IO_STACK_HIGH_WATER).
#![no_std]
#![no_main]
#![deny(warnings)]
#![deny(unsafe_code)]

mod clock;
mod nor;
mod robot;
mod stack;
mod uart;

use core::cell::RefCell;
use fw_core::config::{self as cfg, i2c_addr};
use fw_core::cycle::{CycleA, CycleB, GroundSink, LinksA, LinksB, PeripheralsA, PeripheralsB};
use fw_core::files::Files;
use fw_core::flash::SharedFlash;
use fw_core::link::{self, ByteQueue, Counters, TcChannel};
use fw_core::link_store::{self, FlashIvStore};
use fw_core::periph::ads7828::PowerMode;
use fw_core::periph::{
    ActiveLowEnable, ActiveLowSwitch, Ads7828, As5600, BolterMux, BolterServos, Mpu6000, PwmServo, SideOutputs,
};
use fw_core::spacelink::FrameLink;
use mmic_cfdp::flash::{FlashStore, OpenError};
use mmic_stream::Deframer;
use obsw_core::flash_store::MibFlashStore;
use obsw_core::obsw::{Config, Obsw};
use obsw_core::tm::TmStore;
use robot::{ArmSwitchLine, Device, Pin, Pwm};

/// The flash file, in QEMU's working folder.
pub const FLASH_FILE: &core::ffi::CStr = c"qemu-board.flash";

/// Uplinked TC frames, the downlink, the A–B queues (as board A's and board B's statics).
static TCS: TcChannel = TcChannel::new();
static TM: ByteQueue<{ cfg::TM_DOWNLINK_BYTES }> = ByteQueue::new();
static A_RX: ByteQueue<{ cfg::AB_RX_BYTES }> = ByteQueue::new();
static A_TX: ByteQueue<{ cfg::AB_TX_BYTES }> = ByteQueue::new();
static B_RX: ByteQueue<{ cfg::AB_RX_BYTES }> = ByteQueue::new();
static B_TX: ByteQueue<{ cfg::AB_TX_BYTES }> = ByteQueue::new();
static UPLINK_STATS: Counters = Counters::new();
static DOWNLINK_STATS: Counters = Counters::new();
static A_RX_STATS: Counters = Counters::new();
static A_TX_STATS: Counters = Counters::new();
static B_RX_STATS: Counters = Counters::new();
static B_TX_STATS: Counters = Counters::new();

type Servo = PwmServo<Pwm>;
type Side = SideOutputs<Servo, Servo, Servo, Servo, BolterMux<Pin, Pin>>;
type Store<'a> = MibFlashStore<'a, nor::FileFlash>;
type Link<'a> = FrameLink<FlashIvStore<SharedFlash<'a, nor::FileFlash>>>;

fn servo() -> Servo {
    PwmServo::new(Pwm { duty: 0 })
}

fn side() -> Side {
    SideOutputs {
        arm: servo(),
        grip: servo(),
        bolter: BolterServos {
            translate: servo(),
            rotate: servo(),
        },
        mux: BolterMux::new(Pin { high: true }, Pin { high: true }),
    }
}

/// A start-up step that cannot go on: said on the semihosting stdout, exit code 2.
fn fail(what: &str) -> ! {
    semihosting::println!("qemu-board: {}", what);
    semihosting::process::exit(2)
}

/// No heap: every allocation fails (`fw_core::no_heap`: why one is named at all).
#[global_allocator]
static NO_HEAP: fw_core::no_heap::NoHeap = fw_core::no_heap::NoHeap;

#[riscv_rt::entry]
fn main() -> ! {
    let flash = RefCell::new(match nor::open(FLASH_FILE) {
        Ok(f) => f,
        Err(nor::OpenError::Open) => fail("no flash file qemu-board.flash in the working folder"),
        Err(nor::OpenError::Size(n)) => {
            semihosting::println!("qemu-board: qemu-board.flash has {} bytes", n);
            fail("the flash file is not the size of the module's flash")
        }
    });
    let mut uart = uart::Uart::new();
    let start = clock::now_ms();

    // Module discovery's probes over the mock buses, then the drivers take them (board
    // A's order).
    let (mut imu_bus, mut adc_bus, mut enc_bus) = (
        Device::imu(),
        Device::adc([3200, 2020, 300, 50, 20, 0]),
        Device::encoder(cfg::HIP_ENCODER_ZERO),
    );
    let probes_a = fw_core::modules::probe_a(&mut imu_bus, &mut adc_bus, &mut enc_bus, &mut ArmSwitchLine);
    let mut io_a = PeripheralsA {
        adc: Ads7828::new(adc_bus, i2c_addr::ADS7828, PowerMode::RefOnAdcOn),
        imu: Mpu6000::init(imu_bus, i2c_addr::MPU6000).ok(),
        hip_encoder: As5600::new(enc_bus, i2c_addr::AS5600, cfg::HIP_ENCODER_ZERO),
        arm_switch: ActiveLowSwitch(Pin { high: false }),
        side: side(),
        hip: servo(),
        regulator: ActiveLowEnable(Pin { high: true }),
    };
    let (mut imu_b, mut adc_b) = (Device::imu(), Device::adc([3200, 0, 0, 50, 20, 0]));
    let probes_b = fw_core::modules::probe_b(&mut imu_b, &mut adc_b, &mut ArmSwitchLine);
    let mut io_b = PeripheralsB {
        adc: Ads7828::new(adc_b, i2c_addr::ADS7828, PowerMode::RefOnAdcOn),
        imu: Mpu6000::init(imu_b, i2c_addr::MPU6000).ok(),
        arm_switch: ActiveLowSwitch(Pin { high: false }),
        side: side(),
    };

    // The PUS 15 store on its partition, as board A: what it held before the restart
    // stays, and the sequence counts go on from its newest packet.
    let mut store: Store<'_> = match MibFlashStore::open(&flash, mib::memory::store::OFFSET) {
        Ok(s) => s,
        Err(_) => fail("TM store layout"),
    };
    let held = store.len();
    // No real-time clock here either: the on-board time goes on from the newest stored
    // packet (board A's rule).
    let epoch_unix_ms = fw_core::resume::epoch_after_store(&mut store);
    let mut obsw = Obsw::new(
        Config {
            robot: cfg::ROBOT,
            epoch_unix_ms,
        },
        store,
    );
    obsw.set_accepted_config(Some(fw_core::modules::integrated_config()));
    obsw.start_discovery(clock::now_ms() - start, &fw_core::modules::TABLE_A, probes_a);

    // The file service (fw_core::files) over the file store in the flash's `files`
    // partition, as board A's image composes them: the files survive a restart.
    let region = mib::memory::FILE_STORE.offset..mib::memory::FILE_STORE.end();
    let file_store = match FlashStore::open(SharedFlash(&flash), region.clone()) {
        Ok(s) => s,
        Err(OpenError::Flash) => {
            if FlashStore::format(&mut SharedFlash(&flash), region.clone()).is_err() {
                fail("file store format");
            }
            match FlashStore::open(SharedFlash(&flash), region) {
                Ok(s) => s,
                Err(_) => fail("file store after format"),
            }
        }
        Err(OpenError::Layout) => fail("file store layout"),
    };
    let file_parts = mmic_cfdp::Parts::new(file_store);
    let mut files = Files::new(cfg::ROBOT, &file_parts);

    // The space link: keys and counters from the key and counter area, as board A.
    let mut ground: Link<'_> = {
        let mut area = SharedFlash(&flash);
        let keys = link_store::read_keys(&mut area, link_store::AREA_OFFSET);
        let counters = FlashIvStore::open(area, link_store::AREA_OFFSET);
        let resume = keys.map(|k| counters.resume(k.tc_spi, k.tm_spi)).unwrap_or_default();
        if keys.is_none() {
            semihosting::println!("qemu-board: no key record at 0x9000: no TC frame is accepted");
        }
        FrameLink::new(keys.as_ref(), resume, counters)
    };

    let links_a = LinksA {
        tcs: &TCS,
        tc_stats: &UPLINK_STATS,
        tm: &TM,
        tm_stats: &DOWNLINK_STATS,
        ab_rx: &A_RX,
        ab_rx_stats: &A_RX_STATS,
        ab_tx: &A_TX,
        ab_tx_stats: &A_TX_STATS,
    };
    let links_b = LinksB {
        ab_rx: &B_RX,
        ab_tx: &B_TX,
        ab_tx_stats: &B_TX_STATS,
    };
    let mut a = CycleA::new();
    let mut b = CycleB::new();
    b.board.set_modules(&fw_core::modules::TABLE_B, probes_b);
    io_a.release_all();
    {
        // BOOT (reset cause "other": QEMU names none; no panic record survives here).
        let mut sink = GroundSink {
            link: &mut ground,
            queue: &TM,
            counters: &DOWNLINK_STATS,
        };
        let mut record = [0u32; fw_core::panic_record::WORDS];
        fw_core::boot::announce(clock::now_ms() - start, None, &mut record, &mut obsw, &mut sink);
    }
    semihosting::println!("READY robot {} store {} packets", cfg::ROBOT, held);

    let mut deframer: Deframer<{ cfg::GROUND_RX_BUF }> = Deframer::new();
    let mut rx = [0u8; 64];
    let mut wire = [0u8; cfg::AB_TX_BYTES];
    let mut out = [0u8; cfg::TM_DOWNLINK_BYTES];
    let (mut out_len, mut out_at) = (0usize, 0usize);
    let period = u64::from(cfg::CONTROL_PERIOD_MS);
    let mut next = clock::now_ms();
    let mut probe = stack::Probe::new();
    let (mut high_a, mut high_b) = (0usize, 0usize);
    loop {
        // The uplink task: bytes from the UART through the deframer into the TC queue.
        loop {
            let n = uart.read(&mut rx);
            if n == 0 {
                break;
            }
            link::uplink_bytes(&mut deframer, &rx[..n], &TCS, &UPLINK_STATS);
        }
        let now = clock::now_ms();
        if now >= next {
            // A period late by more than one is not made up (board A's ticker skips too).
            next = if now - next > period {
                now + period
            } else {
                next + period
            };
            let t = now - start;
            let (_, depth_a) = probe.depth(|| a.run(t, &mut obsw, &mut ground, &mut files, &mut io_a, &links_a));
            let (_, depth_b) = probe.depth(|| b.run(t, &mut io_b, &links_b));
            if depth_a > high_a || depth_b > high_b {
                (high_a, high_b) = (high_a.max(depth_a), high_b.max(depth_b));
                semihosting::println!(
                    "stack high-water of the control period: board A {} bytes, board B {} bytes (probe {})",
                    high_a,
                    high_b,
                    stack::PROBE_BYTES
                );
            }
            // PLATFORM_IO's IO_STACK_HIGH_WATER, as board A reports its own.
            obsw.io.stack_high_water = high_a as u32;
            // The A–B UARTs: what each side queued arrives at the other.
            let n = link::drain(&A_TX, &mut wire);
            link::push_bytes(&B_RX, &wire[..n], &B_RX_STATS);
            let n = link::drain(&B_TX, &mut wire);
            link::push_bytes(&A_RX, &wire[..n], &A_RX_STATS);
        }
        // The downlink task: queued TM frames out of the UART.
        if out_at == out_len {
            out_len = link::drain(&TM, &mut out);
            out_at = 0;
        }
        out_at += uart.write(&out[out_at..out_len]);
        if out_at == out_len && clock::now_ms() < next {
            clock::idle_1ms();
        }
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    semihosting::println!("qemu-board: panic: {}", info);
    semihosting::process::exit(101)
}
