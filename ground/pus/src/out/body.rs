//! A packet body walked along its MIB field list: plain, calibrated and named fields,
//! sub-structures, repeated groups, embedded packets and the tails whose layout a field
//! before them selects (failure data, event parameters, HK parameters).

use mib::layout::{Field, Item, Names, Tail};
use mib_wire::Reader;

use super::{decimals, tables, BodyError, Format, Writer};
use crate::raw_value;

impl Writer {
    pub(super) fn field(&mut self, f: &Field, raw: i64) {
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

    pub(super) fn fields(&mut self, fields: &[Field], r: &mut Reader<'_>) -> Result<(), BodyError> {
        for f in fields {
            let u = r.uint(f.bits, f.name).map_err(|e| BodyError(e.to_string()))?;
            let raw = raw_value(f.ptype, u);
            self.ctx.push((f.name, raw));
            self.field(f, raw);
        }
        Ok(())
    }

    pub(super) fn items(&mut self, items: &[Item], r: &mut Reader<'_>) -> Result<(), BodyError> {
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

    pub(super) fn tail(&mut self, t: Tail, r: &mut Reader<'_>) -> Result<(), BodyError> {
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
    pub(super) fn body(&mut self, items: &[Item], prefix: &[Field], data: &[u8]) -> Result<(), BodyError> {
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
}
