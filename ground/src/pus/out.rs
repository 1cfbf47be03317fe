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

use std::io::{self, Write};
use std::sync::OnceLock;

use mib::layout::{Field, Item, Names, Tail};
use mib::types::PType;
use mib_wire::header::{HeaderError, TcPacket, TmPacket};
use mib_wire::{CdsTime, Reader};

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

fn raw_of(t: PType, u: u32) -> i64 {
    match t {
        PType::I16 => u as u16 as i16 as i64,
        PType::I32 => u as i32 as i64,
        _ => u as i64,
    }
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
        Writer {
            out: Vec::with_capacity(1 << 16),
            fmt,
            ctx: Vec::with_capacity(16),
            comma: false,
            itoa: itoa::Buffer::new(),
            ryu: ryu::Buffer::new(),
        }
    }

    #[inline]
    fn int(&mut self, v: i64) {
        let s = self.itoa.format(v);
        self.out.extend_from_slice(s.as_bytes());
    }

    /// An engineering value with `decimals` digits after the point (fixed point, so
    /// that no float formatting is needed per value); shortest form beyond 10^15.
    #[inline]
    fn float(&mut self, v: f64, decimals: u32) {
        if !v.is_finite() {
            self.out.extend_from_slice(b"null");
            return;
        }
        let p = 10i64.pow(decimals);
        let scaled = (v * p as f64).round();
        if scaled.abs() >= 1e15 {
            let s = self.ryu.format_finite(v);
            self.out.extend_from_slice(s.as_bytes());
            return;
        }
        let n = scaled as i64;
        if n < 0 {
            self.out.push(b'-');
        }
        let a = n.unsigned_abs();
        let s = self.itoa.format(a / p as u64);
        self.out.extend_from_slice(s.as_bytes());
        if decimals > 0 {
            self.out.push(b'.');
            let frac = a % p as u64;
            let s = self.itoa.format(frac);
            for _ in s.len()..decimals as usize {
                self.out.push(b'0');
            }
            self.out.extend_from_slice(s.as_bytes());
        }
    }

    /// A JSON string (escaped).
    fn jstr(&mut self, s: &str) {
        self.out.push(b'"');
        for c in s.bytes() {
            match c {
                b'"' => self.out.extend_from_slice(b"\\\""),
                b'\\' => self.out.extend_from_slice(b"\\\\"),
                0..=0x1F => {
                    self.out.extend_from_slice(b"\\u00");
                    let h = b"0123456789abcdef";
                    self.out.push(h[(c >> 4) as usize]);
                    self.out.push(h[(c & 15) as usize]);
                }
                _ => self.out.push(c),
            }
        }
        self.out.push(b'"');
    }

    /// `"key":` (JSON) or ` key=` (text), with the separating comma.
    fn key(&mut self, k: &str) {
        match self.fmt {
            Format::Json => {
                if self.comma {
                    self.out.push(b',');
                }
                self.out.push(b'"');
                self.out.extend_from_slice(k.as_bytes());
                self.out.extend_from_slice(b"\":");
            }
            Format::Text => {
                self.out.push(b' ');
                self.out.extend_from_slice(k.as_bytes());
                self.out.push(b'=');
            }
        }
        self.comma = true;
    }

    fn open(&mut self, c: u8) {
        if self.fmt == Format::Json {
            self.out.push(c);
        } else if c == b'[' || c == b'{' {
            self.out.push(if c == b'[' { b'[' } else { b'(' });
        }
        self.comma = false;
    }

    fn close(&mut self, c: u8) {
        if self.fmt == Format::Json {
            self.out.push(c);
        } else {
            self.out.push(if c == b']' { b']' } else { b')' });
        }
        self.comma = true;
    }

    fn elem_sep(&mut self) {
        if self.comma {
            self.out.push(if self.fmt == Format::Json { b',' } else { b' ' });
        }
        self.comma = false;
    }

    fn field(&mut self, f: &Field, raw: i64) {
        self.key(f.name);
        let name = if f.names == Names::Mode {
            self.ctx
                .iter()
                .rev()
                .find(|(n, _)| *n == "node")
                .and_then(|(_, node)| Names::mode_name_for(*node, raw))
                .or_else(|| f.names.name(raw))
        } else {
            f.names.name(raw)
        };
        let calibrated = !f.calib.is_identity();
        match self.fmt {
            Format::Json => {
                if !f.names.is_none() {
                    self.out.extend_from_slice(b"{\"raw\":");
                    self.int(raw);
                    self.out.extend_from_slice(b",\"name\":");
                    match name {
                        Some(n) => self.jstr(n),
                        None => self.out.extend_from_slice(b"null"),
                    }
                    self.out.push(b'}');
                } else if calibrated {
                    self.out.extend_from_slice(b"{\"raw\":");
                    self.int(raw);
                    self.out.extend_from_slice(b",\"eng\":");
                    self.float(f.calib.eng(raw), decimals(f.calib.scale));
                    self.out.extend_from_slice(b",\"unit\":");
                    self.jstr(f.unit);
                    self.out.push(b'}');
                } else {
                    self.int(raw);
                }
            }
            Format::Text => {
                if let Some(n) = name {
                    self.out.extend_from_slice(n.as_bytes());
                } else if calibrated {
                    self.float(f.calib.eng(raw), decimals(f.calib.scale));
                    self.out.extend_from_slice(f.unit.as_bytes());
                } else {
                    self.int(raw);
                    self.out.extend_from_slice(f.unit.as_bytes());
                }
            }
        }
    }

    fn fields(&mut self, fields: &[Field], r: &mut Reader<'_>) -> Result<(), BodyError> {
        for f in fields {
            let u = r.uint(f.bits, f.name).map_err(|e| BodyError(e.to_string()))?;
            let raw = raw_of(f.ptype, u);
            self.ctx.push((f.name, raw));
            self.field(f, raw);
        }
        Ok(())
    }

    fn items(&mut self, items: &[Item], r: &mut Reader<'_>) -> Result<(), BodyError> {
        for it in items {
            match it {
                Item::Field(f) => self.fields(std::slice::from_ref(f), r)?,
                Item::Sub { name, sub } => {
                    self.key(name);
                    self.open(b'{');
                    self.fields(sub.fields, r)?;
                    self.close(b'}');
                }
                Item::Group {
                    name,
                    count,
                    max,
                    items,
                } => {
                    let n = self.ctx.iter().rev().find(|(c, _)| c == count).map_or(0, |(_, v)| *v) as usize;
                    if n > *max {
                        return Err(BodyError(format!("`{name}`: {n} entries, at most {max}")));
                    }
                    self.key(name);
                    self.open(b'[');
                    for _ in 0..n {
                        self.elem_sep();
                        self.open(b'{');
                        self.items(items, r)?;
                        self.close(b'}');
                    }
                    self.close(b']');
                }
                Item::Packet { name, max_len } => {
                    let b = r.packet(*max_len, name).map_err(|e| BodyError(e.to_string()))?;
                    self.key(name);
                    self.hex(b);
                }
                Item::Tail(t) => self.tail(*t, r)?,
            }
        }
        Ok(())
    }

    fn hex(&mut self, b: &[u8]) {
        let h = b"0123456789abcdef";
        if self.fmt == Format::Json {
            self.out.push(b'"');
        }
        for x in b {
            self.out.push(h[(x >> 4) as usize]);
            self.out.push(h[(x & 15) as usize]);
        }
        if self.fmt == Format::Json {
            self.out.push(b'"');
        }
    }

    fn tail(&mut self, t: Tail, r: &mut Reader<'_>) -> Result<(), BodyError> {
        let d = self
            .ctx
            .iter()
            .rev()
            .find(|(n, _)| *n == t.discriminant())
            .map_or(0, |(_, v)| *v);
        let (key, fields): (&str, Option<&[Field]>) = match t {
            Tail::FailureData => (
                "failure_data",
                match mib::FailureCode::from_code(d as u16) {
                    mib::FailureCode::Unknown(_) => None,
                    c => Some(c.data()),
                },
            ),
            Tail::EventParams => ("params", mib::events::by_id(d as u16).map(|e| e.params)),
            Tail::HkParams => (
                "params",
                match tables().hk.get(d as usize).and_then(|h| h.as_deref()) {
                    Some(f) => Some(f),
                    None => return Err(BodyError(format!("housekeeping structure ID {d} not in the MIB"))),
                },
            ),
        };
        self.key(key);
        match fields {
            Some(f) => {
                self.open(b'{');
                self.fields(f, r)?;
                self.close(b'}');
            }
            None => {
                // A code this MIB does not define: its data as hex.
                let rest = r.rest();
                let n = rest.len();
                self.hex(rest);
                let _ = r.take(n, "data");
            }
        }
        Ok(())
    }

    /// Writes the body of `items` (the whole of `data` must be used).
    fn body(&mut self, items: &[Item], prefix: &[Field], data: &[u8]) -> Result<(), BodyError> {
        self.ctx.clear();
        let mut r = Reader::new(data);
        // Text: the body's fields follow the packet name on the same line.
        let json = self.fmt == Format::Json;
        if json {
            self.open(b'{');
        }
        self.comma = false;
        self.fields(prefix, &mut r)?;
        self.items(items, &mut r)?;
        r.finish().map_err(|e| BodyError(e.to_string()))?;
        if json {
            self.close(b'}');
        }
        Ok(())
    }

    fn time(&mut self, t: &CdsTime) {
        // ISO 8601 UTC from days since 1958-01-01 (civil-from-days, H. Hinnant).
        let z = t.days as i64 - mib_wire::header::CCSDS_TO_UNIX_DAYS + 719_468;
        let era = z.div_euclid(146_097);
        let doe = z - era * 146_097;
        let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
        let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
        let mp = (5 * doy + 2) / 153;
        let d = doy - (153 * mp + 2) / 5 + 1;
        let m = if mp < 10 { mp + 3 } else { mp - 9 };
        let y = yoe + era * 400 + if m <= 2 { 1 } else { 0 };
        let ms = t.ms_of_day as i64;
        let digits = |out: &mut Vec<u8>, v: i64, n: u32| {
            let mut p = 10i64.pow(n - 1);
            while p > 0 {
                out.push(b'0' + (v / p % 10) as u8);
                p /= 10;
            }
        };
        digits(&mut self.out, y, 4);
        self.out.push(b'-');
        digits(&mut self.out, m, 2);
        self.out.push(b'-');
        digits(&mut self.out, d, 2);
        self.out.push(b'T');
        digits(&mut self.out, ms / 3_600_000, 2);
        self.out.push(b':');
        digits(&mut self.out, ms / 60_000 % 60, 2);
        self.out.push(b':');
        digits(&mut self.out, ms / 1000 % 60, 2);
        self.out.push(b'.');
        digits(&mut self.out, ms % 1000, 3);
        self.out.push(b'Z');
    }

    /// `{offset:8} TM  apid=0x{apid:03X} seq={seq:5} [{service},{subservice}]`, without fmt.
    fn text_head(&mut self, offset: usize, kind: &[u8], apid: u16, seq: u16, service: u8, subservice: u8) {
        let pad = |out: &mut Vec<u8>, s: &str, w: usize| {
            for _ in s.len()..w {
                out.push(b' ');
            }
            out.extend_from_slice(s.as_bytes());
        };
        pad(&mut self.out, self.itoa.format(offset as u64), 8);
        self.out.push(b' ');
        self.out.extend_from_slice(kind);
        self.out.extend_from_slice(b"  apid=0x");
        let h = b"0123456789ABCDEF";
        for sh in [8, 4, 0] {
            self.out.push(h[(apid >> sh & 15) as usize]);
        }
        self.out.extend_from_slice(b" seq=");
        pad(&mut self.out, self.itoa.format(seq), 5);
        self.out.extend_from_slice(b" [");
        self.int(service as i64);
        self.out.push(b',');
        self.int(subservice as i64);
        self.out.push(b']');
    }

    /// Writes one TM packet (one line).
    pub fn tm(&mut self, offset: usize, p: &TmPacket<'_>) -> Result<(), BodyError> {
        let def = tm_def(p.service, p.subservice);
        let name = def.map_or("UNKNOWN", |d| d.name);
        let robot = mib::apid::apid_robot(p.primary.apid);
        let start = self.out.len();
        match self.fmt {
            Format::Json => {
                self.out.extend_from_slice(b"{\"type\":\"tm\",\"offset\":");
                self.int(offset as i64);
                self.out.extend_from_slice(b",\"apid\":");
                self.int(p.primary.apid as i64);
                self.out.extend_from_slice(b",\"robot\":");
                match robot {
                    Some(r) => self.int(r as i64),
                    None => self.out.extend_from_slice(b"null"),
                }
                self.out.extend_from_slice(b",\"seq\":");
                self.int(p.primary.seq_count as i64);
                self.out.extend_from_slice(b",\"service\":");
                self.int(p.service as i64);
                self.out.extend_from_slice(b",\"subservice\":");
                self.int(p.subservice as i64);
                self.out.extend_from_slice(b",\"name\":\"");
                self.out.extend_from_slice(name.as_bytes());
                self.out.extend_from_slice(b"\",\"msg_counter\":");
                self.int(p.msg_counter as i64);
                self.out.extend_from_slice(b",\"time\":\"");
                self.time(&p.time);
                self.out.extend_from_slice(b"\",\"len\":");
                self.int(p.primary.len as i64);
                self.out.extend_from_slice(b",\"body\":");
            }
            Format::Text => {
                self.text_head(
                    offset,
                    b"TM",
                    p.primary.apid,
                    p.primary.seq_count,
                    p.service,
                    p.subservice,
                );
                self.out.push(b' ');
                self.time(&p.time);
                self.out.push(b' ');
                self.out.extend_from_slice(name.as_bytes());
            }
        }
        let res = match def {
            Some(d) => self.body(d.body, &[], p.source),
            None => Err(BodyError(format!("TM[{},{}] not in the MIB", p.service, p.subservice))),
        };
        self.finish_packet(start, res, p.source)
    }

    /// Writes one TC packet (one line).
    pub fn tc(&mut self, offset: usize, p: &TcPacket<'_>) -> Result<(), BodyError> {
        let function = if p.service == mib::tc::service::FUNCTION {
            p.app_data.get(..2).map(|b| u16::from_be_bytes([b[0], b[1]]))
        } else {
            None
        };
        let def = mib::tc::lookup(p.service, p.subservice, function);
        let name = def.map_or("UNKNOWN", |d| d.name);
        let robot = mib::apid::apid_robot(p.primary.apid);
        let start = self.out.len();
        match self.fmt {
            Format::Json => {
                self.out.extend_from_slice(b"{\"type\":\"tc\",\"offset\":");
                self.int(offset as i64);
                self.out.extend_from_slice(b",\"apid\":");
                self.int(p.primary.apid as i64);
                self.out.extend_from_slice(b",\"robot\":");
                match robot {
                    Some(r) => self.int(r as i64),
                    None => self.out.extend_from_slice(b"null"),
                }
                self.out.extend_from_slice(b",\"seq\":");
                self.int(p.primary.seq_count as i64);
                self.out.extend_from_slice(b",\"service\":");
                self.int(p.service as i64);
                self.out.extend_from_slice(b",\"subservice\":");
                self.int(p.subservice as i64);
                self.out.extend_from_slice(b",\"ack\":");
                self.int(p.ack as i64);
                self.out.extend_from_slice(b",\"source_id\":");
                self.int(p.source_id as i64);
                self.out.extend_from_slice(b",\"name\":\"");
                self.out.extend_from_slice(name.as_bytes());
                self.out.extend_from_slice(b"\",\"len\":");
                self.int(p.primary.len as i64);
                self.out.extend_from_slice(b",\"body\":");
            }
            Format::Text => {
                self.text_head(
                    offset,
                    b"TC",
                    p.primary.apid,
                    p.primary.seq_count,
                    p.service,
                    p.subservice,
                );
                self.out.push(b' ');
                self.out.extend_from_slice(name.as_bytes());
            }
        }
        let res = match def {
            Some(d) => {
                let func = mib::layout::f("function", PType::U16, "PUS 8 function ID").names(Names::Function);
                let mut prefix: Vec<Field> = Vec::with_capacity(d.args.len() + 1);
                if d.service == mib::tc::service::FUNCTION {
                    prefix.push(func);
                }
                prefix.extend_from_slice(d.args);
                self.body(d.rest, &prefix, p.app_data)
            }
            None => Err(BodyError(match function {
                Some(f) => format!("function {f} not in the MIB"),
                None => format!("TC[{},{}] not in the MIB", p.service, p.subservice),
            })),
        };
        self.finish_packet(start, res, p.app_data)
    }

    /// Ends the line; on a body error, replaces the partial body by the error and the
    /// body's bytes in hex.
    fn finish_packet(&mut self, start: usize, res: Result<(), BodyError>, data: &[u8]) -> Result<(), BodyError> {
        if let Err(e) = &res {
            // Cut back to the end of the header part and write the error instead.
            let head_end = match self.fmt {
                Format::Json => find_last(&self.out[start..], b",\"body\":").map(|i| start + i),
                Format::Text => None,
            };
            match (self.fmt, head_end) {
                (Format::Json, Some(h)) => {
                    self.out.truncate(h);
                    self.out.extend_from_slice(b",\"error\":");
                    self.jstr(&e.0);
                    self.out.extend_from_slice(b",\"data\":");
                    self.hex(data);
                    self.out.push(b'}');
                }
                _ => {
                    let _ = write!(self.out, " (body does not match the MIB: {}; data ", e.0);
                    self.hex(data);
                    self.out.push(b')');
                }
            }
        } else if self.fmt == Format::Json {
            self.out.push(b'}');
        }
        self.out.push(b'\n');
        self.comma = false;
        res
    }

    /// Writes a corrupt stretch.
    pub fn corrupt(&mut self, offset: usize, len: usize, reason: &HeaderError) {
        match self.fmt {
            Format::Json => {
                self.out.extend_from_slice(b"{\"type\":\"corrupt\",\"offset\":");
                self.int(offset as i64);
                self.out.extend_from_slice(b",\"len\":");
                self.int(len as i64);
                self.out.extend_from_slice(b",\"reason\":");
                self.jstr(&reason.to_string());
                self.out.extend_from_slice(b"}\n");
            }
            Format::Text => {
                let _ = writeln!(self.out, "{offset:8} CORRUPT {len} bytes skipped: {reason}");
            }
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

fn find_last(h: &[u8], n: &[u8]) -> Option<usize> {
    h.windows(n.len()).rposition(|w| w == n)
}

/// One item of a raw packet stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RawItem<'a> {
    Tm {
        offset: usize,
        packet: TmPacket<'a>,
    },
    Tc {
        offset: usize,
        packet: TcPacket<'a>,
    },
    /// Bytes skipped until the next packet with valid headers and CRC.
    Corrupt {
        offset: usize,
        len: usize,
        reason: HeaderError,
    },
}

fn raw_packet(b: &[u8], offset: usize) -> Result<(RawItem<'_>, usize), HeaderError> {
    let p = mib_wire::header::check_primary(b)?;
    if p.is_tc {
        TcPacket::parse(b).map(|packet| (RawItem::Tc { offset, packet }, p.len))
    } else {
        TmPacket::parse(b).map(|packet| (RawItem::Tm { offset, packet }, p.len))
    }
}

/// Splits concatenated space packets (headers and CRC checked); after bytes that are
/// not a packet it scans byte by byte to the next valid packet and reports the stretch.
pub struct RawStream<'a> {
    buf: &'a [u8],
    pos: usize,
    pending: Option<RawItem<'a>>,
}

