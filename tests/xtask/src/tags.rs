//! Requirement tags in test sources: a comment line `// verifies: ID, ID` directly above a
//! test function (above or between its attributes, e.g. `#[test]`, also inside
//! `proptest! { .. }` blocks). The scanner blanks comments and string literals to track
//! inline `mod NAME { .. }` nesting, so a tag yields the test's module path inside its
//! target (`tests::foo`, `services::hk::tests::bar`).

use std::path::{Path, PathBuf};

/// The marker every tag line starts with (after `//` and spaces).
pub const MARKER: &str = "verifies:";

#[derive(Clone, Debug)]
pub struct Tag {
    pub file: PathBuf,
    /// 1-based line of the tag comment.
    pub line: usize,
    /// Inline modules around the function, outermost first.
    pub inline_mods: Vec<String>,
    pub fn_name: String,
    pub ids: Vec<String>,
}

/// A tag comment not followed by a function (reported as a finding).
#[derive(Clone, Debug)]
pub struct Orphan {
    pub file: PathBuf,
    pub line: usize,
    pub text: String,
}

/// Parses `// verifies: A-1, B-2` → ["A-1", "B-2"]; None if the line is no tag.
pub fn parse_tag_line(line: &str) -> Option<Vec<String>> {
    let t = line.trim_start();
    let rest = t.strip_prefix("//")?;
    let rest = rest.trim_start_matches('/').trim_start();
    let ids = rest.strip_prefix(MARKER)?;
    Some(
        ids.split([',', ' ', '\t'])
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(str::to_string)
            .collect(),
    )
}

/// Code of each line with comments and the contents of string/char literals blanked.
pub fn code_lines(src: &str) -> Vec<String> {
    lex(src).0
}

/// [`code_lines`], and for each line whether it starts in plain code (not inside a string
/// literal or a block comment).
fn lex(src: &str) -> (Vec<String>, Vec<bool>) {
    #[derive(Clone, Copy, PartialEq)]
    enum St {
        Code,
        Block(u32),
        Str,
        Raw(usize),
    }
    let chars: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut starts_in_code = vec![true];
    let mut cur = String::new();
    let mut st = St::Code;
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '\n' {
            out.push(std::mem::take(&mut cur));
            starts_in_code.push(st == St::Code);
            i += 1;
            continue;
        }
        match st {
            St::Code => {
                if c == '/' && next == Some('/') {
                    // skip to end of line
                    while i < chars.len() && chars[i] != '\n' {
                        i += 1;
                    }
                    continue;
                } else if c == '/' && next == Some('*') {
                    st = St::Block(1);
                    i += 2;
                    continue;
                } else if c == '"' {
                    st = St::Str;
                    cur.push('"');
                } else if c == 'r' && (next == Some('"') || next == Some('#')) && !prev_is_ident(&chars, i) {
                    let mut j = i + 1;
                    let mut hashes = 0;
                    while chars.get(j) == Some(&'#') {
                        hashes += 1;
                        j += 1;
                    }
                    if chars.get(j) == Some(&'"') {
                        st = St::Raw(hashes);
                        cur.push('"');
                        i = j + 1;
                        continue;
                    }
                    cur.push(c);
                } else if c == '\'' {
                    // char literal or lifetime
                    if next == Some('\\') {
                        let mut j = i + 2;
                        while j < chars.len() && chars[j] != '\'' && chars[j] != '\n' {
                            j += 1;
                        }
                        cur.push_str("' '");
                        i = j + 1;
                        continue;
                    } else if chars.get(i + 2) == Some(&'\'') {
                        cur.push_str("' '");
                        i += 3;
                        continue;
                    }
                    cur.push(c);
                } else {
                    cur.push(c);
                }
            }
            St::Block(d) => {
                if c == '*' && next == Some('/') {
                    st = if d == 1 { St::Code } else { St::Block(d - 1) };
                    i += 2;
                    continue;
                } else if c == '/' && next == Some('*') {
                    st = St::Block(d + 1);
                    i += 2;
                    continue;
                }
            }
            St::Str => {
                if c == '\\' && next == Some('\n') {
                    // a line continuation: the newline still ends a line
                    i += 1;
                    continue;
                } else if c == '\\' {
                    i += 2;
                    continue;
                } else if c == '"' {
                    st = St::Code;
                    cur.push('"');
                }
            }
            St::Raw(h) => {
                if c == '"' && (0..h).all(|k| chars.get(i + 1 + k) == Some(&'#')) {
                    st = St::Code;
                    cur.push('"');
                    i += 1 + h;
                    continue;
                }
            }
        }
        i += 1;
    }
    out.push(cur);
    (out, starts_in_code)
}

fn prev_is_ident(chars: &[char], i: usize) -> bool {
    i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_')
}

/// Name declared by `fn NAME` in a line of code, if any.
fn fn_name(code: &str) -> Option<String> {
    let toks: Vec<&str> = code
        .split(|c: char| !(c.is_alphanumeric() || c == '_'))
        .filter(|s| !s.is_empty())
        .collect();
    let pos = toks.iter().position(|t| *t == "fn")?;
    toks.get(pos + 1).map(|s| s.to_string())
}

