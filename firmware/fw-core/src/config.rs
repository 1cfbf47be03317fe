//! Firmware capacities and periods: the one place where the images' queues and buffers
//! are sized. Shared numbers come from `mib::config`; the rest are firmware-only.

use mib::config as mc;

/// Period of the control loop task (sensor sampling, controllers, monitoring).
pub const CONTROL_PERIOD_MS: u32 = mc::CONTROL_PERIOD_MS;
/// Period of board B's heartbeat to board A.
pub const B_HEARTBEAT_PERIOD_MS: u32 = mc::B_HEARTBEAT_PERIOD_MS;
/// Baud rate of the A–B UART.
pub const AB_LINK_BAUD: u32 = mc::AB_LINK_BAUD;
/// Baud rate of the ground link UART (USB-serial bridge of the dev board).
pub const GROUND_BAUD: u32 = 115_200;

/// Largest space packet on the ground link.
pub const MAX_PACKET_LEN: usize = mc::MAX_PACKET_LEN;

/// Longest COBS encoding of `n` payload bytes, both 0x00 delimiters included.
pub const fn cobs_frame_len(n: usize) -> usize {
    // one overhead byte per started block of 254 bytes, plus the two sentinels
    n + n / 254 + 1 + 2
}

/// Ground link: longest encoded frame on the wire.
pub const GROUND_FRAME_MAX: usize = cobs_frame_len(MAX_PACKET_LEN);
/// Ground link: decoded TC buffer (one packet).
pub const GROUND_RX_BUF: usize = MAX_PACKET_LEN;

/// TCs decoded by the ground link and waiting for the OBSW task. When full, the ground
/// link drops the TC and counts it: an unacknowledged TC is resent by the ground.
pub const TC_QUEUE_DEPTH: usize = 4;
/// TM packets waiting for the ground link transmitter. When full, the producer keeps the
/// packet in the OBSW's own TM queue/store (nothing is dropped by the channel itself).
pub const TM_QUEUE_DEPTH: usize = 8;
/// Largest TM packet the firmware sends (HK ROBOT_STATUS is the largest, ~100 bytes;
/// memory dumps and definition reports are capped at this size).
pub const TM_PACKET_MAX: usize = 256;

/// Largest A–B link frame payload (heartbeat and module commands are far smaller).
pub const AB_PAYLOAD_MAX: usize = 64;
/// Longest encoded A–B frame on the wire.
pub const AB_FRAME_MAX: usize = cobs_frame_len(AB_PAYLOAD_MAX);
/// A–B frames received and waiting for the consumer (board A: control task; board B:
/// command executor). When full the oldest is kept and the new frame is counted lost.
pub const AB_RX_DEPTH: usize = 4;
/// A–B frames waiting for the UART transmitter.
pub const AB_TX_DEPTH: usize = 4;

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
const _: () = assert!(TM_PACKET_MAX <= MAX_PACKET_LEN);
