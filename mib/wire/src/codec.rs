//! The table-driven codec: bodies that are a flat list of MIB-typed values — housekeeping
//! reports (`HkDef::params`), event reports (`EventDef::params`) and a TC's fixed
//! arguments (`TcDef::args`, range-checked) — read and written by one loop over the MIB's
//! table at run time. Flight code uses this: one copy of the loop serves every SID, event
//! and TC, where the generated typed code ([`crate::Hk`], [`crate::Event`], `tc::*`) costs
//! code per kind (4.5 KB of board A's flash for the HK structures alone). The generated
//! types are the typed front end for the host, the ground and the tests, and the tests
//! check that both give the same bytes (`tests/codec.rs`). No allocation.

use mib::events::{self, EventDef};
use mib::failure::FailureCode;
use mib::hk::{self, HkDef};
use mib::params::{self, ParamDef};
use mib::tc::{service, TcDef};

/// Most fixed arguments any TC has.
pub use mib::tc::MAX_ARGS;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CodecError {
    /// Output buffer too small.
    BufferTooShort {
        need: usize,
        have: usize,
    },
    /// Input shorter or longer than its definition.
    LengthMismatch {
        expected: usize,
        got: usize,
    },
    UnknownSid(u16),
    UnknownEvent(u16),
    UnknownParam(u16),
}

impl core::fmt::Display for CodecError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            CodecError::BufferTooShort { need, have } => {
                write!(f, "buffer too short: need {need} bytes, have {have}")
            }
            CodecError::LengthMismatch { expected, got } => {
                write!(f, "length mismatch: expected {expected} bytes, got {got}")
            }
            CodecError::UnknownSid(s) => write!(f, "unknown housekeeping structure ID {s}"),
            CodecError::UnknownEvent(e) => write!(f, "unknown event ID 0x{e:04X}"),
            CodecError::UnknownParam(p) => write!(f, "unknown parameter ID {p}"),
        }
    }
}

impl core::error::Error for CodecError {}

fn need(buf: &[u8], n: usize) -> Result<(), CodecError> {
    if buf.len() < n {
        Err(CodecError::BufferTooShort {
            need: n,
            have: buf.len(),
        })
    } else {
        Ok(())
    }
}

/// Writes the source data of TM[3,25] for `def`, reading each raw value from `value`.
pub fn encode_hk(def: &HkDef, mut value: impl FnMut(u16) -> i64, buf: &mut [u8]) -> Result<usize, CodecError> {
    let len = def.data_len();
    need(buf, len)?;
    buf[..2].copy_from_slice(&def.sid.to_be_bytes());
    let mut off = 2;
    for id in def.params {
        let p = params::by_id(*id).ok_or(CodecError::UnknownParam(*id))?;
        off += p
            .ptype
            .encode(value(*id), &mut buf[off..])
            .ok_or(CodecError::BufferTooShort {
                need: len,
                have: buf.len(),
            })?;
    }
    Ok(off)
}

/// A decoded housekeeping report (borrowing the packet's source data).
#[derive(Clone, Copy, Debug)]
pub struct HkReport<'a> {
    pub def: &'static HkDef,
    data: &'a [u8],
}

impl<'a> HkReport<'a> {
    /// `(parameter, raw value)` in structure order.
    pub fn values(&self) -> impl Iterator<Item = (&'static ParamDef, i64)> + 'a {
        let data = self.data;
        let mut off = 2;
        self.def.params.iter().filter_map(move |id| {
            let p = params::by_id(*id)?;
            let v = p.ptype.decode(&data[off..])?;
            off += p.ptype.size();
            Some((p, v))
        })
    }
    /// Raw value of one parameter of the report.
    pub fn get(&self, param: u16) -> Option<i64> {
        self.values().find(|(p, _)| p.id == param).map(|(_, v)| v)
    }
}

/// Checks and decodes the source data of a TM[3,25].
pub fn decode_hk(data: &[u8]) -> Result<HkReport<'_>, CodecError> {
    need(data, 2)?;
    let sid = u16::from_be_bytes([data[0], data[1]]);
    let def = hk::by_sid(sid).ok_or(CodecError::UnknownSid(sid))?;
    if data.len() != def.data_len() {
        return Err(CodecError::LengthMismatch {
            expected: def.data_len(),
            got: data.len(),
        });
    }
    Ok(HkReport { def, data })
}

/// Writes the source data of a TM[5,x] event report.
pub fn encode_event(def: &EventDef, args: &[i64], buf: &mut [u8]) -> Result<usize, CodecError> {
    let len = def.data_len();
    need(buf, len)?;
    buf[..2].copy_from_slice(&def.id.to_be_bytes());
    let mut off = 2;
    for (i, p) in def.params.iter().enumerate() {
        let v = args.get(i).copied().unwrap_or(0);
        off += p.ptype.encode(v, &mut buf[off..]).ok_or(CodecError::BufferTooShort {
            need: len,
            have: buf.len(),
        })?;
    }
    Ok(off)
}

