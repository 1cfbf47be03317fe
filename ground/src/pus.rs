//! PUS on the wire: building TCs and decoding TC/TM packets into owned structs.
//!
//! Every number comes from the MIB (`mib`): APIDs, services, function IDs, argument
//! types and ranges, HK structures, events, failure codes and TM layouts. Packets are
//! built and read with `satrs::spacepackets` (PUS-C, CRC-16/CCITT-FALSE). Untrusted
//! bytes are checked here before they reach the `spacepackets` readers, so a corrupt
//! packet is an error value and never a panic.

pub mod out;

use std::collections::HashMap;
use std::fmt;

use arbitrary_int::{u11, u14};
use mib::codec::{self, ArgError};
use mib::config::{GROUND_ID, MAX_PACKET_LEN, TIMESTAMP_LEN};
use mib::events::Severity;
use mib::tc::{service, TcDef};
use mib::FailureCode;
use mib_wire::header::{HeaderError, TcPacket, TmPacket};
use satrs::spacepackets::ecss::tc::{AckFlags, ACK_ALL};
use satrs::spacepackets::ecss::tm::{PusTmCreator, PusTmSecondaryHeader};
use satrs::spacepackets::ecss::{CreatorConfig, MessageTypeId, WritablePusPacket};
use satrs::spacepackets::SpHeader;
use serde::Serialize;

pub use mib_wire::header::{
    CDS_PFIELD, CRC_LEN, MIN_TC_LEN, MIN_TM_LEN, PRIMARY_HEADER_LEN, TC_SEC_HEADER_LEN, TM_SEC_HEADER_LEN,
};

/// Why a packet could not be decoded.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum DecodeError {
    /// Fewer bytes than the header or the length field promise.
    Truncated { need: usize, have: usize },
    /// Length field beyond the largest packet of this mission.
    TooLong { len: usize },
    /// CCSDS version not 0, no secondary header, or not PUS-C.
    NotPus { reason: &'static str },
    /// Packet error control does not match.
    Crc { received: u16, computed: u16 },
    /// Source or application data does not match its MIB definition.
    Data { what: String },
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Truncated { need, have } => {
                write!(f, "truncated packet: need {need} bytes, have {have}")
            }
            DecodeError::TooLong { len } => {
                write!(f, "packet length {len} exceeds {MAX_PACKET_LEN}")
            }
            DecodeError::NotPus { reason } => write!(f, "not a PUS-C packet: {reason}"),
            DecodeError::Crc { received, computed } => {
                write!(f, "CRC mismatch: received 0x{received:04X}, computed 0x{computed:04X}")
            }
            DecodeError::Data { what } => write!(f, "bad data field: {what}"),
        }
    }
}

impl std::error::Error for DecodeError {}

/// Why a TC could not be built.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum BuildError {
    /// Robot number outside the MIB's range.
    UnknownRobot(u8),
    /// Arguments refused by the MIB (count or range).
    Args { tc: &'static str, err: ArgError },
    /// Application data too long for a TC.
    TooLong(usize),
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::UnknownRobot(n) => write!(
                f,
                "robot {n} is not in the MIB (robots {}..={})",
                mib::apid::ROBOT_MIN,
                mib::apid::ROBOT_MAX
            ),
            BuildError::Args { tc, err } => match err {
                ArgError::Length { got, expected } => {
                    write!(f, "{tc}: {got} arguments given, {expected} expected")
                }
                ArgError::OutOfRange { index, value } => {
                    let def = mib::tc::by_name(tc);
                    match def.and_then(|d| d.args.get(*index as usize)) {
                        Some(a) => write!(f, "{tc}: argument {} = {value} outside {}..={}", a.name, a.min, a.max),
                        None => write!(f, "{tc}: argument {index} = {value} out of range"),
                    }
                }
            },
            BuildError::TooLong(n) => write!(f, "application data of {n} bytes is too long"),
        }
    }
}

impl std::error::Error for BuildError {}

/// The request ID of PUS 1: packet ID and packet sequence control of the TC.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct RequestId {
    pub packet_id: u16,
    pub psc: u16,
}

impl RequestId {
    pub fn apid(self) -> u16 {
        self.packet_id & 0x7FF
    }
    pub fn seq(self) -> u16 {
        self.psc & 0x3FFF
    }
    fn from_wire(r: &mib_wire::RequestId) -> RequestId {
        RequestId {
            packet_id: r.packet_id(),
            psc: r.psc(),
        }
    }
}

impl fmt::Display for RequestId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "apid 0x{:03X} seq {}", self.apid(), self.seq())
    }
}

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
        *c = (v + 1) & 0x3FFF;
        v
    }
    /// Starts the counter of `apid` at `start` (e.g. a random offset so that a new
    /// ground session is not taken for duplicates of an earlier one).
    pub fn set(&mut self, apid: u16, start: u16) {
        self.next.insert(apid, start & 0x3FFF);
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
        mib_wire::RequestId::of_tc(&self.bytes).map_or(RequestId { packet_id: 0, psc: 0 }, |r| RequestId::from_wire(&r))
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
        seq: seq & 0x3FFF,
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
        seq_count: seq & 0x3FFF,
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
    let sp = SpHeader::new_for_unseg_tm(u11::new(apid & 0x7FF), u14::new(seq & 0x3FFF), 0);
    let sec = PusTmSecondaryHeader::new(MessageTypeId::new(service, subservice), msg_counter, GROUND_ID, time);
    let tm = PusTmCreator::new(sp, sec, source, CreatorConfig::default());
    let mut v = Vec::with_capacity(tm.len_written());
    // Cannot fail: the vector grows as needed.
    let _ = tm.append_to_vec(&mut v);
    v
}

/// A CDS short time stamp (p-field, days since 1958-01-01, ms of day).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct CdsShort {
    pub days: u16,
    pub ms_of_day: u32,
}

impl CdsShort {
    pub fn parse(b: &[u8]) -> Option<CdsShort> {
        let t = mib_wire::CdsTime::parse(b.get(..TIMESTAMP_LEN)?).ok()?;
        Some(CdsShort::from_wire(&t))
    }
    pub fn from_wire(t: &mib_wire::CdsTime) -> CdsShort {
        CdsShort {
            days: t.days,
            ms_of_day: t.ms_of_day,
        }
    }
    fn wire(self) -> mib_wire::CdsTime {
        mib_wire::CdsTime {
            pfield: CDS_PFIELD,
            days: self.days,
            ms_of_day: self.ms_of_day,
        }
    }
    pub fn to_bytes(self) -> [u8; TIMESTAMP_LEN] {
        self.wire().to_bytes()
    }
    /// Milliseconds since the Unix epoch.
    pub fn unix_ms(self) -> i64 {
        self.wire().unix_ms()
    }
    pub fn from_unix_ms(ms: i64) -> CdsShort {
        CdsShort::from_wire(&mib_wire::CdsTime::from_unix_ms(ms))
    }
    pub fn now() -> CdsShort {
        CdsShort::from_unix_ms(chrono::Utc::now().timestamp_millis())
    }
}

