//! Board A (ESP32-C3): the on-board software. `obsw_core::Obsw` (PUS services, mode
//! tree, FDIR, and through `mmic_domain` the motion generation, bolter state machine
//! and hip controller) runs on the control task; the rest moves bytes.
//!
//! | task        | runs                                              | talks through                    |
//! |-------------|---------------------------------------------------|----------------------------------|
//! | `control`   | every 10 ms `fw_core::cycle::CycleA::run`: TCs, sensors → `Obsw::tick` → outputs | `TCS`, `AB_RX` in; `AB_TX`, `TM` out |
//! | `uplink`    | ground link receiver: COBS frames → TC frames     | → `TCS` (channel of TC frames)   |
//! | `downlink`  | ground link transmitter: TM frames                | `TM` (COBS bytes) → USB          |
//! | `ab_rx`     | UART1 receiver from board B                       | → `AB_RX` (byte queue)           |
//! | `ab_tx`     | UART1 transmitter to board B                      | `AB_TX` → UART1                  |
//!
//! The ground link carries CCSDS TC and TM transfer frames with SDLS and COP-1
//! (`fw_core::spacelink`, the host's `mmic-link` code), keys and counters in the flash
//! area of `fw_core::link_store`. The PUS 15 store is `obsw_core::flash_store` on the
//! flash partition `mib::memory::TM_STORE` (the host obsw's store code, over esp-storage
//! here): it survives a reset, and the sequence counts go on from its newest packet. No bare space packet is taken or sent (docs/space-link.md: the
//! bare-packet link never in firmware; `fw_core::link::BarePackets` exists only for test
//! harnesses, and this image refuses to build with it).
//!
//! The paper's rx/tx queues between the ESP32's two cores become these bounded
//! embassy-sync queues between tasks of one executor on the single-core ESP32-C3.
//! Pins and wiring: docs/firmware.md.
#![no_std]
#![no_main]
#![deny(warnings)]

use core::cell::RefCell;
use embassy_executor::Spawner;
use embassy_time::{Duration, Ticker};
use esp_hal::gpio::{Input, InputConfig, Level, Output, OutputConfig, Pull};
use esp_hal::i2c::master::{Config as I2cConfig, I2c};
use esp_hal::ledc::channel::Number as Ch;
use esp_hal::ledc::Ledc;
use esp_hal::peripherals::TIMG1;
use esp_hal::time::Rate;
use esp_hal::timer::timg::{MwdtStage, TimerGroup, Wdt};
use esp_hal::uart::{Config as UartConfig, Uart, UartRx, UartTx};
use esp_hal::usb::usb_serial_jtag::{UsbSerialJtag, UsbSerialJtagRx, UsbSerialJtagTx};
use esp_hal::Async;
use esp_storage::FlashStorage;
use fw_core::config::{self as cfg, i2c_addr};
use fw_core::cycle::{CycleA, GroundSink, LinksA, PeripheralsA};
use fw_core::files::Files;
use fw_core::flash::SharedFlash;
use fw_core::link::{self, ByteQueue, Counters, TcChannel};
use fw_core::link_store::{self, FlashIvStore};
use fw_core::periph::ads7828::PowerMode;
use fw_core::periph::{
    ActiveLowEnable, ActiveLowSwitch, Ads7828, As5600, BolterMux, BolterServos, Mpu6000, SideOutputs,
};
use fw_core::spacelink::FrameLink;
use fw_esp::bus::{self, SensorDevice};
use fw_esp::servos::{Servo, ServoBank};
use mmic_cfdp::flash::{FlashStore, OpenError};
use mmic_cfdp::Parts;
use obsw_core::flash_store::MibFlashStore;
use obsw_core::obsw::{Config, Obsw};
use static_cell::StaticCell;

esp_bootloader_esp_idf::esp_app_desc!();

/// No heap: every allocation fails (`fw_core::no_heap`: why one is named at all).
#[global_allocator]
static NO_HEAP: fw_core::no_heap::NoHeap = fw_core::no_heap::NoHeap;

/// Uplinked TC frames (COBS decoded), waiting for the control task's frame link.
static TCS: TcChannel = TcChannel::new();
/// Downlink: TM frames (COBS encoded) waiting for the ground link transmitter.
static TM: ByteQueue<{ cfg::TM_DOWNLINK_BYTES }> = ByteQueue::new();
/// Bytes from board B / for board B.
static AB_RX: ByteQueue<{ cfg::AB_RX_BYTES }> = ByteQueue::new();
static AB_TX: ByteQueue<{ cfg::AB_TX_BYTES }> = ByteQueue::new();

