//! The one place the archive reads decoded TM bodies (`pus::TmBody`): everything else in
//! the archive works on [`Content`] and on raw packets, so a change of the decoder
//! touches only this file.

use ground_pus::{Tm, TmBody};

/// What the archive keeps of a decoded TM packet besides its raw bytes.
#[derive(Clone, Debug, PartialEq)]
pub enum Content {
    /// HK report: `(parameter id, raw value)` in report order.
    Hk {
        sid: u16,
        values: Vec<(u16, i64)>,
    },
    Event(EventRow),
    Verification(VerificationRow),
    /// Kept as the raw packet only (decoded again when read).
    Other,
}

#[derive(Clone, Debug, PartialEq)]
pub struct EventRow {
    pub event_id: u16,
    pub name: String,
    pub severity: String,
    /// Severity as the TM[5,n] subservice (1 info .. 4 high).
    pub level: u8,
    pub fault: bool,
    /// Parameters as a JSON object text.
    pub params: String,
    pub description: String,
}

#[derive(Clone, Debug, PartialEq)]
pub struct VerificationRow {
    pub req_apid: u16,
    pub req_seq: u16,
    pub stage: String,
    pub success: bool,
    pub step: Option<u8>,
    pub code: Option<u16>,
    pub code_name: Option<String>,
    pub failure: Option<String>,
}

/// The archive's view of a decoded TM body.
pub fn content(tm: &Tm) -> Content {
    match &tm.body {
        TmBody::Hk(h) => Content::Hk {
            sid: h.sid,
            values: h.values.iter().map(|v| (v.id, v.raw)).collect(),
        },
        TmBody::Event(e) => {
            let params: serde_json::Map<String, serde_json::Value> = e
                .params
                .iter()
                .map(|p| (p.name.clone(), serde_json::Value::from(p.value)))
                .collect();
            Content::Event(EventRow {
                event_id: e.id,
                name: e.name.to_string(),
                severity: e.severity.to_string(),
                level: tm.subservice,
                fault: e.fault,
                params: serde_json::Value::Object(params).to_string(),
                description: e.description.to_string(),
            })
        }
        TmBody::Verification(v) => Content::Verification(VerificationRow {
            req_apid: v.request.apid(),
            req_seq: v.request.seq(),
            stage: v.stage.name().to_string(),
            success: v.success,
            step: v.step,
            code: v.failure.as_ref().map(|f| f.code),
            code_name: v.failure.as_ref().map(|f| f.name.to_string()),
            failure: v.failure.as_ref().map(|f| f.to_string()),
        }),
        TmBody::DisabledEvents { .. }
        | TmBody::TimeReport { .. }
        | TmBody::MonDefinitions { .. }
        | TmBody::MonTransition { .. }
        | TmBody::StoreDownlinkDone { .. }
        | TmBody::PingReply
        | TmBody::EaDefinitions { .. }
        | TmBody::ParamValue { .. }
        | TmBody::ModeReply { .. }
        | TmBody::ModeCantReach { .. }
        | TmBody::TeamStatus { .. }
        | TmBody::PlanStatus { .. }
        | TmBody::Unknown { .. } => Content::Other,
    }
}

/// The decoded body as JSON (names and raw values), for `archive query --type tm`.
pub fn body_json(tm: &Tm) -> serde_json::Value {
    serde_json::to_value(&tm.body).unwrap_or_else(|e| serde_json::Value::String(format!("not serialisable: {e}")))
}