impl fmt::Display for CdsShort {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match chrono::DateTime::from_timestamp_millis(self.unix_ms()) {
            Some(t) => write!(f, "{}", t.format("%Y-%m-%dT%H:%M:%S%.3fZ")),
            None => write!(f, "days {} ms {}", self.days, self.ms_of_day),
        }
    }
}

/// PUS 1 stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    Acceptance,
    Start,
    Progress,
    Completion,
}

impl Stage {
    pub fn name(self) -> &'static str {
        match self {
            Stage::Acceptance => "acceptance",
            Stage::Start => "start",
            Stage::Progress => "progress",
            Stage::Completion => "completion",
        }
    }
}

/// One named field of failure data, decoded with the layout the MIB gives for the code.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Field {
    pub name: String,
    pub value: i64,
}

/// A PUS 1 failure notice.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Failure {
    pub code: u16,
    pub name: &'static str,
    pub description: &'static str,
    /// Failure data decoded per the MIB layout (empty if it does not fit).
    pub fields: Vec<Field>,
    /// Raw failure data.
    #[serde(serialize_with = "ser_hex")]
    pub data: Vec<u8>,
}

impl Failure {
    pub fn from_code(code: u16, data: &[u8]) -> Failure {
        let fc = FailureCode::from_code(code);
        Failure {
            code,
            name: fc.name(),
            description: fc.description(),
            fields: decode_fields(fc.data(), data),
            data: data.to_vec(),
        }
    }
    pub fn field(&self, name: &str) -> Option<i64> {
        self.fields.iter().find(|f| f.name == name).map(|f| f.value)
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ({}): {}", self.name, self.code, self.description)?;
        if !self.fields.is_empty() {
            write!(f, " [")?;
            let defs = FailureCode::from_code(self.code).data();
            for (i, fl) in self.fields.iter().enumerate() {
                if i > 0 {
                    write!(f, ", ")?;
                }
                write!(f, "{}={}", fl.name, named(defs, &self.fields, i))?;
            }
            write!(f, "]")?;
        }
        Ok(())
    }
}

/// The value of field `i` as a person reads it: the MIB's name for it (a mode named for
/// the `node` field beside it) with the raw value, or the raw value alone.
fn named(defs: &[mib::layout::Field], values: &[Field], i: usize) -> String {
    let v = values[i].value;
    let Some(def) = defs.get(i) else {
        return v.to_string();
    };
    let name = if def.names == mib::layout::Names::Mode {
        values
            .iter()
            .find(|x| x.name == "node")
            .and_then(|n| mib::layout::Names::mode_name_for(n.value, v))
            .or_else(|| def.names.name(v))
    } else {
        def.names.name(v)
    };
    match name {
        Some(n) => format!("{n} ({v})"),
        None => v.to_string(),
    }
}

fn ser_hex<S: serde::Serializer>(v: &[u8], s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&hex(v))
}

/// Lower-case hex of a byte slice.
pub fn hex(v: &[u8]) -> String {
    use std::fmt::Write;
    let mut s = String::with_capacity(v.len() * 2);
    for b in v {
        let _ = write!(s, "{b:02x}");
    }
    s
}

/// Decodes `data` with a MIB field list; returns the fields that fit.
pub fn decode_fields(fields: &[mib::layout::Field], data: &[u8]) -> Vec<Field> {
    let mut r = mib_wire::Reader::new(data);
    let mut out = Vec::with_capacity(fields.len());
    for f in fields {
        let Ok(u) = r.uint(f.bits, f.name) else { break };
        out.push(Field {
            name: f.name.to_string(),
            value: raw_value(f.ptype, u),
        });
    }
    out
}

/// Raw value of an unsigned wire word read for a field of type `t`.
pub fn raw_value(t: mib::PType, u: u32) -> i64 {
    match t {
        mib::PType::I16 => u as u16 as i16 as i64,
        mib::PType::I32 => u as i32 as i64,
        _ => u as i64,
    }
}

/// A PUS 1 verification report.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Verification {
    pub stage: Stage,
    pub success: bool,
    pub request: RequestId,
    /// Step number of TM[1,5] / TM[1,6].
    pub step: Option<u8>,
    pub failure: Option<Failure>,
}

/// One decoded HK parameter.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HkValue {
    pub id: u16,
    pub name: &'static str,
    pub raw: i64,
    pub eng: f64,
    pub unit: &'static str,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Hk {
    pub sid: u16,
    pub name: &'static str,
    pub values: Vec<HkValue>,
}

