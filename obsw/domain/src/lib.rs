//! MMIC-I robot domain (no_std, no heap, no I/O).
//!
//! Everything board A and board B do with the robot, free of I/O so that the host, the
//! simulator and the firmware run the same code. Time is always passed in (`now_ms`).
//!
//! - [`search`]: shortest primitive sequence over `mib::robot::RECONFIG_MAP` (BFS).
//! - [`filter`]: the 50-sample moving average applied to every raw sensor channel.
//! - [`imu`], [`estimate`]: gravity model and the configuration state computed from
//!   IMU gravity vectors, hip encoder and arm PWM.
//! - [`control`]: interpolated open-loop PWM and the hip PI controller.
//! - [`bolter`]: the bolter state machine for one fastener pair.
//! - [`ablink`]: the framed, CRC-checked board A ↔ board B protocol and A's link manager.
//! - [`board_b`]: board B, the subordinate.
//! - [`controller`]: board A's robot logic driven by the OBSW core.
//! - [`discovery`], [`calib`]: the module set found at boot and the calibration it brings.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]

pub mod ablink;
pub mod board_b;
pub mod bolter;
pub mod calib;
pub mod consts;
pub mod control;
pub mod controller;
pub mod discovery;
pub mod estimate;
pub mod filter;
pub mod imu;
pub mod search;
pub mod tunables;
pub mod types;

pub use mib::robot::Side;
pub use types::{ActuatorsA, BolterDrive, SensorsA, SensorsB, SideActuators};
