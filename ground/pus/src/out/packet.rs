//! One packet, one line: the TM's or TC's headers, then its body, or, when the body does
//! not follow the MIB, the error and the body's bytes in hex.

use std::io::Write;

use mib::layout::{Field, Names};
use mib::types::PType;
use mib_wire::header::{HeaderError, TcPacket, TmPacket};

use super::{tm_def, BodyError, Format, Writer};

impl Writer {
    /// Writes one TM packet (one line).
    pub fn tm(&mut self, offset: usize, p: &TmPacket<'_>) -> Result<(), BodyError> {
        let def = tm_def(p.service, p.subservice);
        let name = def.map_or("UNKNOWN", |d| d.name);
        let start = self.out.len();
        self.head(b"tm", offset, &p.primary, p.service, p.subservice);
        match self.fmt {
            Format::Json => {
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
        let start = self.out.len();
        self.head(b"tc", offset, &p.primary, p.service, p.subservice);
        match self.fmt {
            Format::Json => {
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
}

fn find_last(h: &[u8], n: &[u8]) -> Option<usize> {
    h.windows(n.len()).rposition(|w| w == n)
}
