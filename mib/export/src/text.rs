//! One-line text of the MIB's packet layouts, for the ICD and the JSON export.

use mib::layout::{Field, Item, Tail};

/// Human-readable one-line summary of a body ("request_id (RequestId), step u8").
pub fn summary(items: &[Item]) -> String {
    let parts: Vec<String> = items
        .iter()
        .map(|it| match it {
            Item::Field(f) => format!("{} {}", f.name, type_name(f)),
            Item::Sub { name, sub } => format!("{name} ({})", sub.name),
            Item::Group { name, count, items, .. } => format!("{name}[{count}] of ({})", summary(items)),
            Item::Packet { name, max_len } => format!("{name} (space packet, <= {max_len} bytes)"),
            Item::Tail(t) => match t {
                Tail::FailureData => "failure data (per failure_code)".to_string(),
                Tail::EventParams => "parameters (per event_id)".to_string(),
                Tail::HkParams => "parameters (per sid)".to_string(),
            },
        })
        .collect();
    if parts.is_empty() {
        "(empty)".to_string()
    } else {
        parts.join(", ")
    }
}

/// One-line summary of a field list ("side u8, pair u8").
pub fn fields_summary(fields: &[Field]) -> String {
    fields
        .iter()
        .map(|f| format!("{} {}", f.name, type_name(f)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Wire type name of a field: the type, or `uN` for a bit field.
pub fn type_name(f: &Field) -> String {
    if f.is_whole() {
        f.ptype.name().to_string()
    } else {
        format!("u{}", f.bits)
    }
}
