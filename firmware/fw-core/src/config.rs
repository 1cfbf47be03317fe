//! Firmware capacities and periods: the one place where the images' queues and buffers
//! are sized. Shared numbers come from `mib::config`; the rest are firmware-only.

use mib::config as mc;

/// Period of the control loop task (sensor sampling, controllers, monitoring).
pub const CONTROL_PERIOD_MS: u32 = mc::CONTROL_PERIOD_MS;
/// Period of board B's heartbeat to board A.
pub const B_HEARTBEAT_PERIOD_MS: u32 = mc::B_HEARTBEAT_PERIOD_MS;
/// Baud rate of the A–B UART.
pub const AB_LINK_BAUD: u32 = mc::AB_LINK_BAUD;

/// Largest space packet on the ground link.
pub const MAX_PACKET_LEN: usize = mc::MAX_PACKET_LEN;

/// Longest COBS encoding of `n` payload bytes, both 0x00 delimiters included.
pub const fn cobs_frame_len(n: usize) -> usize {
    // The one rule of the stream framing (the `cobs` crate's bound plus the two sentinels).
    mmic_stream::encoded_len(n)
}

/// Ground link: longest encoded frame on the wire.
pub const GROUND_FRAME_MAX: usize = cobs_frame_len(MAX_PACKET_LEN);
/// Ground link: decoded TC buffer (one packet).
pub const GROUND_RX_BUF: usize = MAX_PACKET_LEN;

/// TCs decoded by the ground link and waiting for the OBSW task. When full, the ground
/// link drops the TC and counts it: an unacknowledged TC is resent by the ground.
pub const TC_QUEUE_DEPTH: usize = 4;
/// Downlink byte queue (COBS frames of TM packets) between the OBSW task and the ground
/// link transmitter: four of the largest packets. When a frame does not fit, the OBSW
/// keeps the packet in its own TM queue / on-board store and retries next cycle.
pub const TM_DOWNLINK_BYTES: usize = 4 * GROUND_FRAME_MAX;

/// A–B link: bytes received and waiting for the control task. 115 200 Bd carries ~115
/// bytes per 10 ms control period; the queue holds four periods. Overflowing bytes are
/// dropped and counted; the A–B protocol's CRC and resend recover.
pub const AB_RX_BYTES: usize = 512;
/// A–B link: bytes waiting for the UART transmitter (four periods' worth of the
/// domain's per-tick transmit capacity).
pub const AB_TX_BYTES: usize = 512;

/// UART receive chunk read per wake-up (bytes).
pub const UART_READ_CHUNK: usize = 64;
/// UART RX FIFO threshold that wakes the reader (bytes).
pub const UART_FIFO_THRESHOLD: u16 = 32;

/// Bytes of panic message kept in RTC fast RAM for the next boot.
pub const PANIC_MSG_LEN: usize = 120;

/// Servo PWM frame (50 Hz).
pub const SERVO_PERIOD_US: u32 = 20_000;
/// Servo PWM frequency.
pub const SERVO_FREQ_HZ: u32 = 1_000_000 / SERVO_PERIOD_US;

/// ADS7828 channel wiring (single-ended inputs), identical on both boards.
pub mod adc_channel {
    /// Battery voltage through the 15 V full-scale divider.
    pub const V_BAT: u8 = 0;
    /// Regulated 7.4 V servo supply.
    pub const V_REG: u8 = 1;
    /// Battery current (board A only: the pack is shared).
    pub const I_BAT: u8 = 2;
    /// Locomotion current (arm + hip on A, arm on B).
    pub const I_LOC: u8 = 3;
    /// Gripper current.
    pub const I_GRIP: u8 = 4;
    /// Bolter current.
    pub const I_BO: u8 = 5;
    /// Channels sampled every control cycle.
    pub const SAMPLED: [u8; 6] = [V_BAT, V_REG, I_BAT, I_LOC, I_GRIP, I_BO];
}

/// I2C addresses on the sensor bus.
pub mod i2c_addr {
    /// ADS7828 with A1 = A0 = 0.
    pub const ADS7828: u8 = 0x48;
    /// MPU-6000 with AD0 = 0.
    pub const MPU6000: u8 = 0x68;
    /// AS5600 magnetic absolute encoder (fixed address).
    pub const AS5600: u8 = 0x36;
}

