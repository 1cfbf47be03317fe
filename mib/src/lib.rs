//! MMIC-I mission information base (MIB).
//!
//! Every number the system shares — APIDs, services, function IDs, arguments and
//! their ranges, housekeeping structures and parameters with calibrations and limits,
//! events, failure codes, modes, configuration states, motion primitives, the
//! reconfiguration map, on-board monitors, event-action links and tunable parameters —
//! is defined here, once. The OBSW, the simulator, the firmware and the ground tool
//! read it; the exporters (crate `mib-export`, beside this one) turn it into SCOS-2000
//! tables, XTCE, JSON, a Yamcs instance and the ICD.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]

pub mod apid;
pub mod cfdp;
pub mod config;
pub mod events;
pub mod failure;
pub mod fdir;
pub mod files;
pub mod ground_config;
pub mod headers;
pub mod hk;
pub mod host_config;
pub mod layout;
pub mod link;
pub mod memory;
pub mod modes;
pub mod modules;
pub mod params;
pub mod plan;
pub mod robot;
pub mod tc;
pub mod team;
pub mod tunables;
pub mod types;
pub mod update;

pub use failure::FailureCode;
pub use types::{Calib, Limits, PType};
