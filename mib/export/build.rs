//! Generates `constants.rs`: every public numeric constant the MIB declares (`pub const
//! NAME: u8|u16|u32|u64|usize|i8|i16|i32|i64|f32|f64`, at any public module path of the
//! `mib` crate's sources), with its doc comment, for the JSON export. Read from the
//! sources so that a constant added to the MIB reaches the export without a list to keep;
//! the values are the compiled constants themselves (the generated code names each one).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const NUMERIC: &[&str] = &[
    "u8", "u16", "u32", "u64", "usize", "i8", "i16", "i32", "i64", "f32", "f64",
];

/// (module path, name, doc) of one constant.
type Found = (Vec<String>, String, String);

fn doc_of(attrs: &[syn::Attribute]) -> String {
    let lines: Vec<String> = attrs
        .iter()
        .filter(|a| a.path().is_ident("doc"))
        .filter_map(|a| match &a.meta {
            syn::Meta::NameValue(nv) => match &nv.value {
                syn::Expr::Lit(syn::ExprLit {
                    lit: syn::Lit::Str(s), ..
                }) => Some(s.value().trim().to_string()),
                _ => None,
            },
            _ => None,
        })
        .collect();
    lines.join(" ").trim().to_string()
}

/// Items under a `cfg` (tests, features) are not in every build of the MIB.
fn gated(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| a.path().is_ident("cfg"))
}

fn numeric(ty: &syn::Type) -> bool {
    matches!(ty, syn::Type::Path(p) if p.path.get_ident().is_some_and(|i| NUMERIC.contains(&i.to_string().as_str())))
}

fn public(v: &syn::Visibility) -> bool {
    matches!(v, syn::Visibility::Public(_))
}

/// The body of a `named_codes!`: the names constant's docs and name, `;`, then the module.
struct NamedCodes(syn::ItemMod);

impl syn::parse::Parse for NamedCodes {
    fn parse(input: syn::parse::ParseStream) -> syn::Result<Self> {
        input.call(syn::Attribute::parse_outer)?;
        input.parse::<syn::Ident>()?;
        input.parse::<syn::Token![;]>()?;
        Ok(NamedCodes(input.parse()?))
    }
}

fn scan_items(items: &[syn::Item], module: &[String], out: &mut Vec<Found>) {
    for item in items {
        match item {
            syn::Item::Const(c) if public(&c.vis) && !gated(&c.attrs) => {
                if let syn::Type::Path(p) = &*c.ty {
                    if p.path
                        .get_ident()
                        .is_some_and(|i| NUMERIC.contains(&i.to_string().as_str()))
                    {
                        out.push((module.to_vec(), c.ident.to_string(), doc_of(&c.attrs)));
                    }
                }
            }
            // Associated constants of an inherent impl (`SeqCount::MODULUS`).
            syn::Item::Impl(i) if i.trait_.is_none() && !gated(&i.attrs) => {
                let syn::Type::Path(ty) = &*i.self_ty else { continue };
                let Some(ty) = ty.path.get_ident() else { continue };
                for it in &i.items {
                    if let syn::ImplItem::Const(c) = it {
                        if public(&c.vis) && !gated(&c.attrs) && numeric(&c.ty) {
                            out.push((module.to_vec(), format!("{ty}::{}", c.ident), doc_of(&c.attrs)));
                        }
                    }
                }
            }
            // A module of codes and its names (`mib::named_codes!`): its module as written.
            syn::Item::Macro(m) if m.mac.path.segments.last().is_some_and(|s| s.ident == "named_codes") => {
                let NamedCodes(inner) = m
                    .mac
                    .parse_body()
                    .unwrap_or_else(|e| panic!("named_codes! in {}: {e}", module.join("::")));
                scan_items(&[syn::Item::Mod(inner)], module, out);
            }
            syn::Item::Mod(m) if public(&m.vis) && !gated(&m.attrs) => {
                if let Some((_, inner)) = &m.content {
                    let mut path = module.to_vec();
                    path.push(m.ident.to_string());
                    scan_items(inner, &path, out);
                }
            }
            _ => {}
        }
    }
}

/// The file of module `path` under `src` (`a.rs` or `a/mod.rs`).
fn module_file(src: &Path, path: &[String]) -> Option<PathBuf> {
    let base = path.iter().fold(src.to_path_buf(), |p, m| p.join(m));
    let flat = base.with_extension("rs");
    let nested = base.join("mod.rs");
    [flat, nested].into_iter().find(|p| p.is_file())
}

/// Scans the file of module `path` and the public out-of-line modules it declares.
fn scan_module(src: &Path, file: &Path, path: &[String], out: &mut Vec<Found>) {
    println!("cargo:rerun-if-changed={}", file.display());
    let text = std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let ast = syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    scan_items(&ast.items, path, out);
    for item in &ast.items {
        if let syn::Item::Mod(m) = item {
            if m.content.is_none() && public(&m.vis) && !gated(&m.attrs) {
                let mut sub = path.to_vec();
                sub.push(m.ident.to_string());
                let f = module_file(src, &sub).unwrap_or_else(|| panic!("module {} has no file", sub.join("::")));
                scan_module(src, &f, &sub, out);
            }
        }
    }
}

fn main() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../src");
    let mut found = Vec::new();
    scan_module(&src, &src.join("lib.rs"), &[], &mut found);
    let mut code = String::from(
        "/// Every public numeric constant of the MIB: (module path, name, value, doc).\n\
         pub fn constants() -> Vec<(&'static str, &'static str, serde_json::Value, &'static str)> {\n    vec![\n",
    );
    for (module, name, doc) in &found {
        let m = module.join("::");
        let _ = writeln!(
            code,
            "        ({m:?}, {name:?}, serde_json::json!(mib::{m}::{name}), {doc:?}),"
        );
    }
    code.push_str("    ]\n}\n");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("OUT_DIR")).join("constants.rs");
    std::fs::write(out, code).expect("write constants.rs");
}
