//! ESP32-C3 platform layer shared by the board A and board B images: everything that
//! touches esp-hal and is the same on both boards. The robot logic is in `mmic-domain`
//! and `obsw-core`; the hardware-independent glue in `fw-core`.
#![no_std]

pub mod bus;
pub mod clock;
pub mod defmt_sink;
pub mod gpio;
pub mod panic;
pub mod servos;
pub mod stack;
