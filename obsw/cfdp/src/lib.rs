//! Files over the space link (`docs/files.md`): a CFDP entity (CCSDS 727.0-B-5, class 1
//! and 2) on cfdp-rs' handlers and spacepackets' PDUs, the reserved messages it takes
//! (proxy put, directory listing), and the checked flat file store behind it. The same
//! code is the robot's entity and the ground's; time is passed in and PDUs go in and out
//! as byte slices, so the host obsw, the board and the ground each add only their I/O.
//!
//! no_std, no heap: capacities are in `mib::cfdp`.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]

#[cfg(feature = "std")]
pub mod dir;
pub mod entity;
pub mod flash;
pub mod gaps;
pub mod msg;
pub mod packet;
pub mod pdu;
pub mod seq;
pub mod store;
pub mod trace;
pub mod watch;

pub use entity::{Class, Entity, Finished, Parts, PutError};
/// The PDU types (the spacepackets version cfdp-rs is built on).
pub use spacepackets;
pub use store::{Checked, FileName, FlatStore, StoreError};
