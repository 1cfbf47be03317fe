//! Generates `generated.rs`: a `Repr` with parse/emit for every TC and TM body of the MIB,
//! the typed failure data, event parameters and housekeeping structures, from the MIB's
//! field lists (`mib::layout`). Nothing here knows a packet layout; it only translates the
//! MIB's items into Rust.

use std::fmt::Write as _;

use mib::layout::{Field, Item, Sub, Tail, CDS_TIME, REQUEST_ID};
use mib::types::PType;

fn camel(s: &str) -> String {
    s.split('_')
        .filter(|p| !p.is_empty())
        .map(|p| {
            let mut c = p.chars();
            let first = c.next().map(|c| c.to_ascii_uppercase()).unwrap_or_default();
            first.to_string() + &c.as_str().to_ascii_lowercase()
        })
        .collect()
}

fn ident(s: &str) -> String {
    let s = s.to_ascii_lowercase();
    match s.as_str() {
        "type" | "match" | "ref" | "move" | "fn" | "in" | "loop" | "mod" | "use" | "impl" | "trait" | "struct"
        | "enum" | "where" | "self" | "super" | "crate" | "const" | "static" | "let" | "if" | "else" | "for"
        | "while" | "return" | "break" | "continue" | "as" | "pub" | "true" | "false" | "box" | "dyn" => {
            format!("r#{s}")
        }
        _ => s,
    }
}

fn rust_type(f: &Field) -> &'static str {
    match f.ptype {
        PType::Bool => "bool",
        PType::U8 => "u8",
        PType::U16 => "u16",
        PType::U32 => "u32",
        PType::I16 => "i16",
        PType::I32 => "i32",
    }
}

fn read_expr(f: &Field) -> String {
    let n = f.name;
    let b = f.bits;
    match f.ptype {
        PType::Bool => format!("r.boolean(\"{n}\")?"),
        PType::U8 => format!("r.uint({b}, \"{n}\")? as u8"),
        PType::U16 => format!("r.uint({b}, \"{n}\")? as u16"),
        PType::U32 => format!("r.uint({b}, \"{n}\")?"),
        PType::I16 => format!("r.uint({b}, \"{n}\")? as u16 as i16"),
        PType::I32 => format!("r.uint({b}, \"{n}\")? as i32"),
    }
}

fn write_stmt(f: &Field, expr: &str) -> String {
    let b = f.bits;
    match f.ptype {
        PType::Bool | PType::U8 | PType::U16 | PType::U32 => format!("w.uint({b}, {expr} as u32)?;"),
        PType::I16 => format!("w.uint({b}, {expr} as u16 as u32)?;"),
        PType::I32 => format!("w.uint({b}, {expr} as u32)?;"),
    }
}

/// Saturating conversion from a raw i64 (what `codec` and the OBSW's parameter
/// functions produce) to the field's type.
fn from_i64(f: &Field, v: &str) -> String {
    // One out-of-line saturation per type (crate::sat): the clamp of an i64 is some ten
    // instructions on a 32-bit target, repeated for every HK parameter otherwise.
    match f.ptype {
        PType::Bool => format!("{v} != 0"),
        PType::U8 => format!("sat::u8({v})"),
        PType::U16 => format!("sat::u16({v})"),
        PType::U32 => format!("sat::u32({v})"),
        PType::I16 => format!("sat::i16({v})"),
        PType::I32 => format!("sat::i32({v})"),
    }
}

/// A body item after the roles of count and discriminant fields are known.
enum G {
    Member(Field),
    Count {
        field: Field,
        group: String,
    },
    Disc {
        field: Field,
        tail: Tail,
    },
    Const {
        field: Field,
        value: i64,
    },
    Sub {
        name: String,
        sub: &'static Sub,
    },
    Group {
        name: String,
        count: String,
        max: usize,
        elem: String,
    },
    Packet {
        name: String,
        max: usize,
    },
    Tail(Tail),
}

fn tail_type(t: Tail) -> (&'static str, &'static str, &'static str) {
    // (type, member name, discriminant accessor)
    match t {
        Tail::FailureData => ("Failure", "failure", "code"),
        Tail::EventParams => ("Event", "event", "id"),
        Tail::HkParams => ("Hk", "hk", "sid"),
    }
}

struct Gen {
    out: String,
}

