//! Lines to standard output and standard error that never panic on a closed pipe.

use std::io::Write;

use anyhow::Result;

/// Writes a line to standard error, ignoring a closed stderr (no panic, unlike
/// `eprintln!`).
macro_rules! err_line {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($t)*);
    }};
}
pub(crate) use err_line;

/// Writes a line to standard output; a closed pipe surfaces as an error that `main`
/// turns into a quiet exit.
pub(crate) fn out(line: &str) -> Result<()> {
    let mut o = std::io::stdout().lock();
    o.write_all(line.as_bytes())?;
    o.write_all(b"\n")?;
    Ok(())
}
