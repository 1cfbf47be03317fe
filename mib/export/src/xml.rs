//! The indented XML writer the XTCE exporters share.

/// `s` with the five XML special characters escaped.
pub(crate) fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            _ => o.push(c),
        }
    }
    o
}

/// An XML text being written, one element per line, two spaces per level of `depth`.
pub(crate) struct Xml {
    pub(crate) s: String,
    pub(crate) depth: usize,
}

impl Xml {
    pub(crate) fn line(&mut self, l: &str) {
        for _ in 0..self.depth {
            self.s.push_str("  ");
        }
        self.s.push_str(l);
        self.s.push('\n');
    }
    pub(crate) fn open(&mut self, l: &str) {
        self.line(l);
        self.depth += 1;
    }
    pub(crate) fn close(&mut self, l: &str) {
        self.depth = self.depth.saturating_sub(1);
        self.line(l);
    }
}
