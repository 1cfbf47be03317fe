//! The table-driven codec: bodies that are a flat list of MIB-typed values — housekeeping
//! reports (`HkDef::params`), event reports (`EventDef::params`) and a TC's fixed
//! arguments (`TcDef::args`, range-checked) — read and written by one loop over the MIB's
//! table at run time. Flight code uses this: one copy of the loop serves every SID, event
//! and TC, where the generated typed code ([`crate::Hk`], [`crate::Event`], `tc::*`) costs
//! code per kind (4.5 KB of board A's flash for the HK structures alone). The generated
//! types are the typed front end for the host, the ground and the tests, and the tests
//! check that both give the same bytes (`tests/codec.rs`).
//!
//! The implementation still lives in `mib::codec` while its remaining users outside the
//! flight code move to this path (mib/wire/README.md, "One codec").

pub use mib::codec::*;
