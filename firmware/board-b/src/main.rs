//! Board B (ESP32-C3): the subordinate. It executes board A's module commands for side
//! B (arm, gripper, bolter), acknowledges each, and sends A a heartbeat every
//! `mib::config::B_HEARTBEAT_PERIOD_MS` — all of it `mmic_domain::board_b::BoardB`.
//! This file only wires the hardware and runs three embassy tasks:
//!
//! | task      | runs                                   | talks through            |
//! |-----------|----------------------------------------|--------------------------|
//! | `control` | every 10 ms `fw_core::cycle::CycleB::run`: sensors → BoardB → outputs | `AB_RX` in, `AB_TX` out  |
//! | `ab_rx`   | UART1 receiver                         | → `AB_RX` (byte queue)   |
//! | `ab_tx`   | UART1 transmitter                      | `AB_TX` → UART1          |
//! | `console` | once at boot: reset cause and the panic recorded before the reset, as text on the USB-Serial-JTAG port | — |
//!
//! Pins: see docs/firmware.md.
#![no_std]
#![no_main]
#![deny(warnings)]

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
use esp_hal::usb::usb_serial_jtag::{UsbSerialJtag, UsbSerialJtagTx};
use esp_hal::Async;
use fw_core::config::{self as cfg, i2c_addr};
use fw_core::cycle::{CycleB, LinksB, PeripheralsB};
use fw_core::link::{self, ByteQueue, Counters};
use fw_core::panic_record::PanicReport;
use fw_core::periph::ads7828::PowerMode;
use fw_core::periph::{ActiveLowSwitch, Ads7828, BolterMux, BolterServos, Mpu6000, SideOutputs};
use fw_esp::bus::{self, SensorDevice};
use fw_esp::servos::{Servo, ServoBank};
use mmic_domain::discovery::BoardProbes;

esp_bootloader_esp_idf::esp_app_desc!();

/// No heap: every allocation fails (`fw_core::no_heap`: why one is named at all).
#[global_allocator]
static NO_HEAP: fw_core::no_heap::NoHeap = fw_core::no_heap::NoHeap;

/// Bytes from board A, waiting for the control task.
static AB_RX: ByteQueue<{ cfg::AB_RX_BYTES }> = ByteQueue::new();
/// Bytes for board A, waiting for the UART.
static AB_TX: ByteQueue<{ cfg::AB_TX_BYTES }> = ByteQueue::new();
static AB_RX_STATS: Counters = Counters::new();
static AB_TX_STATS: Counters = Counters::new();

type Io = PeripheralsB<
    Ads7828<SensorDevice>,
    Option<Mpu6000<SensorDevice>>,
    ActiveLowSwitch<Input<'static>>,
    Servo,
    Servo,
    Servo,
    Servo,
    BolterMux<Output<'static>, Output<'static>>,
>;

#[embassy_executor::task]
async fn ab_rx(rx: UartRx<'static, Async>) {
    link::reader_to_queue(rx, &AB_RX, &AB_RX_STATS).await
}

#[embassy_executor::task]
async fn ab_tx(tx: UartTx<'static, Async>) {
    link::queue_to_writer(&AB_TX, tx, &AB_TX_STATS).await
}

/// Boot report on the debug console. Asynchronous: with no USB host attached the write
/// simply waits, and nothing else is held up.
#[embassy_executor::task]
async fn console(
    mut usb: UsbSerialJtagTx<'static, Async>,
    reset_cause: u8,
    raw_reset: Option<u8>,
    panic: Option<PanicReport>,
) {
    use core::fmt::Write as _;
    use embedded_io_async::Write as _;
    let mut line: heapless::String<{ cfg::PANIC_MSG_LEN + 64 }> = heapless::String::new();
    let name = fw_core::boot::reset_cause_name(reset_cause);
    let raw = raw_reset.unwrap_or(0);
    let _ = write!(line, "board-b: boot, reset cause {name} ({reset_cause}, raw {raw})\r\n");
    let _ = usb.write_all(line.as_bytes()).await;
    if let Some(p) = panic {
        line.clear();
        let _ = write!(line, "board-b: panic #{} before reset: {}\r\n", p.count, p.message);
        let _ = usb.write_all(line.as_bytes()).await;
    }
    let _ = usb.flush().await;
}