impl<'a> RawStream<'a> {
    pub fn new(buf: &'a [u8]) -> Self {
        RawStream {
            buf,
            pos: 0,
            pending: None,
        }
    }
}

impl<'a> Iterator for RawStream<'a> {
    type Item = RawItem<'a>;
    fn next(&mut self) -> Option<RawItem<'a>> {
        if let Some(p) = self.pending.take() {
            return Some(p);
        }
        if self.pos >= self.buf.len() {
            return None;
        }
        let start = self.pos;
        let first_err = match raw_packet(&self.buf[start..], start) {
            Ok((item, len)) => {
                self.pos += len;
                return Some(item);
            }
            Err(e) => e,
        };
        let mut off = start + 1;
        while off < self.buf.len() {
            if let Ok((item, len)) = raw_packet(&self.buf[off..], off) {
                self.pending = Some(item);
                self.pos = off + len;
                return Some(RawItem::Corrupt {
                    offset: start,
                    len: off - start,
                    reason: first_err,
                });
            }
            off += 1;
        }
        self.pos = self.buf.len();
        Some(RawItem::Corrupt {
            offset: start,
            len: self.buf.len() - start,
            reason: first_err,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pus::{build_tm, CDS_PFIELD};

    const T0: [u8; 7] = [CDS_PFIELD, 0x5A, 0x00, 0x00, 0x00, 0x03, 0xE8];

    fn json_of(raw: &[u8]) -> serde_json::Value {
        let mut w = Writer::new(Format::Json);
        let Some(RawItem::Tm { offset, packet }) = RawStream::new(raw).next() else {
            panic!("not a TM")
        };
        let _ = w.tm(offset, &packet);
        serde_json::from_slice(&w.out).unwrap()
    }

    // verifies: DD-DEC-01, PUS-1-02
    #[test]
    fn failure_report_json_splits_request_id_and_names_code_and_data() {
        // TM[1,4] START_FAILURE for TC 0x1901/0xC007: NOT_ALLOWED_IN_MODE, mode 0.
        let src = [0x19, 0x01, 0xC0, 0x07, 0x00, 10, 0];
        let v = json_of(&build_tm(0x101, 3, 1, 4, 0, &T0, &src));
        assert_eq!(v["name"], "START_FAILURE");
        assert_eq!(v["body"]["request_id"]["apid"], 0x101);
        assert_eq!(v["body"]["request_id"]["seq_count"], 7);
        assert_eq!(v["body"]["request_id"]["seq_flags"]["name"], "UNSEGMENTED");
        assert_eq!(v["body"]["failure_code"]["name"], "NOT_ALLOWED_IN_MODE");
        assert_eq!(v["body"]["failure_code"]["raw"], 10);
        assert_eq!(v["body"]["failure_data"]["mode"]["name"], "STANDBY");
        assert_eq!(v["time"], "2021-01-30T00:00:01.000Z");
    }

    // verifies: DD-DEC-01, PUS-200-01
    #[test]
    fn mode_changed_event_names_node_and_modes_of_that_node() {
        let mut src = mib::events::eid::MODE_CHANGED.to_be_bytes().to_vec();
        for v in [10u32, 0, 1] {
            src.extend_from_slice(&v.to_be_bytes());
        }
        src.extend_from_slice(&0u16.to_be_bytes());
        let v = json_of(&build_tm(0x101, 3, 5, 1, 0, &T0, &src));
        assert_eq!(v["body"]["event_id"]["name"], "MODE_CHANGED");
        assert_eq!(v["body"]["params"]["node"]["name"], "BOLTER_B");
        assert_eq!(v["body"]["params"]["from"]["name"], "OFF");
        assert_eq!(v["body"]["params"]["to"]["name"], "ON");
    }

    // verifies: DD-DEC-01, GND-08
    #[test]
    fn a_body_that_does_not_match_is_an_error_line_with_its_bytes() {
        let v = json_of(&build_tm(0x101, 3, 17, 2, 0, &T0, &[1, 2]));
        assert_eq!(v["name"], "PING_REPLY");
        assert!(v["error"].as_str().unwrap().contains("2 bytes after"));
        assert_eq!(v["data"], "0102");
    }

    // verifies: DD-DEC-01
    #[test]
    fn engineering_values_show_one_raw_count() {
        assert_eq!(decimals(0.001), 3);
        assert_eq!(decimals(0.01), 2);
        assert_eq!(decimals(15.0 / 4095.0), 4);
        assert_eq!(decimals(1.0), 0);
        let mut w = Writer::new(Format::Json);
        w.float(-0.0405, 3);
        w.out.push(b' ');
        w.float(9.597069597, 4);
        w.out.push(b' ');
        w.float(23.58, 2);
        assert_eq!(String::from_utf8(w.out).unwrap(), "-0.041 9.5971 23.58");
    }

    // verifies: DD-DEC-01
    #[test]
    fn every_mib_name_and_unit_is_plain_json() {
        let plain = |s: &str| s.bytes().all(|c| c >= 0x20 && c != b'"' && c != b'\\');
        for p in mib::params::PARAMS {
            assert!(plain(p.name) && plain(p.unit));
        }
        for t in mib::tc::TMS {
            assert!(plain(t.name));
        }
    }
}