impl Gen {
    /// Normalises a body and emits the structs it needs (group elements first).
    fn body(&mut self, ty: &str, prefix: &[G], items: &[Item], doc: &str) -> Vec<G> {
        let mut g: Vec<G> = Vec::new();
        let counts: Vec<(&str, &str)> = items
            .iter()
            .filter_map(|i| match i {
                Item::Group { name, count, .. } => Some((*count, *name)),
                _ => None,
            })
            .collect();
        let tail = items.iter().find_map(|i| match i {
            Item::Tail(t) => Some(*t),
            _ => None,
        });
        for p in prefix {
            g.push(match p {
                G::Member(f) => G::Member(*f),
                G::Const { field, value } => G::Const {
                    field: *field,
                    value: *value,
                },
                _ => unreachable!("prefix holds plain fields"),
            });
        }
        // A count may be a prefix field (the TC's fixed arguments).
        for x in g.iter_mut() {
            if let G::Member(f) = x {
                if let Some((_, grp)) = counts.iter().find(|(c, _)| *c == f.name) {
                    *x = G::Count {
                        field: *f,
                        group: grp.to_string(),
                    };
                }
            }
        }
        for it in items {
            g.push(match it {
                Item::Field(f) => {
                    if let Some((_, grp)) = counts.iter().find(|(c, _)| *c == f.name) {
                        G::Count {
                            field: *f,
                            group: grp.to_string(),
                        }
                    } else if let Some(t) = tail.filter(|t| t.discriminant() == f.name) {
                        G::Disc { field: *f, tail: t }
                    } else {
                        G::Member(*f)
                    }
                }
                Item::Sub { name, sub } => G::Sub {
                    name: name.to_string(),
                    sub,
                },
                Item::Group {
                    name,
                    count,
                    max,
                    items,
                } => {
                    let elem = format!("{ty}{}", camel(name));
                    self.body(&elem, &[], items, &format!("One entry of `{ty}::{name}`."));
                    G::Group {
                        name: name.to_string(),
                        count: count.to_string(),
                        max: *max,
                        elem,
                    }
                }
                Item::Packet { name, max_len } => G::Packet {
                    name: name.to_string(),
                    max: *max_len,
                },
                Item::Tail(t) => G::Tail(*t),
            });
        }
        self.emit_struct(ty, &g, doc);
        g
    }

    /// A zero-copy view over a body (smoltcp's `Packet<T>`): getters and setters of the
    /// fields at fixed offsets, up to the first variable part.
    fn emit_view(&mut self, ty: &str, g: &[G]) {
        let o = &mut self.out;
        let v = format!("{ty}View");
        let _ = writeln!(
            o,
            "/// A view over the bytes of a [`{ty}`] body: the fields at fixed offsets, read and written in place.\n#[derive(Clone, Copy, Debug, PartialEq, Eq)]\npub struct {v}<T: AsRef<[u8]>> {{ buffer: T }}\n"
        );
        let _ = writeln!(o, "impl<T: AsRef<[u8]>> {v}<T> {{");
        let _ = writeln!(
            o,
            "    /// Wraps bytes without a check (getters of missing bytes read 0).\n    pub const fn new_unchecked(buffer: T) -> Self {{ {v} {{ buffer }} }}"
        );
        let _ = writeln!(
            o,
            "    /// Wraps bytes that hold a whole, well-formed body.\n    pub fn new_checked(buffer: T) -> Result<Self, Error> {{ {ty}::parse(buffer.as_ref())?; Ok({v} {{ buffer }}) }}"
        );
        let _ = writeln!(o, "    pub fn into_inner(self) -> T {{ self.buffer }}");
        let mut bit = 0usize;
        let mut setters = Vec::new();
        for x in g {
            match x {
                G::Member(f) | G::Count { field: f, .. } | G::Disc { field: f, .. } | G::Const { field: f, .. } => {
                    let n = ident(f.name);
                    let conv = match f.ptype {
                        PType::Bool => "!= 0".to_string(),
                        PType::I16 => "as u16 as i16".to_string(),
                        PType::I32 => "as i32".to_string(),
                        PType::U32 => String::new(),
                        _ => format!("as {}", rust_type(f)),
                    };
                    let _ = writeln!(
                        o,
                        "    #[doc = {:?}]\n    pub fn {}(&self) -> {} {{ get_bits(self.buffer.as_ref(), {bit}, {}) {conv} }}",
                        field_doc(f),
                        n.trim_start_matches("r#"),
                        rust_type(f),
                        f.bits
                    );
                    let wconv = match f.ptype {
                        PType::I16 => "as u16 as u32",
                        _ => "as u32",
                    };
                    setters.push(format!(
                        "    pub fn set_{}(&mut self, value: {}) {{ set_bits(self.buffer.as_mut(), {bit}, {}, value {wconv}) }}",
                        n.trim_start_matches("r#"),
                        rust_type(f),
                        f.bits
                    ));
                    bit += f.bits as usize;
                }
                G::Sub { name, sub } => {
                    let _ = writeln!(
                        o,
                        "    pub fn {}(&self) -> Result<{}, Error> {{ {}::read(&mut Reader::new(self.buffer.as_ref().get({}..).unwrap_or(&[]))) }}",
                        ident(name),
                        sub.name,
                        sub.name,
                        bit / 8
                    );
                    bit += sub.len() * 8;
                }
                G::Group { .. } | G::Packet { .. } | G::Tail(_) => {
                    let _ = writeln!(
                        o,
                        "    /// The variable part of the body (from the first field whose offset depends on the data).\n    pub fn rest(&self) -> &[u8] {{ self.buffer.as_ref().get({}..).unwrap_or(&[]) }}",
                        bit / 8
                    );
                    break;
                }
            }
        }
        let _ = writeln!(o, "}}\n");
        if !setters.is_empty() {
            let _ = writeln!(
                o,
                "impl<T: AsRef<[u8]> + AsMut<[u8]>> {v}<T> {{\n{}\n}}\n",
                setters.join("\n")
            );
        }
    }