impl Hk {
    pub fn raw(&self, id: u16) -> Option<i64> {
        self.values.iter().find(|v| v.id == id).map(|v| v.raw)
    }
    pub fn eng(&self, id: u16) -> Option<f64> {
        self.values.iter().find(|v| v.id == id).map(|v| v.eng)
    }
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Event {
    pub id: u16,
    pub name: &'static str,
    pub severity: &'static str,
    /// True for the faults of the FDIR table.
    pub fault: bool,
    pub description: &'static str,
    pub params: Vec<Field>,
}

impl Event {
    pub fn param(&self, name: &str) -> Option<i64> {
        self.params.iter().find(|f| f.name == name).map(|f| f.value)
    }
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} [{}] {}", self.name, self.severity, self.description)?;
        let defs = mib::events::by_id(self.id).map_or(&[][..], |e| e.params);
        for (i, p) in self.params.iter().enumerate() {
            write!(f, " {}={}", p.name, named(defs, &self.params, i))?;
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct MonDefinition {
    pub id: u16,
    pub param: u16,
    pub enabled: bool,
    pub low: i32,
    pub high: i32,
    pub persistence: u16,
    pub event: u16,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct EaDefinition {
    pub event: u16,
    pub enabled: bool,
    pub mode: u32,
    pub deferred: bool,
}

/// The source data of a TM packet, decoded per `mib::tc::TMS`.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TmBody {
    Verification(Verification),
    Hk(Hk),
    Event(Event),
    DisabledEvents {
        events: Vec<u16>,
    },
    TimeReport {
        rate_exp: u8,
        time: CdsShort,
    },
    MonDefinitions {
        monitors: Vec<MonDefinition>,
    },
    MonTransition {
        monitor: u16,
        param: u16,
        value: i32,
        limit: i32,
        state: u8,
    },
    StoreDownlinkDone {
        packets: u32,
        /// On-board time of the oldest packet still in the store.
        oldest_time: CdsShort,
        /// Sequence count of the oldest packet still in the store.
        oldest_seq: u16,
        /// Stored packets overwritten since boot.
        overwritten: u32,
    },
    PingReply,
    EaDefinitions {
        links: Vec<EaDefinition>,
    },
    ParamValue {
        param: u16,
        value: i32,
    },
    ModeReply {
        node: u32,
        mode: u32,
        submode: u16,
    },
    ModeCantReach {
        node: u32,
        mode: u32,
        submode: u16,
        reason: u16,
    },
    /// TM[210,2]: team coordination without the ground (issue 25).
    TeamStatus {
        term: u32,
        /// 0 follower, 1 candidate, 2 leader.
        role: u8,
        /// 0 = none known.
        leader: u8,
        ground_seen: bool,
        lease: bool,
        voted_for: u8,
        auth_plan: u16,
        auth_first_step: u16,
        auth_steps: u8,
        auth_left_s: u32,
        refused: u32,
        foreign: u32,
        roster: Vec<u8>,
    },
    /// A TM type the MIB does not define.
    Unknown {
        #[serde(serialize_with = "ser_hex")]
        data: Vec<u8>,
    },
}

/// A decoded TM packet.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Tm {
    pub apid: u16,
    /// Robot number of the APID (`None` for APIDs that are not a robot's).
    pub robot: Option<u8>,
    pub seq: u16,
    pub service: u8,
    pub subservice: u8,
    pub name: &'static str,
    pub msg_counter: u16,
    pub time: CdsShort,
    pub len: usize,
    pub body: TmBody,
}

/// A decoded TC packet.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Tc {
    pub apid: u16,
    pub robot: Option<u8>,
    pub seq: u16,
    pub service: u8,
    pub subservice: u8,
    pub ack: u8,
    pub source_id: u16,
    /// MIB name, `None` if the service/subservice/function is not in the MIB.
    pub name: Option<&'static str>,
    pub function: Option<u16>,
    pub args: Vec<Field>,
    /// Why the application data does not match the MIB, if it does not.
    pub arg_error: Option<String>,
    pub len: usize,
}

/// A decoded packet of either kind.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Packet {
    Tc(Tc),
    Tm(Tm),
}

fn header_err(e: HeaderError) -> DecodeError {
    match e {
        HeaderError::Truncated { need, have } => DecodeError::Truncated { need, have },
        HeaderError::TooLong { len } => DecodeError::TooLong { len },
        HeaderError::NotPus { reason } => DecodeError::NotPus { reason },
        HeaderError::WrongType { is_tc: true } => DecodeError::NotPus {
            reason: "packet is a TC, TM expected",
        },
        HeaderError::WrongType { is_tc: false } => DecodeError::NotPus {
            reason: "packet is a TM, TC expected",
        },
        HeaderError::Crc { received, computed } => DecodeError::Crc { received, computed },
        // HeaderError is non_exhaustive (another crate): a new kind is still an error.
        other => DecodeError::Data {
            what: other.to_string(),
        },
    }
}

/// Length of the packet at the start of `b`, if its header is plausible.
pub fn packet_len(b: &[u8]) -> Result<usize, DecodeError> {
    mib_wire::header::check_primary(b).map(|p| p.len).map_err(header_err)
}

/// Decodes the packet at the start of `b` (trailing bytes are ignored).
pub fn decode_packet(b: &[u8]) -> Result<Packet, DecodeError> {
    let p = mib_wire::header::check_primary(b).map_err(header_err)?;
    if p.is_tc {
        decode_tc(&b[..p.len]).map(Packet::Tc)
    } else {
        decode_tm(&b[..p.len]).map(Packet::Tm)
    }
}

/// `(APID, sequence count, on-board ms)` of a TM packet whose headers and CRC are intact,
/// whether or not its body decodes.
pub fn intact_position(raw: &[u8]) -> Option<(u16, u16, i64)> {
    let p = mib_wire::header::TmPacket::parse(raw).ok()?;
    Some((
        p.primary.apid,
        p.primary.seq_count,
        CdsShort::from_wire(&p.time).unix_ms(),
    ))
}

/// Decodes one TM packet (headers, CRC and body checked against the MIB).
pub fn decode_tm(b: &[u8]) -> Result<Tm, DecodeError> {
    let p = TmPacket::parse(b).map_err(header_err)?;
    let body = decode_tm_source(p.service, p.subservice, p.source)?;
    let apid = p.primary.apid;
    Ok(Tm {
        apid,
        robot: mib::apid::apid_robot(apid),
        seq: p.primary.seq_count,
        service: p.service,
        subservice: p.subservice,
        name: mib::tc::tm_by_type(p.service, p.subservice).map_or("UNKNOWN", |d| d.name),
        msg_counter: p.msg_counter,
        time: CdsShort::from_wire(&p.time),
        len: p.primary.len,
        body,
    })
}

fn data_err(what: impl Into<String>) -> DecodeError {
    DecodeError::Data { what: what.into() }
}

