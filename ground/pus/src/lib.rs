//! PUS on the wire: building TCs and decoding TC/TM packets into owned structs.
//!
//! Every number comes from the MIB (`mib`): APIDs, services, function IDs, argument
//! types and ranges, HK structures, events, failure codes and TM layouts. Packets are
//! built and read with `satrs::spacepackets` (PUS-C, CRC-16/CCITT-FALSE). Untrusted
//! bytes are checked here before they reach the `spacepackets` readers, so a corrupt
//! packet is an error value and never a panic.
//!
//! - `build`: TCs (from the MIB, or raw), TMs, sequence counters; the request ID is
//!   [`RequestId`], `mib_wire`'s one type;
//! - `decode`: packets into [`Packet`] / [`Tm`] / [`Tc`] (`packet`, with `fields` for
//!   named failure data and event parameters, `time` for the CDS time stamp);
//! - [`seq`]: a packet's place in its APID's sequence and the one rule for the next
//!   step (next, gap, restart, behind);
//! - `stream`: splitting a byte stream of packets; `describe`: a line of text each;
//! - [`out`]: the fast JSON/text decode output that writes straight into a buffer;
//! - `error`: [`DecodeError`] and [`BuildError`].
//!
//! A crate of its own (`ground-pus`) so that the decoder and the archive build
//! and test without the collector's runtime: no tokio, axum or clap below this line. The
//! `ground` crate re-exports it as `ground::pus`.

#![deny(unsafe_code)]

mod build;
mod decode;
mod describe;
mod error;
mod fields;
pub mod out;
mod packet;
pub mod seq;
mod stream;
mod time;

#[cfg(test)]
mod tests;

pub use build::{ack_flags_for, build_raw_tc, build_tc, build_tm, BuiltTc, SeqCounters};
pub use decode::{decode_hk, decode_packet, decode_tc, decode_tm, intact_position, packet_len};
pub use describe::{describe, describe_body, mode_name, node_name};
pub use error::{BuildError, DecodeError};
pub use fields::{decode_fields, hex, raw_value, Failure, NamedValue};
pub use mib_wire::header::{
    CDS_PFIELD, CRC_LEN, MIN_TC_LEN, MIN_TM_LEN, PRIMARY_HEADER_LEN, TC_SEC_HEADER_LEN, TM_SEC_HEADER_LEN,
};
/// The PUS 1 request ID: the one type of the project, from the MIB's layout (CODEC-RID-01).
pub use mib_wire::RequestId;
pub use packet::{Event, Hk, HkValue, Packet, Stage, Tc, Tm, TmBody, Verification};
pub use stream::{StreamDecoder, StreamItem, StreamStats};
pub use time::CdsShort;