#[embassy_executor::task]
async fn control(mut io: Io, mut watchdog: Wdt<TIMG1<'static>>, probes: BoardProbes) {
    let links = LinksB {
        ab_rx: &AB_RX,
        ab_tx: &AB_TX,
        ab_tx_stats: &AB_TX_STATS,
    };
    let mut cycle = CycleB::new();
    // Side B's descriptor table (flash) and probes, sent to board A over the A-B link.
    cycle.board.set_modules(&fw_core::modules::TABLE_B, probes);
    io.side.release_all();
    let mut ticker = Ticker::every(Duration::from_millis(cfg::CONTROL_PERIOD_MS as u64));
    loop {
        ticker.next().await;
        watchdog.feed();
        cycle.run(fw_esp::clock::now_ms(), &mut io, &links);
    }
}

#[esp_hal::main]
async fn main(spawner: Spawner) {
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
    let panic = fw_esp::panic::take_report();
    let reset_cause = fw_core::boot::reset_cause(raw_reset, panic.is_some());
    let (_, usb_tx) = UsbSerialJtag::new(p.USB_DEVICE).into_async().split();

    // A↔B link on UART1: TX GPIO21, RX GPIO20 (crossed to board A).
    let uart = Uart::new(p.UART1, UartConfig::default().with_baudrate(cfg::AB_LINK_BAUD))
        .expect("UART1 config")
        .with_tx(p.GPIO21)
        .with_rx(p.GPIO20)
        .into_async();
    let (uart_rx, uart_tx) = uart.split();

    // Sensor bus: I2C0, SDA GPIO4, SCL GPIO5, 400 kHz.
    let i2c = I2c::new(
        p.I2C0,
        I2cConfig::default().with_frequency(Rate::from_khz(cfg::I2C_FREQ_KHZ)),
    )
    .expect("I2C0 config")
    .with_sda(p.GPIO4)
    .with_scl(p.GPIO5);
    let bus = bus::share(i2c);
    // Arm-contracted switch to ground on GPIO10 (run-time pull: up).
    let mut arm_line = Input::new(p.GPIO10, InputConfig::default().with_pull(Pull::Up));
    // Module discovery (docs/modules.md): side B's probes; the table and probes go to board A
    // over the A-B link (BoardB::set_modules).
    let probes = fw_core::modules::probe_b(
        &mut bus::device(bus),
        &mut bus::device(bus),
        &mut fw_esp::gpio::PullLine(&mut arm_line),
    );
    let adc = Ads7828::new(bus::device(bus), i2c_addr::ADS7828, PowerMode::RefOnAdcOn);
    let imu = Mpu6000::init(bus::device(bus), i2c_addr::MPU6000).ok();

    // Servos on LEDC: arm GPIO0, gripper GPIO1, bolter translate GPIO6, rotate GPIO7.
    let bank = ServoBank::new(Ledc::new(p.LEDC)).expect("LEDC timer");
    let side = SideOutputs {
        arm: bank.servo(Ch::Channel0, p.GPIO0).expect("arm servo"),
        grip: bank.servo(Ch::Channel1, p.GPIO1).expect("gripper servo"),
        bolter: BolterServos {
            translate: bank.servo(Ch::Channel2, p.GPIO6).expect("bolter translate"),
            rotate: bank.servo(Ch::Channel3, p.GPIO7).expect("bolter rotate"),
        },
        // Bolter multiplexer A0 GPIO8, A1 GPIO2 (strapping pins, pulled up on the board).
        mux: BolterMux::new(
            Output::new(p.GPIO8, Level::High, OutputConfig::default()),
            Output::new(p.GPIO2, Level::High, OutputConfig::default()),
        ),
    };
    let arm_switch = ActiveLowSwitch(arm_line);

    spawner.spawn(console(usb_tx, reset_cause, raw_reset, panic).expect("console task"));
    spawner.spawn(ab_rx(uart_rx).expect("ab_rx task"));
    spawner.spawn(ab_tx(uart_tx).expect("ab_tx task"));
    let io = Io {
        adc,
        imu,
        arm_switch,
        side,
    };
    spawner.spawn(control(io, watchdog, probes).expect("control task"));
}