/// A decoded event report.
#[derive(Clone, Copy, Debug)]
pub struct EventReport<'a> {
    pub def: &'static EventDef,
    data: &'a [u8],
}

impl<'a> EventReport<'a> {
    /// `(parameter name, raw value)` in definition order.
    pub fn params(&self) -> impl Iterator<Item = (&'static str, i64)> + 'a {
        let data = self.data;
        let mut off = 2;
        self.def.params.iter().filter_map(move |p| {
            let v = p.ptype.decode(&data[off..])?;
            off += p.ptype.size();
            Some((p.name, v))
        })
    }
    pub fn param(&self, name: &str) -> Option<i64> {
        self.params().find(|(n, _)| *n == name).map(|(_, v)| v)
    }
}

/// Checks and decodes the source data of a TM[5,x].
pub fn decode_event(data: &[u8]) -> Result<EventReport<'_>, CodecError> {
    need(data, 2)?;
    let id = u16::from_be_bytes([data[0], data[1]]);
    let def = events::by_id(id).ok_or(CodecError::UnknownEvent(id))?;
    if data.len() != def.data_len() {
        return Err(CodecError::LengthMismatch {
            expected: def.data_len(),
            got: data.len(),
        });
    }
    Ok(EventReport { def, data })
}

/// Why TC arguments were refused; maps to a PUS 1 failure code and its data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArgError {
    Length { got: usize, expected: usize },
    OutOfRange { index: u8, value: i64 },
}

impl ArgError {
    pub const fn failure_code(self) -> FailureCode {
        match self {
            ArgError::Length { .. } => FailureCode::BAD_ARG_LENGTH,
            ArgError::OutOfRange { .. } => FailureCode::ARG_OUT_OF_RANGE,
        }
    }
    /// Failure data as laid out in the MIB. Returns the number of bytes written.
    pub fn failure_data(self, buf: &mut [u8; 5]) -> usize {
        match self {
            ArgError::Length { got, expected } => {
                buf[..2].copy_from_slice(&(got.min(u16::MAX as usize) as u16).to_be_bytes());
                buf[2..4].copy_from_slice(&(expected as u16).to_be_bytes());
                4
            }
            ArgError::OutOfRange { index, value } => {
                buf[0] = index;
                buf[1..5].copy_from_slice(&(value.clamp(i32::MIN as i64, i32::MAX as i64) as i32).to_be_bytes());
                5
            }
        }
    }
}

/// Encodes a TC's application data (function ID first for PUS 8). The arguments are
/// range-checked against the MIB so that the ground never builds an invalid TC.
///
/// A variable TC whose rest is one group of single bytes (UPDATE_INSTALL's file name, a
/// PLAN_LOAD chunk) may be given the group's bytes as further arguments after its fixed
/// ones: their number must then be the value of the group's count argument (without them
/// only the fixed arguments are encoded, for a caller that appends the bytes itself).
pub fn encode_args(def: &TcDef, args: &[i64], buf: &mut [u8]) -> Result<usize, ArgError> {
    if let Some(count_index) = byte_group_count(def).filter(|_| args.len() > def.args.len()) {
        let (fixed, bytes) = args.split_at(def.args.len().min(args.len()));
        let count = fixed.get(count_index).copied().unwrap_or(-1);
        if fixed.len() != def.args.len() || count != bytes.len() as i64 {
            return Err(ArgError::Length {
                got: args.len(),
                expected: def.args.len() + usize::try_from(count).unwrap_or(0),
            });
        }
        let n = encode_args_fixed(def, fixed, buf)?;
        let Some(out) = buf.get_mut(n..n + bytes.len()) else {
            return Err(ArgError::Length {
                got: buf.len(),
                expected: n + bytes.len(),
            });
        };
        for (i, (o, b)) in out.iter_mut().zip(bytes).enumerate() {
            *o = u8::try_from(*b).map_err(|_| ArgError::OutOfRange {
                index: (def.args.len() + i).min(255) as u8,
                value: *b,
            })?;
        }
        return Ok(n + bytes.len());
    }
    encode_args_fixed(def, args, buf)
}

/// The index of the count argument of a TC whose rest is one group of single bytes.
fn byte_group_count(def: &TcDef) -> Option<usize> {
    let [mib::layout::Item::Group { count, items, .. }] = def.rest else {
        return None;
    };
    let [mib::layout::Item::Field(f)] = items else {
        return None;
    };
    if !def.variable || f.ptype != mib::types::PType::U8 {
        return None;
    }
    def.args.iter().position(|a| a.name == *count)
}

