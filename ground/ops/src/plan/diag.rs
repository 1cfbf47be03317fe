//! Plan errors placed in their file: byte spans turned into line and column.

use std::fmt;
use std::ops::Range;

use serde::Serialize;

/// One problem found in a plan, located by a byte range of the source.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlanError {
    pub span: Range<usize>,
    pub message: String,
}

/// A [`PlanError`] placed in a file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Diagnostic {
    pub file: String,
    pub line: usize,
    pub column: usize,
    pub message: String,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: error: {}",
            self.file, self.line, self.column, self.message
        )
    }
}

/// 1-based line and column (in characters) of a byte offset.
pub fn line_col(src: &str, offset: usize) -> (usize, usize) {
    Cursor::new(src).advance_to(offset)
}

/// Places errors in `file`, sorted by position. One pass over the source for all errors
/// (linear in the source and the number of errors).
pub fn diagnostics(file: &str, src: &str, errors: &[PlanError]) -> Vec<Diagnostic> {
    let mut errs: Vec<&PlanError> = errors.iter().collect();
    errs.sort_by_key(|e| e.span.start);
    let mut cursor = Cursor::new(src);
    errs.into_iter()
        .map(|e| {
            let (line, column) = cursor.advance_to(e.span.start);
            Diagnostic {
                file: file.to_string(),
                line,
                column,
                message: e.message.clone(),
            }
        })
        .collect()
}

/// A walk forward through a source, counting lines and characters.
struct Cursor<'s> {
    len: usize,
    chars: std::iter::Peekable<std::str::CharIndices<'s>>,
    line: usize,
    col: usize,
}

impl<'s> Cursor<'s> {
    fn new(src: &'s str) -> Self {
        Cursor {
            len: src.len(),
            chars: src.char_indices().peekable(),
            line: 1,
            col: 1,
        }
    }

    /// Line and column of byte `offset` (clamped to the source); offsets must not
    /// decrease from one call to the next.
    fn advance_to(&mut self, offset: usize) -> (usize, usize) {
        let offset = offset.min(self.len);
        while let Some(&(i, c)) = self.chars.peek() {
            if i >= offset {
                break;
            }
            if c == '\n' {
                self.line += 1;
                self.col = 1;
            } else {
                self.col += 1;
            }
            self.chars.next();
        }
        (self.line, self.col)
    }
}