/// Scans one source file for tags.
pub fn scan(file: &Path, src: &str) -> (Vec<Tag>, Vec<Orphan>) {
    let raw: Vec<&str> = src.lines().collect();
    let (code, in_code) = lex(src);
    let is_tag = |i: usize| in_code.get(i).copied().unwrap_or(false) && parse_tag_line(raw[i]).is_some();
    // module stack at the start of each line
    let mut depth: usize = 0;
    let mut stack: Vec<(String, usize)> = Vec::new();
    let mut pending_mod: Option<String> = None;
    let mut mods_at: Vec<Vec<String>> = Vec::with_capacity(code.len());
    for line in &code {
        mods_at.push(stack.iter().map(|(n, _)| n.clone()).collect());
        let toks = tokens(line);
        let mut k = 0;
        while k < toks.len() {
            let t = toks[k].as_str();
            match t {
                "mod" => {
                    if let Some(n) = toks.get(k + 1) {
                        if n.chars().all(|c| c.is_alphanumeric() || c == '_') {
                            pending_mod = Some(n.clone());
                            k += 1;
                        }
                    }
                }
                "{" => {
                    depth += 1;
                    if let Some(n) = pending_mod.take() {
                        stack.push((n, depth));
                    }
                }
                "}" => {
                    if stack.last().is_some_and(|(_, d)| *d == depth) {
                        stack.pop();
                    }
                    depth = depth.saturating_sub(1);
                }
                ";" => pending_mod = None,
                _ => {}
            }
            k += 1;
        }
    }
    let mut tags = Vec::new();
    let mut orphans = Vec::new();
    let mut i = 0;
    while i < raw.len() {
        let Some(ids) = parse_tag_line(raw[i]).filter(|_| is_tag(i)) else {
            i += 1;
            continue;
        };
        let mut found = None;
        let mut j = i + 1;
        while j < raw.len() {
            let t = raw[j].trim();
            if is_tag(j) {
                break;
            }
            if let Some(n) = code.get(j).and_then(|c| fn_name(c)) {
                found = Some((j, n));
                break;
            }
            if t.is_empty() || t.starts_with("//") || t.starts_with("#[") || t.starts_with("#!") {
                j += 1;
                continue;
            }
            // attribute continuation lines (multi-line #[..])
            if t.starts_with(')') || t.starts_with(']') || t.ends_with(',') {
                j += 1;
                continue;
            }
            break;
        }
        match found {
            Some((j, name)) => tags.push(Tag {
                file: file.to_path_buf(),
                line: i + 1,
                inline_mods: mods_at[j].clone(),
                fn_name: name,
                ids,
            }),
            None => orphans.push(Orphan {
                file: file.to_path_buf(),
                line: i + 1,
                text: raw[i].trim().to_string(),
            }),
        }
        i += 1;
    }
    (tags, orphans)
}

fn tokens(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for c in line.chars() {
        if c.is_alphanumeric() || c == '_' {
            cur.push(c);
        } else {
            if !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
            if matches!(c, '{' | '}' | ';') {
                out.push(c.to_string());
            }
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: REV-TRACE-01
    #[test]
    fn tags_find_functions_inside_inline_modules_and_skip_strings() {
        let src = r##"
mod outer {
    const S: &str = "mod fake { ";
    const R: &str = r#"} } mod x {"#;
    const C: char = '{';
    #[cfg(test)]
    mod tests {
        // verifies: A-1, B-2
        #[test]
        fn first() { let _ = '}'; }
        /* mod nope { */
        #[test]
        // verifies: C-3
        fn second<'a>(_: &'a str) {}
    }
    proptest! {
        // verifies: D-4
        #[test]
        fn third(x in 0..1u8) { let _ = x; }
    }
}
// verifies: E-5
const NOT_A_FN: u8 = 0;
"##;
        let (tags, orphans) = scan(Path::new("f.rs"), src);
        assert_eq!(tags.len(), 3, "{tags:?}");
        assert_eq!(tags[0].fn_name, "first");
        assert_eq!(tags[0].inline_mods, vec!["outer", "tests"]);
        assert_eq!(tags[0].ids, vec!["A-1", "B-2"]);
        assert_eq!(tags[1].fn_name, "second");
        assert_eq!(tags[1].inline_mods, vec!["outer", "tests"]);
        assert_eq!(tags[2].fn_name, "third");
        assert_eq!(tags[2].inline_mods, vec!["outer"]);
        assert_eq!(orphans.len(), 1);
        assert_eq!(orphans[0].line, 22);
    }

    // verifies: REV-TRACE-01
    #[test]
    fn tags_inside_string_literals_are_not_tags() {
        let src = "const S: &str = \"\n// verifies: X-1\n\";\nfn not_tagged() {}\n/*\n// verifies: Y-2\n*/\nfn nor_this() {}\n";
        let (tags, orphans) = scan(Path::new("f.rs"), src);
        assert!(tags.is_empty(), "{tags:?}");
        assert!(orphans.is_empty(), "{orphans:?}");
    }

    // verifies: REV-TRACE-01
    #[test]
    fn a_string_continued_over_lines_keeps_the_line_numbers() {
        let src = "const S: &str = \"a \\\n  b\";\n// verifies: X-1\n#[test]\nfn after_continuation() {}\n";
        let (tags, orphans) = scan(Path::new("x.rs"), src);
        assert!(orphans.is_empty());
        assert_eq!(tags.len(), 1);
        assert_eq!((tags[0].line, tags[0].fn_name.as_str()), (3, "after_continuation"));
    }

    // verifies: REV-TRACE-01
    #[test]
    fn tag_lines_parse_with_commas_or_spaces() {
        assert_eq!(
            parse_tag_line("    // verifies: PUS-17-01, MMIC-CMD-03"),
            Some(vec!["PUS-17-01".to_string(), "MMIC-CMD-03".to_string()])
        );
        assert_eq!(parse_tag_line("/// verifies: X-1 Y-2").unwrap().len(), 2);
        assert_eq!(parse_tag_line("// verify this"), None);
        assert_eq!(parse_tag_line("let x = 1; // verifies: A-1"), None);
    }
}