static UPLINK_STATS: Counters = Counters::new();
static DOWNLINK_STATS: Counters = Counters::new();
static AB_RX_STATS: Counters = Counters::new();
static AB_TX_STATS: Counters = Counters::new();

/// The chip's flash, one driver for the layouts in its partitions: the key and counter
/// area (`link_store`) and the PUS 15 store. Both are used by the control task only.
static FLASH: StaticCell<RefCell<FlashStorage<'static>>> = StaticCell::new();
type Flash = RefCell<FlashStorage<'static>>;
/// The PUS 15 store on its partition (`mib::memory::store`).
type Store = MibFlashStore<'static, FlashStorage<'static>>;
/// The OBSW lives in a static (it holds the schedule and the plans: tens of KiB), owned
/// by the control task.
static OBSW: StaticCell<Obsw<Store>> = StaticCell::new();
type Link = FrameLink<FlashIvStore<SharedFlash<'static, FlashStorage<'static>>>>;
// Issue 22: the bare-packet ground link is never in firmware (test harnesses only).
const _: () = assert!(
    !fw_core::link::BARE_LINK_BUILT,
    "fw-core's test-only bare-packet link (feature bare-link) in board A's image"
);
/// The ground link (TC receiver with its SDLS keys, TM framer), owned by the control task.
static LINK: StaticCell<Link> = StaticCell::new();
/// The file service (docs/files.md, On the board), owned by the control task: the CFDP
/// entity over the file store on the `files` partition (`mib::memory::FILE_STORE`, the
/// same flash).
type FileService = Files<'static, FileStore>;
type FileStore = FlashStore<SharedFlash<'static, FlashStorage<'static>>>;
/// The file service's store, clock and outbox; the service.
static FILE_PARTS: StaticCell<Parts<FileStore>> = StaticCell::new();
static FILES: StaticCell<FileService> = StaticCell::new();

type Io = PeripheralsA<
    Ads7828<SensorDevice>,
    Option<Mpu6000<SensorDevice>>,
    As5600<SensorDevice>,
    ActiveLowSwitch<Input<'static>>,
    Servo,
    Servo,
    Servo,
    Servo,
    BolterMux<Output<'static>, Output<'static>>,
    Servo,
    ActiveLowEnable<Output<'static>>,
>;

/// `Ok` value of a start-up step, or a panic with a static message. Not `expect`: that
/// formats the error with `Debug`, which keeps the error type's `Debug` impl and the
/// formatting under it in the image. The panic record keeps this line (board A's
/// PREVIOUS_PANIC after the reset), which names the step.
macro_rules! must {
    ($r:expr, $what:literal) => {
        match $r {
            Ok(v) => v,
            Err(_) => panic!($what),
        }
    };
}

#[embassy_executor::task]
async fn uplink(rx: UsbSerialJtagRx<'static, Async>) {
    link::uplink_task(rx, &TCS, &UPLINK_STATS).await
}

#[embassy_executor::task]
async fn downlink(tx: UsbSerialJtagTx<'static, Async>) {
    link::queue_to_writer(&TM, tx, &DOWNLINK_STATS).await
}

#[embassy_executor::task]
async fn ab_rx(rx: UartRx<'static, Async>) {
    link::reader_to_queue(rx, &AB_RX, &AB_RX_STATS).await
}

#[embassy_executor::task]
async fn ab_tx(tx: UartTx<'static, Async>) {
    link::queue_to_writer(&AB_TX, tx, &AB_TX_STATS).await
}

/// The boot report, on a copy of the panic record so that interrupts stay enabled while
/// the events are encoded (a plain function: the copy lives on the stack, not in the
/// control task's future).
fn announce_boot(
    raw_reset: Option<u8>,
    obsw: &mut Obsw<Store>,
    sink: &mut GroundSink<'_, Link, { cfg::TM_DOWNLINK_BYTES }>,
) {
    let mut record = fw_esp::panic::with_record(|rec| *rec);
    fw_core::boot::announce(fw_esp::clock::now_ms(), raw_reset, &mut record, obsw, sink);
    fw_esp::panic::with_record(|rec| *rec = record);
}

