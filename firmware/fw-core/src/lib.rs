//! Hardware-independent part of the MMIC-I ESP32-C3 firmware.
//!
//! Everything here is plain `no_std` Rust without `unsafe` (but the allocator that fails,
//! [`no_heap`]), so it runs unchanged on the
//! boards, on the host and in the QEMU test binary:
//! - [`config`]: every firmware buffer, queue depth and period, derived from
//!   `mib::config` (the single place where firmware capacities are set);
//! - [`periph`]: the small traits the boards' peripherals sit behind, and the drivers
//!   for the ADS7828 ADC, the MPU-6000 IMU, the AS5600 hip encoder, the LEDC servo
//!   outputs and the bolter multiplexer, written against `embedded-hal` 1.0;
//! - [`panic_record`]: the layout of the panic reason kept in RTC fast RAM across a reset;
//! - [`boot`]: board A's boot report (named reset cause, the previous run's panic);
//! - [`cycle`]: one control period of each board, generic over the peripheral traits;
//! - [`link`], [`sampling`]: the bounded queues between tasks, sensor sampling;
//! - [`resume`]: the on-board time's epoch after a reset, from the newest stored packet;
//! - [`modules`]: the descriptor tables in flash and the probes of module discovery;
//! - [`team`]: the transport of inter-robot team packets (the radio is future work);
//! - [`spacelink`], [`link_store`]: board A's ground link over TC/TM transfer frames with
//!   SDLS and COP-1 (`mmic-link`), and its key and counter area in flash;
//! - [`files`]: board A's file service, the CFDP entity (`mmic-cfdp`) in the control
//!   period;
//! - [`no_heap`]: the global allocator without memory the binaries name (no heap);
//! - [`flash`]: one NOR flash shared by the layouts in its partitions (key and counter
//!   area, PUS 15 store).
//!
//! The robot logic itself (filters, controllers, bolter, A–B protocol, PUS services)
//! is `mmic-domain` and `obsw-core`, shared with the host.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]

pub mod boot;
pub mod config;
pub mod cycle;
pub mod files;
pub mod flash;
pub mod link;
pub mod link_store;
pub mod modules;
pub mod no_heap;
pub mod panic_record;
pub mod periph;
pub mod resume;
pub mod sampling;
pub mod spacelink;
pub mod stack;
pub mod team;
