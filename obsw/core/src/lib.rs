//! MMIC-I on-board software core: PUS services, mode tree and FDIR on top of the robot
//! domain. No I/O, no clock, no heap: the host binary and the firmware feed it TCs,
//! sensor readings and the time, and it returns TM and actuator commands.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]

pub mod accept;
pub mod fdir;
pub mod modes;
pub mod obsw;
pub mod time;
pub mod tm;