/// Decodes TM source data through the wire crate's `Repr`s (generated from the MIB).
fn decode_tm_source(service: u8, subservice: u8, d: &[u8]) -> Result<TmBody, DecodeError> {
    use mib_wire::Tm as W;
    if mib::tc::tm_by_type(service, subservice).is_none() {
        return Ok(TmBody::Unknown { data: d.to_vec() });
    }
    let w = W::parse(service, subservice, d).map_err(|e| data_err(format!("TM[{service},{subservice}]: {e}")))?;
    let verif = |stage, success, rid: &mib_wire::RequestId, step: Option<u8>, f: Option<&mib_wire::Failure>| {
        Verification {
            stage,
            success,
            request: RequestId::from_wire(rid),
            step,
            // The failure data is the tail of the source data.
            failure: f.map(|f| Failure::from_code(f.code(), &d[d.len() - f.buffer_len()..])),
        }
    };
    Ok(match w {
        W::AcceptanceSuccess(x) => TmBody::Verification(verif(Stage::Acceptance, true, &x.request_id, None, None)),
        W::AcceptanceFailure(x) => {
            TmBody::Verification(verif(Stage::Acceptance, false, &x.request_id, None, Some(&x.failure)))
        }
        W::StartSuccess(x) => TmBody::Verification(verif(Stage::Start, true, &x.request_id, None, None)),
        W::StartFailure(x) => TmBody::Verification(verif(Stage::Start, false, &x.request_id, None, Some(&x.failure))),
        W::ProgressSuccess(x) => TmBody::Verification(verif(Stage::Progress, true, &x.request_id, Some(x.step), None)),
        W::ProgressFailure(x) => TmBody::Verification(verif(
            Stage::Progress,
            false,
            &x.request_id,
            Some(x.step),
            Some(&x.failure),
        )),
        W::CompletionSuccess(x) => TmBody::Verification(verif(Stage::Completion, true, &x.request_id, None, None)),
        W::CompletionFailure(x) => {
            TmBody::Verification(verif(Stage::Completion, false, &x.request_id, None, Some(&x.failure)))
        }
        W::HkReport(x) => TmBody::Hk(hk_of(&x.hk)?),
        W::EventInfo(x) => TmBody::Event(event_of(subservice, &x.event, d)?),
        W::EventLow(x) => TmBody::Event(event_of(subservice, &x.event, d)?),
        W::EventMedium(x) => TmBody::Event(event_of(subservice, &x.event, d)?),
        W::EventHigh(x) => TmBody::Event(event_of(subservice, &x.event, d)?),
        W::DisabledEvents(x) => TmBody::DisabledEvents {
            events: x.events.iter().map(|e| e.event_id).collect(),
        },
        W::TimeReport(x) => TmBody::TimeReport {
            rate_exp: x.rate_exp,
            time: CdsShort::from_wire(&x.time),
        },
        W::MonDefinitions(x) => TmBody::MonDefinitions {
            monitors: x
                .monitors
                .iter()
                .map(|m| MonDefinition {
                    id: m.monitor_id,
                    param: m.param,
                    enabled: m.enabled != 0,
                    low: m.low,
                    high: m.high,
                    persistence: m.persistence,
                    event: m.event,
                })
                .collect(),
        },
        W::MonTransition(x) => TmBody::MonTransition {
            monitor: x.monitor_id,
            param: x.param,
            value: x.value,
            limit: x.limit,
            state: x.state,
        },
        W::StoreDownlinkDone(x) => TmBody::StoreDownlinkDone {
            packets: x.packets,
            oldest_time: CdsShort::from_wire(&x.oldest_time),
            oldest_seq: x.oldest_seq,
            overwritten: x.overwritten,
        },
        W::PingReply(_) => TmBody::PingReply,
        W::EaDefinitions(x) => TmBody::EaDefinitions {
            links: x
                .links
                .iter()
                .map(|l| EaDefinition {
                    event: l.event,
                    enabled: l.enabled != 0,
                    mode: l.mode,
                    deferred: l.deferred != 0,
                })
                .collect(),
        },
        W::ParamValue(x) => TmBody::ParamValue {
            param: x.param_id,
            value: x.value,
        },
        W::ModeReply(x) => TmBody::ModeReply {
            node: x.node,
            mode: x.mode,
            submode: x.submode,
        },
        W::ModeCantReach(x) => TmBody::ModeCantReach {
            node: x.node,
            mode: x.mode,
            submode: x.submode,
            reason: x.reason,
        },
        // TM[210,3] (issue 24): checked, then kept as bytes until the ground has a module
        // view (`mib::modules::report::ModuleReport::parse` rebuilds the set).
        W::ModuleReport(_) => TmBody::Unknown { data: d.to_vec() },
        W::TeamStatus(x) => TmBody::TeamStatus {
            term: x.term,
            role: x.role,
            leader: x.leader,
            ground_seen: x.ground_seen != 0,
            lease: x.lease != 0,
            voted_for: x.voted_for,
            auth_plan: x.auth_plan,
            auth_first_step: x.auth_first_step,
            auth_steps: x.auth_steps,
            auth_left_s: x.auth_left_s,
            refused: x.refused,
            foreign: x.foreign,
            roster: x.roster.iter().map(|r| r.robot).collect(),
        },
    })
}

fn event_of(subservice: u8, e: &mib_wire::Event, d: &[u8]) -> Result<Event, DecodeError> {
    let Some(def) = mib::events::by_id(e.id()) else {
        return Err(data_err(format!("event ID 0x{:04X} not in the MIB", e.id())));
    };
    if Some(def.severity) != Severity::from_subservice(subservice) {
        return Err(data_err(format!(
            "event {} has severity {} but came as TM[5,{subservice}]",
            def.name,
            def.severity.name()
        )));
    }
    Ok(Event {
        id: def.id,
        name: def.name,
        severity: def.severity.name(),
        fault: def.fault,
        description: def.desc,
        params: decode_fields(def.params, &d[2..]),
    })
}

/// The decoded values of a housekeeping report, in structure order.
fn hk_of(h: &mib_wire::Hk) -> Result<Hk, DecodeError> {
    let Some(def) = mib::hk::by_sid(h.sid()) else {
        return Err(data_err(format!(
            "housekeeping structure ID {} not in the MIB",
            h.sid()
        )));
    };
    let mut values = Vec::with_capacity(def.params.len());
    for id in def.params {
        let (Some(p), Some(raw)) = (mib::params::by_id(*id), h.get(*id)) else {
            return Err(data_err(format!("HK parameter {id} not in the MIB")));
        };
        values.push(HkValue {
            id: p.id,
            name: p.name,
            raw,
            eng: p.calib.eng(raw),
            unit: p.unit,
        });
    }
    Ok(Hk {
        sid: def.sid,
        name: def.name,
        values,
    })
}

/// Decodes TM[3,25] source data.
pub fn decode_hk(d: &[u8]) -> Result<Hk, DecodeError> {
    let r = mib_wire::tm::HkReport::parse(d).map_err(|e| data_err(format!("TM[3,25]: {e}")))?;
    hk_of(&r.hk)
}