    fn emit_struct(&mut self, ty: &str, g: &[G], doc: &str) {
        let o = &mut self.out;
        let _ = writeln!(o, "#[doc = {doc:?}]");
        let _ = writeln!(o, "#[derive(Clone, Debug, PartialEq, Eq)]");
        let _ = writeln!(o, "pub struct {ty} {{");
        for x in g {
            match x {
                G::Member(f) => {
                    let _ = writeln!(o, "    #[doc = {:?}]", field_doc(f));
                    let _ = writeln!(o, "    pub {}: {},", ident(f.name), rust_type(f));
                }
                G::Sub { name, sub } => {
                    let _ = writeln!(o, "    pub {}: {},", ident(name), sub.name);
                }
                G::Group { name, max, elem, .. } => {
                    let _ = writeln!(o, "    pub {}: heapless::Vec<{elem}, {max}>,", ident(name));
                }
                G::Packet { name, max } => {
                    let _ = writeln!(o, "    /// An embedded space packet.");
                    let _ = writeln!(o, "    pub {}: heapless::Vec<u8, {max}>,", ident(name));
                }
                G::Tail(t) => {
                    let (tt, m, _) = tail_type(*t);
                    let _ = writeln!(o, "    pub {m}: {tt},");
                }
                G::Count { .. } | G::Disc { .. } | G::Const { .. } => {}
            }
        }
        let _ = writeln!(o, "}}\n");
        let _ = writeln!(o, "impl {ty} {{");
        // read
        let _ = writeln!(o, "    /// Reads the body from `r` (structure checked).");
        let _ = writeln!(o, "    #[allow(clippy::needless_question_mark, unused_variables)]");
        let _ = writeln!(o, "    pub fn read(r: &mut Reader<'_>) -> Result<Self, Error> {{");
        let mut members = Vec::new();
        for x in g {
            match x {
                G::Member(f) => {
                    let _ = writeln!(o, "        let {} = {};", ident(f.name), read_expr(f));
                    members.push(ident(f.name));
                }
                G::Count { field, .. } => {
                    let _ = writeln!(o, "        let {} = {} as usize;", ident(field.name), read_expr(field));
                }
                G::Disc { field, .. } => {
                    let _ = writeln!(o, "        let {} = {};", ident(field.name), read_expr(field));
                }
                G::Const { field, value } => {
                    let _ = writeln!(
                        o,
                        "        let got = {};\n        if got != {value} {{ return Err(Error::WrongFunction {{ expected: {value}, got }}); }}",
                        read_expr(field)
                    );
                }
                G::Sub { name, sub } => {
                    let _ = writeln!(o, "        let {} = {}::read(r)?;", ident(name), sub.name);
                    members.push(ident(name));
                }
                G::Group { name, count, max, elem } => {
                    let n = ident(name);
                    let c = ident(count);
                    let _ = writeln!(
                        o,
                        "        if {c} > {max} {{ return Err(Error::TooMany {{ field: \"{name}\", count: {c}, max: {max} }}); }}\n        let mut {n}: heapless::Vec<{elem}, {max}> = heapless::Vec::new();\n        for _ in 0..{c} {{ {n}.push({elem}::read(r)?).map_err(|_| Error::TooMany {{ field: \"{name}\", count: {c}, max: {max} }})?; }}"
                    );
                    members.push(n);
                }
                G::Packet { name, max } => {
                    let n = ident(name);
                    let _ = writeln!(
                        o,
                        "        let b = r.packet({max}, \"{name}\")?;\n        let {n} = heapless::Vec::from_slice(b).map_err(|_| Error::BadPacket {{ field: \"{name}\", len: b.len() }})?;"
                    );
                    members.push(n);
                }
                G::Tail(t) => {
                    let (tt, m, _) = tail_type(*t);
                    let _ = writeln!(o, "        let {m} = {tt}::read({}, r)?;", ident(t.discriminant()));
                    members.push(m.to_string());
                }
            }
        }
        let _ = writeln!(o, "        Ok({ty} {{ {} }})", members.join(", "));
        let _ = writeln!(o, "    }}");
        // write
        let _ = writeln!(o, "    /// Writes the body to `w`.");
        let _ = writeln!(o, "    #[allow(unused_variables)]");
        let _ = writeln!(o, "    pub fn write(&self, w: &mut Writer<'_>) -> Result<(), Error> {{");
        for x in g {
            match x {
                G::Member(f) => {
                    let _ = writeln!(o, "        {}", write_stmt(f, &format!("self.{}", ident(f.name))));
                }
                G::Count { field, group } => {
                    let _ = writeln!(
                        o,
                        "        {}",
                        write_stmt(field, &format!("self.{}.len()", ident(group)))
                    );
                }
                G::Disc { field, tail } => {
                    let (_, m, acc) = tail_type(*tail);
                    let _ = writeln!(o, "        {}", write_stmt(field, &format!("self.{m}.{acc}()")));
                }
                G::Const { field, value } => {
                    let _ = writeln!(o, "        {}", write_stmt(field, &format!("{value}u32")));
                }
                G::Sub { name, .. } => {
                    let _ = writeln!(o, "        self.{}.write(w)?;", ident(name));
                }
                G::Group { name, .. } => {
                    let _ = writeln!(o, "        for e in &self.{} {{ e.write(w)?; }}", ident(name));
                }
                G::Packet { name, .. } => {
                    let _ = writeln!(o, "        w.bytes(&self.{})?;", ident(name));
                }
                G::Tail(t) => {
                    let (_, m, _) = tail_type(*t);
                    let _ = writeln!(o, "        self.{m}.write(w)?;");
                }
            }
        }
        let _ = writeln!(o, "        Ok(())\n    }}");
        // length
        let mut fixed_bits = 0usize;
        let mut dynamic = Vec::new();
        for x in g {
            match x {
                G::Member(f) | G::Count { field: f, .. } | G::Disc { field: f, .. } | G::Const { field: f, .. } => {
                    fixed_bits += f.bits as usize
                }
                G::Sub { sub, .. } => fixed_bits += sub.len() * 8,
                G::Group { name, .. } => dynamic.push(format!(
                    "self.{}.iter().map(|e| e.buffer_len()).sum::<usize>()",
                    ident(name)
                )),
                G::Packet { name, .. } => dynamic.push(format!("self.{}.len()", ident(name))),
                G::Tail(t) => dynamic.push(format!("self.{}.buffer_len()", tail_type(*t).1)),
            }
        }
        dynamic.insert(0, format!("{}", fixed_bits / 8));
        let _ = writeln!(o, "    /// Length of the body on the wire.");
        let _ = writeln!(o, "    pub fn buffer_len(&self) -> usize {{ {} }}", dynamic.join(" + "));
        let _ = writeln!(
            o,
            "    /// Parses a whole body (every byte must belong to it).\n    pub fn parse(data: &[u8]) -> Result<Self, Error> {{ let mut r = Reader::new(data); let v = Self::read(&mut r)?; r.finish()?; Ok(v) }}"
        );
        let _ = writeln!(
            o,
            "    /// Emits the body into `buf`; returns the bytes written.\n    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, Error> {{ let mut w = Writer::new(buf); self.write(&mut w)?; Ok(w.len()) }}"
        );
        let _ = writeln!(o, "}}\n");
    }

