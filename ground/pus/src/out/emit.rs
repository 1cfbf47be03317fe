//! The writer's primitives: numbers without `fmt`, JSON strings, keys and brackets in
//! either format, hex, ISO 8601 time, the text line's head.

use mib_wire::header::Primary;
use mib_wire::CdsTime;

use super::{Format, Writer};

impl Writer {
    #[inline]
    pub(super) fn int(&mut self, v: i64) {
        let s = self.itoa.format(v);
        self.out.extend_from_slice(s.as_bytes());
    }

    /// An engineering value with `decimals` digits after the point (fixed point, so
    /// that no float formatting is needed per value); shortest form beyond 10^15.
    #[inline]
    pub(super) fn float(&mut self, v: f64, decimals: u32) {
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
    pub(super) fn jstr(&mut self, s: &str) {
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
    pub(super) fn key(&mut self, k: &str) {
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

    pub(super) fn open(&mut self, c: u8) {
        if self.fmt == Format::Json {
            self.out.push(c);
        } else if c == b'[' || c == b'{' {
            self.out.push(if c == b'[' { b'[' } else { b'(' });
        }
        self.comma = false;
    }

    pub(super) fn close(&mut self, c: u8) {
        if self.fmt == Format::Json {
            self.out.push(c);
        } else {
            self.out.push(if c == b']' { b']' } else { b')' });
        }
        self.comma = true;
    }

    pub(super) fn elem_sep(&mut self) {
        if self.comma {
            self.out.push(if self.fmt == Format::Json { b',' } else { b' ' });
        }
        self.comma = false;
    }

    pub(super) fn hex(&mut self, b: &[u8]) {
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

    pub(super) fn time(&mut self, t: &CdsTime) {
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

    /// `{offset:8} TM  apid=0x{apid:03X} seq={seq:5} [{service},{subservice}]`, without fmt
    /// (`kind` `tm` or `tc`, written in upper case).
    fn text_head(&mut self, offset: usize, kind: &[u8], apid: u16, seq: u16, service: u8, subservice: u8) {
        let pad = |out: &mut Vec<u8>, s: &str, w: usize| {
            for _ in s.len()..w {
                out.push(b' ');
            }
            out.extend_from_slice(s.as_bytes());
        };
        pad(&mut self.out, self.itoa.format(offset as u64), 8);
        self.out.push(b' ');
        self.out.extend(kind.iter().map(u8::to_ascii_uppercase));
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

    /// The start of a packet's line: in JSON `{"type":"tm","offset":…,"apid":…,"robot":…,
    /// "seq":…,"service":…,"subservice":…` (`kind` `tm` or `tc`), in text the line's head.
    pub(super) fn head(&mut self, kind: &[u8], offset: usize, primary: &Primary, service: u8, subservice: u8) {
        let (apid, seq) = (primary.apid, primary.seq_count);
        match self.fmt {
            Format::Json => {
                self.out.extend_from_slice(b"{\"type\":\"");
                self.out.extend_from_slice(kind);
                self.out.extend_from_slice(b"\",\"offset\":");
                self.int(offset as i64);
                self.out.extend_from_slice(b",\"apid\":");
                self.int(apid as i64);
                self.out.extend_from_slice(b",\"robot\":");
                match mib::apid::apid_robot(apid) {
                    Some(r) => self.int(r as i64),
                    None => self.out.extend_from_slice(b"null"),
                }
                self.out.extend_from_slice(b",\"seq\":");
                self.int(seq as i64);
                self.out.extend_from_slice(b",\"service\":");
                self.int(service as i64);
                self.out.extend_from_slice(b",\"subservice\":");
                self.int(subservice as i64);
            }
            Format::Text => self.text_head(offset, kind, apid, seq, service, subservice),
        }
    }
}