#[embassy_executor::task]
async fn control(
    mut io: Io,
    mut watchdog: Wdt<TIMG1<'static>>,
    obsw: &'static mut Obsw<Store>,
    ground: &'static mut Link,
    raw_reset: Option<u8>,
    files: &'static mut FileService,
) {
    let links = LinksA {
        tcs: &TCS,
        tc_stats: &UPLINK_STATS,
        tm: &TM,
        tm_stats: &DOWNLINK_STATS,
        ab_rx: &AB_RX,
        ab_rx_stats: &AB_RX_STATS,
        ab_tx: &AB_TX,
        ab_tx_stats: &AB_TX_STATS,
    };
    let mut cycle = CycleA::new();
    io.release_all();
    let mut sink = GroundSink {
        link: &mut *ground,
        queue: &TM,
        counters: &DOWNLINK_STATS,
    };
    // BOOT with the named reset cause; the previous run's panic (if the RTC-RAM record
    // holds one) as PREVIOUS_PANIC, after which the record is marked reported.
    announce_boot(raw_reset, obsw, &mut sink);
    let mut ticker = Ticker::every(Duration::from_millis(cfg::CONTROL_PERIOD_MS as u64));
    let (bottom, top) = fw_esp::stack::bounds();
    let mut stack = fw_core::stack::StackWatch::new(bottom, top);
    loop {
        ticker.next().await;
        watchdog.feed();
        cycle.run(fw_esp::clock::now_ms(), obsw, ground, files, &mut io, &links);
        // PLATFORM_IO's IO_STACK_HIGH_WATER: the painted stack, swept a little per period.
        obsw.io.stack_high_water = stack.step(fw_core::stack::WORDS_PER_PERIOD, fw_esp::stack::word);
    }
}