    /// An enum over the variable tails (failure data, event parameters).
    fn tail_enum(&mut self, ty: &str, disc: &str, disc_ty: &str, doc: &str, cases: &[(i64, &str, &[Field], &str)]) {
        // Each case's fields become a struct `{ty}{Case}`-free enum variant.
        let o = &mut self.out;
        let _ = writeln!(o, "#[doc = {doc:?}]");
        let _ = writeln!(o, "#[derive(Clone, Debug, PartialEq, Eq)]\npub enum {ty} {{");
        for (_, name, fields, d) in cases {
            let _ = writeln!(o, "    #[doc = {d:?}]");
            if fields.is_empty() {
                let _ = writeln!(o, "    {},", camel(name));
            } else {
                let fs: Vec<String> = fields
                    .iter()
                    .map(|f| format!("{}: {}", ident(f.name), rust_type(f)))
                    .collect();
                let _ = writeln!(o, "    {} {{ {} }},", camel(name), fs.join(", "));
            }
        }
        let _ = writeln!(
            o,
            "    /// A code this MIB does not define, with its data (at most `MAX_UNKNOWN_DATA` bytes).\n    Unknown {{ {disc}: {disc_ty}, data: heapless::Vec<u8, MAX_UNKNOWN_DATA> }},\n}}\n"
        );
        let _ = writeln!(o, "impl {ty} {{");
        let _ = writeln!(
            o,
            "    /// The discriminant on the wire.\n    pub fn {disc}(&self) -> {disc_ty} {{ match self {{"
        );
        for (v, name, fields, _) in cases {
            let pat = if fields.is_empty() { "" } else { " { .. }" };
            let _ = writeln!(o, "        {ty}::{}{pat} => {v},", camel(name));
        }
        let _ = writeln!(o, "        {ty}::Unknown {{ {disc}, .. }} => *{disc},\n    }} }}");
        // read
        let _ = writeln!(
            o,
            "    /// Reads the data that follows the discriminant (to the end of the body).\n    pub fn read({disc}: {disc_ty}, r: &mut Reader<'_>) -> Result<Self, Error> {{ Ok(match {disc} {{"
        );
        for (v, name, fields, _) in cases {
            if fields.is_empty() {
                let _ = writeln!(o, "        {v} => {ty}::{},", camel(name));
            } else {
                let fs: Vec<String> = fields
                    .iter()
                    .map(|f| format!("{}: {}", ident(f.name), read_expr(f)))
                    .collect();
                let _ = writeln!(o, "        {v} => {ty}::{} {{ {} }},", camel(name), fs.join(", "));
            }
        }
        let _ = writeln!(
            o,
            "        other => {{ let rest = r.rest(); let data = heapless::Vec::from_slice(rest).map_err(|_| Error::UnknownTooLong {{ code: other as u16, len: rest.len() }})?; r.take(rest.len(), \"data\")?; {ty}::Unknown {{ {disc}: other, data }} }}\n    }}) }}"
        );
        // write
        let _ = writeln!(
            o,
            "    /// Writes the data that follows the discriminant.\n    pub fn write(&self, w: &mut Writer<'_>) -> Result<(), Error> {{ match self {{"
        );
        for (_, name, fields, _) in cases {
            if fields.is_empty() {
                let _ = writeln!(o, "        {ty}::{} => {{}}", camel(name));
            } else {
                let names: Vec<String> = fields.iter().map(|f| ident(f.name)).collect();
                let ws: Vec<String> = fields
                    .iter()
                    .map(|f| write_stmt(f, &format!("*{}", ident(f.name))))
                    .collect();
                let _ = writeln!(
                    o,
                    "        {ty}::{} {{ {} }} => {{ {} }}",
                    camel(name),
                    names.join(", "),
                    ws.join(" ")
                );
            }
        }
        let _ = writeln!(
            o,
            "        {ty}::Unknown {{ data, .. }} => w.bytes(data)?,\n    }} Ok(()) }}"
        );
        // length
        let _ = writeln!(
            o,
            "    /// Length of the data on the wire.\n    pub fn buffer_len(&self) -> usize {{ match self {{"
        );
        for (_, name, fields, _) in cases {
            let pat = if fields.is_empty() { "" } else { " { .. }" };
            let _ = writeln!(
                o,
                "        {ty}::{}{pat} => {},",
                camel(name),
                mib::layout::fields_len(fields)
            );
        }
        let _ = writeln!(
            o,
            "        {ty}::Unknown {{ data, .. }} => data.len(),\n    }} }}\n}}\n"
        );
    }
}