fn encode_args_fixed(def: &TcDef, args: &[i64], buf: &mut [u8]) -> Result<usize, ArgError> {
    if args.len() != def.args.len() {
        return Err(ArgError::Length {
            got: args.len(),
            expected: def.args.len(),
        });
    }
    let len = def.fixed_len();
    if buf.len() < len {
        return Err(ArgError::Length {
            got: buf.len(),
            expected: len,
        });
    }
    let mut off = 0;
    if def.service == service::FUNCTION {
        buf[..2].copy_from_slice(&def.function.to_be_bytes());
        off = 2;
    }
    for (i, (a, v)) in def.args.iter().zip(args).enumerate() {
        if *v < a.min || *v > a.max {
            return Err(ArgError::OutOfRange {
                index: i as u8,
                value: *v,
            });
        }
        off += a.ptype.encode(*v, &mut buf[off..]).unwrap_or(0);
    }
    Ok(off)
}

/// Decodes and range-checks a TC's fixed arguments from its application data (for
/// PUS 8 the function ID must already be stripped: pass the bytes after it).
/// Returns the argument values and the remaining (variable) data.
pub fn decode_args<'a>(def: &TcDef, data: &'a [u8]) -> Result<([i64; MAX_ARGS], &'a [u8]), ArgError> {
    let fixed: usize = def.args.iter().map(|a| a.ptype.size()).sum();
    let exact = !def.variable;
    if data.len() < fixed || (exact && data.len() != fixed) {
        let off = if def.service == service::FUNCTION { 2 } else { 0 };
        return Err(ArgError::Length {
            got: data.len() + off,
            expected: fixed + off,
        });
    }
    let mut out = [0i64; MAX_ARGS];
    let mut off = 0;
    for (i, a) in def.args.iter().enumerate().take(MAX_ARGS) {
        let v = a.ptype.decode(&data[off..]).unwrap_or(0);
        if v < a.min || v > a.max {
            return Err(ArgError::OutOfRange {
                index: i as u8,
                value: v,
            });
        }
        out[i] = v;
        off += a.ptype.size();
    }
    Ok((out, &data[off..]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::params::pid;
    use mib::tc::{self, function};

    // verifies: PUS-3-01
    #[test]
    fn hk_round_trip_preserves_every_value() {
        for def in hk::HK_STRUCTS {
            let mut buf = [0u8; 256];
            let n = encode_hk(def, |id| (id as i64 * 37) % 200, &mut buf).unwrap();
            let rep = decode_hk(&buf[..n]).unwrap();
            assert_eq!(rep.def.sid, def.sid);
            let mut count = 0;
            for (p, v) in rep.values() {
                let expect = p.ptype.saturate((p.id as i64 * 37) % 200);
                assert_eq!(v, expect, "{}", p.name);
                count += 1;
            }
            assert_eq!(count, def.params.len());
        }
    }

    // verifies: PUS-3-04
    #[test]
    fn hk_decode_rejects_truncation_and_unknown_sid() {
        let def = hk::by_sid(hk::sid::ROBOT_STATUS).unwrap();
        let mut buf = [0u8; 256];
        let n = encode_hk(def, |_| 1, &mut buf).unwrap();
        assert!(matches!(
            decode_hk(&buf[..n - 1]),
            Err(CodecError::LengthMismatch { .. })
        ));
        assert_eq!(decode_hk(&[0, 99, 1]).unwrap_err(), CodecError::UnknownSid(99));
        assert!(decode_hk(&[0]).is_err());
        // a short output buffer is an error, not a panic
        assert!(encode_hk(def, |_| 1, &mut buf[..10]).is_err());
        let rep = decode_hk(&buf[..n]).unwrap();
        assert_eq!(rep.get(pid::MODE), Some(1));
    }

    // verifies: PUS-5-01
    #[test]
    fn event_round_trip() {
        let def = events::by_id(events::eid::LOW_BATTERY).unwrap();
        let mut buf = [0u8; 32];
        let n = encode_event(def, &[20, 2700, 2730], &mut buf).unwrap();
        let ev = decode_event(&buf[..n]).unwrap();
        assert_eq!(ev.param("value"), Some(2700));
        assert_eq!(ev.params().count(), 3);
        assert!(decode_event(&buf[..n - 1]).is_err());
    }

    // verifies: PUS-8-02
    #[test]
    fn args_are_range_checked_both_ways() {
        let def = tc::lookup(8, 1, Some(function::RECONFIGURE)).unwrap();
        let mut buf = [0u8; 16];
        let n = encode_args(def, &[0, 1], &mut buf).unwrap();
        assert_eq!(&buf[..n], &[0, 1, 0, 1]);
        let (v, rest) = decode_args(def, &buf[2..n]).unwrap();
        assert_eq!((v[0], v[1], rest.len()), (0, 1, 0));
        assert_eq!(
            encode_args(def, &[0, 15], &mut buf),
            Err(ArgError::OutOfRange { index: 1, value: 15 })
        );
        assert_eq!(
            decode_args(def, &[0, 15]),
            Err(ArgError::OutOfRange { index: 1, value: 15 })
        );
        assert_eq!(decode_args(def, &[0]), Err(ArgError::Length { got: 3, expected: 4 }));
    }
}
