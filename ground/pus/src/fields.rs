//! Values read along a MIB field list: failure data and event parameters, each named.

use std::fmt;

use mib::FailureCode;
use serde::Serialize;

/// One named field of failure data, decoded with the layout the MIB gives for the code.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct NamedValue {
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
    pub fields: Vec<NamedValue>,
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
pub(super) fn named(defs: &[mib::layout::Field], values: &[NamedValue], i: usize) -> String {
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

pub(super) fn ser_hex<S: serde::Serializer>(v: &[u8], s: S) -> Result<S::Ok, S::Error> {
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
pub fn decode_fields(fields: &[mib::layout::Field], data: &[u8]) -> Vec<NamedValue> {
    let mut r = mib_wire::Reader::new(data);
    let mut out = Vec::with_capacity(fields.len());
    for f in fields {
        let Ok(u) = r.uint(f.bits, f.name) else { break };
        out.push(NamedValue {
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