fn field_doc(f: &Field) -> String {
    let mut d = f.desc.to_string();
    if !f.unit.is_empty() {
        d.push_str(&format!(" [{}]", f.unit));
    }
    d
}

fn sub_struct(g: &mut Gen, sub: &'static Sub) {
    let items: Vec<Item> = sub.fields.iter().map(|f| Item::Field(*f)).collect();
    let items: &'static [Item] = Box::leak(items.into_boxed_slice());
    g.body(sub.name, &[], items, sub.desc);
    let _ = writeln!(g.out, "impl Copy for {} {{}}\n", sub.name);
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../src");
    let mut g = Gen { out: String::new() };
    let o = &mut g.out;
    let _ = writeln!(
        o,
        "// Generated by mib/wire/build.rs from the MIB's field lists. Do not edit.\n"
    );

    sub_struct(&mut g, &REQUEST_ID);
    sub_struct(&mut g, &CDS_TIME);

    // Failure data per failure code.
    let cases: Vec<(i64, &str, &[Field], &str)> = mib::FailureCode::ALL
        .iter()
        .map(|c| (c.code() as i64, c.name(), c.data(), c.description()))
        .collect();
    g.tail_enum(
        "Failure",
        "code",
        "u16",
        "A PUS 1 failure: the failure code and the failure data the MIB defines for it.",
        &cases,
    );
    // Event parameters per event ID.
    let cases: Vec<(i64, &str, &[Field], &str)> = mib::events::EVENTS
        .iter()
        .map(|e| (e.id as i64, e.name, e.params, e.desc))
        .collect();
    g.tail_enum(
        "Event",
        "id",
        "u16",
        "A PUS 5 event: the event ID and the parameters the MIB defines for it.",
        &cases,
    );

    // The severity of each event is its TM[5,x] subservice.
    let o = &mut g.out;
    let _ = writeln!(
        o,
        "impl Event {{\n    /// Subservice of the event's TM[5,x] (its severity); `None` for an unknown event.\n    pub fn subservice(&self) -> Option<u8> {{ match self {{"
    );
    for e in mib::events::EVENTS {
        let pat = if e.params.is_empty() { "" } else { " { .. }" };
        let _ = writeln!(
            o,
            "        Event::{}{pat} => Some({}),",
            camel(e.name),
            e.severity.subservice()
        );
    }
    let _ = writeln!(o, "        Event::Unknown {{ .. }} => None,\n    }} }}\n}}\n");

    // Typed event parameters: one struct per event, named fields of the MIB's types, whose
    // `values()` gives them in MIB order for the table codec (`codec::encode_event`). A
    // caller names every field, so a reordered MIB list cannot swap values.
    let _ = writeln!(
        g.out,
        "/// Typed parameters of every event, for raising it through the table codec ([`EventArgs`]).\npub mod ev {{\n    use super::*;\n"
    );
    for e in mib::events::EVENTS {
        let ty = camel(e.name);
        let o = &mut g.out;
        let _ = writeln!(o, "#[doc = {:?}]", e.desc);
        let _ = writeln!(o, "#[derive(Clone, Copy, Debug, PartialEq, Eq)]");
        if e.params.is_empty() {
            let _ = writeln!(o, "pub struct {ty};");
        } else {
            let _ = writeln!(o, "pub struct {ty} {{");
            for f in e.params {
                let _ = writeln!(o, "    pub {}: {},", ident(f.name), rust_type(f));
            }
            let _ = writeln!(o, "}}");
        }
        let vals: Vec<String> = e
            .params
            .iter()
            .map(|f| format!("self.{} as i64", ident(f.name)))
            .collect();
        let _ = writeln!(
            o,
            "impl EventArgs for {ty} {{\n    const ID: u16 = {};\n    type Values = [i64; {}];\n    #[inline]\n    fn values(&self) -> [i64; {}] {{ [{}] }}\n}}\n",
            e.id,
            e.params.len(),
            e.params.len(),
            vals.join(", ")
        );
    }
    let _ = writeln!(g.out, "}}\n");

    // Typed TC arguments: one struct per TC with fixed arguments, built from the values
    // `codec::decode_args` range-checked (so every cast is exact), by name.
    let _ = writeln!(
        g.out,
        "/// Typed fixed arguments of every TC that has some, from the values [`codec::decode_args`] checked.\npub mod args {{\n    use super::*;\n"
    );
    let mut args_kinds = Vec::new();
    for t in mib::tc::TCS {
        if t.args.is_empty() {
            continue;
        }
        let ty = camel(t.name);
        let o = &mut g.out;
        let _ = writeln!(o, "#[doc = {:?}]", t.desc);
        let _ = writeln!(o, "#[derive(Clone, Copy, Debug, PartialEq, Eq)]\npub struct {ty} {{");
        for f in t.args {
            let _ = writeln!(o, "    #[doc = {:?}]", field_doc(f));
            let _ = writeln!(o, "    pub {}: {},", ident(f.name), rust_type(f));
        }
        let _ = writeln!(o, "}}");
        let fs: Vec<String> = t
            .args
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let v = match f.ptype {
                    PType::Bool => format!("a[{i}] != 0"),
                    _ => format!("a[{i}] as {}", rust_type(f)),
                };
                format!("{}: {v}", ident(f.name))
            })
            .collect();
        let by_name: Vec<String> = t
            .args
            .iter()
            .map(|f| format!("{:?} => self.{} as i64", f.name, ident(f.name)))
            .collect();
        let _ = writeln!(
            o,
            "impl {ty} {{\n    /// The arguments of an accepted TC of this kind (values range-checked against the MIB).\n    #[inline]\n    pub fn of(a: &[i64; codec::MAX_ARGS]) -> Self {{ {ty} {{ {} }} }}\n    /// The value of the argument the MIB names `name`.\n    pub fn field(&self, name: &str) -> Option<i64> {{ Some(match name {{ {}, _ => return None }}) }}\n}}\n",
            fs.join(", "),
            by_name.join(", ")
        );
        args_kinds.push((t.name, ty));
    }
    let _ = writeln!(
        g.out,
        "/// Argument `field` of TC `tc` (MIB names) taken from decoded values `a` through the typed struct.\npub fn field_of(tc: &str, a: &[i64; codec::MAX_ARGS], field: &str) -> Option<i64> {{ match tc {{"
    );
    for (name, ty) in &args_kinds {
        let _ = writeln!(g.out, "    {name:?} => {ty}::of(a).field(field),");
    }
    let _ = writeln!(g.out, "    _ => None,\n}} }}\n}}\n");

    // Housekeeping structures.
    let _ = writeln!(
        g.out,
        "/// Housekeeping structures, one struct per SID.\npub mod hk {{\n    use super::*;\n"
    );
    let mut hk_cases = Vec::new();
    for h in mib::hk::HK_STRUCTS {
        let fields: Vec<Item> = h
            .params
            .iter()
            .filter_map(|id| mib::params::by_id(*id))
            .map(|p| Item::Field(p.field()))
            .collect();
        let fields: &'static [Item] = Box::leak(fields.into_boxed_slice());
        let ty = camel(h.name);
        g.body(&ty, &[], fields, h.desc);
        let o = &mut g.out;
        let _ = writeln!(o, "impl {ty} {{\n    pub const SID: u16 = {};", h.sid);
        let _ = writeln!(
            o,
            "    /// Builds the report from raw parameter values (saturated to each parameter's type).\n    pub fn from_values(mut value: impl FnMut(u16) -> i64) -> Self {{ {ty} {{"
        );
        for id in h.params {
            let p = mib::params::by_id(*id).expect("HK parameter in the MIB");
            let _ = writeln!(
                o,
                "        {}: {},",
                ident(p.name),
                from_i64(&p.field(), &format!("value({id})"))
            );
        }
        let _ = writeln!(o, "    }} }}");
        let _ = writeln!(
            o,
            "    /// Raw value of a parameter of the structure.\n    pub fn get(&self, param: u16) -> Option<i64> {{ Some(match param {{"
        );
        for id in h.params {
            let p = mib::params::by_id(*id).expect("HK parameter in the MIB");
            let _ = writeln!(o, "        {id} => self.{} as i64,", ident(p.name));
        }
        let _ = writeln!(o, "        _ => return None,\n    }}) }}\n}}\n");
        hk_cases.push((h.sid, ty));
    }
    let o = &mut g.out;
    let _ = writeln!(o, "}}\n");
    let _ = writeln!(
        o,
        "/// A housekeeping report body after the SID: the structure the SID names.\n#[derive(Clone, Debug, PartialEq, Eq)]\npub enum Hk {{"
    );
    for (_, ty) in &hk_cases {
        let _ = writeln!(o, "    {ty}(hk::{ty}),");
    }
    let _ = writeln!(o, "}}\n\nimpl Hk {{\n    pub fn sid(&self) -> u16 {{ match self {{");
    for (sid, ty) in &hk_cases {
        let _ = writeln!(o, "        Hk::{ty}(_) => {sid},");
    }
    let _ = writeln!(o, "    }} }}\n    /// Reads the parameters of structure `sid`.\n    pub fn read(sid: u16, r: &mut Reader<'_>) -> Result<Self, Error> {{ Ok(match sid {{");
    for (sid, ty) in &hk_cases {
        let _ = writeln!(o, "        {sid} => Hk::{ty}(hk::{ty}::read(r)?),");
    }
    let _ = writeln!(o, "        other => return Err(Error::UnknownSid(other)),\n    }}) }}");
    let _ = writeln!(
        o,
        "    pub fn write(&self, w: &mut Writer<'_>) -> Result<(), Error> {{ match self {{"
    );
    for (_, ty) in &hk_cases {
        let _ = writeln!(o, "        Hk::{ty}(x) => x.write(w),");
    }
    let _ = writeln!(o, "    }} }}\n    pub fn buffer_len(&self) -> usize {{ match self {{");
    for (_, ty) in &hk_cases {
        let _ = writeln!(o, "        Hk::{ty}(x) => x.buffer_len(),");
    }
    let _ = writeln!(
        o,
        "    }} }}\n    /// Builds structure `sid` from raw parameter values; `None` for an unknown SID.\n    pub fn from_values(sid: u16, value: impl FnMut(u16) -> i64) -> Option<Hk> {{ Some(match sid {{"
    );
    for (sid, ty) in &hk_cases {
        let _ = writeln!(o, "        {sid} => Hk::{ty}(hk::{ty}::from_values(value)),");
    }
    let _ = writeln!(o, "        _ => return None,\n    }}) }}");
    let _ = writeln!(o, "    /// Raw value of a parameter of the report.\n    pub fn get(&self, param: u16) -> Option<i64> {{ match self {{");
    for (_, ty) in &hk_cases {
        let _ = writeln!(o, "        Hk::{ty}(x) => x.get(param),");
    }
    let _ = writeln!(o, "    }} }}\n}}\n");

    // TM kinds.
    let _ = writeln!(
        g.out,
        "/// Every TM kind's source data.\npub mod tm {{\n    use super::*;\n"
    );
    let mut tm_kinds = Vec::new();
    for t in mib::tc::TMS {
        let ty = camel(t.name);
        let parts = g.body(&ty, &[], t.body, t.desc);
        g.emit_view(&ty, &parts);
        let _ = writeln!(
            g.out,
            "impl {ty} {{ pub const SERVICE: u8 = {}; pub const SUBSERVICE: u8 = {}; pub const NAME: &'static str = {:?}; }}\n",
            t.service, t.subservice, t.name
        );
        tm_kinds.push((t.service, t.subservice, ty));
    }
    let _ = writeln!(g.out, "}}\n");
    kind_enum(&mut g.out, "Tm", "tm", &tm_kinds, false);

    // TC kinds.
    let _ = writeln!(
        g.out,
        "/// Every TC kind's application data.\npub mod tc {{\n    use super::*;\n"
    );
    let mut tc_kinds = Vec::new();
    for t in mib::tc::TCS {
        let ty = camel(t.name);
        let prefix: Vec<G> = if t.service == mib::tc::service::FUNCTION {
            vec![G::Const {
                field: mib::layout::f("function", PType::U16, "PUS 8 function ID"),
                value: t.function as i64,
            }]
        } else {
            vec![]
        };
        let mut prefix = prefix;
        prefix.extend(t.args.iter().map(|a| G::Member(*a)));
        let parts = g.body(&ty, &prefix, t.rest, t.desc);
        g.emit_view(&ty, &parts);
        let _ = writeln!(
            g.out,
            "impl {ty} {{ pub const SERVICE: u8 = {}; pub const SUBSERVICE: u8 = {}; pub const FUNCTION: Option<u16> = {}; pub const NAME: &'static str = {:?}; }}\n",
            t.service,
            t.subservice,
            if t.service == mib::tc::service::FUNCTION {
                format!("Some({})", t.function)
            } else {
                "None".into()
            },
            t.name
        );
        tc_kinds.push((t.service, t.subservice, ty));
    }
    let _ = writeln!(g.out, "}}\n");
    kind_enum(&mut g.out, "Tc", "tc", &tc_kinds, true);

    let dest = std::path::Path::new(&std::env::var("OUT_DIR").expect("OUT_DIR")).join("generated.rs");
    std::fs::write(dest, g.out).expect("write generated.rs");
}