/// I2C bus clock.
pub const I2C_FREQ_KHZ: u32 = 400;

const _: () = assert!(GROUND_FRAME_MAX == 1024 + 4 + 1 + 2);

/// Bolter drive pulse widths (continuous-rotation servos, 1500 µs = stop). Hardware
/// wiring values of the bolter mechanism, not telemetry: candidates for
/// `mib::robot::servo` if the ground ever needs them.
pub mod bolter_servo {
    pub const STOP_US: u16 = 1500;
    /// Translation toward the fastener (pushes against the stop when there).
    pub const TRANSLATE_PUSH_US: u16 = 1800;
    /// Translation back toward home.
    pub const TRANSLATE_BACK_US: u16 = 1200;
    /// Head rotation in the locking direction.
    pub const ROTATE_LOCK_US: u16 = 1800;
    /// Head rotation in the releasing direction.
    pub const ROTATE_UNLOCK_US: u16 = 1200;
}

/// Robot number of this image (1..=254, APID 0x100 + N), from the build environment
/// variable `MMIC_ROBOT` (default `mib::apid::DEFAULT_ROBOT`).
pub const ROBOT: u8 = match option_env!("MMIC_ROBOT") {
    Some(s) => parse_robot(s),
    None => mib::apid::DEFAULT_ROBOT,
};

const fn parse_robot(s: &str) -> u8 {
    let b = s.as_bytes();
    let mut i = 0;
    let mut v: u32 = 0;
    assert!(!b.is_empty(), "MMIC_ROBOT is empty");
    while i < b.len() {
        assert!(b[i] >= b'0' && b[i] <= b'9', "MMIC_ROBOT must be a decimal number");
        v = v * 10 + (b[i] - b'0') as u32;
        assert!(v <= 254, "MMIC_ROBOT must be 1..=254");
        i += 1;
    }
    assert!(v >= 1, "MMIC_ROBOT must be 1..=254");
    v as u8
}

/// Bytes of the RAM TM store (`obsw_core::tm::RingStore`) of the test harnesses that run
/// the control period without a flash (the host tests against the simulator, the QEMU
/// tests): ≈ 520 HK ROBOT_STATUS reports of 91 bytes. Board A and the QEMU board keep
/// their PUS 15 store in flash (`obsw_core::flash_store`, partition `mib::memory::TM_STORE`).
pub const TM_STORE_BYTES: usize = 48 * 1024;

/// Hip continuous servo: pulse width at standstill and the span that corresponds to
/// the controller's largest speed command (`mmic_domain::consts::HIP_MAX_CMD_CDEG_S`).
pub mod hip_servo {
    pub const STOP_US: u16 = 1500;
    pub const SPAN_US: u16 = 500;
}

/// AS5600 raw count read with the hip at its contracted (home) angle; set per robot at
/// integration (build variable `MMIC_HIP_ZERO`, 0..=4095; default 0).
pub const HIP_ENCODER_ZERO: u16 = match option_env!("MMIC_HIP_ZERO") {
    Some(s) => parse_u12(s),
    None => 0,
};

const fn parse_u12(s: &str) -> u16 {
    let b = s.as_bytes();
    let mut i = 0;
    let mut v: u32 = 0;
    assert!(!b.is_empty(), "MMIC_HIP_ZERO is empty");
    while i < b.len() {
        assert!(b[i] >= b'0' && b[i] <= b'9', "MMIC_HIP_ZERO must be a decimal number");
        v = v * 10 + (b[i] - b'0') as u32;
        assert!(v <= 4095, "MMIC_HIP_ZERO must be 0..=4095");
        i += 1;
    }
    v as u16
}

/// Task watchdog (TIMG1 MWDT, system reset): fed by the control task every period; a
/// control loop stalled for this long resets the chip (reset cause 8, `CoreMwdt1`,
/// reported in the next BOOT event).
pub const WATCHDOG_TIMEOUT_MS: u64 = 500;
const _: () = assert!(WATCHDOG_TIMEOUT_MS >= 10 * CONTROL_PERIOD_MS as u64);
