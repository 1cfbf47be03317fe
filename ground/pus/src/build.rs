//! Building packets: TCs from the MIB (arguments range-checked), raw TCs and TMs, their
//! request IDs and the per-APID sequence counters.

use std::collections::HashMap;

use arbitrary_int::{u11, u14};
use mib::config::{GROUND_ID, MAX_PACKET_LEN, TIMESTAMP_LEN};
use mib::headers::SeqCount;
use mib::tc::TcDef;
use mib_wire::{codec, RequestId};
use satrs::spacepackets::ecss::tc::{AckFlags, ACK_ALL};
use satrs::spacepackets::ecss::tm::{PusTmCreator, PusTmSecondaryHeader};
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId, WritablePusPacket};
use satrs::spacepackets::SpHeader;

use super::{BuildError, MIN_TC_LEN};

/// Per-APID 14-bit sequence counters for outgoing TCs.
#[derive(Clone, Debug, Default)]
pub struct SeqCounters {
    next: HashMap<u16, u16>,
}

impl SeqCounters {
    pub fn new() -> Self {
        Self::default()
    }
    /// Returns the next sequence count of `apid` (wrapping at 2^14).
    pub fn next(&mut self, apid: u16) -> u16 {
        let c = self.next.entry(apid).or_insert(0);
        let v = *c;
        *c = SeqCount::new(v).next().get();
        v
    }
    /// Starts the counter of `apid` at `start` (e.g. a random offset so that a new
    /// ground session is not taken for duplicates of an earlier one).
    pub fn set(&mut self, apid: u16, start: u16) {
        self.next.insert(apid, SeqCount::new(start).get());
    }
}

/// Acknowledgement flags for a TC: robot actions request every verification stage,
/// other TCs acceptance and completion.
pub fn ack_flags_for(def: &TcDef) -> AckFlags {
    if def.long_running {
        ACK_ALL
    } else {
        AckFlags::builder()
            .with_acceptance(true)
            .with_start(false)
            .with_progress(false)
            .with_completion(true)
            .build()
    }
}

/// A built telecommand.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BuiltTc {
    pub def: &'static TcDef,
    pub args: Vec<i64>,
    pub apid: u16,
    pub seq: u16,
    pub bytes: Vec<u8>,
}

impl BuiltTc {
    pub fn request_id(&self) -> RequestId {
        // A built TC always has its primary header.
        RequestId::of_tc(&self.bytes).unwrap_or(RequestId::from_words(0, 0))
    }
}

/// Builds the TC `def` with `args` (range-checked against the MIB) for robot `robot`.
pub fn build_tc(robot: u8, seq: u16, def: &'static TcDef, args: &[i64]) -> Result<BuiltTc, BuildError> {
    let apid = mib::apid::robot_apid(robot).ok_or(BuildError::UnknownRobot(robot))?;
    let mut app = [0u8; mib::config::MAX_TC_APP_DATA];
    let n = codec::encode_args(def, args, &mut app).map_err(|err| BuildError::Args { tc: def.name, err })?;
    let bytes = build_raw_tc(apid, seq, def.service, def.subservice, ack_flags_for(def), &app[..n])?;
    Ok(BuiltTc {
        def,
        args: args.to_vec(),
        apid,
        seq: SeqCount::new(seq).get(),
        bytes,
    })
}

/// Builds a raw PUS-C TC (no MIB check of the application data), through the wire
/// crate's TC emitter (the one the OBSW's tests and the firmware share).
pub fn build_raw_tc(
    apid: u16,
    seq: u16,
    service: u8,
    subservice: u8,
    ack: AckFlags,
    app_data: &[u8],
) -> Result<Vec<u8>, BuildError> {
    if app_data.len() > MAX_PACKET_LEN - MIN_TC_LEN {
        return Err(BuildError::TooLong(app_data.len()));
    }
    let h = mib_wire::header::TcHeader {
        apid: apid & 0x7FF,
        seq_count: SeqCount::new(seq).get(),
        ack: ack.raw_value().value(),
        service,
        subservice,
        source_id: GROUND_ID,
    };
    let mut v = vec![0u8; MIN_TC_LEN + app_data.len()];
    let n = mib_wire::header::emit_tc(&h, &mut v, |b| {
        b[..app_data.len()].copy_from_slice(app_data);
        Ok(app_data.len())
    })
    .map_err(|_| BuildError::TooLong(app_data.len()))?;
    v.truncate(n);
    Ok(v)
}

/// Builds a raw PUS-C TM packet (used by tests, the fake OBSW and the benchmark
/// generator). `time` is the 7-byte CDS short time stamp.
pub fn build_tm(
    apid: u16,
    seq: u16,
    service: u8,
    subservice: u8,
    msg_counter: u16,
    time: &[u8; TIMESTAMP_LEN],
    source: &[u8],
) -> Vec<u8> {
    let sp = SpHeader::new_for_unseg_tm(u11::new(apid & 0x7FF), u14::new(SeqCount::new(seq).get()), 0);
    let sec = PusTmSecondaryHeader::new(MessageTypeId::new(service, subservice), msg_counter, GROUND_ID, time);
    let tm = PusTmCreator::new(sp, sec, source, CreatorConfig::default());
    let mut v = Vec::with_capacity(tm.len_written());
    // Cannot fail: the vector grows as needed.
    let _ = tm.append_to_vec(&mut v);
    v
}