/// Decodes one TC packet (CRC checked) and its arguments against the MIB.
pub fn decode_tc(b: &[u8]) -> Result<Tc, DecodeError> {
    let p = TcPacket::parse(b).map_err(header_err)?;
    let (service, subservice, app) = (p.service, p.subservice, p.app_data);
    let apid = p.primary.apid;
    let (function, data) = if service == service::FUNCTION && app.len() >= 2 {
        (Some(u16::from_be_bytes([app[0], app[1]])), &app[2..])
    } else {
        (None, app)
    };
    let def = mib::tc::lookup(service, subservice, function);
    let mut args = Vec::new();
    let mut arg_error = None;
    match def {
        Some(def) => match codec::decode_args(def, data) {
            Ok((vals, _rest)) => {
                args = def
                    .args
                    .iter()
                    .zip(vals.iter())
                    .map(|(a, v)| Field {
                        name: a.name.to_string(),
                        value: *v,
                    })
                    .collect();
                // The structure (variable part included) must follow the MIB too.
                if let Err(e) = mib_wire::Tc::parse(service, subservice, app) {
                    arg_error = Some(format!("{}: {e}", def.name));
                }
            }
            Err(e) => arg_error = Some(BuildError::Args { tc: def.name, err: e }.to_string()),
        },
        None => {
            arg_error = Some(match function {
                Some(f) => format!("function {f} not in the MIB"),
                None => format!("TC[{service},{subservice}] not in the MIB"),
            })
        }
    }
    Ok(Tc {
        apid,
        robot: mib::apid::apid_robot(apid),
        seq: p.primary.seq_count,
        service,
        subservice,
        ack: p.ack,
        source_id: p.source_id,
        name: def.map(|d| d.name),
        function,
        args,
        arg_error,
        len: p.primary.len,
    })
}

/// One item of a packet stream.
#[derive(Clone, Debug, PartialEq)]
pub enum StreamItem {
    Packet {
        offset: usize,
        packet: Packet,
    },
    /// A stretch of bytes that did not decode; `reason` is why the first attempt failed.
    Corrupt {
        offset: usize,
        len: usize,
        reason: DecodeError,
    },
}

/// Splits a byte stream of concatenated space packets. After a packet that does not
/// decode, it scans byte by byte for the next offset where a packet with a valid header
/// and CRC starts, and reports the skipped bytes as one corrupt stretch.
pub struct StreamDecoder<'a> {
    buf: &'a [u8],
    pos: usize,
    pending: Option<StreamItem>,
}

impl<'a> StreamDecoder<'a> {
    pub fn new(buf: &'a [u8]) -> Self {
        StreamDecoder {
            buf,
            pos: 0,
            pending: None,
        }
    }
}

impl Iterator for StreamDecoder<'_> {
    type Item = StreamItem;
    fn next(&mut self) -> Option<StreamItem> {
        if let Some(p) = self.pending.take() {
            return Some(p);
        }
        if self.pos >= self.buf.len() {
            return None;
        }
        let start = self.pos;
        let first_err = match decode_packet(&self.buf[start..]) {
            Ok(p) => {
                let len = match &p {
                    Packet::Tc(t) => t.len,
                    Packet::Tm(t) => t.len,
                };
                self.pos += len;
                return Some(StreamItem::Packet {
                    offset: start,
                    packet: p,
                });
            }
            Err(e) => e,
        };
        // Resynchronise: find the next offset where a packet decodes.
        let mut off = start + 1;
        while off < self.buf.len() {
            if let Ok(p) = decode_packet(&self.buf[off..]) {
                let len = match &p {
                    Packet::Tc(t) => t.len,
                    Packet::Tm(t) => t.len,
                };
                self.pending = Some(StreamItem::Packet { offset: off, packet: p });
                self.pos = off + len;
                return Some(StreamItem::Corrupt {
                    offset: start,
                    len: off - start,
                    reason: first_err,
                });
            }
            off += 1;
        }
        self.pos = self.buf.len();
        Some(StreamItem::Corrupt {
            offset: start,
            len: self.buf.len() - start,
            reason: first_err,
        })
    }
}

/// Counters of a stream decode.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct StreamStats {
    pub tc: u64,
    pub tm: u64,
    /// Packets whose service/subservice (or function) the MIB does not define.
    pub unknown: u64,
    pub corrupt_stretches: u64,
    pub corrupt_bytes: u64,
}

impl StreamStats {
    pub fn add(&mut self, item: &StreamItem) {
        match item {
            StreamItem::Packet { packet, .. } => match packet {
                Packet::Tc(t) => {
                    self.tc += 1;
                    if t.name.is_none() {
                        self.unknown += 1;
                    }
                }
                Packet::Tm(t) => {
                    self.tm += 1;
                    if matches!(t.body, TmBody::Unknown { .. }) {
                        self.unknown += 1;
                    }
                }
            },
            StreamItem::Corrupt { len, .. } => {
                self.corrupt_stretches += 1;
                self.corrupt_bytes += *len as u64;
            }
        }
    }
}

/// One line of human-readable text for a packet.
pub fn describe(p: &Packet) -> String {
    match p {
        Packet::Tc(t) => {
            let mut s = format!(
                "TC  apid=0x{:03X} seq={:5} [{},{}] {}",
                t.apid,
                t.seq,
                t.service,
                t.subservice,
                t.name.unwrap_or("UNKNOWN")
            );
            for a in &t.args {
                s.push_str(&format!(" {}={}", a.name, a.value));
            }
            if let Some(e) = &t.arg_error {
                s.push_str(&format!(" (bad arguments: {e})"));
            }
            s
        }
        Packet::Tm(t) => format!(
            "TM  apid=0x{:03X} seq={:5} [{},{}] {} {} {}",
            t.apid,
            t.seq,
            t.service,
            t.subservice,
            t.time,
            t.name,
            describe_body(&t.body)
        ),
    }
}

