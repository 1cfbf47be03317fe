//! MMIC-I space link: CCSDS TC (232.0-B-4) and TM (132.0-B-3) transfer frames, the CLCW,
//! COP-1 (232.1-B-2: FARM-1 on board, FOP-1 on the ground) and SDLS (355.0-B-2,
//! AES-256-GCM in Yamcs 5.12.8's layout). `no_std`, no heap, time passed in.
//!
//! Layers, smoltcp style:
//! - [`tc`], [`tm`], [`clcw`]: wire formats, a zero-copy view and a `Repr` each, checked
//!   constructors for untrusted bytes.
//! - [`sdls`]: security associations, the anti-replay window and the persisted IV counters.
//! - [`persist`]: the persisted link state record (SDLS counters, FARM-1), two CRC-checked
//!   slots; with `std`, the host's state file and key files.
//! - [`farm`], [`fop`]: COP-1 as pure state machines, `on_event(now, input) -> effects`.
//! - [`mux`]: space packets into fixed TM frames and back.
//! - [`downlink`]: TM frames on board (VC0 realtime, VC1 replay, VC7 idle) and their
//!   reception on the ground.
//! - [`rx`]: the on-board TC receive pipeline CRC → lengths → SDLS → FARM → packet, with the
//!   rejection counters the host puts in HK.
//! - [`endpoint`]: the robot's whole space-link endpoint without I/O (receive pipeline, TM
//!   framer, counter store, SPACE_LINK values and link events), time passed in: the one
//!   the host obsw and board A drive from their own transports.
//!
//! Every number (SCID, VCIDs, lengths, windows, SPIs) comes from `mib::link`.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]

pub mod clcw;
pub mod downlink;
pub mod endpoint;
pub mod farm;
pub mod fecf;
pub mod fop;
pub mod gcm;
pub mod hk;
pub mod mux;
pub mod persist;
pub mod rx;
pub mod sdls;
pub mod stream;
pub mod tc;
pub mod test_keys;
pub mod tm;

pub use clcw::Clcw;