fn kind_enum(o: &mut String, name: &str, module: &str, kinds: &[(u8, u8, String)], functions: bool) {
    let _ = writeln!(
        o,
        "/// Every {name} kind of the MIB.\n#[derive(Clone, Debug, PartialEq, Eq)]\npub enum {name} {{"
    );
    for (_, _, ty) in kinds {
        let _ = writeln!(o, "    {ty}({module}::{ty}),");
    }
    let _ = writeln!(o, "}}\n\nimpl {name} {{");
    let _ = writeln!(
        o,
        "    /// Parses the body of a `[service, subservice]` packet{}.\n    pub fn parse(service: u8, subservice: u8, data: &[u8]) -> Result<Self, Error> {{",
        if functions { " (PUS 8: by the function ID in front)" } else { "" }
    );
    if functions {
        let _ = writeln!(
            o,
            "        let function = if service == {} {{ data.get(..2).map(|b| u16::from_be_bytes([b[0], b[1]])) }} else {{ None }};",
            mib::tc::service::FUNCTION
        );
    }
    let _ = writeln!(o, "        Ok(match (service, subservice) {{");
    for (s, ss, ty) in kinds {
        if functions && *s == mib::tc::service::FUNCTION {
            let _ = writeln!(
                o,
                "            ({s}, {ss}) if function == {module}::{ty}::FUNCTION => {name}::{ty}({module}::{ty}::parse(data)?),"
            );
        } else {
            let _ = writeln!(
                o,
                "            ({s}, {ss}) => {name}::{ty}({module}::{ty}::parse(data)?),"
            );
        }
    }
    let _ = writeln!(
        o,
        "            _ => return Err(Error::UnknownKind {{ service, subservice }}),\n        }})\n    }}"
    );
    let _ = writeln!(
        o,
        "    /// Service and subservice.\n    pub fn kind(&self) -> (u8, u8) {{ match self {{"
    );
    for (s, ss, ty) in kinds {
        let _ = writeln!(o, "        {name}::{ty}(_) => ({s}, {ss}),");
    }
    let _ = writeln!(
        o,
        "    }} }}\n    /// MIB name.\n    pub fn name(&self) -> &'static str {{ match self {{"
    );
    for (_, _, ty) in kinds {
        let _ = writeln!(o, "        {name}::{ty}(_) => {module}::{ty}::NAME,");
    }
    let _ = writeln!(o, "    }} }}\n    /// Emits the body; returns the bytes written.\n    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, Error> {{ match self {{");
    for (_, _, ty) in kinds {
        let _ = writeln!(o, "        {name}::{ty}(x) => x.emit(buf),");
    }
    let _ = writeln!(o, "    }} }}\n    pub fn buffer_len(&self) -> usize {{ match self {{");
    for (_, _, ty) in kinds {
        let _ = writeln!(o, "        {name}::{ty}(x) => x.buffer_len(),");
    }
    let _ = writeln!(o, "    }} }}\n}}\n");
}