/// Human-readable text for a TM body.
pub fn describe_body(b: &TmBody) -> String {
    match b {
        TmBody::Verification(v) => {
            let mut s = format!(
                "{} {} for {}",
                v.stage.name(),
                if v.success { "ok" } else { "FAILED" },
                v.request
            );
            if let Some(st) = v.step {
                s.push_str(&format!(" step {st}"));
            }
            if let Some(f) = &v.failure {
                s.push_str(&format!(": {f}"));
            }
            s
        }
        TmBody::Hk(h) => {
            let mut s = format!("{} (sid {})", h.name, h.sid);
            for v in &h.values {
                if v.unit.is_empty() {
                    s.push_str(&format!(" {}={}", v.name, v.raw));
                } else {
                    s.push_str(&format!(" {}={:.3}{}", v.name, v.eng, v.unit));
                }
            }
            s
        }
        TmBody::Event(e) => e.to_string(),
        TmBody::DisabledEvents { events } => format!("disabled events {events:04X?}"),
        TmBody::TimeReport { rate_exp, time } => format!("on-board time {time} rate 2^{rate_exp} s"),
        TmBody::MonDefinitions { monitors } => format!("{} monitors {monitors:?}", monitors.len()),
        TmBody::MonTransition {
            monitor,
            param,
            value,
            limit,
            state,
        } => format!(
            "monitor {monitor} param {} value {value} limit {limit} state {}",
            mib::params::by_id(*param).map_or("?", |p| p.name),
            match state {
                0 => "ok",
                1 => "below low",
                2 => "above high",
                _ => "?",
            }
        ),
        TmBody::StoreDownlinkDone {
            packets,
            oldest_time,
            oldest_seq,
            overwritten,
        } => format!(
            "store downlink done, {packets} packets; oldest stored: {oldest_time} seq {oldest_seq}; {overwritten} overwritten since boot"
        ),
        TmBody::PingReply => "ping reply".to_string(),
        TmBody::EaDefinitions { links } => format!("{} links {links:?}", links.len()),
        TmBody::ParamValue { param, value } => format!(
            "parameter {} = {value}",
            mib::tunables::by_id(*param).map_or("?", |t| t.name)
        ),
        TmBody::ModeReply { node, mode, submode } => format!(
            "node {} mode {} submode {submode}",
            node_name(*node),
            mode_name(*node, *mode)
        ),
        TmBody::ModeCantReach {
            node,
            mode,
            submode,
            reason,
        } => format!(
            "node {} cannot reach mode {} submode {submode}: reason {reason} ({})",
            node_name(*node),
            mode_name(*node, *mode),
            FailureCode::from_code(*reason).name()
        ),
        TmBody::TeamStatus {
            term,
            role,
            leader,
            ground_seen,
            roster,
            auth_steps,
            ..
        } => format!(
            "team term {term} role {} leader {leader} ground {} roster {roster:?} authorised steps {auth_steps}",
            mib::team::TEAM_ROLE_NAMES.name(i64::from(*role)).unwrap_or("?"),
            if *ground_seen { "seen" } else { "lost" }
        ),
        TmBody::Unknown { data } => format!("undefined TM type, data {}", hex(data)),
    }
}

/// Name of a mode-tree node.
pub fn node_name(node: u32) -> String {
    mib::modes::node_by_id(node).map_or_else(|| format!("#{node}"), |n| n.name.to_string())
}

