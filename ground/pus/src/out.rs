//! Fast decode output: walks a packet body along the MIB's field list (`mib::layout`) and
//! writes JSON or text straight into a buffer — no intermediate values per field. Names
//! come from the MIB (node, mode, state, failure code, event, parameter...); JSON keeps the
//! raw value next to the name and the calibrated value next to the raw one.
//!
//! JSON shape of a body: one object; a plain field is `"name": raw`; a calibrated field
//! `"name": {"raw": r, "eng": e, "unit": "u"}`; a named field
//! `"name": {"raw": r, "name": "NAME"}` (`null` when the value has no name); a
//! sub-structure (request ID, time stamp) a nested object; a repeated group an array of
//! objects; an embedded packet a hex string; the tail (failure data, event parameters, HK
//! parameters) an object under `failure_data` / `params`.

//!
//! The writer's primitives are in `emit`, the walk along a field list in `body`, one
//! packet's line in `packet`, and the splitting of a byte stream in `stream`.

mod body;
mod emit;
mod packet;
mod stream;

#[cfg(test)]
mod tests;

use std::io;
use std::sync::OnceLock;

use mib::layout::Field;

pub use stream::{RawItem, RawStream};

/// Output format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Json,
    Text,
}

/// Why a body does not follow its field list.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyError(pub String);

/// Per-SID HK field lists and per-kind lookups, built once from the MIB.
struct Tables {
    hk: Vec<Option<Vec<Field>>>,
    tm: Vec<Option<&'static mib::tc::TmDef>>,
}

fn tables() -> &'static Tables {
    static T: OnceLock<Tables> = OnceLock::new();
    T.get_or_init(|| {
        let max_sid = mib::hk::HK_STRUCTS.iter().map(|h| h.sid).max().unwrap_or(0) as usize;
        let mut hk = vec![None; max_sid + 1];
        for h in mib::hk::HK_STRUCTS {
            hk[h.sid as usize] = Some(
                h.params
                    .iter()
                    .filter_map(|id| mib::params::by_id(*id))
                    .map(|p| p.field())
                    .collect(),
            );
        }
        let mut tm = vec![None; 256 * 256];
        for t in mib::tc::TMS {
            tm[(t.service as usize) << 8 | t.subservice as usize] = Some(t);
        }
        Tables { hk, tm }
    })
}

fn tm_def(service: u8, subservice: u8) -> Option<&'static mib::tc::TmDef> {
    tables().tm[(service as usize) << 8 | subservice as usize]
}

/// The body of a report (`data`, its source data) written alone along its MIB field list:
/// a JSON object, or the text's ` name=value` pairs. The ground's one rendering of the TM
/// kinds it has no view of (`TmBody::Report`).
pub(crate) fn report(fmt: Format, r: &mib_wire::Tm, data: &[u8]) -> Result<Vec<u8>, BodyError> {
    let (service, subservice) = r.kind();
    let def =
        tm_def(service, subservice).ok_or_else(|| BodyError(format!("TM[{service},{subservice}] not in the MIB")))?;
    let mut w = Writer::with_capacity(fmt, 64 + 2 * data.len());
    w.body(def.body, &[], data)?;
    Ok(w.out)
}

/// Writes decoded packets into a byte buffer (the caller flushes it to its writer).
pub struct Writer {
    pub out: Vec<u8>,
    fmt: Format,
    /// Values of the body's fields so far (counts, discriminants, the node of a mode).
    ctx: Vec<(&'static str, i64)>,
    /// Comma needed before the next JSON member/element.
    comma: bool,
    itoa: itoa::Buffer,
    ryu: ryu::Buffer,
}

impl Writer {
    pub fn new(fmt: Format) -> Self {
        Writer::with_capacity(fmt, 1 << 16)
    }

    fn with_capacity(fmt: Format, capacity: usize) -> Self {
        Writer {
            out: Vec::with_capacity(capacity),
            fmt,
            ctx: Vec::with_capacity(16),
            comma: false,
            itoa: itoa::Buffer::new(),
            ryu: ryu::Buffer::new(),
        }
    }

    /// Moves the buffered output to `w` once it is large.
    pub fn flush_if_full(&mut self, w: &mut impl io::Write) -> io::Result<()> {
        if self.out.len() >= 1 << 16 {
            self.flush(w)?;
        }
        Ok(())
    }

    pub fn flush(&mut self, w: &mut impl io::Write) -> io::Result<()> {
        w.write_all(&self.out)?;
        self.out.clear();
        Ok(())
    }
}

/// Digits after the decimal point that show one raw count of a calibration with this
/// scale: enough to reach the scale's first significant digit, one more when the scale is
/// not a power of ten (e.g. 15/4095 V per count: 4 digits; 0.001 A: 3; 0.01 deg: 2).
pub fn decimals(scale: f64) -> u32 {
    let mut s = scale.abs();
    if s == 0.0 || !s.is_finite() {
        return 0;
    }
    let mut d = 0;
    while s < 1.0 - 1e-9 && d < 9 {
        s *= 10.0;
        d += 1;
    }
    if (s - s.round()).abs() > 1e-9 && d < 9 {
        d += 1;
    }
    d
}
