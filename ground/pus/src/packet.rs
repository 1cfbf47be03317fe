//! Decoded packets as owned values: [`Packet`] (a [`Tc`] or a [`Tm`]) and the TM bodies
//! ([`TmBody`]: verification reports, housekeeping, events, and the other TM types of
//! the MIB).

use std::fmt;

use serde::ser::{SerializeStruct, Serializer};
use serde::Serialize;

use super::fields::{named, ser_hex};
use super::{CdsShort, Failure, Field, RequestId};

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
    /// TM[211,2] TEAM_STATUS: team coordination without the ground.
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
    /// TM[18,9] PLAN_STATUS: the on-board plan (fields of the generated MIB type).
    PlanStatus {
        plan_id: u32,
        /// `mib::plan::state`.
        state: u8,
        steps: u8,
        next_step: u8,
        done: u8,
        /// 0 = none.
        wait_robot: u8,
        wait_step: u8,
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
