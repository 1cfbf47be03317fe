//! MMIC-I on-board software core: PUS services, mode tree and FDIR on top of the robot
//! domain. No I/O, no clock, no heap: the host binary and the firmware feed it TCs,
//! sensor readings and the time, and it returns TM and actuator commands.
//!
//! A TC goes `accept` (header, CRC, MIB arguments) → `request` (a typed request of one
//! service, every MIB look-up done) → `obsw` (`duplicates`, verification, routing) → the
//! service's file under `services/`. Everything sent goes through `downlink`.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]

pub mod accept;
pub mod downlink;
mod duplicates;
pub mod failure;
pub mod fdir;
pub mod flash_store;
pub mod modes;
pub mod obsw;
pub mod request;
pub mod robot;
pub mod services;
pub mod time;
pub mod tm;