/// The file service on the file store in its partition: what the store held stays (files
/// whose transfer a reset cut are removed by the service). A region that holds something
/// else than a store (a first boot after another layout) is formatted: its bytes were no
/// files.
fn file_service(flash: &'static Flash) -> &'static mut FileService {
    let region = mib::memory::FILE_STORE.offset..mib::memory::FILE_STORE.end();
    let store = match FlashStore::open(SharedFlash(flash), region.clone()) {
        Ok(s) => s,
        Err(OpenError::Flash) => {
            let mut raw = SharedFlash(flash);
            must!(FlashStore::format(&mut raw, region.clone()), "file store format");
            must!(FlashStore::open(raw, region), "file store after format")
        }
        Err(OpenError::Layout) => panic!("file store layout"),
    };
    FILES.init(Files::new(cfg::ROBOT, FILE_PARTS.init(Parts::new(store))))
}

#[esp_hal::main]
async fn main(spawner: Spawner) {
    // First: the free stack painted, for its high-water mark in housekeeping.
    fw_esp::stack::paint();
    let p = esp_hal::init(esp_hal::Config::default());
    let timg0 = TimerGroup::new(p.TIMG0);
    esp_rtos::start(timg0.timer0, p.FROM_CPU_INTR0);
    // Task watchdog: the control task feeds it every period.
    let mut watchdog = TimerGroup::new(p.TIMG1).wdt;
    watchdog.set_timeout(
        MwdtStage::Stage0,
        esp_hal::time::Duration::from_millis(cfg::WATCHDOG_TIMEOUT_MS),
    );
    watchdog.enable();
    let raw_reset = fw_esp::panic::reset_reason();

    // Regulator enable first, so the servo rail stays off: GPIO9, active low.
    let regulator = ActiveLowEnable(Output::new(p.GPIO9, Level::High, OutputConfig::default()));

    // Ground link: the chip's USB-Serial-JTAG (GPIO18/19), COBS-framed TC/TM frames.
    let (usb_rx, usb_tx) = UsbSerialJtag::new(p.USB_DEVICE).into_async().split();

    // A↔B link on UART1: TX GPIO21, RX GPIO20 (crossed to board B).
    let uart = must!(
        Uart::new(p.UART1, UartConfig::default().with_baudrate(cfg::AB_LINK_BAUD)),
        "UART1 config"
    )
    .with_tx(p.GPIO21)
    .with_rx(p.GPIO20)
    .into_async();
    let (uart_rx, uart_tx) = uart.split();

    // Sensor bus: I2C0, SDA GPIO4, SCL GPIO5, 400 kHz.
    let i2c = must!(
        I2c::new(
            p.I2C0,
            I2cConfig::default().with_frequency(Rate::from_khz(cfg::I2C_FREQ_KHZ)),
        ),
        "I2C0 config"
    )
    .with_sda(p.GPIO4)
    .with_scl(p.GPIO5);
    let bus = bus::share(i2c);
    // Arm-contracted switch to ground on GPIO10 (run-time pull: up).
    let mut arm_line = Input::new(p.GPIO10, InputConfig::default().with_pull(Pull::Up));
    // Module discovery (docs/modules.md): probe side A's modules before the drivers take the bus
    // (MPU-6000 WHO_AM_I, ADS7828 and AS5600 acknowledge, arm-switch line under both
    // pulls); the OBSW completes discovery with board B's half from the A-B link.
    let probes = fw_core::modules::probe_a(
        &mut bus::device(bus),
        &mut bus::device(bus),
        &mut bus::device(bus),
        &mut fw_esp::gpio::PullLine(&mut arm_line),
    );
    let adc = Ads7828::new(bus::device(bus), i2c_addr::ADS7828, PowerMode::RefOnAdcOn);
    let imu = Mpu6000::init(bus::device(bus), i2c_addr::MPU6000).ok();
    let hip_encoder = As5600::new(bus::device(bus), i2c_addr::AS5600, cfg::HIP_ENCODER_ZERO);

    // Servos on LEDC: arm GPIO0, gripper GPIO1, hip GPIO3, bolter translate GPIO6,
    // bolter rotate GPIO7.
    let bank = must!(ServoBank::new(Ledc::new(p.LEDC)), "LEDC timer");
    let side = SideOutputs {
        arm: must!(bank.servo(Ch::Channel0, p.GPIO0), "arm servo"),
        grip: must!(bank.servo(Ch::Channel1, p.GPIO1), "gripper servo"),
        bolter: BolterServos {
            translate: must!(bank.servo(Ch::Channel3, p.GPIO6), "bolter translate"),
            rotate: must!(bank.servo(Ch::Channel4, p.GPIO7), "bolter rotate"),
        },
        // Bolter multiplexer A0 GPIO8, A1 GPIO2 (strapping pins, pulled up on the board).
        mux: BolterMux::new(
            Output::new(p.GPIO8, Level::High, OutputConfig::default()),
            Output::new(p.GPIO2, Level::High, OutputConfig::default()),
        ),
    };
    let hip = must!(bank.servo(Ch::Channel2, p.GPIO3), "hip servo");
    let arm_switch = ActiveLowSwitch(arm_line);

    let flash: &'static Flash = FLASH.init(RefCell::new(FlashStorage::new(p.FLASH)));
    // The store keeps what it held before the reset (a write cut by it is repaired on
    // first use); the OBSW's sequence counts go on from its newest packet.
    let mut store = must!(Store::open(flash, mib::memory::store::OFFSET), "TM store layout");
    // No real-time clock: the on-board time goes on from the newest stored packet.
    let epoch_unix_ms = fw_core::resume::epoch_after_store(&mut store);
    let obsw = OBSW.init(Obsw::new(
        Config {
            robot: cfg::ROBOT,
            epoch_unix_ms,
        },
        store,
    ));
    // Board A's descriptor table (flash) and probes; discovery runs in the control period
    // once board B's half is in (or its wait is over), then the module report goes out.
    obsw.set_accepted_config(Some(fw_core::modules::integrated_config()));
    obsw.start_discovery(fw_esp::clock::now_ms(), &fw_core::modules::TABLE_A, probes);

    let files = file_service(flash);

    // Space link: keys from the provisioning area in flash (none: no TC frame is
    // accepted), SDLS counters and FARM-1 state from the counter log next to it.
    let ground = {
        let mut flash = SharedFlash(flash);
        let keys = link_store::read_keys(&mut flash, link_store::AREA_OFFSET);
        let store = FlashIvStore::open(flash, link_store::AREA_OFFSET);
        let resume = keys.map(|k| store.resume(k.tc_spi, k.tm_spi)).unwrap_or_default();
        LINK.init(FrameLink::new(keys.as_ref(), resume, store))
    };

    spawner.spawn(must!(uplink(usb_rx), "uplink task"));
    spawner.spawn(must!(downlink(usb_tx), "downlink task"));
    spawner.spawn(must!(ab_rx(uart_rx), "ab_rx task"));
    spawner.spawn(must!(ab_tx(uart_tx), "ab_tx task"));
    let io = Io {
        adc,
        imu,
        hip_encoder,
        arm_switch,
        side,
        hip,
        regulator,
    };
    spawner.spawn(must!(
        control(io, watchdog, obsw, ground, raw_reset, files),
        "control task"
    ));
}
