//! Decoded packets as owned values: [`Packet`] (a [`Tc`] or a [`Tm`]) and the TM bodies
//! ([`TmBody`]: verification reports, housekeeping and events with their MIB names, every
//! other TM kind as the generated `mib_wire` value).

use std::fmt;

use serde::ser::{SerializeStruct, Serializer};
use serde::Serialize;

use super::fields::{named, ser_hex};
use super::out::Format;
use super::{CdsShort, Failure, NamedValue, RequestId};

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

/// A PUS 1 verification report.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Verification {
    pub stage: Stage,
    pub success: bool,
    /// Written as `{"packet_id": .., "psc": ..}` (the two words), as before the one type.
    #[serde(serialize_with = "ser_request")]
    pub request: RequestId,
    /// Step number of TM[1,5] / TM[1,6].
    pub step: Option<u8>,
    pub failure: Option<Failure>,
}

/// A request ID in JSON: `{"packet_id": .., "psc": ..}`.
fn ser_request<S: Serializer>(r: &RequestId, s: S) -> Result<S::Ok, S::Error> {
    let mut st = s.serialize_struct("RequestId", 2)?;
    st.serialize_field("packet_id", &r.packet_id())?;
    st.serialize_field("psc", &r.psc())?;
    st.end()
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
    pub params: Vec<NamedValue>,
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

/// The source data of a TM packet, decoded per `mib::tc::TMS`.
///
/// One model per packet: every kind is the generated `mib_wire` value. The three report
/// families the ground reads by name — verification, housekeeping and events — carry the
/// MIB's names and calibrated values beside it (what the wire value does not hold); every
/// other kind is [`TmBody::Report`], the wire value as it is, so a new TM kind of the MIB
/// needs no change here.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TmBody {
    Verification(Verification),
    Hk(Hk),
    Event(Event),
    /// A TM type the MIB does not define.
    Unknown {
        #[serde(serialize_with = "ser_hex")]
        data: Vec<u8>,
    },
    /// Any other kind of the MIB (never a verification, housekeeping or event report: the
    /// decoder gives those their own variant). In JSON: `{"kind": <MIB name in lower
    /// case>, ...}` with the fields as `ground decode --json` writes them (names beside raw
    /// values).
    /// Boxed: the largest kinds (the module report) hold their repeated groups inline.
    #[serde(untagged, serialize_with = "ser_report")]
    Report(Box<mib_wire::Tm>),
}

impl TmBody {
    /// The wire value of a [`TmBody::Report`] body.
    pub fn report(&self) -> Option<&mib_wire::Tm> {
        match self {
            TmBody::Report(r) => Some(r.as_ref()),
            TmBody::Verification(_) | TmBody::Hk(_) | TmBody::Event(_) | TmBody::Unknown { .. } => None,
        }
    }
}

/// A report's source data bytes (the wire value emits exactly the bytes it was parsed from).
pub(super) fn report_bytes(r: &mib_wire::Tm) -> Result<Vec<u8>, mib_wire::Error> {
    let mut buf = vec![0; r.buffer_len()];
    let n = r.emit(&mut buf)?;
    buf.truncate(n);
    Ok(buf)
}

/// A report in JSON: its kind, then its fields as the decode output writes them.
#[allow(clippy::borrowed_box)] // serde hands the field as it is
fn ser_report<S: Serializer>(r: &Box<mib_wire::Tm>, s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::{Error, SerializeMap};
    let json = report_bytes(r)
        .map_err(S::Error::custom)
        .and_then(|b| super::out::report(Format::Json, r, &b).map_err(|e| S::Error::custom(e.0)))?;
    let fields: serde_json::Map<String, serde_json::Value> = serde_json::from_slice(&json).map_err(S::Error::custom)?;
    let mut m = s.serialize_map(Some(fields.len() + 1))?;
    m.serialize_entry("kind", &r.name().to_ascii_lowercase())?;
    for (k, v) in &fields {
        m.serialize_entry(k, v)?;
    }
    m.end()
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
    pub args: Vec<NamedValue>,
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