/// Name of a mode of a node.
pub fn mode_name(node: u32, mode: u32) -> String {
    mib::modes::node_by_id(node)
        .and_then(|n| mib::modes::mode_name(n.kind, mode))
        .map_or_else(|| format!("#{mode}"), |s| s.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::events::eid;
    use mib::params::pid;
    use mib::tc::function;

    const T0: [u8; 7] = [CDS_PFIELD, 0x5A, 0x00, 0x00, 0x00, 0x03, 0xE8];

    // verifies: MMIC-FW-01
    #[test]
    fn events_and_failures_read_with_the_mib_names() {
        let mut src = mib::events::eid::MODE_CHANGED.to_be_bytes().to_vec();
        for v in [10u32, 0, 1] {
            src.extend_from_slice(&v.to_be_bytes());
        }
        src.extend_from_slice(&0u16.to_be_bytes());
        let TmBody::Event(e) = decode_tm(&tm(5, 1, &src)).unwrap().body else {
            panic!("not an event")
        };
        let s = e.to_string();
        assert!(s.contains("node=BOLTER_B (10) from=OFF (0) to=ON (1)"), "{s}");
        let f = Failure::from_code(FailureCode::INITIAL_STATE_MISMATCH.code(), &[0, 4]);
        assert!(f.to_string().contains("believed="), "{f}");
        assert!(!f.to_string().contains("believed=0,"), "{f}");
    }

    // verifies: PUS-PKT-01
    #[test]
    fn raw_tc_bytes_equal_the_sat_rs_encoder() {
        use satrs::spacepackets::ecss::tc::{PusTcCreator, PusTcSecondaryHeader};
        let data: Vec<u8> = (0..=255u8).collect();
        for (apid, seq, svc, sub, n) in [
            (0x101u16, 0u16, 17u8, 1u8, 0usize),
            (0x7FF, 0x3FFF, 8, 1, 6),
            (0x10A, 1234, 200, 1, 10),
            (0x102, 99, 11, 4, 255),
        ] {
            for ack in [ACK_ALL, ack_flags_for(mib::tc::by_name("PING").unwrap())] {
                let ours = build_raw_tc(apid, seq, svc, sub, ack, &data[..n]).unwrap();
                let sp = SpHeader::new_for_unseg_tc(u11::new(apid), u14::new(seq), 0);
                let sec = PusTcSecondaryHeader::new(MessageTypeId::new(svc, sub), ack, GROUND_ID);
                let tc = PusTcCreator::new(sp, sec, &data[..n], CreatorConfig::default());
                let mut theirs = Vec::new();
                tc.append_to_vec(&mut theirs);
                assert_eq!(ours, theirs, "apid {apid:#x} seq {seq} TC[{svc},{sub}] {n} bytes");
            }
        }
        assert!(matches!(
            build_raw_tc(0x101, 0, 17, 1, ACK_ALL, &[0u8; MAX_PACKET_LEN]),
            Err(BuildError::TooLong(_))
        ));
    }

    // verifies: PUS-PKT-01
    #[test]
    fn ping_tc_bytes_match_ccsds_and_pus_c_layout() {
        let def = mib::tc::by_name("PING").unwrap();
        let tc = build_tc(1, 5, def, &[]).unwrap();
        // primary header: TC, sec header, APID 0x101; unsegmented, seq 5; length 5+2-1
        assert_eq!(&tc.bytes[..6], &[0x19, 0x01, 0xC0, 0x05, 0x00, 0x06]);
        // PUS-C, ack acceptance+completion; service 17/1; source ID 0
        assert_eq!(&tc.bytes[6..11], &[0x29, 17, 1, 0, 0]);
        let crc = satrs::spacepackets::crc::CRC_CCITT_FALSE.checksum(&tc.bytes[..11]);
        assert_eq!(&tc.bytes[11..], &crc.to_be_bytes());
        assert_eq!(
            tc.request_id(),
            RequestId {
                packet_id: 0x1901,
                psc: 0xC005
            }
        );
    }

    // verifies: PUS-1-03
    #[test]
    fn robot_action_requests_all_four_acknowledgements_and_round_trips() {
        let def = mib::tc::lookup(8, 1, Some(function::RECONFIGURE)).unwrap();
        let tc = build_tc(2, 77, def, &[0, 4]).unwrap();
        assert_eq!(tc.bytes[6] & 0x0F, 0x0F);
        assert_eq!(tc.apid, 0x102);
        let Packet::Tc(d) = decode_packet(&tc.bytes).unwrap() else {
            panic!("not a TC")
        };
        assert_eq!(d.name, Some("RECONFIGURE"));
        assert_eq!(d.robot, Some(2));
        assert_eq!(d.seq, 77);
        assert_eq!(d.function, Some(function::RECONFIGURE));
        assert_eq!(
            d.args.iter().map(|a| (a.name.as_str(), a.value)).collect::<Vec<_>>(),
            vec![("from", 0), ("to", 4)]
        );
        assert_eq!(d.arg_error, None);
    }

    // verifies: PUS-8-02
    #[test]
    fn out_of_range_argument_is_refused_before_sending() {
        let def = mib::tc::by_name("BOLT_FACE").unwrap();
        let e = build_tc(1, 0, def, &[0, 16]).unwrap_err();
        assert!(e.to_string().contains("pairs = 16 outside 1..=15"), "{e}");
        assert!(matches!(build_tc(0, 0, def, &[0, 1]), Err(BuildError::UnknownRobot(0))));
    }

    // verifies: PUS-PKT-03
    #[test]
    fn sequence_counts_are_per_apid_and_wrap_at_14_bits() {
        let mut s = SeqCounters::new();
        assert_eq!(s.next(0x101), 0);
        assert_eq!(s.next(0x101), 1);
        assert_eq!(s.next(0x102), 0);
        s.set(0x103, 0x3FFF);
        assert_eq!(s.next(0x103), 0x3FFF);
        assert_eq!(s.next(0x103), 0);
    }

    fn tm(service: u8, sub: u8, src: &[u8]) -> Vec<u8> {
        build_tm(0x101, 9, service, sub, 3, &T0, src)
    }

    // verifies: PUS-1-01
    #[test]
    fn acceptance_success_from_static_bytes() {
        // TM[1,1] for request 0x1901/0xC005, hand-assembled.
        let mut b = vec![
            0x09, 0x01, 0xC0, 0x09, 0x00, 0x00, // primary header (length patched below)
            0x20, 1, 1, 0x00, 0x03, 0x00, 0x00, // PUS-C TM sec header, msg counter 3, dest 0
        ];
        b.extend_from_slice(&T0);
        b.extend_from_slice(&[0x19, 0x01, 0xC0, 0x05]);
        let len = (b.len() + 2 - 7) as u16;
        b[4..6].copy_from_slice(&len.to_be_bytes());
        let crc = satrs::spacepackets::crc::CRC_CCITT_FALSE.checksum(&b);
        b.extend_from_slice(&crc.to_be_bytes());
        assert_eq!(b, tm(1, 1, &[0x19, 0x01, 0xC0, 0x05]));
        let t = decode_tm(&b).unwrap();
        assert_eq!(t.name, "ACCEPTANCE_SUCCESS");
        assert_eq!(t.robot, Some(1));
        assert_eq!(t.msg_counter, 3);
        assert_eq!(t.time.days, 0x5A00);
        assert_eq!(t.time.ms_of_day, 1000);
        let TmBody::Verification(v) = t.body else { panic!() };
        assert_eq!(v.stage, Stage::Acceptance);
        assert!(v.success);
        assert_eq!(v.request.apid(), 0x101);
        assert_eq!(v.request.seq(), 5);
    }

    // verifies: PUS-1-03
    #[test]
    fn progress_and_failure_reports_carry_step_code_and_named_data() {
        let t = decode_tm(&tm(1, 5, &[0x19, 0x01, 0xC0, 0x05, 2])).unwrap();
        let TmBody::Verification(v) = t.body else { panic!() };
        assert_eq!((v.stage, v.step, v.success), (Stage::Progress, Some(2), true));

        let code = FailureCode::BOLT_FAILED.code().to_be_bytes();
        let src = [0x19, 0x01, 0xC0, 0x05, 3, code[0], code[1], 1, 3, 3];
        let TmBody::Verification(v) = decode_tm(&tm(1, 6, &src)).unwrap().body else {
            panic!()
        };
        let f = v.failure.unwrap();
        assert_eq!(v.step, Some(3));
        assert_eq!(f.name, "BOLT_FAILED");
        assert_eq!(
            (f.field("side"), f.field("pair"), f.field("attempts")),
            (Some(1), Some(3), Some(3))
        );
        assert!(f.to_string().contains("did not lock"));

        let code = FailureCode::NOT_ALLOWED_IN_MODE.code().to_be_bytes();
        let src = [0x19, 0x01, 0xC0, 0x05, code[0], code[1], 0];
        let TmBody::Verification(v) = decode_tm(&tm(1, 2, &src)).unwrap().body else {
            panic!()
        };
        assert_eq!(v.stage, Stage::Acceptance);
        assert_eq!(v.failure.unwrap().field("mode"), Some(0));
        // success report with trailing bytes is refused
        assert!(decode_tm(&tm(1, 7, &[0x19, 0x01, 0xC0, 0x05, 9])).is_err());
    }

    // verifies: PUS-3-01
    #[test]
    fn hk_report_decodes_with_calibration() {
        let def = mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).unwrap();
        let mut src = [0u8; 256];
        let n = codec::encode_hk(def, |id| if id == pid::V_BAT_A { 3276 } else { 1 }, &mut src).unwrap();
        let t = decode_tm(&tm(3, 25, &src[..n])).unwrap();
        let TmBody::Hk(h) = t.body else { panic!() };
        assert_eq!(h.name, "ROBOT_STATUS");
        assert_eq!(h.values.len(), def.params.len());
        assert_eq!(h.raw(pid::V_BAT_A), Some(3276));
        assert!((h.eng(pid::V_BAT_A).unwrap() - 12.0).abs() < 0.01);
        // truncated HK is an error value
        assert!(decode_tm(&tm(3, 25, &src[..n - 1])).is_err());
    }

    // verifies: PUS-5-01
    #[test]
    fn event_report_must_match_its_severity() {
        let def = mib::events::by_id(eid::BOLT_FAILURE).unwrap();
        let mut src = [0u8; 16];
        let n = codec::encode_event(def, &[0, 2, 3], &mut src).unwrap();
        let TmBody::Event(e) = decode_tm(&tm(5, 4, &src[..n])).unwrap().body else {
            panic!()
        };
        assert!(e.fault);
        assert_eq!(e.param("pair"), Some(2));
        assert!(decode_tm(&tm(5, 1, &src[..n])).is_err());
    }

    // verifies: DD-DEC-01
    #[test]
    fn other_tm_types_decode_per_mib_layouts() {
        assert_eq!(decode_tm(&tm(17, 2, &[])).unwrap().body, TmBody::PingReply);
        let b = decode_tm(&tm(200, 6, &[0, 0, 0, 1, 0, 0, 0, 1, 0, 0])).unwrap().body;
        assert_eq!(
            b,
            TmBody::ModeReply {
                node: 1,
                mode: 1,
                submode: 0
            }
        );
        assert_eq!(describe_body(&b), "node ROBOT mode OPERATIONAL submode 0");
        let b = decode_tm(&tm(5, 8, &[0, 2, 1, 1, 2, 6])).unwrap().body;
        assert_eq!(
            b,
            TmBody::DisabledEvents {
                events: vec![0x0101, 0x0206]
            }
        );
        let mut src = vec![3u8];
        src.extend_from_slice(&T0);
        assert!(matches!(
            decode_tm(&tm(9, 2, &src)).unwrap().body,
            TmBody::TimeReport { rate_exp: 3, .. }
        ));
        assert_eq!(
            decode_tm(&tm(20, 2, &[0, 3, 0, 0, 0, 4])).unwrap().body,
            TmBody::ParamValue { param: 3, value: 4 }
        );
        assert_eq!(
            decode_tm(&tm(
                15,
                19,
                &[0, 0, 1, 0, CDS_PFIELD, 0x5A, 0, 0, 0, 0, 1, 0, 7, 0, 0, 0, 2]
            ))
            .unwrap()
            .body,
            TmBody::StoreDownlinkDone {
                packets: 256,
                oldest_time: CdsShort {
                    days: 0x5A00,
                    ms_of_day: 1
                },
                oldest_seq: 7,
                overwritten: 2
            }
        );
        let mon = [
            0, 1, 0, 1, 0, 20, 1, 0, 0, 0x0A, 0xAA, 0x7F, 0xFF, 0xFF, 0xFF, 0, 50, 1, 4,
        ];
        let TmBody::MonDefinitions { monitors } = decode_tm(&tm(12, 9, &mon)).unwrap().body else {
            panic!()
        };
        assert_eq!(monitors[0].param, pid::V_BAT_A);
        assert_eq!(monitors[0].event, eid::LOW_BATTERY);
        assert!(decode_tm(&tm(12, 9, &mon[..mon.len() - 1])).is_err());
        let ea = [0, 1, 1, 1, 1, 0, 0, 0, 0, 0];
        let TmBody::EaDefinitions { links } = decode_tm(&tm(19, 9, &ea)).unwrap().body else {
            panic!()
        };
        assert_eq!(links[0].event, eid::BOLT_FAILURE);
        let tr = [0, 1, 0, 20, 0, 0, 10, 0, 0, 0, 11, 0, 1];
        assert!(matches!(
            decode_tm(&tm(12, 12, &tr)).unwrap().body,
            TmBody::MonTransition { state: 1, .. }
        ));
        assert!(matches!(
            decode_tm(&tm(99, 1, &[1, 2])).unwrap().body,
            TmBody::Unknown { .. }
        ));
    }

    // verifies: PUS-PKT-01
    #[test]
    fn crc_error_and_bad_versions_are_values() {
        let mut b = tm(17, 2, &[]);
        let last = b.len() - 1;
        b[last] ^= 1;
        assert!(matches!(decode_tm(&b), Err(DecodeError::Crc { .. })));
        let mut b = tm(17, 2, &[]);
        b[6] = 0x10; // PUS-A
        assert!(matches!(decode_packet(&b), Err(DecodeError::NotPus { .. })));
        assert!(matches!(
            decode_packet(&[0x08, 1, 0xC0, 0, 0, 0]),
            Err(DecodeError::Truncated { .. })
        ));
        assert!(matches!(
            decode_packet(&[0x08, 1, 0xC0, 0, 0xFF, 0xFF]),
            Err(DecodeError::TooLong { .. })
        ));
    }

    // verifies: DD-LINK-01
    #[test]
    fn stream_decoder_resynchronises_after_garbage() {
        let mut s = tm(17, 2, &[]);
        s.extend_from_slice(&[0xFF, 0x00, 0x13]);
        let ping = build_tc(1, 1, mib::tc::by_name("PING").unwrap(), &[]).unwrap();
        s.extend_from_slice(&ping.bytes);
        s.extend_from_slice(&tm(17, 2, &[])[..10]);
        let items: Vec<_> = StreamDecoder::new(&s).collect();
        let mut st = StreamStats::default();
        items.iter().for_each(|i| st.add(i));
        assert_eq!((st.tm, st.tc, st.corrupt_stretches, st.corrupt_bytes), (1, 1, 2, 13));
        assert!(matches!(items[1], StreamItem::Corrupt { len: 3, .. }));
    }

    // verifies: PUS-PKT-04
    #[test]
    fn time_stamp_round_trips_through_unix_ms() {
        let t = CdsShort::from_unix_ms(1_700_000_000_123);
        assert_eq!(t.unix_ms(), 1_700_000_000_123);
        assert_eq!(CdsShort::parse(&t.to_bytes()), Some(t));
        assert_eq!(t.to_string(), "2023-11-14T22:13:20.123Z");
    }

    mod fuzz {
        use super::*;
        use proptest::prelude::*;
        proptest! {
            #![proptest_config(ProptestConfig::with_cases(2000))]
            // verifies: DD-ROBUST-01
            #[test]
            fn random_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..400)) {
                let mut st = StreamStats::default();
                let mut covered = 0usize;
                for item in StreamDecoder::new(&data) {
                    st.add(&item);
                    covered += match &item {
                        StreamItem::Packet { packet: Packet::Tc(t), .. } => t.len,
                        StreamItem::Packet { packet: Packet::Tm(t), .. } => t.len,
                        StreamItem::Corrupt { len, .. } => *len,
                    };
                }
                prop_assert_eq!(covered, data.len());
            }

            // verifies: GND-08
            #[test]
            fn valid_header_random_body_never_panics(
                tc in any::<bool>(), svc in any::<u8>(), sub in any::<u8>(),
                body in proptest::collection::vec(any::<u8>(), 0..64)) {
                let b = if tc {
                    build_raw_tc(0x101, 1, svc, sub, ACK_ALL, &body).unwrap()
                } else {
                    build_tm(0x101, 1, svc, sub, 0, &T0, &body)
                };
                // Valid CRC, arbitrary content: decodes or reports, never panics.
                let _ = decode_packet(&b);
                let mut flipped = b.clone();
                let i = body.len() % flipped.len();
                flipped[i] ^= 0x5A;
                let _ = decode_packet(&flipped);
            }
        }
    }
}
